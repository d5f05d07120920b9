import dataclasses

import numpy as np
import pytest

from solver import SensorGrid


def test_regular_grid_is_row_major_x_fastest_and_centred():
    grid = SensorGrid.regular(4, 3, pitch=2e-3, thickness=1e-3)
    assert grid.shape == (3, 4) and grid.size == 12
    k = 1 * 4 + 2  # iy = 1, ix = 2
    np.testing.assert_allclose(grid.positions[k], [(2 - 1.5) * 2e-3, 0.0])
    np.testing.assert_allclose(grid.positions.mean(0), 0, atol=1e-18)
    # a frame reshapes to (ny, nx) with x along the rows
    xs = grid.positions[:, 0].reshape(grid.shape)
    assert np.all(np.diff(xs, axis=1) > 0) and np.all(np.diff(xs, axis=0) == 0)
    assert grid.is_regular


def test_grid_is_frozen_and_its_positions_read_only():
    grid = SensorGrid.regular(2, 2, 1e-3, 1e-3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        grid.pitch = 2e-3
    with pytest.raises(ValueError, match="read-only"):
        grid.positions[0, 0] = 1.0


def test_irregular_layout_and_thickness_change():
    positions = np.array([[0.0, 0.0], [1e-3, 0.0], [0.3e-3, 1.2e-3]])
    grid = SensorGrid(positions, 1e-3, 1e-3, (3,))
    assert not grid.is_regular and grid.size == 3
    thicker = grid.with_thickness(2e-3)
    assert thicker.thickness == 2e-3 and thicker.positions is not positions
    np.testing.assert_array_equal(thicker.positions, positions)


@pytest.mark.parametrize("kwargs, message", [
    (dict(positions=np.zeros((3, 3)), thickness=1e-3, pitch=1e-3, shape=(3,)), r"positions must have shape \(m, 2\)"),
    (dict(positions=np.full((2, 2), np.nan), thickness=1e-3, pitch=1e-3, shape=(2,)), "positions must be finite"),
    (dict(positions=np.zeros((4, 2)), thickness=1e-3, pitch=1e-3, shape=(3,)), r"shape \(3,\) does not hold"),
    (dict(positions=np.zeros((1, 2)), thickness="thick", pitch=1e-3, shape=(1,)), "thickness must be .* got 'thick'"),
    (dict(positions=np.zeros((1, 2)), thickness=1e-3, pitch=np.inf, shape=(1,)), "pitch must be .* got inf"),
], ids=["columns", "nan", "shape", "text", "inf"])
def test_invalid_layouts_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SensorGrid(**kwargs)


def test_repr_names_the_geometry():
    assert repr(SensorGrid.regular(3, 2, 2e-3, 1e-3)) == "SensorGrid(shape=(2, 3), pitch=0.002 m, thickness=0.001 m)"

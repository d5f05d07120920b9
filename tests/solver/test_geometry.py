"""SensorGrid: layout order, centring, immutability, regularity, material and taxel size, rejected input."""

import dataclasses
import math

import numpy as np
import pytest

from solver import SensorGrid


@pytest.mark.parametrize("nx, ny", [(4, 3), (3, 4), (1, 5), (5, 1), (1, 1)])
def test_regular_grid_is_row_major_x_fastest(nx, ny):
    pitch = 2e-3
    grid = SensorGrid.regular(nx, ny, pitch=pitch, thickness=1e-3)
    assert grid.shape == (ny, nx) and grid.size == nx * ny
    assert grid.positions.shape == (nx * ny, 2) and grid.positions.dtype == float
    for iy in range(ny):
        for ix in range(nx):
            k = iy * nx + ix
            expected = [(ix - (nx - 1) / 2) * pitch, (iy - (ny - 1) / 2) * pitch]
            np.testing.assert_allclose(grid.positions[k], expected, rtol=0, atol=1e-15)


def test_a_frame_reshapes_to_ny_nx():
    grid = SensorGrid.regular(4, 3, pitch=2e-3, thickness=1e-3)
    xs = grid.positions[:, 0].reshape(grid.shape)
    ys = grid.positions[:, 1].reshape(grid.shape)
    # along a row x grows and y is fixed; down a column y grows and x is fixed
    np.testing.assert_allclose(np.diff(xs, axis=1), 2e-3)
    np.testing.assert_array_equal(np.diff(xs, axis=0), 0)
    np.testing.assert_allclose(np.diff(ys, axis=0), 2e-3)
    np.testing.assert_array_equal(np.diff(ys, axis=1), 0)


@pytest.mark.parametrize("nx, ny", [(4, 3), (5, 5), (1, 6), (1, 1)])
def test_regular_grid_is_centred_on_the_origin(nx, ny):
    grid = SensorGrid.regular(nx, ny, pitch=1.5e-3, thickness=1e-3)
    np.testing.assert_allclose(grid.positions.mean(axis=0), 0, atol=1e-18)
    # symmetric: the first and the last node are mirror images
    np.testing.assert_allclose(grid.positions[0], -grid.positions[-1], atol=1e-18)
    half = [(nx - 1) / 2 * 1.5e-3, (ny - 1) / 2 * 1.5e-3]
    np.testing.assert_allclose(grid.positions.max(axis=0), half)


def test_scalars_are_stored_as_floats():
    grid = SensorGrid.regular(np.int64(3), 2, pitch=2, thickness=1)  # integer metres are fine
    assert grid.shape == (2, 3) and all(type(s) is int for s in grid.shape)
    assert type(grid.pitch) is float and type(grid.thickness) is float
    assert grid.pitch == 2.0 and grid.thickness == 1.0


@pytest.mark.parametrize("field, value", [
    ("positions", np.zeros((4, 2))), ("thickness", 2e-3), ("pitch", 2e-3), ("shape", (4, 1)),
    ("poisson_ratio", 0.3), ("sensor_size", 1e-4),
])
def test_grid_is_frozen(field, value):
    grid = SensorGrid.regular(2, 2, 1e-3, 1e-3)
    with pytest.raises(dataclasses.FrozenInstanceError, match=f"cannot assign to field '{field}'"):
        setattr(grid, field, value)
    assert grid.shape == (2, 2) and grid.pitch == 1e-3 and grid.thickness == 1e-3


def test_positions_are_read_only_and_a_copy():
    source = np.array([[0.0, 0.0], [1e-3, 0.0]])
    grid = SensorGrid(source, 1e-3, 1e-3, (1, 2))
    with pytest.raises(ValueError, match="read-only"):
        grid.positions[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        grid.positions += 1.0
    source[0, 0] = 5.0  # changing the caller's array afterwards does not move the sensors
    assert grid.positions[0, 0] == 0.0
    regular = SensorGrid.regular(3, 3, 1e-3, 1e-3)
    with pytest.raises(ValueError, match="read-only"):
        regular.positions[4] = (1.0, 1.0)


def test_is_regular():
    grid = SensorGrid.regular(4, 3, 2e-3, 1e-3)
    assert grid.is_regular
    assert grid.with_thickness(5e-3).is_regular
    # the same lattice shifted as a whole is still a regular grid
    shifted = SensorGrid(grid.positions + [0.7e-3, -3e-3], 1e-3, 2e-3, (3, 4))
    assert shifted.is_regular


@pytest.mark.parametrize("change", ["column-major", "reversed", "wrong-pitch", "jittered", "flat-shape"])
def test_is_not_regular(change):
    grid = SensorGrid.regular(3, 3, 2e-3, 1e-3)
    positions, pitch, shape = grid.positions.copy(), grid.pitch, grid.shape
    if change == "column-major":
        positions = positions[:, ::-1]  # y fastest
    elif change == "reversed":
        positions = positions[::-1]
    elif change == "wrong-pitch":
        pitch = 1e-3
    elif change == "jittered":
        positions[4] += [0.1e-3, 0.0]
    else:
        shape = (9,)
    assert not SensorGrid(positions, grid.thickness, pitch, shape).is_regular


def test_irregular_layout_and_thickness_change():
    positions = np.array([[0.0, 0.0], [1e-3, 0.0], [0.3e-3, 1.2e-3]])
    grid = SensorGrid(positions, 1e-3, 1e-3, (3,))
    assert not grid.is_regular and grid.size == 3 and grid.shape == (3,)
    thicker = grid.with_thickness(2e-3)
    assert thicker.thickness == 2e-3 and grid.thickness == 1e-3
    assert thicker.pitch == grid.pitch and thicker.shape == grid.shape
    np.testing.assert_array_equal(thicker.positions, positions)
    with pytest.raises(ValueError, match="thickness must be a positive finite number of metres, got 0"):
        grid.with_thickness(0)


def test_repr_names_the_geometry():
    assert repr(SensorGrid.regular(3, 2, 2e-3, 1e-3)) == "SensorGrid(shape=(2, 3), pitch=0.002 m, thickness=0.001 m, nu=0.5)"
    assert (repr(SensorGrid.regular(3, 2, 2e-3, 1e-3, poisson_ratio=0.45, sensor_size=1e-3))
            == "SensorGrid(shape=(2, 3), pitch=0.002 m, thickness=0.001 m, nu=0.45, sensor_size=0.001 m)")


# -- the elastomer's Poisson ratio and the taxel size -------------------------------------------

def test_material_and_taxel_defaults():
    # an incompressible layer read by point sensors, as every file without the keys means
    for grid in (SensorGrid.regular(3, 2, 2e-3, 1e-3), SensorGrid(np.zeros((1, 2)), 1e-3, 1e-3, (1,))):
        assert grid.poisson_ratio == 0.5 and type(grid.poisson_ratio) is float
        assert grid.sensor_size == 0.0 and type(grid.sensor_size) is float


@pytest.mark.parametrize("poisson_ratio, sensor_size", [
    (0.45, 1e-3), (0, 0), (0.5, 2e-3), (np.float32(0.25), np.float64(5e-4)), (np.int64(0), 0.0),
], ids=["typical", "zeros", "incompressible-full-cover", "numpy-floats", "numpy-int"])
def test_material_and_taxel_are_stored_as_floats(poisson_ratio, sensor_size):
    grid = SensorGrid.regular(4, 3, 2e-3, 1e-3, poisson_ratio=poisson_ratio, sensor_size=sensor_size)
    assert type(grid.poisson_ratio) is float and grid.poisson_ratio == float(poisson_ratio)
    assert type(grid.sensor_size) is float and grid.sensor_size == float(sensor_size)
    assert grid.is_regular  # nu and the taxel size do not move the sensors
    direct = SensorGrid(grid.positions, 1e-3, 2e-3, (3, 4), poisson_ratio, sensor_size)
    assert direct.poisson_ratio == grid.poisson_ratio and direct.sensor_size == grid.sensor_size


def test_thickness_change_and_replace_keep_material_and_taxel():
    grid = SensorGrid.regular(4, 3, 2e-3, 1e-3, poisson_ratio=0.45, sensor_size=1e-3)
    thicker = grid.with_thickness(3e-3)
    assert thicker.thickness == 3e-3 and thicker.poisson_ratio == 0.45 and thicker.sensor_size == 1e-3
    window = grid.replace(positions=grid.positions[:4], shape=(4,))
    assert window.size == 4 and window.poisson_ratio == 0.45 and window.sensor_size == 1e-3
    assert window.pitch == grid.pitch and window.thickness == grid.thickness
    softer = grid.replace(poisson_ratio=0.3)
    assert softer.poisson_ratio == 0.3 and grid.poisson_ratio == 0.45  # a copy: the original stays
    np.testing.assert_array_equal(softer.positions, grid.positions)
    # a changed field is checked like a new grid's
    with pytest.raises(ValueError, match=r"poisson_ratio must be a finite number in \[0, 0.5\], got 0.7"):
        grid.replace(poisson_ratio=0.7)
    with pytest.raises(ValueError, match=r"sensor_size must be at most the pitch \(taxels cannot overlap\), "
                                         r"got 0.001 m with pitch 0.0005 m"):
        grid.replace(pitch=0.5e-3)  # the taxels that fitted at 2 mm overlap at 0.5 mm
    with pytest.raises(TypeError, match="unexpected keyword argument 'nu'"):
        grid.replace(nu=0.3)


NU_RULE = r"poisson_ratio must be a finite number in \[0, 0.5\], got "
SIZE_RULE = r"sensor_size must be a finite number of metres >= 0 \(0 for point sensors\), got "
OVERLAP_RULE = r"sensor_size must be at most the pitch \(taxels cannot overlap\), got "


@pytest.mark.parametrize("kwargs, message", [
    (dict(poisson_ratio=0.7), NU_RULE + "0.7$"),
    (dict(poisson_ratio=0.5000001), NU_RULE + "0.5000001$"),
    (dict(poisson_ratio=-0.1), NU_RULE + "-0.1$"),
    (dict(poisson_ratio=math.nan), NU_RULE + "nan$"),
    (dict(poisson_ratio=math.inf), NU_RULE + "inf$"),
    (dict(poisson_ratio=-math.inf), NU_RULE + "-inf$"),
    (dict(poisson_ratio="abc"), NU_RULE + "'abc'$"),
    (dict(poisson_ratio="0.3"), NU_RULE + "'0.3'$"),
    (dict(poisson_ratio=None), NU_RULE + "None$"),
    (dict(poisson_ratio=True), NU_RULE + "True$"),
    (dict(poisson_ratio=np.bool_(False)), NU_RULE + "False$"),
    (dict(poisson_ratio=np.float64(0.7)), NU_RULE + "0.7$"),
    (dict(poisson_ratio=[0.3]), NU_RULE + r"\[0.3\]$"),
    (dict(sensor_size=-1e-4), SIZE_RULE + "-0.0001$"),
    (dict(sensor_size=math.nan), SIZE_RULE + "nan$"),
    (dict(sensor_size=math.inf), SIZE_RULE + "inf$"),
    (dict(sensor_size="1mm"), SIZE_RULE + "'1mm'$"),
    (dict(sensor_size=None), SIZE_RULE + "None$"),
    (dict(sensor_size=False), SIZE_RULE + "False$"),
    (dict(sensor_size=1.5e-3), OVERLAP_RULE + "0.0015 m with pitch 0.001 m$"),
    (dict(sensor_size=1e-3 * (1 + 1e-9)), OVERLAP_RULE + "0.001 m with pitch 0.001 m$"),
], ids=["nu-above", "nu-just-above", "nu-negative", "nu-nan", "nu-inf", "nu-minus-inf", "nu-text",
        "nu-numeric-text", "nu-none", "nu-bool", "nu-numpy-bool", "nu-numpy", "nu-list", "size-negative",
        "size-nan", "size-inf", "size-text", "size-none", "size-bool", "size-overlap", "size-just-over"])
def test_impossible_material_or_taxel_is_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SensorGrid.regular(4, 3, pitch=1e-3, thickness=1e-3, **kwargs)
    with pytest.raises(ValueError, match=message):
        SensorGrid(np.zeros((1, 2)), 1e-3, 1e-3, (1,), **kwargs)
    with pytest.raises(ValueError, match=message):
        SensorGrid.regular(4, 3, pitch=1e-3, thickness=1e-3).replace(**kwargs)


@pytest.mark.parametrize("kwargs, message", [
    (dict(nx=0), r"nx must be a positive integer \(a grid needs at least one taxel\), got 0"),
    (dict(ny=-2), r"ny must be a positive integer \(a grid needs at least one taxel\), got -2"),
    (dict(nx=2.5), "nx must be a positive integer, got 2.5"),
    (dict(nx=3.0), "nx must be a positive integer, got 3.0"),
    (dict(ny="3"), "ny must be a positive integer, got '3'"),
    (dict(nx=True), "nx must be a positive integer, got True"),
    (dict(ny=None), "ny must be a positive integer, got None"),
    (dict(pitch=0), "pitch must be a positive finite number of metres, got 0"),
    (dict(pitch=-1e-3), "pitch must be a positive finite number of metres, got -0.001"),
    (dict(pitch=math.inf), "pitch must be a positive finite number of metres, got inf"),
    (dict(pitch="wide"), "pitch must be a positive finite number of metres, got 'wide'"),
    (dict(pitch=None), "pitch must be a positive finite number of metres, got None"),
    (dict(thickness=0.0), "thickness must be a positive finite number of metres, got 0.0"),
    (dict(thickness=-math.inf), "thickness must be a positive finite number of metres, got -inf"),
    (dict(thickness=math.nan), "thickness must be a positive finite number of metres, got nan"),
], ids=["nx0", "ny-negative", "nx-fraction", "nx-float", "ny-text", "nx-bool", "ny-none", "pitch0",
        "pitch-negative", "pitch-inf", "pitch-text", "pitch-none", "thickness0", "thickness-minus-inf",
        "thickness-nan"])
def test_regular_rejects_impossible_arguments(kwargs, message):
    arguments = dict(nx=4, ny=3, pitch=1e-3, thickness=1e-3)
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        SensorGrid.regular(**arguments)


@pytest.mark.parametrize("kwargs, message", [
    (dict(positions=np.zeros((3, 3)), shape=(3,)), r"positions must have shape \(m, 2\) with m >= 1, got shape \(3, 3\)"),
    (dict(positions=np.zeros(2), shape=(1,)), r"positions must have shape \(m, 2\) with m >= 1, got shape \(2,\)"),
    (dict(positions=np.zeros((0, 2)), shape=(0,)), r"positions must have shape \(m, 2\) with m >= 1, got shape \(0, 2\)"),
    (dict(positions=np.full((2, 2), np.nan), shape=(2,)), "positions must be finite, got NaN or inf"),
    (dict(positions=[[0.0, np.inf]], shape=(1,)), "positions must be finite, got NaN or inf"),
    (dict(positions=np.zeros((4, 2)), shape=(3,)), r"shape \(3,\) does not hold the 4 positions given"),
    (dict(positions=np.zeros((4, 2)), shape=(2, 3)), r"shape \(2, 3\) does not hold the 4 positions given"),
    (dict(positions=np.zeros((1, 2)), thickness="thick"), "thickness must be a positive finite number of metres, got 'thick'"),
    (dict(positions=np.zeros((1, 2)), pitch=np.inf), "pitch must be a positive finite number of metres, got inf"),
], ids=["columns", "flat", "empty", "nan", "inf", "count", "count-2d", "text", "inf-pitch"])
def test_invalid_layouts_are_rejected(kwargs, message):
    arguments = dict(thickness=1e-3, pitch=1e-3, shape=(1,))
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        SensorGrid(**arguments)


@pytest.mark.parametrize("shape", [(-2, -2), (2.9, 2.1), (1, -1, -4)], ids=["negative", "fraction", "3d-negative"])
def test_impossible_shapes_are_rejected(shape):
    with pytest.raises(ValueError, match=r"shape entries must be whole numbers >= 1, got \("):
        SensorGrid(np.zeros((4, 2)), 1e-3, 1e-3, shape)


def test_border_is_the_outer_rows_and_columns_of_a_regular_grid():
    grid = SensorGrid.regular(5, 4, 1e-3, 1e-3)
    edge = grid.border.reshape(grid.shape)
    assert edge[[0, -1], :].all() and edge[:, [0, -1]].all() and not edge[1:-1, 1:-1].any()
    assert grid.border.sum() == 2 * 5 + 2 * 4 - 4
    with pytest.raises(ValueError, match="read-only"):
        grid.border[0] = False
    # an irregular layout has no rows and columns to be outer
    scattered = grid.replace(positions=grid.positions[:7], shape=(7,))
    assert scattered.border.shape == (7,) and not scattered.border.any()

"""Sensor layout files (tactile_viewer/io/layout.py): round trips, calibration, every malformed-file path."""

import json
import re

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.layout import LayoutError, SensorLayout, load_layout, save_layout
from tests.tactile_viewer.skins import NU, TAXEL, grid32, grid_with_material

# -- SensorLayout ---------------------------------------------------------------------------------

@pytest.mark.parametrize("units, scale", [("Pa", 1.0), ("kPa", 1e3), ("MPa", 1e6), ("counts", 1.0)])
def test_to_pascals_scales_by_units(units, scale):
    layout = SensorLayout(grid32(), units)
    raw = np.arange(6.0)
    np.testing.assert_allclose(layout.to_pascals(raw), raw * scale, rtol=1e-15)
    assert layout.count == 6


def test_counts_use_the_gain_as_pascals_per_count():
    layout = SensorLayout(grid32(), "counts", gain=2.5, offset=100.0)
    np.testing.assert_allclose(layout.to_pascals(np.full(6, 140.0)), np.full(6, 100.0))  # 2.5 * (140 - 100)


def test_per_taxel_gain_and_offset_apply_to_single_frames_and_stacks():
    gain, offset = np.arange(1.0, 7.0), np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    layout = SensorLayout(grid32(), "kPa", gain=gain, offset=offset)
    raw = np.full(6, 10.0)
    expected = gain * (raw - offset) * 1e3
    np.testing.assert_allclose(layout.to_pascals(raw), expected)
    # (T, m): each row calibrated the same way
    np.testing.assert_allclose(layout.to_pascals(np.stack([raw, raw, raw])), np.stack([expected] * 3))


def test_scalar_gain_and_offset_broadcast_to_read_only_arrays():
    layout = SensorLayout(grid32(), gain=2, offset=-1)
    assert layout.gain.shape == layout.offset.shape == (6,)
    assert layout.gain.dtype == float and np.all(layout.gain == 2.0) and np.all(layout.offset == -1.0)
    for array in (layout.gain, layout.offset):
        assert not array.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 5.0


def test_per_taxel_arrays_are_copied_not_shared():
    gain = np.ones(6)
    layout = SensorLayout(grid32(), gain=gain)
    gain[0] = 99.0  # the caller's array changing later must not recalibrate the layout
    assert layout.gain[0] == 1.0 and not layout.gain.flags.writeable


@pytest.mark.parametrize("kwargs, message", [
    (dict(units="N"), r"units must be one of .*'N'"),
    (dict(units="kpa"), r"units must be one of"),
    (dict(gain=np.ones(5)), r"gain must be one number or 6 numbers .*\(5,\)"),
    (dict(gain=np.ones((2, 3))), r"gain must be one number or 6 numbers .*\(2, 3\)"),
    (dict(offset=[1.0, 2.0]), r"offset must be one number or 6 numbers"),
    (dict(offset=np.array([0, 0, np.nan, 0, 0, 0])), r"offset must be finite"),
    (dict(gain=np.inf), r"gain must be finite"),
])
def test_layout_rejects(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SensorLayout(grid32(), **kwargs)


# -- layout files ---------------------------------------------------------------------------------

def test_layout_round_trip_regular(tmp_path):
    layout = SensorLayout(grid32(), "kPa", gain=1.5, offset=0.25)
    back = load_layout(save_layout(layout, tmp_path / "board.json"))
    assert back.units == "kPa" and back.grid.shape == (2, 3)
    assert back.grid.pitch == 2e-3 and back.grid.thickness == 1.5e-3 and back.grid.is_regular
    np.testing.assert_array_equal(back.grid.positions, layout.grid.positions)
    np.testing.assert_array_equal(back.gain, layout.gain)
    np.testing.assert_array_equal(back.offset, layout.offset)
    # a uniform gain is written as one number, as a person would write it
    spec = json.loads((tmp_path / "board.json").read_text())
    assert spec["gain"] == 1.5 and "positions" not in spec


def test_layout_round_trip_with_explicit_positions_and_per_taxel_calibration(tmp_path):
    positions = grid32().positions.copy()
    positions[4] += [0.3e-3, -0.2e-3]  # one taxel off the grid: the positions must be written
    grid = SensorGrid(positions, 1.5e-3, 2e-3, (2, 3))
    rng = np.random.default_rng(7)  # fixed seed
    layout = SensorLayout(grid, "counts", gain=rng.uniform(0.5, 2, 6), offset=rng.uniform(0, 100, 6))
    path = save_layout(layout, tmp_path / "irregular.json")
    assert "positions" in json.loads(path.read_text())
    back = load_layout(path)
    assert back.units == "counts" and back.grid.shape == (2, 3) and not back.grid.is_regular
    np.testing.assert_array_equal(back.grid.positions, positions)  # JSON floats round trip exactly
    np.testing.assert_array_equal(back.gain, layout.gain)
    np.testing.assert_array_equal(back.offset, layout.offset)


def test_layout_round_trip_keeps_a_shifted_regular_grid(tmp_path):
    shifted = SensorGrid(grid32().positions + [5e-3, 0.0], 1.5e-3, 2e-3, (2, 3))
    back = load_layout(save_layout(SensorLayout(shifted), tmp_path / "shifted.json"))
    np.testing.assert_array_equal(back.grid.positions, shifted.positions)


GOOD = {"nx": 3, "ny": 2, "pitch": 2e-3, "thickness": 1.5e-3}


@pytest.mark.parametrize("content, message", [
    ("{nx: 3", r"not JSON"),
    ("[1, 2, 3]", r"expected a JSON object, got list"),
    ('"a string"', r"expected a JSON object, got str"),
    (json.dumps({"nx": 3, "pitch": 1e-3}), r"missing 'ny', 'thickness'"),
    (json.dumps({**GOOD, "nx": 2.5}), r"nx and ny must be whole numbers, got 2.5 and 2"),
    (json.dumps({**GOOD, "nx": "4"}), r"nx and ny must be whole numbers, got '4'"),
    (json.dumps({**GOOD, "ny": True}), r"nx and ny must be whole numbers"),
    (json.dumps({**GOOD, "nx": 0}), r"nx must be a positive integer"),
    (json.dumps({**GOOD, "pitch": 0}), r"pitch must be a positive finite number"),
    (json.dumps({**GOOD, "thickness": "thick"}), r"thickness must be a number of metres, got 'thick'"),
    (json.dumps({**GOOD, "thickness": "2e-3"}), r"thickness must be a number of metres, got '2e-3'"),
    (json.dumps({**GOOD, "gain": [1, 2, 3]}), r"gain must be one number or 6 numbers"),
    (json.dumps({**GOOD, "offset": float("nan")}), r"offset must be finite"),
    (json.dumps({**GOOD, "units": "psi"}), r"units must be one of"),
    (json.dumps({**GOOD, "positions": [[0, 0], [1, 1]]}), r"shape \(2, 3\) does not hold the 2 positions"),
    # they reached the window's "Unexpected error": a RecursionError and a bare ValueError
    ("[" * 100000 + "]" * 100000, r"not a layout: JSON nested too deep to read"),
    ('{"nx": ' + "9" * 5000 + ', "ny": 2, "pitch": 2e-3, "thickness": 1.5e-3}', r"not JSON \(.*4300 digits"),
])
def test_bad_layout_files_name_the_file_and_the_problem(tmp_path, content, message):
    path = tmp_path / "bad layout.json"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(LayoutError, match=re.escape(str(path)) + ".*" + message):
        load_layout(path)


# the elastomer's Poisson ratio and the taxel size travel with the layout
def test_layout_round_trip_keeps_poisson_ratio_and_sensor_size(tmp_path):
    path = save_layout(SensorLayout(grid_with_material(), "kPa"), tmp_path / "board.json")
    spec = json.loads(path.read_text())
    assert spec["poisson_ratio"] == NU and spec["sensor_size"] == TAXEL  # readable in the file itself
    back = load_layout(path).grid
    assert back.poisson_ratio == NU and back.sensor_size == TAXEL and back.is_regular
    # irregular positions are written separately: the material must survive that path too
    positions = grid_with_material().positions.copy()
    positions[1] += [0.2e-3, 0.0]
    moved = grid_with_material().replace(positions=positions)
    back = load_layout(save_layout(SensorLayout(moved), tmp_path / "moved.json")).grid
    assert back.poisson_ratio == NU and back.sensor_size == TAXEL
    np.testing.assert_array_equal(back.positions, positions)


def test_default_layout_writes_the_defaults_explicitly(tmp_path):
    spec = json.loads(save_layout(SensorLayout(grid32()), tmp_path / "board.json").read_text())
    assert spec["poisson_ratio"] == 0.5 and spec["sensor_size"] == 0.0


def test_layout_without_poisson_ratio_or_sensor_size_opens_with_the_defaults(tmp_path):
    # files written before the layer kernel: an incompressible layer, point sensors
    path = tmp_path / "old.json"
    path.write_text(json.dumps(GOOD), encoding="utf-8")
    grid = load_layout(path).grid
    assert grid.poisson_ratio == 0.5 and grid.sensor_size == 0.0
    path.write_text(json.dumps({**GOOD, "poisson_ratio": 0}), encoding="utf-8")
    assert load_layout(path).grid.poisson_ratio == 0.0  # 0 is allowed and not taken for "absent"


@pytest.mark.parametrize("changes, message", [
    (dict(poisson_ratio=0.7), r"poisson_ratio must be a finite number in \[0, 0.5\], got 0.7$"),
    (dict(poisson_ratio="abc"), r"poisson_ratio must be a finite number in \[0, 0.5\], got 'abc'$"),
    (dict(poisson_ratio="0.45"), r"poisson_ratio must be a finite number in \[0, 0.5\], got '0.45'$"),
    (dict(poisson_ratio=-0.2), r"poisson_ratio must be a finite number in \[0, 0.5\], got -0.2$"),
    (dict(poisson_ratio=True), r"poisson_ratio must be a finite number in \[0, 0.5\], got True$"),
    (dict(poisson_ratio=None), r"poisson_ratio must be a finite number in \[0, 0.5\], got None$"),
    (dict(sensor_size=3e-3), r"sensor_size must be at most the pitch \(taxels cannot overlap\), "
                             r"got 0.003 m with pitch 0.002 m$"),
    (dict(sensor_size=-1e-3), r"sensor_size must be a finite number of metres >= 0 .*, got -0.001$"),
    (dict(sensor_size="1 mm"), r"sensor_size must be a finite number of metres >= 0 .*, got '1 mm'$"),
], ids=["nu-above-half", "nu-text", "nu-numeric-text", "nu-negative", "nu-bool", "nu-null", "taxel-overlap",
        "taxel-negative", "taxel-text"])
def test_bad_poisson_ratio_or_sensor_size_in_a_layout_names_file_and_field(tmp_path, changes, message):
    path = tmp_path / "bad layout.json"
    path.write_text(json.dumps({**GOOD, **changes}), encoding="utf-8")
    with pytest.raises(LayoutError, match=re.escape(str(path)) + ": " + message):
        load_layout(path)


def test_missing_and_undecodable_layout_files(tmp_path):
    missing = tmp_path / "nowhere.json"
    with pytest.raises(LayoutError, match=re.escape(str(missing)) + r": cannot read"):
        load_layout(missing)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00garbage")  # not UTF-8 at all
    with pytest.raises(LayoutError, match=re.escape(str(binary)) + r": not JSON"):
        load_layout(binary)
    assert issubclass(LayoutError, ValueError)  # callers catching ValueError see it too



def test_an_irregular_layout_round_trips(tmp_path):
    rng = np.random.default_rng(13)  # fixed seed: the same scattered taxels every run
    grid = SensorGrid(rng.uniform(-4e-3, 4e-3, (36, 2)), 1.5e-3, 2e-3, (36,))
    path = save_layout(SensorLayout(grid, "Pa"), tmp_path / "scattered.json")
    spec = json.loads(path.read_text())
    assert spec["taxels"] == 36 and "nx" not in spec and len(spec["positions"]) == 36
    back = load_layout(path)
    assert back.grid.shape == (36,)
    np.testing.assert_array_equal(back.grid.positions, grid.positions)


def test_a_layout_declaring_a_huge_grid_is_refused(tmp_path):
    path = tmp_path / "huge.json"
    path.write_text('{"nx": 100000, "ny": 100000, "pitch": 0.002, "thickness": 0.002}')
    with pytest.raises(LayoutError, match=r"huge.json: a 100000x100000 grid is not a skin this viewer opens"):
        load_layout(path)

"""The Recording and the geometry every format declares (tactile_viewer/io/recording.py): the Poisson ratio
and taxel size, irregular and moved layouts, a grid too large to believe, inconsistent arrays; each through NPZ
and CSV alike. The formats themselves are in test_npz.py and test_csv_table.py, the one load and save in
test_files.py, the MCAP recorder and reader in test_mcap*.py."""

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.files import load, save
from tactile_viewer.io.recording import Recording, RecordingError, grid_from_fields
from tests.tactile_viewer.io.test_csv_table import HEADER
from tests.tactile_viewer.io.test_npz import write_npz
from tests.tactile_viewer.skins import NU, TAXEL

# -- the elastomer's Poisson ratio and the taxel size ---------------------------------------------

@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_poisson_ratio_and_sensor_size_round_trip(recording, tmp_path, suffix):
    grid = recording.grid.replace(poisson_ratio=NU, sensor_size=TAXEL)
    soft = Recording(grid, recording.frames, recording.t, description="soft skin")
    back = load(save(soft, tmp_path / f"soft{suffix}")).grid
    assert back.poisson_ratio == NU and back.sensor_size == TAXEL  # exact: repr in CSV, float64 in NPZ
    assert back.shape == (2, 3) and back.pitch == 2e-3 and back.thickness == 1.5e-3


def test_files_write_the_defaults_explicitly(recording, tmp_path):
    with np.load(save(recording, tmp_path / "r.npz")) as data:
        assert float(data["poisson_ratio"]) == 0.5 and float(data["sensor_size"]) == 0.0
    text = save(recording, tmp_path / "r.csv").read_text()
    assert "# poisson_ratio=0.5\n" in text and "# sensor_size=0.0\n" in text


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_files_without_poisson_ratio_or_sensor_size_load_with_the_defaults(tmp_path, suffix):
    # recordings made before the layer kernel: an incompressible layer read by point sensors
    path = tmp_path / f"old{suffix}"
    write_npz(path) if suffix == ".npz" else path.write_text(HEADER + "0, 1, 2\n")
    grid = load(path).grid
    assert grid.poisson_ratio == 0.5 and grid.sensor_size == 0.0


# -- the recording itself ----------------------------------------------------------------------------

def test_arrays_are_read_only(recording):
    with pytest.raises(ValueError, match="read-only"):
        recording.frames[0, 0] = 0
    with pytest.raises(ValueError, match="read-only"):
        recording.t[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        recording.truth_forces[0, 0, 0] = 1.0


@pytest.mark.parametrize("kwargs, message", [
    (dict(frames=np.ones((2, 5))), r"frames must have shape \(T, 4\), got \(2, 5\)"),
    (dict(t=[0.0, 1.0, 2.0]), r"t must have shape \(2,\), got \(3,\)"),
    (dict(t=[0.0, np.nan]), "t must be finite and non-decreasing"),
    (dict(truth_forces=np.zeros((2, 4))), r"truth_forces must have shape \(2, 4, 3\), got \(2, 4\)"),
], ids=["frames", "t-length", "t-nan", "truth"])
def test_recording_rejects_inconsistent_arrays(kwargs, message):
    arguments = dict(grid=SensorGrid.regular(2, 2, 1e-3, 1e-3), frames=np.ones((2, 4)), t=[0.0, 1.0])
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=message):
        Recording(**arguments)


# -- irregular layouts (shape (m,)) and declared sizes ------------------------------------------


def scattered(count=7):
    # a skin whose taxels follow no grid: shape (m,)
    rng = np.random.default_rng(11)  # fixed seed: the same layout every run
    return SensorGrid(rng.uniform(-5e-3, 5e-3, (count, 2)), 1.5e-3, 2e-3, (count,), poisson_ratio=0.45,
                      sensor_size=1e-3)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_an_irregular_layout_round_trips(tmp_path, suffix):
    grid = scattered()
    rng = np.random.default_rng(12)  # fixed seed
    recording = Recording(grid, rng.uniform(0, 1e3, (3, 7)), [0.0, 0.1, 0.2], description="scattered")
    back = load(save(recording, tmp_path / f"scattered{suffix}"))
    assert back.grid.shape == (7,) and not back.grid.is_regular
    np.testing.assert_array_equal(back.grid.positions, grid.positions)  # repr round-trips floats exactly
    assert (back.grid.pitch, back.grid.thickness, back.grid.poisson_ratio, back.grid.sensor_size) == \
        (2e-3, 1.5e-3, 0.45, 1e-3)
    np.testing.assert_allclose(back.frames, recording.frames, rtol=1e-8)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_a_regular_grid_moved_off_centre_keeps_its_place(tmp_path, suffix):
    grid = SensorGrid.regular(3, 2, 2e-3, 1e-3)
    moved = grid.replace(positions=grid.positions + [4e-3, -1e-3])
    back = load(save(Recording(moved, np.ones((1, 6)), [0.0]), tmp_path / f"moved{suffix}"))
    assert back.grid.shape == (2, 3)
    np.testing.assert_allclose(back.grid.positions, moved.positions, rtol=0, atol=1e-15)


def test_a_huge_declared_grid_is_refused_before_anything_is_allocated(tmp_path):
    # 1.6 KB on disk, 74 GiB if the header were believed
    path = tmp_path / "huge.npz"
    np.savez(path, frames=np.zeros((1, 4)), t=[0.0], nx=100000, ny=100000, pitch=2e-3, thickness=2e-3)
    with pytest.raises(RecordingError, match=r"a 100000x100000 grid is not a skin this viewer opens"):
        load(path)
    csv = tmp_path / "huge.csv"
    csv.write_text("# nx=100000\n# ny=100000\n# pitch=0.002\n# thickness=0.002\n0,1,2,3,4\n")
    with pytest.raises(RecordingError, match=r"huge.csv: impossible geometry: a 100000x100000 grid"):
        load(csv)


@pytest.mark.parametrize("fields, message", [
    (dict(taxels=3), r"an irregular layout \('taxels'\) needs 'positions'"),
    (dict(taxels=3, positions=[[0.0, 0.0]] * 2), r"shape \(3,\) does not hold the 2 positions given"),
    (dict(taxels=3, positions=[[0.0, 0.0]] * 3, width=4), r"declares 3 taxels but its frames have 4 values each"),
    (dict(nx=2), r"missing 'nx' and 'ny' \(or 'taxels' and 'positions'\)"),
], ids=["no-positions", "too-few-positions", "width", "no-ny"])
def test_declared_geometries_are_checked(fields, message):
    with pytest.raises(ValueError, match=message):
        grid_from_fields(pitch=1e-3, thickness=1e-3, **fields)

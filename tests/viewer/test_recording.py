"""Recordings in NPZ and CSV: round trips and every malformed-file path."""

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.recording import Recording, RecordingError, load, save


@pytest.fixture
def recording():
    grid = SensorGrid.regular(3, 2, 2e-3, 1.5e-3)
    rng = np.random.default_rng(0)  # fixed seed
    frames = rng.normal(1e3, 200, size=(5, 6))
    truth = rng.normal(0, 0.1, size=(5, 6, 3))
    return Recording(grid, frames, np.arange(5) / 100, truth, "five frames")


def test_npz_round_trip(recording, tmp_path):
    back = load(save(recording, tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.frames, recording.frames)
    np.testing.assert_array_equal(back.t, recording.t)
    np.testing.assert_array_equal(back.truth_forces, recording.truth_forces)
    np.testing.assert_array_equal(back.grid.positions, recording.grid.positions)
    assert back.grid.shape == (2, 3) and back.grid.thickness == 1.5e-3
    assert back.description == "five frames"


def test_csv_round_trip(recording, tmp_path):
    back = load(save(recording, tmp_path / "r.csv"))
    np.testing.assert_allclose(back.frames, recording.frames, rtol=1e-8)
    np.testing.assert_allclose(back.t, recording.t)
    assert back.truth_forces is None and back.grid.pitch == 2e-3 and back.description == "five frames"


def test_csv_in_kilopascals(tmp_path):
    path = tmp_path / "k.csv"
    path.write_text("# nx=2\n# ny=1\n# pitch=0.002\n# thickness=0.001\n# units=kPa\n0.0, 1.5, 2\n0.01, 3, 4\n")
    back = load(path)
    np.testing.assert_allclose(back.frames, [[1500, 2000], [3000, 4000]])


def test_arrays_are_read_only(recording):
    with pytest.raises(ValueError, match="read-only"):
        recording.frames[0, 0] = 0


def write_npz(path, **overrides):
    data = dict(frames=np.ones((2, 4)), t=[0.0, 0.1], nx=2, ny=2, pitch=1e-3, thickness=1e-3)
    data.update(overrides)
    np.savez(path, **{k: v for k, v in data.items() if v is not None})
    return path


@pytest.mark.parametrize("name, make, message", [
    ("garbage.npz", lambda p: p.write_bytes(b"\x00garbage" * 10), "not a readable NPZ archive"),
    ("nokey.npz", lambda p: write_npz(p, frames=None), "missing 'frames'"),
    ("nopitch.npz", lambda p: write_npz(p, pitch=None), "missing 'pitch'"),
    ("count.npz", lambda p: write_npz(p, frames=np.ones((2, 5))), "frames must have 4 values each"),
    ("nan.npz", lambda p: write_npz(p, frames=np.array([[1, 2, 3, 4], [1, np.nan, 3, 4]])),
     "frame 1 taxel 1 is not a finite number"),
    ("pitch.npz", lambda p: write_npz(p, pitch=0.0), "impossible geometry: pitch must be"),
    ("time.npz", lambda p: write_npz(p, t=[0.1, 0.0]), "t must be finite and non-decreasing"),
    ("units.npz", lambda p: write_npz(p, units="psi"), "units must be one of"),
    ("rows.csv", lambda p: p.write_text("# nx=2\n# ny=1\n# pitch=1e-3\n# thickness=1e-3\n0, 1, 2\n1, 1\n"),
     "line 6: 1 values, earlier rows have 2"),
    ("text.csv", lambda p: p.write_text("# nx=2\n# ny=1\n# pitch=1e-3\n# thickness=1e-3\n0, 1, 2\nhello\n"),
     "line 6: not a row of numbers: 'hello'"),
    ("empty.csv", lambda p: p.write_text("# nx=2\n# ny=1\n# pitch=1e-3\n# thickness=1e-3\n"), "no frames"),
    ("nogrid.csv", lambda p: p.write_text("0, 1, 2\n"), "missing 'nx'"),
    ("data.txt", lambda p: p.write_text("1 2 3"), "unknown recording type '.txt'"),
], ids=lambda v: v if isinstance(v, str) and "." in v else "")
def test_malformed_files_name_the_file_and_the_problem(tmp_path, name, make, message):
    path = tmp_path / name
    make(path)
    with pytest.raises(RecordingError, match=message) as info:
        load(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(RecordingError, match="missing.npz: cannot read|missing.npz: not a readable"):
        load(tmp_path / "missing.npz")

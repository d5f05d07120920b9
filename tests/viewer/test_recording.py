"""Recordings in NPZ and CSV (tactile_viewer/recording.py): round trips, units, every malformed-file
path, calibrations. The MCAP recorder and reader are in test_container.py."""

import re

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.recording import Recording, RecordingError, grid_from_fields, load, save
from tests.viewer.skins import NU, TAXEL

HEADER = "# nx=2\n# ny=1\n# pitch=1e-3\n# thickness=1e-3\n"  # a 2x1 grid: rows of t, v0, v1


@pytest.fixture
def recording():
    grid = SensorGrid.regular(3, 2, 2e-3, 1.5e-3)
    rng = np.random.default_rng(0)  # fixed seed
    frames = rng.normal(1e3, 200, size=(5, 6))
    truth = rng.normal(0, 0.1, size=(5, 6, 3))
    return Recording(grid, frames, np.arange(5) / 100, truth, "five frames")


# -- round trips ----------------------------------------------------------------------------------

def test_npz_round_trip(recording, tmp_path):
    path = save(recording, tmp_path / "r.npz")
    assert path == tmp_path / "r.npz" and path.is_file()
    back = load(path)
    np.testing.assert_array_equal(back.frames, recording.frames)
    np.testing.assert_array_equal(back.t, recording.t)
    np.testing.assert_array_equal(back.truth_forces, recording.truth_forces)
    np.testing.assert_array_equal(back.grid.positions, recording.grid.positions)
    assert back.grid.shape == (2, 3) and back.grid.pitch == 2e-3 and back.grid.thickness == 1.5e-3
    assert back.description == "five frames" and len(back) == 5


def test_npz_round_trip_of_an_irregular_layout(tmp_path):
    # explicit positions are kept (a (1, 3) "grid" whose middle sensor is off the line)
    positions = np.array([[0.0, 0.0], [1e-3, 0.2e-3], [2e-3, 0.0]])
    grid = SensorGrid(positions, 1e-3, 1e-3, (1, 3))
    back = load(save(Recording(grid, np.ones((2, 3)), [0.0, 1.0]), tmp_path / "irregular.npz"))
    np.testing.assert_array_equal(back.grid.positions, positions)
    assert not back.grid.is_regular and back.truth_forces is None and back.description == ""


def test_csv_round_trip(recording, tmp_path):
    back = load(save(recording, tmp_path / "r.csv"))
    np.testing.assert_allclose(back.frames, recording.frames, rtol=1e-8)  # written with 9 digits
    np.testing.assert_allclose(back.t, recording.t, rtol=1e-8, atol=1e-12)
    assert back.grid.shape == (2, 3) and back.grid.pitch == 2e-3 and back.grid.thickness == 1.5e-3
    np.testing.assert_array_equal(back.grid.positions, recording.grid.positions)
    assert back.truth_forces is None  # CSV carries frames and geometry only
    assert back.description == "five frames"


def test_csv_keeps_a_multi_line_description_on_one_line(tmp_path):
    grid = SensorGrid.regular(2, 1, 1e-3, 1e-3)
    path = save(Recording(grid, np.ones((1, 2)), [0.0], None, "two\nlines"), tmp_path / "d.csv")
    assert load(path).description == "two lines"


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


def test_npz_without_t_counts_frames(tmp_path):
    path = tmp_path / "no_t.npz"
    np.savez(path, frames=np.ones((3, 4)), nx=2, ny=2, pitch=1e-3, thickness=1e-3)
    np.testing.assert_array_equal(load(path).t, [0.0, 1.0, 2.0])


@pytest.mark.parametrize("suffix", [".NPZ", ".Csv"])
def test_extension_is_case_insensitive(recording, tmp_path, suffix):
    path = save(recording, tmp_path / f"upper{suffix}")
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"upper{suffix}"]
    back = load(path)
    np.testing.assert_allclose(back.frames, recording.frames, rtol=1e-8)


# -- units ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("units, scale", [("Pa", 1.0), ("kPa", 1e3), ("MPa", 1e6)])
def test_csv_units_are_scaled_to_pascals(tmp_path, units, scale):
    path = tmp_path / f"{units}.csv"
    path.write_text(HEADER + f"# units={units}\n0.0, 1.5, 2\n0.01, 3, -4\n")
    back = load(path)
    np.testing.assert_allclose(back.frames, np.array([[1.5, 2.0], [3.0, -4.0]]) * scale)
    np.testing.assert_allclose(back.t, [0.0, 0.01])  # time is not scaled


def test_csv_without_units_is_in_pascals(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text(HEADER + "0.0, 1.5, 2\n")
    np.testing.assert_allclose(load(path).frames, [[1.5, 2.0]])


def test_npz_in_kilopascals(tmp_path):
    path = tmp_path / "k.npz"
    np.savez(path, frames=[[1.0, 2.5]], nx=2, ny=1, pitch=1e-3, thickness=1e-3, units="kPa")
    np.testing.assert_allclose(load(path).frames, [[1000.0, 2500.0]])


def test_csv_tolerates_comments_blank_lines_and_semicolons(tmp_path):
    path = tmp_path / "loose.csv"
    path.write_text("# recorded on the bench\n" + HEADER + "\n# units = kPa\n0; 1; 2\n\n  0.5, 3, 4  \n")
    back = load(path)
    np.testing.assert_allclose(back.frames, [[1e3, 2e3], [3e3, 4e3]])
    np.testing.assert_allclose(back.t, [0.0, 0.5])


def test_arrays_are_read_only(recording):
    with pytest.raises(ValueError, match="read-only"):
        recording.frames[0, 0] = 0
    with pytest.raises(ValueError, match="read-only"):
        recording.t[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        recording.truth_forces[0, 0, 0] = 1.0


# -- malformed files ----------------------------------------------------------------------------------

def write_npz(path, **overrides):
    data = dict(frames=np.ones((2, 4)), t=[0.0, 0.1], nx=2, ny=2, pitch=1e-3, thickness=1e-3)
    data.update(overrides)
    np.savez(path, **{k: v for k, v in data.items() if v is not None})
    return path


def write_csv(body, header=HEADER):
    return lambda p: p.write_text(header + body)


MALFORMED = [
    # NPZ
    ("garbage.npz", lambda p: p.write_bytes(b"\x00garbage" * 10), "not a readable NPZ archive"),
    ("empty.npz", lambda p: p.write_bytes(b""), "not a readable NPZ archive"),
    ("nokey.npz", lambda p: write_npz(p, frames=None), "missing 'frames'"),
    ("nopitch.npz", lambda p: write_npz(p, pitch=None), "missing 'pitch'"),
    ("nonx.npz", lambda p: write_npz(p, nx=None), "missing 'nx'"),
    ("count.npz", lambda p: write_npz(p, frames=np.ones((2, 5))),
     r"declares a 2x2 grid \(4 taxels\) but its frames have 5 values each"),
    ("flat.npz", lambda p: write_npz(p, frames=np.ones(4)), r"frames must be a \(T, 4\) table for a 2x2 grid, got shape \(4,\)"),
    ("noframes.npz", lambda p: write_npz(p, frames=np.ones((0, 4)), t=[]), "no frames"),
    ("nan.npz", lambda p: write_npz(p, frames=np.array([[1, 2, 3, 4], [1, np.nan, 3, 4]])),
     "frame 1 taxel 1 is not a finite number"),
    ("inf.npz", lambda p: write_npz(p, frames=np.array([[1, 2, 3, -np.inf], [1, 2, 3, 4]])),
     "frame 0 taxel 3 is not a finite number"),
    ("pitch.npz", lambda p: write_npz(p, pitch=0.0),
     "impossible geometry: pitch must be a positive finite number of metres, got 0.0"),
    ("thick.npz", lambda p: write_npz(p, thickness=-1e-3),
     "impossible geometry: thickness must be a positive finite number of metres, got -0.001"),
    ("nx0.npz", lambda p: write_npz(p, nx=0, frames=np.ones((2, 0))),
     r"impossible geometry: nx must be a positive integer .* got 0"),
    ("nanpitch.npz", lambda p: write_npz(p, pitch=np.nan), "'pitch' must be finite, got nan"),
    ("textnx.npz", lambda p: write_npz(p, nx="two"), "'nx' must be a single number"),
    ("pairnx.npz", lambda p: write_npz(p, nx=[2, 2]), "'nx' must be a single number"),
    ("positions.npz", lambda p: write_npz(p, positions=np.zeros((3, 2))),
     r"impossible geometry: shape \(2, 2\) does not hold the 3 positions given"),
    ("time.npz", lambda p: write_npz(p, t=[0.1, 0.0]), "t must be finite and non-decreasing"),
    ("tlen.npz", lambda p: write_npz(p, t=[0.0]), r"t must have shape \(2,\), got \(1,\)"),
    ("truth.npz", lambda p: write_npz(p, truth_forces=np.zeros((2, 4))),
     r"truth_forces must have shape \(2, 4, 3\), got \(2, 4\)"),
    ("units.npz", lambda p: write_npz(p, units="psi"), r"units must be one of \['MPa', 'Pa', 'kPa'\], got 'psi'"),
    ("pickle.npz", lambda p: write_npz(p, frames=np.array([1, "a", None], dtype=object)), "allow_pickle=False"),
    ("nu.npz", lambda p: write_npz(p, poisson_ratio=0.7),
     r"impossible geometry: poisson_ratio must be a finite number in \[0, 0.5\], got 0.7$"),
    ("nutext.npz", lambda p: write_npz(p, poisson_ratio="abc"), r"'poisson_ratio' must be a single number, got 'abc'$"),
    ("nunan.npz", lambda p: write_npz(p, poisson_ratio=np.nan), "'poisson_ratio' must be finite, got nan$"),
    ("nupair.npz", lambda p: write_npz(p, poisson_ratio=[0.4, 0.45]), "'poisson_ratio' must be a single number"),
    ("taxel.npz", lambda p: write_npz(p, sensor_size=2e-3),
     r"impossible geometry: sensor_size must be at most the pitch \(taxels cannot overlap\), got 0.002 m with pitch 0.001 m$"),
    ("taxelneg.npz", lambda p: write_npz(p, sensor_size=-1e-4),
     r"impossible geometry: sensor_size must be a finite number of metres >= 0 .* got -0.0001$"),
    ("taxeltext.npz", lambda p: write_npz(p, sensor_size="big"), r"'sensor_size' must be a single number, got 'big'$"),
    # CSV
    ("nu.csv", write_csv("0, 1, 2\n", header=HEADER + "# poisson_ratio=0.7\n"),
     r"impossible geometry: poisson_ratio must be a finite number in \[0, 0.5\], got 0.7$"),
    ("nutext.csv", write_csv("0, 1, 2\n", header=HEADER + "# poisson_ratio=abc\n"),
     r"'poisson_ratio' must be a single number, got 'abc'$"),
    ("nuinf.csv", write_csv("0, 1, 2\n", header=HEADER + "# poisson_ratio=inf\n"), "'poisson_ratio' must be finite, got inf$"),
    ("taxel.csv", write_csv("0, 1, 2\n", header=HEADER + "# sensor_size=0.0015\n"),
     r"impossible geometry: sensor_size must be at most the pitch .* got 0.0015 m with pitch 0.001 m$"),
    ("taxeltext.csv", write_csv("0, 1, 2\n", header=HEADER + "# sensor_size=1 mm\n"),
     r"'sensor_size' must be a single number, got '1 mm'$"),
    ("rows.csv", write_csv("0, 1, 2\n1, 1\n"), "line 6: 1 values, earlier rows have 2"),
    ("text.csv", write_csv("0, 1, 2\nhello\n"), "line 6: not a row of numbers: 'hello'"),
    ("cell.csv", write_csv("0, 1, 2\n\n1, 1, x2\n"), "line 7: not a row of numbers: '1, 1, x2'"),
    ("trailing.csv", write_csv("0, 1, 2,\n"), "line 5: not a row of numbers"),
    ("count.csv", write_csv("0, 1, 2, 3\n1, 1, 2, 3\n"),
     r"declares a 2x1 grid \(2 taxels\) but its frames have 3 values each"),
    ("nan.csv", write_csv("0, 1, 2\n1, nan, 2\n"), "frame 1 taxel 0 is not a finite number"),
    ("inf.csv", write_csv("0, 1, 2\n1, 2, -inf\n"), "frame 1 taxel 1 is not a finite number"),
    ("nan_t.csv", write_csv("nan, 1, 2\n"), "t must be finite and non-decreasing"),
    ("back.csv", write_csv("1, 1, 2\n0, 1, 2\n"), "t must be finite and non-decreasing"),
    ("empty.csv", write_csv(""), "no frames"),
    ("nogrid.csv", lambda p: p.write_text("0, 1, 2\n"), "missing 'nx'"),
    ("pitch0.csv", write_csv("0, 1, 2\n", header=HEADER.replace("pitch=1e-3", "pitch=0")),
     "impossible geometry: pitch must be a positive finite number of metres, got 0.0"),
    ("pitchtext.csv", write_csv("0, 1, 2\n", header=HEADER.replace("pitch=1e-3", "pitch=wide")),
     "'pitch' must be a single number, got 'wide'"),
    ("nxfraction.csv", write_csv("0, 1, 2\n", header=HEADER.replace("nx=2", "nx=2.5")),
     "'nx' must be a whole number, got 2.5"),
    ("units.csv", write_csv("0, 1, 2\n", header=HEADER + "# units=bar\n"), "units must be one of .* got 'bar'"),
    ("latin1.csv", lambda p: p.write_bytes(HEADER.encode() + b"0, 1, \xb52\n"), "can't decode byte 0xb5"),
    # neither
    ("data.txt", lambda p: p.write_text("1 2 3"), r"unknown recording type '\.txt', expected one of \('\.mcap', '\.npz', '\.csv'\)"),
    ("noextension", lambda p: p.write_text("1 2 3"), r"unknown recording type '', expected one of \('\.mcap', '\.npz', '\.csv'\)"),
]


@pytest.mark.parametrize("name, make, message", MALFORMED, ids=[case[0] for case in MALFORMED])
def test_malformed_files_name_the_file_and_the_problem(tmp_path, name, make, message):
    path = tmp_path / name
    make(path)
    with pytest.raises(RecordingError, match=message) as info:
        load(path)
    # the message starts with the file's path
    assert str(info.value).startswith(f"{path}: ")
    assert isinstance(info.value, ValueError)  # callers catching ValueError see it too


@pytest.mark.parametrize("name", ["missing.npz", "missing.csv"])
def test_missing_file(tmp_path, name):
    path = tmp_path / name
    with pytest.raises(RecordingError, match="No such file or directory") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_a_directory_is_not_a_recording(tmp_path):
    path = tmp_path / "folder.csv"
    path.mkdir()
    with pytest.raises(RecordingError, match=re.escape(f"{path}: cannot read: Is a directory")):
        load(path)


def test_a_bare_npy_array_named_npz(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as handle:
        np.save(handle, np.ones(4))
    with pytest.raises(RecordingError) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_truncated_npz(recording, tmp_path):
    path = save(recording, tmp_path / "cut.npz")
    path.write_bytes(path.read_bytes()[:300])  # a crash while writing
    with pytest.raises(RecordingError, match="not a readable NPZ archive") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_corrupted_npz_member(tmp_path):
    path = tmp_path / "flipped.npz"
    frames = np.arange(8.0).reshape(2, 4)
    write_npz(path, frames=frames)  # uncompressed, so the bytes of the values can be found
    raw = bytearray(path.read_bytes())
    raw[raw.index(frames.tobytes()[8:16])] ^= 1  # one bit of frames[0, 1]
    path.write_bytes(bytes(raw))
    with pytest.raises(RecordingError, match="damaged NPZ archive") as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_a_bare_npy_array_named_npz_is_rejected(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as handle:
        np.save(handle, np.ones((2, 4)))
    with pytest.raises(RecordingError, match=r"array\.npz: not an NPZ archive \(a single array"):
        load(path)


def test_fractional_grid_size_in_npz(tmp_path):
    path = write_npz(tmp_path / "fraction.npz", nx=2.5)  # 2.5 x 2 "grid" with 4 values per frame
    with pytest.raises(RecordingError, match="'nx' must be a whole number, got 2.5"):
        load(path)


def test_save_rejects_an_unknown_extension(recording, tmp_path):
    with pytest.raises(RecordingError, match=r"r\.json: unknown recording type '\.json'"):
        save(recording, tmp_path / "r.json")
    assert not (tmp_path / "r.json").exists()


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

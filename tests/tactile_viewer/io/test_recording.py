"""Recordings in NPZ and CSV (tactile_viewer/io/recording.py): round trips, units, every malformed-file
path, declared sizes and decompression bombs. The MCAP recorder and reader are in test_container.py."""

import contextlib
import io
import struct
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

import tactile_viewer.io.recording as recording_module
from solver import SensorGrid
from tactile_viewer.io.files import load
from tactile_viewer.io.recording import Recording, RecordingError, grid_from_fields, save
from tests.tactile_viewer.skins import NU, TAXEL

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


def test_a_csv_cut_inside_its_last_value_leaves_that_row_out_and_says_so(recording, tmp_path):
    path = save(recording, tmp_path / "whole.csv")
    whole = path.read_text()
    cut = tmp_path / "cut.csv"
    cut.write_text(whole[:-3])  # a crash inside the last value: 1234.5678 would read as 1234.5
    back, full = load(cut), load(path)
    assert back.truncated and len(back) == len(recording) - 1 and not full.truncated
    np.testing.assert_array_equal(back.frames, full.frames[:-1])
    lone = tmp_path / "lone.csv"
    lone.write_text(HEADER + "0, 1, 2")
    with pytest.raises(RecordingError, match=r"no frames \(its one row has no line end: cut short\)"):
        load(lone)


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
    ("garbage.npz", lambda p: p.write_bytes(b"\x00garbage" * 10), r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b.\\x00garbage"),
    ("empty.npz", lambda p: p.write_bytes(b""), r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b..\)"),
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


def flip_name_bit(path, name, bit):
    # one bit of a member's name in the zip's directory (its local header keeps the old name: numpy reads
    # the directory), as a damaged file may have it
    raw = bytearray(path.read_bytes())
    at = raw.index(name.encode(), raw.index(b"PK\x01\x02"))  # in the central directory
    raw[at] ^= 1 << bit
    path.write_bytes(bytes(raw))


@pytest.mark.parametrize("field, value, renamed", [
    ("t", [0.0, 0.1], "u"), ("units", "kPa", "tnits"), ("seq", [7, 8], "req"),
    ("positions", [[0, 0], [1e-3, 0], [0, 1e-3], [1e-3, 1e-3]], "qositions"),
    ("poisson_ratio", 0.45, "qoisson_ratio"), ("sensor_size", 1e-4, "rensor_size"),
])
def test_a_damaged_member_name_is_refused_not_read_as_a_missing_field(tmp_path, field, value, renamed):
    # a flipped bit in the directory's 't.npy' gave times 0, 1, 2 s; 'units' read kPa as Pa
    path = write_npz(tmp_path / "named.npz", **{field: value})
    flip_name_bit(path, f"{field}.npy", 0)
    assert f"{renamed}.npy" in zipfile.ZipFile(path).namelist()
    with pytest.raises(RecordingError, match=rf"member '{renamed}.npy' is no field of a recording and "
                                             rf"'{field}.npy' is missing: the archive's directory is damaged"):
        load(path)


def test_extra_members_beside_every_field_still_load(tmp_path):
    # a member of the user's own (notes) is no damaged name: nothing it could be is missing
    path = write_npz(tmp_path / "extra.npz", notes="run 4", u=[1.0])
    assert len(load(path)) == 2


def test_a_chunk_without_a_field_the_others_have_is_refused(tmp_path):
    path = tmp_path / "chunks.npz"
    np.savez(path, nx=2, ny=2, pitch=1e-3, thickness=1e-3, chunk000000_frames=np.ones((2, 4)),
             chunk000000_t=[0.0, 0.1], chunk000001_frames=np.ones((1, 4)), chunk000001_x=[0.2])
    with pytest.raises(RecordingError, match="chunk000001_x.npy' is no field .* 'chunk000001_t.npy' is missing"):
        load(path)
    np.savez(path, nx=2, ny=2, pitch=1e-3, thickness=1e-3, chunk000000_frames=np.ones((2, 4)),
             chunk000000_t=[0.0, 0.1], chunk000001_frames=np.ones((1, 4)), chunk000001_when=[0.2])
    with pytest.raises(RecordingError, match=r"chunk\(s\) chunk000001 have no 't' while the others have it"):
        load(path)


@pytest.mark.parametrize("suffix", [".mcap", ".npz", ".csv"])
def test_only_a_regular_file_is_opened(tmp_path, suffix):
    import os
    import threading

    # a named pipe: open() would wait for a writer (File > Open froze the window)
    fifo = tmp_path / f"pipe{suffix}"
    os.mkfifo(fifo)
    outcome = []

    def opening():
        try:
            load(fifo)
        except RecordingError as exc:
            outcome.append(str(exc))
    thread = threading.Thread(target=opening, daemon=True)
    thread.start()
    thread.join(5)
    if thread.is_alive():  # release it, so the test fails instead of hanging
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail("load() blocked on a named pipe")
    assert outcome == [f"{fifo}: not a recording file: it is a named pipe (FIFO)"]
    # a device behind a link never ends; a folder is no file
    device = tmp_path / f"zeros{suffix}"
    device.symlink_to("/dev/zero")
    with pytest.raises(RecordingError, match=r"not a recording file: it is a device"):
        load(device)
    folder = tmp_path / f"folder{suffix}"
    folder.mkdir()
    with pytest.raises(RecordingError, match=r"not a recording file: it is a folder"):
        load(folder)


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


# -- declared sizes and decompression bombs ---------------------------------------------------------
# Files that declare more than they hold: a .npy header, a zip directory, a deflate stream or a CSV
# line. Each is refused with a RecordingError naming the field before anything of the declared size
# is made; tracemalloc sees numpy's allocations too (even untouched ones), so a load that believed
# the file would show its gigabytes here.


SKIN = dict(nx=16, ny=16, pitch=1e-3, thickness=1e-3)  # frames of 256 values, 2 KiB each
MIB = 2**20


@contextlib.contextmanager
def allocating_at_most(megabytes):
    """Fail when the block's traced allocations ever reach ``megabytes`` at once, even when the
    block failed otherwise (a load that allocated gigabytes is the news)."""
    tracemalloc.start()
    try:
        yield
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < megabytes * MIB, f"peak {peak / MIB:.0f} MiB"


def npy_header(shape, descr="<f8", version=1):
    """The .npy header of an array of ``shape``, written by hand: no array of that size is made."""
    text = f"{{'descr': {descr!r}, 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    width = 2 if version == 1 else 4  # bytes of the header's length
    text += " " * (-(8 + width + len(text) + 1) % 64) + "\n"  # numpy aligns the values to 64 bytes
    return b"\x93NUMPY" + bytes([version, 0]) + len(text).to_bytes(width, "little") + text.encode("latin1")


def npy(value):
    buffer = io.BytesIO()
    np.save(buffer, value)
    return buffer.getvalue()


def hostile_npz(path, members, compression=zipfile.ZIP_STORED):
    """An NPZ of ``members`` (name: .npy bytes) beside an honest 16x16 skin, written by zipfile alone."""
    with zipfile.ZipFile(path, "w", compression) as archive:
        for name, content in {**{key: npy(value) for key, value in SKIN.items()}, **members}.items():
            archive.writestr(f"{name}.npy", content)
    return path


def zero_frames(path, name="frames", mebibytes=256, compression=zipfile.ZIP_DEFLATED):
    """Add ``mebibytes`` of all-zero frames of the 16x16 skin, compressed a block at a time (never
    held whole): a decompression bomb, about 1028:1 deflated."""
    with zipfile.ZipFile(path, "a", compression) as archive, \
            archive.open(f"{name}.npy", "w", force_zip64=True) as member:
        member.write(npy_header((mebibytes * MIB // 2048, 256)))
        block = bytes(MIB)
        for _ in range(mebibytes):
            member.write(block)
    return path


def forge_directory(path, name, compressed, uncompressed):
    """Rewrite the sizes the zip's central directory gives member ``name`` (None: keep that one); the
    data stay as they are."""
    raw = bytearray(path.read_bytes())
    at = raw.index(b"PK\x01\x02")  # the central directory's first entry
    while raw[at + 46:at + 46 + len(name)] != name.encode():
        at = raw.index(b"PK\x01\x02", at + 4)
    kept = struct.unpack_from("<II", raw, at + 20)
    struct.pack_into("<II", raw, at + 20, kept[0] if compressed is None else compressed,
                     kept[1] if uncompressed is None else uncompressed)
    path.write_bytes(bytes(raw))
    return path


def declared(shape):  # a member of values that are not there: its header alone
    return npy_header(shape)


def chunked_zero_frames(path, chunks=5, mebibytes=15):
    """A live recording of ``chunks`` chunks of zero frames, each under the allowance alone."""
    hostile_npz(path, {})
    for index in range(chunks):
        zero_frames(path, f"chunk{index:06d}_frames", mebibytes)
    return path


HUGE = (20000, 20000)  # 3.2 GB of float64 declared by a 128-byte header
HOSTILE_NPZ = [
    ("stored", lambda p: hostile_npz(p, {"frames": declared(HUGE)}),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) but the file holds 1\.\d KB: not a recording"),
    ("deflated", lambda p: hostile_npz(p, {"frames": declared(HUGE)}, zipfile.ZIP_DEFLATED),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) from \d+ B compressed, \d+:1, more than the 1000:1 "
     r"any recording reaches: a decompression bomb"),
    # the directory agrees with the header, and both lie about what the file holds
    ("forged-directory", lambda p: forge_directory(hostile_npz(p, {"frames": declared(HUGE)}), "frames.npy",
                                                   3_200_000_128, 3_200_000_128),
     r"'frames' declares 20000x20000 values \(3\.2 GB\) but the file holds 1\.\d KB: not a recording"),
    ("forged-compressed-size",
     lambda p: forge_directory(hostile_npz(p, {"frames": declared(HUGE)}, zipfile.ZIP_DEFLATED), "frames.npy",
                               3_200_000_000, 3_200_000_128),
     r"damaged NPZ archive: its directory says 'frames' is 3\.2 GB compressed but the file holds \d+ B"),
    ("ceiling", lambda p: hostile_npz(p, {"frames": declared((40000, 20000))}),
     r"'frames' declares 40000x20000 values \(6\.4 GB\): the recording would take 6\.4 GB, more than the "
     r"4\.3 GB this viewer loads"),
    # an honest header and a directory that disagrees with it: damage
    ("lying-directory", lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}),
                                                  "frames.npy", 10000, 10000),
     r"damaged NPZ archive: its directory says 'frames' holds 10\.0 KB but its array header declares 4\.2 KB"),
    ("lying-directory-deflated",
     lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}, zipfile.ZIP_DEFLATED),
                               "frames.npy", None, 10000),
     r"damaged NPZ archive: its directory says 'frames' holds 10\.0 KB but its array header declares 4\.2 KB"),
    # a directory too short for the header itself: zipfile's own check of the CRC ends the read
    ("short-directory", lambda p: forge_directory(hostile_npz(p, {"frames": npy(np.zeros((2, 256)))}),
                                                  "frames.npy", 100, 100),
     r"damaged NPZ archive \(Bad CRC-32 for file 'frames\.npy'\)"),
    ("object-frames", lambda p: hostile_npz(p, {"frames": npy_header((2, 256), "|O") + b"\x80\x04junk"}),
     r"'frames' holds Python objects \(dtype object\), .*\(allow_pickle=False\)"),
    ("object-nx", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))), "nx": npy_header((), "|O")}),
     r"'nx' holds Python objects"),
    ("structured", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256), dtype=[("v", "<f8")]))}),
     r"'frames' must hold numbers, got dtype \[\('v', '<f8'\)\]"),
    ("huge-nx", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))), "nx": declared(HUGE)}),
     r"'nx' must be a single number, got shape \(20000, 20000\)"),
    ("huge-description", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                   "description": npy_header((), "<U100000000")}),
     r"'description' declares 1 value \(400\.0 MB\), more than the 1\.0 MB one field may hold"),
    ("huge-positions", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                 "positions": declared((20000000, 2))}),
     r"'positions' must be x, y pairs of metres \(shape \(m, 2\), m at most 1000000\), got shape \(20000000, 2\)"),
    ("t-longer-than-frames", lambda p: hostile_npz(p, {"frames": npy(np.zeros((2, 256))),
                                                       "t": npy(np.zeros(100000))}, zipfile.ZIP_DEFLATED),
     r"t must have shape \(2,\), got \(100000,\)"),
    ("not-npy", lambda p: hostile_npz(p, {"frames": b"PK not an array" * 100}),
     r"'frames' is not a NumPy array \(\.npy\): not a recording"),
    # a version 2.0 header may say it is 4 GiB long: np.load would read that much before refusing it
    ("header-length", lambda p: hostile_npz(p, {"frames": npy_header((2, 256), version=2)[:8]
                                                + (2**32 - 1).to_bytes(4, "little")}),
     r"'frames' declares an array header of 4294967295 bytes \(at most 10000\)"),
    ("deflate-bomb", lambda p: zero_frames(hostile_npz(p, {})),
     r"'frames' declares 131072x256 values \(268\.4 MB\) from 2\d\d\.\d KB compressed, 10\d\d:1, more than the "
     r"1000:1 any recording reaches: a decompression bomb"),
    # zipfile would inflate a bzip2 member's block whole (here 128 MiB from some 200 bytes) to read 8 bytes
    ("bzip2-bomb", lambda p: zero_frames(hostile_npz(p, {}), mebibytes=128, compression=zipfile.ZIP_BZIP2),
     r"'frames' is compressed by zip method 12, which numpy never writes \(only stored or deflated\)"),
    # five chunks, each under the allowance alone, together over it
    ("chunked-bomb", chunked_zero_frames,
     r"'chunk000004_frames' declares 7680x256 values \(15\.7 MB\) from \d+\.\d KB compressed, 10\d\d:1"),
]


@pytest.mark.parametrize("make, message", [case[1:] for case in HOSTILE_NPZ], ids=[case[0] for case in HOSTILE_NPZ])
def test_declared_sizes_are_checked_before_anything_is_allocated(tmp_path, make, message):
    path = make(tmp_path / "hostile.npz")
    with allocating_at_most(200), pytest.raises(RecordingError, match=message) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_the_ceiling_counts_every_member_together(tmp_path, monkeypatch):
    # gigabytes of real data are too slow for a test: the same rule under a ceiling of 14000 bytes,
    # which frames (4096 bytes) and truth_forces (12288) each fit alone
    monkeypatch.setattr(recording_module, "_MAX_RECORDING_BYTES", 14000)
    path = hostile_npz(tmp_path / "both.npz", {"frames": npy(np.zeros((2, 256))),
                                               "truth_forces": npy(np.zeros((2, 256, 3)))})
    with pytest.raises(RecordingError, match=r"'truth_forces' declares 2x256x3 values \(12\.3 KB\): the "
                                             r"recording would take 16\.4 KB, more than the 14\.0 KB"):
        load(path)


def test_a_field_that_does_not_fit_the_frames_is_refused_before_it_is_read(tmp_path):
    # 60 MiB of times for 2 frames: within every ceiling (zeros inflate past 1000:1, but within the
    # allowance), refused by its shape alone
    path = hostile_npz(tmp_path / "times.npz", {"frames": npy(np.zeros((2, 256)))})
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as archive, archive.open("t.npy", "w") as member:
        member.write(npy_header((60 * MIB // 8,)))
        for _ in range(60):
            member.write(bytes(MIB))
    with allocating_at_most(20), pytest.raises(RecordingError, match=r"t must have shape \(2,\), got \(7864320,\)"):
        load(path)


def test_the_tiny_file_of_the_report_is_tiny(tmp_path):
    # the fault report's case: some 1.6 KB declaring a 20000x20000 grid (3.2 GB)
    path = hostile_npz(tmp_path / "tiny.npz", {"frames": declared(HUGE)})
    assert path.stat().st_size < 2000


@pytest.mark.parametrize("count", [1000, 16384])
def test_an_honest_all_zero_recording_still_loads(tmp_path, count):
    # a skin that never felt anything is the legitimate worst case of compression: 16384 frames of
    # 16x16 (32 MiB) inflate past 1000:1 and load through the allowance
    grid = SensorGrid.regular(16, 16, 1e-3, 1e-3)
    path = save(Recording(grid, np.zeros((count, 256)), np.arange(count) / 1000), tmp_path / "idle.npz")
    with zipfile.ZipFile(path) as archive:
        member = archive.getinfo("frames.npy")
    assert (member.file_size > 1000 * member.compress_size) == (count == 16384)
    back = load(path)
    assert back.frames.shape == (count, 256) and not back.frames.any()


def test_an_honest_chunked_recording_still_joins(tmp_path):
    path = tmp_path / "chunks.npz"
    np.savez(path, **SKIN, chunk000000_frames=np.ones((2, 256)), chunk000000_t=[0.0, 0.1],
             chunk000001_frames=np.ones((1, 256)), chunk000001_t=[0.2])
    back = load(path)
    assert back.frames.shape == (3, 256) and back.t.tolist() == [0.0, 0.1, 0.2]
    np.savez(path, **SKIN, chunk000000_frames=np.ones((2, 256)), chunk000001_frames=np.ones((1, 255)))
    with pytest.raises(RecordingError, match=r"'chunk000001_frames' has shape \(1, 255\) but "
                                             r"'chunk000000_frames' has \(2, 256\): the chunks do not join"):
        load(path)


CSV_SKIN = "# nx=16\n# ny=16\n# pitch=1e-3\n# thickness=1e-3\n"


def write_lines(path, *pieces):
    # pieces of text, each written as it is or (text, times) repeated: never joined in memory
    with open(path, "w", encoding="utf-8") as handle:
        for piece in pieces:
            text, times = piece if isinstance(piece, tuple) else (piece, 1)
            for _ in range(times):
                handle.write(text)
    return path


HOSTILE_CSV = [
    # one line of 68 MiB with no end: read no further than 64 MiB
    ("long-line", lambda p: write_lines(p, CSV_SKIN, ("0," * (MIB // 2), 68)),
     r"line 5 is longer than 67108864 characters: not a recording"),
    # 2 million values within the line limit: counted before a Python float is made of any
    ("wide-row", lambda p: write_lines(p, CSV_SKIN, ("0,", 2_000_000), "0\n"),
     r"line 5 holds 2000001 values, more than a frame of the largest skin this viewer opens \(1000000 taxels\)"),
    ("positions", lambda p: write_lines(p, "# taxels=4\n# pitch=1e-3\n# thickness=1e-3\n# positions=",
                                        ("0,0;", 2_000_000), "\n0,1,2,3,4\n"),
     r"'positions' holds 2000001 x,y pairs, more than the 1000000 taxels"),
]


@pytest.mark.parametrize("make, message", [case[1:] for case in HOSTILE_CSV], ids=[case[0] for case in HOSTILE_CSV])
def test_a_csv_line_cannot_make_the_loader_allocate_what_the_file_does_not_hold(tmp_path, make, message):
    path = make(tmp_path / "hostile.csv")
    with allocating_at_most(200), pytest.raises(RecordingError, match=message) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ")


def test_csv_rows_are_packed_as_they_are_read(tmp_path):
    # 200000 values of 2 characters each: 1.6 MB as float64, some 13 MB as lists of Python floats;
    # loading takes about 7 MiB at its peak (the frames' transient copies included), 19 MiB unpacked
    path = write_lines(tmp_path / "long.csv", CSV_SKIN.replace("nx=16\n# ny=16", "nx=1\n# ny=1"),
                       ("0,0\n", 100_000))
    with allocating_at_most(12):
        back = load(path)
    assert back.frames.shape == (100_000, 1)


def test_csv_frames_beyond_the_ceiling_are_refused(tmp_path, monkeypatch):
    # 4 GiB of CSV is too slow for a test: the same rule, under a ceiling of 40 values
    monkeypatch.setattr(recording_module, "_MAX_RECORDING_BYTES", 40 * 8)
    path = write_lines(tmp_path / "many.csv", HEADER, ("0,1,2\n", 14))
    with pytest.raises(RecordingError, match=r"line 18: the frames would take more than the 320 B this viewer"):
        load(path)


# -- what a file is, said plainly -------------------------------------------------------------------

def test_files_that_are_not_recordings_say_what_they_are(tmp_path):
    from tactile_viewer.io.forces import save_forces
    from tactile_viewer.model.force_tables import reconstruct_frames
    from tactile_viewer.model.viewer_model import ViewerModel

    (tmp_path / "empty.csv").write_text("")
    (tmp_path / "notes.npz").write_text("hello world\n")
    sample = load(Path(__file__).resolve().parents[3] / "sample_data" / "hertz_static.npz")
    table = reconstruct_frames(sample, ViewerModel.build(sample.grid, "point"), [0])
    for suffix in (".npz", ".csv"):
        save_forces(table, tmp_path / f"forces{suffix}")
    cases = {"empty.csv": r"empty: a CSV recording has '# key=value' header lines \(nx, ny, pitch, thickness\)",
             "notes.npz": r"not an NPZ archive \(an NPZ is a zip of \.npy arrays; this file starts with b'hello",
             "forces.npz": r"a force export of this viewer \(forces per node, not the sensor stresses",
             "forces.csv": r"a force export of this viewer \(forces per node, not the sensor stresses"}
    for name, message in cases.items():
        with pytest.raises(RecordingError, match=message) as info:
            load(tmp_path / name)
        assert "allow_pickle" not in str(info.value) and name in str(info.value)

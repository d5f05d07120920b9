"""CSV recordings (tactile_viewer/io/csv_table.py): round trips, a file cut short, units, every malformed-table
path, and lines that would make the loader allocate what the file does not hold. What every format shares is in
test_recording.py, the one load in test_files.py."""

import numpy as np
import pytest

import tactile_viewer.io.csv_table as csv_table_module
from solver import SensorGrid
from tactile_viewer.io.files import load, save
from tactile_viewer.io.recording import Recording, RecordingError
from tests.tactile_viewer.io.test_npz import MIB, allocating_at_most

HEADER = "# nx=2\n# ny=1\n# pitch=1e-3\n# thickness=1e-3\n"  # a 2x1 grid: rows of t, v0, v1


# -- round trips ----------------------------------------------------------------------------------

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


def test_csv_tolerates_comments_blank_lines_and_semicolons(tmp_path):
    path = tmp_path / "loose.csv"
    path.write_text("# recorded on the bench\n" + HEADER + "\n# units = kPa\n0; 1; 2\n\n  0.5, 3, 4  \n")
    back = load(path)
    np.testing.assert_allclose(back.frames, [[1e3, 2e3], [3e3, 4e3]])
    np.testing.assert_allclose(back.t, [0.0, 0.5])


# -- malformed tables ---------------------------------------------------------------------------------

def write_csv(body, header=HEADER):
    return lambda p: p.write_text(header + body)


MALFORMED = [
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


# -- lines that declare more than the file holds ------------------------------------------------------

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
    monkeypatch.setattr(csv_table_module, "MAX_RECORDING_BYTES", 40 * 8)
    path = write_lines(tmp_path / "many.csv", HEADER, ("0,1,2\n", 14))
    with pytest.raises(RecordingError, match=r"line 18: the frames would take more than the 320 B this viewer"):
        load(path)

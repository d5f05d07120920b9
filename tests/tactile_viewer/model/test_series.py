"""The time series of a recording (no Qt): the data types, their checks and the CSV format."""

import numpy as np
import pytest

from tactile_viewer.io.recording import Recording
from tactile_viewer.model.series import CSV_MARKER, Quantities, Series, TruthErrors
from tactile_viewer.model.series_solving import SeriesBuilder, compute_series
from tactile_viewer.model.solved import Solved

QUANTITIES = ("fz", "tangential", "direction", "shear_ratio", "centroid_x", "centroid_y")


def without_truth(recording):
    return Recording(recording.grid, recording.frames, recording.t, None, recording.description)


def assert_same(a, b, **tolerance):
    np.testing.assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True,
                               **tolerance)


def test_a_series_export_that_fails_leaves_no_partial_file(skin, tmp_path, monkeypatch):
    recording, solver = skin
    series = compute_series(recording, solver, frames=[0, 1])

    def half_then_full(self, text, **kwargs):
        with open(self, "w") as handle:
            handle.write(text[: len(text) // 2])
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(type(tmp_path), "write_text", half_then_full)
    with pytest.raises(OSError, match="No space left on device"):
        series.to_csv(tmp_path / "series.csv")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("truth", [True, False])
@pytest.mark.parametrize("given", [{}, dict(shear_ratio=0.25, shear_direction=-2.0)], ids=["auto", "manual"])
def test_csv_round_trips_with_its_header(skin, tmp_path, truth, given):
    recording, solver = skin
    series = compute_series(recording if truth else without_truth(recording), solver,
                            source="take 1\nsecond line", **given)
    path = series.to_csv(tmp_path / "series.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == f"# {CSV_MARKER}"
    header = [line for line in lines if line.startswith("#")]
    assert "# source=take 1 second line" in header and "# kernel=layer" in header
    assert any(line.startswith("# units=") and "newtons" in line and "degrees" in line for line in header)
    columns = lines[len(header)].split(",")
    assert columns[:8] == ["frame", "t_s", "fz_N", "tangential_N", "direction_deg", "shear_ratio",
                           "centroid_x_m", "centroid_y_m"]
    assert ("truth_fz_N" in columns and "fz_error_pct" in columns) == truth
    assert len(lines) == len(header) + 1 + len(recording)
    # the unloaded last frame: its undefined quantities are written as nan
    assert lines[-1].split(",")[4] == "nan"

    back = Series.from_csv(path)
    assert (back.kernel, back.mode, back.source, back.total) == ("layer", series.mode, "take 1 second line",
                                                                  len(recording))
    if given:
        assert back.shear_ratio == pytest.approx(0.25) and back.shear_direction == pytest.approx(-2.0)
    np.testing.assert_array_equal(back.frame, series.frame)
    np.testing.assert_array_equal(back.t, series.t)
    for part in ("estimate", "truth") if truth else ("estimate",):
        for name in QUANTITIES:
            assert_same(getattr(getattr(back, part), name), getattr(getattr(series, part), name), rtol=1e-14)
    if truth:
        for name in ("normal", "tangential", "direction_deg"):
            assert_same(getattr(back.errors, name), getattr(series.errors, name), rtol=1e-14)
    else:
        assert back.truth is None and back.errors is None


def test_an_empty_series_round_trips(skin, tmp_path):
    recording, _ = skin
    series = SeriesBuilder(recording.grid, mode="as shown", span=60.0).series()
    back = Series.from_csv(series.to_csv(tmp_path / "empty.csv"))
    assert len(back) == 0 and back.mode == "as shown" and back.complete


def test_bad_series_are_refused(skin):
    recording, solver = skin
    solved = Solved.of(recording.grid, recording.frames[0], solver.solve(recording.frames[0]))
    with pytest.raises(ValueError, match="truth must be given for every frame of a series with truth"):
        SeriesBuilder(recording.grid, truth=True).add(solved)
    with pytest.raises(ValueError, match=r"truth must have shape \(64, 3\), got \(3,\)"):
        SeriesBuilder(recording.grid, truth=True).add(solved, np.zeros(3))
    estimate = Quantities(*np.zeros((6, 2)))
    with pytest.raises(ValueError, match=r"frame and t must be 1-D arrays of one length, got shapes \(2,\) and \(3,\)"):
        Series([0, 1], [0.0, 0.1, 0.2], estimate)
    with pytest.raises(ValueError, match="estimate must be Quantities of 3 frames"):
        Series([0, 1, 2], [0.0, 0.1, 0.2], estimate)
    with pytest.raises(ValueError, match="errors must be TruthErrors of 2 frames, and only beside a truth"):
        Series([0, 1], [0.0, 0.1], estimate, errors=TruthErrors(*np.zeros((3, 2))))
    with pytest.raises(ValueError, match="total must be a whole number >= the 2 frames held, got 1"):
        Series([0, 1], [0.0, 0.1], estimate, total=1)
    with pytest.raises(ValueError, match="mode must be one of"):
        Series([0, 1], [0.0, 0.1], estimate, mode="fast")
    with pytest.raises(ValueError, match="must be 1-D arrays of one length"):
        Quantities(*np.zeros((5, 2)), np.zeros(3))
    with pytest.raises(ValueError, match=r"forces must have shape \(n, 64, 3\), got \(2, 3\)"):
        Quantities.of_forces(recording.grid, np.zeros((2, 3)))
    for contacts, identities in (([(0, estimate)], r"\[0\]"), ([(2, estimate), (1, estimate)], r"\[2, 1\]"),
                                 ([estimate], r"\[None\]"), ([(1, Quantities(*np.zeros((6, 3))))], r"\[1\]")):
        with pytest.raises(ValueError, match=r"contacts must be \(identity, Quantities of 2 frames\) pairs by "
                           rf"increasing identity from 1, got identities {identities}"):
            Series([0, 1], [0.0, 0.1], estimate, contacts=contacts)


@pytest.mark.parametrize("text, message", [
    ("frame,t_s\n", "not a time series of this viewer"),
    ("", "got 'an empty file'"),
    (f"# {CSV_MARKER}\nframe,t_s,fz_N\n0,0.0,1.0\n", "the columns must be frame,t_s,fz_N"),
    (f"# {CSV_MARKER}\nframe,t_s,fz_N,tangential_N,direction_deg,shear_ratio,centroid_x_m,centroid_y_m,"
     "contact1_fz_N\n", "the columns must be frame,t_s,fz_N"),
    (f"# {CSV_MARKER}\nframe,t_s,fz_N,tangential_N,direction_deg,shear_ratio,centroid_x_m,centroid_y_m\n"
     "0,0.0,1.0,0.1,20,0.1,0,abc\n", "line 3: every value must be a number, got '0,0.0"),
    (f"# {CSV_MARKER}\nframe,t_s,fz_N,tangential_N,direction_deg,shear_ratio,centroid_x_m,centroid_y_m\n"
     "0,0.0,1.0\n", "line 3: 8 values expected, got 3"),
    (f"# {CSV_MARKER}\n# mode=manual\n"
     "frame,t_s,fz_N,tangential_N,direction_deg,shear_ratio,centroid_x_m,centroid_y_m\n",
     "damaged header: 'shear_ratio'"),
])
def test_files_that_are_not_series_are_refused_by_name(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{path}: .*{message}" if message.startswith("got") else
                       f"{path}: {message}"):
        Series.from_csv(path)

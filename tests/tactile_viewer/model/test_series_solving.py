"""Solving a recording's time series (no Qt): per-frame solves, truth, cancelling, partial series, builders."""

import math

import numpy as np
import pytest

from solver import SensorGrid, loads, metrics
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.series import Quantities, Series
from tactile_viewer.model.series_solving import SeriesBuilder, compute_series, nearest_frame, spread_frames
from tactile_viewer.model.solved import Solved, load_centroid
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.model.worker import Cancelled
from tactile_viewer.sources.source import RecordingSource
from tests.tactile_viewer.model.test_series import QUANTITIES, assert_same, without_truth


def expected_row(forces, centroid):
    fx, fy, fz = forces.sum(axis=0)
    tangential = math.hypot(fx, fy)
    return (fz, tangential, math.atan2(fy, fx) if tangential > 0 else math.nan,
            tangential / fz if fz > 0 else math.nan,
            *(centroid if centroid is not None else (math.nan, math.nan)))


@pytest.mark.parametrize("given", [{}, dict(shear_ratio=0.4, shear_direction=1.0)], ids=["auto", "manual"])
def test_the_series_is_the_models_solve_of_each_frame(skin, given):
    recording, solver = skin
    series = compute_series(recording, solver, **given)
    # the window's model, solving in place, frame by frame
    model = ViewerModel()
    model.set_source(RecordingSource(recording), solver)
    if given:
        model.set_parameters(**given)
    rows = []
    for k in range(len(recording)):
        model.set_frame(k)
        solved = model.solve()
        rows.append(expected_row(solved.result.forces, solved.centroid))
    rows = np.array(rows)
    assert series.complete and len(series) == len(recording) == series.total
    np.testing.assert_array_equal(series.frame, np.arange(len(recording)))
    np.testing.assert_array_equal(series.t, recording.t)
    for i, name in enumerate(QUANTITIES):
        # the automatic search starts from the previous frame's answer, and the model's first
        # frame follows the series' last one: the two agree to rounding, not to the bit
        assert_same(getattr(series.estimate, name), rows[:, i], rtol=1e-8, atol=1e-12)
    assert series.mode == ("manual" if given else "auto") and series.kernel == "layer"
    assert math.isnan(series.estimate.centroid_x[-1]) and math.isnan(series.estimate.direction[-1])
    assert np.all(np.isfinite(series.estimate.direction[:-1]))  # every press here has shear
    for array in (series.frame, series.t, series.estimate.fz, series.truth.fz, series.errors.normal):
        assert not array.flags.writeable


def test_the_truth_columns_are_the_totals_of_the_true_forces(skin):
    recording, solver = skin
    series = compute_series(recording, solver)
    truth = recording.truth_forces
    totals = truth.sum(axis=1)
    np.testing.assert_allclose(series.truth.fz, totals[:, 2])
    np.testing.assert_allclose(series.truth.tangential, np.hypot(totals[:, 0], totals[:, 1]))
    assert_same(series.truth.direction[:-1], np.arctan2(totals[:-1, 1], totals[:-1, 0]))
    assert_same(series.truth.shear_ratio[:-1], np.hypot(totals[:-1, 0], totals[:-1, 1]) / totals[:-1, 2])
    centroids = [load_centroid(recording.grid.positions, frame[:, 2]) for frame in truth[:-1]]
    assert_same(series.truth.centroid_x[:-1], [c[0] for c in centroids])
    assert_same(series.truth.centroid_y[:-1], [c[1] for c in centroids])
    assert math.isnan(series.truth.centroid_x[-1]) and math.isnan(series.truth.shear_ratio[-1])
    # the errors are solver.metrics' figures, frame by frame
    for k in range(len(recording) - 1):
        forces = solver.solve(recording.frames[k]).forces
        assert series.errors.normal[k] == pytest.approx(metrics.normal_total_error(forces, truth[k]))
        assert series.errors.tangential[k] == pytest.approx(metrics.tangential_total_error(forces, truth[k]))
        assert series.errors.direction_deg[k] == pytest.approx(metrics.direction_error(forces, truth[k]))
    # the same quantities of the truth through the batch path
    batch = Quantities.of_forces(recording.grid, truth)
    for name in QUANTITIES:
        assert_same(getattr(batch, name), getattr(series.truth, name))


def test_a_recording_without_truth_has_no_truth_columns(skin):
    recording, solver = skin
    series = compute_series(without_truth(recording), solver)
    assert series.truth is None and series.errors is None and len(series) == len(recording)


class Counting:
    """The solver, counting its solves."""

    def __init__(self, inner):
        self.inner, self.grid, self.kernel, self.solves = inner, inner.grid, inner.kernel, 0

    def solve(self, stress, **kwargs):
        self.solves += 1
        return self.inner.solve(stress, **kwargs)


def test_cancelling_stops_after_the_frame_being_solved(skin):
    recording, solver = skin
    counting = Counting(solver)
    seen = []

    def progress(done, total):
        seen.append((done, total))
        return done < 2

    with pytest.raises(Cancelled, match="cancelled after 2 of 7 frames"):
        compute_series(recording, counting, progress=progress)
    assert counting.solves == 2 and seen == [(1, 7), (2, 7)]


def test_partial_series_grow_while_solving(skin):
    recording, solver = skin
    partials = []
    series = compute_series(recording, solver, partial=partials.append, every=1e-9)
    # every frame but the last hands out the frames so far; the last is the result itself
    assert [len(p) for p in partials] == list(range(1, len(recording)))
    assert all(p.total == len(recording) and not p.complete for p in partials)
    np.testing.assert_array_equal(partials[2].estimate.fz, series.estimate.fz[:3])
    assert series.complete


def test_some_frames_spread_over_the_whole_recording(skin):
    recording, solver = skin
    frames = spread_frames(len(recording), 3)
    assert frames.tolist() == [0, 3, 6]
    series = compute_series(recording, solver, frames=frames)
    np.testing.assert_array_equal(series.frame, frames)
    np.testing.assert_array_equal(series.t, recording.t[frames])
    whole = compute_series(recording, solver)
    assert_same(series.estimate.fz, whole.estimate.fz[frames])
    assert spread_frames(10, 20).tolist() == list(range(10))


def test_a_rolling_builder_keeps_the_last_span_seconds(skin):
    recording, solver = skin
    builder = SeriesBuilder(recording.grid, mode="as shown", span=0.1)
    for k in range(len(recording)):
        builder.add(Solved.of(recording.grid, recording.frames[k], solver.solve(recording.frames[k]), frame=k,
                              time=float(recording.t[k])))
    series = builder.series()
    # the last frame is at 0.2 s: frames at 0.1 s and later stay
    np.testing.assert_array_equal(series.frame, [3, 4, 5, 6])
    assert series.complete and series.truth is None


def test_a_frame_solved_again_replaces_its_row(skin):
    recording, solver = skin
    builder = SeriesBuilder(recording.grid, mode="as shown", span=60.0)
    stress = recording.frames[2]
    for ratio in (0.0, 0.5):  # a quiet live board: its last frame again with new parameters
        builder.add(Solved.of(recording.grid, stress, solver.solve(stress, shear_ratio=ratio, shear_direction=0.0),
                              frame=2, time=float(recording.t[2])))
    series = builder.series()
    assert len(series) == 1 and series.frame.tolist() == [2]
    assert series.estimate.shear_ratio[0] == pytest.approx(0.5, abs=0.05)  # the newer solve's


@pytest.fixture(scope="module")
def two():
    """Frame 0: a press on the left; 1 and 2: a second on the right too; 3: the left one lifted."""
    grid = SensorGrid.regular(14, 8, 2e-3, 2e-3)
    left, right = loads.hertz((-6e-3, 0.0), 3e-3, 0.8), loads.hertz((6e-3, 0.0), 3e-3, 0.5, shear_ratio=0.3)
    scenes = [[left], [left, right], [left, right], [right]]
    frames = [loads.simulate(grid, scene, noise=0.005, rng=k).stress for k, scene in enumerate(scenes)]
    return Recording(grid, np.array(frames), np.arange(4) / 30.0, description="two presses"), \
        ViewerModel.build(grid, "layer")


def test_each_contact_has_its_own_series_by_identity(two, tmp_path):
    recording, solver = two
    series = compute_series(recording, solver)
    assert series.identities == (1, 2)
    left, right = series.contact(1), series.contact(2)
    assert_same(np.isnan(left.fz), [False, False, False, True])  # lifted on the last frame
    assert_same(np.isnan(right.fz), [True, False, False, False])
    assert left.fz[:3] == pytest.approx([0.8] * 3, rel=0.05)
    assert right.fz[1:] == pytest.approx([0.5] * 3, rel=0.05)
    assert np.all(right.shear_ratio[1:] > 0.1)  # the sheared one (0.3 true; accuracy is not the point)
    assert left.centroid_x[:3] == pytest.approx([-6e-3] * 3, abs=0.5e-3)
    assert right.centroid_x[1:] == pytest.approx([6e-3] * 3, abs=0.5e-3)
    # each contact's quantities are its own resultant's, as the contacts table shows them
    for k in range(4):
        result = solver.solve(recording.frames[k])
        assert np.nansum([left.fz[k], right.fz[k]]) == pytest.approx(sum(c.total_force[2]
                                                                         for c in result.contacts), rel=1e-6)
    with pytest.raises(KeyError, match=r"no contact 3 in the series \(identities \[1, 2\]\)"):
        series.contact(3)
    # the CSV carries them, column groups contact<N>_..., and reads them back
    path = series.to_csv(tmp_path / "two.csv")
    columns = next(line for line in path.read_text().splitlines() if not line.startswith("#")).split(",")
    assert columns[8:10] == ["contact1_fz_N", "contact1_tangential_N"] and columns[-1] == "contact2_centroid_y_m"
    back = Series.from_csv(path)
    assert back.identities == (1, 2)
    for identity in (1, 2):
        for name in QUANTITIES:
            assert_same(getattr(back.contact(identity), name), getattr(series.contact(identity), name),
                        rtol=1e-14)


def test_a_builder_keeps_only_followed_contacts_and_drops_them_with_their_rows(two):
    recording, solver = two
    builder = SeriesBuilder(recording.grid, mode="as shown", span=0.05)
    for k in range(4):  # solved alone: identity 0, in the totals only
        builder.add(Solved.of(recording.grid, recording.frames[k], solver.solve(recording.frames[k]), frame=k,
                              time=float(recording.t[k])))
    assert builder.series().contacts == ()
    model = ViewerModel()  # the model's results carry their identities
    model.set_source(RecordingSource(recording), solver)
    builder = SeriesBuilder(recording.grid, mode="as shown", span=0.05)
    for k in range(4):
        model.set_frame(k)
        builder.add(model.solve())
    series = builder.series()
    np.testing.assert_array_equal(series.frame, [2, 3])  # the rolling window took the rest
    assert series.identities == (1, 2)
    assert_same(np.isnan(series.contact(1).fz), [False, True])


def test_nearest_frame():
    t = [0.0, 0.1, 0.2, 0.2, 0.5]
    assert [nearest_frame(t, x) for x in (-1.0, 0.04, 0.06, 0.15, 0.2, 0.36, 9.0)] == [0, 0, 1, 1, 2, 4, 4]


def test_bad_arguments_are_named(skin):
    recording, solver = skin
    other = ViewerModel.build(SensorGrid.regular(8, 8, 2e-3, 3e-3), "layer")
    with pytest.raises(ValueError, match="recording must be a Recording, got ndarray"):
        compute_series(recording.frames, solver)
    with pytest.raises(ValueError, match="solver must have solve"):
        compute_series(recording, object())
    with pytest.raises(ValueError, match="solver was built for another geometry"):
        compute_series(recording, other)
    with pytest.raises(ValueError, match=r"shear_ratio must be finite and >= 0 \(or None\), got -0.5"):
        compute_series(recording, solver, shear_ratio=-0.5, shear_direction=0.0)
    with pytest.raises(ValueError, match=r"frames must be increasing indices in \[0, 6\], got \[0, 7\]"):
        compute_series(recording, solver, frames=[0, 7])
    with pytest.raises(ValueError, match=r"frames must be increasing indices in \[0, 6\], got \[3, 1\]"):
        compute_series(recording, solver, frames=[3, 1])
    with pytest.raises(ValueError, match="frames must be a 1-D sequence of whole numbers, got dtype float64"):
        compute_series(recording, solver, frames=[0.5])
    with pytest.raises(ValueError, match="progress must be callable or None, got 3"):
        compute_series(recording, solver, progress=3)
    with pytest.raises(ValueError, match="every must be finite seconds > 0, got 0"):
        compute_series(recording, solver, every=0)
    with pytest.raises(ValueError, match="limit must be a whole number >= 2, got 1"):
        spread_frames(10, 1)
    with pytest.raises(ValueError, match="count must be a whole number >= 0, got -1"):
        spread_frames(-1)
    with pytest.raises(ValueError, match=r"t must be a non-empty 1-D array of seconds, got shape \(0,\)"):
        nearest_frame([], 0.0)
    with pytest.raises(ValueError, match="x must be finite seconds, got nan"):
        nearest_frame([0.0], math.nan)
    with pytest.raises(ValueError, match="span must be finite seconds > 0 \\(or None\\), got -1"):
        SeriesBuilder(recording.grid, span=-1)
    with pytest.raises(ValueError, match="mode must be one of"):
        SeriesBuilder(recording.grid, mode="live")

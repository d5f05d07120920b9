"""The viewer model in plain Python (no Qt): installing, signals, parameters, solving, describing, Display."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from solver import ContactTracker, Reconstructor, SensorGrid, loads
from solver.kernels import KERNELS
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.display import Display, display_scales
from tactile_viewer.model.shear_parameters import MAX_SHEAR_RATIO
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.source import RecordingSource, Source, SourceFrame
from tests.tactile_viewer.model.conftest import PITCH, THICKNESS

ROOT = Path(__file__).resolve().parents[3]

SIGNALS = ("recording_changed", "frame_changed", "parameters_changed", "display_changed", "solved")


def listen(model):
    """Every signal of the model as (name, args) in the order they fire."""
    events = []
    for name in SIGNALS:
        getattr(model, name).connect(lambda *args, name=name: events.append((name, args)))
    return events


def names(events):
    return [name for name, _ in events]


# -- installing ----------------------------------------------------------------------------------

def test_set_source_announces_the_recording_then_its_display(recording, reconstructor):
    model = ViewerModel()
    events = listen(model)
    model.set_source(RecordingSource(recording, "takes/sliding.npz"), reconstructor)
    # the window builds the scene on recording_changed, then reads the display it was given
    assert events == [("recording_changed", ()), ("display_changed", ())]
    assert model.recording is recording and model.reconstructor is reconstructor
    assert model.kernel == "layer" and model.path == Path("takes/sliding.npz")
    assert model.frame == 0 and model.last is None


def test_set_source_scales_the_display_to_the_recording(model, recording, reconstructor):
    # readable defaults, loosely (the exact rule is a heuristic): the largest normal-only node force
    # of the recording draws an arrow of a few pitches, and the fixed colour range holds every frame
    peak = max(np.abs(reconstructor.solve_normal(frame).forces[:, 2]).max() for frame in recording.frames)
    assert 1 * PITCH <= model.display.arrow_scale * peak <= 8 * PITCH
    assert model.display.range_max >= np.abs(recording.frames).max()
    assert math.isfinite(model.display.resultant_scale) and model.display.resultant_scale > 0


def test_a_new_source_starts_over_at_frame_zero(model, recording, reconstructor):
    model.set_frame(3)
    model.solve()
    model.set_display(map="stress")
    model.set_source(RecordingSource(recording), reconstructor)
    assert model.frame == 0 and model.last is None and model.path is None
    assert model.display.map == "stress"  # the user's choices stay; only the scales follow the data


def test_set_source_accepts_the_same_geometry_built_separately(recording, reconstructor):
    twin = Recording(SensorGrid.regular(6, 5, PITCH, THICKNESS), recording.frames, recording.t)
    assert twin.grid is not reconstructor.grid
    model = ViewerModel()
    model.set_source(RecordingSource(twin), reconstructor)
    assert model.recording is twin


@pytest.mark.parametrize("other", [
    SensorGrid.regular(5, 6, PITCH, THICKNESS),        # x and y swapped: same size, other shape
    SensorGrid.regular(6, 5, PITCH, 3e-3),             # a thicker layer
    SensorGrid.regular(6, 5, 2.5e-3, THICKNESS),       # another pitch (so other positions)
    SensorGrid.regular(6, 5, PITCH, THICKNESS, poisson_ratio=0.45),  # a compressible elastomer
    SensorGrid.regular(6, 5, PITCH, THICKNESS, sensor_size=1e-3),    # taxels that average
], ids=["transposed", "thicker", "wider", "other-nu", "taxel-size"])
def test_set_source_rejects_a_reconstructor_for_another_geometry(model, recording, other):
    events = listen(model)
    shown = model.recording
    with pytest.raises(ValueError, match="reconstructor was built for another geometry than the source's"):
        model.set_source(RecordingSource(recording), Reconstructor(other, kernel="cell"))
    assert model.recording is shown and events == []


def test_set_source_rejects_a_reconstructor_for_another_pitch():
    positions = SensorGrid.regular(4, 4, PITCH, THICKNESS).positions
    grid = SensorGrid(positions, THICKNESS, PITCH, (16,))
    other = SensorGrid(positions, THICKNESS, 1.5 * PITCH, (16,))
    recording = Recording(grid, np.full((2, 16), 1e3), [0.0, 1.0])
    assert not np.allclose(Reconstructor(grid).engine.matrix, Reconstructor(other).engine.matrix)  # really another geometry
    with pytest.raises(ValueError, match="another geometry"):
        ViewerModel().set_source(RecordingSource(recording), Reconstructor(other))


# -- frames --------------------------------------------------------------------------------------

def test_set_frame_announces_only_a_change(model):
    events = listen(model)
    model.set_frame(np.int64(2))  # the slider and numpy both hand over integers of other types
    model.set_frame(2)
    model.set_frame(0)
    assert events == [("frame_changed", (2,)), ("frame_changed", (0,))]
    assert type(model.frame) is int


@pytest.mark.parametrize("index", [-1, 4, 100])
def test_set_frame_out_of_range_raises_and_keeps_the_frame(model, index):
    model.set_frame(1)
    events = listen(model)
    with pytest.raises(ValueError, match=rf"frame must be in \[0, 3\], got {index}"):
        model.set_frame(index)
    assert model.frame == 1 and events == []


def test_a_model_with_nothing_open_ignores_frames_and_solves():
    model = ViewerModel()
    events = listen(model)
    model.set_frame(5)
    assert model.solve() is None
    assert model.frame == 0 and model.last is None and events == []


# -- parameters ----------------------------------------------------------------------------------

def test_set_auto_announces_only_a_change(model):
    events = listen(model)
    model.set_auto(True)  # already on after install
    model.set_auto(False)
    model.set_auto(0)
    model.set_auto(True)
    assert names(events) == ["parameters_changed", "parameters_changed"]
    assert model.auto is True


def test_set_parameters_switches_auto_off(model):
    assert model.auto
    events = listen(model)
    model.set_parameters(shear_ratio=0.7)
    assert events == [("parameters_changed", ())]
    assert not model.auto and model.shear_ratio == 0.7 and model.shear_direction == 0.0
    model.set_parameters(shear_direction=-1.0)
    assert model.shear_ratio == 0.7 and model.shear_direction == -1.0  # each slider alone
    assert names(events) == ["parameters_changed", "parameters_changed"]


@pytest.mark.parametrize("direction",
                         [3 * math.pi / 2, -3 * math.pi / 2, 2 * math.pi, 7.0, -20.0, math.pi, -math.pi])
def test_set_parameters_wraps_the_direction(model, direction):
    model.set_parameters(shear_direction=direction)
    wrapped = model.shear_direction
    assert -math.pi <= wrapped <= math.pi
    # the same direction on the circle
    assert math.cos(wrapped) == pytest.approx(math.cos(direction), abs=1e-12)
    assert math.sin(wrapped) == pytest.approx(math.sin(direction), abs=1e-12)


@pytest.mark.parametrize("ratio", [0.0, MAX_SHEAR_RATIO])
def test_set_parameters_accepts_both_ends_of_the_ratio(model, ratio):
    model.set_parameters(shear_ratio=ratio)
    assert model.shear_ratio == ratio


@pytest.mark.parametrize(("changes", "message"), [
    (dict(shear_ratio=-0.1), r"shear_ratio must be in \[0, 1.5\], got -0.1"),
    (dict(shear_ratio=MAX_SHEAR_RATIO + 1e-9), r"shear_ratio must be in \[0, 1.5\], got 1.500000001"),
    (dict(shear_ratio=math.nan), r"shear_ratio must be in \[0, 1.5\], got nan"),
    (dict(shear_ratio=math.inf), r"shear_ratio must be in \[0, 1.5\], got inf"),
    (dict(shear_direction=math.nan), r"shear_direction must be finite radians, got nan"),
    (dict(shear_direction=-math.inf), r"shear_direction must be finite radians, got -inf"),
])
def test_set_parameters_rejects_values_out_of_range(model, changes, message):
    model.set_parameters(shear_ratio=0.3, shear_direction=0.2)
    model.set_auto(True)
    events = listen(model)
    with pytest.raises(ValueError, match=message):
        model.set_parameters(**changes)
    # nothing changed and nothing was announced; Auto stays on
    assert (model.shear_ratio, model.shear_direction, model.auto) == (0.3, 0.2, True) and events == []


def test_a_rejected_set_parameters_changes_nothing(model):
    model.set_parameters(shear_ratio=0.3, shear_direction=0.2)
    with pytest.raises(ValueError, match="shear_direction must be finite radians"):
        model.set_parameters(shear_ratio=0.9, shear_direction=math.nan)
    assert model.shear_ratio == 0.3


def test_repeating_the_manual_parameters_announces_nothing(model):
    model.set_parameters(shear_ratio=0.3, shear_direction=0.2)
    events = listen(model)
    model.set_parameters(shear_ratio=0.3, shear_direction=0.2)
    assert events == []


# -- display -------------------------------------------------------------------------------------

def test_set_display_replaces_the_display_and_announces_it(model):
    events = listen(model)
    before = model.display
    model.set_display(map="stress", threshold=1e-3)
    assert events == [("display_changed", ())]
    assert model.display == replace(before, map="stress", threshold=1e-3)
    assert before.map == "pressure"  # the old Display object is untouched (frozen)


def test_setting_the_same_display_announces_nothing(model):
    events = listen(model)
    model.set_display(map=model.display.map, arrows=model.display.arrows)
    assert events == []


def test_set_display_rejects_a_bad_value_and_keeps_the_display(model):
    events = listen(model)
    before = model.display
    with pytest.raises(ValueError, match=r"map must be one of \('pressure', 'stress', 'none'\), got 'heat'"):
        model.set_display(map="heat")
    with pytest.raises(ValueError, match=r"threshold must be finite and >= 0, got -1"):
        model.set_display(threshold=-1)
    assert model.display is before and events == []


def test_auto_solve_reports_what_it_found_and_keeps_the_manual_values(model, recording, reconstructor):
    model.set_parameters(shear_ratio=0.7, shear_direction=-2.0)
    model.set_auto(True)
    model.set_frame(1)
    events = listen(model)
    solved = model.solve()
    assert events == [("solved", (solved,))]
    expected = reconstructor.solve(recording.frames[1])
    np.testing.assert_array_equal(solved.result.forces, expected.forces)
    assert model.auto and solved.auto
    assert expected.shear_ratio > 0.2  # found the simulated shear (0.4): the result says so
    # the user's manual values are still there for when Auto is switched off
    assert (model.shear_ratio, model.shear_direction) == (0.7, -2.0)
    assert model.last is solved


def test_manual_solve_is_the_reconstructors_solve_exactly(model, recording, reconstructor):
    model.set_frame(2)
    model.set_parameters(shear_ratio=0.7, shear_direction=-2.0)
    events = listen(model)
    solved = model.solve()
    assert events == [("solved", (solved,))]  # a manual solve leaves the parameters alone
    expected = reconstructor.solve(recording.frames[2], shear_ratio=0.7, shear_direction=-2.0)
    np.testing.assert_array_equal(solved.result.forces, expected.forces)
    assert solved.result.shear_ratio == pytest.approx(0.7)
    assert solved.result.shear_direction == pytest.approx(-2.0)
    assert (model.shear_ratio, model.shear_direction, model.auto, solved.auto) == (0.7, -2.0, False, False)


def test_solved_carries_the_frame_its_time_and_its_stress(model, recording):
    model.set_frame(3)
    solved = model.solve()
    assert solved.frame == 3 and solved.time == recording.t[3] == 0.15
    np.testing.assert_array_equal(solved.stress, recording.frames[3])
    assert solved.solve_ms >= 0 and math.isfinite(solved.solve_ms)


def test_manual_solve_on_an_all_zero_frame(recording, reconstructor):
    # a skin at rest: nothing to reconstruct, nothing to raise
    zero = Recording(recording.grid, np.zeros((2, recording.grid.size)), [0.0, 1.0])
    model = ViewerModel()
    model.set_source(RecordingSource(zero), reconstructor)
    model.set_parameters(shear_ratio=0.5, shear_direction=1.0)
    assert not np.any(model.solve().result.forces)
    model.set_auto(True)
    assert not np.any(model.solve().result.forces)


# -- describe ------------------------------------------------------------------------------------

def test_describe_carries_frame_mode_and_parameters(model, recording):
    model.set_frame(2)
    model.set_parameters(shear_ratio=0.7, shear_direction=-math.pi / 2)
    model.solve()
    info = model.describe()
    assert info["recording"] == str(Path("takes/sliding.npz"))
    assert info["frame"] == 2 and info["t"] == recording.t[2] and info["kernel"] == "layer"
    assert info["mode"] == "manual"
    assert info["shear_ratio"] == pytest.approx(0.7)
    assert info["shear_direction_deg"] == pytest.approx(-90.0)
    assert info["residual"] == model.last.result.residual and math.isfinite(info["condition"])
    assert info["display"] == dict(model.display.__dict__)
    assert info["poisson_ratio"] == 0.5 and info["sensor_size"] == 0.0  # the solver's geometry
    # it describes the last solve, not settings changed since (the screenshot shows that solve)
    model.set_auto(True)
    model.set_frame(0)
    assert model.describe()["mode"] == "manual" and model.describe()["frame"] == 2
    model.solve()
    info = model.describe()
    assert info["mode"] == "auto" and info["shear_ratio"] == model.last.result.shear_ratio
    assert info["shear_direction_deg"] == pytest.approx(math.degrees(model.last.result.shear_direction))


def test_describe_names_the_material_solved_with(recording):
    grid = recording.grid.replace(poisson_ratio=0.45, sensor_size=1e-3)
    model = ViewerModel()
    model.set_source(RecordingSource(Recording(grid, recording.frames, recording.t)), ViewerModel.build(grid, "point"))
    model.solve()
    info = model.describe()
    assert info["poisson_ratio"] == 0.45 and info["sensor_size"] == 1e-3 and info["kernel"] == "point"


def test_the_default_kernel_is_the_solvers_first():
    assert ViewerModel().kernel == KERNELS[0]


def test_describe_without_a_path(recording, reconstructor):
    model = ViewerModel()
    model.set_source(RecordingSource(recording), reconstructor)
    model.solve()
    assert model.describe()["recording"] is None  # an in-memory recording


def test_large_skins_are_solved_contact_by_contact():
    from solver import SensorGrid
    from solver.region import DENSE_LIMIT

    small = ViewerModel.build(SensorGrid.regular(8, 8, 2e-3, 2e-3), "cell")
    large = ViewerModel.build(SensorGrid.regular(80, 80, 2e-3, 2e-3), "cell")
    assert hasattr(small.engine, "matrix")  # the full reconstructor
    assert not hasattr(large.engine, "matrix") and large.grid.size > DENSE_LIMIT  # no dense matrix
    assert large.solve(np.zeros(large.grid.size)).forces.shape == (6400, 3)


# -- the model schedules its own solves (a worker thread, results through dispatch) ---------------

class Posted:
    """A dispatch that queues what the worker hands back, run by the test as the GUI loop would."""

    def __init__(self):
        self.calls = []

    def __call__(self, fn):
        self.calls.append(fn)

    def run(self, model):
        assert model.wait_idle(timeout=30)
        calls, self.calls = self.calls, []
        for fn in calls:
            fn()
        return len(calls)


@pytest.fixture
def threaded(recording, reconstructor):
    posted = Posted()
    model = ViewerModel(dispatch=posted)
    yield model, posted
    model.close()


def test_changes_schedule_a_solve_on_the_worker(threaded, recording, reconstructor):
    model, posted = threaded
    events = listen(model)
    model.set_source(RecordingSource(recording), reconstructor)
    assert posted.run(model) == 1  # the first frame, solved without being asked
    assert names(events) == ["recording_changed", "display_changed", "solved"]
    np.testing.assert_array_equal(model.last.result.forces, reconstructor.solve(recording.frames[0]).forces)
    events.clear()
    model.set_frame(2)
    posted.run(model)
    assert names(events) == ["frame_changed", "solved"] and model.last.frame == 2
    events.clear()
    model.set_parameters(shear_ratio=0.3, shear_direction=1.0)
    posted.run(model)
    assert names(events) == ["parameters_changed", "solved"]
    expected = reconstructor.solve(recording.frames[2], shear_ratio=0.3, shear_direction=1.0)
    np.testing.assert_array_equal(model.last.result.forces, expected.forces)
    events.clear()
    model.set_display(map="stress")  # drawing only: nothing to solve
    assert posted.run(model) == 0 and names(events) == ["display_changed"]


class SlowSolver:
    """Holds every solve until released, so a test controls what the worker is doing."""

    def __init__(self, inner):
        import threading

        self.inner, self.grid, self.kernel = inner, inner.grid, inner.kernel
        self.release = threading.Event()
        self.started = threading.Semaphore(0)
        self.frames = []

    def solve(self, stress, **kwargs):
        self.started.release()
        assert self.release.wait(30)
        self.frames.append(stress)
        return self.inner.solve(stress, **kwargs)

    def solve_normal(self, stress):
        return self.inner.solve_normal(stress)


def test_the_newest_request_wins(threaded, recording, reconstructor):
    model, posted = threaded
    slow = SlowSolver(reconstructor)
    model.set_source(RecordingSource(recording), slow)
    assert slow.started.acquire(timeout=30)  # frame 0 is being solved
    for index in (1, 2, 3):  # three frames while it runs: only the last is worth solving
        model.set_frame(index)
    slow.release.set()
    posted.run(model)
    assert [s.frame for s in [model.last]] == [3]
    assert len(slow.frames) == 2  # frame 0 (already running) and frame 3; 1 and 2 were dropped
    np.testing.assert_array_equal(slow.frames[1], recording.frames[3])


def test_results_of_a_replaced_solver_are_dropped(threaded, recording, reconstructor):
    model, posted = threaded
    slow = SlowSolver(reconstructor)
    model.set_source(RecordingSource(recording), slow)
    assert slow.started.acquire(timeout=30)
    model.set_source(RecordingSource(recording), reconstructor)  # the user changed the kernel meanwhile
    slow.release.set()
    events = listen(model)
    posted.run(model)
    solved = [args[0] for name, args in events if name == "solved"]
    assert len(solved) == 1  # only the new solver's
    np.testing.assert_array_equal(solved[0].result.forces, reconstructor.solve(recording.frames[0]).forces)


def test_a_failing_solve_is_reported_and_the_model_goes_on(threaded, recording, reconstructor):
    model, posted = threaded

    class Broken(SlowSolver):
        def solve(self, stress, **kwargs):
            raise FloatingPointError("the solver blew up")
    broken = Broken(reconstructor)
    events = listen(model)
    failures = []
    model.solve_failed.connect(failures.append)
    model.set_source(RecordingSource(recording), broken)
    posted.run(model)
    assert failures == ["solve of frame 0 failed: the solver blew up"]
    assert model.last is None and "solved" not in names(events)
    model.set_source(RecordingSource(recording), reconstructor)  # and the next solver works
    posted.run(model)
    assert model.last is not None and model.last.frame == 0


def test_closing_ends_the_worker_thread(recording, reconstructor):
    import threading

    model = ViewerModel(dispatch=Posted())
    model.set_source(RecordingSource(recording), reconstructor)
    model.close()
    assert not [t for t in threading.enumerate() if t.name == "tactile-solver" and t.is_alive()]
    posted = model._dispatch
    model.set_frame(1)  # a change after closing (a task finishing late) is kept and solves nothing
    assert model.frame == 1 and posted.calls == [] and model.last is None


def test_a_change_waits_for_a_fast_solve_up_to_settle(recording, reconstructor):
    # the window's settle: a change returns with its solve already handed back, so the new frame
    # can be drawn in the same repaint as the control that asked for it
    posted = Posted()
    model = ViewerModel(dispatch=posted, settle=30.0)
    try:
        model.set_source(RecordingSource(recording), reconstructor)
        assert len(posted.calls) == 1  # no wait_idle needed: install returned after the solve
        model.set_frame(2)
        assert len(posted.calls) == 2
    finally:
        model.close()
    slow = SlowSolver(reconstructor)  # never released within settle: the change returns anyway
    model = ViewerModel(dispatch=Posted(), settle=0.05)
    try:
        model.set_source(RecordingSource(recording), slow)
        assert model.solving
    finally:
        slow.release.set()
        model.close()


class Pushed(Source):
    """A live source whose frames come from a thread of its own."""

    live = True

    def __init__(self, grid):
        super().__init__("test board (binary)", grid)
        self.stopped = 0

    def push(self, stress, index):
        import threading

        thread = threading.Thread(target=self._publish, args=([SourceFrame(stress, 0.01 * index, index)],))
        thread.start()
        thread.join()

    def stop(self):
        self.stopped += 1
        super().stop()


def test_pushed_frames_are_handed_to_the_models_thread_and_solved(threaded, recording, reconstructor):
    model, posted = threaded
    board = Pushed(recording.grid)
    model.set_source(board, reconstructor)
    assert model.live and model.recording is None and model.current is None
    board.push(recording.frames[1], 41)
    assert model.current is None  # not taken on the reader's thread
    posted.run(model)  # the hand-over: take and schedule
    posted.run(model)  # the result
    assert model.last.frame == 41 and model.last.time == pytest.approx(0.41)
    np.testing.assert_array_equal(model.last.result.forces, reconstructor.solve(recording.frames[1]).forces)
    assert model.describe()["recording"] == "test board (binary)"


def test_with_pace_a_pushed_frame_waits_until_the_last_result_is_shown(recording, reconstructor):
    posted = Posted()
    model = ViewerModel(dispatch=posted, pace=True)
    try:
        board = Pushed(recording.grid)
        model.set_source(board, reconstructor)
        board.push(recording.frames[0], 0)
        posted.run(model)
        posted.run(model)
        assert model.last.frame == 0
        for k in (1, 2, 3):  # three frames before the first result reached the screen
            board.push(recording.frames[k], k)
            posted.run(model)
        assert model.current.index == 0 and not model.solving  # none taken: it could not be drawn
        model.shown()  # frame 0 is on screen: the newest is taken
        posted.run(model)
        assert model.last.frame == 3 and model.worker_stats()["done"] == 2
    finally:
        model.close()


def test_with_pace_a_playing_recording_waits_for_the_last_result_on_screen_and_a_paused_one_does_not(
        recording, reconstructor):
    posted = Posted()
    model = ViewerModel(dispatch=posted, pace=True)
    try:
        played = RecordingSource(recording)
        model.set_source(played, reconstructor)
        played.play(now=0.0)
        played.advance(now=0.0)  # frame 0
        posted.run(model)
        assert model.last.frame == 0
        for k in (1, 2):  # two frames due before frame 0 reached the screen
            played.advance(now=k * recording.t[1])
        assert played.position == 2 and model.current.index == 0 and not model.solving
        model.shown()  # frame 0 on screen: the newest is taken, the one between never solved
        posted.run(model)
        assert model.last.frame == 2 and model.worker_stats()["done"] == 2
        played.pause()
        played.seek(0)  # paused: a step is taken at once, though frame 2 is not on screen yet
        posted.run(model)
        assert model.last.frame == 0
        played.seek(1)
        assert model.current.index == 1
    finally:
        model.close()


@pytest.fixture
def held(recording, reconstructor):
    """``(model, posted, played)``: paced playback with frame 1 solved and delivered but not on
    screen yet, and frame 2 waiting for it."""
    posted = Posted()
    model = ViewerModel(dispatch=posted, pace=True)
    try:
        played = RecordingSource(recording)
        model.set_source(played, reconstructor)
        posted.run(model)
        model.shown()
        played.play(now=0.0)
        played.advance(now=recording.t[1])  # frame 1, solved and delivered: not on screen yet
        posted.run(model)
        played.advance(now=recording.t[2])  # frame 2 waits for the screen
        assert model.current.index == 1 and played.position == 2
        yield model, posted, played
    finally:
        model.close()


def test_a_pause_while_a_playing_frame_waits_for_the_screen_takes_it_and_the_next_step_at_once(held):
    # before: the waiting frame was left untaken at the pause, the source announced no later frame
    # while it waited, and a step after the pause was not taken until the last result's paint
    model, posted, played = held
    played.pause()
    assert model.current.index == 2  # the frame playback stopped at
    played.seek(0)  # a step, frame 1's result still not on screen
    assert model.current.index == 0
    posted.run(model)
    assert model.last.frame == 0


def test_a_new_solver_while_a_playing_frame_waits_for_the_screen_shows_that_frame(held, recording):
    # before: the held frame's notice was never renewed, and nothing was shown again (found in review)
    model, posted, played = held
    model.set_source(played, ViewerModel.build(recording.grid, "cell"))  # another kernel
    posted.run(model)
    assert model.current.index == 2 and model.last.frame == 2 and model.kernel == "cell"
    played.pause()
    model.shown()
    played.seek(0)
    posted.run(model)
    assert model.last.frame == 0


def test_a_new_source_stops_the_old_one_and_the_same_source_keeps_its_frame(recording, reconstructor):
    model = ViewerModel()
    board = Pushed(recording.grid)
    model.set_source(board, reconstructor)
    board.push(recording.frames[2], 9)
    assert model.current.index == 9  # no dispatch: taken where it arrived
    model.set_source(board, ViewerModel.build(recording.grid, "cell"))  # another kernel, same board
    assert board.stopped == 0 and model.current.index == 9 and model.kernel == "cell"
    played = RecordingSource(recording)
    model.set_source(played, reconstructor)
    played.seek(3)
    model.set_source(played, ViewerModel.build(recording.grid, "cell"))
    assert board.stopped == 1 and model.frame == 3  # a new kernel does not rewind the recording
    board.push(recording.frames[0], 10)
    assert model.current.index == 3  # the stopped board is no longer followed


def test_a_sources_news_reaches_the_model_and_a_failing_stop_is_reported(recording, reconstructor, tmp_path):
    model = ViewerModel()
    board = Pushed(recording.grid)
    model.set_source(board, reconstructor)
    messages = []
    model.message.connect(lambda *m: messages.append(m))
    board.start_recording(tmp_path / "take.mcap")
    board.push(recording.frames[0], 0)
    model.set_source(RecordingSource(recording), reconstructor)  # closing the board closes its recording
    assert messages == [("info", "recording saved", str(tmp_path / "take.mcap"))]

    class Stuck(Pushed):
        def stop(self):
            raise RuntimeError("the port hung")
    stuck = Stuck(recording.grid)
    model.set_source(stuck, reconstructor)
    model.set_source(RecordingSource(recording), reconstructor)  # still shown, the error said
    assert messages[-1] == ("error", "Source did not stop cleanly", "test board (binary): the port hung")
    assert model.recording is not None


def test_a_new_solver_for_a_quiet_board_solves_its_last_frame_again(threaded, recording, reconstructor):
    model, posted = threaded
    board = Pushed(recording.grid)
    model.set_source(board, reconstructor)
    board.push(recording.frames[1], 5)
    posted.run(model)
    posted.run(model)
    assert model.last.frame == 5 and model.kernel == "layer"
    cell = ViewerModel.build(recording.grid, "cell")
    model.set_source(board, cell)  # no frame since: the one shown is solved with the new kernel
    assert model.last is None
    posted.run(model)
    assert model.last.frame == 5
    np.testing.assert_array_equal(model.last.result.forces, cell.solve(recording.frames[1]).forces)


# -- re-taring a recording that keeps raw values ---------------------------------------------------

def test_a_tare_retaken_cleared_or_restored_changes_what_is_solved_not_the_file(recording, reconstructor,
                                                                                tmp_path):
    import hashlib

    from tactile_viewer.io.files import load
    from tactile_viewer.io.mcap_writer import Recorder
    from tactile_viewer.io.recording import StressCalibration, Tare

    path = tmp_path / "take.mcap"
    offset = np.linspace(50.0, 80.0, recording.grid.size)  # a board's zero drifting per taxel, pascals
    recorder = Recorder(path, recording.grid, dtype="float64", calibration=StressCalibration(
        "Pa", 1.0, 0.0, (Tare(0, offset, t=0.0, frames=50),)))
    for k in range(4):
        recorder.add(k, float(recording.t[k]), np.asarray(recording.frames[k]) + offset)
    recorder.close()
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    model = ViewerModel()
    model.set_source(RecordingSource(load(path), path), reconstructor)
    model.set_frame(2)
    np.testing.assert_allclose(model.solve().stress, recording.frames[2], atol=1e-9)  # the recorded tare
    assert model.retare("clear") == "no tare"
    np.testing.assert_allclose(model.solve().stress, recording.frames[2] + offset, atol=1e-9)
    assert model.retare("here", frames=2) == "tare from frames 2 to 3"
    assert model.frame == 2
    np.testing.assert_allclose(model.solve().stress, (recording.frames[2] - recording.frames[3]) / 2, atol=1e-9)
    assert model.retare("recorded") == "the tares taken while recording (1)"
    np.testing.assert_allclose(model.solve().stress, recording.frames[2], atol=1e-9)
    with pytest.raises(ValueError, match=r"how must be 'here', 'clear' or 'recorded', got 'now'"):
        model.retare("now")
    with pytest.raises(ValueError, match="frames must be a positive integer, got 0"):
        model.retare("here", frames=0)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before  # the raw values are untouched


def test_the_display_scales_follow_a_tare_cleared_or_taken(recording, reconstructor, tmp_path):
    from tactile_viewer.io.files import load
    from tactile_viewer.io.mcap_writer import Recorder
    from tactile_viewer.io.recording import StressCalibration, Tare

    # an untared board reads a large offset: cleared, the scales must be those of what is shown
    path = tmp_path / "take.mcap"
    offset = np.full(recording.grid.size, 20 * float(np.abs(recording.frames[:]).max()))
    recorder = Recorder(path, recording.grid, dtype="float64", calibration=StressCalibration(
        "Pa", 1.0, 0.0, (Tare(0, offset, t=0.0, frames=50),)))
    for k in range(4):
        recorder.add(k, float(recording.t[k]), np.asarray(recording.frames[k]) + offset)
    recorder.close()
    model = ViewerModel()
    source = RecordingSource(load(path), path)
    model.set_source(source, reconstructor)
    tared = model.display
    model.retare("clear")
    assert model.display.resultant_scale == pytest.approx(display_scales(source, reconstructor)["resultant_scale"])
    assert model.display.resultant_scale < tared.resultant_scale / 5  # the total is far larger now
    model.retare("recorded")
    assert model.display.resultant_scale == pytest.approx(tared.resultant_scale)
    assert model.display.arrow_scale == pytest.approx(tared.arrow_scale)


def test_retare_errors_are_named(model):
    with pytest.raises(ValueError, match=r"only a recording that keeps raw values \(a live recording, \.mcap\)"):
        model.retare("here")  # an NPZ holds stresses only
    with pytest.raises(ValueError, match="only a recording"):
        ViewerModel().retare("clear")


def test_a_damaged_chunk_is_reported_once_and_the_rest_of_the_recording_shows(recording, reconstructor,
                                                                             tmp_path):
    from tactile_viewer.io.files import load
    from tactile_viewer.io.mcap_writer import Recorder

    path = tmp_path / "damaged.mcap"
    recorder = Recorder(path, recording.grid, dtype="float64", flush_interval=0.1)
    for k in range(40):
        recorder.add(k, k / 20, np.asarray(recording.frames[k % 4]))
    recorder.close()
    chunk = load(path).frames._index.chunks[2]
    data = bytearray(path.read_bytes())
    data[chunk.data_offset + int(chunk.offsets[0]) + 40] ^= 0x10  # one bit of a value in chunk 2
    path.write_bytes(bytes(data))
    model = ViewerModel()
    messages = []
    model.message.connect(lambda *m: messages.append(m))
    model.set_source(RecordingSource(load(path), path), reconstructor)  # opens: the scales skip the chunk
    model.set_frame(chunk.first)
    (level, title, text), = messages
    assert (level, title) == ("error", "Frame not readable") and "damaged (chunk checksum mismatch)" in text
    assert model.frame == 0  # it stays where it was
    model.set_frame(chunk.first + len(chunk.offsets))  # the chunk after it reads
    np.testing.assert_array_equal(model.solve().stress, recording.frames[(chunk.first + len(chunk.offsets)) % 4])


def test_a_new_recording_hides_arrows_under_two_percent_of_its_largest_node_force(recording, reconstructor):
    from tactile_viewer.model.display import HIDE_BELOW

    model = ViewerModel()
    model.set_source(RecordingSource(recording, "takes/sliding.npz"), reconstructor)
    loaded = int(np.argmax(np.abs(recording.frames).sum(axis=1)))
    peak = np.abs(reconstructor.solve_normal(recording.frames[loaded]).forces[:, 2]).max()
    assert HIDE_BELOW == 0.02 and model.display.threshold == pytest.approx(0.02 * peak)
    forces = np.linalg.norm(model.solve().result.forces, axis=1)
    assert 0 < np.sum(forces > model.display.threshold) < recording.grid.size  # the noise arrows go


# -- contacts followed over time ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def crossing():
    """Two presses whose sizes cross: the left grows from 0.4 to 1 N, the right falls from 0.9 to 0.5 N."""
    grid = SensorGrid.regular(14, 8, PITCH, THICKNESS)
    frames = [loads.simulate(grid, [loads.hertz((-6e-3, 0.0), 3e-3, 0.4 + 0.15 * k),
                                    loads.hertz((6e-3, 0.0), 3e-3, 0.9 - 0.1 * k)], noise=0.005, rng=k).stress
              for k in range(5)]
    recording = Recording(grid, frames, 0.05 * np.arange(5), description="crossing sizes")
    return recording, ViewerModel.build(grid, "layer")


def sides(solved):
    """{"left" / "right": identity} of a solved frame's two contacts."""
    left, right = sorted(solved.result.contacts, key=lambda c: c.centre[0])
    return {"left": left.identity, "right": right.identity}


def test_contacts_keep_their_numbers_during_playback_and_start_again_after_a_seek_back(crossing):
    recording, solver = crossing
    model = ViewerModel()
    model.set_source(RecordingSource(recording), solver)
    for k in range(5):
        model.set_frame(k)
        solved = model.solve()
        # numbered on frame 0, largest first: the right one is 1 and stays 1 after the left outgrows it
        assert sides(solved) == {"left": 2, "right": 1}, k
    assert solved.result.contacts[0].identity == 2  # listed first (the larger now), still number 2
    model.set_parameters(shear_ratio=0.2, shear_direction=0.0)  # the same frame solved again
    assert sides(model.solve()) == {"left": 2, "right": 1}
    assert model._tracker.next_identity == 3  # matched again from before the frame: nothing drifted
    model.set_frame(3)  # a step back: nothing is known of the way there, the numbers start again
    assert sides(model.solve()) == {"left": 1, "right": 2}
    model.set_frame(4)
    assert sides(model.solve()) == {"left": 1, "right": 2}


def test_frames_skipped_by_playback_continue_the_numbers_and_count_against_patience(crossing):
    recording, solver = crossing
    model = ViewerModel()
    model.set_source(RecordingSource(recording), solver)
    model._tracker = ContactTracker(recording.grid, patience=1)  # so that a skip of 2 exceeds it
    for k in (0, 2, 4):  # slow drawing shows every other frame: more than patience apart each time
        model.set_frame(k)
        assert sides(model.solve()) == {"left": 2, "right": 1}, k  # not renumbered by force
    model.set_frame(0)
    model.solve()  # a seek back starts again: right 1 (the larger at frame 0), left 2
    model.set_frame(3)  # two frames skipped, both unseen: more than patience, the tracks end ...
    assert sides(model.solve()) == {"left": 3, "right": 4}  # ... but the numbers go on, never reused
    assert model._tracker.next_identity == 5


def test_a_new_source_numbers_its_contacts_from_one(crossing):
    recording, solver = crossing
    model = ViewerModel()
    model.set_source(RecordingSource(recording), solver)
    for k in range(3):
        model.set_frame(k)
        model.solve()
    model.set_source(RecordingSource(recording), solver)
    model.set_frame(4)
    assert sides(model.solve()) == {"left": 1, "right": 2}


def test_live_frames_delivered_by_the_worker_carry_their_numbers(threaded, crossing):
    recording, solver = crossing
    model, posted = threaded
    board = Pushed(recording.grid)
    model.set_source(board, solver)
    for k in range(5):
        board.push(recording.frames[k], 100 + k)
        posted.run(model)  # the hand-over
        posted.run(model)  # the result
        assert model.last.frame == 100 + k and sides(model.last) == {"left": 2, "right": 1}


# -- smoothing the forces drawn (issue 31, item 17) --------------------------------------------------

def pressed(frames, dt, rng):
    """A constant 1 N Hertz press on the 6x5 skin, fresh 1% noise each frame ``dt`` seconds apart."""
    grid = SensorGrid.regular(6, 5, PITCH, THICKNESS)
    stress = [loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0), noise=0.01, rng=rng).stress
              for _ in range(frames)]
    return Recording(grid, stress, np.arange(frames) * dt, description="held press")


def drawn_and_solved(model, frames):
    drawn, solved = [], []
    for k in range(frames):
        model.set_frame(k)
        model.solve()
        drawn.append(model.drawn.forces_drawn[:, 2])
        solved.append(model.last.result.forces[:, 2])
    return np.array(drawn), np.array(solved)


def test_smoothing_steadies_the_drawn_node_forces_and_leaves_the_solved_ones(reconstructor):
    # before: on a constant press the node Fz drawn varied frame to frame as much as the noise made it
    recording = pressed(40, 1 / 30, np.random.default_rng(21))  # fixed seed; 30 frames per second
    model = ViewerModel()
    model.set_source(RecordingSource(recording, "held.npz"), reconstructor)
    model.set_auto(False)  # one member of the family for every frame: only the noise moves the forces
    _, plain = drawn_and_solved(model, 40)
    model.set_frame(0)
    model.set_display(smoothing=0.2)
    drawn, solved = drawn_and_solved(model, 40)
    # what exports and the read-out see is untouched (to the warm start's last bits)
    np.testing.assert_allclose(solved, plain, rtol=0, atol=1e-12)
    loaded = plain.mean(axis=0) > 0.5 * plain.mean(axis=0).max()  # the press's core nodes
    step_plain = np.median(np.abs(np.diff(plain[:, loaded], axis=0)))
    step_drawn = np.median(np.abs(np.diff(drawn[10:, loaded], axis=0)))  # once the start has passed
    # white noise through one exponential step of alpha per frame changes by sqrt(alpha/(2 - alpha))
    # as much: alpha = 1 - exp(-1/6) = 0.15, so 0.29 times
    assert step_drawn < 0.45 * step_plain
    np.testing.assert_allclose(drawn.mean(axis=0)[loaded], plain.mean(axis=0)[loaded], rtol=0.1)
    pitch = recording.grid.pitch
    np.testing.assert_allclose(model.drawn.pressure, model.drawn.forces_drawn[:, 2] / pitch**2)
    assert model.last.drawn_forces is None and model.last.forces_drawn is model.last.result.forces


def test_smoothing_is_checked_and_switching_it_redraws_from_the_frame_shown(model):
    with pytest.raises(ValueError, match=r"smoothing must be finite and >= 0, got -0.1"):
        Display(smoothing=-0.1)
    with pytest.raises(ValueError, match=r"smoothing must be at most 10 s, got 11"):
        Display(smoothing=11)
    model.solve()
    events = listen(model)
    model.set_display(smoothing=0.5)
    assert names(events) == ["display_changed"]
    np.testing.assert_array_equal(model.drawn.forces_drawn, model.last.result.forces)  # nothing before it
    model.set_display(smoothing=0.0)
    assert model.drawn is model.last

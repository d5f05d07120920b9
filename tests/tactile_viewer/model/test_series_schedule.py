"""The time plots' schedule (no Qt): what is solved in the background, when, and what is cached.

Driven by hand: a fake model (the attributes the schedule reads), a fake
background runner that keeps the work and its callbacks until the test runs
them, and the finished/failed callbacks recorded.
"""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from tactile_viewer.model.series_schedule import CACHED, SeriesSchedule
from tactile_viewer.model.solved import Solved
from tactile_viewer.model.worker import Cancelled


class Task:
    def __init__(self, work, done, failed):
        self.work, self.done, self.failed = work, done, failed
        self.cancelled = False

    def cancel(self):
        self.cancelled = True

    def run(self):
        """The work to its end, its result handed back as the runner would."""
        self.done(self.work(lambda done, total: True))


class Runner:
    """Background tasks kept until the test runs them."""

    def __init__(self):
        self.tasks = []

    def __call__(self, work, done, failed):
        self.tasks.append(Task(work, done, failed))
        return self.tasks[-1]


def fake_model(recording, solver, **overrides):
    values = dict(recording=recording, reconstructor=solver, auto=True, shear_ratio=0.0, shear_direction=0.0,
                  path=None, live=False, is_open=True)
    values.update(overrides)
    return SimpleNamespace(**values)


@pytest.fixture
def setup(skin):
    recording, solver = skin
    model = fake_model(recording, solver)
    runner, finished, failed = Runner(), [], []
    schedule = SeriesSchedule(model, runner, finished=finished.append, failed=failed.append, every=1e-9)
    return SimpleNamespace(model=model, runner=runner, finished=finished, failed=failed, schedule=schedule,
                           recording=recording, solver=solver)


def test_the_wanted_series_is_solved_in_the_background_and_kept(setup):
    schedule, runner = setup.schedule, setup.runner
    assert schedule.wanted() == (setup.recording, setup.solver, None)
    assert schedule.start() == len(setup.recording) and schedule.solving and len(runner.tasks) == 1
    assert not setup.finished  # nothing until the task is done
    runner.tasks[0].run()
    assert not schedule.solving and len(setup.finished) == 1
    series = setup.finished[0]
    assert series.complete and len(series) == len(setup.recording) and series.mode == "auto"
    assert series.source == setup.recording.description
    # the same again: from the cache, at once, no task
    assert schedule.start() is None and len(runner.tasks) == 1 and setup.finished[1] is series
    assert schedule.asked_for(setup.recording) and not schedule.asked_for(None)


def test_given_parameters_are_solved_and_auto_again_comes_from_the_cache(setup):
    schedule, runner, model = setup.schedule, setup.runner, setup.model
    schedule.start()
    runner.tasks[-1].run()
    model.auto, model.shear_ratio, model.shear_direction = False, 0.4, 1.0
    assert schedule.wanted()[2] == (0.4, 1.0)
    schedule.start()
    runner.tasks[-1].run()
    assert setup.finished[-1].mode == "manual" and setup.finished[-1].shear_ratio == pytest.approx(0.4)
    model.auto = True
    assert schedule.start() is None and len(runner.tasks) == 2 and setup.finished[-1].mode == "auto"


def test_the_cache_keeps_the_last_parameters_and_a_new_source_forgets_them(setup):
    schedule, runner, model = setup.schedule, setup.runner, setup.model
    model.auto = False
    for k in range(CACHED + 1):
        model.shear_ratio = 0.1 * k
        schedule.start()
        runner.tasks[-1].run()
    model.shear_ratio = 0.0  # the oldest: dropped
    assert schedule.start() is not None and len(runner.tasks) == CACHED + 2
    runner.tasks[-1].run()
    model.shear_ratio = 0.1 * CACHED  # still kept
    assert schedule.start() is None
    schedule.new_source()
    assert schedule.start() is not None


def test_a_new_series_cancels_the_one_running_and_drops_its_result(setup):
    schedule, runner = setup.schedule, setup.runner
    schedule.start()
    old = runner.tasks[0]
    schedule.start()
    assert old.cancelled and len(runner.tasks) == 2
    old.run()  # it ended anyway: its result is of an older series
    assert not setup.finished and schedule.solving
    old.failed(RuntimeError("late"))
    assert not setup.failed
    runner.tasks[1].run()
    assert len(setup.finished) == 1


def test_a_failure_is_reported_and_a_cancel_is_not(setup):
    schedule, runner = setup.schedule, setup.runner
    schedule.start()
    runner.tasks[0].failed(Cancelled("stopped"))
    assert not setup.failed and schedule.solving
    runner.tasks[0].failed(RuntimeError("the solver broke"))
    assert [str(e) for e in setup.failed] == ["the solver broke"] and not schedule.solving


def test_a_hidden_dock_solves_nothing_until_shown(setup):
    schedule = setup.schedule
    assert schedule.start(visible=False) is None and schedule.stale and not setup.runner.tasks
    assert schedule.start(visible=True) is not None and not schedule.stale


def test_nothing_open_solves_nothing(setup):
    setup.model.recording = None
    assert setup.schedule.start() is None and not setup.runner.tasks and not setup.schedule.stale


def test_new_parameters_drop_the_series_at_once_unless_live_or_nothing_open(setup):
    schedule, runner, model = setup.schedule, setup.runner, setup.model
    schedule.start()
    assert schedule.parameters_changed() and runner.tasks[0].cancelled and not schedule.solving
    schedule.start()
    for live, is_open in ((True, True), (False, False)):
        model.live, model.is_open = live, is_open
        assert not schedule.parameters_changed() and not runner.tasks[1].cancelled


def test_a_retared_recording_is_solved_again(setup):
    schedule, runner, model = setup.schedule, setup.runner, setup.model
    schedule.start()
    runner.tasks[0].run()
    frame = Solved.of(setup.recording.grid, setup.recording.frames[0], setup.solver.solve(setup.recording.frames[0]))
    assert not schedule.solved(frame)
    model.recording = replace(setup.recording, frames=setup.recording.frames * 0.5)  # same file, other stresses
    assert schedule.solved(frame)
    assert schedule.start() is not None  # the cache was of the old stresses


def test_partial_series_are_handed_on_once(setup):
    schedule, runner = setup.schedule, setup.runner
    schedule.start()
    assert schedule.new_partial() is None
    handed = []
    task = runner.tasks[0]
    task.work(lambda done, total: handed.append(schedule.new_partial()) or True)
    partials = [p for p in handed if p is not None]
    assert partials and all(not p.complete for p in partials)
    assert len({id(p) for p in partials}) == len(partials)  # each once
    schedule.new_partial()  # the last one handed over, if the loop did not take it
    assert schedule.new_partial() is None


def test_a_live_source_collects_its_frames_solved(setup):
    schedule, model, recording, solver = setup.schedule, setup.model, setup.recording, setup.solver
    model.live = True
    empty = schedule.follow_live(recording.grid, kernel="layer", source="tcp://lab", span=0.1)
    assert len(empty) == 0 and empty.mode == "as shown" and schedule.live is not None
    assert schedule.new_live_series() is None
    for k in range(3):
        frame = Solved.of(recording.grid, recording.frames[k], solver.solve(recording.frames[k]), frame=k,
                          time=float(recording.t[k]))
        assert not schedule.solved(frame)
    series = schedule.new_live_series()
    np.testing.assert_array_equal(series.frame, [0, 1, 2])
    assert schedule.new_live_series() is None  # nothing new since
    schedule.new_source()
    assert schedule.live is None


def test_bad_max_frames_are_named(setup):
    with pytest.raises(ValueError, match="limit must be a whole number >= 2"):
        SeriesSchedule(setup.model, setup.runner, finished=print, failed=print, max_frames=1)

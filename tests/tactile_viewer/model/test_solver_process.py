"""A solver in a process of its own (tactile_viewer/model/solver_process.py): the child's answers equal the
solver's own, a frame that fails fails alone, a child that ends is said and replaced, a build that fails is
named, and the stream takes what waits in one round trip."""

import functools
import math
import os
import threading
from dataclasses import replace

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.model.batch import settings_from_preset
from tactile_viewer.model.force_stream import ForceStream
from tactile_viewer.model.solver_process import BATCH_FRAMES, SolverProcess, warm
from tactile_viewer.sources.source import Source, SourceFrame

GRID = SensorGrid.regular(6, 5, 2e-3, 2e-3)
WAIT_S = 10.0
EXIT_MARK = -12345.0  # a first taxel that makes Exits end its process


@pytest.fixture(scope="module")
def stresses():
    """Ten frames of a sheared Hertz press moving along x (noise with a fixed seed, 7)."""
    rng = np.random.default_rng(7)
    return [loads.simulate(GRID, loads.hertz((x, -0.3e-3), 3e-3, 1.0, shear_ratio=0.25, shear_direction=-0.7),
                           noise=0.01, rng=rng).stress for x in np.linspace(-2e-3, 2e-3, 10)]


class Exits:
    """A solver whose process ends (exit status 3) at a frame whose first taxel is EXIT_MARK."""

    def __init__(self):
        self.inner = Reconstructor(GRID)
        self.grid = GRID

    def solve(self, stress, **parameters):
        if stress[0] == EXIT_MARK:
            os._exit(3)
        return self.inner.solve(stress, **parameters)


def cannot_build():
    raise OSError("no such skin")


@pytest.fixture(scope="module")
def process():
    child = SolverProcess(Exits, name="test solver")
    yield child
    child.close()


def test_the_childs_answers_are_its_solvers_own(process, stresses):
    # the same frames in the same order through a warmed solver here: each automatic fit starts from the
    # frame before, which changes an answer only by rounding
    here = Reconstructor(GRID)
    warm(here)
    cpu_before = process.cpu_time
    answers = process.solve_each(stresses[:6]) + [(process.solve(stress), None) for stress in stresses[6:]]
    for stress, (result, error) in zip(stresses, answers, strict=True):
        assert error is None
        expected = here.solve(stress)
        np.testing.assert_allclose(result.forces, expected.forces, rtol=0, atol=1e-9 * np.abs(expected.forces).max())
        assert result.shear_ratio == pytest.approx(expected.shear_ratio, abs=1e-9)
    assert process.cpu_time > cpu_before  # the child's CPU, as it said with its answers
    given = process.solve(stresses[0], shear_ratio=0.2, shear_direction=0.5)
    assert (given.shear_ratio, given.shear_direction) == (0.2, 0.5)


def test_a_frame_that_fails_fails_alone(process, stresses):
    bad = np.array(stresses[1])
    bad[3] = math.nan
    answers = process.solve_each([stresses[0], bad, stresses[2]])
    assert [error is None for _, error in answers] == [True, False, True]
    assert isinstance(answers[1][1], ValueError) and "stress" in str(answers[1][1])
    with pytest.raises(ValueError, match="stress"):
        process.solve(bad)


def test_a_child_that_ends_fails_its_frames_and_the_next_call_starts_another(process, stresses):
    ending = np.array(stresses[0])
    ending[0] = EXIT_MARK
    with pytest.raises(RuntimeError, match=r"test solver ended while it solved \(exit code 3\); another is "
                                           r"started"):
        process.solve_each([stresses[1], ending])
    assert process.restarts == 1 and not process.closed  # started at once, waited for by the next call
    result = process.solve(stresses[1])
    assert result.forces.shape == (GRID.size, 3)
    # one that ends while idle is replaced before frames are sent to it
    process._process.kill()
    process._process.join()
    assert process.solve(stresses[1]).forces.shape == (GRID.size, 3)
    assert process.restarts == 2


def test_a_closed_solver_process_says_so(stresses):
    child = SolverProcess(Exits, name="closing")
    child.close()
    child.close()  # a second close does nothing
    with pytest.raises(RuntimeError, match="closing is closed"):
        child.solve(stresses[0])


def test_a_build_that_fails_is_named():
    with pytest.raises(RuntimeError, match="broken could not build its solver: no such skin"):
        SolverProcess(cannot_build, name="broken")
    with pytest.raises(RuntimeError, match="slow did not build its solver within 0.001 s"):
        SolverProcess(functools.partial(Reconstructor, GRID), name="slow", start_timeout=0.001)


class Board(Source):
    live = True

    def __init__(self):
        super().__init__("board", GRID)

    def now(self):
        return 1.0

    def send(self, frames):
        self._publish(frames)


class Batches:
    """A solver in the manner of SolverProcess (``solve_each``), held at its first call until released;
    each call counts a second of CPU."""

    batch, closed = BATCH_FRAMES, False

    def __init__(self, fail_batch=None):
        self.sizes, self.release, self.started = [], threading.Event(), threading.Event()
        self.took = threading.Condition()
        self.cpu_time = 0.0
        self.alone, self.fail_batch = Reconstructor(GRID), fail_batch

    def wait_ready(self):
        pass

    def solve_each(self, stresses, **_):
        with self.took:
            self.sizes.append(len(stresses))
            self.cpu_time += 1.0
            self.took.notify_all()
        self.started.set()
        assert self.release.wait(WAIT_S)
        if len(self.sizes) == self.fail_batch:
            raise RuntimeError("the child ended")
        return [(self.alone.solve_normal(stress), None) for stress in stresses]


class Indices:
    """``publish``: the indices of the frames published, and their results, in order."""

    def __init__(self):
        self.done, self.indices, self.results = threading.Condition(), [], []

    def __call__(self, frame, result):
        with self.done:
            self.indices.append(frame.index)
            self.results.append(result)
            self.done.notify_all()


def published_after(solver, held, stresses, count, **options):
    # the first frame sent alone and held in ``held`` (``solver`` or one of its solvers); the others sent
    # while it is solved; the stream stopped once ``count`` are published
    board, published = Board(), Indices()
    frames = [SourceFrame(stress, 0.001 * k, k) for k, stress in enumerate(stresses)]
    stream = ForceStream(board, solver, published, **options)
    stream.start()
    board.send(frames[:1])
    assert held.started.wait(WAIT_S)
    board.send(frames[1:])
    held.release.set()
    with published.done:
        assert published.done.wait_for(lambda: len(published.indices) >= count, WAIT_S)
    stream.stop()
    return stream, published


def test_a_solver_in_another_process_takes_what_waits_in_one_round_trip(stresses):
    solver = Batches()
    stream, published = published_after([solver], solver, stresses, len(stresses))
    assert published.indices == list(range(len(stresses)))
    assert solver.sizes == [1, 8, 1]  # at most BATCH_FRAMES a batch
    totals = stream.totals()
    assert (totals.solved, totals.published, totals.failed) == (10, 10, 0)
    assert totals.cpu >= 100 * 3 / totals.elapsed  # the solver's own CPU counted: a second a call


def test_a_batch_whose_round_trip_fails_fails_its_frames_and_the_stream_goes_on(stresses):
    solver = Batches(fail_batch=2)
    stream, published = published_after([solver], solver, stresses, 2)
    assert published.indices == [0, 9]
    totals = stream.totals()
    assert (totals.published, totals.failed) == (2, 8)
    assert stream.last_error == "frame 8: RuntimeError: the child ended"


@pytest.mark.parametrize(("solver", "options", "message"), [
    ([], {}, "solver must be a solver or a sequence of one or more, got an empty one"),
    ([None, None], {"solvers": 3}, "solvers must be left out or equal the 2 solvers given, got 3"),
    ([None], {"faster": object()}, "faster goes with one solver solved on this process's threads"),
])
def test_a_sequence_of_solvers_is_checked(solver, options, message):
    with pytest.raises(ValueError, match=message):
        ForceStream(Board(), solver, print, **options)


def test_solvers_in_other_processes_each_take_their_share_of_what_waits(stresses):
    # both solvers held at their first frame while eight more come: the first released takes half of the
    # eight (one that took all would leave the other idle once it is free)
    board, published = Board(), Indices()
    first, second = Batches(), Batches()
    stream = ForceStream(board, [first, second], published)
    frames = [SourceFrame(stress, 0.001 * k, k) for k, stress in enumerate(stresses)]
    stream.start()
    board.send(frames[:1])
    board.send(frames[1:2])
    assert first.started.wait(WAIT_S) and second.started.wait(WAIT_S)
    board.send(frames[2:])
    first.release.set()
    with first.took:
        assert first.took.wait_for(lambda: len(first.sizes) >= 2, WAIT_S)
    second.release.set()
    with published.done:
        assert published.done.wait_for(lambda: len(published.indices) == len(frames), WAIT_S)
    stream.stop()
    assert published.indices == list(range(len(frames)))
    assert first.sizes[:2] == [1, 4] and second.sizes[0] == 1
    assert sum(first.sizes) + sum(second.sizes) == len(frames)


class CannotStart:
    """A solver process that could not be started again: its thread ends, the others take the frames."""

    batch, closed, cpu_time = BATCH_FRAMES, False, 0.0

    def wait_ready(self):
        self.closed = True
        raise RuntimeError("test solver could not build its solver: no memory")

    def solve_each(self, stresses, **_):
        raise AssertionError("a closed solver was given frames")


def test_a_solver_that_cannot_start_again_leaves_the_frames_to_the_others(stresses):
    board, published, working = Board(), Indices(), Batches()
    working.release.set()
    stream = ForceStream(board, [CannotStart(), working], published)
    frames = [SourceFrame(stress, 0.001 * k, k) for k, stress in enumerate(stresses)]
    stream.start()
    board.send(frames)
    with published.done:
        assert published.done.wait_for(lambda: len(published.indices) == len(frames), WAIT_S)
    stream.stop()
    assert published.indices == list(range(len(frames)))
    assert stream.totals().failed == 0 and stream.last_error == ""
    assert stream.solver_error == "RuntimeError: test solver could not build its solver: no memory"
    assert stream.solvers_left == 1


class Held:
    """A plain solver held at its first solve until released; its answers' own fallback is ``own``."""

    def __init__(self, own=""):
        self.release, self.started, self.own = threading.Event(), threading.Event(), own
        self.alone = Reconstructor(GRID)

    def solve(self, stress, **_):
        self.started.set()
        assert self.release.wait(WAIT_S)
        return replace(self.alone.solve_normal(stress), fallback=self.own)


def test_a_stream_behind_catches_up_with_the_faster_member_and_says_so(stresses):
    # the first frame held while nine more come: with catch_up=5 the frames taken while 5 or more wait go
    # to the faster member, each marked, counted; the rest to the solver
    solver, faster = Held(), Held(own="1 contact of weaker evidence left out")
    faster.release.set()
    stream, published = published_after(solver, solver, stresses, len(stresses), catch_up=5, faster=faster)
    results = published.results
    assert published.indices == list(range(len(stresses)))
    # waiting when taken: 9, 8, 7, 6, 5 (faster), then 4, 3, 2, 1 (the solver)
    marked = [bool(r.fallback) for r in results]
    assert marked == [False] + [True] * 5 + [False] * 4
    assert results[1].fallback == ("solved by the faster member while the stream was 9 frames behind; 1 contact "
                                   "of weaker evidence left out")  # the faster member's own reason kept
    totals = stream.totals()
    assert (totals.published, totals.faster, totals.skipped) == (10, 5, 0)


def test_a_solver_process_solves_with_its_faster_member_when_asked(stresses):
    whole_cell = functools.partial(settings_from_preset("layer, whole-cell profile").build, GRID)
    child = SolverProcess(functools.partial(settings_from_preset(None).build, GRID), faster=whole_cell,
                          name="two members")
    try:
        assert child.has_faster
        standard, = child.solve_each(stresses[:1])
        quick, = child.solve_each(stresses[:1], faster=True)
    finally:
        child.close()
    here = whole_cell()
    warm(here)
    expected = here.solve(stresses[0])
    peak = np.abs(expected.forces).max()
    np.testing.assert_allclose(quick[0].forces, expected.forces, rtol=0, atol=1e-9 * peak)
    assert np.abs(standard[0].forces - quick[0].forces).max() > 1e-3 * peak  # not the same member

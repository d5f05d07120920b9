"""Forces at sensor rate (tactile_viewer/model/force_stream.py): every frame solved and published in order,
a slow solver's skips counted, failures counted and survived, latency figures."""

import math
import threading
from dataclasses import replace

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.model.force_stream import ForceStream
from tactile_viewer.sources.source import Source, SourceFrame

GRID = SensorGrid.regular(6, 5, 2e-3, 2e-3)
WAIT_S = 10.0  # bounded waits on the stream's thread


class FakeBoard(Source):
    """A live source driven by the test: frames produced on the test's thread, its clock stopped at ``clock``."""

    live = True

    def __init__(self, clock=1.0):
        super().__init__("fake board", GRID)
        self.clock = clock

    def now(self):
        return self.clock

    def send(self, frames):
        self._publish(frames)


@pytest.fixture(scope="module")
def frames():
    """Twelve frames of a sheared Hertz press moving along x (noise with a fixed seed, 3)."""
    rng = np.random.default_rng(3)
    stresses = [loads.simulate(GRID, loads.hertz((x, 0.2e-3), 3e-3, 1.0, shear_ratio=0.3, shear_direction=0.4),
                               noise=0.01, rng=rng).stress for x in np.linspace(-2e-3, 2e-3, 12)]
    return [SourceFrame(stress, 0.001 * k, k) for k, stress in enumerate(stresses)]


@pytest.fixture(scope="module")
def solver():
    return Reconstructor(GRID)


class Published:
    def __init__(self):
        self.frames, self.results = [], []
        self.done = threading.Condition()

    def __call__(self, frame, result):
        with self.done:
            self.frames.append(frame)
            self.results.append(result)
            self.done.notify_all()

    def wait(self, count):
        with self.done:
            assert self.done.wait_for(lambda: len(self.frames) >= count, WAIT_S), len(self.frames)


class SlowSolver:
    """Holds its first solve until released: the board runs ahead meanwhile."""

    def __init__(self):
        self.started, self.release = threading.Event(), threading.Event()

    def solve(self, stress, **_):
        self.started.set()
        assert self.release.wait(WAIT_S)
        return Reconstructor(GRID).solve_normal(stress)


def test_every_frame_is_solved_and_published_in_order_with_the_solvers_own_forces(frames):
    board, published = FakeBoard(clock=0.004), Published()
    stream = ForceStream(board, Reconstructor(GRID), published)
    stream.start()
    for k in range(0, len(frames), 3):  # three frames per read, as a reader delivers them
        board.send([replace(frame, t=0.0) for frame in frames[k:k + 3]])
    published.wait(len(frames))
    stream.stop()
    alone = Reconstructor(GRID)  # the same frames in the same order: the same warm starts
    assert [f.index for f in published.frames] == list(range(len(frames)))
    for frame, result in zip(frames, published.results, strict=True):
        np.testing.assert_array_equal(result.forces, alone.solve(frame.stress).forces)
    totals = stream.totals()
    assert (totals.received, totals.solved, totals.published, totals.skipped, totals.failed) == (12, 12, 12, 0, 0)
    # every frame published 4 ms after its stamp by the board's clock: the histogram's bin holds it
    assert totals.latency_median == pytest.approx(0.004, rel=0.012)
    assert totals.latency_p99 == pytest.approx(0.004, rel=0.012)


def test_given_parameters_reach_every_solve(frames, solver):
    board, published = FakeBoard(), Published()
    stream = ForceStream(board, Reconstructor(GRID), published, shear_ratio=0.2, shear_direction=1.0)
    stream.start()
    board.send(frames[:4])
    published.wait(4)
    stream.stop()
    for frame, result in zip(frames, published.results, strict=False):
        np.testing.assert_allclose(result.forces, solver.solve(frame.stress, shear_ratio=0.2,
                                                               shear_direction=1.0).forces, rtol=0, atol=1e-12)
        assert (result.shear_ratio, result.shear_direction) == pytest.approx((0.2, 1.0))


def test_a_slow_solver_skips_the_oldest_frames_and_counts_them(frames):
    board, published, slow = FakeBoard(), Published(), SlowSolver()
    stream = ForceStream(board, slow, published, queue_frames=3)
    stream.start()
    board.send(frames[:1])
    assert slow.started.wait(WAIT_S)  # frame 0 is being solved, and holds the solver
    for frame in frames[1:9]:
        board.send([frame])
    behind = stream.figures()
    assert (behind.received, behind.skipped, behind.waiting, behind.published) == (9, 5, 3, 0)
    slow.release.set()
    published.wait(4)
    stream.stop()
    # the newest three waited; frames 1 to 5 were pushed out, never solved
    assert [f.index for f in published.frames] == [0, 6, 7, 8]
    totals = stream.totals()
    assert (totals.received, totals.published, totals.skipped, totals.failed) == (9, 4, 5, 0)
    assert totals.received == totals.published + totals.skipped


def test_stopping_solves_what_waits_and_counts_what_could_not_be(frames):
    board, published, slow = FakeBoard(), Published(), SlowSolver()
    stream = ForceStream(board, slow, published, queue_frames=10)
    stream.start()
    board.send(frames[:4])
    assert slow.started.wait(WAIT_S)
    # the stop's wait ends before the solver is released: the three waiting are counted as skipped
    stream.stop(timeout=0.01)
    assert stream.totals().skipped == 3
    slow.release.set()


def test_a_frame_that_fails_is_counted_and_named_and_the_stream_goes_on(frames, solver):
    board, published = FakeBoard(), Published()
    stream = ForceStream(board, Reconstructor(GRID), published)
    stream.start()
    bad = SourceFrame(np.full(GRID.size, np.nan), 0.5, 99)
    board.send([frames[0], bad, frames[1]])
    published.wait(2)
    stream.stop()
    assert [f.index for f in published.frames] == [0, 1]
    totals = stream.totals()
    assert (totals.received, totals.published, totals.failed, totals.skipped) == (3, 2, 1, 0)
    assert stream.last_error.startswith("frame 99: ValueError: ")


def test_a_publish_that_raises_is_a_failed_frame_not_an_ended_stream(frames):
    board, calls = FakeBoard(), []

    def publish(frame, result):
        calls.append(frame.index)
        if frame.index == 1:
            raise ValueError("forces must be finite numbers of newtons")
    stream = ForceStream(board, Reconstructor(GRID), publish)
    stream.start()
    board.send(frames[:3])
    stream.stop()
    assert calls == [0, 1, 2]
    assert stream.totals().failed == 1 and stream.totals().published == 2
    assert "frame 1: ValueError: forces must be finite" in stream.last_error


def test_figures_cover_the_interval_since_the_last_call(frames):
    board, published = FakeBoard(clock=0.002), Published()
    stream = ForceStream(board, Reconstructor(GRID), published)
    stream.start()
    board.send([replace(frame, t=0.0) for frame in frames[:5]])
    published.wait(5)
    first = stream.figures()
    board.send([replace(frame, t=0.0) for frame in frames[5:7]])
    published.wait(7)
    second = stream.figures()
    stream.stop()
    assert (first.received, first.published, second.received, second.published) == (5, 5, 2, 2)
    assert first.latency_median == pytest.approx(0.002) and second.latency_p99 == pytest.approx(0.002)
    assert first.solve_time > 0 and first.cpu >= 0
    empty = stream.figures()
    assert empty.published == 0 and math.isnan(empty.latency_median) and math.isnan(empty.solve_time)


class SideBySide:
    """Solves normal-only; the first two solves return only once both are running (so they ran at
    once), and each even frame takes longer than the odd one after it (so frames finish out of order)."""

    def __init__(self, fail=None):
        self.both_running = threading.Barrier(2, timeout=WAIT_S)
        self.calls, self.lock, self.fail = 0, threading.Lock(), fail
        self.alone = Reconstructor(GRID)

    def solve(self, stress, **_):
        with self.lock:
            self.calls += 1
            first_two = self.calls <= 2
        if first_two:
            self.both_running.wait()  # raises BrokenBarrierError when the solves do not overlap
        index = int(round(stress[0]))  # the test's frames carry their index in the first taxel
        threading.Event().wait(0.02 if index % 2 == 0 else 0.0)
        if index == self.fail:
            raise ValueError(f"frame {index} is bad")
        return self.alone.solve_normal(stress)


def numbered(frames):
    # the frames with their index in the first taxel (read back by SideBySide)
    out = []
    for frame in frames:
        stress = np.array(frame.stress)
        stress[0] = frame.index
        out.append(replace(frame, stress=stress))
    return out


def test_several_solver_threads_solve_side_by_side_and_publish_in_frame_order(frames):
    board, published, solver = FakeBoard(), Published(), SideBySide()
    stream = ForceStream(board, solver, published, solvers=2)
    stream.start()
    sent = numbered(frames)
    for k in range(0, len(sent), 2):
        board.send(sent[k:k + 2])
    published.wait(len(sent))
    stream.stop()
    assert not solver.both_running.broken  # the first two frames were solved at the same time
    assert [f.index for f in published.frames] == list(range(len(sent)))
    for frame, result in zip(sent, published.results, strict=True):
        np.testing.assert_array_equal(result.forces, solver.alone.solve_normal(frame.stress).forces)
    totals = stream.totals()
    assert (totals.received, totals.solved, totals.published, totals.skipped, totals.failed) == (12, 12, 12, 0, 0)


def test_a_failed_frame_among_several_solver_threads_keeps_the_others_in_order(frames):
    board, published, solver = FakeBoard(), Published(), SideBySide(fail=4)
    stream = ForceStream(board, solver, published, solvers=3)
    stream.start()
    board.send(numbered(frames))
    published.wait(len(frames) - 1)
    stream.stop()
    assert [f.index for f in published.frames] == [k for k in range(len(frames)) if k != 4]
    totals = stream.totals()
    assert (totals.published, totals.failed) == (11, 1)
    assert stream.last_error == "frame 4: ValueError: frame 4 is bad"


class HeldFirst:
    """Solves normal-only; frame 0 is held until the test releases it, and says which frames it solved."""

    def __init__(self):
        self.release, self.solved, self.lock = threading.Event(), [], threading.Lock()
        self.alone = Reconstructor(GRID)
        self.all_but_first = threading.Event()

    def solve(self, stress, **_):
        index = int(round(stress[0]))  # the test's frames carry their index in the first taxel
        if index == 0:
            assert self.release.wait(WAIT_S)
        with self.lock:
            self.solved.append(index)
            if len(self.solved) == 3 and 0 not in self.solved:
                self.all_but_first.set()
        return self.alone.solve_normal(stress)


def test_a_thread_whose_frame_was_solved_early_goes_on_to_the_next_frame(frames):
    # frame 0 is held on one thread: the other solves frames 1, 2 and 3 meanwhile (before, it waited
    # with frame 1 solved until frame 0 was published, and the stream had one thread for the time)
    board, published, solver = FakeBoard(), Published(), HeldFirst()
    stream = ForceStream(board, solver, published, solvers=2)
    stream.start()
    board.send(numbered(frames[:4]))
    try:
        assert solver.all_but_first.wait(WAIT_S), solver.solved
        assert published.frames == []  # nothing before frame 0: publishing keeps the frames' order
    finally:
        solver.release.set()
    published.wait(4)
    stream.stop()
    assert [f.index for f in published.frames] == [0, 1, 2, 3]
    assert solver.solved == [1, 2, 3, 0]
    assert stream.totals().published == 4


@pytest.mark.parametrize(("options", "message"), [
    ({"queue_frames": 0}, "queue_frames must be a whole number >= 1, got 0"),
    ({"queue_frames": 2.5}, "queue_frames must be a whole number >= 1, got 2.5"),
    ({"solvers": 0}, "solvers must be a whole number >= 1, got 0"),
])
def test_bad_options_are_named(options, message):
    with pytest.raises(ValueError, match=message):
        ForceStream(FakeBoard(), None, print, **options)


def test_a_source_without_a_clock_needs_one():
    with pytest.raises(ValueError, match="clock must be given for a source without a now"):
        ForceStream(Source("no clock", GRID), None, print)

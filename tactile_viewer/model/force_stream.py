"""Forces at sensor rate: every frame of a live source solved and published, in order. No Qt.

:class:`ForceStream` follows a source's ``frames_produced`` (every frame, in
order, on the reader's thread) into a bounded queue, and its solver threads
take them oldest first: each solves with its solver (automatic fits start from
the frame that solver solved last) and hands the frame and its
:class:`solver.Reconstruction` to ``publish`` (an LSL outlet, a force log).
A thread's solver is the stream's one solver, shared, taken a frame at a time,
or its own: a :class:`~tactile_viewer.model.solver_process.SolverProcess`, a
solver in a process of its own, to which the thread sends its share of what
waits (up to :data:`~tactile_viewer.model.solver_process.BATCH_FRAMES` frames)
in one round trip and waits for the answers. A solver process that ends fails
the frames it held (counted) and is started again; its thread waits for the
new one before it takes frames. With
several threads, frames are solved side by side, out of order, on as many
cores; ``publish`` still takes them one at a time, in frame order: a frame
solved before the one taken ahead of it waits, solved, while its thread goes on
to the next frame, and the thread that solves the frame whose turn it is
publishes it and every solved one after it.

The reader never waits for the solver: it only appends to the queue, so the
board is read and recorded at its own pace whatever the solver does. When the
solver cannot keep up, the queue fills; a frame arriving at a full queue
pushes out the oldest waiting one, which is *skipped*: never solved nor
published, and counted (:attr:`StreamFigures.skipped`). The queue's bound is
the most latency a slow solver can add (``queue_frames`` over the board's
rate), and nothing is ever held back silently.

Latency is the time from a frame's receive stamp (the reader's clock, set
when its bytes were read) to the moment ``publish`` returned.
:meth:`ForceStream.figures` gives it, with the counts, solves per second and
the CPU used (this process's and its solver processes'), for the interval
since its last call and for the whole run (percentiles of the whole run from a
histogram with 1.2% wide bins, so a run of hours keeps a fixed memory).

The forces published are kept for a force file by
:class:`~tactile_viewer.model.force_log.ForceLog`.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from solver.checks import whole_number
from solver.threads import one_blas_thread

from ..sources.source import Source, SourceFrame

__all__ = ["StreamFigures", "ForceStream", "DEFAULT_QUEUE_FRAMES", "solve_each"]

# Frames that may wait for the solver: 0.2 s of a 1 kHz board. A hiccup of the machine (another
# process, a garbage collection) shorter than that is caught up without a skip; a solver slower
# than the board skips frames within that much latency instead of falling ever further behind.
DEFAULT_QUEUE_FRAMES = 200

# latency histogram: log-spaced bins from 1 us to 100 s, 1.2% wide (1600 over 8 decades)
_EDGES = np.logspace(-6, 2, 1601)


@dataclass(frozen=True)
class StreamFigures:
    """What a :class:`ForceStream` did over an interval (or the whole run).

    Attributes
    ----------
    elapsed : float
        Seconds the figures cover.
    received : int
        Frames the source produced (each went into the queue).
    solved : int
        Frames solved (a solve that raised is not counted here but in ``failed``).
    published : int
        Frames whose forces ``publish`` took.
    skipped : int
        Frames pushed out of the full queue, oldest first: never solved.
    failed : int
        Frames whose solve or publish raised (counted, :attr:`ForceStream.last_error` says why).
    faster : int
        Frames solved and published by the solver's faster member while the stream caught up
        (``catch_up``; each one's ``fallback`` says so).
    waiting : int
        Frames in the queue at the end of the interval.
    solve_rate : float
        Frames solved per second over the interval.
    solve_time : float
        Median seconds of one solve over the interval (nan when none, and for the whole run); for
        a solver process, its round trip over the frames it took.
    latency_median, latency_p99 : float
        Seconds from a frame's receive stamp to its publication: the median and
        99th percentile over the interval (nan when nothing was published).
    cpu : float
        CPU time over the interval in percent of one core (200 is two cores
        busy): this process's and its solver processes'.
    """

    elapsed: float
    received: int
    solved: int
    published: int
    skipped: int
    failed: int
    faster: int
    waiting: int
    solve_rate: float
    solve_time: float
    latency_median: float
    latency_p99: float
    cpu: float


class ForceStream:
    """Solve and publish every frame of a live source, on threads of its own (module notes).

    Parameters
    ----------
    source : Source
        Where frames come from (its ``frames_produced``); started and stopped by its owner.
    solver : solver.Reconstructor, SolverProcess or sequence of them
        Solves each frame (``solver.solve(stress, shear_ratio=..., shear_direction=...)``, or a
        :class:`~tactile_viewer.model.solver_process.SolverProcess`'s ``solve_each``), on this
        stream's threads: one solver shared by ``solvers`` threads (its solves may run side by
        side: it keeps no per-call state), or a sequence, one thread for each (solver processes
        share no GIL).
    publish : callable
        ``publish(frame, result)`` with the :class:`~tactile_viewer.sources.source.SourceFrame`
        and its :class:`solver.Reconstruction`, on one of the stream's threads, one call at a
        time, in frame order.
    shear_ratio, shear_direction : float or None, optional
        Given parameters (``mu``, ``theta`` in radians) for every frame; both None (default):
        found for each frame.
    queue_frames : int, optional
        Frames that may wait for the solver (default :data:`DEFAULT_QUEUE_FRAMES`); a frame
        arriving at a full queue skips the oldest.
    solvers : int, optional
        Threads sharing one ``solver`` (default 1; a sequence of solvers sets it). The solver's
        compiled and BLAS work releases Python's GIL, so the threads overlap there: on the
        project's 2-core machine two threads solved 1.3 times as many frames a second as one with
        automatic parameters, 1.05 times with given ones (``docs/interop.md``).
    clock : callable, optional
        Seconds on the clock of the frames' receive stamps (default ``source.now``).
    catch_up : int or None, optional
        Frames waiting at which a solver takes its frames to its faster member (a solver process's
        ``faster``, or ``faster`` here), so that a stream fallen behind catches up rather than
        skip frames; each such result's ``fallback`` says so. None (default): never.
    faster : solver.Reconstructor, optional
        The faster member of a ``solver`` solved on this process's threads (not with a sequence).
    faster_member : str, optional
        What the faster member is, in the marks of the frames it solved (default "the faster
        member").

    Raises
    ------
    ValueError
        For ``queue_frames`` or ``solvers`` not a whole number >= 1, an empty sequence of solvers
        or ``solvers`` other than its length, or a clock neither given nor the source's.
    """

    def __init__(self, source: Source, solver, publish, *, shear_ratio: float | None = None,
                 shear_direction: float | None = None, queue_frames: int = DEFAULT_QUEUE_FRAMES,
                 solvers: int = 1, clock=None, catch_up: int | None = None, faster=None,
                 faster_member: str = "the faster member"):
        self.queue_frames = whole_number("queue_frames", queue_frames, low=1)
        self.solvers = whole_number("solvers", solvers, low=1)
        if isinstance(solver, Sequence):
            if not solver:
                raise ValueError("solver must be a solver or a sequence of one or more, got an empty one")
            if solvers not in (1, len(solver)):
                raise ValueError(f"solvers must be left out or equal the {len(solver)} solvers given, "
                                 f"got {solvers}")
            self.solvers = len(solver)
            if faster is not None:
                raise ValueError("faster goes with one solver solved on this process's threads; a sequence's "
                                 "solvers bring their own (SolverProcess(faster=...))")
            self._each = tuple(_own(each) for each in solver)
        else:
            self._each = (_own(solver, faster),) * self.solvers
        self._distinct = tuple({id(s): s for s in self._each}.values())  # a shared solver once
        self.catch_up = None if catch_up is None else whole_number("catch_up", catch_up, low=1)
        self.faster_member = faster_member
        clock = clock if clock is not None else getattr(source, "now", None)
        if not callable(clock):
            raise ValueError(f"clock must be given for a source without a now() clock, got {source!r}")
        self.source, self.solver, self.publish, self.clock = source, solver, publish, clock
        self.parameters = {"shear_ratio": shear_ratio, "shear_direction": shear_direction}
        self.last_error = ""  # why the last failed frame failed ("" when none did)
        self.solver_error = ""  # why the last solver that stopped for good did ("" when none did)
        self._ended = 0  # solver threads ended before the stream stopped (their solver could not go on)
        self._queue: deque = deque()
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)      # a frame queued, or stopping
        self._taken = 0                                    # frames taken from the queue so far
        self._turn = 0                                     # the frame (in order taken) published next
        self._solved: dict[int, tuple] = {}                # solved frames waiting for their turn, by turn
        self._publishing = False                           # a thread is publishing the solved frames in turn
        self._stopping = False
        self._threads: list[threading.Thread] = []
        self._counts = dict.fromkeys(("received", "solved", "published", "skipped", "failed", "faster"), 0)
        self._latencies: list[float] = []  # this interval's
        self._solve_times: list[float] = []  # this interval's
        self._histogram = np.zeros(len(_EDGES) + 1, np.int64)  # the whole run's latencies
        self._run_start = self._interval = self._mark()

    # -- control (the owner's thread) ----------------------------------------------------------------

    def start(self) -> None:
        """Follow the source's frames and start solving them."""
        with self._ready:
            self._run_start = self._interval = self._mark()
        self._threads = [threading.Thread(target=self._run, args=(solver,), name=f"force stream {k + 1}",
                                          daemon=True) for k, solver in enumerate(self._each)]
        for thread in self._threads:
            thread.start()
        self.source.frames_produced.connect(self._take)

    def stop(self, *, timeout: float = 5.0) -> None:
        """Stop following the source; the frames already queued are solved and published first.

        Waits at most ``timeout`` seconds for them (what is still queued then is skipped and counted).
        """
        with contextlib.suppress(ValueError):  # stopped before, or never started
            self.source.frames_produced.disconnect(self._take)
        with self._ready:
            self._stopping = True
            self._ready.notify_all()
        deadline = time.monotonic() + timeout
        for thread in self._threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        with self._ready:
            self._counts["skipped"] += len(self._queue)
            self._queue.clear()

    # -- the reader's side: never waits for the solver ------------------------------------------------

    def _take(self, frames: list[SourceFrame]) -> None:
        with self._ready:
            for frame in frames:
                if len(self._queue) >= self.queue_frames:
                    self._queue.popleft()  # the oldest waiting: the newest are what a robot acts on
                    self._counts["skipped"] += 1
                self._queue.append(frame)
            self._counts["received"] += len(frames)
            self._ready.notify(len(frames))

    # -- the solver's thread --------------------------------------------------------------------------

    def _run(self, solver) -> None:
        with one_blas_thread():  # a frame's products are small: one BLAS thread (solver.threads)
            while True:
                try:
                    # a solver process started again is ready before its thread takes frames, which
                    # would wait in it, and every frame after them for their turn to be published
                    solver.wait_ready()
                except Exception as exc:  # noqa: BLE001 (the thread ends; the others take the frames)
                    with self._lock:
                        self.solver_error = f"{type(exc).__name__}: {exc}"
                        self._ended += 1
                    return
                with self._ready:
                    while not self._queue and not self._stopping:
                        self._ready.wait()
                    if not self._queue:
                        return
                    # a solver in another process takes its share of what waits in one round trip
                    # (taking all would leave the others idle), a thread of this one frame at a time
                    behind = len(self._queue)
                    share = -(-behind // self.solvers)  # rounded up
                    frames = [self._queue.popleft() for _ in range(min(solver.batch, share))]
                    first = self._taken
                    self._taken += len(frames)
                hurry = self.catch_up is not None and behind >= self.catch_up and solver.has_faster
                self._solve(solver, frames, first, behind if hurry else 0)

    def _solve(self, solver, frames: list[SourceFrame], first: int, behind: int) -> None:
        # behind: frames that waited when these were taken, when they go to the faster member (else 0)
        started = time.perf_counter()
        try:
            answers = solver.solve_each([frame.stress for frame in frames], faster=bool(behind),
                                        **self.parameters)
        except Exception as exc:  # noqa: BLE001 (a failed round trip fails its frames; the stream goes on)
            answers = [(None, exc)] * len(frames)
        if behind:
            why = f"solved by {self.faster_member} while the stream was {behind} frames behind"
            # the faster member's own reason (a contact left out ...) kept after it
            answers = [(None if result is None else
                        replace(result, fallback="; ".join(filter(None, (why, result.fallback)))), error)
                       for result, error in answers]
        solve_time = (time.perf_counter() - started) / len(frames)
        with self._lock:
            for turn, frame, (result, error) in zip(range(first, first + len(frames)), frames, answers,
                                                    strict=True):
                self._solved[turn] = (frame, result, error, solve_time, bool(behind))
            if self._publishing:
                return  # the thread publishing takes them in their turn; this one solves the next frames
            self._publishing = True
        # Publish in order every solved frame whose turn has come. A thread that waited here for the
        # frame taken ahead of its own could not solve meanwhile: with two threads, whenever the
        # later frame was solved first, one of them stood still.
        while True:
            with self._lock:
                waiting = self._solved.pop(self._turn, None)
                if waiting is None:
                    self._publishing = False
                    return
            self._publish(*waiting)

    def _publish(self, frame: SourceFrame, result, error, solve_time: float, faster: bool) -> None:
        try:
            if error is None:
                self.publish(frame, result)
        except Exception as exc:  # noqa: BLE001 (as in _solve)
            error = exc
        latency = self.clock() - frame.t
        with self._lock:
            self._turn += 1
            if error is not None:
                self._counts["failed"] += 1
                self.last_error = f"frame {frame.index}: {type(error).__name__}: {error}"
                return
            self._counts["solved"] += 1
            self._counts["published"] += 1
            self._counts["faster"] += faster
            self._solve_times.append(solve_time)
            self._latencies.append(latency)
            self._histogram[np.searchsorted(_EDGES, latency)] += 1

    @property
    def solvers_left(self) -> int:
        """Solver threads still able to solve: all but those whose solver stopped for good
        (:attr:`solver_error` says why); at 0 every frame from then on is skipped."""
        return self.solvers - self._ended

    # -- figures (any thread) -------------------------------------------------------------------------

    def figures(self) -> StreamFigures:
        """The figures since the last call (or the start), and a new interval begins."""
        with self._ready:
            mark = self._mark()
            start, self._interval = self._interval, mark
            latencies, self._latencies = self._latencies, []
            solve_times, self._solve_times = self._solve_times, []
            waiting = len(self._queue)
        median, p99 = np.percentile(latencies, [50, 99]) if latencies else (math.nan, math.nan)
        return _figures(start, mark, waiting, float(np.median(solve_times)) if solve_times else math.nan,
                        float(median), float(p99))

    def totals(self) -> StreamFigures:
        """The figures of the whole run so far (latency percentiles to the histogram's 1.2%)."""
        with self._ready:
            mark = self._mark()
            histogram = self._histogram.copy()
            waiting = len(self._queue)
        median, p99 = _histogram_percentiles(histogram, (50, 99))
        return _figures(self._run_start, mark, waiting, math.nan, median, p99)

    def _mark(self) -> tuple:
        # (wall seconds, CPU seconds of this process and of the solvers' own, counts) at one instant;
        # counts read under the lock
        own = sum(solver.cpu_time for solver in self._distinct)
        return time.monotonic(), time.process_time() + own, dict(self._counts)


def solve_each(solver, stresses, parameters: dict) -> list:
    """``(result, None)`` for each frame ``solver.solve`` solved, ``(None, exception)`` for each it
    raised on: one bad frame must not end a stream (here, or in a solver process)."""
    answers = []
    for stress in stresses:
        try:
            answers.append((solver.solve(stress, **parameters), None))
        except Exception as exc:  # noqa: BLE001 (counted and said by the stream)
            answers.append((None, exc))
    return answers


class _InThread:
    # a solver solved on the stream's own threads, seen as the stream's solvers are (SolverProcess)
    batch = 1          # one frame a take: the other threads share the solver and take the next ones
    closed = False
    cpu_time = 0.0     # in this process's own

    def __init__(self, solver, faster=None):
        self.solver, self.faster = solver, faster

    @property
    def has_faster(self) -> bool:
        return self.faster is not None

    def wait_ready(self) -> None:
        pass

    def solve_each(self, stresses, *, faster: bool = False, **parameters) -> list:
        return solve_each(self.faster if faster and self.faster is not None else self.solver, stresses,
                          parameters)


def _own(solver, faster=None):
    # a solver of the stream's own kind (solve_each and the rest) as it is; a plain one wrapped
    return solver if hasattr(solver, "solve_each") else _InThread(solver, faster)


def _figures(start: tuple, end: tuple, waiting: int, solve_time: float, median: float,
             p99: float) -> StreamFigures:
    elapsed = end[0] - start[0]
    counts = {key: end[2][key] - start[2][key] for key in end[2]}
    rate = counts["solved"] / elapsed if elapsed > 0 else 0.0
    cpu = 100.0 * (end[1] - start[1]) / elapsed if elapsed > 0 else 0.0
    return StreamFigures(elapsed, waiting=waiting, solve_rate=rate, solve_time=solve_time,
                         latency_median=median, latency_p99=p99, cpu=cpu, **counts)


def _histogram_percentiles(histogram: np.ndarray, percents) -> tuple:
    total = int(histogram.sum())
    if not total:
        return tuple(math.nan for _ in percents)
    cumulative = np.cumsum(histogram)
    # a bin's geometric middle; the first and last bins (under 1 us, over 100 s) their edge
    middles = np.concatenate(([_EDGES[0]], np.sqrt(_EDGES[:-1] * _EDGES[1:]), [_EDGES[-1]]))
    return tuple(float(middles[np.searchsorted(cumulative, math.ceil(p / 100 * total))]) for p in percents)

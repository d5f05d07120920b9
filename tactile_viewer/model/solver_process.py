"""A solver in a process of its own, for frames solved side by side at sensor rate. No Qt.

Threads of one process share Python's GIL: the Python around a solve's compiled
calls (its decisions, the argument checks, the result's assembly, about a third
of a one-contact solve) runs on one thread at a time, and every release of the
GIL (each compiled or BLAS call, each wait) hands it over to another thread and
waits to get it back. Two solver threads on the project's 2-core machine solved
1.3 times as many frames a second as one; two processes fed from memory solve
twice as many (``docs/interop.md``). :class:`SolverProcess` is a solver for
:class:`~tactile_viewer.model.force_stream.ForceStream`: :meth:`~SolverProcess.solve_each`
sends frames' stress to a child process, which solves them with a solver of its
own, and waits (the GIL released) for their results. Frames go in batches: a
stream that has fallen behind sends what waits in one message and gets the
answers in one, so the cost of the round trip (pickling, two pipe transfers, a
process and a thread woken: about 0.13 ms of the parent's CPU and 0.15 ms of the
child's a message on the project's VM, measured) is shared by the frames when
the machine has least to spare.

The child is started with ``spawn`` (never ``fork``: the parent's reader and
LSL threads would be copied half-way through what they were doing), builds its
solver with the picklable ``build`` it is given, and solves one frame first so
that its compiled code is loaded before the first real frame comes. It ignores
Ctrl+C (the parent stops it) and ends when the parent closes its pipe or dies.
A child that ends while the stream runs (killed, out of memory) fails the
frames it held; another is started at once and counted (:attr:`restarts`), and
the next call waits for it.
"""

from __future__ import annotations

import multiprocessing
import signal
import threading
import time
from contextlib import contextmanager

import numpy as np

from solver.threads import one_blas_thread

__all__ = ["SolverProcess", "warm", "START_TIMEOUT", "BATCH_FRAMES"]

START_TIMEOUT = 120.0  # seconds a child has to import, build its solver and solve its first frame
# Most frames sent in one round trip. Only a stream that has fallen behind has more than one
# waiting; a batch of 8 one-contact frames adds about 10 ms to the first one's latency.
BATCH_FRAMES = 8
_STOPPING = (signal.SIGINT, signal.SIGTERM)


def warm(*solvers) -> None:
    """Load the solvers' compiled code (numba's cache, once for all) and touch each one's matrices:
    one solve of a round load in the middle of its skin. Without it the first frame of a stream
    would take a second, and the frames of that second would be skipped."""
    from solver.warmup import warm_up

    warm_up()
    for solver in solvers:
        grid = solver.grid
        x, y = grid.positions.T
        solver.solve(1e3 * np.exp(-((x - x.mean()) ** 2 + (y - y.mean()) ** 2) / (2 * grid.pitch ** 2)))


class SolverProcess:
    """A solver running in a child process (module notes); one caller at a time.

    What :class:`~tactile_viewer.model.force_stream.ForceStream` asks of a solver of its own:
    :meth:`solve_each`, :meth:`wait_ready`, :attr:`closed`, :attr:`cpu_time` and :attr:`batch`.

    Parameters
    ----------
    build : callable
        ``build()`` returns the solver (``solver.Reconstructor``); called in the child, so it must be
        picklable (a module-level function, or ``functools.partial`` of one with picklable arguments).
    faster : callable, optional
        As ``build``, a faster (less accurate) solver, used for the frames of a call with
        ``faster=True`` (a stream catching up); None (default): none.
    name : str, optional
        The child's name (``ps``, error messages).
    start_timeout : float, optional
        Seconds the child has to build and warm its solver (default :data:`START_TIMEOUT`).
    wait : bool, optional
        Wait here until the child is ready (default); False: :meth:`wait_ready` waits (several
        children started first, then waited for, start side by side).

    Raises
    ------
    RuntimeError
        When the child could not build its solver (its error's text), or did not say it was ready
        within ``start_timeout`` (here, or from :meth:`wait_ready`).
    OSError
        When the child could not be started (no memory, too many open files).
    """

    batch = BATCH_FRAMES  # most frames a caller sends in one round trip

    def __init__(self, build, *, faster=None, name: str = "solver process",
                 start_timeout: float = START_TIMEOUT, wait: bool = True):
        self.build, self.faster, self.name, self.start_timeout = build, faster, name, float(start_timeout)
        self.restarts = 0  # children started again after one ended
        # one caller at a time through the pipe (and starting children); re-entrant: solve_each
        # waits for readiness under it
        self._lock = threading.RLock()
        self._process = self._connection = None
        self._ready = self._closed = False
        self._cpu = (0.0, 0.0)  # CPU seconds of the children that ended, and of the running one as it said
        self._start()
        if wait:
            self.wait_ready()

    @property
    def cpu_time(self) -> float:
        """CPU seconds the children used, as of their last answer."""
        ended, running = self._cpu
        return ended + running

    @property
    def has_faster(self) -> bool:
        """Whether the child has a faster member (``faster`` given)."""
        return self.faster is not None

    @property
    def closed(self) -> bool:
        """True after :meth:`close`, or once a child could not be started or built again."""
        return self._closed

    def _start(self) -> None:
        if self._closed:
            raise RuntimeError(f"{self.name} is closed")
        context = multiprocessing.get_context("spawn")
        ours, theirs = context.Pipe()
        process = context.Process(target=_serve, args=(theirs, self.build, self.faster), name=self.name,
                                  daemon=True)
        try:
            with _quiet_signals():
                process.start()
        except BaseException:
            self._closed = True
            ours.close()
            raise
        finally:
            theirs.close()  # the child's end lives in the child: our recv sees EOF when the child ends
        self._cpu = (self.cpu_time, 0.0)
        self._process, self._connection, self._ready = process, ours, False

    def wait_ready(self) -> None:
        """Wait until the child has built and warmed its solver (at once when it has); a child that
        ended since the last call (killed while idle) is replaced first.

        Raises
        ------
        RuntimeError
            As the constructor's, or when this is closed (the child is ended first; solving after
            raises).
        OSError
            When a child could not be started again (this is closed).
        """
        with self._lock:
            process = self._process  # close() may run meanwhile on another thread: it does not wait
            if self._closed or process is None:
                raise RuntimeError(f"{self.name} is closed")
            if self._ready and not process.is_alive():  # ended while idle: before frames wait in it
                self._restart()
                process = self._process
            if self._ready:
                return
            connection = self._connection
            try:
                if not connection.poll(self.start_timeout):
                    raise RuntimeError(f"{self.name} did not build its solver within "
                                       f"{self.start_timeout:g} s")
                _, error, cpu = connection.recv()
            except EOFError:
                error = RuntimeError(f"it ended (exit code {_exit_code(process)})")
            except BaseException:
                self.close()
                raise
            if error is not None:
                self.close()
                raise RuntimeError(f"{self.name} could not build its solver: {error}")
            self._cpu = (self._cpu[0], cpu)
            self._ready = True

    def solve(self, stress, **parameters):
        """The child's solver's ``solve(stress, **parameters)``: its result, or its exception raised here.

        Raises
        ------
        RuntimeError
            As :meth:`solve_each`'s.
        """
        ((result, error),) = self.solve_each([stress], **parameters)
        if error is not None:
            raise error
        return result

    def solve_each(self, stresses, *, faster: bool = False, **parameters) -> list:
        """Each frame of ``stresses`` solved in turn by the child's solver (its faster one with
        ``faster``, when it has one): ``(result, None)`` for one solved, ``(None, exception)`` for one
        whose solve raised.

        Raises
        ------
        RuntimeError
            When the child ended before it answered (its frames fail; another child is started at
            once, and :meth:`wait_ready` or the next call waits for it), or this is closed.
        """
        with self._lock:
            self.wait_ready()
            process, connection = self._process, self._connection
            try:
                connection.send(([np.asarray(stress) for stress in stresses], parameters, faster))
                answers, cpu = connection.recv()
            except (EOFError, OSError) as exc:  # OSError: a broken pipe, or closed meanwhile
                process.join(1.0)
                ended = f"{self.name} ended while it solved (exit code {_exit_code(process)})"
                if self._closed:
                    raise RuntimeError(ended) from exc
                try:
                    self._restart()
                except Exception as failure:  # noqa: BLE001 (said with the end it followed)
                    raise RuntimeError(f"{ended}; another could not be started: {failure}") from exc
                raise RuntimeError(f"{ended}; another is started") from exc
            self._cpu = (self._cpu[0], cpu)
        return answers

    def _restart(self) -> None:
        # another child in place of one that ended, not waited for: its first caller waits
        self._connection.close()
        self._start()
        self.restarts += 1

    def close(self, *, timeout: float = 5.0) -> None:
        """End the child (asked first, killed after ``timeout`` seconds); solving after raises.

        A second call does nothing.
        """
        process, connection = self._process, self._connection
        self._closed, self._ready = True, False
        self._process = None
        if process is None:
            return
        try:
            connection.send(None)
        except OSError:  # it had ended
            pass
        process.join(timeout)
        if process.is_alive():
            process.kill()
            process.join()
        connection.close()


@contextmanager
def _quiet_signals():
    # A child is a new Python, which handles Ctrl+C and SIGTERM by dying with a traceback until it
    # reaches _serve's own handling, a second or two into its imports; sent to the terminal's or a
    # service's whole process group, they would reach it while it starts. A signal ignored when it
    # starts stays ignored in it. Signals can only be set on the main thread: a child started again
    # by a solver thread is started without this.
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {number: signal.signal(number, signal.SIG_IGN) for number in _STOPPING}
    try:
        yield
    finally:
        for number, handler in before.items():
            signal.signal(number, handler)


def _exit_code(process) -> str:
    code = process.exitcode
    if code is not None and code < 0:
        return f"signal {-code}"
    return str(code)


def _serve(connection, build, faster) -> None:
    # the child: build and warm the solvers, say so, then solve batch after batch until None or EOF
    from .force_stream import solve_each

    for number in _STOPPING:  # the parent stops us, after the frames it still wants (module notes)
        signal.signal(number, signal.SIG_IGN)
    with one_blas_thread():
        try:
            solver = build()
            fast = None if faster is None else faster()
            warm(*(s for s in (solver, fast) if s is not None))
        except Exception as exc:  # noqa: BLE001 (said to the parent, which raises it)
            _answer(connection, (None, _portable(exc), time.process_time()))
            return
        if not _answer(connection, (None, None, time.process_time())):
            return
        while True:
            try:
                message = connection.recv()
            except (EOFError, OSError):  # the parent closed its end, or ended
                return
            if message is None:
                return
            stresses, parameters, hurry = message
            used = fast if hurry and fast is not None else solver
            answers = [(result, error if error is None else _portable(error))
                       for result, error in solve_each(used, stresses, parameters)]
            if not _answer(connection, (answers, time.process_time())):
                return


def _answer(connection, message) -> bool:
    # False when the parent is gone. An answer that does not pickle (a result the solver should never
    # give) fails its frames rather than this child.
    try:
        connection.send(message)
    except (BrokenPipeError, EOFError, OSError):
        return False
    except Exception as exc:  # noqa: BLE001 (pickling: any error)
        failed = RuntimeError(f"the solver's answer could not be sent back: {type(exc).__name__}: {exc}")
        if len(message) == 3:  # the first: ready, or why not
            return _answer(connection, (None, failed, message[2]))
        answers, cpu = message
        return _answer(connection, ([(None, failed)] * len(answers), cpu))
    return True


def _portable(exc: Exception) -> Exception:
    # an exception the parent can unpickle: most are; one that is not becomes a RuntimeError with its text
    import pickle

    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:  # noqa: BLE001 (any failure to round-trip)
        return RuntimeError(f"{type(exc).__name__}: {exc}")
    return exc

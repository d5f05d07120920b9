"""Where a batch's tasks run, and how their outcomes become files. No Qt, no pyvista.

An engine takes the chunk tasks of :mod:`tactile_viewer.model.batch` and yields
one :class:`~tactile_viewer.model.batch.ChunkOutcome` per task as they finish:

- :class:`JoblibEngine`: joblib's ``loky`` processes on this machine (one
  worker: in this process, no process started);
- :class:`DaskEngine`: a Dask cluster, reached at its scheduler's address
  (:meth:`DaskEngine.connect`; its workers need this package installed and the
  recordings at the same paths) or started here (:meth:`DaskEngine.local`).
  ``dask.distributed`` is optional (``pip install 'tactile-viewer[batch]'``).

:func:`run_batch` feeds the outcomes to a :class:`BatchCollector`, which writes
each file once its last chunk is in (its contacts numbered in frame order) and
fails it at its first failed chunk; the other files go on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from solver.checks import shown, whole_number

from .batch import ChunkOutcome, FileOutcome, FilePlan, assemble_table, solve_chunk
from .batch_inputs import write_output

__all__ = ["JoblibEngine", "DaskEngine", "BatchCollector", "run_batch", "check_scheduler", "DASK_SCHEMES",
           "CONNECT_TIMEOUT"]

CONNECT_TIMEOUT = 10.0  # seconds a scheduler has to answer
DASK_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")  # the addresses a Dask scheduler listens on


class JoblibEngine:
    """Tasks on ``workers`` joblib processes (``loky``), outcomes in the order of the tasks.

    Parameters
    ----------
    workers : int
        Processes, >= 1; 1 solves in this process.
    """

    def __init__(self, workers: int):
        self.workers = whole_number("--workers", workers, low=1, unit="of processes ")

    @property
    def description(self) -> str:
        """The engine in words, for the summary."""
        if self.workers == 1:
            return "joblib, 1 worker (this process)"
        return f"joblib, {self.workers} worker processes (loky)"

    def outcomes(self, tasks):
        """Run ``tasks`` (an iterable, read as workers free up) and yield each outcome."""
        from joblib import Parallel, delayed

        parallel = Parallel(n_jobs=self.workers, backend="loky", return_as="generator", batch_size=1,
                            pre_dispatch="2*n_jobs")
        yield from parallel(delayed(solve_chunk)(task) for task in tasks)

    def close(self) -> None:
        """Nothing to release: joblib keeps its worker processes for the next run and ends them at exit."""


def check_scheduler(address) -> str:
    """``address`` when it is a Dask scheduler's address (``tcp://host:port`` ...), before connecting.

    Raises
    ------
    ValueError
        Naming ``--scheduler``, the forms accepted and what was given.
    """
    scheme, _, rest = str(address).partition("://")
    if scheme not in DASK_SCHEMES or not rest:
        raise ValueError(f"--scheduler must be 'local' or a scheduler's address "
                         f"({'|'.join(DASK_SCHEMES)}://host:port), got {shown(address)}")
    return address


class DaskEngine:
    """Tasks on a Dask cluster through a ``distributed.Client``, outcomes as they finish.

    Parameters
    ----------
    client : distributed.Client
    cluster : distributed.LocalCluster, optional
        A cluster started for this run, closed with the engine.
    """

    def __init__(self, client, cluster=None):
        self.client, self.cluster = client, cluster

    @staticmethod
    def _distributed():
        try:
            import distributed
        except ImportError as exc:
            raise ValueError("--scheduler needs dask.distributed, which is not installed: "
                             "pip install 'tactile-viewer[batch]'") from exc
        return distributed

    @classmethod
    def connect(cls, address: str, *, timeout: float | None = None) -> DaskEngine:
        """The cluster whose scheduler listens at ``address`` (``tcp://host:port``).

        ``timeout`` defaults to :data:`CONNECT_TIMEOUT` seconds.

        Raises
        ------
        ValueError
            An address of another form, or dask.distributed missing.
        OSError
            No scheduler answered within ``timeout`` seconds.
        """
        check_scheduler(address)
        distributed = cls._distributed()
        timeout = CONNECT_TIMEOUT if timeout is None else timeout
        try:
            return cls(distributed.Client(address, timeout=timeout))
        except (OSError, TimeoutError) as exc:
            raise OSError(f"--scheduler {address}: no Dask scheduler answered within {timeout:g} s ({exc})") \
                from exc

    @classmethod
    def local(cls, workers: int, *, processes: bool = True) -> DaskEngine:
        """A ``distributed.LocalCluster`` of ``workers`` single-threaded workers, started here.

        ``processes=False`` runs the workers as threads of this process (tests).
        """
        workers = whole_number("--workers", workers, low=1, unit="of processes ")
        distributed = cls._distributed()
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                                           dashboard_address=None)
        try:
            return cls(distributed.Client(cluster), cluster)
        except BaseException:
            cluster.close()
            raise

    @property
    def description(self) -> str:
        """The engine in words, for the summary."""
        info = self.client.scheduler_info()
        workers = len(info.get("workers", {}))
        where = "started here" if self.cluster is not None else f"at {info.get('address', '?')}"
        return f"Dask cluster {where}, {workers} worker{'s' if workers != 1 else ''}"

    def outcomes(self, tasks):
        """Submit every task and yield each outcome as it finishes (any order)."""
        distributed = self._distributed()
        submitted = {}
        for task in tasks:
            submitted[self.client.submit(solve_chunk, task, pure=False)] = task
        for future in distributed.as_completed(list(submitted)):
            task = submitted.pop(future)
            try:
                outcome = future.result()
            except Exception as exc:  # noqa: BLE001 (a worker lost: that chunk fails, the rest go on)
                outcome = ChunkOutcome(task, error=f"frames {task.start} to {task.stop - 1}: the Dask "
                                                   f"task failed: {type(exc).__name__}: {exc}")
            future.release()
            yield outcome

    def close(self) -> None:
        """Close the client, and the cluster if it was started here."""
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


@dataclass
class BatchCollector:
    """Gathers the outcomes of the files' chunks as they come (any order) and writes each finished file.

    :meth:`take` returns the :class:`~tactile_viewer.model.batch.FileOutcome` of
    the file when that chunk finished it (written, or failed at its first
    failed chunk), else None. A file's results are kept only until it is written.
    """

    plans: list
    done_frames: int = 0
    _parts: dict = field(default_factory=dict)
    _closed: set = field(default_factory=set)

    def __post_init__(self):
        self._by_path = {str(plan.input.path): plan for plan in self.plans}

    @property
    def total_frames(self) -> int:
        """Frames of every planned file."""
        return sum(plan.frames for plan in self.plans)

    def take(self, outcome: ChunkOutcome) -> FileOutcome | None:
        """Count a chunk's frames; write or fail its file when this was its last or a failed chunk."""
        plan = self._by_path[outcome.task.path]
        self.done_frames += outcome.task.stop - outcome.task.start
        key = str(plan.input.path)
        if key in self._closed:
            return None  # a file that already failed: its other chunks are dropped
        if outcome.error:
            self._closed.add(key)
            self._parts.pop(key, None)
            return FileOutcome(plan.input, "failed", plan.frames, outcome.error)
        parts = self._parts.setdefault(key, {})
        parts[outcome.task.start] = outcome.results
        if len(parts) < len(plan.chunks):
            return None
        del self._parts[key]
        return self._finish(plan, [result for start in sorted(parts) for result in parts[start]])

    def unfinished(self, reason: str) -> list[FileOutcome]:
        """The planned files not yet written or failed, failed with ``reason`` (the engine stopped)."""
        left = [plan for plan in self.plans if str(plan.input.path) not in self._closed]
        self._closed.update(str(plan.input.path) for plan in left)
        self._parts.clear()
        return [FileOutcome(plan.input, "failed", plan.frames, reason) for plan in left]

    def _finish(self, plan: FilePlan, results) -> FileOutcome:
        self._closed.add(str(plan.input.path))
        try:
            write_output(plan, assemble_table(plan, results))
        except (OSError, ValueError) as exc:  # ValueError: a Foxglove file's recording unreadable since
            return FileOutcome(plan.input, "failed", plan.frames,
                               f"cannot write {plan.input.output}: {getattr(exc, 'strerror', None) or exc}")
        return FileOutcome(plan.input, "written", plan.frames)


def run_batch(plans, engine, *, on_chunk=None, on_file=None) -> list[FileOutcome]:
    """Solve every planned file on ``engine`` and write each as its last chunk comes in.

    Parameters
    ----------
    plans : list of FilePlan
    engine : JoblibEngine or DaskEngine
        Anything with ``outcomes(tasks)`` and ``description``.
    on_chunk : callable, optional
        ``on_chunk(done_frames, total_frames)`` after each chunk.
    on_file : callable, optional
        ``on_file(file_outcome)`` as each file is written or fails.

    Returns
    -------
    list of FileOutcome
        One per plan, in the order they finished. When the engine itself stops
        (a worker process killed), the files not finished fail with its error.
    """
    collector = BatchCollector(list(plans))
    finished = []

    def tell(outcome: FileOutcome):
        finished.append(outcome)
        if on_file is not None:
            on_file(outcome)

    tasks = (task for plan in collector.plans for task in plan.tasks())
    try:
        for outcome in engine.outcomes(tasks):
            done = collector.take(outcome)
            if on_chunk is not None:
                on_chunk(collector.done_frames, collector.total_frames)
            if done is not None:
                tell(done)
    except Exception as exc:  # noqa: BLE001 (the engine broke: every file left is reported, none half-written)
        for outcome in collector.unfinished(f"the engine stopped ({engine.description}): "
                                            f"{type(exc).__name__}: {exc}"):
            tell(outcome)
    return finished

"""The viewer's state in plain Python: what is open, which frame, which parameters.

No Qt and no pyvista here (napari's split): the window and the scene only
follow this model's signals and set its fields. The model calls the solver; it
never draws. Given a ``dispatch`` function it schedules its own solves: every
change that alters what is shown (a frame, a live frame, the parameters, a new
solver) submits a solve to one latest-wins worker thread that owns the solver,
and the result comes back through ``dispatch`` (the Qt layer posts it to the
GUI thread) as the ``solved`` signal.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from solver import Reconstruction, Reconstructor, SensorGrid, make_solver
from solver.arrays import read_only
from solver.kernels import KERNELS

from .recording import Recording
from .worker import LatestWorker

log = logging.getLogger(__name__)

__all__ = ["Signal", "Display", "Solved", "ViewerModel", "MAX_SHEAR_RATIO", "KERNEL_HELP", "geometry_text"]

MAX_SHEAR_RATIO = 1.5  # the slider's end; the automatic search uses the same bound
MAPS = ("pressure", "stress", "none")
KERNEL_HELP = "layer: elastomer layer bonded to a rigid hull (default); cell/point: half-space"


def geometry_text(grid: SensorGrid) -> str:
    """One line naming a geometry for people: taxels, pitch, thickness, nu, taxel size.

    Examples
    --------
    >>> geometry_text(SensorGrid.regular(16, 12, 2e-3, 1.5e-3, poisson_ratio=0.45, sensor_size=1e-3))
    '16x12 taxels, pitch 2 mm, thickness 1.5 mm, nu 0.45, taxel 1 mm'
    """
    taxels = f"{grid.shape[1]}x{grid.shape[0]} taxels" if len(grid.shape) == 2 else f"{grid.size} taxels"
    size = f"taxel {grid.sensor_size * 1e3:g} mm" if grid.sensor_size > 0 else "point sensors"
    return (f"{taxels}, pitch {grid.pitch * 1e3:g} mm, thickness {grid.thickness * 1e3:g} mm, "
            f"nu {grid.poisson_ratio:g}, {size}")


class Signal:
    """A minimal callback list: ``connect(fn)``, ``disconnect(fn)``, ``emit(*args)``."""

    def __init__(self):
        self._slots = []

    def connect(self, slot):
        self._slots.append(slot)

    def disconnect(self, slot):
        self._slots.remove(slot)

    def emit(self, *args):
        for slot in list(self._slots):
            slot(*args)


@dataclass(frozen=True)
class Display:
    """What the scene shows.

    Attributes
    ----------
    map : {"pressure", "stress", "none"}
        Reconstructed normal pressure (``Fz / pitch^2``) or measured sensor stress.
    arrows, resultant : bool
        Per-node force arrows; the resultant at the contact centroid.
    arrow_scale : float
        Arrow length per newton, metres per newton.
    resultant_scale : float
        Length of the resultant's arrow per newton, metres per newton.
    threshold : float
        Arrows of nodes with ``|F|`` below this many newtons are hidden.
    auto_range : bool
        Colour range follows each frame; otherwise ``0 .. range_max``.
    range_max : float
        Upper end of the fixed colour range, pascals.
    """

    map: str = "pressure"
    arrows: bool = True
    resultant: bool = True
    arrow_scale: float = 0.01
    resultant_scale: float = 0.01
    threshold: float = 0.0
    auto_range: bool = True
    range_max: float = 50e3

    def __post_init__(self):
        if self.map not in MAPS:
            raise ValueError(f"map must be one of {MAPS}, got {self.map!r}")
        for name in ("arrow_scale", "resultant_scale", "threshold", "range_max"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True)
class Solved:
    """One reconstructed frame, how it was made, and what the scene shows of it.

    ``frame`` is the index in the recording, or for a live source the frame's
    sequence number (-1 for text frames, which carry none); ``time`` seconds.
    The scene draws these fields and computes no physics itself.

    Attributes
    ----------
    pressure : (m,) ndarray
        Reconstructed normal pressure ``Fz / pitch^2``, pascals.
    centroid : (2,) ndarray or None
        Where the compressive normal load is centred, metres (None when
        nothing presses).
    """

    frame: int
    time: float
    stress: np.ndarray
    result: Reconstruction
    solve_ms: float
    auto: bool
    pressure: np.ndarray
    centroid: np.ndarray | None

    @classmethod
    def of(cls, grid: SensorGrid, stress, result: Reconstruction, *, frame: int = 0, time: float = 0.0,
           solve_ms: float = 0.0, auto: bool = True) -> Solved:
        """A solved frame of ``grid`` with its pressure map and load centroid."""
        forces = result.forces
        push = np.clip(forces[:, 2], 0.0, None)
        centroid = grid.positions.T @ push / push.sum() if push.sum() > 0 else None
        return cls(frame, time, np.asarray(stress, dtype=float), result, solve_ms, auto,
                   read_only(forces[:, 2] / grid.pitch**2), None if centroid is None else read_only(centroid))


@dataclass(frozen=True)
class _Job:
    # one solve as the model stood when it was asked for
    generation: int
    solver: object
    frame: int
    time: float
    stress: np.ndarray
    auto: bool
    shear_ratio: float
    shear_direction: float


class ViewerModel:
    """State of one viewer window.

    Signals
    -------
    recording_changed()
        A recording (and its reconstructor) was installed.
    frame_changed(int)
    parameters_changed()
        Auto flag, shear ratio, shear direction or kernel changed.
    display_changed()
    solved(Solved)
        A frame was reconstructed.
    solve_failed(str)
        A solve raised; the message (the error is logged with its traceback).

    Parameters
    ----------
    dispatch : callable, optional
        ``dispatch(fn)`` runs ``fn()`` on the thread that owns the model. Given,
        the model solves on its own worker thread whenever what is shown
        changes; None (the default: command line, tests), it solves only
        when :meth:`solve` is called.
    settle : float, optional
        Seconds a change waits for its own solve before returning (with
        ``dispatch``). Default 0. A window passes a few hundredths: a fast
        solve is then posted before the window repaints, so the control that
        asked for it and the new frame reach the screen in one repaint
        instead of two, while a slow solve still leaves the window free.
    """

    def __init__(self, *, dispatch=None, settle: float = 0.0):
        self.recording: Recording | None = None
        self.live = False  # showing a live source instead of a recording
        self.live_frame = None
        self.live_label = ""
        self.path: Path | None = None
        self.reconstructor: Reconstructor | None = None
        self.kernel = KERNELS[0]  # the solver lists its default first
        self.configuration = None  # a solver.tradeoff.Configuration (quality preset), None: standard
        self.frame = 0
        self.auto = True
        self.shear_ratio = 0.0
        self.shear_direction = 0.0  # radians
        self.display = Display()
        self.last: Solved | None = None
        self.recording_changed = Signal()
        self.frame_changed = Signal()
        self.parameters_changed = Signal()
        self.display_changed = Signal()
        self.solved = Signal()
        self.solve_failed = Signal()
        self._dispatch = dispatch
        self.settle = float(settle)
        self._generation = 0  # grows with each installed solver: results of older ones are dropped
        self._closed = False
        self._worker = None if dispatch is None else LatestWorker(self._work, name="tactile-solver")

    # -- building -----------------------------------------------------------------

    @staticmethod
    def build(grid: SensorGrid, kernel: str, configuration=None):
        """The solver for a geometry (slow for large grids: run it off the GUI thread).

        ``configuration`` is a :class:`solver.tradeoff.Configuration` (a quality
        preset); None is the standard exact solve. Its kernel is replaced by ``kernel``.
        """
        if configuration is None:
            # solver.make_solver: dense up to 32x32, contact by contact beyond
            return make_solver(grid, kernel=kernel, max_shear_ratio=MAX_SHEAR_RATIO)
        return replace(configuration, kernel=kernel).build(grid)

    @property
    def is_open(self) -> bool:
        """A recording or a live source is shown."""
        return self.recording is not None or self.live

    @property
    def grid(self) -> SensorGrid | None:
        """The geometry shown (the solver's), None when nothing is open."""
        return self.reconstructor.grid if self.is_open else None

    def install_live(self, reconstructor: Reconstructor, label: str):
        """Show a live source on ``reconstructor.grid``; frames come through :meth:`show_live`."""
        self.recording, self.path, self.live, self.live_label = None, None, True, label
        self.live_frame = None
        self.reconstructor = reconstructor
        self.kernel = reconstructor.kernel
        self.frame = 0
        self.last = None
        # nominal arrow lengths until the user sets them: 50 mN per node spans
        # three pitches, a 1 N total a third of the skin
        grid = reconstructor.grid
        width = float(np.ptp(grid.positions[:, 0])) + grid.pitch
        self.display = replace(self.display, arrow_scale=3 * grid.pitch / 0.05, resultant_scale=width / 3)
        self._generation += 1
        self.recording_changed.emit()
        self.display_changed.emit()

    def show_live(self, frame):
        """The newest live frame (a :class:`~tactile_viewer.live_source.LiveFrame`); solve to show it."""
        if not self.live:
            raise RuntimeError("show_live needs install_live first")
        if frame.stress.shape != (self.reconstructor.grid.size,):
            raise ValueError(f"live frame must have {self.reconstructor.grid.size} values, "
                             f"got shape {frame.stress.shape}")
        self.live_frame = frame
        self._schedule()

    def install(self, recording: Recording, reconstructor: Reconstructor, path=None):
        """Show a recording with its ready reconstructor; starts at frame 0.

        Raises
        ------
        ValueError
            When the reconstructor was built for another geometry: other
            positions, thickness, pitch, Poisson ratio or taxel size (the
            layer kernel's matrix depends on all of them).
        """
        if reconstructor.grid.key != recording.grid.key:
            raise ValueError("reconstructor was built for another geometry than the recording's")
        self.recording = recording
        self.live, self.live_frame, self.live_label = False, None, ""
        self.reconstructor = reconstructor
        self.kernel = reconstructor.kernel
        self.path = Path(path) if path is not None else None
        self.frame = 0
        self.last = None
        # readable default arrow lengths: on the recording's most loaded frame the
        # largest node force spans about three pitches, the total a third of the skin
        loaded = int(np.argmax(np.abs(recording.frames).sum(axis=1)))
        first = reconstructor.solve_normal(recording.frames[loaded]).forces[:, 2]
        peak = float(np.abs(first).max()) or 1.0
        total = abs(float(first.sum())) or peak
        width = float(np.ptp(recording.grid.positions[:, 0])) + recording.grid.pitch
        self.display = replace(self.display, arrow_scale=3 * recording.grid.pitch / peak,
                               resultant_scale=width / 3 / total,
                               range_max=max(float(np.abs(recording.frames).max()),
                                             peak / recording.grid.pitch**2, 1.0))
        self._generation += 1
        self.recording_changed.emit()
        self.display_changed.emit()
        self._schedule()

    # -- state changes ---------------------------------------------------------------

    def set_frame(self, index: int):
        if self.recording is None:
            return
        index = int(index)
        if not 0 <= index < len(self.recording):
            raise ValueError(f"frame must be in [0, {len(self.recording) - 1}], got {index}")
        if index != self.frame:
            self.frame = index
            self.frame_changed.emit(index)
            self._schedule()

    def set_auto(self, auto: bool):
        if bool(auto) != self.auto:
            self.auto = bool(auto)
            self.parameters_changed.emit()
            self._schedule()

    def set_parameters(self, *, shear_ratio: float | None = None, shear_direction: float | None = None):
        """Manual parameters (a slider was touched): switches Auto off.

        Both values are checked before either is stored; ``parameters_changed``
        fires only when something changed.
        """
        ratio, direction = self.shear_ratio, self.shear_direction
        if shear_ratio is not None:
            if not (math.isfinite(shear_ratio) and 0 <= shear_ratio <= MAX_SHEAR_RATIO):
                raise ValueError(f"shear_ratio must be in [0, {MAX_SHEAR_RATIO}], got {shear_ratio!r}")
            ratio = float(shear_ratio)
        if shear_direction is not None:
            if not math.isfinite(shear_direction):
                raise ValueError(f"shear_direction must be finite radians, got {shear_direction!r}")
            direction = math.remainder(float(shear_direction), 2 * math.pi)
        if (ratio, direction, False) != (self.shear_ratio, self.shear_direction, self.auto):
            self.shear_ratio, self.shear_direction, self.auto = ratio, direction, False
            self.parameters_changed.emit()
            self._schedule()

    def set_display(self, **changes):
        display = replace(self.display, **changes)
        if display != self.display:
            self.display = display
            self.display_changed.emit()

    def describe(self) -> dict:
        """What the last solve shows, for screenshot sidecars.

        Besides the frame and the parameters it names the material the forces
        were solved with: ``poisson_ratio`` and ``sensor_size`` (metres).
        """
        last = self.last
        r = last.result
        grid = self.reconstructor.grid
        source = self.live_label if self.live else (str(self.path) if self.path else None)
        return dict(recording=source, frame=last.frame, t=last.time,
                    kernel=self.kernel, poisson_ratio=grid.poisson_ratio, sensor_size=grid.sensor_size,
                    mode="auto" if last.auto else "manual",
                    shear_ratio=r.shear_ratio, shear_direction_deg=math.degrees(r.shear_direction),
                    efficiency=r.efficiency, residual=r.residual, condition=r.condition,
                    display=dict(self.display.__dict__))

    # -- the work ------------------------------------------------------------------------

    def _job(self) -> _Job | None:
        if self.live:
            if self.live_frame is None:
                return None
            stress, time_s = self.live_frame.stress, self.live_frame.t
            index = self.live_frame.seq if self.live_frame.seq is not None else -1
        elif self.recording is not None:
            stress, index = self.recording.frames[self.frame], self.frame
            time_s = float(self.recording.t[self.frame])
        else:
            return None
        return _Job(self._generation, self.reconstructor, index, time_s, stress, self.auto,
                    self.shear_ratio, self.shear_direction)

    @staticmethod
    def _compute(job: _Job) -> Solved:
        start = time.perf_counter()
        if job.auto:
            result = job.solver.solve(job.stress)
        else:
            result = job.solver.solve(job.stress, shear_ratio=job.shear_ratio,
                                      shear_direction=job.shear_direction)
        elapsed = 1e3 * (time.perf_counter() - start)
        return Solved.of(job.solver.grid, job.stress, result, frame=job.frame, time=job.time,
                         solve_ms=elapsed, auto=job.auto)

    def solve(self) -> Solved | None:
        """Reconstruct the current frame with the current parameters, here and now, and announce it.

        In Auto mode the parameters found are in the result; the manual
        values (``shear_ratio``, ``shear_direction``) stay the user's.
        """
        job = self._job()
        if job is None:
            return None
        self.last = self._compute(job)
        self.solved.emit(self.last)
        return self.last

    def _schedule(self):
        # what is shown changed: solve it on the worker (newest request wins)
        if self._worker is None or self._closed:
            return
        job = self._job()
        if job is not None:
            self._worker.submit(job)
            if self.settle > 0:
                self._worker.wait_idle(self.settle)

    def _work(self, job: _Job):
        # on the worker thread: solve, then hand the outcome to the model's own thread
        try:
            solved = self._compute(job)
        except Exception as exc:
            log.exception("solve of frame %s failed", job.frame)
            message = f"solve of frame {job.frame} failed: {exc}"
            if not self._closed:
                self._dispatch(lambda: self._failed(job, message))
            return
        if not self._closed:  # after close the dispatcher (a Qt object) may be gone
            self._dispatch(lambda: self._deliver(job, solved))

    def _deliver(self, job: _Job, solved: Solved):
        if job.generation != self._generation:
            return  # solved with a solver that has been replaced since
        self.last = solved
        self.solved.emit(solved)

    def _failed(self, job: _Job, message: str):
        if job.generation == self._generation:
            self.solve_failed.emit(message)

    def worker_stats(self) -> dict:
        """Solves the worker ran (``done``) and requests it dropped for a newer one (``dropped``)."""
        worker = self._worker
        return dict(done=worker.done if worker else 0, dropped=worker.dropped if worker else 0)

    @property
    def solving(self) -> bool:
        """A scheduled solve is waiting or running."""
        return self._worker is not None and self._worker.busy

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until the worker has nothing waiting or running (True at once without a worker)."""
        return self._worker is None or self._worker.wait_idle(timeout)

    def close(self):
        """End the worker thread (the running solve finishes; its result is dropped).

        Changes after this are kept but solve nothing.
        """
        self._closed = True
        self._generation += 1
        if self._worker is not None:
            self._worker.close()

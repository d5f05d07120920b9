"""The viewer's state in plain Python: which source, which frame, which parameters.

No Qt and no pyvista here (napari's split): the window and the scene only
follow this model's signals and set its fields. The model follows its
:class:`~tactile_viewer.sources.source.Source` (a recording or a live board), calls the
solver and never draws. Given a ``dispatch`` function it schedules its own
solves: every change that alters what is shown (a frame the source produced,
the parameters, a new solver) submits a solve to one latest-wins worker thread
that owns the solver, and the result comes back through ``dispatch`` (the Qt
layer posts it to the GUI thread) as the ``solved`` signal.

Contacts followed over time: the model owns a :class:`solver.ContactTracker`
per source and numbers the contacts of each result as it is delivered, in the
order the frames are shown (``Contact.identity``, from 1, in ``Solved.result``).
A live source's frames only move on: every frame continues the tracks. A
recording's continue while playback (or a step or a seek) moves forward; the
frames it skipped (playback drops frames when drawing is slower than the
recording, and at 2x) count as frames in which the contacts not seen were
missing (``ContactTracker.update``'s ``frames``), so a jump further than the
tracker's ``patience`` ends the lost tracks but keeps the numbers of the
contacts still there. A seek backwards starts the numbers again at that frame
(the tracker is reset). The same frame solved again (new parameters, a re-tare)
is matched again from the tracks as they stood before it, so the numbers do not
drift. A new source or solver (another kernel or quality) starts from 1.
Played from its start, a recording is numbered as the whole-recording force
export and ``--report`` number it (the same tracker over the same frames; the
frames playback skipped can only matter where contacts merge or split). After
a seek the window numbers from that frame and the exports keep theirs.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from solver import ContactTracker, Reconstruction, Reconstructor, SensorGrid
from solver.arguments import MAX_STRESS
from solver.arrays import read_only
from solver.checks import one_of
from solver.kernels import KERNELS

from ..io.recording import Recording, Tare
from ..sources.source import RecordingSource, Signal, Source, SourceFrame
from .worker import LatestWorker

log = logging.getLogger(__name__)

__all__ = ["Display", "Solved", "ViewerModel", "MAX_SHEAR_RATIO", "KERNEL_HELP", "geometry_text",
           "load_centroid"]

# the map's fixed colour range over the most loaded frame's normal-only peak pressure (_display_scales)
RANGE_MARGIN = 1.75
MAX_SHEAR_RATIO = 1.5  # the slider's end; the automatic search uses the same bound
MAX_SMOOTHING = 10.0  # seconds: past any contact a lab follows
MAPS = ("pressure", "stress", "none")
HIDE_BELOW = 0.02  # default "hide below": this fraction of the largest node force of a new source

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


@dataclass(frozen=True)
class Display:
    """What the scene shows.

    Attributes
    ----------
    map : {"pressure", "stress", "none"}
        Reconstructed normal pressure (``Fz / pitch^2``) or measured sensor stress.
    arrows, resultant : bool
        Per-node force arrows; the resultants (one per contact, at its own
        load centroid; one for the whole frame when the solve found no contacts).
    arrow_scale : float
        Arrow length per newton, metres per newton.
    resultant_scale : float
        Length of the resultant's arrow per newton, metres per newton.
    threshold : float
        Arrows of nodes with ``|F|`` below this many newtons are hidden
        (``|(Fx, Fy)|`` for in-plane arrows).
    auto_range : bool
        Colour range follows each frame; otherwise ``0 .. range_max``.
    range_max : float
        Upper end of the fixed colour range, pascals.
    colormap : str
        Colour map of the pressure or stress map, one of :attr:`COLORMAPS`
        (perceptually uniform, and ``gray`` for print).
    arrow_auto_range : bool
        The arrows' colour range follows each frame (``0 ..`` its largest shown
        force); otherwise ``0 .. arrow_range_max``, the same for every frame.
    arrow_range_max : float
        Upper end of the arrows' fixed colour range, newtons.
    in_plane : bool
        Arrows (and resultants) show only ``(Fx, Fy)``, flat on the surface:
        the Top view's shear picture. The Top camera button switches it on,
        the Iso button off.
    in_plane_gain : float
        In-plane arrows and resultants are drawn this many times longer than
        3-D ones (shear is a fraction of the normal force); the scales the
        scene states include it. Positive.
    axes : bool
        x and y ticks in millimetres beside the skin and the direction
        convention (0 deg = +x, 90 deg = +y) at its corner.
    taxel_ids : bool
        Each taxel's node index (from 0, as everywhere) on its square.
    smoothing : float
        Time constant, seconds, of the exponential smoothing of the node
        forces drawn (arrows and pressure map) over frame time; 0 is off
        (the default). Smoothed forces lag the data by about this much and a
        step reaches 63% of its height after it. Never applied to exports,
        the read-out, the contacts or the status line.
    """

    COLORMAPS: ClassVar[tuple] = ("viridis", "cividis", "plasma", "inferno", "magma", "gray")

    map: str = "pressure"
    arrows: bool = True
    resultant: bool = True
    arrow_scale: float = 0.01
    resultant_scale: float = 0.01
    threshold: float = 0.0
    auto_range: bool = True
    range_max: float = 50e3
    colormap: str = "viridis"
    arrow_auto_range: bool = True
    arrow_range_max: float = 0.05
    in_plane: bool = False
    in_plane_gain: float = 2.0
    axes: bool = True
    taxel_ids: bool = False
    smoothing: float = 0.0

    CAMERAS: ClassVar[tuple] = ("top", "iso")

    def seen_from(self, camera: str) -> Display:
        """This display as a camera preset shows it: from ``"top"`` the arrows lie flat
        (``in_plane``: the shear alone), from ``"iso"`` they stand in 3-D.

        The one place of this rule: the window's camera buttons and menu, the
        headless screenshot and the movie all follow it.
        """
        one_of("camera", camera, self.CAMERAS)
        return replace(self, in_plane=camera == "top")

    def __post_init__(self):
        one_of("map", self.map, MAPS)
        one_of("colormap", self.colormap, self.COLORMAPS)
        for name in ("arrow_scale", "resultant_scale", "threshold", "range_max", "arrow_range_max",
                     "smoothing"):
            value = getattr(self, name)
            # bool is a number to Python, but never a scale a caller meant
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if self.smoothing > MAX_SMOOTHING:
            raise ValueError(f"smoothing must be at most {MAX_SMOOTHING:g} s, got {self.smoothing!r}")
        if not (isinstance(self.in_plane_gain, (int, float, np.integer, np.floating))
                and not isinstance(self.in_plane_gain, bool)
                and math.isfinite(self.in_plane_gain) and self.in_plane_gain > 0):
            raise ValueError(f"in_plane_gain must be finite and > 0, got {self.in_plane_gain!r}")
        for name in ("arrows", "resultant", "auto_range", "arrow_auto_range", "in_plane", "axes",
                     "taxel_ids"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {value!r}")


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
    contact_centroids : tuple of (2,) ndarray
        Each contact's :attr:`solver.Contact.centre` (the solver's formula:
        its load's centre, its nodes' middle when nothing of it presses),
        metres, in the order of ``result.contacts``.
    drawn_forces : (m, 3) ndarray or None
        The node forces the scene draws, newtons, when they differ from
        ``result.forces`` (smoothed over time: :class:`ForceSmoothing`);
        ``pressure`` is then theirs too.

    The contacts of a result the model delivers carry their identities
    (``result.contacts[k].identity``, from 1: module notes); ``Solved.of``
    alone leaves them as the solver gave them.
    """

    frame: int
    time: float
    stress: np.ndarray
    result: Reconstruction
    solve_ms: float
    auto: bool
    pressure: np.ndarray
    centroid: np.ndarray | None
    contact_centroids: tuple = ()
    drawn_forces: np.ndarray | None = None

    @property
    def forces_drawn(self) -> np.ndarray:
        """``(m, 3)`` node forces as drawn: :attr:`drawn_forces`, else the result's."""
        return self.result.forces if self.drawn_forces is None else self.drawn_forces

    @classmethod
    def of(cls, grid: SensorGrid, stress, result: Reconstruction, *, frame: int = 0, time: float = 0.0,
           solve_ms: float = 0.0, auto: bool = True) -> Solved:
        """A solved frame of ``grid`` with its pressure map and load centroids."""
        forces = result.forces
        return cls(frame, time, np.asarray(stress, dtype=float), result, solve_ms, auto,
                   read_only(forces[:, 2] / grid.pitch**2), load_centroid(grid.positions, forces[:, 2]),
                   tuple(read_only(c.centre) for c in result.contacts))


class ForceSmoothing:
    """Exponential smoothing of the node forces drawn, over the frames' time. Qt-free.

    Each frame moves the drawn forces ``d`` towards the solved ones ``f`` by
    ``d += (1 - exp(-dt / tau)) * (f - d)``, ``dt`` the time since the frame
    before, so frames skipped by playback count by their time. A frame
    solved again (other parameters) is smoothed from where its first solve
    started; a frame before the last (a seek back) starts afresh.
    """

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self._key = self._time = self._base = self._value = None
        self._alpha = 1.0

    def __call__(self, solved: Solved, time_constant: float, pitch: float) -> Solved:
        """``solved`` with its drawn forces and pressure smoothed over ``time_constant`` s (0: itself)."""
        if time_constant <= 0:
            self.reset()
            return solved
        forces = solved.result.forces
        key = (solved.frame, solved.time)
        if key == self._key and self._base.shape == forces.shape:
            base, alpha = self._base, self._alpha  # the same frame solved again
        elif self._value is None or self._value.shape != forces.shape or solved.time < self._time:
            base, alpha = forces, 1.0  # nothing before it to smooth with
        else:
            base, alpha = self._value, -math.expm1(-(solved.time - self._time) / time_constant)
        value = read_only(base + alpha * (forces - base))
        self._key, self._time, self._base, self._alpha, self._value = key, solved.time, base, alpha, value
        return replace(solved, drawn_forces=value, pressure=read_only(value[:, 2] / pitch**2))


def load_centroid(positions, fz) -> np.ndarray | None:
    """Where a normal load presses, centred: the ``Fz``-weighted mean of ``positions`` over ``Fz > 0``.

    Parameters
    ----------
    positions : (m, 2) ndarray
        Node positions, metres.
    fz : (m,) ndarray
        Normal force per node, newtons (tension, ``Fz < 0``, is left out).

    Returns
    -------
    (2,) ndarray or None
        Read-only, metres; None when nothing presses.
    """
    push = np.clip(np.asarray(fz, dtype=float), 0.0, None)
    total = push.sum()
    return read_only(np.asarray(positions, dtype=float).T @ push / total) if total > 0 else None


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
        A source (and its reconstructor) was installed.
    frame_changed(int)
        The recording moved to another frame.
    parameters_changed()
        Auto flag, shear ratio, shear direction or kernel changed.
    display_changed()
    solved(Solved)
        A frame was reconstructed.
    solve_failed(str)
        A solve raised; the message (the error is logged with its traceback).
    message(str, str, str)
        A source's news for people: ``(level, title, text)``, level "info" or
        "error" (a recording saved, a recording that could not be completed).

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
    pace : bool, optional
        Frames a live source pushes are taken only once the last result is
        on screen (the window calls :meth:`shown`): a solve that could never
        be drawn is not run. Default False.
    """

    def __init__(self, *, dispatch=None, settle: float = 0.0, pace: bool = False):
        self.source: Source | None = None
        self.current: SourceFrame | None = None  # the frame being shown
        self.reconstructor: Reconstructor | None = None
        self.kernel = KERNELS[0]  # the solver lists its default first
        self.configuration = None  # a solver.quality.Configuration (quality preset), None: standard
        self.auto = True
        self.shear_ratio = 0.0
        self.shear_direction = 0.0  # radians
        self.display = Display()
        self.last: Solved | None = None  # the frame solved last, as solved (exports, read-out)
        self.drawn: Solved | None = None  # the same as the scene draws it (display.smoothing)
        self._smoothing = ForceSmoothing()
        self.recording_changed = Signal()
        self.frame_changed = Signal()
        self.parameters_changed = Signal()
        self.display_changed = Signal()
        self.solved = Signal()
        self.solve_failed = Signal()
        self.message = Signal()
        self._dispatch = dispatch
        self.settle = float(settle)
        self.pace = bool(pace)
        self._owner = threading.get_ident()
        self._unshown = False  # a pushed frame's result is not on screen yet
        self._waiting = False  # a pushed frame arrived meanwhile
        self._generation = 0  # grows with each installed solver: results of older ones are dropped
        self._closed = False
        self._worker = None if dispatch is None else LatestWorker(self._work, name="tactile-solver")
        self._tracker: ContactTracker | None = None  # numbers the contacts of the source's frames
        self._tracked = None  # (frame, time) last numbered, the tracker before it, frames elapsed

    # -- building -----------------------------------------------------------------

    @staticmethod
    def build(grid: SensorGrid, kernel: str, configuration=None):
        """The solver for a geometry (slow for large grids: run it off the GUI thread).

        ``configuration`` is a :class:`solver.quality.Configuration` (a quality
        preset) whose kernel is replaced by ``kernel``; None is the standard
        solve (:class:`solver.Reconstructor`: dense up to 32x32, contact by
        contact beyond).
        """
        return Reconstructor(grid, kernel=kernel, max_shear_ratio=MAX_SHEAR_RATIO, quality=configuration)

    # -- what is shown ---------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        """A source is shown."""
        return self.source is not None

    @property
    def live(self) -> bool:
        """The source is live (frames pushed at its own pace)."""
        return self.source is not None and self.source.live

    @property
    def recording(self) -> Recording | None:
        """The recording shown, None for a live source or nothing."""
        return self.source.recording if isinstance(self.source, RecordingSource) else None

    @property
    def path(self) -> Path | None:
        """The file of the recording shown, if it came from one."""
        return self.source.path if isinstance(self.source, RecordingSource) else None

    @property
    def frame(self) -> int:
        """The recording's frame shown (0 for a live source)."""
        return self.source.position if isinstance(self.source, RecordingSource) else 0

    @property
    def grid(self) -> SensorGrid | None:
        """The geometry shown (the solver's), None when nothing is open."""
        return self.reconstructor.grid if self.is_open else None

    def set_source(self, source: Source, reconstructor: Reconstructor):
        """Show ``source`` with its ready reconstructor.

        A recording starts at frame 0; a live source shows its next frame. A
        different source replaces the one shown, which is stopped (its
        recording closed). Installing the same source again (another kernel or
        quality) keeps its frame.

        Raises
        ------
        ValueError
            When the reconstructor was built for another geometry: other
            positions, thickness, pitch, Poisson ratio or taxel size (the
            layer kernel's matrix depends on all of them).
        """
        if reconstructor.grid.key != source.grid.key:
            raise ValueError("reconstructor was built for another geometry than the source's")
        old, same = self.source, source is self.source
        # all or nothing: what can fail comes before the source shown is stopped (a failure after
        # it left the window without a source and every later open failing)
        scales = None if same else _display_scales(source, reconstructor)
        if old is not None and not same:
            old.frame_arrived.disconnect(self._frame_arrived)
            self._stop(old)  # its last news (a recording saved) still reaches the user
            old.message.disconnect(self._source_message)
        self.source = source
        self.reconstructor = reconstructor
        self.kernel = reconstructor.kernel
        self.last = self.drawn = None
        self._smoothing.reset()
        self._tracker, self._tracked = ContactTracker(reconstructor.grid), None  # numbers from 1 again
        self._unshown = self._waiting = False
        if not same:
            self.current = None
            self.display = replace(self.display, **scales)
            source.frame_arrived.connect(self._frame_arrived)
            source.message.connect(self._source_message)
        self._generation += 1
        self.recording_changed.emit()
        self.display_changed.emit()
        if isinstance(source, RecordingSource):
            source.seek(source.position if same else 0)
        elif not self._take() and same:
            self._schedule()  # a quiet board: its last frame again, with the new solver

    def retare(self, how: str, *, frames: int = 50) -> str:
        """Change the tare of the recording shown (its file keeps the raw values and is not changed).

        Parameters
        ----------
        how : {"here", "clear", "recorded"}
            ``"here"``: the baseline is the mean of ``frames`` frames from the
            current one on, applied to every frame; ``"clear"``: no tare;
            ``"recorded"``: the tares taken while recording.
        frames : int
            Frames averaged by ``"here"``.

        Returns
        -------
        str
            What was done, for the status line.

        Raises
        ------
        ValueError
            When no recording with raw values (MCAP) is shown, or for an unknown ``how``.
        """
        source = self.source
        if not isinstance(source, RecordingSource) or source.recording.calibration is None:
            raise ValueError("only a recording that keeps raw values (a live recording, .mcap) can be "
                             "re-tared")
        if how not in ("here", "clear", "recorded"):
            raise ValueError(f"how must be 'here', 'clear' or 'recorded', got {how!r}")
        if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
            raise ValueError(f"frames must be a positive integer, got {frames!r}")
        calibration = source.recording.calibration
        if how == "recorded":
            calibration = source.loaded_calibration
            text = f"the tares taken while recording ({len(calibration.tares)})"
        elif how == "clear":
            calibration = calibration.retared(None)
            text = "no tare"
        else:
            rows = np.arange(source.position, min(source.position + frames, len(source)))
            untared = calibration.retared(None).apply(source.recording.frames.raw(rows), rows)
            taken = float(source.recording.t[rows[0]])
            calibration = calibration.retared(Tare(0, untared.mean(axis=0), taken, len(rows)))
            text = f"tare from frames {rows[0]} to {rows[-1]}"
        source.recalibrate(calibration)
        # the scales follow the stresses now shown (cleared, a tare's offsets are load: the resultant
        # kept the scale of the tared frames and was drawn 50 mm long)
        self.set_display(**_display_scales(source, self.reconstructor))
        return text

    def _stop(self, source: Source):
        try:
            source.stop()
        except Exception as exc:  # a source that fails to stop must not keep the next from showing
            log.exception("stopping %s failed", source.label)
            self.message.emit("error", "Source did not stop cleanly", f"{source.label}: {exc}")

    def _here(self) -> bool:
        # on the model's own thread, or with no other to hand work to
        return self._dispatch is None or threading.get_ident() == self._owner

    def _source_message(self, level: str, title: str, text: str):
        if self._here():
            self.message.emit(level, title, text)
        elif not self._closed:
            self._dispatch(lambda: self.message.emit(level, title, text))

    def _frame_arrived(self):
        # a source produced a frame: on our thread (a recording seeks) take it now; from a
        # reader thread hand it over, then take the newest once the last result is shown
        if self._here():
            self._take()
        elif not self._closed:
            self._dispatch(self._take_pushed)

    def _take_pushed(self):
        if self._unshown:
            self._waiting = True
            return
        self._take()

    def _take(self) -> bool:
        # the source's newest frame becomes the one shown; False when none waits
        source = self.source
        frame = source.take_latest() if source is not None else None
        if frame is None:
            return False
        previous, self.current = self.current, frame
        if previous is not None and frame.index != previous.index and isinstance(source, RecordingSource):
            self.frame_changed.emit(frame.index)
        self._schedule()
        return True

    def shown(self):
        """The last result is on screen: a live frame that waited is taken now (with ``pace``)."""
        self._unshown = False
        if self._waiting:
            self._waiting = False
            self._take()

    # -- state changes ---------------------------------------------------------------

    def set_frame(self, index: int):
        """Show frame ``index`` of the recording (nothing for a live source); playback goes on from it."""
        source = self.source
        if not isinstance(source, RecordingSource):
            return
        if int(index) != source.position:
            source.seek(index, now=time.perf_counter())

    def set_auto(self, auto: bool):
        """Automatic parameters on or off. Leaving Auto starts from what it found on the frame shown
        (not from manual values set long before: unticking Auto made the shear of a contact drop
        from 401 to 3 mN)."""
        if bool(auto) != self.auto:
            if not auto:
                self.shear_ratio, self.shear_direction = self._found()
            self.auto = bool(auto)
            self.parameters_changed.emit()
            self._schedule()

    def _found(self) -> tuple[float, float]:
        # the parameters Auto shows (those of the frame's largest contact), or the manual ones
        last = self.last
        if not (self.auto and last is not None and last.auto):
            return self.shear_ratio, self.shear_direction
        return (min(float(last.result.shear_ratio), MAX_SHEAR_RATIO),
                math.remainder(float(last.result.shear_direction), 2 * math.pi))

    def set_parameters(self, *, shear_ratio: float | None = None, shear_direction: float | None = None):
        """Manual parameters (a slider was touched): switches Auto off.

        A parameter not given keeps its manual value, or, when this leaves
        Auto, what Auto found. Both values are checked before either is
        stored; ``parameters_changed`` fires only when something changed.
        """
        ratio, direction = self._found()
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
            smoothing = display.smoothing != self.display.smoothing
            self.display = display
            if smoothing and self.last is not None:  # smoothed afresh from the frame shown
                self._smoothing.reset()
                self._show(self.last)
            self.display_changed.emit()

    def describe(self) -> dict:
        """What the last solve shows, for screenshot sidecars.

        Besides the frame and the parameters it names the material the forces
        were solved with: ``poisson_ratio`` and ``sensor_size`` (metres).
        """
        last = self.last
        r = last.result
        grid = self.reconstructor.grid
        source = self.source.label if self.live else (str(self.path) if self.path else None)
        return dict(recording=source, frame=last.frame, t=last.time,
                    kernel=self.kernel, poisson_ratio=grid.poisson_ratio, sensor_size=grid.sensor_size,
                    mode="auto" if last.auto else "manual",
                    shear_ratio=r.shear_ratio, shear_direction_deg=math.degrees(r.shear_direction),
                    efficiency=r.efficiency, residual=r.residual, condition=r.condition,
                    display=dict(self.display.__dict__))

    # -- the work ------------------------------------------------------------------------

    def _job(self) -> _Job | None:
        frame = self.current
        if frame is None or self.reconstructor is None:
            return None
        return _Job(self._generation, self.reconstructor, frame.index if frame.index is not None else -1,
                    frame.t, frame.stress, self.auto, self.shear_ratio, self.shear_direction)

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

    def _track(self, solved: Solved) -> Solved:
        # on the model's thread, in the order results are shown: number the contacts (module notes)
        tracker = self._tracker
        if tracker is None:
            return solved
        key = (solved.frame, solved.time)
        last = self._tracked
        frames = 1  # live: every frame continues the tracks
        if last is not None and last[0] == key:
            tracker = self._tracker = last[1].copy()  # the same frame again: matched from before it
            frames = last[2]
        elif last is not None and not self.live:
            frames = solved.frame - last[0][0]
            if frames <= 0:
                tracker.reset()  # a seek backwards: the numbers start again at this frame
                frames = 1
        self._tracked = (key, tracker.copy(), frames)
        try:
            # frames playback skipped (slow drawing, 2x) count as frames the lost contacts were unseen
            return replace(solved, result=tracker.update(solved.result, frames))
        except ValueError:  # a solver whose results the tracker cannot read: shown unnumbered
            log.exception("the contacts of frame %s could not be followed", solved.frame)
            return solved

    def solve(self) -> Solved | None:
        """Reconstruct the current frame with the current parameters, here and now, and announce it.

        In Auto mode the parameters found are in the result; the manual
        values (``shear_ratio``, ``shear_direction``) stay the user's. The
        contacts are numbered as the frames go by (module notes).
        """
        job = self._job()
        if job is None:
            return None
        self._show(self._track(self._compute(job)))
        self.solved.emit(self.last)
        return self.last

    def _show(self, solved: Solved) -> None:
        # the frame solved, and as it is drawn (smoothed over time when the display asks)
        self.last = solved
        self.drawn = self._smoothing(solved, self.display.smoothing, self.reconstructor.grid.pitch)

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
        solved = self._track(solved)
        self._show(solved)
        self._unshown = self.pace and self.live
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
        """Stop the source and end the worker thread (the running solve finishes; its result is dropped).

        Changes after this are kept but solve nothing.
        """
        self._closed = True
        self._generation += 1
        if self.source is not None:
            self._stop(self.source)
        if self._worker is not None:
            self._worker.close()


def _display_scales(source: Source, reconstructor) -> dict:
    # readable default arrow lengths and colour range for a new source
    grid = source.grid
    width = float(np.ptp(grid.positions[:, 0])) + grid.pitch
    if not isinstance(source, RecordingSource):
        # nothing seen yet: 50 mN per node spans three pitches, a 1 N total half the skin,
        # and 50 mN tops the arrows' fixed colour range
        return dict(arrow_scale=3 * grid.pitch / 0.05, resultant_scale=width / 2, threshold=HIDE_BELOW * 0.05,
                    arrow_range_max=0.05)
    # on the recording's most loaded frame the largest node force spans about three pitches,
    # the total half the skin (each contact has its own resultant: with two, each must still
    # stand out of its contact's arrows); the fixed colour ranges hold every frame
    recording = source.recording
    if hasattr(recording.frames, "sample"):
        # an MCAP recording is read lazily: a frame from each of a few chunks, damaged ones skipped
        frames = recording.frames.sample()
    else:
        spread = np.linspace(0, len(recording) - 1, min(len(recording), 2048)).astype(int)
        frames = recording.frames[np.unique(spread)]
    # a frame the solver refuses (a value beyond MAX_STRESS) is reported when it is shown, not here
    frames = frames[np.all(np.abs(frames) <= MAX_STRESS, axis=1)]
    if not len(frames):
        return dict(arrow_scale=3 * grid.pitch / 0.05, resultant_scale=width / 2, threshold=HIDE_BELOW * 0.05,
                    arrow_range_max=0.05)
    loaded = int(np.argmax(np.abs(frames).sum(axis=1)))
    first = reconstructor.solve_normal(frames[loaded]).forces[:, 2]
    peak = float(np.abs(first).max()) or 1.0
    total = abs(float(first.sum())) or peak
    # arrows under 2% of the largest node force are noise more often than load: hidden by default.
    # The arrows' fixed colour range: the full solve concentrates a contact's load on fewer nodes
    # than this normal-only one (the four samples' largest node force over every frame is 1.24 to
    # 1.73 times `peak`), so 1.5 times it; a stronger node shows in the top colour
    # The map's fixed colour range: the pressure the map shows is the full solve's, which concentrates
    # the load more than this normal-only one (set at 1 times it, the core saturated on 16 to 60 of
    # 30 to 60 frames of every sample); their frames' peak pressure is up to 1.66 times the most
    # loaded frame's normal-only peak, so RANGE_MARGIN times it. The stress map shares the range.
    return dict(arrow_scale=3 * grid.pitch / peak, resultant_scale=width / 2 / total,
                range_max=max(float(np.abs(frames).max()), RANGE_MARGIN * peak / grid.pitch**2, 1.0),
                threshold=HIDE_BELOW * peak, arrow_range_max=1.5 * peak)

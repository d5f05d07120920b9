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
order the frames are shown (``Contact.identity``, from 1, in ``Solved.result``;
the rules: :mod:`tactile_viewer.model.contact_numbering`).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import replace
from pathlib import Path

from solver import ContactTracker, Reconstructor, SensorGrid
from solver.kernels import KERNELS

from ..io.recording import Recording
from ..sources.source import RecordingSource, Signal, Source, SourceFrame
from .contact_numbering import number_contacts
from .display import Display, display_scales
from .shear_parameters import MAX_SHEAR_RATIO, auto_found, leave_auto
from .solve_job import SolveJob
from .solved import ForceSmoothing, Solved
from .taring import keeps_raw_values, retare_source
from .worker import LatestWorker

log = logging.getLogger(__name__)

__all__ = ["ViewerModel"]


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
        Frames a live source pushes, and those a playing recording produces,
        are taken only once the last result is on screen (the window calls
        :meth:`shown`), the newest then: a solve that could never be drawn is
        not run, and no solve runs beside the drawing of the one before
        (measured in ``docs/efficiency.md``); a window that paints nothing
        (hidden) calls :meth:`shown` itself. A pause takes the frame playback
        stopped at, and a step while paused is taken at once. Default False.
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
        self._unshown = False  # (pace) the last result is not on screen yet
        self._waiting = False  # (pace) a frame arrived meanwhile
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
        scales = None if same else display_scales(source, reconstructor)
        if old is not None and not same:
            old.frame_arrived.disconnect(self._frame_arrived)
            old.state_changed.disconnect(self._state_changed)
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
            source.state_changed.connect(self._state_changed)
            source.message.connect(self._source_message)
        self._generation += 1
        self.recording_changed.emit()
        self.display_changed.emit()
        if isinstance(source, RecordingSource):
            # a frame held back for the last paint (pace) is dropped, so the seek's own is announced
            source.take_latest()
            source.seek(source.position if same else 0)
        elif not self._take() and same:
            self._schedule()  # a quiet board: its last frame again, with the new solver

    def retare(self, how: str, *, frames: int = 50) -> str:
        """Change the tare of the source shown (a recording's file keeps the raw values, unchanged).

        The one way every caller changes a tare (:mod:`tactile_viewer.model.taring`).

        Parameters
        ----------
        how : {"here", "clear", "recorded"}
            ``"here"``: the baseline is the mean of ``frames`` frames from the
            current one on, applied to every frame (a live board: its next
            ``frames`` frames); ``"clear"``: no tare; ``"recorded"``: the tares
            taken while recording.
        frames : int
            Frames averaged by ``"here"``.

        Returns
        -------
        str
            What was done, for the status line.

        Raises
        ------
        ValueError
            When no recording with raw values (MCAP) or live board is shown, or for an unknown ``how``.
        """
        text = retare_source(self.source, how, frames=frames)
        if self.recording is not None:
            # the scales follow the stresses now shown (cleared, a tare's offsets are load: the resultant
            # kept the scale of the tared frames and was drawn 50 mm long)
            self.set_display(**display_scales(self.source, self.reconstructor))
        return text

    @property
    def retarable(self) -> bool:
        """The recording shown keeps raw values: its tare can be retaken, cleared or restored."""
        return keeps_raw_values(self.source)

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
        # a source produced a frame: on our thread (a recording seeks) take it, from a reader
        # thread hand it over; either waits (pace) until the last result is shown
        if self._here():
            self._take_when_shown()
        elif not self._closed:
            self._dispatch(self._take_when_shown)

    def _state_changed(self):
        # (pace) playback paused while a frame waited for the last paint: that frame is taken now.
        # The source announces no new frame while one waits untaken, so a step after the pause
        # would otherwise wait for that paint too (a paused step is taken at once).
        if self._here():
            self._take_waiting()
        elif not self._closed:
            self._dispatch(self._take_waiting)

    def _take_waiting(self):
        if self._waiting and not self._paced() and not self._closed:
            self._waiting = False
            self._take()

    def _take_when_shown(self):
        if self._unshown and self._paced():
            self._waiting = True
            return
        self._take()

    def _paced(self) -> bool:
        # (pace) frames now come at the source's pace, not the user's: a board, or playback
        return self.pace and self.source is not None and (self.live or self.source.state == "playing")

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
        """The last result is on screen (or will not be: a hidden window): a frame that waited for
        it (``pace``) is taken now. Nothing after :meth:`close`."""
        self._unshown = False
        if self._waiting and not self._closed:
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
        return auto_found(self.last if self.auto else None, (self.shear_ratio, self.shear_direction))

    def set_parameters(self, *, shear_ratio: float | None = None, shear_direction: float | None = None):
        """Manual parameters (a slider was touched): switches Auto off.

        A parameter not given keeps its manual value, or, when this leaves
        Auto, what Auto found (:func:`~tactile_viewer.model.shear_parameters.leave_auto`).
        Both values are checked before either is stored; ``parameters_changed``
        fires only when something changed.
        """
        ratio, direction = leave_auto(self._found(), shear_ratio=shear_ratio, shear_direction=shear_direction)
        if (ratio, direction, False) != (self.shear_ratio, self.shear_direction, self.auto):
            self.shear_ratio, self.shear_direction, self.auto = ratio, direction, False
            self.parameters_changed.emit()
            self._schedule()

    def move_parameters(self, **changes):
        """A parameter control moved: :meth:`set_parameters` (leaving Auto); nothing with nothing open."""
        if self.is_open:
            self.set_parameters(**changes)

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

    def _job(self) -> SolveJob | None:
        frame = self.current
        if frame is None or self.reconstructor is None:
            return None
        return SolveJob(self._generation, self.reconstructor, frame.index if frame.index is not None else -1,
                    frame.t, frame.stress, self.auto, self.shear_ratio, self.shear_direction)

    def _track(self, solved: Solved) -> Solved:
        # on the model's thread, in the order results are shown: number the contacts (module notes)
        solved, self._tracker, self._tracked = number_contacts(solved, self._tracker, self._tracked,
                                                               live=self.live)
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
        self._show(self._track(job.run()))
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

    def _work(self, job: SolveJob):
        # on the worker thread: solve, then hand the outcome to the model's own thread
        try:
            solved = job.run()
        except Exception as exc:
            log.exception("solve of frame %s failed", job.frame)
            message = f"solve of frame {job.frame} failed: {exc}"
            if not self._closed:
                self._dispatch(lambda: self._failed(job, message))
            return
        if not self._closed:  # after close the dispatcher (a Qt object) may be gone
            self._dispatch(lambda: self._deliver(job, solved))

    def _deliver(self, job: SolveJob, solved: Solved):
        if job.generation != self._generation:
            return  # solved with a solver that has been replaced since
        solved = self._track(solved)
        self._show(solved)
        self._unshown = self._paced()
        self.solved.emit(solved)

    def _failed(self, job: SolveJob, message: str):
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


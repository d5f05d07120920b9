"""Exports from the window: a screenshot with its sidecar, the forces of a frame or of a whole recording,
a movie of the recording.

The file formats are :mod:`tactile_viewer.io.forces`'s and :mod:`tactile_viewer.render.movie`'s; here are
the dialogs and the checks that keep a bad folder from ending the app. Whole-recording
exports run as a task behind a progress dialog. A movie solves with the model's own solver
(a solver may be shared between threads: see :mod:`tactile_viewer.model.series_solving`,
whose rule the whole-recording force export and the time plots follow too) and renders its
frames on the GUI thread (VTK draws on the thread that owns its windows), one per timer
tick, so the window stays responsive behind the progress dialog.

Only the file picked in the save dialog (which asks before replacing it) is
replaced. The names the export derives from it -- the ``.png`` ending given to
a name without it, the sidecar ``<image name>.view.json`` -- never replace a file the
user did not pick: the image's is refused, the sidecar's is skipped (the image
kept) and the error names the file left alone.
"""

from __future__ import annotations

import errno
import logging
import os
from pathlib import Path

from PyQt6 import QtCore, QtWidgets

from ..io import sidecar
from ..io.forces import save_forces
from ..io.recording import written_whole
from ..model import movie_settings
from ..model.force_tables import force_table, reconstruct_frames
from ..model.viewer_model import ViewerModel
from ..model.worker import Cancelled
from ..render import movie
from ..render.scene import Scene
from .form_rows import add_buttons
from .foxglove_dialog import FoxgloveExportAction
from .tasks import TaskRunner

log = logging.getLogger(__name__)

__all__ = ["ExportActions", "MovieRunner"]

MOVIE_FILTERS = "MP4 video (*.mp4);;MKV video (*.mkv);;AVI video (*.avi);;Animated GIF (*.gif)"


class ExportActions:
    """The File menu's exports for one window.

    Parameters
    ----------
    parent : QWidget
        The window the dialogs belong to.
    model, scene, tasks
        What is shown, what draws it, where slow work runs.
    error, notify : callable
        ``error(title, text)`` shows an error; ``notify(text)`` a passing note.
    """

    def __init__(self, parent: QtWidgets.QWidget, model: ViewerModel, scene: Scene, tasks: TaskRunner, *,
                 error, notify):
        self.parent, self.model, self.scene, self.tasks = parent, model, scene, tasks
        self._error, self._notify = error, notify
        self.movies = MovieRunner(parent, model, scene, tasks, error=error, notify=notify)
        self.foxglove = FoxgloveExportAction(parent, model, tasks, error=error, notify=notify)

    def add_actions(self, menu: QtWidgets.QMenu) -> list:
        """The export entries of the File menu; returned so the window can enable them.

        In order: screenshot, forces of this frame, forces of the whole recording, movie, Foxglove
        (the last three need a recording: a live source has no whole recording).
        """
        return [
            menu.addAction("Export &screenshot...", self.screenshot_dialog),
            menu.addAction("Export forces of this &frame...", lambda: self.forces_dialog(whole=False)),
            menu.addAction("Export forces of the whole &recording...",
                           lambda: self.forces_dialog(whole=True)),
            menu.addAction("Export &movie...", self.movie_dialog),
            self.foxglove.add_action(menu),
        ]

    def screenshot_dialog(self):
        dialog = QtWidgets.QDialog(self.parent)
        dialog.setWindowTitle("Export screenshot")
        form = QtWidgets.QFormLayout(dialog)
        what = QtWidgets.QComboBox()
        what.addItems(["the 3-D scene", "the whole window (time plots and controls too)"])
        what.setToolTip("The scene alone (any size), or the window as it is on screen")
        scale = QtWidgets.QComboBox()
        scale.addItems(["1x", "2x", "4x"])
        scale.setToolTip("The image's size in multiples of the scene's on screen")
        transparent = QtWidgets.QCheckBox("transparent background")
        transparent.setToolTip("The scene's white background left transparent (for slides)")
        what.currentIndexChanged.connect(lambda i: (scale.setEnabled(i == 0), transparent.setEnabled(i == 0)))
        form.addRow("what", what)
        form.addRow("size", scale)
        form.addRow(transparent)
        if not _confirmed(dialog, form):
            return
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self.parent, "Save screenshot", "screenshot.png",
                                                        "PNG (*.png)")
        if path:
            try:
                if what.currentIndex() == 1:
                    self.export_screenshot(path, window=True)
                else:
                    self.export_screenshot(path, scale=int(scale.currentText()[0]),
                                           transparent=transparent.isChecked())
            except sidecar.SidecarConflict as exc:  # the image is written: say so, and why the sidecar is not
                self._error("Screenshot saved without its sidecar", f"{exc.image} was saved; {exc}")
            except (OSError, ValueError) as exc:
                self._error("Cannot save screenshot", f"{path}: {getattr(exc, 'strerror', None) or exc}")

    def export_screenshot(self, path, *, scale: int = 1, transparent: bool = False,
                          window: bool = False) -> Path:
        """Save the scene (or the whole window) as PNG plus its JSON sidecar naming the recording,
        frame and parameters.

        Parameters
        ----------
        path : str or Path
            The file picked. A name not ending in ``.png`` is given that ending
            (``shot`` -> ``shot.png``, ``shot.PNG`` -> ``shot.png``); that name must then be
            free, since it is not the file picked (nor the one the save dialog asked about).
        scale : int
            The image's size in multiples of the window's.
        transparent : bool
            Whether the background is transparent.
        window : bool
            The whole window as it is on screen (time plots, controls and status
            included) instead of the scene; ``scale`` and ``transparent`` must
            then be left at 1 and False.

        Returns
        -------
        Path
            The image written; its sidecar is :func:`~tactile_viewer.io.sidecar.sidecar_path` of it
            (``shot.png.view.json``).

        Raises
        ------
        ValueError
            No frame has been reconstructed yet; nothing is written.
        OSError
            The folder is missing or cannot be written, or the ``.png`` name made from
            the name picked is an existing file (:class:`FileExistsError`); nothing is written.
        sidecar.SidecarConflict
            The sidecar's name is taken by a file that is not one of our sidecars:
            the image has been written, the sidecar has not, that file is untouched.
        """
        picked = Path(path)
        if self.model.last is None:
            # the sidecar names the frame and parameters shown: there must be one
            raise ValueError("no frame has been reconstructed yet")
        # VTK would only print a warning and write nothing
        if not picked.parent.is_dir():
            raise FileNotFoundError(2, "the folder does not exist", str(picked.parent))
        if not os.access(picked.parent, os.W_OK):
            raise PermissionError(13, "the folder cannot be written", str(picked.parent))
        path = sidecar.derived_name(picked, ".png", what="image")  # lower case: pyvista's ending
        if window:
            if (scale, transparent) != (1, False):
                raise ValueError(f"a window image is taken as shown: scale must be 1 and transparent False, "
                                 f"got scale={scale!r}, transparent={transparent!r}")
            with written_whole(path) as temporary:
                if not self.parent.grab().save(str(temporary), "PNG"):
                    raise OSError(errno.EIO, "the image could not be written", str(path))
        else:
            self.scene.screenshot(path, scale=scale, transparent=transparent)
        sidecar.write_sidecar(path, **self.model.describe(), scale=scale, transparent=transparent,
                             content="window" if window else "scene")
        self._notify(f"saved {path}")
        return path

    def forces_dialog(self, *, whole: bool):
        path, _ = QtWidgets.QFileDialog.getSaveFileName(
            self.parent, "Export forces", "forces.npz", "NumPy archive (*.npz);;CSV (*.csv)")
        if path:
            self.export_forces(path, whole=whole)

    def export_forces(self, path, *, whole: bool):
        """Write reconstructed forces of the frame on screen or of all frames (in a task, with progress).

        The frame on screen is written as it was solved (a live frame too); the whole recording
        is solved again frame by frame with the current parameters.
        """
        model = self.model
        source = model.source.label if model.source is not None else ""
        if not whole:
            last = model.last
            if last is None:
                self._error("Nothing to export", "no frame has been reconstructed yet")
                return

            def work(progress):
                table = force_table([last.result], [last.frame], [last.time], model.grid,
                                           solver=model.reconstructor, source=source,
                                           mode="auto" if last.auto else "manual")
                return save_forces(table, path, source=source)
        else:
            recording, reconstructor = model.recording, model.reconstructor
            if recording is None:
                self._error("Nothing to export", "a live source has no whole recording: record it first")
                return
            given = {} if model.auto else dict(shear_ratio=model.shear_ratio,
                                               shear_direction=model.shear_direction)

            def work(progress):
                table = reconstruct_frames(recording, reconstructor, None, progress=progress, **given)
                return save_forces(table, path, source=source)

        self.tasks.run(work, lambda written: self._notify(f"saved {written}"), "Exporting forces...",
                       determinate=True)

    # -- movies ------------------------------------------------------------------------------------------

    def movie_dialog(self):
        """Ask for the frames, rate and size, then for the file, and start the movie."""
        recording = self.model.recording
        if recording is None:
            self._error("Nothing to export", "a live source has no whole recording: record it first")
            return
        if self.movies.running:
            self._error("Movie export running", "one movie at a time: wait for it or cancel it")
            return
        count = len(recording)
        dialog = QtWidgets.QDialog(self.parent)
        dialog.setWindowTitle("Export movie")
        form = QtWidgets.QFormLayout(dialog)
        first = QtWidgets.QSpinBox()
        first.setRange(0, count - 1)
        stop = QtWidgets.QSpinBox()
        stop.setRange(1, count)
        stop.setValue(count)
        stop.setToolTip("exclusive: the movie ends before this frame (the frame count: to the end)")
        fps = QtWidgets.QDoubleSpinBox()
        fps.setRange(0.1, 240.0)
        fps.setDecimals(2)
        fps.setValue(movie_settings.DEFAULT_FPS)
        fps.setToolTip(f"one movie frame per recording frame; a GIF plays at most "
                       f"{movie_settings.GIF_MAX_FPS:g} fps")
        width, height = QtWidgets.QSpinBox(), QtWidgets.QSpinBox()
        for spin, value in zip((width, height), self.default_movie_size(), strict=True):
            spin.setRange(16, 8192)
            spin.setSingleStep(2)
            spin.setValue(value)
            spin.setSuffix(" px")
        summary = QtWidgets.QLabel()

        def show_summary():
            frames = stop.value() - first.value()
            if frames > 0:
                summary.setText(f"frames {first.value()} to {stop.value() - 1}: {frames} frames, "
                                f"{frames / fps.value():.1f} s")
            else:
                summary.setText("no frames: stop must come after the first frame")

        for spin in (first, stop, fps):
            spin.valueChanged.connect(show_summary)
        show_summary()
        form.addRow("first frame (from 0)", first)
        form.addRow("stop before frame", stop)
        form.addRow("frames per second", fps)
        form.addRow("width", width)
        form.addRow("height", height)
        form.addRow(summary)
        if not _confirmed(dialog, form):
            return
        picked, chosen = QtWidgets.QFileDialog.getSaveFileName(self.parent, "Export movie", "movie.mp4",
                                                               MOVIE_FILTERS)
        if not picked:
            return
        try:
            path = _movie_name(Path(picked), chosen)
        except OSError as exc:
            self._error("Cannot export movie", f"{picked}: {exc.strerror or exc}")
            return
        self.export_movie(path, start=first.value(), stop=stop.value(), fps=fps.value(),
                          size=(width.value(), height.value()))

    def default_movie_size(self) -> tuple:
        """The scene's size on screen, rounded down to even numbers (a video's sides must be even)."""
        try:
            width, height = (int(v) for v in self.scene.plotter.window_size)
        except Exception:  # a plotter without a window yet: the command line's size
            return movie_settings.DEFAULT_SIZE
        if width < 16 or height < 16:
            return movie_settings.DEFAULT_SIZE
        return min(width, 8192) // 2 * 2, min(height, 8192) // 2 * 2

    def export_movie(self, path, *, start: int = 0, stop: int | None = None,
                     fps: float = movie_settings.DEFAULT_FPS, size=None) -> bool:
        """Make a movie of the recording shown, as the window shows it (see :class:`MovieRunner`).

        Returns
        -------
        bool
            False when it was refused (the reason shown); True when it started:
            ``movies.finished`` then brings its outcome.
        """
        return self.movies.start(path, start=start, stop=stop, fps=fps,
                                 size=self.default_movie_size() if size is None else size)


class MovieRunner(QtCore.QObject):
    """Makes a movie of the recording shown without blocking the window.

    The movie shows what the window shows: the recording (its current tare), the kernel and
    quality, the display settings, Auto or the manual parameters, and the camera (copied
    whole: a zoomed, parallel Top view stays one), as they were when it started. It solves
    with the model's own solver, ``model.reconstructor``: a solver may be shared between
    threads (:mod:`tactile_viewer.model.series_solving`), so the movie on the GUI thread and the model's
    worker thread may both solve with it, as the time plots and the whole-recording force
    export do (see :mod:`tactile_viewer.model.series_solving`); nothing is built again. A single-shot timer
    renders one frame per tick on the GUI thread behind a window-modal progress dialog with
    Cancel. A failure is shown with ``error(title, text)`` and never raised; a cancelled or
    failed movie leaves no file. A window closing cancels it.

    Signals
    -------
    finished(object)
        The movie ended: its :class:`movie.MovieResult`, or the exception that ended it
        (:class:`Cancelled` when cancelled).
    """

    finished = QtCore.pyqtSignal(object)

    def __init__(self, parent: QtWidgets.QWidget, model: ViewerModel, scene: Scene, tasks: TaskRunner, *,
                 error, notify):
        super().__init__(parent)
        self.parent, self.model, self.scene, self.tasks = parent, model, scene, tasks
        self._error, self._notify = error, notify
        self.export: movie.MovieExport | None = None
        self._path = None
        self._cancelled = False
        self._dialog: QtWidgets.QProgressDialog | None = None
        # single-shot, restarted at the end of each tick: a tick never runs inside another
        # (the progress dialog processes events while it updates)
        self._timer = QtCore.QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._tick)
        parent.installEventFilter(self)

    @property
    def running(self) -> bool:
        """A movie is being written."""
        return self.export is not None

    def start(self, path, *, start: int = 0, stop: int | None = None, fps: float = movie_settings.DEFAULT_FPS,
              size=movie_settings.DEFAULT_SIZE) -> bool:
        """Check everything and start writing; the frames follow, one per timer tick.

        Returns
        -------
        bool
            False when refused (the reason shown with ``error``; nothing written and ``finished``
            not emitted); True when started: ``finished`` brings its outcome.
        """
        model = self.model
        recording = model.recording
        if recording is None:
            self._error("Nothing to export", "a live source has no whole recording: record it first")
            return False
        if self.running:
            self._error("Movie export running", "one movie at a time: wait for it or cancel it")
            return False
        try:
            # checks every argument (movie_settings.check_frames and the others: one place for the window and
            # the command line) before the temporary file is made; the camera is copied now
            export = movie.MovieExport(
                recording, model.reconstructor, path, start=start, stop=stop, fps=fps, size=size,
                display=model.display, shear_ratio=None if model.auto else model.shear_ratio,
                shear_direction=None if model.auto else model.shear_direction,
                camera=self.scene.plotter.renderer.GetActiveCamera())
        except ValueError as exc:
            self._error("Cannot export movie", f"{path}: {exc}")
            return False
        except Exception as exc:  # a folder gone since it was picked, a renderer that cannot start
            log.error("movie %s could not start", path, exc_info=exc)
            self._error("Cannot export movie", f"{path}: {_reason(exc)}")
            return False
        self.export, self._path, self._cancelled = export, Path(path), False
        dialog = QtWidgets.QProgressDialog("Exporting movie...", "Cancel", 0, export.total, self.parent)
        dialog.setWindowTitle("Export movie")
        dialog.setWindowModality(QtCore.Qt.WindowModality.WindowModal)
        dialog.setMinimumDuration(0)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(self.cancel)
        self._dialog = dialog
        dialog.setValue(0)
        self._timer.start()
        return True

    def cancel(self):
        """Stop the movie at the next frame; its file is removed."""
        self._cancelled = True

    def _tick(self):
        export = self.export
        if export is None:
            return
        try:
            if self._cancelled or self.tasks.closed:
                raise Cancelled(f"cancelled after {export.done} of {export.total} frames")
            export.step()
            if self._dialog is not None:
                self._dialog.setLabelText(f"Exporting movie: frame {export.done} of {export.total}")
                self._dialog.setValue(export.done)  # processes events: Cancel, the window closing
            if self.export is not export:
                return  # ended while the dialog processed events
            if self._cancelled or (self._dialog is not None and self._dialog.wasCanceled()):
                # (wasCanceled: cancelled without the signal, by QProgressDialog.cancel())
                raise Cancelled(f"cancelled after {export.done} of {export.total} frames")
            if export.remaining:
                self._timer.start()
                return
            outcome = export.finish()
        except Exception as exc:  # reported, never raised: a slot's exception would end the app
            outcome = exc
        self._end(outcome)

    def _end(self, outcome):
        export, self.export = self.export, None
        self._timer.stop()
        if export is not None and not isinstance(outcome, movie.MovieResult):
            export.cancel()  # removes the temporary file; idempotent
        dialog, self._dialog = self._dialog, None
        if dialog is not None:
            dialog.canceled.disconnect(self.cancel)  # closing it would emit canceled
            dialog.close()
            dialog.deleteLater()
        if isinstance(outcome, movie.MovieResult):
            width, height = outcome.size
            self._notify(f"saved {outcome.path}: {outcome.frames} frames, {width} x {height}, "
                         f"{outcome.fps:g} fps")
        elif not isinstance(outcome, Cancelled):
            log.error("movie %s failed", self._path, exc_info=outcome)
            self._error("Cannot export movie", f"{self._path}: {_reason(outcome)}")
        self.finished.emit(outcome)

    def eventFilter(self, watched, event):  # noqa: N802 (Qt's name)
        # the window closing ends the movie now: the event loop may stop before another tick
        if watched is self.parent and event.type() == QtCore.QEvent.Type.Close and self.export is not None:
            self._end(Cancelled("the window closed"))
        return False


def _reason(exc: BaseException) -> str:
    # an OSError's own words without its errno prefix; anything else as it reads
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__


def _confirmed(dialog: QtWidgets.QDialog, form: QtWidgets.QFormLayout) -> bool:
    """Add OK and Cancel under ``form``, run ``dialog``: whether the user pressed OK."""
    add_buttons(form, dialog.accept, dialog.reject)
    return dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted


def _filter_suffix(chosen_filter: str) -> str:
    """The ending a save dialog's filter names: ``"MKV video (*.mkv)"`` -> ``".mkv"``; ``""`` for none."""
    text = chosen_filter or ""
    start = text.find("(*.")
    end = text.find(")", start)
    return text[start + 2:end].lower() if start >= 0 and end > start else ""


def _movie_name(picked: Path, chosen_filter: str) -> Path:
    """The name a movie is saved as: the name picked when it ends in a movie type; a name with no
    ending gets the chosen filter's (it must then be free: the save dialog asked about the name
    picked, not about this one); any other ending is refused by :func:`movie_settings.movie_kind`."""
    if picked.suffix:
        return picked
    return sidecar.derived_name(picked, _filter_suffix(chosen_filter) or ".mp4", what="movie")

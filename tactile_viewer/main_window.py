"""The main window: composes the panels, the scene, the menus; opens, exports, connects.

Data flows one way: the panels set fields of the :class:`~tactile_viewer.model.ViewerModel`,
the model schedules its own solve on its worker thread and announces the result, the
:class:`~tactile_viewer.scene.Scene` draws it. Slow one-off work (factoring a large geometry,
exporting a whole recording, measuring the quality presets) runs in a
:class:`~tactile_viewer.tasks.Task` behind a progress dialog.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import os
from pathlib import Path

os.environ.setdefault("QT_API", "pyqt6")

from PyQt6 import QtCore, QtGui, QtWidgets  # noqa: E402
from pyvistaqt import QtInteractor  # noqa: E402

from solver import tradeoff  # noqa: E402

from . import export  # noqa: E402
from .connect_dialog import ConnectDialog  # noqa: E402
from .layout import LayoutError, SensorLayout, load_layout  # noqa: E402
from .live_source import SerialReader  # noqa: E402
from .model import ViewerModel  # noqa: E402
from .panels import DisplayPanel, LivePanel, ParametersPanel, PlaybackPanel, status_text  # noqa: E402
from .recording import Recording, RecordingError, load  # noqa: E402
from .scene import Scene  # noqa: E402
from .tasks import Dispatcher, Task  # noqa: E402

log = logging.getLogger(__name__)

__all__ = ["MainWindow"]

PRESET_LIMIT = 32 * 32  # skins whose quality presets are measured automatically
SETTLE_S = 0.03  # the longest a control waits for its solve (docs/architecture.md)


class MainWindow(QtWidgets.QMainWindow):
    """The viewer window.

    Signals
    -------
    ready
        A recording is installed and its first frame drawn.
    rendered
        A frame is on screen (emitted when the scene widget's repaint after a
        solve or a display change has been swapped to the window).
    """

    ready = QtCore.pyqtSignal()
    rendered = QtCore.pyqtSignal()
    task_finished = QtCore.pyqtSignal(object)
    live_frame_arrived = QtCore.pyqtSignal()  # emitted from the reader thread, queued to ours
    presets_measured = QtCore.pyqtSignal()

    def __init__(self, parent=None):
        super().__init__(parent)
        self.setWindowTitle("tactile-viewer")
        self.resize(1280, 820)
        self._dispatcher = Dispatcher(self)
        # the model solves on its own worker thread; a solve done within SETTLE_S is drawn in the
        # same repaint as the slider or frame change that asked for it
        self.model = ViewerModel(dispatch=self._dispatcher.post, settle=SETTLE_S)
        self._first_frame = False  # a recording was installed and its first frame is not drawn yet
        self._closing = False
        self._tasks: list[Task] = []
        self._measured_for = None  # the geometry the quality presets were measured on

        central = QtWidgets.QFrame(self)
        layout = QtWidgets.QVBoxLayout(central)
        layout.setContentsMargins(0, 0, 0, 0)
        self.banner = QtWidgets.QLabel("NO DATA", central)
        self.banner.setAlignment(QtCore.Qt.AlignmentFlag.AlignCenter)
        self.banner.setStyleSheet("background: #b00020; color: white; font-weight: bold; padding: 4px")
        self.banner.hide()
        layout.addWidget(self.banner)
        self.plotter = QtInteractor(central, auto_update=False)
        layout.addWidget(self.plotter.interactor)
        self.setCentralWidget(central)
        self.scene = Scene(self.plotter)
        self._drawing = False
        self._live_waiting = False  # a live frame arrived while the last one was being drawn
        self.plotter.interactor.frameSwapped.connect(self._frame_swapped)

        self.parameters = ParametersPanel(self.model)
        self.parameters.kernel_chosen.connect(self._kernel_changed)
        self.parameters.quality_chosen.connect(self._quality_changed)
        self.display_panel = DisplayPanel(self.model)
        self.display_panel.camera.connect(self._camera)
        self.playback = PlaybackPanel(self.model)
        self.live_panel = LivePanel()
        actions = {"tare": lambda: self.tare(50), "record": self.record_dialog,
                   "stop_recording": self.stop_recording, "disconnect": self.disconnect_live}
        self.live_panel.action.connect(lambda name: actions[name]())
        self._controls = QtWidgets.QWidget()
        column = QtWidgets.QVBoxLayout(self._controls)
        for panel in (self.parameters, self.display_panel, self.playback, self.live_panel):
            column.addWidget(panel)
        column.addStretch(1)
        dock = QtWidgets.QDockWidget("Controls", self)
        dock.setFeatures(QtWidgets.QDockWidget.DockWidgetFeature.NoDockWidgetFeatures)
        dock.setWidget(self._controls)
        self.addDockWidget(QtCore.Qt.DockWidgetArea.RightDockWidgetArea, dock)
        self._build_menus()
        self.status = QtWidgets.QLabel("open a recording (File > Open) or connect a board (Live > Connect)")
        self.statusBar().addPermanentWidget(self.status, 1)
        self.reader: SerialReader | None = None
        self.live_frame_arrived.connect(self._take_live_frame)
        self._live_timer = QtCore.QTimer(self, interval=250)
        self._live_timer.timeout.connect(self._update_live_status)

        self.model.recording_changed.connect(self._on_recording)
        self.model.display_changed.connect(self._redraw)
        self.model.solved.connect(self._on_solved)
        self.model.solve_failed.connect(self._on_solve_failed)
        self._set_enabled(False)

    # -- widgets -----------------------------------------------------------------------

    def _build_menus(self):
        menu = self.menuBar().addMenu("&File")
        action = menu.addAction("&Open recording...", self.open_dialog)
        action.setShortcut(QtGui.QKeySequence.StandardKey.Open)
        self._exports = [
            menu.addAction("Export &screenshot...", self.screenshot_dialog),
            menu.addAction("Export forces of this &frame...", lambda: self.forces_dialog(whole=False)),
            menu.addAction("Export forces of the whole &recording...",
                           lambda: self.forces_dialog(whole=True)),
        ]
        menu.addSeparator()
        menu.addAction("&Quit", self.close).setShortcut(QtGui.QKeySequence.StandardKey.Quit)
        live = self.menuBar().addMenu("&Live")
        live.addAction("&Connect...", self.connect_dialog)
        self._live_actions = [
            live.addAction("&Disconnect", self.disconnect_live),
            live.addAction("&Tare (average 50 frames)", lambda: self.tare(50)),
            live.addAction("&Record...", self.record_dialog),
            live.addAction("&Stop recording", self.stop_recording),
        ]
        view = self.menuBar().addMenu("&View")
        view.addAction("&Top", lambda: self._camera("top"))
        view.addAction("&Iso", lambda: self._camera("iso"))

    def _set_enabled(self, on: bool):
        live = self.model.live
        self._controls.setEnabled(on)
        self.playback.setEnabled(on and not live)
        for action in self._exports:
            action.setEnabled(on)
        self._exports[2].setEnabled(on and not live)  # a live source has no "whole recording"
        self.live_panel.setVisible(live)
        for action in self._live_actions:
            action.setEnabled(live)
        recording = self.reader is not None and self.reader.recorder is not None
        self._live_actions[3].setEnabled(live and recording)

    # -- opening ----------------------------------------------------------------------------

    def open_dialog(self):
        path, _ = QtWidgets.QFileDialog.getOpenFileName(
            self, "Open recording", str(Path.cwd()), "Recordings (*.npz *.csv);;All files (*)")
        if path:
            self.open(path)

    def open(self, path) -> bool:
        """Load a recording; on failure show the error and keep what was shown."""
        try:
            recording = load(path)
        except RecordingError as exc:
            self._error("Cannot open recording", str(exc))
            return False
        self._install(recording, self.model.kernel, path)
        return True

    def show_recording(self, recording: Recording, path=None):
        """Show an in-memory recording (the live view and the tests use this)."""
        self._install(recording, self.model.kernel, path)

    def _install(self, recording, kernel, path):
        # Factoring is the slow part for large grids: do it in a worker thread.
        def work(progress):
            return ViewerModel.build(recording.grid, kernel, self.model.configuration)

        def done(reconstructor):
            self.playback.stop()
            self._stop_reader()
            self.model.install(recording, reconstructor, path)

        ny, nx = recording.grid.shape[0], recording.grid.shape[-1]
        self._run(work, done, f"Factoring the {nx}x{ny} geometry...",
                  determinate=False)

    def _kernel_changed(self, kernel):
        if not self.model.is_open or kernel == self.model.kernel:
            return
        self._rebuild(kernel, f"Factoring for the {kernel} kernel...")

    def _rebuild(self, kernel, label):
        # the same geometry with another kernel or quality: keep the frame shown
        grid, configuration = self.model.grid, self.model.configuration

        def work(progress):
            return ViewerModel.build(grid, kernel, configuration)

        if self.model.live:
            live_label = self.model.live_label
            self._run(work, lambda solver: self.model.install_live(solver, live_label), label,
                      determinate=False)
            return
        frame, recording, path = self.model.frame, self.model.recording, self.model.path

        def done(solver):
            self.model.install(recording, solver, path)
            self.model.set_frame(frame)

        self._run(work, done, label, determinate=False)

    def _quality_changed(self, configuration):
        if configuration == self.model.configuration or not self.model.is_open:
            self.model.configuration = configuration
            return
        self.model.configuration = configuration
        label = self.parameters.quality_box.currentText().split(":")[0]
        self._rebuild(self.model.kernel, f"Setting up '{label}'...")

    def _measure_if_open(self):
        # measuring builds every configuration, full ones included: keep it to skins where
        # that takes seconds (tactile-tradeoff measures larger ones from the command line)
        if self.isVisible() and self.model.is_open and self.model.grid.size <= PRESET_LIMIT:
            self.measure_presets()

    def measure_presets(self):
        """Measure the speed/accuracy front for the shown geometry in the background; fill the
        quality presets with their measured cost and error (emits ``presets_measured``)."""
        grid = self.model.grid
        key = grid.key
        if self._measured_for == (key, "done"):
            self.presets_measured.emit()
            return
        if self._measured_for == (key, "measuring"):
            return  # presets_measured comes when it is done
        self._measured_for = (key, "measuring")

        def work(progress):
            # In another process: measuring takes seconds of Python, which in this process would
            # take the interpreter lock from the solve thread and slow every slider move.
            with multiprocessing.get_context("spawn").Pool(1) as pool:
                pending = pool.apply_async(tradeoff.preset_front, (grid,))
                while True:
                    try:
                        return pending.get(timeout=0.1)
                    except multiprocessing.TimeoutError:
                        if not progress(0, 0):  # the window closed: leaving the block ends the process
                            raise export.ExportCancelled("presets not measured: the window closed") from None

        def done(chosen):
            self.parameters.set_presets(chosen, lambda m: f"{m.name}, {m.frame_ms:.2f} ms/frame, "
                                                          f"error {100 * tradeoff.error_of(m):.1f}% of |F|")
            self._measured_for = (key, "done")
            self.presets_measured.emit()

        task = Task(work, self)
        task.succeeded.connect(done)
        def failed(exc):
            self._measured_for = None
            if not isinstance(exc, export.ExportCancelled):
                self.statusBar().showMessage(f"could not measure presets: {exc}", 5000)

        task.failed.connect(failed)
        task.finished.connect(task.deleteLater)
        task.finished.connect(lambda: self._tasks.remove(task) if task in self._tasks else None)
        self._tasks.append(task)
        task.start()

    def _on_recording(self):
        self.scene.set_grid(self.model.grid)
        if self.model.live:
            self.setWindowTitle(f"tactile-viewer - live: {self.model.live_label}")
        else:
            name = self.model.path.name if self.model.path else "recording"
            self.setWindowTitle(f"tactile-viewer - {name}")
        self._set_enabled(True)
        if self.model.live and self.model.live_frame is None:
            self.ready.emit()  # no frame yet: the first to arrive is solved and drawn as it comes
        else:
            self._first_frame = True  # ready follows with its first solve
        # the quality presets of this geometry, measured in the background once things settle
        QtCore.QTimer.singleShot(1000, self._measure_if_open)

    def _redraw(self):
        # the display settings changed: draw the last result again
        if self.model.last is not None:
            self.scene.update(self.model.last, self.model.display, render=False)
            self._draw()

    def _camera(self, preset):
        if self.scene.grid is not None:
            self.scene.camera(preset)
            self.plotter.render()

    # -- solving -------------------------------------------------------------------------------

    def _on_solve_failed(self, message):
        self.statusBar().showMessage(message, 10000)

    def _on_solved(self, solved):
        self.scene.update(solved, self.model.display, render=False)
        self.status.setText(status_text(solved, self.model))
        self._draw()
        if self._first_frame:
            self._first_frame = False
            self.ready.emit()

    def _draw(self):
        # Ask Qt to repaint the scene widget rather than rendering here: its
        # paint always renders, so an explicit render would draw every frame twice.
        self._drawing = True
        self.plotter.interactor.update()

    def _frame_swapped(self):
        if self._drawing:
            self._drawing = False
            self.rendered.emit()
        if self._live_waiting:
            self._live_waiting = False
            self._take_live_frame()

    # -- exports ---------------------------------------------------------------------------------

    def screenshot_dialog(self):
        dialog = QtWidgets.QDialog(self)
        dialog.setWindowTitle("Export screenshot")
        form = QtWidgets.QFormLayout(dialog)
        scale = QtWidgets.QComboBox()
        scale.addItems(["1x", "2x", "4x"])
        transparent = QtWidgets.QCheckBox("transparent background")
        form.addRow("size", scale)
        form.addRow(transparent)
        buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.StandardButton.Ok
                                             | QtWidgets.QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(dialog.accept)
        buttons.rejected.connect(dialog.reject)
        form.addRow(buttons)
        if dialog.exec() != QtWidgets.QDialog.DialogCode.Accepted:
            return
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Save screenshot", "screenshot.png",
                                                        "PNG (*.png)")
        if path:
            try:
                self.export_screenshot(path, scale=int(scale.currentText()[0]),
                                       transparent=transparent.isChecked())
            except (OSError, ValueError) as exc:
                self._error("Cannot save screenshot", f"{path}: {getattr(exc, 'strerror', None) or exc}")

    def export_screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> Path:
        """Save the scene as PNG plus a JSON sidecar naming the recording, frame and parameters."""
        path = Path(path).with_suffix(".png")
        if self.model.last is None:
            # the sidecar names the frame and parameters shown: there must be one
            raise ValueError("no frame has been reconstructed yet")
        # VTK would only print a warning and write nothing
        if not path.parent.is_dir():
            raise FileNotFoundError(2, "the folder does not exist", str(path.parent))
        if not os.access(path.parent, os.W_OK):
            raise PermissionError(13, "the folder cannot be written", str(path.parent))
        self.scene.screenshot(path, scale=scale, transparent=transparent)
        export.write_sidecar(path, **self.model.describe(), scale=scale, transparent=transparent)
        self.statusBar().showMessage(f"saved {path}", 5000)
        return path

    def forces_dialog(self, *, whole: bool):
        path, _ = QtWidgets.QFileDialog.getSaveFileName(
            self, "Export forces", "forces.npz", "NumPy archive (*.npz);;CSV (*.csv)")
        if path:
            self.export_forces(path, whole=whole)

    def export_forces(self, path, *, whole: bool):
        """Write reconstructed forces of the frame on screen or of all frames (in a worker, with progress).

        The frame on screen is written as it was solved (a live frame too); the whole recording
        is solved again frame by frame with the current parameters.
        """
        model = self.model
        if not whole:
            last = model.last
            if last is None:
                self._error("Nothing to export", "no frame has been reconstructed yet")
                return
            source = model.live_label if model.live else (str(model.path) if model.path else
                                                          model.recording.description)

            def work(progress):
                table = export.force_table([last.result], [last.frame], [last.time], model.grid,
                                           solver=model.reconstructor, source=source,
                                           mode="auto" if last.auto else "manual")
                return export.save_forces(table, path, source=source)
        else:
            recording, reconstructor = model.recording, model.reconstructor
            given = {} if model.auto else dict(shear_ratio=model.shear_ratio,
                                               shear_direction=model.shear_direction)
            source = str(model.path) if model.path else recording.description

            def work(progress):
                table = export.reconstruct_frames(recording, reconstructor, None, progress=progress, **given)
                return export.save_forces(table, path, source=source)

        def done(written):
            self.statusBar().showMessage(f"saved {written}", 5000)

        self._run(work, done, "Exporting forces...", determinate=True)

    # -- background work ---------------------------------------------------------------------------

    def _run(self, work, done, label, *, determinate):
        task = Task(work, self)
        dialog = QtWidgets.QProgressDialog(label, "Cancel", 0, 0 if not determinate else 100, self)
        dialog.setWindowModality(QtCore.Qt.WindowModality.WindowModal)
        dialog.setMinimumDuration(400)
        dialog.setAutoClose(False)
        dialog.setAutoReset(False)
        dialog.canceled.connect(task.cancel)
        if determinate:
            task.progressed.connect(lambda d, t: (dialog.setMaximum(t), dialog.setValue(d)))

        def finish(outcome, ok):
            dialog.close()
            dialog.deleteLater()
            self._tasks.remove(task)
            if self._closing:
                return  # the window closed while it ran: nothing left to show it in
            if ok:
                done(outcome)
            elif not isinstance(outcome, export.ExportCancelled):
                self._error("Failed", f"{label.rstrip('.')}: {outcome}")
            self.task_finished.emit(outcome)

        task.succeeded.connect(lambda result: finish(result, True))
        task.failed.connect(lambda exc: finish(exc, False))
        task.finished.connect(task.deleteLater)
        self._tasks.append(task)
        task.start()
        return task

    def _error(self, title, message):
        log.warning("%s: %s", title, message)
        QtWidgets.QMessageBox.critical(self, title, message)

    # -- live ------------------------------------------------------------------------------------

    def connect_dialog(self):
        dialog = ConnectDialog(self)
        if dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted:
            chosen = dialog.connection()
            self.connect_live(chosen.url, chosen.layout, fmt=chosen.fmt, baudrate=chosen.baudrate)

    def connect_live(self, url: str, layout, *, fmt: str = "binary", baudrate: int = 115200) -> bool:
        """Show frames from a serial URL; ``layout`` is a SensorLayout or its JSON path.

        Errors (bad layout, port that cannot be opened) are shown and change nothing.
        """
        try:
            if not isinstance(layout, SensorLayout):
                layout = load_layout(layout)
            reader = SerialReader(url, layout, fmt=fmt, baudrate=baudrate,
                                  on_frame=self.live_frame_arrived.emit)
            reader.start()
        except (LayoutError, ValueError, OSError) as exc:  # pyserial's SerialException is an OSError
            self._error("Cannot connect", f"{url}: {exc}")
            return False
        kernel, grid = self.model.kernel, layout.grid

        def done(reconstructor):
            self.playback.stop()
            self._stop_reader()
            self.reader = reader
            self.model.install_live(reconstructor, f"{url} ({fmt})")
            self._live_timer.start()
            self._set_enabled(True)
            self._take_live_frame()  # frames that arrived while factoring announced themselves already

        def work(progress):
            return ViewerModel.build(grid, kernel, self.model.configuration)

        task = self._run(work, done, f"Factoring the {grid.size}-taxel geometry...", determinate=False)
        task.failed.connect(lambda _: reader.stop())
        # closed while factoring: done() never runs, so nothing else would stop the reader
        task.succeeded.connect(lambda _: reader.stop() if self._closing else None)
        return True

    def disconnect_live(self):
        """Stop reading (and recording); the last frame stays on screen."""
        self._stop_reader()
        self._set_enabled(self.model.is_open)

    def _stop_reader(self):
        reader, self.reader = self.reader, None
        if reader is not None:
            written = self._close_recording(reader)
            reader.stop()
            if written is not None:
                self.statusBar().showMessage(f"recording saved: {written}", 10000)
        self._live_timer.stop()
        self.banner.hide()
        self.live_panel.status.setText("")

    def tare(self, frames: int = 50):
        """Average the next ``frames`` frames as the zero of every taxel."""
        if self.reader is not None:
            self.reader.calibration.tare(frames)
            self.statusBar().showMessage(f"taring: averaging the next {frames} frames", 3000)

    def record_dialog(self):
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Record live frames", "live.npz",
                                                        "NumPy archive (*.npz);;CSV (*.csv)")
        if path:
            self.start_recording(path)

    def start_recording(self, path) -> bool:
        """Record every received frame (not only the displayed ones) to NPZ or CSV."""
        if self.reader is None:
            return False
        self.stop_recording()
        try:
            self.reader.start_recording(path)
        except (ValueError, OSError) as exc:
            self._error("Cannot record", f"{path}: {exc}")
            return False
        self._set_enabled(True)
        return True

    def _close_recording(self, reader) -> Path | None:
        # a full disk or a vanished folder must not lose the session: say what is kept
        recorder = reader.recorder
        try:
            return reader.stop_recording()
        except (OSError, ValueError) as exc:
            self._error("Recording not completed",
                        f"{recorder.path}: {getattr(exc, 'strerror', None) or exc}. The frames written "
                        f"before the error ({recorder.written}) are in the file; the live view goes on.")
            return None

    def stop_recording(self) -> Path | None:
        written = self._close_recording(self.reader) if self.reader is not None else None
        if written is not None:
            self.statusBar().showMessage(f"recording saved: {written}", 10000)
        self._set_enabled(self.model.is_open)
        return written

    def _take_live_frame(self):
        if self._drawing:
            # the previous frame is not on screen yet: solving now would be overtaken
            # before it is drawn; take the newest frame once it is
            self._live_waiting = True
            return
        frame = self.reader.take_latest() if self.reader is not None else None
        if frame is not None and self.model.live:
            self.model.show_live(frame)

    def _update_live_status(self):
        reader = self.reader
        if reader is None:
            return
        stats = reader.stats
        silence = stats.silence(reader.now())
        self.banner.setVisible(silence > 1.0)
        if silence > 1.0:
            since = "no frame received yet" if silence == math.inf else f"no frame for {silence:.1f} s"
            state = reader.state + (f": {reader.error}" if reader.error else "")
            self.banner.setText(f"NO DATA: {since} ({state})")
        self.live_panel.show_reader(reader)

    def closeEvent(self, event):
        self._closing = True
        self._stop_reader()
        self.playback.stop()
        self.model.close()
        for task in list(self._tasks):
            task.cancel()
            task.wait()
        self.plotter.close()
        super().closeEvent(event)

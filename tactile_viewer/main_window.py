"""The main window: controls, playback, status, exports; wires recording -> solver -> scene.

Data flows one way: the widgets change the :class:`~tactile_viewer.model.ViewerModel`,
the model solves and announces, the :class:`~tactile_viewer.scene.Scene` draws.
Solves are coalesced (a slider drag re-solves only the latest value); slow work
(factoring a large geometry, exporting a whole recording) runs in a worker
thread behind a progress dialog.
"""

from __future__ import annotations

import logging
import math
import os
import time
from pathlib import Path

os.environ.setdefault("QT_API", "pyqt6")

from PyQt6 import QtCore, QtGui, QtWidgets  # noqa: E402
from pyvistaqt import QtInteractor  # noqa: E402

from solver import tradeoff  # noqa: E402
from solver.kernels import KERNELS  # noqa: E402

from . import export  # noqa: E402
from .connect_dialog import ConnectDialog  # noqa: E402
from .model import KERNEL_HELP, MAX_SHEAR_RATIO, ViewerModel, geometry_text  # noqa: E402
from .recording import Recording, RecordingError, load  # noqa: E402
from .scene import Scene  # noqa: E402
from .sources import LayoutError, SensorLayout, SerialReader, load_layout  # noqa: E402

log = logging.getLogger(__name__)

__all__ = ["MainWindow"]

MAP_CHOICES = (("normal pressure", "pressure"), ("sensor stress", "stress"), ("none", "none"))
SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)
PRESET_LIMIT = 32 * 32  # skins whose quality presets are measured automatically
SETTLE_S = 0.03  # the longest a control waits for its solve (docs/architecture.md)


class Task(QtCore.QThread):
    """Runs ``fn(progress)`` in a worker thread; ``progress(done, total)`` returns False to cancel."""

    progressed = QtCore.pyqtSignal(int, int)
    succeeded = QtCore.pyqtSignal(object)
    failed = QtCore.pyqtSignal(object)

    def __init__(self, fn, parent=None):
        super().__init__(parent)
        self._fn = fn
        self._cancelled = False

    def cancel(self):
        self._cancelled = True

    def _progress(self, done, total):
        self.progressed.emit(int(done), int(total))
        return not self._cancelled

    def run(self):
        try:
            result = self._fn(self._progress)
        except Exception as exc:  # handed to the GUI thread, which shows it
            self.failed.emit(exc)
        else:
            self.succeeded.emit(result)


class Dispatcher(QtCore.QObject):
    """Runs callables on the thread that owns it (the GUI thread), posted from any thread.

    The model's ``dispatch``: its worker thread hands results back through it.
    """

    _posted = QtCore.pyqtSignal(object)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._posted.connect(self._call, QtCore.Qt.ConnectionType.QueuedConnection)

    def post(self, fn):
        self._posted.emit(fn)

    @staticmethod
    def _call(fn):
        fn()


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

        self._build_controls()
        self._build_menus()
        self.status = QtWidgets.QLabel("open a recording (File > Open) or connect a board (Live > Connect)")
        self.statusBar().addPermanentWidget(self.status, 1)
        self.reader: SerialReader | None = None
        self.live_frame_arrived.connect(self._take_live_frame)
        self._live_timer = QtCore.QTimer(self, interval=250)
        self._live_timer.timeout.connect(self._update_live_status)

        self._play_timer = QtCore.QTimer(self, interval=15)
        self._play_timer.timeout.connect(self._play_tick)
        self._play_origin = (0.0, 0.0)  # (wall clock, recording time) when playback started

        self.model.recording_changed.connect(self._on_recording)
        self.model.frame_changed.connect(self._on_frame)
        self.model.parameters_changed.connect(self._sync_parameters)
        self.model.display_changed.connect(self._sync_display)
        self.model.solved.connect(self._on_solved)
        self.model.solve_failed.connect(self._on_solve_failed)
        self._set_enabled(False)

    # -- widgets -----------------------------------------------------------------------

    def _build_controls(self):
        panel = QtWidgets.QWidget()
        form = QtWidgets.QVBoxLayout(panel)

        params = QtWidgets.QGroupBox("Parameters")
        grid = QtWidgets.QGridLayout(params)
        self.auto_box = QtWidgets.QCheckBox("Auto (efficiency maximum)")
        self.auto_box.setChecked(True)
        self.auto_box.toggled.connect(self._auto_toggled)
        grid.addWidget(self.auto_box, 0, 0, 1, 3)
        self.ratio_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.ratio_slider.setRange(0, round(MAX_SHEAR_RATIO * 100))
        self.ratio_spin = QtWidgets.QDoubleSpinBox(decimals=2, singleStep=0.01, maximum=MAX_SHEAR_RATIO)
        self.direction_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.direction_slider.setRange(-180, 180)
        self.direction_spin = QtWidgets.QDoubleSpinBox(decimals=1, singleStep=1.0, minimum=-180.0,
                                                       maximum=180.0, wrapping=True, suffix=" deg")
        grid.addWidget(QtWidgets.QLabel("shear ratio"), 1, 0)
        grid.addWidget(self.ratio_slider, 1, 1)
        grid.addWidget(self.ratio_spin, 1, 2)
        grid.addWidget(QtWidgets.QLabel("direction"), 2, 0)
        grid.addWidget(self.direction_slider, 2, 1)
        grid.addWidget(self.direction_spin, 2, 2)
        self.ratio_slider.valueChanged.connect(lambda v: self._manual(shear_ratio=v / 100))
        self.ratio_spin.valueChanged.connect(lambda v: self._manual(shear_ratio=v))
        self.direction_slider.valueChanged.connect(lambda v: self._manual(shear_direction=math.radians(v)))
        self.direction_spin.valueChanged.connect(lambda v: self._manual(shear_direction=math.radians(v)))
        self.kernel_box = QtWidgets.QComboBox()
        # the solver's list, its default first: a kernel added there appears here
        self.kernel_box.addItems(list(KERNELS))
        self.kernel_box.setCurrentText(self.model.kernel)
        self.kernel_box.setToolTip(KERNEL_HELP)
        self.kernel_box.currentTextChanged.connect(self._kernel_changed)
        grid.addWidget(QtWidgets.QLabel("kernel"), 3, 0)
        grid.addWidget(self.kernel_box, 3, 1, 1, 2)
        self.quality_box = QtWidgets.QComboBox()
        self.quality_box.addItem("standard (exact, efficiency maximum)", None)
        self.quality_box.setToolTip("Presets from the measured speed/accuracy front of this geometry "
                                    "(tactile-tradeoff): time per frame and median error")
        self.quality_box.currentIndexChanged.connect(self._quality_changed)
        grid.addWidget(QtWidgets.QLabel("quality"), 4, 0)
        grid.addWidget(self.quality_box, 4, 1, 1, 2)
        # the geometry the forces are solved on, nu included: the layer kernel depends on it
        self.geometry_label = QtWidgets.QLabel("")
        self.geometry_label.setWordWrap(True)
        self.geometry_label.setToolTip("From the recording or the sensor layout file: taxels, pitch, "
                                       "elastomer thickness, Poisson ratio nu, taxel size")
        grid.addWidget(self.geometry_label, 5, 0, 1, 3)
        form.addWidget(params)

        shown = QtWidgets.QGroupBox("Display")
        grid = QtWidgets.QGridLayout(shown)
        self.map_box = QtWidgets.QComboBox()
        for label, _ in MAP_CHOICES:
            self.map_box.addItem(label)
        self.map_box.currentIndexChanged.connect(lambda i: self.model.set_display(map=MAP_CHOICES[i][1]))
        self.arrows_box = QtWidgets.QCheckBox("force arrows")
        self.arrows_box.setChecked(True)
        self.arrows_box.toggled.connect(lambda on: self.model.set_display(arrows=on))
        self.resultant_box = QtWidgets.QCheckBox("resultant")
        self.resultant_box.setChecked(True)
        self.resultant_box.toggled.connect(lambda on: self.model.set_display(resultant=on))
        self.scale_spin = QtWidgets.QDoubleSpinBox(decimals=1, maximum=1e6, singleStep=5.0, suffix=" mm/N")
        self.scale_spin.valueChanged.connect(lambda v: self.model.set_display(arrow_scale=v / 1e3))
        self.threshold_spin = QtWidgets.QDoubleSpinBox(decimals=2, maximum=1e6, singleStep=1.0, suffix=" mN")
        self.threshold_spin.valueChanged.connect(lambda v: self.model.set_display(threshold=v / 1e3))
        self.range_box = QtWidgets.QCheckBox("automatic colour range")
        self.range_box.setChecked(True)
        self.range_box.toggled.connect(lambda on: self.model.set_display(auto_range=on))
        self.range_spin = QtWidgets.QDoubleSpinBox(decimals=2, maximum=1e6, singleStep=1.0, suffix=" kPa")
        self.range_spin.valueChanged.connect(lambda v: self.model.set_display(range_max=v * 1e3))
        top = QtWidgets.QPushButton("Top")
        top.clicked.connect(lambda: self._camera("top"))
        iso = QtWidgets.QPushButton("Iso")
        iso.clicked.connect(lambda: self._camera("iso"))
        grid.addWidget(QtWidgets.QLabel("map"), 0, 0)
        grid.addWidget(self.map_box, 0, 1, 1, 2)
        grid.addWidget(self.arrows_box, 1, 0, 1, 2)
        grid.addWidget(self.resultant_box, 1, 2)
        grid.addWidget(QtWidgets.QLabel("arrow scale"), 2, 0)
        grid.addWidget(self.scale_spin, 2, 1, 1, 2)
        grid.addWidget(QtWidgets.QLabel("hide below"), 3, 0)
        grid.addWidget(self.threshold_spin, 3, 1, 1, 2)
        grid.addWidget(self.range_box, 4, 0, 1, 3)
        grid.addWidget(QtWidgets.QLabel("range max"), 5, 0)
        grid.addWidget(self.range_spin, 5, 1, 1, 2)
        grid.addWidget(QtWidgets.QLabel("camera"), 6, 0)
        grid.addWidget(top, 6, 1)
        grid.addWidget(iso, 6, 2)
        form.addWidget(shown)

        playback = QtWidgets.QGroupBox("Playback")
        grid = QtWidgets.QGridLayout(playback)
        self.play_button = QtWidgets.QPushButton("Play")
        self.play_button.setCheckable(True)
        self.play_button.toggled.connect(self._play_toggled)
        back = QtWidgets.QPushButton("<")
        back.clicked.connect(lambda: self.step(-1))
        forward = QtWidgets.QPushButton(">")
        forward.clicked.connect(lambda: self.step(1))
        self.frame_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.frame_slider.valueChanged.connect(self._frame_slider_moved)
        self.speed_box = QtWidgets.QComboBox()
        self.speed_box.addItems([f"{s:g}x" for s in SPEEDS])
        self.speed_box.setCurrentIndex(SPEEDS.index(1.0))
        self.speed_box.currentIndexChanged.connect(lambda _: self._restart_clock())
        self.loop_box = QtWidgets.QCheckBox("loop")
        self.time_label = QtWidgets.QLabel("-")
        grid.addWidget(back, 0, 0)
        grid.addWidget(self.play_button, 0, 1)
        grid.addWidget(forward, 0, 2)
        grid.addWidget(self.speed_box, 0, 3)
        grid.addWidget(self.loop_box, 0, 4)
        grid.addWidget(self.frame_slider, 1, 0, 1, 5)
        grid.addWidget(self.time_label, 2, 0, 1, 5)
        form.addWidget(playback)
        self._playback = playback

        self._live_box = QtWidgets.QGroupBox("Live")
        box = QtWidgets.QVBoxLayout(self._live_box)
        self.live_status = QtWidgets.QLabel("")
        self.live_status.setWordWrap(True)
        box.addWidget(self.live_status)
        buttons = QtWidgets.QHBoxLayout()
        for label, slot in (("Tare", lambda: self.tare(50)), ("Record...", self.record_dialog),
                            ("Stop recording", self.stop_recording), ("Disconnect", self.disconnect_live)):
            button = QtWidgets.QPushButton(label)
            button.clicked.connect(slot)
            buttons.addWidget(button)
        box.addLayout(buttons)
        self._live_box.hide()
        form.addWidget(self._live_box)
        form.addStretch(1)

        dock = QtWidgets.QDockWidget("Controls", self)
        dock.setFeatures(QtWidgets.QDockWidget.DockWidgetFeature.NoDockWidgetFeatures)
        dock.setWidget(panel)
        self.addDockWidget(QtCore.Qt.DockWidgetArea.RightDockWidgetArea, dock)
        self._controls = panel

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
        self._playback.setEnabled(on and not live)
        for action in self._exports:
            action.setEnabled(on)
        self._exports[2].setEnabled(on and not live)  # a live source has no "whole recording"
        self._live_box.setVisible(live)
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
            self.set_playing(False)
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

    def _quality_changed(self, index):
        configuration = self.quality_box.itemData(index)
        if configuration == self.model.configuration or not self.model.is_open:
            self.model.configuration = configuration
            return
        self.model.configuration = configuration
        self._rebuild(self.model.kernel, f"Setting up '{self.quality_box.currentText().split(':')[0]}'...")

    def _measure_if_open(self):
        # measuring builds every configuration, full ones included: keep it to skins where
        # that takes seconds (tactile-tradeoff measures larger ones from the command line)
        if self.isVisible() and self.model.is_open and self.model.grid.size <= PRESET_LIMIT:
            self.measure_presets()

    def measure_presets(self):
        """Measure the speed/accuracy front for the shown geometry in the background; fill the
        quality presets with their measured cost and error (emits ``presets_measured``)."""
        grid = self.model.grid
        key = (grid.shape, grid.pitch, grid.thickness, grid.poisson_ratio, grid.sensor_size)
        if self._measured_for == (key, "done"):
            self.presets_measured.emit()
            return
        if self._measured_for == (key, "measuring"):
            return  # presets_measured comes when it is done
        self._measured_for = (key, "measuring")

        def work(progress):
            def check(_):
                if not progress(0, 0):  # the window closed: stop after this configuration
                    raise export.ExportCancelled("presets not measured: the window closed")

            cases = tradeoff.default_cases(grid, noises=(0.01,))
            # no memory tracing here: tracemalloc is not safe beside the reader thread
            measured = tradeoff.measure_all(grid, cases=cases, repeat=1, progress=check, memory=False)
            return tradeoff.presets(measured)

        def done(chosen):
            self.quality_box.blockSignals(True)
            while self.quality_box.count() > 1:
                self.quality_box.removeItem(1)
            for label, m in chosen.items():
                self.quality_box.addItem(f"{label}: {m.name}, {m.frame_ms:.2f} ms/frame, "
                                         f"error {100 * tradeoff.error_of(m):.1f}% of |F|", m.configuration)
            self.quality_box.blockSignals(False)
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
        self.geometry_label.setText(geometry_text(self.model.grid))
        self.kernel_box.blockSignals(True)
        self.kernel_box.setCurrentText(self.model.kernel)
        self.kernel_box.blockSignals(False)
        if self.model.live:
            self.setWindowTitle(f"tactile-viewer - live: {self.model.live_label}")
            self.time_label.setText("live")
        else:
            recording = self.model.recording
            self.frame_slider.blockSignals(True)
            self.frame_slider.setRange(0, len(recording) - 1)
            self.frame_slider.setValue(0)
            self.frame_slider.blockSignals(False)
            name = self.model.path.name if self.model.path else "recording"
            self.setWindowTitle(f"tactile-viewer - {name}")
        self._set_enabled(True)
        if self.model.live and self.model.live_frame is None:
            self.ready.emit()  # no frame yet: the first to arrive is solved and drawn as it comes
        else:
            self._first_frame = True  # ready follows with its first solve
        # the quality presets of this geometry, measured in the background once things settle
        QtCore.QTimer.singleShot(1000, self._measure_if_open)

    # -- parameters ---------------------------------------------------------------------------

    def _manual(self, **changes):
        if not self.model.is_open:
            return
        self.model.set_parameters(**changes)

    def _auto_toggled(self, on):
        self.model.set_auto(on)

    def _sync_parameters(self):
        # model -> widgets, without echoing back
        widgets = (self.auto_box, self.ratio_slider, self.ratio_spin, self.direction_slider,
                   self.direction_spin)
        for w in widgets:
            w.blockSignals(True)
        ratio, direction = self.model.shear_ratio, self.model.shear_direction
        last = self.model.last
        if self.model.auto and last is not None and last.auto:
            # Auto shows what it found; the user's manual values stay in the model
            ratio, direction = last.result.shear_ratio, last.result.shear_direction
        degrees = math.degrees(direction)
        self.auto_box.setChecked(self.model.auto)
        self.ratio_slider.setValue(round(ratio * 100))
        self.ratio_spin.setValue(ratio)
        self.direction_slider.setValue(round(degrees))
        self.direction_spin.setValue(degrees)
        for w in widgets:
            w.blockSignals(False)

    def _sync_display(self):
        d = self.model.display
        widgets = (self.map_box, self.arrows_box, self.resultant_box, self.scale_spin, self.threshold_spin,
                   self.range_box, self.range_spin)
        for w in widgets:
            w.blockSignals(True)
        self.map_box.setCurrentIndex([key for _, key in MAP_CHOICES].index(d.map))
        self.arrows_box.setChecked(d.arrows)
        self.resultant_box.setChecked(d.resultant)
        self.scale_spin.setValue(d.arrow_scale * 1e3)
        self.threshold_spin.setValue(d.threshold * 1e3)
        self.range_box.setChecked(d.auto_range)
        self.range_spin.setValue(d.range_max / 1e3)
        self.range_spin.setEnabled(not d.auto_range)
        for w in widgets:
            w.blockSignals(False)
        if self.model.last is not None:
            last = self.model.last
            self.scene.update(last.stress, last.result, d, render=False)
            self._draw()

    def _camera(self, preset):
        if self.scene.grid is not None:
            self.scene.camera(preset)
            self.plotter.render()

    # -- solving -------------------------------------------------------------------------------

    def _on_solve_failed(self, message):
        self.statusBar().showMessage(message, 10000)

    def _on_solved(self, solved):
        self.scene.update(solved.stress, solved.result, self.model.display, render=False)
        if solved.auto:
            self._sync_parameters()
        r = solved.result
        total = r.total_force
        if r.normal_only:
            shear = "normal only"  # the fast preset
        elif solved.auto and not r.shear_detected:
            shear = "auto: no shear signature"
        else:
            shear = (f"{'auto' if solved.auto else 'manual'}: mu {r.shear_ratio:.2f}, "
                     f"theta {math.degrees(r.shear_direction):+.0f} deg")
        if len(r.contacts) > 1:  # solved contact by contact: each has its own parameters
            shear += "  (" + "; ".join(
                f"contact {k + 1}: mu {c.shear_ratio:.2f}, theta "
                f"{math.degrees(c.shear_direction):+.0f}" for k, c in enumerate(r.contacts)) + ")"
        where = (f"seq {solved.frame}" if solved.frame >= 0 else "live") if self.model.live \
            else f"frame {solved.frame + 1}/{len(self.model.recording)}"
        self.status.setText(
            f"{where}  t {solved.time:.3f} s  |  "
            f"solve {solved.solve_ms:.2f} ms  |  {shear}  |  efficiency {r.efficiency:.3f}  "
            f"residual {r.residual:.1e}  condition {r.condition:.3g}"
            f"{' (damped)' if r.regularized else ''}  |  "
            f"Fz {total[2] * 1e3:.1f} mN  Ft {math.hypot(total[0], total[1]) * 1e3:.1f} mN")
        if not self.model.live:
            self.time_label.setText(f"frame {solved.frame + 1} of {len(self.model.recording)},  "
                                    f"t = {solved.time:.3f} s")
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

    # -- playback ------------------------------------------------------------------------------

    def _on_frame(self, index):
        self.frame_slider.blockSignals(True)
        self.frame_slider.setValue(index)
        self.frame_slider.blockSignals(False)

    def _frame_slider_moved(self, value):
        self.model.set_frame(value)
        self._restart_clock()

    def step(self, delta: int):
        if self.model.recording is None:
            return
        self.model.set_frame(min(max(self.model.frame + delta, 0), len(self.model.recording) - 1))
        self._restart_clock()

    @property
    def speed(self) -> float:
        return SPEEDS[self.speed_box.currentIndex()]

    def set_playing(self, on: bool):
        self.play_button.setChecked(on)

    def _play_toggled(self, on):
        self.play_button.setText("Pause" if on else "Play")
        if on and self.model.recording is not None:
            if self.model.frame == len(self.model.recording) - 1:
                self.model.set_frame(0)
            self._restart_clock()
            self._play_timer.start()
        else:
            self._play_timer.stop()

    def _restart_clock(self):
        if self.model.recording is not None:
            self._play_origin = (time.perf_counter(), float(self.model.recording.t[self.model.frame]))

    def _play_tick(self):
        # Show the frame whose time has come: slow rendering skips frames
        # rather than slowing the recording down.
        recording = self.model.recording
        t = recording.t
        wall, start = self._play_origin
        now = start + (time.perf_counter() - wall) * self.speed
        looping = self.loop_box.isChecked() and len(recording) > 1
        if looping and now > t[-1]:
            # the recording repeats with one mean frame interval after its last frame
            period = (t[-1] - t[0]) * len(recording) / (len(recording) - 1)
            if period > 0:
                now = t[0] + (now - t[0]) % period
        index = int(min(max(t.searchsorted(now, side="right") - 1, 0), len(recording) - 1))
        if index != self.model.frame:
            self.model.set_frame(index)
        if index == len(recording) - 1 and not looping:
            self.set_playing(False)

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
            except OSError as exc:
                self._error("Cannot save screenshot", f"{path}: {exc.strerror or exc}")

    def export_screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> Path:
        """Save the scene as PNG plus a JSON sidecar naming the recording, frame and parameters."""
        path = Path(path).with_suffix(".png")
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
            self.set_playing(False)
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
        self.live_status.setText("")

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
        rejected = reader.rejected()
        parts = [f"{reader.url} ({reader.fmt}): {reader.state}", f"{stats.rate(reader.now()):.0f} fps",
                 f"received {stats.received}", f"lost {stats.lost}"]
        if rejected or reader.decoder.skipped_bytes:
            parts.append("rejected " + (", ".join(f"{k} {v}" for k, v in sorted(rejected.items())) or "0")
                         + f"; skipped {reader.decoder.skipped_bytes} B")
        if reader.reconnects:
            parts.append(f"reconnected {reader.reconnects}x")
        if reader.failures:
            parts.append(f"{reader.failures} chunks failed: {reader.error}")
        if reader.calibration.taring:
            parts.append("taring")
        if reader.recorder is not None:
            parts.append(f"recording {reader.recorder.path.name} ({reader.recorder.written} frames saved)")
        self.live_status.setText("\n".join(parts))

    def closeEvent(self, event):
        self._stop_reader()
        self._play_timer.stop()
        self.model.close()
        for task in list(self._tasks):
            task.cancel()
            task.wait()
        self.plotter.close()
        super().closeEvent(event)

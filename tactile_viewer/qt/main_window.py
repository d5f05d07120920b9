"""The main window: composes the panels, the scene and the menus; opens sources.

Data flows one way: a :class:`~tactile_viewer.sources.source.Source` produces frames,
the :class:`~tactile_viewer.model.viewer_model.ViewerModel` solves them on its worker
thread, the :class:`~tactile_viewer.render.scene.Scene` draws the results. The panels
only set model fields and follow its events. Slow one-off work (factoring a
geometry, exporting a whole recording, measuring the quality presets) runs in
the window's :class:`~tactile_viewer.qt.tasks.TaskRunner`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

os.environ.setdefault("QT_API", "pyqt6")

from PyQt6 import QtCore, QtGui, QtWidgets  # noqa: E402
from pyvistaqt import QtInteractor  # noqa: E402

from ..io.files import is_recording_path
from ..io.recording import Recording, RecordingError
from ..model.captions import recording_warnings, window_title
from ..model.solver_build import SolverBuild
from ..model.viewer_model import ViewerModel
from ..render.scene import Scene
from ..sources.source import RecordingSource, Source
from .bag_dialog import ask_recording_path, load_asking
from .contacts_panel import ContactsPanel
from .control_column import ControlColumn
from .display_panel import DisplayPanel
from .export_dialogs import ExportActions
from .hover import TaxelReadout
from .live_panel import LivePanel
from .parameters_panel import ParametersPanel
from .playback_panel import PlaybackPanel
from .preferences import (
    RecentFiles,
    remember_folder,
    save_view,
    save_window_state,
    saved_view,
    saved_window_state,
)
from .presets import PresetMeasurer
from .quick_help import HELP_HTML, about_text
from .status_line import status_details, status_text
from .tasks import Dispatcher, TaskRunner
from .text_line import TextLine
from .time_plots import TimePlotsDock

log = logging.getLogger(__name__)

__all__ = ["MainWindow"]

SETTLE_S = 0.03  # the longest a control waits for its solve (docs/architecture.md)


TITLE_BAR_PX = 40  # room left for the window manager's title bar when the window is first sized
TIME_PLOTS_PX = 240  # the time plots' first height: the scene keeps most of a 760 px window


def first_size(width: int, height: int) -> tuple[int, int]:
    """The window's size on its first run on a screen of ``width`` x ``height`` free pixels.

    Most of a large screen (it opened at 1280x760 on 1920x1080), all of a laptop's 1280x800 but
    its title bar, and never more than the screen.
    """
    return (min(width, max(1280, round(0.8 * width))),
            min(height - TITLE_BAR_PX, max(760, round(0.85 * height))))


class MainWindow(QtWidgets.QMainWindow):
    """The viewer window.

    Signals
    -------
    ready
        A source is installed and its first frame drawn (a live source without
        frames yet: installed).
    rendered
        A frame is on screen (emitted when the scene widget's repaint after a
        solve or a display change has been swapped to the window).
    """

    ready = QtCore.pyqtSignal()
    rendered = QtCore.pyqtSignal()

    def __init__(self, parent=None):
        super().__init__(parent)
        self.setWindowTitle("tactile-viewer")
        self._place()
        self._dispatcher = Dispatcher(self)
        # the model solves on its own worker thread; a solve done within SETTLE_S is drawn in the
        # same repaint as the slider or frame change that asked for it; live and playing frames are
        # taken once the last one is on screen
        self.model = ViewerModel(dispatch=self._dispatcher.post, settle=SETTLE_S, pace=True)
        self.tasks = TaskRunner(self, self._error)
        self._first_frame = False  # a source was installed and its first frame is not drawn yet
        self._drawing = False

        central = QtWidgets.QFrame(self)
        layout = QtWidgets.QVBoxLayout(central)
        layout.setContentsMargins(0, 0, 0, 0)
        self.plotter = QtInteractor(central, auto_update=False)
        self.scene = Scene(self.plotter)
        self.plotter.interactor.frameSwapped.connect(self._frame_swapped)
        self.parameters = ParametersPanel(self.model)
        self.parameters.kernel_chosen.connect(lambda kernel: self._rebuild(kernel, self.model.configuration))
        self.parameters.quality_chosen.connect(lambda chosen: self._rebuild(self.model.kernel, chosen))
        self.display_panel = DisplayPanel(self.model)
        self.display_panel.camera.connect(self._camera)
        self.contacts_panel = ContactsPanel(self.model)
        self.playback = PlaybackPanel(self.model)
        self.live_panel = LivePanel(self.model, install=self.show_source, error=self._error,
                                    notify=self._notify)
        self.rendered.connect(self.live_panel.frame_drawn)
        # the title said "live" after a disconnect
        self.live_panel.disconnected.connect(lambda: self._title(disconnected=True))
        # the title says a recording runs, whatever part of the window is in view
        self.live_panel.recording_to.connect(self._on_recording_to)
        self.presets = PresetMeasurer(self.model, self.parameters, self.tasks, notify=self._notify,
                                      parent=self)
        self.exports = ExportActions(self, self.model, self.scene, self.tasks, error=self._error,
                                     notify=self._notify)
        # the whole recording over time, under the scene (View > Time plots hides it)
        self.time_plots = TimePlotsDock(self.model, self.tasks, self, error=self._error, notify=self._notify)
        self.addDockWidget(QtCore.Qt.DockWidgetArea.BottomDockWidgetArea, self.time_plots)
        # the controls keep the window's full height; the time plots sit under the scene only
        self.setCorner(QtCore.Qt.Corner.BottomRightCorner, QtCore.Qt.DockWidgetArea.RightDockWidgetArea)
        self.resizeDocks([self.time_plots], [TIME_PLOTS_PX], QtCore.Qt.Orientation.Vertical)

        layout.addWidget(self.live_panel.banner)
        layout.addWidget(self.plotter.interactor, 1)
        # the timeline (a recording) or the live bar (a board) under the scene, never scrolled away
        layout.addWidget(self.playback)
        layout.addWidget(self.live_panel)
        self.setCentralWidget(central)
        self._controls = QtWidgets.QWidget()
        column = QtWidgets.QVBoxLayout(self._controls)
        column.addWidget(self.parameters)
        column.addWidget(self.display_panel)
        column.addWidget(self.contacts_panel, 1)  # the table takes the height left
        # on a short screen the column scrolls rather than push the status bar off it
        dock = QtWidgets.QDockWidget("Controls", self)
        dock.setObjectName("controls")  # saveState/restoreState find the dock by it
        dock.setFeatures(QtWidgets.QDockWidget.DockWidgetFeature.NoDockWidgetFeatures)
        dock.setWidget(ControlColumn(self._controls))
        self.addDockWidget(QtCore.Qt.DockWidgetArea.RightDockWidgetArea, dock)
        self._build_menus()
        # a normal widget, not a permanent one: a passing message ("saved ...") replaces it for its
        # few seconds instead of being drawn underneath it; a long line is cut with an ellipsis
        # rather than widening the window, and a new one (every frame) repaints only itself
        self.status = TextLine("open a recording (File > Open) or connect a board (Live > Connect)")
        self.statusBar().addWidget(self.status, 1)
        # the taxel under the mouse (or pinned by a click), beside the frame's status
        self.readout_label = QtWidgets.QLabel("")
        self.readout_label.setToolTip("The taxel under the mouse; click a taxel to keep it, click it "
                                      "again to let go")
        self.statusBar().addPermanentWidget(self.readout_label)
        self.readout = TaxelReadout(self.plotter.interactor, self.scene, self.model, parent=self)
        self.readout.text_changed.connect(self.readout_label.setText)

        self.model.recording_changed.connect(self._on_source)
        self.model.display_changed.connect(self._redraw)
        self.model.solved.connect(self._on_solved)
        self.model.solve_failed.connect(lambda message: self.statusBar().showMessage(message, 10000))
        self.model.message.connect(self._on_message)
        self.setAcceptDrops(True)  # a recording dropped anywhere on the window opens
        docks = saved_window_state("docks")
        if docks is not None and not self.restoreState(docks):  # time plots shown or hidden, their size
            log.warning("settings: the saved dock layout could not be restored; using the default")
        self._restore_view()
        self._set_enabled(False)

    def _build_menus(self):
        menu = self.menuBar().addMenu("&File")
        action = menu.addAction("&Open recording...", self.open_dialog)
        action.setShortcut(QtGui.QKeySequence.StandardKey.Open)
        self.recent_menu = menu.addMenu("Open &recent")
        self.recent_menu.aboutToShow.connect(self._fill_recent)
        self._fill_recent()
        self._exports = self.exports.add_actions(menu)
        menu.addSeparator()
        menu.addAction("&Quit", self.close).setShortcut(QtGui.QKeySequence.StandardKey.Quit)
        self.live_panel.add_actions(self.menuBar().addMenu("&Live"))
        # a live recording keeps the raw values: its tare can be retaken, cleared or restored later
        tare = self.menuBar().addMenu("&Recording")
        self.tare_actions = {
            how: tare.addAction(label, lambda how=how: self.retare(how))
            for how, label in (("here", "&Tare from this frame (50 frames)"), ("clear", "&Clear tare"),
                               ("recorded", "&Restore the tares taken while recording"))}
        view = self.menuBar().addMenu("&View")
        # as the panel's buttons: Top also lays the arrows flat to show the shear, Iso stands them up
        view.addAction("&Top", lambda: self.display_panel.view("top"))
        view.addAction("&Iso", lambda: self.display_panel.view("iso"))
        view.addSeparator()
        view.addAction(self.time_plots.toggleViewAction())
        self._build_playback_menu()
        self._build_help_menu()

    def _build_playback_menu(self):
        menu = self.menuBar().addMenu("&Playback")
        self.playback_actions = self.playback.add_actions(menu)
        menu.addSeparator()
        self.auto_action = self.parameters.add_auto_action(menu)

    def _build_help_menu(self):
        menu = self.menuBar().addMenu("&Help")
        menu.addAction("Quick &help", self.show_help).setShortcut(QtGui.QKeySequence.StandardKey.HelpContents)
        menu.addAction("&About tactile-viewer", self.show_about)

    def _fill_recent(self):
        self.recent_menu.clear()
        paths = RecentFiles().paths()
        for number, path in enumerate(paths, start=1):
            action = self.recent_menu.addAction(f"&{number} {path.name}", lambda path=path: self.open(path))
            action.setToolTip(str(path))
            action.setStatusTip(str(path))
        if paths:
            self.recent_menu.addSeparator()
            self.recent_menu.addAction("&Clear the list", RecentFiles().clear)
        self.recent_menu.setEnabled(bool(paths))
        self.recent_menu.setToolTipsVisible(True)

    def _set_enabled(self, on: bool):
        live = self.model.live
        self._controls.setEnabled(on)
        self.playback.setEnabled(on and not live)
        self.playback.setVisible(not live)
        for action in self.playback_actions.values():
            action.setEnabled(on and not live)
        self.auto_action.setEnabled(on)
        for action in self._exports:
            action.setEnabled(on)
        for action in self._exports[2:]:  # whole recording, movie, Foxglove: a live source has no recording
            action.setEnabled(on and not live)
        raw = on and self.model.retarable  # a recording that keeps raw values (never a live source)
        for action in self.tare_actions.values():
            action.setEnabled(raw)

    # -- sources ------------------------------------------------------------------------

    def open_dialog(self):
        path = ask_recording_path(self)
        if path:
            self.open(path)

    def open(self, path, **bag) -> bool:
        """Load a recording or a ROS 2 bag (``bag``: its ``layout``, ``topic``, ``field``; a dialog
        asks for what is missing); on failure show the error and keep what was shown.

        A recording that opens goes first in File > Open recent and its folder
        is where the next open dialog starts; one that is gone leaves the list.
        """
        try:
            recording = load_asking(self, path, **bag)
        except RecordingError as exc:
            if not Path(path).exists():
                RecentFiles().remove(path)
            self._error("Cannot open recording", str(exc))
            return False
        if recording is None:  # the bag's dialog was cancelled
            return False
        RecentFiles().add(path)
        remember_folder(path)
        return self.show_source(RecordingSource(recording, path))

    # -- drag and drop -----------------------------------------------------------------

    @staticmethod
    def dropped_recording(mime: QtCore.QMimeData) -> Path | None:
        """The one local recording file (by its suffix) or ROS 2 bag in a drag's data, else None."""
        urls = mime.urls() if mime.hasUrls() else []
        paths = [Path(u.toLocalFile()) for u in urls if u.isLocalFile()]
        return paths[0] if len(paths) == 1 and is_recording_path(paths[0]) else None

    def dragEnterEvent(self, event):
        if self.dropped_recording(event.mimeData()) is not None:
            event.acceptProposedAction()
        else:
            event.ignore()

    def dragMoveEvent(self, event):
        self.dragEnterEvent(event)

    def dropEvent(self, event):
        path = self.dropped_recording(event.mimeData())
        if path is None:
            event.ignore()
            return
        event.acceptProposedAction()
        # opened after the drop returns: the drag source is not kept waiting on the file's load
        QtCore.QTimer.singleShot(0, lambda: self.open(path))

    def show_recording(self, recording: Recording, path=None) -> bool:
        """Show an in-memory recording (the tests use this)."""
        return self.show_source(RecordingSource(recording, path))

    def show_source(self, source: Source) -> bool:
        """Build the solver for ``source`` in a task (slow for large grids), then show it.

        The source shown so far stays until then; ``source`` is stopped if the
        build fails or the window closes first.
        """
        grid = source.grid
        shape = "x".join(map(str, grid.shape[::-1])) if len(grid.shape) == 2 else f"{grid.size}-taxel"
        task = self._install(SolverBuild.for_source(self.model, source), f"Factoring the {shape} geometry...")
        task.failed.connect(lambda _: source.stop())
        task.succeeded.connect(lambda _: source.stop() if self.tasks.closed else None)
        return True

    def _rebuild(self, kernel, configuration):
        # the same source with another kernel or quality: its frame stays
        other_kernel = kernel != self.model.kernel
        build = SolverBuild.for_choice(self.model, kernel, configuration)
        if build is None:
            return  # nothing open (the preset waits for the next source), or already in use
        label = (f"Factoring for the {kernel} kernel..." if other_kernel else
                 f"Setting up '{self.parameters.quality_box.currentText().split(':')[0]}'...")
        self._install(build, label)

    def _install(self, build: SolverBuild, label: str):
        # the one path from a source to the screen: build its solver in a task, then show it
        # (dropped by the model when it was a rebuild for a source replaced meanwhile)
        return self.tasks.run(lambda progress: build.build(),
                              lambda solver: build.install(self.model, solver), label, determinate=False)

    def _on_source(self):
        self.scene.set_grid(self.model.grid)
        self._title()
        self._set_enabled(True)
        for title, text in recording_warnings(self.model.source, self.model.recording):
            self._on_message("warning", title, text)
        if self.model.current is None and self.model.live:
            self.ready.emit()  # no frame yet: the first to arrive is solved and drawn as it comes
        else:
            self._first_frame = True  # ready follows with its first solve

    def _on_recording_to(self, path: str):
        source = self.model.source
        if source is not None and source.live and source.state != "stopped":
            self._title(recording_to=path)

    def _title(self, *, recording_to: str = "", disconnected: bool = False):
        # the one place the title is set (the words: model.captions.window_title)
        self.setWindowTitle(window_title(self.model.source, self.model.recording, recording_to=recording_to,
                                         disconnected=disconnected))

    def retare(self, how: str) -> bool:
        """Retake ("here"), clear or restore ("recorded") the tare of the recording shown (not its file)."""
        try:
            done = self.model.retare(how)
        except ValueError as exc:
            self._error("Cannot change the tare", str(exc))
            return False
        self._notify(f"showing {done}; the file keeps its raw values")
        return True

    # -- drawing ------------------------------------------------------------------------------

    def _on_solved(self, solved):
        self.scene.update(self.model.drawn, self.model.display, render=False)
        self.status.setText(status_text(solved, self.model))
        self.status.setToolTip(status_details(solved))
        self._draw()
        if not self._paints():
            # no paint will say the result is on screen: the next frame is taken after every slot of
            # this result has run (playback, a live board and its LSL publishing go on while hidden)
            QtCore.QTimer.singleShot(0, self.model.shown)
        if self._first_frame:
            self._first_frame = False
            self.ready.emit()

    def _redraw(self):
        # the display settings changed: draw the last result again
        if self.model.drawn is not None:
            self.scene.update(self.model.drawn, self.model.display, render=False)
            self._draw()

    def _draw(self):
        # Ask Qt to repaint the scene widget rather than rendering here: its
        # paint always renders, so an explicit render would draw every frame twice.
        self._drawing = True
        self.plotter.interactor.update()

    def _paints(self) -> bool:
        # hidden or minimized, the window paints nothing until it is shown again
        return self.isVisible() and not self.isMinimized()

    def hideEvent(self, event):
        # hidden or minimized (a spontaneous hide) with a result not yet painted: a frame waiting
        # for that paint (pace) is taken now, and the results that follow go on without one
        super().hideEvent(event)
        self.model.shown()

    def _frame_swapped(self):
        if self._drawing:
            self._drawing = False
            self.rendered.emit()
        self.model.shown()

    def _camera(self, preset):
        if self.scene.grid is not None:
            self.scene.camera(preset)
            self.plotter.render()

    # -- telling the user ------------------------------------------------------------------------

    def _on_message(self, level, title, text):
        if level == "error":
            self._error(title, text)
        elif level == "warning":
            log.warning("%s: %s", title, text)
            self.statusBar().showMessage(f"Warning: {title} {text}", 20000)
        else:
            self._notify(f"{title}: {text}")

    def _notify(self, text):
        self.statusBar().showMessage(text, 5000)

    def _error(self, title, message):
        log.warning("%s: %s", title, message)
        QtWidgets.QMessageBox.critical(self, title, message)

    # -- help -------------------------------------------------------------------------------------

    def show_help(self):
        """Help > Quick help: the controls, the keys and what the numbers mean (non-modal)."""
        box = QtWidgets.QMessageBox(QtWidgets.QMessageBox.Icon.NoIcon, "tactile-viewer: quick help",
                                    HELP_HTML, QtWidgets.QMessageBox.StandardButton.Close, self)
        box.setTextFormat(QtCore.Qt.TextFormat.RichText)
        box.setModal(False)
        box.show()
        self.help_box = box
        return box

    def show_about(self):
        """Help > About: the version, the libraries it runs on and where the log is."""
        QtWidgets.QMessageBox.about(self, "About tactile-viewer", about_text())

    def _restore_view(self):
        changes, playback = saved_view()
        if changes:
            self.model.set_display(**changes)
            self.display_panel.follow()
        self.playback.restore(**playback)

    def _place(self):
        # where the user left it; the first time, a size that fits the screen with its title bar
        geometry = saved_window_state("geometry")
        if geometry is not None and self.restoreGeometry(geometry):
            return
        screen = self.screen().availableGeometry()
        self.resize(*first_size(screen.width(), screen.height()))

    def closeEvent(self, event):
        save_window_state("geometry", self.saveGeometry())
        save_window_state("docks", self.saveState())
        save_view(self.model.display, speed=self.playback.speed, loop=self.playback.loop_box.isChecked())
        self.playback.stop()
        self.live_panel.cancel_connecting()  # an LSL connection being made: waited for, its source stopped
        self.tasks.close()  # first: a result arriving while the source stops is dropped
        self.model.close()
        self.plotter.close()
        super().closeEvent(event)

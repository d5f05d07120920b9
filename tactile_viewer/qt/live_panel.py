"""The live bar: connect a board, tare, record, disconnect; its state and the NO DATA banner.

The panel builds a :class:`~tactile_viewer.sources.serial_reader.SerialReader` and hands
it to the window's ``install`` (which builds the solver and sets it as the
model's source); from then on it follows the source: a timer shows its rate,
counts, rejections and recording, and raises the banner when frames stop.
Tare goes through the model (:meth:`~tactile_viewer.model.viewer_model.ViewerModel.retare`,
as the Recording menu's); recording acts on the source directly; what it reports
(a saved or failed recording) comes back through the model's ``message``.

An LSL stream is connected in a :class:`~tactile_viewer.qt.tasks.Task` (opening its inlet
waits for the network, up to seconds); the outcome comes back on the GUI thread as
``lsl_connected``. A connection still being made when the window closes is waited for and
the source it made is stopped.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from PyQt6 import QtCore, QtGui, QtWidgets

from ..io.layout import LayoutError, SensorLayout, load_layout
from ..model.force_publishing import ForcePublishing
from ..model.viewer_model import ViewerModel
from ..sources.live import LiveSource
from ..sources.lsl_inlet import FoundStream, LslSource
from ..sources.serial_reader import SerialReader
from .connect_dialog import ConnectDialog
from .lsl_connect_dialog import LslConnectDialog
from .tasks import Task

__all__ = ["LivePanel", "TARE_FRAMES", "SILENCE_S"]

TARE_FRAMES = 50  # frames averaged by a tare
SILENCE_S = 1.0  # seconds without a frame before the banner says NO DATA
DISPLAY_WINDOW_S = 2.0  # seconds of drawn frames the on-screen rate is measured over
_CONNECT_ERRORS = (LayoutError, ValueError, OSError, RuntimeError)  # RuntimeError: pylsl's own


@dataclass(eq=False)
class _Attempt:
    """An LSL connection being made off the GUI thread."""

    stream: FoundStream
    task: Task | None = None
    source: LslSource | None = None  # set by the task once made (read on the GUI thread after it ends)
    abandoned: bool = False  # the window closed first: its outcome is dropped, its source stopped


class LivePanel(QtWidgets.QFrame):
    """A live source's state and its actions: the bar under the scene while a board is shown.

    It takes the timeline's place (a board has no timeline) and is never scrolled away: the
    counts, the REC indicator and the buttons stay in view.

    Parameters
    ----------
    model : ViewerModel
    install : callable
        ``install(source) -> bool``: build the solver for ``source`` and show
        it (the window's; it stops the source if that fails).
    error : callable
        ``error(title, text)``: show an error to the user.
    notify : callable
        ``notify(text)``: a passing note in the status bar.

    Attributes
    ----------
    banner : QLabel
        The NO DATA banner, placed by the window above the scene.

    Signals
    -------
    lsl_connected(bool)
        A connection started by :meth:`connect_lsl` ended: True once its source is
        started and handed to ``install``, False when it failed (the error is shown)
        or the window closed first.
    """

    disconnected = QtCore.pyqtSignal()  # the board shown was disconnected by the user
    recording_to = QtCore.pyqtSignal(str)  # the file frames are recorded to now ("": none)
    lsl_connected = QtCore.pyqtSignal(bool)  # the outcome of connect_lsl's connection

    def __init__(self, model: ViewerModel, *, install, error, notify, parent=None):
        super().__init__(parent)
        self.model = model
        self._install, self._error, self._notify = install, error, notify
        self._layout_name = ""  # the layout file of the board shown, to name it
        self._recording_to = ""
        self._connecting: _Attempt | None = None  # the LSL connection being made
        self.setFrameShape(QtWidgets.QFrame.Shape.StyledPanel)
        bar = QtWidgets.QHBoxLayout(self)
        bar.setContentsMargins(6, 2, 6, 2)
        box = QtWidgets.QVBoxLayout()
        self.status = QtWidgets.QLabel("")
        self.status.setWordWrap(True)
        policy = QtWidgets.QSizePolicy.Policy
        self.status.setSizePolicy(policy.Ignored, policy.Preferred)  # wraps, never widens the window
        box.addWidget(self.status)
        # seen at a glance while every frame goes to a file
        self.recording_indicator = QtWidgets.QLabel("")
        self.recording_indicator.setStyleSheet("color: #b00020; font-weight: bold")
        self.recording_indicator.hide()
        box.addWidget(self.recording_indicator)
        bar.addLayout(box, 1)
        self._drawn: deque = deque()  # when frames reached the screen (monotonic seconds)
        buttons = QtWidgets.QHBoxLayout()
        self.buttons = {}
        tips = {"tare": f"Take the mean of the next {TARE_FRAMES} frames as the zero of every taxel "
                        "(nothing may touch the skin meanwhile)",
                "record": "Write every frame received, raw, with its calibration and tares, to an .mcap file",
                "stop_recording": "Close the recording file (its frames are safe on disk already)",
                "disconnect": "Close the port; the last frame stays shown"}
        for label, name, slot in (("Tare", "tare", self.tare), ("Record...", "record", self.record_dialog),
                                  ("Stop recording", "stop_recording", self.stop_recording),
                                  ("Disconnect", "disconnect", self.disconnect_live)):
            button = QtWidgets.QPushButton(label)
            button.setToolTip(tips[name])
            button.clicked.connect(lambda _=False, slot=slot: slot())
            buttons.addWidget(button)
            self.buttons[name] = button
        bar.addLayout(buttons)
        self.banner = QtWidgets.QLabel("NO DATA")
        self.banner.setAlignment(QtCore.Qt.AlignmentFlag.AlignCenter)
        self.banner.setStyleSheet("background: #b00020; color: white; font-weight: bold; padding: 4px")
        # a long reason ("reconnecting: could not open port ...") wraps instead of widening the window
        self.banner.setWordWrap(True)
        policy = QtWidgets.QSizePolicy.Policy
        self.banner.setSizePolicy(policy.Ignored, policy.Preferred)
        self.banner.hide()
        self.actions: dict[str, QtGui.QAction] = {}  # those that need a connection
        self.connect_actions: dict[str, QtGui.QAction] = {}  # off while a connection is being made
        self.publish_actions: dict[str, QtGui.QAction] = {}  # publishing is chosen at any time
        self._timer = QtCore.QTimer(self, interval=250)
        self._timer.timeout.connect(self.follow)
        model.recording_changed.connect(self._on_source)
        self.publishing = ForcePublishing(model)  # Live > Publish over LSL
        self.publishing.changed.connect(self.follow)
        self.hide()

    def add_actions(self, menu: QtWidgets.QMenu):
        """Fill the Live menu: connect a board or an LSL stream, disconnect, tare, record, publish."""
        self.connect_actions["connect"] = menu.addAction("&Connect...", self.connect_dialog)
        self.connect_actions["lsl"] = menu.addAction("Connect to an &LSL stream...", self.lsl_connect_dialog)
        for name, label, slot in (("disconnect", "&Disconnect", self.disconnect_live),
                                  ("tare", f"&Tare (average {TARE_FRAMES} frames)", self.tare),
                                  ("record", "&Record...", self.record_dialog),
                                  ("stop_recording", "&Stop recording", self.stop_recording)):
            self.actions[name] = menu.addAction(label, slot)
        menu.addSeparator()
        tips = {"publish": "Publish the node forces of every solved live frame as the LSL stream "
                           f"{self.publishing.name!r} of type TactileForce (newtons)",
                "publish_stress": "Also publish the calibrated stress as type Tactile (pascals), beside "
                                  "the forces"}
        for name, label in (("publish", "&Publish over LSL"), ("publish_stress", "Publish the stress &too")):
            action = menu.addAction(label)
            action.setCheckable(True)
            action.setToolTip(tips[name])
            action.toggled.connect(self._publishing_toggled)
            self.publish_actions[name] = action
        menu.setToolTipsVisible(True)
        self._enable()

    @property
    def reader(self) -> LiveSource | None:
        """The live source shown, None when a recording or nothing is."""
        source = self.model.source
        return source if isinstance(source, LiveSource) else None

    # -- connecting ----------------------------------------------------------------------

    def connect_dialog(self):
        dialog = ConnectDialog(self.window())
        if dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted:
            chosen = dialog.connection()
            self.connect_live(chosen.url, chosen.layout, fmt=chosen.fmt, baudrate=chosen.baudrate)

    def connect_live(self, url: str, layout, *, fmt: str = "binary", baudrate: int = 115200) -> bool:
        """Show frames from a serial URL; ``layout`` is a SensorLayout or its JSON path.

        Errors (bad layout, port that cannot be opened) are shown and change nothing; so is a
        call while an LSL connection is being made (refused: False).
        """
        if self._refused_while_connecting():
            return False
        try:
            named = "" if isinstance(layout, SensorLayout) else Path(layout).name
            if not isinstance(layout, SensorLayout):
                layout = load_layout(layout)
            reader = SerialReader(url, layout, fmt=fmt, baudrate=baudrate)
            self._layout_name = named
            reader.start()
        except (LayoutError, ValueError, OSError) as exc:  # pyserial's SerialException is an OSError
            self._error("Cannot connect", f"{url}: {exc}")
            return False
        return self._install(reader)

    def lsl_connect_dialog(self):
        dialog = LslConnectDialog(self.window())
        dialog.search()  # what is on the network now, without a click
        if dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted:
            chosen = dialog.connection()
            self.connect_lsl(chosen.stream, chosen.layout or None)

    def connect_lsl(self, stream: FoundStream, layout=None) -> bool:
        """Connect to an LSL stream off the GUI thread, then show its frames.

        Opening the stream's inlet waits for the network (up to the source's ``timeout``,
        2 s, for its description and again to open it), so the layout file is read and the
        :class:`~tactile_viewer.sources.lsl_inlet.LslSource` made in a
        :class:`~tactile_viewer.qt.tasks.Task` while the window stays responsive; the status
        bar says "connecting to lsl:NAME ..." and the Connect actions are off meanwhile. Once
        it is made, on the GUI thread, the source is started and handed to ``install``;
        ``lsl_connected`` reports the outcome.

        Parameters
        ----------
        stream : FoundStream
            The stream chosen (:func:`~tactile_viewer.sources.lsl_inlet.find_streams`).
        layout : SensorLayout, str, Path or None
            The layout, its JSON path, or None for the one in the stream's description.

        Returns
        -------
        bool
            True when a connection was started; False when it was refused because
            another is still being made (the status bar says so; nothing changes).

        Notes
        -----
        Errors (bad layout, a channel count that is not the layout's, a stream gone) are
        shown as "Cannot connect" when the attempt ends and change nothing
        (``lsl_connected(False)``). When the window closes first, the close waits for the
        attempt and stops the source it made.
        """
        if self._refused_while_connecting():
            return False
        named = "" if layout is None or isinstance(layout, SensorLayout) else Path(layout).name
        attempt = _Attempt(stream)

        def connect(_progress):
            chosen = layout if layout is None or isinstance(layout, SensorLayout) else load_layout(layout)
            attempt.source = LslSource(stream, chosen)
            return attempt.source

        attempt.task = Task(connect, self)
        attempt.task.succeeded.connect(lambda reader: self._lsl_made(attempt, reader, named))
        attempt.task.failed.connect(lambda exc: self._lsl_failed(attempt, exc))
        attempt.task.finished.connect(attempt.task.deleteLater)
        self._connecting = attempt
        self._enable()
        self._notify(f"connecting to {stream.url} ...")
        attempt.task.start()
        return True

    def _refused_while_connecting(self) -> bool:
        if self._connecting is None:
            return False
        self._notify(f"still connecting to {self._connecting.stream.url}: connect again once it has ended")
        return True

    def _lsl_made(self, attempt: _Attempt, reader: LslSource, named: str):
        if attempt.abandoned:
            return  # the window closed first: cancel_connecting stopped it
        self._connecting = None
        self._enable()
        url = attempt.stream.url
        try:
            self._layout_name = named
            reader.start()
        except _CONNECT_ERRORS as exc:
            self._notify(f"not connected to {url}")
            self._error("Cannot connect", f"{url}: {exc}")
            self.lsl_connected.emit(False)
            return
        self._notify(f"connected to {url}")
        self.lsl_connected.emit(bool(self._install(reader)))

    def _lsl_failed(self, attempt: _Attempt, exc: Exception):
        if attempt.abandoned:
            return
        self._connecting = None
        self._enable()
        self._notify(f"not connected to {attempt.stream.url}")
        expected = isinstance(exc, _CONNECT_ERRORS)
        if expected:
            self._error("Cannot connect", f"{attempt.stream.url}: {exc}")
        self.lsl_connected.emit(False)
        if not expected:
            raise exc  # a bug: to the app's error hook, as when it was raised on the GUI thread

    def cancel_connecting(self):
        """Give up the LSL connection being made (the window is closing): wait for it, stop what it made.

        Its outcome is dropped (no error is shown) and ``lsl_connected(False)`` is emitted.
        The wait lasts as long as the inlet's own wait (seconds at worst): a task must not
        outlive the window.
        """
        attempt, self._connecting = self._connecting, None
        if attempt is None:
            return
        attempt.abandoned = True
        attempt.task.wait()
        if attempt.source is not None:
            attempt.source.stop()  # never started: closes the inlet it opened
        self._enable()
        self.lsl_connected.emit(False)


    def _publishing_toggled(self, _checked: bool):
        actions = self.publish_actions
        self.set_publishing(actions["publish"].isChecked(), stress=actions["publish_stress"].isChecked())

    def set_publishing(self, on: bool, *, stress: bool = False) -> bool:
        """Publish the forces of every solved live frame over LSL (and the stress); False when it failed."""
        try:
            if on:
                self.publishing.start(stress=stress)
            else:
                self.publishing.stop()
        except (RuntimeError, ValueError) as exc:  # liblsl could not make an outlet
            self._error("Cannot publish over LSL", str(exc))
            if "publish" in self.publish_actions:
                with QtCore.QSignalBlocker(self.publish_actions["publish"]):
                    self.publish_actions["publish"].setChecked(False)
            return False
        return True

    def disconnect_live(self):
        """Stop reading (and recording); the last frame stays on screen."""
        reader = self.reader
        if reader is not None:
            reader.stop()
            self.disconnected.emit()
        self.follow()

    # -- acting on the source --------------------------------------------------------------

    def frame_drawn(self):
        """A frame reached the screen (the window's ``rendered``)."""
        now = time.monotonic()
        self._drawn.append(now)
        while self._drawn and self._drawn[0] < now - DISPLAY_WINDOW_S:
            self._drawn.popleft()

    def display_rate(self) -> float:
        """Frames drawn per second over the last :data:`DISPLAY_WINDOW_S` seconds."""
        now = time.monotonic()
        while self._drawn and self._drawn[0] < now - DISPLAY_WINDOW_S:
            self._drawn.popleft()
        return len(self._drawn) / DISPLAY_WINDOW_S

    def tare(self, frames: int = TARE_FRAMES):
        """Average the next ``frames`` frames as the zero of every taxel."""
        if self._connected():
            self._notify(self.model.retare("here", frames=frames))  # the model's one way to tare

    def record_dialog(self):
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self.window(), "Record live frames", "live.mcap",
                                                        "MCAP recording (*.mcap)")
        if path:
            self.start_recording(path)

    def start_recording(self, path) -> bool:
        """Record every received frame (not only the displayed ones), raw, with its calibration, to MCAP."""
        if not self._connected():
            return False
        self.stop_recording()
        try:
            self.reader.start_recording(path)
        except (ValueError, OSError) as exc:
            self._error("Cannot record", f"{path}: {exc}")
            return False
        self.follow()
        return True

    def stop_recording(self):
        """Close the recording; the path written (None when nothing was recorded or it failed)."""
        written = self.reader.stop_recording() if self.reader is not None else None
        self.follow()
        return written

    # -- following the source ---------------------------------------------------------------

    def _connected(self) -> bool:
        return self.reader is not None and self.reader.state != "stopped"

    def _on_source(self):
        live = self.model.live
        self.setVisible(live)
        if live:
            self._timer.start()
        else:
            self._timer.stop()
        self.follow()

    def _enable(self):
        connected = self._connected()
        recording = connected and self.reader.recorder is not None
        for name, on in (("tare", connected), ("record", connected), ("stop_recording", recording),
                         ("disconnect", connected)):
            self.buttons[name].setEnabled(on)
            if name in self.actions:
                self.actions[name].setEnabled(on)
        for action in self.connect_actions.values():
            action.setEnabled(self._connecting is None)

    def follow(self):
        """Show the source's state: rate, counts, rejections, recording; NO DATA after a silence."""
        self._enable()
        reader = self.reader
        recorder = reader.recorder if reader is not None and reader.state != "stopped" else None
        path = str(recorder.path) if recorder is not None else ""
        if path != self._recording_to:
            self._recording_to = path
            self.recording_to.emit(path)
        if recorder is None:
            self.recording_indicator.hide()
        if reader is None or reader.state == "stopped":
            self.banner.hide()
            self.status.setText(f"{reader.label}: stopped" if reader is not None else "")
            return
        stats = reader.stats.snapshot(reader.now())  # one count: the reader thread goes on counting
        silence = stats.silence
        self.banner.setVisible(silence > SILENCE_S)
        if silence > SILENCE_S:
            since = "no frame received yet" if silence == math.inf else f"no frame for {silence:.1f} s"
            state = reader.state + (f": {reader.error}" if reader.error else "")
            self.banner.setText(f"NO DATA: {since} ({state})")
        rejected = reader.rejected()
        parts = [f"{reader.label}: {reader.state}",
                 f"{stats.rate:.0f} fps received, {self.display_rate():.0f} fps on screen",
                 f"received {stats.received}", f"lost {stats.lost}"]
        if rejected or reader.decoder.skipped_bytes:
            parts.append("rejected " + (", ".join(f"{k} {v}" for k, v in sorted(rejected.items())) or "0")
                         + f"; skipped {reader.decoder.skipped_bytes} B")
            mismatch = reader.size_mismatch(self._layout_name)
            if mismatch:
                parts.append(mismatch)
        if reader.reconnects:
            parts.append(f"reconnected {reader.reconnects}x")
        if reader.backlog_bytes:
            parts.append(f"dropped {reader.backlog_bytes} B queued before connecting")
        if reader.identity_notice:
            parts.append(reader.identity_notice)
        if reader.failures:
            parts.append(f"{reader.failures} chunks failed: {reader.error}")
        if reader.calibration.taring:
            parts.append("taring")
        if self.publishing.status():
            parts.append(self.publishing.status())
        if recorder is not None:
            self.recording_indicator.show()
            self.recording_indicator.setText(
                f"\u25cf REC {recorder.path.name}: {recorder.added} frames ({recorder.written} on disk)"
                + (f", {recorder.dropped} not recorded (the disk is slower than the board)"
                   if recorder.dropped else ""))
        self.status.setText("  \u00b7  ".join(parts))

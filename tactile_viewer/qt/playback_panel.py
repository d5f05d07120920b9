"""The Playback panel: the timeline under the scene, and the Playback menu's keys.

It ticks the recording source's clock and sets the frame through the model;
the live bar takes its place for a board (:mod:`tactile_viewer.qt.live_panel`).
"""

from __future__ import annotations

import time

from PyQt6 import QtCore, QtGui, QtWidgets

from ..model.viewer_model import ViewerModel
from ..sources.source import RecordingSource
from .number_fields import quietly
from .text_line import TextLine

__all__ = ["PlaybackPanel", "SPEEDS"]

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)


class PlaybackPanel(QtWidgets.QFrame):
    """The timeline under the scene: step, play, the frame slider, frame and time, speed, loop.

    One row with a permanent place (as in rviz and Foxglove), never scrolled away.

    The :class:`~tactile_viewer.sources.source.RecordingSource` keeps the clock and
    shows the frame whose time has come, so slow drawing skips frames rather
    than slowing the recording down; this panel only ticks it.
    """

    def __init__(self, model: ViewerModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.setFrameShape(QtWidgets.QFrame.Shape.StyledPanel)
        row = QtWidgets.QHBoxLayout(self)
        row.setContentsMargins(6, 2, 6, 2)
        self.play_button = QtWidgets.QPushButton("Play")
        self.play_button.setCheckable(True)
        self.play_button.toggled.connect(self._play_toggled)
        back = QtWidgets.QPushButton("<")
        back.clicked.connect(lambda: self.step(-1))
        forward = QtWidgets.QPushButton(">")
        forward.clicked.connect(lambda: self.step(1))
        self.frame_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.frame_slider.valueChanged.connect(model.set_frame)
        self.speed_box = QtWidgets.QComboBox()
        self.speed_box.addItems([f"{s:g}x" for s in SPEEDS])
        self.speed_box.setCurrentIndex(SPEEDS.index(1.0))
        self.speed_box.currentIndexChanged.connect(lambda _: self._follow_controls())
        self.loop_box = QtWidgets.QCheckBox("loop")
        self.loop_box.toggled.connect(lambda _: self._follow_controls())
        # room for the longest label, so that the slider does not jump as it changes; a new label
        # (every frame) repaints only itself
        self.time_label = TextLine("-", room_for="frame 0000 (of 0-0000),  t = 000.000 s")
        for widget, tip in ((back, "One frame back (Left)"), (forward, "One frame on (Right)"),
                            (self.play_button, "Play the recording in real time times the speed, or pause "
                                               "(Space); slow drawing skips frames, never slows time"),
                            (self.frame_slider, "The frame shown, numbered from 0 (Home, End: first, last)"),
                            (self.speed_box, "Playback speed: recording seconds per wall-clock second"),
                            (self.loop_box, "Start again from frame 0 at the end")):
            widget.setToolTip(tip)
        for button in (back, forward):
            button.setFixedWidth(button.fontMetrics().horizontalAdvance("<") + 24)
        self.play_button.setFixedWidth(self.play_button.fontMetrics().horizontalAdvance("Pause") + 24)
        for widget in (back, self.play_button, forward):
            row.addWidget(widget)
        row.addWidget(self.frame_slider, 1)
        for widget in (self.time_label, self.speed_box, self.loop_box):
            row.addWidget(widget)
        self._timer = QtCore.QTimer(self, interval=15)
        self._timer.timeout.connect(self._tick)
        self.source: RecordingSource | None = None
        model.recording_changed.connect(self._on_recording)
        model.frame_changed.connect(self._on_frame)
        model.solved.connect(self._on_solved)

    @property
    def speed(self) -> float:
        return SPEEDS[self.speed_box.currentIndex()]

    def restore(self, *, speed: float | None = None, loop: bool | None = None):
        """Set the speed (one of :data:`SPEEDS`; another is ignored) and loop, e.g. as saved last run."""
        if speed is not None and speed in SPEEDS:
            self.speed_box.setCurrentIndex(SPEEDS.index(speed))
        if loop is not None:
            self.loop_box.setChecked(bool(loop))

    def set_playing(self, on: bool):
        self.play_button.setChecked(on)

    def stop(self):
        self.set_playing(False)

    def step(self, delta: int):
        if self.source is not None:
            self.model.set_frame(min(max(self.model.frame + delta, 0), len(self.source) - 1))

    def _on_recording(self):
        source = self.model.source
        if source is self.source:
            return  # the same recording with another solver
        if self.source is not None:
            self.source.state_changed.disconnect(self._follow_state)
        self.stop()
        self.source = source if isinstance(source, RecordingSource) else None
        if self.source is None:
            self.time_label.setText("live")
            return
        self.source.state_changed.connect(self._follow_state)
        self._follow_controls()

        def apply():
            self.frame_slider.setRange(0, len(self.source) - 1)
            self.frame_slider.setValue(self.source.position)
        quietly([self.frame_slider], apply)

    def _follow_controls(self):
        if self.source is not None:
            self.source.loop = self.loop_box.isChecked()
            self.source.set_speed(self.speed, time.perf_counter())

    def _follow_state(self):
        # the recording stopped itself at its end
        if self.source is not None and self.source.state != "playing":
            self.set_playing(False)

    def _on_frame(self, index):
        # while playing, the slider moves with the frame's result (_on_solved), in the window's
        # repaint of that frame: moved here, before the solve, it cost the window a repaint of its own
        # on every frame (the whole window composed again, 12 ms under software rendering)
        if self.source is None or self.source.state != "playing":
            self._show_frame(index)

    def _on_solved(self, solved):
        if self.source is not None:
            # playing, the frame drawn, even when a later one was taken meanwhile (a slow solve);
            # paused, only the frame shown: an older result does not move the slider back
            if self.source.state == "playing" or solved.frame == self.model.frame:
                self._show_frame(solved.frame)
            # numbered from 0, as in exports, sidecars, --frame and --report
            self.time_label.setText(f"frame {solved.frame} (of 0-{len(self.source) - 1}),  "
                                    f"t = {solved.time:.3f} s")

    def _show_frame(self, index):
        quietly([self.frame_slider], lambda: self.frame_slider.setValue(index))

    def _play_toggled(self, on):
        self.play_button.setText("Pause" if on else "Play")
        if on and self.source is not None:
            self.source.play(time.perf_counter())
            self._timer.start()
        else:
            self._timer.stop()
            if self.source is not None:
                self.source.pause()
                self._show_frame(self.model.frame)  # a frame taken but not yet drawn: it is the one shown

    def _tick(self):
        if self.source is not None:
            self.source.advance(time.perf_counter())

    def add_actions(self, menu: QtWidgets.QMenu) -> dict:
        """Fill the Playback menu: play, step back and on, first and last frame; the actions by name."""
        # window-wide keys: a text field keeps the keys it edits with (Qt gives it the shortcut
        # override), a slider or button with the focus does not
        keys = QtCore.Qt.Key

        def add(label, key, slot, tip):
            action = menu.addAction(label, slot)
            action.setShortcut(QtGui.QKeySequence(key))
            action.setToolTip(tip)
            return action

        return {
            "play": add("&Play / pause", keys.Key_Space, self.play_button.toggle,
                        "Play the recording at the chosen speed, or pause it"),
            "back": add("Step &back", keys.Key_Left, lambda: self.step(-1), "One frame back"),
            "forward": add("Step &forward", keys.Key_Right, lambda: self.step(1), "One frame on"),
            "first": add("&First frame", keys.Key_Home, lambda: self.go_to(0), "Frame 0"),
            "last": add("&Last frame", keys.Key_End, lambda: self.go_to(-1), "The recording's last frame"),
        }

    def go_to(self, index: int):
        """Show frame ``index`` of the recording, from its end when negative (nothing for a live source)."""
        recording = self.model.recording
        if recording is not None and not self.model.live:
            self.model.set_frame(index % len(recording))

"""The window's control panels: each sets model fields and follows the model's events.

No panel solves, draws or reads files: :class:`ParametersPanel` and
:class:`DisplayPanel` edit the :class:`~tactile_viewer.model.viewer_model.ViewerModel`;
:class:`PlaybackPanel` ticks the recording source's clock (the live panel is
:mod:`tactile_viewer.qt.live_panel`). Requests that need the window (a new kernel
to factor, a camera preset) leave as Qt signals.
"""

from __future__ import annotations

import math
import time

from PyQt6 import QtCore, QtWidgets

from solver.kernels import KERNELS

from ..model.viewer_model import (
    KERNEL_HELP,
    MAX_SHEAR_RATIO,
    MAX_SMOOTHING,
    Solved,
    ViewerModel,
    geometry_text,
)
from ..sources.source import RecordingSource

__all__ = ["ParametersPanel", "DisplayPanel", "PlaybackPanel", "status_text", "status_details", "MAP_CHOICES",
           "SPEEDS"]

MAP_CHOICES = (("normal pressure", "pressure"), ("sensor stress", "stress"), ("none", "none"))
SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)


def _quietly(widgets, apply):
    # model -> widgets without echoing back into the model
    for w in widgets:
        w.blockSignals(True)
    try:
        apply()
    finally:
        for w in widgets:
            w.blockSignals(False)


def _number_field(**options) -> QtWidgets.QDoubleSpinBox:
    # A typed number takes effect on Enter or on leaving the field (arrows and the wheel at once):
    # with keyboard tracking every key set the model, which wrote its value back into the field
    # while the user typed (0.8 became 0.00).
    field = QtWidgets.QDoubleSpinBox(**options)
    field.setKeyboardTracking(False)
    return field


def _show_number(field: QtWidgets.QDoubleSpinBox, value: float):
    # model -> field, except over what the user is typing there and has not entered yet (in Auto
    # every solved frame shows its parameters)
    if field.hasFocus() and field.cleanText() != field.textFromValue(field.value()):
        return
    field.setValue(value)


# contacts named on the status line; the rest are in its tooltip
STATUS_CONTACTS = 3


def status_text(solved: Solved, model: ViewerModel) -> str:
    """The status line of a solved frame: where, how fast, the parameters, the forces.

    Short enough for a 1280 px window with several contacts and the taxel
    read-out beside it; the fit's figures and every contact are in
    :func:`status_details` (the line's tooltip).
    """
    r = solved.result
    total = r.total_force
    if r.fallback:
        # a load too broad for the accurate path within its budget: what the solver did, in short
        shear = f"cheaper answer: {r.fallback.split(':', 1)[0]}"
    elif r.normal_only:
        shear = "normal only"  # the fast preset
    else:
        mode = "auto" if solved.auto else "manual"
        contacts = r.contacts if len(r.contacts) > 1 else ()
        if not contacts:
            shear = (f"{mode}: no shear signature" if solved.auto and not r.shear_detected else
                     f"{mode}: mu {r.shear_ratio:.2f}, theta {math.degrees(r.shear_direction):+.0f} deg")
        else:
            named = "; ".join(_contact_text(c, k) for k, c in enumerate(contacts[:STATUS_CONTACTS]))
            more = len(contacts) - STATUS_CONTACTS
            shear = f"{mode}: {named}" + (f"; {more} more" if more > 0 else "")
    where = (f"seq {solved.frame}" if solved.frame >= 0 else "live") if model.live \
        else f"frame {solved.frame} (of 0-{len(model.recording) - 1})"
    return (f"{where}  t {solved.time:.3f} s  |  {solved.solve_ms:.2f} ms  |  {shear}  |  "
            f"Fz {total[2] * 1e3:.1f} mN  Ft {math.hypot(total[0], total[1]) * 1e3:.1f} mN")


def _contact_text(contact, k: int) -> str:
    number = contact.identity or k + 1
    if contact.shear_ratio == 0:
        return f"#{number} no shear"
    return f"#{number} mu {contact.shear_ratio:.2f} {math.degrees(contact.shear_direction):+.0f} deg"


def status_details(solved: Solved) -> str:
    """The status line's tooltip: every contact, the fit's figures in words, a cheaper answer's reason."""
    r = solved.result
    lines = []
    if r.fallback:
        lines.append(f"Cheaper answer: {r.fallback}")
    for k, contact in enumerate(r.contacts):
        fz = contact.total_force[2]
        lines.append(f"{_contact_text(contact, k)}, Fz {fz * 1e3:.1f} mN"
                     + (" (on the skin's edge)" if contact.at_edge else ""))
    if math.isfinite(r.efficiency):
        lines.append(f"efficiency {r.efficiency:.3f}: how much of the sensor stress the fitted contact load "
                     "explains (1: all of it)")
    else:
        lines.append("efficiency: none (no contact load was fitted: a normal-only answer or an empty frame)")
    lines.append(f"residual {r.residual:.1e}: the sensor stress the forces shown leave unexplained, "
                 "relative to the stress")
    lines.append(f"condition {r.condition:.3g}: how much the inversion can amplify sensor noise"
                 + (" (damped: the layer is thick for its pitch)" if r.regularized else ""))
    return "\n".join(lines)


class ParametersPanel(QtWidgets.QGroupBox):
    """Auto, shear ratio and direction, kernel and quality preset, the geometry line.

    Signals
    -------
    kernel_chosen(str)
        The user picked another kernel (the window factors it).
    quality_chosen(object)
        The user picked a quality preset (a ``solver.quality.Configuration`` or None).
    """

    kernel_chosen = QtCore.pyqtSignal(str)
    quality_chosen = QtCore.pyqtSignal(object)

    def __init__(self, model: ViewerModel, parent=None):
        super().__init__("Parameters", parent)
        self.model = model
        grid = QtWidgets.QGridLayout(self)
        self.auto_box = QtWidgets.QCheckBox("Auto (efficiency maximum)")
        self.auto_box.setChecked(True)
        self.auto_box.setToolTip("Per contact, the shear ratio and direction whose compressive load explains "
                                 "the sensors best (key A). Moving a slider switches Auto off.")
        self.auto_box.toggled.connect(model.set_auto)
        grid.addWidget(self.auto_box, 0, 0, 1, 3)
        self.ratio_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.ratio_slider.setRange(0, round(MAX_SHEAR_RATIO * 100))
        self.ratio_spin = _number_field(decimals=2, singleStep=0.01, maximum=MAX_SHEAR_RATIO)
        self.direction_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.direction_slider.setRange(-180, 180)
        self.direction_spin = _number_field(decimals=1, singleStep=1.0, minimum=-180.0,
                                                       maximum=180.0, wrapping=True, suffix=" deg")
        grid.addWidget(QtWidgets.QLabel("shear ratio"), 1, 0)
        grid.addWidget(self.ratio_slider, 1, 1)
        grid.addWidget(self.ratio_spin, 1, 2)
        grid.addWidget(QtWidgets.QLabel("direction"), 2, 0)
        grid.addWidget(self.direction_slider, 2, 1)
        grid.addWidget(self.direction_spin, 2, 2)
        for widget in (self.ratio_slider, self.ratio_spin):
            widget.setToolTip("Shear ratio mu: tangential over normal force of the contact's load "
                              "(0: pressing only). Setting it switches Auto off.")
        for widget in (self.direction_slider, self.direction_spin):
            widget.setToolTip("Shear direction theta: degrees from +x (0 = +x, 90 = +y). Setting it switches "
                              "Auto off.")
        self.ratio_slider.valueChanged.connect(lambda v: self._manual(shear_ratio=v / 100))
        self.ratio_spin.valueChanged.connect(lambda v: self._manual(shear_ratio=v))
        self.direction_slider.valueChanged.connect(lambda v: self._manual(shear_direction=math.radians(v)))
        self.direction_spin.valueChanged.connect(lambda v: self._manual(shear_direction=math.radians(v)))
        self.kernel_box = QtWidgets.QComboBox()
        # the solver's list, its default first: a kernel added there appears here
        self.kernel_box.addItems(list(KERNELS))
        self.kernel_box.setCurrentText(model.kernel)
        self.kernel_box.setToolTip(KERNEL_HELP)
        self.kernel_box.currentTextChanged.connect(self.kernel_chosen)
        grid.addWidget(QtWidgets.QLabel("kernel"), 3, 0)
        grid.addWidget(self.kernel_box, 3, 1, 1, 2)
        self.quality_box = QtWidgets.QComboBox()
        self.quality_box.addItem("standard (exact, efficiency maximum)", None)
        self.quality_box.setToolTip("Presets from the measured speed/accuracy front of this geometry "
                                    "(tactile-tradeoff): time per frame and median error")
        self.quality_box.currentIndexChanged.connect(
            lambda i: self.quality_chosen.emit(self.quality_box.itemData(i)))
        grid.addWidget(QtWidgets.QLabel("quality"), 4, 0)
        grid.addWidget(self.quality_box, 4, 1, 1, 2)
        # the geometry the forces are solved on, nu included: the layer kernel depends on it
        self.geometry_label = QtWidgets.QLabel("")
        self.geometry_label.setWordWrap(True)
        self.geometry_label.setToolTip("From the recording or the sensor layout file: taxels, pitch, "
                                       "elastomer thickness, Poisson ratio nu, taxel size")
        grid.addWidget(self.geometry_label, 5, 0, 1, 3)
        # a preset that solves normal forces only cannot honour the shear controls: say so, disable them
        self.shear_note = QtWidgets.QLabel("")
        self.shear_note.setWordWrap(True)
        self.shear_note.hide()
        grid.addWidget(self.shear_note, 6, 0, 1, 3)
        model.parameters_changed.connect(self.follow)
        model.recording_changed.connect(self._on_recording)
        model.solved.connect(lambda solved: self.follow() if solved.auto else None)

    def _manual(self, **changes):
        if self.model.is_open:
            self.model.set_parameters(**changes)  # leaving Auto, the other keeps what Auto found

    def _on_recording(self):
        self.geometry_label.setText(geometry_text(self.model.grid))
        self.show_kernel(self.model.kernel)
        configuration = self.model.configuration
        normal_only = configuration is not None and configuration.path == "normal"
        for control in (self.auto_box, self.ratio_slider, self.ratio_spin, self.direction_slider,
                        self.direction_spin):
            control.setEnabled(not normal_only)
        self.shear_note.setText(f"The '{configuration.name}' preset solves normal forces only: shear ratio "
                                "and direction do not apply (choose another quality to use them)."
                                if normal_only else "")
        self.shear_note.setVisible(normal_only)

    def show_kernel(self, kernel: str):
        """Show ``kernel`` as chosen without asking for a rebuild."""
        _quietly([self.kernel_box], lambda: self.kernel_box.setCurrentText(kernel))

    def follow(self):
        """Show the model's parameters: in Auto what the last solve found, else the manual values."""
        ratio, direction = self.model.shear_ratio, self.model.shear_direction
        last = self.model.last
        if self.model.auto and last is not None and last.auto:
            # Auto shows what it found; the user's manual values stay in the model
            ratio, direction = last.result.shear_ratio, last.result.shear_direction
        degrees = math.degrees(direction)

        def apply():
            self.auto_box.setChecked(self.model.auto)
            self.ratio_slider.setValue(round(ratio * 100))
            _show_number(self.ratio_spin, ratio)
            self.direction_slider.setValue(round(degrees))
            _show_number(self.direction_spin, degrees)
        _quietly([self.auto_box, self.ratio_slider, self.ratio_spin, self.direction_slider,
                  self.direction_spin], apply)

    def set_presets(self, chosen: dict, describe):
        """Offer measured presets: ``chosen`` label -> measurement, ``describe(m)`` its text."""
        def apply():
            while self.quality_box.count() > 1:
                self.quality_box.removeItem(1)
            for label, m in chosen.items():
                self.quality_box.addItem(f"{label}: {describe(m)}", m.configuration)
        _quietly([self.quality_box], apply)


class DisplayPanel(QtWidgets.QGroupBox):
    """Map and its colours, arrows and their colours, resultant, scales, axes, taxel numbers, camera.

    The Top button looks straight down (orthographic) and switches the arrows
    to in-plane ``(Fx, Fy)``; Iso looks from the front right and switches
    them back to 3-D. The "in-plane arrows" box changes them in either view
    (:meth:`view`; the View menu should go through it too).

    Signals
    -------
    camera(str)
        "top" or "iso" was asked for.
    """

    camera = QtCore.pyqtSignal(str)

    def __init__(self, model: ViewerModel, parent=None):
        super().__init__("Display", parent)
        self.model = model
        grid = QtWidgets.QGridLayout(self)
        self.map_box = QtWidgets.QComboBox()
        for label, _ in MAP_CHOICES:
            self.map_box.addItem(label)
        self.map_box.currentIndexChanged.connect(lambda i: model.set_display(map=MAP_CHOICES[i][1]))
        self.colormap_box = QtWidgets.QComboBox()
        self.colormap_box.addItems(list(model.display.COLORMAPS))
        self.colormap_box.currentTextChanged.connect(lambda name: model.set_display(colormap=name))
        self.arrows_box = QtWidgets.QCheckBox("force arrows")
        self.arrows_box.setChecked(True)
        self.arrows_box.toggled.connect(lambda on: model.set_display(arrows=on))
        self.resultant_box = QtWidgets.QCheckBox("resultant")
        self.resultant_box.setChecked(True)
        self.resultant_box.toggled.connect(lambda on: model.set_display(resultant=on))
        self.scale_spin = _number_field(decimals=1, maximum=1e6, singleStep=5.0, suffix=" mm/N")
        self.scale_spin.valueChanged.connect(lambda v: model.set_display(arrow_scale=v / 1e3))
        self.threshold_spin = _number_field(decimals=2, maximum=1e6, singleStep=1.0, suffix=" mN")
        self.threshold_spin.valueChanged.connect(lambda v: model.set_display(threshold=v / 1e3))
        self.range_box = QtWidgets.QCheckBox("auto map range")
        self.range_box.setChecked(True)
        self.range_box.toggled.connect(lambda on: model.set_display(auto_range=on))
        self.range_spin = _number_field(decimals=2, maximum=1e6, singleStep=1.0, suffix=" kPa")
        self.range_spin.valueChanged.connect(lambda v: model.set_display(range_max=v * 1e3))
        self.arrow_range_box = QtWidgets.QCheckBox("auto arrow range")
        self.arrow_range_box.setChecked(True)
        self.arrow_range_box.toggled.connect(lambda on: model.set_display(arrow_auto_range=on))
        self.arrow_range_spin = _number_field(decimals=2, maximum=1e6, singleStep=5.0,
                                                         suffix=" mN")
        self.arrow_range_spin.valueChanged.connect(lambda v: model.set_display(arrow_range_max=v / 1e3))
        self.in_plane_box = QtWidgets.QCheckBox("in-plane arrows")
        self.in_plane_box.toggled.connect(lambda on: model.set_display(in_plane=on))
        self.gain_spin = _number_field(decimals=1, minimum=0.1, maximum=100.0, singleStep=0.5,
                                                  prefix="x ")
        self.gain_spin.setValue(model.display.in_plane_gain)
        self.gain_spin.valueChanged.connect(lambda v: model.set_display(in_plane_gain=v))
        self.smoothing_spin = _number_field(decimals=2, maximum=MAX_SMOOTHING, singleStep=0.05,
                                            prefix="smooth ", suffix=" s")
        self.smoothing_spin.setSpecialValueText("no smoothing")  # at 0
        self.smoothing_spin.valueChanged.connect(lambda v: model.set_display(smoothing=v))
        self.axes_box = QtWidgets.QCheckBox("axes")
        self.axes_box.setChecked(model.display.axes)
        self.axes_box.toggled.connect(lambda on: model.set_display(axes=on))
        self.ids_box = QtWidgets.QCheckBox("taxel numbers")
        self.ids_box.toggled.connect(lambda on: model.set_display(taxel_ids=on))
        top = QtWidgets.QPushButton("Top")
        top.clicked.connect(lambda: self.view("top"))
        iso = QtWidgets.QPushButton("Iso")
        iso.clicked.connect(lambda: self.view("iso"))
        for widget, tip in (
                (self.map_box, "The map on the skin: the reconstructed normal pressure (Fz over the taxel's "
                               "area) or the stress the sensors measured, kPa"),
                (self.colormap_box, "Colours of the map: perceptually uniform maps (equal steps look equal), "
                                    "cividis also for colour-blind readers, gray for print"),
                (self.range_box, "The map's colours span 0 to this frame's largest value (on), or 0 to "
                                 "the value beside on every frame (off)"),
                (self.range_spin, "Top of the map's fixed colour range, kPa (set from the recording's "
                                  "most loaded frame when it opens)"),
                (self.arrows_box, "One arrow per taxel: the force on the skin there, its tip on the surface, "
                                  "pointing where it pushes, coloured by its size"),
                (self.resultant_box, "One red arrow per contact: the contact's total force, at the centre "
                                     "of its pressing load (the frame's total when no contact was found)"),
                (self.scale_spin, "Arrow length per newton, mm/N; the scene states it as '1 mm = ... mN'"),
                (self.threshold_spin, "Taxels with a smaller force (in-plane: shear) draw no arrow, mN"),
                (self.smoothing_spin, "Smooth the arrows and the pressure map over this time constant "
                                      "(exponentially, over the frames' time) so that node forces stop "
                                      "flickering; they then lag the data by about this much. Off by "
                                      "default; never applied to exports, the read-out or the numbers"),
                (self.arrow_range_box, "The arrows' colours span 0 to this frame's largest shown force (on), "
                                       "or 0 to the value beside on every frame, so colours compare across "
                                       "frames (off)"),
                (self.arrow_range_spin, "Top of the arrows' fixed colour range, mN (set from the recording's "
                                        "loads when it opens); larger forces show in the top colour"),
                (self.in_plane_box, "Arrows and resultants show only the in-plane force (Fx, Fy), flat on "
                                    "the skin: the shear picture. Top switches it on, Iso off"),
                (self.gain_spin, "In-plane arrows are drawn this many times longer than 3-D ones (shear is "
                                 "a fraction of the pressing force); the stated scales include it"),
                (self.axes_box, "x and y ticks in mm beside the skin, and the direction convention at its "
                                "corner: 0 deg = +x, 90 deg = +y (the shear direction's angles)"),
                (self.ids_box, "Each taxel's number (node index from 0, as in exports and the read-out) "
                               "on its square; skins of up to 4096 taxels"),
                (top, "Look straight down (orthographic, +x right, +y up) with in-plane arrows"),
                (iso, "Look from the front right, in perspective, with 3-D arrows")):
            widget.setToolTip(tip)
        # two controls to a row where one qualifies the other: the column fits 1280x800 unscrolled
        rows = [(QtWidgets.QLabel("map"), self.map_box, self.colormap_box),
                (self.range_box, self.range_spin),
                (self.arrows_box, self.resultant_box),
                (QtWidgets.QLabel("arrow scale"), self.scale_spin),
                (QtWidgets.QLabel("hide below"), self.threshold_spin, self.smoothing_spin),
                (self.arrow_range_box, self.arrow_range_spin),
                (self.in_plane_box, self.gain_spin),
                (self.axes_box, self.ids_box),
                (QtWidgets.QLabel("camera"), top, iso)]
        for row, widgets in enumerate(rows):
            grid.addWidget(widgets[0], row, 0)
            if len(widgets) == 2:
                grid.addWidget(widgets[1], row, 1, 1, 2)
            else:
                grid.addWidget(widgets[1], row, 1)
                grid.addWidget(widgets[2], row, 2)
        model.display_changed.connect(self.follow)

    def view(self, preset: str):
        """Look from ``preset`` ("top" or "iso"): in-plane arrows from the top, 3-D arrows otherwise."""
        display = self.model.display.seen_from(preset)
        if self.model.is_open:
            self.model.set_display(in_plane=display.in_plane)
        self.camera.emit(preset)

    def follow(self):
        d = self.model.display

        def apply():
            self.map_box.setCurrentIndex([key for _, key in MAP_CHOICES].index(d.map))
            self.colormap_box.setCurrentText(d.colormap)
            self.arrows_box.setChecked(d.arrows)
            self.resultant_box.setChecked(d.resultant)
            _show_number(self.scale_spin, d.arrow_scale * 1e3)
            _show_number(self.threshold_spin, d.threshold * 1e3)
            self.range_box.setChecked(d.auto_range)
            _show_number(self.range_spin, d.range_max / 1e3)
            self.arrow_range_box.setChecked(d.arrow_auto_range)
            _show_number(self.arrow_range_spin, d.arrow_range_max * 1e3)
            self.in_plane_box.setChecked(d.in_plane)
            _show_number(self.gain_spin, d.in_plane_gain)
            _show_number(self.smoothing_spin, d.smoothing)
            self.axes_box.setChecked(d.axes)
            self.ids_box.setChecked(d.taxel_ids)
        _quietly([self.map_box, self.colormap_box, self.arrows_box, self.resultant_box, self.scale_spin,
                  self.threshold_spin, self.range_box, self.range_spin, self.arrow_range_box,
                  self.arrow_range_spin, self.in_plane_box, self.gain_spin, self.smoothing_spin,
                  self.axes_box, self.ids_box],
                 apply)
        self.range_spin.setEnabled(not d.auto_range)
        self.arrow_range_spin.setEnabled(not d.arrow_auto_range)
        self.gain_spin.setEnabled(d.in_plane)


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
        self.time_label = QtWidgets.QLabel("-")
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
        # room for the longest label, so that the slider does not jump as it changes
        self.time_label.setMinimumWidth(self.time_label.fontMetrics().horizontalAdvance(
            "frame 0000 (of 0-0000),  t = 000.000 s"))
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
        _quietly([self.frame_slider], apply)

    def _follow_controls(self):
        if self.source is not None:
            self.source.loop = self.loop_box.isChecked()
            self.source.set_speed(self.speed, time.perf_counter())

    def _follow_state(self):
        # the recording stopped itself at its end
        if self.source is not None and self.source.state != "playing":
            self.set_playing(False)

    def _on_frame(self, index):
        _quietly([self.frame_slider], lambda: self.frame_slider.setValue(index))

    def _on_solved(self, solved):
        if self.source is not None:
            # numbered from 0, as in exports, sidecars, --frame and --report
            self.time_label.setText(f"frame {solved.frame} (of 0-{len(self.source) - 1}),  "
                                    f"t = {solved.time:.3f} s")

    def _play_toggled(self, on):
        self.play_button.setText("Pause" if on else "Play")
        if on and self.source is not None:
            self.source.play(time.perf_counter())
            self._timer.start()
        else:
            self._timer.stop()
            if self.source is not None:
                self.source.pause()

    def _tick(self):
        if self.source is not None:
            self.source.advance(time.perf_counter())

"""The Display panel: the map and its colours, the arrows and theirs, scales, axes, camera.

It sets :class:`~tactile_viewer.model.display.Display` fields through the model
and follows its ``display_changed``; a camera preset leaves as a Qt signal for
the window.
"""

from __future__ import annotations

from PyQt6 import QtCore, QtWidgets

from ..model.display import MAX_SMOOTHING
from ..model.viewer_model import ViewerModel
from .number_fields import number_field, quietly, show_number

__all__ = ["DisplayPanel", "MAP_CHOICES"]

MAP_CHOICES = (("normal pressure", "pressure"), ("sensor stress", "stress"), ("none", "none"))


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
        self.scale_spin = number_field(decimals=1, maximum=1e6, singleStep=5.0, suffix=" mm/N")
        self.scale_spin.valueChanged.connect(lambda v: model.set_display(arrow_scale=v / 1e3))
        self.threshold_spin = number_field(decimals=2, maximum=1e6, singleStep=1.0, suffix=" mN")
        self.threshold_spin.valueChanged.connect(lambda v: model.set_display(threshold=v / 1e3))
        self.range_box = QtWidgets.QCheckBox("auto map range")
        self.range_box.setChecked(True)
        self.range_box.toggled.connect(lambda on: model.set_display(auto_range=on))
        self.range_spin = number_field(decimals=2, maximum=1e6, singleStep=1.0, suffix=" kPa")
        self.range_spin.valueChanged.connect(lambda v: model.set_display(range_max=v * 1e3))
        self.arrow_range_box = QtWidgets.QCheckBox("auto arrow range")
        self.arrow_range_box.setChecked(True)
        self.arrow_range_box.toggled.connect(lambda on: model.set_display(arrow_auto_range=on))
        self.arrow_range_spin = number_field(decimals=2, maximum=1e6, singleStep=5.0,
                                                         suffix=" mN")
        self.arrow_range_spin.valueChanged.connect(lambda v: model.set_display(arrow_range_max=v / 1e3))
        self.in_plane_box = QtWidgets.QCheckBox("in-plane arrows")
        self.in_plane_box.toggled.connect(lambda on: model.set_display(in_plane=on))
        self.gain_spin = number_field(decimals=1, minimum=0.1, maximum=100.0, singleStep=0.5,
                                                  prefix="x ")
        self.gain_spin.setValue(model.display.in_plane_gain)
        self.gain_spin.valueChanged.connect(lambda v: model.set_display(in_plane_gain=v))
        self.smoothing_spin = number_field(decimals=2, maximum=MAX_SMOOTHING, singleStep=0.05,
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
                (self.range_box, "The map's colours span 0 to this frame's largest value rounded up to a "
                                 "round number (on: the bar's labels stay still while the peak moves a "
                                 "little), or 0 to the value beside on every frame (off)"),
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
                (self.arrow_range_box, "The arrows' colours span 0 to this frame's largest shown force "
                                       "rounded up to a round number (on), or 0 to the value beside on every "
                                       "frame, so colours compare across frames (off)"),
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
            show_number(self.scale_spin, d.arrow_scale * 1e3)
            show_number(self.threshold_spin, d.threshold * 1e3)
            self.range_box.setChecked(d.auto_range)
            show_number(self.range_spin, d.range_max / 1e3)
            self.arrow_range_box.setChecked(d.arrow_auto_range)
            show_number(self.arrow_range_spin, d.arrow_range_max * 1e3)
            self.in_plane_box.setChecked(d.in_plane)
            show_number(self.gain_spin, d.in_plane_gain)
            show_number(self.smoothing_spin, d.smoothing)
            self.axes_box.setChecked(d.axes)
            self.ids_box.setChecked(d.taxel_ids)
        quietly([self.map_box, self.colormap_box, self.arrows_box, self.resultant_box, self.scale_spin,
                  self.threshold_spin, self.range_box, self.range_spin, self.arrow_range_box,
                  self.arrow_range_spin, self.in_plane_box, self.gain_spin, self.smoothing_spin,
                  self.axes_box, self.ids_box],
                 apply)
        self.range_spin.setEnabled(not d.auto_range)
        self.arrow_range_spin.setEnabled(not d.arrow_auto_range)
        self.gain_spin.setEnabled(d.in_plane)

"""The Parameters panel: Auto, shear ratio and direction, kernel and quality preset, the geometry line.

It sets model fields and follows the model's events: a moved slider goes to
:meth:`~tactile_viewer.model.viewer_model.ViewerModel.move_parameters` (the
rule for leaving Auto is the model's); a kernel or quality preset to factor
leaves as a Qt signal for the window.
"""

from __future__ import annotations

import math

from PyQt6 import QtCore, QtGui, QtWidgets

from solver.kernels import KERNELS

from ..model.captions import KERNEL_HELP, geometry_text
from ..model.shear_parameters import MAX_SHEAR_RATIO
from ..model.viewer_model import ViewerModel
from .number_fields import number_field, quietly, show_number

__all__ = ["ParametersPanel"]


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
        self.ratio_spin = number_field(decimals=2, singleStep=0.01, maximum=MAX_SHEAR_RATIO)
        self.direction_slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.direction_slider.setRange(-180, 180)
        self.direction_spin = number_field(decimals=1, singleStep=1.0, minimum=-180.0,
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
        # leaving Auto, the other keeps what Auto found (the model's rule)
        self.ratio_slider.valueChanged.connect(lambda v: model.move_parameters(shear_ratio=v / 100))
        self.ratio_spin.valueChanged.connect(lambda v: model.move_parameters(shear_ratio=v))
        self.direction_slider.valueChanged.connect(
            lambda v: model.move_parameters(shear_direction=math.radians(v)))
        self.direction_spin.valueChanged.connect(
            lambda v: model.move_parameters(shear_direction=math.radians(v)))
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
        quietly([self.kernel_box], lambda: self.kernel_box.setCurrentText(kernel))

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
            show_number(self.ratio_spin, ratio)
            self.direction_slider.setValue(round(degrees))
            show_number(self.direction_spin, degrees)
        quietly([self.auto_box, self.ratio_slider, self.ratio_spin, self.direction_slider,
                  self.direction_spin], apply)

    def set_presets(self, chosen: dict, describe):
        """Offer measured presets: ``chosen`` label -> measurement, ``describe(m)`` its text."""
        def apply():
            while self.quality_box.count() > 1:
                self.quality_box.removeItem(1)
            for label, m in chosen.items():
                self.quality_box.addItem(f"{label}: {describe(m)}", m.configuration)
        quietly([self.quality_box], apply)

    def add_auto_action(self, menu: QtWidgets.QMenu) -> QtGui.QAction:
        """Add the Auto key (A) to ``menu``: the same switch as the checkbox."""
        action = menu.addAction("&Auto parameters", self._toggle_auto)
        action.setShortcut(QtGui.QKeySequence(QtCore.Qt.Key.Key_A))
        action.setToolTip("Toggle Auto: the shear ratio and direction found by the efficiency "
                          "maximum, or the sliders' values")
        return action

    def _toggle_auto(self):
        # the same switch as the checkbox (which a normal-only preset disables)
        if self.auto_box.isEnabled() and self.model.is_open:
            self.auto_box.toggle()

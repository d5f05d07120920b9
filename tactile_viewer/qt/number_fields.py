"""Quiet updates and typed number fields: how every panel shows model values in its widgets.

Model -> widgets goes through :func:`quietly` (no echo back into the model);
a number field (:func:`number_field`) takes a typed value on Enter, and
:func:`show_number` leaves alone what the user is typing there.
"""

from __future__ import annotations

from PyQt6 import QtWidgets

__all__ = ["quietly", "number_field", "show_number"]


def quietly(widgets, apply):
    # model -> widgets without echoing back into the model
    for w in widgets:
        w.blockSignals(True)
    try:
        apply()
    finally:
        for w in widgets:
            w.blockSignals(False)


def number_field(**options) -> QtWidgets.QDoubleSpinBox:
    # A typed number takes effect on Enter or on leaving the field (arrows and the wheel at once):
    # with keyboard tracking every key set the model, which wrote its value back into the field
    # while the user typed (0.8 became 0.00).
    field = QtWidgets.QDoubleSpinBox(**options)
    field.setKeyboardTracking(False)
    return field


def show_number(field: QtWidgets.QDoubleSpinBox, value: float):
    # model -> field, except over what the user is typing there and has not entered yet (in Auto
    # every solved frame shows its parameters)
    if field.hasFocus() and field.cleanText() != field.textFromValue(field.value()):
        return
    field.setValue(value)

"""Rows the window's dialogs share: a field with a button beside it, a message line, OK and Cancel."""

from __future__ import annotations

from PyQt6 import QtWidgets

__all__ = ["with_button", "layout_file_row", "add_message", "add_buttons"]

_ERROR_COLOUR = "color: #b00020"


def with_button(widget, label, slot) -> QtWidgets.QHBoxLayout:
    """``widget`` stretched, with a push button ``label`` calling ``slot`` beside it."""
    button = QtWidgets.QPushButton(label)
    button.clicked.connect(slot)
    row = QtWidgets.QHBoxLayout()
    row.addWidget(widget, 1)
    row.addWidget(button)
    return row


def layout_file_row(parent, line_edit: QtWidgets.QLineEdit, *, chosen=None) -> QtWidgets.QHBoxLayout:
    """``line_edit`` for a sensor layout file's path, with a *Browse...* button that picks one.

    ``chosen()``, when given, is called after a file was picked.
    """
    def browse():
        path, _ = QtWidgets.QFileDialog.getOpenFileName(parent, "Sensor layout", line_edit.text(),
                                                        "Sensor layout (*.json);;All files (*)")
        if path:
            line_edit.setText(path)
            if chosen is not None:
                chosen()
    return with_button(line_edit, "Browse...", browse)


def add_message(form: QtWidgets.QFormLayout, *, error: bool = True) -> QtWidgets.QLabel:
    """An empty, word-wrapped line under ``form`` for what the dialog has to say (in red: ``error``)."""
    message = QtWidgets.QLabel("")
    if error:
        message.setStyleSheet(_ERROR_COLOUR)
    message.setWordWrap(True)
    form.addRow(message)
    return message


def add_buttons(form: QtWidgets.QFormLayout, accept, reject, *,
                accept_button=QtWidgets.QDialogButtonBox.StandardButton.Ok) -> QtWidgets.QDialogButtonBox:
    """``accept_button`` (OK by default) and Cancel under ``form``, calling ``accept`` and ``reject``."""
    buttons = QtWidgets.QDialogButtonBox(accept_button | QtWidgets.QDialogButtonBox.StandardButton.Cancel)
    buttons.accepted.connect(accept)
    buttons.rejected.connect(reject)
    form.addRow(buttons)
    return buttons

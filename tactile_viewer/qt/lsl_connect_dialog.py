"""The Connect to an LSL stream dialog: look for streams (by name, type), pick one, its layout; remembered."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from PyQt6 import QtCore, QtWidgets

from ..sources.lsl_inlet import FoundStream, find_streams
from .form_rows import add_buttons, add_message, layout_file_row, with_button
from .preferences import Settings
from .tasks import Task

__all__ = ["LslConnection", "LslConnectDialog", "RESOLVE_TIMEOUT_S"]

RESOLVE_TIMEOUT_S = 1.0  # seconds the dialog listens for streams' announcements


@dataclass(frozen=True)
class LslConnection:
    """What to read: ``stream``, and ``layout`` (a JSON path, "" for the stream's own description)."""

    stream: FoundStream
    layout: str


class LslConnectDialog(QtWidgets.QDialog):
    """Look for LSL streams, list them, choose one and where its layout comes from.

    The search runs off the GUI thread (it listens for ``timeout`` seconds);
    the list shows every stream found, those matching the name and type typed.

    Parameters
    ----------
    timeout : float
        Seconds each search listens (default :data:`RESOLVE_TIMEOUT_S`).
    """

    searched = QtCore.pyqtSignal(int)  # a search ended with this many streams listed

    def __init__(self, parent=None, *, timeout: float = RESOLVE_TIMEOUT_S):
        super().__init__(parent)
        self.setWindowTitle("Connect to an LSL stream")
        self.setMinimumWidth(560)
        self.timeout = timeout
        self._task: Task | None = None
        form = QtWidgets.QFormLayout(self)
        self.name_edit = QtWidgets.QLineEdit()
        self.name_edit.setPlaceholderText("any name")
        form.addRow("stream name", self.name_edit)
        self.type_edit = QtWidgets.QLineEdit()
        self.type_edit.setPlaceholderText("any type (a tactile stream's is Tactile)")
        form.addRow("stream type", with_button(self.type_edit, "Search", self.search))
        self.stream_list = QtWidgets.QListWidget()
        form.addRow("streams found", self.stream_list)
        self.from_description = QtWidgets.QRadioButton("from the stream's description (<layout>)")
        self.from_file = QtWidgets.QRadioButton("from a layout file")
        self.from_description.setChecked(True)
        form.addRow("sensor layout", self.from_description)
        self.layout_edit = QtWidgets.QLineEdit()
        row = layout_file_row(self, self.layout_edit, chosen=lambda: self.from_file.setChecked(True))
        row.insertWidget(0, self.from_file)
        form.addRow("", row)
        self.layout_edit.textEdited.connect(lambda _text: self.from_file.setChecked(True))
        for widget, tip in (
                (self.name_edit, "The stream's exact LSL name; empty lists every stream"),
                (self.type_edit, "The stream's exact LSL type (Tactile for a tactile stream); empty: any"),
                (self.stream_list, "The streams that answered the last search: one float channel per taxel"),
                (self.from_description, "The stream describes its skin in <desc><layout> (nx, ny, pitch, "
                                        "thickness, units ...): see the LSL section of the documentation"),
                (self.layout_edit, "A sensor layout JSON file, as many taxels as the stream has channels")):
            widget.setToolTip(tip)
        self.message = add_message(form, error=False)
        add_buttons(form, self._accept, self.reject)
        self._restore()

    def search(self):
        """Look for streams in the background; the list fills when the search ends (``searched``)."""
        if self._task is not None and self._task.isRunning():
            return
        name, kind = self.name_edit.text().strip() or None, self.type_edit.text().strip() or None
        self.message.setStyleSheet("")
        self.message.setText(f"listening for streams for {self.timeout:g} s ...")
        timeout = self.timeout
        self._task = Task(lambda _progress: find_streams(name=name, stream_type=kind, timeout=timeout), self)
        self._task.succeeded.connect(self._found)
        self._task.failed.connect(self._search_failed)
        self._task.start()

    def _found(self, streams):
        self.stream_list.clear()
        for stream in streams:
            item = QtWidgets.QListWidgetItem(stream.describe())
            item.setData(QtCore.Qt.ItemDataRole.UserRole, stream)
            self.stream_list.addItem(item)
        if streams:
            self.stream_list.setCurrentRow(0)
            self.message.setText(f"{len(streams)} streams found")
        else:
            self._warn("no stream found: is its program running on this network, and are the name and type "
                       "exact? Search again")
        self.searched.emit(len(streams))

    def _search_failed(self, exc):
        self._warn(f"the search failed: {exc}")
        self.searched.emit(0)

    def _warn(self, text: str):
        self.message.setStyleSheet("color: #b00020")
        self.message.setText(text)


    def _restore(self):
        store = settings()

        def text(name):  # an edited file's number or list is no text
            value = store.value(name)
            return value if isinstance(value, str) else ""
        self.name_edit.setText(text("lsl_name"))
        self.type_edit.setText(text("lsl_type"))
        self.layout_edit.setText(text("lsl_layout"))
        if text("lsl_layout_from") == "file":
            self.from_file.setChecked(True)

    def connection(self) -> LslConnection:
        """The stream chosen and its layout; ValueError names what is missing."""
        item = self.stream_list.currentItem()
        if item is None:
            raise ValueError("search, then choose a stream from the list")
        layout = ""
        if self.from_file.isChecked():
            layout = self.layout_edit.text().strip()
            if not layout:
                raise ValueError("choose the sensor layout file (JSON), or take the layout from the stream")
            if not Path(layout).is_file():
                raise ValueError(f"sensor layout {layout} does not exist")
        return LslConnection(item.data(QtCore.Qt.ItemDataRole.UserRole), layout)

    def _accept(self):
        try:
            chosen = self.connection()
        except ValueError as exc:
            self._warn(str(exc))
            return
        settings().update(dict(lsl_name=self.name_edit.text().strip(), lsl_type=self.type_edit.text().strip(),
                               lsl_layout=self.layout_edit.text().strip(),
                               lsl_layout_from="file" if chosen.layout else "description"))
        self.accept()

    def done(self, result):
        # a search still listening finishes first: its thread must not outlive the dialog
        if self._task is not None:
            self._task.wait()
        super().done(result)


def settings() -> Settings:
    """The Connect dialog's store (``live.json``): the LSL values sit beside the port's."""
    from .connect_dialog import settings as live_settings

    return live_settings()

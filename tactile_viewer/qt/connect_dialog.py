"""The Connect dialog of the live mode: port or URL, baud rate, format, sensor layout; remembered."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from PyQt6 import QtCore, QtWidgets

from ..sources.device import announced_boards
from ..sources.protocol import FORMATS
from ..sources.serial_reader import MAX_BAUDRATE, check_baudrate
from .form_rows import add_buttons, add_message, layout_file_row, with_button
from .preferences import Settings

__all__ = ["Connection", "ConnectDialog", "settings"]

BAUD_RATES = ("9600", "57600", "115200", "230400", "460800", "921600", "1000000", "2000000")


@dataclass(frozen=True)
class Connection:
    """What to connect to: ``url`` (a device path or pyserial URL), ``layout`` (JSON path)."""

    url: str
    baudrate: int
    fmt: str
    layout: str


def settings() -> Settings:
    """Where the dialog remembers its last values (``live.json`` beside the window's settings)."""
    return Settings("live")


def available_ports() -> list[tuple[str, str, dict]]:
    """``(device, description, facts)`` of the serial ports present, then of tactile-sim boards running.

    Serial ports come with their links (``/dev/serial/by-id/...``); a simulated board (a
    pseudo-terminal, in no list of serial ports) by its link when it has one, with its layout file
    and format in ``facts`` (empty for a serial port).
    """
    from serial.tools import list_ports

    ports = [(p.device, p.description or "", {})
             for p in sorted(list_ports.comports(include_links=True), key=lambda p: p.device)]
    for board in announced_boards():
        described = (f"tactile-sim, scene {board.get('scene')}, {board.get('format')}"
                     + (f", on {board['device']}" if board.get("link") else ""))
        ports.append((board.get("link") or board["device"], described, board))
    return ports


class ConnectDialog(QtWidgets.QDialog):
    """Choose a port (listed, or any URL typed in), baud rate, format and sensor layout file."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.setWindowTitle("Connect to a sensor board")
        self.setMinimumWidth(560)  # room for a device path and its description (it was 320 px)
        form = QtWidgets.QFormLayout(self)
        self.port_box = QtWidgets.QComboBox(editable=True)
        self.port_box.setInsertPolicy(QtWidgets.QComboBox.InsertPolicy.NoInsert)
        self._fill_ports()
        self.port_box.activated.connect(self._port_chosen)
        self.port_box.lineEdit().setPlaceholderText("/dev/ttyACM0, loop://, socket://host:port")
        form.addRow("port or URL", with_button(self.port_box, "Refresh", self._refresh))
        self.baud_box = QtWidgets.QComboBox(editable=True)
        self.baud_box.addItems(BAUD_RATES)
        form.addRow("baud rate", self.baud_box)
        self.format_box = QtWidgets.QComboBox()
        self.format_box.addItems(FORMATS)
        form.addRow("format", self.format_box)
        self.layout_edit = QtWidgets.QLineEdit()
        form.addRow("sensor layout", layout_file_row(self, self.layout_edit))
        for widget, tip in (
                (self.port_box, "A serial port of this machine, a tactile-sim board running here (its "
                                "layout and format come with it), or a pyserial URL (socket://host:port, "
                                "loop://)"),
                (self.baud_box, "The board's baud rate (ignored by pseudo-terminals and sockets)"),
                (self.format_box, "binary: framed float32 frames with sequence numbers and CRC; text: one "
                                  "line of values per frame"),
                (self.layout_edit, "The board's sensor layout file (JSON: grid or positions, pitch, "
                                   "elastomer thickness, Poisson ratio, calibration)")):
            widget.setToolTip(tip)
        self.message = add_message(form)
        add_buttons(form, self._accept, self.reject)
        self._restore()

    def _fill_ports(self):
        for device, description, facts in available_ports():
            self.port_box.addItem(f"{device}  ({description})" if description else device, (device, facts))
            self.port_box.setItemData(self.port_box.count() - 1, description,
                                      QtCore.Qt.ItemDataRole.ToolTipRole)

    def _port_chosen(self, index: int):
        # the list shows "device  (description)": the field keeps the device; a simulated board
        # brings its own layout file and format
        data = self.port_box.itemData(index)
        if not data:
            return
        device, facts = data
        self.port_box.setEditText(device)
        if facts.get("layout"):
            self.layout_edit.setText(facts["layout"])
        if facts.get("format") in FORMATS:
            self.format_box.setCurrentText(facts["format"])

    def _refresh(self):
        text = self.port_box.currentText()
        self.port_box.clear()
        self._fill_ports()
        self.port_box.setEditText(text)


    def _restore(self):
        store = settings()

        def text(name, default):  # an edited file's number or list is no text: the default
            value = store.value(name)
            return value if isinstance(value, str) else default
        self.port_box.setEditText(text("url", ""))
        self.baud_box.setEditText(text("baudrate", "115200"))
        self.format_box.setCurrentText(text("format", "binary"))
        self.layout_edit.setText(text("layout", ""))

    def connection(self) -> Connection:
        """The values entered; ValueError names what is missing or wrong."""
        url = self.port_box.currentText().strip()
        if not url:
            raise ValueError("choose a port or type a URL")
        text = self.baud_box.currentText().strip()
        try:
            baudrate = check_baudrate(int(text) if text.isdigit() and len(text) <= 10 else text)
        except ValueError:
            raise ValueError(f"baud rate must be a whole number from 1 to {MAX_BAUDRATE}, "
                             f"got {text!r}") from None
        layout = self.layout_edit.text().strip()
        if not layout:
            raise ValueError("choose the sensor layout file (JSON) that describes the board")
        if not Path(layout).is_file():
            raise ValueError(f"sensor layout {layout} does not exist")
        return Connection(url, baudrate, self.format_box.currentText(), layout)

    def _accept(self):
        try:
            chosen = self.connection()
        except ValueError as exc:
            self.message.setText(str(exc))
            return
        settings().update(dict(url=chosen.url, baudrate=str(chosen.baudrate), format=chosen.fmt,
                               layout=chosen.layout))
        self.accept()


"""The serial board: a live source over pyserial's ``serial_for_url``, and its port's checks. No Qt.

:class:`SerialReader` is the :class:`~tactile_viewer.sources.live.LiveSource` transport for
device paths, ``loop://``, ``socket://`` ...: it reconnects only to the device it started with
(:mod:`tactile_viewer.sources.device`), and drops what a port held before it was opened
(:func:`drain_backlog`). :func:`check_baudrate` is the baud rate a port takes.
"""

from __future__ import annotations

import time

from ..io.layout import SensorLayout
from .device import DeviceCheck, DeviceMismatch, identify
from .live import LiveSource

__all__ = ["SerialReader"]


# The largest baud rate a serial port takes: the operating system holds it in a C int (a larger one
# raised OverflowError on the reader's thread). USB boards ignore it; UARTs stop far below.
MAX_BAUDRATE = 2**31 - 1


def check_baudrate(baudrate) -> int:
    """``baudrate`` as an int; ValueError unless it is a whole number from 1 to :data:`MAX_BAUDRATE`."""
    if isinstance(baudrate, bool) or not isinstance(baudrate, int) or not 1 <= baudrate <= MAX_BAUDRATE:
        raise ValueError(f"baud rate must be a whole number from 1 to {MAX_BAUDRATE}, got {baudrate!r}")
    return baudrate


BACKLOG_PAUSE_S = 0.0005  # nothing more after this long: the backlog is out, the board's present comes
BACKLOG_LIMIT_S = 0.25  # the most a connection spends dropping what was queued before it


def drain_backlog(port, *, pause: float = BACKLOG_PAUSE_S, limit: float = BACKLOG_LIMIT_S) -> int:
    """Read and drop what ``port`` holds already, until nothing more comes within ``pause``; bytes dropped.

    A backlog comes at memory speed, a board's frames at its pace: what is still waiting, or comes
    within ``pause`` of the last read, is the backlog. Stops after ``limit`` seconds however busy
    the port is.
    """
    dropped, start = 0, time.monotonic()
    while time.monotonic() - start < limit:
        waiting = port.in_waiting
        if not waiting:
            time.sleep(pause)
            if not port.in_waiting:
                break
            continue
        dropped += len(port.read(waiting))
    return dropped


class SerialReader(LiveSource):
    """The serial board: a :class:`LiveSource` over pyserial's ``serial_for_url``.

    Parameters
    ----------
    url : str
        A device path or any pyserial URL (``loop://``, ``socket://host:port``).
    layout : SensorLayout
    fmt : {"binary", "text"}
    baudrate : int
    reconnect_interval
        As for :class:`LiveSource`.
    """

    def __init__(self, url: str, layout: SensorLayout, *, fmt: str = "binary", baudrate: int = 115200,
                 reconnect_interval: float = 0.5):
        import serial  # pyserial; imported here so that the codecs work without it

        self.baudrate = check_baudrate(baudrate)
        super().__init__(url, layout, fmt=fmt, reconnect_interval=reconnect_interval)
        self.lost = (serial.SerialException, OSError)
        self.device = DeviceCheck(url)  # reconnect only to the device it started with

    @property
    def same_device_known(self) -> bool:
        return self.device.known

    @property
    def identity_notice(self) -> str:
        return self.device.notice

    def _open(self):
        import serial

        identity = identify(self.url)
        if self.device.started:
            self.device.require(identity)  # another device at the path: refused, retried later
        port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.05)
        if not self.device.started:
            self.device.first(identity)
        else:
            try:  # and again: the device at the path may have changed while it was being opened
                self.device.require(identify(self.url))
            except DeviceMismatch:
                port.close()
                raise
        port.reset_input_buffer()  # stale bytes queued before we connected
        # and what a pseudo-terminal or a driver still pushes of them: a backlog stamped on arrival
        # would read as a burst of thousands of frames a second (a real board sends at its pace)
        self.backlog_bytes += drain_backlog(port)
        return port

    def _read(self, port) -> bytes:
        # the first byte (waiting up to the port's timeout when none is there), then what came with
        # it: a frame arrives in one piece and is handled in one pass (a 1 kHz board's reader took
        # 25 to 28% of a core at two passes a frame, 23 to 25% at one)
        data = port.read(max(1, port.in_waiting))
        waiting = port.in_waiting if data else 0
        return data + port.read(waiting) if waiting else data

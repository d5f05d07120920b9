"""Live sources: what every transport shares (:class:`LiveSource`) and the serial board. No Qt.

A new transport (a network stream, say) is one subclass of :class:`LiveSource`
that opens, reads and closes its connection; the reader thread, reconnection,
decoding, calibration, statistics, recording and the hand-off to the GUI are
shared.

The reader runs in its own thread (``threading``): it reads (the serial board
through pyserial's ``serial_for_url``: device paths, ``loop://``,
``socket://`` ...), decodes, turns raw values into pascals, stamps each frame with its receive time, counts,
records every frame, and hands the latest to the GUI through a callback. The
GUI thread never reads the port and the reader never touches the scene.
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .layout import SensorLayout
from .protocol import Frame, make_decoder
from .recording import Recorder

__all__ = ["Calibration", "LiveStats", "LiveFrame", "LiveSource", "SerialReader"]


class Calibration:
    """Raw values to pascals, minus a baseline taken by :meth:`tare`. Thread-safe."""

    def __init__(self, layout: SensorLayout):
        self.layout = layout
        self.baseline = np.zeros(layout.count)
        self._lock = threading.Lock()
        self._taring: list | None = None
        self._tare_count = 0

    def tare(self, frames: int = 50) -> None:
        """Average the next ``frames`` frames and subtract that baseline from then on."""
        if isinstance(frames, bool) or not (isinstance(frames, int) and frames >= 1):
            raise ValueError(f"frames must be a positive integer, got {frames!r}")
        with self._lock:
            self._taring, self._tare_count = [], frames

    @property
    def taring(self) -> bool:
        return self._taring is not None

    def __call__(self, raw: np.ndarray) -> np.ndarray:
        pascals = self.layout.to_pascals(raw)
        with self._lock:
            if self._taring is not None:
                self._taring.append(pascals)
                if len(self._taring) >= self._tare_count:
                    self.baseline = np.mean(self._taring, axis=0)
                    self._taring = None
            return pascals - self.baseline


class LiveStats:
    """Received frames, their rate from receive times, lost frames from sequence gaps.

    Parameters
    ----------
    window : float
        Seconds of receive times the rate is measured over.
    """

    def __init__(self, window: float = 1.0):
        self.window = window
        self.received = 0
        self.lost = 0
        self.out_of_order = 0
        self.last_time: float | None = None
        self.last_seq: int | None = None  # unwrapped, continuing across reconnections
        self._wire: int | None = None  # the last uint16 seen on this connection
        self._times: deque = deque()

    def new_connection(self) -> None:
        """A (re)opened device starts its own sequence: no gap is counted across the reconnection."""
        self._wire = None

    def add(self, seq: int | None, t: float) -> int | None:
        """Count one frame received at ``t`` seconds; returns its unwrapped sequence number."""
        self.received += 1
        self.last_time = t
        self._times.append(t)
        while self._times and self._times[0] < t - self.window:
            self._times.popleft()
        if seq is None:
            return None
        if self._wire is None:
            self._wire = seq
            self.last_seq = seq if self.last_seq is None else self.last_seq + 1
            return self.last_seq
        # uint16 on the wire: a step is the forward distance modulo 2^16; a large
        # one means a reordered or repeated frame, not 60000 lost ones
        step = (seq - self._wire) % 65536
        if step == 0 or step > 32768:
            self.out_of_order += 1
            return self.last_seq + (step - 65536 if step else 0)
        self._wire = seq
        self.lost += step - 1
        self.last_seq += step
        return self.last_seq

    def rate(self, now: float | None = None) -> float:
        """Frames per second over the last ``window`` seconds (0 when silent)."""
        times = self._times
        if len(times) < 2 or (now is not None and now - times[-1] > self.window):
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0]) if times[-1] > times[0] else 0.0

    def silence(self, now: float) -> float:
        """Seconds since the last frame (inf before the first)."""
        return math.inf if self.last_time is None else now - self.last_time


@dataclass(frozen=True)
class LiveFrame:
    """One received frame in pascals.

    Attributes
    ----------
    stress : (m,) ndarray
        Pascals, calibrated and tared.
    t : float
        Receive time, seconds since the reader started.
    seq : int or None
        Unwrapped sequence number (binary), None for text.
    """

    stress: np.ndarray
    t: float
    seq: int | None


class LiveSource:
    """A live source of frames: the part every transport shares. No Qt.

    A transport (a serial port, a network stream) subclasses this and says how
    to open a connection, read bytes from it and close it (:meth:`_open`,
    :meth:`_read`, :meth:`_close`, and which errors mean "connection lost":
    :attr:`lost`). Everything else is here, the same for every source: a
    reader thread that reconnects, decoding, calibration to pascals, statistics,
    recording of every frame (any source can record), and the hand-off of the
    newest frame to the GUI.

    Parameters
    ----------
    label : str
        What the source is, for people (the URL).
    layout : SensorLayout
    fmt : {"binary", "text"}
    on_frame : callable, optional
        Called from the reader thread with no arguments when a new frame is
        waiting in :meth:`take_latest` (once until it is taken: the GUI may
        skip frames, the recorder never does).
    reconnect_interval : float
        Seconds between attempts to reopen a lost connection.
    """

    lost: tuple = (OSError,)

    def __init__(self, label: str, layout: SensorLayout, *, fmt: str = "binary", on_frame=None,
                 reconnect_interval: float = 0.5):
        self.url, self.layout, self.fmt = label, layout, fmt
        self.calibration = Calibration(layout)
        self.decoder = make_decoder(fmt, layout.count)
        self.stats = LiveStats()
        self.state = "stopped"
        self.error = ""
        self.reconnects = 0
        self.failures = 0  # chunks whose handling raised (shown in the live status)
        self.recorder: Recorder | None = None
        self._on_frame = on_frame
        self._reconnect_interval = reconnect_interval
        self._latest: LiveFrame | None = None
        self._notified = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._origin = time.perf_counter()

    # -- what a transport provides ------------------------------------------------------------

    def _open(self):
        """A new connection (raising one of :attr:`lost` when it cannot be opened now)."""
        raise NotImplementedError

    def _read(self, connection) -> bytes:
        """The bytes waiting (``b""`` after a short wait when there are none)."""
        raise NotImplementedError

    def _close(self, connection) -> None:
        connection.close()

    # -- control (any thread) ------------------------------------------------------------

    def start(self) -> None:
        """Connect (raising if that fails now; later losses are retried) and start reading."""
        connection = self._open()
        self.state = "connected"
        self._origin = time.perf_counter()
        self._thread = threading.Thread(target=self._run, args=(connection,), name=f"source {self.url}",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self.state = "stopped"
        self.stop_recording()

    def start_recording(self, path, *, flush_interval: float = 1.0) -> Recorder:
        recorder = Recorder(path, self.layout, flush_interval=flush_interval,
                            description=f"live from {self.url} ({self.fmt})")
        self.recorder = recorder
        return recorder

    def stop_recording(self) -> Path | None:
        recorder, self.recorder = self.recorder, None
        return recorder.close() if recorder is not None else None

    def take_latest(self) -> LiveFrame | None:
        """The newest frame not yet taken (None if none arrived since)."""
        with self._lock:
            frame, self._latest, self._notified = self._latest, None, False
        return frame

    def now(self) -> float:
        return time.perf_counter() - self._origin

    def rejected(self) -> Counter:
        """Rejected frames by reason so far (a copy)."""
        return Counter(self.decoder.rejected)

    # -- the reader thread -------------------------------------------------------------------

    def _run(self, connection) -> None:
        while not self._stop.is_set():
            if connection is None:
                try:
                    connection = self._open()
                except (*self.lost, ValueError) as exc:
                    self.state, self.error = "reconnecting", str(exc)
                    self._stop.wait(self._reconnect_interval)
                    continue
                self.decoder.reset()
                self.stats.new_connection()
                self.reconnects += 1
                self.state, self.error = "connected", ""
            try:
                data = self._read(connection)
            except self.lost as exc:
                self.state, self.error = "reconnecting", str(exc)
                self._close(connection)
                connection = None
                continue
            if data:
                try:
                    self._handle(data)
                except Exception as exc:  # a bug must not end the reading (or the recording)
                    self.failures += 1
                    self.error = f"internal error while decoding: {exc!r}"
            elif self.recorder is not None:
                self.recorder.tick(self.now())
        if connection is not None:
            self._close(connection)

    def _handle(self, data: bytes) -> None:
        t = self.now()
        frames: list[Frame] = self.decoder.feed(data)
        latest = None
        for frame in frames:
            stress = self.calibration(frame.values)
            seq = self.stats.add(frame.seq, t)
            recorder = self.recorder
            if recorder is not None:
                recorder.add(seq if seq is not None else self.stats.received - 1, t, stress)
            latest = LiveFrame(stress, t, seq)
        if latest is not None:
            with self._lock:
                self._latest = latest
                notify = not self._notified
                self._notified = True
            if notify and self._on_frame is not None:
                self._on_frame()


class SerialReader(LiveSource):
    """The serial board: a :class:`LiveSource` over pyserial's ``serial_for_url``.

    Parameters
    ----------
    url : str
        A device path or any pyserial URL (``loop://``, ``socket://host:port``).
    layout : SensorLayout
    fmt : {"binary", "text"}
    baudrate : int
    on_frame, reconnect_interval
        As for :class:`LiveSource`.
    """

    def __init__(self, url: str, layout: SensorLayout, *, fmt: str = "binary", baudrate: int = 115200,
                 on_frame=None, reconnect_interval: float = 0.5):
        import serial  # pyserial; imported here so that the codecs work without it

        super().__init__(url, layout, fmt=fmt, on_frame=on_frame, reconnect_interval=reconnect_interval)
        self.baudrate = baudrate
        self.lost = (serial.SerialException, OSError)

    def _open(self):
        import serial

        port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.05)
        port.reset_input_buffer()  # stale bytes queued before we connected
        return port

    def _read(self, port) -> bytes:
        return port.read(max(1, port.in_waiting))

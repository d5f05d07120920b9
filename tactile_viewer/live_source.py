"""Live sources: what every transport shares (:class:`LiveSource`) and the serial board. No Qt.

A :class:`LiveSource` is a :class:`~tactile_viewer.source.Source` whose frames
come from a connection read on its own thread. A new transport (a network
stream, say) is one subclass that opens, reads and closes its connection; the
reader thread, reconnection, decoding, calibration, statistics, recording
and the hand-off of the newest frame are shared.

The reader (the serial board through pyserial's ``serial_for_url``: device
paths, ``loop://``, ``socket://`` ...) decodes, turns raw values into pascals,
stamps each frame with its receive time, counts, records every frame, and
announces the newest through ``frame_arrived``. The GUI thread never reads
the port and the reader never touches the scene.
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter, deque

import numpy as np

from .layout import SensorLayout
from .protocol import Frame, make_decoder
from .source import Source, SourceFrame

__all__ = ["Calibration", "LiveStats", "LiveSource", "SerialReader"]


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


class LiveSource(Source):
    """A live source of frames: the part every transport shares. No Qt.

    A transport (a serial port, a network stream) subclasses this and says how
    to open a connection, read bytes from it and close it (:meth:`_open`,
    :meth:`_read`, :meth:`_close`, and which errors mean "connection lost":
    :attr:`lost`). Everything else is here, the same for every transport: a
    reader thread that reconnects, decoding, calibration to pascals,
    statistics, and the :class:`~tactile_viewer.source.Source` interface
    (recording of every frame, the newest frame for the display). Its
    :attr:`state` is "stopped", "connected" or "reconnecting"; frames carry
    their receive time and unwrapped sequence number.

    Parameters
    ----------
    url : str
        Where the transport connects.
    layout : SensorLayout
    fmt : {"binary", "text"}
    reconnect_interval : float
        Seconds between attempts to reopen a lost connection.
    """

    live = True
    lost: tuple = (OSError,)

    def __init__(self, url: str, layout: SensorLayout, *, fmt: str = "binary",
                 reconnect_interval: float = 0.5):
        super().__init__(f"{url} ({fmt})", layout.grid)
        self.url, self.layout, self.fmt = url, layout, fmt
        self.calibration = Calibration(layout)
        self.decoder = make_decoder(fmt, layout.count)
        self.stats = LiveStats()
        self.error = ""
        self.reconnects = 0
        self.failures = 0  # chunks whose handling raised (shown in the live status)
        self._reconnect_interval = reconnect_interval
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
        self._set_state("connected")
        self._origin = time.perf_counter()
        self._thread = threading.Thread(target=self._run, args=(connection,), name=f"source {self.url}",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        super().stop()

    def now(self) -> float:
        """Seconds since the reader started (the clock of the frames' receive times)."""
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
                    self.error = str(exc)
                    self._set_state("reconnecting")
                    self._stop.wait(self._reconnect_interval)
                    continue
                self.decoder.reset()
                self.stats.new_connection()
                self.reconnects += 1
                self.error = ""
                self._set_state("connected")
            try:
                data = self._read(connection)
            except self.lost as exc:
                self.error = str(exc)
                self._set_state("reconnecting")
                self._close(connection)
                connection = None
                continue
            if data:
                try:
                    self._handle(data)
                except Exception as exc:  # a bug must not end the reading (or the recording)
                    self.failures += 1
                    self.error = f"internal error while decoding: {exc!r}"
            else:
                self._tick_recording(self.now())
        if connection is not None:
            self._close(connection)

    def _handle(self, data: bytes) -> None:
        t = self.now()
        frames: list[Frame] = self.decoder.feed(data)
        self._publish([SourceFrame(self.calibration(frame.values), t, self.stats.add(frame.seq, t))
                       for frame in frames])


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

        super().__init__(url, layout, fmt=fmt, reconnect_interval=reconnect_interval)
        self.baudrate = baudrate
        self.lost = (serial.SerialException, OSError)

    def _open(self):
        import serial

        port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.05)
        port.reset_input_buffer()  # stale bytes queued before we connected
        return port

    def _read(self, port) -> bytes:
        return port.read(max(1, port.in_waiting))

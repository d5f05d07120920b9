"""Live sources: what every transport shares (:class:`LiveSource`), its calibration and statistics. No Qt.

A :class:`LiveSource` is a :class:`~tactile_viewer.sources.source.Source` whose frames
come from a connection read on its own thread. A new transport (a network
stream, say) is one subclass that opens, reads and closes its connection; the
reader thread, reconnection, decoding, calibration, statistics, recording
and the hand-off of the newest frame are shared.

The reader (the serial board, :class:`~tactile_viewer.sources.serial_reader.SerialReader`,
through pyserial's ``serial_for_url``: device paths, ``loop://``, ``socket://`` ...)
decodes, turns raw values into pascals, stamps each frame with its receive time,
counts, records every frame, and announces the newest through ``frame_arrived``.
The GUI thread never reads the port and the reader never touches the scene.
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from solver.arguments import MAX_STRESS

from ..io.layout import SensorLayout
from ..io.recording import StressCalibration, Tare
from .device import unknown_identity_notice
from .protocol import make_decoder
from .source import Source, SourceFrame

__all__ = ["Calibration", "LiveStats", "StatsSnapshot", "LiveSource", "loaded_while_taring",
           "LOADED_TARE_NOISE"]


class Calibration:
    """Raw values to pascals (the layout's units, gain, offset), minus a baseline taken by :meth:`tare`.

    Thread-safe: the reader calibrates, the GUI asks for a tare.
    """

    def __init__(self, layout: SensorLayout):
        self.layout = layout
        self.baseline = np.zeros(layout.count)
        self.warning: str | None = None  # why the last tare looked loaded (None: it did not)
        self._lock = threading.Lock()
        self._taring: list | None = None
        self._tare_count = 0
        self._completed: Tare | None = None

    def tare(self, frames: int = 50) -> None:
        """Average the next ``frames`` frames and subtract that baseline from then on."""
        if isinstance(frames, bool) or not (isinstance(frames, int) and frames >= 1):
            raise ValueError(f"frames must be a positive integer, got {frames!r}")
        with self._lock:
            self._taring, self._tare_count = [], frames

    @property
    def taring(self) -> bool:
        return self._taring is not None

    def stress_calibration(self) -> StressCalibration:
        """What a recording keeps: the layout's conversion and the baseline in force (from frame 0)."""
        return self.layout.calibration.retared(Tare(0, self.baseline) if np.any(self.baseline) else None)

    def take_completed(self) -> Tare | None:
        """The tare completed by the last frame calibrated, once (None when none was)."""
        with self._lock:
            tare, self._completed = self._completed, None
        return tare

    def __call__(self, raw: np.ndarray, t: float = math.nan) -> np.ndarray | None:
        """Pascals of one frame of raw values received at ``t`` seconds.

        None when the frame is no stress the solver takes: a value not finite
        once in pascals (a text board's 1e308 in kPa), or beyond
        :data:`solver.arguments.MAX_STRESS`; such a frame is not averaged into a tare.
        """
        pascals = self.layout.to_pascals(raw)
        if not np.all(np.abs(pascals) <= MAX_STRESS):  # NaN fails it too
            return None
        with self._lock:
            if self._taring is not None:
                self._taring.append(pascals)
                if len(self._taring) >= self._tare_count:
                    # (frames within MAX_STRESS: their mean cannot overflow)
                    samples, self._taring = np.array(self._taring), None
                    self.warning = loaded_while_taring(samples, self.baseline)
                    self.baseline = samples.mean(axis=0)
                    self._completed = Tare(0, self.baseline, t, len(samples))
            stress = pascals - self.baseline
        return stress if np.all(np.abs(stress) <= MAX_STRESS) else None


# A contact under the skin raises a group of taxels by many times their noise; an unloaded skin
# moves its tared zero by a fraction of it. Five times the noise is far above what 50 averaged
# noisy frames give (about 3/sqrt(50) of it at the highest of 256 taxels).
LOADED_TARE_NOISE = 5.0

# why a decoded frame is rejected after calibration (Calibration returns None for it)
NOT_A_STRESS = f"not a stress once calibrated (inf, or beyond {MAX_STRESS:g} Pa)"


def loaded_while_taring(samples: np.ndarray, previous: np.ndarray) -> str | None:
    """Why the frames averaged by a tare look like a contact, or None when they do not.

    Parameters
    ----------
    samples : (n, m) ndarray
        The frames averaged, pascals before any tare.
    previous : (m,) ndarray
        The baseline in force before (zeros: the layout's own zero).

    Notes
    -----
    The rise of each taxel over ``previous`` is compared, about the skin's
    median rise, with the frame-to-frame noise (the median over taxels of
    each taxel's standard deviation across the samples, or 1e-6 of the
    largest rise when the samples do not vary). A rise above
    :data:`LOADED_TARE_NOISE` times that noise is called a contact.
    """
    rise = samples.mean(axis=0) - previous
    excess = rise - np.median(rise)
    peak = int(np.argmax(excess))
    noise = float(np.median(samples.std(axis=0))) if len(samples) > 1 else 0.0
    noise = max(noise, 1e-6 * float(np.abs(excess).max()), np.finfo(float).tiny)
    if excess[peak] <= LOADED_TARE_NOISE * noise:
        return None
    return (f"the skin looked loaded while taring: taxel {peak} stood {excess[peak]:.4g} Pa above the rest "
            f"({excess[peak] / noise:.0f} times the noise). If something touched it, its load is now "
            "the zero: retake the tare with nothing on the skin (recordings keep the raw values, so a "
            "recording can be re-tared when it is opened).")


@dataclass(frozen=True)
class StatsSnapshot:
    """The statistics of a live source at one instant, all of them from the same count.

    Attributes
    ----------
    received, lost, out_of_order : int
        Frames received, lost to sequence gaps, and out of order or repeated.
    rate : float
        Frames per second over the last window (:meth:`LiveStats.rate`).
    silence : float
        Seconds since the last frame (inf before the first).
    longest_gap : float
        The longest wait between two reads that brought frames, seconds.
    """

    received: int
    lost: int
    out_of_order: int
    rate: float
    silence: float
    longest_gap: float


class LiveStats:
    """Received frames, their rate from receive times, lost frames from sequence gaps.

    The reader thread counts (:meth:`add`) while others read: :meth:`snapshot`
    gives every figure from one instant (reading the attributes one by one
    from another thread may mix two counts, and :meth:`rate` reads the
    receive times the reader is changing).

    Parameters
    ----------
    window : float
        Seconds of receive times the rate is measured over.
    """

    def __init__(self, window: float = 1.0):
        self._lock = threading.Lock()
        self.window = window
        self.received = 0
        self.lost = 0
        self.out_of_order = 0
        self.last_time: float | None = None
        self.longest_gap = 0.0  # seconds: the longest wait between two reads that brought frames
        self.last_seq: int | None = None  # unwrapped, continuing across reconnections
        self._wire: int | None = None  # the last uint16 seen on this connection
        self._times: deque = deque()

    def new_connection(self) -> None:
        """A (re)opened device starts its own sequence: no gap is counted across the reconnection."""
        self._wire = None

    def add(self, seq: int | None, t: float) -> int | None:
        """Count one frame received at ``t`` seconds; returns its unwrapped sequence number."""
        with self._lock:
            return self._add(seq, t)

    def snapshot(self, now: float) -> StatsSnapshot:
        """Every figure at ``now`` (seconds, the reader's clock), from one count."""
        with self._lock:
            return StatsSnapshot(self.received, self.lost, self.out_of_order, self.rate(now),
                                 self.silence(now), self.longest_gap)

    def _add(self, seq, t):
        self.received += 1
        if self.last_time is not None:
            self.longest_gap = max(self.longest_gap, t - self.last_time)
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
        """Frames per second over the last ``window`` seconds (0 when silent).

        Frames that arrive together share one receive time, so the frames
        that came with the window's first read are left out of the count:
        what arrived after it, over the time since it. (Counting them would
        read 110 on a 100 Hz board read ten frames at a time.)
        """
        times = self._times
        if len(times) < 2 or (now is not None and now - times[-1] > self.window):
            return 0.0
        span = times[-1] - times[0]
        if span <= 0:
            return 0.0
        return (len(times) - bisect.bisect_right(times, times[0])) / span

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
    statistics, and the :class:`~tactile_viewer.sources.source.Source` interface
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
        self.raw_dtype = "float32" if fmt == "binary" else "float64"  # binary frames carry float32
        self.calibration = Calibration(layout)
        self.decoder = make_decoder(fmt, layout.count)
        self.stats = LiveStats()
        self.error = ""
        self.reconnects = 0
        self.failures = 0  # chunks whose handling raised (shown in the live status)
        self.backlog_bytes = 0  # bytes queued before a connection, dropped when it opened
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

    @property
    def same_device_known(self) -> bool:
        """Whether a reconnection is known to reach the same device (a transport that can tell says so).

        When it is not known, a reconnection ends any recording, so that two
        devices' frames never share a file.
        """
        return False

    @property
    def identity_notice(self) -> str:
        """For the live panel: what an unknown device identity means ("" when the device is known)."""
        return "" if self.same_device_known else unknown_identity_notice(self.url)

    def _end_recording_at_reconnection(self) -> None:
        recorder = self.recorder
        if recorder is None:
            return
        written = self.stop_recording()
        self.message.emit("warning", "Recording ended at a reconnection",
                          f"{self.url} reconnected and cannot be identified as the same device, so the "
                          f"frames from now on are not added to {written or recorder.path}; start a new "
                          "recording to keep them.")

    # -- control (any thread) ------------------------------------------------------------

    def start(self) -> None:
        """Connect (raising if that fails now; later losses are retried) and start reading."""
        connection = self._open()
        self._set_state("connected")
        self._origin = time.perf_counter()
        self.clock_origin = time.time()
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

    def recorded_calibration(self) -> StressCalibration:
        return self.calibration.stress_calibration()

    def size_mismatch(self, layout_name: str = "") -> str:
        """What frames of the wrong value count held against the layout, in words ("" when none).

        Parameters
        ----------
        layout_name : str, optional
            The layout's file, to name it.
        """
        sizes = self.decoder.wrong_sizes.most_common()
        if not sizes:
            return ""
        held = ", ".join(f"{count} values ({frames} frames)" for count, frames in sizes[:3])
        named = f" {layout_name}" if layout_name else ""
        return f"frames of {held}; the layout{named} describes {self.layout.count} taxels"

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
                if not self.same_device_known:  # before "connected": a recording started then is kept
                    self._end_recording_at_reconnection()
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
            # on every pass, not only when the line is quiet: bytes that bring no frame (garbage,
            # rejected frames) must not hold back the frames waiting for their chunk
            self._tick_recording(self.now())
        if connection is not None:
            self._close(connection)

    def _handle(self, data: bytes) -> None:
        t = self.now()
        batch = []
        for frame in self.decoder.feed(data):
            stress = self.calibration(frame.values, t)
            if stress is None:
                # counted beside the decoder's own rejections (the live panel lists them), not
                # recorded: the frame is no stress (it was recorded, and failed every solve)
                self.decoder.rejected[NOT_A_STRESS] += 1
                continue
            tare = self.calibration.take_completed()
            if tare is not None:
                # frames before it go out untared, so the recording says from which frame it applies
                self._publish(batch)
                batch = []
                self._tare_taken(tare)
            batch.append(SourceFrame(stress, t, self.stats.add(frame.seq, t), frame.values))
        self._publish(batch)

    def _tare_taken(self, tare: Tare) -> None:
        self._to_recorder(lambda recorder: recorder.tare(tare))
        warning = self.calibration.warning
        if warning is not None:
            self.message.emit("warning", "Tare taken under load?", warning)

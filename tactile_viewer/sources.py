"""Live frame sources: sensor layouts, calibration, statistics, recording, the serial reader. No Qt.

The reader runs in its own thread (``threading``): it reads through pyserial's
``serial_for_url`` (device paths, ``loop://``, ``socket://`` ...), decodes, turns
raw values into pascals, stamps each frame with its receive time, counts,
records every frame, and hands the latest to the GUI through a callback. The
GUI thread never reads the port and the reader never touches the scene.
"""

from __future__ import annotations

import json
import math
import os
import threading
import time
import zipfile
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from solver import SensorGrid
from solver.arrays import read_only

from .protocol import Frame, make_decoder
from .recording import UNIT_SCALES, csv_geometry_header, geometry_fields, grid_from_fields

__all__ = ["LayoutError", "SensorLayout", "load_layout", "save_layout", "Calibration", "LiveStats",
           "Recorder", "LiveFrame", "SerialReader"]

RAW_UNITS = (*UNIT_SCALES, "counts")


class LayoutError(ValueError):
    """A sensor layout file that cannot be used; the message names the file and the problem."""


@dataclass(frozen=True, eq=False)
class SensorLayout:
    """How a board's raw values map onto the skin.

    ``pascals = gain * (raw - offset) * scale(units)`` per taxel, where
    ``scale`` is 1, 1e3 or 1e6 for ``"Pa"``, ``"kPa"``, ``"MPa"`` and 1 for
    ``"counts"`` (the gain then is pascals per count).

    Attributes
    ----------
    grid : SensorGrid
    units : str
        One of ``"Pa"``, ``"kPa"``, ``"MPa"``, ``"counts"``.
    gain : (m,) ndarray
    offset : (m,) ndarray
        Raw units.
    """

    grid: SensorGrid
    units: str = "Pa"
    gain: np.ndarray = field(default=1.0)
    offset: np.ndarray = field(default=0.0)

    def __post_init__(self):
        if self.units not in RAW_UNITS:
            raise ValueError(f"units must be one of {RAW_UNITS}, got {self.units!r}")
        m = self.grid.size
        for name in ("gain", "offset"):
            value = np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (m,)) \
                if np.ndim(getattr(self, name)) == 0 else np.asarray(getattr(self, name), dtype=float)
            if value.shape != (m,):
                raise ValueError(f"{name} must be one number or {m} numbers (one per taxel), "
                                 f"got shape {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be finite")
            object.__setattr__(self, name, read_only(value))

    @property
    def count(self) -> int:
        """Values per frame."""
        return self.grid.size

    def to_pascals(self, raw) -> np.ndarray:
        """``(m,)`` or ``(T, m)`` raw values to pascals."""
        return self.gain * (np.asarray(raw, dtype=float) - self.offset) * UNIT_SCALES.get(self.units, 1.0)


def load_layout(path) -> SensorLayout:
    """Read a sensor layout JSON file.

    Keys: ``nx``, ``ny``, ``pitch``, ``thickness`` (metres); optional
    ``poisson_ratio`` (the elastomer's nu, default 0.5), ``sensor_size`` (side
    of a square taxel, metres, default 0: point sensors), ``positions``
    ([[x, y], ...] metres), ``units``, ``gain``, ``offset`` (a number or one per
    taxel). Files written before nu and the taxel size were recorded have
    neither key and open with the defaults.

    Raises
    ------
    LayoutError
        The message names the file and the key that is wrong.
    """
    path = Path(path)
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LayoutError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LayoutError(f"{path}: not JSON ({exc})") from None
    if not isinstance(spec, dict):
        raise LayoutError(f"{path}: expected a JSON object, got {type(spec).__name__}")
    counts = ("taxels",) if "taxels" in spec else ("nx", "ny")
    missing = [k for k in (*counts, "pitch", "thickness") if k not in spec]
    if missing:
        raise LayoutError(f"{path}: missing {', '.join(repr(k) for k in missing)}")
    try:
        if not all(isinstance(spec[k], int) and not isinstance(spec[k], bool) for k in counts):
            raise ValueError(f"{' and '.join(counts)} must be whole numbers, got "
                             f"{' and '.join(repr(spec[k]) for k in counts)}")
        for key in ("pitch", "thickness"):
            if isinstance(spec[key], bool) or not isinstance(spec[key], (int, float)):
                raise ValueError(f"{key} must be a number of metres, got {spec[key]!r}")
        # SensorGrid checks nu and the taxel size (a string or a bool is no number there either)
        grid = grid_from_fields(pitch=float(spec["pitch"]), thickness=float(spec["thickness"]),
                                positions=spec.get("positions"), poisson_ratio=spec.get("poisson_ratio", 0.5),
                                sensor_size=spec.get("sensor_size", 0.0), **{k: spec[k] for k in counts})
        return SensorLayout(grid, spec.get("units", "Pa"), spec.get("gain", 1.0), spec.get("offset", 0.0))
    except (ValueError, TypeError) as exc:
        raise LayoutError(f"{path}: {exc}") from None


def save_layout(layout: SensorLayout, path) -> Path:
    """Write ``layout`` as the JSON file :func:`load_layout` reads (nu and the taxel size always written).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    one = lambda a: float(a[0]) if np.all(a == a[0]) else a.tolist()  # noqa: E731
    spec = {key: value.tolist() if isinstance(value, np.ndarray) else value
            for key, value in geometry_fields(layout.grid).items()}
    spec.update(units=layout.units, gain=one(layout.gain), offset=one(layout.offset))
    path.write_text(json.dumps(spec, indent=2) + "\n", encoding="utf-8")
    return path


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


class Recorder:
    """Writes every frame it is given to a recording, incrementally.

    ``.npz``: each flush appends one chunk (frames, t, seq) to the archive, which
    is a valid, loadable recording after every flush; :meth:`close` rewrites it
    as one plain recording. ``.csv``: rows ``seq, t, v0, ...`` appended and
    flushed. Flushes happen at least every ``flush_interval`` seconds of receive
    time, so a crash loses at most that much.
    """

    def __init__(self, path, layout: SensorLayout, *, flush_interval: float = 1.0, description: str = ""):
        path = Path(path)
        self.kind = path.suffix.lower()
        if self.kind not in (".npz", ".csv"):
            raise ValueError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
        self.path = path
        self.layout = layout
        self.flush_interval = flush_interval
        self.description = description or "live recording"
        self.written = 0
        self._rows: list = []
        self._closed = False
        self._chunks = 0
        self._last_flush: float | None = None
        self._lock = threading.Lock()
        grid = layout.grid
        # the geometry as every recording declares it (recording.geometry_fields), positions always
        self._meta = dict(geometry_fields(grid), units="Pa")
        self._meta["positions"] = grid.positions
        if self.kind == ".npz":
            with zipfile.ZipFile(path, "w") as archive:
                for key, value in (*self._meta.items(), ("description", self.description)):
                    _write_member(archive, key, np.asarray(value))
        else:
            header = csv_geometry_header(grid) + "# units=Pa\n"
            header += f"# description={' '.join(self.description.split())}\n# columns=seq,t\n"
            path.write_text(header, encoding="utf-8")

    def add(self, seq: int, t: float, stress: np.ndarray) -> None:
        """Queue one frame (``t`` in seconds); flushes when ``flush_interval`` has passed."""
        with self._lock:
            if self._closed:
                return  # the reader took this recorder just before it was stopped: the frame is past the end
            self._rows.append((seq, t, stress))
            if self._last_flush is None:
                self._last_flush = t
            if t - self._last_flush >= self.flush_interval:
                self._flush(t)

    def tick(self, now: float) -> None:
        """Flush if frames have waited ``flush_interval`` (called while the line is quiet)."""
        with self._lock:
            if self._rows and now - self._last_flush >= self.flush_interval:
                self._flush(now)

    def _flush(self, now: float | None = None) -> None:
        rows, self._rows = self._rows, []
        self._last_flush = now
        if rows:
            seq = np.array([r[0] for r in rows], dtype=np.int64)
            t = np.array([r[1] for r in rows])
            frames = np.array([r[2] for r in rows])
            if self.kind == ".npz":
                with zipfile.ZipFile(self.path, "a") as archive:
                    name = f"chunk{self._chunks:06d}"
                    for key, value in (("frames", frames), ("t", t), ("seq", seq)):
                        _write_member(archive, f"{name}_{key}", value)
                self._chunks += 1
            else:
                with open(self.path, "a", encoding="utf-8") as f:
                    np.savetxt(f, np.column_stack([seq, t, frames]), delimiter=",",
                               fmt=["%d", "%.6f"] + ["%.9g"] * frames.shape[1])
            self.written += len(rows)

    def close(self) -> Path | None:
        """Write what is left; an NPZ becomes one plain recording (chunks joined).

        Returns the path, or None (and no file) when no frame was recorded.
        """
        with self._lock:
            self._flush()
            self._closed = True
            if self.written == 0:
                self.path.unlink(missing_ok=True)
                return None
            if self.kind == ".npz":
                from .recording import load  # the chunk reader lives with the format
                recording = load(self.path)
                temporary = self.path.with_name(self.path.name + ".tmp")
                with open(temporary, "wb") as handle:
                    np.savez(handle, frames=recording.frames, t=recording.t,
                             seq=recording.seq if recording.seq is not None else np.zeros(0, np.int64),
                             description=self.description, **self._meta)
                os.replace(temporary, self.path)
        return self.path


def _write_member(archive: zipfile.ZipFile, key: str, value: np.ndarray) -> None:
    with archive.open(f"{key}.npy", "w", force_zip64=True) as member:
        np.lib.format.write_array(member, np.asarray(value), allow_pickle=False)


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


class SerialReader:
    """Reads frames from a serial URL in a worker thread, reconnecting when the device goes away.

    Parameters
    ----------
    url : str
        A device path or any pyserial URL (``loop://``, ``socket://host:port``).
    layout : SensorLayout
    fmt : {"binary", "text"}
    baudrate : int
    on_frame : callable, optional
        Called from the reader thread with no arguments when a new frame is
        waiting in :meth:`take_latest` (once until it is taken: the GUI may
        skip frames, the recorder never does).
    reconnect_interval : float
        Seconds between attempts to reopen a lost device.
    """

    def __init__(self, url: str, layout: SensorLayout, *, fmt: str = "binary", baudrate: int = 115200,
                 on_frame=None, reconnect_interval: float = 0.5):
        self.url, self.layout, self.fmt, self.baudrate = url, layout, fmt, baudrate
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

    # -- control (any thread) ------------------------------------------------------------

    def start(self) -> None:
        """Open the port (raising if it cannot be opened now) and start reading."""
        port = self._open()  # the first failure goes to the caller, later ones are retried
        self.state = "connected"
        self._origin = time.perf_counter()
        self._thread = threading.Thread(target=self._run, args=(port,), name=f"serial {self.url}",
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

    # -- the worker ------------------------------------------------------------------------

    def _open(self):
        import serial  # pyserial; imported here so that the codecs work without it

        port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.05)
        port.reset_input_buffer()  # stale bytes queued before we connected
        return port

    def _run(self, port) -> None:
        import serial

        while not self._stop.is_set():
            if port is None:
                try:
                    port = self._open()
                except (serial.SerialException, OSError, ValueError) as exc:
                    self.state, self.error = "reconnecting", str(exc)
                    self._stop.wait(self._reconnect_interval)
                    continue
                self.decoder.reset()
                self.stats.new_connection()
                self.reconnects += 1
                self.state, self.error = "connected", ""
            try:
                data = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError) as exc:
                self.state, self.error = "reconnecting", str(exc)
                port.close()
                port = None
                continue
            if data:
                try:
                    self._handle(data)
                except Exception as exc:  # a bug must not end the reading (or the recording)
                    self.failures += 1
                    self.error = f"internal error while decoding: {exc!r}"
            elif self.recorder is not None:
                self.recorder.tick(self.now())
        if port is not None:
            port.close()

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

    def rejected(self) -> Counter:
        """Rejected frames by reason so far (a copy)."""
        return Counter(self.decoder.rejected)

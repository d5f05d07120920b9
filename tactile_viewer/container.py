"""Live recordings in MCAP: append-only, chunked, a CRC per chunk, readable after a crash. No Qt.

:class:`Recorder` writes every frame a source produces; :func:`open_recording`
reads a file lazily (metadata and an index at open, frames a chunk at a time).
Both go through the MCAP container of the ``mcap`` package (the ROS 2 bag
format): records are only ever appended, so a file cut short by a kill, a
power cut of the program or a full disk is complete up to its last whole chunk.
HDF5 in SWMR mode was tried too and rejected: on a full disk its writer
crashed the process and its file showed frames that were never written (the
figures are in ``docs/recordings.md``).

A file holds
- metadata ``tactile-viewer.recording``: ``version``, ``description``,
  ``taxels``, ``dtype`` of the raw values (``float32`` as a binary board sends
  them, ``float64`` for text), the ``channel`` id of the frames;
- metadata ``tactile-viewer.geometry``: the fields of
  :func:`~tactile_viewer.recording.geometry_fields` (JSON values);
- metadata ``tactile-viewer.calibration``: ``units``, ``gain``, ``offset``
  turning raw values into pascals (``gain * (raw - offset) * scale(units)``);
- metadata ``tactile-viewer.tare``, zero or more: a baseline (pascals)
  subtracted from frame ``from_frame`` on, with the receive time it was taken;
- one message per frame on channel ``/tactile/raw``: the raw values as
  received, little-endian; ``log_time`` the receive time (UNIX nanoseconds),
  ``sequence`` the frame's sequence number (modulo 2**32).

Chunks are closed every ``flush_interval`` seconds of receive time (1 s), so a
crash loses at most that much. Nothing is fsynced: a crash of the program
loses nothing the operating system was given; a power cut of the machine may
lose what it had not yet written back.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import struct
import threading
import zlib
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Metadata
from mcap.writer import CompressionType, Writer

from solver import SensorGrid
from solver.arrays import read_only

from .recording import (
    MAX_TAXELS,
    Recording,
    RecordingError,
    StressCalibration,
    Tare,
    geometry_fields,
    grid_from_fields,
    json_ready,
)

__all__ = ["Recorder", "FrameTable", "open_recording", "SUFFIX", "RAW_DTYPES"]

SUFFIX = ".mcap"
VERSION = "1"
TOPIC = "/tactile/raw"
RAW_DTYPES = {"float32": "<f4", "float64": "<f8"}
_MAGIC = b"\x89MCAP0\r\n"
_RECORD = struct.Struct("<BQ")  # opcode, content length
_CHUNK_HEAD = struct.Struct("<QQQII")  # start time, end time, uncompressed size, crc, compression length
_CHUNK_BYTES = 2**31  # past any second of frames (a 1000x1000 skin at 1 kHz writes 4 GB/s: not a case)
_MESSAGE_HEAD = 9 + 22  # record header, then channel u16, sequence u32, log time u64, publish time u64
# no metadata record of ours comes near this; a larger one is damage, not data
_MAX_METADATA = 64 * 2**20


def _not_through_a_link(path, flags):
    # open()'s opener: O_NOFOLLOW refuses a symbolic link as the file itself (ELOOP)
    return os.open(path, flags | os.O_NOFOLLOW, 0o666)


class Recorder:
    """Writes every frame it is given to an MCAP recording, a chunk per ``flush_interval``.

    Thread-safe: frames come from a reader thread, :meth:`close` from the GUI.

    Parameters
    ----------
    path : path-like
        Ends in ``.mcap``.
    grid : SensorGrid
    calibration : StressCalibration, optional
        How the raw values become pascals (default: they are pascals).
    dtype : {"float32", "float64"}
        How the raw values are stored: as the source delivers them.
    flush_interval : float
        Seconds of receive time between chunks: the most a crash can lose (0: a chunk per frame).
    description : str
    clock_origin : float
        UNIX seconds of receive time 0 (frames carry seconds since it).

    Raises
    ------
    ValueError
        For a path not ending in ``.mcap`` or an unknown ``dtype``.
    OSError
        When the file cannot be created (the message names it).
    """

    def __init__(self, path, grid: SensorGrid, *, calibration: StressCalibration | None = None,
                 dtype: str = "float32", flush_interval: float = 1.0, description: str = "",
                 clock_origin: float = 0.0):
        path = Path(path)
        if path.suffix.lower() != SUFFIX:
            raise ValueError(f"{path}: a recording is written as {SUFFIX}, got {path.suffix!r}")
        if dtype not in RAW_DTYPES:
            raise ValueError(f"dtype must be one of {sorted(RAW_DTYPES)}, got {dtype!r}")
        if not flush_interval >= 0:
            raise ValueError(f"flush_interval must be >= 0 seconds, got {flush_interval!r}")
        self.path = path
        self.flush_interval = float(flush_interval)
        self.dtype = np.dtype(RAW_DTYPES[dtype])
        self.description = description or "live recording"
        self.added = 0  # frames given, in the file's order (the index of the next one)
        self.written = 0  # frames in complete chunks on disk: what a crash now would keep
        self._m = grid.size
        self._origin = float(clock_origin)
        self._closed = False
        self._last_flush: float | None = None
        self._first_t: float | None = None  # receive time of the first frame recorded
        self._lock = threading.Lock()
        calibration = calibration or StressCalibration.identity(grid.size)
        # never through a link (a dangling one at the path created its target)
        try:
            self._stream = open(path, "wb", opener=_not_through_a_link)  # noqa: SIM115 (close, abandon)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise OSError(exc.errno, "is a symbolic link: a recording is not written through one",
                              str(path)) from None
            raise
        try:
            # chunks close on time (flush_interval), not on mcap's default 1 MiB
            writer = Writer(self._stream, compression=CompressionType.NONE, chunk_size=_CHUNK_BYTES)
            writer.start(profile="tactile-viewer", library="tactile-viewer")
            writer.add_metadata("tactile-viewer.recording", {
                "version": VERSION, "description": self.description, "taxels": str(grid.size),
                "dtype": dtype, "channel": "1"})
            writer.add_metadata("tactile-viewer.geometry", _json_fields(geometry_fields(grid)))
            writer.add_metadata("tactile-viewer.calibration", _json_fields(calibration.fields()))
            self._channel = writer.register_channel(TOPIC, f"tactile-raw/{dtype}-le", schema_id=0,
                                                    metadata={"taxels": str(grid.size)})
            self._writer = writer
            for tare in calibration.tares:
                self._write_tare(tare)
            self._stream.flush()
        except BaseException:
            self.abandon()
            raise

    def add(self, seq: int, t: float, raw) -> None:
        """Write one frame received at ``t`` seconds; closes a chunk when ``flush_interval`` has passed."""
        with self._lock:
            if self._closed:
                return  # the reader took this recorder just before it was stopped: past the end
            values = np.asarray(raw, dtype=self.dtype)
            if values.shape != (self._m,):
                raise ValueError(f"a frame must have {self._m} values, got shape {values.shape}")
            stamp = round((self._origin + t) * 1e9)
            with self._ending_on_failure():
                self._writer.add_message(self._channel, log_time=stamp, data=values.tobytes(),
                                         publish_time=stamp, sequence=int(seq) % 2**32)
                self.added += 1
                if self._last_flush is None:
                    self._first_t = self._last_flush = t
                if t - self._last_flush >= self.flush_interval:
                    self._flush(t)

    def tick(self, now: float) -> None:
        """Close the open chunk if its frames have waited ``flush_interval`` (a quiet line)."""
        with self._lock:
            waiting = not self._closed and self.added > self.written
            if waiting and now - self._last_flush >= self.flush_interval:
                with self._ending_on_failure():
                    self._flush(now)

    def tare(self, tare: Tare) -> None:
        """Record a baseline taken while recording; it applies from the next frame written."""
        with self._lock:
            if not self._closed:
                # its time on the recording's clock: seconds since the first frame recorded
                since = tare.t - self._first_t if self._first_t is not None else 0.0
                with self._ending_on_failure():
                    self._write_tare(Tare(self.added, tare.baseline, since, tare.frames))
                    self._stream.flush()

    @contextlib.contextmanager
    def _ending_on_failure(self):
        # a write that failed leaves the writer mid-chunk: writing on would repeat or tear records,
        # so the recorder ends here and the file keeps its complete chunks
        try:
            yield
        except BaseException:
            self._closed = True
            self._release()
            raise

    def _write_tare(self, tare: Tare) -> None:
        self._writer.add_metadata("tactile-viewer.tare", _json_fields(tare.fields()))

    def _flush(self, now: float) -> None:
        self._writer.flush()
        self.written = self.added
        self._last_flush = now

    def close(self) -> Path | None:
        """Finish the file (the open chunk and the summary: at most a chunk's work).

        Returns the path, or None (and no file) when no frame was recorded.
        """
        with self._lock:
            if self._closed:
                return self.path if self.written else None
            self._closed = True
            if self.added == 0:
                self._stream.close()
                self.path.unlink(missing_ok=True)
                return None
            try:
                self._writer.finish()
                self._stream.close()
            except BaseException:
                self._release()
                raise
            self.written = self.added
        return self.path

    def abandon(self) -> None:
        """Stop writing after a failure; the complete chunks already on disk stay readable."""
        with self._lock:
            self._closed = True
            self._release()

    def _release(self) -> None:
        try:
            self._stream.close()
        except OSError:
            pass  # the buffered tail could not be written either: the file ends at its last chunk


def _json_fields(fields: dict) -> dict:
    return {key: json.dumps(value) for key, value in json_ready(fields).items()}


# -- reading ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Chunk:
    data_offset: int  # file offset of the chunk's records
    length: int
    crc: int  # CRC-32 of the records, 0 when not computed
    first: int  # index of its first frame in the recording
    offsets: np.ndarray  # offsets of its frame messages within the records


@dataclass(frozen=True)
class _Index:
    path: Path
    chunks: tuple
    log_times: np.ndarray  # (T,) receive times, UNIX nanoseconds
    metadata: dict  # name -> the last record of that name
    tares: tuple  # the tare records in file order
    truncated: bool  # never finished (a crash, a full disk): it ends at its last whole record


class FrameTable:
    """The ``(T, m)`` stresses (pascals) of an MCAP recording, read a chunk at a time.

    Indexing works as for an array (an int gives one frame ``(m,)``; a slice
    or an index array gives ``(k, m)``); ``np.asarray`` reads every frame.
    The raw values stay in the file; :attr:`calibration` turns them into
    pascals and :meth:`with_calibration` gives the same frames under another
    one (a tare retaken or cleared) without reading anything.
    """

    ndim = 2
    dtype = np.dtype(float)

    def __init__(self, index: _Index, m: int, raw_dtype, calibration: StressCalibration, cache=None):
        self._index = index
        self._m = m
        self.raw_dtype = np.dtype(raw_dtype)
        self.calibration = calibration
        self._cache = cache if cache is not None else _ChunkCache(index, m, self.raw_dtype)
        self._starts = np.array([chunk.first for chunk in index.chunks], dtype=np.int64)

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self._index.log_times), self._m)

    def __len__(self) -> int:
        return len(self._index.log_times)

    def with_calibration(self, calibration: StressCalibration) -> FrameTable:
        """The same frames under ``calibration`` (sharing the file and its cache)."""
        return FrameTable(self._index, self._m, self.raw_dtype, calibration, self._cache)

    def _rows(self, key):
        # frame indices of ``key`` (an int, a slice, indices) without an index array of the whole take
        count = len(self)
        if isinstance(key, slice):
            return np.arange(*key.indices(count))
        rows = np.asarray(key)
        if rows.dtype == bool:
            return np.flatnonzero(rows)
        if rows.dtype.kind not in "iu":
            raise IndexError(f"frames are indexed by whole numbers, got {key!r}")
        if np.any((rows < -count) | (rows >= count)):
            raise IndexError(f"frame {key} is out of range for {count} frames")
        return np.where(rows < 0, rows + count, rows) if rows.ndim else int(rows) % count

    def raw(self, key) -> np.ndarray:
        """The raw values of frames ``key`` as stored (an int gives ``(m,)``)."""
        rows = self._rows(key)
        single = np.ndim(rows) == 0
        rows = np.atleast_1d(rows)
        out = np.empty((len(rows), self._m), dtype=self.raw_dtype)
        which = np.searchsorted(self._starts, rows, side="right") - 1
        for chunk in np.unique(which):
            taken = which == chunk
            out[taken] = self._cache.raw(int(chunk))[rows[taken] - self._starts[chunk]]
        return out[0] if single else out

    def __getitem__(self, key) -> np.ndarray:
        within = ()
        if isinstance(key, tuple):  # frames[rows, taxels]
            key, within = key[0], key[1:]
        rows = self._rows(key)
        stress = self.calibration.apply(self.raw(rows), rows)
        return stress[(slice(None),) * np.ndim(rows) + within] if within else stress

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self[:], dtype=dtype)

    def sample(self, count: int = 64) -> np.ndarray:
        """``(k, m)`` stresses: the first frame of up to ``count`` chunks spread over the recording.

        Reads at most ``count`` chunks; damaged ones are left out (``k`` may be 0).
        """
        chunks = np.unique(np.linspace(0, len(self._starts) - 1, min(count, len(self._starts))).astype(int))
        rows = []
        for k in chunks:
            try:
                rows.append(self[int(self._starts[k])])
            except RecordingError:
                continue
        return np.array(rows).reshape(len(rows), self._m)

    def sequence(self) -> np.ndarray:
        """``(T,)`` sequence numbers as written (modulo 2**32; reads every chunk)."""
        return np.concatenate([self._cache.sequence(k) for k in range(len(self._index.chunks))]
                              or [np.zeros(0, np.int64)])


class _ChunkCache:
    """The few chunks read last, decoded (playback reads one chunk for about a second)."""

    def __init__(self, index: _Index, m: int, raw_dtype, size: int = 4):
        self._index, self._m, self._raw_dtype, self._size = index, m, raw_dtype, size
        self._decoded: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def raw(self, k: int) -> np.ndarray:
        return self._get(k)[0]

    def sequence(self, k: int) -> np.ndarray:
        return self._get(k)[1]

    def _get(self, k: int):
        with self._lock:
            if k in self._decoded:
                self._decoded.move_to_end(k)
                return self._decoded[k]
        decoded = _decode_chunk(self._index.path, self._index.chunks[k], self._m, self._raw_dtype)
        with self._lock:
            self._decoded[k] = decoded
            while len(self._decoded) > self._size:
                self._decoded.popitem(last=False)
        return decoded


def _read_records(path: Path, chunk: _Chunk) -> bytes:
    with open(path, "rb") as handle:
        handle.seek(chunk.data_offset)
        records = handle.read(chunk.length)
    if len(records) != chunk.length:
        raise RecordingError(f"{path}: the file became shorter while reading it")
    if chunk.crc and zlib.crc32(records) != chunk.crc:
        span = (f"frames {chunk.first} to {chunk.first + len(chunk.offsets) - 1}" if len(chunk.offsets)
                else f"the chunk at byte {chunk.data_offset}")
        raise RecordingError(f"{path}: {span} are damaged (chunk checksum mismatch)")
    return records


def _decode_chunk(path: Path, chunk: _Chunk, m: int, raw_dtype) -> tuple:
    records = np.frombuffer(_read_records(path, chunk), dtype=np.uint8)
    size = _MESSAGE_HEAD + m * raw_dtype.itemsize
    offsets = chunk.offsets
    if len(offsets) and (offsets.min() < 0 or offsets.max() + size > len(records)):
        raise RecordingError(f"{path}: a message index points outside its chunk at frame {chunk.first}")
    heads = records[offsets[:, None] + np.arange(_MESSAGE_HEAD)]
    lengths = heads[:, 1:9].copy().view("<u8")[:, 0]
    bad = np.flatnonzero((heads[:, 0] != Opcode.MESSAGE) | (lengths != size - 9))
    if bad.size:
        raise RecordingError(f"{path}: frame {chunk.first + bad[0]} is not a frame of {m} "
                             f"{raw_dtype.name} values")
    raw = records[offsets[:, None] + _MESSAGE_HEAD + np.arange(m * raw_dtype.itemsize)]
    sequence = heads[:, 11:15].copy().view("<u4")[:, 0].astype(np.int64)
    return read_only(raw.view(raw_dtype).reshape(len(offsets), m)), read_only(sequence)


class _Torn(Exception):
    """Inside the scan: a record that cannot be whole; the file is read up to the chunk before it."""


def _scan(path: Path) -> _Index:
    # one pass over the record headers, seeking past each chunk's frames. A record cut short or
    # damaged (a kill, a full disk, a torn page) ends the scan: the file is what came before it.
    size = path.stat().st_size
    chunks, log_times, metadata, tares = [], [], {}, []
    truncated = True  # until the end of the data section is met: a finished file has it
    pending = None  # a chunk whose message index has not been met yet
    frames = 0  # in the chunks so far
    with open(path, "rb") as handle:
        if handle.read(len(_MAGIC)) != _MAGIC:
            raise RecordingError(f"{path}: not an MCAP recording (no MCAP magic at the start)")
        position = len(_MAGIC)
        try:
            while position + _RECORD.size <= size:
                opcode, length = _RECORD.unpack(handle.read(_RECORD.size))
                end = position + _RECORD.size + length
                if end > size:
                    break  # a record cut short: the file ends at the one before
                if opcode == Opcode.CHUNK:
                    if pending is not None:
                        chunks.append(_walked(path, pending, frames, log_times))
                        frames += len(chunks[-1].offsets)
                    pending = _chunk_header(handle, path, position, end)
                elif opcode == Opcode.MESSAGE_INDEX:
                    content = handle.read(length)
                    if length < 6:
                        raise _Torn
                    channel, entries = struct.unpack_from("<HI", content)
                    if channel == 1 and pending is not None:
                        if entries % 16 or 6 + entries > length:
                            raise _Torn
                        pairs = np.frombuffer(content, "<u8", count=entries // 8, offset=6).reshape(-1, 2)
                        order = np.argsort(pairs[:, 1], kind="stable")  # file order, as written
                        times = pairs[order, 0]
                        start, stop = pending[3:]
                        if len(times) and (times.min() < start or times.max() > stop
                                           or np.any(np.diff(times.astype(np.int64)) < 0)):
                            # the index is not under the chunk's CRC: when it disagrees with the
                            # chunk, the chunk's own records say where its frames are
                            chunks.append(_walked(path, pending, frames, log_times))
                        else:
                            chunks.append(_Chunk(*pending[:3], frames, pairs[order, 1].astype(np.int64)))
                            log_times.append(times)
                        frames += len(chunks[-1].offsets)
                        pending = None
                elif opcode == Opcode.METADATA:
                    if length > _MAX_METADATA:
                        raise RecordingError(f"{path}: a metadata record declares {length} bytes "
                                             f"(at most {_MAX_METADATA})")
                    try:
                        record = Metadata.read(ReadDataStream(io.BytesIO(handle.read(length))))
                    except (McapError, struct.error, UnicodeDecodeError):
                        raise _Torn from None
                    metadata[record.name] = record.metadata
                    if record.name == "tactile-viewer.tare":
                        tares.append(record.metadata)
                elif opcode == Opcode.DATA_END:
                    truncated = False
                    break  # the summary that follows repeats what was read
                position = end
                handle.seek(position)
            if pending is not None:
                chunks.append(_walked(path, pending, frames, log_times))
        except _Torn:
            truncated = True
    times = np.concatenate(log_times) if log_times else np.zeros(0, np.uint64)
    return _Index(path, tuple(chunks), times, metadata, tuple(tares), truncated)


def _chunk_header(handle, path, position, end):
    if end - position < _RECORD.size + _CHUNK_HEAD.size + 8:
        raise _Torn
    _start, _stop, uncompressed, crc, name_length = _CHUNK_HEAD.unpack(handle.read(_CHUNK_HEAD.size))
    data_offset = position + _RECORD.size + _CHUNK_HEAD.size + name_length + 8
    if data_offset > end:
        raise _Torn
    compression = handle.read(name_length)
    (length,) = struct.unpack("<Q", handle.read(8))
    if compression:
        raise RecordingError(f"{path}: compressed chunks ({compression.decode(errors='replace')!r}) are "
                             "not read; this viewer writes them uncompressed")
    if data_offset + length != end or uncompressed != length:
        raise _Torn
    return data_offset, length, crc, _start, _stop


def _walked(path, pending, first, log_times) -> _Chunk:
    # a chunk without a (trustworthy) index, e.g. written just before a crash: walk its records,
    # which its CRC vouches for; a chunk that fails its CRC ends the file there
    data_offset, length, crc = pending[:3]
    try:
        records = _read_records(path, _Chunk(data_offset, length, crc, first, np.zeros(0, np.int64)))
    except RecordingError:
        raise _Torn from None
    offsets, times, position = [], [], 0
    while position + _RECORD.size <= len(records):
        opcode, size = _RECORD.unpack_from(records, position)
        if opcode == Opcode.MESSAGE and size >= 22 and position + _RECORD.size + 14 <= len(records):
            channel, _sequence, log_time = struct.unpack_from("<HIQ", records, position + _RECORD.size)
            if channel == 1:
                offsets.append(position)
                times.append(log_time)
        position += _RECORD.size + size
    log_times.append(np.array(times, dtype=np.uint64))
    return _Chunk(data_offset, length, crc, first, np.array(offsets, dtype=np.int64))


def _loads(fields: dict, name: str, path) -> dict:
    try:
        return {key: json.loads(value) for key, value in fields.items()}
    except (ValueError, RecursionError):
        raise RecordingError(f"{path}: metadata {name!r} is not JSON values") from None


def open_recording(path) -> Recording:
    """Open an MCAP recording lazily: metadata and an index now, frames on demand.

    A file cut short (a kill, a full disk) opens with every frame of its
    complete chunks.

    Raises
    ------
    RecordingError
        Naming the file and what is wrong (not MCAP, missing metadata, sizes
        the file cannot hold).
    """
    path = Path(path)
    index = _scan(path)
    if index.truncated and not len(index.log_times):
        raise RecordingError(f"{path}: no frames (the file was cut short before its first chunk)")
    for name in ("recording", "geometry", "calibration"):
        if f"tactile-viewer.{name}" not in index.metadata:
            raise RecordingError(f"{path}: missing metadata 'tactile-viewer.{name}' (not a recording of "
                                 "this viewer)")
    info = index.metadata["tactile-viewer.recording"]
    dtype = info.get("dtype")
    if dtype not in RAW_DTYPES:
        raise RecordingError(f"{path}: 'dtype' must be one of {sorted(RAW_DTYPES)}, got {dtype!r}")
    try:
        taxels = int(info.get("taxels", ""))
    except ValueError:
        raise RecordingError(f"{path}: 'taxels' must be a whole number, got {info.get('taxels')!r}") from None
    if not 1 <= taxels <= MAX_TAXELS:
        raise RecordingError(f"{path}: 'taxels' must be in [1, {MAX_TAXELS}], got {taxels}")
    geometry = _loads(index.metadata["tactile-viewer.geometry"], "geometry", path)
    try:
        grid = grid_from_fields(width=taxels, **geometry)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: impossible geometry: {exc}") from None
    try:
        calibration = StressCalibration.from_fields(
            taxels, **_loads(index.metadata["tactile-viewer.calibration"], "calibration", path),
            tares=[Tare.from_fields(taxels, **_loads(fields, "tare", path)) for fields in index.tares])
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: calibration: {exc}") from None
    if not len(index.log_times):
        raise RecordingError(f"{path}: no frames")
    frames = FrameTable(index, taxels, RAW_DTYPES[dtype], calibration)
    times = index.log_times.astype(np.int64)
    t = (times - times[0]) * 1e-9
    try:
        return Recording(grid, frames, t, None, info.get("description", ""), received=times[0] * 1e-9,
                         truncated=index.truncated)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None

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
  :func:`~tactile_viewer.io.recording.geometry_fields` (JSON values);
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
import queue
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
VERSION = "2"  # 2: a checksum in every metadata record of ours, and a record of each chunk
VERSIONS = ("1", "2")
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

    Thread-safe: frames come from a reader thread, :meth:`close` from the GUI. The
    file is written on a thread of its own behind a queue of at most ``backlog``
    bytes of frames, so a slow disk never stalls the reader (and the board with
    it). A frame that finds the queue full is not recorded and is counted in
    :attr:`dropped`. A write that fails ends the recording; the next call of
    :meth:`add`, :meth:`tick`, :meth:`tare` or :meth:`close` raises its error.

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
    backlog : int
        Bytes of frames that may wait for the disk (default 8 MiB: 8 s of a 16x16 board at
        1 kHz). :meth:`close` waits for them: at most ``backlog`` over the disk's speed.

    Raises
    ------
    ValueError
        For a path not ending in ``.mcap``, an unknown ``dtype`` or a backlog under one frame.
    OSError
        When the file cannot be created (the message names it).
    """

    def __init__(self, path, grid: SensorGrid, *, calibration: StressCalibration | None = None,
                 dtype: str = "float32", flush_interval: float = 1.0, description: str = "",
                 clock_origin: float = 0.0, backlog: int = 8 * 2**20):
        path = Path(path)
        if path.suffix.lower() != SUFFIX:
            raise ValueError(f"{path}: a recording is written as {SUFFIX}, got {path.suffix!r}")
        if dtype not in RAW_DTYPES:
            raise ValueError(f"dtype must be one of {sorted(RAW_DTYPES)}, got {dtype!r}")
        if not flush_interval >= 0:
            raise ValueError(f"flush_interval must be >= 0 seconds, got {flush_interval!r}")
        frame_bytes = grid.size * np.dtype(RAW_DTYPES[dtype]).itemsize
        if not backlog >= frame_bytes:
            raise ValueError(f"backlog must be at least one frame ({frame_bytes} bytes), got {backlog!r}")
        self.path = path
        self.flush_interval = float(flush_interval)
        self.dtype = np.dtype(RAW_DTYPES[dtype])
        self.description = description or "live recording"
        self.added = 0  # frames accepted, in the file's order (the index of the next one)
        self.dropped = 0  # frames that found the queue full: not recorded
        self.written = 0  # frames in complete chunks on disk: what a crash now would keep
        self._m = grid.size
        self._origin = float(clock_origin)
        self._closed = False  # no more frames are accepted
        self._failure: BaseException | None = None  # the write error that ended the recording
        self._last_flush: float | None = None
        self._first_t: float | None = None  # receive time of the first frame recorded
        self._lock = threading.Lock()  # the accepting side: added, dropped, closed
        self._tares = 0  # tare records written
        self._chunk_times: list[int] = []  # receive times of the open chunk's frames, nanoseconds
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, backlog // frame_bytes))
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
            # chunks close on time (flush_interval), not on mcap's default 1 MiB; the data section's
            # CRC lands in its end record
            writer = Writer(self._stream, compression=CompressionType.NONE, chunk_size=_CHUNK_BYTES,
                            enable_data_crcs=True)
            writer.start(profile="tactile-viewer", library="tactile-viewer")
            self._writer = writer
            self._add_metadata("recording", {"version": VERSION, "description": self.description,
                                             "taxels": str(grid.size), "dtype": dtype, "channel": "1"})
            self._add_metadata("geometry", _json_fields(geometry_fields(grid)))
            self._add_metadata("calibration", _json_fields(calibration.fields()))
            self._channel = writer.register_channel(TOPIC, f"tactile-raw/{dtype}-le", schema_id=0,
                                                    metadata={"taxels": str(grid.size)})
            for tare in calibration.tares:
                self._write_tare(tare)
            self._stream.flush()
        except BaseException:
            self._release()
            raise
        self._thread = threading.Thread(target=self._write_queued, name=f"recorder {path.name}", daemon=True)
        self._thread.start()

    # -- the accepting side (any thread) ------------------------------------------------------------

    def add(self, seq: int, t: float, raw) -> bool:
        """Record one frame received at ``t`` seconds; False when it was dropped (the queue is full).

        Its chunk closes on the writer's thread when ``flush_interval`` has passed.
        """
        values = np.array(raw, dtype=self.dtype)  # a copy: the caller may reuse its buffer
        if values.shape != (self._m,):
            raise ValueError(f"a frame must have {self._m} values, got shape {values.shape}")
        with self._lock:
            self._raise_failure()
            if self._closed:
                return False  # the reader took this recorder just before it was stopped: past the end
            try:
                self._queue.put_nowait(("frame", int(seq), float(t), values))
            except queue.Full:
                self.dropped += 1
                return False
            self.added += 1
            if self._first_t is None:
                self._first_t = float(t)
            return True

    def tick(self, now: float) -> None:
        """Close the open chunk if its frames have waited ``flush_interval`` (a quiet line)."""
        with self._lock:
            self._raise_failure()
            if not self._closed:
                with contextlib.suppress(queue.Full):  # a full queue closes chunks by itself
                    self._queue.put_nowait(("tick", float(now)))

    def tare(self, tare: Tare) -> None:
        """Record a baseline taken while recording; it applies from the next frame recorded."""
        with self._lock:
            self._raise_failure()
            if not self._closed:
                # its time on the recording's clock: seconds since the first frame recorded
                since = tare.t - self._first_t if self._first_t is not None else 0.0
                self._queue.put(("tare", Tare(self.added, tare.baseline, since, tare.frames)))

    def drain(self) -> None:
        """Wait until everything given so far has been written (or discarded after a failure)."""
        self._queue.join()

    def close(self) -> Path | None:
        """Finish the file: the frames waiting, the open chunk and the summary.

        Returns the path, or None (and no file) when no frame was recorded.

        Raises
        ------
        OSError
            The write error that ended the recording (the file keeps its complete chunks).
        """
        with self._lock:
            self._closed = True
        self._end_writer("close")
        with self._lock:
            self._raise_failure()
        return self.path if self.written else None

    def abandon(self) -> None:
        """Stop writing after a failure: the frames waiting go into chunks, but the file is not finished.

        The complete chunks on disk stay readable (the file reads as cut short).
        """
        with self._lock:
            self._closed = True
            self._failure = self._failure or _Abandoned()
        self._end_writer("abandon")  # after what waits: the file ends at the last chunk written

    def _end_writer(self, how: str) -> None:
        if self._thread.is_alive():  # once ended (closed before), nothing takes from the queue
            self._queue.put((how, None))
        self._thread.join()

    def _raise_failure(self) -> None:
        # the write error that ended the recording, raised once, to whoever calls next
        failure = self._failure
        if failure is not None and not isinstance(failure, _Abandoned):
            self._failure = _Abandoned()
            raise failure

    # -- the writer's thread ------------------------------------------------------------------------

    def _write_queued(self) -> None:
        writing = True
        while True:
            kind, *item = self._queue.get()
            try:
                if kind in ("close", "abandon"):
                    if writing and kind == "close":
                        self._finish()
                    elif writing:
                        self._release()
                    return
                if writing:
                    getattr(self, f"_write_{kind}")(*item)
            except BaseException as exc:  # a full disk, a vanished folder: the file ends at its last chunk
                writing = False
                with self._lock:
                    self._closed = True
                    if self._failure is None:
                        self._failure = exc
                self._release()
            finally:
                self._queue.task_done()

    def _write_frame(self, seq: int, t: float, values) -> None:
        stamp = round((self._origin + t) * 1e9)
        self._writer.add_message(self._channel, log_time=stamp, data=values.tobytes(), publish_time=stamp,
                                 sequence=seq % 2**32)
        self._chunk_times.append(stamp)
        if self._last_flush is None:
            self._last_flush = t
        if t - self._last_flush >= self.flush_interval:
            self._flush(t)

    def _write_tick(self, now: float) -> None:
        if self._chunk_times and now - self._last_flush >= self.flush_interval:
            self._flush(now)

    def _write_tare(self, tare: Tare) -> None:
        self._add_metadata("tare", _json_fields(tare.fields()))
        self._tares += 1
        self._stream.flush()

    def _add_metadata(self, name: str, fields: dict) -> None:
        fields = dict(fields)
        fields["crc32"] = _checksum(fields)
        self._writer.add_metadata(f"tactile-viewer.{name}", fields)

    def _flush(self, now: float) -> None:
        self._end_chunk()
        self._last_flush = now

    def _end_chunk(self) -> None:
        # the chunk, its message index, then our checksummed record of it: where it is, its frames'
        # numbers and the checksum of their receive times (what the index says but no CRC covers),
        # and the tares written so far (so that a lost tare record is noticed)
        if not self._chunk_times:
            return
        count = len(self._chunk_times)
        position = self._stream.tell()
        self._writer.flush()
        # the chunk record, then the message index of our one channel: 16 bytes a frame
        length = self._stream.tell() - position - _RECORD.size - (_RECORD.size + 6 + 16 * count)
        self._add_metadata("chunk", {
            "offset": str(position), "length": str(length), "first": str(self.written),
            "frames": str(count), "times_crc32": _times_checksum(self._chunk_times),
            "tares": str(self._tares)})
        self._chunk_times = []
        self._stream.flush()
        self.written += count

    def _finish(self) -> None:
        if not self.written and not self._chunk_times:  # no frame recorded: no file
            self._stream.close()
            self.path.unlink(missing_ok=True)
            return
        self._end_chunk()
        self._writer.finish()
        self._stream.close()

    def _release(self) -> None:
        try:
            self._stream.close()
        except OSError:
            pass  # the buffered tail could not be written either: the file ends at its last chunk


class _Abandoned(Exception):
    """The recording was ended (after a failure already reported): nothing more to raise."""


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
    metadata: dict  # name -> the last sound record of that name
    truncated: bool  # never finished (a crash, a full disk): it ends at its last whole record
    damage: tuple  # what could not be read, a sentence each
    data_end: tuple | None  # position of the data section's end record and the section's CRC (0: none)


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

    @property
    def data_checksum(self) -> bool:
        """Whether the file keeps a checksum of its data section (finished files from version 2 on)."""
        return self._index.data_end is not None and self._index.data_end[1] != 0

    def verify(self) -> list[str]:
        """Read the whole file and check every checksum: what fails, a sentence each (empty: all good).

        Each chunk's frames against the chunk's CRC, and the data section (everything before
        the summary) against the CRC in its end record, when the file has one.
        """
        problems = []
        for chunk in self._index.chunks:
            try:
                _read_records(self._index.path, chunk)
            except RecordingError as exc:
                problems.append(str(exc).split(": ", 1)[1])
        if self.data_checksum:
            position, expected = self._index.data_end
            crc = 0
            with open(self._index.path, "rb") as handle:
                while position > 0:
                    block = handle.read(min(position, _BLOCK))
                    if not block:
                        break
                    crc = zlib.crc32(block, crc)
                    position -= len(block)
            if crc != expected:
                problems.append("the data section fails its checksum: a record outside the frames is "
                                "damaged (what could not be read is said above)")
        return problems

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
    """Inside the scan: a record whose framing cannot be right (a cut, a flipped length or opcode)."""


# what our data section holds: any other opcode there is damage, not a record
_DATA_RECORDS = {Opcode.HEADER, Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.METADATA, Opcode.DATA_END}
_OURS = b"tactile-viewer."
_DATA_END = struct.pack("<BQI", Opcode.DATA_END, 4, 0)[:9]  # opcode and length; its CRC follows
_BLOCK = 2**24  # bytes searched at a time when looking past damage


@dataclass
class _Found:
    """A chunk met in the scan (a mutable draft; :class:`_Chunk` is what the reader keeps)."""

    position: int  # of the chunk record
    data_offset: int
    length: int
    crc: int
    start: int  # its header's time span (not under any checksum)
    stop: int
    index: tuple | None = None  # (offsets, times) from the message index after it
    record: dict | None = None  # our checksummed record of it (version 2)
    suspect: bool = False  # reached past damage: its records are read and checked at open


@dataclass
class _Meta:
    position: int
    name: str
    fields: dict
    checksum: str  # "good", "bad" or "none" (version 1 records carry none)


def _checksum(fields: dict) -> str:
    # CRC-32 of the record's other fields in a canonical form, as 8 hex digits (metadata values
    # are strings)
    text = json.dumps(sorted((key, value) for key, value in fields.items() if key != "crc32"),
                      separators=(",", ":"))
    return f"{zlib.crc32(text.encode()):08x}"


def _times_checksum(times) -> str:
    return f"{zlib.crc32(np.asarray(times, dtype='<u8').tobytes()):08x}"


class _Scan:
    """One pass over the record headers of a file, seeking past each chunk's frames.

    A record whose framing cannot be right (an unknown opcode, a length past the end, a body that
    does not parse) is damage: the scan looks forward for the next record it can vouch for (a
    chunk header whose sizes agree, a metadata record of ours that parses, the end of the data
    section) and goes on from there. When nothing follows, the file was cut there.
    """

    def __init__(self, path: Path, handle):
        self.path = path
        self.fd = handle.fileno()
        self.size = os.fstat(self.fd).st_size
        self.chunks: dict[int, _Found] = {}
        self.metadata: list[_Meta] = []
        self.damaged: list[int] = []  # positions where the framing was damaged
        self.resumed: set[int] = set()  # positions where the scan went on after damage
        self.ended = False  # the end of the data section was met
        self.data_end: tuple[int, int] | None = None  # its position and the data section's CRC (0: none)
        self.cut = False  # damage with nothing good after it: the file ends there

    def read(self, position: int, count: int) -> bytes:
        return os.pread(self.fd, count, position)

    def run(self) -> _Scan:
        position, last_chunk = len(_MAGIC), None
        while position + _RECORD.size <= self.size:
            opcode, length = _RECORD.unpack(self.read(position, _RECORD.size))
            end = position + _RECORD.size + length
            try:
                if opcode not in _DATA_RECORDS or end > self.size:
                    raise _Torn
                if opcode == Opcode.CHUNK:
                    self.chunks[position] = last_chunk = self._chunk(position, end)
                    last_chunk.suspect = position in self.resumed
                elif opcode == Opcode.MESSAGE_INDEX:
                    self._message_index(position, length, last_chunk)
                    last_chunk = None  # one index per chunk: a second would be damage
                elif opcode == Opcode.METADATA:
                    self.metadata.append(self._metadata(position, end))
                elif opcode == Opcode.DATA_END:
                    if length != 4:
                        raise _Torn
                    self.ended = True
                    self.data_end = (position, struct.unpack("<I", self.read(position + _RECORD.size, 4))[0])
                    break  # the summary that follows repeats what was read
            except _Torn:
                resumed = self._next_record(position + 1)
                if resumed is None:
                    self.cut = True
                    break
                self.damaged.append(position)
                position, last_chunk = resumed, None
                self.resumed.add(position)
                continue
            position = end
        # a finished file ends in the footer and the magic: damage in between is not a cut
        self.cut = not (self.ended or self.read(self.size - len(_MAGIC), len(_MAGIC)) == _MAGIC)
        return self

    def _chunk(self, position: int, end: int) -> _Found:
        head = self.read(position + _RECORD.size, _CHUNK_HEAD.size + 8)
        if end - position < _RECORD.size + _CHUNK_HEAD.size + 8 or len(head) < _CHUNK_HEAD.size:
            raise _Torn
        start, stop, uncompressed, crc, name_length = _CHUNK_HEAD.unpack_from(head)
        if name_length:
            compression = self.read(position + _RECORD.size + _CHUNK_HEAD.size, min(name_length, 16))
            if compression.isascii() and compression.isalnum():  # a real name, not a flipped length
                raise RecordingError(f"{self.path}: compressed chunks ({compression.decode()!r}) are not "
                                     "read; this viewer writes them uncompressed")
            raise _Torn
        (length,) = struct.unpack_from("<Q", head, _CHUNK_HEAD.size)
        data_offset = position + _RECORD.size + _CHUNK_HEAD.size + 8
        if data_offset + length != end or uncompressed != length:
            raise _Torn
        return _Found(position, data_offset, length, crc, start, stop)

    def _message_index(self, position: int, length: int, chunk: _Found | None) -> None:
        content = self.read(position + _RECORD.size, length)
        if length < 6:
            raise _Torn
        channel, entries = struct.unpack_from("<HI", content)
        if entries % 16 or 6 + entries > length:
            raise _Torn
        if channel == 1 and chunk is not None:
            pairs = np.frombuffer(content, "<u8", count=entries // 8, offset=6).reshape(-1, 2)
            order = np.argsort(pairs[:, 1], kind="stable")  # file order, as written
            chunk.index = (pairs[order, 1].astype(np.int64), pairs[order, 0])

    def _metadata(self, position: int, end: int) -> _Meta:
        length = end - position - _RECORD.size
        if length > _MAX_METADATA:
            raise _Torn  # no record of ours comes near this: a flipped length
        try:
            record = Metadata.read(ReadDataStream(io.BytesIO(self.read(position + _RECORD.size, length))))
        except (McapError, struct.error, UnicodeDecodeError, ValueError):
            raise _Torn from None
        fields = record.metadata
        checksum = ("none" if "crc32" not in fields else
                    "good" if fields["crc32"] == _checksum(fields) else "bad")
        return _Meta(position, record.name, fields, checksum)

    # -- looking past damage ------------------------------------------------------------------

    def _next_record(self, start: int) -> int | None:
        # the first position at or after ``start`` where a record we can vouch for begins
        finders = [self._next_chunk, self._next_metadata, self._next_data_end]
        found = [finder(start) for finder in finders]
        while any(position is not None for position in found):
            position = min(p for p in found if p is not None)
            kind = found.index(position)
            if self._vouched(kind, position):
                return position
            found[kind] = finders[kind](position + 1)
        return None

    def _vouched(self, kind: int, position: int) -> bool:
        opcode, length = _RECORD.unpack(self.read(position, _RECORD.size))
        end = position + _RECORD.size + length
        if end > self.size:
            return False
        try:
            if kind == 0:
                self._chunk(position, end)
            elif kind == 1:
                self._metadata(position, end)
        except (_Torn, RecordingError):
            return False
        return True

    def _search(self, start: int, match, overlap: int) -> int | None:
        # the first hit of ``match(block) -> offset or None`` at or after ``start``, a block at a time
        while start < self.size:
            block = self.read(start, _BLOCK + overlap)
            hit = match(block)
            if hit is not None:
                return start + hit
            if len(block) <= overlap:
                return None
            start += _BLOCK
        return None

    def _next_metadata(self, start: int) -> int | None:
        head = _RECORD.size + 4  # the name follows the record header and its own length
        def match(block):
            at = block.find(_OURS, head)
            while at >= 0:
                if block[at - head] == Opcode.METADATA:
                    return at - head
                at = block.find(_OURS, at + 1)
            return None
        return self._search(start, match, len(_OURS) + head)

    def _next_data_end(self, start: int) -> int | None:
        def match(block):
            at = block.find(_DATA_END)
            return None if at < 0 else at
        return self._search(start, match, len(_DATA_END))

    def _next_chunk(self, start: int) -> int | None:
        # a chunk header whose sizes agree with each other: opcode, length L, two times, the
        # uncompressed size L - 40, a CRC, an empty compression name, the records' size L - 40
        head = _RECORD.size + _CHUNK_HEAD.size + 8
        def match(block):
            view = np.frombuffer(block, np.uint8)
            at = np.flatnonzero(view[:max(len(view) - head, 0)] == Opcode.CHUNK)
            if not at.size:
                return None
            def field(offset, width):
                taken = view[at[:, None] + offset + np.arange(width)]
                return taken.copy().view(f"<u{width}")[:, 0]
            length, uncompressed = field(1, 8), field(25, 8)
            good = ((length >= 40) & (uncompressed == length - 40) & (field(37, 4) == 0)
                    & (field(41, 8) == uncompressed))
            hits = at[good]
            return int(hits[0]) if hits.size else None
        return self._search(start, match, head)


def _walk(path: Path, found: _Found):
    # a chunk's frames from its own records, which its CRC vouches for: (offsets, times), or None
    # when the chunk fails its CRC
    try:
        records = _read_records(path, _Chunk(found.data_offset, found.length, found.crc, 0,
                                             np.zeros(0, np.int64)))
    except RecordingError:
        return None
    offsets, times, position = [], [], 0
    while position + _RECORD.size <= len(records):
        opcode, size = _RECORD.unpack_from(records, position)
        if opcode == Opcode.MESSAGE and size >= 22 and position + _RECORD.size + 14 <= len(records):
            channel, _sequence, log_time = struct.unpack_from("<HIQ", records, position + _RECORD.size)
            if channel == 1:
                offsets.append(position)
                times.append(log_time)
        position += _RECORD.size + size
    return np.array(offsets, dtype=np.int64), np.array(times, dtype=np.uint64)


def _indexed(scan: _Scan, found: _Found, size: int, version: str):
    # the chunk's message index, when it agrees with what vouches for it: (offsets, times) or None.
    # Our chunks hold a frame message after another, after the channel record in the first one,
    # so the offsets follow from the chunk's length; the times from our checksummed record of the
    # chunk (version 2) or, failing that, from the chunk header's span
    if found.index is None:
        return None
    offsets, times = found.index
    count = len(offsets)
    prefix = found.length - count * size
    if prefix < 0 or np.any(offsets != prefix + size * np.arange(count)):
        return None
    if prefix:
        opcode, length = _RECORD.unpack(scan.read(found.data_offset, _RECORD.size))
        if opcode != Opcode.CHANNEL or _RECORD.size + length != prefix:
            return None
    if found.record is not None:
        if count != found.record["frames"] or _times_checksum(times) != found.record["times_crc32"]:
            return None
    elif version != "1" or (count and (times.min() < found.start or times.max() > found.stop
                                        or np.any(np.diff(times.astype(np.int64)) < 0))):
        return None
    return offsets, times


def _chunk_records(scan: _Scan, metadata: list) -> None:
    # attach our records of chunks (version 2) to the chunks they describe; a chunk whose own
    # header was damaged is found through its record
    for meta in metadata:
        if meta.name != "tactile-viewer.chunk":
            continue
        try:
            record = {key: int(meta.fields[key]) for key in ("offset", "length", "first", "frames", "tares")}
        except (KeyError, ValueError):
            continue
        record["times_crc32"] = meta.fields.get("times_crc32")
        position = record["offset"]
        if position not in scan.chunks:
            # its header is damaged: our chunks are uncompressed, so the record's length says
            # where its frames are, and their CRC says whether they are whole
            end = position + _RECORD.size + record["length"]
            if record["length"] < _CHUNK_HEAD.size + 8 or end > scan.size:
                continue
            start, stop, _size, crc, _name = _CHUNK_HEAD.unpack(scan.read(position + _RECORD.size,
                                                                         _CHUNK_HEAD.size))
            found = _Found(position, position + _RECORD.size + _CHUNK_HEAD.size + 8,
                           record["length"] - _CHUNK_HEAD.size - 8, crc, start, stop, suspect=True)
            scan.chunks[position] = found
            after = found.data_offset + found.length  # its message index follows it
            opcode, length = _RECORD.unpack(scan.read(after, _RECORD.size))
            if opcode == Opcode.MESSAGE_INDEX and after + _RECORD.size + length <= scan.size:
                with contextlib.suppress(_Torn):
                    scan._message_index(after, length, found)
        scan.chunks[position].record = record


def _assemble(scan: _Scan, metadata: list, tares: list, size: int, version: str):
    """Chunks, receive times, tares (numbered as loaded), what is lost and when, from a scan."""
    path = scan.path
    _chunk_records(scan, metadata)
    # kept: (chunk position, written number of its first frame or None, count, loaded number)
    chunks, log_times, lost, kept, gaps = [], [], [], [], []
    loaded = written = 0
    certain = True  # the written number of the next frame is known
    for found in sorted(scan.chunks.values(), key=lambda chunk: chunk.position):
        record = found.record
        first = record["first"] if record else (written if certain else None)
        if record and certain and first > written:  # a chunk and its record both lost
            gaps.append((written, first - written))
        frames = (None if found.suspect else _indexed(scan, found, size, version)) or _walk(path, found)
        if frames is None:  # the chunk fails its CRC
            count = record["frames"] if record else None
            exact = bool(record and count and found.index is not None
                         and _times_checksum(found.index[1]) == record["times_crc32"])
            lost.append((found.position, first, count,
                         found.index[1][[0, -1]] if exact else (found.start, found.stop), exact))
            certain = count is not None and first is not None
            written = first + count if certain else written
            continue
        offsets, times = frames
        if not len(offsets):
            continue
        chunks.append(_Chunk(found.data_offset, found.length, found.crc, loaded, offsets))
        log_times.append(times)
        kept.append((found.position, first, len(offsets), loaded))
        certain = first is not None
        written = first + len(offsets) if certain else written
        loaded += len(offsets)
    times = np.concatenate(log_times) if log_times else np.zeros(0, np.uint64)
    origin = int(times[0]) if len(times) else 0
    damage = []
    damage = [_lost(*chunk, origin) for chunk in lost]
    spans = tuple(((int(span[0]) - origin) * 1e-9, (int(span[-1]) - origin) * 1e-9)
                  for _position, _first, _count, span, _exact in lost)
    for first, count in gaps:
        damage.append(f"frames {first} to {first + count - 1} as recorded are lost: their chunk is damaged "
                      "beyond finding")
    tares = _renumbered(tares, kept, scan, damage)
    return tuple(chunks), times, tares, tuple(damage), spans


def _lost(position, first, count, span, exact, origin) -> str:
    start, stop = ((int(end) - origin) * 1e-9 for end in (span[0], span[-1]))
    when = (f"t {start:.3f} to {stop:.3f} s" if start >= 0 else  # the first frames kept come after them
            f"{-start:.3f} to {-stop:.3f} s before the first frame kept")
    if not exact:
        when = "about " + when  # the chunk header's span, under no checksum
    if count is None:
        what = f"an unknown number of frames ({when})"
    elif first is None:
        what = f"{count} frames ({when})"
    else:
        what = f"frames {first} to {first + count - 1} as recorded ({count} frames, {when})"
    return f"{what} are lost: their chunk at byte {position} is damaged"


def _renumbered(tares: list, kept: list, scan: _Scan, damage: list) -> list:
    # tares name the frame they apply from as numbered when written; frames lost before it move it.
    # A tare that cannot be placed, or whose record is damaged or lost, is said
    def loaded_after(position):  # the first frame kept from a chunk written after ``position``
        return next((loaded for at, _first, _count, loaded in kept if at > position), None)
    def offset_from(position):
        after = loaded_after(position)
        return f": frames from {after} on may be offset" if after is not None else ""
    known = [(first, count) for _at, first, count, _loaded in kept if first is not None]
    uncounted = len(known) < len(kept)
    placed = []
    for meta in tares:
        if meta.checksum == "bad":
            damage.append(f"the tare recorded at byte {meta.position} is damaged and not applied"
                          + offset_from(meta.position))
            continue
        fields = dict(meta.fields)
        try:
            written = int(json.loads(fields["from_frame"]))
        except (KeyError, ValueError, TypeError):
            placed.append(fields)  # Tare.from_fields says what is wrong, naming the file
            continue
        if uncounted and not any(first <= written < first + count for first, count in known):
            damage.append(f"the tare from frame {written} as recorded may apply from the wrong frame "
                          "(frames before it were lost in numbers not known)")
        fields["from_frame"] = json.dumps(sum(min(max(written - first, 0), count) for first, count in known))
        placed.append(fields)
    # each record of a chunk counts the tares written so far: fewer found means some are lost
    counted = [(chunk.position, chunk.record["tares"]) for chunk in scan.chunks.values() if chunk.record]
    missing = max((tares for _at, tares in counted), default=0) - len(tares)
    if missing > 0:
        at = min(at for at, count in counted if count > len(tares))
        damage.append(f"{missing} tare record{'s are' if missing > 1 else ' is'} lost" + offset_from(at - 1))
    return placed


def _loads(fields: dict, name: str, path) -> dict:
    try:
        return {key: json.loads(value) for key, value in fields.items() if key != "crc32"}
    except (ValueError, RecursionError):
        raise RecordingError(f"{path}: metadata {name!r} is not JSON values") from None


def open_recording(path) -> Recording:
    """Open an MCAP recording lazily: metadata and an index now, frames on demand.

    A file cut short (a kill, a full disk) opens with every frame of its
    complete chunks. A damaged file opens with what is good and says what is
    not in :attr:`~tactile_viewer.io.recording.Recording.damage`: frames of a
    chunk that fails its checksum are left out (their numbers and times said
    when the chunk's record keeps them), a tare whose record is damaged or
    lost is said with the frames it may offset. Records around damage are
    found again by looking forward for the next record that checks out.

    Raises
    ------
    RecordingError
        Naming the file and what is wrong (not MCAP, missing or damaged
        metadata, sizes the file cannot hold).
    """
    path = Path(path)
    with open(path, "rb") as handle:
        if handle.read(len(_MAGIC)) != _MAGIC:
            raise RecordingError(f"{path}: not an MCAP recording (no MCAP magic at the start)")
        scan = _Scan(path, handle).run()
        return _opened(scan)


def _opened(scan: _Scan) -> Recording:
    path = scan.path
    if scan.cut and not scan.chunks:
        raise RecordingError(f"{path}: no frames (the file was cut short before its first chunk)")
    ours = [meta for meta in scan.metadata if meta.name.startswith("tactile-viewer.")]
    info = next((meta for meta in reversed(ours) if meta.name == "tactile-viewer.recording"), None)
    if info is None:
        raise RecordingError(f"{path}: missing metadata 'tactile-viewer.recording' (not a recording of "
                             "this viewer)")
    version = info.fields.get("version")
    if info.checksum == "bad":
        raise RecordingError(f"{path}: metadata 'tactile-viewer.recording' is damaged (checksum mismatch)")
    if version not in VERSIONS:
        raise RecordingError(f"{path}: recording version {version!r} is not read by this viewer "
                             f"(it reads {', '.join(VERSIONS)})")
    # version 1 wrote no checksums; from version 2 on every record of ours carries one
    good = [meta for meta in ours if meta.checksum == "good" or (version == "1" and meta.checksum == "none")]
    if version != "1":
        for meta in ours:
            if meta not in good:
                meta.checksum = "bad"
    metadata = {meta.name: meta.fields for meta in good}
    for name in ("geometry", "calibration"):
        name = f"tactile-viewer.{name}"
        if name not in metadata:
            damaged = any(meta.name == name for meta in ours)
            raise RecordingError(f"{path}: metadata {name!r} is damaged (checksum mismatch)" if damaged else
                                 f"{path}: missing metadata {name!r} (not a recording of this viewer)")
    info = metadata["tactile-viewer.recording"]
    dtype = info.get("dtype")
    if dtype not in RAW_DTYPES:
        raise RecordingError(f"{path}: 'dtype' must be one of {sorted(RAW_DTYPES)}, got {dtype!r}")
    try:
        taxels = int(info.get("taxels", ""))
    except ValueError:
        raise RecordingError(f"{path}: 'taxels' must be a whole number, got {info.get('taxels')!r}") from None
    if not 1 <= taxels <= MAX_TAXELS:
        raise RecordingError(f"{path}: 'taxels' must be in [1, {MAX_TAXELS}], got {taxels}")
    geometry = _loads(metadata["tactile-viewer.geometry"], "geometry", path)
    try:
        grid = grid_from_fields(width=taxels, **geometry)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: impossible geometry: {exc}") from None
    raw_dtype = np.dtype(RAW_DTYPES[dtype])
    tares = [meta for meta in ours if meta.name == "tactile-viewer.tare"]
    chunk_records = [meta for meta in good if meta.name == "tactile-viewer.chunk"]
    chunks, log_times, tares, damage, lost = _assemble(scan, chunk_records, tares,
                                                       _MESSAGE_HEAD + taxels * raw_dtype.itemsize, version)
    try:
        calibration = StressCalibration.from_fields(
            taxels, **_loads(metadata["tactile-viewer.calibration"], "calibration", path),
            tares=[Tare.from_fields(taxels, **_loads(fields, "tare", path)) for fields in tares])
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{path}: calibration: {exc}") from None
    if not len(log_times):
        raise RecordingError(f"{path}: no frames" + (" (the file was cut short before its first chunk)"
                                                     if scan.cut and not damage else "")
                             + "".join(f"; {what}" for what in damage))
    index = _Index(path, chunks, log_times, metadata, scan.cut, damage, scan.data_end)
    frames = FrameTable(index, taxels, raw_dtype, calibration)
    times = log_times.astype(np.int64)
    t = (times - times[0]) * 1e-9
    try:
        return Recording(grid, frames, t, None, info.get("description", ""), received=times[0] * 1e-9,
                         truncated=scan.cut, damage=damage, lost_spans=lost)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None

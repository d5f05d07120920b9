"""The frames of an opened MCAP recording: :class:`FrameTable`, read a chunk at a time. No Qt.

:func:`~tactile_viewer.io.mcap_reader.open_recording` finds the chunks and
their frames (an :class:`Index`); the frames' raw values stay in the file and
are read, checked against their chunk's CRC and decoded when indexed, the few
chunks read last kept decoded. Every frame message of a recording has the same
size and layout (:class:`~tactile_viewer.io.ros2_message.FrameMessage`), so a
chunk's frames are read as one strided array, not one message at a time.
"""

from __future__ import annotations

import threading
import zlib
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.opcode import Opcode

from .mcap_format import BLOCK, MESSAGE_HEAD
from .recording import RecordingError, StressCalibration
from .ros2_message import FrameMessage

__all__ = ["FrameTable", "Chunk", "Index", "read_records"]


@dataclass(frozen=True)
class Chunk:
    """A chunk of frames as the reader keeps it: where its records are, their CRC, its frames."""

    data_offset: int  # file offset of the chunk's records
    length: int
    crc: int  # CRC-32 of the records, 0 when not computed
    first: int  # index of its first frame in the recording
    offsets: np.ndarray  # offsets of its frame messages within the records


@dataclass(frozen=True)
class Index:
    """What was found in a file at open: its chunks, receive times, metadata and damage."""

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

    def __init__(self, index: Index, message: FrameMessage, calibration: StressCalibration, cache=None):
        self._index = index
        self._message = message
        self._m = message.taxels
        self.raw_dtype = message.dtype
        self.calibration = calibration
        self._cache = cache if cache is not None else _ChunkCache(index, message)
        self._starts = np.array([chunk.first for chunk in index.chunks], dtype=np.int64)

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self._index.log_times), self._m)

    def __len__(self) -> int:
        return len(self._index.log_times)

    def with_calibration(self, calibration: StressCalibration) -> FrameTable:
        """The same frames under ``calibration`` (sharing the file and its cache)."""
        return FrameTable(self._index, self._message, calibration, self._cache)

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
                read_records(self._index.path, chunk)
            except RecordingError as exc:
                problems.append(str(exc).split(": ", 1)[1])
        if self.data_checksum:
            position, expected = self._index.data_end
            crc = 0
            with open(self._index.path, "rb") as handle:
                while position > 0:
                    block = handle.read(min(position, BLOCK))
                    if not block:
                        break
                    crc = zlib.crc32(block, crc)
                    position -= len(block)
            if crc != expected:
                problems.append("the data section fails its checksum: a record outside the frames is "
                                "damaged (what could not be read is said above)")
        return problems

    def sequence(self) -> np.ndarray:
        """``(T,)`` sequence numbers as written (versions 1 and 2 kept them modulo 2**32).

        Reads every chunk.
        """
        return np.concatenate([self._cache.sequence(k) for k in range(len(self._index.chunks))]
                              or [np.zeros(0, np.int64)])


class _ChunkCache:
    """The few chunks read last, decoded (playback reads one chunk for about a second)."""

    def __init__(self, index: Index, message: FrameMessage, size: int = 4):
        self._index, self._message, self._size = index, message, size
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
        decoded = _decode_chunk(self._index.path, self._index.chunks[k], self._message)
        with self._lock:
            self._decoded[k] = decoded
            while len(self._decoded) > self._size:
                self._decoded.popitem(last=False)
        return decoded


def read_records(path: Path, chunk: Chunk) -> bytes:
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


def _decode_chunk(path: Path, chunk: Chunk, message: FrameMessage) -> tuple:
    """``(raw (n, m), sequence (n,))`` of a chunk's frames, read-only, checked against its CRC."""
    records = np.frombuffer(read_records(path, chunk), dtype=np.uint8)
    size = MESSAGE_HEAD + message.size
    offsets = chunk.offsets
    if len(offsets) and (offsets.min() < 0 or offsets.max() + size > len(records)):
        raise RecordingError(f"{path}: a message index points outside its chunk at frame {chunk.first}")
    rows = _message_rows(records, offsets, size)
    # the record header (opcode, length) and every byte of the message that is the same in each
    # frame (encapsulation, frame_id, value count, padding) say that it is a frame of this file
    lengths = rows[:, 1:9].copy().view("<u8")[:, 0]
    bad = (rows[:, 0] != Opcode.MESSAGE) | (lengths != size - 9)
    if message.fixed.size:
        bad |= np.any(rows[:, MESSAGE_HEAD + message.fixed_at] != message.fixed, axis=1)
    bad = np.flatnonzero(bad)
    if bad.size:
        raise RecordingError(f"{path}: frame {chunk.first + bad[0]} is not a frame of {message.taxels} "
                             f"{message.dtype.name} values")
    at = MESSAGE_HEAD + message.values_at
    raw = np.ascontiguousarray(rows[:, at:at + message.taxels * message.dtype.itemsize]).view(message.dtype)
    if message.sequence_at is None:  # versions 1 and 2: the record's own sequence, modulo 2**32
        sequence = rows[:, 11:15].copy().view("<u4")[:, 0].astype(np.int64)
    else:
        at = MESSAGE_HEAD + message.sequence_at
        sequence = rows[:, at:at + 8].copy().view("<u8")[:, 0].astype(np.int64)
    raw.setflags(write=False)
    sequence.setflags(write=False)
    return raw, sequence


def _message_rows(records: np.ndarray, offsets: np.ndarray, size: int) -> np.ndarray:
    # (n, size) bytes of the messages at ``offsets``: a strided view when they follow one another
    # at equal steps (every chunk this viewer writes), else gathered
    count = len(offsets)
    if count and np.all(np.diff(offsets) == size):
        return np.lib.stride_tricks.as_strided(records[offsets[0]:], shape=(count, size), strides=(size, 1),
                                               writeable=False)
    return records[offsets[:, None] + np.arange(size)]

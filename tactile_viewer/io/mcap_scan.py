"""The scan of an MCAP recording at open: its chunks and metadata, found again past damage. No Qt.

:class:`Scan` makes one pass over the record headers of a file, seeking past
each chunk's frames; a record whose framing cannot be right is damage, and the
scan looks forward for the next record it can vouch for. It then finds each
chunk's frames: from the chunk's message index when what vouches for it agrees
(our record of the chunk, or its header), else from the chunk's own records.
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Metadata

from .mcap_format import BLOCK, CHUNK_HEAD, MAGIC, RECORD, metadata_checksum, times_checksum
from .mcap_frames import Chunk, read_records
from .recording import RecordingError

__all__ = ["Scan"]

# no metadata record of ours comes near this; a larger one is damage, not data
_MAX_METADATA = 64 * 2**20


class _Torn(Exception):
    """Inside the scan: a record whose framing cannot be right (a cut, a flipped length or opcode)."""


# what our data section holds: any other opcode there is damage, not a record
_DATA_RECORDS = {Opcode.HEADER, Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.METADATA, Opcode.DATA_END}
_OURS = b"tactile-viewer."
_DATA_END = struct.pack("<BQI", Opcode.DATA_END, 4, 0)[:9]  # opcode and length; its CRC follows


@dataclass
class _Found:
    """A chunk met in the scan (a mutable draft; :class:`Chunk` is what the reader keeps)."""

    position: int  # of the chunk record
    data_offset: int
    length: int
    crc: int
    start: int  # its header's time span (not under any checksum)
    stop: int
    index: tuple | None = None  # (offsets, times) from the message index after it
    record: dict | None = None  # our checksummed record of it (version 2)
    suspect: bool = False  # reached past damage: its records are read and checked at open

    def times_recorded(self) -> bool:
        """Whether the times of its message index are those our record of it keeps a checksum of."""
        return (self.index is not None and self.record is not None
                and times_checksum(self.index[1]) == self.record["times_crc32"])


@dataclass
class _Meta:
    position: int
    name: str
    fields: dict
    checksum: str  # "good", "bad" or "none" (version 1 records carry none)


class Scan:
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

    def run(self) -> Scan:
        position, last_chunk = len(MAGIC), None
        while position + RECORD.size <= self.size:
            opcode, length = RECORD.unpack(self.read(position, RECORD.size))
            end = position + RECORD.size + length
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
                    self.data_end = (position, struct.unpack("<I", self.read(position + RECORD.size, 4))[0])
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
        self.cut = not (self.ended or self.read(self.size - len(MAGIC), len(MAGIC)) == MAGIC)
        return self

    def _chunk(self, position: int, end: int) -> _Found:
        head = self.read(position + RECORD.size, CHUNK_HEAD.size + 8)
        if end - position < RECORD.size + CHUNK_HEAD.size + 8 or len(head) < CHUNK_HEAD.size:
            raise _Torn
        _start, _stop, uncompressed, _crc, name_length = CHUNK_HEAD.unpack_from(head)
        if name_length:
            compression = self.read(position + RECORD.size + CHUNK_HEAD.size, min(name_length, 16))
            if compression.isascii() and compression.isalnum():  # a real name, not a flipped length
                raise RecordingError(f"{self.path}: compressed chunks ({compression.decode()!r}) are not "
                                     "read; this viewer writes them uncompressed")
            raise _Torn
        (length,) = struct.unpack_from("<Q", head, CHUNK_HEAD.size)
        if position + RECORD.size + CHUNK_HEAD.size + 8 + length != end or uncompressed != length:
            raise _Torn
        return self.chunk_at(position, end, head)

    def _message_index(self, position: int, length: int, chunk: _Found | None) -> None:
        content = self.read(position + RECORD.size, length)
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
        length = end - position - RECORD.size
        if length > _MAX_METADATA:
            raise _Torn  # no record of ours comes near this: a flipped length
        try:
            record = Metadata.read(ReadDataStream(io.BytesIO(self.read(position + RECORD.size, length))))
        except (McapError, struct.error, UnicodeDecodeError, ValueError):
            raise _Torn from None
        fields = record.metadata
        checksum = ("none" if "crc32" not in fields else
                    "good" if fields["crc32"] == metadata_checksum(fields) else "bad")
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
        opcode, length = RECORD.unpack(self.read(position, RECORD.size))
        end = position + RECORD.size + length
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
            block = self.read(start, BLOCK + overlap)
            hit = match(block)
            if hit is not None:
                return start + hit
            if len(block) <= overlap:
                return None
            start += BLOCK
        return None

    def _next_metadata(self, start: int) -> int | None:
        head = RECORD.size + 4  # the name follows the record header and its own length
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
        head = RECORD.size + CHUNK_HEAD.size + 8
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


    # -- the frames of each chunk -------------------------------------------------------------

    def chunk_at(self, position: int, end: int, head: bytes | None = None, *,
                 suspect: bool = False) -> _Found:
        """The chunk whose record spans ``position`` to ``end``, as its header says.

        ``head``: the header's bytes when already read (read here if not given).
        """
        if head is None:
            head = self.read(position + RECORD.size, CHUNK_HEAD.size)
        start, stop, _size, crc, _name = CHUNK_HEAD.unpack_from(head)
        data_offset = position + RECORD.size + CHUNK_HEAD.size + 8
        return _Found(position, data_offset, end - data_offset, crc, start, stop, suspect=suspect)

    def attach_records(self, metadata: list) -> None:
        """Attach our records of chunks (version 2) to the chunks they describe.

        A chunk whose own header was damaged is found through its record.
        """
        for meta in metadata:
            if meta.name != "tactile-viewer.chunk":
                continue
            try:
                record = {key: int(meta.fields[key])
                          for key in ("offset", "length", "first", "frames", "tares")}
            except (KeyError, ValueError):
                continue
            record["times_crc32"] = meta.fields.get("times_crc32")
            position = record["offset"]
            if position not in self.chunks:
                # its header is damaged: our chunks are uncompressed, so the record's length says
                # where its frames are, and their CRC says whether they are whole
                end = position + RECORD.size + record["length"]
                if record["length"] < CHUNK_HEAD.size + 8 or end > self.size:
                    continue
                found = self.chunk_at(position, end, suspect=True)
                self.chunks[position] = found
                after = found.data_offset + found.length  # its message index follows it
                opcode, length = RECORD.unpack(self.read(after, RECORD.size))
                if opcode == Opcode.MESSAGE_INDEX and after + RECORD.size + length <= self.size:
                    with contextlib.suppress(_Torn):
                        self._message_index(after, length, found)
            self.chunks[position].record = record

    def frames(self, found: _Found, size: int, version: str):
        """``(offsets, times)`` of a chunk's frames of ``size`` bytes each, or None when it fails its CRC.

        From its message index when what vouches for it agrees, else from its own records.
        """
        return (None if found.suspect else self._indexed(found, size, version)) or self._walk(found)

    def _walk(self, found: _Found):
        # a chunk's frames from its own records, which its CRC vouches for: (offsets, times), or None
        # when the chunk fails its CRC
        try:
            records = read_records(self.path, Chunk(found.data_offset, found.length, found.crc, 0,
                                                    np.zeros(0, np.int64)))
        except RecordingError:
            return None
        offsets, times, position = [], [], 0
        while position + RECORD.size <= len(records):
            opcode, size = RECORD.unpack_from(records, position)
            if opcode == Opcode.MESSAGE and size >= 22 and position + RECORD.size + 14 <= len(records):
                channel, _sequence, log_time = struct.unpack_from("<HIQ", records, position + RECORD.size)
                if channel == 1:
                    offsets.append(position)
                    times.append(log_time)
            position += RECORD.size + size
        return np.array(offsets, dtype=np.int64), np.array(times, dtype=np.uint64)

    def _indexed(self, found: _Found, size: int, version: str):
        # the chunk's message index, when it agrees with what vouches for it: (offsets, times) or None.
        # Our chunks hold a frame message after another, after the schema (version 3) and channel
        # records in the first one, so the offsets follow from the chunk's length; the times from our
        # checksummed record of the chunk (from version 2 on) or, failing that, the chunk header's span
        if found.index is None:
            return None
        offsets, times = found.index
        count = len(offsets)
        prefix = found.length - count * size
        if prefix < 0 or np.any(offsets != prefix + size * np.arange(count)):
            return None
        if prefix and not self._registrations(found.data_offset, prefix):
            return None
        if found.record is not None:
            if count != found.record["frames"] or not found.times_recorded():
                return None
        elif version != "1" or (count and (times.min() < found.start or times.max() > found.stop
                                            or np.any(np.diff(times.astype(np.int64)) < 0))):
            return None
        return offsets, times

    def _registrations(self, position: int, length: int) -> bool:
        # whether the ``length`` bytes at ``position`` are a schema record then a channel record, or a
        # channel record alone (versions 1 and 2), and nothing else
        end = position + length
        for opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            if position + RECORD.size > end:  # a damaged length took it past them
                break
            found, size = RECORD.unpack(self.read(position, RECORD.size))
            if found == opcode:
                position += RECORD.size + size
        return position == end

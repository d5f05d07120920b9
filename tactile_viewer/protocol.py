"""Serial frame codecs: text lines and binary frames with CRC. No Qt.

Text
    One frame per line: the ``m`` values separated by commas and/or spaces,
    ``\\n`` terminated (``\\r\\n`` accepted). Lines starting with ``#`` are
    comments; empty lines are ignored. Text frames carry no sequence number.

Binary (all little-endian)::

    0xA5 0x5A | seq uint16 | count uint16 | count x float32 | crc uint16

    crc = CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no
    final xor) over seq, count and the values; the sync bytes are not covered.

The decoders are incremental: ``feed(data)`` takes whatever bytes arrived
and returns the complete frames in them. They survive garbage, truncated
frames, wrong value counts and absurd lengths by resynchronizing, never
return a corrupted frame, and count every rejection by reason
(:attr:`Decoder.rejected`) and every byte skipped while searching for a frame
(:attr:`Decoder.skipped_bytes`).
"""

from __future__ import annotations

import binascii
import io
import struct
import warnings
from collections import Counter
from dataclasses import dataclass

import numpy as np

from solver.arrays import read_only

__all__ = ["SYNC", "MAX_VALUES", "FORMATS", "Frame", "Decoder", "TextDecoder", "BinaryDecoder",
           "crc16", "encode_binary", "encode_text", "make_decoder"]

SYNC = b"\xa5\x5a"
MAX_VALUES = 16384  # longer frames are garbage: no tactile board sends 64 KiB per frame
FORMATS = ("text", "binary")
_HEADER = struct.Struct("<HH")
_PLAIN = b"0123456789.+-eE, \t\nnaifntyNAIFTY"  # the bytes of lines of plain numbers (and nan, inf)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (``crc16(b"123456789") == 0x29B1``)."""
    # binascii.crc_hqx is the same polynomial, unreflected, with a given initial value
    return binascii.crc_hqx(data, 0xFFFF)


def encode_binary(seq: int, values) -> bytes:
    """One binary frame; ``seq`` is taken modulo 65536."""
    body = np.asarray(values, dtype="<f4").ravel()
    if body.size > MAX_VALUES:
        raise ValueError(f"values must number at most {MAX_VALUES}, got {body.size}")
    payload = _HEADER.pack(seq % 65536, body.size) + body.tobytes()
    return SYNC + payload + struct.pack("<H", crc16(payload))


def encode_text(values, *, digits: int = 6) -> bytes:
    """One text line: the values separated by commas, ``digits`` significant digits."""
    return (",".join(f"{v:.{digits}g}" for v in np.asarray(values, dtype=float).ravel()) + "\n").encode()


@dataclass(frozen=True)
class Frame:
    """One decoded frame.

    Attributes
    ----------
    values : (count,) ndarray
        The raw values as sent (float64, read-only).
    seq : int or None
        Sequence number (binary frames), None for text.
    """

    values: np.ndarray
    seq: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "values", read_only(self.values))


class Decoder:
    """Common state of the incremental decoders.

    Attributes
    ----------
    rejected : collections.Counter
        Rejected frames (or lines) by reason.
    skipped_bytes : int
        Bytes discarded while looking for the start of a frame.
    accepted : int
        Frames returned so far.
    """

    def __init__(self, count: int | None = None):
        if count is not None and not (isinstance(count, int) and 1 <= count <= MAX_VALUES):
            raise ValueError(f"count must be an integer in [1, {MAX_VALUES}] (or None), got {count!r}")
        self.count = count
        self.rejected: Counter = Counter()
        self.skipped_bytes = 0
        self.accepted = 0
        self._buffer = bytearray()

    def reset(self) -> None:
        """Drop any partial frame (after a reconnection); the counters are kept."""
        self._buffer.clear()

    @property
    def pending(self) -> int:
        """Bytes held while waiting for the rest of a frame."""
        return len(self._buffer)

    def feed(self, data: bytes) -> list[Frame]:
        raise NotImplementedError

    def _accept(self, values: np.ndarray, seq, out: list) -> None:
        if self.count is not None and values.size != self.count:
            self.rejected["wrong value count"] += 1
        elif not np.all(np.isfinite(values)):
            self.rejected["non-finite value"] += 1
        else:
            out.append(Frame(values, seq))
            self.accepted += 1


class TextDecoder(Decoder):
    """Incremental decoder of text lines.

    Parameters
    ----------
    count : int, optional
        Values per frame; lines with another count are rejected. None accepts any.
    max_line : int, optional
        Longest line accepted, bytes (default: 32 per expected value, at least
        4096); a longer run without newline is discarded up to the next newline.
    """

    def __init__(self, count: int | None = None, *, max_line: int | None = None):
        super().__init__(count)
        self.max_line = max_line if max_line is not None else max(4096, 32 * (count or 0))
        self._overlong = False  # inside a line already rejected as too long

    def reset(self) -> None:
        super().reset()
        self._overlong = False

    def feed(self, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        self._buffer += data
        start = 0
        buffer = self._buffer
        lines = []
        while True:
            end = buffer.find(b"\n", start)
            if end < 0:
                break
            line = bytes(buffer[start:end])
            start = end + 1
            if self._overlong:
                self._overlong = False
                self.skipped_bytes += len(line) + 1
                continue
            if len(line) > self.max_line:
                self.rejected["line too long"] += 1
                self.skipped_bytes += len(line) + 1
                continue
            text = line.strip()
            if text and not text.startswith(b"#"):
                lines.append(text)
        del buffer[:start]
        if lines:
            self._lines(lines, out)
        if len(buffer) > self.max_line:
            # no newline in sight: drop what we have and everything up to the next newline
            if not self._overlong:
                self.rejected["line too long"] += 1
            self._overlong = True
            self.skipped_bytes += len(buffer)
            buffer.clear()
        return out

    def _lines(self, lines: list, out: list) -> None:
        # numpy's C parser reads a block of well-formed lines about 1.5 times
        # faster than line by line; any irregular line sends the block down the
        # careful path, which gives the same answer line by line
        block = b"\n".join(lines)
        table = None
        # only plain numbers go the fast way: numpy splits on a few more bytes than bytes.split does
        if not block.translate(None, _PLAIN):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    table = np.loadtxt(io.BytesIO(block.replace(b",", b" ")), ndmin=2, comments=None)
            except (ValueError, Warning):
                table = None
        if table is not None and table.shape[0] == len(lines):
            for row in table:
                self._accept(row, None, out)
        else:
            for text in lines:
                self._line(text, out)

    def _line(self, text: bytes, out: list) -> None:
        try:
            values = np.array(text.replace(b",", b" ").split(), dtype=float)
        except ValueError:
            self.rejected["not numbers"] += 1
            return
        if values.size == 0:
            self.rejected["not numbers"] += 1
            return
        self._accept(values, None, out)


class BinaryDecoder(Decoder):
    """Incremental decoder of binary frames (see the module notes).

    Parameters
    ----------
    count : int, optional
        Values per frame. When given, a header announcing another count is
        rejected at once (a wrong frame or a false sync) and the search goes on
        from the next byte, so the decoder never waits for a bogus length.
    """

    def feed(self, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        buffer = self._buffer
        buffer += data
        position = 0
        while True:
            sync = buffer.find(SYNC, position)
            if sync < 0:
                # keep a trailing 0xA5 not yet decoded: it may be the first half of a sync
                keep = 1 if position < len(buffer) and buffer[-1] == SYNC[0] else 0
                self.skipped_bytes += len(buffer) - position - keep
                position = len(buffer) - keep
                break
            self.skipped_bytes += sync - position
            position = sync
            if len(buffer) - sync < 6:
                break  # header incomplete
            seq, count = _HEADER.unpack_from(buffer, sync + 2)
            if count == 0 or count > MAX_VALUES:
                self.rejected["absurd length"] += 1
                self.skipped_bytes += 1
                position = sync + 1
                continue
            if self.count is not None and count != self.count:
                self.rejected["wrong value count"] += 1
                self.skipped_bytes += 1
                position = sync + 1
                continue
            end = sync + 6 + 4 * count + 2
            if len(buffer) < end:
                break  # body incomplete: wait for more
            payload = bytes(buffer[sync + 2:end - 2])
            (sent_crc,) = struct.unpack_from("<H", buffer, end - 2)
            if crc16(payload) != sent_crc:
                # a corrupted frame or a false sync: search again from the next byte
                self.rejected["bad CRC"] += 1
                self.skipped_bytes += 1
                position = sync + 1
                continue
            values = np.frombuffer(payload, dtype="<f4", offset=4).astype(float)
            self._accept(values, seq, out)
            position = end
        del buffer[:position]
        return out


def make_decoder(fmt: str, count: int | None = None) -> Decoder:
    """A decoder for ``fmt`` in :data:`FORMATS`."""
    if fmt == "text":
        return TextDecoder(count)
    if fmt == "binary":
        return BinaryDecoder(count)
    raise ValueError(f"fmt must be one of {FORMATS}, got {fmt!r}")

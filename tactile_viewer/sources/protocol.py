"""Serial frame codecs: text lines (optionally checksummed) and binary frames with CRC. No Qt.

Text
    One frame per line: the ``m`` values separated by commas and/or spaces,
    ``\\n`` terminated (``\\r\\n`` accepted). Lines starting with ``#`` are
    comments; empty lines are ignored. Text frames carry no sequence number.

    A line may end with a checksum: ``*`` and exactly four hex digits, upper
    or lower case, then the line end::

        1.5,2,-0.25*808D\\r\\n

    The digits are the CRC-16/CCITT-FALSE (:func:`crc16`) of the exact bytes of
    the line before the ``*``: every byte after the previous ``\\n`` up to the
    ``*``, leading and trailing spaces included. The ``*``, the four digits and
    the line end (``\\n``, or ``\\r\\n``: one ``\\r`` before the ``\\n`` is
    removed first) are not covered. A comment that ends in ``*`` and four hex
    digits is checked too (a data line whose first digit was corrupted into
    ``#`` must not vanish as a comment); a ``*`` elsewhere in a comment is text.

Binary (all little-endian)::

    0xA5 0x5A | seq uint16 | count uint16 | count x float32 | crc uint16

    crc = CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no
    final xor) over seq, count and the values; the sync bytes are not covered.

Integrity
    Binary frames are always checked by their CRC. Text lines are checked only
    when they carry ``*XXXX``; without it a text frame cannot be checked: a
    flipped bit that turns a digit into another is returned as a wrong value.
    A data line with a ``*`` is rejected when its checksum does not match, when
    the ``*`` is not followed by exactly four hex digits and the line end, or
    when it has several ``*``. Once a connection has delivered a line with a
    valid checksum, every later data line must carry one (comments need not),
    so that a line whose ``*`` was corrupted cannot pass as an unchecked line;
    :meth:`Decoder.reset` (a reconnection) forgets this. The lines before the
    first valid checksum of a connection are taken as they come, so a bit error
    in the ``*`` of that very first checksummed line can still pass it unchecked
    (``*`` to ``.`` appends the digits to the last value; ``*`` to ``\\n`` sends
    them as a line of their own).

The decoders are incremental: ``feed(data)`` takes whatever bytes arrived
and returns the complete frames in them. They survive garbage, truncated
frames, wrong value counts and absurd lengths by resynchronizing, return no
frame that fails its check (the CRC of a binary frame, the checksum of a text
line that has one), and count every rejection by reason
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
from solver.checks import one_of

__all__ = ["SYNC", "MAX_VALUES", "FORMATS", "DecodedFrame", "Decoder", "TextDecoder", "BinaryDecoder",
           "crc16", "encode_binary", "encode_text", "make_decoder"]

SYNC = b"\xa5\x5a"
MAX_VALUES = 16384  # longer frames are garbage: no tactile board sends 64 KiB per frame
FORMATS = ("text", "binary")
_HEADER = struct.Struct("<HH")
_PLAIN = b"0123456789.+-eE, \t\nnaifntyNAIFTY"  # the bytes of lines of plain numbers (and nan, inf)
_HEX = b"0123456789abcdefABCDEF"  # int(..., 16) alone would also take "0x12", " 12 " and "1_2"


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


def encode_text(values, *, digits: int = 6, checksum: bool = False) -> bytes:
    """One text line: the values separated by commas, ``\\n`` terminated.

    Parameters
    ----------
    values : array_like
        The frame's values (flattened).
    digits : int
        Significant digits of each value.
    checksum : bool
        Append ``*`` and the CRC-16/CCITT-FALSE of the line's bytes before it in
        four upper-case hex digits (see the module notes), so that the decoder
        can reject a corrupted line.

    Returns
    -------
    bytes
        The line, ASCII.
    """
    body = ",".join(f"{v:.{digits}g}" for v in np.asarray(values, dtype=float).ravel()).encode()
    if checksum:
        return body + b"*%04X\n" % crc16(body)
    return body + b"\n"


@dataclass(frozen=True)
class DecodedFrame:
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
    wrong_sizes : collections.Counter
        How many values the frames rejected for their count held (value
        count: frames), to say what the board sends against what the layout
        describes.
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
        self.wrong_sizes: Counter = Counter()  # value counts of the frames rejected for their count
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

    def feed(self, data: bytes) -> list[DecodedFrame]:
        raise NotImplementedError

    def _accept(self, values: np.ndarray, seq, out: list) -> None:
        if self.count is not None and values.size != self.count:
            self.rejected["wrong value count"] += 1
            self.wrong_sizes[values.size] += 1
        elif not np.all(np.isfinite(values)):
            self.rejected["non-finite value"] += 1
        else:
            out.append(DecodedFrame(values, seq))
            self.accepted += 1


class TextDecoder(Decoder):
    """Incremental decoder of text lines, with or without checksums (see the module notes).

    Parameters
    ----------
    count : int, optional
        Values per frame; lines with another count are rejected. None accepts any.
    max_line : int, optional
        Longest line accepted, bytes, checksum included (default: 32 per expected
        value, at least 4096); a longer run without newline is discarded up to the
        next newline.

    Notes
    -----
    Besides the reasons of :class:`Decoder`, lines are rejected for ``"bad
    checksum"`` (four hex digits that do not match the line), ``"malformed
    checksum"`` (a ``*`` not followed by exactly four hex digits and the line end,
    or several ``*``) and ``"missing checksum"`` (no ``*XXXX`` on a connection that
    has delivered a valid one, see :attr:`checked`).
    """

    def __init__(self, count: int | None = None, *, max_line: int | None = None):
        super().__init__(count)
        self.max_line = max_line if max_line is not None else max(4096, 32 * (count or 0))
        self._overlong = False  # inside a line already rejected as too long
        self._checked = False

    @property
    def checked(self) -> bool:
        """Whether this connection delivered a line with a valid checksum.

        From then on a line without one is rejected; :meth:`reset` clears it.
        """
        return self._checked

    def reset(self) -> None:
        """Drop any partial line and forget :attr:`checked` (a reconnection); the counters are kept."""
        super().reset()
        self._overlong = False
        self._checked = False

    def feed(self, data: bytes) -> list[DecodedFrame]:
        out: list[DecodedFrame] = []
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
            if not text:
                continue
            if self._checked or b"*" in text:
                text = self._verified(line, text)
                if text is not None:
                    lines.append(text)
            elif not text.startswith(b"#"):
                lines.append(text)
        del buffer[:start]
        if lines:
            self._lines(lines, out)
        if self._overlong or len(buffer) > self.max_line:
            # no newline in sight: drop what we have and everything up to the next newline (inside a
            # line already too long, at once: how the stream was split must not change the counts)
            if not self._overlong:
                self.rejected["line too long"] += 1
            self._overlong = True
            self.skipped_bytes += len(buffer)
            buffer.clear()
        return out

    def _verified(self, line: bytes, text: bytes) -> bytes | None:
        """The values part of a data line that passes the checksum rules, else None.

        ``line`` is the whole line without its ``\\n``, ``text`` the same stripped.
        Rejections are counted here; comments give None uncounted unless they
        carry a checksum that does not match.
        """
        if line.endswith(b"\r"):
            line = line[:-1]
        if text.startswith(b"#"):
            # a data line whose first digit was corrupted into "#" still ends in its checksum: it must
            # be counted, not pass as a comment; a comment's own "*" in other places means nothing
            if len(line) >= 5 and line[-5] == 0x2A and not line[-4:].translate(None, _HEX):
                if crc16(line[:-5]) != int(line[-4:], 16):
                    self.rejected["bad checksum"] += 1
                else:
                    self._checked = True
            return None
        star = line.find(b"*")
        if star < 0:
            self.rejected["missing checksum"] += 1
            return None
        # the first "*" must be the one before the last four bytes: a second "*" is never hex
        if star != len(line) - 5 or line[-4:].translate(None, _HEX):
            self.rejected["malformed checksum"] += 1
            return None
        body = line[:star]
        if crc16(body) != int(line[-4:], 16):
            self.rejected["bad checksum"] += 1
            return None
        self._checked = True
        return body.strip()  # an empty one is "not numbers", as a line of separators only

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

    def feed(self, data: bytes) -> list[DecodedFrame]:
        out: list[DecodedFrame] = []
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
    one_of("fmt", fmt, FORMATS)
    return TextDecoder(count) if fmt == "text" else BinaryDecoder(count)

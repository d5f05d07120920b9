"""A live source that reads a Lab Streaming Layer stream: one float channel per taxel. No Qt.

:func:`find_streams` lists the streams on the network (by name and/or type);
:class:`LslSource` reads one as a live board is read (a
:class:`~tactile_viewer.sources.live.LiveSource`: the same reader thread,
calibration, tare, statistics, recording and NO DATA), its layout from a file
or from the stream's ``<layout>`` description (:mod:`tactile_viewer.sources.lsl`).

A sample of the wrong channel count or with a value that is not finite is
rejected and counted (the live bar lists the rejections), never handed on. A
stream that goes away is looked for again, by its name, type and (when it has
one) source id, every ``reconnect_interval``; meanwhile the live bar shows NO
DATA with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from solver.checks import real_number

from ..io.layout import SensorLayout
from .live import LiveSource
from .lsl import layout_from_description
from .protocol import DecodedFrame, Decoder

__all__ = ["FoundStream", "LslSource", "StreamNotFound", "find_streams", "SampleDecoder", "URL_PREFIX"]

URL_PREFIX = "lsl:"  # how a stream is named where a port would be (``lsl:NAME``)
PULL_TIMEOUT_S = 0.05  # the reader waits this long for a sample before it looks at its stop flag
MAX_CHUNK = 1024  # samples taken per pull: a 1 kHz stream's second in one go at worst
LOOK_AGAIN_S = 0.3  # seconds each look for a lost stream listens (a stop waits for at most one look)
_DTYPES = {"float32": np.float32, "double64": np.float64, "int8": np.int8, "int16": np.int16,
           "int32": np.int32, "int64": np.int64}  # what liblsl writes into a pull's buffer
_FORMATS = {1: "float32", 2: "double64", 3: "string", 4: "int32", 5: "int16", 6: "int8", 7: "int64",
            0: "undefined"}  # pylsl's cf_* codes


class StreamNotFound(ConnectionError):
    """No stream on the network matches (now): a lost stream that may come back."""


@dataclass(frozen=True)
class FoundStream:
    """A stream a resolve found (what LSL announces; its description comes with :meth:`LslSource.open`).

    Attributes
    ----------
    name, type, source_id, hostname, uid : str
    channel_count : int
    channel_format : str
        ``"float32"``, ``"double64"``, ``"int16"``, ... or ``"string"``.
    nominal_rate : float
        Hertz, 0 for an irregular rate.
    info : pylsl.StreamInfo
        What the resolve returned, to open an inlet with.
    """

    name: str
    type: str
    channel_count: int
    channel_format: str
    nominal_rate: float
    source_id: str
    hostname: str
    uid: str
    info: object = field(repr=False, compare=False)

    @classmethod
    def of(cls, info) -> FoundStream:
        return cls(info.name(), info.type(), info.channel_count(), _FORMATS.get(info.channel_format(), "?"),
                   info.nominal_srate(), info.source_id(), info.hostname(), info.uid(), info)

    @property
    def url(self) -> str:
        """``lsl:NAME``, how the live bar and recordings name the stream."""
        return URL_PREFIX + self.name

    def describe(self) -> str:
        """One line for a list: name, type, channels, rate, host."""
        rate = f"{self.nominal_rate:g} Hz" if self.nominal_rate > 0 else "irregular rate"
        return (f"{self.name}  (type {self.type or '-'}, {self.channel_count} {self.channel_format} "
                f"channels, {rate}, on {self.hostname})")


def find_streams(*, name: str | None = None, stream_type: str | None = None,
                 timeout: float = 1.0) -> list[FoundStream]:
    """The LSL streams on the network, those with ``name`` and ``stream_type`` when given.

    Parameters
    ----------
    name, stream_type : str or None
        Exact stream name and type to match (None: any).
    timeout : float
        Seconds to listen for announcements (default 1). All streams that
        answer within it are listed, sorted by name.

    Raises
    ------
    ValueError
        For a timeout that is not a positive number of seconds.
    """
    timeout = real_number("timeout", timeout, rule="a positive finite number of seconds",
                          valid=lambda t: math.isfinite(t) and t > 0)
    import pylsl

    found = pylsl.resolve_streams(wait_time=timeout)
    streams = [FoundStream.of(info) for info in found if (name is None or info.name() == name)
               and (stream_type is None or info.type() == stream_type)]
    return sorted(streams, key=lambda s: (s.name, s.type, s.hostname, s.uid))


class SampleDecoder(Decoder):
    """The decoder of an LSL inlet: samples, not bytes; the same checks and counts as a board's.

    :meth:`feed` takes a chunk ``(samples (k, channels), stamps (k,))`` as pulled
    and returns its frames; a sample of the wrong value count or with a value
    not finite is rejected and counted by reason (:attr:`rejected`), as a
    serial decoder does. LSL carries no sequence numbers.
    """

    def feed(self, data) -> list[DecodedFrame]:
        samples, _stamps = data
        out: list[DecodedFrame] = []
        values = np.asarray(samples, dtype=float)
        for row in values.reshape(len(values), -1):
            self._accept(row, None, out)
        return out


class LslSource(LiveSource):
    """An LSL stream as a live source: one channel per taxel, in the layout's taxel order.

    Parameters
    ----------
    stream : FoundStream
        The stream to read (:func:`find_streams`).
    layout : SensorLayout or None
        How the samples map onto the skin and become pascals; None reads it
        from the stream's ``<layout>`` description.
    timeout : float
        Seconds to wait for the stream's description when opening (default 2).
    reconnect_interval : float
        Seconds between looks for a lost stream (default 0.5).

    Raises
    ------
    ValueError
        For a stream of strings, a layout that the description lacks or gets
        wrong, or a channel count other than the layout's taxels (the message
        names both).
    StreamNotFound
        When the stream cannot be opened now.

    Notes
    -----
    Frames carry their receive time on the reader's clock as a board's do;
    the stream's own stamps are not kept (a recording stores receive times).
    A stream with a ``source_id`` is known again after it was lost (only a
    stream with the same id is taken); one without is not, so a recording
    ends when it comes back (:class:`LiveSource`).
    """

    def __init__(self, stream: FoundStream, layout: SensorLayout | None = None, *, timeout: float = 2.0,
                 reconnect_interval: float = 0.5):
        if not isinstance(stream, FoundStream):
            raise TypeError(f"stream must be a FoundStream (find_streams), got {type(stream).__name__}")
        if stream.channel_format not in _DTYPES:
            raise ValueError(f"stream {stream.name!r} sends {stream.channel_format} channels; a tactile "
                             "stream sends numbers (one float channel per taxel)")
        self.stream = stream
        self.timeout = real_number("timeout", timeout, rule="a positive finite number of seconds",
                                   valid=lambda t: math.isfinite(t) and t > 0)
        # the first connection is made here: the layout may be in its description
        inlet, info = self._inlet(stream.info)
        try:
            if layout is None:
                try:
                    layout = layout_from_description(info.desc())
                except ValueError as exc:
                    raise ValueError(f"stream {stream.name!r}: {exc}; choose a layout file") from None
            self._check_count(stream.channel_count, layout)
            super().__init__(stream.url, layout, reconnect_interval=reconnect_interval)
        except Exception:
            inlet.close_stream()
            raise
        self.label = f"{stream.url} ({stream.type or 'no type'}, {stream.channel_count} channels)"
        self.raw_dtype = "float32" if stream.channel_format in ("float32", "int8", "int16") else "float64"
        self.decoder = SampleDecoder(layout.count)
        self.described = info  # the full stream info, description included
        self._pending = inlet
        self._buffer = np.zeros((MAX_CHUNK, stream.channel_count), dtype=_DTYPES[stream.channel_format])

        # every pylsl error is a RuntimeError (LostError, TimeoutError, InternalError ...): each
        # means the stream is gone for now, and the reader looks for it again rather than ending
        self.lost = (StreamNotFound, RuntimeError, OSError)

    @staticmethod
    def _check_count(channels: int, layout: SensorLayout) -> None:
        if channels != layout.count:
            raise ValueError(f"the stream has {channels} channels but the layout describes {layout.count} "
                             "taxels (one channel per taxel)")

    def _inlet(self, info):
        import pylsl

        # no recovery inside liblsl: a lost stream must show as lost (NO DATA, reconnecting)
        inlet = pylsl.StreamInlet(info, max_buflen=60, recover=False)
        try:
            full = inlet.info(timeout=self.timeout)
            inlet.open_stream(timeout=self.timeout)
        except pylsl.util.TimeoutError:
            inlet.close_stream()
            raise StreamNotFound(f"stream {info.name()!r} did not answer within {self.timeout:g} s") from None
        return inlet, full

    @property
    def same_device_known(self) -> bool:
        return bool(self.stream.source_id)

    @property
    def identity_notice(self) -> str:
        if self.same_device_known:
            return ""
        return (f"stream {self.stream.name!r} has no source_id: a stream that comes back under its name may "
                "be another; recordings end at a reconnection")

    def _open(self):
        pending, self._pending = self._pending, None
        if pending is not None:
            return pending
        import pylsl

        wanted = self.stream
        found = pylsl.resolve_byprop("name", wanted.name, minimum=1, timeout=LOOK_AGAIN_S)
        matches = [info for info in found if info.type() == wanted.type
                   and (not wanted.source_id or info.source_id() == wanted.source_id)]
        if not matches:
            raise StreamNotFound(f"stream {wanted.name!r} of type {wanted.type!r} is not on the network")
        info = matches[0]
        # a stream that came back with another channel count: refused (the reader says why and looks again)
        self._check_count(info.channel_count(), self.layout)
        if _FORMATS.get(info.channel_format()) != wanted.channel_format:
            raise ValueError(f"stream {wanted.name!r} came back with {_FORMATS.get(info.channel_format())} "
                             f"channels instead of {wanted.channel_format}")
        inlet, _ = self._inlet(info)
        return inlet

    def _read(self, inlet):
        buffer = self._buffer
        samples, stamps = inlet.pull_chunk(timeout=PULL_TIMEOUT_S, max_samples=len(buffer), dest_obj=buffer,
                                           min_samples=1, as_numpy=True)
        if len(stamps) == 0:
            return None
        return samples.copy(), stamps  # the buffer is refilled by the next pull

    def stop(self) -> None:
        """Stop reading; a source never started closes the inlet its constructor opened."""
        pending, self._pending = self._pending, None
        if pending is not None:
            self._close(pending)
        super().stop()

    def _close(self, inlet) -> None:
        try:
            inlet.close_stream()
        except RuntimeError:  # pylsl's LostError and TimeoutError: the stream is gone anyway
            pass

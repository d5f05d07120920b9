"""The writer of MCAP recordings: :class:`Recorder`, every frame a source produces, a chunk per second. No Qt.

The format is :mod:`tactile_viewer.io.mcap_format`; each frame is a ROS 2
message (:mod:`tactile_viewer.io.ros2_message`), so ROS 2 tools and Foxglove
read the file as it is written. Chunks are closed every
``flush_interval`` seconds of receive time (1 s), so a crash loses at most
that much. Each chunk gets a CRC of its own and, after it, a checksummed
record of it. Nothing is fsynced: a crash of the program loses nothing the
operating system was given; a power cut of the machine may lose what it had
not yet written back.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import queue
import threading
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer

from solver import SensorGrid

from .mcap_format import (
    LIBRARY,
    PROFILE,
    RAW_DTYPES,
    RECORD,
    SUFFIX,
    TOPIC,
    VERSION,
    metadata_checksum,
    times_checksum,
)
from .recording import StressCalibration, Tare, geometry_fields, json_ready
from .ros2_message import FRAME_ID, MESSAGE_ENCODING, SCHEMA_ENCODING, SCHEMAS, FrameMessage

__all__ = ["Recorder"]

_CHUNK_BYTES = 2**31  # past any second of frames (a 1000x1000 skin at 1 kHz writes 4 GB/s: not a case)


def _not_through_a_link(path, flags):
    # open()'s opener: O_NOFOLLOW refuses a symbolic link as the file itself (ELOOP)
    return os.open(path, flags | os.O_NOFOLLOW, 0o666)


class Recorder:
    """Writes every frame it is given to an MCAP recording, a chunk per ``flush_interval``.

    Each frame is a ROS 2 message of type ``tactile_viewer_msgs/msg/TactileFrame32``
    (``...64`` for float64 values; :mod:`tactile_viewer.io.ros2_message`): its receive
    time in the header, its sequence number and its raw values.

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
        self._message = FrameMessage.ros2(grid.size, dtype)
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
            writer.start(profile=PROFILE, library=LIBRARY)
            self._writer = writer
            self._add_metadata("recording", {"version": VERSION, "description": self.description,
                                             "taxels": str(grid.size), "dtype": dtype, "channel": "1",
                                             "frame_id": FRAME_ID})
            self._add_metadata("geometry", _json_fields(geometry_fields(grid)))
            self._add_metadata("calibration", _json_fields(calibration.fields()))
            schema = writer.register_schema(self._message.type_name, SCHEMA_ENCODING, SCHEMAS[dtype].encode())
            self._channel = writer.register_channel(TOPIC, MESSAGE_ENCODING, schema_id=schema,
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
        self._writer.add_message(self._channel, log_time=stamp, data=self._message.encode(seq, stamp, values),
                                 publish_time=stamp, sequence=seq % 2**32)
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
        fields["crc32"] = metadata_checksum(fields)
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
        length = self._stream.tell() - position - RECORD.size - (RECORD.size + 6 + 16 * count)
        self._add_metadata("chunk", {
            "offset": str(position), "length": str(length), "first": str(self.written),
            "frames": str(count), "times_crc32": times_checksum(self._chunk_times),
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

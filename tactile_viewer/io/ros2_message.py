"""Frames as ROS 2 messages: the message types of our recordings, their schema and byte layout. No Qt.

From recording version 3 on, every frame in an MCAP recording is a ROS 2
message (message encoding ``cdr``, schema encoding ``ros2msg``, the schema in
the file), so Foxglove shows and plots frames and ``rosbags`` or
``mcap-ros2-support`` decode them without ROS. There is no standard ROS 2
tactile message, so the types are ours, one per raw dtype (the values stay as
the board sent them: float32 from a binary board, float64 from text)::

    tactile_viewer_msgs/msg/TactileFrame32   (float32[] values)
    tactile_viewer_msgs/msg/TactileFrame64   (float64[] values)

    std_msgs/Header header   stamp: the frame's receive time; frame_id: FRAME_ID
    uint64 sequence          the frame's sequence number as the source counted it
    floatNN[] values         raw values, one per taxel, row-major (x fastest)

The layout of the skin and the calibration that turns values into pascals stay
in the file's metadata (:mod:`tactile_viewer.io.mcap_format`), written once.

Every frame of a recording has the same number of values and the same
``frame_id``, so every message has the same size and each field sits at the
same byte in each: :class:`FrameMessage` says where, so a chunk of frames is
read as a strided array, never decoded one message at a time. It also
describes the messages of versions 1 and 2 (the raw values alone, in the
private encoding ``tactile-raw/<dtype>-le``), which still open.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from solver.arrays import read_only
from solver.checks import one_of, whole_number

__all__ = ["MESSAGE_ENCODING", "SCHEMA_ENCODING", "MESSAGE_TYPES", "SCHEMAS", "VALUES_FIELD", "FRAME_ID",
           "FrameMessage"]

MESSAGE_ENCODING = "cdr"
SCHEMA_ENCODING = "ros2msg"
VALUES_FIELD = "values"
# the coordinate frame named in every header: a lab's TF tree may attach the skin under this name
FRAME_ID = "tactile_skin"
MESSAGE_TYPES = {"float32": "tactile_viewer_msgs/msg/TactileFrame32",
                 "float64": "tactile_viewer_msgs/msg/TactileFrame64"}

_SEPARATOR = "=" * 80
_DEPENDENCIES = f"""{_SEPARATOR}
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.
builtin_interfaces/Time stamp
string frame_id
{_SEPARATOR}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


def _schema(dtype: str) -> str:
    return f"""# One frame of a tactile array (a robot skin of normal-stress sensors) as it was received.
# Values are raw, as the board sent them; the file's metadata tactile-viewer.calibration turns
# them into pascals (stress = gain * (raw - offset) * scale(units), minus the tare) and
# tactile-viewer.geometry gives the layout (nx, ny, pitch, thickness in metres).
std_msgs/Header header  # stamp: the frame's receive time; frame_id: the skin
uint64 sequence  # the frame's number as the source counted it
{dtype}[] {VALUES_FIELD}  # one per taxel, taxel k = iy * nx + ix (row-major, x fastest)
{_DEPENDENCIES}"""


SCHEMAS = {dtype: _schema(dtype) for dtype in MESSAGE_TYPES}

_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little-endian, no options


def _aligned(position: int, size: int) -> int:
    # CDR aligns each primitive to its own size, counted from after the encapsulation header
    return -(-position // size) * size


@dataclass(frozen=True)
class FrameMessage:
    """Where the fields of a recording's frame messages lie: every message has the same size.

    Build one with :meth:`ros2` (version 3: a CDR message) or :meth:`legacy`
    (versions 1 and 2: the raw values alone). Offsets count bytes from the start
    of the message's data (the MCAP message record's payload).

    Attributes
    ----------
    taxels : int
        Values per frame.
    dtype : numpy.dtype
        The raw values' dtype, little-endian.
    size : int
        Bytes of every message's data.
    values_at : int
        Where the values start.
    sequence_at : int or None
        Where the uint64 sequence number is; None when only the MCAP record's
        sequence (modulo 2**32) keeps it (versions 1 and 2).
    fixed_at : (k,) ndarray of int
        Bytes that are the same in every message (encapsulation, frame_id, value
        count, padding): a message whose bytes there differ is not a frame.
    fixed : (k,) ndarray of uint8
        What they hold.
    head : struct.Struct or None
        Version 3: the message up to its values, packed in one call by :meth:`encode`.
    frame_id : bytes
        Version 3: the header's frame_id with its terminating NUL.
    """

    taxels: int
    dtype: np.dtype
    size: int
    values_at: int
    sequence_at: int | None
    fixed_at: np.ndarray = field(compare=False)
    fixed: np.ndarray = field(compare=False)
    head: struct.Struct | None = field(default=None, compare=False)
    frame_id: bytes = b""

    @classmethod
    def ros2(cls, taxels: int, dtype: str, frame_id: str = FRAME_ID) -> FrameMessage:
        """The CDR message ``MESSAGE_TYPES[dtype]`` of ``taxels`` values with header ``frame_id``.

        Raises
        ------
        ValueError
            For a taxel count under 1, a dtype other than float32 or float64, or a
            frame_id that is not printable ASCII of at most 255 characters.
        """
        taxels, dtype = cls._checked(taxels, dtype)
        if not (isinstance(frame_id, str) and len(frame_id) <= 255 and frame_id.isascii()
                and frame_id.isprintable()):
            raise ValueError(f"frame_id must be printable ASCII of at most 255 characters, got {frame_id!r}")
        name = frame_id.encode() + b"\x00"  # a CDR string counts and keeps its terminating NUL
        # offsets after the encapsulation: stamp 0, frame_id's length 8 and characters 12, then
        # the sequence, the value count and the values, each aligned to its size
        after_name = 12 + len(name)
        sequence_at = _aligned(after_name, 8)
        count_at = sequence_at + 8
        values_at = _aligned(count_at + 4, dtype.itemsize)
        head = struct.Struct(f"<4sIII{len(name)}s{sequence_at - after_name}xQI{values_at - count_at - 4}x")
        # the stamp and the sequence differ from message to message; every other byte up to the
        # values (padding included, zeros as ROS 2 writes them) is the same in each
        template = np.frombuffer(head.pack(_ENCAPSULATION, 0, 0, len(name), name, 0, taxels), np.uint8)
        varying = np.zeros(len(template), bool)
        varying[4:12] = True
        varying[4 + sequence_at:4 + sequence_at + 8] = True
        fixed_at = np.flatnonzero(~varying)
        return cls(taxels, dtype, 4 + values_at + taxels * dtype.itemsize, 4 + values_at, 4 + sequence_at,
                   read_only(fixed_at, int), read_only(template[fixed_at], np.uint8), head, name)

    @classmethod
    def legacy(cls, taxels: int, dtype: str) -> FrameMessage:
        """The message of recording versions 1 and 2: ``taxels`` raw values and nothing else."""
        taxels, dtype = cls._checked(taxels, dtype)
        nothing = read_only([], int)
        return cls(taxels, dtype, taxels * dtype.itemsize, 0, None, nothing, read_only(nothing, np.uint8))

    @staticmethod
    def _checked(taxels, dtype) -> tuple[int, np.dtype]:
        taxels = whole_number("taxels", taxels, low=1)
        one_of("dtype", dtype, tuple(MESSAGE_TYPES))
        return taxels, np.dtype(dtype).newbyteorder("<")

    @property
    def type_name(self) -> str:
        """The ROS 2 message type (``tactile_viewer_msgs/msg/TactileFrame32`` for float32)."""
        return MESSAGE_TYPES[self.dtype.name]

    def encode(self, sequence: int, stamp: int, values: np.ndarray) -> bytes:
        """The message data of one frame (version 3 only).

        Parameters
        ----------
        sequence : int
            The frame's sequence number (stored modulo 2**64).
        stamp : int
            Receive time, UNIX nanoseconds (>= 0).
        values : (taxels,) ndarray of ``dtype``
        """
        seconds, nanoseconds = divmod(stamp, 10**9)
        # int32 seconds end in 2038 as in ROS 2 itself; wrapping keeps the recording going, and
        # the MCAP log_time (uint64 nanoseconds) stays exact
        return self.head.pack(_ENCAPSULATION, seconds % 2**32, nanoseconds, len(self.frame_id), self.frame_id,
                              sequence % 2**64, self.taxels) + values.tobytes()

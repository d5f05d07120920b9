"""The MCAP recording format: its constants, the layout of its records and its checksums. No Qt.

Live recordings are MCAP files: :class:`~tactile_viewer.io.mcap_writer.Recorder`
writes them, :func:`~tactile_viewer.io.mcap_reader.open_recording` reads them
lazily. Both go through the MCAP container of the ``mcap`` package (the ROS 2
bag format): records are only ever appended, so a file cut short by a kill, a
power cut of the program or a full disk is complete up to its last whole chunk.
HDF5 in SWMR mode was tried too and rejected: on a full disk its writer
crashed the process and its file showed frames that were never written (the
figures are in ``docs/recordings.md``).

The header names the profile ``ros2`` (so that ROS 2 tools such as ``rosbags``
take the file) and the library ``tactile-viewer``; what makes a file a
recording of ours is its metadata ``tactile-viewer.recording``
(:func:`is_recording_of_ours`). A file holds
- metadata ``tactile-viewer.recording``: ``version``, ``description``,
  ``taxels``, ``dtype`` of the raw values (``float32`` as a binary board sends
  them, ``float64`` for text), the ``channel`` id of the frames and (version 3)
  the ``frame_id`` in every frame's header;
- metadata ``tactile-viewer.geometry``: the fields of
  :func:`~tactile_viewer.io.recording.geometry_fields` (JSON values);
- metadata ``tactile-viewer.calibration``: ``units``, ``gain``, ``offset``
  turning raw values into pascals (``gain * (raw - offset) * scale(units)``);
- metadata ``tactile-viewer.tare``, zero or more: a baseline (pascals)
  subtracted from frame ``from_frame`` on, with the receive time it was taken;
- one message per frame on channel ``/tactile/raw``; ``log_time`` the receive
  time (UNIX nanoseconds), ``sequence`` the frame's sequence number (modulo
  2**32). From version 3 on a ROS 2 message (CDR, its ``ros2msg`` schema in the
  file: :mod:`tactile_viewer.io.ros2_message`) with the receive time in its
  header and the whole sequence number; before, the raw values alone,
  little-endian, in the private encoding ``tactile-raw/<dtype>-le``.

From version 2 on every metadata record of ours carries ``crc32``
(:func:`metadata_checksum`), and each chunk is followed by a record
``tactile-viewer.chunk`` of it: where it is, its frames' numbers, the checksum
of their receive times (:func:`times_checksum`) and the tares written so far.
"""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np

__all__ = ["SUFFIX", "VERSION", "VERSIONS", "TOPIC", "PROFILE", "LIBRARY", "RAW_DTYPES", "MAGIC", "RECORD",
           "CHUNK_HEAD", "MESSAGE_HEAD", "BLOCK", "metadata_checksum", "times_checksum",
           "is_recording_of_ours"]

SUFFIX = ".mcap"
# 2: a checksum in every metadata record of ours, and a record of each chunk; 3: frames are ROS 2 messages
VERSION = "3"
VERSIONS = ("1", "2", "3")
PROFILE = "ros2"  # versions 1 and 2 named "tactile-viewer", which ROS 2 tools refuse
LIBRARY = "tactile-viewer"
TOPIC = "/tactile/raw"
RAW_DTYPES = {"float32": "<f4", "float64": "<f8"}
MAGIC = b"\x89MCAP0\r\n"
RECORD = struct.Struct("<BQ")  # opcode, content length
CHUNK_HEAD = struct.Struct("<QQQII")  # start time, end time, uncompressed size, crc, compression length
MESSAGE_HEAD = 9 + 22  # record header, then channel u16, sequence u32, log time u64, publish time u64
# bytes read at a time: when looking past damage, and checking the data section's CRC
BLOCK = 2**24


def metadata_checksum(fields: dict) -> str:
    """CRC-32 of a metadata record's fields but ``crc32`` in a canonical form, as 8 hex digits."""
    # metadata values are strings
    text = json.dumps(sorted((key, value) for key, value in fields.items() if key != "crc32"),
                      separators=(",", ":"))
    return f"{zlib.crc32(text.encode()):08x}"


def times_checksum(times) -> str:
    """CRC-32 of receive times (UNIX nanoseconds, little-endian u64), as 8 hex digits."""
    return f"{zlib.crc32(np.asarray(times, dtype='<u8').tobytes()):08x}"


def is_recording_of_ours(path) -> bool:
    """Whether the MCAP file at ``path`` is a recording this viewer wrote (any version).

    Cheap (reads its first 4 KiB): its header names our library, or the metadata
    ``tactile-viewer.recording`` that every version writes first follows it. A
    ROS 2 bag of another program is neither, even when it holds our frame
    messages. Raises OSError when the file cannot be read.
    """
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if not head.startswith(MAGIC):
        return False
    if b"tactile-viewer.recording" in head:
        return True
    # the header record: opcode, length, then the profile and the library as length-prefixed strings
    at = len(MAGIC) + RECORD.size
    if len(head) < at + 4:
        return False
    (profile,) = struct.unpack_from("<I", head, at)
    at += 4 + profile
    if len(head) < at + 4:
        return False
    (library,) = struct.unpack_from("<I", head, at)
    return head[at + 4:at + 4 + library] == LIBRARY.encode()

"""ROS 2 bags as recordings: one topic of numeric arrays read through a sensor layout file. No Qt.

A ROS 2 bag (a folder with ``metadata.yaml``, or a bare ``.mcap`` or ``.db3``
storage file) that is not a recording of this viewer opens as a
:class:`~tactile_viewer.io.recording.Recording` from one topic whose messages
hold one frame each in an array of numbers: ``std_msgs/msg/Float32MultiArray`` or
``Float64MultiArray`` (field ``data``), or any message with a numeric array field
(``float32[]``, ``uint16[256]`` ..., also inside a nested message: ``array.data``).
A message's values are the raw values of a frame; the sensor layout file
(:func:`~tactile_viewer.io.layout.load_layout`, the one a live board uses) gives
the geometry and turns them into pascals.

:func:`array_topics` lists what can be chosen; :func:`load_ros2_bag` reads one
(:func:`tactile_viewer.io.files.load` sends a bag here). rosbags decodes the
messages (:class:`rosbags.highlevel.AnyReader`) from the message definitions the
bag stores; a type the bag does not define comes from the ROS 2 distribution it
was recorded with (the newest one rosbags knows when the bag does not say).
Times are the messages' ``header.stamp`` when they have a ``std_msgs/Header
header`` whose stamps are set, else the bag's log (receive) time.

A message that cannot be a frame (another number of values than the layout's
taxels, a value that is no finite number, one that cannot be decoded, a header
stamp of zero among set ones) is left out, counted and said in
:attr:`Recording.damage <tactile_viewer.io.recording.Recording.damage>`, its time
shaded through ``lost_spans``; the rest loads. When no message can be a frame,
the error says what they hold. A bag opens whole, like NPZ and CSV, so the
frames must fit :data:`~tactile_viewer.io.recording.MAX_RECORDING_BYTES`.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.opcode import Opcode
from rosbags.highlevel import AnyReader
from rosbags.interfaces import Nodetype
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from solver.checks import shown

from .bag_topics import ArrayField, candidates, choose, field_value, no_arrays, sized
from .foxglove_mcap import is_foxglove_export
from .layout import LayoutError, SensorLayout, load_layout
from .mcap_format import MAGIC, RECORD, is_recording_of_ours
from .recording import MAX_RECORDING_BYTES, Recording, RecordingError, bytes_text

__all__ = ["is_ros2_bag", "bag_location", "array_topics", "load_ros2_bag", "BAG_METADATA"]

BAG_METADATA = "metadata.yaml"
# how many shaded spans of left-out messages the time plots get at most (one per run of them)
_MAX_SPANS = 100


def is_ros2_bag(path) -> bool:
    """Whether ``path`` is a ROS 2 bag for :func:`load_ros2_bag` rather than a recording of ours.

    A folder holding ``metadata.yaml`` (or that file itself), a ``.db3`` file, or an MCAP file
    whose header names another program and that holds no metadata of ours
    (:func:`~tactile_viewer.io.mcap_format.is_recording_of_ours`) and is no Foxglove export of
    ours (:func:`~tactile_viewer.io.foxglove_mcap.is_foxglove_export`). Only an ``.mcap`` file is
    read (its first kilobytes); one too short to tell, or no MCAP at all, is left to the reader
    of our recordings, which says what it is.
    """
    path = Path(path)
    try:
        if path.is_dir():
            return (path / BAG_METADATA).is_file()
        # only a regular file: reading a named pipe would block
        if not path.is_file():
            return False
        if path.name == BAG_METADATA or path.suffix.lower() == ".db3":
            return True
        if path.suffix.lower() != ".mcap" or is_recording_of_ours(path) or is_foxglove_export(path):
            return False
        with open(path, "rb") as handle:
            head = handle.read(len(MAGIC) + RECORD.size)
    except OSError:  # unreadable: the recording reader says why
        return False
    if len(head) < len(MAGIC) + RECORD.size or not head.startswith(MAGIC):
        return False
    # the whole header record is there (the library it names is another's): a file of ours cut
    # inside its header is not taken for another program's bag
    opcode, length = RECORD.unpack_from(head, len(MAGIC))
    return opcode == Opcode.HEADER and path.stat().st_size >= len(head) + length


def bag_location(path) -> Path:
    """The bag ``path`` names: the folder of a ``metadata.yaml``, else ``path`` itself."""
    path = Path(path)
    return path.parent if path.name == BAG_METADATA else path


def array_topics(path) -> list[ArrayField]:
    """Every numeric array field of every topic of the bag at ``path``, with its first message's size.

    Returns
    -------
    list of tactile_viewer.io.bag_topics.ArrayField
        In topic order.

    Raises
    ------
    RecordingError
        The bag cannot be read, or none of its topics has a numeric array field (the error
        names its topics).
    """
    path = bag_location(path)
    with _reading(path) as reader:
        fields = candidates(reader)
        if not fields:
            raise RecordingError(no_arrays(reader, path))
        return sized(reader, fields)


def load_ros2_bag(path, *, layout, topic=None, field=None) -> Recording:
    """Open one numeric array topic of a ROS 2 bag as a recording, through a sensor layout.

    Parameters
    ----------
    path : str or Path
        A bag folder (with ``metadata.yaml``, or that file), or a bare ``.mcap`` or ``.db3``.
    layout : SensorLayout or str or Path
        The skin's sensor layout, or its JSON file: the geometry, and the units, gain and offset
        that turn a message's values into pascals. Its taxel count is the number of values
        every message must hold.
    topic, field : str or None
        The topic and the field of its messages (dot-separated when nested, ``array.data``).
        None: the only topic or field with a numeric array; among several, the only one whose
        first message holds as many values as the layout has taxels.

    Returns
    -------
    Recording
        Frames ``(T, m)`` in pascals, times in seconds from the first frame (``header.stamp``
        when the messages have a set one, else the bag's log time), ``received`` the first
        frame's time in UNIX seconds; messages left out are said in ``damage``.

    Raises
    ------
    RecordingError
        Naming the bag, topic and field and what was found: no layout, an unreadable bag or
        layout, a topic or field that is missing, not numeric, ambiguous or empty, frames over
        :data:`~tactile_viewer.io.recording.MAX_RECORDING_BYTES`, or no message that can be a frame.
    ValueError
        ``topic`` or ``field`` is not text.
    """
    for name, value in (("topic", topic), ("field", field)):
        if value is not None and (not isinstance(value, str) or not value):
            raise ValueError(f"{name} must be a non-empty name (text) or None, got {shown(value)}")
    path = bag_location(path)
    layout, layout_name = _layout(layout, path)
    with _reading(path) as reader:
        choice = choose(reader, path, topic, field, layout.count)
        frames = _read_frames(reader, choice, layout, path)
    return frames.recording(layout, f"ROS 2 bag {path.name}, topic {choice.topic}, field {choice.field} "
                                    f"({choice.msgtype}), layout {layout_name}")


# -- reading a bag -----------------------------------------------------------------------------------


def _reason(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


@contextlib.contextmanager
def _reading(path: Path):
    """An open AnyReader of the bag, its typestore completed from the bag's ROS 2 distribution."""
    try:
        with Reader(path) as bag:
            distro = bag.ros_distro
        store = get_typestore(getattr(Stores, f"ROS2_{str(distro).upper()}", Stores.LATEST))
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    # rosbags raises many kinds on a file it cannot read (its own errors, sqlite3's, asserts)
    except Exception as exc:
        raise RecordingError(f"{path}: not a readable ROS 2 bag ({_reason(exc)})") from None
    try:
        # the bag's own definitions come first; a type it does not define is its distribution's
        missing = {}
        for connection in reader.connections:
            if connection.msgtype not in reader.typestore.fielddefs:
                missing.update(_definitions(store, connection.msgtype))
        if missing:
            reader.typestore.register(missing)
        yield reader
    finally:
        reader.close()


def _definitions(store, msgtype: str, found=None) -> dict:
    # ``msgtype`` and every type it names, as defined in ``store`` (none if it is not defined there)
    found = {} if found is None else found
    if msgtype in found or msgtype not in store.fielddefs:
        return found
    found[msgtype] = store.fielddefs[msgtype]
    for _name, (kind, detail) in store.fielddefs[msgtype][1]:
        named = detail if kind == Nodetype.NAME else detail[0][1] if kind != Nodetype.BASE else None
        if isinstance(named, str):
            _definitions(store, named, found)
    return found


# -- the frames ----------------------------------------------------------------------------------------


@dataclass
class _Frames:
    """The messages of a topic read as frames (a mutable draft: :meth:`recording` makes the Recording)."""

    path: Path
    raw: np.ndarray  # (k, m) the values of the messages kept
    logged: np.ndarray  # (k,) log times, ns
    stamps: np.ndarray | None  # (k,) header stamps, ns (None: no header)
    positions: np.ndarray  # (k,) each kept message's place among the topic's messages
    read: int  # messages read
    left_out: dict  # reason: [place of each message left out]
    choice: ArrayField
    stopped: str | None  # why reading stopped before the end (a damaged bag), or None

    def keep(self, mask: np.ndarray, reason: str):
        # leave out the kept messages where ``mask`` is false, for ``reason``
        if not np.all(mask):
            self.left_out.setdefault(reason, []).extend(self.positions[~mask].tolist())
            self.raw, self.logged, self.positions = self.raw[mask], self.logged[mask], self.positions[mask]
            self.stamps = None if self.stamps is None else self.stamps[mask]

    def recording(self, layout: SensorLayout, description: str) -> Recording:
        with np.errstate(over="ignore", invalid="ignore"):  # checked just below
            pascals = layout.to_pascals(self.raw)
        finite = np.all(np.isfinite(pascals), axis=1)
        if not np.all(finite):  # a copy only when there is something to leave out (a bag may be GBs)
            self.keep(finite, "beyond a float once in pascals")
            pascals = pascals[finite]
        if self.stamps is not None and np.any(self.stamps):
            set_stamps = self.stamps != 0
            if not np.all(set_stamps):
                pascals = pascals[set_stamps]
                self.keep(set_stamps, "header.stamp zero (not set) while the others are set")
        times, clock = self.clock()
        if not len(times):
            raise RecordingError(self.unusable())
        reordered = int(np.sum(np.diff(times) < 0))
        if reordered:  # frames in the order they were measured (a stable sort keeps equal stamps in order)
            clock += f", {reordered} message{'s' if reordered > 1 else ''} out of step put in stamp order"
            order = np.argsort(times, kind="stable")
            pascals, times = pascals[order], times[order]
        damage = [f"{self.where()}: {reason}" for reason in self.reasons()]
        if self.stopped:
            damage.append(f"{self.where()}: reading stopped after {self.read} messages: {self.stopped}")
        return Recording(layout.grid, pascals, (times - times[0]) * 1e-9,
                         description=f"{description}; times from {clock}", received=float(times[0]) * 1e-9,
                         truncated=self.stopped is not None, damage=tuple(damage),
                         lost_spans=self.spans(times[0]))

    def clock(self) -> tuple[np.ndarray, str]:
        """The times of the frames kept (ns, in the topic's order) and what they are."""
        if self.stamps is None:
            return self.logged, "the bag's log time (the messages have no header)"
        if not np.any(self.stamps):
            return self.logged, "the bag's log time (every header.stamp is zero: not set)"
        return self.stamps, "header.stamp"

    def where(self) -> str:
        return f"topic {self.choice.topic!r} field {self.choice.field!r}"

    def unusable(self) -> str:
        """The error when no message can be a frame: what they hold."""
        return f"{self.path}: {self.where()}: no message can be a frame: {'; '.join(self.reasons())}"

    def reasons(self) -> list[str]:
        return [f"{len(places)} of {self.read} messages left out: {reason}"
                for reason, places in self.left_out.items()]

    def spans(self, origin) -> tuple:
        """When frames are missing: from the frame kept before each run of messages left out to the one
        after, seconds from ``origin`` (ns, on the clock of the times kept)."""
        times = self.clock()[0]
        lost = np.unique(np.concatenate([np.asarray(p, dtype=np.int64) for p in self.left_out.values()]
                                        or [np.zeros(0, np.int64)]))
        if not lost.size or not len(times):
            return ()
        # a run: messages left out with no kept one between them (by their place in the topic)
        after = np.searchsorted(self.positions, lost)
        runs = np.unique(after)
        if len(runs) > _MAX_SPANS:
            runs = runs[np.linspace(0, len(runs) - 1, _MAX_SPANS).round().astype(int)]
        seconds = (times - origin) * 1e-9
        spans = []
        for run in runs:
            before = seconds[max(run - 1, 0)]
            following = seconds[min(run, len(seconds) - 1)]
            spans.append((float(min(before, following)), float(max(before, following))))
        return tuple(spans)


def _layout(layout, path: Path) -> tuple[SensorLayout, str]:
    if isinstance(layout, SensorLayout):
        return layout, "given"
    if layout is None:
        raise RecordingError(f"{path}: a ROS 2 bag needs the sensor layout file of its skin (the layout JSON "
                             "a live board uses: geometry, units, gain, offset) to turn its values into "
                             "stresses: give it (layout=; on the command line --layout FILE)")
    if not isinstance(layout, (str, os.PathLike)):
        raise ValueError(f"layout must be a SensorLayout or the path of a layout file, got {shown(layout)}")
    try:
        return load_layout(layout), Path(layout).name
    except LayoutError as exc:  # it names the layout file
        raise RecordingError(f"sensor layout {exc}") from None


def _read_frames(reader, choice: ArrayField, layout: SensorLayout, path: Path) -> _Frames:
    """Every message of the chosen topic: the ones that can be frames kept, the others counted."""
    taxels = layout.count
    connections = [c for c in reader.connections if c.topic == choice.topic]
    rows = max(sum(c.msgcount for c in connections), 1)
    raw = _grown(None, rows, taxels, path, choice)
    logged, stamps, positions = (np.zeros(rows, np.int64) for _ in range(3))
    left_out, sizes, kept, read, stopped = {}, {}, 0, 0, None
    messages = reader.messages(connections=connections)
    while True:
        try:
            item = next(messages, None)
        except Exception as exc:  # a damaged bag (rosbags raises many kinds): what was read is kept
            stopped = _reason(exc)
            break
        if item is None:
            break
        connection, log_time, data = item
        place, read = read, read + 1
        try:
            message = reader.deserialize(data, connection.msgtype)
            values = field_value(message, choice.field)
            stamp = message.header.stamp if choice.stamped else None
        except Exception:  # undecodable (rosbags raises many kinds): counted
            left_out.setdefault(f"cannot be decoded as {choice.msgtype}", []).append(place)
            continue
        if values.size != taxels:
            sizes.setdefault(values.size, []).append(place)
            continue
        if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
            left_out.setdefault("values that are not finite numbers (NaN or inf)", []).append(place)
            continue
        if kept == len(raw):
            raw = _grown(raw, 2 * kept, taxels, path, choice)
            logged, stamps, positions = (np.resize(a, 2 * kept) for a in (logged, stamps, positions))
        raw[kept] = values.ravel()
        logged[kept], positions[kept] = log_time, place
        if stamp is not None:
            stamps[kept] = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
        kept += 1
    messages.close()
    for size, places in sorted(sizes.items(), key=lambda item: -len(item[1])):
        left_out[f"{size} values, not the layout's {taxels}"] = places
    if not read:
        raise RecordingError(f"{path}: topic {choice.topic!r} holds no messages" + (
            f" that could be read ({stopped})" if stopped else ""))
    frames = _Frames(path, raw[:kept], logged[:kept], stamps[:kept] if choice.stamped else None,
                     positions[:kept], read, left_out, choice, stopped)
    if not kept:  # nothing to show: an error that says what the messages hold
        raise RecordingError(frames.unusable())
    return frames


def _grown(raw, rows: int, taxels: int, path: Path, choice: ArrayField) -> np.ndarray:
    """``raw`` with room for ``rows`` frames, or a RecordingError past MAX_RECORDING_BYTES."""
    needed = rows * taxels * 8
    if needed > MAX_RECORDING_BYTES:
        raise RecordingError(f"{path}: topic {choice.topic!r}: {rows} messages of {taxels} values would take "
                             f"{bytes_text(needed)}, more than the {bytes_text(MAX_RECORDING_BYTES)} this "
                             "viewer loads (a bag opens whole): split the bag into parts (ros2 bag convert)")
    grown = np.empty((rows, taxels))
    if raw is not None:
        grown[:len(raw)] = raw
    return grown

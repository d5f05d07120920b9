"""Which topic and field of a ROS 2 bag hold frames: the numeric array fields of its message types.

:class:`ArrayField` is one such field of one topic; :func:`candidates` finds them
all in an open :class:`rosbags.highlevel.AnyReader` (nested messages searched,
``array.data``), :func:`chosen_fields` narrows them by what the user named, and
:func:`choose` picks the one to read or raises an error that says what the bag
holds instead (a missing topic or field, a field of another type, several
candidates). :mod:`tactile_viewer.io.ros2_bag` reads the frames. No Qt.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype

from .recording import RecordingError

__all__ = ["ArrayField", "NUMERIC_TYPES", "numeric_arrays", "stamped_type", "candidates", "field_value",
           "sized", "chosen_fields", "choose", "no_arrays"]

NUMERIC_TYPES = ("float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
                 "uint64")
_MAX_NESTING = 8  # message types nested deeper than this are not searched for arrays
_LISTED = 12  # topics or fields named in an error message at most


@dataclass(frozen=True)
class ArrayField:
    """A numeric array field of a topic's messages: frames that
    :func:`~tactile_viewer.io.ros2_bag.load_ros2_bag` can read.

    Attributes
    ----------
    topic : str
    msgtype : str
        The ROS 2 message type, ``std_msgs/msg/Float32MultiArray``.
    field : str
        The field's path in the message, dot-separated in nested messages (``data``, ``array.data``).
    element : str
        The ROS type of its values (``float32``).
    count : int
        Messages on the topic.
    values : int or None
        Values in the field of the topic's first message (None: not read, or the topic has none
        that decodes).
    stamped : bool
        The message has a ``std_msgs/Header header``: times come from ``header.stamp``.
    """

    topic: str
    msgtype: str
    field: str
    element: str
    count: int
    values: int | None = None
    stamped: bool = False

    def label(self) -> str:
        """``/skin data (std_msgs/msg/Float32MultiArray: 500 messages of 256 values)``."""
        size = "" if self.values is None else f" of {self.values} values"
        return f"{self.topic} {self.field} ({self.msgtype}: {self.count} messages{size})"


def numeric_arrays(typestore, msgtype: str, prefix: str = "", depth: int = 0) -> list[tuple[str, str]]:
    """``(path, element type)`` of each numeric array field of ``msgtype``, nested messages searched."""
    found = []
    for name, (kind, detail) in typestore.fielddefs[msgtype][1]:
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (element_kind, element), _length = detail
            if element_kind == Nodetype.BASE and element[0] in NUMERIC_TYPES:
                found.append((prefix + name, element[0]))
        elif kind == Nodetype.NAME and depth < _MAX_NESTING and detail in typestore.fielddefs:
            found += numeric_arrays(typestore, detail, f"{prefix}{name}.", depth + 1)
    return found


def stamped_type(typestore, msgtype: str) -> bool:
    """Whether ``msgtype`` has a ``std_msgs/Header header`` (its stamps are the frames' times)."""
    fields = dict(typestore.fielddefs[msgtype][1])
    return fields.get("header") == (Nodetype.NAME, "std_msgs/msg/Header")


def candidates(reader) -> list[ArrayField]:
    """Every numeric array field of every topic of an open AnyReader, in topic order (sizes not read)."""
    fields = []
    for topic, info in sorted(reader.topics.items()):
        if info.msgtype is None or info.msgtype not in reader.typestore.fielddefs:
            continue  # several types on one topic, or one the bag and its distribution do not define
        stamped = stamped_type(reader.typestore, info.msgtype)
        fields += [ArrayField(topic, info.msgtype, name, element, info.msgcount, stamped=stamped)
                   for name, element in numeric_arrays(reader.typestore, info.msgtype)]
    return fields


def field_value(message, field: str) -> np.ndarray:
    """The values of ``field`` (dot-separated) of a decoded message."""
    for name in field.split("."):
        message = getattr(message, name)
    return np.asarray(message)


def sized(reader, fields: list[ArrayField]) -> list[ArrayField]:
    """``fields`` with :attr:`ArrayField.values` read from the first message of each topic (once a topic)."""
    sizes = {}
    for topic in dict.fromkeys(f.topic for f in fields):
        messages = reader.messages(connections=[c for c in reader.connections if c.topic == topic])
        try:
            first = next(messages, None)
            sizes[topic] = None if first is None else reader.deserialize(first[2], first[0].msgtype)
        except Exception:  # an undecodable first message (rosbags raises many kinds): size unknown
            sizes[topic] = None
        finally:
            messages.close()

    def size(f):
        try:
            return None if sizes[f.topic] is None else int(field_value(sizes[f.topic], f.field).size)
        except AttributeError:
            return None
    return [replace(f, values=size(f)) for f in fields]


def _listed(items: list[str]) -> str:
    more = len(items) - _LISTED
    return ", ".join(items[:_LISTED]) + (f" and {more} more" if more > 0 else "")


def no_arrays(reader, path: Path) -> str:
    """The error of a bag none of whose topics has a numeric array field: what its topics are."""
    return (f"{path}: no topic whose messages hold an array of numbers (such as "
            f"std_msgs/msg/Float32MultiArray); the bag's topics: {_topics_text(reader)}")


def _topics_text(reader) -> str:
    return _listed([f"{topic} ({info.msgtype or 'several types'})"
                    for topic, info in sorted(reader.topics.items())]) or "none"


def _type_text(kind, detail) -> str:
    if kind == Nodetype.BASE:
        return detail[0]
    if kind == Nodetype.NAME:
        return detail
    (element_kind, element), length = detail
    inner = element[0] if element_kind == Nodetype.BASE else element
    return f"{inner}[{length if kind == Nodetype.ARRAY else ''}]"


def _fields_text(typestore, msgtype: str) -> str:
    return _listed([f"{name} ({_type_text(*node)})" for name, node in typestore.fielddefs[msgtype][1]])


def _field_problem(typestore, msgtype: str, field: str, topic: str) -> str:
    # why ``field`` of ``msgtype`` is no numeric array: missing, or of another type
    named = f"field {field!r} of topic {topic!r} ({msgtype})"
    where, kind, detail = msgtype, Nodetype.NAME, msgtype
    for name in field.split("."):
        if kind != Nodetype.NAME:
            return f"{named} goes inside a {_type_text(kind, detail)}, which has no fields"
        fields = dict(typestore.fielddefs[where][1]) if where in typestore.fielddefs else {}
        if name not in fields:
            return (f"topic {topic!r} ({msgtype}) has no field {field!r}; the fields of {where}: "
                    f"{_fields_text(typestore, where) if fields else 'not defined'}")
        kind, detail = fields[name]
        where = detail if kind == Nodetype.NAME else where
    if kind == Nodetype.NAME and where in typestore.fielddefs:
        return (f"{named} is a message ({detail}), not an array of numbers; its fields: "
                f"{_fields_text(typestore, detail)}")
    return f"{named} is {_type_text(kind, detail)}, not an array of numbers"


def chosen_fields(fields, *, topic=None, field=None, taxels=None) -> list[ArrayField]:
    """The fields of ``fields`` that ``topic`` and ``field`` (None: any) leave; one is a choice.

    When more than one is left and ``taxels`` is given, those whose first message holds
    ``taxels`` values, if that leaves exactly one.
    """
    left = [f for f in fields if (topic is None or f.topic == topic) and (field is None or f.field == field)]
    sized = [f for f in left if taxels is not None and f.values == taxels]
    return sized if len(left) > 1 and len(sized) == 1 else left


def choose(reader, path: Path, topic, field, taxels: int) -> ArrayField:
    """The one field to read: ``topic`` and ``field`` (None: any), then the layout's ``taxels`` decide.

    Raises
    ------
    RecordingError
        Naming the bag and what it holds instead: no such topic, a topic whose type cannot be
        decoded or has no numeric array, a field that is missing or no numeric array, no
        candidate at all, or several left.
    """
    fields = candidates(reader)
    topics = reader.topics
    if topic is not None and topic not in topics:
        raise RecordingError(f"{path}: no topic {topic!r}; the bag's topics: {_topics_text(reader)}")
    if topic is not None and not any(f.topic == topic for f in fields):
        msgtype = topics[topic].msgtype
        if msgtype is None:
            types = sorted({c.msgtype for c in topics[topic].connections})
            raise RecordingError(f"{path}: topic {topic!r} carries several message types "
                                 f"({', '.join(types)})")
        if msgtype not in reader.typestore.fielddefs:
            raise RecordingError(f"{path}: topic {topic!r} has type {msgtype!r}, which neither the bag nor "
                                 "its ROS 2 distribution defines: its messages cannot be decoded")
        if field is None:
            raise RecordingError(f"{path}: topic {topic!r} ({msgtype}) has no field that is an array of "
                                 f"numbers; its fields: {_fields_text(reader.typestore, msgtype)}")
    left = chosen_fields(fields, topic=topic, field=field)
    if not left:
        if topic is not None:
            problem = _field_problem(reader.typestore, topics[topic].msgtype, field, topic)
            raise RecordingError(f"{path}: {problem}")
        if field is not None:
            raise RecordingError(f"{path}: no topic has a numeric array field {field!r}; the numeric array "
                                 f"fields: {_listed([f'{f.topic} {f.field}' for f in fields]) or 'none'}")
        raise RecordingError(no_arrays(reader, path))
    if len(left) > 1:
        left = chosen_fields(sized(reader, left), taxels=taxels)
    if len(left) > 1:
        raise RecordingError(f"{path}: {len(left)} topic fields hold arrays of numbers and not exactly one "
                             f"holds the layout's {taxels} values: choose one (topic and field; on the "
                             f"command line --topic and --field): {_listed([f.label() for f in left])}")
    return left[0]

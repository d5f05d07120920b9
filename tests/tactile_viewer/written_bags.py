"""ROS 2 bags written by rosbags' own writer for the bag tests: a skin's frames as the lab's topics carry them.

Three message types: ``std_msgs/msg/Float32MultiArray`` and ``Float64MultiArray``
(no header: times are the bag's log times) and a lab's own stamped message
(:data:`SKIN_TYPE`: a header, a label and the pressures), whose definition only
the bag holds.
"""

import sqlite3

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from solver import SensorGrid
from tactile_viewer.io.layout import SensorLayout, save_layout

SKIN_TYPE = "lab_msgs/msg/SkinFrame"
SKIN_DEFINITION = "std_msgs/Header header\nstring label\nfloat32[] pressures\nuint32 count\n"
NESTED_TYPE = "lab_msgs/msg/NestedFrame"
NESTED_DEFINITION = "std_msgs/Header header\nstd_msgs/Float64MultiArray array\n"
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
T0_NS = 1_700_000_000_000_000_000  # the first log time: 2023-11-14, in UNIX nanoseconds
PERIOD_NS = 10_000_000  # 100 Hz


def typestore():
    """ROS 2 Humble's types with the lab's own messages registered."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(SKIN_DEFINITION, SKIN_TYPE))
    store.register(get_types_from_msg(NESTED_DEFINITION, NESTED_TYPE))
    return store


STORE = typestore()


def layout_file(folder, *, nx=3, ny=2, units="kPa", gain=2.0, offset=0.5):
    """A layout JSON of an ``nx`` by ``ny`` skin whose values are ``gain * (raw - offset)`` kPa."""
    layout = SensorLayout(SensorGrid.regular(nx, ny, 2e-3, 1.5e-3), units, gain, offset)
    return save_layout(layout, folder / "skin_layout.json"), layout


def skin_frames(count, taxels=6, seed=3):
    """``(count, taxels)`` raw values as a board sends them (float32)."""
    return np.random.default_rng(seed).normal(5.0, 2.0, size=(count, taxels)).astype(np.float32)  # fixed seed


def multiarray(values, kind="std_msgs/msg/Float32MultiArray"):
    cls = STORE.types[kind]
    layout = STORE.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    dtype = np.float32 if kind.endswith("Float32MultiArray") else np.float64
    return cls(layout=layout, data=np.asarray(values, dtype=dtype))


def header(stamp_ns, frame_id="skin"):
    time = STORE.types["builtin_interfaces/msg/Time"](sec=stamp_ns // 1_000_000_000,
                                                    nanosec=stamp_ns % 1_000_000_000)
    return STORE.types["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


def skin_message(values, stamp_ns, count=0):
    return STORE.types[SKIN_TYPE](header=header(stamp_ns), label="left palm",
                                  pressures=np.asarray(values, dtype=np.float32), count=count)


def nested_message(values, stamp_ns):
    return STORE.types[NESTED_TYPE](header=header(stamp_ns),
                                    array=multiarray(values, "std_msgs/msg/Float64MultiArray"))


def write_bag(path, messages, *, storage="mcap", topics=()):
    """Write ``messages`` ``(topic, msgtype, log time ns, message)`` as a bag folder at ``path``.

    ``topics``: more ``(topic, msgtype)`` connections, with no messages. Returns ``path``.
    """
    connections = {}
    with Writer(path, version=9, storage_plugin=STORAGES[storage]) as writer:
        for topic, msgtype in [*((m[0], m[1]) for m in messages), *topics]:
            if (topic, msgtype) not in connections:
                connections[topic, msgtype] = writer.add_connection(topic, msgtype, typestore=STORE)
        for topic, msgtype, log_ns, message in messages:
            writer.write(connections[topic, msgtype], log_ns, STORE.serialize_cdr(message, msgtype))
    return path


def frames_bag(path, frames, *, storage="mcap", kind="std_msgs/msg/Float32MultiArray", topic="/skin/pressure",
               stamps=None):
    """A bag of one topic whose messages hold ``frames``, logged at 100 Hz from :data:`T0_NS`.

    ``kind``: a multiarray type, :data:`SKIN_TYPE` or :data:`NESTED_TYPE` (these two stamped
    with ``stamps``, ns). Returns the bag folder and the log times.
    """
    logged = T0_NS + PERIOD_NS * np.arange(len(frames), dtype=np.int64)
    messages = []
    for k, values in enumerate(frames):
        if kind == SKIN_TYPE:
            message = skin_message(values, int(stamps[k]), count=k)
        elif kind == NESTED_TYPE:
            message = nested_message(values, int(stamps[k]))
        else:
            message = multiarray(values, kind)
        messages.append((topic, kind, int(logged[k]), message))
    return write_bag(path, messages, storage=storage), logged


def storage_file(bag):
    """The one storage file of a bag folder (a bare ``.mcap`` or ``.db3``)."""
    (found,) = [p for p in bag.iterdir() if p.suffix in (".mcap", ".db3")]
    return found


def without_definitions(db3, distro="humble"):
    """Strip the message definitions from a bare ``.db3`` (as bags before ROS 2 Iron were) and name its
    distribution: rosbags must then take the types from ``distro``."""
    with sqlite3.connect(db3) as connection:
        connection.execute("DELETE FROM message_definitions")
        connection.execute("UPDATE schema SET ros_distro = ?", (distro,))
    return db3

"""The frame messages of our recordings (tactile_viewer/io/ros2_message.py): byte for byte what ROS 2's CDR
serializer (rosbags) writes for our schema, whatever the frame_id and dtype; fields where the layout says;
arguments checked."""

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tactile_viewer.io.ros2_message import FRAME_ID, MESSAGE_TYPES, SCHEMAS, VALUES_FIELD, FrameMessage


def rosbags_types():
    """A rosbags type store that knows our message types from their schema text alone."""
    store = get_typestore(Stores.EMPTY)
    for dtype, schema in SCHEMAS.items():
        # a ros2msg schema in MCAP: the type itself, then each dependency after a line of "=" and "MSG: name"
        main, *dependencies = schema.split("=" * 80)
        types = get_types_from_msg(main, MESSAGE_TYPES[dtype])
        for text in dependencies:
            first, rest = text.strip().split("\n", 1)
            name = first.removeprefix("MSG: ").replace("/", "/msg/")
            types.update(get_types_from_msg(rest, name))
        store.register(types)
    return store


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("frame_id", ["", "a", FRAME_ID, "seven77", "eight888", "left_hand/palm_skin_01"])
@pytest.mark.parametrize("taxels", [1, 3, 256])
def test_a_frame_message_is_what_rosbags_serializes(dtype, frame_id, taxels):
    # every length of frame_id moves the padding before the sequence, and float64 values pad after
    # their count: the layout must match the CDR serializer in each case
    store = rosbags_types()
    kind = store.types[MESSAGE_TYPES[dtype]]
    rng = np.random.default_rng(taxels)  # fixed seed
    values = rng.normal(1e3, 300, taxels).astype(dtype)
    stamp, sequence = 1_700_000_000_123_456_789, 2**40 + 7
    reference = kind(header=store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=1_700_000_000, nanosec=123_456_789),
        frame_id=frame_id), sequence=sequence, **{VALUES_FIELD: values})
    message = FrameMessage.ros2(taxels, dtype, frame_id)
    data = message.encode(sequence, stamp, values)
    assert data == bytes(store.serialize_cdr(reference, MESSAGE_TYPES[dtype]))
    assert len(data) == message.size and message.type_name == MESSAGE_TYPES[dtype]
    # the fields lie where the layout says, and the bytes it calls fixed are those of any frame
    np.testing.assert_array_equal(np.frombuffer(data, dtype, taxels, message.values_at), values)
    assert int(np.frombuffer(data, "<u8", 1, message.sequence_at)[0]) == sequence
    np.testing.assert_array_equal(np.frombuffer(data, np.uint8)[message.fixed_at], message.fixed)
    other = message.encode(3, 5, values[::-1].copy())
    np.testing.assert_array_equal(np.frombuffer(other, np.uint8)[message.fixed_at], message.fixed)
    decoded = store.deserialize_cdr(data, MESSAGE_TYPES[dtype])
    assert decoded.header.frame_id == frame_id and decoded.sequence == sequence


def test_a_stamp_past_2038_is_written_as_ros_2_wraps_it():
    # ROS 2's seconds are int32: a receive time past 2038 must not end a recording
    message = FrameMessage.ros2(2, "float32")
    stamp = 2**31 * 10**9 + 42
    decoded = rosbags_types().deserialize_cdr(message.encode(1, stamp, np.zeros(2, np.float32)),
                                              MESSAGE_TYPES["float32"])
    assert decoded.header.stamp.sec == -(2**31) and decoded.header.stamp.nanosec == 42


def test_the_legacy_message_is_the_raw_values_alone():
    message = FrameMessage.legacy(6, "float64")
    assert (message.size, message.values_at, message.sequence_at, message.fixed.size) == (48, 0, None, 0)


@pytest.mark.parametrize(("arguments", "error"), [
    ((0, "float32"), r"taxels must be a whole number >= 1, got 0"),
    ((2.5, "float32"), r"taxels must be a whole number >= 1, got 2\.5"),
    ((6, "int16"), r"dtype must be one of \('float32', 'float64'\), got 'int16'"),
    ((6, "float32", "skin\u00e9"), r"frame_id must be printable ASCII of at most 255 characters, got 'skin\u00e9'"),
    ((6, "float32", "a\nb"), r"frame_id must be printable ASCII of at most 255 characters, got 'a\\nb'"),
    ((6, "float32", "x" * 256), r"frame_id must be printable ASCII of at most 255 characters, got 'xxx"),
])
def test_frame_message_arguments_are_checked(arguments, error):
    with pytest.raises(ValueError, match=error):
        FrameMessage.ros2(*arguments)


def test_the_legacy_message_arguments_are_checked():
    with pytest.raises(ValueError, match=r"dtype must be one of \('float32', 'float64'\), got 'float16'"):
        FrameMessage.legacy(6, "float16")

"""ROS 2 bags written by rosbags (both storage plugins) opened as recordings: values, stamps, rejections, errors."""

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from tactile_viewer.io import ros2_bag
from tactile_viewer.io.files import is_recording_path, load
from tactile_viewer.io.layout import load_layout
from tactile_viewer.io.mcap_writer import Recorder
from tactile_viewer.io.recording import RecordingError
from tactile_viewer.io.ros2_bag import bag_location, is_ros2_bag, load_ros2_bag
from tests.tactile_viewer.skins import grid32
from tests.tactile_viewer.written_bags import (
    NESTED_TYPE,
    PERIOD_NS,
    SKIN_TYPE,
    T0_NS,
    frames_bag,
    layout_file,
    multiarray,
    skin_frames,
    skin_message,
    storage_file,
    without_definitions,
    write_bag,
)

F32, F64 = "std_msgs/msg/Float32MultiArray", "std_msgs/msg/Float64MultiArray"


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("kind", [F32, F64, SKIN_TYPE, NESTED_TYPE])
@pytest.mark.parametrize("opened", ["folder", "metadata.yaml", "bare file"])
def test_a_bag_opens_with_the_values_and_stamps_written(tmp_path, storage, kind, opened):
    frames = skin_frames(12)
    # header stamps a little before the log times, one of them out of step: the stamps are the times
    stamps = T0_NS - 2_500_000 + PERIOD_NS * np.arange(12, dtype=np.int64) + np.arange(12) * 37
    bag, logged = frames_bag(tmp_path / "bag", frames, storage=storage, kind=kind, stamps=stamps)
    layout_path, layout = layout_file(tmp_path)
    path = {"folder": bag, "metadata.yaml": bag / "metadata.yaml", "bare file": storage_file(bag)}[opened]
    assert is_ros2_bag(path) and is_recording_path(path)
    recording = load(path, layout=layout_path)
    # gain 2 (raw - 0.5) kPa: the layout's calibration applied to the values as sent
    np.testing.assert_array_equal(recording.frames, layout.to_pascals(frames.astype(np.float64)))
    times = stamps if kind in (SKIN_TYPE, NESTED_TYPE) else logged
    np.testing.assert_allclose(recording.t, (times - times[0]) * 1e-9, rtol=0, atol=1e-12)
    assert recording.received == pytest.approx(times[0] * 1e-9, abs=1e-6)
    assert recording.grid.shape == (2, 3) and recording.damage == () and not recording.truncated
    clock = "header.stamp" if kind in (SKIN_TYPE, NESTED_TYPE) else "the bag's log time (the messages have no header)"
    field = "array.data" if kind == NESTED_TYPE else "pressures" if kind == SKIN_TYPE else "data"
    assert recording.description == (f"ROS 2 bag {bag_location(path).name}, topic /skin/pressure, field {field} "
                                     f"({kind}), layout skin_layout.json; times from {clock}")


def test_the_frames_equal_what_mcap_ros2_decodes_from_the_same_file(tmp_path):
    # the other side's own decoder (mcap-ros2-support), not rosbags, reads the bag's messages
    frames = skin_frames(20, seed=11)  # fixed seed
    stamps = T0_NS + PERIOD_NS * np.arange(20, dtype=np.int64)
    bag, _ = frames_bag(tmp_path / "bag", frames, kind=SKIN_TYPE, stamps=stamps)
    layout_path, layout = layout_file(tmp_path)
    recording = load_ros2_bag(storage_file(bag), layout=layout_path)
    with open(storage_file(bag), "rb") as handle:
        decoded = [(message.header.stamp.sec * 10**9 + message.header.stamp.nanosec, message.pressures)
                   for _schema, _channel, _message, message in
                   make_reader(handle, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert len(decoded) == len(recording) == 20
    np.testing.assert_array_equal(recording.frames, layout.to_pascals(np.array([v for _, v in decoded])))
    np.testing.assert_allclose(recording.t, [(s - decoded[0][0]) * 1e-9 for s, _ in decoded], atol=1e-12)


def test_integer_counts_become_pascals_through_the_layout_gain(tmp_path):
    # a board's ADC counts as uint16[]: pascals per count from the layout
    write_bag(tmp_path / "counts", [("/adc", "std_msgs/msg/UInt16MultiArray", T0_NS + k,
                                     _uint16([100 * k + j for j in range(6)])) for k in range(3)])
    layout_path, layout = layout_file(tmp_path, units="counts", gain=0.25, offset=10)
    recording = load_ros2_bag(tmp_path / "counts", layout=layout_path)
    np.testing.assert_array_equal(recording.frames[2], 0.25 * (np.arange(200, 206) - 10))


def _uint16(values):
    from tests.tactile_viewer.written_bags import STORE

    kind = STORE.types["std_msgs/msg/UInt16MultiArray"]
    return kind(layout=STORE.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                data=np.asarray(values, dtype=np.uint16))


def test_our_own_recordings_are_not_taken_for_bags(tmp_path):
    path = tmp_path / "ours.mcap"
    recorder = Recorder(path, grid32())
    for k in range(5):
        recorder.add(k, k / 100, np.full(6, 100.0 + k))
    recorder.close()
    assert not is_ros2_bag(path)
    np.testing.assert_array_equal(load(path).frames[:, 0], 100.0 + np.arange(5))
    # cut inside its header, it is still ours: our reader says what is wrong
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:20])
    assert not is_ros2_bag(cut)
    with pytest.raises(RecordingError, match="cut.mcap: no frames"):
        load(cut)
    with pytest.raises(RecordingError, match=r"ours.mcap: not a ROS 2 bag: a layout, topic and field are for bags"):
        load(path, layout=tmp_path / "any.json")


def test_single_bad_messages_are_left_out_counted_and_shaded(tmp_path):
    frames = skin_frames(10).astype(np.float64)
    frames[2, 1] = np.nan
    frames[6, 0] = np.inf
    messages = [("/skin", F64, T0_NS + PERIOD_NS * k, multiarray(values, F64)) for k, values in enumerate(frames)]
    messages[4] = ("/skin", F64, T0_NS + PERIOD_NS * 4, multiarray(np.ones(5), F64))  # a short frame
    messages[5] = ("/skin", F64, T0_NS + PERIOD_NS * 5, multiarray(np.ones(7), F64))  # a long one
    layout_path, layout = layout_file(tmp_path)
    recording = load_ros2_bag(write_bag(tmp_path / "bag", messages), layout=layout_path)
    kept = [0, 1, 3, 7, 8, 9]
    np.testing.assert_array_equal(recording.frames, layout.to_pascals(frames[kept]))
    np.testing.assert_allclose(recording.t, np.array(kept) * PERIOD_NS * 1e-9, atol=1e-12)
    assert recording.damage == (
        "topic '/skin' field 'data': 2 of 10 messages left out: values that are not finite numbers (NaN or inf)",
        "topic '/skin' field 'data': 1 of 10 messages left out: 5 values, not the layout's 6",
        "topic '/skin' field 'data': 1 of 10 messages left out: 7 values, not the layout's 6")
    # the gaps in time between the frames kept around each run of messages left out
    np.testing.assert_allclose(recording.lost_spans, [(0.01, 0.03), (0.03, 0.07)], atol=1e-12)


def test_values_beyond_a_float_in_pascals_are_left_out(tmp_path):
    frames = skin_frames(3).astype(np.float64)
    frames[1, 3] = 1e306  # finite as sent, beyond a float once times 2e3 (kPa and the gain)
    bag, _ = frames_bag(tmp_path / "bag", frames, kind=F64)
    recording = load_ros2_bag(bag, layout=layout_file(tmp_path)[0])
    assert len(recording) == 2 and recording.damage == (
        "topic '/skin/pressure' field 'data': 1 of 3 messages left out: beyond a float once in pascals",)


def test_stamps_that_were_never_set_fall_back_to_the_log_time(tmp_path):
    frames = skin_frames(4)
    bag, logged = frames_bag(tmp_path / "unset", frames, kind=SKIN_TYPE, stamps=np.zeros(4, np.int64))
    recording = load_ros2_bag(bag, layout=layout_file(tmp_path)[0])
    np.testing.assert_allclose(recording.t, (logged - logged[0]) * 1e-9, atol=1e-12)
    assert recording.description.endswith("times from the bag's log time (every header.stamp is zero: not set)")
    # one stamp unset among set ones: that message is left out
    stamps = T0_NS + PERIOD_NS * np.arange(4, dtype=np.int64)
    stamps[2] = 0
    bag, _ = frames_bag(tmp_path / "one", frames, kind=SKIN_TYPE, stamps=stamps)
    recording = load_ros2_bag(bag, layout=layout_file(tmp_path)[0])
    assert len(recording) == 3 and recording.damage == (
        "topic '/skin/pressure' field 'pressures': 1 of 4 messages left out: header.stamp zero (not set) while "
        "the others are set",)


def test_messages_stamped_out_of_order_are_put_in_stamp_order(tmp_path):
    frames = skin_frames(4)
    stamps = T0_NS + np.array([0, 20, 10, 30], dtype=np.int64) * 1_000_000  # the third measured before the second
    bag, _ = frames_bag(tmp_path / "bag", frames, kind=SKIN_TYPE, stamps=stamps)
    layout_path, layout = layout_file(tmp_path)
    recording = load_ros2_bag(bag, layout=layout_path)
    np.testing.assert_allclose(recording.t, [0, 0.01, 0.02, 0.03], atol=1e-12)
    np.testing.assert_array_equal(recording.frames, layout.to_pascals(frames[[0, 2, 1, 3]].astype(float)))
    assert recording.description.endswith("times from header.stamp, 1 message out of step put in stamp order")


def test_a_bag_without_message_definitions_takes_its_distributions_types(tmp_path):
    bag, _ = frames_bag(tmp_path / "old", skin_frames(3), storage="sqlite3", kind=F64)
    db3 = without_definitions(storage_file(bag))
    np.testing.assert_array_equal(load_ros2_bag(db3, layout=layout_file(tmp_path)[0]).t, [0, 0.01, 0.02])
    custom, _ = frames_bag(tmp_path / "custom", skin_frames(3), storage="sqlite3", kind=SKIN_TYPE,
                           stamps=T0_NS + np.arange(3))
    db3 = without_definitions(storage_file(custom))
    with pytest.raises(RecordingError, match=r"topic '/skin/pressure' has type 'lab_msgs/msg/SkinFrame', which "
                                             r"neither the bag nor its ROS 2 distribution defines"):
        load_ros2_bag(db3, layout=layout_file(tmp_path)[0], topic="/skin/pressure")


# -- errors ----------------------------------------------------------------------------------------------


def test_every_message_of_the_wrong_size_is_an_error_that_says_what_they_hold(tmp_path):
    bag, _ = frames_bag(tmp_path / "bag", skin_frames(4, taxels=5))
    with pytest.raises(RecordingError, match=r"bag: topic '/skin/pressure' field 'data': no message can be a "
                                             r"frame: 4 of 4 messages left out: 5 values, not the layout's 6$"):
        load_ros2_bag(bag, layout=layout_file(tmp_path)[0])


def test_an_empty_topic_is_an_error(tmp_path):
    bag = write_bag(tmp_path / "bag", [("/other", F32, T0_NS, multiarray(np.ones(3)))], topics=[("/skin", F64)])
    with pytest.raises(RecordingError, match=r"bag: topic '/skin' holds no messages"):
        load_ros2_bag(bag, layout=layout_file(tmp_path)[0], topic="/skin")


def test_a_bag_needs_its_layout(tmp_path):
    bag, _ = frames_bag(tmp_path / "bag", skin_frames(2))
    with pytest.raises(RecordingError, match=r"bag: a ROS 2 bag needs the sensor layout file of its skin"):
        load(bag)
    (tmp_path / "broken.json").write_text('{"nx": 3}')
    with pytest.raises(RecordingError, match=r"sensor layout .*broken.json: missing 'ny', 'pitch', 'thickness'"):
        load(bag, layout=tmp_path / "broken.json")
    with pytest.raises(ValueError, match=r"layout must be a SensorLayout or the path of a layout file, got 3"):
        load_ros2_bag(bag, layout=3)
    # a layout object works as its file does
    assert len(load_ros2_bag(bag, layout=load_layout(layout_file(tmp_path)[0]))) == 2


@pytest.mark.parametrize("name, value", [("topic", 5), ("topic", ""), ("field", b"data")])
def test_topic_and_field_must_be_names(tmp_path, name, value):
    with pytest.raises(ValueError, match=rf"{name} must be a non-empty name \(text\) or None, got {value!r}"):
        load_ros2_bag(tmp_path, layout=None, **{name: value})


@pytest.mark.parametrize("content, what", [(b"SQLite format 3\x00" + b"\x07" * 200, "a damaged .db3"),
                                           (b"not a database at all", "text")])
def test_an_unreadable_bag_names_the_file(tmp_path, content, what):
    path = tmp_path / "broken.db3"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match=r"broken.db3: not a readable ROS 2 bag \("):
        load(path, layout=layout_file(tmp_path)[0])


def test_a_foreign_mcap_that_is_no_bag_names_the_file(tmp_path):
    bag, _ = frames_bag(tmp_path / "bag", skin_frames(2))
    data = bytearray(storage_file(bag).read_bytes())
    garbled = tmp_path / "garbled.mcap"
    garbled.write_bytes(bytes(data[:60]) + b"\xff" * 40)  # a foreign header, then nothing MCAP
    assert is_ros2_bag(garbled)
    with pytest.raises(RecordingError, match=r"garbled.mcap: not a readable ROS 2 bag \("):
        load(garbled, layout=layout_file(tmp_path)[0])


def test_a_folder_that_is_no_bag_says_so(tmp_path):
    (tmp_path / "run").mkdir()
    assert not is_ros2_bag(tmp_path / "run") and not is_recording_path(tmp_path / "run")
    with pytest.raises(RecordingError, match=r"run: a folder, and no ROS 2 bag \(it holds no metadata.yaml\)"):
        load(tmp_path / "run")


def test_frames_beyond_the_memory_bound_are_refused_before_they_are_read(tmp_path, monkeypatch):
    bag, _ = frames_bag(tmp_path / "bag", skin_frames(10))
    monkeypatch.setattr(ros2_bag, "MAX_RECORDING_BYTES", 10 * 6 * 8 - 1)  # one byte short of 10 frames
    with pytest.raises(RecordingError, match=r"topic '/skin/pressure': 10 messages of 6 values would take 480 B, "
                                             r"more than the 479 B this viewer loads \(a bag opens whole\)"):
        load_ros2_bag(bag, layout=layout_file(tmp_path)[0])


def test_a_bag_whose_index_counts_fewer_messages_still_reads_them_all(tmp_path, monkeypatch):
    # the count a bag declares only sizes the first allocation: more messages grow it, within the bound
    bag, _ = frames_bag(tmp_path / "bag", skin_frames(9))
    real = ros2_bag._read_frames

    def undercounted(reader, choice, layout, path):
        reader.connections[:] = [c._replace(msgcount=2) for c in reader.connections]
        return real(reader, choice, layout, path)
    monkeypatch.setattr(ros2_bag, "_read_frames", undercounted)
    layout_path, layout = layout_file(tmp_path)
    np.testing.assert_array_equal(load_ros2_bag(bag, layout=layout_path).frames,
                                  layout.to_pascals(skin_frames(9).astype(float)))
    monkeypatch.setattr(ros2_bag, "MAX_RECORDING_BYTES", 5 * 6 * 8)  # room for 5 frames, not the 8 it grows to
    with pytest.raises(RecordingError, match=r"8 messages of 6 values would take 384 B"):
        load_ros2_bag(bag, layout=layout_path)


def test_an_undecodable_message_is_left_out(tmp_path):
    frames = skin_frames(3)
    messages = [("/skin", SKIN_TYPE, T0_NS + k, skin_message(v, T0_NS + k)) for k, v in enumerate(frames)]
    bag = write_bag(tmp_path / "bag", messages, storage="sqlite3")
    import sqlite3

    with sqlite3.connect(storage_file(bag)) as db:  # the second message cut to 10 bytes
        db.execute("UPDATE messages SET data = substr(data, 1, 10) WHERE id = 2")
    recording = load_ros2_bag(bag, layout=layout_file(tmp_path)[0])
    assert len(recording) == 2 and recording.damage == (
        f"topic '/skin' field 'pressures': 1 of 3 messages left out: cannot be decoded as {SKIN_TYPE}",)


def test_a_bag_that_fails_while_it_is_read_keeps_the_frames_before_and_says_so(tmp_path, monkeypatch):
    # a damaged chunk: rosbags raises in the middle of the messages (injected after the third)
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import ReaderError

    bag, _ = frames_bag(tmp_path / "bag", skin_frames(6))
    layout_path, layout = layout_file(tmp_path)
    real = AnyReader.messages

    def failing_after(count):
        def messages(self, connections=(), start=None, stop=None):
            for k, item in enumerate(real(self, connections, start, stop)):
                if k == count:
                    raise ReaderError("chunk at byte 4242 is damaged")
                yield item
        return messages
    monkeypatch.setattr(AnyReader, "messages", failing_after(3))
    recording = load_ros2_bag(bag, layout=layout_path)
    np.testing.assert_array_equal(recording.frames, layout.to_pascals(skin_frames(6)[:3].astype(float)))
    assert recording.truncated and recording.damage == (
        "topic '/skin/pressure' field 'data': reading stopped after 3 messages: ReaderError: chunk at byte 4242 "
        "is damaged",)
    monkeypatch.setattr(AnyReader, "messages", failing_after(0))
    with pytest.raises(RecordingError, match=r"bag: topic '/skin/pressure' holds no messages that could be read "
                                             r"\(ReaderError: chunk at byte 4242 is damaged\)"):
        load_ros2_bag(bag, layout=layout_path, topic="/skin/pressure")

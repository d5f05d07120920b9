"""Choosing a ROS 2 bag's topic and field: what array_topics lists, what is chosen, and every refusal."""

import numpy as np
import pytest

from tactile_viewer.io.bag_topics import ArrayField, chosen_fields
from tactile_viewer.io.recording import RecordingError
from tactile_viewer.io.ros2_bag import array_topics, load_ros2_bag
from tests.tactile_viewer.written_bags import (
    NESTED_TYPE,
    SKIN_TYPE,
    STORE,
    T0_NS,
    layout_file,
    multiarray,
    nested_message,
    skin_frames,
    skin_message,
    write_bag,
)

F32, F64 = "std_msgs/msg/Float32MultiArray", "std_msgs/msg/Float64MultiArray"


def _string(text):
    return STORE.types["std_msgs/msg/String"](data=text)


@pytest.fixture
def lab_bag(tmp_path):
    """A robot's bag: the skin (6 values, stamped), a 4-value force sensor, a nested array, log text."""
    frames = skin_frames(3)
    messages = []
    for k in range(3):
        log = T0_NS + 10_000_000 * k
        messages += [("/skin", SKIN_TYPE, log, skin_message(frames[k], log)),
                     ("/wrist/force", F64, log, multiarray(np.arange(4.0) + k, F64)),
                     ("/nested", NESTED_TYPE, log, nested_message(np.ones(3), log)),
                     ("/log", "std_msgs/msg/String", log, _string(f"step {k}"))]
    return write_bag(tmp_path / "lab", messages, topics=[("/idle", F32)])


def test_array_topics_lists_every_numeric_array_field_with_its_size(lab_bag):
    assert array_topics(lab_bag) == [
        ArrayField("/idle", F32, "data", "float32", 0, None, False),
        ArrayField("/nested", NESTED_TYPE, "array.data", "float64", 3, 3, True),
        ArrayField("/skin", SKIN_TYPE, "pressures", "float32", 3, 6, True),
        ArrayField("/wrist/force", F64, "data", "float64", 3, 4, False)]
    assert array_topics(lab_bag)[2].label() == "/skin pressures (lab_msgs/msg/SkinFrame: 3 messages of 6 values)"


def test_the_layouts_size_picks_the_one_topic_that_fits(lab_bag, tmp_path):
    # several topics hold numbers, one holds the layout's 6 values: it is the skin
    recording = load_ros2_bag(lab_bag, layout=layout_file(tmp_path)[0])
    assert len(recording) == 3 and "topic /skin, field pressures" in recording.description
    fields = array_topics(lab_bag)
    assert chosen_fields(fields, taxels=6) == [fields[2]]
    assert chosen_fields(fields, topic="/wrist/force", taxels=6) == [fields[3]]
    assert chosen_fields(fields, taxels=5) == fields  # none fits: all are left to choose from


def test_a_field_is_found_by_its_path_in_nested_messages(lab_bag, tmp_path):
    recording = load_ros2_bag(lab_bag, layout=layout_file(tmp_path, nx=3, ny=1)[0], topic="/nested",
                              field="array.data")
    assert recording.frames.shape == (3, 3)


def test_when_no_single_topic_fits_the_choice_is_asked_for(lab_bag, tmp_path):
    with pytest.raises(RecordingError, match=r"lab: 4 topic fields hold arrays of numbers and not exactly one holds "
                                             r"the layout's 2 values: choose one \(topic and field; on the command "
                                             r"line --topic and --field\): /idle data \(std_msgs/msg/Float32Multi"
                                             r"Array: 0 messages\), /nested array.data \(lab_msgs/msg/NestedFrame: 3 "
                                             r"messages of 3 values\), /skin pressures"):
        load_ros2_bag(lab_bag, layout=layout_file(tmp_path, nx=2, ny=1)[0])


@pytest.mark.parametrize("topic, field, message", [
    ("/nowhere", None, r"lab: no topic '/nowhere'; the bag's topics: /idle \(std_msgs/msg/Float32MultiArray\), "
                       r"/log \(std_msgs/msg/String\), /nested"),
    ("/log", None, r"lab: topic '/log' \(std_msgs/msg/String\) has no field that is an array of numbers; its "
                   r"fields: data \(string\)$"),
    ("/log", "data", r"lab: field 'data' of topic '/log' \(std_msgs/msg/String\) is string, not an array of numbers"),
    ("/skin", "label", r"lab: field 'label' of topic '/skin' \(lab_msgs/msg/SkinFrame\) is string, not an array"),
    ("/skin", "count", r"field 'count' of topic '/skin' \(lab_msgs/msg/SkinFrame\) is uint32, not an array of num"),
    ("/skin", "header", r"field 'header' of topic '/skin' \(lab_msgs/msg/SkinFrame\) is a message "
                        r"\(std_msgs/msg/Header\), not an array of numbers; its fields: stamp "
                        r"\(builtin_interfaces/msg/Time\), frame_id \(string\)"),
    ("/skin", "pressure", r"topic '/skin' \(lab_msgs/msg/SkinFrame\) has no field 'pressure'; the fields of "
                          r"lab_msgs/msg/SkinFrame: header \(std_msgs/msg/Header\), label \(string\), pressures "
                          r"\(float32\[\]\), count \(uint32\)"),
    ("/skin", "pressures.x", r"field 'pressures.x' of topic '/skin' \(lab_msgs/msg/SkinFrame\) goes inside a "
                             r"float32\[\], which has no fields"),
    ("/nested", "array.size", r"topic '/nested' \(lab_msgs/msg/NestedFrame\) has no field 'array.size'; the fields "
                              r"of std_msgs/msg/Float64MultiArray: layout \(std_msgs/msg/MultiArrayLayout\), data"),
    (None, "values", r"lab: no topic has a numeric array field 'values'; the numeric array fields: /idle data, "
                     r"/nested array.data, /skin pressures, /wrist/force data$"),
])
def test_a_topic_or_field_that_holds_no_frames_is_refused_naming_what_is_there(lab_bag, tmp_path, topic, field,
                                                                               message):
    with pytest.raises(RecordingError, match=message):
        load_ros2_bag(lab_bag, layout=layout_file(tmp_path)[0], topic=topic, field=field)


def test_a_bag_without_numeric_arrays_names_its_topics(tmp_path):
    bag = write_bag(tmp_path / "chat", [("/log", "std_msgs/msg/String", T0_NS, _string("hello"))])
    expected = (r"chat: no topic whose messages hold an array of numbers \(such as std_msgs/msg/Float32MultiArray\); "
                r"the bag's topics: /log \(std_msgs/msg/String\)$")
    with pytest.raises(RecordingError, match=expected):
        array_topics(bag)
    with pytest.raises(RecordingError, match=expected):
        load_ros2_bag(bag, layout=layout_file(tmp_path)[0])


def test_a_topic_carrying_two_types_is_refused(tmp_path):
    bag = write_bag(tmp_path / "mixed", [("/skin", F32, T0_NS, multiarray(np.ones(6))),
                                         ("/skin", F64, T0_NS + 1, multiarray(np.ones(6), F64))])
    with pytest.raises(RecordingError, match=r"the bag's topics: /skin \(several types\)$"):
        array_topics(bag)  # listed by neither type: frames of one topic have one type
    with pytest.raises(RecordingError, match=r"mixed: topic '/skin' carries several message types "
                                             r"\(std_msgs/msg/Float32MultiArray, std_msgs/msg/Float64MultiArray\)"):
        load_ros2_bag(bag, layout=layout_file(tmp_path)[0], topic="/skin")


def test_many_topics_are_named_up_to_a_dozen(tmp_path):
    bag = write_bag(tmp_path / "many", [(f"/log{k:02d}", "std_msgs/msg/String", T0_NS, _string("x"))
                                        for k in range(15)])
    with pytest.raises(RecordingError, match=r"/log11 \(std_msgs/msg/String\) and 3 more$"):
        array_topics(bag)

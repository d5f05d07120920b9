"""The MCAP recording format (tactile_viewer/io/mcap_format.py): our recordings of every version are told
apart from other programs' ROS 2 bags, even bags of our own frame messages."""

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from tactile_viewer.io.mcap_format import TOPIC, is_recording_of_ours
from tactile_viewer.io.mcap_reader import open_recording
from tactile_viewer.io.recording import RecordingError
from tactile_viewer.io.ros2_message import MESSAGE_TYPES, FrameMessage
from tests.tactile_viewer.io.test_mcap_reader import version_1_file
from tests.tactile_viewer.io.test_mcap_writer import record
from tests.tactile_viewer.io.test_ros2_message import rosbags_types
from tests.tactile_viewer.skins import frames_for

DATA = Path(__file__).parent / "data"


def test_our_recordings_of_every_version_are_ours(tmp_path):
    record(tmp_path / "v3.mcap", frames_for(5, seed=19))  # fixed seed
    version_1_file(tmp_path / "v1.mcap", frames_for(6, seed=20), tare_at=3)  # fixed seed
    for path in (tmp_path / "v3.mcap", tmp_path / "v1.mcap", DATA / "version2_float32.mcap"):
        assert is_recording_of_ours(path), path


def test_a_ros_2_bag_of_another_program_is_not_ours_even_with_our_messages(tmp_path):
    store = rosbags_types()
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(TOPIC, MESSAGE_TYPES["float32"], typestore=store)
        message = FrameMessage.ros2(6, "float32")
        for k in range(3):
            writer.write(connection, 10**9 + k, message.encode(k, 10**9 + k, np.ones(6, np.float32)))
    [bag] = (tmp_path / "bag").glob("*.mcap")
    assert not is_recording_of_ours(bag)
    with pytest.raises(RecordingError, match="missing metadata 'tactile-viewer.recording'"):
        open_recording(bag)  # our reader refuses it too (load gives it to the ROS 2 bag reader)


def test_other_files_are_not_ours(tmp_path):
    (tmp_path / "notes.mcap").write_text("frames,t\n")
    (tmp_path / "empty.mcap").write_bytes(b"")
    assert not is_recording_of_ours(tmp_path / "notes.mcap")
    assert not is_recording_of_ours(tmp_path / "empty.mcap")
    with pytest.raises(FileNotFoundError):
        is_recording_of_ours(tmp_path / "missing.mcap")

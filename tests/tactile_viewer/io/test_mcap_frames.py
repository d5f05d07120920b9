"""The frames of an MCAP recording (tactile_viewer/io/mcap_frames.py): indexed like an array and read a
chunk at a time, a damaged chunk named, frames of another size refused, a tare retaken on them."""

import hashlib

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from tactile_viewer.io import mcap_frames as container
from tactile_viewer.io.files import load
from tactile_viewer.io.mcap_format import PROFILE, TOPIC, VERSION, metadata_checksum
from tactile_viewer.io.mcap_reader import open_recording
from tactile_viewer.io.recording import RecordingError, Tare
from tactile_viewer.io.ros2_message import FRAME_ID, MESSAGE_ENCODING, SCHEMA_ENCODING, SCHEMAS, FrameMessage
from tests.tactile_viewer.io.test_mcap_writer import record
from tests.tactile_viewer.skins import frames_for


def test_frames_index_like_an_array_and_read_lazily(tmp_path, monkeypatch):
    stress = frames_for(50, seed=3)  # fixed seed
    record(tmp_path / "lazy.mcap", stress, flush_interval=0.3, dtype="float64")
    decoded = []
    original = container._decode_chunk
    monkeypatch.setattr(container, "_decode_chunk", lambda *a: decoded.append(a[1].first) or original(*a))
    loaded = open_recording(tmp_path / "lazy.mcap")
    assert decoded == [] and loaded.frames.shape == (50, 6) and len(loaded) == 50  # nothing read at open
    np.testing.assert_array_equal(loaded.frames[7], stress[7])
    np.testing.assert_array_equal(loaded.frames[-1], stress[-1])
    np.testing.assert_array_equal(loaded.frames[[49, 0, 20]], stress[[49, 0, 20]])
    np.testing.assert_array_equal(loaded.frames[10:30:3], stress[10:30:3])
    np.testing.assert_array_equal(np.asarray(loaded.frames), stress)
    assert len(set(decoded)) == len(loaded.frames._index.chunks) > 10  # each chunk read when needed
    with pytest.raises(IndexError):
        loaded.frames[50]



def test_a_damaged_chunk_is_named_and_the_others_still_read(tmp_path):
    stress = frames_for(30, seed=7)  # fixed seed
    path = tmp_path / "flipped.mcap"
    record(path, stress, dtype="float64")
    loaded = load(path)
    chunk = loaded.frames._index.chunks[1]
    data = bytearray(path.read_bytes())
    data[chunk.data_offset + int(chunk.offsets[0]) + 40] ^= 0x10  # a bit of a value in chunk 1
    path.write_bytes(bytes(data))
    damaged = load(path)
    with pytest.raises(RecordingError, match=rf"frames {chunk.first} to \d+ are damaged \(chunk checksum"):
        damaged.frames[chunk.first]
    np.testing.assert_array_equal(damaged.frames[0], stress[0])




@pytest.mark.parametrize(("taxels", "frame_id"), [(5, FRAME_ID), (6, "tactile_skim"), (6, "tactile_skin2")])
def test_frames_of_another_size_or_layout_than_declared_are_refused(tmp_path, taxels, frame_id):
    # as if the metadata declared 5 taxels for frames of 6 values, or another frame_id in their
    # headers (one of the same length: the same size, but other bytes where every frame is alike)
    path = tmp_path / "short.mcap"
    record(path, frames_for(5, seed=8))  # fixed seed
    loaded = load(path)
    other = loaded.frames.with_calibration(loaded.calibration)
    other._m = taxels
    other._cache = container._ChunkCache(loaded.frames._index, FrameMessage.ros2(taxels, "float32", frame_id))
    with pytest.raises(RecordingError, match=f"frame 0 is not a frame of {taxels} float32 values"):
        other[0]



def test_a_tare_retaken_on_a_reopened_recording_changes_the_forces_not_the_file(tmp_path):
    raw = frames_for(10, seed=10)  # fixed seed
    path = tmp_path / "retare.mcap"
    record(path, raw, dtype="float64")
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    loaded = load(path)
    baseline = loaded.frames[3]
    retared = loaded.recalibrated(loaded.calibration.retared(Tare(0, baseline)))
    np.testing.assert_allclose(retared.frames[3], 0, atol=1e-9)
    np.testing.assert_allclose(retared.frames[:], raw - baseline)
    cleared = retared.recalibrated(retared.calibration.retared(None))
    np.testing.assert_array_equal(cleared.frames[:], raw)
    np.testing.assert_array_equal(loaded.frames[:], raw)  # the opened recording is unchanged
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before


def test_frames_between_another_channel_s_messages_are_read_one_by_one(tmp_path):
    # a file of ours that another tool rewrote with a second topic between the frames: the frames
    # are no longer evenly spaced in their chunks, so they are gathered, not read as one strided array
    path = tmp_path / "merged.mcap"
    stress = frames_for(12, seed=21)  # fixed seed
    message = FrameMessage.ros2(6, "float64")
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE, chunk_size=2**31)
        writer.start(profile=PROFILE, library="mcap merge")
        fields = {"recording": {"version": VERSION, "description": "merged", "taxels": "6", "dtype": "float64",
                                "channel": "1", "frame_id": FRAME_ID},
                  "geometry": {"nx": "3", "ny": "2", "pitch": "0.002", "thickness": "0.0015"},
                  "calibration": {"units": '"Pa"', "gain": "1", "offset": "0"}}
        for name, values in fields.items():
            writer.add_metadata(f"tactile-viewer.{name}", dict(values, crc32=metadata_checksum(values)))
        schema = writer.register_schema(message.type_name, SCHEMA_ENCODING, SCHEMAS["float64"].encode())
        frames = writer.register_channel(TOPIC, MESSAGE_ENCODING, schema)
        notes = writer.register_channel("/notes", "json", 0)
        for k, values in enumerate(stress):
            stamp = 10**9 + k * 10**8
            writer.add_message(frames, log_time=stamp, data=message.encode(50 + k, stamp, values),
                               publish_time=stamp, sequence=50 + k)
            writer.add_message(notes, log_time=stamp, data=b"{}" * (k + 1), publish_time=stamp)
            if k % 4 == 3:
                writer.flush()
        writer.finish()
    loaded = load(path)
    assert len(loaded.frames._index.chunks) == 3
    assert len(set(np.diff(loaded.frames._index.chunks[0].offsets))) > 1  # not evenly spaced
    np.testing.assert_array_equal(loaded.frames[:], stress)
    np.testing.assert_array_equal(loaded.sequence(), np.arange(12) + 50)
    np.testing.assert_allclose(loaded.t, np.arange(12) / 10)

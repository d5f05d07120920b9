"""The frames of an MCAP recording (tactile_viewer/io/mcap_frames.py): indexed like an array and read a
chunk at a time, a damaged chunk named, frames of another size refused, a tare retaken on them."""

import hashlib

import numpy as np
import pytest

from tactile_viewer.io import mcap_frames as container
from tactile_viewer.io.files import load
from tactile_viewer.io.mcap_reader import open_recording
from tactile_viewer.io.recording import RecordingError, Tare
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




def test_frames_of_another_size_than_declared_are_refused(tmp_path):
    path = tmp_path / "short.mcap"
    record(path, frames_for(5, seed=8))  # fixed seed
    loaded = load(path)
    other = loaded.frames.with_calibration(loaded.calibration)
    other._m = 5  # as if the header declared 5 taxels for frames of 6 values
    other._cache = container._ChunkCache(loaded.frames._index, 5, loaded.frames.raw_dtype)
    with pytest.raises(RecordingError, match="frame 0 is not a frame of 5 float32 values"):
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

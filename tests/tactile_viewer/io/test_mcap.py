"""MCAP recordings (tactile_viewer/io/mcap.py): the recorder, the lazy reader, files cut short at any
byte, a full disk, damaged chunks, declared sizes, raw values with their calibration."""

import errno
import hashlib
import io
import struct
import threading

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from solver import SensorGrid
from tactile_viewer.io import mcap as container
from tactile_viewer.io.files import load
from tactile_viewer.io.mcap import Recorder, open_recording
from tactile_viewer.io.recording import RecordingError, StressCalibration, Tare
from tactile_viewer.sources.source import Source, SourceFrame
from tests.tactile_viewer.skins import NU, TAXEL, frames_for, grid32, grid_with_material


def record(path, stress, *, flush_interval=0.5, step=0.1, close=True, **options):
    recorder = Recorder(path, grid32(), flush_interval=flush_interval, **options)
    for k, frame in enumerate(stress):
        recorder.add(1000 + k, k * step, frame)
    if close:
        recorder.close()
    else:
        recorder.drain()  # written as a crash now would leave it
    return recorder


def test_a_recording_is_loadable_after_every_chunk(tmp_path):
    # a crash can come at any time: close() is never called here, the file on disk must be enough
    path = tmp_path / "live.mcap"
    recorder = Recorder(path, grid32(), flush_interval=0.5, dtype="float64")
    stress = frames_for(13, seed=1)  # fixed seed

    def check(count):
        recorder.drain()  # what the writer's thread has been given is on disk
        loaded = load(path)
        assert len(loaded) == count == recorder.written
        np.testing.assert_array_equal(loaded.sequence(), np.arange(count) + 1000)
        np.testing.assert_allclose(loaded.t, np.arange(count) / 10, atol=1e-6)
        np.testing.assert_array_equal(loaded.frames[:], stress[:count])
        assert loaded.grid.shape == (2, 3) and loaded.grid.pitch == 2e-3

    for k in range(5):
        recorder.add(1000 + k, k / 10, stress[k])  # t = 0 .. 0.4: less than flush_interval since the first
    recorder.drain()
    assert recorder.written == 0
    with pytest.raises(RecordingError, match="no frames"):
        load(path)  # nothing in a complete chunk yet: metadata only
    recorder.add(1005, 0.5, stress[5])  # 0.5 s after the first frame: a chunk of all six
    check(6)
    for k in range(6, 10):
        recorder.add(1000 + k, k / 10, stress[k])
    check(6)  # t = 0.9: not yet
    recorder.add(1010, 1.0, stress[10])
    check(11)
    recorder.add(1011, 1.1, stress[11])
    recorder.add(1012, 1.2, stress[12])
    recorder.tick(1.4)  # a quiet line, but only 0.4 s since the last chunk
    check(11)
    recorder.tick(1.5)  # the frames waiting must not wait for the next one to arrive
    check(13)
    recorder.tick(5.0)  # nothing waiting: nothing written
    check(13)
    assert recorder.close() == path
    check(13)
    assert not load(path).truncated


def test_binary_frames_are_stored_as_float32(tmp_path):
    stress = frames_for(40, seed=2).astype(np.float32)  # fixed seed; float32 as a binary board sends
    record(tmp_path / "f32.mcap", stress)
    record(tmp_path / "f64.mcap", stress, dtype="float64")
    loaded = load(tmp_path / "f32.mcap")
    assert loaded.frames.raw_dtype == np.float32
    np.testing.assert_array_equal(loaded.frames[:], stress)
    # 6 values of 4 instead of 8 bytes, plus 31 bytes of message header and 16 of index per frame
    saved = (tmp_path / "f64.mcap").stat().st_size - (tmp_path / "f32.mcap").stat().st_size
    assert saved == 40 * 6 * 4


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


def test_geometry_and_description_round_trip(tmp_path):
    rng = np.random.default_rng(14)  # fixed seed: the same scattered taxels and frames every run
    scattered = SensorGrid(rng.uniform(-4e-3, 4e-3, (9, 2)), 1.5e-3, 2e-3, (9,))
    for grid in (grid_with_material(), scattered):
        path = tmp_path / f"g{grid.size}.mcap"
        recorder = Recorder(path, grid, description="bench run", clock_origin=1.7e9)
        for k in range(3):
            recorder.add(k, k / 10, np.ones(grid.size))
        recorder.close()
        back = load(path)
        assert back.grid.shape == grid.shape and back.description == "bench run"
        np.testing.assert_array_equal(back.grid.positions, grid.positions)
        assert back.grid.poisson_ratio == grid.poisson_ratio and back.grid.sensor_size == grid.sensor_size
        assert back.received == pytest.approx(1.7e9)
    assert load(tmp_path / "g6.mcap").grid.poisson_ratio == NU and TAXEL == load(tmp_path / "g6.mcap").grid.sensor_size


def test_no_frame_leaves_no_file(tmp_path):
    path = tmp_path / "empty.mcap"
    recorder = Recorder(path, grid32())
    assert path.exists()  # created at once, so that a bad path fails when recording starts
    assert recorder.close() is None
    assert not path.exists()


@pytest.mark.parametrize(("name", "options", "message"), [
    ("live.npz", {}, r"a recording is written as \.mcap, got '\.npz'"),
    ("live.mcap", {"dtype": "int16"}, r"dtype must be one of \['float32', 'float64'\], got 'int16'"),
    ("live.mcap", {"flush_interval": -1}, r"flush_interval must be >= 0 seconds, got -1"),
])
def test_recorder_arguments_are_checked(tmp_path, name, options, message):
    with pytest.raises(ValueError, match=message):
        Recorder(tmp_path / name, grid32(), **options)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("target", ["missing.mcap", "elsewhere.mcap"])
def test_a_recording_is_not_written_through_a_symbolic_link(tmp_path, target):
    # a dangling link at the path created its target
    link = tmp_path / "take.mcap"
    link.symlink_to(tmp_path / target)
    if target == "elsewhere.mcap":
        (tmp_path / target).write_bytes(b"another file")
    with pytest.raises(OSError, match=r"is a symbolic link: a recording is not written through one"):
        Recorder(link, grid32())
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"take.mcap", target} - {"missing.mcap"})
    if target == "elsewhere.mcap":
        assert (tmp_path / target).read_bytes() == b"another file"


def test_a_frame_of_the_wrong_size_is_refused(tmp_path):
    recorder = Recorder(tmp_path / "live.mcap", grid32())
    with pytest.raises(ValueError, match=r"a frame must have 6 values, got shape \(5,\)"):
        recorder.add(0, 0.0, np.ones(5))


def test_a_folder_that_cannot_be_written_says_so(tmp_path):
    with pytest.raises(OSError, match="No such file or directory"):
        Recorder(tmp_path / "missing" / "live.mcap", grid32())


# -- crashes and full disks -----------------------------------------------------------------------

def test_a_file_cut_at_any_byte_opens_with_every_complete_chunk(tmp_path):
    # a kill or a full disk leaves the file ended at some byte: whatever byte, the file opens with
    # exactly the frames of the chunks that were complete, and nothing else
    stress = frames_for(30, seed=5)  # fixed seed
    path = tmp_path / "whole.mcap"
    recorder = Recorder(path, grid32(), flush_interval=0.35, dtype="float64")
    ends = []  # (file size, frames in complete chunks) after each chunk
    for k in range(30):
        recorder.add(k, k / 10, stress[k])
        recorder.drain()
        if recorder.written and (not ends or ends[-1][1] != recorder.written):
            ends.append((path.stat().st_size, recorder.written))
    recorder.close()
    data = path.read_bytes()
    cut_path = tmp_path / "cut.mcap"
    for cut in range(len(data) - 1, 8, -7):
        cut_path.write_bytes(data[:cut])
        complete = max((frames for size, frames in ends if size <= cut), default=0)
        try:
            loaded = load(cut_path)
        except RecordingError as error:
            assert complete == 0 and "no frames" in str(error)
            continue
        assert len(loaded) >= complete  # a chunk whose index was cut off is walked instead
        np.testing.assert_array_equal(loaded.frames[:], stress[:len(loaded)])
        np.testing.assert_array_equal(loaded.sequence(), np.arange(len(loaded)))


class FullDisk(io.FileIO):
    """A file on a disk with ``room`` bytes left: the write that overflows writes what fits, then fails.

    Each test using it sets ``room`` first.
    """

    room = 0

    def write(self, data):
        fits = max(0, min(len(data), FullDisk.room - self.tell()))
        if fits < len(data):
            super().write(bytes(data[:fits]))
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(data)


class Publisher(Source):
    def send(self, k, stress):
        self._publish([SourceFrame(stress, k / 100, k)])


def test_a_full_disk_stops_the_recording_and_keeps_what_fit(tmp_path, monkeypatch):
    grid = grid32()
    path = tmp_path / "full.mcap"
    FullDisk.room = 4000  # metadata and a few chunks of 6-value frames
    monkeypatch.setattr(container, "open", lambda name, mode, **kw: io.BufferedWriter(FullDisk(name, "w", **kw))
                        if mode == "wb" else open(name, mode, **kw), raising=False)
    source = Publisher("board", grid)
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    source.start_recording(path, flush_interval=0.05)
    stress = frames_for(200, seed=6)  # fixed seed
    recorder = source.recorder
    for k in range(200):
        source.send(k, stress[k])  # the source goes on after the failure
        recorder.drain()  # the disk as fast as the board: the failure comes with the next frame
    assert source.published == 200 and source.recorder is None
    [(level, title, text)] = messages
    assert level == "error" and title == "Recording stopped"
    assert str(path) in text and "No space left on device" in text
    kept = int(text.split("(")[1].split(")")[0])
    loaded = load(path)
    assert loaded.truncated and len(loaded) >= kept > 0
    np.testing.assert_array_equal(loaded.frames[:], stress[:len(loaded)])


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


# -- declared sizes and foreign files ---------------------------------------------------------------

def metadata_record(name, fields):
    body = struct.pack("<I", len(name)) + name.encode()
    pairs = b"".join(struct.pack("<I", len(k)) + k.encode() + struct.pack("<I", len(v)) + v.encode()
                     for k, v in fields.items())
    body += struct.pack("<I", len(pairs)) + pairs
    return struct.pack("<BQ", 0x0C, len(body)) + body


def test_not_an_mcap_file(tmp_path):
    path = tmp_path / "text.mcap"
    path.write_text("frames,t\n1,2\n")
    with pytest.raises(RecordingError, match=r"text\.mcap: not an MCAP recording \(no MCAP magic"):
        load(path)


def test_an_mcap_file_of_another_program(tmp_path):
    path = tmp_path / "other.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        writer.start()
        writer.add_metadata("robot", {"arm": "left"})
        writer.add_message(writer.register_channel("/joints", "json", 0), log_time=1, data=b"{}", publish_time=1)
        writer.finish()
    with pytest.raises(RecordingError, match="missing metadata 'tactile-viewer.recording'"):
        load(path)


def test_a_huge_metadata_record_is_refused_before_reading_it(tmp_path):
    path = tmp_path / "bomb.mcap"
    path.write_bytes(container._MAGIC + struct.pack("<BQ", 0x0C, 2**40) + b"x" * 100)
    loaded_error = pytest.raises(RecordingError, match="no frames|missing metadata")
    with loaded_error:
        load(path)  # the record claims more than the file holds: the file ends before it


@pytest.mark.parametrize(("field", "value", "message"), [
    ("taxels", "4000000000", r"'taxels' must be in \[1, 1000000\], got 4000000000"),
    ("taxels", "six", r"'taxels' must be a whole number, got 'six'"),
    ("dtype", "int8", r"'dtype' must be one of \['float32', 'float64'\], got 'int8'"),
])
def test_declared_sizes_are_checked_before_anything_is_read(tmp_path, field, value, message):
    # a damaged or hostile header: refused before any frame is read or any array of its size made
    path = tmp_path / "declared.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        fields = {"version": "1", "description": "", "taxels": "6", "dtype": "float32", "channel": "1"}
        writer.add_metadata("tactile-viewer.recording", dict(fields, **{field: value}))
        writer.add_metadata("tactile-viewer.geometry", {"nx": "3", "ny": "2", "pitch": "0.002",
                                                       "thickness": "0.0015"})
        writer.add_metadata("tactile-viewer.calibration", {"units": '"Pa"', "gain": "1", "offset": "0"})
        writer.finish()
    with pytest.raises(RecordingError, match=message):
        load(path)


def test_frames_of_another_size_than_declared_are_refused(tmp_path):
    path = tmp_path / "short.mcap"
    record(path, frames_for(5, seed=8))  # fixed seed
    loaded = load(path)
    other = loaded.frames.with_calibration(loaded.calibration)
    other._m = 5  # as if the header declared 5 taxels for frames of 6 values
    other._cache = container._ChunkCache(loaded.frames._index, 5, loaded.frames.raw_dtype)
    with pytest.raises(RecordingError, match="frame 0 is not a frame of 5 float32 values"):
        other[0]


# -- raw values and calibration ---------------------------------------------------------------------

def test_raw_values_are_kept_and_calibrated_on_load(tmp_path):
    raw = frames_for(12, seed=9) / 1e3  # fixed seed; kPa as a board sends them
    calibration = StressCalibration("kPa", 2.0, 0.25, (Tare(0, np.full(6, 10.0), t=0.0, frames=50),))
    path = tmp_path / "raw.mcap"
    recorder = Recorder(path, grid32(), calibration=calibration, dtype="float64", flush_interval=0.2)
    for k in range(12):
        recorder.add(k, k / 10, raw[k])
        if k == 5:
            recorder.tare(Tare(0, np.full(6, 30.0), t=0.5, frames=20))  # applies from frame 6 on
    recorder.close()
    loaded = load(path)
    expected = 2.0 * (raw - 0.25) * 1e3 - 10.0
    expected[6:] -= 20.0
    np.testing.assert_allclose(loaded.frames[:], expected)
    np.testing.assert_array_equal(loaded.frames.raw(slice(None)), raw)
    assert [tare.from_frame for tare in loaded.calibration.tares] == [0, 6]
    assert loaded.calibration.tares[1].frames == 20 and loaded.calibration.tares[1].t == 0.5


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


def test_calibration_arguments_are_checked():
    with pytest.raises(ValueError, match=r"units must be one of \('Pa', 'kPa', 'MPa', 'counts'\), got 'psi'"):
        StressCalibration("psi", 1.0, 0.0)
    with pytest.raises(ValueError, match=r"gain must be one number or 3 numbers \(one per taxel\)"):
        StressCalibration("Pa", np.ones(3), np.zeros(3)).from_fields(3, units="Pa", gain=[1, 2], offset=0)
    with pytest.raises(ValueError, match=r"a tare baseline must have 3 values, got shape \(2,\)"):
        StressCalibration("Pa", np.ones(3), np.zeros(3), (Tare(0, np.zeros(2)),))
    with pytest.raises(ValueError, match="from_frame must be a whole number >= 0, got -1"):
        Tare(-1, np.zeros(3))


def test_a_chunk_without_its_index_in_the_middle_is_read_from_its_own_records(tmp_path):
    stress = frames_for(30, seed=11)  # fixed seed
    path = tmp_path / "noindex.mcap"
    record(path, stress, dtype="float64")
    index = load(path).frames._index
    data = bytearray(path.read_bytes())
    second = index.chunks[1]
    # the record after chunk 1's records is its message index: an unknown opcode hides it
    at = second.data_offset + second.length
    assert data[at] == 0x07
    data[at] = 0x7F
    path.write_bytes(bytes(data))
    loaded = load(path)
    np.testing.assert_array_equal(loaded.frames[:], stress)
    np.testing.assert_array_equal(loaded.sequence(), np.arange(30) + 1000)
    assert [c.first for c in loaded.frames._index.chunks] == [c.first for c in index.chunks]


@pytest.mark.parametrize("where", ["the last chunk's frames", "the last chunk's header"])
def test_a_torn_last_chunk_leaves_the_chunks_before_it(tmp_path, where):
    # a power cut or a torn page: the file has its length, but the last chunk holds zeros
    stress = frames_for(30, seed=12)  # fixed seed
    path = tmp_path / "torn.mcap"
    record(path, stress, dtype="float64", close=False)
    chunks = load(path).frames._index.chunks
    last = chunks[-1]
    data = bytearray(path.read_bytes())
    start = last.data_offset if where == "the last chunk's frames" else last.data_offset - 40
    data[start:] = bytes(len(data) - start)
    path.write_bytes(bytes(data))
    loaded = load(path)
    assert loaded.truncated and len(loaded) == last.first
    np.testing.assert_array_equal(loaded.frames[:], stress[:last.first])


def test_a_recorder_whose_write_failed_writes_nothing_more(tmp_path, monkeypatch):
    path = tmp_path / "full.mcap"
    FullDisk.room = 3000
    monkeypatch.setattr(container, "open", lambda name, mode, **kw: io.BufferedWriter(FullDisk(name, "w", **kw))
                        if mode == "wb" else open(name, mode, **kw), raising=False)
    recorder = Recorder(path, grid32(), flush_interval=0.05, dtype="float64")
    stress = frames_for(100, seed=13)  # fixed seed
    with pytest.raises(OSError, match="No space left on device"):
        for k in range(100):
            recorder.add(k, k / 100, stress[k])
            recorder.drain()  # the failure comes with the next call
    FullDisk.room = 10**9  # space freed: writing on would repeat the failed chunk's records
    recorder.add(100, 1.0, stress[0])
    recorder.tick(5.0)
    size = path.stat().st_size
    assert recorder.close() == path and path.stat().st_size == size
    loaded = load(path)
    np.testing.assert_array_equal(loaded.frames[:], stress[:len(loaded)])
    np.testing.assert_array_equal(loaded.sequence(), np.arange(len(loaded)))


# -- damage outside the chunk checksums (issue 31, item 3) -------------------------------------------

def tared_recording(path, *, frames=30, tare_at=20):
    """30 frames in chunks of 6 (t = 0, 0.1, ... s), a tare of 50 Pa taken after frame ``tare_at - 1``.

    Returns the raw values and the stresses the file must give back (the tare applied from ``tare_at``).
    """
    raw = frames_for(frames, seed=14)  # fixed seed
    recorder = Recorder(path, grid32(), dtype="float64", flush_interval=0.5)
    for k in range(frames):
        recorder.add(1000 + k, k / 10, raw[k])
        if k == tare_at - 1:
            recorder.tare(Tare(0, np.full(6, 50.0), t=k / 10, frames=10))
    recorder.close()
    expected = raw.copy()
    expected[tare_at:] -= 50.0
    return raw, expected


def flipped(path, at, bit=0x01):
    data = bytearray(path.read_bytes())
    data[at] ^= bit
    path.write_bytes(bytes(data))


def chunk_positions(path):
    index = load(path).frames._index
    return [chunk.data_offset - container._RECORD.size - container._CHUNK_HEAD.size - 8
            for chunk in index.chunks]


def test_a_chunk_whose_opcode_is_flipped_is_found_through_its_record(tmp_path):
    # before: the chunk was skipped as an unknown record, its 6 frames dropped with no word and the
    # tare after it applied 6 frames late
    path = tmp_path / "opcode.mcap"
    _raw, expected = tared_recording(path)
    flipped(path, chunk_positions(path)[1], 0x20)
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], expected)
    np.testing.assert_allclose(loaded.t, np.arange(30) / 10, atol=1e-6)
    assert loaded.damage == ()


def test_a_lost_chunk_is_said_with_its_frames_and_the_tare_after_it_keeps_its_frame(tmp_path):
    path = tmp_path / "lost.mcap"
    _raw, expected = tared_recording(path)
    position = chunk_positions(path)[1]
    data_offset = load(path).frames._index.chunks[1].data_offset
    flipped(path, position, 0x20)  # its header unreadable, so it is walked, and then
    flipped(path, data_offset + 100)  # a value of it fails the chunk's CRC
    loaded = load(path)
    kept = np.r_[0:6, 11:30]  # chunks of frames 0-5, 6-10, 11-15, 16-20, ...
    np.testing.assert_allclose(loaded.frames[:], expected[kept])  # the tare still from frame 20 as recorded
    np.testing.assert_allclose(loaded.t, kept / 10, atol=1e-6)
    assert loaded.damage == (f"frames 6 to 10 as recorded (5 frames, t 0.600 to 1.000 s) are lost: their "
                             f"chunk at byte {position} is damaged",)
    assert not loaded.truncated


@pytest.mark.parametrize("name", ["geometry", "calibration", "recording"])
def test_damaged_metadata_is_refused_by_its_checksum(tmp_path, name):
    # before: a pitch of 0.002 m read as 4.002 m
    path = tmp_path / "meta.mcap"
    tared_recording(path)
    data = path.read_bytes()
    # pitch 0.002 to 4.002, gain 1.0 to 5.0, "live recording" to "hive recording"
    field, after = {"geometry": (b"pitch", 9), "calibration": (b"gain", 8), "recording": (b"live recording", 0)}[name]
    start = data.index(f"tactile-viewer.{name}".encode())
    flipped(path, data.index(field, start) + after, 0x04)
    with pytest.raises(RecordingError, match=rf"metadata 'tactile-viewer.{name}' is damaged \(checksum"):
        load(path)


def test_a_damaged_tare_record_is_said_not_applied(tmp_path):
    path = tmp_path / "tare.mcap"
    raw, _expected = tared_recording(path)
    data = path.read_bytes()
    tare = data.index(b"tactile-viewer.tare") - 13
    flipped(path, data.index(b"baseline", tare) + 12, 0x02)  # a digit of the baseline
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], raw)
    [said] = loaded.damage
    assert said == f"the tare recorded at byte {tare} is damaged and not applied: frames from 16 on may be offset"


def index_entries(path, chunk):
    # the (time, offset) pairs of the message index after ``chunk`` and where they are in the file
    at = chunk.data_offset + chunk.length
    data = path.read_bytes()
    opcode, length = struct.unpack_from("<BQ", data, at)
    assert opcode == 0x07
    count = struct.unpack_from("<I", data, at + 11)[0] // 16
    return at + 15, np.frombuffer(data, "<u8", count=2 * count, offset=at + 15).reshape(-1, 2).copy()


@pytest.mark.parametrize("change", ["a time", "a duplicate", "two swapped", "a dropped entry"])
def test_a_message_index_is_checked_against_what_vouches_for_it(tmp_path, change):
    # before: the index, under no checksum, dropped, duplicated or moved frames and changed times
    path = tmp_path / "index.mcap"
    _raw, expected = tared_recording(path)
    chunk = load(path).frames._index.chunks[2]
    at, pairs = index_entries(path, chunk)
    if change == "a time":
        pairs[3, 0] += 2**20  # a millisecond later
    elif change == "a duplicate":
        pairs[3, 1] = pairs[2, 1]
    elif change == "two swapped":
        pairs[[2, 3], 1] = pairs[[3, 2], 1]
    else:  # the last entry's offset says the first: one frame fewer once sorted and deduplicated
        pairs[-1] = pairs[0]
    data = bytearray(path.read_bytes())
    data[at:at + pairs.nbytes] = pairs.tobytes()
    path.write_bytes(bytes(data))
    loaded = load(path)
    np.testing.assert_allclose(loaded.frames[:], expected)
    np.testing.assert_array_equal(loaded.t, load_truth_t())
    assert loaded.damage == ()


def load_truth_t():
    return (np.round(np.arange(30) / 10 * 1e9).astype(np.int64) - 0) * 1e-9


@pytest.mark.parametrize("record", ["the tare", "a message index", "a chunk"])
def test_a_flipped_length_hides_nothing_after_it(tmp_path, record):
    # before: one flipped length bit ended the file there (every later chunk hidden) or refused it
    path = tmp_path / "length.mcap"
    raw, expected = tared_recording(path)
    data = path.read_bytes()
    chunks = load(path).frames._index.chunks
    at = {"the tare": data.index(b"tactile-viewer.tare") - 13,
          "a message index": chunks[1].data_offset + chunks[1].length,
          "a chunk": chunk_positions(path)[2]}[record]
    flipped(path, at + 1 + 5, 0x10)  # a high byte of the record's length: past the end of the file
    loaded = load(path)
    assert len(loaded) == 30 and not loaded.truncated
    if record == "the tare":
        np.testing.assert_allclose(loaded.frames[:], raw)
        # the chunk of frames 16 to 20, written after the tare, is the first it may apply in
        assert loaded.damage == ("1 tare record is lost: frames from 16 on may be offset",)
    else:
        np.testing.assert_allclose(loaded.frames[:], expected)
        assert loaded.damage == ()


def version_1_file(path, raw, tare_at):
    # a recording as this viewer wrote it before checksummed metadata and chunk records: metadata
    # without checksums, a chunk of 6 frames at a time, a tare record between chunks
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE, chunk_size=2**31)
        writer.start(profile="tactile-viewer", library="tactile-viewer")
        writer.add_metadata("tactile-viewer.recording", {"version": "1", "description": "old", "taxels": "6",
                                                         "dtype": "float64", "channel": "1"})
        writer.add_metadata("tactile-viewer.geometry", {"nx": "3", "ny": "2", "pitch": "0.002",
                                                       "thickness": "0.0015"})
        writer.add_metadata("tactile-viewer.calibration", {"units": '"Pa"', "gain": "1", "offset": "0"})
        channel = writer.register_channel("/tactile/raw", "tactile-raw/float64-le", schema_id=0)
        for k, values in enumerate(raw):
            writer.add_message(channel, log_time=k * 10**8, data=values.tobytes(), publish_time=k * 10**8,
                               sequence=k)
            if k % 6 == 5:
                writer.flush()
            if k == tare_at - 1:
                writer.add_metadata("tactile-viewer.tare", {"from_frame": str(tare_at),
                                                            "baseline": "[50, 50, 50, 50, 50, 50]"})
        writer.finish()


def test_a_version_1_recording_still_opens(tmp_path):
    path = tmp_path / "old.mcap"
    raw = frames_for(30, seed=15)  # fixed seed
    version_1_file(path, raw, tare_at=20)
    loaded = load(path)
    expected = raw.copy()
    expected[20:] -= 50.0
    np.testing.assert_allclose(loaded.frames[:], expected)
    assert loaded.description == "old" and loaded.damage == () and not loaded.truncated


def test_an_unknown_version_is_refused(tmp_path):
    path = tmp_path / "future.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        writer.start()
        writer.add_metadata("tactile-viewer.recording", {"version": "9", "taxels": "6", "dtype": "float64"})
        writer.add_message(writer.register_channel("/tactile/raw", "x", 0), log_time=1, data=bytes(48),
                           publish_time=1)
        writer.finish()
    with pytest.raises(RecordingError, match=r"recording version '9' is not read by this viewer \(it reads 1, 2\)"):
        load(path)


# -- a slow disk (issue 31, item 7) -------------------------------------------------------------------

class StuckDisk(io.FileIO):
    """A disk that takes no write while ``StuckDisk.turning`` is clear (a slow or stalled device)."""

    turning = threading.Event()

    def write(self, data):
        assert StuckDisk.turning.wait(timeout=30), "the disk was never released"
        return super().write(data)


@pytest.fixture
def stuck_disk(monkeypatch):
    StuckDisk.turning.set()
    monkeypatch.setattr(container, "open", lambda name, mode, **kw: io.BufferedWriter(StuckDisk(name, "w", **kw))
                        if mode == "wb" else open(name, mode, **kw), raising=False)
    yield StuckDisk.turning
    StuckDisk.turning.set()


def test_a_stalled_disk_never_stalls_the_frames_given_to_the_recorder(tmp_path, stuck_disk):
    # before: every chunk was written on the caller's (the reader's) thread, which waited for the disk
    path = tmp_path / "slow.mcap"
    recorder = Recorder(path, grid32(), flush_interval=0.0, dtype="float64")
    stress = frames_for(50, seed=16)  # fixed seed
    stuck_disk.clear()
    given = []
    board = threading.Thread(target=lambda: given.extend(recorder.add(k, k / 100, stress[k]) for k in range(50)))
    board.start()
    board.join(timeout=10)  # a hang detector, not a speed bar: the disk stays stuck all along
    assert not board.is_alive() and given == [True] * 50 and recorder.dropped == 0
    assert recorder.written == 0  # nothing reached the disk yet
    stuck_disk.set()
    assert recorder.close() == path
    np.testing.assert_array_equal(load(path).frames[:], stress)


def test_a_full_queue_drops_frames_counts_them_and_the_source_says_so(tmp_path, stuck_disk):
    source = Publisher("board", grid32())
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    path = tmp_path / "behind.mcap"
    source.recorder = Recorder(path, grid32(), flush_interval=0.0, dtype="float64", backlog=10 * 6 * 8)
    recorder = source.recorder
    stress = frames_for(40, seed=17)  # fixed seed
    stuck_disk.clear()
    for k in range(40):
        source.send(k, stress[k])
    # ten wait in the queue, and the writer may hold one more it took before the disk stalled
    assert recorder.added in (10, 11) and recorder.dropped == 40 - recorder.added
    assert [m[:2] for m in messages] == [("warning", "Recording falls behind")]
    stuck_disk.set()
    assert source.stop_recording() == path
    loaded = load(path)
    np.testing.assert_array_equal(loaded.frames[:], stress[:recorder.added])  # the first ones, in order
    assert messages[-1] == ("warning", "recording saved", f"{path}: {recorder.dropped} frames not recorded "
                            "(the disk was slower than the board)")


def test_a_backlog_under_one_frame_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"backlog must be at least one frame \(24 bytes\), got 10"):
        Recorder(tmp_path / "x.mcap", grid32(), backlog=10)

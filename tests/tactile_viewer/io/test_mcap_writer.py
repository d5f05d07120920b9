"""The MCAP recorder (tactile_viewer/io/mcap_writer.py): chunks on time, its arguments, raw values with
their calibration, a full disk, a stalled disk and a full queue."""

import errno
import io
import threading

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from solver import SensorGrid
from tactile_viewer.io import mcap_writer as container
from tactile_viewer.io.files import load
from tactile_viewer.io.mcap_format import TOPIC
from tactile_viewer.io.mcap_writer import Recorder
from tactile_viewer.io.recording import RecordingError, StressCalibration, Tare
from tactile_viewer.io.ros2_message import FRAME_ID, MESSAGE_TYPES
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
    # 6 values of 4 instead of 8 bytes per frame, and no 4 bytes of CDR padding to align float64
    # values after their 4-byte count (the header, sequence and index are the same)
    saved = (tmp_path / "f64.mcap").stat().st_size - (tmp_path / "f32.mcap").stat().st_size
    assert saved == 40 * (6 * 4 + 4)



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


# -- full disks -----------------------------------------------------------------------------------

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



def test_calibration_arguments_are_checked():
    with pytest.raises(ValueError, match=r"units must be one of \('Pa', 'kPa', 'MPa', 'counts'\), got 'psi'"):
        StressCalibration("psi", 1.0, 0.0)
    with pytest.raises(ValueError, match=r"gain must be one number or 3 numbers \(one per taxel\)"):
        StressCalibration("Pa", np.ones(3), np.zeros(3)).from_fields(3, units="Pa", gain=[1, 2], offset=0)
    with pytest.raises(ValueError, match=r"a tare baseline must have 3 values, got shape \(2,\)"):
        StressCalibration("Pa", np.ones(3), np.zeros(3), (Tare(0, np.zeros(2)),))
    with pytest.raises(ValueError, match="from_frame must be a whole number >= 0, got -1"):
        Tare(-1, np.zeros(3))


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


# -- what ROS 2 tools read (issue 32, item 1) ---------------------------------------------------------

ORIGIN = 1_700_000_000.25  # UNIX seconds of receive time 0


def ros2_take(path, dtype):
    """25 frames 10 ms apart in chunks of 5, their sequence numbers crossing 2**32, a tare after 12.

    Returns the raw values and sequence numbers given to the recorder.
    """
    raw = (frames_for(25, seed=18) / 1e3).astype(dtype)  # fixed seed; kPa as a board sends them
    sequence = 2**32 - 10 + np.arange(25)
    calibration = StressCalibration("kPa", 2.0, 0.25)
    recorder = Recorder(path, grid32(), calibration=calibration, dtype=dtype, flush_interval=0.04,
                        clock_origin=ORIGIN)
    for k in range(25):
        recorder.add(int(sequence[k]), k / 100, raw[k])
        if k == 12:
            recorder.tare(Tare(0, np.full(6, 5.0), t=0.12, frames=10))
    recorder.close()
    return raw, sequence


def expected_stamps(stamps):
    # receive times 10 ms apart from ORIGIN, to the rounding of a float's seconds (under 1 us here)
    np.testing.assert_allclose(np.asarray(stamps, dtype=np.int64) - int(ORIGIN * 1e9),
                               np.arange(25) * 10**7, atol=1e3)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_rosbags_decodes_every_frame_of_a_recording(tmp_path, dtype):
    path = tmp_path / "take.mcap"
    raw, sequence = ros2_take(path, dtype)
    stamps, values, numbers = [], [], []
    with AnyReader([path]) as reader:  # a bare .mcap, no ROS installed: the schema comes from the file
        [connection] = reader.connections
        assert (connection.topic, connection.msgtype) == (TOPIC, MESSAGE_TYPES[dtype])
        for connection, log_time, data in reader.messages():
            frame = reader.deserialize(data, connection.msgtype)
            assert frame.header.frame_id == FRAME_ID
            assert frame.header.stamp.sec * 10**9 + frame.header.stamp.nanosec == log_time
            assert frame.values.dtype == dtype
            stamps.append(log_time)
            values.append(frame.values)
            numbers.append(frame.sequence)
    np.testing.assert_array_equal(values, raw)
    np.testing.assert_array_equal(numbers, sequence)  # whole, not modulo 2**32
    expected_stamps(stamps)
    ours = load(path)  # and our reader agrees with it
    np.testing.assert_array_equal(ours.frames.raw(slice(None)), raw)
    np.testing.assert_array_equal(ours.sequence(), sequence)
    np.testing.assert_allclose(ours.t, (np.array(stamps) - stamps[0]) * 1e-9)
    assert ours.received == pytest.approx(ORIGIN)
    assert [tare.from_frame for tare in ours.calibration.tares] == [13]


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_mcap_ros2_decodes_every_frame_of_a_recording(tmp_path, dtype):
    # Foxglove's own decoder for ROS 2 messages in MCAP, as its app uses
    path = tmp_path / "take.mcap"
    raw, sequence = ros2_take(path, dtype)
    stamps, values, numbers = [], [], []
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, message, frame in reader.iter_decoded_messages():
            assert (schema.name, schema.encoding) == (MESSAGE_TYPES[dtype], "ros2msg")
            assert (channel.topic, channel.message_encoding) == (TOPIC, "cdr")
            assert frame.header.stamp.sec * 10**9 + frame.header.stamp.nanosec == message.log_time
            assert frame.header.frame_id == FRAME_ID and message.sequence == frame.sequence % 2**32
            stamps.append(message.log_time)
            values.append(frame.values)
            numbers.append(frame.sequence)
        summary = reader.get_summary()
    np.testing.assert_array_equal(np.array(values, dtype=dtype), raw)
    np.testing.assert_array_equal(numbers, sequence)
    expected_stamps(stamps)
    assert summary.statistics.message_count == 25 and summary.statistics.channel_message_counts == {1: 25}
    # the layout and calibration stay where they were: metadata of the file
    names = [index.name for index in summary.metadata_indexes]
    assert names[:3] == [f"tactile-viewer.{name}" for name in ("recording", "geometry", "calibration")]
    assert names.count("tactile-viewer.tare") == 1

"""Live sources without Qt (tactile_viewer/sources/live.py): calibration, statistics, and a new transport
as one subclass."""

import threading

import numpy as np
import pytest

from tactile_viewer.io import files
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.sources.live import Calibration, LiveStats
from tactile_viewer.sources.protocol import encode_binary
from tests.tactile_viewer.skins import grid32, wait_for

# -- Calibration ----------------------------------------------------------------------------------

def test_calibration_subtracts_nothing_before_tare():
    calibration = Calibration(SensorLayout(grid32(), "kPa"))
    assert not calibration.taring
    np.testing.assert_array_equal(calibration(np.full(6, 2.0)), np.full(6, 2000.0))


def test_tare_averages_the_next_frames_and_subtracts_them_from_then_on():
    calibration = Calibration(SensorLayout(grid32()))
    calibration.tare(3)
    assert calibration.taring
    # while taring the frames come out untared; the third completes the baseline (mean of 1, 2, 6 = 3)
    np.testing.assert_array_equal(calibration(np.full(6, 1.0)), np.full(6, 1.0))
    np.testing.assert_array_equal(calibration(np.full(6, 2.0)), np.full(6, 2.0))
    assert calibration.taring
    np.testing.assert_array_equal(calibration(np.full(6, 6.0)), np.full(6, 3.0))
    assert not calibration.taring
    np.testing.assert_array_equal(calibration.baseline, np.full(6, 3.0))
    np.testing.assert_array_equal(calibration(np.arange(6.0)), np.arange(6.0) - 3.0)
    np.testing.assert_array_equal(calibration(np.arange(6.0)), np.arange(6.0) - 3.0)  # and stays


def test_a_second_tare_replaces_the_baseline_with_absolute_values():
    calibration = Calibration(SensorLayout(grid32(), "kPa"))
    calibration.tare(1)
    calibration(np.full(6, 1.0))  # baseline 1000 Pa
    calibration.tare(2)
    calibration(np.full(6, 4.0))
    out = calibration(np.full(6, 2.0))  # new baseline: mean(4000, 2000), not measured from the old one
    np.testing.assert_array_equal(calibration.baseline, np.full(6, 3000.0))
    np.testing.assert_array_equal(out, np.full(6, -1000.0))


@pytest.mark.parametrize("frames", [0, -1, 2.0, "5", None, True])
def test_tare_needs_a_positive_integer(frames):
    calibration = Calibration(SensorLayout(grid32()))
    with pytest.raises(ValueError, match="frames must be a positive integer"):
        calibration.tare(frames)
    assert not calibration.taring


# -- LiveStats ------------------------------------------------------------------------------------

def test_rate_from_receive_times():
    stats = LiveStats(window=1.0)
    assert stats.rate() == 0.0 and stats.silence(5.0) == float("inf")
    for k in range(100):
        stats.add(k, k / 100)  # 10 ms apart
    assert stats.rate() == pytest.approx(100.0)
    assert stats.rate(now=1.0) == pytest.approx(100.0)  # recent enough
    assert stats.rate(now=2.5) == 0.0  # silent for longer than the window
    assert stats.silence(1.24) == pytest.approx(0.25)
    assert stats.received == 100 and stats.lost == 0


def test_rate_measures_only_the_window():
    stats = LiveStats(window=1.0)
    for k in range(100):
        stats.add(None, k / 100)  # 100 fps for a second ...
    for k in range(1, 21):
        stats.add(None, 0.99 + k / 10)  # ... then 10 fps for two
    assert stats.rate() == pytest.approx(10.0)


def test_rate_of_frames_read_in_batches():
    # a 100 Hz board read ten frames at a time: every ten frames share one receive time
    stats = LiveStats(window=1.0)
    for batch in range(30):
        for k in range(10):
            stats.add(batch * 10 + k, batch / 10)
    assert stats.rate() == pytest.approx(100.0)  # counting the first read's frames would give 110


def test_lost_frames_from_gaps():
    stats = LiveStats()
    assert [stats.add(s, 0.0) for s in (100, 101, 104, 105, 110)] == [100, 101, 104, 105, 110]
    assert stats.lost == 2 + 4 and stats.received == 5 and stats.out_of_order == 0


def test_uint16_wrap():
    stats = LiveStats()
    assert [stats.add(s, 0.0) for s in (65534, 65535, 0, 1)] == [65534, 65535, 65536, 65537]
    assert stats.lost == 0
    stats = LiveStats()
    stats.add(65535, 0.0)
    assert stats.add(2, 0.0) == 65538 and stats.lost == 2  # 0 and 1 went missing across the wrap


def test_duplicates_and_reordered_frames_are_out_of_order_not_lost():
    stats = LiveStats()
    for s in (10, 11):
        stats.add(s, 0.0)
    assert stats.add(11, 0.0) == 11  # a repeat
    assert stats.add(5, 0.0) == 5  # a late one keeps its own number
    assert stats.out_of_order == 2 and stats.lost == 0
    assert stats.add(12, 0.0) == 12 and stats.lost == 0  # the count goes on from the newest
    # a frame overtaken by the next one: the gap was already counted when 14 came; 13 adds no loss
    stats.add(14, 0.0)
    assert stats.add(13, 0.0) == 13
    assert stats.lost == 1 and stats.out_of_order == 3 and stats.received == 7


def test_new_connection_continues_the_numbering_without_loss():
    stats = LiveStats()
    for s in (40, 41, 42):
        stats.add(s, 0.0)
    stats.new_connection()  # the board restarted: it counts from 0 again
    assert [stats.add(s, 1.0) for s in (0, 1, 3)] == [43, 44, 46]
    assert stats.lost == 1 and stats.out_of_order == 0  # only the real gap 1 -> 3


def test_a_snapshot_is_of_one_count_while_the_reader_counts():
    # every other frame lost: after n frames received, n - 1 lost. Read while a reader thread
    # counts, a snapshot keeps that (attribute by attribute, received could already count a frame
    # whose gap lost did not yet), and its rate is of the same receive times
    import threading

    stats = LiveStats(window=0.05)
    done = threading.Event()

    def reader():
        for k in range(200000):
            stats.add((2 * k) % 65536, k * 1e-4)
        done.set()

    thread = threading.Thread(target=reader)
    thread.start()
    seen = 0
    while not done.is_set():
        snap = stats.snapshot(now=stats.last_time or 0.0)
        if snap.received:
            assert snap.lost == snap.received - 1, snap
            assert 0 <= snap.rate <= 10000.0 + 1e-6  # 10 kHz of receive times
            seen += 1
    thread.join()
    assert seen > 10 and stats.snapshot(now=20.0).received == 200000


def test_text_frames_have_no_sequence():
    stats = LiveStats()
    assert stats.add(None, 0.0) is None and stats.add(None, 0.5) is None
    assert stats.received == 2 and stats.lost == 0 and stats.last_seq is None
    assert stats.silence(0.75) == pytest.approx(0.25) and stats.rate() == pytest.approx(2.0)


def values(k):
    return np.linspace(0.5, 3.0, 6) + k  # kPa; exact in float32


def test_a_new_transport_is_one_subclass(tmp_path):
    # what LiveSource promises: a transport only opens, reads and closes; decoding, calibration,
    # statistics, recording, reconnection and the hand-off come with it
    import queue

    from tactile_viewer.sources.live import LiveSource

    class Dropped(OSError):
        pass

    class QueueSource(LiveSource):
        lost = (Dropped,)

        def __init__(self, chunks, **kwargs):
            super().__init__("queue://test", SensorLayout(grid32(), "kPa"), **kwargs)
            self.chunks, self.opened = chunks, 0

        def _open(self):
            self.opened += 1
            return self.chunks

        def _read(self, chunks):
            try:
                chunk = chunks.get(timeout=0.01)
            except queue.Empty:
                return b""
            if chunk is None:
                raise Dropped("the stream went away")
            return chunk

        def _close(self, chunks):
            pass

    chunks = queue.Queue()
    arrived = threading.Event()
    source = QueueSource(chunks, reconnect_interval=0.01)
    source.frame_arrived.connect(arrived.set)
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    source.start_recording(tmp_path / "queue.mcap", flush_interval=0.0)
    source.start()
    try:
        for k in range(3):
            chunks.put(encode_binary(k, values(k)))
        wait_for(lambda: source.stats.received == 3, what="three frames")
        assert arrived.is_set()
        np.testing.assert_allclose(source.take_latest().stress, values(2) * 1e3, rtol=1e-6)  # kPa to Pa
        chunks.put(None)  # the connection drops: the source reconnects by itself
        wait_for(lambda: source.reconnects == 1 and source.state == "connected", what="reconnection")
        chunks.put(encode_binary(3, values(3)))
        wait_for(lambda: source.stats.received == 4, what="a frame after reconnecting")
    finally:
        source.stop()
    assert source.opened == 2 and source.stats.lost == 0
    # a transport that cannot tell whether the same device came back ends the recording there:
    # two devices' frames never share a file
    saved = files.load(tmp_path / "queue.mcap")
    assert len(saved) == 3 and list(saved.sequence()) == [0, 1, 2]
    assert ("warning", "Recording ended at a reconnection") in [m[:2] for m in messages]


def test_a_tare_of_an_unloaded_skin_does_not_warn_and_a_pressed_one_does():
    from tactile_viewer.sources.live import loaded_while_taring

    rng = np.random.default_rng(8)  # fixed seed: 50 frames of 1 Pa noise on 256 taxels
    quiet = rng.normal(0, 1.0, (50, 256)) + 300.0  # a uniform drift of the zero is no contact
    assert loaded_while_taring(quiet, np.zeros(256)) is None
    pressed = quiet.copy()
    pressed[:, 40] += 8.0  # 8 times the noise on one taxel
    assert "taxel 40 stood" in loaded_while_taring(pressed, np.zeros(256))
    assert loaded_while_taring(pressed, pressed.mean(axis=0)) is None  # the same load as the last tare


def test_frames_too_large_to_average_are_no_part_of_a_tare():
    # 1.5e308 Pa each is finite, but their sum is not: such frames are refused before any tare sees them
    calibration = Calibration(SensorLayout(grid32(), "kPa"))
    calibration.tare(2)
    huge = np.full(6, 1.5e305)  # kPa
    assert calibration(huge, 0.0) is None and calibration(huge, 0.0) is None
    assert calibration.taring and calibration.take_completed() is None
    np.testing.assert_array_equal(calibration.baseline, 0.0)  # the zero in force is kept

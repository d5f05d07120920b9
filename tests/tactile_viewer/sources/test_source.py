"""Sources of frames (tactile_viewer/sources/source.py), without Qt: events, recording, the recording's clock."""

import threading

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.files import load
from tactile_viewer.io.recording import Recording
from tactile_viewer.sources.source import RecordingSource, Signal, Source, SourceFrame

GRID = SensorGrid.regular(3, 2, 2e-3, 2e-3)
T = [0.0, 0.1, 0.2, 0.3]  # four frames, 10 per second


@pytest.fixture
def recording():
    frames = np.arange(4 * GRID.size, dtype=float).reshape(4, GRID.size) * 100.0  # frame k starts at 600 k Pa
    return Recording(GRID, frames, T, description="ramp")


def arrivals(source):
    """Every frame_arrived, with the frame then waiting (taken at once, as a display does)."""
    taken = []
    source.frame_arrived.connect(lambda: taken.append(source.take_latest()))
    return taken




def test_signal_calls_its_slots_in_order_and_forgets_disconnected_ones():
    signal, calls = Signal(), []
    first, second = (lambda *a: calls.append(("first", a))), (lambda *a: calls.append(("second", a)))
    signal.connect(first)
    signal.connect(second)
    signal.emit(1, "x")
    signal.disconnect(first)
    signal.emit(2)
    assert calls == [("first", (1, "x")), ("second", (1, "x")), ("second", (2,))]


def test_a_slot_may_disconnect_itself_while_the_signal_fires():
    signal, calls = Signal(), []

    def once(value):
        calls.append(("once", value))
        signal.disconnect(once)

    signal.connect(once)
    signal.connect(lambda value: calls.append(("always", value)))
    signal.emit(1)
    signal.emit(2)  # the self-removal must not have skipped the second slot on the first emit
    assert calls == [("once", 1), ("always", 1), ("always", 2)]


# -- RecordingSource: seek, step, play ----------------------------------------------------------------

def test_seek_produces_the_frame_once(recording):
    source = RecordingSource(recording, "takes/ramp.npz")
    assert source.label == "takes/ramp.npz" and source.grid is GRID and not source.live
    taken = arrivals(source)
    source.seek(2)
    assert [f.index for f in taken] == [2] and source.position == 2
    np.testing.assert_array_equal(taken[0].stress, recording.frames[2])
    assert taken[0].t == pytest.approx(0.2)
    assert source.take_latest() is None  # taken: nothing new since


def test_frame_arrived_fires_once_until_the_frame_is_taken(recording):
    source, calls = RecordingSource(recording), []
    source.frame_arrived.connect(lambda: calls.append(1))
    source.seek(1)
    source.seek(2)  # the display has not taken frame 1: no second notification
    assert len(calls) == 1 and source.take_latest().index == 2  # the newest wins
    source.seek(3)
    assert len(calls) == 2


@pytest.mark.parametrize("index", [-1, 4])
def test_seek_outside_the_recording_is_refused(recording, index):
    source = RecordingSource(recording)
    with pytest.raises(ValueError, match=rf"frame must be in \[0, 3\], got {index}"):
        source.seek(index)
    assert source.position == 0


def test_playing_follows_the_recordings_clock_and_stops_at_the_end(recording):
    source = RecordingSource(recording)
    taken, states = arrivals(source), []
    source.state_changed.connect(lambda: states.append(source.state))
    source.play(now=100.0)
    source.advance(100.05)
    assert taken == []  # frame 0 is still due
    source.advance(100.25)  # slow drawing skips frame 1
    assert [f.index for f in taken] == [2]
    source.advance(100.31)
    assert [f.index for f in taken] == [2, 3] and states == ["playing", "stopped"]
    source.advance(101.0)  # stopped: nothing more
    assert len(taken) == 2


def test_play_at_the_end_starts_over_and_loops_when_asked(recording):
    source = RecordingSource(recording)
    taken = arrivals(source)
    source.seek(3)
    taken.clear()
    source.loop = True
    source.play(now=0.0)
    assert [f.index for f in taken] == [0]
    source.advance(0.41)  # one period of 0.4 s: back to the start, still playing
    source.advance(0.55)
    assert [f.index for f in taken] == [0, 1] and source.state == "playing"


def test_speed_is_checked_and_scales_time(recording):
    source = RecordingSource(recording)
    with pytest.raises(ValueError, match="speed must be > 0, got 0"):
        source.set_speed(0, now=0.0)
    source.set_speed(4.0, now=0.0)
    source.play(now=0.0)
    source.advance(0.05)  # 0.2 s of recording in 0.05 s
    assert source.position == 2


def test_a_seek_with_a_time_restarts_the_clock_there(recording):
    source = RecordingSource(recording)
    source.play(now=0.0)
    source.seek(2, now=10.0)
    source.advance(10.05)
    assert source.position == 2
    source.advance(10.11)
    assert source.position == 3


# -- recording what a source produces -------------------------------------------------------------------

class Pushed(Source):
    """A source that produces the frames it is given from a thread of its own, as a live one does."""

    live = True

    def push(self, frames):
        thread = threading.Thread(target=self._publish, args=(frames,), name="pushing")
        thread.start()
        thread.join()


def test_any_source_records_every_frame_it_produces(tmp_path):
    source = Pushed("test stream", GRID)
    source.start_recording(tmp_path / "stream.mcap", flush_interval=0.0)
    frames = [SourceFrame(np.full(GRID.size, 10.0 * k), 0.01 * k, 100 + k) for k in range(5)]
    source.push(frames[:2])
    source.push(frames[2:])
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    written = source.stop_recording()
    back = load(written)
    assert len(back) == 5 and list(back.sequence()) == [100, 101, 102, 103, 104]  # every frame, not the newest
    np.testing.assert_array_equal(back.frames[:, 0], [0, 10, 20, 30, 40])
    assert back.description == "test stream"
    assert messages == [("info", "recording saved", str(written))]
    assert source.take_latest().index == 104


def test_unnumbered_frames_are_recorded_in_order(tmp_path):
    source = Pushed("text", GRID)
    source.start_recording(tmp_path / "text.mcap", flush_interval=0.0)
    source.push([SourceFrame(np.zeros(GRID.size), 0.01 * k, None) for k in range(3)])
    assert list(load(source.stop_recording()).sequence()) == [0, 1, 2]


def test_a_recording_that_fails_to_close_says_so_and_the_source_goes_on(tmp_path):
    source = Pushed("board", GRID)
    recorder = source.start_recording(tmp_path / "full.mcap", flush_interval=0.0)
    source.push([SourceFrame(np.zeros(GRID.size), 0.0, 0)])

    def full_disk():
        raise OSError(28, "No space left on device")
    recorder.close = full_disk
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    assert source.stop_recording() is None and source.recorder is None
    (level, title, text), = messages
    assert (level, title) == ("error", "Recording not completed")
    assert "full.mcap: No space left on device" in text and "(1) are in the file" in text
    source.push([SourceFrame(np.ones(GRID.size), 0.1, 1)])  # still producing
    assert source.take_latest().index == 1


def test_stopping_closes_the_recording_and_announces_the_state(tmp_path):
    source = Pushed("board", GRID)
    states = []
    source.state_changed.connect(lambda: states.append(source.state))
    source.start()
    source.start_recording(tmp_path / "stop.mcap", flush_interval=0.0)
    source.push([SourceFrame(np.zeros(GRID.size), 0.0, 7)])
    source.stop()
    assert states == ["running", "stopped"] and source.recorder is None
    assert list(load(tmp_path / "stop.mcap").sequence()) == [7]


def test_a_recording_with_no_frame_says_so_and_writes_no_file(tmp_path):
    source = Pushed("board", GRID)
    source.start_recording(tmp_path / "empty.mcap")
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    assert source.stop_recording() is None and not (tmp_path / "empty.mcap").exists()
    assert messages == [("info", "nothing recorded", f"no frame arrived; {tmp_path / 'empty.mcap'} not written")]


@pytest.mark.parametrize("when", ["a frame arrives", "the line is quiet"])
def test_a_write_that_fails_while_recording_stops_the_recording_not_the_source(tmp_path, when):
    source = Pushed("board", GRID)
    recorder = source.start_recording(tmp_path / "full.mcap", flush_interval=0.0)
    source.push([SourceFrame(np.zeros(GRID.size), 0.0, 0)])  # one frame written

    def full_disk(*args):
        raise OSError(28, "No space left on device")
    messages = []
    source.message.connect(lambda *m: messages.append(m))
    if when == "a frame arrives":
        recorder.add = full_disk
        source.push([SourceFrame(np.ones(GRID.size), 0.1, 1)])
    else:
        recorder.tick = full_disk
        source._tick_recording(0.5)
    (level, title, text), = messages
    assert (level, title) == ("error", "Recording stopped") and source.recorder is None
    assert "full.mcap: No space left on device" in text and "(1) are in the file" in text
    assert list(load(tmp_path / "full.mcap").sequence()) == [0]  # what was written stays readable
    source.push([SourceFrame(np.ones(GRID.size), 0.2, 2)])  # and the source goes on
    assert source.take_latest().index == 2

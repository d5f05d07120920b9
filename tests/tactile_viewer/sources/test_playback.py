"""The playback clock (tactile_viewer/sources/playback.py), without Qt: which frame is due when."""

import pytest

from tactile_viewer.sources.playback import PlaybackClock

T = [0.0, 0.1, 0.2, 0.3]  # four frames, 10 per second


def test_the_recordings_own_times_decide_the_frame():
    clock = PlaybackClock(T)
    clock.restart(0, now=100.0)
    assert clock.due(100.0) == (0, False)
    assert clock.due(100.15) == (1, False)
    assert clock.due(100.25) == (2, False)  # frames are never shown early
    assert clock.due(100.31) == (3, True)  # the last frame: playback is over
    assert clock.due(200.0) == (3, True)


def test_speed_scales_time_and_slow_drawing_skips_frames():
    clock = PlaybackClock(T)
    clock.restart(0, now=0.0)
    assert clock.due(0.05, speed=4.0) == (2, False)  # 0.2 s of recording in 0.05 s: frame 1 skipped
    assert clock.due(0.1, speed=0.5) == (0, False)


def test_looping_repeats_with_one_frame_interval_after_the_last():
    clock = PlaybackClock(T)
    clock.restart(0, now=0.0)
    assert clock.due(0.35, loop=True) == (3, False)  # still the last frame's interval
    assert clock.due(0.41, loop=True) == (0, False)  # period 0.4 s: back to the start
    assert clock.due(0.55, loop=True) == (1, False)


def test_restarting_from_a_frame_plays_on_from_it():
    clock = PlaybackClock(T)
    clock.restart(2, now=10.0)
    assert clock.due(10.0) == (2, False)
    assert clock.due(10.11) == (3, True)


def test_a_single_frame_recording_is_over_at_once_and_never_loops():
    clock = PlaybackClock([5.0])
    clock.restart(0, now=0.0)
    assert clock.due(1.0, loop=True) == (0, True)


@pytest.mark.parametrize("t", [[], [[0.0, 1.0]]], ids=["empty", "2-D"])
def test_frame_times_are_checked(t):
    with pytest.raises(ValueError, match="t must be a non-empty list of frame times"):
        PlaybackClock(t)

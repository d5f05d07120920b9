"""Live sources without Qt: layouts, calibration, statistics, the recorder, the serial reader on a pty."""

import json
import os
import re
import threading
import time
import tty

import numpy as np
import pytest
import serial

from solver import SensorGrid
from tactile_viewer import recording
from tactile_viewer.protocol import encode_binary
from tactile_viewer.sources import (
    Calibration,
    LayoutError,
    LiveStats,
    Recorder,
    SensorLayout,
    SerialReader,
    load_layout,
    save_layout,
)


def grid32():
    return SensorGrid.regular(3, 2, 2e-3, 1.5e-3)  # six taxels, two rows of three


def wait_for(predicate, timeout=5.0, what="condition"):
    """Poll ``predicate`` until true; fail with ``what`` after ``timeout`` seconds (no bare sleeps)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.002)


# -- SensorLayout ---------------------------------------------------------------------------------

@pytest.mark.parametrize("units, scale", [("Pa", 1.0), ("kPa", 1e3), ("MPa", 1e6), ("counts", 1.0)])
def test_to_pascals_scales_by_units(units, scale):
    layout = SensorLayout(grid32(), units)
    raw = np.arange(6.0)
    np.testing.assert_allclose(layout.to_pascals(raw), raw * scale, rtol=1e-15)
    assert layout.count == 6


def test_counts_use_the_gain_as_pascals_per_count():
    layout = SensorLayout(grid32(), "counts", gain=2.5, offset=100.0)
    np.testing.assert_allclose(layout.to_pascals(np.full(6, 140.0)), np.full(6, 100.0))  # 2.5 * (140 - 100)


def test_per_taxel_gain_and_offset_apply_to_single_frames_and_stacks():
    gain, offset = np.arange(1.0, 7.0), np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    layout = SensorLayout(grid32(), "kPa", gain=gain, offset=offset)
    raw = np.full(6, 10.0)
    expected = gain * (raw - offset) * 1e3
    np.testing.assert_allclose(layout.to_pascals(raw), expected)
    # (T, m): each row calibrated the same way
    np.testing.assert_allclose(layout.to_pascals(np.stack([raw, raw, raw])), np.stack([expected] * 3))


def test_scalar_gain_and_offset_broadcast_to_read_only_arrays():
    layout = SensorLayout(grid32(), gain=2, offset=-1)
    assert layout.gain.shape == layout.offset.shape == (6,)
    assert layout.gain.dtype == float and np.all(layout.gain == 2.0) and np.all(layout.offset == -1.0)
    for array in (layout.gain, layout.offset):
        assert not array.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 5.0


def test_per_taxel_arrays_are_copied_not_shared():
    gain = np.ones(6)
    layout = SensorLayout(grid32(), gain=gain)
    gain[0] = 99.0  # the caller's array changing later must not recalibrate the layout
    assert layout.gain[0] == 1.0 and not layout.gain.flags.writeable


@pytest.mark.parametrize("kwargs, message", [
    (dict(units="N"), r"units must be one of .*'N'"),
    (dict(units="kpa"), r"units must be one of"),
    (dict(gain=np.ones(5)), r"gain must be one number or 6 numbers .*\(5,\)"),
    (dict(gain=np.ones((2, 3))), r"gain must be one number or 6 numbers .*\(2, 3\)"),
    (dict(offset=[1.0, 2.0]), r"offset must be one number or 6 numbers"),
    (dict(offset=np.array([0, 0, np.nan, 0, 0, 0])), r"offset must be finite"),
    (dict(gain=np.inf), r"gain must be finite"),
])
def test_layout_rejects(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SensorLayout(grid32(), **kwargs)


# -- layout files ---------------------------------------------------------------------------------

def test_layout_round_trip_regular(tmp_path):
    layout = SensorLayout(grid32(), "kPa", gain=1.5, offset=0.25)
    back = load_layout(save_layout(layout, tmp_path / "board.json"))
    assert back.units == "kPa" and back.grid.shape == (2, 3)
    assert back.grid.pitch == 2e-3 and back.grid.thickness == 1.5e-3 and back.grid.is_regular
    np.testing.assert_array_equal(back.grid.positions, layout.grid.positions)
    np.testing.assert_array_equal(back.gain, layout.gain)
    np.testing.assert_array_equal(back.offset, layout.offset)
    # a uniform gain is written as one number, as a person would write it
    spec = json.loads((tmp_path / "board.json").read_text())
    assert spec["gain"] == 1.5 and "positions" not in spec


def test_layout_round_trip_with_explicit_positions_and_per_taxel_calibration(tmp_path):
    positions = grid32().positions.copy()
    positions[4] += [0.3e-3, -0.2e-3]  # one taxel off the grid: the positions must be written
    grid = SensorGrid(positions, 1.5e-3, 2e-3, (2, 3))
    rng = np.random.default_rng(7)  # fixed seed
    layout = SensorLayout(grid, "counts", gain=rng.uniform(0.5, 2, 6), offset=rng.uniform(0, 100, 6))
    path = save_layout(layout, tmp_path / "irregular.json")
    assert "positions" in json.loads(path.read_text())
    back = load_layout(path)
    assert back.units == "counts" and back.grid.shape == (2, 3) and not back.grid.is_regular
    np.testing.assert_array_equal(back.grid.positions, positions)  # JSON floats round trip exactly
    np.testing.assert_array_equal(back.gain, layout.gain)
    np.testing.assert_array_equal(back.offset, layout.offset)


def test_layout_round_trip_keeps_a_shifted_regular_grid(tmp_path):
    shifted = SensorGrid(grid32().positions + [5e-3, 0.0], 1.5e-3, 2e-3, (2, 3))
    back = load_layout(save_layout(SensorLayout(shifted), tmp_path / "shifted.json"))
    np.testing.assert_array_equal(back.grid.positions, shifted.positions)


GOOD = {"nx": 3, "ny": 2, "pitch": 2e-3, "thickness": 1.5e-3}


@pytest.mark.parametrize("content, message", [
    ("{nx: 3", r"not JSON"),
    ("[1, 2, 3]", r"expected a JSON object, got list"),
    ('"a string"', r"expected a JSON object, got str"),
    (json.dumps({"nx": 3, "pitch": 1e-3}), r"missing 'ny', 'thickness'"),
    (json.dumps({**GOOD, "nx": 2.5}), r"nx and ny must be whole numbers, got 2.5 and 2"),
    (json.dumps({**GOOD, "nx": "4"}), r"nx and ny must be whole numbers, got '4'"),
    (json.dumps({**GOOD, "ny": True}), r"nx and ny must be whole numbers"),
    (json.dumps({**GOOD, "nx": 0}), r"nx must be a positive integer"),
    (json.dumps({**GOOD, "pitch": 0}), r"pitch must be a positive finite number"),
    (json.dumps({**GOOD, "thickness": "thick"}), r"thickness must be a number of metres, got 'thick'"),
    (json.dumps({**GOOD, "thickness": "2e-3"}), r"thickness must be a number of metres, got '2e-3'"),
    (json.dumps({**GOOD, "gain": [1, 2, 3]}), r"gain must be one number or 6 numbers"),
    (json.dumps({**GOOD, "offset": float("nan")}), r"offset must be finite"),
    (json.dumps({**GOOD, "units": "psi"}), r"units must be one of"),
    (json.dumps({**GOOD, "positions": [[0, 0], [1, 1]]}), r"shape \(2, 3\) does not hold the 2 positions"),
])
def test_bad_layout_files_name_the_file_and_the_problem(tmp_path, content, message):
    path = tmp_path / "bad layout.json"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(LayoutError, match=re.escape(str(path)) + ".*" + message):
        load_layout(path)


# the elastomer's Poisson ratio and the taxel size travel with the layout
NU, TAXEL = 0.45, 1e-3


def grid_with_material():
    return SensorGrid.regular(3, 2, 2e-3, 1.5e-3, poisson_ratio=NU, sensor_size=TAXEL)


def test_layout_round_trip_keeps_poisson_ratio_and_sensor_size(tmp_path):
    path = save_layout(SensorLayout(grid_with_material(), "kPa"), tmp_path / "board.json")
    spec = json.loads(path.read_text())
    assert spec["poisson_ratio"] == NU and spec["sensor_size"] == TAXEL  # readable in the file itself
    back = load_layout(path).grid
    assert back.poisson_ratio == NU and back.sensor_size == TAXEL and back.is_regular
    # irregular positions are written separately: the material must survive that path too
    positions = grid_with_material().positions.copy()
    positions[1] += [0.2e-3, 0.0]
    moved = grid_with_material().replace(positions=positions)
    back = load_layout(save_layout(SensorLayout(moved), tmp_path / "moved.json")).grid
    assert back.poisson_ratio == NU and back.sensor_size == TAXEL
    np.testing.assert_array_equal(back.positions, positions)


def test_default_layout_writes_the_defaults_explicitly(tmp_path):
    spec = json.loads(save_layout(SensorLayout(grid32()), tmp_path / "board.json").read_text())
    assert spec["poisson_ratio"] == 0.5 and spec["sensor_size"] == 0.0


def test_layout_without_poisson_ratio_or_sensor_size_opens_with_the_defaults(tmp_path):
    # files written before the layer kernel: an incompressible layer, point sensors
    path = tmp_path / "old.json"
    path.write_text(json.dumps(GOOD), encoding="utf-8")
    grid = load_layout(path).grid
    assert grid.poisson_ratio == 0.5 and grid.sensor_size == 0.0
    path.write_text(json.dumps({**GOOD, "poisson_ratio": 0}), encoding="utf-8")
    assert load_layout(path).grid.poisson_ratio == 0.0  # 0 is allowed and not taken for "absent"


@pytest.mark.parametrize("changes, message", [
    (dict(poisson_ratio=0.7), r"poisson_ratio must be a finite number in \[0, 0.5\], got 0.7$"),
    (dict(poisson_ratio="abc"), r"poisson_ratio must be a finite number in \[0, 0.5\], got 'abc'$"),
    (dict(poisson_ratio="0.45"), r"poisson_ratio must be a finite number in \[0, 0.5\], got '0.45'$"),
    (dict(poisson_ratio=-0.2), r"poisson_ratio must be a finite number in \[0, 0.5\], got -0.2$"),
    (dict(poisson_ratio=True), r"poisson_ratio must be a finite number in \[0, 0.5\], got True$"),
    (dict(poisson_ratio=None), r"poisson_ratio must be a finite number in \[0, 0.5\], got None$"),
    (dict(sensor_size=3e-3), r"sensor_size must be at most the pitch \(taxels cannot overlap\), "
                             r"got 0.003 m with pitch 0.002 m$"),
    (dict(sensor_size=-1e-3), r"sensor_size must be a finite number of metres >= 0 .*, got -0.001$"),
    (dict(sensor_size="1 mm"), r"sensor_size must be a finite number of metres >= 0 .*, got '1 mm'$"),
], ids=["nu-above-half", "nu-text", "nu-numeric-text", "nu-negative", "nu-bool", "nu-null", "taxel-overlap",
        "taxel-negative", "taxel-text"])
def test_bad_poisson_ratio_or_sensor_size_in_a_layout_names_file_and_field(tmp_path, changes, message):
    path = tmp_path / "bad layout.json"
    path.write_text(json.dumps({**GOOD, **changes}), encoding="utf-8")
    with pytest.raises(LayoutError, match=re.escape(str(path)) + ": " + message):
        load_layout(path)


def test_missing_and_undecodable_layout_files(tmp_path):
    missing = tmp_path / "nowhere.json"
    with pytest.raises(LayoutError, match=re.escape(str(missing)) + r": cannot read"):
        load_layout(missing)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00garbage")  # not UTF-8 at all
    with pytest.raises(LayoutError, match=re.escape(str(binary)) + r": not JSON"):
        load_layout(binary)
    assert issubclass(LayoutError, ValueError)  # callers catching ValueError see it too


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


def test_text_frames_have_no_sequence():
    stats = LiveStats()
    assert stats.add(None, 0.0) is None and stats.add(None, 0.5) is None
    assert stats.received == 2 and stats.lost == 0 and stats.last_seq is None
    assert stats.silence(0.75) == pytest.approx(0.25) and stats.rate() == pytest.approx(2.0)


# -- Recorder -------------------------------------------------------------------------------------

def frames_for(n, seed):
    return np.random.default_rng(seed).normal(1e3, 300, size=(n, 6))


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_recorder_file_is_loadable_after_every_flush(tmp_path, suffix):
    # a crash can come at any time: close() is never called here, the file on disk must be enough
    path = tmp_path / f"live{suffix}"
    recorder = Recorder(path, SensorLayout(grid32()), flush_interval=0.5)
    stress = frames_for(13, seed=1)  # fixed seed
    exact = suffix == ".npz"

    def check(count):
        loaded = recording.load(path)
        assert len(loaded) == count == recorder.written
        np.testing.assert_array_equal(loaded.seq, np.arange(count) + 1000)
        np.testing.assert_allclose(loaded.t, np.arange(count) / 10, atol=1e-9)
        if exact:
            np.testing.assert_array_equal(loaded.frames, stress[:count])
        else:
            np.testing.assert_allclose(loaded.frames, stress[:count], rtol=1e-8)  # 9 digits in CSV
        assert loaded.grid.shape == (2, 3) and loaded.grid.pitch == 2e-3

    for k in range(5):
        recorder.add(1000 + k, k / 10, stress[k])  # t = 0 .. 0.4: less than flush_interval since the first
    assert recorder.written == 0
    with pytest.raises(recording.RecordingError):
        recording.load(path)  # nothing flushed yet: no frames (but a valid header)
    recorder.add(1005, 0.5, stress[5])  # 0.5 s after the first frame: flushes all six
    check(6)
    for k in range(6, 10):
        recorder.add(1000 + k, k / 10, stress[k])
    check(6)  # t = 0.9: not yet
    recorder.add(1010, 1.0, stress[10])
    check(11)  # 0.5 s after the last flush
    recorder.add(1011, 1.1, stress[11])
    recorder.add(1012, 1.2, stress[12])
    recorder.tick(1.4)  # a quiet line, but only 0.4 s since the last flush
    check(11)
    recorder.tick(1.5)  # the frames waiting must not wait for the next one to arrive
    check(13)
    recorder.tick(5.0)  # nothing waiting: nothing written
    check(13)


def test_recorder_close_makes_a_plain_npz(tmp_path):
    path = tmp_path / "live.npz"
    recorder = Recorder(path, SensorLayout(grid32(), "kPa"), flush_interval=0.25, description="bench run")
    stress = frames_for(20, seed=2)  # fixed seed
    for k in range(20):
        recorder.add(k, k / 20, stress[k])
    assert 0 < recorder.written < 20  # some flushed in chunks, the rest waits for close
    assert recorder.close() == path
    with np.load(path) as data:
        assert {"frames", "t", "seq"} <= set(data.files)
        assert not [name for name in data.files if name.startswith("chunk")]
        np.testing.assert_array_equal(data["frames"], stress)
    loaded = recording.load(path)
    np.testing.assert_array_equal(loaded.frames, stress)  # already pascals: the recording says "Pa"
    np.testing.assert_array_equal(loaded.t, np.arange(20) / 20)
    np.testing.assert_array_equal(loaded.seq, np.arange(20))
    assert loaded.description == "bench run"
    assert not path.with_name(path.name + ".tmp").exists()


def test_recorder_close_csv(tmp_path):
    path = tmp_path / "live.csv"
    recorder = Recorder(path, SensorLayout(grid32()), description="two\nlines")
    stress = frames_for(4, seed=3)  # fixed seed
    for k in range(4):
        recorder.add(7 + k, 0.001 * k, stress[k])
    assert recorder.close() == path
    text = path.read_text()
    assert "# columns=seq,t\n" in text and "# description=two lines\n" in text
    loaded = recording.load(path)
    np.testing.assert_array_equal(loaded.seq, [7, 8, 9, 10])
    np.testing.assert_allclose(loaded.t, 0.001 * np.arange(4), atol=1e-9)
    np.testing.assert_allclose(loaded.frames, stress, rtol=1e-8)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_recorder_keeps_poisson_ratio_and_sensor_size(tmp_path, suffix):
    # both while recording (a crash leaves the unclosed file) and after close() rewrote it
    path = tmp_path / f"live{suffix}"
    recorder = Recorder(path, SensorLayout(grid_with_material()), flush_interval=0.1)
    stress = frames_for(5, seed=4)  # fixed seed
    for k in range(5):
        recorder.add(k, k / 10, stress[k])
    unclosed = recording.load(path).grid
    assert unclosed.poisson_ratio == NU and unclosed.sensor_size == TAXEL
    assert recorder.close() == path
    closed = recording.load(path)
    assert closed.grid.poisson_ratio == NU and closed.grid.sensor_size == TAXEL and len(closed) == 5
    if suffix == ".csv":
        text = path.read_text()
        assert f"# poisson_ratio={NU!r}\n" in text and f"# sensor_size={TAXEL!r}\n" in text


@pytest.mark.parametrize("suffix", [".npz", ".CSV"])
def test_recorder_close_without_frames_leaves_no_file(tmp_path, suffix):
    path = tmp_path / f"empty{suffix}"
    recorder = Recorder(path, SensorLayout(grid32()))
    assert path.exists()  # created at once, so that a bad path fails when recording starts
    assert recorder.close() is None
    assert not path.exists()


def test_recorder_rejects_unknown_extensions(tmp_path):
    with pytest.raises(ValueError, match=r"unknown recording type '\.txt', expected \.npz or \.csv"):
        Recorder(tmp_path / "live.txt", SensorLayout(grid32()))
    assert not (tmp_path / "live.txt").exists()


# -- SerialReader on a pseudo-terminal ------------------------------------------------------------

@pytest.fixture
def pty():
    """A raw pseudo-terminal: (master fd to write the board's bytes to, slave device path)."""
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo, no newline translation
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


@pytest.fixture
def make_reader(pty):
    readers = []

    def make(**kwargs):
        layout = SensorLayout(grid32(), "kPa")
        reader = SerialReader(pty[1], layout, **kwargs)
        readers.append(reader)
        return reader

    yield make
    for reader in readers:
        reader.stop()  # always: the worker thread must not outlive the test


def write_all(fd, data):
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def values(k):
    return np.linspace(0.5, 3.0, 6) + k  # kPa; exact in float32


def test_reader_calibrates_to_pascals_and_keeps_the_newest(pty, make_reader):
    reader = make_reader()
    reader.start()
    assert reader.state == "connected"
    write_all(pty[0], b"".join(encode_binary(s, values(s)) for s in (0, 1, 2)))
    wait_for(lambda: reader.stats.received == 3, what="three frames")
    frame = reader.take_latest()
    assert frame.seq == 2 and frame.t >= 0
    np.testing.assert_array_equal(frame.stress, values(2) * 1000)  # kPa -> Pa
    assert reader.take_latest() is None  # taken: nothing new since
    assert reader.stats.lost == 0 and reader.rejected() == {}


def test_on_frame_fires_once_until_taken(pty, make_reader):
    calls = []
    reader = make_reader(on_frame=lambda: calls.append(threading.current_thread().name))
    reader.start()
    write_all(pty[0], encode_binary(0, values(0)))
    wait_for(lambda: len(calls) == 1, what="the first notification")
    assert calls[0].startswith("serial ")  # called from the reader thread, not ours
    write_all(pty[0], encode_binary(1, values(1)))
    wait_for(lambda: reader.stats.received == 2, what="the second frame")
    write_all(pty[0], encode_binary(2, values(2)))
    wait_for(lambda: reader.stats.received == 3, what="the third frame")
    assert len(calls) == 1  # the GUI has not taken the first yet: no second notification
    # a frame is published just after it is counted: wait for it before taking, without re-arming
    wait_for(lambda: reader._latest is not None and reader._latest.seq == 2, what="the third frame published")
    assert len(calls) == 1
    assert reader.take_latest().seq == 2  # the newest; the ones before it were skipped, as the GUI may
    write_all(pty[0], encode_binary(3, values(3)))
    wait_for(lambda: len(calls) == 2, what="the notification after taking")
    assert reader.take_latest().seq == 3


def test_reader_skips_garbage(pty, make_reader):
    reader = make_reader()
    reader.start()
    rng = np.random.default_rng(4)  # fixed seed
    garbage = bytes(b for b in rng.integers(0, 256, 300, dtype=np.uint8).tobytes() if b != 0xA5)  # no sync
    write_all(pty[0], garbage + encode_binary(0, values(0)) + garbage[:50] + encode_binary(1, values(1)))
    wait_for(lambda: reader.stats.received == 2, what="both frames past the garbage")
    assert reader.decoder.skipped_bytes == len(garbage) + 50
    assert reader.take_latest().seq == 1


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_reader_records_every_frame(pty, make_reader, tmp_path, suffix):
    reader = make_reader()
    reader.start()
    recorder = reader.start_recording(tmp_path / f"rec{suffix}", flush_interval=0.05)
    assert reader.recorder is recorder
    for start in range(0, 300, 50):  # bursts, so that the reader sees many reads
        write_all(pty[0], b"".join(encode_binary(s, values(s % 7)) for s in range(start, start + 50)))
        time.sleep(0.01)
    wait_for(lambda: reader.stats.received == 300, what="300 frames")
    path = reader.stop_recording()
    assert path == tmp_path / f"rec{suffix}" and reader.recorder is None
    loaded = recording.load(path)
    np.testing.assert_array_equal(loaded.seq, np.arange(300))  # every frame, no gap
    np.testing.assert_allclose(loaded.frames, np.array([values(s % 7) for s in range(300)]) * 1000, rtol=1e-8)
    assert np.all(np.diff(loaded.t) >= 0)
    assert reader.stats.lost == 0


def test_reader_start_fails_at_once_on_a_missing_device(tmp_path):
    reader = SerialReader(str(tmp_path / "no-such-tty"), SensorLayout(grid32()))
    try:
        with pytest.raises(serial.SerialException) as info:
            reader.start()
        assert isinstance(info.value, OSError)
        assert reader._thread is None  # no worker left retrying behind the caller's back
    finally:
        reader.stop()


def test_reader_rejects_an_unknown_format():
    with pytest.raises(ValueError, match=r"fmt must be one of .*'hex'"):
        SerialReader("loop://", SensorLayout(grid32()), fmt="hex")


def test_reader_reads_a_socket_url_and_reconnects_to_it():
    import socket

    # a board behind TCP (pyserial's socket:// URL), dropped and reaccepted
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    layout = SensorLayout(grid32(), "kPa")
    accepted = []
    thread = threading.Thread(target=lambda: accepted.append(server.accept()[0]), daemon=True)
    thread.start()
    reader = SerialReader(f"socket://127.0.0.1:{port}", layout, reconnect_interval=0.05)
    try:
        reader.start()
        thread.join(5)
        accepted[0].sendall(b"".join(encode_binary(s, values(s)) for s in range(5)))
        wait_for(lambda: reader.stats.received == 5, what="five frames over TCP")
        np.testing.assert_array_equal(reader.take_latest().stress, values(4) * 1000)
        thread = threading.Thread(target=lambda: accepted.append(server.accept()[0]), daemon=True)
        thread.start()
        accepted[0].close()  # the board goes away ...
        thread.join(5)  # ... and the reader is back as soon as the server takes it again
        wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
        accepted[1].sendall(encode_binary(0, values(7)))
        wait_for(lambda: reader.stats.received == 6, what="a frame after reconnecting")
        assert reader.stats.lost == 0 and reader.failures == 0
    finally:
        reader.stop()
        for connection in accepted:
            connection.close()
        server.close()


def test_an_irregular_layout_round_trips(tmp_path):
    rng = np.random.default_rng(13)  # fixed seed: the same scattered taxels every run
    grid = SensorGrid(rng.uniform(-4e-3, 4e-3, (36, 2)), 1.5e-3, 2e-3, (36,))
    path = save_layout(SensorLayout(grid, "Pa"), tmp_path / "scattered.json")
    spec = json.loads(path.read_text())
    assert spec["taxels"] == 36 and "nx" not in spec and len(spec["positions"]) == 36
    back = load_layout(path)
    assert back.grid.shape == (36,)
    np.testing.assert_array_equal(back.grid.positions, grid.positions)


def test_a_layout_declaring_a_huge_grid_is_refused(tmp_path):
    path = tmp_path / "huge.json"
    path.write_text('{"nx": 100000, "ny": 100000, "pitch": 0.002, "thickness": 0.002}')
    with pytest.raises(LayoutError, match=r"huge.json: a 100000x100000 grid is not a skin this viewer opens"):
        load_layout(path)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_recorder_records_an_irregular_layout(tmp_path, suffix):
    rng = np.random.default_rng(14)  # fixed seed: the same scattered taxels and frames every run
    grid = SensorGrid(rng.uniform(-4e-3, 4e-3, (9, 2)), 1.5e-3, 2e-3, (9,))
    path = tmp_path / f"scattered{suffix}"
    recorder = Recorder(path, SensorLayout(grid), flush_interval=0.1)
    stress = rng.uniform(0, 1e3, (4, 9))
    for k in range(4):
        recorder.add(k, k / 10, stress[k])
    assert recording.load(path).grid.shape == (9,)  # unclosed, as after a crash
    recorder.close()
    back = recording.load(path)
    assert back.grid.shape == (9,) and len(back) == 4
    np.testing.assert_array_equal(back.grid.positions, grid.positions)
    np.testing.assert_allclose(back.frames, stress, rtol=1e-8)

"""tactile-sim: the Board byte stream, the contact cycle, and the command line on a real pseudo-terminal."""

import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import serial

from solver import SensorGrid
from tactile_viewer.layout import SensorLayout, load_layout
from tactile_viewer.protocol import BinaryDecoder, TextDecoder, crc16, make_decoder
from tactile_viewer.simulator import Board, contact_cycle, main


@pytest.fixture(scope="module")
def layout():
    # 4x4 keeps the precomputed cycle fast; kPa as the CLI sends by default
    return SensorLayout(SensorGrid.regular(4, 4, 2e-3, 2e-3), "kPa")


def stream(board, frames):
    return b"".join(board.next_bytes() for _ in range(frames))


def decode(fmt, count, data, seed=0):
    """Feed ``data`` in random pieces (as a serial port delivers it); the decoder and its frames."""
    decoder = make_decoder(fmt, count)
    rng = np.random.default_rng(seed)
    frames, start = [], 0
    while start < len(data):
        end = start + int(rng.integers(1, 200))
        frames += decoder.feed(data[start:end])
        start = end
    return decoder, frames


def clean(board, seq):
    """The noiseless frame ``seq`` in the units on the wire (the cycle advances with time, not frames)."""
    index = int((seq / board.rate) / 2.0 * len(board.cycle)) % len(board.cycle)
    return board.cycle[index] * 1e-3


# -- Board ----------------------------------------------------------------------------------------

def test_board_cycle_is_the_contact_cycle(layout):
    board = Board(layout)
    np.testing.assert_array_equal(board.cycle, contact_cycle(layout.grid))


@pytest.mark.parametrize("fmt", ["binary", "text"])
def test_noiseless_board_sends_the_clean_cycle(layout, fmt):
    board = Board(layout, fmt=fmt, rate=50.0, noise=0.0)  # 50 Hz: one cycle row per frame
    decoder, frames = decode(fmt, layout.count, stream(board, 250))
    assert board.sent == len(frames) == decoder.accepted == 250
    assert board.dropped == board.garbage_bursts == 0 and decoder.skipped_bytes == 0 and not decoder.rejected
    expected = np.array([clean(board, k) for k in range(250)])
    np.testing.assert_array_equal(expected[100], expected[0])  # the contact went once round in 2 s
    got = np.array([f.values for f in frames])
    if fmt == "binary":
        assert [f.seq for f in frames] == list(range(250))
        np.testing.assert_array_equal(got, expected.astype(np.float32))  # float32 on the wire, exactly
    else:
        assert all(f.seq is None for f in frames)
        np.testing.assert_allclose(got, expected, rtol=5e-6, atol=0)  # six significant digits


def test_noise_is_gaussian_relative_to_the_peak(layout):
    board = Board(layout, rate=100.0, noise=0.02, seed=11)  # fixed seed
    _, frames = decode("binary", layout.count, stream(board, 400))
    assert [f.seq for f in frames] == list(range(400))
    residual = np.array([f.values - clean(board, f.seq) for f in frames])
    sigma = 0.02 * np.abs(board.cycle).max() * 1e-3
    assert board.noise * 1e-3 == pytest.approx(sigma)
    assert np.abs(residual).max() < 6 * sigma  # 6400 samples: 6 sigma is never reached by chance
    assert residual.std() == pytest.approx(sigma, rel=0.05)
    assert abs(residual.mean()) < 0.05 * sigma


def test_boards_with_the_same_seed_send_the_same_bytes(layout):
    a = Board(layout, noise=0.01, garbage=0.2, dropout=0.1, seed=3)  # fixed seed
    b = Board(layout, noise=0.01, garbage=0.2, dropout=0.1, seed=3)
    assert stream(a, 50) == stream(b, 50)


def test_dropout_leaves_sequence_gaps_of_exactly_the_dropped_frames(layout):
    board = Board(layout, dropout=0.2, seed=5)  # fixed seed
    decoder, frames = decode("binary", layout.count, stream(board, 300))
    seqs = [f.seq for f in frames]
    assert 30 < board.dropped < 90 and board.sent + board.dropped == 300 == board.seq
    assert len(frames) == board.sent and decoder.skipped_bytes == 0
    assert seqs == sorted(seqs)
    missing = set(range(300)) - set(seqs)
    assert len(missing) == board.dropped
    # the gaps inside the stream plus any drops at its two ends
    assert sum(np.diff(seqs) - 1) + seqs[0] + (299 - seqs[-1]) == board.dropped


def test_binary_garbage_is_counted_and_every_frame_recovered(layout):
    board = Board(layout, fmt="binary", garbage=0.3, seed=9)  # fixed seed
    decoder, frames = decode("binary", layout.count, stream(board, 400), seed=1)
    assert 60 < board.garbage_bursts < 180 and board.garbage_bytes >= board.garbage_bursts
    assert [f.seq for f in frames] == list(range(400))  # every frame, in order
    # each garbage byte is skipped exactly once, by the search or by a rejected false sync
    assert decoder.skipped_bytes == board.garbage_bytes


def test_text_garbage_lines_are_rejected_or_skipped(layout):
    board = Board(layout, fmt="text", rate=50.0, noise=0.0, garbage=0.3, seed=9)  # fixed seed
    decoder, frames = decode("text", layout.count, stream(board, 300), seed=2)
    assert board.garbage_bursts > 50
    assert len(frames) == board.sent == 300
    # a bad line is rejected (not numbers, wrong count); a blank or '#' one is skipped uncounted
    assert 0 < sum(decoder.rejected.values()) <= board.garbage_bursts
    np.testing.assert_allclose([f.values for f in frames], [clean(board, k) for k in range(300)], rtol=5e-6)


def test_board_checksum_ends_each_text_line_with_its_crc(layout):
    plain = Board(layout, fmt="text", rate=50.0, noise=0.01, seed=4)  # fixed seed, the same for both
    checked = Board(layout, fmt="text", rate=50.0, noise=0.01, seed=4, checksum=True)
    data, reference = stream(checked, 200), stream(plain, 200)
    lines = data.splitlines()
    assert len(lines) == 200
    for line in lines:
        body, digits = re.fullmatch(rb"([^*]+)\*([0-9A-F]{4})", line).groups()
        assert int(digits, 16) == crc16(body)
    # the same frames as without checksum, each followed by its "*XXXX"
    assert re.sub(rb"\*[0-9A-F]{4}\n", b"\n", data) == reference
    decoder, frames = decode("text", layout.count, data, seed=3)
    assert len(frames) == 200 and not decoder.rejected and decoder.checked
    _, expected = decode("text", layout.count, reference)
    np.testing.assert_array_equal([f.values for f in frames], [f.values for f in expected])


def test_board_checksum_rejects_text_garbage_lines_as_missing_their_checksum(layout):
    board = Board(layout, fmt="text", rate=50.0, noise=0.0, garbage=0.3, seed=9, checksum=True)  # fixed seed
    decoder, frames = decode("text", layout.count, stream(board, 300), seed=2)
    assert board.garbage_bursts > 50 and len(frames) == board.sent == 300
    np.testing.assert_allclose([f.values for f in frames], [clean(board, k) for k in range(300)], rtol=5e-6)
    # after the first checked line, a garbage line (blank and "#" ones aside) lacks a checksum
    assert decoder.rejected["missing checksum"] > 0
    assert 0 < sum(decoder.rejected.values()) <= board.garbage_bursts


def test_board_refuses_a_checksum_for_binary_frames(layout):
    with pytest.raises(ValueError, match=r"checksum applies to the text format only \(binary frames always "
                                         r"carry a CRC\), got fmt='binary'"):
        Board(layout, fmt="binary", checksum=True)


def test_board_sends_in_the_layout_units():
    grid = SensorGrid.regular(3, 2, 2e-3, 2e-3)
    pascals = Board(SensorLayout(grid, "Pa"), noise=0.0)
    megapascals = Board(SensorLayout(grid, "MPa"), noise=0.0)
    _, (pa,) = decode("binary", 6, pascals.next_bytes())
    _, (mpa,) = decode("binary", 6, megapascals.next_bytes())
    np.testing.assert_allclose(mpa.values * 1e6, pa.values, rtol=1e-6)
    np.testing.assert_allclose(pa.values, pascals.cycle[0], rtol=1e-7)


# -- contact_cycle --------------------------------------------------------------------------------

def test_contact_cycle_circles_the_centre():
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    cycle = contact_cycle(grid, 8)
    assert cycle.shape == (8, 64) and np.all(np.isfinite(cycle))
    assert np.all(cycle.sum(axis=1) > 0)  # a press, every frame
    weights = np.clip(cycle, 0, None)
    centroids = weights @ grid.positions / weights.sum(axis=1, keepdims=True)
    # frame k is at angle 2 pi k / 8 around the centre: the centroid follows it round
    angles = np.arctan2(centroids[:, 1], centroids[:, 0])
    turned = np.angle(np.exp(1j * (angles - 2 * np.pi * np.arange(8) / 8)))
    assert np.abs(turned).max() < 0.2
    assert np.linalg.norm(centroids[0] - centroids[4]) > 2 * grid.pitch  # opposite sides: it moved
    assert np.all(np.linalg.norm(centroids, axis=1) > grid.pitch)  # never parked on the centre


# -- the command line -----------------------------------------------------------------------------

def run_sim(tmp_path, *options):
    link, layout = tmp_path / "board", tmp_path / "layout.json"
    process = subprocess.Popen(
        [sys.executable, "-m", "tactile_viewer.simulator", "--link", str(link), "--layout", str(layout),
         *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return process, link, layout


def read_link_until_exit(link, process):
    """Open the board's link as a reader would and take everything until the board exits."""
    port = serial.serial_for_url(str(link), timeout=0.05)
    try:
        return read_until_exit(port, process)
    finally:
        port.close()


def read_until_exit(port, process, timeout=15.0):
    """Everything the board sends until it exits (its pseudo-terminal then reports an error)."""
    data = bytearray()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            chunk = port.read(max(1, port.in_waiting))
        except (serial.SerialException, OSError):
            break  # the master side closed: the board is gone
        data += chunk
        if not chunk and process.poll() is not None:
            break
    else:
        pytest.fail("the simulator did not finish in time")
    return bytes(data)


@pytest.fixture
def processes():
    started = []
    yield started
    for process in started:
        if process.poll() is None:
            process.kill()
        process.communicate(timeout=10)


def test_cli_streams_through_a_linked_pseudo_terminal(tmp_path, processes):
    process, link, layout_path = run_sim(tmp_path, "--rate", "500", "--duration", "1",
                                         "--nx", "6", "--ny", "4", "--noise", "0")
    processes.append(process)
    line = process.stdout.readline().strip()
    assert line.startswith("/dev/pts/") and line.endswith(f"(link {link})")
    device = line.split()[0]
    assert link.is_symlink() and os.path.realpath(link) == os.path.realpath(device)  # exists while running
    data = read_link_until_exit(link, process)
    assert process.wait(timeout=10) == 0
    assert not link.exists() and not link.is_symlink()  # removed at exit
    assert "sent 500 frames, dropped 0" in process.stderr.read()

    layout = load_layout(layout_path)
    assert layout.grid.shape == (4, 6) and layout.units == "kPa" and layout.grid.pitch == 2e-3
    decoder = BinaryDecoder(layout.count)
    frames = decoder.feed(data)
    seqs = np.array([f.seq for f in frames])
    # opening the port flushes what was queued before, so the first few may be missed; none after that
    assert len(frames) >= 450 and seqs[-1] == 499
    np.testing.assert_array_equal(np.diff(seqs), 1)
    assert not decoder.rejected and decoder.pending == 0
    # the frames are the cycle of the layout it wrote, in kPa
    cycle = contact_cycle(layout.grid) * 1e-3
    index = (seqs / 500 / 2.0 * len(cycle)).astype(int) % len(cycle)
    np.testing.assert_allclose([f.values for f in frames], cycle[index], rtol=1e-6)


def test_cli_text_format(tmp_path, processes):
    process, link, layout_path = run_sim(tmp_path, "--format", "text", "--rate", "200", "--duration", "0.5",
                                         "--nx", "3", "--ny", "2", "--noise", "0")
    processes.append(process)
    process.stdout.readline()
    data = read_link_until_exit(link, process)
    assert process.wait(timeout=10) == 0
    layout = load_layout(layout_path)
    decoder = TextDecoder(layout.count)
    frames = decoder.feed(data)
    # the port may open in the middle of a line: at most that one is rejected
    assert len(frames) >= 80 and sum(decoder.rejected.values()) <= 1
    cycle = contact_cycle(layout.grid) * 1e-3
    for frame in frames[1:]:  # the first may be the tail of a cut line that still parses
        assert np.abs(frame.values / cycle - 1).max(axis=1).min() < 1e-5  # one of the cycle's frames


def test_cli_text_format_with_checksum(tmp_path, processes):
    process, link, layout_path = run_sim(tmp_path, "--format", "text", "--checksum", "--rate", "200",
                                         "--duration", "0.5", "--nx", "3", "--ny", "2", "--noise", "0")
    processes.append(process)
    process.stdout.readline()
    data = read_link_until_exit(link, process)
    assert process.wait(timeout=10) == 0
    layout = load_layout(layout_path)
    decoder = TextDecoder(layout.count)
    frames = decoder.feed(data)
    # the port may open in the middle of a line: at most that one fails its checksum
    assert len(frames) >= 80 and decoder.checked and sum(decoder.rejected.values()) <= 1
    assert all(re.fullmatch(rb"[^*]+\*[0-9A-F]{4}", line) for line in data.splitlines()[1:])
    cycle = contact_cycle(layout.grid) * 1e-3
    for frame in frames:  # a cut first line fails its checksum instead of passing as a tail that parses
        assert np.abs(frame.values / cycle - 1).max(axis=1).min() < 1e-5


@pytest.mark.parametrize("options", [["--checksum"], ["--checksum", "--format", "binary"]])
def test_cli_refuses_checksum_with_binary_frames(options, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main([*options, "--link", str(tmp_path / "board")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: tactile-sim")
    assert err.splitlines()[-1].endswith("--checksum needs --format text (binary frames always carry a CRC), "
                                         "got --format binary")
    assert not (tmp_path / "board").exists()


def test_cli_sigterm_exits_cleanly_and_removes_the_link(tmp_path, processes):
    process, link, _ = run_sim(tmp_path, "--rate", "200", "--nx", "3", "--ny", "2")  # no duration: runs on
    processes.append(process)
    process.stdout.readline()
    port = serial.serial_for_url(str(link), timeout=0.05)
    try:
        deadline = time.monotonic() + 10
        while not port.read(64):  # bytes flowing: the main loop (and its SIGTERM handler) is running
            assert time.monotonic() < deadline, "no bytes from the simulator"
    finally:
        port.close()
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=10) == 0
    assert not link.is_symlink()
    assert "sent " in process.stderr.read()


@pytest.mark.parametrize("option, value", [
    ("--rate", "0"), ("--rate", "2000"), ("--rate", "nan"), ("--garbage", "1.5"), ("--dropout", "-0.1"),
    ("--nx", "0"), ("--ny", "-2"), ("--pitch", "0"), ("--format", "hex"), ("--units", "counts"),
])
def test_cli_rejects_bad_arguments(option, value, capsys, tmp_path):
    # argument errors come before the pseudo-terminal is opened, so main() can run in this process
    with pytest.raises(SystemExit) as info:
        main([option, value, "--link", str(tmp_path / "board")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: tactile-sim")
    assert option.lstrip("-") in err.splitlines()[-1]  # the message names the option
    assert not (tmp_path / "board").exists()


def test_cli_writes_poisson_ratio_and_sensor_size_to_its_layout(tmp_path):
    layout_path = tmp_path / "layout.json"
    out = subprocess.run([sys.executable, "-m", "tactile_viewer.simulator", "--nx", "3", "--ny", "2",
                          "--poisson-ratio", "0.45", "--sensor-size", "1e-3", "--duration", "0",
                          "--layout", str(layout_path), "--link", str(tmp_path / "board")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-500:]
    grid = load_layout(layout_path).grid
    assert grid.poisson_ratio == 0.45 and grid.sensor_size == 1e-3 and grid.shape == (2, 3)


def test_cli_layout_defaults_to_an_incompressible_layer_and_point_sensors(tmp_path):
    layout_path = tmp_path / "layout.json"
    out = subprocess.run([sys.executable, "-m", "tactile_viewer.simulator", "--nx", "3", "--ny", "2",
                          "--duration", "0", "--layout", str(layout_path), "--link", str(tmp_path / "board")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-500:]
    spec = json.loads(layout_path.read_text())
    assert spec["poisson_ratio"] == 0.5 and spec["sensor_size"] == 0.0


@pytest.mark.parametrize("option, value, message", [
    ("--poisson-ratio", "0.7", r"poisson_ratio must be a finite number in [0, 0.5], got 0.7"),
    ("--poisson-ratio", "nan", r"poisson_ratio must be a finite number in [0, 0.5], got nan"),
    ("--sensor-size", "3e-3", r"sensor_size must be at most the pitch (taxels cannot overlap), got 0.003 m"),
    ("--sensor-size", "-1e-3", r"sensor_size must be a finite number of metres >= 0"),
])
def test_cli_rejects_an_impossible_material_or_taxel(option, value, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main([f"{option}={value}", "--link", str(tmp_path / "board")])  # "=": argparse takes -1e-3 for an option
    assert info.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "board").exists()


def test_cli_rejects_negative_noise(tmp_path):
    out = subprocess.run([sys.executable, "-m", "tactile_viewer.simulator", "--noise", "-0.1", "--nx", "3",
                          "--ny", "2", "--duration", "0.2", "--link", str(tmp_path / "board")],
                         capture_output=True, text=True, timeout=30)
    assert out.returncode == 2 and "--noise" in out.stderr, out.stderr[-500:]


def test_cli_duration_bounds_the_frame_count():
    # --duration 0.1 at 100 Hz: exactly 10 sequence numbers are used, even with nobody reading
    out = subprocess.run([sys.executable, "-m", "tactile_viewer.simulator", "--rate", "100",
                          "--duration", "0.1", "--nx", "3", "--ny", "2",
                          "--dropout", "0.5", "--seed", "1"],  # fixed seed: some dropped, some sent
                         capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    counts = re.search(r"sent (\d+) frames, dropped (\d+)", out.stderr)
    sent, dropped = int(counts[1]), int(counts[2])
    assert sent + dropped == 10 and dropped > 0


def test_the_port_and_layout_exist_before_the_contact_is_computed(tmp_path, monkeypatch, capsys):
    # a viewer told the port connects at once: the slow part (the finely integrated contact) comes
    # after the device path is printed, the link made and the layout written
    import threading

    from tactile_viewer import simulator

    link, layout = tmp_path / "board", tmp_path / "board.json"
    seen = {}
    release = threading.Event()

    def slow_cycle(grid, *args, **kwargs):
        release.wait(10)
        return np.zeros((4, grid.size))

    def look():
        deadline = time.monotonic() + 10
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        seen.update(link=link.exists(), layout=layout.exists(), opened=serial.Serial(str(link)).is_open)
        release.set()
    monkeypatch.setattr(simulator, "contact_cycle", slow_cycle)
    checker = threading.Thread(target=look)
    checker.start()
    assert main(["--link", str(link), "--layout", str(layout), "--duration", "0.05"]) == 0
    checker.join()
    assert seen == dict(link=True, layout=True, opened=True)  # all while the contact was computing
    assert capsys.readouterr().out.startswith("/dev/pts/")

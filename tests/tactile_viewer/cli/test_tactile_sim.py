"""tactile-sim: the Board byte stream, the scenes, the lazy cycle, the command line on a real pseudo-terminal."""

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import tty

import numpy as np
import pytest
import serial

from solver import SensorGrid
from tactile_viewer.cli import tactile_sim
from tactile_viewer.cli.tactile_sim import Board, main
from tactile_viewer.io.layout import SensorLayout, load_layout
from tactile_viewer.sources import simulated
from tactile_viewer.sources.protocol import BinaryDecoder, TextDecoder, crc16, make_decoder
from tactile_viewer.sources.simulated import SCENES, Cycle, contact_cycle, scene_contacts
from tests.tactile_viewer.sources.test_simulated import fake_frames


@pytest.fixture(scope="module")
def layout():
    # 4x4 keeps the cycle fast; kPa as the CLI sends by default
    return SensorLayout(SensorGrid.regular(4, 4, 2e-3, 2e-3), "kPa")


@pytest.fixture
def make_board():
    """``make_board(layout, **options)``: a :class:`Board` closed when the test ends, however it ends."""
    boards = []

    def make(*args, **kwargs):
        boards.append(Board(*args, **kwargs))
        return boards[-1]
    try:
        yield make
    finally:
        for board in boards:
            board.close()


def wait_for(condition, what, timeout=30.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


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
    index = int((seq / board.rate) / board.period * len(board.cycle)) % len(board.cycle)
    assert index == board.index(seq)
    return board.cycle[index] * 1e-3


# -- Board ----------------------------------------------------------------------------------------

def test_board_cycle_is_the_contact_cycle(layout, make_board):
    board = make_board(layout)
    assert board.period == 2.0 and len(board.cycle) == 100  # the circling contact, by default
    cycle = contact_cycle(layout.grid)
    for k in (0, 13, 50, 99):
        # computed here, independently of any cycle: the scene's contacts through the bonded layer ...
        contacts = scene_contacts("circle", layout.grid, k / 100)
        coarse = simulated.loads.simulate(layout.grid, contacts, medium="layer",
                                          subdivisions=simulated._subdivisions(layout.grid, contacts))
        np.testing.assert_array_equal(board.cycle[k], coarse.clean_stress)
        np.testing.assert_array_equal(cycle[k], coarse.clean_stress)
        # ... and on loads' default (finer) sub-cells: within 0.65% of the peak, as the module says
        fine = simulated.loads.simulate(layout.grid, contacts, medium="layer").clean_stress
        np.testing.assert_allclose(board.cycle[k], fine, rtol=0, atol=0.0065 * np.abs(fine).max())


@pytest.mark.parametrize("fmt", ["binary", "text"])
def test_noiseless_board_sends_the_clean_cycle(layout, fmt, make_board):
    board = make_board(layout, fmt=fmt, rate=50.0, noise=0.0)  # 50 Hz: one cycle row per frame
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


def test_noise_is_gaussian_relative_to_the_frames_peak(layout, make_board):
    board = make_board(layout, rate=100.0, noise=0.02, seed=11)  # fixed seed
    _, frames = decode("binary", layout.count, stream(board, 400))
    assert [f.seq for f in frames] == list(range(400))
    # in units of each frame's own sigma: 2% of its peak clean stress (as loads.simulate has it)
    sigma = np.array([0.02 * np.abs(clean(board, f.seq)).max() for f in frames])
    assert sigma.max() > 1.5 * sigma.min()  # the circling contact's force varies: so does the noise
    residual = np.array([(f.values - clean(board, f.seq)) / s for f, s in zip(frames, sigma, strict=True)])
    assert np.abs(residual).max() < 6  # 6400 samples: 6 sigma is never reached by chance
    assert residual.std() == pytest.approx(1.0, rel=0.05)
    assert abs(residual.mean()) < 0.05


def test_an_unloaded_start_gives_a_tare_its_moment_then_the_scene(layout, make_board):
    # before: the simulator's contact never left the skin, so every tare taken on it warned
    from tactile_viewer.sources.live import loaded_while_taring

    board = make_board(layout, rate=50.0, noise=0.01, seed=12, unloaded=1.0)  # fixed seed; 50 frames unloaded
    _, frames = decode("binary", layout.count, stream(board, 100))
    values = np.array([f.values for f in frames])
    assert loaded_while_taring(values[:50] * 1e3, np.zeros(layout.count)) is None  # kPa on the wire
    assert np.abs(values[:50]).max() < 0.1 * np.abs(values[50:]).max()  # then the contact comes
    np.testing.assert_allclose(values[50:], [clean(board, k) for k in range(50, 100)],
                               atol=6 * 0.01 * max(board.cycle.peak(k) for k in range(100)))


def test_boards_with_the_same_seed_send_the_same_bytes(layout, make_board):
    a = make_board(layout, noise=0.01, garbage=0.2, dropout=0.1, seed=3)  # fixed seed
    b = make_board(layout, noise=0.01, garbage=0.2, dropout=0.1, seed=3)
    assert stream(a, 50) == stream(b, 50)


def test_dropout_leaves_sequence_gaps_of_exactly_the_dropped_frames(layout, make_board):
    board = make_board(layout, dropout=0.2, seed=5)  # fixed seed
    decoder, frames = decode("binary", layout.count, stream(board, 300))
    seqs = [f.seq for f in frames]
    assert 30 < board.dropped < 90 and board.sent + board.dropped == 300 == board.seq
    assert len(frames) == board.sent and decoder.skipped_bytes == 0
    assert seqs == sorted(seqs)
    missing = set(range(300)) - set(seqs)
    assert len(missing) == board.dropped
    # the gaps inside the stream plus any drops at its two ends
    assert sum(np.diff(seqs) - 1) + seqs[0] + (299 - seqs[-1]) == board.dropped


def test_binary_garbage_is_counted_and_every_frame_recovered(layout, make_board):
    board = make_board(layout, fmt="binary", garbage=0.3, seed=9)  # fixed seed
    decoder, frames = decode("binary", layout.count, stream(board, 400), seed=1)
    assert 60 < board.garbage_bursts < 180 and board.garbage_bytes >= board.garbage_bursts
    assert [f.seq for f in frames] == list(range(400))  # every frame, in order
    # each garbage byte is skipped exactly once, by the search or by a rejected false sync
    assert decoder.skipped_bytes == board.garbage_bytes


def test_text_garbage_lines_are_rejected_or_skipped(layout, make_board):
    board = make_board(layout, fmt="text", rate=50.0, noise=0.0, garbage=0.3, seed=9)  # fixed seed
    decoder, frames = decode("text", layout.count, stream(board, 300), seed=2)
    assert board.garbage_bursts > 50
    assert len(frames) == board.sent == 300
    # a bad line is rejected (not numbers, wrong count); a blank or '#' one is skipped uncounted
    assert 0 < sum(decoder.rejected.values()) <= board.garbage_bursts
    np.testing.assert_allclose([f.values for f in frames], [clean(board, k) for k in range(300)], rtol=5e-6)


def test_board_checksum_ends_each_text_line_with_its_crc(layout, make_board):
    plain = make_board(layout, fmt="text", rate=50.0, noise=0.01, seed=4)  # fixed seed, the same for both
    checked = make_board(layout, fmt="text", rate=50.0, noise=0.01, seed=4, checksum=True)
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


def test_board_checksum_rejects_text_garbage_lines_as_missing_their_checksum(layout, make_board):
    board = make_board(layout, fmt="text", rate=50.0, noise=0.0, garbage=0.3, seed=9, checksum=True)  # fixed seed
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


def test_board_sends_in_the_layout_units(make_board):
    grid = SensorGrid.regular(3, 2, 2e-3, 2e-3)
    pascals = make_board(SensorLayout(grid, "Pa"), noise=0.0)
    megapascals = make_board(SensorLayout(grid, "MPa"), noise=0.0)
    _, (pa,) = decode("binary", 6, pascals.next_bytes())
    _, (mpa,) = decode("binary", 6, megapascals.next_bytes())
    np.testing.assert_allclose(mpa.values * 1e6, pa.values, rtol=1e-6)
    np.testing.assert_allclose(pa.values, pascals.cycle[0], rtol=1e-7)


@pytest.mark.parametrize("options, message", [
    (dict(rate=0), r"rate must be a finite number of frames per second > 0, got 0$"),
    (dict(rate=-5.0), r"rate must be a finite number of frames per second > 0, got -5.0$"),
    (dict(rate=float("nan")), r"rate must be a finite number of frames per second > 0, got nan$"),
    (dict(rate=float("inf")), r"rate must be a finite number of frames per second > 0, got inf$"),
    (dict(noise=-0.1), r"noise must be a finite number >= 0 \(relative to the frame's peak\), got -0.1$"),
    (dict(noise=float("nan")), r"noise must be a finite number >= 0 \(relative to the frame's peak\), got nan$"),
    (dict(garbage=1.5), r"garbage must be a probability in \[0, 1\], got 1.5$"),
    (dict(dropout=-0.1), r"dropout must be a probability in \[0, 1\], got -0.1$"),
    (dict(fmt="hex"), r"fmt must be one of \('binary', 'text'\), got 'hex'$"),
    (dict(unloaded=-1.0), r"unloaded must be a finite number of seconds >= 0, got -1.0$"),
])
def test_board_refuses_bad_arguments_naming_them(layout, options, message, monkeypatch):
    monkeypatch.setattr(simulated, "_CYCLES", {})
    with pytest.raises(ValueError, match=message):
        Board(layout, **options)
    assert simulated._CYCLES == {}  # refused up front: no cycle made, no thread started


# -- the command line -----------------------------------------------------------------------------

def run_sim(tmp_path, *options):
    link, layout = tmp_path / "board", tmp_path / "layout.json"
    process = subprocess.Popen(
        [sys.executable, "-m", "tactile_viewer.cli.tactile_sim", "--link", str(link), "--layout", str(layout),
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


@pytest.fixture(scope="module")
def cycles():
    """``cycles(scene, grid)``: the module's Cycle of ``scene`` on ``grid``, never started: only the frames
    the tests ask for are computed (each once; a frame of a small skin takes a tenth of a second)."""
    made = {}

    def get(scene, grid):
        return made.setdefault((scene, grid.key), Cycle(scene, grid))
    return get


@pytest.fixture
def processes():
    started = []
    yield started
    for process in started:
        if process.poll() is None:
            process.kill()
        process.communicate(timeout=10)


def test_cli_streams_through_a_linked_pseudo_terminal(tmp_path, processes, cycles):
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
    cycle = cycles("circle", layout.grid)
    index = (seqs / 500 / 2.0 * len(cycle)).astype(int) % len(cycle)
    np.testing.assert_allclose([f.values for f in frames], [cycle[k] * 1e-3 for k in index], rtol=1e-6)


# the text runs send 0.5 s at 200 Hz of the 2 s circling contact: frames 0 to 24 of its 100-frame cycle
SENT = 25


def test_cli_text_format(tmp_path, processes, cycles):
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
    cycle = np.array([cycles("circle", layout.grid)[k] for k in range(SENT)]) * 1e-3
    for frame in frames[1:]:  # the first may be the tail of a cut line that still parses
        assert np.abs(frame.values / cycle - 1).max(axis=1).min() < 1e-5  # one of the cycle's frames


def test_cli_text_format_with_checksum(tmp_path, processes, cycles):
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
    cycle = np.array([cycles("circle", layout.grid)[k] for k in range(SENT)]) * 1e-3
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
    ("--drop-after", "0"), ("--drop-after", "inf"), ("--drop-after", "nan"),
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


# tactile-sim runs that end by themselves, one after another in one process (a start of Python costs
# seconds; main() is not run in the test's own process: it opens a pseudo-terminal and takes SIGTERM):
# each one's exit code and stderr
RUNS = {
    "material": ["--nx", "3", "--ny", "2", "--poisson-ratio", "0.45", "--sensor-size", "1e-3", "--duration", "0",
                 "--layout", "{tmp}/material.json", "--link", "{tmp}/board1"],
    "defaults": ["--nx", "3", "--ny", "2", "--duration", "0", "--layout", "{tmp}/defaults.json",
                 "--link", "{tmp}/board2"],
    # --duration 0.1 at 100 Hz, nobody reading; fixed seed: some dropped, some sent
    "duration": ["--rate", "100", "--duration", "0.1", "--nx", "3", "--ny", "2", "--dropout", "0.5", "--seed", "1"],
}
EACH_IN_TURN = """
import contextlib, io, json, sys
from tactile_viewer.cli import tactile_sim

results = {}
for name, arguments in json.loads(sys.argv[1]).items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = tactile_sim.main(arguments)
        except SystemExit as exit:
            code = exit.code
    results[name] = {"code": code, "stderr": err.getvalue()}
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``(folder, results)``: RUNS run in turn, {tmp} the folder; results by name: code and stderr."""
    folder = tmp_path_factory.mktemp("runs")
    arguments = {name: [a.format(tmp=folder) for a in run] for name, run in RUNS.items()}
    done = subprocess.run([sys.executable, "-c", EACH_IN_TURN, json.dumps(arguments)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return folder, json.loads(done.stdout.splitlines()[-1])


def test_cli_writes_poisson_ratio_and_sensor_size_to_its_layout(runs):
    folder, results = runs
    assert results["material"]["code"] == 0, results["material"]["stderr"][-500:]
    grid = load_layout(folder / "material.json").grid
    assert grid.poisson_ratio == 0.45 and grid.sensor_size == 1e-3 and grid.shape == (2, 3)


def test_cli_layout_defaults_to_an_incompressible_layer_and_point_sensors(runs):
    folder, results = runs
    assert results["defaults"]["code"] == 0, results["defaults"]["stderr"][-500:]
    spec = json.loads((folder / "defaults.json").read_text())
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


def test_cli_rejects_negative_noise(tmp_path, capsys):
    # an argument error, before the pseudo-terminal is opened: main() runs in this process
    with pytest.raises(SystemExit) as info:
        main(["--noise", "-0.1", "--nx", "3", "--ny", "2", "--duration", "0.2", "--link", str(tmp_path / "board")])
    err = capsys.readouterr().err
    assert info.value.code == 2 and "--noise" in err, err[-500:]
    assert not (tmp_path / "board").exists()


def test_cli_duration_bounds_the_frame_count(runs):
    # --duration 0.1 at 100 Hz: exactly 10 sequence numbers are used, even with nobody reading
    out = runs[1]["duration"]
    assert out["code"] == 0, out["stderr"]
    counts = re.search(r"sent (\d+) frames, dropped (\d+)", out["stderr"])
    sent, dropped = int(counts[1]), int(counts[2])
    assert sent + dropped == 10 and dropped > 0


@pytest.mark.parametrize("value", ["nan", "-1", "-inf"])
def test_cli_refuses_a_duration_that_is_no_number_of_seconds(value, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main([f"--duration={value}", "--link", str(tmp_path / "board")])  # "=": argparse takes -1 for an option
    assert info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"tactile-sim: error: --duration must be a number of seconds >= 0 (inf: no limit), got {value}")
    assert not (tmp_path / "board").exists()


def test_the_port_and_layout_exist_before_the_first_frame_is_computed(tmp_path, monkeypatch, capsys):
    # a viewer told the port connects at once: the device path is printed, the link made and
    # the layout written before any frame is computed
    link, layout = tmp_path / "board", tmp_path / "board.json"
    seen = {}
    release = threading.Event()

    def look():
        deadline = time.monotonic() + 10
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        seen.update(link=link.exists(), layout=layout.exists(), opened=serial.Serial(str(link)).is_open,
                    computed=[cycle.computed for cycle in simulated._CYCLES.values()])
        release.set()
    fake_frames(monkeypatch, lambda k: release.wait(10))
    checker = threading.Thread(target=look)
    checker.start()
    assert main(["--link", str(link), "--layout", str(layout), "--duration", "0.05", "--nx", "3", "--ny", "2"]) == 0
    checker.join()
    # all while no frame was computed (the cycle may not even exist yet)
    assert seen == dict(link=True, layout=True, opened=True, computed=seen["computed"])
    assert seen["computed"] in ([], [0])
    assert capsys.readouterr().out.startswith("/dev/pts/")


def test_the_first_frame_is_sent_before_the_rest_of_the_cycle_is_computed(tmp_path, monkeypatch, capsys):
    # the board sends frame 0 while frame 1 cannot be computed yet: it does not compute its whole
    # cycle before sending (as it once did, for about 3 s)
    link = tmp_path / "board"
    opened, release = threading.Event(), threading.Event()
    got = {}

    def gate(k):
        opened.wait(10)  # no frame before the reader has the port open (opening flushes what is queued)
        if k > 0:
            release.wait(10)

    def read():
        deadline = time.monotonic() + 10
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        decoder = BinaryDecoder(6)
        with serial.Serial(str(link), timeout=0.05) as port:
            opened.set()
            frames = []
            while not frames and time.monotonic() < deadline:
                frames += decoder.feed(port.read(64))
            got.update(seq=frames[0].seq if frames else None,
                       computed=[(cycle.computed, len(cycle)) for cycle in simulated._CYCLES.values()])
            release.set()
            while port.read(4096):  # drain, so that the board never stalls on a full port
                pass
    fake_frames(monkeypatch, gate)
    reader = threading.Thread(target=read)
    reader.start()
    assert main(["--link", str(link), "--duration", "0.1", "--nx", "3", "--ny", "2", "--noise", "0"]) == 0
    reader.join()
    assert got == dict(seq=0, computed=[(1, 100)])  # frame 0 on the wire, 1 of the cycle's 100 computed
    assert "sent 10 frames" in capsys.readouterr().err


def test_duration_sends_all_its_frames_even_when_frames_are_slow_to_compute(tmp_path, monkeypatch, capsys):
    # 0.1 s at 100 Hz is 10 frames, also when computing them takes longer than sending them would
    fake_frames(monkeypatch, lambda k: time.sleep(0.05))
    assert main(["--link", str(tmp_path / "board"), "--duration", "0.1", "--nx", "3", "--ny", "2"]) == 0
    assert "sent 10 frames, dropped 0" in capsys.readouterr().err


# -- the lazy cycle -------------------------------------------------------------------------------


def test_a_board_sends_its_first_frame_while_its_cycle_is_still_computing(monkeypatch):
    # the background thread is held at frame 1: the board sends frame 0 (and any frame asked for
    # computes itself), then the thread finishes the cycle
    release = threading.Event()
    fake_frames(monkeypatch, lambda k: k > 0 and release.wait(10))
    board = Board(SensorLayout(SensorGrid.regular(8, 8, 2e-3, 2e-3), "Pa"), rate=50.0, noise=0.0)
    try:
        _, (first,) = decode("binary", 64, board.next_bytes())
        assert first.seq == 0 and board.cycle.computed == 1 and not board.cycle.ready(1)
        np.testing.assert_allclose(first.values, board.cycle[0], rtol=1e-7)
        release.set()
        deadline = time.monotonic() + 30
        while board.cycle.computed < len(board.cycle):
            assert time.monotonic() < deadline, "the background thread did not finish the cycle"
            time.sleep(0.01)
    finally:
        release.set()
        board.close()


@pytest.mark.slow
def test_boards_sharing_a_cycle_keep_it_computing_until_the_last_one_closes(monkeypatch):
    fake_frames(monkeypatch, lambda k: time.sleep(0.01))  # slower: the thread is seen at work
    layout = SensorLayout(SensorGrid.regular(3, 2, 2e-3, 2e-3), "Pa")
    a, b = Board(layout, rate=50.0, noise=0.0), Board(layout, rate=50.0, noise=0.0)
    try:
        cycle = a.cycle
        assert b.cycle is cycle and cycle.users == 2
        a.close()
        a.close()  # closing twice lets go once
        assert cycle.users == 1 and cycle.computing  # b still has its frames computed ahead
        closed_at = cycle.computed
        wait_for(lambda: cycle.computed >= min(closed_at + 3, len(cycle)),
                 "the thread stopped although b still uses the cycle")  # b has asked for no frame yet
        _, frames = decode("binary", 6, stream(b, 100))  # 2 s at 50 Hz: the cycle's frames
        assert [f.seq for f in frames] == list(range(100))
        expected = [simulated.loads.simulate(layout.grid, contacts, medium="layer",
                                             subdivisions=simulated._subdivisions(layout.grid, contacts)).clean_stress
                    for contacts in (scene_contacts("circle", layout.grid, k / 100) for k in range(100))]
        np.testing.assert_allclose([f.values for f in frames], [expected[b.index(f.seq)] for f in frames],
                                   rtol=1e-6)
    finally:
        a.close()
        b.close()
    assert cycle.users == 0


def test_the_last_board_to_close_stops_the_thread_and_a_new_one_restarts_it(monkeypatch):
    fake_frames(monkeypatch, lambda k: time.sleep(0.03), stand_in=True)  # 3 s a cycle
    layout = SensorLayout(SensorGrid.regular(3, 2, 2e-3, 2e-3), "Pa")
    a, b = Board(layout, noise=0.0), Board(layout, noise=0.0)
    cycle = a.cycle
    worker = cycle._worker
    try:
        a.close()
        assert worker.is_alive()
    finally:
        b.close()
    assert not worker.is_alive() and not cycle.computing and cycle.users == 0  # ended after its frame
    stopped_at = cycle.computed
    assert stopped_at < len(cycle)
    with Board(layout, noise=0.0) as c:  # a board after the stop: a new thread finishes the cycle
        assert c.cycle is cycle and cycle.users == 1 and cycle.computing
        wait_for(lambda: cycle.computed == len(cycle), "the restarted thread did not finish the cycle")
    assert cycle.users == 0 and not cycle._worker.is_alive()


# -- the scenes -----------------------------------------------------------------------------------


@pytest.mark.parametrize("scene", ["pinch", "press"])
def test_board_streams_the_scene_it_is_given(layout, scene):
    with Board(layout, scene=scene, rate=50.0, noise=0.0) as board:
        pass  # the frames sent are computed when sent: no need for the rest of the cycle
    assert board.period == SCENES[scene].period and board.cycle.scene.name == scene
    _, frames = decode("binary", layout.count, stream(board, 20))
    expected = Cycle(scene, layout.grid)  # computes only the frames asked for
    np.testing.assert_allclose([f.values for f in frames],
                               [expected[board.index(f.seq)] * 1e-3 for f in frames], rtol=1e-6)


@pytest.mark.parametrize("call", [
    lambda grid: Board(SensorLayout(grid, "kPa"), scene="squeeze"),
    lambda grid: scene_contacts("squeeze", grid, 0.0),
    lambda grid: Cycle("squeeze", grid),
    lambda grid: contact_cycle(grid, scene="Pinch"),
])
def test_an_unknown_scene_is_refused_naming_the_scenes(call):
    with pytest.raises(ValueError, match=r"scene must be one of \('circle', 'pinch', 'two', 'three', 'press', "
                                         r"'twist', 'palm'\), got '(squeeze|Pinch)'"):
        call(SensorGrid.regular(3, 2, 2e-3, 2e-3))


@pytest.mark.parametrize("value", ["squeeze", "", "Circle"])
def test_cli_refuses_an_unknown_scene(value, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["--scene", value, "--link", str(tmp_path / "board")])
    assert info.value.code == 2
    last = capsys.readouterr().err.splitlines()[-1]
    assert last == (f"tactile-sim: error: argument --scene: invalid choice: '{value}' (choose from 'circle', "
                    f"'pinch', 'two', 'three', 'press', 'twist', 'palm')")
    assert not (tmp_path / "board").exists()


def test_cli_streams_a_scene(tmp_path, processes, cycles):
    process, link, layout_path = run_sim(tmp_path, "--scene", "two", "--rate", "100", "--duration", "0.5",
                                         "--nx", "6", "--ny", "4", "--noise", "0")
    processes.append(process)
    process.stdout.readline()
    data = read_link_until_exit(link, process)
    assert process.wait(timeout=10) == 0
    layout = load_layout(layout_path)
    frames = BinaryDecoder(layout.count).feed(data)
    assert len(frames) >= 40
    cycle = cycles("two", layout.grid)  # computes only the frames asked for
    index = (np.array([f.seq for f in frames]) / 100 / 4.0 * len(cycle)).astype(int) % len(cycle)
    np.testing.assert_allclose([f.values for f in frames], [cycle[k] * 1e-3 for k in index], rtol=1e-6)


def test_frames_queued_before_a_reader_came_are_dropped_not_stamped_as_a_burst(tmp_path, processes):
    # before: frames queued while nobody read the pseudo-terminal came all at once when a reader
    # came, and tactile-record stamped seconds of old frames on arrival (a 2,720 frames/s burst)
    import serial

    from tactile_viewer.sources.serial_reader import drain_backlog

    process, link, _layout = run_sim(tmp_path, "--rate", "1000", "--noise", "0")
    processes.append(process)
    process.stdout.readline()
    started = time.monotonic()  # the board's clock starts about now
    # nobody reads for 4 s: 16x16 frames at 1 kHz fill the terminal's buffer in well under a
    # second, and the board's writes then block
    while time.monotonic() - started < 4.0:
        assert process.poll() is None
        time.sleep(0.1)
    decoder = BinaryDecoder(256)
    with serial.Serial(str(link), timeout=0.05) as port:
        port.reset_input_buffer()  # what a reader does on opening: what the terminal had queued,
        drain_backlog(port)  # and what it still pushes of it
        opened = time.monotonic() - started
        frames = []
        while not frames:
            frames = decoder.feed(port.read(max(1, port.in_waiting)))
    process.terminate()
    _out, err = process.communicate(timeout=10)
    # the first frame read is of the board's present, not of the seconds nobody read (a write
    # blocked for less than simulator.BLOCKED_WRITE_S still sends its frames, late)
    assert frames[0].seq >= (opened - 1.0) * 1000, (frames[0].seq, opened)
    assert int(re.search(r"frames skipped while nobody read (\d+)", err).group(1)) > 0


def test_a_reader_coming_at_any_moment_gets_the_frames_at_the_boards_pace(tmp_path, processes):
    # before: a reader that came within BLOCKED_WRITE_S of a write's start (half the moments while
    # nobody read) got the frames of that wait in a burst, 180 in its first 10 ms, which a 1 kHz
    # tactile-stream took as 1,470 frames in its first second and skipped 300 of. Then: the one frame
    # a blocked write held went out when a reader came, after it had dropped its backlog, and
    # tactile-record counted the frames between it and the present as lost (1 run in 7 under load)
    from tactile_viewer.sources.serial_reader import drain_backlog

    process, link, _layout = run_sim(tmp_path, "--rate", "1000", "--noise", "0")
    processes.append(process)
    process.stdout.readline()
    time.sleep(1.2)  # nobody reads: the terminal's buffer is full and the board's writes block
    excess = []
    # after BLOCKED_WRITE_S without a reader the board waits for room half a second at a time: these
    # moments fall at different points of a wait (a reader back sooner is one that fell behind: it
    # gets the frames of its absence late)
    for away in (0.0, 0.6, 0.75, 0.9, 1.05):
        time.sleep(away)
        assert process.poll() is None
        decoder, received = BinaryDecoder(256), []  # 16x16
        with serial.Serial(str(link), timeout=0.005) as port:  # opening drops what was queued
            drain_backlog(port)  # and what the terminal still pushes of it
            opened = time.monotonic()
            while time.monotonic() - opened < 0.1:
                received += decoder.feed(port.read(1 << 20))
            elapsed = time.monotonic() - opened
        sequence = [frame.seq for frame in received]
        assert len(sequence) >= 20 and np.all(np.diff(sequence) == 1), sequence  # at its pace, none lost
        # the board's time the frames read cover, beyond the time spent reading: any frame made
        # before the reader came (the old burst of the wait, or a lone stale frame ahead of the
        # present) adds the wait. Counted in the board's own time, a stall of the board does not
        excess.append((sequence[-1] - sequence[0]) / 1000 - elapsed)
    process.terminate()
    process.communicate(timeout=10)
    assert max(excess) < 0.03, excess


@pytest.mark.parametrize("drop_after", [None, "10"])
def test_a_reader_held_up_loses_frames_only_past_drop_after(tmp_path, processes, drop_after):
    # a reader that stops reading for 1.5 s while its port stays open (a busy machine): past
    # --drop-after (0.5 s by default) the board drops that time's frames; given longer, every frame
    # comes, late
    process, link, _layout = run_sim(tmp_path, "--rate", "1000", "--noise", "0",
                                     *(["--drop-after", drop_after] if drop_after else []))
    processes.append(process)
    process.stdout.readline()
    decoder, received = BinaryDecoder(256), []  # 16x16
    with serial.Serial(str(link), timeout=0.01) as port:
        started = time.monotonic()
        while len(received) < 100:
            received += decoder.feed(port.read(1 << 20))
            assert time.monotonic() - started < 60, "no frames from the simulator"
        time.sleep(1.5)
        count = len(received)
        resumed = time.monotonic()
        while len(received) < count + 1700 and time.monotonic() - resumed < 10:
            received += decoder.feed(port.read(1 << 20))
    process.terminate()
    process.communicate(timeout=10)
    gaps = np.diff([frame.seq for frame in received])
    assert np.all(gaps >= 1)
    if drop_after is None:
        assert gaps.max() > 500  # the frames of the time past the wait are gone
    else:
        assert np.all(gaps == 1) and len(received) >= count + 1700  # all of them, late


def test_a_write_is_blocked_only_when_the_reader_left_no_room():
    master, slave = os.openpty()
    tty.setraw(slave)  # bytes pass as they are (no line to wait for)
    os.set_blocking(master, False)
    try:
        # a reader: everything sent, never blocked
        assert tactile_sim._write_all(master, b"x" * 100, stall=1.0) == (True, False)
        assert len(os.read(slave, 100)) == 100
        # nobody reads: the buffer fills, the rest is dropped after the stall, and it was blocked
        started = time.perf_counter()
        assert tactile_sim._write_all(master, b"x" * (1 << 22), stall=0.6) == (False, True)
        assert time.perf_counter() - started >= 0.6
    finally:
        os.close(master)
        os.close(slave)


def test_a_stall_of_the_board_itself_is_not_a_reader_that_stopped(monkeypatch):
    # the board's own process held up for longer than BLOCKED_WRITE_S inside a write (another thread
    # holding the GIL, a busy machine) while the reader kept reading: not blocked, nothing skipped
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    real = tactile_sim.select.select

    def held_up(*arguments):
        time.sleep(tactile_sim.BLOCKED_WRITE_S + 0.1)
        return real(*arguments)
    monkeypatch.setattr(tactile_sim.select, "select", held_up)
    try:
        assert tactile_sim._write_all(master, b"x" * 100, stall=1.0) == (True, False)
    finally:
        os.close(master)
        os.close(slave)

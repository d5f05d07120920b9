"""tactile-stream (tactile_viewer/cli/tactile_stream.py): a simulated board on a pseudo-terminal solved frame by frame,
its forces read back by a plain pylsl inlet, its raw frames recorded, its skips counted, its errors named."""

import errno
import os
import re
import signal
import socket
import threading
import time
import tty
import uuid
from dataclasses import replace

import numpy as np
import pylsl
import pytest

from solver import SensorGrid
from tactile_viewer.cli import tactile_stream
from tactile_viewer.cli.tactile_sim import Board
from tactile_viewer.io.files import load
from tactile_viewer.io.forces import load_forces
from tactile_viewer.io.layout import SensorLayout, save_layout
from tactile_viewer.model import force_log
from tactile_viewer.model.batch import settings_from_preset
from tactile_viewer.sources.source import SourceFrame

GRID = SensorGrid.regular(8, 8, 2e-3, 2e-3)
FRAMES = 240  # frames the board sends
RATE = 200.0  # frames per second
WAIT_S = 20.0  # bounded waits for the command and the network


@pytest.fixture
def layout(tmp_path):
    path = tmp_path / "layout.json"
    save_layout(SensorLayout(GRID, "kPa"), path)
    return path


@pytest.fixture
def handlers():
    """main() installs SIGINT and SIGTERM handlers in this process: they are put back after."""
    saved = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)}
    yield
    for number, handler in saved.items():
        signal.signal(number, handler)


class PtyBoard:
    """The simulated board (tactile-sim's Board, circle scene) behind a pseudo-terminal, as tactile-sim serves it.

    On a thread: waits until the command's LSL stream is on the network (the command opens the board
    right after), with ``inlet`` reads it with a plain pylsl inlet, sends its frames (all at once with
    ``burst``, else at RATE), and stops the command with SIGINT once the inlet has every sample (or
    ``stop_after`` seconds after sending).
    """

    def __init__(self, name, *, burst=False, inlet=True, stop_after=None):
        self.name, self.burst, self.with_inlet, self.stop_after = name, burst, inlet, stop_after
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # bytes pass as they are
        self.url = os.ttyname(self.slave)
        self.sent: list[np.ndarray] = []  # kPa, as sent
        self.samples, self.stamps = [], []
        self.error = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        try:
            self._serve()
        except BaseException as exc:  # noqa: BLE001 (said by the test)
            self.error = exc
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # the command's stop, as Ctrl+C
            os.close(self.master)
            os.close(self.slave)

    def _serve(self):
        found = pylsl.resolve_byprop("name", self.name, minimum=1, timeout=WAIT_S)
        assert found and found[0].type() == "TactileForce"
        inlet = None
        if self.with_inlet:
            inlet = pylsl.StreamInlet(found[0], max_buflen=60)
            inlet.open_stream(timeout=WAIT_S)
        time.sleep(0.5)  # the port is open and what it held before is drained (the reader's backlog drop)
        with Board(SensorLayout(GRID, "kPa"), rate=RATE, noise=0.01, seed=11) as board:
            chunks = []
            for _ in range(FRAMES):
                chunk = board.next_bytes()  # a binary frame: header, float32 values, CRC-16
                self.sent.append(np.frombuffer(chunk[-2 - 4 * GRID.size:-2], "<f4").copy())
                chunks.append(chunk)
        if self.burst:
            self._write(b"".join(chunks))
        else:
            start = time.perf_counter()
            for seq, chunk in enumerate(chunks):
                self._write(chunk)
                time.sleep(max(0.0, seq / RATE - (time.perf_counter() - start)))
        deadline = time.monotonic() + (self.stop_after if self.stop_after is not None else WAIT_S)
        while inlet is not None and len(self.samples) < FRAMES and time.monotonic() < deadline:
            samples, stamps = inlet.pull_chunk(timeout=0.2)
            self.samples += samples
            self.stamps += stamps
        if self.stop_after is not None:
            time.sleep(max(0.0, deadline - time.monotonic()))

    def _write(self, data):
        view = memoryview(data)
        while view:
            view = view[os.write(self.master, view):]


def run(arguments, capsys):
    code = tactile_stream.main([str(a) for a in arguments])
    out, err = capsys.readouterr()
    return code, out, err


def unique_name():
    return f"tactile-stream-test-{uuid.uuid4().hex[:12]}"


@pytest.mark.parametrize("solvers", [1, 2])  # a thread of the command's process; two processes of their own
def test_every_frame_is_solved_published_and_recorded(layout, tmp_path, capsys, handlers, solvers):
    name = unique_name()
    board = PtyBoard(name)
    record, forces = tmp_path / "take.mcap", tmp_path / "take.forces.npz"
    code, out, err = run([board.url, "--layout", layout, "--name", name, "--record", record, "--forces", forces,
                          "--solvers", solvers], capsys)
    board.thread.join(WAIT_S)
    assert board.error is None, board.error
    assert code == 0, err
    last = [line for line in out.splitlines() if line.startswith("stopped after")][-1]
    assert f"{FRAMES} frames received, {FRAMES} solved and published, 0 skipped, 0 failed" in last
    assert ("(1 solver thread)" if solvers == 1 else f"({solvers} solver processes)") in out
    assert "lost 0, rejected 0" in last
    # the plain pylsl inlet: every frame, 3 channels a node, in newtons, equal to the solver's own forces
    recording = load(record)
    assert len(recording) == FRAMES and not recording.truncated
    np.testing.assert_array_equal(recording.frames.raw(FRAMES - 1), board.sent[-1])
    assert len(board.samples) == FRAMES
    received = np.array(board.samples).reshape(FRAMES, GRID.size, 3)
    solver = settings_from_preset(None).build(GRID)
    expected = np.array([solver.solve(recording.frames[k]).forces for k in range(FRAMES)])
    peak = np.abs(expected).max()
    np.testing.assert_allclose(received, expected, rtol=0, atol=1e-5 * peak)  # float32 on the wire
    assert np.all(np.diff(board.stamps) >= 0)  # receive times (shared by frames read together) on LSL's clock
    assert abs(board.stamps[-1] - pylsl.local_clock()) < WAIT_S
    table = load_forces(forces)
    assert table["frames"].tolist() == list(range(FRAMES))
    np.testing.assert_allclose(table["forces"], received, rtol=0, atol=1e-5 * peak)


def test_a_burst_the_solver_cannot_follow_is_skipped_oldest_first_and_counted(layout, capsys, handlers):
    name = unique_name()
    board = PtyBoard(name, burst=True, inlet=False, stop_after=1.0)
    # a queue of 2 frames and 240 frames arriving at once: the solver cannot take them as they come
    code, out, err = run([board.url, "--layout", layout, "--name", name, "--queue", "2"], capsys)
    board.thread.join(WAIT_S)
    assert board.error is None, board.error
    assert code == 0, err
    last = [line for line in out.splitlines() if line.startswith("stopped after")][-1]
    received, published, skipped = (int(last.split(word)[0].split()[-1]) for word in
                                    (" frames received", " solved and published", " skipped"))
    assert received == FRAMES and skipped > 0 and published + skipped == FRAMES
    assert f"the solver did not keep up: {skipped} of {FRAMES} frames were skipped" in out
    assert "FALLING BEHIND" in out


def test_forces_after_the_disk_filled_are_left_out_counted_and_said(layout, tmp_path, capsys, handlers,
                                                                    monkeypatch):
    name = unique_name()
    board = PtyBoard(name, inlet=False, stop_after=1.0)
    forces = tmp_path / "take.forces.npz"
    written = force_log._write_all
    calls = []

    def filling(descriptor, data):  # the disk fills at the eleventh frame's forces (three writes a frame)
        calls.append(len(data))
        if len(calls) > 30:
            raise OSError(errno.ENOSPC, "No space left on device")
        written(descriptor, data)
    monkeypatch.setattr(force_log, "_write_all", filling)
    code, out, err = run([board.url, "--layout", layout, "--name", name, "--forces", forces], capsys)
    board.thread.join(WAIT_S)
    assert board.error is None, board.error
    assert code == 1, err  # the file does not hold every frame published
    last = [line for line in out.splitlines() if line.startswith("stopped after")][-1]
    published = int(last.split(" solved and published")[0].split()[-1])
    assert published > 10
    said = re.search(rf"--forces {re.escape(str(forces))}: frames published are left out of it \((\d+) after a "
                     r"write failed: No space left on device\); they are still solved and published", err)
    assert said and 1 <= int(said.group(1)) <= published - 10  # said while streaming
    assert (f"--forces {forces} holds 10 of the frames published; {published - 10} were left out "
            f"({published - 10} after a write failed: No space left on device)") in err
    assert load_forces(forces)["frames"].tolist() == list(range(10))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json", "take.forces.npz"]  # no spool left


@pytest.mark.parametrize(("arguments", "message"), [
    (["socket://127.0.0.1:9"], "--layout is needed for a board"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--duration", "0"],
     "--duration must be a finite number of seconds > 0, got 0.0"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--queue", "0"],
     "--queue must be a whole number of frames >= 1, got 0"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--solvers", "0"],
     "--solvers must be a whole number of solvers >= 1, got 0"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--catch-up", "-1"],
     r"--catch-up must be a whole number of frames from 0 \(never\) to --queue \(200\), got -1"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--queue", "50", "--catch-up", "60"],
     r"--catch-up must be a whole number of frames from 0 \(never\) to --queue \(50\), got 60"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--preset", "normal only", "--catch-up", "5"],
     "--catch-up 5: only the standard automatic solve has a faster member to catch up with"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--no-lsl", "--stress"], "--stress publishes over LSL"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--forces", "{tmp}/f.txt"],
     "--forces must end in .npz or .csv, got '.*f.txt'"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--record", "{tmp}/r.npz"],
     "--record must end in .mcap, got '.*r.npz'"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--shear-ratio", "0.3"],
     "--shear-ratio and --shear-direction must be given together"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--shear-ratio", "-1", "--shear-direction", "0"],
     "--shear-ratio must be"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--preset", "fastest"], "invalid choice: 'fastest'"),
    (["lsl:", "--layout", "{layout}"], "an LSL source is lsl:NAME with the stream's name, got 'lsl:'"),
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--name", " "], "--name must name the LSL stream, got ' '"),
])
def test_bad_options_end_with_status_2_and_say_why(layout, tmp_path, capsys, arguments, message):
    filled = [a.format(layout=layout, tmp=tmp_path) for a in arguments]
    with pytest.raises(SystemExit) as ended:
        tactile_stream.main(filled)
    assert ended.value.code == 2
    _, err = capsys.readouterr()
    assert re.search(message, err), err


@pytest.mark.parametrize("option", ["--record", "--forces"])
def test_an_existing_output_is_not_replaced_without_overwrite(layout, tmp_path, capsys, option):
    path = tmp_path / ("exists.mcap" if option == "--record" else "exists.forces.npz")
    path.write_bytes(b"kept")
    with pytest.raises(SystemExit) as ended:
        tactile_stream.main(["socket://127.0.0.1:9", "--layout", str(layout), option, str(path)])
    assert ended.value.code == 2
    assert f"{option} {path} exists: not replacing it (--overwrite replaces it)" in capsys.readouterr().err
    assert path.read_bytes() == b"kept"


def test_a_normal_only_solve_runs_on_one_thread_by_default_any_other_on_a_process_per_core(monkeypatch):
    monkeypatch.setattr(tactile_stream, "_cpus", lambda: 8)
    assert tactile_stream.default_solvers(settings_from_preset("normal only")) == 1
    assert tactile_stream.default_solvers(settings_from_preset(None)) == tactile_stream.MOST_SOLVERS == 2
    monkeypatch.setattr(tactile_stream, "_cpus", lambda: 1)
    assert tactile_stream.default_solvers(settings_from_preset(None)) == 1


class StopsAfterStart:
    """In place of SolverProcess: ready when the command starts it, unable to go on once the stream asks."""

    batch, closed, cpu_time, restarts, has_faster = 8, False, 0.0, 0, False

    def __init__(self, build, *, faster=None, name, wait=True):
        self.name, self.asked = name, 0

    def wait_ready(self):
        self.asked += 1
        if self.asked > 1:
            self.closed = True
            raise RuntimeError(f"{self.name} could not build its solver: no memory")

    def solve_each(self, stresses, **_):
        raise AssertionError("a stopped solver was given frames")

    def close(self):
        pass


def test_a_stream_with_no_solver_left_says_so_and_stops(layout, capsys, handlers, monkeypatch):
    monkeypatch.setattr(tactile_stream, "SolverProcess", StopsAfterStart)
    with socket.create_server(("127.0.0.1", 0)) as board:  # a board that connects and sends nothing
        port = board.getsockname()[1]
        code, out, err = run([f"socket://127.0.0.1:{port}", "--layout", layout, "--no-lsl", "--solvers", 2],
                             capsys)
    assert code == 1
    assert "tactile-stream: a solver stopped: RuntimeError: tactile-stream solver " in err
    assert "could not build its solver: no memory" in err
    assert "tactile-stream: no solver is left; stopping" in err


def test_frames_solved_while_catching_up_are_counted_and_marked_in_the_force_file(layout, tmp_path, capsys,
                                                                                 handlers):
    # --catch-up 1: every frame taken finds itself waiting, so every one goes to the faster member
    name = unique_name()
    board = PtyBoard(name, inlet=False)
    forces = tmp_path / "take.forces.csv"
    code, out, err = run([board.url, "--layout", layout, "--name", name, "--catch-up", 1, "--solvers", 2,
                          "--forces", forces], capsys)
    board.thread.join(WAIT_S)
    assert board.error is None, board.error
    assert code == 0, err
    last = [line for line in out.splitlines() if line.startswith("stopped after")][-1]
    assert (f"{FRAMES} frames received, {FRAMES} solved and published ({FRAMES} of them by the whole-cell fit, "
            "catching up), 0 skipped") in last
    assert "CATCHING UP: " in out
    marks = load_forces(forces)["fallback"]
    assert len(marks) == FRAMES
    assert all(re.fullmatch(r"solved by the whole-cell fit while the stream was \d+ frames behind(; .*)?", why)
               for why in marks)


def test_only_the_standard_automatic_solve_catches_up_with_the_whole_cell_fit():
    faster = tactile_stream.faster_settings(settings_from_preset(None, "cell"))
    assert (faster.preset, faster.kernel, faster.mode) == ("layer, whole-cell profile", "cell", "auto")
    assert faster.configuration.subdivision == 1
    for given in (settings_from_preset("normal only"), settings_from_preset("layer, coarse search"),
                  replace(settings_from_preset(None), shear_ratio=0.2, shear_direction=0.0)):
        assert tactile_stream.faster_settings(given) is None


def test_solvers_that_cannot_start_are_named(layout, capsys, monkeypatch):
    def cannot_start(*_, **__):
        raise OSError("Cannot allocate memory")

    monkeypatch.setattr(tactile_stream, "SolverProcess", cannot_start)
    code, out, err = run(["socket://127.0.0.1:9", "--layout", layout, "--solvers", 2], capsys)
    assert code == 1
    assert "tactile-stream: cannot start 2 solver processes: Cannot allocate memory" in err


def test_a_layout_that_cannot_be_read_is_named(tmp_path, capsys):
    code, _, err = run(["socket://127.0.0.1:9", "--layout", tmp_path / "missing.json"], capsys)
    assert code == 2 and "missing.json" in err


def test_a_board_that_cannot_be_opened_is_named(layout, capsys, handlers):
    code, _, err = run(["socket://127.0.0.1:9", "--layout", layout, "--no-lsl"], capsys)
    assert code == 1 and "cannot open socket://127.0.0.1:9" in err


def test_an_lsl_stream_that_is_not_there_is_named(layout, capsys, handlers, monkeypatch):
    monkeypatch.setattr(tactile_stream, "LSL_WAIT_S", 0.3)
    name = unique_name()
    code, _, err = run([f"lsl:{name}", "--layout", layout], capsys)
    assert code == 1 and f"no LSL stream named {name!r}" in err


def test_an_lsl_stream_of_stress_in_becomes_an_lsl_stream_of_forces_out(layout, capsys, handlers):
    name_in, name_out = unique_name(), unique_name()
    rng = np.random.default_rng(5)  # fixed seed: the values sent
    sent = (rng.random((60, GRID.size)) * 2.0).astype(np.float32)  # kPa, as the layout says
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name_in, "Tactile", GRID.size, 100, pylsl.cf_float32, name_in))
    received, problems = [], []

    def feed():
        try:
            found = pylsl.resolve_byprop("name", name_out, minimum=1, timeout=WAIT_S)
            inlet = pylsl.StreamInlet(found[0], max_buflen=60)
            inlet.open_stream(timeout=WAIT_S)
            time.sleep(0.3)
            for row in sent:
                outlet.push_sample(row)
                time.sleep(0.005)
            deadline = time.monotonic() + WAIT_S
            while len(received) < len(sent) and time.monotonic() < deadline:
                received.extend(inlet.pull_chunk(timeout=0.2)[0])
        except BaseException as exc:  # noqa: BLE001 (said by the test)
            problems.append(exc)
        finally:
            os.kill(os.getpid(), signal.SIGINT)
    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    code, out, err = run([f"lsl:{name_in}", "--layout", layout, "--name", name_out,
                          "--shear-ratio", "0.2", "--shear-direction", "45"], capsys)
    feeder.join(WAIT_S)
    assert not problems, problems
    assert code == 0, err
    assert "60 frames received, 60 solved and published, 0 skipped" in out
    solver = settings_from_preset(None).build(GRID)
    expected = [solver.solve(1e3 * row.astype(float), shear_ratio=0.2, shear_direction=np.radians(45)).forces
                for row in sent]
    np.testing.assert_allclose(np.array(received).reshape(60, GRID.size, 3), expected, rtol=0,
                               atol=1e-5 * np.abs(expected).max())


def _spool_of_a_killed_stream(kill_log, path, frames=3):
    # a stream's log killed with its spool open
    log = force_log.ForceLog(GRID, kernel="layer", mode="auto", source="socket://board", spool_beside=path)
    x, y = GRID.positions.T
    solver = settings_from_preset(None).build(GRID)
    for k in range(frames):
        stress = 5e3 * np.exp(-((x - 1e-3 * k) ** 2 + y ** 2) / (2 * 3e-3 ** 2))
        log.add(SourceFrame(stress, 0.01 * k, k), solver.solve(stress))
    return kill_log(log)


def test_a_stream_killed_before_it_wrote_its_forces_is_said_and_recovered(layout, tmp_path, capsys, handlers,
                                                                           kill_log):
    forces = tmp_path / "take.forces.npz"
    left = _spool_of_a_killed_stream(kill_log, forces)
    # the next stream writing the same file says where the forces are, and streams as ever
    name = unique_name()
    board = PtyBoard(name, inlet=False, stop_after=0.5)
    code, out, err = run([board.url, "--layout", layout, "--name", name, "--forces", forces], capsys)
    board.thread.join(WAIT_S)
    assert code == 0, err
    assert (f"a stream writing {forces} was stopped before it wrote it; its forces are in {left} ("
            in err and f"tactile-stream --recover {left} writes them" in err)
    assert left.is_dir()  # left as it was
    # the file it was for exists now: not replaced without --overwrite; --forces names another
    code, out, err = run(["--recover", left], capsys)
    assert code == 2 and f"{forces} exists: not replacing it" in err and left.is_dir()
    code, out, err = run(["--recover", left, "--forces", tmp_path / "recovered.forces.csv"], capsys)
    assert code == 0, err
    assert f"wrote the forces of 3 frames to {tmp_path / 'recovered.forces.csv'}; removed {left}" in out
    assert not left.exists()
    assert load_forces(tmp_path / "recovered.forces.csv")["frames"].tolist() == [0, 1, 2]


def test_recover_writes_the_file_the_spool_was_for(tmp_path, capsys, kill_log):
    left = _spool_of_a_killed_stream(kill_log, tmp_path / "take.forces.npz", frames=2)
    code, out, err = run(["--recover", left], capsys)
    assert code == 0, err
    table = load_forces(tmp_path / "take.forces.npz")
    assert table["frames"].tolist() == [0, 1] and table["forces"].shape == (2, GRID.size, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.forces.npz"]


@pytest.mark.parametrize(("arguments", "status", "message"), [
    (["socket://127.0.0.1:9", "--recover", "{tmp}"], 2, "--recover writes a spool's forces and streams nothing"),
    (["--recover", "{tmp}", "--forces", "{tmp}/f.txt"], 2, "--forces must end in .npz or .csv"),
    (["--layout", "{tmp}/layout.json"], 2, r"the board \(SOURCE\) is needed, or --recover SPOOL"),
    (["--recover", "{tmp}"], 1, "is not a force spool: it has no about.json"),
])
def test_recover_refuses_what_it_cannot_do(tmp_path, capsys, arguments, status, message):
    arguments = [a.format(tmp=tmp_path) for a in arguments]
    try:
        code, _, err = run(arguments, capsys)
    except SystemExit as exc:  # the parser's own errors
        code, err = exc.code, capsys.readouterr().err
    assert code == status and re.search(message, err), err

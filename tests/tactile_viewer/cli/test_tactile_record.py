"""tactile-record (tactile_viewer/cli/tactile_record.py): killed at any instant, its file opens with every frame but
the last second; Ctrl+C, SIGTERM and --duration stop it cleanly; its errors are named."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from tactile_viewer.io.files import load
from tactile_viewer.io.recording import RecordingError
from tests.tactile_viewer.conftest import Board

# Recorders to kill: one Python imports tactile-record once, then for each line it reads (output file,
# slow-disk marker or "", the command's arguments, tab-separated) forks a recorder, a process of its
# own writing its output to that file (its errors beside it, in .err), says its pid, waits for it to end and says its wait status.
# Ten kills would otherwise start Python ten times (seconds of imports each); the launcher only
# waits while a recorder runs. With a marker, the recorder is on a slow disk: every write of the
# file goes out in 4 KiB pieces 5 ms apart (a second of frames takes about 1.3 s), and the marker
# file exists while a write is under way, so that a kill can be aimed inside one (the marker stays
# when the write dies with the process).
LAUNCHER = """
import io, os, sys, time
from pathlib import Path
from tactile_viewer.cli import tactile_record as record
from tactile_viewer.io import mcap_writer as container


def on_a_slow_disk(marker):
    class SlowDisk(io.FileIO):
        def write(self, data):
            marker.touch()
            view, done = memoryview(data), 0
            while done < len(view):
                done += super().write(view[done:done + 4096])
                time.sleep(0.005)
            marker.unlink()
            return done

    container.open = lambda name, mode, **kw: (io.BufferedWriter(SlowDisk(name, "w", **kw)) if mode == "wb"
                                              else io.open(name, mode, **kw))


for line in sys.stdin:
    out, marker, *arguments = line.rstrip("\\n").split("\\t")
    pid = os.fork()
    if pid == 0:  # the recorder
        code = 1
        try:
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            os.dup2(os.open(out, os.O_WRONLY | os.O_TRUNC), 1)
            os.dup2(os.open(out + ".err", os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 2)
            sys.stdout = open(1, "w", buffering=1, closefd=False)
            sys.stderr = open(2, "w", buffering=1, closefd=False)
            if marker:
                on_a_slow_disk(Path(marker))
            code = record.main(arguments)
        except SystemExit as exit:
            code = exit.code
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code if isinstance(code, int) else 1)
    print(pid, flush=True)
    print(os.waitpid(pid, 0)[1], flush=True)
"""


def spawn(board, out, *extra):
    arguments = [str(board.link), "--layout", str(board.layout), "--out", str(out), *extra]
    return subprocess.Popen([sys.executable, "-m", "tactile_viewer.cli.tactile_record", *arguments],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    """One 1 kHz binary board for the whole module (starting one costs seconds)."""
    made = Board(tmp_path_factory.mktemp("board"))
    made.start("--rate", "1000", "--seed", "4")
    yield made
    made.stop()


def wait_for(condition, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.001)


@pytest.fixture
def launcher():
    """The LAUNCHER process; the recorder it forked last, if any, is killed when the test ends."""
    process = subprocess.Popen([sys.executable, "-c", LAUNCHER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               text=True)
    process.recorder = None
    yield process
    if process.recorder is not None:
        try:
            os.kill(process.recorder, signal.SIGKILL)
        except ProcessLookupError:
            pass
    process.stdin.close()  # the launcher's loop ends: it exits
    process.wait(timeout=30)
    process.stdout.close()


@pytest.mark.slow
def test_killed_at_any_instant_the_file_opens_with_every_frame_but_the_last_second(board, tmp_path, launcher):
    rng = np.random.default_rng(21)  # fixed seed: the same kill instants every run
    inside_a_write = 0
    for k in range(10):
        path, marker, said = tmp_path / f"kill{k}.mcap", tmp_path / f"writing{k}", tmp_path / f"kill{k}.out"
        slow = k % 2 == 1  # every other one on the slow disk, killed inside a chunk's write
        arguments = [board.link, "--layout", board.layout, "--out", path]
        said.write_text("")
        launcher.stdin.write("\t".join(map(str, [said, marker if slow else "", *arguments])) + "\n")
        launcher.stdin.flush()
        launcher.recorder = int(launcher.stdout.readline())
        # its first line, once it has opened the board
        wait_for(lambda said=said: "\n" in said.read_text(), timeout=60)
        assert said.read_text().startswith("recording"), said.read_text() + Path(f"{said}.err").read_text()
        # on the slow disk the first chunk is on disk about 2.3 s in: kill inside a later one
        time.sleep(float(rng.uniform(2.6, 3.5) if slow else rng.uniform(1.0, 2.5)))
        if slow:
            wait_for(marker.exists)
            time.sleep(float(rng.uniform(0.0, 0.05)))
        killed = time.time()
        os.kill(launcher.recorder, signal.SIGKILL)
        status = int(launcher.stdout.readline())  # the launcher waited for it: it is gone
        launcher.recorder = None
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, Path(f"{said}.err").read_text()
        inside_a_write += slow and marker.exists()
        try:
            recording = load(path)
        except RecordingError as error:
            # a loaded machine can make the slow disk's first chunk the one the kill lands in: that
            # file holds no frame and says so, which is right; nothing else may fail to open
            assert slow and "no frames (the file was cut short before its first chunk)" in str(error)
            continue
        assert recording.truncated  # never finished: it opens all the same
        steps = np.diff(recording.sequence())
        # every frame received up to its end; the slow disk stalls the reader beyond what the
        # pseudo-terminal buffers, so there the board itself drops frames (gaps, never repeats)
        assert np.all(steps >= 1) and (slow or np.all(steps == 1))
        behind = killed - (recording.received + float(recording.t[-1]))
        # a chunk closes each second; on the slow disk, writing one takes up to about 1.3 s more
        assert 0 <= behind <= (2.6 if slow else 1.3), f"kill {k}: the file ends {behind:.2f} s before it"
        assert np.all(np.isfinite(recording.frames[-1]))
    assert inside_a_write >= 3  # the kills did land inside writes (counted from the marker left)


@pytest.mark.parametrize("stop", ["SIGTERM", "SIGINT", "--duration"])
def test_a_stop_leaves_a_complete_file_and_says_what_was_recorded(board, tmp_path, stop):
    path = tmp_path / "take.mcap"
    process = spawn(board, path, *(["--duration", "1.5"] if stop == "--duration" else []))
    assert process.stdout.readline().startswith(f"recording {board.link} (binary) to {path}")
    if stop != "--duration":
        assert "frames/s" in process.stdout.readline()  # once a second: rate, recorded, lost, rejected
        process.send_signal(getattr(signal, stop))
    out, err = process.communicate(timeout=20)
    assert process.returncode == 0, err
    last = out.strip().splitlines()[-1]
    assert last.startswith("stopped: ") and "lost 0" in last and "rejected 0" in last
    recorded = int(last.split()[1])
    recording = load(path)
    assert not recording.truncated and len(recording) == recorded > 200
    assert recording.grid.shape == (16, 16) and recording.frames.raw_dtype == np.float32
    if stop == "SIGTERM":  # once: the file tactile-record wrote, as ROS 2's own readers decode it
        raw = recording.frames.raw(slice(None))
        with AnyReader([path]) as reader:
            decoded = [reader.deserialize(data, connection.msgtype) for connection, _, data in reader.messages()]
        np.testing.assert_array_equal([frame.values for frame in decoded], raw)
        np.testing.assert_array_equal([frame.sequence for frame in decoded], recording.sequence())
        stamps = np.array([frame.header.stamp.sec + frame.header.stamp.nanosec * 1e-9 for frame in decoded])
        np.testing.assert_allclose(stamps - recording.received, recording.t, atol=2e-6)
        with open(path, "rb") as stream:
            frames = [frame for *_, frame in make_reader(stream, decoder_factories=[DecoderFactory()])
                      .iter_decoded_messages()]
        np.testing.assert_array_equal(np.array([frame.values for frame in frames]), raw)


ERRORS = [
    (["socket://127.0.0.1:9", "--layout", "{layout}", "--out", "{tmp}/a.mcap"], 1, "cannot open socket://"),
    (["{link}", "--layout", "{tmp}/missing.json", "--out", "{tmp}/a.mcap"], 2, "missing.json"),
    (["{link}", "--layout", "{layout}", "--out", "{tmp}/a.npz"], 1,
     r"cannot record: .*a\.npz: a recording is written as \.mcap, got '\.npz'"),
    (["{link}", "--layout", "{layout}", "--out", "{tmp}/no/such/folder/a.mcap"], 1,
     "cannot record: .*No such file or directory"),
    (["{link}", "--layout", "{layout}", "--out", "{tmp}/a.mcap", "--duration", "0"], 2,
     "--duration must be a finite number of seconds > 0, got 0.0"),
    (["{link}", "--layout", "{layout}", "--out", "{tmp}/a.mcap", "--duration", "nan"], 2,
     "--duration must be a finite number of seconds > 0, got nan"),
    (["{link}", "--layout", "{layout}", "--out", "{tmp}/a.mcap", "--baudrate", "4294967296"], 2,
     "baud rate must be a whole number from 1 to 2147483647, got 4294967296"),
]

# the error cases one after another in one process (a start of Python costs seconds): each one's exit code
# and stderr, and the threads it left that would keep a process of its own from ending
EACH_IN_TURN = """
import contextlib, io, json, sys, threading
from tactile_viewer.cli import tactile_record as record

results = []
for arguments in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = record.main(arguments)
        except SystemExit as exit:  # argparse's errors
            code = exit.code
    left = [t for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon]
    for thread in left:
        thread.join(30)  # as long as a process of its own would have been given to end
    results.append({"code": code, "stderr": err.getvalue(), "left": [t.name for t in left if t.is_alive()]})
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def error_runs(board, tmp_path_factory):
    """Per case of ERRORS: its own folder ({tmp}) and what running it gave."""
    folders = [tmp_path_factory.mktemp("error") for _ in ERRORS]
    runs = [[a.format(layout=board.layout, link=board.link, tmp=folder) for a in arguments]
            for (arguments, _, _), folder in zip(ERRORS, folders, strict=True)]
    done = subprocess.run([sys.executable, "-c", EACH_IN_TURN, json.dumps(runs)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return list(zip(folders, json.loads(done.stdout.splitlines()[-1]), strict=True))


@pytest.mark.parametrize(("arguments", "code", "message"), ERRORS)
def test_errors_are_named_and_nothing_is_left_running(error_runs, arguments, code, message):
    folder, done = error_runs[ERRORS.index((arguments, code, message))]
    assert done["code"] == code
    assert re.search(message, done["stderr"]), done["stderr"]
    assert not done["left"], f"threads left running: {done['left']}"
    assert not (folder / "a.mcap").exists()


FULL_DISK = """
import errno, io, sys
from tactile_viewer.cli import tactile_record as record
from tactile_viewer.io import mcap_writer as container

class FullDisk(io.FileIO):
    room = 60000  # bytes: the header and a chunk or two of 16x16 frames
    def write(self, data):
        if len(data) > FullDisk.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        FullDisk.room -= len(data)
        return super().write(data)

container.open = lambda name, mode, **kw: (io.BufferedWriter(FullDisk(name, "w", **kw)) if mode == "wb"
                                          else io.open(name, mode, **kw))
sys.exit(record.main(sys.argv[1:]))
"""


def test_after_a_write_error_the_last_line_counts_what_the_file_holds(board, tmp_path):
    # it said 2,303 frames recorded for a file holding none: it counted the frames handed over
    path = tmp_path / "full.mcap"
    done = subprocess.run([sys.executable, "-c", FULL_DISK, str(board.link), "--layout", str(board.layout),
                           "--out", str(path), "--duration", "3"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 1 and "No space left on device" in done.stderr
    last = done.stdout.strip().splitlines()[-1]
    recorded = int(last.split()[1])
    held = len(load(path)) if recorded else 0
    assert last.startswith("stopped: ") and recorded == held
    assert re.search(r"; \d+ received but not written$", last), last


def refused_here(arguments, capsys):
    """tactile-record's main() in this process, for a refusal that comes before the board is opened (and
    before its signal handlers are installed): its exit code and stderr."""
    from tactile_viewer.cli.tactile_record import main

    code = main([str(a) for a in arguments])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("overwrite", [False, True])
def test_the_output_is_never_written_through_a_dangling_link(board, tmp_path, overwrite, capsys):
    # --out followed a dangling symbolic link and created its target
    link, target = tmp_path / "take.mcap", tmp_path / "target.mcap"
    link.symlink_to(target)
    arguments = [board.link, "--layout", board.layout, "--out", link, "--duration", "1"]
    if overwrite:  # refused once the board is open: the command itself
        done = subprocess.run([sys.executable, "-m", "tactile_viewer.cli.tactile_record", *map(str, arguments),
                               "--overwrite"], capture_output=True, text=True, timeout=30)
        code, err = done.returncode, done.stderr
    else:
        code, err = refused_here(arguments, capsys)
    assert code == (1 if overwrite else 2)
    assert ("is a symbolic link: a recording is not written through one" if overwrite else
            "exists: not replacing a recording") in err
    assert not target.exists() and link.is_symlink()


def test_an_existing_recording_is_not_replaced_without_overwrite(board, tmp_path, capsys):
    path = tmp_path / "take.mcap"
    path.write_bytes(b"an earlier session")
    arguments = [str(board.link), "--layout", str(board.layout), "--out", str(path)]
    code, err = refused_here(arguments, capsys)
    assert code == 2 and "exists: not replacing a recording (--overwrite replaces it)" in err
    assert path.read_bytes() == b"an earlier session"
    done = subprocess.run([sys.executable, "-m", "tactile_viewer.cli.tactile_record", *arguments, "--overwrite",
                           "--duration", "1.2"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert len(load(path)) > 100

"""Recording at 1 kHz through a pseudo-terminal: a long take, then random kills.

``python -m benchmarks.recording_endurance [--seconds 600] [--kills 20] [--out DIR]``

1. ``tactile-sim`` sends binary 16x16 frames at 1 kHz on a pseudo-terminal and
   ``tactile-record`` records them for ``--seconds``: frames sent, recorded,
   lost, the longest wait between frames (reader stalls), the recorder's CPU
   time, the file size per minute, and the time to stop.
2. The file is opened and seeked in a fresh process: time and peak memory.
3. ``--kills`` times, ``tactile-record`` is killed with SIGKILL at a random
   instant 1 to 4 s in: every file must open; the frames lost per kill are
   the receive time not in the file before the kill, times the rate.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from measurement.timing import machine
from tactile_viewer.io.files import load

OPEN_AND_SEEK = """
import resource, sys, time
import numpy as np
start_cpu, start = time.process_time(), time.perf_counter()
from tactile_viewer.io.files import load
imported = time.perf_counter()
recording = load(sys.argv[1])
opened = time.perf_counter()
rng = np.random.default_rng(0)  # fixed seed: the same 20 frames every run
for k in rng.integers(0, len(recording), 20):
    recording.frames[int(k)]
seeked = time.perf_counter()
print(len(recording), opened - imported, (seeked - opened) / 20, time.process_time() - start_cpu,
      resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def start_board(folder: Path, rate: float) -> tuple[subprocess.Popen, Path, Path]:
    link, layout = folder / "board", folder / "layout.json"
    board = subprocess.Popen([sys.executable, "-m", "tactile_viewer.cli.tactile_sim", "--link", str(link),
                              "--layout", str(layout), "--rate", str(rate), "--seed", "3"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    board.stdout.readline()
    return board, link, layout


def recorder(link, layout, out, *extra) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tactile_viewer.cli.tactile_record", str(link), "--layout",
                             str(layout), "--out", str(out), *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def endurance(folder: Path, seconds: float, rate: float, out) -> Path:
    board, link, layout = start_board(folder, rate)
    path = folder / "endurance.mcap"
    process = recorder(link, layout, path, "--duration", str(seconds))
    _, status, usage = os.wait4(process.pid, 0)
    report = process.stdout.read().strip().splitlines()
    board.send_signal(signal.SIGTERM)
    sent = board.communicate(timeout=30)[1].strip().splitlines()[-1]  # its report goes to stderr
    recording = load(path)
    sequence = recording.sequence()
    minutes = float(recording.t[-1]) / 60
    print(f"{seconds:g} s at {rate:g} Hz, binary 16x16 through a pseudo-terminal:", file=out)
    print(f"  board: {sent}", file=out)
    print(f"  recorder: {report[-1]}", file=out)
    print(f"  file: {len(recording)} frames, sequence gaps {int(np.sum(np.diff(sequence) - 1))}, "
          f"{path.stat().st_size / 2**20 / minutes:.1f} MiB per minute", file=out)
    print(f"  recorder CPU {usage.ru_utime + usage.ru_stime:.1f} s over {seconds:g} s "
          f"({(usage.ru_utime + usage.ru_stime) / seconds:.1%} of a core), peak RSS "
          f"{usage.ru_maxrss / 1024:.0f} MiB, exit {os.waitstatus_to_exitcode(status)}", file=out)
    return path


def open_and_seek(path: Path, out, runs: int = 5) -> None:
    rows = []
    for _ in range(runs):
        done = subprocess.run([sys.executable, "-c", OPEN_AND_SEEK, str(path)], capture_output=True,
                              text=True, check=True)
        rows.append([float(v) for v in done.stdout.split()])
    frames, opened, seek, cpu, rss = (statistics.median(column) for column in zip(*rows, strict=True))
    print(f"  open {opened * 1e3:.0f} ms, seek a random frame {seek * 1e3:.2f} ms, "
          f"process CPU {cpu:.2f} s, "
          f"peak RSS of the whole process (Python, numpy, scipy included) {rss:.0f} MiB "
          f"(medians of {runs} fresh processes, {int(frames)} frames)", file=out)


def kills(folder: Path, count: int, rate: float, out) -> None:
    board, link, layout = start_board(folder, rate)
    rng = np.random.default_rng(11)  # fixed seed: the same kill instants every run
    lost, opened = [], 0
    try:
        for k in range(count):
            path = folder / f"kill{k}.mcap"
            process = recorder(link, layout, path)
            process.stdout.readline()  # recording from here on
            time.sleep(float(rng.uniform(1.0, 4.0)))
            killed = time.time()
            process.send_signal(signal.SIGKILL)
            process.wait()
            try:
                recording = load(path)
            except Exception as exc:  # the measurement: a file that does not open is counted, not fatal
                print(f"  kill {k}: the file does not open: {exc}", file=out)
                continue
            opened += 1
            last = recording.received + float(recording.t[-1])
            lost.append((killed - last) * rate)
    finally:
        board.send_signal(signal.SIGTERM)
        board.communicate(timeout=30)
    print(f"{count} kills (SIGKILL 1 to 4 s in, {rate:g} Hz): {opened} of {count} files open; "
          "frames lost per kill (receive time not in the file, times the rate): "
          f"median {statistics.median(lost):.0f}, "
          f"max {max(lost):.0f}", file=out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=600)
    parser.add_argument("--kills", type=int, default=20)
    parser.add_argument("--rate", type=float, default=1000)
    args = parser.parse_args(argv)
    out = sys.stdout
    print(f"machine: {machine()}", file=out)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        if args.seconds > 0:
            path = endurance(folder, args.seconds, args.rate, out)
            open_and_seek(path, out)
        if args.kills > 0:
            kills(folder, args.kills, args.rate, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""How fast the MCAP recorder writes, and the reader decodes, a 16x16 board's frames.

``python -m benchmarks.recorder_throughput [--frames 60000] [--taxels 256] [--runs 5]``

Each run gives :class:`~tactile_viewer.io.mcap_writer.Recorder` ``--frames``
float32 frames stamped 1 ms apart (60 s of a 1 kHz board by default) as fast as
it takes them, with a backlog that holds them all (so none is dropped and the
writer's thread is what is timed), and waits for :meth:`close`. It then opens
the file and reads every frame. Printed: the median over ``--runs`` of the
frames written per second of wall time, the process CPU time per frame while
writing (the caller's and the writer's threads together), the file size per
frame, and the frames read per second. Wall times on a shared machine vary:
compare medians taken back to back.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from measurement.timing import machine
from solver import SensorGrid
from tactile_viewer.io.files import load
from tactile_viewer.io.mcap_writer import Recorder


def one_run(folder: Path, frames: np.ndarray, run: int) -> dict:
    """Write ``frames`` through a Recorder, then read them back: rates and sizes of this run."""
    count, taxels = frames.shape
    side = int(round(np.sqrt(taxels)))
    grid = SensorGrid.regular(side, taxels // side, 2e-3, 1.5e-3)
    path = folder / f"run{run}.mcap"
    cpu, wall = time.process_time(), time.perf_counter()
    recorder = Recorder(path, grid, dtype="float32", backlog=frames.nbytes + 2**20, clock_origin=1.7e9)
    for k in range(count):
        recorder.add(k, k * 1e-3, frames[k])
    recorder.close()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    assert recorder.dropped == 0 and recorder.written == count
    start = time.perf_counter()
    read = np.asarray(load(path).frames.raw(slice(None)))
    reading = time.perf_counter() - start
    np.testing.assert_array_equal(read, frames)
    size = path.stat().st_size
    path.unlink()
    return {"written/s": count / wall, "CPU us/frame": cpu / count * 1e6, "bytes/frame": size / count,
            "read/s": count / reading}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60_000,
                        help="frames per run (default 60000: 60 s at 1 kHz)")
    parser.add_argument("--taxels", type=int, default=256, help="values per frame (default 256: 16x16)")
    parser.add_argument("--runs", type=int, default=5, help="runs; the median is printed (default 5)")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)  # fixed seed: the same frames every run
    frames = rng.normal(1e3, 300, size=(args.frames, args.taxels)).astype(np.float32)
    with tempfile.TemporaryDirectory() as folder:
        runs = [one_run(Path(folder), frames, run) for run in range(args.runs)]
    print(f"# {machine()}")
    print(f"# {args.frames} frames of {args.taxels} float32 values, median of {args.runs} runs")
    for key in runs[0]:
        values = [run[key] for run in runs]
        runs_text = ", ".join(f"{v:.1f}" for v in values)
        print(f"{key:>13}: {statistics.median(values):12.1f}   (runs: {runs_text})")


if __name__ == "__main__":
    main()

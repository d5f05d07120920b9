"""Movie export cost: ``python -m benchmarks.movie_cost`` (measured, never asserted).

For each bundled sample, writes the whole recording as a movie the way ``tactile-viewer REC
--movie OUT`` does (the app's scene on an off-screen plotter, anti-aliased, 1200 x 800, the
caption burnt in) and prints:

- per frame (solve, render, grab, hand to the writer): the median wall and CPU time of this
  process, the median solve alone (measured again after the movie), and the median of the last
  third of the frames over that of the first third (about 1 when every frame costs the same);
- for the whole sample: wall seconds from loading the file to the finished movie (solver set-up
  and closing the file included), this process's CPU seconds, and the CPU seconds of the encoder
  (ffmpeg runs as a child process for a video; a GIF is quantized in this process and encoded by
  Pillow when it is closed, the "finish" column).

Off-screen rendering needs no display (VTK falls back to EGL); under Xvfb it uses the X server's.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from measurement.timing import machine

SAMPLES = Path(__file__).resolve().parents[1] / "sample_data"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)  # waited-for children: ffmpeg once closed
    return usage.ru_utime + usage.ru_stime


def measure(path, folder, *, suffix=".mp4", size=(1200, 800), smooth=True) -> dict:
    """Write ``path`` whole as ``<folder>/<stem><suffix>``; the costs measured (seconds)."""
    from tactile_viewer.io.files import load
    from tactile_viewer.model.movie_settings import default_display
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.render import movie

    wall, cpu, children = time.perf_counter(), time.process_time(), _children_cpu()
    recording = load(path)
    solver = ViewerModel.build(recording.grid, "layer")
    display = default_display(recording, solver)
    export = movie.MovieExport(recording, solver, Path(folder) / (Path(path).stem + suffix), size=size,
                               display=display, smooth=smooth)
    frame_wall, frame_cpu = [], []
    try:
        while export.remaining:
            start, start_cpu = time.perf_counter(), time.process_time()
            export.step()
            frame_wall.append(time.perf_counter() - start)
            frame_cpu.append(time.process_time() - start_cpu)
        result = export.finish()
    finally:
        export.cancel()  # nothing to undo after finish; releases the renderer after a failure
    total_s, cpu_s = time.perf_counter() - wall, time.process_time() - cpu
    encoder_cpu_s = _children_cpu() - children
    # the solves alone, again, for the share of a frame that is numerics rather than drawing
    solve = []
    for k in export.frames:
        start = time.perf_counter()
        export.solve(k)
        solve.append(time.perf_counter() - start)
    third = max(1, len(frame_wall) // 3)
    return dict(solve_ms=1e3 * float(np.median(solve)), frames=result.frames, size=result.size,
                bytes=result.path.stat().st_size,
                frame_ms=1e3 * float(np.median(frame_wall)), frame_cpu_ms=1e3 * float(np.median(frame_cpu)),
                drift=float(np.median(frame_wall[-third:]) / np.median(frame_wall[:third])),
                finish_s=result.finish_seconds, total_s=total_s, cpu_s=cpu_s, encoder_cpu_s=encoder_cpu_s)


def main(argv=None, out=None):
    out = sys.stdout if out is None else out
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--formats", nargs="*", default=[".mp4", ".gif"], help="movie types to write")
    parser.add_argument("--fast", action="store_true", help="no anti-aliasing (the window's own rendering)")
    parser.add_argument("--samples", nargs="*", type=Path, default=sorted(SAMPLES.glob("*.npz")))
    args = parser.parse_args(argv)
    print(f"machine: {machine()}", file=out)
    smoothing = "no anti-aliasing" if args.fast else "anti-aliased (8 samples)"
    print(f"1200 x 800, {smoothing}, 30 fps; per frame: solve + render + grab + write; whole: load to "
          "finished file", file=out)
    header = (f"{'sample':<24} {'type':<4} {'frames':>6} {'ms/frame':>8} {'CPU ms':>7} {'solve ms':>8} "
              f"{'last/first':>10} "
              f"{'finish s':>8} {'whole s':>7} {'CPU s':>6} {'encoder CPU s':>13} {'MB':>6}")
    print(header, file=out)
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for suffix in args.formats:
            for sample in args.samples:
                r = measure(sample, folder, suffix=suffix, smooth=not args.fast)
                results[sample.name, suffix] = r
                print(f"{sample.name:<24} {suffix[1:]:<4} {r['frames']:6d} {r['frame_ms']:8.1f} "
                      f"{r['frame_cpu_ms']:7.1f} {r['solve_ms']:8.1f} {r['drift']:10.2f} "
                      f"{r['finish_s']:8.2f} {r['total_s']:7.2f} {r['cpu_s']:6.2f} "
                      f"{r['encoder_cpu_s']:13.2f} {r['bytes'] / 1e6:6.2f}", file=out,
                      flush=True)
    return results


if __name__ == "__main__":
    main()

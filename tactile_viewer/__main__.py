"""Command line: ``tactile-viewer RECORDING [--report]``.

Reconstructs every frame (or one, with ``--frame``) and prints the total
force, the shear parameters, the errors against the truth when the
recording has it, and the solve time.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from solver import Reconstructor, metrics

from .recording import RecordingError, load


def report(path, *, frame=None, kernel="cell", shear_ratio=None, shear_direction_deg=None, out=None):
    out = sys.stdout if out is None else out
    recording = load(path)
    grid = recording.grid
    start = time.perf_counter()
    reconstructor = Reconstructor(grid, kernel=kernel)
    setup = time.perf_counter() - start
    print(f"{path}: {len(recording)} frames, {grid.shape[1]}x{grid.shape[0]} grid, pitch "
          f"{grid.pitch * 1e3:g} mm, thickness {grid.thickness * 1e3:g} mm, kernel {kernel}; "
          f"set-up {setup * 1e3:.1f} ms", file=out)
    if recording.description:
        print(f"  {recording.description}", file=out)
    direction = None if shear_direction_deg is None else math.radians(shear_direction_deg)
    indices = range(len(recording)) if frame is None else [frame]
    header = f"{'frame':>5} {'t s':>6} {'Fz N':>7} {'Ft N':>6} {'mu':>5} {'theta':>6} {'eff':>6}"
    if recording.truth_forces is not None:
        header += f" {'dFz':>6} {'dFt/F':>6} {'dth':>6}"
    print(header + f" {'ms':>6}", file=out)
    times = []
    for k in indices:
        start = time.perf_counter()
        result = reconstructor.solve(recording.frames[k], shear_ratio=shear_ratio, shear_direction=direction)
        times.append(time.perf_counter() - start)
        total = result.total_force
        line = (f"{k:5d} {recording.t[k]:6.3f} {total[2]:7.4f} {math.hypot(total[0], total[1]):6.4f} "
                f"{result.shear_ratio:5.2f} {math.degrees(result.shear_direction):+6.0f} "
                f"{result.efficiency:6.3f}")
        if recording.truth_forces is not None:
            e = metrics.compare(result.forces, recording.truth_forces[k])
            line += f" {100 * e.normal_total:5.1f}% {100 * e.tangential_total:5.1f}% {e.direction_deg:6.1f}"
        print(line + f" {times[-1] * 1e3:6.2f}", file=out)
    print(f"median solve {np.median(times) * 1e3:.2f} ms over {len(times)} frames", file=out)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="tactile-viewer", description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("--report", action="store_true", help="print the reconstruction (headless)")
    parser.add_argument("--frame", type=int)
    parser.add_argument("--kernel", choices=("cell", "point"), default="cell")
    parser.add_argument("--shear-ratio", type=float)
    parser.add_argument("--shear-direction", type=float, help="degrees")
    args = parser.parse_args(argv)
    try:
        report(args.recording, frame=args.frame, kernel=args.kernel, shear_ratio=args.shear_ratio,
               shear_direction_deg=args.shear_direction)
    except (RecordingError, ValueError, IndexError) as exc:
        print(f"tactile-viewer: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

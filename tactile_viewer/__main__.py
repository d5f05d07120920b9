"""Command line: ``tactile-viewer [RECORDING] [options]``.

- no option: open the window (on RECORDING if given);
- ``--screenshot out.png``: render one frame off screen, save the PNG and its
  JSON sidecar ``out.png.view.json``, exit (batch figures);
- ``--report``: reconstruct headlessly and print a per-frame table;
- ``--info``: print what the file holds, one fact per line, solving nothing.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from solver import make_solver, metrics
from solver.kernels import KERNELS

from .model import KERNEL_HELP, geometry_text
from .recording import RecordingError, facts, load


def report(path, *, frame=None, kernel=KERNELS[0], shear_ratio=None, shear_direction_deg=None, out=None):
    """Reconstruct a recording headlessly and print one line per frame (with errors when it has truth).

    The first line names the geometry, the elastomer's Poisson ratio included.
    """
    out = sys.stdout if out is None else out
    recording = load(path)
    grid = recording.grid
    start = time.perf_counter()
    reconstructor = make_solver(grid, kernel=kernel)
    setup = time.perf_counter() - start
    print(f"{path}: {len(recording)} frames, {geometry_text(grid)}, kernel {kernel}; "
          f"set-up {setup * 1e3:.1f} ms", file=out)
    if recording.description:
        print(f"  {recording.description}", file=out)
    direction = None if shear_direction_deg is None else math.radians(shear_direction_deg)
    indices = range(len(recording)) if frame is None else [_frame_index(frame, recording)]
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


def _frame_index(frame, recording):
    if not 0 <= frame < len(recording):
        raise ValueError(f"--frame must be in [0, {len(recording) - 1}] for this recording, got {frame}")
    return frame


def screenshot(path, out, *, frame=0, kernel=KERNELS[0], shear_ratio=None, shear_direction_deg=None,
               scale=1, transparent=False, camera="iso", size=(1200, 800), display_map="pressure"):
    """Render one frame off screen with the window's own scene; save the PNG and its sidecar
    ``<PNG>.view.json`` (never over a file that is not an earlier sidecar)."""
    import pyvista as pv

    from . import export
    from .model import ViewerModel
    from .scene import Scene
    from .source import RecordingSource

    out = Path(out)
    if not out.suffix:  # pyvista would write <out>.png, a name the user did not give
        raise ValueError(f"{out}: --screenshot needs a file name with its type, e.g. {out.name}.png")
    export.check_sidecar(out)  # refused before anything is rendered or written
    recording = load(path)
    model = ViewerModel()
    model.set_source(RecordingSource(recording, path), ViewerModel.build(recording.grid, kernel))
    model.set_frame(_frame_index(frame, recording))
    if shear_ratio is not None or shear_direction_deg is not None:
        model.set_parameters(shear_ratio=shear_ratio if shear_ratio is not None else model.shear_ratio,
                             shear_direction=math.radians(shear_direction_deg or 0.0))
    model.set_display(map=display_map)
    solved = model.solve()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    try:
        scene = Scene(plotter, smooth=True)
        scene.set_grid(recording.grid)
        scene.camera(camera)
        scene.update(solved, model.display, render=False)
        scene.screenshot(out, scale=scale, transparent=transparent)
    finally:
        plotter.close()
    export.write_sidecar(out, **model.describe(), scale=scale, transparent=transparent)
    return solved


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="tactile-viewer", description="Contact forces on a robot skin from its normal-stress sensors: "
        "open RECORDING in the viewer (no option), or describe, report or render it headlessly.")
    parser.add_argument("recording", nargs="?", metavar="RECORDING",
                        help="a recording to open: .mcap (live recordings), .npz or .csv")
    parser.add_argument("--info", action="store_true",
                        help="print frames, span, sequence gaps, receive times, geometry and calibration "
                             "of RECORDING, one per line, and exit (nothing is solved)")
    parser.add_argument("--report", action="store_true", help="print the reconstruction (headless)")
    parser.add_argument("--frame", type=int, metavar="N",
                        help="the frame to report or render, numbered from 0 as everywhere; default: "
                             "every frame for --report, 0 for --screenshot")
    parser.add_argument("--kernel", choices=KERNELS, default=KERNELS[0], help=KERNEL_HELP)
    parser.add_argument("--shear-ratio", type=float, metavar="MU",
                        help="fixed shear ratio (default: found automatically)")
    parser.add_argument("--shear-direction", type=float, metavar="DEG",
                        help="fixed shear direction, degrees from +x (default: found automatically)")
    parser.add_argument("--screenshot", metavar="PNG",
                        help="render one frame to PNG (+ JSON sidecar PNG.view.json) and exit")
    parser.add_argument("--scale", type=int, choices=(1, 2, 4), default=1, help="screenshot size multiplier")
    parser.add_argument("--transparent", action="store_true", help="screenshot with transparent background")
    parser.add_argument("--camera", choices=("iso", "top"), default="iso",
                        help="screenshot view: iso (oblique, default) or top (looking down on the skin)")
    parser.add_argument("--map", choices=("pressure", "stress", "none"), default="pressure",
                        help="screenshot colour map: pressure (normal force per area, default), stress "
                             "(sensor readings) or none")
    args = parser.parse_args(argv)
    try:
        if args.report or args.screenshot or args.info:
            if not args.recording:
                parser.error("a RECORDING is needed with --info, --report or --screenshot")
            if args.info:
                print("\n".join(facts(load(args.recording))))
            elif args.report:
                report(args.recording, frame=args.frame, kernel=args.kernel, shear_ratio=args.shear_ratio,
                       shear_direction_deg=args.shear_direction)
            else:
                solved = screenshot(args.recording, args.screenshot, frame=args.frame or 0,
                                    kernel=args.kernel,
                                    shear_ratio=args.shear_ratio, shear_direction_deg=args.shear_direction,
                                    scale=args.scale, transparent=args.transparent, camera=args.camera,
                                    display_map=args.map)
                print(f"saved {args.screenshot} (frame {solved.frame}, mu {solved.result.shear_ratio:.2f}, "
                      f"theta {math.degrees(solved.result.shear_direction):+.0f} deg)")
            return 0
    except (RecordingError, ValueError) as exc:
        print(f"tactile-viewer: {exc}", file=sys.stderr)
        return 2
    return run_window(args.recording, kernel=args.kernel)


def run_window(path=None, *, kernel=KERNELS[0]):
    from PyQt6 import QtWidgets

    from . import errors
    from .main_window import MainWindow

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication(sys.argv[:1])
    app.setApplicationName("tactile-viewer")
    # before any window exists: an error while building it is reported, not fatal
    log_path = errors.setup_logging()
    app.reporter = errors.Reporter(log_path, app)
    errors.install(app.reporter)
    errors.log.info("tactile-viewer started (log %s)", log_path)
    window = MainWindow()
    window.model.kernel = kernel
    window.parameters.show_kernel(kernel)  # nothing is open yet: nothing to rebuild
    window.show()
    if path:
        window.open(path)
    return app.exec()


if __name__ == "__main__":
    sys.exit(main())

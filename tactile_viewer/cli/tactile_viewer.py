"""Command line: ``tactile-viewer [RECORDING] [options]``.

RECORDING is a recording file, or a ROS 2 bag with ``--layout FILE`` (and ``--topic``,
``--field`` when the bag has several numeric array topics: :mod:`tactile_viewer.io.ros2_bag`).

- no option: open the window (on RECORDING if given; a bag without ``--layout`` asks for it);
- ``--screenshot out.png``: render one frame off screen, save the PNG and its
  JSON sidecar ``out.png.view.json``, exit (batch figures);
- ``--movie out.mp4``: render frames ``--start`` to ``--stop`` (exclusive) off screen with the
  time, parameters and forces burnt in, write them as a video (.mp4, .mkv, .avi) or an animated
  GIF, exit;
- ``--report``: reconstruct headlessly and print a per-frame table, each frame's contacts
  (followed over the frames, numbered from 1) under its line;
- ``--info``: print what the file holds, one fact per line, solving nothing.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import threading
import time
from pathlib import Path

import numpy as np

from solver import ContactTracker, Reconstructor, metrics
from solver.kernels import KERNELS

from ..io.facts import facts
from ..io.files import load
from ..io.recording import RecordingError
from ..model.captions import KERNEL_HELP, geometry_text
from ..model.display import Display
from ..model.viewer_model import ViewerModel


def report(path, *, frame=None, kernel=KERNELS[0], shear_ratio=None, shear_direction_deg=None, out=None,
           bag=None):
    """Reconstruct a recording headlessly and print one line per frame (with errors when it has truth).

    ``bag``: the ``layout``, ``topic`` and ``field`` of a ROS 2 bag (:func:`tactile_viewer.io.files.load`).

    The first line names the geometry, the elastomer's Poisson ratio included. Under each
    frame's line, one line per contact (largest normal force first): its identity
    (``#1``, ``#2`` ...: :class:`solver.ContactTracker` follows the contacts over the
    frames reported, in order, so a number is the same contact from frame to frame),
    its normal and tangential force, its own shear ratio and direction in the frame's
    columns, then its centre in millimetres.
    """
    out = sys.stdout if out is None else out
    recording = load(path, **(bag or {}))
    grid = recording.grid
    start = time.perf_counter()
    reconstructor = Reconstructor(grid, kernel=kernel)
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
    tracker = ContactTracker(grid)
    for k in indices:
        start = time.perf_counter()
        result = reconstructor.solve(recording.frames[k], shear_ratio=shear_ratio, shear_direction=direction)
        times.append(time.perf_counter() - start)
        result = tracker.update(result)
        total = result.total_force
        line = (f"{k:5d} {recording.t[k]:6.3f} {total[2]:7.4f} {math.hypot(total[0], total[1]):6.4f} "
                f"{result.shear_ratio:5.2f} {math.degrees(result.shear_direction):+6.0f} "
                f"{result.efficiency:6.3f}")
        if recording.truth_forces is not None:
            e = metrics.compare(result.forces, recording.truth_forces[k])
            line += f" {100 * e.normal_total:5.1f}% {100 * e.tangential_total:5.1f}% {e.direction_deg:6.1f}"
        print(line + f" {times[-1] * 1e3:6.2f}", file=out)
        for contact in result.contacts:
            fx, fy, fz = contact.total_force
            x, y = contact.centre * 1e3
            print(f"{'#' + str(contact.identity):>5} {'':6} {fz:7.4f} {math.hypot(fx, fy):6.4f} "
                  f"{contact.shear_ratio:5.2f} {math.degrees(contact.shear_direction):+6.0f} "
                  f"at x {x:+.2f} y {y:+.2f} mm", file=out)
    print(f"median solve {np.median(times) * 1e3:.2f} ms over {len(times)} frames", file=out)


def _frame_index(frame, recording):
    # the movie's frame check (one rule and one message for every frame the command line takes)
    from ..model.movie_settings import check_frame

    return check_frame(len(recording), frame, name="--frame", what="the frame to report or render")


def screenshot(path, out, *, frame=0, kernel=KERNELS[0], shear_ratio=None, shear_direction_deg=None,
               scale=1, transparent=False, camera="iso", size=(1200, 800), display_map="pressure", bag=None):
    """Render one frame off screen with the window's own scene; save the PNG and its sidecar
    ``<PNG>.view.json`` (never over a file that is not an earlier sidecar).

    ``bag``: the ``layout``, ``topic`` and ``field`` of a ROS 2 bag (:func:`tactile_viewer.io.files.load`).

    The display is the window's default for the recording seen from ``camera``
    (:meth:`Display.seen_from`): from ``"top"`` the arrows lie flat (in-plane), as the
    window's Top button shows them; from ``"iso"`` they stand in 3-D.

    Raises
    ------
    ValueError
        A bad argument (``camera`` not a preset, a frame out of range, an output name
        without its type), before anything is rendered or written.
    """
    import pyvista as pv

    from ..io import sidecar
    from ..render.scene import Scene
    from ..sources.source import RecordingSource

    seen = Display().seen_from(camera)  # the camera checked before anything is loaded
    out = Path(out)
    if not out.suffix:  # pyvista would write <out>.png, a name the user did not give
        raise ValueError(f"{out}: --screenshot needs a file name with its type, e.g. {out.name}.png")
    sidecar.check_sidecar(out)  # refused before anything is rendered or written
    recording = load(path, **(bag or {}))
    model = ViewerModel()
    model.set_source(RecordingSource(recording, path), ViewerModel.build(recording.grid, kernel))
    model.set_frame(_frame_index(frame, recording))
    if shear_ratio is not None or shear_direction_deg is not None:
        model.set_parameters(shear_ratio=shear_ratio if shear_ratio is not None else model.shear_ratio,
                             shear_direction=math.radians(shear_direction_deg or 0.0))
    model.set_display(map=display_map, in_plane=seen.in_plane)
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
    sidecar.write_sidecar(out, **model.describe(), scale=scale, transparent=transparent)
    return solved


def movie(path, out, *, kernel=KERNELS[0], shear_ratio=None, shear_direction_deg=None, start=0, stop=None,
          fps=30.0, size=(1200, 800), camera="iso", display_map="pressure", stream=None, bag=None):
    """Write a movie of a recording's frames ``start .. stop - 1`` (``stop`` exclusive) off screen.

    The display is the window's default for the recording with the colour ranges fixed over the
    movie, seen from ``camera`` (:meth:`Display.seen_from`: in-plane arrows from the top, as the
    window's Top button shows them); the parameters are found for each frame unless
    ``shear_ratio`` or ``shear_direction_deg`` is given (the other is then 0, as for
    ``--screenshot``). Progress goes to ``stream`` (default stdout) at most every 2 s.

    Parameters
    ----------
    path : str or Path
        The recording.
    out : str or Path
        The movie: .mp4, .mkv, .avi (H.264) or .gif.
    kernel : str
        The solver's kernel.
    shear_ratio, shear_direction_deg : float or None
        Fixed parameters (the direction in degrees); both None: found for each frame.
    start, stop : int
        Frames ``start .. stop - 1``, numbered from 0 (``stop`` None: to the end).
    fps : float
        Frames per second of the movie (> 0; at most 50 for a GIF).
    size : (2,) tuple of int
        Width and height, pixels (even for a video).
    camera : {"iso", "top"}
    display_map : {"pressure", "stress", "none"}
    stream : file, optional
        Where progress is printed.
    bag : dict, optional
        The ``layout``, ``topic`` and ``field`` of a ROS 2 bag (:func:`tactile_viewer.io.files.load`).

    Returns
    -------
    movie.MovieResult

    Raises
    ------
    ValueError
        A bad option, named as on the command line, before anything is written.
    OSError
        The movie could not be written; nothing is left under ``out``.
    """
    from ..model import movie_settings
    from ..render import movie as movies

    stream = sys.stdout if stream is None else stream
    kind = movie_settings.movie_kind(out, name="--movie")
    # the options are checked, with the command line's names, before the recording is solved
    fps = movie_settings.check_fps(fps, kind, name="--fps")
    size = movie_settings.check_size(size, kind, name="--size")
    if shear_ratio is not None or shear_direction_deg is not None:  # one given: the other is 0
        shear_ratio = 0.0 if shear_ratio is None else shear_ratio
        shear_direction_deg = 0.0 if shear_direction_deg is None else shear_direction_deg
    ratio, direction = movie_settings.check_movie_parameters(shear_ratio, shear_direction_deg, degrees=True,
                                                       names=("--shear-ratio", "--shear-direction"))
    Display().seen_from(camera)  # a preset, checked before the recording is loaded
    recording = load(path, **(bag or {}))
    frames = movie_settings.check_frames(len(recording), start, stop, names=("--start", "--stop"))
    solver = ViewerModel.build(recording.grid, kernel)
    display = movie_settings.default_display(recording, solver, display_map=display_map, camera=camera)
    last = [time.monotonic()]

    def progress(done, total):
        now = time.monotonic()
        if now - last[0] >= 2.0 and done < total:
            last[0] = now
            print(f"  {done} of {total} frames", file=stream, flush=True)
        return True

    return movies.write_movie(recording, out, solver=solver, progress=progress, start=frames.start,
                              stop=frames.stop, fps=fps, size=size, display=display, shear_ratio=ratio,
                              shear_direction=direction, camera=camera)


def _size(text):
    # argparse type of --size: "WxH", each side from 16 to 8192 pixels (a video's evenness is
    # checked with the movie's type)
    from ..model.movie_settings import check_size

    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match:
        raise argparse.ArgumentTypeError(f"must be WIDTHxHEIGHT in pixels, e.g. 1200x800, got {text!r}")
    try:
        return check_size((int(match[1]), int(match[2])), "image", name="")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="tactile-viewer", description="Contact forces on a robot skin from its normal-stress sensors: "
        "open RECORDING in the viewer (no option), or describe, report or render it headlessly.")
    parser.add_argument("recording", nargs="?", metavar="RECORDING",
                        help="a recording to open: .mcap (live recordings), .npz or .csv; or a ROS 2 bag "
                             "(a folder with metadata.yaml, a .mcap or .db3) with --layout")
    parser.add_argument("--layout", metavar="FILE",
                        help="a ROS 2 bag's sensor layout (JSON, as for a live board): geometry, units, gain "
                             "and offset of its values; the window asks for it when not given")
    parser.add_argument("--topic", metavar="T", help="the bag's topic of numeric arrays (default: the only "
                        "one, or the only one whose messages hold the layout's taxel count of values)")
    parser.add_argument("--field", metavar="F", help="the field of its messages that holds the values, "
                        "dot-separated when nested, e.g. data or array.data (default: the only numeric "
                        "array)")
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
    parser.add_argument("--movie", metavar="OUT",
                        help="render frames --start to --stop (exclusive) to a movie with the frame, time, "
                             "parameters and forces burnt in, and exit: .mp4, .mkv, .avi (H.264 video) or "
                             ".gif (animated GIF, at most 50 fps)")
    parser.add_argument("--fps", type=float, metavar="F",
                        help="movie frames per second, > 0 (default 30); each recording frame is one movie "
                             "frame, so 30 plays a 30 Hz recording in real time")
    parser.add_argument("--start", type=int, metavar="N",
                        help="first frame of the movie, numbered from 0 (default 0)")
    parser.add_argument("--stop", type=int, metavar="N",
                        help="the movie ends before frame N (exclusive, as a Python slice: --start 10 "
                             "--stop 20 is frames 10 to 19); default: the end of the recording")
    parser.add_argument("--size", type=_size, default=(1200, 800), metavar="WxH",
                        help="image size in pixels for --screenshot (before --scale) and --movie (even "
                             "numbers for a video), default 1200x800")
    parser.add_argument("--scale", type=int, choices=(1, 2, 4), default=1, help="screenshot size multiplier")
    parser.add_argument("--transparent", action="store_true", help="screenshot with transparent background")
    parser.add_argument("--camera", choices=("iso", "top"), default="iso",
                        help="screenshot and movie view: iso (oblique, default) or top (looking down on the "
                             "skin)")
    parser.add_argument("--map", choices=("pressure", "stress", "none"), default="pressure",
                        help="screenshot and movie colour map: pressure (normal force per area, default), "
                             "stress (sensor readings) or none")
    args = parser.parse_args(argv)
    # a ROS 2 bag's choices, as load takes them (only those given)
    bag = {name: value for name in ("layout", "topic", "field") if (value := getattr(args, name)) is not None}
    movie_options = [f"--{name}" for name in ("fps", "start", "stop") if getattr(args, name) is not None]
    if args.movie:
        if args.info or args.report or args.screenshot:
            parser.error("--movie cannot be combined with --info, --report or --screenshot")
        if args.frame is not None:
            parser.error("--frame chooses one frame; a movie's frames are chosen with --start and --stop")
        if args.scale != 1 or args.transparent:
            parser.error("--scale and --transparent are for --screenshot; a movie's size is --size")
    elif movie_options:
        parser.error(f"{', '.join(movie_options)} {'goes' if len(movie_options) == 1 else 'go'} with --movie")
    try:
        if args.report or args.screenshot or args.info or args.movie:
            if not args.recording:
                parser.error("a RECORDING is needed with --info, --report, --screenshot or --movie")
            if args.info:
                print("\n".join(facts(load(args.recording, **bag))))
            elif args.report:
                report(args.recording, frame=args.frame, kernel=args.kernel, shear_ratio=args.shear_ratio,
                       shear_direction_deg=args.shear_direction, bag=bag)
            elif args.movie:
                written = movie(args.recording, args.movie, kernel=args.kernel, shear_ratio=args.shear_ratio,
                                shear_direction_deg=args.shear_direction, start=args.start or 0,
                                stop=args.stop, fps=30.0 if args.fps is None else args.fps, size=args.size,
                                camera=args.camera, display_map=args.map, bag=bag)
                print(written.summary())
            else:
                solved = screenshot(args.recording, args.screenshot, frame=args.frame or 0,
                                    kernel=args.kernel,
                                    shear_ratio=args.shear_ratio, shear_direction_deg=args.shear_direction,
                                    scale=args.scale, transparent=args.transparent, camera=args.camera,
                                    size=args.size, display_map=args.map, bag=bag)
                print(f"saved {args.screenshot} (frame {solved.frame}, mu {solved.result.shear_ratio:.2f}, "
                      f"theta {math.degrees(solved.result.shear_direction):+.0f} deg)")
            return 0
    except (RecordingError, ValueError) as exc:
        print(f"tactile-viewer: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the movie could not be written (nothing is left under its name)
        reason = f"{exc.filename}: {exc.strerror}" if exc.filename and exc.strerror else str(exc)
        print(f"tactile-viewer: {reason}", file=sys.stderr)
        return 2
    if bag and not args.recording:
        parser.error("--layout, --topic and --field go with a ROS 2 bag given as RECORDING")
    return run_window(args.recording, kernel=args.kernel, bag=bag)


def run_window(path=None, *, kernel=KERNELS[0], bag=None):
    # ``bag``: the layout, topic and field of a ROS 2 bag; the window asks for what is not given
    from PyQt6 import QtWidgets

    from ..qt import errors
    from ..qt.main_window import MainWindow

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication(sys.argv[:1])
    app.setApplicationName("tactile-viewer")
    # before any window exists: an error while building it is reported, not fatal
    log_path = errors.setup_logging()
    app.reporter = errors.Reporter(log_path, app)
    errors.install(app.reporter)
    errors.log.info("tactile-viewer started (log %s)", log_path)
    warm_in_background(errors.log)
    window = MainWindow()
    window.model.kernel = kernel
    window.parameters.show_kernel(kernel)  # nothing is open yet: nothing to rebuild
    window.show()
    if path:
        window.open(path, **(bag or {}))
    return app.exec()


def warm_in_background(log) -> threading.Thread:
    """Load the solver's compiled core (:func:`solver.warmup.warm_up`) on a thread of its own while
    the window is built and a recording read; the thread is returned, started.

    Without it the first frames of a recording paid the loading as each took a path of the solve
    for the first time (``docs/efficiency.md``). A failure is logged, never raised: the solves then
    load what they need themselves.
    """
    def run():
        start = time.perf_counter()
        try:
            from solver.warmup import warm_up

            warm_up()
        except Exception:  # noqa: BLE001 (never fatal: the first solves load the code themselves)
            log.warning("loading the solver's compiled code ahead failed; the first solves load it",
                        exc_info=True)
        else:
            log.info("solver's compiled code loaded ahead in %.2f s", time.perf_counter() - start)

    thread = threading.Thread(target=run, name="solver warm-up", daemon=True)
    thread.start()
    return thread


if __name__ == "__main__":
    sys.exit(main())

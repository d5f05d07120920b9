"""tactile-stream: reconstruct every frame of a live board and publish the forces over LSL, without a display.

``tactile-stream SOURCE [--layout LAYOUT.json] [--format text|binary] [--duration S] [--record OUT.mcap]
[--forces OUT.forces.npz] [--shear-ratio R --shear-direction DEG] [--preset NAME]
[--kernel K] [--name NAME] [--stress] [--no-lsl] [--queue FRAMES] [--catch-up FRAMES] [--solvers N]``;
``tactile-stream --recover SPOOL [--forces OUT] [--overwrite]``

SOURCE is a serial port (``/dev/ttyACM0``), any pyserial URL (``socket://host:port``,
``loop://``) or ``lsl:NAME`` (an LSL stream of one channel per taxel). Every frame is
solved (automatic parameters by default, each fit starting from the frame its solver
solved last; ``--solvers`` side by side: processes of their own, or one thread) and its node
forces published, in frame
order, as an LSL stream of type ``TactileForce`` stamped with the frame's receive
time on LSL's clock. ``--record`` writes the raw frames
as ``tactile-record`` does (crash-safe MCAP); ``--forces`` keeps the forces of
every frame published on disk as they come (a hidden spool beside the file, so
memory does not grow with the take) and writes them when the stream stops (the
viewer's force export). A stream killed before it wrote them leaves the spool:
the next stream writing the same file says so, and ``--recover SPOOL`` writes
every frame whole in it to the force file it was for (or ``--forces``) and
removes it.

Once a second, and at the end: frames in, solves per second, frames published and
skipped, the queue, the latency from receive to publish (median and 99th
percentile), the solve time and the CPU used. A solver slower than the board
never builds a silent backlog: at most ``--queue`` frames wait, a frame arriving
at a full queue skips the oldest, and every skipped frame is counted and said.
Before that, with the standard automatic solve, once ``--catch-up`` frames wait
they are solved by the whole-cell fit (faster, less accurate) until the stream
has caught up, each such frame marked (its ``fallback``, the force file) and
counted. No Qt.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import pickle
import shutil
import sys
import time
from dataclasses import replace
from pathlib import Path

from solver.kernels import KERNELS

from ..io.forces import save_forces
from ..io.layout import LayoutError, load_layout
from ..model.batch import PRESET_NAMES, settings_from_preset
from ..model.captions import KERNEL_HELP
from ..model.force_log import ForceLog, leftover_spools, recover
from ..model.force_stream import DEFAULT_QUEUE_FRAMES, ForceStream
from ..model.movie_settings import check_movie_parameters
from ..model.solver_process import SolverProcess, warm
from ..sources.lsl_inlet import URL_PREFIX
from .board_options import add_board_arguments, check_duration, print_messages, seconds_left, stop_on_signals

__all__ = ["main", "open_source", "status_line", "final_lines"]

PROG = "tactile-stream"
LSL_WAIT_S = 3.0  # how long a lsl:NAME source is looked for on the network
# Python's GIL switch interval while streaming (its default is 0.005 s). With one solver (a thread of
# this process) the reader and the solver share the GIL; at the default, the reader's thousand
# wake-ups a second each force the solver to hand it over and wait to get it back. Given parameters,
# 1000 frames/s in, 4 to 5 s runs on the 2-core machine at load 2 to 3: 90 to 380 solves/s at
# 0.005 s, 700 to 780 at 0.02 s, 900 at 0.05 s. The solver releases the GIL in its compiled and BLAS
# calls many times a frame, so the reader still gets it within a fraction of a millisecond.
SWITCH_INTERVAL_S = 0.05
# Most solvers by default (one per core, as processes). Measured on the 2-core machine only (1 kHz
# board, 60 s runs with the automatic solve alternating with two threads of one process: 0 and 471
# frames skipped against 4,522 and 10,210, docs/interop.md); more processes, each about 265 MB for a
# 16x16 skin, were not measured.
MOST_SOLVERS = 2
# What a stream catches up with (--catch-up, by default at half the queue: frames are solved faster
# well before any is skipped): the preset (faster_settings) and how its frames are marked.
FASTER_PRESET = "layer, whole-cell profile"
FASTER_MEMBER = "the whole-cell fit"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("source", metavar="SOURCE", nargs="?",
                        help="the board: a device path (/dev/ttyACM0), a pyserial URL (socket://host:port), "
                             "or lsl:NAME, an LSL stream with one channel per taxel")
    parser.add_argument("--layout", metavar="LAYOUT.json",
                        help="the sensor layout: geometry and the calibration of the raw values (needed for "
                             "a board; an LSL stream may carry its own in its description)")
    add_board_arguments(parser, format_help="the board's frame format (default binary; an LSL stream "
                                                    "has none)")
    parser.add_argument("--record", metavar="OUT.mcap",
                        help="also record every raw frame, as tactile-record does (crash-safe)")
    parser.add_argument("--forces", metavar="OUT.forces.npz",
                        help="also write the forces of every frame published (.npz or .csv, the viewer's "
                             "force export) when the stream stops; until then they are kept on disk beside "
                             "it (a 16x16 skin at 1 kHz: 3.1 MB a second), not in memory")
    parser.add_argument("--overwrite", action="store_true", help="replace the --record or --forces file")
    parser.add_argument("--recover", metavar="SPOOL",
                        help="instead of streaming: write the forces a stream that was killed left in its "
                             "spool (the hidden .NAME.XXXXXXXX.spool folder beside its --forces file) to "
                             "that file, or to --forces, and remove the spool")
    parser.add_argument("--shear-ratio", type=float, metavar="R",
                        help="a given shear ratio for every frame (with --shear-direction; default: found "
                             "for each frame)")
    parser.add_argument("--shear-direction", type=float, metavar="DEG",
                        help="a given shear direction, degrees from +x (with --shear-ratio)")
    parser.add_argument("--preset", metavar="NAME", choices=PRESET_NAMES,
                        help="a quality setting, by name: " + ", ".join(map(repr, PRESET_NAMES))
                        + " (default: the standard solve)")
    parser.add_argument("--kernel", choices=KERNELS,
                        help=f"the stress kernel (default: the preset's, else {KERNELS[0]}). "
                             + KERNEL_HELP.replace("\n", " "))
    parser.add_argument("--name", default="tactile-viewer",
                        help="the LSL stream's name (default tactile-viewer; its type is TactileForce)")
    parser.add_argument("--stress", action="store_true",
                        help="also publish the calibrated stress (LSL type Tactile, pascals)")
    parser.add_argument("--no-lsl", action="store_true", help="publish nothing (solve, count, record)")
    parser.add_argument("--queue", type=int, default=DEFAULT_QUEUE_FRAMES, metavar="FRAMES",
                        help=f"frames that may wait for the solver (default {DEFAULT_QUEUE_FRAMES}); a frame "
                             "arriving at a full queue skips the oldest")
    parser.add_argument("--catch-up", type=int, metavar="FRAMES",
                        help="with the standard automatic solve: once this many frames wait, solve them with "
                             f"{FASTER_MEMBER} (faster, less accurate; each such frame says so in the "
                             "force file and the counts) until the stream has caught up (at most --queue; "
                             "default half of it; 0: never, skip frames instead)")
    parser.add_argument("--solvers", type=int, metavar="N",
                        help="solvers working side by side, out of order: 1 is a thread of this process, "
                             "more are processes of their own, each on a core; the forces are still "
                             "published in frame order (default: the cores this process may use, at most "
                             f"{MOST_SOLVERS}, here {default_solvers()}; 1 with --preset \"normal only\", "
                             "whose solve costs less than a round trip to a process)")
    return parser


def default_solvers(settings=None) -> int:
    """Solvers by default: one per core this process may use, at most :data:`MOST_SOLVERS`; one for
    a normal-only solve (``settings``' path ``normal``). A normal-only solve (under 0.1 ms) costs
    less than a process's round trip (0.28 ms of CPU): at 1 kHz one thread used 37% CPU, two
    processes 74%, neither skipping a frame (docs/interop.md)."""
    configuration = None if settings is None else settings.configuration
    if configuration is not None and configuration.path == "normal":
        return 1
    return max(1, min(MOST_SOLVERS, _cpus()))


def _check(parser, args):
    """The settings the options ask for; a bad option ends the command (exit status 2)."""
    if args.forces is not None and Path(args.forces).suffix.lower() not in (".npz", ".csv"):
        parser.error(f"--forces must end in .npz or .csv, got {args.forces!r}")
    if args.recover is not None:
        if args.source is not None:
            parser.error(f"--recover writes a spool's forces and streams nothing: it takes no SOURCE, got "
                         f"{args.source!r}")
        return None
    if args.source is None:
        parser.error("the board (SOURCE) is needed, or --recover SPOOL")
    check_duration(parser, args)
    if args.queue < 1:
        parser.error(f"--queue must be a whole number of frames >= 1, got {args.queue}")
    if args.catch_up is not None and not 0 <= args.catch_up <= args.queue:
        parser.error(f"--catch-up must be a whole number of frames from 0 (never) to --queue ({args.queue}), "
                     f"got {args.catch_up}")
    if args.solvers is not None and args.solvers < 1:
        parser.error(f"--solvers must be a whole number of solvers >= 1, got {args.solvers}")
    if not args.name.strip():
        parser.error(f"--name must name the LSL stream, got {args.name!r}")
    if args.no_lsl and args.stress:
        parser.error("--stress publishes over LSL: it cannot go with --no-lsl")
    if not args.source.startswith(URL_PREFIX) and args.layout is None:
        parser.error(f"--layout is needed for a board (only an LSL stream may carry its own), got "
                     f"{args.source} without one")
    if args.source.startswith(URL_PREFIX) and not args.source[len(URL_PREFIX):].strip():
        parser.error(f"an LSL source is lsl:NAME with the stream's name, got {args.source!r}")
    if args.record is not None and Path(args.record).suffix.lower() != ".mcap":
        parser.error(f"--record must end in .mcap, got {args.record!r}")
    for option in ("record", "forces"):
        path = getattr(args, option)
        if path is not None and os.path.lexists(path) and not args.overwrite:  # a dangling link too
            parser.error(f"--{option} {path} exists: not replacing it (--overwrite replaces it)")
    try:
        ratio, direction = check_movie_parameters(args.shear_ratio, args.shear_direction, degrees=True,
                                                  names=("--shear-ratio", "--shear-direction"))
        settings = replace(settings_from_preset(args.preset, args.kernel), shear_ratio=ratio,
                           shear_direction=direction)
    except ValueError as exc:
        parser.error(str(exc))
    if args.solvers is None:
        args.solvers = default_solvers(settings)
    if args.catch_up is None:
        args.catch_up = args.queue // 2 if faster_settings(settings) is not None else 0
    elif args.catch_up and faster_settings(settings) is None:
        parser.error(f"--catch-up {args.catch_up}: only the standard automatic solve has a faster member to "
                     "catch up with (given parameters and the presets do not; --catch-up 0 skips instead)")
    return settings


def open_source(spec: str, layout, *, fmt: str = "binary", baudrate: int = 115200, wait: float | None = None):
    """The live source SPEC names: ``lsl:NAME`` an LSL stream (layout None: its description's), else a board.

    ``wait`` is how long an LSL stream is looked for (default :data:`LSL_WAIT_S` seconds).

    Raises
    ------
    ValueError
        For a bad baud rate or layout, or an LSL stream that is missing or does not fit.
    """
    if spec.startswith(URL_PREFIX):
        from ..sources.lsl import FORCE_TYPE
        from ..sources.lsl_inlet import LslSource, find_streams

        name = spec[len(URL_PREFIX):]
        wait = LSL_WAIT_S if wait is None else wait
        # our own output may share the name: a stream of forces is never an input
        found = [s for s in find_streams(name=name, timeout=wait) if s.type != FORCE_TYPE]
        if not found:
            raise ValueError(f"no LSL stream named {name!r} (other than a {FORCE_TYPE} stream) answered "
                             f"within {wait:g} s")
        found.sort(key=lambda s: s.type != "Tactile")  # the conventional type first
        return LslSource(found[0], layout)
    from ..sources.serial_reader import SerialReader

    return SerialReader(spec, layout, fmt=fmt, baudrate=baudrate)


def status_line(elapsed: float, figures, source) -> str:
    """The line printed once a second: the interval's figures and the source's counts."""
    stats = source.stats.snapshot(source.now())
    text = (f"{elapsed:7.1f} s  in {stats.rate:6.1f}/s  solved {figures.solve_rate:6.1f}/s  published "
            f"{figures.published}  skipped {figures.skipped}  queue {figures.waiting}  latency "
            f"{_ms(figures.latency_median)} / {_ms(figures.latency_p99)} ms (median / p99)  solve "
            f"{_ms(figures.solve_time)} ms  CPU {figures.cpu:.0f}%  lost {stats.lost}  rejected "
            f"{sum(source.rejected().values())}  {source.state}")
    if source.error:
        text += f" ({source.error})"
    if figures.faster:
        text += f"  CATCHING UP: {figures.faster} frames solved by {FASTER_MEMBER}"
    if figures.skipped:
        text += f"  FALLING BEHIND: {figures.skipped} frames skipped"
    if figures.failed:
        text += f"  {figures.failed} failed"
    return text


def final_lines(totals, source, cpus: int) -> list[str]:
    """What is printed when the stream stops: the whole run's figures."""
    stats = source.stats
    faster = f" ({totals.faster} of them by {FASTER_MEMBER}, catching up)" if totals.faster else ""
    lines = [f"stopped after {totals.elapsed:.1f} s: {totals.received} frames received, {totals.published} "
             f"solved and published{faster}, {totals.skipped} skipped, {totals.failed} failed; latency "
             f"median {_ms(totals.latency_median)} ms, p99 {_ms(totals.latency_p99)} ms; "
             f"{totals.solve_rate:.1f} solves/s; CPU {totals.cpu:.0f}% (of {100 * cpus}%); lost "
             f"{stats.lost}, rejected {sum(source.rejected().values())}"]
    if totals.skipped:
        lines.append(f"{PROG}: the solver did not keep up: {totals.skipped} of {totals.received} frames were "
                     "skipped (not solved, not published; a recording keeps them). Given parameters "
                     "(--shear-ratio, --shear-direction) or a faster --preset solve faster.")
    return lines


def _ms(seconds: float) -> str:
    return "-" if math.isnan(seconds) else f"{seconds * 1e3:.2f}"


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def main(argv=None) -> int:
    """Run ``tactile-stream``.

    Returns
    -------
    int
        0 after a clean stop, 1 when the board could not be opened, a recording or
        force file failed, or the force file could not hold every frame published (its
        disk filled or fell behind), 2 for bad options.
    """
    parser = _parser()
    args = parser.parse_args(argv)
    settings = _check(parser, args)
    if args.recover is not None:
        return _recover(args.recover, args.forces, overwrite=args.overwrite)
    if args.forces is not None:
        for spool in leftover_spools(args.forces):
            print(f"{PROG}: a stream writing {args.forces} was stopped before it wrote it; its forces are in "
                  f"{spool} ({_size(spool)}): tactile-stream --recover {spool} writes them",
                  file=sys.stderr, flush=True)
    layout = None
    if args.layout is not None:
        try:
            layout = load_layout(args.layout)
        except (OSError, LayoutError) as exc:
            print(f"{PROG}: {exc}", file=sys.stderr)
            return 2
    stop = stop_on_signals()
    try:
        source = open_source(args.source, layout, fmt=args.format, baudrate=args.baudrate)
    except (OSError, ValueError, RuntimeError) as exc:  # RuntimeError: any of pylsl's errors
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2 if not args.source.startswith(URL_PREFIX) else 1
    failed = print_messages(source)
    grid = source.grid
    try:
        solvers, faster = _solvers(settings, grid, args.solvers, catch_up=bool(args.catch_up))
    except (RuntimeError, OSError, pickle.PicklingError) as exc:
        what = "the solver" if args.solvers == 1 else f"{args.solvers} solver processes"
        print(f"{PROG}: cannot start {what}: {exc}", file=sys.stderr)
        return 1
    outlet = log = None
    if not args.no_lsl:
        from ..sources.lsl import ForceOutlet

        try:
            outlet = ForceOutlet(grid, name=args.name, source_id=f"{PROG} {args.source}", stress=args.stress)
        except (OSError, RuntimeError) as exc:  # liblsl could not make the outlet (RuntimeError: pylsl's)
            print(f"{PROG}: cannot publish over LSL: {exc}", file=sys.stderr)
            _close(solvers)
            return 1
    if args.forces is not None:
        try:
            log = ForceLog(grid, kernel=settings.kernel, mode=settings.mode, source=args.source,
                           spool_beside=args.forces)
        except OSError as exc:
            print(f"{PROG}: --forces {args.forces}: cannot keep the forces beside it: {exc.strerror or exc}",
                  file=sys.stderr)
            if outlet is not None:
                outlet.close()
            _close(solvers)
            return 1
    switch_interval = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        return _stream(args, source, solvers, faster, settings, outlet, log, stop, failed)
    finally:
        sys.setswitchinterval(switch_interval)
        _close(solvers)
        if outlet is not None:
            outlet.close()
        if log is not None:
            log.close()


def _stream(args, source, solvers, faster, settings, outlet, log, stop, failed) -> int:
    stream = ForceStream(source, solvers, _publisher(source, outlet, log, stress=args.stress),
                         shear_ratio=settings.shear_ratio, shear_direction=settings.shear_direction,
                         queue_frames=args.queue, faster=faster, catch_up=args.catch_up or None,
                         faster_member=FASTER_MEMBER)
    stream.start()  # before the board: its first frame is followed too
    try:
        source.start()
    except (OSError, ValueError, RuntimeError) as exc:
        stream.stop()
        print(f"{PROG}: cannot open {args.source}: {exc}", file=sys.stderr)
        return 1
    recorder = None
    if args.record is not None:
        try:
            recorder = source.start_recording(args.record)  # after start: the file's clock is the reader's
        except (OSError, ValueError) as exc:
            source.stop()
            stream.stop()
            print(f"{PROG}: cannot record: {exc}", file=sys.stderr)
            return 1
    where = "nothing (--no-lsl)" if outlet is None else f"LSL stream {args.name!r} (type TactileForce)"
    threads = "1 solver thread" if args.solvers == 1 else f"{args.solvers} solver processes"
    print(f"streaming forces of {args.source} to {where} ({threads})"
          + (f", recording to {args.record}" if recorder else "") + "; Ctrl+C stops", flush=True)
    start = time.monotonic()
    said_failure = said_full = said_solver = False
    try:
        while not stop.wait(min(1.0, seconds_left(start, args.duration))):
            elapsed = time.monotonic() - start
            print(status_line(elapsed, stream.figures(), source), flush=True)
            if log is not None and log.left_out and not said_full:  # the first; the end counts them all
                print(f"{PROG}: --forces {args.forces}: frames published are left out of it "
                      f"({log.reason()}); they are still solved and published", file=sys.stderr, flush=True)
                said_full = True
            if stream.last_error and not said_failure:  # the first; the count goes on in the lines
                print(f"{PROG}: a frame failed: {stream.last_error}", file=sys.stderr, flush=True)
                said_failure = True
            if stream.solver_error and not said_solver:
                print(f"{PROG}: a solver stopped: {stream.solver_error}", file=sys.stderr, flush=True)
                said_solver = True
            if not stream.solvers_left:  # every frame from now on would be skipped
                print(f"{PROG}: no solver is left; stopping", file=sys.stderr, flush=True)
                failed.set()
                break
            if recorder is not None and source.recorder is None:  # a write error or a reconnection
                failed.set()
                break
            if args.duration is not None and elapsed >= args.duration:
                break
    finally:
        source.stop()  # the reader first (and the recording with it): the queue then only empties
        stream.stop()
        totals = stream.totals()
    for line in final_lines(totals, source, _cpus()):
        print(line, flush=True)
    if stream.last_error:
        print(f"{PROG}: the last frame that failed: {stream.last_error}", file=sys.stderr, flush=True)
    restarts = sum(solver.restarts for solver in _processes(solvers))
    if restarts:
        times = "once" if restarts == 1 else f"{restarts} times"
        print(f"{PROG}: solver processes that ended were started again {times}", file=sys.stderr, flush=True)
    if recorder is not None:
        unwritten = recorder.added - recorder.written + recorder.dropped
        print(f"recorded {recorder.written} frames to {args.record}"
              + (f"; {unwritten} received but not written" if unwritten else ""), flush=True)
    if log is not None and not _write_forces(log, args.forces):
        failed.set()
    return 1 if failed.is_set() else 0


def _publisher(source, outlet, log, *, stress: bool):
    """``publish(frame, result)``: the forces to the LSL outlet (stamped on LSL's clock) and the log."""
    from ..sources.lsl import clock_offset

    offset = None

    def publish(frame, result):
        nonlocal offset
        if outlet is not None:
            if offset is None:  # at the first frame: the reader's clock starts when the board is opened
                offset = clock_offset(source.now)
            outlet.push(result.forces, stamp=frame.t + offset, stress=frame.stress if stress else None)
        if log is not None:
            log.add(frame, result)
    return publish


def faster_settings(settings):
    """What a stream that has fallen behind solves with (``--catch-up``): for the standard automatic
    solve, the automatic fit on whole cells (the trade-off tool's faster member, about a third of
    the standard solve's time); None for any other setting (given parameters and the presets are
    fast already, or chosen)."""
    if settings.preset is not None or settings.mode != "auto":
        return None
    return replace(settings, preset=FASTER_PRESET)


def _solvers(settings, grid, count: int, *, catch_up: bool) -> tuple:
    """The stream's solver and the faster member beside it, both built and warmed here (a thread of
    this process), or a list of ``count`` processes, each building and warming its own (and no
    faster member here).

    Raises
    ------
    RuntimeError, OSError
        When a solver could not be built or a process started (the ones started are ended first).
    """
    faster = faster_settings(settings) if catch_up else None  # built only to be used
    if count == 1:
        solver = settings.build(grid)
        quick = None if faster is None else faster.build(grid)
        warm(*(s for s in (solver, quick) if s is not None))
        return solver, quick
    build = functools.partial(settings.build, grid)
    quick = None if faster is None else functools.partial(faster.build, grid)
    started = []
    try:
        # started together, then waited for: each takes a second or two to import and warm up
        for k in range(count):
            started.append(SolverProcess(build, faster=quick, name=f"{PROG} solver {k + 1}", wait=False))
        for process in started:
            process.wait_ready()
    except BaseException:
        _close(started)
        raise
    return started, None


def _processes(solvers) -> list:
    return [solver for solver in solvers if isinstance(solver, SolverProcess)] \
        if isinstance(solvers, list) else []


def _close(solvers) -> None:
    for solver in _processes(solvers):
        solver.close()  # a second close of the same one does nothing


def _size(spool: Path) -> str:
    total = sum(p.stat().st_size for p in spool.iterdir() if p.is_file())
    return f"{total / 1e6:.1f} MB"


def _recover(spool: str, out: str | None, *, overwrite: bool) -> int:
    """``--recover``: the spool's frames to the force file it was for (or ``out``), then the spool removed."""
    try:
        table, target = recover(spool)
    except (OSError, ValueError) as exc:
        print(f"{PROG}: --recover {spool}: {getattr(exc, 'strerror', None) or exc}", file=sys.stderr)
        return 1
    path = Path(out) if out is not None else target
    if os.path.lexists(path) and not overwrite:
        print(f"{PROG}: --recover {spool}: {path} exists: not replacing it (--overwrite replaces it, "
              f"--forces names another file)", file=sys.stderr)
        return 2
    T = len(table.frames)
    if not _save(table, path, f" from {spool}", f"--recover {spool}: cannot write {path}"):
        return 1
    del table  # its forces are mapped from the spool
    shutil.rmtree(spool, ignore_errors=True)
    print(f"wrote the forces of {T} frames to {path}; removed {spool}", flush=True)
    return 0


def _save(table, path, origin: str, failure: str) -> bool:
    # the force table to its file, said before (a large take's takes a while) and when it fails
    print(f"writing the forces of {len(table.frames)} frames{origin} to {path} ...", flush=True)
    try:
        save_forces(table, path)
    except OSError as exc:
        print(f"{PROG}: {failure}: {exc.strerror or exc}", file=sys.stderr, flush=True)
        return False
    return True


def _write_forces(log: ForceLog, path: str) -> bool:
    try:
        table = log.table()
    except ValueError as exc:
        print(f"{PROG}: --forces {path} not written: {exc}", file=sys.stderr, flush=True)
        return False
    if not _save(table, path, "", f"--forces {path}: cannot write"):
        return False
    print(f"wrote the forces of {len(log)} frames to {path}", flush=True)
    if log.left_out:
        print(f"{PROG}: --forces {path} holds {len(log)} of the frames published; {log.left_out} were left "
              f"out ({log.reason()})", file=sys.stderr, flush=True)
        return False
    return True


if __name__ == "__main__":
    sys.exit(main())

"""tactile-batch: reconstruct every frame of many recordings into force files, in parallel.

``tactile-batch INPUT... --out DIR [--preset NAME | --view SIDECAR.view.json] [--kernel K]
[--format npz|csv|foxglove] [--workers N] [--scheduler local|tcp://host:port] [--chunk FRAMES]
[--layout SKIN.json [--topic T] [--field F]]``
writes ``DIR/<recording name>.forces.npz`` (or ``.csv``) for each recording, the
viewer's whole-recording force export (File > Export forces), or ``.forces.mcap``
for Foxglove (``--format foxglove``: File > Export for Foxglove), and beside it
``<output>.batch.json`` naming the input and the settings; a rerun skips the
outputs already finished. Frames are solved in chunks on joblib's processes or a
Dask cluster. ROS 2 bags among the inputs (a folder with ``metadata.yaml``, a
``.db3``, another program's ``.mcap``) are read through ``--layout`` (and
``--topic``/``--field``), each decoded at most once per worker process. A
progress line and a summary go to stderr; a file that fails is
named with its reason and the others go on (exit status 1). No Qt.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from solver.kernels import KERNELS

from ..io.recording import RecordingError
from ..model.batch import (
    DEFAULT_CHUNK,
    PRESET_NAMES,
    FileOutcome,
    plan_file,
    settings_from_preset,
    settings_from_view,
)
from ..model.batch_engines import DaskEngine, JoblibEngine, check_scheduler, run_batch
from ..model.batch_inputs import FORMATS, BagOptions, find_recordings, is_finished
from ..model.captions import KERNEL_HELP

__all__ = ["main"]

PROG = "tactile-batch"


def _cpu_count() -> int:
    # the CPUs this process may run on (a container's or taskset's share), not the machine's
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="recordings (.mcap, .npz, .csv), ROS 2 bags (a folder with metadata.yaml, "
                             "a .db3, another program's .mcap) or folders: every recording and bag in a "
                             "folder and its sub-folders (a bag folder is one bag; hidden files and "
                             "*.forces.* files left out)")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="the folder for the force files (made if missing); a folder's recordings keep "
                             "their sub-folders there")
    settings = parser.add_mutually_exclusive_group()
    settings.add_argument("--preset", metavar="NAME", choices=PRESET_NAMES,
                          help="a quality setting, by name: " + ", ".join(map(repr, PRESET_NAMES))
                          + " (default: the standard solve, automatic parameters)")
    settings.add_argument("--view", metavar="SIDECAR.view.json",
                          help="solve with the kernel and parameters of a screenshot's sidecar (automatic, "
                               "or the fixed shear ratio and direction it names)")
    parser.add_argument("--kernel", choices=KERNELS,
                        help="the stress kernel, replacing the preset's or sidecar's (default: theirs, "
                             f"else {KERNELS[0]}). " + KERNEL_HELP.replace("\n", " "))
    parser.add_argument("--format", choices=FORMATS, default="npz",
                        help="the force files' format (default npz; npz and csv are the viewer's force "
                             "exports, foxglove an MCAP file Foxglove shows: <name>.forces.mcap with "
                             "pressure maps, force arrows and per-contact totals)")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="worker processes on this machine for joblib or --scheduler local "
                             f"(default: the CPUs this process may use, {_cpu_count()} here)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="solve on Dask: 'local' starts a cluster of --workers processes here, "
                             "tcp://host:port uses a running cluster (its workers need tactile-viewer "
                             "installed and the recordings at the same paths); default: joblib")
    bags = parser.add_argument_group("ROS 2 bags", "how every bag among the inputs is read (recordings of "
                                     "this viewer carry their own layout and ignore these)")
    bags.add_argument("--layout", metavar="FILE",
                      help="the skin's sensor layout JSON (geometry, units, gain, offset; the one a live "
                           "board uses): needed when an input is a bag")
    bags.add_argument("--topic", metavar="TOPIC",
                      help="the bags' array topic (default: the only one whose messages fit the layout)")
    bags.add_argument("--field", metavar="FIELD",
                      help="the numeric array field of its messages, dot-separated when nested (default: the "
                           "only one)")
    parser.add_argument("--chunk", type=int, default=DEFAULT_CHUNK, metavar="FRAMES",
                        help=f"frames per task (default {DEFAULT_CHUNK}); a worker opens each recording "
                             "or bag once and solves its chunks")
    return parser


class ProgressLine:
    """The progress line on a stream: frames done of all, frames per second, time left.

    Rewritten in place at most 4 times a second on a terminal; elsewhere (a log,
    a pipe) one line at most once a second.
    """

    def __init__(self, stream, *, clock=time.monotonic):
        self.stream, self.clock = stream, clock
        self.terminal = bool(getattr(stream, "isatty", lambda: False)())
        self.interval = 0.25 if self.terminal else 1.0
        self.start = clock()
        self._last = -math.inf
        self._open = False  # a line being rewritten in place waits for its end
        self._latest, self._behind = (0, 0), False  # the last counts given; not shown yet

    def update(self, done: int, total: int, *, force: bool = False) -> None:
        """Show ``done`` of ``total`` frames unless the last line is younger than the interval."""
        now = self.clock()
        self._latest = (done, total)
        if not force and now - self._last < self.interval:
            self._behind = True
            return
        self._last, self._behind = now, False
        elapsed = now - self.start
        rate = done / elapsed if elapsed > 0 else 0.0
        left = _clock((total - done) / rate) if rate > 0 else "unknown"
        share = 100 * done / total if total else 100.0
        text = f"frames {done}/{total} ({share:.0f}%), {rate:.1f} frames/s, left {left}"
        if self.terminal:
            self.stream.write("\r" + text + "\x1b[K")
            self._open = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def show_last(self) -> None:
        """Show the last counts given if the interval held them back (the final line)."""
        if self._behind:
            self.update(*self._latest, force=True)

    def say(self, text: str, *, stream=None) -> None:
        """A line of its own (a file written or failed) on ``stream`` (default the line's), below the line."""
        self.end()
        stream = stream or self.stream
        stream.write(text + "\n")
        stream.flush()

    def end(self) -> None:
        """End the line being rewritten, if any."""
        if self._open:
            self.stream.write("\n")
            self._open = False


def _clock(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def summary(outcomes, *, wall: float, engine: str) -> str:
    """The last line: files written, skipped and failed, frames written, wall time, frames per second."""
    count = {status: sum(o.status == status for o in outcomes) for status in ("written", "skipped", "failed")}
    frames = sum(o.frames for o in outcomes if o.status == "written")
    rate = frames / wall if wall > 0 else 0.0
    files = f"{count['written']} file{'s' if count['written'] != 1 else ''} written"
    return (f"{PROG}: {files}, {count['skipped']} skipped, {count['failed']} failed; {frames} frames in "
            f"{wall:.1f} s wall ({rate:.1f} frames/s; {engine})")


def _engine(args):
    if args.scheduler is None:
        return JoblibEngine(args.workers or _cpu_count())
    if args.scheduler == "local":
        return DaskEngine.local(args.workers or _cpu_count())
    return DaskEngine.connect(args.scheduler)


def main(argv=None) -> int:
    """Run ``tactile-batch``.

    Parameters
    ----------
    argv : list of str, optional
        The arguments; default the command line's.

    Returns
    -------
    int
        0 when every file was written or skipped, 1 when one failed (the others
        are written), 2 for bad options, 130 when interrupted.
    """
    started = time.monotonic()
    parser = _parser()
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error(f"--workers must be a whole number of processes >= 1, got {args.workers}")
    if args.workers is not None and args.scheduler not in (None, "local"):
        parser.error(f"--workers applies to joblib and --scheduler local, not to the cluster at "
                     f"{args.scheduler} (its workers are the cluster's), got --workers {args.workers}")
    if args.chunk < 1:
        parser.error(f"--chunk must be a whole number of frames >= 1, got {args.chunk}")
    try:
        settings = (settings_from_view(args.view, args.kernel) if args.view is not None
                    else settings_from_preset(args.preset, args.kernel))
        if args.scheduler not in (None, "local"):
            check_scheduler(args.scheduler)
        if args.layout is None and (args.topic, args.field) != (None, None):
            raise ValueError("--topic and --field choose what a ROS 2 bag is read from: give --layout too "
                             f"(got --topic {args.topic}, --field {args.field})")
        bag = (None if args.layout is None
               else BagOptions.from_layout_file(args.layout, topic=args.topic, field=args.field))
        inputs = find_recordings(args.inputs, args.out, args.format, bag=bag)
        if os.path.lexists(args.out) and not Path(args.out).is_dir():
            raise ValueError(f"--out must be a folder, got {args.out!r} (a file)")
    except ValueError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    try:
        Path(args.out).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"{PROG}: --out {args.out}: cannot make the folder: {exc.strerror or exc}", file=sys.stderr)
        return 2
    progress = ProgressLine(sys.stderr)
    outcomes: list[FileOutcome] = []
    if bag is not None and all(i.bag is None for i in inputs):
        progress.say(f"{PROG}: note: --layout, --topic and --field are unused: no input is a ROS 2 bag "
                     "(recordings of this viewer carry their own layout)")

    def tell(outcome: FileOutcome):
        outcomes.append(outcome)
        if outcome.status == "failed":
            progress.say(f"{PROG}: failed: {outcome.input.path}: {outcome.reason}")
        elif outcome.status == "written":
            progress.say(f"wrote {outcome.input.output} ({outcome.frames} frames of {outcome.input.path})",
                         stream=sys.stdout)

    engine, description = None, "nothing to solve"
    try:
        plans = _plans(inputs, settings, args.chunk, tell, progress)
        if plans:
            try:
                engine = _engine(args)
            except (OSError, ValueError) as exc:
                print(f"{PROG}: {exc}", file=sys.stderr)
                return 2
            description = engine.description
            total = sum(plan.frames for plan in plans)
            progress.start = progress.clock()  # frames per second of the solving, not of the planning
            progress.update(0, total, force=True)
            run_batch(plans, engine, on_chunk=progress.update, on_file=tell)
            progress.show_last()
        progress.end()
    except KeyboardInterrupt:
        progress.say(f"{PROG}: interrupted: the files written so far are whole, the others were not written")
        return 130
    finally:
        if engine is not None:
            engine.close()
    print(summary(outcomes, wall=time.monotonic() - started, engine=description), file=sys.stderr, flush=True)
    return 1 if any(o.status == "failed" for o in outcomes) else 0


def _plans(inputs, settings, chunk, tell, progress) -> list:
    # skip the finished outputs, open the others once (their frames, geometry, times), report the unreadable
    plans = []
    for batch_input in inputs:
        if is_finished(batch_input, settings):
            tell(FileOutcome(batch_input, "skipped"))
            print(f"skipped {batch_input.path}: {batch_input.output} is finished (same input and settings)",
                  flush=True)
            continue
        try:
            plan = plan_file(batch_input, settings, chunk)
        except (RecordingError, OSError) as exc:
            tell(FileOutcome(batch_input, "failed", 0, str(exc)))
            continue
        for damage in plan.damage:
            progress.say(f"{PROG}: note: {batch_input.path}: {damage} (the frames read are solved)")
        plans.append(plan)
    return plans


if __name__ == "__main__":
    sys.exit(main())

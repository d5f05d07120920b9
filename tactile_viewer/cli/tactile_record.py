"""tactile-record: record a live board to an MCAP file without a display (robot PCs).

``tactile-record URL --layout LAYOUT.json --out FILE.mcap [--format text|binary] [--duration S]``
records every frame the board sends (raw values, their calibration, receive
times and sequence numbers: the viewer opens the file like any recording),
prints the frame rate, the recorded, lost and rejected counts once a second,
and stops cleanly on Ctrl+C or SIGTERM (the file is then complete; a kill -9
leaves it readable up to its last complete chunk, at most a second before).
No Qt.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ..io.layout import LayoutError, load_layout
from ..sources.serial_reader import SerialReader
from .board_options import add_board_arguments, check_duration, print_messages, seconds_left, stop_on_signals

__all__ = ["main"]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tactile-record", description=__doc__.splitlines()[0])
    parser.add_argument("url", metavar="URL",
                        help="the board: a device path (/dev/ttyACM0) or a pyserial URL (socket://host:port)")
    parser.add_argument("--layout", required=True, metavar="LAYOUT.json",
                        help="the sensor layout: geometry and the calibration of the raw values")
    parser.add_argument("--out", required=True, metavar="FILE.mcap", help="the recording to write")
    parser.add_argument("--overwrite", action="store_true", help="replace FILE.mcap if it exists")
    add_board_arguments(parser)
    args = parser.parse_args(argv)
    check_duration(parser, args)
    try:
        layout = load_layout(args.layout)
    except (OSError, LayoutError) as exc:
        print(f"tactile-record: {exc}", file=sys.stderr)
        return 2
    if os.path.lexists(args.out) and not args.overwrite:  # a dangling link is something there too
        print(f"tactile-record: {args.out} exists: not replacing a recording (--overwrite replaces it)",
              file=sys.stderr)
        return 2
    stop = stop_on_signals()
    try:
        reader = SerialReader(args.url, layout, fmt=args.format, baudrate=args.baudrate)
    except ValueError as exc:
        print(f"tactile-record: {exc}", file=sys.stderr)
        return 2
    failed = print_messages(reader)
    try:
        reader.start()
    except (OSError, ValueError) as exc:
        print(f"tactile-record: cannot open {args.url}: {exc}", file=sys.stderr)
        return 1
    try:
        recorder = reader.start_recording(args.out)
    except (OSError, ValueError) as exc:
        reader.stop()
        print(f"tactile-record: cannot record: {exc}", file=sys.stderr)
        return 1
    print(f"recording {args.url} ({args.format}) to {args.out}; Ctrl+C stops", flush=True)
    start = time.monotonic()
    try:
        while not stop.wait(min(1.0, seconds_left(start, args.duration))):
            elapsed = time.monotonic() - start
            stats = reader.stats.snapshot(reader.now())
            print(f"{elapsed:7.1f} s  {stats.rate:7.1f} frames/s  recorded {recorder.added}  "
                  + (f"not recorded {recorder.dropped} (the disk is slower)  " if recorder.dropped else "")
                  + f"lost {stats.lost}  rejected {sum(reader.rejected().values())}  {reader.state}"
                  + (f" ({reader.error})" if reader.error else ""), flush=True)
            if reader.recorder is None:  # ended by a write error or a reconnection (said on stderr)
                failed.set()
                break
            if args.duration is not None and elapsed >= args.duration:
                break
    finally:
        closing = time.perf_counter()
        written = reader.stop_recording()
        closing = time.perf_counter() - closing
        reader.stop()
    stats = reader.stats
    # what the file holds, not what was handed to the recorder (after a write error they differ)
    unwritten = recorder.added - recorder.written + recorder.dropped
    print(f"stopped: {recorder.written} frames recorded to {written or args.out} (closed in "
          f"{closing * 1e3:.0f} ms), lost {stats.lost}, rejected {sum(reader.rejected().values())}, "
          f"longest wait between frames {stats.longest_gap * 1e3:.0f} ms"
          + (f"; {unwritten} received but not written" if unwritten else ""), flush=True)
    mismatch = reader.size_mismatch(Path(args.layout).name)
    if mismatch:
        print(f"tactile-record: rejected for their value count: {mismatch}", file=sys.stderr, flush=True)
    return 1 if failed.is_set() else 0


if __name__ == "__main__":
    sys.exit(main())

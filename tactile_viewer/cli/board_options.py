"""The options and the clock of the headless commands that read a live board.

``tactile-record`` and ``tactile-stream`` read a board the same way: its frame
format, baud rate and how long to run, checked alike. No Qt.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time

from ..sources.protocol import FORMATS

__all__ = ["add_board_arguments", "check_duration", "seconds_left", "stop_on_signals", "print_messages"]


def add_board_arguments(parser: argparse.ArgumentParser, *, format_help: str = "the board's frame format "
                        "(default binary)") -> None:
    """Add ``--format``, ``--baudrate`` and ``--duration``."""
    parser.add_argument("--format", choices=FORMATS, default="binary", help=format_help)
    parser.add_argument("--baudrate", type=int, default=115200,
                        help="the board's baud rate (default 115200; pseudo-terminals and sockets ignore it)")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="stop after S seconds (default: on Ctrl+C or SIGTERM)")


def check_duration(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """End the command (``parser.error``, exit status 2) for a ``--duration`` that is not finite and > 0."""
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration must be a finite number of seconds > 0, got {args.duration!r}")


def seconds_left(start: float, duration: float | None) -> float:
    """Seconds until ``duration`` after ``start`` (``time.monotonic``), 1 without a duration: how long
    a once-a-second report loop waits next."""
    if duration is None:
        return 1.0
    return max(0.0, duration - (time.monotonic() - start))


def stop_on_signals() -> threading.Event:
    """An event that Ctrl+C (SIGINT) and SIGTERM set: the command's loop ends cleanly on it."""
    stop = threading.Event()
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda *_: stop.set())
    return stop


def print_messages(source) -> threading.Event:
    """Print a source's messages on stderr as ``level: title: text``; the event returned is set by
    the first error (the command then exits 1)."""
    failed = threading.Event()

    def tell(level, title, text):
        print(f"{level}: {title}: {text}", file=sys.stderr, flush=True)
        if level == "error":
            failed.set()
    source.message.connect(tell)
    return failed

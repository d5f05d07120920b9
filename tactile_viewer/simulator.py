"""``tactile-sim``: a virtual sensor board streaming a moving simulated contact.

It creates a pseudo-terminal and prints its device path (``--link PATH`` also
makes a stable symlink to it, so a restarted board reappears at the same
path), or writes to any pyserial URL (``--url socket://host:port``). Frames
of a Hertzian contact circling the skin with turning shear, from
:mod:`solver.loads`, go out at ``--rate`` Hz (up to 1 kHz) in text or binary
format, in kPa, with optional injected garbage bytes and dropped frames;
``--checksum`` ends each text line with its ``*XXXX`` CRC-16 (binary frames
always carry one).
``--layout PATH`` writes the sensor layout JSON that goes with the stream,
the elastomer's Poisson ratio (``--poisson-ratio``) and the taxel size
(``--sensor-size``) included.
"""

from __future__ import annotations

import argparse
import math
import os
import select
import signal
import sys
import time
import tty
from pathlib import Path

import numpy as np

from solver import SensorGrid, loads

from .layout import SensorLayout, save_layout
from .protocol import encode_binary, encode_text

__all__ = ["Board", "contact_cycle", "main"]

PERIOD = 2.0  # seconds for the contact to go once round
CYCLE = 100  # precomputed frames per period (the loads are integrated finely: slow)


def contact_cycle(grid: SensorGrid, frames: int = CYCLE, *, force: float = 1.0) -> np.ndarray:
    """``(frames, m)`` clean stress, pascals: a Hertzian press circling the centre, its shear turning."""
    half = 0.25 * min(grid.positions.max(axis=0) - grid.positions.min(axis=0))
    radius = 2.5 * grid.pitch
    out = []
    for k in range(frames):
        phase = 2 * math.pi * k / frames
        centre = (half * math.cos(phase), half * math.sin(phase))
        press = force * (0.75 + 0.25 * math.sin(2 * phase))
        contact = loads.hertz(centre, radius, press, shear_ratio=0.3,
                              shear_direction=math.remainder(phase + math.pi / 2, 2 * math.pi))
        out.append(loads.simulate(grid, contact).stress)
    return np.array(out)


class Board:
    """Makes the byte stream of a simulated board, frame by frame.

    Parameters
    ----------
    layout : SensorLayout
        Values are sent in ``layout.units`` (with gain 1 and offset 0 assumed).
    fmt : {"binary", "text"}
    noise : float
        Gaussian noise, standard deviation relative to the peak clean stress.
    garbage : float
        Probability per frame of a burst of 1 to 40 random bytes before it.
    dropout : float
        Probability per frame of not sending it (its sequence number is used up).
    seed : int
    checksum : bool
        End each text line with ``*XXXX``, its CRC-16 (:func:`~tactile_viewer.protocol.encode_text`);
        text format only, binary frames always carry a CRC.
    """

    def __init__(self, layout: SensorLayout, *, fmt="binary", rate=100.0, noise=0.01, garbage=0.0,
                 dropout=0.0, seed=0, checksum=False):
        if checksum and fmt != "text":
            raise ValueError(f"checksum applies to the text format only (binary frames always carry a CRC), "
                             f"got fmt={fmt!r}")
        self.layout, self.fmt, self.rate, self.checksum = layout, fmt, rate, checksum
        self.rng = np.random.default_rng(seed)
        self.cycle = contact_cycle(layout.grid)
        self.noise = noise * float(np.abs(self.cycle).max())
        self.garbage, self.dropout = garbage, dropout
        self.scale = {"Pa": 1.0, "kPa": 1e-3, "MPa": 1e-6, "counts": 1.0}[layout.units]
        self.seq = 0
        self.sent = self.dropped = self.garbage_bursts = self.garbage_bytes = 0

    def next_bytes(self) -> bytes:
        """The bytes for the next frame (possibly garbage only, or nothing when dropped)."""
        seq, self.seq = self.seq, self.seq + 1
        phase = (seq / self.rate) / PERIOD * len(self.cycle)
        stress = self.cycle[int(phase) % len(self.cycle)] + self.rng.normal(0, self.noise, self.layout.count)
        out = b""
        if self.garbage and self.rng.random() < self.garbage:
            burst = self.rng.integers(0, 256, self.rng.integers(1, 41), dtype=np.uint8).tobytes()
            if self.fmt == "text":
                burst = burst.replace(b"\n", b"") + b"\n"  # text garbage is a bad line
            out += burst
            self.garbage_bursts += 1
            self.garbage_bytes += len(burst)
        if self.dropout and self.rng.random() < self.dropout:
            self.dropped += 1
            return out
        values = stress * self.scale
        if self.fmt == "binary":
            out += encode_binary(seq, values)
        else:
            out += encode_text(values, checksum=self.checksum)
        self.sent += 1
        return out


def _open_pty(link: Path | None):
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo, no newline translation: bytes pass as they are
    name = os.ttyname(slave)
    if link is not None:
        temporary = link.with_name(link.name + ".new")
        temporary.unlink(missing_ok=True)
        temporary.symlink_to(name)
        os.replace(temporary, link)
    return master, slave, name


def _write_all(fd: int, data: bytes, stall: float) -> bool:
    """Write everything unless the reader stalls for ``stall`` seconds (then drop the rest).

    ``fd`` is non-blocking, so a reader that stops reading never blocks the board (or its
    SIGTERM) for longer than ``stall``.
    """
    view = memoryview(data)
    while view:
        _, writable, _ = select.select([], [fd], [], stall)
        if not writable:
            return False
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            continue
    return True


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tactile-sim", description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=100.0, help="frames per second (max 1000)")
    parser.add_argument("--format", choices=("binary", "text"), default="binary")
    parser.add_argument("--checksum", action="store_true",
                        help="end each text line with *XXXX, its CRC-16 (text format only)")
    parser.add_argument("--nx", type=int, default=16)
    parser.add_argument("--ny", type=int, default=16)
    parser.add_argument("--pitch", type=float, default=2e-3, help="metres")
    parser.add_argument("--thickness", type=float, default=2e-3, help="metres")
    parser.add_argument("--poisson-ratio", type=float, default=0.5,
                        help="Poisson ratio nu of the elastomer, in [0, 0.5] (default 0.5: incompressible)")
    parser.add_argument("--sensor-size", type=float, default=0.0,
                        help="side of a square taxel, metres, at most the pitch (default 0: point sensors)")
    parser.add_argument("--units", choices=("Pa", "kPa", "MPa"), default="kPa")
    parser.add_argument("--noise", type=float, default=0.01)
    parser.add_argument("--garbage", type=float, default=0.0, help="probability of a garbage burst per frame")
    parser.add_argument("--dropout", type=float, default=0.0, help="probability of dropping a frame")
    parser.add_argument("--duration", type=float, default=math.inf, help="seconds, then exit")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--url", help="write to this pyserial URL instead of a pseudo-terminal")
    parser.add_argument("--link", type=Path, help="symlink to the pseudo-terminal (a stable device path)")
    parser.add_argument("--layout", type=Path, help="write the matching sensor layout JSON here")
    args = parser.parse_args(argv)
    if not 0 < args.rate <= 1000:
        parser.error(f"--rate must be in (0, 1000], got {args.rate:g}")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        parser.error(f"--noise must be finite and >= 0, got {args.noise:g}")
    if args.checksum and args.format != "text":
        parser.error(f"--checksum needs --format text (binary frames always carry a CRC), "
                     f"got --format {args.format}")
    for name in ("garbage", "dropout"):
        if not 0 <= getattr(args, name) <= 1:
            parser.error(f"--{name} must be a probability in [0, 1], got {getattr(args, name):g}")
    try:
        grid = SensorGrid.regular(args.nx, args.ny, args.pitch, args.thickness,
                                  poisson_ratio=args.poisson_ratio, sensor_size=args.sensor_size)
    except ValueError as exc:
        parser.error(str(exc))
    layout = SensorLayout(grid, args.units)
    if args.layout:
        save_layout(layout, args.layout)

    stopping = []
    # installed before the device path is printed: whoever reads it may stop us at once
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(True))
    if args.url:
        import serial

        port = serial.serial_for_url(args.url, baudrate=115200)
        write = lambda data: port.write(data) == len(data)  # noqa: E731
        print(f"writing to {args.url}", flush=True)
    else:
        master, slave, name = _open_pty(args.link)
        os.set_blocking(master, False)
        write = lambda data: _write_all(master, data, stall=1.0)  # noqa: E731
        print(name + (f" (link {args.link})" if args.link else ""), flush=True)
    # the device exists from here on: a viewer may connect at once and sees frames once the
    # contact is computed (a few seconds of finely integrated loads)
    board = Board(layout, fmt=args.format, rate=args.rate, noise=args.noise, garbage=args.garbage,
                  dropout=args.dropout, seed=args.seed, checksum=args.checksum)
    unsent = 0
    start = time.perf_counter()
    try:
        while not stopping:
            now = time.perf_counter() - start
            if now >= args.duration:
                break
            due = int(now * args.rate) + 1
            if math.isfinite(args.duration):
                due = min(due, math.ceil(args.duration * args.rate))
            chunk = b"".join(board.next_bytes() for _ in range(due - board.seq))
            if chunk and not write(chunk):
                unsent += 1
            time.sleep(max(0.0, (board.seq / args.rate) - (time.perf_counter() - start)))
    except KeyboardInterrupt:
        pass
    finally:
        if args.link:
            args.link.unlink(missing_ok=True)
    print(f"sent {board.sent} frames, dropped {board.dropped}, garbage bursts {board.garbage_bursts} "
          f"({board.garbage_bytes} bytes), unsent writes {unsent}", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

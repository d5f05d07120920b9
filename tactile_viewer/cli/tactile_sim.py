"""tactile-sim: a virtual sensor board streaming simulated contacts.

It creates a pseudo-terminal and prints its device path (``--link PATH`` also
makes a stable symlink to it, so a restarted board reappears at the same
path), or writes to any pyserial URL (``--url socket://host:port``). Frames
of a scene (``--scene``, default ``circle``: a Hertzian contact circling the
skin with turning shear; see :data:`~tactile_viewer.sources.simulated.SCENES`),
from :mod:`solver.loads` through the bonded layer, go out at ``--rate`` Hz (up
to 1 kHz) in text or binary format, in kPa, with optional injected garbage
bytes and dropped frames;
``--checksum`` ends each text line with its ``*XXXX`` CRC-16 (binary frames
always carry one).
``--layout PATH`` writes the sensor layout JSON that goes with the stream,
the elastomer's Poisson ratio (``--poisson-ratio``) and the taxel size
(``--sensor-size``) included.

The scenes and their frames are :mod:`tactile_viewer.sources.simulated`'s: one period of
``CYCLE`` frames that repeats, computed lazily (:class:`~tactile_viewer.sources.simulated.Cycle`):
the first when it is first sent, the rest in a background thread ahead of the stream, so the
board sends within a fraction of a second of its port appearing, and the stream does not depend
on timing.
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

from solver.checks import one_of, real_number

from ..io.layout import SensorLayout, save_layout
from ..sources.device import announce_board, forget_board
from ..sources.protocol import encode_binary, encode_text
from ..sources.simulated import SCENES, shared_cycle
from .skin_options import add_skin_arguments, skin_grid

__all__ = ["Board", "main"]

# A write that waited this long for room (by default: --drop-after): nobody was reading, and the
# frames of that time are skipped. A reader that falls behind for less (a busy machine) gets them
# late, as from a host's buffer: at 0.1 s, a window starved by a loaded machine lost frames of a
# 1 kHz board.
BLOCKED_WRITE_S = 0.5


class Board:
    """Makes the byte stream of a simulated board, frame by frame.

    Parameters
    ----------
    layout : SensorLayout
        Values are sent in ``layout.units`` (with gain 1 and offset 0 assumed).
    scene : str
        One of ``SCENES``; frame ``seq`` shows the scene at ``seq / rate`` seconds.
    fmt : {"binary", "text"}
    noise : float
        Gaussian noise, standard deviation relative to the frame's peak clean stress (as
        :func:`solver.loads.simulate` and the samples have it).
    garbage : float
        Probability per frame of a burst of 1 to 40 random bytes before it.
    dropout : float
        Probability per frame of not sending it (its sequence number is used up).
    seed : int
    checksum : bool
        End each text line with ``*XXXX``, its CRC-16 (:func:`~tactile_viewer.sources.protocol.encode_text`);
        text format only, binary frames always carry a CRC.

    The scene's frames come from :func:`~tactile_viewer.sources.simulated.shared_cycle`: computed
    in the background from the moment the board is made, and each at the latest when it is first
    sent. The board uses the cycle until :meth:`close` (or the end of a ``with`` block); other
    boards of the same scene and grid share it, and it stops computing ahead when the last of them
    closes.

    Raises ``ValueError`` naming the argument for a format, rate, noise or probability out of range.
    """

    def __init__(self, layout: SensorLayout, *, scene="circle", fmt="binary", rate=100.0, noise=0.01,
                 garbage=0.0, dropout=0.0, seed=0, checksum=False, unloaded=0.0):
        one_of("fmt", fmt, ("binary", "text"))
        if checksum and fmt != "text":
            raise ValueError(f"checksum applies to the text format only (binary frames always carry a CRC), "
                             f"got fmt={fmt!r}")
        rate = real_number("rate", rate, rule="a finite number of frames per second > 0",
                           valid=lambda r: math.isfinite(r) and r > 0)
        noise = real_number("noise", noise, rule="a finite number >= 0 (relative to the frame's peak)",
                            valid=lambda n: math.isfinite(n) and n >= 0)
        unloaded = real_number("unloaded", unloaded, rule="a finite number of seconds >= 0",
                               valid=lambda u: math.isfinite(u) and u >= 0)
        garbage, dropout = (real_number(name, value, rule="a probability in [0, 1]",
                                        valid=lambda p: 0 <= p <= 1)
                            for name, value in (("garbage", garbage), ("dropout", dropout)))
        self.layout, self.fmt, self.rate, self.checksum = layout, fmt, rate, checksum
        self.rng = np.random.default_rng(seed)
        self.noise = noise
        self.unloaded = unloaded  # seconds of nothing on the skin first: a tare's moment
        self.garbage, self.dropout = garbage, dropout
        self._closed = False
        self.cycle = shared_cycle(scene, layout.grid).acquire()  # last: nothing to undo if anything fails
        self.period = self.cycle.period
        self.scale = {"Pa": 1.0, "kPa": 1e-3, "MPa": 1e-6, "counts": 1.0}[layout.units]
        self.seq = 0
        self.sent = self.dropped = self.garbage_bursts = self.garbage_bytes = 0

    def index(self, seq: int) -> int:
        """The cycle's frame that sequence number ``seq`` shows."""
        return int((seq / self.rate) / self.period * len(self.cycle)) % len(self.cycle)

    def next_bytes(self) -> bytes:
        """The bytes for the next frame (possibly garbage only, or nothing when dropped)."""
        seq, self.seq = self.seq, self.seq + 1
        k = self.index(seq)
        load = self.cycle[k] if seq >= self.unloaded * self.rate else np.zeros(self.layout.count)
        stress = load + self.rng.normal(0, self.noise * self.cycle.peak(k), self.layout.count)
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

    def close(self):
        """Let go of the cycle: the last board using it stops its computing ahead (later frames are
        then computed when sent). Closing twice does nothing."""
        if not self._closed:
            self._closed = True
            self.cycle.release()

    def __enter__(self) -> Board:
        return self

    def __exit__(self, *exc):
        self.close()


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


def _write_all(fd: int, data: bytes, stall: float) -> tuple[bool, bool]:
    """Write everything unless the reader leaves no room for ``stall`` seconds (then drop the rest).

    ``fd`` is non-blocking, so a reader that stops reading never blocks the board (or its
    SIGTERM) for longer than ``stall``.

    Returns
    -------
    sent : bool
        Everything was written.
    blocked : bool
        The reader left no room for ``stall`` seconds, as the kernel saw it (``select`` timed
        out): the rest was dropped. A stall of this process (another thread holding the GIL, a
        busy machine) is not one: ``select`` looks at the descriptor again when it wakes, while
        the wall time of the whole write would count the stall too (a board computing its cycle
        ahead once skipped 514 frames of a reader that never waited more than 6 ms).
    """
    view = memoryview(data)
    while view:
        _, writable, _ = select.select([], [fd], [], stall)
        if not writable:
            return False, True
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            continue
    return True, False


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tactile-sim", description=__doc__.splitlines()[0])
    scenes = "; ".join(f"{s.name}: {s.summary} ({s.period:g} s period)" for s in SCENES.values())
    parser.add_argument("--scene", choices=tuple(SCENES), default="circle", metavar="NAME",
                        help=f"what the board feels (default circle), one of: {scenes}".replace("%", "%%"))
    parser.add_argument("--rate", type=float, default=100.0, help="frames per second (max 1000)")
    parser.add_argument("--format", choices=("binary", "text"), default="binary",
                        help="frames as binary packets with a CRC (default) or as text lines")
    parser.add_argument("--checksum", action="store_true",
                        help="end each text line with *XXXX, its CRC-16 (text format only)")
    add_skin_arguments(parser)
    parser.add_argument("--units", choices=("Pa", "kPa", "MPa"), default="kPa",
                        help="units of the values sent (default kPa)")
    parser.add_argument("--noise", type=float, default=0.01,
                        help="sensor noise relative to the peak stress (default 0.01)")
    parser.add_argument("--garbage", type=float, default=0.0, help="probability of a garbage burst per frame")
    parser.add_argument("--dropout", type=float, default=0.0, help="probability of dropping a frame")
    parser.add_argument("--duration", type=float, default=math.inf, help="seconds, then exit")
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise and garbage (default 0)")
    parser.add_argument("--unloaded", type=float, default=0.0, metavar="S",
                        help="send S seconds of noise alone, nothing touching, before the scene starts: "
                             "time to connect and tare (default 0)")
    parser.add_argument("--drop-after", type=float, default=BLOCKED_WRITE_S, metavar="S",
                        help="a write that finds no room for S seconds drops its frames, and the frames "
                             "of the time nobody reads are skipped, as a board's whose host does not read "
                             f"(default {BLOCKED_WRITE_S:g}); a reader held up for less gets every frame, "
                             "late. Long: a test that must not lose a frame to a busy machine")
    parser.add_argument("--url", help="write to this pyserial URL instead of a pseudo-terminal")
    parser.add_argument("--link", type=Path, help="symlink to the pseudo-terminal (a stable device path)")
    parser.add_argument("--layout", type=Path, help="write the matching sensor layout JSON here")
    args = parser.parse_args(argv)
    if not 0 < args.rate <= 1000:
        parser.error(f"--rate must be in (0, 1000], got {args.rate:g}")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        parser.error(f"--noise must be finite and >= 0, got {args.noise:g}")
    if not args.duration >= 0:  # nan too
        parser.error(f"--duration must be a number of seconds >= 0 (inf: no limit), got {args.duration:g}")
    if args.checksum and args.format != "text":
        parser.error(f"--checksum needs --format text (binary frames always carry a CRC), "
                     f"got --format {args.format}")
    if not (math.isfinite(args.unloaded) and args.unloaded >= 0):
        parser.error(f"--unloaded must be a finite number of seconds >= 0, got {args.unloaded:g}")
    if not (math.isfinite(args.drop_after) and args.drop_after > 0):
        parser.error(f"--drop-after must be a finite number of seconds > 0, got {args.drop_after:g}")
    stall = args.drop_after
    for name in ("garbage", "dropout"):
        if not 0 <= getattr(args, name) <= 1:
            parser.error(f"--{name} must be a probability in [0, 1], got {getattr(args, name):g}")
    grid = skin_grid(parser, args)
    layout = SensorLayout(grid, args.units)
    if args.layout:
        save_layout(layout, args.layout)

    stopping = []
    # installed before the device path is printed: whoever reads it may stop us at once
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(True))
    if args.url:
        import serial

        port = serial.serial_for_url(args.url, baudrate=115200)
        def write(data):  # a port's write blocks: a write that took that long found no room
            started = time.perf_counter()
            sent = port.write(data) == len(data)
            return sent, time.perf_counter() - started > stall
        room = None  # a port tells no room before a write
        print(f"writing to {args.url}", flush=True)
    else:
        master, slave, name = _open_pty(args.link)
        os.set_blocking(master, False)
        # a write that found no room for the stall drops the rest of its frames: kept waiting,
        # they went to the next reader after it had dropped its backlog, stamped as new
        write = lambda data: _write_all(master, data, stall=stall)  # noqa: E731
        room = lambda: bool(select.select([], [master], [], stall)[1])  # noqa: E731

        note = announce_board(device=name, link=str(args.link) if args.link else None,
                              layout=str(args.layout.resolve()) if args.layout else None, format=args.format,
                              scene=args.scene, rate=args.rate)
        print(name + (f" (link {args.link})" if args.link else ""), flush=True)
    # the device exists from here on: a viewer may connect at once. The first frame is computed
    # when it is sent (tens of milliseconds), the rest of the cycle in the background ahead of the
    # stream; should that fall behind, the stream waits for it and catches up in a burst
    board = Board(layout, scene=args.scene, fmt=args.format, rate=args.rate, noise=args.noise,
                  garbage=args.garbage, dropout=args.dropout, seed=args.seed, checksum=args.checksum,
                  unloaded=args.unloaded)
    total = math.ceil(args.duration * args.rate) if math.isfinite(args.duration) else math.inf
    unsent = unread = 0
    start = time.perf_counter()
    blocked = False
    try:
        while not stopping and board.seq < total:  # --duration: exactly its frames, however slow
            if blocked and room is not None and not room():
                # still nobody reads: no frame is made to wait for a reader (one made now and sent
                # when a reader comes would reach it after it dropped its backlog: 435 frames
                # "lost" between that stale frame and the present)
                due = min(int((time.perf_counter() - start) * args.rate), total)
                unread += max(0, due - board.seq)
                board.seq = max(board.seq, due)
                continue
            now = time.perf_counter() - start
            due = min(int(now * args.rate) + 1, total)
            # nobody read (the last write waited for room): as a real board's, the frames of that
            # time are gone, not queued to arrive later in a burst a reader would stamp all at once
            # (180 frames in 10 ms after opening the terminal, 300 frames a 1 kHz stream skipped)
            if blocked and due - board.seq > 1:
                unread += due - 1 - board.seq
                board.seq = due - 1
            chunk = b"".join(board.next_bytes() for _ in range(due - board.seq))
            sent, blocked = write(chunk) if chunk else (True, False)
            unsent += not sent
            time.sleep(max(0.0, (board.seq / args.rate) - (time.perf_counter() - start)))
    except KeyboardInterrupt:
        pass
    finally:
        board.close()
        if args.link:
            args.link.unlink(missing_ok=True)
        if not args.url:
            forget_board(note)
    print(f"sent {board.sent} frames, dropped {board.dropped}, garbage bursts {board.garbage_bursts} "
          f"({board.garbage_bytes} bytes), unsent writes {unsent}, frames skipped while nobody read "
          f"{unread}", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

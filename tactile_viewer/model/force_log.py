"""The forces a stream published, kept on disk as they come and written as the viewer's force table. No Qt.

:class:`ForceLog` takes each frame published by a
:class:`~tactile_viewer.model.force_stream.ForceStream` (``tactile-stream
--forces``) and appends it at once to spool files in a hidden folder
beside the force file: the node forces (float32, 12 bytes per node), the
frame's row (index, time, parameters, efficiency, residual, condition), its
contacts, followed over the frames published with a
:class:`solver.ContactTracker`, and, for a frame solved by a cheaper member
than the accurate path, a line saying why (its result's ``fallback``). Memory
does not grow with the take: a 16x16 skin at 1 kHz puts 3.1 MB a second on
disk, 11 GB an hour, and the process holds none of it. :meth:`ForceLog.table`
maps the spool back as the viewer's force table (:class:`~tactile_viewer.io.forces.ForceTable`, File > Export
forces) without reading it into memory, and
:func:`~tactile_viewer.io.forces.save_forces` writes it in pieces.

The stream's publishing never waits for the disk: :meth:`ForceLog.add` only
queues the frame, and a thread of the log follows the contacts and writes
(the kernel's write-back stalls a write now and then for tens of milliseconds,
measured: with the writes in the publishing thread the latency's p99 at 1 kHz
went from 6 to 18 ms to about 45 ms, and a stall skipped 199 frames). At most
:data:`QUEUE_FRAMES` frames wait; a frame published while that many wait is
left out of the file and counted (:attr:`ForceLog.behind`).

A frame is appended whole or not at all: each spool file is written without
a buffer, and a frame counts as kept only once all three writes returned.
When a write fails (a full disk), that frame and every later one are counted
(:attr:`ForceLog.unwritten`) and the error kept (:attr:`ForceLog.failure`);
the stream goes on publishing them. :meth:`ForceLog.close` removes the spool.

A stream that ends without closing its log (killed, a power cut) leaves its
spool behind, with a description of the skin and the solve (``about.json``,
written first): :func:`recover` reads the frames whole in it as the same force
table, and :func:`leftover_spools` finds such spools beside a force file
(``tactile-stream --recover SPOOL``).
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import secrets
import shutil
import threading
import time
from pathlib import Path

import numpy as np

from solver import ContactTracker, SensorGrid
from solver.checks import whole_number

from ..io.forces import ForceTable
from ..sources.source import SourceFrame
from .force_tables import CONTACT_FIELDS, contact_records, contact_slots

__all__ = ["ForceLog", "recover", "leftover_spools", "ROW_FIELDS",
           "QUEUE_FRAMES"]

# Frames that may wait for the log's writer: 4 s of a 1 kHz board (a result is about 20 kB on a 16x16
# skin, so at most about 80 MB), far longer than the write-back stalls measured (tens of ms).
QUEUE_FRAMES = 4096

# one float64 each per frame, in this order (each contact: force_tables.CONTACT_FIELDS, its row the
# frame's in the order kept)
ROW_FIELDS = ("frame", "t", "shear_ratio", "shear_direction", "efficiency", "residual", "condition")


# the spool's description of the skin and the solve, written when it is made
ABOUT = "about.json"
SPOOL_VERSION = 2  # 2: each frame's fallback beside it (a spool of 1, which has none, still recovers)
_READ_VERSIONS = (1, 2)


def _write_all(descriptor: int, data: bytes) -> None:
    # os.write may write less than asked (a signal, a nearly full disk): the rest until all is written
    view = memoryview(data)
    while view:
        view = view[os.write(descriptor, view):]


class ForceLog:
    """The forces of the frames a stream published, spooled to disk (module notes).

    Parameters
    ----------
    grid : SensorGrid
        The skin solved.
    kernel : str
        The solver's kernel (recorded in the table).
    mode : {"auto", "manual"}
        Whether the parameters were found for each frame or given.
    source : str
        What the frames came from (recorded in the table).
    spool_beside : path-like
        The spool is a hidden folder in this file's folder (the force file's:
        the same disk, which then also holds the file written from it).

    queue_frames : int, optional
        Most frames waiting for the writer (default :data:`QUEUE_FRAMES`).

    Raises
    ------
    OSError
        When the spool cannot be made there.
    """

    def __init__(self, grid: SensorGrid, *, kernel: str, mode: str, spool_beside, source: str = "",
                 queue_frames: int = QUEUE_FRAMES):
        self.grid, self.kernel, self.mode, self.source = grid, kernel, mode, source
        self.behind = 0  # frames published while queue_frames waited (the disk did not keep up)
        self.unwritten = 0  # frames published after a write failed
        self.failure: Exception | None = None  # the write that failed (an OSError but for a defect)
        self._queue: queue.Queue = queue.Queue(maxsize=whole_number("queue_frames", queue_frames, low=1))
        self._kept = 0
        self._contacts = 0
        self._last_index: int | None = None
        self._tracker = ContactTracker(grid)
        target = Path(spool_beside)
        self.spool = target.parent / f".{target.name}.{secrets.token_hex(4)}.spool"
        self.spool.mkdir()
        self._files = {}
        try:
            (self.spool / ABOUT).write_text(json.dumps(dict(
                version=SPOOL_VERSION, target=target.name, kernel=kernel, mode=mode, source=source,
                shape=list(grid.shape), pitch=grid.pitch, thickness=grid.thickness,
                poisson_ratio=grid.poisson_ratio, sensor_size=grid.sensor_size,
                positions=grid.positions.tolist())))
            for part in ("forces", "rows", "contacts", "fallback"):
                self._files[part] = os.open(self.spool / part, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError:
            self.close()
            raise
        self._writer = threading.Thread(target=self._write, name="force log", daemon=True)
        self._writer.start()

    def __len__(self) -> int:
        """Frames kept so far (on disk, whole)."""
        return self._kept

    @property
    def left_out(self) -> int:
        """Frames published but not in the file: :attr:`behind` plus :attr:`unwritten`."""
        return self.behind + self.unwritten

    def reason(self) -> str:
        """Why frames were left out, in words ("" when none was)."""
        reasons = []
        if self.failure is not None:
            reasons.append(f"{self.unwritten} after a write failed: "
                           f"{getattr(self.failure, 'strerror', None) or self.failure}")
        if self.behind:
            reasons.append(f"{self.behind} while the disk fell {self._queue.maxsize} frames behind")
        return "; ".join(reasons)

    def add(self, frame: SourceFrame, result) -> None:
        """Queue one published frame for the file (frames in the order published); never waits.

        A frame published while :data:`QUEUE_FRAMES` wait is left out and counted (:attr:`behind`).
        """
        try:
            self._queue.put_nowait((frame.index, frame.t, result))
        except queue.Full:
            self.behind += 1

    def flush(self) -> None:
        """Wait until every frame queued so far is written (or counted as unwritten)."""
        self._queue.join()

    def _write(self):
        # the writer thread: frames in the order queued; None ends it
        while True:
            item = self._queue.get()
            try:
                if item is None:
                    return
                self._append(*item)
                # hand the GIL over after each frame: the stream runs with a long switch interval
                # (tactile-stream's SWITCH_INTERVAL_S), during which a backlog of frames would keep
                # the reader and the solvers waiting for it
                time.sleep(0)
            except Exception as exc:  # not a write's (those are counted in _append): the rest are unwritten
                self.failure = exc
                self.unwritten += 1
            finally:
                self._queue.task_done()

    def _append(self, index, t, result) -> None:
        if self.failure is not None:
            self.unwritten += 1
            return
        index = self._kept if index is None else index
        # frames skipped between two published ones count as frames their contacts were unseen
        step = max(1, index - self._last_index) if self._last_index is not None else 1
        numbered = self._tracker.update(result, step)
        self._last_index = index
        contacts = contact_records(numbered.contacts, self._kept)
        row = np.array([index, t, result.shear_ratio, result.shear_direction, result.efficiency,
                        result.residual, result.condition], dtype=np.float64)
        try:
            # the row last: a frame whose row is written is whole (the table reads as many as were kept)
            _write_all(self._files["forces"], np.ascontiguousarray(result.forces, np.float32).tobytes())
            _write_all(self._files["contacts"], contacts.tobytes())
            if result.fallback:  # a frame off the accurate path: "ROW<tab>why" (one line)
                _write_all(self._files["fallback"],
                           f"{self._kept}\t{' '.join(result.fallback.split())}\n".encode())
            _write_all(self._files["rows"], row.tobytes())
        except OSError as exc:
            self.failure = exc
            self.unwritten += 1
            return
        self._kept += 1
        self._contacts += len(contacts)

    def table(self) -> ForceTable:
        """The force table of every frame kept, read from the spool as it is needed (not into memory).

        ``forces`` is float32 (newtons, what was published), ``frames`` the frames' sequence numbers.
        Waits for the frames queued first (:meth:`flush`).

        Raises
        ------
        ValueError
            When no frame was kept.
        """
        self.flush()
        if not self._kept:
            raise ValueError("no frame was published: there are no forces to write")
        return _spool_table(self.spool, _read_about(self.spool), self._kept, self._contacts)

    def close(self) -> None:
        """Stop the writer, close and remove the spool (a table taken from it before can no longer be read).

        Frames still queued are written first.
        """
        writer = getattr(self, "_writer", None)
        if writer is not None and writer.is_alive():
            self._queue.put(None)
            writer.join()
        for descriptor in self._files.values():
            os.close(descriptor)
        self._files = {}
        shutil.rmtree(self.spool, ignore_errors=True)


def _read_about(spool: Path) -> dict:
    # the spool's description, checked: a ValueError names what is wrong with it
    try:
        about = json.loads((spool / ABOUT).read_text())
    except FileNotFoundError:
        raise ValueError(f"{spool} is not a force spool: it has no {ABOUT}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{spool / ABOUT} is not a spool's description: {exc}") from None
    if not isinstance(about, dict) or about.get("version") not in _READ_VERSIONS:
        found = about.get("version") if isinstance(about, dict) else about
        raise ValueError(f"{spool / ABOUT}: a spool of version {' or '.join(map(str, _READ_VERSIONS))} was "
                         f"expected, got {found!r}")
    return about


def _spool_table(spool: Path, about: dict, kept: int, contacts: int) -> ForceTable:
    # the force table of the first ``kept`` frames of a spool and their contacts (of the first
    # ``contacts`` records: a frame cut short may have written its contacts but not its row)
    positions = np.array(about["positions"], dtype=np.float64).reshape(-1, 2)
    forces = np.memmap(spool / "forces", dtype=np.float32, mode="r", shape=(kept, positions.shape[0], 3))
    rows = np.fromfile(spool / "rows", dtype=np.float64, count=kept * len(ROW_FIELDS)).reshape(kept, -1)
    flat = np.fromfile(spool / "contacts", dtype=np.float64,
                       count=contacts * len(CONTACT_FIELDS)).reshape(-1, len(CONTACT_FIELDS))
    identity, force, centre = contact_slots(flat[flat[:, 0] < kept], kept)
    fallback = np.full(kept, "", dtype=object)
    with contextlib.suppress(FileNotFoundError):  # a spool of version 1 has none
        # whole lines only: the last one of a frame cut short may stop anywhere, even inside its row
        for line in (spool / "fallback").read_text(encoding="utf-8", errors="replace").split("\n")[:-1]:
            row, tab, why = line.partition("\t")
            if tab and row.isdigit() and int(row) < kept:
                fallback[int(row)] = why
    return ForceTable(forces=forces, frames=rows[:, 0].astype(np.int64), t=rows[:, 1],
                      shear_ratio=rows[:, 2], shear_direction=rows[:, 3], efficiency=rows[:, 4],
                      residual=rows[:, 5], condition=rows[:, 6], positions=positions,
                      shape=tuple(about["shape"]), pitch=about["pitch"], thickness=about["thickness"],
                      kernel=about["kernel"], mode=about["mode"], source=about["source"],
                      poisson_ratio=about["poisson_ratio"], sensor_size=about["sensor_size"],
                      contact_identity=identity, contact_force=force, contact_centre=centre,
                      fallback=fallback.astype(str))


def recover(spool) -> tuple:
    """The force table of a spool a stream left behind (module notes), and the file it was for.

    A frame is whole once its row is written (the row is its last write), so
    the frames are the whole rows; a frame cut short by the end is not one.
    ``forces`` is read from the spool as it is needed: write the table
    (:func:`~tactile_viewer.io.forces.save_forces`) before removing the spool.

    Parameters
    ----------
    spool : path-like
        The spool folder (``.NAME.XXXXXXXX.spool`` beside the force file).

    Returns
    -------
    table : ForceTable
        Every whole frame in the spool.
    target : Path
        The force file the stream was writing (beside the spool).

    Raises
    ------
    ValueError
        When the folder is not a spool this version can read, or holds no whole frame.
    OSError
        When it cannot be read.
    """
    spool = Path(spool)
    about = _read_about(spool)
    m = len(about["positions"])
    kept = min((spool / "rows").stat().st_size // (8 * len(ROW_FIELDS)),
               (spool / "forces").stat().st_size // (12 * m))
    if not kept:
        raise ValueError(f"{spool} holds no whole frame: there are no forces to write")
    contacts = (spool / "contacts").stat().st_size // (8 * len(CONTACT_FIELDS))
    return _spool_table(spool, about, kept, contacts), spool.parent / about["target"]


def leftover_spools(path) -> list:
    """The spools that streams writing the force file ``path`` left behind beside it, oldest first."""
    target = Path(path)
    found = [p for p in target.parent.glob(f".{target.name}.*.spool") if (p / ABOUT).is_file()]
    return sorted(found, key=lambda p: p.stat().st_mtime)

"""The forces a stream published, kept on disk as they come and written as the viewer's force table. No Qt.

:class:`ForceLog` takes each frame published by a
:class:`~tactile_viewer.model.force_stream.ForceStream` (``tactile-stream
--forces``) and appends it at once to three spool files in a hidden folder
beside the force file: the node forces (float32, 12 bytes per node), the
frame's row (index, time, parameters, efficiency, residual, condition) and its
contacts, followed over the frames published with a
:class:`solver.ContactTracker`. Memory does not grow with the take: a 16x16
skin at 1 kHz puts 3.1 MB a second on disk, 11 GB an hour, and the process
holds none of it. :meth:`ForceLog.table` maps the spool back as the viewer's
force table (:class:`~tactile_viewer.io.forces.ForceTable`, File > Export
forces) without reading it into memory, and
:func:`~tactile_viewer.io.forces.save_forces` writes it in pieces.

A frame is appended whole or not at all: each spool file is written without
a buffer, and a frame counts as kept only once all three writes returned.
When a write fails (a full disk), that frame and every later one are counted
(:attr:`ForceLog.left_out`) and the error kept (:attr:`ForceLog.failure`);
the stream goes on publishing them. :meth:`ForceLog.close` removes the spool.
"""

from __future__ import annotations

import os
import secrets
import shutil
from pathlib import Path

import numpy as np

from solver import ContactTracker, SensorGrid

from ..io.forces import ForceTable
from ..sources.source import SourceFrame

__all__ = ["ForceLog", "ROW_FIELDS", "CONTACT_FIELDS"]

# one float64 each per frame, in this order
ROW_FIELDS = ("frame", "t", "shear_ratio", "shear_direction", "efficiency", "residual", "condition")
# one float64 each per contact: the row of its frame (0, 1, ... in the order kept), then the contact
CONTACT_FIELDS = ("row", "identity", "Fx", "Fy", "Fz", "x", "y")


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
    spool_beside : path-like or None
        The spool is a hidden folder in this file's folder (the force file's:
        the same disk, which then also holds the file written from it); None
        (default): the system's temporary folder.

    Raises
    ------
    OSError
        When the spool cannot be made there.
    """

    def __init__(self, grid: SensorGrid, *, kernel: str, mode: str, source: str = "", spool_beside=None):
        self.grid, self.kernel, self.mode, self.source = grid, kernel, mode, source
        self.left_out = 0  # frames published after a write failed
        self.failure: OSError | None = None  # the write that failed
        self._kept = 0
        self._contacts = 0
        self._last_index: int | None = None
        self._tracker = ContactTracker(grid)
        if spool_beside is None:
            import tempfile

            folder = Path(tempfile.gettempdir())
            name = f"tactile-forces.{secrets.token_hex(4)}.spool"
        else:
            target = Path(spool_beside)
            folder, name = target.parent, f".{target.name}.{secrets.token_hex(4)}.spool"
        self.spool = folder / name
        self.spool.mkdir()
        self._files = {}
        try:
            for part in ("forces", "rows", "contacts"):
                self._files[part] = os.open(self.spool / part, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError:
            self.close()
            raise

    def __len__(self) -> int:
        return self._kept

    def add(self, frame: SourceFrame, result) -> None:
        """Append one published frame (frames in the order published), or count it once a write has failed."""
        if self.failure is not None:
            self.left_out += 1
            return
        index = self._kept if frame.index is None else frame.index
        # frames skipped between two published ones count as frames their contacts were unseen
        step = max(1, index - self._last_index) if self._last_index is not None else 1
        numbered = self._tracker.update(result, step)
        self._last_index = index
        contacts = np.array([(self._kept, c.identity, *c.total_force, *c.centre) for c in numbered.contacts],
                            dtype=np.float64).reshape(-1, len(CONTACT_FIELDS))
        row = np.array([index, frame.t, result.shear_ratio, result.shear_direction, result.efficiency,
                        result.residual, result.condition], dtype=np.float64)
        try:
            # the row last: a frame whose row is written is whole (the table reads as many as were kept)
            _write_all(self._files["forces"], np.ascontiguousarray(result.forces, np.float32).tobytes())
            _write_all(self._files["contacts"], contacts.tobytes())
            _write_all(self._files["rows"], row.tobytes())
        except OSError as exc:
            self.failure = exc
            self.left_out += 1
            return
        self._kept += 1
        self._contacts += len(contacts)

    def table(self) -> ForceTable:
        """The force table of every frame kept, read from the spool as it is needed (not into memory).

        ``forces`` is float32 (newtons, what was published), ``frames`` the frames' sequence numbers.

        Raises
        ------
        ValueError
            When no frame was kept.
        """
        if not self._kept:
            raise ValueError("no frame was published: there are no forces to write")
        T, m = self._kept, self.grid.size
        forces = np.memmap(self.spool / "forces", dtype=np.float32, mode="r", shape=(T, m, 3))
        rows = np.fromfile(self.spool / "rows", dtype=np.float64, count=T * len(ROW_FIELDS)).reshape(T, -1)
        identity, force, centre = self._contact_arrays(T)
        grid = self.grid
        return ForceTable(forces=forces, frames=rows[:, 0].astype(np.int64), t=rows[:, 1],
                          shear_ratio=rows[:, 2], shear_direction=rows[:, 3], efficiency=rows[:, 4],
                          residual=rows[:, 5], condition=rows[:, 6], positions=grid.positions,
                          shape=tuple(grid.shape), pitch=grid.pitch, thickness=grid.thickness,
                          kernel=self.kernel, mode=self.mode, source=self.source,
                          poisson_ratio=grid.poisson_ratio, sensor_size=grid.sensor_size,
                          contact_identity=identity, contact_force=force, contact_centre=centre)

    def _contact_arrays(self, T: int):
        # the contacts as the force table's slots (force_tables.contact_arrays): largest normal force first
        # in each frame, as the tracker returned them; identity 0 and nan in the empty slots
        flat = np.fromfile(self.spool / "contacts", dtype=np.float64,
                           count=self._contacts * len(CONTACT_FIELDS)).reshape(-1, len(CONTACT_FIELDS))
        row = flat[:, 0].astype(np.int64)
        counts = np.bincount(row, minlength=T)
        width = int(counts.max(initial=0))
        slot = np.arange(row.size) - np.repeat(np.cumsum(counts) - counts, counts)
        identity = np.zeros((T, width), np.int64)
        force = np.full((T, width, 3), np.nan)
        centre = np.full((T, width, 2), np.nan)
        identity[row, slot] = flat[:, 1].astype(np.int64)
        force[row, slot] = flat[:, 2:5]
        centre[row, slot] = flat[:, 5:7]
        return identity, force, centre

    def close(self) -> None:
        """Close and remove the spool (a table taken from it before can no longer be read)."""
        for descriptor in self._files.values():
            os.close(descriptor)
        self._files = {}
        shutil.rmtree(self.spool, ignore_errors=True)

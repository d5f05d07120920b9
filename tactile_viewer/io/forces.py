"""Force exports: reconstructed forces of a recording's frames as CSV or NPZ, and reading them back. No Qt.

Force exports write the one file named, nothing beside it.

Forces NPZ keys: ``forces (T, m, 3)`` N (float64; float32 from ``tactile-stream``,
as it published them), ``frames (T,)`` indices into the recording, ``t (T,)``
s, ``shear_ratio (T,)``, ``shear_direction (T,)`` rad, ``efficiency (T,)``,
``residual (T,)``, ``condition (T,)``, ``positions (m, 2)`` m, ``nx``, ``ny``,
``pitch``, ``thickness`` (m), ``poisson_ratio`` (the elastomer's nu),
``sensor_size`` (side of a square taxel, m; 0: point sensors), ``kernel``,
``mode`` ("auto" or "manual"), ``source`` (the recording's path), ``fallback
(T,)`` str: why a frame's forces are a cheaper member than the solver's
accurate path, and which ("" for a frame that took it; an export from before it
reads as all "").

Per-contact totals (both formats): the contacts of each frame as the solver
found them, largest normal force first, each with its identity
(:class:`solver.ContactTracker`: the number it keeps while it persists, from 1;
the frames are followed in the order they were solved, so a whole-recording
export numbers them from its first frame on). NPZ keys ``contact_identity (T,
K)`` int (0: no contact in that slot), ``contact_force (T, K, 3)`` N (its
resultant Fx, Fy, Fz) and ``contact_centre (T, K, 2)`` m (where its compressive
load is centred); ``K`` is the most contacts of any frame, empty slots hold 0
and nan.

Forces CSV: ``#`` header lines ``key=value`` (source, kernel, mode, nx, ny,
pitch, thickness, poisson_ratio, sensor_size), then one row per frame and node:
``frame, t, node, x, y, Fx, Fy, Fz, shear_ratio, shear_direction_deg``. The
per-contact totals follow the node rows as ``#`` lines in the header's
``key=value`` form, so a reader that skips ``#`` lines reads the node table
alone, as before: the header's ``contact_columns=frame,t,identity,Fx,Fy,Fz,x,y``
(newtons, metres) names the fields of each ``# contact=...`` line, one per frame
and contact. A frame solved by a cheaper member has a ``# fallback=FRAME,TEXT``
line after them (the text may hold commas: the first one ends the frame).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver.arrays import read_only

from .recording import written_whole

__all__ = ["ForceTable", "save_forces", "load_forces", "CSV_COLUMNS", "CONTACT_COLUMNS", "CONTACT_TAG",
           "FALLBACK_TAG"]

CSV_COLUMNS = ("frame", "t", "node", "x", "y", "Fx", "Fy", "Fz", "shear_ratio", "shear_direction_deg")
CONTACT_TAG = "contact"  # the key of each "# contact=..." line of the CSV (one per frame and contact)
FALLBACK_TAG = "fallback"  # the key of each "# fallback=..." line of the CSV (a frame off the accurate path)
CONTACT_COLUMNS = ("frame", "t", "identity", "Fx", "Fy", "Fz", "x", "y")


@dataclass(frozen=True)
class ForceTable:
    """Reconstructed forces of some frames of a recording (arrays as in the NPZ format).

    ``poisson_ratio`` and ``sensor_size`` (metres) are those of the geometry the
    forces were solved on: the layer kernel's forces depend on them.
    ``contact_identity (T, K)``, ``contact_force (T, K, 3)`` and
    ``contact_centre (T, K, 2)`` are each frame's contacts (module notes;
    :func:`contact_arrays`); None (the default) is no contacts, ``K = 0``.
    ``forces`` is float64, or float32 or float64 kept as given when it is
    read-only already (a memory-mapped spool: :class:`~tactile_viewer.model.force_log.ForceLog`).
    ``fallback (T,)`` is each frame's :attr:`solver.Reconstruction.fallback` (None, the default:
    every frame took the accurate path).
    """

    forces: np.ndarray
    frames: np.ndarray
    t: np.ndarray
    shear_ratio: np.ndarray
    shear_direction: np.ndarray
    efficiency: np.ndarray
    residual: np.ndarray
    condition: np.ndarray
    positions: np.ndarray
    shape: tuple
    pitch: float
    thickness: float
    kernel: str
    mode: str
    source: str
    poisson_ratio: float = 0.5
    sensor_size: float = 0.0
    contact_identity: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    contact_centre: np.ndarray | None = None
    fallback: np.ndarray | None = None

    def __post_init__(self):
        forces = self.forces
        if not (isinstance(forces, np.ndarray) and forces.dtype in (np.float32, np.float64)
                and not forces.flags.writeable):
            # kept as given when read-only already: a stream's spooled forces stay on disk (memory-mapped)
            object.__setattr__(self, "forces", read_only(forces, float))
        for name in ("frames", "t", "shear_ratio", "shear_direction", "efficiency", "residual",
                     "condition", "positions"):
            object.__setattr__(self, name, read_only(getattr(self, name), int if name == "frames" else float))
        count = len(self.frames)
        fallback = [""] * count if self.fallback is None else list(np.asarray(self.fallback, object).ravel())
        if np.shape(self.fallback if self.fallback is not None else fallback) != (count,):
            raise ValueError(f"fallback must be (T,) for the T = {count} frames, got shape "
                             f"{np.shape(self.fallback)}")
        if not all(isinstance(why, str) for why in fallback):
            raise ValueError(f"fallback must hold text (\"\" for a frame on the accurate path), got "
                             f"{next(why for why in fallback if not isinstance(why, str))!r}")
        # one line of text each, as every format keeps it
        object.__setattr__(self, "fallback", read_only([" ".join(why.split()) for why in fallback], str))
        for name, tail, dtype in (("contact_identity", (), np.int64), ("contact_force", (3,), float),
                                  ("contact_centre", (2,), float)):
            value = getattr(self, name)
            value = np.zeros((count, 0) + tail, dtype) if value is None else value
            object.__setattr__(self, name, read_only(value, dtype))
        shapes = [getattr(self, name).shape for name in ("contact_identity", "contact_force",
                                                         "contact_centre")]
        if len(shapes[0]) != 2 or shapes[0][0] != count or shapes[1] != shapes[0] + (3,) \
                or shapes[2] != shapes[0] + (2,):
            raise ValueError(f"contact_identity, contact_force and contact_centre must be (T, K), (T, K, 3) "
                             f"and (T, K, 2) for the T = {count} frames, got shapes {shapes}")


def save_forces(table: ForceTable, path, *, source: str = "") -> Path:
    """Write a force table as ``.npz`` or ``.csv`` (see the module notes)."""
    path = Path(path)
    ny, nx = table.shape if len(table.shape) == 2 else (1, table.shape[0])
    source = source or table.source
    if path.suffix.lower() == ".npz":
        # a handle: np.savez would turn "x.NPZ" into "x.NPZ.npz"
        with written_whole(path) as temporary, open(temporary, "wb") as handle:
            np.savez_compressed(handle, forces=table.forces, frames=table.frames, t=table.t,
                                shear_ratio=table.shear_ratio, shear_direction=table.shear_direction,
                                efficiency=table.efficiency, residual=table.residual,
                                condition=table.condition, positions=table.positions, nx=nx, ny=ny,
                                pitch=table.pitch, thickness=table.thickness,
                                poisson_ratio=table.poisson_ratio, sensor_size=table.sensor_size,
                                kernel=table.kernel, mode=table.mode, source=source,
                                contact_identity=table.contact_identity, contact_force=table.contact_force,
                                contact_centre=table.contact_centre, fallback=table.fallback)
    elif path.suffix.lower() == ".csv":
        with written_whole(path) as temporary, open(temporary, "w", encoding="utf-8", newline="\n") as handle:
            _write_csv(handle, table, source, nx, ny)
    else:
        raise ValueError(f"{path}: unknown export type {path.suffix!r}, expected .npz or .csv")
    return path


# Frames written per piece of a CSV export: a long take (a stream's hour is millions of frames) is
# formatted a few megabytes at a time, never as one table in memory.
CSV_FRAMES_PER_PIECE = 1024


def _write_csv(handle, table: ForceTable, source: str, nx: int, ny: int) -> None:
    for key, value in (("source", " ".join(source.split())), ("kernel", table.kernel),
                       ("mode", table.mode), ("nx", nx), ("ny", ny), ("pitch", repr(table.pitch)),
                       ("thickness", repr(table.thickness)), ("poisson_ratio", repr(table.poisson_ratio)),
                       ("sensor_size", repr(table.sensor_size)), ("units", "m, N, degrees"),
                       (f"{CONTACT_TAG}_columns", ",".join(CONTACT_COLUMNS))):
        handle.write(f"# {key}={value}\n")
    handle.write(",".join(CSV_COLUMNS) + "\n")
    T, m = table.forces.shape[:2]
    for start in range(0, T, CSV_FRAMES_PER_PIECE):
        piece = slice(start, min(T, start + CSV_FRAMES_PER_PIECE))
        count = piece.stop - piece.start
        rows = np.column_stack([
            np.repeat(table.frames[piece], m), np.repeat(table.t[piece], m), np.tile(np.arange(m), count),
            np.tile(table.positions[:, 0], count), np.tile(table.positions[:, 1], count),
            np.asarray(table.forces[piece], dtype=float).reshape(-1, 3),
            np.repeat(table.shear_ratio[piece], m),
            np.degrees(np.repeat(table.shear_direction[piece], m)),
        ])
        np.savetxt(handle, rows, delimiter=",", fmt=["%d", "%.6f", "%d"] + ["%.9g"] * 7)
    # the per-contact totals: "# contact=..." lines after the node rows
    for row, slot in zip(*np.nonzero(table.contact_identity), strict=True):
        values = (*table.contact_force[row, slot], *table.contact_centre[row, slot])
        handle.write(f"# {CONTACT_TAG}={table.frames[row]:d},{table.t[row]:.6f},"
                     f"{table.contact_identity[row, slot]:d},{','.join(f'{v:.9g}' for v in values)}\n")
    for row in np.flatnonzero(table.fallback != ""):
        handle.write(f"# {FALLBACK_TAG}={table.frames[row]:d},{' '.join(table.fallback[row].split())}\n")


def load_forces(path) -> dict:
    """Read a force export back: ``forces (T, m, 3)``, ``frames``, ``t`` and the rest.

    Both formats give the per-contact arrays ``contact_identity (T, K)``,
    ``contact_force (T, K, 3)`` and ``contact_centre (T, K, 2)`` (``K = 0`` for
    an export written before they were).
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        with np.load(path, allow_pickle=False) as data:
            loaded = {k: data[k] for k in data.files}
        count = len(loaded["frames"]) if "frames" in loaded else len(loaded["forces"])
        defaults = {"contact_identity": np.zeros((count, 0), np.int64),  # an export from before them
                    "contact_force": np.zeros((count, 0, 3)), "contact_centre": np.zeros((count, 0, 2)),
                    "fallback": np.full(count, "")}
        return defaults | loaded
    table = np.loadtxt(path, delimiter=",", skiprows=_header_lines(path), ndmin=2)  # "#" lines skipped
    frames = np.unique(table[:, 0]).astype(int)
    m = int(table[:, 2].max()) + 1
    loaded = {"frames": frames, "t": table[::m, 1], "forces": table[:, 5:8].reshape(frames.size, m, 3),
              "shear_ratio": table[::m, 8], "shear_direction": np.radians(table[::m, 9])}
    # the per-contact lines, back into slots in the order written
    tag, fallback_tag = f"# {CONTACT_TAG}=", f"# {FALLBACK_TAG}="
    rows, fallback = [], np.full(frames.size, "", dtype=object)
    where = {int(k): i for i, k in enumerate(frames)}
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            if line.startswith(tag):
                rows.append([float(v) for v in line[len(tag):].split(",")])
            elif line.startswith(fallback_tag):
                frame, comma, text = line[len(fallback_tag):].rstrip("\n").partition(",")
                if not comma or not frame.strip().isdigit() or int(frame) not in where:
                    raise ValueError(f"{path}: a line {fallback_tag}FRAME,WHY must name a frame of the "
                                     f"table, got {line.strip()!r}")
                fallback[where[int(frame)]] = text
    per_frame: dict[int, list] = {}
    for row in rows:
        per_frame.setdefault(int(row[0]), []).append(row)
    width = max((len(v) for v in per_frame.values()), default=0)
    identity = np.zeros((frames.size, width), np.int64)
    force = np.full((frames.size, width, 3), np.nan)
    centre = np.full((frames.size, width, 2), np.nan)
    for k, contacts in per_frame.items():
        for slot, row in enumerate(contacts):
            identity[where[k], slot] = int(row[2])
            force[where[k], slot] = row[3:6]
            centre[where[k], slot] = row[6:8]
    return loaded | {"contact_identity": identity, "contact_force": force, "contact_centre": centre,
                     "fallback": fallback.astype(str)}


def _header_lines(path) -> int:
    # the comment lines and the column-name line after them
    with open(path, encoding="utf-8") as f:
        for count, line in enumerate(f, start=1):
            if not line.startswith("#"):
                return count
    return 0

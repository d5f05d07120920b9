"""Exports: reconstructed forces (CSV or NPZ) and the JSON sidecar of a screenshot. No Qt.

Screenshot sidecar: ``<image name>.view.json`` beside the image, the image's
full name kept (``board.png`` -> ``board.png.view.json``), so it never takes the
name of another file of the same stem (``board.json``). It is a JSON object
whose ``tactile_viewer_sidecar`` key (the format's version, 1) marks it as ours;
then what the image shows (recording, frame, parameters, display). An existing
file of the sidecar's name is replaced only when it carries that key: anything
else is left as it is and :class:`SidecarConflict` names it.

Force exports write the one file named, nothing beside it.

Forces NPZ keys: ``forces (T, m, 3)`` N, ``frames (T,)`` indices into the
recording, ``t (T,)`` s, ``shear_ratio (T,)``, ``shear_direction (T,)`` rad,
``efficiency (T,)``, ``residual (T,)``, ``condition (T,)``, ``positions (m, 2)``
m, ``nx``, ``ny``, ``pitch``, ``thickness`` (m), ``poisson_ratio`` (the
elastomer's nu), ``sensor_size`` (side of a square taxel, m; 0: point sensors),
``kernel``, ``mode`` ("auto" or "manual"), ``source`` (the recording's path).

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
and contact.
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver import ContactTracker, Reconstructor
from solver.arrays import read_only

from .recording import Recording, written_whole
from .worker import Cancelled

__all__ = ["ForceTable", "reconstruct_frames", "force_table", "save_forces", "load_forces", "contact_arrays",
           "CSV_COLUMNS", "CONTACT_COLUMNS", "CONTACT_TAG", "SIDECAR_SUFFIX",
           "SIDECAR_MARKER", "SIDECAR_VERSION", "SidecarConflict", "sidecar_path", "check_sidecar",
           "write_sidecar", "derived_name"]

CSV_COLUMNS = ("frame", "t", "node", "x", "y", "Fx", "Fy", "Fz", "shear_ratio", "shear_direction_deg")
CONTACT_TAG = "contact"  # the key of each "# contact=..." line of the CSV (one per frame and contact)
CONTACT_COLUMNS = ("frame", "t", "identity", "Fx", "Fy", "Fz", "x", "y")

SIDECAR_SUFFIX = ".view.json"  # appended to the image's full name
SIDECAR_MARKER = "tactile_viewer_sidecar"  # the key that marks a sidecar as ours; its value is the version
SIDECAR_VERSION = 1
_SIDECAR_MAX_BYTES = 1 << 20  # a sidecar is about 1 kB: a larger file is not one of ours


def derived_name(picked, suffix: str, *, what: str = "file") -> Path:
    """The name an export is written under: the name picked, ending in ``suffix``.

    A name already ending in ``suffix`` (in any case) keeps it, in lower case;
    another gets ``suffix`` added (``shot`` -> ``shot.png``, ``a.b`` -> ``a.b.png``).
    A name so made is not the one the save dialog asked about replacing, so
    it must be free.

    Parameters
    ----------
    picked : str or Path
        The name picked in the save dialog.
    suffix : str
        The ending, with its dot, in lower case (``".png"``).
    what : str
        What is written, for the error ("image", "movie").

    Raises
    ------
    FileExistsError
        When the name made differs from ``picked`` and a file has it; nothing
        is written.
    """
    picked = Path(picked)
    if picked.suffix.lower() == suffix:
        path = picked.with_suffix(suffix)
    else:
        path = picked.with_name(picked.name + suffix)
    if path != picked and os.path.lexists(path):
        found = (f"not replaced: the {what} would be {path.name} (the name picked, ending in {suffix!r}), "
                 "which exists and is not the file picked")
        raise FileExistsError(errno.EEXIST, found, str(path))
    return path


@dataclass(frozen=True)
class ForceTable:
    """Reconstructed forces of some frames of a recording (arrays as in the NPZ format).

    ``poisson_ratio`` and ``sensor_size`` (metres) are those of the geometry the
    forces were solved on: the layer kernel's forces depend on them.
    ``contact_identity (T, K)``, ``contact_force (T, K, 3)`` and
    ``contact_centre (T, K, 2)`` are each frame's contacts (module notes;
    :func:`contact_arrays`); None (the default) is no contacts, ``K = 0``.
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

    def __post_init__(self):
        for name in ("forces", "frames", "t", "shear_ratio", "shear_direction", "efficiency", "residual",
                     "condition", "positions"):
            object.__setattr__(self, name, read_only(getattr(self, name), int if name == "frames" else float))
        count = len(self.frames)
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


def reconstruct_frames(recording: Recording, reconstructor: Reconstructor, frames=None, *,
                       shear_ratio=None, shear_direction=None, progress=None) -> ForceTable:
    """Solve the given frames (default: all) with automatic or given parameters.

    The contacts are followed over the frames in the order given
    (:class:`solver.ContactTracker`): give them increasing for identities that
    mean the same contact over time.

    Parameters
    ----------
    progress : callable, optional
        ``progress(done, total) -> bool``; returning False cancels
        (:class:`Cancelled` is raised).
    """
    frames = np.arange(len(recording)) if frames is None else np.atleast_1d(np.asarray(frames, dtype=int))
    if frames.size and (frames.min() < 0 or frames.max() >= len(recording)):
        raise ValueError(f"frames must be in [0, {len(recording) - 1}], got {frames.tolist()}")
    results = []
    tracker = ContactTracker(recording.grid)  # the contacts numbered in the order the frames are solved
    for i, k in enumerate(frames):
        results.append(tracker.update(reconstructor.solve(recording.frames[k], shear_ratio=shear_ratio,
                                                          shear_direction=shear_direction)))
        if progress is not None and progress(i + 1, frames.size) is False:
            raise Cancelled(f"cancelled after {i + 1} of {frames.size} frames")
    auto = shear_ratio is None and shear_direction is None
    return force_table(results, frames, recording.t[frames], recording.grid, solver=reconstructor,
                       mode="auto" if auto else "manual", source=recording.description)


def force_table(results, frames, t, grid, *, solver, mode: str, source: str = "") -> ForceTable:
    """The table of already solved frames: ``results[i]`` is frame ``frames[i]`` at time ``t[i]``.

    ``solver`` is what solved them: its kernel and its geometry's material are recorded. The
    contacts keep the identities the results carry (the viewer's, followed as it showed them);
    results whose contacts carry none (0: solved alone) are followed here, in the order given.
    """
    fields = ("shear_ratio", "shear_direction", "efficiency", "residual", "condition")
    if any(c.identity == 0 for r in results for c in r.contacts):
        tracker = ContactTracker(grid)
        results = [tracker.update(r) for r in results]
    identity, force, centre = contact_arrays(results)
    return ForceTable(contact_identity=identity, contact_force=force, contact_centre=centre,
                      forces=np.array([r.forces for r in results]).reshape(len(results), grid.size, 3),
                      frames=np.asarray(frames), t=np.asarray(t, dtype=float), positions=grid.positions,
                      shape=tuple(grid.shape), pitch=grid.pitch, thickness=grid.thickness,
                      kernel=solver.kernel, mode=mode, source=source,
                      # the material the forces were solved with, which is the solver's
                      poisson_ratio=solver.grid.poisson_ratio, sensor_size=solver.grid.sensor_size,
                      **{name: np.array([getattr(r, name) for r in results], dtype=float) for name in fields})


def contact_arrays(results) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The contacts of solved frames as arrays: one row per frame, one slot per contact.

    Parameters
    ----------
    results : sequence of solver.Reconstruction
        ``T`` solved frames.

    Returns
    -------
    identity : (T, K) ndarray of int
        Each contact's identity (:attr:`solver.Contact.identity`) in the
        result's order (largest normal force first); 0 in the slots beyond a
        frame's contacts. ``K`` is the most contacts of any frame.
    force : (T, K, 3) ndarray
        Each contact's resultant (Fx, Fy, Fz), newtons; nan in empty slots.
    centre : (T, K, 2) ndarray
        Each contact's centre, metres; nan in empty slots.
    """
    count = len(results)
    width = max((len(r.contacts) for r in results), default=0)
    identity = np.zeros((count, width), np.int64)
    force = np.full((count, width, 3), np.nan)
    centre = np.full((count, width, 2), np.nan)
    for row, result in enumerate(results):
        for slot, contact in enumerate(result.contacts):
            identity[row, slot] = contact.identity
            force[row, slot] = contact.total_force
            centre[row, slot] = contact.centre
    return identity, force, centre


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
                                contact_centre=table.contact_centre)
    elif path.suffix.lower() == ".csv":
        T, m = table.forces.shape[:2]
        rows = np.column_stack([
            np.repeat(table.frames, m), np.repeat(table.t, m), np.tile(np.arange(m), T),
            np.tile(table.positions[:, 0], T), np.tile(table.positions[:, 1], T),
            table.forces.reshape(-1, 3), np.repeat(table.shear_ratio, m),
            np.degrees(np.repeat(table.shear_direction, m)),
        ])
        buffer = io.StringIO()
        for key, value in (("source", " ".join(source.split())), ("kernel", table.kernel),
                           ("mode", table.mode), ("nx", nx), ("ny", ny), ("pitch", repr(table.pitch)),
                           ("thickness", repr(table.thickness)), ("poisson_ratio", repr(table.poisson_ratio)),
                           ("sensor_size", repr(table.sensor_size)), ("units", "m, N, degrees"),
                           (f"{CONTACT_TAG}_columns", ",".join(CONTACT_COLUMNS))):
            buffer.write(f"# {key}={value}\n")
        buffer.write(",".join(CSV_COLUMNS) + "\n")
        np.savetxt(buffer, rows, delimiter=",", fmt=["%d", "%.6f", "%d"] + ["%.9g"] * 7)
        # the per-contact totals: "# contact=..." lines after the node rows
        for row, slot in zip(*np.nonzero(table.contact_identity), strict=True):
            values = (*table.contact_force[row, slot], *table.contact_centre[row, slot])
            buffer.write(f"# {CONTACT_TAG}={table.frames[row]:d},{table.t[row]:.6f},"
                         f"{table.contact_identity[row, slot]:d},{','.join(f'{v:.9g}' for v in values)}\n")
        with written_whole(path) as temporary:
            temporary.write_text(buffer.getvalue(), encoding="utf-8")
    else:
        raise ValueError(f"{path}: unknown export type {path.suffix!r}, expected .npz or .csv")
    return path


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
                    "contact_force": np.zeros((count, 0, 3)), "contact_centre": np.zeros((count, 0, 2))}
        return defaults | loaded
    table = np.loadtxt(path, delimiter=",", skiprows=_header_lines(path), ndmin=2)  # "#" lines skipped
    frames = np.unique(table[:, 0]).astype(int)
    m = int(table[:, 2].max()) + 1
    loaded = {"frames": frames, "t": table[::m, 1], "forces": table[:, 5:8].reshape(frames.size, m, 3),
              "shear_ratio": table[::m, 8], "shear_direction": np.radians(table[::m, 9])}
    # the per-contact lines, back into slots in the order written
    tag = f"# {CONTACT_TAG}="
    with open(path, encoding="utf-8") as handle:
        rows = [[float(v) for v in line[len(tag):].split(",")] for line in handle if line.startswith(tag)]
    per_frame: dict[int, list] = {}
    for row in rows:
        per_frame.setdefault(int(row[0]), []).append(row)
    width = max((len(v) for v in per_frame.values()), default=0)
    identity = np.zeros((frames.size, width), np.int64)
    force = np.full((frames.size, width, 3), np.nan)
    centre = np.full((frames.size, width, 2), np.nan)
    where = {int(k): i for i, k in enumerate(frames)}
    for k, contacts in per_frame.items():
        for slot, row in enumerate(contacts):
            identity[where[k], slot] = int(row[2])
            force[where[k], slot] = row[3:6]
            centre[where[k], slot] = row[6:8]
    return loaded | {"contact_identity": identity, "contact_force": force, "contact_centre": centre}


def _header_lines(path) -> int:
    # the comment lines and the column-name line after them
    with open(path, encoding="utf-8") as f:
        for count, line in enumerate(f, start=1):
            if not line.startswith("#"):
                return count
    return 0


class SidecarConflict(ValueError):
    """A screenshot's sidecar name is taken by a file that is not one of our sidecars.

    Nothing was written to that file. A :class:`ValueError`, so the command line
    reports it as it reports bad input.

    Attributes
    ----------
    path : Path
        The sidecar's name, the file that was left alone.
    image : Path
        The screenshot the sidecar belongs to.
    """

    def __init__(self, path, image, found: str):
        self.path, self.image = Path(path), Path(image)
        super().__init__(f"{self.path}: the sidecar of {self.image.name} was not written: a sidecar replaces "
                         f"only an earlier sidecar (a JSON object with the key {SIDECAR_MARKER!r}), "
                         f"and this file {found}")


def sidecar_path(image_path) -> Path:
    """The name of a screenshot's sidecar: the image's full name plus ``.view.json``.

    Parameters
    ----------
    image_path : str or Path
        The screenshot, e.g. ``board.png``.

    Returns
    -------
    Path
        ``board.png.view.json`` beside it.
    """
    image = Path(image_path)
    return image.with_name(image.name + SIDECAR_SUFFIX)


def check_sidecar(image_path) -> Path:
    """The sidecar's name for ``image_path``, checked free: absent, or one of our sidecars.

    Writes nothing; callers may use it to refuse before doing any work.

    Returns
    -------
    Path
        :func:`sidecar_path` of ``image_path``.

    Raises
    ------
    SidecarConflict
        When a file of that name exists and is not one of our sidecars (not JSON,
        not an object, without :data:`SIDECAR_MARKER`, a folder, unreadable).
    """
    path = sidecar_path(image_path)
    found = _foreign(path)
    if found:
        raise SidecarConflict(path, image_path, found)
    return path


def _foreign(path: Path) -> str:
    """What makes ``path`` something other than one of our sidecars ("" when absent or ours)."""
    if not os.path.lexists(path):
        return ""
    if path.is_dir():
        return "is a folder"
    if not path.exists():
        return "is a link to nothing"
    try:
        size = path.stat().st_size
        if size > _SIDECAR_MAX_BYTES:
            return f"has {size} bytes, more than any sidecar"
        info = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    except ValueError:  # JSONDecodeError and UnicodeDecodeError alike
        return "is not JSON"
    if not isinstance(info, dict):
        return f"is a JSON {type(info).__name__}, not an object"
    if SIDECAR_MARKER not in info:
        return "is JSON without that key"
    return ""


def write_sidecar(image_path, **info) -> Path:
    """Write the sidecar ``<image name>.view.json`` next to a screenshot, naming what it shows.

    The file starts with the marker ``tactile_viewer_sidecar: 1``; non-finite
    floats are written as null. It replaces an earlier sidecar of ours and
    nothing else.

    Parameters
    ----------
    image_path : str or Path
        The screenshot the sidecar describes (the image itself is not touched).
    **info
        What the image shows, as JSON values (others are written as strings).

    Returns
    -------
    Path
        The sidecar written, :func:`sidecar_path` of ``image_path``.

    Raises
    ------
    SidecarConflict
        When the sidecar's name is taken by a file that is not one of our sidecars;
        that file is left as it was.
    TypeError
        When ``info`` has the marker key itself.
    """
    if SIDECAR_MARKER in info:
        raise TypeError(f"{SIDECAR_MARKER!r} is written by write_sidecar, not given to it")
    # "x" when there was nothing: a file that appears after the check is not overwritten either
    mode = "w" if os.path.lexists(sidecar_path(image_path)) else "x"
    path = check_sidecar(image_path)
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in info.items()}
    text = json.dumps({SIDECAR_MARKER: SIDECAR_VERSION, **clean}, indent=2, default=str) + "\n"
    try:
        with open(path, mode, encoding="utf-8") as handle:
            handle.write(text)
    except FileExistsError:
        raise SidecarConflict(path, image_path, "appeared while the sidecar was being written") from None
    return path

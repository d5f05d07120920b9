"""Recordings: a sensor grid, frames of stress and their timestamps, in NPZ or CSV.

One module for the format: :func:`load` reads it, :func:`save` writes a whole
recording, :class:`Recorder` writes one frame by frame as a live source delivers
them, and :func:`grid_from_fields` / :func:`geometry_fields` are the one reader
and writer of the geometry that every file (layouts included) declares.

NPZ keys: ``frames (T, m)`` pascals, ``t (T,)`` seconds, ``nx``, ``ny`` (or
``taxels`` and ``positions`` for an irregular layout), ``pitch``, ``thickness``
(metres), optional ``poisson_ratio`` (the elastomer's nu, default 0.5),
optional ``sensor_size`` (side of a square taxel, metres, default 0: point
sensors), optional ``positions (m, 2)``, optional ``truth_forces (T, m, 3)``
newtons, optional ``seq (T,)`` sequence numbers of live frames, ``units``,
``description``. A live recording that was never closed (a crash) holds its
frames in chunks ``chunkNNNNNN_frames``, ``chunkNNNNNN_t``,
``chunkNNNNNN_seq``; they load as one recording.

CSV: ``#`` header lines of ``key=value`` (nx, ny, pitch, thickness, optional
poisson_ratio and sensor_size, units, description, optional ``columns=seq,t``;
an irregular layout has ``taxels`` and ``positions=x,y;x,y;...`` metres instead
of nx and ny),
then one frame per row: ``t, v0, v1, ...`` (or ``seq, t, v0, v1, ...``).

Files written before nu and the taxel size were recorded have neither key:
they load as an incompressible layer (nu 0.5) read by point sensors.

No Qt here: the command line, the tests and the solver tools use it too.
"""

from __future__ import annotations

import io
import math
import os
import threading
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver import SensorGrid
from solver.arrays import read_only

__all__ = ["Recording", "RecordingError", "load", "save", "Recorder", "grid_from_fields", "geometry_fields",
           "csv_geometry_header", "MAX_TAXELS"]

UNIT_SCALES = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6}

# A 1000x1000 skin. A header declaring more is far likelier damaged than real, and believing it
# would allocate gigabytes before anything could say so.
MAX_TAXELS = 1_000_000


def grid_from_fields(*, pitch, thickness, nx=None, ny=None, taxels=None, positions=None,
                     poisson_ratio=0.5, sensor_size=0.0, width=None) -> SensorGrid:
    """The geometry a file declares: ``nx`` by ``ny`` (optionally moved to ``positions``), or
    ``taxels`` at ``positions`` (an irregular layout). Every format reads through this.

    ``width``, the values per frame the file actually holds, is checked against the declared
    size before any array of that size is made.

    Raises
    ------
    ValueError
        Naming the field that is wrong and what it holds.
    """
    if taxels is None:
        if nx is None or ny is None:
            raise ValueError("missing 'nx' and 'ny' (or 'taxels' and 'positions')")
        declared, label = nx * ny, f"a {nx}x{ny} grid"
    else:
        declared, label = taxels, f"{taxels} taxels"
    if declared > MAX_TAXELS:
        raise ValueError(f"{label} is not a skin this viewer opens (1 to {MAX_TAXELS} taxels)")
    if width is not None and width != declared:
        size = label if taxels is not None else f"{label} ({declared} taxels)"
        raise ValueError(f"declares {size} but its frames have {width} values each")
    if taxels is not None:
        if positions is None:
            raise ValueError("an irregular layout ('taxels') needs 'positions'")
        return SensorGrid(np.asarray(positions, dtype=float), thickness, pitch, (taxels,),
                          poisson_ratio=poisson_ratio, sensor_size=sensor_size)
    grid = SensorGrid.regular(nx, ny, pitch, thickness, poisson_ratio=poisson_ratio, sensor_size=sensor_size)
    if positions is not None:
        grid = grid.replace(positions=np.asarray(positions, dtype=float))
    return grid


def csv_geometry_header(grid: SensorGrid) -> str:
    """The ``# key=value`` lines of a CSV recording that declare ``grid`` (read by :func:`load`)."""
    fields = geometry_fields(grid)
    positions = fields.pop("positions", None)
    lines = [f"# {key}={value!r}\n" for key, value in fields.items()]
    if positions is not None:
        lines.append("# positions=" + ";".join(f"{x!r},{y!r}" for x, y in positions.tolist()) + "\n")
    return "".join(lines)


def geometry_fields(grid: SensorGrid) -> dict:
    """What every format writes for ``grid`` (the inverse of :func:`grid_from_fields`).

    ``positions`` is present for an irregular layout and for a regular one
    that does not sit where ``SensorGrid.regular`` puts it.
    """
    fields = dict(pitch=grid.pitch, thickness=grid.thickness, poisson_ratio=grid.poisson_ratio,
                  sensor_size=grid.sensor_size)
    if len(grid.shape) == 1:
        return dict(fields, taxels=grid.size, positions=grid.positions)
    ny, nx = grid.shape
    regular = SensorGrid.regular(nx, ny, grid.pitch, grid.thickness).positions
    if not np.allclose(grid.positions, regular, rtol=0, atol=1e-12):
        fields["positions"] = grid.positions
    return dict(fields, nx=nx, ny=ny)


class RecordingError(ValueError):
    """A recording file that cannot be read; the message names the file and the problem."""


@dataclass(frozen=True, eq=False)
class Recording:
    """Frames of sensor stress over time.

    Attributes
    ----------
    grid : SensorGrid
    frames : (T, m) ndarray
        Stress at each sensor, pascals, compression positive.
    t : (T,) ndarray
        Time of each frame, seconds, non-decreasing.
    truth_forces : (T, m, 3) ndarray or None
        Known nodal forces (simulated recordings), newtons.
    description : str
    seq : (T,) ndarray of int or None
        Sequence numbers of frames received live (gaps are lost frames).
    """

    grid: SensorGrid
    frames: np.ndarray
    t: np.ndarray
    truth_forces: np.ndarray | None = None
    description: str = ""
    seq: np.ndarray | None = None

    def __post_init__(self):
        frames = np.array(self.frames, dtype=float)
        if frames.ndim != 2 or frames.shape[1] != self.grid.size:
            raise ValueError(f"frames must have shape (T, {self.grid.size}), got {frames.shape}")
        t = np.array(self.t, dtype=float)
        if t.shape != (frames.shape[0],):
            raise ValueError(f"t must have shape ({frames.shape[0]},), got {t.shape}")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
            raise ValueError("t must be finite and non-decreasing")
        object.__setattr__(self, "frames", read_only(frames))
        object.__setattr__(self, "t", read_only(t))
        if self.truth_forces is not None:
            truth = np.array(self.truth_forces, dtype=float)
            if truth.shape != (frames.shape[0], self.grid.size, 3):
                raise ValueError(f"truth_forces must have shape ({frames.shape[0]}, "
                                 f"{self.grid.size}, 3), got {truth.shape}")
            object.__setattr__(self, "truth_forces", read_only(truth))
        if self.seq is not None:
            seq = np.array(self.seq)
            if seq.shape != (frames.shape[0],) or not np.all(seq == np.round(seq)):
                raise ValueError(f"seq must be {frames.shape[0]} whole numbers, got shape {seq.shape}")
            object.__setattr__(self, "seq", read_only(seq, np.int64))

    def __len__(self) -> int:
        return self.frames.shape[0]


def load(path) -> Recording:
    """Read a recording (``.npz`` or ``.csv``); :class:`RecordingError` names what is wrong."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise RecordingError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
    try:
        if suffix == ".npz":
            return _load_npz(path)
        return _load_csv(path)
    except RecordingError:
        raise
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except (ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"{path}: {exc}") from exc
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
        # members are decompressed lazily, so a damaged archive can fail long after np.load
        raise RecordingError(f"{path}: damaged NPZ archive ({exc})") from exc


def _scalar(data, key, path, cast=float, default=None):
    if key not in data:
        if default is not None:
            return default
        raise RecordingError(f"{path}: missing {key!r}")
    try:
        value = float(np.asarray(data[key], dtype=float).item())
    except (ValueError, TypeError):
        raw = data[key]  # an NPZ holds 'abc' as array('abc'): show what was written
        shown = raw.item() if isinstance(raw, np.ndarray) and raw.ndim == 0 else raw
        raise RecordingError(f"{path}: {key!r} must be a single number, got {shown!r}") from None
    if cast is int:
        if not value.is_integer():
            raise RecordingError(f"{path}: {key!r} must be a whole number, got {value!r}")
        return int(value)
    if cast is float and not math.isfinite(value):
        raise RecordingError(f"{path}: {key!r} must be finite, got {value!r}")
    return value


def _grid(meta, path, positions=None, width=None) -> SensorGrid:
    if "taxels" in meta:
        counts = dict(taxels=_scalar(meta, "taxels", path, int))
    else:
        counts = dict(nx=_scalar(meta, "nx", path, int), ny=_scalar(meta, "ny", path, int))
    pitch, thickness = _scalar(meta, "pitch", path), _scalar(meta, "thickness", path)
    # absent from files written before they were recorded: an incompressible layer, point sensors
    poisson_ratio = _scalar(meta, "poisson_ratio", path, default=0.5)
    sensor_size = _scalar(meta, "sensor_size", path, default=0.0)
    try:
        return grid_from_fields(pitch=pitch, thickness=thickness, positions=positions,
                                poisson_ratio=poisson_ratio, sensor_size=sensor_size, width=width, **counts)
    except ValueError as exc:
        raise RecordingError(f"{path}: impossible geometry: {exc}") from None


def _scale(units: str, path) -> float:
    if units not in UNIT_SCALES:
        raise RecordingError(f"{path}: units must be one of {sorted(UNIT_SCALES)}, got {units!r}")
    return UNIT_SCALES[units]


def _checked_frames(frames, grid, path):
    if frames.ndim != 2 or frames.shape[1] != grid.size:
        layout = (f"{grid.shape[1]}x{grid.shape[0]} grid" if len(grid.shape) == 2
                  else f"{grid.size}-taxel layout")
        raise RecordingError(f"{path}: frames must be a (T, {grid.size}) table for a {layout}, "
                             f"got shape {frames.shape}")
    if frames.shape[0] == 0:
        raise RecordingError(f"{path}: no frames")
    bad = np.argwhere(~np.isfinite(frames))
    if bad.size:
        raise RecordingError(f"{path}: frame {bad[0][0]} taxel {bad[0][1]} is not a finite number")
    return frames


def _load_npz(path) -> Recording:
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise RecordingError(f"{path}: not a readable NPZ archive ({exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise RecordingError(f"{path}: not an NPZ archive (a single array, as .npy writes)")
    with data:
        arrays = _joined_chunks(data) if "frames" not in data else {k: data[k] for k in ("frames", "t", "seq")
                                                                    if k in data}
        if "frames" not in arrays:
            raise RecordingError(f"{path}: missing 'frames'")
        grid = _grid(data, path, data["positions"] if "positions" in data else None,
                     width=np.shape(arrays["frames"])[-1] if np.ndim(arrays["frames"]) == 2 else None)
        units = str(data["units"]) if "units" in data else "Pa"
        frames = _checked_frames(np.asarray(arrays["frames"], dtype=float), grid, path) * _scale(units, path)
        t = np.asarray(arrays["t"], dtype=float) if "t" in arrays else np.arange(len(frames), dtype=float)
        seq = arrays.get("seq")
        truth = np.asarray(data["truth_forces"], dtype=float) if "truth_forces" in data else None
        description = str(data["description"]) if "description" in data else ""
    try:
        return Recording(grid, frames, t, truth, description, seq)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def _joined_chunks(data) -> dict:
    # a live recording cut off before it was closed: its chunks in order
    names = sorted({name.split("_", 1)[0] for name in data.files if name.startswith("chunk")})
    if not names:
        return {}
    return {key: np.concatenate([data[f"{name}_{key}"] for name in names]) for key in ("frames", "t", "seq")
            if all(f"{name}_{key}" in data for name in names)}


def _load_csv(path) -> Recording:
    meta, rows = {}, []
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                key, sep, value = text[1:].partition("=")
                if sep:
                    meta[key.strip()] = value.strip()
                continue
            try:
                rows.append([float(v) for v in text.replace(";", ",").split(",")])
            except ValueError:
                raise RecordingError(f"{path}: line {number}: not a row of numbers: {text[:60]!r}") from None
            if len(rows[-1]) != len(rows[0]):
                raise RecordingError(f"{path}: line {number}: {len(rows[-1]) - 1} values, "
                                     f"earlier rows have {len(rows[0]) - 1}")
    if not rows:
        raise RecordingError(f"{path}: no frames")
    table = np.asarray(rows, dtype=float)
    columns = meta.get("columns", "t")
    if columns not in ("t", "seq,t"):
        raise RecordingError(f"{path}: columns must be 't' or 'seq,t', got {columns!r}")
    first = 2 if columns == "seq,t" else 1
    positions = None
    if "positions" in meta:
        try:
            positions = [[float(v) for v in pair.split(",")] for pair in meta["positions"].split(";")
                         if pair.strip()]  # a trailing ';' of a hand-edited file is no pair
        except ValueError:
            raise RecordingError(f"{path}: positions must be x,y pairs of metres separated by ';'") from None
    grid = _grid(meta, path, positions, width=table.shape[1] - first)
    frames = _checked_frames(table[:, first:], grid, path) * _scale(meta.get("units", "Pa"), path)
    seq = table[:, 0] if first == 2 else None
    try:
        return Recording(grid, frames, table[:, first - 1], None, meta.get("description", ""), seq)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def save(recording: Recording, path) -> Path:
    """Write a recording as ``.npz`` (everything) or ``.csv`` (frames and geometry, nu included)."""
    path = Path(path)
    fields = geometry_fields(recording.grid)
    if path.suffix.lower() == ".npz":
        extra = {} if recording.truth_forces is None else {"truth_forces": recording.truth_forces}
        if recording.seq is not None:
            extra["seq"] = recording.seq
        fields.setdefault("positions", recording.grid.positions)
        # through a handle: np.savez would append ".npz" to a name ending ".NPZ"
        with open(path, "wb") as handle:
            np.savez_compressed(handle, frames=recording.frames, t=recording.t, units="Pa",
                                description=recording.description, **fields, **extra)
    elif path.suffix.lower() == ".csv":
        buffer = io.StringIO()
        buffer.write(csv_geometry_header(recording.grid))
        buffer.write("# units=Pa\n")
        if recording.description:
            buffer.write(f"# description={' '.join(recording.description.split())}\n")
        columns = [recording.t, recording.frames]
        if recording.seq is not None:
            buffer.write("# columns=seq,t\n")
            columns.insert(0, recording.seq)
        np.savetxt(buffer, np.column_stack(columns), delimiter=",", fmt="%.9g")
        path.write_text(buffer.getvalue(), encoding="utf-8")
    else:
        raise RecordingError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
    return path


class Recorder:
    """Writes every frame it is given to a recording, incrementally.

    ``.npz``: each flush appends one chunk (frames, t, seq) to the archive, which
    is a valid, loadable recording after every flush; :meth:`close` rewrites it
    as one plain recording. ``.csv``: rows ``seq, t, v0, ...`` appended and
    flushed. Flushes happen at least every ``flush_interval`` seconds of receive
    time, so a crash loses at most that much.
    """

    def __init__(self, path, grid: SensorGrid, *, flush_interval: float = 1.0, description: str = ""):
        path = Path(path)
        self.kind = path.suffix.lower()
        if self.kind not in (".npz", ".csv"):
            raise ValueError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
        self.path = path
        self.flush_interval = flush_interval
        self.description = description or "live recording"
        self.written = 0
        self._rows: list = []
        self._closed = False
        self._chunks = 0
        self._last_flush: float | None = None
        self._lock = threading.Lock()
        # the geometry as every recording declares it (recording.geometry_fields), positions always
        self._meta = dict(geometry_fields(grid), units="Pa")
        self._meta["positions"] = grid.positions
        if self.kind == ".npz":
            with zipfile.ZipFile(path, "w") as archive:
                for key, value in (*self._meta.items(), ("description", self.description)):
                    _write_member(archive, key, np.asarray(value))
        else:
            header = csv_geometry_header(grid) + "# units=Pa\n"
            header += f"# description={' '.join(self.description.split())}\n# columns=seq,t\n"
            path.write_text(header, encoding="utf-8")

    def add(self, seq: int, t: float, stress: np.ndarray) -> None:
        """Queue one frame (``t`` in seconds); flushes when ``flush_interval`` has passed."""
        with self._lock:
            if self._closed:
                return  # the reader took this recorder just before it was stopped: the frame is past the end
            self._rows.append((seq, t, stress))
            if self._last_flush is None:
                self._last_flush = t
            if t - self._last_flush >= self.flush_interval:
                self._flush(t)

    def tick(self, now: float) -> None:
        """Flush if frames have waited ``flush_interval`` (called while the line is quiet)."""
        with self._lock:
            if self._rows and now - self._last_flush >= self.flush_interval:
                self._flush(now)

    def _flush(self, now: float | None = None) -> None:
        rows, self._rows = self._rows, []
        self._last_flush = now
        if rows:
            seq = np.array([r[0] for r in rows], dtype=np.int64)
            t = np.array([r[1] for r in rows])
            frames = np.array([r[2] for r in rows])
            if self.kind == ".npz":
                with zipfile.ZipFile(self.path, "a") as archive:
                    name = f"chunk{self._chunks:06d}"
                    for key, value in (("frames", frames), ("t", t), ("seq", seq)):
                        _write_member(archive, f"{name}_{key}", value)
                self._chunks += 1
            else:
                with open(self.path, "a", encoding="utf-8") as f:
                    np.savetxt(f, np.column_stack([seq, t, frames]), delimiter=",",
                               fmt=["%d", "%.6f"] + ["%.9g"] * frames.shape[1])
            self.written += len(rows)

    def close(self) -> Path | None:
        """Write what is left; an NPZ becomes one plain recording (chunks joined).

        Returns the path, or None (and no file) when no frame was recorded.
        """
        with self._lock:
            self._flush()
            self._closed = True
            if self.written == 0:
                self.path.unlink(missing_ok=True)
                return None
            if self.kind == ".npz":
                recording = load(self.path)
                temporary = self.path.with_name(self.path.name + ".tmp")
                with open(temporary, "wb") as handle:
                    np.savez(handle, frames=recording.frames, t=recording.t,
                             seq=recording.seq if recording.seq is not None else np.zeros(0, np.int64),
                             description=self.description, **self._meta)
                os.replace(temporary, self.path)
        return self.path


def _write_member(archive: zipfile.ZipFile, key: str, value: np.ndarray) -> None:
    with archive.open(f"{key}.npy", "w", force_zip64=True) as member:
        np.lib.format.write_array(member, np.asarray(value), allow_pickle=False)

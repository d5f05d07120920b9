"""Recordings: a sensor grid, frames of stress and their timestamps, in MCAP, NPZ or CSV.

:class:`Recording` is what every format loads into
(:func:`tactile_viewer.io.files.load` reads any of them, this module's
:func:`load_npz` and :func:`load_csv` two). Live recordings are written as MCAP by
:class:`tactile_viewer.io.mcap.Recorder` (raw values with their
:class:`StressCalibration`, crash-safe, opened lazily); NPZ and CSV are export
and import formats written whole by :func:`save`. :func:`grid_from_fields` /
:func:`geometry_fields` are the one reader and writer of the geometry that
every file (layouts included) declares.

NPZ keys: ``frames (T, m)`` pascals, ``t (T,)`` seconds, ``nx``, ``ny`` (or
``taxels`` and ``positions`` for an irregular layout), ``pitch``, ``thickness``
(metres), optional ``poisson_ratio`` (the elastomer's nu, default 0.5),
optional ``sensor_size`` (side of a square taxel, metres, default 0: point
sensors), optional ``positions (m, 2)``, optional ``truth_forces (T, m, 3)``
newtons, optional ``seq (T,)`` sequence numbers of live frames, ``units``,
``description``. Live recordings of earlier versions, written as NPZ chunks
``chunkNNNNNN_frames``, ``chunkNNNNNN_t``, ``chunkNNNNNN_seq`` and never
closed, load as one recording.

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

import contextlib
import datetime
import io
import math
import os
import secrets
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from solver import SensorGrid
from solver.arrays import read_only
from solver.checks import one_of

__all__ = ["Recording", "RecordingError", "StressCalibration", "Tare", "load_npz", "load_csv", "save",
           "grid_from_fields",
           "geometry_fields", "csv_geometry_header", "raw_to_pascals", "per_taxel", "json_ready",
           "MAX_TAXELS", "RAW_UNITS", "SUFFIXES", "facts"]

UNIT_SCALES = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6}
# what a board may send: pressure units, or counts that the gain turns into pascals
RAW_UNITS = (*UNIT_SCALES, "counts")
SUFFIXES = (".mcap", ".npz", ".csv")

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


def raw_to_pascals(raw, units: str, gain, offset) -> np.ndarray:
    """``gain * (raw - offset) * scale(units)``: a board's raw values in pascals.

    ``scale`` is 1, 1e3, 1e6 for ``"Pa"``, ``"kPa"``, ``"MPa"`` and 1 for
    ``"counts"`` (the gain then is pascals per count). A value beyond a float
    once converted (1e308 in kPa) comes out inf, without a warning: the live
    calibration refuses such frames, and the solver any frame it is handed.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return np.asarray(gain) * (np.asarray(raw, dtype=float) - offset) * UNIT_SCALES.get(units, 1.0)


@contextlib.contextmanager
def written_whole(path):
    """A temporary name beside ``path`` to write a file to, renamed to ``path`` once it is whole.

    The rename happens when the block ends without an error; otherwise the
    temporary file is removed. A failed write (a full disk, a renderer that
    fails) leaves no partial file, and an earlier file of that name as it was.
    The temporary name is hidden (``.name.<random>.partial<suffix>``) and keeps
    the suffix, by which writers such as pyvista choose the format.

    Yields
    ------
    Path
    """
    path = Path(path)
    temporary = path.with_name(f".{path.name}.{secrets.token_hex(4)}.partial{path.suffix.lower()}")
    try:
        yield temporary
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _clock(unix: float) -> str:
    # "2023-11-14 22:13:20.000 UTC (1700000000.000000 s)"
    when = datetime.datetime.fromtimestamp(unix, datetime.UTC)
    return f"{when:%Y-%m-%d %H:%M:%S}.{when.microsecond // 1000:03d} UTC ({unix:.6f} s)"


def json_ready(fields: dict) -> dict:
    """``fields`` with arrays as lists: what ``json.dumps`` takes."""
    return {key: value.tolist() if isinstance(value, np.ndarray) else value for key, value in fields.items()}


def per_taxel(value, name: str, m: int) -> np.ndarray:
    """``value`` as ``m`` finite numbers, read-only (one number is shared by every taxel)."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(m, float(array))
    if array.shape != (m,):
        raise ValueError(f"{name} must be one number or {m} numbers (one per taxel), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite")
    return read_only(array)


@dataclass(frozen=True, eq=False)
class Tare:
    """A baseline subtracted from a recording's frames from ``from_frame`` on.

    Attributes
    ----------
    from_frame : int
        Index of the first frame it applies to.
    baseline : (m,) ndarray
        Pascals.
    t : float
        Receive time it was taken at, seconds of the recording's clock (nan: unknown).
    frames : int
        Frames averaged (0: unknown).
    """

    from_frame: int
    baseline: np.ndarray
    t: float = math.nan
    frames: int = 0

    def __post_init__(self):
        if isinstance(self.from_frame, bool) or not isinstance(self.from_frame, (int, np.integer)) \
                or self.from_frame < 0:
            raise ValueError(f"from_frame must be a whole number >= 0, got {self.from_frame!r}")
        baseline = np.asarray(self.baseline, dtype=float)
        object.__setattr__(self, "baseline", per_taxel(baseline, "baseline", baseline.size))
        object.__setattr__(self, "from_frame", int(self.from_frame))

    def fields(self) -> dict:
        return dict(from_frame=self.from_frame, baseline=self.baseline, t=self.t, frames=self.frames)

    @classmethod
    def from_fields(cls, taxels: int, *, from_frame, baseline, t=math.nan, frames=0) -> Tare:
        """As written by :meth:`fields` (JSON values); the baseline must have ``taxels`` values."""
        baseline = np.asarray(baseline, dtype=float)
        if baseline.shape != (taxels,):
            raise ValueError(f"a tare baseline must have {taxels} values, got shape {baseline.shape}")
        return cls(from_frame, baseline, math.nan if t is None else float(t), int(frames))


@dataclass(frozen=True, eq=False)
class StressCalibration:
    """How a recording's raw values become the stresses shown: units, gain, offset, tares.

    ``stress = gain * (raw - offset) * scale(units) - baseline`` where the
    baseline is that of the last tare whose ``from_frame`` the frame reached
    (zero before the first).

    Attributes
    ----------
    units : str
        One of :data:`RAW_UNITS`.
    gain, offset : (m,) ndarray
    tares : tuple of Tare
        In the order they were taken.
    """

    units: str
    gain: np.ndarray
    offset: np.ndarray
    tares: tuple = ()

    def __post_init__(self):
        one_of("units", self.units, RAW_UNITS)
        # one number shared by every taxel stays one number until a tare says how many there are
        m = max(np.size(self.gain), np.size(self.offset), *(np.size(tare.baseline) for tare in self.tares))
        object.__setattr__(self, "gain", per_taxel(self.gain, "gain", m))
        object.__setattr__(self, "offset", per_taxel(self.offset, "offset", m))
        tares = tuple(sorted(self.tares, key=lambda tare: tare.from_frame))
        for tare in tares:
            if tare.baseline.shape != (m,):
                raise ValueError(f"a tare baseline must have {m} values, got shape {tare.baseline.shape}")
        object.__setattr__(self, "tares", tares)

    @classmethod
    def identity(cls, m: int) -> StressCalibration:
        """Raw values that are pascals already."""
        return cls("Pa", np.ones(m), np.zeros(m))

    @classmethod
    def from_fields(cls, taxels: int, *, units, gain, offset, tares=()) -> StressCalibration:
        """As written by :meth:`fields` (JSON values) for ``taxels`` values per frame."""
        return cls(units, per_taxel(gain, "gain", taxels), per_taxel(offset, "offset", taxels), tuple(tares))

    def fields(self) -> dict:
        """``units``, ``gain``, ``offset`` (one number when all taxels share it); tares apart."""
        def one(value):
            return float(value[0]) if np.all(value == value[0]) else value
        return dict(units=self.units, gain=one(self.gain), offset=one(self.offset))

    def retared(self, tare: Tare | None) -> StressCalibration:
        """The same conversion with ``tare`` as the only baseline (None: no tare)."""
        return StressCalibration(self.units, self.gain, self.offset, () if tare is None else (tare,))

    def apply(self, raw, rows) -> np.ndarray:
        """Pascals of the raw values ``(k, m)`` of frames ``rows (k,)`` (or one frame ``(m,)``)."""
        stress = raw_to_pascals(raw, self.units, self.gain, self.offset)
        if not self.tares:
            return stress
        starts = np.array([tare.from_frame for tare in self.tares])
        baselines = np.vstack([np.zeros_like(self.tares[0].baseline), *(t.baseline for t in self.tares)])
        return stress - baselines[np.searchsorted(starts, rows, side="right")]


@dataclass(frozen=True, eq=False)
class Recording:
    """Frames of sensor stress over time.

    Attributes
    ----------
    grid : SensorGrid
    frames : (T, m) ndarray or FrameTable
        Stress at each sensor, pascals, compression positive. A recording
        opened from MCAP holds a :class:`~tactile_viewer.io.mcap.FrameTable`
        that reads frames from the file on demand and indexes like an array.
    t : (T,) ndarray
        Time of each frame, seconds, non-decreasing.
    truth_forces : (T, m, 3) ndarray or None
        Known nodal forces (simulated recordings), newtons.
    description : str
    seq : (T,) ndarray of int or None
        Sequence numbers of frames received live (gaps are lost frames); an
        MCAP recording reads them on demand (:meth:`sequence`).
    received : float or None
        UNIX seconds at which frame 0 was received (None: the file keeps no
        receive clock).
    truncated : bool
        The file was cut short (a crash, a full disk); it holds every frame
        of its complete chunks (MCAP) or rows (CSV: a last row without a
        line end is left out).
    damage : tuple of str
        What the file holds that could not be read, a sentence each (MCAP:
        frames of a chunk that failed its checksum, a tare whose record is
        damaged or lost); empty when nothing is.
    lost_spans : tuple of (float, float)
        When the frames lost to damage were received, seconds on :attr:`t`'s
        clock, first and last (the time plots shade them).
    """

    grid: SensorGrid
    frames: np.ndarray
    t: np.ndarray
    truth_forces: np.ndarray | None = None
    description: str = ""
    seq: np.ndarray | None = None
    received: float | None = None
    truncated: bool = False
    damage: tuple = ()
    lost_spans: tuple = ()

    def __post_init__(self):
        lazy = not isinstance(self.frames, (np.ndarray, list, tuple))
        frames = self.frames if lazy else np.array(self.frames, dtype=float)
        if len(frames.shape) != 2 or frames.shape[1] != self.grid.size:
            raise ValueError(f"frames must have shape (T, {self.grid.size}), got {frames.shape}")
        t = np.array(self.t, dtype=float)
        if t.shape != (frames.shape[0],):
            raise ValueError(f"t must have shape ({frames.shape[0]},), got {t.shape}")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
            raise ValueError("t must be finite and non-decreasing")
        object.__setattr__(self, "frames", frames if lazy else read_only(frames))
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

    @property
    def calibration(self) -> StressCalibration | None:
        """How raw values became these frames, when the file keeps raw values (MCAP); else None."""
        return getattr(self.frames, "calibration", None)

    def recalibrated(self, calibration: StressCalibration) -> Recording:
        """The same recording shown through ``calibration`` (a tare retaken or cleared).

        Raises
        ------
        ValueError
            When the recording keeps no raw values (NPZ and CSV hold stresses only).
        """
        if self.calibration is None:
            raise ValueError("this recording keeps no raw values (NPZ or CSV): its tare cannot change")
        return replace(self, frames=self.frames.with_calibration(calibration))

    def sequence(self) -> np.ndarray | None:
        """Sequence numbers of the frames (read from an MCAP file on first use), or None."""
        if self.seq is not None:
            return self.seq
        return self.frames.sequence() if hasattr(self.frames, "sequence") else None


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


def _checked_shape(shape, grid, path) -> int:
    # from a header, before the frames are read: a table of the wrong shape is refused before it is made
    if len(shape) != 2 or shape[1] != grid.size:
        layout = (f"{grid.shape[1]}x{grid.shape[0]} grid" if len(grid.shape) == 2
                  else f"{grid.size}-taxel layout")
        raise RecordingError(f"{path}: frames must be a (T, {grid.size}) table for a {layout}, "
                             f"got shape {tuple(shape)}")
    if shape[0] == 0:
        raise RecordingError(f"{path}: no frames")
    return shape[0]


def _checked_frames(frames, grid, path, scale: float = 1.0):
    # the frames in pascals; a value that is no number, or none once converted (1e308 kPa), is refused
    _checked_shape(frames.shape, grid, path)
    bad = np.argwhere(~np.isfinite(frames))
    if bad.size:
        raise RecordingError(f"{path}: frame {bad[0][0]} taxel {bad[0][1]} is not a finite number")
    with np.errstate(over="ignore"):  # checked just below
        frames = frames * scale
    bad = np.argwhere(~np.isfinite(frames))
    if bad.size:
        raise RecordingError(f"{path}: frame {bad[0][0]} taxel {bad[0][1]} is not a finite number in pascals")
    return frames


# -- sizes a file declares ------------------------------------------------------------------------
# A file says how big its arrays are before it holds them (an NPZ member's .npy header, the zip's
# directory, a CSV's lines). What it says is checked against the file and these ceilings before
# anything of that size is made: a damaged or hostile file costs a RecordingError, not the memory.

# The most one recording may take once loaded, every array as float64 (what the viewer holds): a
# 32x32 skin at 1 kHz for 8.7 minutes. Loading passes the frames through about three transient
# copies (conversion, scaling, the Recording's own), so this already asks for some 12 GB; longer
# recordings belong in MCAP, which opens lazily a chunk at a time.
_MAX_RECORDING_BYTES = 4 * 2**30
# How many times a compressed NPZ member may expand. Deflate cannot pass about 1032:1, which only
# long runs of one byte reach. Measured with np.savez_compressed (zlib level 6): sensor noise 1.1:1,
# ADC counts stored as floats 3.5:1, 8 of 256 taxels pressed 30 to 67:1, a constant frame 660:1,
# all-zero 16x16 frames 982:1 (1000 frames) rising to 1028:1 (100000 frames). Past 1000:1 a member
# is one repeated byte: a bomb, or an idle skin, which _EXPANSION_ALLOWANCE lets load while small.
_MAX_EXPANSION = 1000
# Bytes, all members together, that may expand more than _MAX_EXPANSION times: an all-zero
# recording of up to 64 MiB (32768 frames of 16x16) loads, a bomb is refused before it is inflated.
_EXPANSION_ALLOWANCE = 64 * 2**20
# A field that is one number or one text (a megabyte is no description).
_MAX_FIELD_BYTES = 2**20
# np.load's own limit on a .npy header (its max_header_size), here checked before the header is read.
_MAX_NPY_HEADER = 10_000
# The NPZ fields that are arrays of numbers; every other field the loader reads is a single value.
_NPZ_ARRAYS = ("frames", "t", "seq", "truth_forces", "positions")
_NPZ_SINGLES = ("nx", "ny", "taxels", "pitch", "thickness", "poisson_ratio", "sensor_size", "units",
                "description")


FORCE_EXPORT = ("a force export of this viewer (forces per node, not the sensor stresses a recording "
                "holds): open the recording it was made from")


def load_npz(path) -> Recording:
    """Read an NPZ recording (:func:`tactile_viewer.io.files.load` checks the path and names errors)."""
    with open(path, "rb") as handle:
        start = handle.read(24)
    # a zip (even a damaged one) or a bare .npy goes on to numpy, whose reasons say more
    if not start.startswith((b"PK", b"\x93NUMPY")):
        raise RecordingError(f"{path}: not an NPZ archive (an NPZ is a zip of .npy arrays; this file starts "
                             f"with {start!r})")
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise RecordingError(f"{path}: not a readable NPZ archive ({exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise RecordingError(f"{path}: not an NPZ archive (a single array, as .npy writes)")
    with data:
        _check_member_names(data, path)
        # the members each field is read from: its own, or those of the chunks of a live recording
        parts = ({key: [key] for key in ("frames", "t", "seq") if key in data} if "frames" in data
                 else _joined_chunks(data))
        if "forces" in data:  # a recording's known forces are 'truth_forces'
            raise RecordingError(f"{path}: {FORCE_EXPORT}")
        if "frames" not in parts:
            raise RecordingError(f"{path}: missing 'frames'")
        parts.update({key: [key] for key in (*_NPZ_SINGLES, "positions", "truth_forces") if key in data})
        shapes = _npz_shapes(data, parts, path)  # from the headers alone: nothing is read before this
        declared = shapes["frames"]
        grid = _grid(data, path, data["positions"] if "positions" in data else None,
                     width=declared[1] if len(declared) == 2 else None)
        count = _checked_shape(declared, grid, path)
        for key, shape in (("t", (count,)), ("seq", (count,)), ("truth_forces", (count, grid.size, 3))):
            if key in shapes and shapes[key] != shape:
                raise RecordingError(f"{path}: {key} must have shape {shape}, got {shapes[key]}")
        arrays = {key: data[names[0]] if len(names) == 1 else np.concatenate([data[name] for name in names])
                  for key, names in parts.items() if key in ("frames", "t", "seq")}
        units = str(data["units"]) if "units" in data else "Pa"
        frames = _checked_frames(np.asarray(arrays["frames"], dtype=float), grid, path, _scale(units, path))
        t = np.asarray(arrays["t"], dtype=float) if "t" in arrays else np.arange(len(frames), dtype=float)
        seq = arrays.get("seq")
        truth = np.asarray(data["truth_forces"], dtype=float) if "truth_forces" in data else None
        description = str(data["description"]) if "description" in data else ""
    try:
        return Recording(grid, frames, t, truth, description, seq)
    except ValueError as exc:
        raise RecordingError(f"{path}: {exc}") from None


def _npz_shapes(data, parts, path) -> dict:
    """The shape of each field of ``parts`` (field: its members), from the members' .npy headers alone.

    Every member is checked before any is read: an array, not pickled objects, of what its field
    holds, whose declared size fits the ceilings above, the file and the zip's directory.

    Raises
    ------
    RecordingError
        Naming the member and the rule it breaks.
    """
    file_size = Path(path).stat().st_size
    loaded = expanding = 0  # bytes the arrays will take; bytes of members expanding past _MAX_EXPANSION
    shapes = {}
    for field, names in parts.items():
        found = []
        for name in names:
            info, shape, dtype, header = _npy_header(data, name, path)
            values = math.prod(shape)
            stored = values * dtype.itemsize
            declares = f"{name!r} declares {_values_text(shape)} ({_bytes_text(stored)})"
            if dtype.hasobject:
                raise RecordingError(f"{path}: {name!r} holds Python objects (dtype {dtype}), which only "
                                     "unpickling could read and no recording holds (allow_pickle=False)")
            if field in _NPZ_ARRAYS:
                if dtype.kind not in "biuf":
                    raise RecordingError(f"{path}: {name!r} must hold numbers, got dtype {dtype}")
                loaded += values * max(dtype.itemsize, 8)  # held as float64
            elif values != 1:
                kind = "text" if field in ("units", "description") else "number"
                raise RecordingError(f"{path}: {name!r} must be a single {kind}, got shape {shape}")
            elif stored > _MAX_FIELD_BYTES:
                raise RecordingError(f"{path}: {declares}, more than the {_bytes_text(_MAX_FIELD_BYTES)} "
                                     "one field may hold")
            else:
                loaded += stored
            if field == "positions" and (len(shape) != 2 or shape[1] != 2 or shape[0] > MAX_TAXELS):
                raise RecordingError(f"{path}: 'positions' must be x, y pairs of metres (shape (m, 2), m at "
                                     f"most {MAX_TAXELS}), got shape {shape}")
            if loaded > _MAX_RECORDING_BYTES:
                raise RecordingError(f"{path}: {declares}: the recording would take {_bytes_text(loaded)}, "
                                     f"more than the {_bytes_text(_MAX_RECORDING_BYTES)} this viewer loads "
                                     "(long recordings belong in MCAP, which opens lazily)")
            member = header + stored  # what the member inflates to, were the header true
            if info.compress_type == zipfile.ZIP_STORED:
                if member > file_size:
                    raise RecordingError(f"{path}: {declares} but the file holds {_bytes_text(file_size)}: "
                                         "not a recording")
            elif info.compress_size > file_size:
                raise RecordingError(f"{path}: damaged NPZ archive: its directory says {name!r} is "
                                     f"{_bytes_text(info.compress_size)} compressed but the file holds "
                                     f"{_bytes_text(file_size)}")
            elif member > _MAX_EXPANSION * info.compress_size:
                expanding += member
                if expanding > _EXPANSION_ALLOWANCE:
                    ratio = member / max(info.compress_size, 1)
                    raise RecordingError(f"{path}: {declares} from {_bytes_text(info.compress_size)} "
                                         f"compressed, {ratio:.0f}:1, more than the {_MAX_EXPANSION}:1 any "
                                         "recording reaches: a decompression bomb, not a recording")
            if info.file_size != member or (info.compress_type == zipfile.ZIP_STORED
                                            and info.compress_size != member):
                raise RecordingError(f"{path}: damaged NPZ archive: its directory says {name!r} holds "
                                     f"{_bytes_text(info.file_size)} but its array header declares "
                                     f"{_bytes_text(member)}")
            found.append(shape)
        shapes[field] = _joined_shape(names, found, path)
    return shapes


def _npy_header(data, name, path):
    """``(zip info, shape, dtype, header bytes)`` of member ``name``, read without its values.

    The header's own length is bounded before the header is read: a version 2.0 header may declare
    4 GiB of itself, which np.load would read whole before its max_header_size refused it.
    """
    try:
        info = data.zip.getinfo(name)
    except KeyError:  # np.savez writes 'frames' as 'frames.npy'; NpzFile finds it by either name
        info = data.zip.getinfo(f"{name}.npy")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        # zipfile inflates a bzip2 or LZMA member a whole compressed block at a time, unbounded (a few
        # hundred bytes of bzip2 can be gigabytes of zeros): not even its header is read. numpy
        # writes members stored or deflated only.
        raise RecordingError(f"{path}: {name!r} is compressed by zip method {info.compress_type}, which "
                             "numpy never writes (only stored or deflated): not a recording")
    try:
        member = data.zip.open(info)
    except RuntimeError as exc:  # an encrypted member
        raise RecordingError(f"{path}: {name!r} cannot be read ({exc})") from None
    with member:
        prefix = member.read(8)  # the magic string and the format version
        try:
            version = np.lib.format.read_magic(io.BytesIO(prefix))
        except ValueError:
            raise RecordingError(f"{path}: {name!r} is not a NumPy array (.npy): not a recording") from None
        if version not in ((1, 0), (2, 0)):  # 3.0 is for field names only structured arrays have
            raise RecordingError(f"{path}: {name!r} is a version {version[0]}.{version[1]} .npy array, "
                                 "which no recording is")
        length_field = member.read(2 if version == (1, 0) else 4)
        length = int.from_bytes(length_field, "little")
        if length > _MAX_NPY_HEADER:
            raise RecordingError(f"{path}: {name!r} declares an array header of {length} bytes (at most "
                                 f"{_MAX_NPY_HEADER}): not a recording")
        text = member.read(length)
    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    try:
        shape, _, dtype = read(io.BytesIO(length_field + text))
    except ValueError as exc:
        raise RecordingError(f"{path}: {name!r} has a damaged array header ({exc})") from None
    if any(size < 0 for size in shape):
        raise RecordingError(f"{path}: {name!r} has a damaged array header (shape {shape})")
    return info, shape, dtype, len(prefix) + len(length_field) + length


def _joined_shape(names, shapes, path) -> tuple:
    # the chunks of a field join along their first axis: the other axes must agree
    if len(shapes) == 1:
        return shapes[0]
    for name, shape in zip(names, shapes, strict=True):
        if not shape or shape[1:] != shapes[0][1:]:
            raise RecordingError(f"{path}: {name!r} has shape {shape} but {names[0]!r} has {shapes[0]}: "
                                 "the chunks do not join")
    return (sum(shape[0] for shape in shapes), *shapes[0][1:])


def _values_text(shape) -> str:
    count = "x".join(map(str, shape)) if len(shape) > 1 else str(math.prod(shape))
    return f"{count} value{'' if count == '1' else 's'}"


def _bytes_text(count) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("KB", 1e3)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count} B"


def _check_member_names(data, path):
    """Refuse an archive whose directory names a member one character away from a missing field.

    The members' contents are under the zip's checksums; their names are not. One flipped bit in
    the directory turns ``t.npy`` into ``u.npy``, and the recording would load with times 0, 1,
    2 s (``units`` read as Pa, ``positions`` as a regular grid ...). So a member that is no field
    of a recording and differs by one character from a field that is missing is a damaged name;
    and every chunk of a live recording must hold the same fields.
    """
    names = data.zip.namelist()
    chunks = sorted({name.split("_", 1)[0] for name in names if name.startswith("chunk")})
    fields = [*_NPZ_ARRAYS, *_NPZ_SINGLES, "forces"]
    fields += [f"{c}_{key}" for c in chunks for key in ("frames", "t", "seq")]
    expected = {f"{field}.npy" for field in fields}
    missing = expected - set(names)
    for name in sorted(set(names) - expected):
        for field in sorted(missing):
            if len(name) == len(field) and sum(a != b for a, b in zip(name, field, strict=True)) == 1:
                raise RecordingError(f"{path}: member {name!r} is no field of a recording and {field!r} is "
                                     "missing: the archive's directory is damaged (one character of a name "
                                     "changed)")
    for key in ("t", "seq"):
        holding = [c for c in chunks if f"{c}_{key}.npy" in names]
        if holding and len(holding) != len(chunks):
            lacking = sorted(set(chunks) - set(holding))
            raise RecordingError(f"{path}: chunk(s) {', '.join(lacking)} have no {key!r} while the others "
                                 "have it: the archive is damaged")


def _joined_chunks(data) -> dict:
    # a live recording cut off before it was closed: for each field every chunk holds, its members in order
    names = sorted({name.split("_", 1)[0] for name in data.files if name.startswith("chunk")})
    if not names:
        return {}
    return {key: [f"{name}_{key}" for name in names] for key in ("frames", "t", "seq")
            if all(f"{name}_{key}" in data for name in names)}


# The longest line a CSV recording needs, in characters: 'positions=' of MAX_TAXELS x,y pairs of
# repr floats (at most 50 characters a pair). A line is read no further than this.
_MAX_CSV_LINE = 64 * 2**20
# Values parsed as Python floats (32 bytes each) before they are packed as float64 (8 bytes each).
_CSV_BLOCK = 2**16


def load_csv(path) -> Recording:
    """Read a CSV recording (:func:`tactile_viewer.io.files.load` checks the path and names errors)."""
    # What bounds the memory, whatever the file says: a line is read no further than _MAX_CSV_LINE
    # characters (reading one peaks at twice that), a row's values are counted before they are parsed
    # (at most MAX_TAXELS + 2), and rows are packed as float64, 8 bytes a value where the file spent at
    # least 2 characters ('0,'): at most four times the file (twice that while the blocks are joined)
    # and at most _MAX_RECORDING_BYTES. 'positions' holds at most MAX_TAXELS pairs.
    meta, blocks, block, width, held, cut = {}, [], [], None, 0, False
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(iter(lambda: handle.readline(_MAX_CSV_LINE + 1), ""), start=1):
            if len(line) > _MAX_CSV_LINE and not line.endswith("\n"):
                raise RecordingError(f"{path}: line {number} is longer than {_MAX_CSV_LINE} characters: "
                                     "not a recording")
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                key, sep, value = text[1:].partition("=")
                if sep:
                    meta[key.strip()] = value.strip()
                continue
            if not line.endswith("\n"):
                # the last row has no line end: the file was cut short, perhaps inside a value (1.25
                # read as 1.2); it is left out, and the recording says it was cut
                cut = True
                continue
            count = text.count(",") + text.count(";") + 1
            if count > MAX_TAXELS + 2:
                raise RecordingError(f"{path}: line {number} holds {count} values, more than a frame of the "
                                     f"largest skin this viewer opens ({MAX_TAXELS} taxels) has")
            try:
                row = [float(v) for v in text.replace(";", ",").split(",")]
            except ValueError:
                if text.replace(" ", "").startswith("frame,t,node,"):
                    raise RecordingError(f"{path}: {FORCE_EXPORT}") from None
                raise RecordingError(f"{path}: line {number}: not a row of numbers: {text[:60]!r}") from None
            if width is None:
                width = len(row)
            elif len(row) != width:
                raise RecordingError(f"{path}: line {number}: {len(row) - 1} values, "
                                     f"earlier rows have {width - 1}")
            held += width
            if held * 8 > _MAX_RECORDING_BYTES:
                raise RecordingError(f"{path}: line {number}: the frames would take more than the "
                                     f"{_bytes_text(_MAX_RECORDING_BYTES)} this viewer loads (long "
                                     "recordings belong in MCAP, which opens lazily)")
            block += row
            if len(block) >= _CSV_BLOCK:
                blocks.append(np.array(block, dtype=float))
                block = []
    if width is None:
        if not meta:
            raise RecordingError(f"{path}: empty: a CSV recording has '# key=value' header lines (nx, ny, "
                                 "pitch, thickness) and then one frame per row (t, v0, v1, ...)")
        raise RecordingError(f"{path}: no frames" + (" (its one row has no line end: cut short)" if cut
                                                     else ""))
    table = np.concatenate([*blocks, np.array(block, dtype=float)]).reshape(-1, width)
    columns = meta.get("columns", "t")
    if columns not in ("t", "seq,t"):
        raise RecordingError(f"{path}: columns must be 't' or 'seq,t', got {columns!r}")
    first = 2 if columns == "seq,t" else 1
    positions = None
    if "positions" in meta:
        pairs = meta["positions"].count(";") + 1
        if pairs > MAX_TAXELS + 1:  # one more: a trailing ';'
            raise RecordingError(f"{path}: 'positions' holds {pairs} x,y pairs, more than the {MAX_TAXELS} "
                                 "taxels of the largest skin this viewer opens")
        try:
            positions = [[float(v) for v in pair.split(",")] for pair in meta["positions"].split(";")
                         if pair.strip()]  # a trailing ';' of a hand-edited file is no pair
        except ValueError:
            raise RecordingError(f"{path}: positions must be x,y pairs of metres separated by ';'") from None
    grid = _grid(meta, path, positions, width=table.shape[1] - first)
    frames = _checked_frames(table[:, first:], grid, path, _scale(meta.get("units", "Pa"), path))
    seq = table[:, 0] if first == 2 else None
    try:
        return Recording(grid, frames, table[:, first - 1], None, meta.get("description", ""), seq,
                         truncated=cut)
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


def facts(recording: Recording) -> list[str]:
    """What ``tactile-viewer FILE --info`` prints: one line per fact, nothing solved.

    ``frames``, ``span`` (seconds), ``sequence gaps`` (frames missing between
    the numbers received, and any repeated or reordered ones), ``first
    received`` and ``last received`` (UNIX seconds, the recorder's receive
    clock), ``cut short``, ``damage`` (what could not be read), ``checksums``
    (MCAP: the whole file read and every checksum checked), ``geometry`` and
    ``calibration``. What a format does not keep is said to be unknown.
    """
    grid = recording.grid
    lines = [f"frames {len(recording)}", f"span {float(recording.t[-1] - recording.t[0]):.3f} s"]
    try:
        sequence = recording.sequence()
    except RecordingError:  # a chunk fails its checksum: the checksums line says which
        lines.append("sequence gaps unknown (a damaged chunk holds some of them)")
    else:
        if sequence is None:
            lines.append("sequence gaps unknown (the file keeps no sequence numbers)")
        else:
            steps = np.diff(sequence)
            gaps = f"sequence gaps {int(np.sum(steps[steps > 1] - 1))}"
            backwards = int(np.sum(steps <= 0))
            lines.append(gaps + (f" ({backwards} repeated or reordered)" if backwards else ""))
    if recording.received is None:
        lines += ["first received unknown (the file keeps no receive clock)", "last received unknown"]
    else:
        # a date and clock time a person reads (UTC, to the millisecond), the UNIX seconds beside it
        lines += [f"first received {_clock(recording.received)}",
                  f"last received {_clock(recording.received + float(recording.t[-1]))}"]
    lines.append("cut short yes: it ends at its last complete chunk or row (a crash or a full disk)"
                 if recording.truncated else "cut short no")
    lines += [f"damage {what}" for what in recording.damage] or ["damage none found"]
    if hasattr(recording.frames, "verify"):
        problems = recording.frames.verify()
        checked = "every chunk's frames" + (" and the data section" if recording.frames.data_checksum else
                                            " (the file keeps no checksum of its data section)")
        lines += ([f"checksums fail: {what}" for what in problems] if problems else
                  [f"checksums good: {checked}, all read and checked"])
    size = (f"{grid.shape[1]}x{grid.shape[0]} taxels" if len(grid.shape) == 2
            else f"{grid.size} taxels (irregular)")
    lines.append(f"geometry {size}, pitch {grid.pitch * 1e3:g} mm, thickness {grid.thickness * 1e3:g} mm, "
                 f"poisson ratio {grid.poisson_ratio:g}, sensor size {grid.sensor_size * 1e3:g} mm")
    calibration = recording.calibration
    if calibration is None:
        lines.append("calibration none kept: the frames are stresses in pascals (NPZ and CSV keep no "
                     "raw values)")
    else:
        fields = calibration.fields()
        def shown(value):
            if np.ndim(value) == 0:
                return f"{value:g}"
            return f"per taxel ({np.min(value):g} to {np.max(value):g})"
        def when(tare):  # a tare of a file that kept no time for it says so, not "nan s"
            return f"taken at {tare.t:.3f} s" if math.isfinite(tare.t) else "taken at an unknown time"
        tares = "; ".join(f"from frame {tare.from_frame} ({when(tare)}, {tare.frames} frames)"
                          for tare in calibration.tares) or "none"
        lines.append(f"calibration raw {recording.frames.raw_dtype.name} in {fields['units']}, "
                     f"gain {shown(fields['gain'])}, offset {shown(fields['offset'])}, tares: {tares}")
    return lines

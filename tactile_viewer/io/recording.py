"""Recordings: a sensor grid, frames of stress and their timestamps, whatever the file format.

:class:`Recording` is what every format loads into
(:func:`tactile_viewer.io.files.load` reads any of them: MCAP, NPZ
(:mod:`tactile_viewer.io.npz`) and CSV (:mod:`tactile_viewer.io.csv_table`)).
Live recordings are written as MCAP by
:class:`tactile_viewer.io.mcap_writer.Recorder` (raw values with their
:class:`StressCalibration`, crash-safe, opened lazily); NPZ and CSV are export
and import formats written whole by :func:`tactile_viewer.io.files.save`.
:func:`grid_from_fields` / :func:`geometry_fields` are the one reader and
writer of the geometry that every file (layouts included) declares;
:func:`declared_grid`, :func:`checked_shape` and :func:`checked_frames` check
what an NPZ or CSV file declares before it is believed.

Files written before nu and the taxel size were recorded have neither key:
they load as an incompressible layer (nu 0.5) read by point sensors.

No Qt here: the command line, the tests and the solver tools use it too.
"""

from __future__ import annotations

import contextlib
import math
import os
import secrets
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from solver import SensorGrid
from solver.arrays import read_only
from solver.checks import one_of

__all__ = ["Recording", "RecordingError", "StressCalibration", "Tare", "grid_from_fields", "geometry_fields",
           "raw_to_pascals", "per_taxel", "json_ready", "declared_grid", "unit_scale", "checked_shape",
           "checked_frames", "bytes_text", "MAX_TAXELS", "MAX_RECORDING_BYTES", "RAW_UNITS", "SUFFIXES",
           "FORCE_EXPORT"]

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
        opened from MCAP holds a :class:`~tactile_viewer.io.mcap_frames.FrameTable`
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


def declared_grid(meta, path, positions=None, width=None) -> SensorGrid:
    """The geometry file ``path`` declares in ``meta``; a :class:`RecordingError` names what is wrong."""
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


def unit_scale(units: str, path) -> float:
    """Pascals per unit of a file's ``units`` (a :class:`RecordingError` for an unknown one)."""
    if units not in UNIT_SCALES:
        raise RecordingError(f"{path}: units must be one of {sorted(UNIT_SCALES)}, got {units!r}")
    return UNIT_SCALES[units]


def checked_shape(shape, grid, path) -> int:
    """The number of frames of a ``(T, m)`` table of ``grid``'s frames, or a :class:`RecordingError`."""
    # from a header, before the frames are read: a table of the wrong shape is refused before it is made
    if len(shape) != 2 or shape[1] != grid.size:
        layout = (f"{grid.shape[1]}x{grid.shape[0]} grid" if len(grid.shape) == 2
                  else f"{grid.size}-taxel layout")
        raise RecordingError(f"{path}: frames must be a (T, {grid.size}) table for a {layout}, "
                             f"got shape {tuple(shape)}")
    if shape[0] == 0:
        raise RecordingError(f"{path}: no frames")
    return shape[0]


def checked_frames(frames, grid, path, scale: float = 1.0):
    """``frames`` times ``scale``: pascals, every one a finite number, or a :class:`RecordingError`."""
    # the frames in pascals; a value that is no number, or none once converted (1e308 kPa), is refused
    checked_shape(frames.shape, grid, path)
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
# directory, a CSV's lines). What it says is checked against the file and these ceilings (an NPZ's
# own are in io/npz.py) before anything of that size is made: a damaged or hostile file costs a
# RecordingError, not the memory.

# The most one recording may take once loaded, every array as float64 (what the viewer holds): a
# 32x32 skin at 1 kHz for 8.7 minutes. Loading passes the frames through about three transient
# copies (conversion, scaling, the Recording's own), so this already asks for some 12 GB; longer
# recordings belong in MCAP, which opens lazily a chunk at a time.
MAX_RECORDING_BYTES = 4 * 2**30


FORCE_EXPORT = ("a force export of this viewer (forces per node, not the sensor stresses a recording "
                "holds): open the recording it was made from")


def bytes_text(count) -> str:
    """``count`` bytes as a person reads them (``"4.3 GB"``)."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("KB", 1e3)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count} B"

"""The time series of a recording: total forces, shear and centroid over every frame. No Qt.

What the time plots draw and export: per frame the total normal force, the
size and direction of the total tangential force, their ratio and where the
compressive load is centred, of the reconstruction and, when the recording
carries its true forces, of the truth (computed from the truth forces by the
same functions) with the error figures of :mod:`solver.metrics`.

:func:`compute_series` solves a recording frame by frame as the window's
model would (automatic or given parameters), reports progress, can be
cancelled and hands out partial series while it runs; :class:`SeriesBuilder`
collects rows as frames are solved (a live source's rolling window);
:meth:`Series.to_csv` and :meth:`Series.from_csv` write and read it.

Threading: a solver (``solver.Reconstructor``) may be shared between threads.
What it builds in its constructor is only read by a solve; the one thing a solve
leaves behind is the last frame's contacts and fit (a slider move on that frame
reuses them, the next frame starts its fit from them), kept as one tuple that a
solve replaces whole, so a solve on another thread reads either the old or the
new one, and its answer depends on which only by rounding (the docstring of
``solver.inverse.DenseSolver.solve``); the large-skin engine's cache of window
set-ups is behind a lock. So the model's solver may serve a background series
while the model's worker thread solves the frame on screen, as the
whole-recording force export already does.

Contacts followed over time: beside the totals, a series holds the same six
quantities of each contact (its resultant and its load centre) by its identity
(:class:`solver.ContactTracker`; nan on the frames it is absent from).
:func:`compute_series` follows the contacts over the frames it solves, in
order (a sampled long take is followed over its samples); a live source's rows
carry the identities the window's model gave them.

CSV: ``#`` header lines (``key=value``: what it is, source, kernel, mode, the
given parameters, the units), one line of column names whose suffixes name the
units, then one row per frame: ``frame, t_s, fz_N, tangential_N,
direction_deg, shear_ratio, centroid_x_m, centroid_y_m`` and, with truth,
the same eight quantities prefixed ``truth_`` (no frame and time) then
``fz_error_pct, tangential_error_pct, direction_error_deg``; then the six
quantities of each contact, prefixed ``contact<identity>_`` (``contact1_fz_N``
...), by identity. Empty cells are written ``nan``.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from solver import ContactTracker
from solver.arguments import MAX_STRESS, check_parameters
from solver.arrays import read_only
from solver.checks import one_of, real_number, shown
from solver.metrics import direction_error, normal_total_error, tangential_total_error

from ..io.recording import Recording, written_whole
from .viewer_model import Solved, load_centroid
from .worker import Cancelled

__all__ = ["Quantities", "TruthErrors", "Series", "SeriesBuilder", "compute_series", "spread_frames",
           "nearest_frame", "MAX_FRAMES", "MODES", "CSV_MARKER"]

MAX_FRAMES = 2000  # frames a series solves at most: a long take is sampled evenly over its whole span
MODES = ("auto", "manual", "as shown")
CSV_MARKER = "tactile-viewer time series"
# A tangential total below this fraction of the whole resultant has no direction worth drawing:
# the exact family's rounding (1e-16 of |F|) would otherwise turn into a random angle.
NO_TANGENTIAL = 1e-9

_QUANTITIES = ("fz", "tangential", "direction", "shear_ratio", "centroid_x", "centroid_y")
# CSV column of each quantity and the factor from the dataclass's unit to the column's
_COLUMNS = (("fz_N", 1.0), ("tangential_N", 1.0), ("direction_deg", 180 / math.pi), ("shear_ratio", 1.0),
            ("centroid_x_m", 1.0), ("centroid_y_m", 1.0))
_ERROR_COLUMNS = (("fz_error_pct", 100.0), ("tangential_error_pct", 100.0), ("direction_error_deg", 1.0))
_NOTHING = (math.nan,) * 6  # a contact's quantities on a frame it is absent from


@dataclass(frozen=True)
class Quantities:
    """Totals of a force field over frames (the reconstruction's or the truth's).

    Attributes
    ----------
    fz : (n,) ndarray
        Total normal force, newtons (positive presses into the skin).
    tangential : (n,) ndarray
        Size of the total tangential force ``|sum (Fx, Fy)|``, newtons.
    direction : (n,) ndarray
        Its direction, radians from +x in ``(-pi, pi]``; nan where there is
        no tangential force.
    shear_ratio : (n,) ndarray
        ``tangential / fz``; nan where the total does not press (``fz <= 0``).
    centroid_x, centroid_y : (n,) ndarray
        Where the compressive normal load is centred, metres (the rule of
        :func:`~tactile_viewer.model.viewer_model.load_centroid`, which
        :meth:`~tactile_viewer.model.viewer_model.Solved.of`
        uses); nan where nothing presses.
    """

    fz: np.ndarray
    tangential: np.ndarray
    direction: np.ndarray
    shear_ratio: np.ndarray
    centroid_x: np.ndarray
    centroid_y: np.ndarray

    def __post_init__(self):
        arrays = {name: np.asarray(getattr(self, name), dtype=float) for name in _QUANTITIES}
        shapes = {array.shape for array in arrays.values()}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise ValueError("fz, tangential, direction, shear_ratio, centroid_x and centroid_y must be "
                             f"1-D arrays of one length, got shapes {[a.shape for a in arrays.values()]}")
        for name, array in arrays.items():
            object.__setattr__(self, name, read_only(array))

    def __len__(self) -> int:
        return self.fz.size

    @classmethod
    def of_forces(cls, grid, forces) -> Quantities:
        """The quantities of nodal forces ``forces (n, m, 3)`` newtons on ``grid``.

        Raises
        ------
        ValueError
            When ``forces`` is not ``(n, m, 3)`` for the grid's ``m`` nodes.
        """
        forces = np.asarray(forces, dtype=float)
        if forces.ndim != 3 or forces.shape[1:] != (grid.size, 3):
            raise ValueError(f"forces must have shape (n, {grid.size}, 3), got {forces.shape}")
        rows = [_row(frame, load_centroid(grid.positions, frame[:, 2])) for frame in forces]
        return cls(*np.array(rows, dtype=float).reshape(-1, 6).T)


@dataclass(frozen=True)
class TruthErrors:
    """The reconstruction's errors against the truth, per frame (:mod:`solver.metrics`).

    Attributes
    ----------
    normal : (n,) ndarray
        ``|sum Fz - sum Fz*| / |sum Fz*|`` (a fraction; nan without true normal force).
    tangential : (n,) ndarray
        ``|sum Ft - sum Ft*| / |sum F*|``, a fraction of the true force's size.
    direction_deg : (n,) ndarray
        Angle between the estimated and the true tangential totals, degrees in
        ``[0, 180]`` (nan where the truth has no tangential force).
    """

    normal: np.ndarray
    tangential: np.ndarray
    direction_deg: np.ndarray

    def __post_init__(self):
        arrays = [np.asarray(getattr(self, f.name), dtype=float) for f in fields(self)]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            raise ValueError(f"normal, tangential and direction_deg must be 1-D arrays of one length, got "
                             f"shapes {[a.shape for a in arrays]}")
        for f, array in zip(fields(self), arrays, strict=True):
            object.__setattr__(self, f.name, read_only(array))


@dataclass(frozen=True)
class Series:
    """The time series of a recording's reconstruction (and of its truth, when known).

    Attributes
    ----------
    frame : (n,) ndarray of int
        Frame index in the recording (a live frame's sequence number).
    t : (n,) ndarray
        Seconds.
    estimate : Quantities
        Of the reconstructed forces.
    truth : Quantities or None
        Of the recording's true forces, computed the same way (None: no truth).
    errors : TruthErrors or None
        Of the estimate against the truth (None without truth).
    kernel : str
        The solver's kernel.
    mode : {"auto", "manual", "as shown"}
        Automatic parameters, the given ``shear_ratio`` and
        ``shear_direction``, or each frame as the window solved it (a live
        source's history, whose parameters may have changed on the way).
    shear_ratio, shear_direction : float
        The given parameters (``shear_direction`` radians); nan when automatic.
    source : str
        The recording's file or label, for people.
    total : int
        Frames the complete series holds: ``n`` once complete, more for a
        partial series handed out while it is computed.
    contacts : tuple of (int, Quantities)
        Each followed contact's quantities over the ``n`` frames (nan where
        it is absent), by increasing identity (from 1); :meth:`contact` finds
        one. Empty when no contact was followed.
    refused : tuple of int
        Frames asked for that the solver refuses (a value beyond
        :data:`solver.arguments.MAX_STRESS`): not in the series, and not counted
        in ``total``.
    """

    frame: np.ndarray
    t: np.ndarray
    estimate: Quantities
    truth: Quantities | None = None
    errors: TruthErrors | None = None
    kernel: str = ""
    mode: str = "auto"
    shear_ratio: float = math.nan
    shear_direction: float = math.nan
    source: str = ""
    total: int = -1
    contacts: tuple = ()
    refused: tuple = ()

    def __post_init__(self):
        frame = np.asarray(self.frame)
        t = np.asarray(self.t, dtype=float)
        n = frame.size
        if frame.shape != (n,) or t.shape != (n,):
            raise ValueError(f"frame and t must be 1-D arrays of one length, got shapes {frame.shape} "
                             f"and {t.shape}")
        if n and not np.all(frame == np.round(frame)):
            raise ValueError("frame must hold whole numbers")
        if not isinstance(self.estimate, Quantities) or len(self.estimate) != n:
            raise ValueError(f"estimate must be Quantities of {n} frames, got {shown(self.estimate)}")
        if self.truth is not None and (not isinstance(self.truth, Quantities) or len(self.truth) != n):
            raise ValueError(f"truth must be None or Quantities of {n} frames, got {shown(self.truth)}")
        if self.errors is not None and (self.truth is None or not isinstance(self.errors, TruthErrors)
                                        or self.errors.normal.size != n):
            raise ValueError(f"errors must be TruthErrors of {n} frames, and only beside a truth")
        one_of("mode", self.mode, MODES)
        total = n if self.total == -1 else self.total
        if isinstance(total, bool) or not isinstance(total, (int, np.integer)) or total < n:
            raise ValueError(f"total must be a whole number >= the {n} frames held, got {shown(self.total)}")
        object.__setattr__(self, "frame", read_only(frame, np.int64))
        object.__setattr__(self, "t", read_only(t))
        object.__setattr__(self, "total", int(total))
        object.__setattr__(self, "shear_ratio", float(self.shear_ratio))
        object.__setattr__(self, "shear_direction", float(self.shear_direction))
        contacts = tuple(self.contacts)
        pairs = all(isinstance(pair, tuple) and len(pair) == 2 for pair in contacts)
        identities = [pair[0] if pairs else None for pair in contacts]
        numbers = all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and i >= 1
                      for i in identities)
        if not (pairs and numbers and identities == sorted(set(identities))
                and all(isinstance(q, Quantities) and len(q) == n for _, q in contacts)):
            raise ValueError(f"contacts must be (identity, Quantities of {n} frames) pairs by increasing "
                             f"identity from 1, got identities {identities}")
        object.__setattr__(self, "contacts", tuple((int(i), q) for i, q in contacts))
        refused = tuple(self.refused)
        if not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0 for k in refused):
            raise ValueError(f"refused must be frame numbers, got {shown(self.refused)}")
        object.__setattr__(self, "refused", tuple(int(k) for k in refused))

    def __len__(self) -> int:
        return self.frame.size

    @property
    def identities(self) -> tuple[int, ...]:
        """The followed contacts' identities, increasing."""
        return tuple(i for i, _ in self.contacts)

    def contact(self, identity: int) -> Quantities:
        """The quantities of contact ``identity`` over the frames (nan where it is absent).

        Raises
        ------
        KeyError
            When no contact of that identity is in the series.
        """
        for i, quantities in self.contacts:
            if i == identity:
                return quantities
        raise KeyError(f"no contact {identity!r} in the series (identities {list(self.identities)})")

    @property
    def complete(self) -> bool:
        """Every frame asked for is in (not a partial series)."""
        return len(self) == self.total

    def to_csv(self, path) -> Path:
        """Write the series as CSV (the module's format); returns the path.

        Raises
        ------
        OSError
            When the file cannot be written.
        """
        path = Path(path)
        # one header line per key: a line break in a label would end its line early
        header = [CSV_MARKER, f"source={' '.join(self.source.splitlines())}", f"kernel={self.kernel}",
                  f"mode={self.mode}"]
        if self.mode == "manual":
            header += [f"shear_ratio={self.shear_ratio!r}",
                       f"shear_direction_deg={math.degrees(self.shear_direction)!r}"]
        header += [f"frames={len(self)}", f"total={self.total}",
                   "units=t seconds; forces newtons; directions degrees from +x; centroid metres; "
                   "fz_error_pct in % of |truth Fz|; tangential_error_pct in % of |truth F|; "
                   "nan where a quantity is undefined"]
        names = ["frame", "t_s", *(name for name, _ in _COLUMNS)]
        columns = [self.frame.astype(float), self.t, *(getattr(self.estimate, q) * factor
                                                       for q, (_, factor) in zip(_QUANTITIES, _COLUMNS,
                                                                                 strict=True))]
        if self.truth is not None:
            names += [f"truth_{name}" for name, _ in _COLUMNS] + [name for name, _ in _ERROR_COLUMNS]
            columns += [getattr(self.truth, q) * factor for q, (_, factor) in zip(_QUANTITIES, _COLUMNS,
                                                                                  strict=True)]
            columns += [getattr(self.errors, f.name) * factor
                        for f, (_, factor) in zip(fields(TruthErrors), _ERROR_COLUMNS, strict=True)]
        for identity, quantities in self.contacts:
            names += [f"contact{identity}_{name}" for name, _ in _COLUMNS]
            columns += [getattr(quantities, q) * factor for q, (_, factor) in zip(_QUANTITIES, _COLUMNS,
                                                                                  strict=True)]
        table = np.column_stack(columns) if len(self) else np.zeros((0, len(names)))
        lines = [f"# {line}" for line in header] + [",".join(names)]
        lines += [",".join([str(int(row[0])), *(repr(float(v)) for v in row[1:])]) for row in table]
        with written_whole(path) as temporary:
            temporary.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return path

    @classmethod
    def from_csv(cls, path) -> Series:
        """Read a series written by :meth:`to_csv`.

        Raises
        ------
        ValueError
            Naming the file and what is wrong with it (not a series, a
            missing or unknown column, a value that is not a number).
        OSError
            When the file cannot be read.
        """
        path = Path(path)
        lines = path.read_text(encoding="utf-8").splitlines()
        if not lines or lines[0] != f"# {CSV_MARKER}":
            raise ValueError(f"{path}: not a time series of this viewer (its first line must be "
                             f"'# {CSV_MARKER}', got {lines[0][:60] if lines else 'an empty file'!r})")
        meta, rows, names = {}, [], None
        for number, line in enumerate(lines[1:], start=2):
            if line.startswith("#"):
                key, _, value = line[1:].strip().partition("=")
                meta[key] = value
            elif names is None:
                names = line.split(",")
            elif line.strip():
                try:
                    rows.append([float(value) for value in line.split(",")])
                except ValueError:
                    raise ValueError(f"{path}: line {number}: every value must be a number, got "
                                     f"{line[:80]!r}") from None
                if len(rows[-1]) != len(names):
                    raise ValueError(f"{path}: line {number}: {len(names)} values expected, got "
                                     f"{len(rows[-1])}")
        plain = ["frame", "t_s", *(name for name, _ in _COLUMNS)]
        with_truth = plain + [f"truth_{name}" for name, _ in _COLUMNS] + [name for name, _ in _ERROR_COLUMNS]
        names = names or []
        base = with_truth if names[:len(with_truth)] == with_truth else plain
        identities = _contact_columns(names[len(base):]) if names[:len(base)] == base else None
        if identities is None:
            raise ValueError(f"{path}: the columns must be {','.join(plain)} (and, with truth, "
                             f"{','.join(with_truth[len(plain):])}; then contact<N>_fz_N ... for each "
                             f"contact), got {names}")
        table = np.array(rows, dtype=float).reshape(len(rows), len(names))

        def quantities(offset):
            return Quantities(*(table[:, offset + i] / factor for i, (_, factor) in enumerate(_COLUMNS)))

        truth = errors = None
        contacts = tuple((identity, quantities(len(base) + k * len(_COLUMNS)))
                         for k, identity in enumerate(identities))
        if base == with_truth:
            truth = quantities(2 + len(_COLUMNS))
            errors = TruthErrors(*(table[:, 2 + 2 * len(_COLUMNS) + i] / factor
                                   for i, (_, factor) in enumerate(_ERROR_COLUMNS)))
        try:
            manual = meta.get("mode") == "manual"
            ratio = float(meta["shear_ratio"]) if manual else math.nan
            direction = math.radians(float(meta["shear_direction_deg"])) if manual else math.nan
            return cls(table[:, 0].astype(np.int64), table[:, 1], quantities(2), truth, errors,
                       kernel=meta.get("kernel", ""), mode=meta.get("mode", "auto"), shear_ratio=ratio,
                       shear_direction=direction, source=meta.get("source", ""),
                       total=int(meta.get("total", len(rows))), contacts=contacts)
        except (KeyError, ValueError) as exc:
            raise ValueError(f"{path}: damaged header: {exc}") from None


def _contact_columns(names) -> list[int] | None:
    # the identities of the contact<N>_... column groups, None when they are not such groups
    width, identities = len(_COLUMNS), []
    if len(names) % width:
        return None
    for start in range(0, len(names), width):
        prefix = names[start].removesuffix(_COLUMNS[0][0])
        number = prefix.removeprefix("contact").removesuffix("_")
        if not (number.isdigit() and int(number) >= 1 and prefix == f"contact{number}_"
                and names[start:start + width] == [prefix + name for name, _ in _COLUMNS]):
            return None
        identities.append(int(number))
    return identities if identities == sorted(set(identities)) else None


def _row(forces, centroid) -> tuple:
    # the six quantities of one frame's nodal forces (m, 3): one rule for estimate and truth
    return _totals(np.asarray(forces, dtype=float).sum(axis=0), centroid)


def _totals(total, centroid) -> tuple:
    # the six quantities of a resultant (Fx, Fy, Fz) and its load centroid (None: nothing presses)
    fx, fy, fz = (float(v) for v in total)
    tangential = math.hypot(fx, fy)
    if tangential > NO_TANGENTIAL * math.hypot(tangential, fz):
        direction = math.atan2(fy, fx)
        direction = math.pi if direction == -math.pi else direction  # (-pi, pi], as the solver's
    else:
        direction = math.nan
    ratio = tangential / fz if fz > 0 else math.nan
    cx, cy = (math.nan, math.nan) if centroid is None else (float(centroid[0]), float(centroid[1]))
    return float(fz), tangential, direction, ratio, cx, cy


class SeriesBuilder:
    """Rows of a :class:`Series` collected as frames are solved; a series of them at any time.

    Parameters
    ----------
    grid : SensorGrid
        The geometry the frames were solved on (the truth's centroid needs it).
    kernel, mode, source, shear_ratio, shear_direction
        As in :class:`Series`.
    truth : bool
        Rows carry true forces (:meth:`add` then needs them).
    total : int, optional
        Frames the complete series will hold (default: those added).
    span : float, optional
        Keep only the rows of the last ``span`` seconds (a live source's
        rolling window); default: keep every row.
    """

    def __init__(self, grid, *, kernel: str = "", mode: str = "auto", source: str = "", truth: bool = False,
                 shear_ratio: float = math.nan, shear_direction: float = math.nan, total: int | None = None,
                 span: float | None = None):
        one_of("mode", mode, MODES)
        if span is not None:
            real_number("span", span, rule="finite seconds > 0 (or None)", valid=lambda v: math.isfinite(v)
                        and v > 0)
        self.grid = grid
        self.truth = bool(truth)
        self.span = None if span is None else float(span)
        self._meta = dict(kernel=kernel, mode=mode, source=source, shear_ratio=shear_ratio,
                          shear_direction=shear_direction)
        self._total = total
        self._rows: deque = deque()
        self._contacts: deque = deque()  # per row: {identity: the contact's six quantities}
        self._refused: list[int] = []

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, solved: Solved, truth=None) -> None:
        """Add a solved frame (``solved.frame``, ``solved.time``, its forces and load centroid);
        the same frame (number and time) as the last one added replaces it.

        Its contacts that carry an identity (followed over frames: the model's
        results, :func:`compute_series`) add to their own series; contacts of
        identity 0 only to the totals.

        Parameters
        ----------
        solved : Solved
        truth : (m, 3) ndarray, optional
            The frame's true nodal forces, newtons (required when the builder
            was made with ``truth=True``, refused otherwise).
        """
        if self.truth != (truth is not None):
            raise ValueError("truth must be given for every frame of a series with truth and for no other, "
                             f"got {'none' if truth is None else 'forces'}")
        forces = solved.result.forces
        row = (solved.frame, solved.time, *_row(forces, solved.centroid))
        if truth is not None:
            truth = np.asarray(truth, dtype=float)
            if truth.shape != forces.shape:
                raise ValueError(f"truth must have shape {forces.shape}, got {truth.shape}")
            # the truth's centroid by the very rule of the one the scene draws (Solved.of)
            row += _row(truth, load_centroid(self.grid.positions, truth[:, 2]))
            row += (normal_total_error(forces, truth), tangential_total_error(forces, truth),
                    direction_error(forces, truth))
        contacts = {c.identity: _totals(c.total_force, centroid)
                    for c, centroid in zip(solved.result.contacts, solved.contact_centroids, strict=True)
                    if c.identity > 0}
        if self._rows and self._rows[-1][:2] == row[:2]:
            # the same frame solved again (new parameters on a quiet board): its row is replaced,
            # so the series never holds one time twice
            self._rows[-1], self._contacts[-1] = row, contacts
        else:
            self._rows.append(row)
            self._contacts.append(contacts)
        if self.span is not None:
            # a live source's rolling window: its clock only moves on, so the oldest rows go first
            while self._rows and self._rows[0][1] < solved.time - self.span:
                self._rows.popleft()
                self._contacts.popleft()

    def refuse(self, frame: int) -> None:
        """Count ``frame`` as refused by the solver: the complete series holds one frame fewer."""
        self._refused.append(int(frame))
        if self._total is not None:
            self._total -= 1

    def series(self) -> Series:
        """The rows so far as a :class:`Series`."""
        width = 2 + 6 + (6 + 3 if self.truth else 0)
        table = np.array(self._rows, dtype=float).reshape(len(self._rows), width)
        truth = Quantities(*table[:, 8:14].T) if self.truth else None
        errors = TruthErrors(*table[:, 14:17].T) if self.truth else None
        total = len(table) if self._total is None else max(self._total, len(table))
        identities = sorted({i for frame in self._contacts for i in frame})
        contacts = tuple((i, Quantities(*np.array([frame.get(i, _NOTHING) for frame in self._contacts],
                                                  dtype=float).reshape(-1, 6).T)) for i in identities)
        return Series(table[:, 0].astype(np.int64), table[:, 1], Quantities(*table[:, 2:8].T), truth, errors,
                      total=total, contacts=contacts, refused=tuple(self._refused), **self._meta)


def spread_frames(count: int, limit: int = MAX_FRAMES) -> np.ndarray:
    """Indices of at most ``limit`` frames of ``count``, evenly over the whole span (first and last in).

    Examples
    --------
    >>> spread_frames(5, 3).tolist()
    [0, 2, 4]
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ValueError(f"count must be a whole number >= 0, got {shown(count)}")
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 2:
        raise ValueError(f"limit must be a whole number >= 2, got {shown(limit)}")
    if count <= limit:
        return np.arange(count)
    return np.unique(np.round(np.linspace(0, count - 1, limit)).astype(np.int64))


def nearest_frame(t, x: float) -> int:
    """Index of the time in ``t`` (non-decreasing seconds) nearest to ``x`` (the earlier on a tie).

    Examples
    --------
    >>> nearest_frame([0.0, 0.1, 0.2], 0.14)
    1
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"t must be a non-empty 1-D array of seconds, got shape {t.shape}")
    x = real_number("x", x, rule="finite seconds", valid=math.isfinite)
    right = int(np.searchsorted(t, x))
    if right == 0:
        return 0
    if right == t.size:
        return t.size - 1
    return right if t[right] - x < x - t[right - 1] else right - 1


def compute_series(recording: Recording, solver, *, shear_ratio=None, shear_direction=None, frames=None,
                   progress=None, partial=None, every: float = 0.3, source: str = "") -> Series:
    """Solve a recording frame by frame (as the window's model does) and collect its time series.

    The contacts are followed over the frames solved, in order
    (:class:`solver.ContactTracker`), each with its own quantities in the
    series (:attr:`Series.contacts`).

    Parameters
    ----------
    recording : Recording
    solver : object
        What :meth:`tactile_viewer.model.viewer_model.ViewerModel.build` returns for the
        recording's geometry (``solve``, ``grid``, ``kernel``).
    shear_ratio, shear_direction : float or None, optional
        Given parameters (``shear_direction`` radians), as the sliders give
        them; both None (default): automatic, each frame's own.
    frames : (k,) array_like of int, optional
        The frames to solve, increasing; default every frame.
    progress : callable, optional
        ``progress(done, total) -> bool`` after each frame; returning False
        cancels (:class:`~tactile_viewer.model.worker.Cancelled` is raised).
    partial : callable, optional
        ``partial(series)``: the frames solved so far, at most every
        ``every`` seconds while solving (a partial :class:`Series`, ``total``
        the frames asked for). Called on the solving thread.
    every : float, optional
        Seconds between partial series. Default 0.3.
    source : str, optional
        The recording's file or label, for the series' header.

    Returns
    -------
    Series

    Raises
    ------
    ValueError
        Naming the argument that is wrong.
    Cancelled
        When ``progress`` returned False.
    """
    if not isinstance(recording, Recording):
        raise ValueError(f"recording must be a Recording, got {type(recording).__name__}")
    grid = getattr(solver, "grid", None)
    if not callable(getattr(solver, "solve", None)) or grid is None:
        raise ValueError(f"solver must have solve() and grid (as ViewerModel.build makes), got "
                         f"{type(solver).__name__}")
    if grid.key != recording.grid.key:
        raise ValueError("solver was built for another geometry than the recording's (its positions, pitch, "
                         "thickness, Poisson ratio or taxel size differ)")
    check_parameters(shear_ratio, shear_direction, None)
    count = len(recording)
    if frames is None:
        frames = np.arange(count)
    else:
        frames = np.asarray(frames)
        if frames.ndim != 1 or (frames.size and not np.issubdtype(frames.dtype, np.integer)):
            raise ValueError(f"frames must be a 1-D sequence of whole numbers, got dtype {frames.dtype} and "
                             f"shape {frames.shape}")
        if frames.size and (frames.min() < 0 or frames.max() >= count or np.any(np.diff(frames) <= 0)):
            raise ValueError(f"frames must be increasing indices in [0, {count - 1}], got "
                             f"{frames[:10].tolist()}{' ...' if frames.size > 10 else ''}")
    for name, value in (("progress", progress), ("partial", partial)):
        if value is not None and not callable(value):
            raise ValueError(f"{name} must be callable or None, got {shown(value)}")
    every = real_number("every", every, rule="finite seconds > 0", valid=lambda v: math.isfinite(v) and v > 0)
    auto = shear_ratio is None and shear_direction is None
    given = {} if auto else dict(shear_ratio=shear_ratio, shear_direction=shear_direction)
    truth = recording.truth_forces
    builder = SeriesBuilder(grid, kernel=getattr(solver, "kernel", ""), mode="auto" if auto else "manual",
                            source=source, truth=truth is not None, total=int(frames.size),
                            shear_ratio=math.nan if shear_ratio is None else shear_ratio,
                            shear_direction=math.nan if shear_direction is None else shear_direction)
    handed = time.perf_counter()
    tracker = ContactTracker(grid)
    for done, k in enumerate(frames.tolist(), start=1):
        stress = recording.frames[k]
        if not np.all(np.abs(stress) <= MAX_STRESS):
            # the solver would refuse it (the window says so when the frame is shown): one frame
            # must not cost the whole series
            builder.refuse(k)
        else:
            result = tracker.update(solver.solve(stress, **given))
            # Solved.of: the load centroid by the very rule of the frame the window draws
            builder.add(Solved.of(grid, stress, result, frame=k, time=float(recording.t[k]), auto=auto),
                        None if truth is None else truth[k])
        if progress is not None and progress(done, frames.size) is False:
            raise Cancelled(f"cancelled after {done} of {frames.size} frames")
        if partial is not None and done < frames.size and time.perf_counter() - handed >= every:
            partial(builder.series())
            handed = time.perf_counter()
    return builder.series()

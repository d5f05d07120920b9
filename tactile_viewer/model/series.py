"""The time series of a recording: total forces, shear and centroid over every frame. No Qt.

What the time plots draw and export: per frame the total normal force, the
size and direction of the total tangential force, their ratio and where the
compressive load is centred, of the reconstruction and, when the recording
carries its true forces, of the truth (computed from the truth forces by the
same functions) with the error figures of :mod:`solver.metrics`.

The data types (:class:`Quantities`, :class:`TruthErrors`, :class:`Series`)
and the series' CSV format: :meth:`Series.to_csv` and :meth:`Series.from_csv`
write and read it. Solving a recording into a series, or collecting one as
frames are solved, is :mod:`tactile_viewer.model.series_solving`.

Contacts followed over time: beside the totals, a series holds the same six
quantities of each contact (its resultant and its load centre) by its identity
(:class:`solver.ContactTracker`; nan on the frames it is absent from).
:func:`~tactile_viewer.model.series_solving.compute_series` follows the
contacts over the frames it solves, in order (a sampled long take is followed
over its samples); a live source's rows carry the identities the window's
model gave them.

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
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from solver.arrays import read_only
from solver.checks import one_of, shown

from ..io.recording import written_whole
from .solved import load_centroid

__all__ = ["Quantities", "TruthErrors", "Series", "frame_quantities", "resultant_quantities", "MODES",
           "CSV_MARKER"]

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
        :func:`~tactile_viewer.model.solved.load_centroid`, which
        :meth:`~tactile_viewer.model.solved.Solved.of`
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
        rows = [frame_quantities(frame, load_centroid(grid.positions, frame[:, 2])) for frame in forces]
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


def frame_quantities(forces, centroid) -> tuple:
    """The six quantities of one frame's nodal forces ``(m, 3)``: one rule for estimate and truth."""
    return resultant_quantities(np.asarray(forces, dtype=float).sum(axis=0), centroid)


def resultant_quantities(total, centroid) -> tuple:
    """The six quantities of a resultant ``(Fx, Fy, Fz)`` and its load centroid (None: nothing presses)."""
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



"""Solving a recording's time series, and collecting one as frames are solved. No Qt.

:func:`compute_series` solves a recording frame by frame as the window's
model would (automatic or given parameters), reports progress, can be
cancelled and hands out partial series while it runs; :class:`SeriesBuilder`
collects rows as frames are solved (a live source's rolling window);
:func:`spread_frames` picks the frames a long take is sampled at and
:func:`nearest_frame` the frame nearest to a time. What a series is and its
CSV format: :mod:`tactile_viewer.model.series`.

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
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np

from solver import ContactTracker
from solver.arguments import MAX_STRESS, check_parameters
from solver.checks import one_of, real_number, shown
from solver.metrics import direction_error, normal_total_error, tangential_total_error

from ..io.recording import Recording
from .series import MODES, Quantities, Series, TruthErrors, frame_quantities, resultant_quantities
from .solved import Solved, load_centroid
from .worker import Cancelled

__all__ = ["SeriesBuilder", "compute_series", "spread_frames", "nearest_frame", "MAX_FRAMES"]

MAX_FRAMES = 2000  # frames a series solves at most: a long take is sampled evenly over its whole span
_NOTHING = (math.nan,) * 6  # a contact's quantities on a frame it is absent from


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
        row = (solved.frame, solved.time, *frame_quantities(forces, solved.centroid))
        if truth is not None:
            truth = np.asarray(truth, dtype=float)
            if truth.shape != forces.shape:
                raise ValueError(f"truth must have shape {forces.shape}, got {truth.shape}")
            # the truth's centroid by the very rule of the one the scene draws (Solved.of)
            row += frame_quantities(truth, load_centroid(self.grid.positions, truth[:, 2]))
            row += (normal_total_error(forces, truth), tangential_total_error(forces, truth),
                    direction_error(forces, truth))
        contacts = {c.identity: resultant_quantities(c.total_force, centroid)
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

"""Force tables of solved frames: a recording's frames solved (or the frames the window solved) as a
:class:`~tactile_viewer.io.forces.ForceTable`, their contacts followed. No Qt."""

from __future__ import annotations

import numpy as np

from solver import ContactTracker, Reconstructor

from ..io.forces import ForceTable
from ..io.recording import Recording
from .worker import Cancelled

__all__ = ["reconstruct_frames", "force_table", "contact_arrays", "contact_records", "contact_slots",
           "CONTACT_FIELDS"]


def reconstruct_frames(recording: Recording, reconstructor: Reconstructor, frames=None, *,
                       shear_ratio=None, shear_direction=None, progress=None, refused=None) -> ForceTable:
    """Solve the given frames (default: all) with automatic or given parameters.

    The contacts are followed over the frames in the order given
    (:class:`solver.ContactTracker`): give them increasing for identities that
    mean the same contact over time.

    Parameters
    ----------
    progress : callable, optional
        ``progress(done, total) -> bool``; returning False cancels
        (:class:`Cancelled` is raised).
    refused : list, optional
        Given, a frame that cannot be read or that the solver refuses is left out of the
        table and appended to it as ``(frame, reason)``; default: the first one raises.
    """
    frames = np.arange(len(recording)) if frames is None else np.atleast_1d(np.asarray(frames, dtype=int))
    if frames.size and (frames.min() < 0 or frames.max() >= len(recording)):
        raise ValueError(f"frames must be in [0, {len(recording) - 1}], got {frames.tolist()}")
    results = []
    tracker = ContactTracker(recording.grid)  # the contacts numbered in the order the frames are solved
    solved = []
    for i, k in enumerate(frames):
        try:
            result = reconstructor.solve(recording.frames[k], shear_ratio=shear_ratio,
                                         shear_direction=shear_direction)
        except ValueError as exc:  # a damaged frame, or values the solver refuses (RecordingError is one)
            if refused is None:
                raise
            refused.append((int(k), str(exc)))
        else:
            results.append(tracker.update(result))
            solved.append(k)
        if progress is not None and progress(i + 1, frames.size) is False:
            raise Cancelled(f"cancelled after {i + 1} of {frames.size} frames")
    auto = shear_ratio is None and shear_direction is None
    frames = np.array(solved, dtype=int)
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
                      fallback=np.array([r.fallback for r in results], dtype=str),
                      forces=np.array([r.forces for r in results]).reshape(len(results), grid.size, 3),
                      frames=np.asarray(frames), t=np.asarray(t, dtype=float), positions=grid.positions,
                      shape=tuple(grid.shape), pitch=grid.pitch, thickness=grid.thickness,
                      kernel=solver.kernel, mode=mode, source=source,
                      # the material the forces were solved with, which is the solver's
                      poisson_ratio=solver.grid.poisson_ratio, sensor_size=solver.grid.sensor_size,
                      **{name: np.array([getattr(r, name) for r in results], dtype=float) for name in fields})


# one contact record: the row (frame) it is in, its identity, resultant (N) and centre (m)
CONTACT_FIELDS = ("row", "identity", "Fx", "Fy", "Fz", "x", "y")


def contact_records(contacts, row: int) -> np.ndarray:
    """``(len(contacts), 7)`` records of one frame's contacts (:data:`CONTACT_FIELDS`), float64."""
    return np.array([(row, c.identity, *c.total_force, *c.centre) for c in contacts],
                    dtype=np.float64).reshape(-1, len(CONTACT_FIELDS))


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
    records = [contact_records(r.contacts, row) for row, r in enumerate(results)]
    return contact_slots(np.concatenate(records) if records else np.empty((0, len(CONTACT_FIELDS))),
                         len(records))


def contact_slots(records: np.ndarray, frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arrays of :func:`contact_arrays` from contact records (:func:`contact_records`).

    Parameters
    ----------
    records : (N, 7) ndarray
        Every contact of ``frames`` frames, by frame and within a frame in the
        result's order; each record's row below ``frames``.
    frames : int
        ``T``.
    """
    row = records[:, 0].astype(np.int64)
    counts = np.bincount(row, minlength=frames)
    width = int(counts.max(initial=0))
    slot = np.arange(row.size) - np.repeat(np.cumsum(counts) - counts, counts)  # place within its frame
    identity = np.zeros((frames, width), np.int64)
    force = np.full((frames, width, 3), np.nan)
    centre = np.full((frames, width, 2), np.nan)
    identity[row, slot] = records[:, 1].astype(np.int64)
    force[row, slot] = records[:, 2:5]
    centre[row, slot] = records[:, 5:7]
    return identity, force, centre

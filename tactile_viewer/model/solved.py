"""One reconstructed frame as the viewer shows it: :class:`Solved`, its load centroid and its smoothing.

No Qt. :meth:`Solved.of` computes what the scene draws of a solver result (the
pressure map, the load centroids); :class:`ForceSmoothing` smooths the forces
drawn over the frames' time (``Display.smoothing``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from solver import Reconstruction, SensorGrid
from solver.arrays import read_only

__all__ = ["Solved", "ForceSmoothing", "load_centroid"]


@dataclass(frozen=True)
class Solved:
    """One reconstructed frame, how it was made, and what the scene shows of it.

    ``frame`` is the index in the recording, or for a live source the frame's
    sequence number (-1 for text frames, which carry none); ``time`` seconds.
    The scene draws these fields and computes no physics itself.

    Attributes
    ----------
    pressure : (m,) ndarray
        Reconstructed normal pressure ``Fz / pitch^2``, pascals.
    centroid : (2,) ndarray or None
        Where the compressive normal load is centred, metres (None when
        nothing presses).
    contact_centroids : tuple of (2,) ndarray
        Each contact's :attr:`solver.Contact.centre` (the solver's formula:
        its load's centre, its nodes' middle when nothing of it presses),
        metres, in the order of ``result.contacts``.
    drawn_forces : (m, 3) ndarray or None
        The node forces the scene draws, newtons, when they differ from
        ``result.forces`` (smoothed over time: :class:`ForceSmoothing`);
        ``pressure`` is then theirs too.

    The contacts of a result the model delivers carry their identities
    (``result.contacts[k].identity``, from 1: module notes); ``Solved.of``
    alone leaves them as the solver gave them.
    """

    frame: int
    time: float
    stress: np.ndarray
    result: Reconstruction
    solve_ms: float
    auto: bool
    pressure: np.ndarray
    centroid: np.ndarray | None
    contact_centroids: tuple = ()
    drawn_forces: np.ndarray | None = None

    @property
    def forces_drawn(self) -> np.ndarray:
        """``(m, 3)`` node forces as drawn: :attr:`drawn_forces`, else the result's."""
        return self.result.forces if self.drawn_forces is None else self.drawn_forces

    @classmethod
    def of(cls, grid: SensorGrid, stress, result: Reconstruction, *, frame: int = 0, time: float = 0.0,
           solve_ms: float = 0.0, auto: bool = True) -> Solved:
        """A solved frame of ``grid`` with its pressure map and load centroids."""
        forces = result.forces
        return cls(frame, time, np.asarray(stress, dtype=float), result, solve_ms, auto,
                   read_only(forces[:, 2] / grid.pitch**2), load_centroid(grid.positions, forces[:, 2]),
                   tuple(read_only(c.centre) for c in result.contacts))


class ForceSmoothing:
    """Exponential smoothing of the node forces drawn, over the frames' time. Qt-free.

    Each frame moves the drawn forces ``d`` towards the solved ones ``f`` by
    ``d += (1 - exp(-dt / tau)) * (f - d)``, ``dt`` the time since the frame
    before, so frames skipped by playback count by their time. A frame
    solved again (other parameters) is smoothed from where its first solve
    started; a frame before the last (a seek back) starts afresh.
    """

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self._key = self._time = self._base = self._value = None
        self._alpha = 1.0

    def __call__(self, solved: Solved, time_constant: float, pitch: float) -> Solved:
        """``solved`` with its drawn forces and pressure smoothed over ``time_constant`` s (0: itself)."""
        if time_constant <= 0:
            self.reset()
            return solved
        forces = solved.result.forces
        key = (solved.frame, solved.time)
        if key == self._key and self._base.shape == forces.shape:
            base, alpha = self._base, self._alpha  # the same frame solved again
        elif self._value is None or self._value.shape != forces.shape or solved.time < self._time:
            base, alpha = forces, 1.0  # nothing before it to smooth with
        else:
            base, alpha = self._value, -math.expm1(-(solved.time - self._time) / time_constant)
        value = read_only(base + alpha * (forces - base))
        self._key, self._time, self._base, self._alpha, self._value = key, solved.time, base, alpha, value
        return replace(solved, drawn_forces=value, pressure=read_only(value[:, 2] / pitch**2))


def load_centroid(positions, fz) -> np.ndarray | None:
    """Where a normal load presses, centred: the ``Fz``-weighted mean of ``positions`` over ``Fz > 0``.

    Parameters
    ----------
    positions : (m, 2) ndarray
        Node positions, metres.
    fz : (m,) ndarray
        Normal force per node, newtons (tension, ``Fz < 0``, is left out).

    Returns
    -------
    (2,) ndarray or None
        Read-only, metres; None when nothing presses.
    """
    push = np.clip(np.asarray(fz, dtype=float), 0.0, None)
    total = push.sum()
    return read_only(np.asarray(positions, dtype=float).T @ push / total) if total > 0 else None

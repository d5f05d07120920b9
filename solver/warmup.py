"""Compile the solver's numba core once, ahead of the first solve."""

from __future__ import annotations

import numpy as np

from .geometry import SensorGrid
from .inverse import DenseSolver
from .region import RegionSolver
from .seen_frame import noise_level

__all__ = ["warm_up"]


def warm_up():
    """Compile (or load from numba's cache) every path of the contact fit and the large-skin
    windows: about 14 s the first time after an install or a change to :mod:`solver.search`,
    0.2 to 0.8 s after. ``make`` runs it once when it installs; without it the first automatic solve
    pays."""
    grid = SensorGrid.regular(6, 6, 1e-3, 1e-3)
    x, y = grid.positions.T
    # one kernel serves all: every kernel's fit columns are read-only arrays of one kind
    solver = DenseSolver(grid, kernel="cell")
    stress = solver.matrix[:, 2 * grid.size:] @ (0.01 * np.exp(-(x ** 2 + y ** 2) / (2 * 1.5e-3 ** 2)))
    for parameters in ({}, dict(shear_ratio=0.2, shear_direction=0.3), dict(shear_direction=0.3),
                       dict(shear_ratio=0.2)):
        solver.solve(stress, **parameters)
    # frames read from a recording or a board are read-only: numba compiles for them apart
    recorded = stress.copy()
    recorded.setflags(write=False)
    solver.sibling().solve(recorded)  # a sibling: the solver itself would reuse the same bytes' frame
    # a pinch: two contacts sharing sensors, each shearing towards the other, both with evidence;
    # each one's own gain is refitted (ContactFit._shear_free_misfit), a path no single contact
    # takes (it cost the first two-contact frame 0.2 s after an install, 25 ms in each new process)
    wide = SensorGrid.regular(8, 8, 1e-3, 1e-3)
    x, y = wide.positions.T
    pinching = DenseSolver(wide, kernel="cell")
    left, right = (0.01 * np.exp(-((x - c) ** 2 + y ** 2) / (2 * 1e-3 ** 2)) for c in (-2e-3, 2e-3))
    pinch = pinching.matrix @ np.concatenate([0.3 * (left - right), np.zeros(wide.size), left + right])
    pinch.setflags(write=False)
    pinching.solve(pinch)
    RegionSolver(grid).windows(stress)  # the large-skin path's windows
    noise_level(stress, grid)  # read where a light load may be a contact (DenseSolver.faint_contacts)

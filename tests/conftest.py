"""Settings for every test: hypothesis draws the same examples on every run (derandomized), so CI
sees what a developer saw and a failure reproduces as it is; the compiled contact fit is ready
before the first test."""

import numpy as np
import pytest
from hypothesis import settings

from solver import Reconstructor, SensorGrid

settings.register_profile("repeatable", derandomize=True)
settings.load_profile("repeatable")


@pytest.fixture(scope="session", autouse=True)
def compiled_contact_fit():
    # numba compiles solver.search on its first call: seconds, once per checkout (then cached).
    # Done here, every path of the search, so that no test's timeout includes it.
    grid = SensorGrid.regular(6, 6, 1e-3, 1e-3)
    r = Reconstructor(grid, kernel="cell")
    x, y = grid.positions.T
    stress = r.matrix[:, 2 * grid.size:] @ (0.01 * np.exp(-(x ** 2 + y ** 2) / (2 * 1.5e-3 ** 2)))
    for parameters in ({}, dict(shear_ratio=0.2, shear_direction=0.3), dict(shear_direction=0.3),
                       dict(shear_ratio=0.2)):
        r.solve(stress, **parameters)

"""A dense solver on a 14x12 skin and a sheared contact on it, shared by the contact fit's tests."""

import math

import pytest

from solver import SensorGrid, loads
from solver.inverse import DenseSolver


@pytest.fixture(scope="module")
def reconstructor():
    return DenseSolver(SensorGrid.regular(14, 12, 2e-3, 2e-3))


@pytest.fixture(scope="module")
def sheared(reconstructor):
    # shear 0.4 towards 120 degrees, no noise
    contact = loads.hertz((0.5e-3, -0.3e-3), 5e-3, 1.0, shear_ratio=0.4, shear_direction=math.radians(120))
    return loads.simulate(reconstructor.grid, contact)

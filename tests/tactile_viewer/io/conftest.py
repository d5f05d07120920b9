"""Fixtures of the recording-format tests: a small recording that holds every field NPZ keeps."""

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.io.recording import Recording


@pytest.fixture
def recording():
    grid = SensorGrid.regular(3, 2, 2e-3, 1.5e-3)
    rng = np.random.default_rng(0)  # fixed seed
    frames = rng.normal(1e3, 200, size=(5, 6))
    truth = rng.normal(0, 0.1, size=(5, 6, 3))
    return Recording(grid, frames, np.arange(5) / 100, truth, "five frames")

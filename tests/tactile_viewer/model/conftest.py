"""Recordings the model's tests share (no Qt)."""

import numpy as np
import pytest

from solver import SensorGrid, loads
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.viewer_model import ViewerModel


@pytest.fixture(scope="module")
def skin():
    """A small skin, a recording of a press that moves and turns its shear (last frame unloaded)."""
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    rng = np.random.default_rng(7)
    frames, truth = [], []
    for k in range(6):
        contact = loads.hertz((1e-3 * (k - 2), 0.5e-3), 3e-3, 0.5 + 0.1 * k, shear_ratio=0.3,
                              shear_direction=0.6 * k)
        frame = loads.simulate(grid, [contact], noise=0.01, rng=rng)
        frames.append(frame.stress)
        truth.append(frame.forces)
    frames.append(np.zeros(grid.size))  # nothing presses: no centroid, no direction
    truth.append(np.zeros((grid.size, 3)))
    recording = Recording(grid, np.array(frames), np.arange(7) / 30.0, np.array(truth), "moving press")
    return recording, ViewerModel.build(grid, "layer")

"""Recordings and models the model's tests share (no Qt)."""

import numpy as np
import pytest

from solver import SensorGrid, loads
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.source import RecordingSource

PITCH, THICKNESS = 2e-3, 2e-3  # the sliding contact's skin


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


@pytest.fixture(scope="module")
def recording():
    """Four frames of a sheared Hertz contact sliding along x on a 6x5 skin, with their truth."""
    grid = SensorGrid.regular(6, 5, PITCH, THICKNESS)
    rng = np.random.default_rng(7)  # fixed seed: the sensor noise of all four frames
    frames = [loads.simulate(grid, loads.hertz((x, 0.3e-3), 3e-3, 1.0 + x / 1e-2, shear_ratio=0.4,
                                               shear_direction=0.5), noise=0.01, rng=rng)
              for x in (-2e-3, -0.5e-3, 1e-3, 2.5e-3)]
    return Recording(grid, [f.stress for f in frames], [0.0, 0.05, 0.1, 0.15],
                     truth_forces=[f.forces for f in frames], description="sliding contact")


@pytest.fixture(scope="module")
def reconstructor(recording):
    return ViewerModel.build(recording.grid, "layer")


@pytest.fixture
def model(recording, reconstructor):
    model = ViewerModel()
    model.set_source(RecordingSource(recording, "takes/sliding.npz"), reconstructor)
    return model

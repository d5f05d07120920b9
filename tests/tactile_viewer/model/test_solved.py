"""A solved frame as the viewer shows it (no Qt): its pressure map, its load centroid, its smoothing."""

import math
from dataclasses import replace

import numpy as np
import pytest

from tactile_viewer.model.solved import ForceSmoothing, Solved
from tests.tactile_viewer.model.conftest import PITCH


def test_solved_carries_the_pressure_map_and_the_load_centroid(model, recording, reconstructor):
    # the scene draws these; it computes no physics
    solved = model.solve()
    grid = recording.grid
    fz = solved.result.forces[:, 2]
    np.testing.assert_allclose(solved.pressure, fz / PITCH**2)
    push = np.clip(fz, 0, None)
    np.testing.assert_allclose(solved.centroid, grid.positions.T @ push / push.sum())
    assert -2e-3 - PITCH < solved.centroid[0] < -2e-3 + PITCH  # frame 0: the contact sits at x = -2 mm
    assert not solved.pressure.flags.writeable
    nothing = Solved.of(grid, np.zeros(grid.size), reconstructor.solve(np.zeros(grid.size)))
    assert nothing.centroid is None and not np.any(nothing.pressure)


# -- sources that push frames (a live board) -------------------------------------------------------

def test_smoothing_follows_a_step_with_the_lag_it_states(model):
    model.solve()
    base = model.last
    grid = model.reconstructor.grid
    smooth = ForceSmoothing()

    def at(time, level, frame=None):
        forces = np.zeros((grid.size, 3))
        forces[:, 2] = level
        frame = round(time * 100) if frame is None else frame
        return replace(base, frame=frame, time=time, result=replace(base.result, forces=forces))

    assert smooth(at(0.0, 0.0), 0.1, grid.pitch).forces_drawn[0, 2] == 0.0
    for k in range(1, 11):  # a step to 1 N at t = 0.01 s, frames every 0.01 s, tau 0.1 s
        drawn = smooth(at(k / 100, 1.0), 0.1, grid.pitch)
    assert drawn.forces_drawn[0, 2] == pytest.approx(1 - math.exp(-1))  # 63% after one time constant
    skipped = smooth(at(0.3, 1.0), 0.1, grid.pitch)  # playback skipped frames: their time counts
    assert skipped.forces_drawn[0, 2] == pytest.approx(1 - math.exp(-3))
    again = smooth(at(0.3, 0.5), 0.1, grid.pitch)  # the same frame solved again with other parameters
    # from where the frame's first solve started (63% at 0.1 s), 0.2 s towards 0.5 N
    assert again.forces_drawn[0, 2] == pytest.approx(0.5 + math.exp(-2) * ((1 - math.exp(-1)) - 0.5))
    back = smooth(at(0.05, 0.25), 0.1, grid.pitch)  # a seek back starts afresh
    assert back.forces_drawn[0, 2] == 0.25
    assert smooth(at(0.06, 0.7), 0.0, grid.pitch).drawn_forces is None  # off: the frame as solved

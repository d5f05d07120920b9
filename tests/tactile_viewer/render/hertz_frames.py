"""Frames the scene's tests draw: a sheared Hertz contact reconstructed on a regular and an irregular
layout, and what its arrows should be, recomputed from the forces rather than read back from the
scene's own arithmetic."""

import numpy as np

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.model.display import Display
from tactile_viewer.model.solved import Solved

MM = 1e3  # metres -> scene millimetres
PITCH, THICKNESS = 2e-3, 2e-3
WINDOW = (400, 300)
RATIO, DIRECTION = 0.4, 2.2  # shear pointing to -x, +y: a sign slip in either axis shows


def regular_grid():
    # nx != ny so that an x/y swap cannot pass
    return SensorGrid.regular(8, 6, PITCH, THICKNESS)


def staggered_grid():
    # every other row shifted by half a pitch, rows 0.9 pitch apart, each taxel jittered:
    # an irregular layout (shape (m,)) whose positions match no regular lattice
    rng = np.random.default_rng(7)  # fixed seed: the jitter of the taxels
    ix, iy = np.meshgrid(np.arange(7), np.arange(6))
    positions = np.column_stack([(ix + 0.5 * (iy % 2)).ravel(), 0.9 * iy.ravel()]) * PITCH
    positions = positions - positions.mean(axis=0) + rng.uniform(-0.15, 0.15, positions.shape) * PITCH
    return SensorGrid(positions, THICKNESS, PITCH, (len(positions),))


LAYOUTS = {"regular": regular_grid, "staggered": staggered_grid}


def reconstruct(grid):
    """Stress and the manual-parameter reconstruction of a sheared Hertz contact off the grid's nodes."""
    contact = loads.hertz((0.7e-3, -0.4e-3), 4e-3, 1.5, shear_ratio=RATIO, shear_direction=DIRECTION)
    # 1% noise gives every node a non-zero force, some pulling (Fz < 0): arrows in every direction
    # half-space data: compressive at every sensor (a bonded layer pulls slightly far away), which
    # test_auto_range_spans_zero_to_the_frame_maximum needs; the scene draws whatever it is given
    frame = loads.simulate(grid, contact, noise=0.01, rng=np.random.default_rng(7),  # fixed seed: the noise
                           medium="halfspace")
    result = Reconstructor(grid).solve(frame.stress, shear_ratio=RATIO, shear_direction=DIRECTION)
    return frame.stress, result



def show(scene, frame, display=None):
    grid, stress, result = frame
    scene.set_grid(grid)
    scene.update(Solved.of(grid, stress, result), display or Display(arrow_scale=0.02), render=False)
    return grid, stress, result


def split_arrows(scene):
    """Points (k, n, 3) and mN values (k, n) of the k drawn arrows, in arrow_nodes order."""
    count = len(scene.arrow_nodes)
    points = np.asarray(scene.arrows.points, dtype=float)
    assert count > 0 and points.shape[0] % count == 0, "every arrow must have the same number of points"
    values = np.asarray(scene.arrows.point_data["mN"], dtype=float)
    return points.reshape(count, -1, 3), values.reshape(count, -1)


def force_vectors(forces, scale):
    """Arrow vectors in mm: the force with z flipped (pressing into the skin points down)."""
    return np.column_stack([forces[:, 0], forces[:, 1], -forces[:, 2]]) * scale * MM


def surface_points(grid):
    return np.column_stack([grid.positions * MM, np.zeros(grid.size)])

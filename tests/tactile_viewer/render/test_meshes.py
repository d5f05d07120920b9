"""The scene's geometry as drawn: every arrow a uniform copy of its template, the axes' ticks beside the
skin, one number on each taxel (none on a skin too large to number)."""

import math

import numpy as np

from solver import Reconstruction, SensorGrid
from tactile_viewer.model.display import Display
from tactile_viewer.model.solved import Solved
from tactile_viewer.render.meshes import MAX_TAXEL_IDS
from tests.tactile_viewer.render.hertz_frames import (
    MM,
    PITCH,
    THICKNESS,
    force_vectors,
    show,
    split_arrows,
    surface_points,
)


def test_each_arrow_is_the_template_turned_and_scaled_uniformly(scene, regular_frame):
    # not sheared, squashed or mirrored (a mirrored copy would turn its faces inside out)
    display = Display(arrow_scale=0.02)
    grid, _, result = show(scene, regular_frame, display)
    points, _ = split_arrows(scene)
    template = scene._arrow_points  # the unit arrow along +x that every glyph copies
    assert np.isclose(template[:, 0].min(), 0.0) and np.isclose(template[:, 0].max(), 1.0)
    design = np.column_stack([template, np.ones(len(template))])
    vectors = force_vectors(result.forces, display.arrow_scale)
    tips = surface_points(grid)
    for k, node in enumerate(scene.arrow_nodes):
        fit, *_ = np.linalg.lstsq(design, points[k], rcond=None)
        np.testing.assert_allclose(design @ fit, points[k], rtol=0, atol=1e-9)  # exactly affine
        linear, start = fit[:3].T, fit[3]
        length = np.linalg.norm(vectors[node])
        np.testing.assert_allclose(linear @ [1.0, 0.0, 0.0], vectors[node], rtol=0, atol=1e-9)
        np.testing.assert_allclose(start, tips[node] - vectors[node], rtol=0, atol=1e-9)
        np.testing.assert_allclose(linear.T @ linear, length**2 * np.eye(3), rtol=0,
                                   atol=1e-9 * max(length**2, 1))
        assert np.linalg.det(linear) > 0


def test_axes_tick_the_skin_in_millimetres_beside_it(scene, frame):
    grid, stress, result = show(scene, frame)  # on by default
    actor = scene._actors["axes"]
    assert actor.GetVisibility()
    points = np.asarray(actor.mapper.dataset.points)
    p = grid.pitch * MM
    x0, y0 = grid.positions.min(axis=0) * MM - p / 2
    x1, y1 = grid.positions.max(axis=0) * MM + p / 2
    # flat in the surface's plane, just above it, and never over the skin (the map stays whole)
    assert np.ptp(points[:, 2]) == 0 and 0 < points[0, 2] < 0.05 * p
    inside = (points[:, 0] > x0 + 1e-9) & (points[:, 0] < x1 - 1e-9) & (points[:, 1] > y0 + 1e-9) \
        & (points[:, 1] < y1 - 1e-9)
    assert not inside.any()
    for axis, (low, high) in (("x", (x0, x1)), ("y", (y0, y1))):
        ticks = scene.ticks[axis]
        step = ticks[1] - ticks[0]
        mantissa = step / 10 ** np.floor(np.log10(step))
        assert any(np.isclose(mantissa, (1, 2, 5)))  # a round step
        np.testing.assert_allclose(ticks / step, np.round(ticks / step), atol=1e-9)
        assert 5 <= ticks.size <= 10 and low - 1e-9 <= ticks.min() and ticks.max() <= high + 1e-9
        assert ticks.min() - step < low and ticks.max() + step > high  # every tick that fits
        # a tick mark below the skin (x) or left of it (y) at each
        for tick in ticks:
            if axis == "x":
                near = (np.abs(points[:, 0] - tick) < 0.05 * p) & (points[:, 1] < y0)
            else:
                near = (np.abs(points[:, 1] - tick) < 0.05 * p) & (points[:, 0] < x0)
            assert near.any()
    scene.update(Solved.of(grid, stress, result), Display(axes=False), render=False)
    assert not actor.GetVisibility()


def test_taxel_numbers_one_on_each_taxel(scene, frame):
    grid, stress, result = show(scene, frame)
    assert "labels" not in scene._actors  # off by default, and not even built
    scene.update(Solved.of(grid, stress, result), Display(taxel_ids=True), render=False)
    actor = scene._actors["labels"]
    assert actor.GetVisibility()
    np.testing.assert_array_equal(scene.label_nodes, np.arange(grid.size))
    points, owner = np.asarray(scene._labels.points), scene._label_owner
    assert set(owner) == set(range(grid.size))  # one label per taxel
    p = grid.pitch * MM
    assert np.ptp(points[:, 2]) == 0 and scene._map.points[:, 2].max() < points[0, 2] < 0.05 * p
    widths, heights = np.zeros(grid.size), np.zeros(grid.size)
    for node in range(grid.size):
        mine = points[owner == node, :2]
        low, high = mine.min(axis=0), mine.max(axis=0)
        np.testing.assert_allclose((low + high) / 2, grid.positions[node] * MM, rtol=0, atol=0.08 * p)
        assert np.all(high - low < 0.96 * p)  # within its square
        widths[node] = high[0] - low[0]
        heights[node] = high[1] - low[1]
    # two digits are about twice as wide as one: the labels are the numbers, not one glyph
    assert 1.6 < np.median(widths[10:]) / np.median(widths[:10]) < 2.6
    # as tall as the widest number lets them be: they were 0.3 p, 4 px at 1280x800
    digits = len(str(grid.size - 1))
    assert np.median(heights) >= 0.9 * min(0.5 * p, 0.95 * p / (0.8 * digits)) > 0.35 * p
    # readable: dark numbers on the light squares, light numbers on the dark ones
    colours = np.asarray(scene._labels.point_data["rgb"])
    brightest, darkest = np.argmax(result.forces[:, 2]), np.argmin(result.forces[:, 2])
    assert np.all(colours[owner == brightest] == 0) and np.all(colours[owner == darkest] == 255)
    scene.update(Solved.of(grid, stress, result), Display(taxel_ids=False), render=False)
    assert not actor.GetVisibility()


def test_a_skin_too_large_to_number_gets_no_numbers(scene):
    side = int(np.ceil(np.sqrt(MAX_TAXEL_IDS + 1)))
    grid = SensorGrid.regular(side, side, PITCH, THICKNESS)
    assert grid.size > MAX_TAXEL_IDS
    m = grid.size
    result = Reconstruction(forces=np.zeros((m, 3)), shear_ratio=0.0, shear_direction=0.0, efficiency=math.nan,
                            residual=0.0, condition=1.0, regularized=False, normal_only=True,
                            shear_detected=False, region=np.zeros(m, bool))
    scene.set_grid(grid)
    scene.update(Solved.of(grid, np.zeros(m), result), Display(taxel_ids=True), render=False)
    assert scene.label_nodes.size == 0 and "labels" not in scene._actors

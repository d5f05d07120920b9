"""The 3-D scene on an off-screen plotter: arrows, threshold, map, resultant, rebuilding, views, screenshots.

Every frame is a real reconstruction of a simulated contact; the assertions are
the scene's defining geometry (millimetres, kPa, mN), recomputed here from the
forces rather than read back from the scene's own arithmetic.
"""

import struct
from dataclasses import replace

import numpy as np
import pytest
import pyvista as pv

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.model import Display, Solved
from tactile_viewer.scene import Scene

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


@pytest.fixture(scope="module", params=sorted(LAYOUTS))
def frame(request):
    """(grid, stress, reconstruction) for a regular and an irregular layout."""
    grid = LAYOUTS[request.param]()
    stress, result = reconstruct(grid)
    return grid, stress, result


@pytest.fixture(scope="module")
def regular_frame():
    grid = regular_grid()
    stress, result = reconstruct(grid)
    return grid, stress, result


@pytest.fixture
def plotter(no_plotter_leak):
    plotter = pv.Plotter(off_screen=True, window_size=list(WINDOW))
    yield plotter
    plotter.close()


@pytest.fixture
def scene(plotter):
    return Scene(plotter)


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


# -- arrows --------------------------------------------------------------------------------------

def test_each_arrow_ends_on_its_node_and_points_along_its_force(scene, frame):
    display = Display(arrow_scale=0.02)
    grid, _, result = show(scene, frame, display)
    magnitude = np.linalg.norm(result.forces, axis=1)
    # threshold 0 and a noisy frame: every node carries a force, so every node has an arrow
    assert np.all(magnitude > 0)
    np.testing.assert_array_equal(scene.arrow_nodes, np.arange(grid.size))
    points, _ = split_arrows(scene)
    vectors = force_vectors(result.forces, display.arrow_scale)
    tips = surface_points(grid)
    for k, node in enumerate(scene.arrow_nodes):
        length = np.linalg.norm(vectors[node])
        along = points[k] @ (vectors[node] / length)
        # the point farthest along the force is the tip, on the surface at the node
        np.testing.assert_allclose(points[k][np.argmax(along)], tips[node], rtol=0, atol=1e-9)
        # the arrow spans exactly |F| * arrow_scale mm along its force, ending at the tip
        np.testing.assert_allclose(np.ptp(along), length, rtol=1e-9)
        # and stays near its axis from tip - vector to tip (the template's tip radius is 0.12)
        relative = points[k] - tips[node]
        across = relative - np.outer(relative @ vectors[node] / length**2, vectors[node])
        assert np.linalg.norm(across, axis=1).max() <= 0.12 * length * (1 + 1e-9)
        assert np.linalg.norm(across, axis=1).max() >= 0.11 * length  # a real arrow head, not a line


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


def test_arrow_colours_are_the_force_in_millinewtons(scene, frame):
    _, _, result = show(scene, frame)
    _, values = split_arrows(scene)
    magnitude_mn = np.linalg.norm(result.forces, axis=1) * 1e3
    # every point of arrow k carries |F| of its node
    expected = np.repeat(magnitude_mn[scene.arrow_nodes, None], values.shape[1], axis=1)
    np.testing.assert_allclose(values, expected, rtol=1e-12)
    actor = scene._actors["arrows"]
    # what is drawn is scene.arrows, coloured by "mN" from 0 to the largest shown force
    assert actor.mapper.dataset is scene.arrows and actor.GetVisibility()
    assert scene.arrows.active_scalars_name == "mN"
    np.testing.assert_allclose(actor.mapper.scalar_range, (0.0, magnitude_mn.max()), rtol=1e-12)


def test_arrow_length_follows_the_display_scale(scene, regular_frame):
    grid, stress, result = regular_frame
    lengths = {}
    for scale in (0.01, 0.05):
        show(scene, regular_frame, Display(arrow_scale=scale))
        points, _ = split_arrows(scene)
        from_tip = points - surface_points(grid)[scene.arrow_nodes, None, :]
        lengths[scale] = np.linalg.norm(from_tip, axis=2).max(axis=1)
    # the farthest point of each arrow from its tip is about one length away: five times the scale,
    # five times the arrows (the base rim sits a hair further than the axis' start, in proportion)
    np.testing.assert_allclose(lengths[0.05], 5 * lengths[0.01], rtol=1e-9)
    expected = np.linalg.norm(result.forces, axis=1) * 0.01 * MM
    np.testing.assert_allclose(lengths[0.01], expected, rtol=0.02)


@pytest.mark.parametrize("quantile", [0.0, 0.3, 0.9])
def test_nodes_at_or_under_the_threshold_have_no_arrow(scene, regular_frame, quantile):
    _, _, result = regular_frame
    magnitude = np.linalg.norm(result.forces, axis=1)
    # a threshold equal to a node's own |F| hides that node too (the rule is |F| <= threshold)
    threshold = float(np.quantile(magnitude, quantile, method="nearest"))
    show(scene, regular_frame, Display(threshold=threshold))
    expected = np.flatnonzero(magnitude > threshold)
    assert magnitude.min() <= threshold  # at least the node at the threshold is hidden
    np.testing.assert_array_equal(scene.arrow_nodes, expected)
    points, _ = split_arrows(scene)
    assert points.shape[0] == expected.size
    assert scene.arrows.n_points == expected.size * len(scene._arrow_points)


def test_a_threshold_above_every_force_draws_no_arrow(scene, regular_frame):
    _, _, result = regular_frame
    show(scene, regular_frame, Display(threshold=float(np.linalg.norm(result.forces, axis=1).max())))
    assert scene.arrow_nodes.size == 0 and scene.arrows.n_points == 0
    assert not scene._actors["arrows"].GetVisibility() and not scene._bars["arrows"].GetVisibility()


def test_arrows_off_draws_none_and_on_again_draws_all(scene, regular_frame):
    grid, stress, result = show(scene, regular_frame, Display(arrows=False))
    assert scene.arrow_nodes.size == 0 and scene.arrows.n_points == 0
    assert not scene._actors["arrows"].GetVisibility()
    scene.update(Solved.of(grid, stress, result), Display(arrows=True), render=False)
    assert scene.arrow_nodes.size == grid.size and scene._actors["arrows"].GetVisibility()


# -- the map -------------------------------------------------------------------------------------

def test_pressure_map_is_normal_force_over_cell_area_in_kpa(scene, frame):
    grid, _, result = show(scene, frame, Display(map="pressure"))
    expected = result.forces[:, 2] / grid.pitch**2 / 1e3
    np.testing.assert_allclose(scene._map.cell_data["kPa"], expected, rtol=1e-12)
    assert scene._actors["map"].mapper.dataset is scene._map  # the data checked is the data drawn
    assert scene._actors["map"].GetVisibility() and scene._bars["map"].GetVisibility()
    assert scene._bars["map"].GetTitle() == "pressure kPa"


def test_stress_map_is_the_measured_stress_in_kpa(scene, frame):
    _, stress, _ = show(scene, frame, Display(map="stress"))
    np.testing.assert_allclose(scene._map.cell_data["kPa"], stress / 1e3, rtol=1e-12)
    assert scene._bars["map"].GetTitle() == "stress kPa"


def test_no_map_uncovers_the_layer_and_its_sensors(scene, regular_frame):
    show(scene, regular_frame, Display(map="none"))
    assert not scene._actors["map"].GetVisibility() and not scene._bars["map"].GetVisibility()
    assert scene._actors["layer_top"].GetVisibility() and scene._actors["sensors"].GetVisibility()
    show(scene, regular_frame, Display(map="pressure"))
    assert not scene._actors["layer_top"].GetVisibility()


def test_one_pitch_square_per_node_centred_on_it(scene, frame):
    # for the staggered layout this is one square per taxel, wherever the taxel is
    grid, _, _ = show(scene, frame)
    assert scene._map.n_cells == grid.size
    centres = scene._map.cell_centers().points
    np.testing.assert_allclose(centres[:, :2], grid.positions * MM, rtol=0, atol=1e-9)
    corners = np.asarray(scene._map.points).reshape(grid.size, 4, 3)
    np.testing.assert_allclose(np.ptp(corners[:, :, 0], axis=1), grid.pitch * MM, rtol=1e-9)
    np.testing.assert_allclose(np.ptp(corners[:, :, 1], axis=1), grid.pitch * MM, rtol=1e-9)
    # on the surface: just above z = 0 so the layer's top cannot hide it, far below a pitch
    assert np.all(corners[:, :, 2] > 0) and np.all(corners[:, :, 2] < 0.01 * grid.pitch * MM)


@pytest.mark.parametrize("kind", ["pressure", "stress"])
def test_auto_range_spans_zero_to_the_frame_maximum(scene, regular_frame, kind):
    grid, stress, result = show(scene, regular_frame, Display(map=kind, auto_range=True))
    values = stress / 1e3 if kind == "stress" else result.forces[:, 2] / grid.pitch**2 / 1e3
    # both sides of the rule: the reconstructed pressure dips below zero (the range must reach down
    # to it), the measured stress of this frame is positive everywhere (the range must start at 0)
    if kind == "pressure":
        assert values.min() < 0 < values.max()
    else:
        assert values.min() > 0
    expected = (min(values.min(), 0.0), values.max())
    np.testing.assert_allclose(scene._actors["map"].mapper.scalar_range, expected, rtol=1e-12)


def test_fixed_range_is_zero_to_range_max_in_kpa(scene, regular_frame):
    show(scene, regular_frame, Display(auto_range=False, range_max=12.5e3))
    np.testing.assert_allclose(scene._actors["map"].mapper.scalar_range, (0.0, 12.5))


# -- the resultant -------------------------------------------------------------------------------

def test_resultant_ends_on_the_compressive_centroid_along_the_total_force(scene, frame):
    display = Display(resultant_scale=0.005)
    grid, _, result = show(scene, frame, display)
    actor = scene._actors["resultant"]
    assert actor.GetVisibility()
    # the drawn mesh is the unit arrow from the origin to (1, 0, 0)
    bounds = actor.mapper.dataset.bounds
    np.testing.assert_allclose((bounds[0], bounds[1]), (0.0, 1.0), atol=1e-9)
    push = np.clip(result.forces[:, 2], 0, None)
    assert push.sum() > 0 and np.any(result.forces[:, 2] < 0)  # pulling nodes must not move the centroid
    centroid = np.append(grid.positions.T @ push / push.sum() * MM, 0.0)
    total = result.forces.sum(axis=0)
    vector = np.array([total[0], total[1], -total[2]]) * display.resultant_scale * MM
    matrix = np.asarray(actor.user_matrix)
    np.testing.assert_allclose(matrix @ [1.0, 0.0, 0.0, 1.0], np.append(centroid, 1.0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(matrix @ [0.0, 0.0, 0.0, 1.0], np.append(centroid - vector, 1.0), rtol=0,
                               atol=1e-9)
    # turned and scaled evenly: the arrow is not sheared
    linear = matrix[:3, :3]
    np.testing.assert_allclose(linear.T @ linear, vector @ vector * np.eye(3), rtol=0, atol=1e-9)
    assert np.linalg.det(linear) > 0


def test_resultant_hides_when_switched_off_and_returns(scene, regular_frame):
    grid, stress, result = show(scene, regular_frame, Display(resultant=False))
    assert not scene._actors["resultant"].GetVisibility()
    scene.update(Solved.of(grid, stress, result), Display(resultant=True), render=False)
    assert scene._actors["resultant"].GetVisibility()


# -- all-zero frames -----------------------------------------------------------------------------

def test_an_all_zero_frame_shows_no_arrow_and_no_resultant(scene, regular_frame):
    grid, _, _ = show(scene, regular_frame)  # arrows and resultant shown first: they must go away
    zero = np.zeros(grid.size)
    result = Reconstructor(grid).solve(zero)  # the automatic path, as the viewer runs it
    assert not np.any(result.forces)
    for kind in ("pressure", "stress"):
        scene.update(Solved.of(grid, zero, result), Display(map=kind), render=True)  # renders an empty arrow set
        assert scene.arrow_nodes.size == 0 and scene.arrows.n_points == 0
        assert not scene._actors["arrows"].GetVisibility()
        assert not scene._actors["resultant"].GetVisibility()
        np.testing.assert_array_equal(scene._map.cell_data["kPa"], 0.0)
        low, high = scene._actors["map"].mapper.scalar_range
        assert low == 0.0 and 0.0 < high < 1e-6  # a valid (non-empty) colour range


def test_a_first_frame_of_zeros_does_not_raise(scene):
    grid = regular_grid()
    scene.set_grid(grid)
    scene.update(Solved.of(grid, np.zeros(grid.size), Reconstructor(grid).solve_normal(np.zeros(grid.size))), Display())
    assert scene.arrows.n_points == 0 and not scene._actors["resultant"].GetVisibility()


# -- building and rebuilding ---------------------------------------------------------------------

def test_update_before_set_grid_raises(scene, regular_frame):
    grid, stress, result = regular_frame
    with pytest.raises(RuntimeError, match="set_grid must come before update"):
        scene.update(Solved.of(grid, stress, result), Display())


def test_a_second_grid_replaces_the_actors(scene, plotter, regular_frame):
    show(scene, regular_frame)
    first = dict(scene._actors)
    count, bars = len(plotter.renderer.actors), len(plotter.scalar_bars)
    small = SensorGrid.regular(3, 4, 3e-3, 1.5e-3)
    stress, result = reconstruct(small)
    for _ in range(2):  # and again: nothing piles up
        scene.set_grid(small)
        assert len(plotter.renderer.actors) == count and len(plotter.scalar_bars) == bars
    drawn = list(plotter.renderer.actors.values())
    assert not any(actor in drawn for actor in first.values())
    assert scene.grid is small and scene._map.n_cells == small.size
    scene.update(Solved.of(small, stress, result), Display())
    assert scene.arrow_nodes.max() < small.size and scene._map.cell_data["kPa"].shape == (small.size,)


def test_a_new_grid_starts_with_no_arrows(scene, regular_frame):
    # arrow_nodes must not keep the previous grid's node indices (past the new grid's size)
    show(scene, regular_frame)
    assert scene.arrow_nodes.size > 0
    scene.set_grid(SensorGrid.regular(3, 3, PITCH, THICKNESS))
    assert not scene._actors["arrows"].GetVisibility()
    assert scene.arrow_nodes.size == 0


# -- views and screenshots -----------------------------------------------------------------------

def test_camera_presets(scene, plotter, regular_frame):
    show(scene, regular_frame)
    scene.camera("top")
    np.testing.assert_allclose(plotter.camera.direction, (0.0, 0.0, -1.0), atol=1e-9)  # looking down
    scene.camera("iso")
    direction = np.asarray(plotter.camera.direction)
    assert direction[2] < 0 and np.hypot(direction[0], direction[1]) > 0.3  # from above and aside
    with pytest.raises(ValueError, match=r"camera preset must be 'top' or 'iso', got 'side'"):
        scene.camera("side")


def png_size(path):
    # width and height from the IHDR chunk, which every PNG starts with
    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n" and header[12:16] == b"IHDR"
    return struct.unpack(">II", header[16:24])


@pytest.mark.parametrize("scale", [1, 2])
def test_screenshot_is_scale_times_the_window(scene, regular_frame, tmp_path, scale):
    show(scene, regular_frame)
    path = tmp_path / "scene.png"
    image = scene.screenshot(path, scale=scale)
    assert png_size(path) == (WINDOW[0] * scale, WINDOW[1] * scale)
    assert image.shape[:2] == (WINDOW[1] * scale, WINDOW[0] * scale)
    assert image[..., :3].std() > 10  # the scene was drawn, not a flat background


@pytest.mark.parametrize("scale", [5, 0])
def test_screenshot_rejects_other_scales(scene, regular_frame, tmp_path, scale):
    show(scene, regular_frame)
    path = tmp_path / "scene.png"
    with pytest.raises(ValueError, match=rf"scale must be 1, 2, 3 or 4, got {scale}"):
        scene.screenshot(path, scale=scale)
    assert not path.exists()


def test_a_display_change_alone_redraws_the_same_forces(scene, regular_frame):
    # the window re-runs update with the last result when a display setting changes
    grid, stress, result = show(scene, regular_frame, Display(arrow_scale=0.02))
    before = np.array(scene.arrows.points, copy=True)
    scene.update(Solved.of(grid, stress, result), replace(Display(arrow_scale=0.02), map="stress"), render=False)
    np.testing.assert_array_equal(scene.arrows.points, before)

"""The simulated scenes (tactile_viewer/sources/simulated.py): their contacts and frames, the lazy cycle."""

import time
from types import SimpleNamespace

import numpy as np
import pytest

from solver import SensorGrid
from tactile_viewer.sources import simulated
from tactile_viewer.sources.simulated import SCENES, Cycle, contact_cycle, scene_contacts, scene_frame


def wait_for(condition, what, timeout=30.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


def fake_frames(monkeypatch, gate, *, stand_in=False):
    """Make the scene frames wait: frame ``k`` of a cycle of ``CYCLE`` is computed once ``gate(k)`` returns.

    The cache of cycles starts empty (and the test's cycles stay out of the real one). With
    ``stand_in``, frame ``k`` is not simulated (a tenth of a second each): its stress is ``k + 1``
    at every sensor, for tests of the threads that compute frames rather than of the frames.
    """
    real = simulated.scene_frame

    def gated(scene, grid, phase, **kwargs):
        k = round(phase * simulated.CYCLE)
        gate(k)
        if stand_in:
            return SimpleNamespace(clean_stress=np.full(grid.size, k + 1.0))
        return real(scene, grid, phase, **kwargs)

    monkeypatch.setattr(simulated, "scene_frame", gated)
    monkeypatch.setattr(simulated, "_CYCLES", {})  # no cycle computed or cached outside this test


# -- contact_cycle --------------------------------------------------------------------------------

def test_contact_cycle_circles_the_centre():
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    cycle = contact_cycle(grid, 8)
    assert cycle.shape == (8, 64) and np.all(np.isfinite(cycle))
    assert np.all(cycle.sum(axis=1) > 0)  # a press, every frame
    weights = np.clip(cycle, 0, None)
    centroids = weights @ grid.positions / weights.sum(axis=1, keepdims=True)
    # frame k is at angle 2 pi k / 8 around the centre: the centroid follows it round
    angles = np.arctan2(centroids[:, 1], centroids[:, 0])
    turned = np.angle(np.exp(1j * (angles - 2 * np.pi * np.arange(8) / 8)))
    assert np.abs(turned).max() < 0.2
    assert np.linalg.norm(centroids[0] - centroids[4]) > 2 * grid.pitch  # opposite sides: it moved
    assert np.all(np.linalg.norm(centroids, axis=1) > grid.pitch)  # never parked on the centre


# -- the lazy cycle -------------------------------------------------------------------------------

def test_a_cycle_computes_a_frame_when_it_is_first_asked_for():
    grid = SensorGrid.regular(3, 2, 2e-3, 2e-3)
    cycle = Cycle("circle", grid, 10)  # never started: no background thread
    assert len(cycle) == 10 and cycle.computed == 0 and not cycle.ready(0)
    first = cycle[0]
    assert cycle.computed == 1 and cycle.ready(0) and not cycle.ready(1)  # only the frame asked for
    np.testing.assert_array_equal(first, scene_frame("circle", grid, 0.0).clean_stress)
    assert cycle.peak(0) == np.abs(first).max() and cycle.computed == 1
    assert cycle[0] is first  # computed once
    # frames depend on their index only, not on the order they were computed in
    backwards = Cycle("circle", grid, 10)
    reversed_frames = [backwards[k] for k in reversed(range(10))][::-1]
    np.testing.assert_array_equal(cycle.array(), reversed_frames)
    np.testing.assert_array_equal(cycle[3], scene_frame("circle", grid, 0.3).clean_stress)
    assert cycle.computed == 10
    with pytest.raises(IndexError, match="frame 10 of a 10-frame cycle"):
        cycle[10]


def test_a_failing_frame_raises_where_it_is_asked_for_and_is_tried_again(monkeypatch):
    failing = {3}

    def gate(k):
        if k in failing:
            raise RuntimeError(f"frame {k} failed")
    fake_frames(monkeypatch, gate)
    cycle = Cycle("circle", SensorGrid.regular(3, 2, 2e-3, 2e-3)).start()
    with pytest.raises(RuntimeError, match="frame 3 failed"):
        cycle[3]
    failing.clear()
    assert np.all(np.isfinite(cycle[3])) and cycle.ready(3)
    cycle.close()


def test_cycles_are_shared_by_scene_and_everything_of_the_grid():
    grid = SensorGrid.regular(3, 2, 2e-3, 2e-3)
    cycle = simulated.shared_cycle("circle", grid)
    assert simulated.shared_cycle("circle", SensorGrid.regular(3, 2, 2e-3, 2e-3)) is cycle
    for other in (grid.replace(thickness=3e-3), grid.replace(poisson_ratio=0.45), grid.replace(sensor_size=1e-3),
                  SensorGrid.regular(2, 3, 2e-3, 2e-3)):
        assert simulated.shared_cycle("circle", other) is not cycle
    assert simulated.shared_cycle("twist", grid) is not cycle


def test_a_cycle_started_while_its_thread_is_stopping_computes_again(monkeypatch):
    fake_frames(monkeypatch, lambda k: time.sleep(0.03))
    # 10 frames (a layer frame takes about 0.2 s here): the stop lands on the first one all the same
    cycle = Cycle("circle", SensorGrid.regular(3, 2, 2e-3, 2e-3), 10).start()
    try:
        stopping = cycle._worker
        cycle.close(timeout=0)  # told to stop, still on its frame
        cycle.start()  # waits for it, then starts anew (once this did nothing, the stop flag left set)
        assert not stopping.is_alive() and cycle.computing
        wait_for(lambda: cycle.computed == len(cycle), "the cycle did not compute again after start()")
    finally:
        cycle.close()


# -- the scenes -----------------------------------------------------------------------------------

GRIDS = [(16, 16), (32, 32), (8, 8), (4, 4), (3, 2), (24, 8), (6, 20), (1, 1)]


@pytest.mark.parametrize("shape", GRIDS)
@pytest.mark.parametrize("scene", list(SCENES))
def test_every_scene_stays_on_the_skin(scene, shape):
    grid = SensorGrid.regular(*shape, 2e-3, 2e-3)
    low = grid.positions.min(axis=0) - grid.pitch / 2  # the node cells' rectangle
    high = grid.positions.max(axis=0) + grid.pitch / 2
    for k in range(0, 100, 2):
        for contact in scene_contacts(scene, grid, k / 100):
            assert contact.angle == 0  # so its support is the box of its semi-axes about its centre
            centre, axes = np.array(contact.center), np.array(contact.semi_axes)
            assert np.all(centre - axes >= low - 1e-12) and np.all(centre + axes <= high + 1e-12), (k, contact)


def contact_totals(frame, side):
    """Nodal truth summed over the nodes where ``side`` (a boolean per node) holds: (Fx, Fy, Fz)."""
    return frame.forces[side].sum(axis=0)


def test_pinch_two_contacts_approach_and_shear_towards_each_other():
    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3)
    assert SCENES["pinch"].period == 3.0
    gaps = []
    for k in range(0, 51, 5):  # from apart to closest, half the period
        left, right = scene_contacts("pinch", grid, k / 100)
        assert left.center[1] == right.center[1] == 0 and left.center[0] < 0 < right.center[0]
        assert left.force == right.force and left.shear_ratio == right.shear_ratio == 0.3
        gaps.append(right.center[0] - left.center[0] - left.semi_axes[0] - right.semi_axes[0])
        frame = scene_frame("pinch", grid, k / 100)
        x = grid.positions[:, 0]
        for side, towards in ((x < 0, 1.0), (x > 0, -1.0)):  # each contact's true force
            fx, fy, fz = contact_totals(frame, side)
            assert fz == pytest.approx(left.force, rel=1e-6)
            assert fx * towards == pytest.approx(0.3 * fz, rel=1e-6) and abs(fy) < 1e-9  # at the other
    assert np.all(np.diff(gaps) < 0) and gaps[0] > 3 * gaps[-1] > 0  # closing in, never touching
    # and parting again: the cycle repeats
    assert scene_contacts("pinch", grid, 0.0) == scene_contacts("pinch", grid, 1.0)
    # the data show the converging shear: compression between the two (beyond the normal loads')
    stress = scene_frame("pinch", grid, 0.5).clean_stress.reshape(16, 16)
    plain = simulated.loads.simulate(grid, [simulated.loads.hertz(c.center, c.semi_axes[0], c.force)
                                           for c in scene_contacts("pinch", grid, 0.5)],
                                     subdivisions=5).clean_stress.reshape(16, 16)
    middle = slice(7, 9)
    assert stress[:, middle].sum() > 1.05 * plain[:, middle].sum()


def test_pinch_runs_along_the_long_side_of_a_narrow_skin():
    grid = SensorGrid.regular(6, 20, 2e-3, 2e-3)
    first, second = scene_contacts("pinch", grid, 0.25)
    assert first.center[0] == second.center[0] == 0 and first.center[1] < second.center[1]
    assert first.shear_direction == pytest.approx(np.pi / 2) and second.shear_direction == pytest.approx(-np.pi / 2)


def paths(scene, grid, count=100):
    """``(count, contacts, 2)`` centres over one period, and the contacts of every step."""
    steps = [scene_contacts(scene, grid, k / count) for k in range(count)]
    return np.array([[c.center for c in contacts] for contacts in steps]), steps


def test_two_contacts_move_independently_on_distinct_paths_with_different_shears():
    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3)
    centres, steps = paths("two", grid)
    assert centres.shape == (100, 2, 2)
    radius = max(max(c.semi_axes) for c in steps[0])
    # distinct paths: every point of one at least two radii plus a pitch from every point of the other
    apart = np.linalg.norm(centres[:, None, 0] - centres[None, :, 1], axis=-1)
    assert apart.min() > 2 * radius + grid.pitch
    # both move, and not together (their displacements are not the same)
    moves = np.diff(centres, axis=0)
    assert np.all(np.linalg.norm(moves, axis=-1).sum(axis=0) > 5 * grid.pitch)
    assert np.abs(moves[:, 0] - moves[:, 1]).max() > 0.5 * grid.pitch / 10
    ratios = {round(c.shear_ratio, 3) for c in steps[0]}
    assert ratios == {0.3, 0.15}
    # the truth agrees: the left contact's tangential force is 0.3 of its normal force, the right one's 0.15
    frame = scene_frame("two", grid, 0.3)
    for side, ratio in ((grid.positions[:, 0] < 0, 0.3), (grid.positions[:, 0] > 0, 0.15)):
        fx, fy, fz = contact_totals(frame, side)
        assert np.hypot(fx, fy) == pytest.approx(ratio * fz, rel=1e-6)


def test_three_contacts_move_apart_from_each_other_with_different_shears():
    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3)
    centres, steps = paths("three", grid)
    assert centres.shape == (100, 3, 2)
    radius = max(max(c.semi_axes) for c in steps[0])
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert np.linalg.norm(centres[:, i] - centres[:, j], axis=-1).min() > 2 * radius  # never touching
        # distinct paths: no point of one is on the other's
        assert np.linalg.norm(centres[:, None, i] - centres[None, :, j], axis=-1).min() > 2 * radius
    travelled = np.linalg.norm(np.diff(centres, axis=0), axis=-1).sum(axis=0)
    assert np.all(travelled > 3 * grid.pitch)  # all three move
    assert [c.shear_ratio for c in steps[0]] == [0.3, 0.2, 0.0]
    directions = np.array([[c.shear_direction for c in contacts] for contacts in steps])
    assert np.ptp(directions[:, 0]) == 0 and np.ptp(np.unwrap(directions[:, 1])) > 6  # fixed; turning
    frame = scene_frame("three", grid, 0.0)
    assert frame.forces[:, 2].sum() == pytest.approx(sum(c.force for c in steps[0]), rel=1e-6)


def test_the_press_covers_most_of_the_skin_with_a_slowly_varying_force():
    for shape in ((16, 16), (32, 32)):
        grid = SensorGrid.regular(*shape, 2e-3, 2e-3)
        frame = scene_frame("press", grid, 0.25)  # full force
        (contact,) = frame.contacts
        skin = np.prod(np.ptp(grid.positions, axis=0) + grid.pitch)
        assert np.pi * np.prod(contact.semi_axes) / skin == pytest.approx(0.69, abs=0.01)  # the load's area
        loaded = frame.forces[:, 2] > 0
        assert 0.65 < loaded.mean() < 0.85  # the nodes whose cells carry some of it
        assert np.all(frame.forces[:, :2] == 0)  # no shear
        assert np.all(frame.clean_stress > 0)  # compression under every sensor
        assert (frame.clean_stress > 0.1 * frame.clean_stress.max()).mean() > 0.6  # and most sensors feel it
    forces = np.array([scene_contacts("press", grid, k / 100)[0].force for k in range(100)])
    assert forces.min() == pytest.approx(0.5 * forces.max(), rel=1e-3)  # from half to full force
    assert np.abs(np.diff(forces)).max() < 0.02 * forces.max()  # slow: under 2% a frame
    assert SCENES["press"].period == 6.0


def test_the_twist_has_torque_but_no_net_shear_and_the_sensors_cannot_see_it():
    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3)
    still = scene_frame("twist", grid, 0.0)  # no torque at the start of the period
    assert np.abs(still.forces[:, :2]).max() < 1e-12
    torques = []
    for phase in (0.25, 0.6, 0.75):
        frame = scene_frame("twist", grid, phase)
        (contact,) = frame.contacts
        assert contact.shear_ratio == 0 and contact.torsion != 0
        x, y = (grid.positions - contact.center).T
        fx, fy = frame.forces[:, 0], frame.forces[:, 1]
        torque = np.sum(x * fy - y * fx)
        torques.append(torque)
        assert torque == pytest.approx(contact.torsion, rel=0.01)
        assert np.hypot(fx, fy).sum() > 0.1 * frame.forces[:, 2].sum()  # plenty of tangential load ...
        assert np.hypot(fx.sum(), fy.sum()) < 1e-9 * np.hypot(fx, fy).sum()  # ... with no net force
        # torsion is invisible to normal-stress sensors: the stress is the untwisted press's
        np.testing.assert_allclose(frame.clean_stress, still.clean_stress, atol=1e-3 * still.clean_stress.max())
    assert torques[0] > 0 > torques[2]  # twisted back and forth


def test_every_scene_makes_a_cycle_of_finite_compressive_frames():
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    for name, scene in SCENES.items():
        cycle = contact_cycle(grid, 4, scene=name)
        assert cycle.shape == (4, 64) and np.all(np.isfinite(cycle)) and np.all(cycle.sum(axis=1) > 0), name
        assert scene.period > 0 and scene.summary

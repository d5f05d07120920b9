"""Per-contact window solves (solver/region.py) against full solves and finely integrated truth."""

import math

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads, metrics
from solver.region import RegionSolver

PITCH = 2e-3


@pytest.fixture(scope="module")
def skin():
    grid = SensorGrid.regular(16, 16, PITCH, PITCH)
    return grid, Reconstructor(grid), RegionSolver(grid)


def test_single_contacts_agree_with_the_full_solve(skin):
    grid, full, region = skin
    rng = np.random.default_rng(21)  # fixed seed: the same contacts and noise every run
    for _ in range(6):
        contact = loads.hertz((rng.uniform(-8e-3, 8e-3), rng.uniform(-8e-3, 8e-3)), 4e-3, 1.0,
                              shear_ratio=rng.choice([0.2, 0.4]), shear_direction=rng.uniform(-3, 3))
        frame = loads.simulate(grid, contact, noise=0.01, rng=rng)
        a, b = full.solve(frame.stress), region.solve(frame.stress)
        ea, eb = metrics.compare(a.forces, frame.forces), metrics.compare(b.forces, frame.forces)
        # equal within the noise level: the window drops only sensors that read noise
        assert abs(eb.normal_total - ea.normal_total) < 0.03
        assert abs(eb.tangential_total - ea.tangential_total) < 0.05
        assert len(b.contacts) == 1 and b.shear_ratio == b.contacts[0].result.shear_ratio


def test_clean_data_is_explained_inside_the_window(skin):
    grid, full, region = skin
    frame = loads.simulate(grid, loads.hertz((1e-3, -2e-3), 4e-3, 1.0, shear_ratio=0.3, shear_direction=1.0))
    result = region.solve(frame.stress)
    window = result.contacts[0]
    rows, columns = window.window
    stress = frame.stress.reshape(grid.shape)
    # C x = b on the window's sensors
    solver = region.reconstructor(*stress[rows, columns].shape)
    x = result.forces.reshape(grid.shape + (3,))[rows, columns].reshape(-1, 3)
    np.testing.assert_allclose(solver.matrix @ x.T.ravel(), stress[rows, columns].ravel(),
                               atol=1e-9 * stress.max())
    outside = np.ones(grid.shape, bool)
    outside[rows, columns] = False
    # what the window leaves out is the tail of the stress spread
    assert np.abs(stress[outside]).max() < 0.05 * stress.max()
    assert result.residual < 0.05
    e = metrics.compare(result.forces, frame.forces)
    assert e.normal_total < 0.01 and e.direction_deg < 10


def window_of(result, grid, centre):
    """The contact whose window holds the node nearest ``centre`` (metres)."""
    node = int(np.argmin(np.linalg.norm(grid.positions - np.asarray(centre), axis=1)))
    row, column = divmod(node, grid.shape[1])
    (found,) = [c for c in result.contacts if c.window[0].start <= row < c.window[0].stop
                and c.window[1].start <= column < c.window[1].stop]
    return found


@pytest.mark.parametrize("count", [2, 3])
def test_several_contacts_each_get_their_own_shear(count):
    grid = SensorGrid.regular(40, 40, PITCH, PITCH)
    region = RegionSolver(grid)
    rng = np.random.default_rng(30 + count)  # fixed seed: the same scenes every run
    centres = [(-20e-3, -20e-3), (20e-3, 20e-3), (20e-3, -20e-3)][:count]
    normal, tangential, direction = [], [], []
    for _ in range(4):
        # as the standard accuracy set: radius 2.5 pitches, 1 N each, 1% noise of the peak
        contacts = [loads.hertz(c, 2.5 * PITCH, 1.0, shear_ratio=rng.choice([0.2, 0.4]),
                                shear_direction=rng.uniform(-math.pi, math.pi)) for c in centres]
        frame = loads.simulate(grid, contacts, noise=0.01, rng=rng)
        result = region.solve(frame.stress)
        assert len(result.contacts) == count
        for centre, contact in zip(centres, contacts, strict=True):
            # each contact against its own truth, inside its own window
            rows, columns = window_of(result, grid, centre).window
            truth = loads.simulate(grid, contact).forces.reshape(grid.shape + (3,))[rows, columns]
            found = result.forces.reshape(grid.shape + (3,))[rows, columns]
            e = metrics.compare(found.reshape(-1, 3), truth.reshape(-1, 3))
            normal.append(e.normal_total)
            tangential.append(e.tangential_total)
            direction.append(e.direction_deg)
    # the solver issue's bars, per contact
    assert np.median(normal) <= 0.03 and np.median(tangential) <= 0.12 and np.median(direction) <= 15


def test_shear_free_loads_get_the_full_solves_answer():
    # The window changes no decision of the efficiency functional: where the full
    # solve finds no shear, neither does the window (and where it does, both do).
    grid = SensorGrid.regular(20, 20, PITCH, PITCH)
    region, full = RegionSolver(grid), Reconstructor(grid)
    rng = np.random.default_rng(44)  # fixed seed
    for shape in (loads.hertz, loads.cone):
        for _ in range(4):
            frame = loads.simulate(grid, shape((rng.uniform(-6e-3, 6e-3), 0.0), 4e-3, 1.0), noise=0.01, rng=rng)
            a, b = region.solve(frame.stress), full.solve(frame.stress)
            assert a.shear_detected == b.shear_detected
            assert a.shear_ratio == pytest.approx(b.shear_ratio, abs=0.03)
    clean = loads.simulate(grid, loads.hertz((1e-3, 2e-3), 4e-3, 1.0))
    assert not region.solve(clean.stress).shear_detected


def test_windows_merge_clip_and_round(skin):
    grid, _, region = skin
    near = loads.simulate(grid, [loads.hertz((-3e-3, 0.0), 2.5e-3, 1.0), loads.hertz((3e-3, 0.0), 2.5e-3, 1.0)])
    assert len(region.windows(near.stress)) == 1  # overlapping windows: one interacting scene
    corner = loads.simulate(grid, loads.hertz((-15e-3, -15e-3), 3e-3, 1.0))
    (rows, columns), = region.windows(corner.stress)
    assert rows.start == 0 and columns.start == 0  # clipped at the skin's edge, not beyond
    for window in region.windows(corner.stress) + region.windows(near.stress):
        for side in window:
            assert (side.stop - side.start) % region.step == 0 or side.stop - side.start == 16
    assert region.windows(np.zeros(grid.size)) == []
    assert region.windows(-np.ones(grid.size)) == []


def test_a_moving_contact_reuses_its_factorizations():
    grid = SensorGrid.regular(64, 64, PITCH, PITCH)
    region = RegionSolver(grid)
    for k in range(12):
        angle = k / 2
        frame = loads.simulate(grid, loads.hertz((20e-3 * math.cos(angle), 20e-3 * math.sin(angle)), 4e-3, 1.0,
                                                 shear_ratio=0.3, shear_direction=angle))
        result = region.solve(frame.stress)
        assert metrics.compare(result.forces, frame.forces).normal_total < 0.02
    assert region.factorizations <= 2  # one window shape (or two at the rounding edge) for 12 frames


def test_a_large_skin_never_forms_its_full_matrix():
    grid = SensorGrid.regular(128, 128, PITCH, PITCH)
    region = RegionSolver(grid)
    frame = loads.simulate(grid, loads.hertz((5e-3, -7e-3), 5e-3, 1.0, shear_ratio=0.3, shear_direction=0.5))
    result = region.solve(frame.stress)
    assert result.forces.shape == (grid.size, 3)
    assert all(r.grid.size <= 32 * 32 for r in region._cache.values())
    e = metrics.compare(result.forces, frame.forces)
    assert e.normal_total < 0.01 and e.tangential_total < 0.05 and e.direction_deg < 5


def test_given_parameters_apply_to_every_contact():
    grid = SensorGrid.regular(32, 32, PITCH, PITCH)
    region = RegionSolver(grid)
    frame = loads.simulate(grid, [loads.hertz((-16e-3, -16e-3), 2.5e-3, 1.0),
                                  loads.hertz((16e-3, 16e-3), 2.5e-3, 1.0)])
    result = region.solve(frame.stress, shear_ratio=0.25, shear_direction=-1.0)
    assert len(result.contacts) == 2
    for contact in result.contacts:
        assert contact.result.shear_ratio == pytest.approx(0.25)
        assert contact.result.shear_direction == pytest.approx(-1.0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(threshold=0.0), r"threshold must be in \(0, 1\), got 0.0"),
    (dict(spread=-1.0), "spread must be finite and >= 0, got -1.0"),
    (dict(step=0), "step must be a whole number >= 1, got 0"),
    (dict(cache=1.5), "cache must be a whole number >= 1, got 1.5"),
    (dict(kernel="exact"), "kernel must be one of"),
])
def test_bad_options_say_what_is_wrong(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RegionSolver(SensorGrid.regular(4, 4, PITCH, PITCH), **kwargs)


def test_irregular_grids_and_bad_stress_are_rejected(skin):
    grid, _, region = skin
    irregular = SensorGrid(np.random.default_rng(0).random((5, 2)) * 1e-2, PITCH, PITCH, (5,))  # fixed seed
    with pytest.raises(ValueError, match="grid must be a regular SensorGrid"):
        RegionSolver(irregular)
    with pytest.raises(ValueError, match=r"stress must be finite, got NaN"):
        region.solve(np.full(grid.size, np.nan))
    with pytest.raises(ValueError, match=r"stress must have shape .* got \(3,\)"):
        region.solve(np.ones(3))

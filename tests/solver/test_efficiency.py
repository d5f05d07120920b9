"""Efficiency functionals and the contact region they look at."""

import math

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from solver.efficiency import Admissibility, ContactFit, Frame, NoShear


@pytest.fixture(scope="module")
def reconstructor():
    return Reconstructor(SensorGrid.regular(14, 12, 2e-3, 2e-3))


@pytest.fixture(scope="module")
def sheared(reconstructor):
    # shear 0.4 towards 120 degrees, no noise
    contact = loads.hertz((0.5e-3, -0.3e-3), 5e-3, 1.0, shear_ratio=0.4, shear_direction=math.radians(120))
    return loads.simulate(reconstructor.grid, contact)


def test_regular_region_equals_the_general_graph_path(reconstructor, sheared):
    grid = reconstructor.grid
    irregular = SensorGrid(grid.positions, grid.thickness, grid.pitch, (grid.size,))
    general = Reconstructor(irregular)
    assert general._disk is None and reconstructor._disk is not None
    rng = np.random.default_rng(8)  # fixed seed
    for noise in (0.0, 0.02, 0.1):
        b = sheared.stress + rng.normal(0, noise * sheared.stress.max(), grid.size)
        normal = reconstructor.solve_normal(b).forces[:, 2]
        np.testing.assert_array_equal(reconstructor.contact_region(normal), general.contact_region(normal))


def test_region_holds_the_contact_and_drops_isolated_spikes(reconstructor, sheared):
    normal = reconstructor.solve_normal(sheared.stress).forces[:, 2].copy()
    region = reconstructor.contact_region(normal)
    assert region[sheared.forces[:, 2] > 0.05 * sheared.forces[:, 2].max()].all()
    # a lone spike far from the contact, at 25% of the peak but carrying 1% of the force
    spike = normal.copy()
    spike[0] = 0.25 * normal.max()
    assert not reconstructor.contact_region(spike)[0]
    assert not reconstructor.contact_region(np.full(reconstructor.grid.size, -1.0)).any()


def test_contact_fit_finds_free_direction_or_free_ratio(reconstructor, sheared):
    direction = reconstructor.solve(sheared.stress, shear_ratio=0.4)
    assert math.degrees(direction.shear_direction) == pytest.approx(120, abs=4)
    ratio = reconstructor.solve(sheared.stress, shear_direction=math.radians(120))
    assert ratio.shear_ratio == pytest.approx(0.4, abs=0.06)
    both = reconstructor.solve(sheared.stress)
    assert both.shear_detected
    assert both.shear_ratio == pytest.approx(0.4, abs=0.06)
    assert both.efficiency > reconstructor.solve(sheared.stress, shear_ratio=0.0,
                                                 shear_direction=0.0).efficiency


def test_gram_kept_or_formed_per_frame_give_the_same_fit(reconstructor, sheared):
    frame = reconstructor._frame(np.asarray(sheared.stress))
    assert frame.gram is not None
    fresh = Frame(stress=frame.stress, normal=frame.normal, region=frame.region, matrix=frame.matrix,
                  max_shear_ratio=frame.max_shear_ratio)
    fit = ContactFit()
    g1, rho1 = fit.fit(frame, 0.1, -0.2)
    g2, rho2 = fit.fit(fresh, 0.1, -0.2)
    np.testing.assert_allclose(g1, g2, rtol=1e-8, atol=1e-12)
    assert rho1 == pytest.approx(rho2, rel=1e-8)
    # rho is the true squared residual of the template fit
    cx, cy, cz = (frame.matrix[:, k * frame.stress.size + frame.region_index] for k in range(3))
    direct = np.sum(((cz + 0.1 * cx - 0.2 * cy) @ g1 - frame.stress) ** 2)
    assert rho1 == pytest.approx(direct, rel=1e-6)


def test_alternative_functionals_plug_in(sheared):
    grid = sheared.grid
    none = Reconstructor(grid, efficiency=NoShear()).solve(sheared.stress)
    assert none.shear_ratio == 0 and not none.shear_detected
    admissible = Reconstructor(grid, efficiency=Admissibility(ratios=7, directions=12)).solve(sheared.stress)
    assert np.isfinite(admissible.forces).all() and admissible.residual < 1e-9


@pytest.mark.parametrize("kwargs, message", [
    (dict(significance=-1), "significance must be finite and >= 0, got -1"),
    (dict(max_iterations=-2), "max_iterations must be >= 0, got -2"),
    (dict(tolerance=0), "tolerance must be > 0, got 0"),
])
def test_contact_fit_checks_its_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ContactFit(**kwargs)


@pytest.mark.parametrize("kwargs, message", [
    (dict(region_threshold=1.5), r"region_threshold must be in \(0, 1\), got 1.5"),
    (dict(region_margin=-1), "region_margin must be a whole number of pitches >= 0, got -1"),
    (dict(region_margin=1.5), "region_margin must be a whole number of pitches >= 0, got 1.5"),
])
def test_region_settings_are_checked(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Reconstructor(SensorGrid.regular(3, 3, 1e-3, 1e-3), **kwargs)

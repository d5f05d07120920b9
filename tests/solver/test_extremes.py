"""Numerical stability at the extremes: thickness, force scale, degenerate frames and grids."""

import math
import warnings

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads

KERNELS = ["cell", "point"]


def hertz_frame(grid, force=1.0, noise=0.0, **kw):
    # a 5 mm Hertzian contact near the middle, shear 0.3 towards 57 degrees
    contact = loads.hertz((0.3e-3, 0.2e-3), 5e-3, force, shear_ratio=0.3, shear_direction=1.0, **kw)
    return loads.simulate(grid, contact, noise=noise, rng=1)  # fixed seed


@pytest.fixture(autouse=True)
def no_warnings():
    # nothing here may divide by zero or overflow quietly
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


@pytest.mark.parametrize("kernel", KERNELS)
def test_thickness_from_005_to_10_pitches(kernel):
    conditions = []
    for ratio in (0.05, 0.3, 1.0, 3.0, 5.0, 10.0):
        grid = SensorGrid.regular(12, 12, 2e-3, ratio * 2e-3)
        frame = hertz_frame(grid, noise=0.01)
        r = Reconstructor(grid, kernel=kernel)
        auto, normal = r.solve(frame.stress), r.solve_normal(frame.stress)
        for result in (auto, normal):
            assert np.isfinite(result.forces).all()
            assert math.isfinite(result.condition) and result.condition >= 1
        conditions.append(auto.condition)
        # thin layers solve undamped, thick ones are damped and say so
        assert auto.regularized == (ratio >= 3.0) and normal.regularized == (ratio >= 3.0)
        if kernel == "cell" or ratio >= 1.0:
            # damping keeps the forces bounded: at most a few times the load (measured <= 4.5x)
            assert np.abs(auto.forces).sum() < 10 * 1.3
            assert np.abs(normal.forces).sum() < 10 * 1.3
    assert conditions[:4] == sorted(conditions[:4])
    # the damping caps the (1-norm) condition of C C^T at about sqrt(m) max_condition^2
    assert max(conditions) <= 1.01 * 12 * 100.0**2


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("scale", [1e-6, 1e-3, 1.0, 1e3])
def test_results_scale_linearly_with_the_load(kernel, scale):
    grid = SensorGrid.regular(10, 10, 2e-3, 2e-3)
    r = Reconstructor(grid, kernel=kernel)
    reference = hertz_frame(grid, noise=0.01).stress
    for solve in (lambda b: r.solve(b), lambda b: r.solve(b, shear_ratio=0.3, shear_direction=1.0),
                  lambda b: r.solve_normal(b)):
        one, scaled = solve(reference), solve(reference * scale)
        np.testing.assert_allclose(scaled.forces / scale, one.forces, rtol=0,
                                   atol=1e-6 * np.abs(one.forces).max())
        assert scaled.shear_ratio == pytest.approx(one.shear_ratio, abs=1e-6)


@pytest.mark.parametrize("kernel", KERNELS)
def test_all_zero_frame(kernel):
    r = Reconstructor(SensorGrid.regular(8, 8, 2e-3, 2e-3), kernel=kernel)
    zero = np.zeros(64)
    for result in (r.solve(zero), r.solve_normal(zero), r.solve(zero, shear_ratio=0.5, shear_direction=1)):
        assert np.all(result.forces == 0)
        assert result.residual == 0
    auto = r.solve(zero)
    assert auto.efficiency == 1.0 and auto.shear_ratio == 0 and not auto.region.any()


@pytest.mark.parametrize("kernel", KERNELS)
def test_all_negative_frame(kernel):
    r = Reconstructor(SensorGrid.regular(8, 8, 2e-3, 2e-3), kernel=kernel)
    tension = -np.linspace(100, 300, 64)
    result = r.solve(tension)
    assert np.isfinite(result.forces).all()
    # no compressive contact anywhere: no template, the minimum-norm exact solution remains
    assert not result.region.any() and result.shear_ratio == 0
    assert result.total_force[2] < 0 and result.residual < 1e-10


@pytest.mark.parametrize("kernel", KERNELS)
def test_one_hot_taxel(kernel):
    r = Reconstructor(SensorGrid.regular(9, 9, 2e-3, 2e-3), kernel=kernel)
    hot = np.zeros(81)
    hot[40] = 5e3
    result = r.solve(hot)
    assert np.isfinite(result.forces).all()
    x = result.forces.T.ravel()
    np.testing.assert_allclose(r.matrix @ x, hot, atol=1e-9 * 5e3)


@pytest.mark.parametrize("center", [(15e-3, 0.0), (15e-3, 15e-3)], ids=["edge", "corner"])
def test_contact_on_an_edge_and_in_a_corner(center):
    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3)  # skin spans -16 mm .. 16 mm
    frame = loads.simulate(grid, loads.hertz(center, 4e-3, 1.0, shear_ratio=0.2), noise=0.01, rng=3)
    on_skin = frame.forces[:, 2].sum()
    result = Reconstructor(grid).solve(frame.stress)
    assert np.isfinite(result.forces).all()
    # the sensors near the edge see only part of the load: measured within 15% of what is on the skin
    assert result.total_force[2] == pytest.approx(on_skin, rel=0.15)


@pytest.mark.parametrize("nx, ny", [(1, 1), (1, 7), (7, 1)])
@pytest.mark.parametrize("kernel", KERNELS)
def test_tiny_grids(nx, ny, kernel):
    grid = SensorGrid.regular(nx, ny, 2e-3, 2e-3)
    r = Reconstructor(grid, kernel=kernel)
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0))
    for result in (r.solve(frame.stress), r.solve_normal(frame.stress),
                   r.solve(frame.stress, shear_ratio=0.4, shear_direction=-2.0)):
        assert result.forces.shape == (grid.size, 3)
        assert np.isfinite(result.forces).all()
        assert result.residual < 1e-9


@pytest.mark.parametrize("kernel", KERNELS)
def test_parameters_at_their_extremes(kernel):
    grid = SensorGrid.regular(10, 10, 2e-3, 2e-3)
    r = Reconstructor(grid, kernel=kernel)
    b = hertz_frame(grid, noise=0.01).stress
    plus, minus = r.solve(b, shear_ratio=0.3, shear_direction=math.pi), r.solve(b, shear_ratio=0.3,
                                                                                  shear_direction=-math.pi)
    np.testing.assert_allclose(plus.forces, minus.forces, atol=1e-12 * np.abs(plus.forces).max())
    assert plus.shear_direction == minus.shear_direction == pytest.approx(math.pi)
    for mu in (0.0, 1.5, 10.0):
        result = r.solve(b, shear_ratio=mu, shear_direction=0.5)
        assert np.isfinite(result.forces).all() and result.residual < 1e-9
        assert -math.pi < result.shear_direction <= math.pi
        assert result.shear_ratio == pytest.approx(mu)
    # the automatic search stays within its bound
    assert r.solve(b).shear_ratio <= r.max_shear_ratio + 1e-12


@pytest.mark.parametrize("bad, message", [
    (lambda m: np.full(m, np.nan), "stress must be finite, got NaN at taxel"),
    (lambda m: np.r_[np.ones(m - 1), np.inf], r"stress must be finite, got inf at taxel\(s\) \[15\]"),
    (lambda m: np.ones(m + 1), r"stress must have shape \(16,\) or \(4, 4\) for this grid, got \(17,\)"),
    (lambda m: np.ones((2, 8)), r"stress must have shape \(16,\) or \(4, 4\) for this grid, got \(2, 8\)"),
    (lambda m: "abc", "stress must be numeric, got str"),
], ids=["nan", "inf", "length", "shape", "text"])
def test_bad_stress_says_what_is_wrong(bad, message):
    r = Reconstructor(SensorGrid.regular(4, 4, 2e-3, 2e-3))
    for solve in (r.solve, r.solve_normal):
        with pytest.raises(ValueError, match=message):
            solve(bad(16))


def test_bad_parameters_say_what_is_wrong():
    r = Reconstructor(SensorGrid.regular(4, 4, 2e-3, 2e-3))
    with pytest.raises(ValueError, match="shear_ratio must be finite and >= 0 .* got -0.1"):
        r.solve(np.ones(16), shear_ratio=-0.1)
    with pytest.raises(ValueError, match="shear_direction must be finite radians .* got nan"):
        r.solve(np.ones(16), shear_direction=math.nan)


@pytest.mark.parametrize("kwargs, message", [
    (dict(nx=4, ny=4, pitch=0.0, thickness=1e-3), "pitch must be a positive finite number of metres, got 0.0"),
    (dict(nx=4, ny=4, pitch=1e-3, thickness=-1e-3), "thickness must be a positive finite number .* got -0.001"),
    (dict(nx=4, ny=4, pitch=math.nan, thickness=1e-3), "pitch must be a positive finite number .* got nan"),
    (dict(nx=0, ny=4, pitch=1e-3, thickness=1e-3), "nx must be a positive integer .* got 0"),
    (dict(nx=4, ny=2.5, pitch=1e-3, thickness=1e-3), "ny must be a positive integer, got 2.5"),
], ids=["pitch0", "negative-thickness", "nan-pitch", "empty", "fractional"])
def test_impossible_geometry_is_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SensorGrid.regular(**kwargs)

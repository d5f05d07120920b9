import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import chi2

from measurement.bounds import (
    ShearBound,
    contact_bounds,
    decision_bound,
    format_decision_bound,
    miss_probability,
    shear_bounds,
)
from measurement.cases import standard_cases
from solver import loads
from solver.geometry import SensorGrid
from solver.kernels import stress_matrix

PITCH = 2e-3


def _frame(thickness_ratio, *, shear_ratio=0.3, noise=0.01, n=8):
    grid = SensorGrid.regular(n, n, PITCH, thickness_ratio * PITCH)
    contact = loads.hertz((0.3 * PITCH, -0.2 * PITCH), 1.6 * PITCH, 1.0, shear_ratio=shear_ratio,
                          shear_direction=0.7)
    return loads.simulate(grid, contact, noise=noise, rng=5)


def test_the_bound_is_the_spread_of_the_maximum_likelihood_shear_on_the_models_own_data():
    # Data from the bound's model (one force per node, layer kernel) with the frame's noise; the
    # shear and every loaded node's force fitted by nonlinear least squares (scipy's own Jacobian).
    # The fits' spread is the inverse of the information within the Monte-Carlo error.
    frame = _frame(1.0)
    bound = shear_bounds([frame])[0]
    m = frame.grid.size
    matrix = stress_matrix(frame.grid, "layer")
    fx, fy, fz = matrix[:, :m], matrix[:, m:2 * m], matrix[:, 2 * m:]
    # the bound's true profile: the simulator's nodal forces, integrated apart
    np.testing.assert_allclose(bound.profile, frame.forces[:, 2], rtol=0, atol=1e-3)
    profile = bound.profile
    loaded = profile > 0

    def stress(theta):
        p = np.zeros(m)
        p[loaded] = theta[:-2]
        return fz @ p + theta[-2] * (fx @ p) + theta[-1] * (fy @ p)

    truth = np.concatenate([profile[loaded], bound.shear])
    clean = stress(truth)
    sigma = frame.noise * np.abs(frame.clean_stress).max()
    rng = np.random.default_rng(3)  # noise draws, fixed
    shears = []
    for _ in range(300):
        data = clean + rng.normal(0.0, sigma, m)
        fit = least_squares(lambda t, d=data: (stress(t) - d) / sigma, truth, method="lm")
        shears.append(fit.x[-2:])
    spread = np.cov(np.array(shears).T)
    expected = np.linalg.inv(bound.information)
    # along both principal directions of the bound: standard deviations within 12% (300 draws)
    values, vectors = np.linalg.eigh(expected)
    for value, vector in zip(values, vectors.T, strict=True):
        assert math.sqrt(vector @ spread @ vector) == pytest.approx(math.sqrt(value), rel=0.12)
    assert bound.ratio_sd == pytest.approx(math.sqrt(values[-1]))


def test_a_free_sub_cell_profile_under_a_thin_layer_leaves_the_shear_undetermined():
    # Under h/p 0.6 the profile's 2x2 sub-cells outnumber what the sensors near the contact see: a
    # profile change explains almost any shear. One force per node leaves it to a few percent.
    frame = _frame(0.6)
    per_node, = shear_bounds([frame])
    per_sub_cell, = shear_bounds([frame], subdivision=2)
    assert per_sub_cell.profile_size > 3 * per_node.profile_size
    assert per_node.ratio_sd < 0.1
    assert per_sub_cell.ratio_sd > 10 * per_node.ratio_sd


def test_the_bound_is_the_shear_block_of_the_inverse_information_of_every_parameter():
    # Exact: invert the information of (profile, s_x, s_y) together, the profile's derivative
    # carrying the shear's terms, and read the shear's block of the covariance.
    frame = _frame(1.0)
    bound, = shear_bounds([frame])
    m = frame.grid.size
    matrix = stress_matrix(frame.grid, "layer")
    fx, fy, fz = matrix[:, :m], matrix[:, m:2 * m], matrix[:, 2 * m:]
    sx, sy = bound.shear
    loaded = bound.profile > 0
    jacobian = np.column_stack([fz[:, loaded] + sx * fx[:, loaded] + sy * fy[:, loaded],
                                fx @ bound.profile, fy @ bound.profile])
    sigma = frame.noise * np.abs(frame.clean_stress).max()
    covariance = np.linalg.inv(jacobian.T @ jacobian / sigma**2)[-2:, -2:]
    np.testing.assert_allclose(np.linalg.inv(bound.information), covariance, rtol=1e-6)


def _pair(gap_pitches, *, n=12, thickness_ratio=1.0):
    # two sheared Hertz contacts of radius 1.6 pitches, gap_pitches apart edge to edge along x
    grid = SensorGrid.regular(n, n, PITCH, thickness_ratio * PITCH)
    half = (1.6 * 2 + gap_pitches) * PITCH / 2
    contacts = [loads.hertz((-half, 0.1 * PITCH), 1.6 * PITCH, 1.0, shear_ratio=0.2, shear_direction=0.4),
                loads.hertz((half, -0.1 * PITCH), 1.6 * PITCH, 0.8, shear_ratio=0.3, shear_direction=2.5)]
    return loads.simulate(grid, contacts, noise=0.01, rng=2)


def _alone(frame, contact):
    # the contact on its own frame with the same absolute sensor noise
    alone = loads.simulate(frame.grid, contact)
    sigma = frame.noise * np.abs(frame.clean_stress).max()
    return shear_bounds([replace(alone, noise=sigma / np.abs(alone.clean_stress).max())])[0]


def test_the_joint_bound_is_the_shear_block_of_the_inverse_information_of_every_contacts_parameters():
    # Exact: the information of every contact's loaded profile forces and every shear together,
    # inverted; each contact's block of the covariance is its bound's
    frame = _pair(1.0)
    bounds = contact_bounds(frame)
    m = frame.grid.size
    matrix = stress_matrix(frame.grid, "layer")
    fx, fy, fz = matrix[:, :m], matrix[:, m:2 * m], matrix[:, 2 * m:]
    nuisance, signature = [], []
    for bound in bounds:
        sx, sy = bound.shear
        loaded = bound.profile > 0
        nuisance.append(fz[:, loaded] + sx * fx[:, loaded] + sy * fy[:, loaded])
        signature += [fx @ bound.profile, fy @ bound.profile]
    jacobian = np.column_stack(nuisance + signature)
    sigma = frame.noise * np.abs(frame.clean_stress).max()
    covariance = np.linalg.inv(jacobian.T @ jacobian / sigma**2)[-4:, -4:]
    for k, bound in enumerate(bounds):
        np.testing.assert_allclose(np.linalg.inv(bound.information), covariance[2 * k:2 * k + 2, 2 * k:2 * k + 2],
                                   rtol=1e-6)
    # each contact's own profile: what the simulator puts on the skin for it alone (given or simulated)
    totals = [loads.simulate(frame.grid, contact).forces[:, 2].sum() for contact in frame.contacts]
    for bound, total in zip(bounds, totals, strict=True):
        assert bound.profile.sum() == pytest.approx(total)
    for given, bound in zip(contact_bounds(frame, totals=totals), bounds, strict=True):
        np.testing.assert_allclose(given.information, bound.information, rtol=1e-12)


def test_a_close_neighbour_widens_the_bound_and_a_far_one_does_not():
    # a pitch apart the neighbour's unknown load explains part of the shear's signature; five and a
    # half thicknesses apart (about 7 pitches edge to edge at h = pitch) it explains none
    close, far = _pair(1.0), _pair(7.0, n=16)
    for frame, widened in ((close, True), (far, False)):
        for bound, contact in zip(contact_bounds(frame), frame.contacts, strict=True):
            alone = _alone(frame, contact)
            lost = alone.information - bound.information  # information the neighbour takes: PSD
            assert np.linalg.eigvalsh(lost).min() >= -1e-9 * np.abs(alone.information).max()
            if widened:
                assert bound.ratio_sd > 1.05 * alone.ratio_sd
            else:
                assert bound.ratio_sd == pytest.approx(alone.ratio_sd, rel=0.01)
    one = _frame(1.0)
    np.testing.assert_allclose(contact_bounds(one)[0].information, shear_bounds([one])[0].information,
                               rtol=1e-12)


def test_the_sub_cell_profile_is_the_load_on_the_kernels_sub_cells():
    # The bound's own model on its true profile and shear gives the simulator's stress (integrated
    # apart, on a finer lattice); the profile's centroid is the contact's centre along x and y.
    frame = _frame(1.0)
    bound, = shear_bounds([frame], subdivision=2)
    m = frame.grid.size
    matrix = stress_matrix(frame.grid, "layer", subdivision=2)
    cx, cy, cz = (matrix[:, c * 4 * m:(c + 1) * 4 * m] for c in range(3))
    sx, sy = bound.shear
    model = (cz + sx * cx + sy * cy) @ bound.profile
    peak = np.abs(frame.clean_stress).max()
    # measured 3.0% of the peak (the 2x2 profile's own error; the sub-cells' x and y swapped: 10%)
    assert np.abs(model - frame.clean_stress).max() < 0.05 * peak
    # sub-cell q of node j: column q * m + j, x fastest within the cell
    offset = np.array([-0.25, 0.25]) * PITCH
    x = (frame.grid.positions[:, 0][None, :] + offset[np.arange(4) % 2, None]).ravel()
    y = (frame.grid.positions[:, 1][None, :] + offset[np.arange(4) // 2, None]).ravel()
    centroid = np.array([x @ bound.profile, y @ bound.profile]) / bound.profile.sum()
    np.testing.assert_allclose(centroid, frame.contacts[0].center, atol=0.002 * PITCH)


def test_the_miss_probability_is_that_of_the_wald_test_on_gaussian_estimates():
    information = np.array([[900.0, 200.0], [200.0, 400.0]])
    shear = np.array([0.08, -0.05])
    rng = np.random.default_rng(8)  # estimates drawn around the shear, fixed
    estimates = rng.multivariate_normal(shear, np.linalg.inv(information), size=40000)
    statistic = np.einsum("ni,ij,nj->n", estimates, information, estimates)
    for rate in (0.05, 1 / 6, 0.4):
        missed = np.mean(statistic <= chi2.ppf(1 - rate, 2))
        assert miss_probability(information, shear, false_rate=rate) == pytest.approx(missed, abs=0.01)
    # no shear: the test misses what it does not give shear, all but the false rate
    assert miss_probability(information, [0.0, 0.0], false_rate=0.2) == pytest.approx(0.8)
    # a bound's miss: along its true direction, at its own ratio or the one asked for
    bound = ShearBound(information, 2 * shear, np.ones(3))
    assert bound.miss(false_rate=0.1) == miss_probability(information, 2 * shear, false_rate=0.1)
    assert bound.miss(np.hypot(*shear), false_rate=0.1) == pytest.approx(
        miss_probability(information, shear, false_rate=0.1))
    still = ShearBound(information, np.zeros(2), np.ones(3))
    assert still.miss(false_rate=0.1) == pytest.approx(0.9)
    assert still.miss(0.1, false_rate=0.1) == miss_probability(information, [0.1, 0.0], false_rate=0.1)


def test_a_shear_decision_misses_less_where_the_layer_is_thicker_and_when_it_allows_more_false():
    rows = decision_bound([standard_cases(seed=100)], false_rates=(1 / 12, 4 / 12))
    assert [r["false"] for r in rows] == pytest.approx([1.0, 4.0])
    assert rows[0]["missed"] > rows[1]["missed"] > 0
    assert rows[0]["none_missed"] < rows[1]["none_missed"] < 1
    for row in rows:
        shares = list(row["missed_by_thickness"].values())
        assert list(row["missed_by_thickness"]) == [0.5, 1.0, 1.5]
        assert shares[0] > shares[1] > shares[2]
    lines = format_decision_bound(rows).splitlines()
    assert lines[0].split()[:3] == ["false", "of", "12"]
    assert len(lines) == 3 and lines[1].split()[0] == "1.0"


def test_bad_input_is_refused_with_the_rule_and_the_value():
    frame = _frame(1.0)
    grid = frame.grid
    two = loads.simulate(grid, [loads.hertz((-4 * PITCH, 0.0), PITCH, 1.0),
                                loads.hertz((4 * PITCH, 0.0), PITCH, 1.0)], noise=0.01, rng=1)
    with pytest.raises(ValueError, match="frames must have one contact each, frame 1 has 2"):
        shear_bounds([frame, two])
    with pytest.raises(ValueError, match=r"frames must have noise > 0 .*frame 0 has 0.0"):
        shear_bounds([_frame(1.0, noise=0.0)])
    with pytest.raises(ValueError, match="subdivision"):
        shear_bounds([frame], subdivision=0)
    with pytest.raises(ValueError, match=r"frame must have noise > 0 \(the bound scales with it\), got 0.0"):
        contact_bounds(_frame(1.0, noise=0.0))
    with pytest.raises(ValueError, match="frame must hold at least one contact, got none"):
        contact_bounds(replace(two, contacts=()))
    with pytest.raises(ValueError, match="subdivision must be"):
        contact_bounds(two, subdivision=0)
    with pytest.raises(ValueError, match=r"totals must give one force per contact \(2\), got 1"):
        contact_bounds(two, totals=[1.0])
    for rate in (0.0, 1.0, math.nan):
        with pytest.raises(ValueError, match=rf"false_rate must be in \(0, 1\), got {rate!r}"):
            miss_probability(np.eye(2), [0.1, 0.0], false_rate=rate)
    with pytest.raises(ValueError, match="shear must be 2 finite numbers"):
        miss_probability(np.eye(2), [0.1, 0.0, 0.0], false_rate=0.1)
    with pytest.raises(ValueError, match="shear must be 2 finite numbers"):
        miss_probability(np.eye(2), [math.nan, 0.0], false_rate=0.1)
    with pytest.raises(ValueError, match=r"information must be a finite \(2, 2\) array"):
        miss_probability(np.eye(3), [0.1, 0.0], false_rate=0.1)
    with pytest.raises(ValueError, match=r"information must be \(2, 2\) and shear \(2,\), got \(3, 3\)"):
        ShearBound(np.eye(3), np.zeros(2), np.ones(3))
    with pytest.raises(ValueError, match="draws must hold at least one draw, got none"):
        decision_bound([])
    with pytest.raises(ValueError, match="rows must hold at least one false rate, got none"):
        format_decision_bound([])


def test_the_ideal_errors_are_those_of_a_gaussian_estimate():
    sigma = 0.02
    # no shear: |ds| is Rayleigh, median sigma sqrt(2 ln 2); no direction to miss
    still = ShearBound(np.eye(2) / sigma**2, np.zeros(2), np.ones(3))
    tangential, direction = still.ideal_errors(samples=40000)
    assert tangential == pytest.approx(sigma * math.sqrt(2 * math.log(2)), rel=0.02)
    assert math.isnan(direction)
    # shear 0.4 at 30 deg, far above the noise: the turn is sigma / mu radians normal, median 0.674 of it;
    # the tangential error is relative to |F| = F_z sqrt(1 + mu^2)
    mu = 0.4
    sheared = ShearBound(np.eye(2) / sigma**2, mu * np.array([math.cos(0.5), math.sin(0.5)]), np.ones(3))
    tangential, direction = sheared.ideal_errors(samples=40000)
    assert tangential == pytest.approx(sigma * math.sqrt(2 * math.log(2)) / math.sqrt(1 + mu**2), rel=0.02)
    assert direction == pytest.approx(math.degrees(0.6745 * sigma / mu), rel=0.03)
    # the same draws every call unless told otherwise
    assert sheared.ideal_errors() == sheared.ideal_errors()
    assert sheared.ideal_errors(rng=1) != sheared.ideal_errors(rng=2)
    # shear the data do not determine
    # shear the data do not determine: a direction at random errs by 90 deg in the median
    undetermined = ShearBound(np.zeros((2, 2)), [0.3, 0.0], np.ones(3))
    assert undetermined.ideal_errors() == (math.inf, 90.0)
    assert undetermined.information.flags.writeable is False and undetermined.shear.flags.writeable is False
    with pytest.raises(ValueError, match="samples must be a whole number >= 1, got 0"):
        sheared.ideal_errors(samples=0)

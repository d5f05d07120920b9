"""Tests of solver/search.py: the compiled, warm-started Lawson-Hanson NNLS against scipy."""

import numpy as np
import pytest
from scipy import ndimage, sparse
from scipy.optimize import nnls
from scipy.spatial import cKDTree

import solver.search as search
from solver import SensorGrid
from solver.geometry import neighbours_within
from solver.inverse import DenseSolver
from solver.search import (
    contact_labels,
    fit_view,
    halved_labels,
    load_decision,
    load_patches,
    misfit_variance,
    near_sums,
    shear_evidence,
    template_misfit,
)


def random_problem(seed):
    rng = np.random.default_rng(seed)  # one random problem per seed, some with more unknowns than rows
    m, n = int(rng.integers(3, 60)), int(rng.integers(1, 30))
    return rng, rng.standard_normal((m, n)), rng.standard_normal(m)


def assert_kkt(A, b, g):
    # the optimality conditions of min |A g - b| over g >= 0
    assert g.shape == (A.shape[1],) and np.all(g >= 0)
    w = A.T @ (b - A @ g)
    scale = np.abs(A.T @ b).max()
    np.testing.assert_allclose(w[g > 0], 0, atol=1e-8 * scale)
    assert np.all(w[g == 0] <= 1e-8 * scale)


def lawson_hanson(A, b, support=None, max_swaps=None):
    # the compiled fit on A's columns from a guessed support; returns the fit, its set changes
    # (-1: stopped short of the optimum) and the final set (the guess, changed in place)
    n = A.shape[1]
    columns = np.ascontiguousarray(A.T)
    free = np.zeros(n, bool) if support is None else np.array(support, bool)
    g = np.zeros(n)
    steps, _ = search.lawson_hanson(columns, b, free, 3 * n + 10 if max_swaps is None else max_swaps, g,
                                    *search.workspace(columns))
    return g, steps, free


@pytest.mark.parametrize("seed", range(40))
def test_lawson_hanson_matches_scipy_cold_and_warm(seed):
    rng, A, b = random_problem(seed)
    n = A.shape[1]
    reference = nnls(A, b, maxiter=30 * n)[0]
    objective = lambda v: np.sum((A @ v - b) ** 2)  # noqa: E731
    supports = {"cold": None, "good": reference > 0, "bad": rng.random(n) < 0.5,
                "empty": np.zeros(n, bool), "full": np.ones(n, bool), "complement": ~(reference > 0)}
    for name, support in supports.items():
        g, steps, final = lawson_hanson(A, b, support)
        assert steps >= 0, name  # reached the optimum without a fallback
        assert_kkt(A, b, g)
        np.testing.assert_array_equal(final, g > 0, err_msg=name)  # the final set is the positive one
        # measured excess at most 2e-16 of |b|^2 over these seeds
        assert objective(g) <= objective(reference) + 1e-12 * (b @ b), name
        if A.shape[0] >= n:  # full column rank: the minimizer is unique (measured 5e-15 apart)
            np.testing.assert_allclose(g, reference, rtol=0, atol=1e-9 * max(np.abs(reference).max(), 1.0),
                                       err_msg=name)


@pytest.mark.parametrize("seed", range(40))
def test_lawson_hanson_from_the_right_support_makes_no_change(seed):
    # the warm start really solves: from the answer's support, no change of the set is needed.
    # Measured, not guaranteed: scipy's support could hold an entry that rounding makes <= 0
    # here (the smallest over these seeds is 8.5e-4 of the largest)
    rng, A, b = random_problem(seed)
    reference = nnls(A, b, maxiter=30 * A.shape[1])[0]
    g, steps, _ = lawson_hanson(A, b, reference > 0, max_swaps=0)
    assert steps == 0
    assert_kkt(A, b, g)


def test_lawson_hanson_stops_short_when_out_of_changes():
    rng, A, b = random_problem(7)  # fixed seed
    reference = nnls(A, b, maxiter=30 * A.shape[1])[0]
    # no changes allowed from the wrong support: stopped short (the caller falls back to scipy)
    g, steps, _ = lawson_hanson(A, b, ~(reference > 0), max_swaps=0)
    assert steps == -1
    assert np.sum((A @ g - b) ** 2) > np.sum((A @ reference - b) ** 2)  # not the optimum


def test_a_cold_fit_takes_columns_in_batches_not_one_scan_each():
    # A fit that takes one column per scan of the columns changes its set at least once per
    # positive column; taking the steepest few per scan, a cold fit of a contact's stress
    # (noise-free, 81 sensors, 160 columns: the cell columns and 79 random mixes) needs far fewer
    # scans than it ends with positive columns (measured 5 against 22; 27 one at a time), and
    # still reaches scipy's optimum.
    rng = np.random.default_rng(3)  # fixed seed: the columns' random mix
    grid = SensorGrid.regular(9, 9, 1.5e-3, 1.5e-3)
    x, y = grid.positions.T
    normal = DenseSolver(grid, kernel="cell").matrix[:, 2 * grid.size:]
    A = np.hstack([normal, normal @ (np.eye(grid.size) + 0.3 * rng.random((grid.size, grid.size)))])[:, :160]
    b = A[:, :81] @ np.clip(1 - (x ** 2 + y ** 2) / (4e-3) ** 2, 0, None)
    g, steps, _ = lawson_hanson(A, b)
    reference = nnls(A, b, maxiter=30 * A.shape[1])[0]
    assert_kkt(A, b, g)
    assert np.sum((A @ g - b) ** 2) <= np.sum((A @ reference - b) ** 2) + 1e-12 * (b @ b)
    positive = np.count_nonzero(g > 0)
    assert positive >= 20
    assert 0 <= steps < positive / 2


def test_lawson_hanson_leaves_a_dependent_column_out_of_the_set():
    # a guess holding a column twice: the twin would make the set's factor singular, so it is
    # left out and the warm start still solves
    rng, A, b = random_problem(7)  # fixed seed
    twin = np.hstack([A, A[:, :1]])
    g, steps, _ = lawson_hanson(twin, b, np.ones(twin.shape[1], bool))
    assert steps >= 0
    assert_kkt(twin, b, g)
    assert g[0] == 0 or g[-1] == 0


def test_the_fallback_survives_scipy_running_out_of_iterations(monkeypatch):
    rng, A, b = random_problem(11)  # fixed seed
    reference = nnls(A, b, maxiter=30 * A.shape[1])[0]

    def exhausted(*args, **kwargs):
        raise RuntimeError("Maximum number of iterations reached.")
    monkeypatch.setattr(search, "nnls", exhausted)
    g = search.scipy_fit(A, b)  # scipy's nnls fails, bounded least squares answers
    np.testing.assert_allclose(g, reference, rtol=0, atol=1e-8 * max(np.abs(reference).max(), 1.0))
    assert_kkt(A, b, g)


def test_load_patches_are_connected_pieces_of_one_contacts_load():
    # nodes 0..7 on a line, neighbours within two steps (a gap of one node is bridged);
    # one column per node, all of contact 0 but nodes 6 and 7 (contact 1)
    m = 8
    neighbours = sparse.csr_matrix(np.abs(np.subtract.outer(np.arange(m), np.arange(m))) <= 2)
    contact = np.array([0, 0, 0, 0, 0, 0, 1, 1])
    node = np.arange(m)
    g = np.array([1.0, 0.0, 2.0, 0.0, 0.0, 3.0, 4.0, 0.0])   # 0 and 2 bridged; 5 alone; 6 another contact
    rng = np.random.default_rng(4)  # fixed seed
    xt, yt, zt = (rng.standard_normal((m, 5)) for _ in range(3))
    shear = np.array([[0.1, -0.2], [0.3, 0.0]])
    column_patch, patch_contact, size, explained = load_patches(
        xt, yt, zt, contact, node, shear, g, neighbours.indptr, neighbours.indices)
    np.testing.assert_array_equal(column_patch, [0, -1, 0, -1, -1, 1, 2, -1])
    np.testing.assert_array_equal(patch_contact, [0, 0, 1])
    np.testing.assert_array_equal(size, [2, 1, 1])
    columns = zt + shear[contact, :1] * xt + shear[contact, 1:] * yt   # A's columns, one per row
    for k in range(3):
        np.testing.assert_allclose(explained[k], (g * (column_patch == k)) @ columns, rtol=1e-12)


def test_the_variance_near_each_contact_is_its_misfit_over_its_freedom_or_the_models_floor():
    # 6 rows: 0-3 near contact 0, 2-5 near contact 1; contact 0 has 2 positive columns, contact 1 has 4
    near = np.zeros((6, 2), bool)
    near[:4, 0] = near[2:, 1] = True
    stress = np.array([1.0, -8.0, 2.0, 3.0, 5.0, -4.0])
    residual = np.array([0.5, -1.0, 0.25, 2.0, -0.5, 1.5])
    contact = np.array([0, 0, 0, 1, 1, 1, 1])
    g = np.array([1.0, 0.0, 2.0, 1.0, 1.0, 3.0, 1.0])
    np.testing.assert_array_equal(near_sums(residual ** 2, near), (residual ** 2) @ near)
    rho = (residual ** 2) @ near
    # contact 0: 4 rows - 2 positive - 1 parameter = 1; its floor (0.01 * 8)^2 is below rho / 1
    # contact 1: 4 rows - 4 positive - 1 = -1, no freedom: the given unknown, or NaN: the floor
    variance = misfit_variance(stress, residual, near, contact, g, 1, 0.01, np.inf)
    np.testing.assert_allclose(variance, [rho[0] / 1, np.inf], rtol=1e-15)
    floor = misfit_variance(stress, residual, near, contact, g, 1, 0.01, np.nan)
    np.testing.assert_allclose(floor, [rho[0], (0.01 * 5.0) ** 2], rtol=1e-15)
    # a floor above the misfit wins
    np.testing.assert_allclose(misfit_variance(stress, residual, near, contact, g, 1, 1.0, np.inf),
                               [64.0, np.inf], rtol=1e-15)


def test_shear_evidence_is_the_f_statistic_with_rounding_as_no_gain():
    near = np.ones((3, 3), bool)
    stress = np.array([1.0, 2.0, 2.0])       # |b|^2 near every contact: 9
    gain = np.array([4.0, 8.0e-10, 1.0])      # contact 1's gain is below 1e-10 |b|^2: rounding
    variance = np.array([0.5, 0.5, 0.0])      # contact 2: no misfit left, infinite evidence
    evidence = shear_evidence(stress, near, gain, variance, 2)
    np.testing.assert_array_equal(evidence, [4.0 / 2 / 0.5, 0.0, np.finfo(float).max])


def test_the_load_decision_drops_the_patches_noise_could_have_made():
    # one contact, nodes 0..5 on a line (neighbours within two steps); patch {0, 1} explains much
    # of the data, the lone column 5 (a patch of its own) almost nothing
    m = 6
    neighbours = sparse.csr_matrix(np.abs(np.subtract.outer(np.arange(m), np.arange(m))) <= 2)
    rng = np.random.default_rng(12)  # fixed seed
    rows = 40
    xt, yt, zt = (rng.standard_normal((m, rows)) for _ in range(3))
    contact, node = np.zeros(m, np.int64), np.arange(m)
    shear = np.array([[0.2, 0.1]])
    g = np.array([3.0, 2.0, 0.0, 0.0, 0.0, 1e-3])
    columns = zt + 0.2 * xt + 0.1 * yt
    noise = 0.1 * rng.standard_normal(rows)
    stress = g @ columns + noise
    residual = g @ columns - stress
    near = np.ones((rows, 1), bool)
    kept, left, evidence = load_decision(xt, yt, zt, contact, node, shear, g, residual, neighbours.indptr,
                                         neighbours.indices, stress, near, 0.002, 10.0)
    np.testing.assert_array_equal(kept, [3.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(left, kept @ columns - stress, atol=1e-12)
    # the evidence of the patch kept, in deviations of chi2 (2 positive columns)
    variance = (residual @ residual) / (rows - 3)
    chi2 = np.sum((g[:2] @ columns[:2]) ** 2) / variance
    np.testing.assert_allclose(evidence, [(chi2 - 2) / 2.0], rtol=1e-12)
    # with -inf every patch stays
    kept, left, _ = load_decision(xt, yt, zt, contact, node, shear, g, residual, neighbours.indptr,
                                  neighbours.indices, stress, near, 0.002, -np.inf)
    np.testing.assert_array_equal(kept, g)
    np.testing.assert_array_equal(left, residual)


def test_the_fit_view_is_the_sub_cell_columns_on_the_rows_near_the_contacts():
    # 5 nodes, 2 sub-cells each: source rows x (q m + j), then y and z each 2 m further
    m, cells = 5, 2
    rng = np.random.default_rng(3)  # fixed seed
    source = rng.standard_normal((3 * cells * m, m))
    labels = np.array([0, 2, 0, 1, 0])
    near = np.zeros((m, 2), bool)
    near[[0, 1, 3], 1] = near[[3, 4], 0] = True
    b = rng.standard_normal(m)
    stress, fit, contact, node, column_id, row_contact = fit_view(b, labels, near, source, cells)
    rows = [0, 1, 3, 4]
    np.testing.assert_array_equal(stress, b[rows])
    np.testing.assert_array_equal(row_contact, near[rows])
    np.testing.assert_array_equal(column_id, [1, 3, 6, 8])
    np.testing.assert_array_equal(node, [1, 3, 1, 3])
    np.testing.assert_array_equal(contact, [1, 0, 1, 0])
    every = np.concatenate([column_id + axis * cells * m for axis in range(3)])
    np.testing.assert_array_equal(fit, source[every][:, rows])


def test_template_misfit_is_the_friction_shaped_load_and_what_it_leaves():
    # 6 nodes: 0 and 1 of contact 1, 3 and 4 of contact 2 (node 4 unloaded), 2 and 5 outside;
    # a profile value outside every contact is no load of the template
    m = 6
    rng = np.random.default_rng(9)  # fixed seed
    matrix = rng.standard_normal((m, 3 * m))   # C, (m, 3m)
    labels = np.array([1, 1, 0, 2, 2, 0])
    shear = np.array([[0.3, -0.1], [0.0, 0.5]])
    g = np.array([1.0, 2.0, 7.0, 3.0, 0.0, 0.0])
    b = rng.standard_normal(m)
    misfit = b.copy()
    template = template_misfit(np.ascontiguousarray(matrix.T), labels, shear, g, misfit)
    inside = np.where(labels > 0, g, 0.0)
    pairs = np.vstack([[0.0, 0.0], shear])[labels]
    expected = np.concatenate([pairs[:, 0] * inside, pairs[:, 1] * inside, inside])
    np.testing.assert_array_equal(template, expected)
    np.testing.assert_allclose(misfit, b - matrix @ expected, rtol=0, atol=1e-14 * np.abs(matrix).sum())


# run in a Python of its own: in the test session other tests compile what warm_up might miss
_AFTER_WARM_UP = """
import json
import numpy as np
import solver.search as search
from solver import SensorGrid, loads
from solver.inverse import DenseSolver
from solver.region import RegionSolver
from solver.warmup import warm_up

warm_up()
compiled = {name: f for name, f in vars(search).items() if hasattr(f, "signatures")}
before = {name: len(f.signatures) for name, f in compiled.items()}
grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
x, y = grid.positions.T
for kernel in ("layer", "cell", "point"):
    r = DenseSolver(grid, kernel=kernel)
    frame = (r.matrix[:, 2 * grid.size:] @ np.exp(-(x ** 2 + y ** 2) / (2 * 3e-3 ** 2))).reshape(grid.shape)
    frame.setflags(write=False)
    for parameters in ({}, dict(shear_ratio=0.2, shear_direction=0.3), dict(shear_direction=0.3),
                       dict(shear_ratio=0.2), dict(shear_ratio=0.2, shear_direction=0.3, exact=False)):
        assert r.solve(frame, **parameters).contacts, (kernel, parameters)
# several contacts: a pinch (each one's own shear evidence refitted) and three contacts
skin = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3)
pinch = [loads.hertz((-3.75e-3, 0.0), 3e-3, 0.8, shear_ratio=0.3, shear_direction=0.0),
         loads.hertz((3.75e-3, 0.0), 3e-3, 0.8, shear_ratio=0.3, shear_direction=np.pi)]
three = [loads.hertz((-6e-3, -5e-3), 3e-3, 1.0, shear_ratio=0.2),
         loads.hertz((6e-3, -5e-3), 3e-3, 0.7), loads.hertz((0.0, 6e-3), 3e-3, 0.9, shear_ratio=0.4)]
# a light broad load beside a sharp one: found by its own scale, after a test on the frame's noise
beside = [loads.cone((-6e-3, -1.5e-3), 3.6e-3, 1.07, shear_ratio=0.2),
          loads.flat_punch((3e-3, 3e-3), 3.5e-3, 0.64, shear_ratio=0.4)]
for contacts in (pinch, three, beside):
    frame = loads.simulate(skin, contacts, noise=0.01, rng=np.random.default_rng(5)).stress
    assert len(DenseSolver(skin).solve(frame).contacts) == len(contacts)
# the large-skin path finds its windows on the frame itself
large = SensorGrid.regular(32, 32, 2e-3, 2e-3)
frame = loads.simulate(large, loads.hertz((1e-3, -2e-3), 4e-3, 1.0, shear_ratio=0.2)).stress
assert not frame.flags.writeable
assert RegionSolver(large).solve(frame).contacts
print(json.dumps({name: len(f.signatures) - before[name] for name, f in compiled.items()
                  if len(f.signatures) != before[name]}))
"""


def test_after_warm_up_a_recorded_frame_compiles_nothing():
    # recordings and the live board hand over read-only frames; numba compiles a function again
    # for each new kind of array, which on the app's first solve cost 0.18 s (found in review);
    # and the first frame with two contacts sharing sensors compiled the own-gain refit's
    # functions (0.2 s after an install, 25 ms loading them in each new process)
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", _AFTER_WARM_UP], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {}


@pytest.mark.parametrize("threshold", [1.0, 2.0])
def test_no_contact_when_nothing_is_above_the_threshold(threshold):
    r = DenseSolver(SensorGrid.regular(4, 4, 1e-3, 1e-3), kernel="cell")
    normal = np.linspace(0.1, 1.0, 16)
    labels, near = _labels(r, normal, threshold=threshold)
    assert labels.shape == (16,) and not labels.any() and near.shape == (16, 0)
    labels, near = _labels(r, normal, threshold=0.95)  # the peak node alone
    assert labels.max() == 1 and near.shape == (16, 1) and near[15, 0]


def test_faint_cores_are_light_loads_the_frame_core_misses():
    grid = SensorGrid.regular(16, 16, 1e-3, 1e-3)
    r = DenseSolver(grid, kernel="cell")
    x, y = (grid.positions / grid.pitch).T
    sharp = np.exp(-((x + 4) ** 2 + y ** 2) / 2)  # the frame's peak, 1
    broad = 0.12 * ((x - 4) ** 2 + y ** 2 <= 9)  # a plateau below the core's 20%
    labels = np.full(grid.size, -1, np.int64)
    assert search.faint_cores(sharp + broad, 0.2, 0.05, r._adjacent, labels) == 1
    np.testing.assert_array_equal(labels, (broad > 0).astype(int))
    # its core at 20% of its own peak: a rim around a lighter middle is left out
    rim = broad * (1 + 4 * ((x - 4) ** 2 + y ** 2 >= 4))  # 0.12 inside, 0.6 on the rim
    assert search.faint_cores(sharp + 0.2 * rim, 0.2, 0.05, r._adjacent, labels) == 1
    np.testing.assert_array_equal(labels > 0, 0.2 * rim > 0.2 * 0.2 * rim.max())
    # none where the frame's core holds the load: the sharp load alone, a plateau at 30% of the
    # peak, a light load joined to the peak's own patch, nothing compressive
    for values in (sharp, sharp + 2.5 * broad, sharp + 0.12 * ((x + 1) ** 2 + y ** 2 <= 4),
                   -sharp, np.zeros(grid.size)):
        assert search.faint_cores(values, 0.2, 0.05, r._adjacent, labels) == 0 and not labels.any()
    # 5% of the largest core's load: of a core patch, even where two cores share one patch at 5%
    column, row = np.arange(grid.size) % 16, np.arange(grid.size) // 16
    bridged = np.zeros(grid.size)
    bridged[(row == 2) & ((column == 2) | (column == 8))] = 1.0
    bridged[(row == 2) & (column > 2) & (column < 8)] = 0.06
    light = (row == 12) & (column == 12)
    bridged[light] = 0.07  # 7% of one core's load, 3.5% of both's
    assert search.faint_cores(bridged, 0.2, 0.05, r._adjacent, labels) == 1
    np.testing.assert_array_equal(labels, light.astype(int))
    bridged[light] = 0.04  # 4%: a speck
    assert search.faint_cores(bridged, 0.2, 0.05, r._adjacent, labels) == 0
    # two light loads: one candidate each, numbered in raster order
    other = 0.1 * ((x - 4) ** 2 + (y + 6) ** 2 <= 2)
    assert search.faint_cores(sharp + broad + other, 0.2, 0.05, r._adjacent, labels) == 2
    assert set(labels[other > 0]) == {1} and set(labels[broad > 0]) == {2}


def test_the_laplacian_noise_is_the_robust_deviation_of_the_laplacian():
    rng = np.random.default_rng(3)  # fixed seed
    image = rng.normal(0.0, 2.5, (40, 30)) + np.linspace(0, 50, 30)  # a linear trend has no Laplacian
    laplacian = (4 * image[1:-1, 1:-1] - image[:-2, 1:-1] - image[2:, 1:-1] - image[1:-1, :-2]
                 - image[1:-1, 2:])
    expected = 1.4826 * np.median(np.abs(laplacian - np.median(laplacian))) / np.sqrt(20)
    assert search.laplacian_noise(image) == pytest.approx(expected, rel=1e-12)
    assert search.laplacian_noise(image) == pytest.approx(2.5, rel=0.1)


def _labels(r, normal, *, threshold=0.2, separation=0.6):
    return contact_labels(np.asarray(normal, float), threshold, separation, r.grid.positions, r._adjacent,
                          r._margin, r._near, np.zeros(r.grid.size, bool))


def _two_bumps(grid, dip):
    # two round bumps of height 1 and 0.8 on one row, 5 pitches apart, joined by a ridge that sinks
    # to ``dip`` between them: one patch above any threshold below ``dip``
    x, y = (grid.positions / grid.pitch).T
    bumps = np.maximum(np.exp(-((x + 2.5) ** 2 + y ** 2) / 1.5), 0.8 * np.exp(-((x - 2.5) ** 2 + y ** 2) / 1.5))
    ridge = dip * np.exp(-(y ** 2) / 1.5) * (np.abs(x) <= 2.5)
    return np.maximum(bumps, ridge)


@pytest.fixture(scope="module")
def plain():
    return DenseSolver(SensorGrid.regular(15, 9, 1e-3, 1e-3), kernel="cell")


def test_a_patch_with_a_dip_between_two_peaks_is_two_contacts(plain):
    grid = plain.grid
    x = grid.positions[:, 0] / grid.pitch
    # the lower peak's node reads 0.8 exp(-1/6) = 0.677: a dip of 0.3 is 0.44 of it, one of 0.5 is 0.74
    for dip, separation, count in ((0.3, 0.6, 2), (0.3, 0.45, 2), (0.3, 0.43, 1), (0.3, 0.0, 1), (0.5, 0.6, 1)):
        normal = _two_bumps(grid, dip)
        core, cores = np.zeros(grid.size, np.int64), None
        cores = search.contact_cores(normal, 0.2, plain._adjacent, core)
        assert cores.sum() == 1  # one patch above the threshold
        labels, near = _labels(plain, normal, separation=separation)
        assert labels.max() == count == near.shape[1], (dip, separation)
        if count == 2:
            # each holds its own peak, and the ridge is cut where it is lowest
            peaks = [np.argmax(np.where(x < 0, normal, 0)), np.argmax(np.where(x > 0, normal, 0))]
            assert labels[peaks[0]] != labels[peaks[1]] and labels[peaks].all()
            row = np.flatnonzero((np.abs(grid.positions[:, 1]) < 1e-9) & (normal > 0.2))  # the core's
            assert set(labels[row[x[row] <= -1]]) == {labels[peaks[0]]}
            assert set(labels[row[x[row] >= 1]]) == {labels[peaks[1]]}
    # every local maximum is a contact at separation 1
    assert _labels(plain, _two_bumps(grid, 0.7), separation=1.0)[0].max() == 2


def _prominent_peaks(grid, normal, threshold, separation):
    # brute force: a peak of a kept core patch is a contact's when every path from it to higher
    # ground sinks to at most separation times its height (its key saddle, found on the level sets)
    structure = np.ones((3, 3))
    image = normal.reshape(grid.shape)
    core, count = ndimage.label(image > threshold * image.max(), structure=structure)
    mass = ndimage.sum_labels(image, core, index=np.arange(1, count + 1))
    peaks = 0
    for k in np.flatnonzero(mass >= 0.05 * mass.max()) + 1:
        patch = core == k
        summit = image[patch].max()
        peaks += 1  # the patch's highest peak
        maxima = patch & (image == ndimage.maximum_filter(np.where(patch, image, -np.inf), footprint=structure))
        for p in zip(*np.nonzero(maxima), strict=True):
            height = image[p]
            if height == summit:
                continue
            # the highest level at which p's component of {v >= level} within the patch reaches higher
            levels = np.sort(image[patch & (image <= height)])[::-1]
            saddle = -np.inf
            for level in levels:
                parts = ndimage.label(patch & (image >= level), structure=structure)[0]
                if (image[parts == parts[p]] > height).any():
                    saddle = level
                    break
            peaks += saddle <= separation * height
    return peaks


def _bump_field(grid, rng, bumps, widest):
    # noise of 0.05 and round bumps of height 0.3 to 1 on the 15 x 9 skin, their squared width 0.5 to
    # ``widest`` pitches^2; ``bumps`` a count, or (low, high) for one drawn after the noise
    x, y = (grid.positions / grid.pitch).T
    values = 0.05 * rng.standard_normal(grid.size)
    for _ in range(bumps if isinstance(bumps, int) else int(rng.integers(*bumps))):
        cx, cy = rng.uniform(-7, 7), rng.uniform(-4, 4)
        values += rng.uniform(0.3, 1.0) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / rng.uniform(0.5, widest))
    return values


@pytest.mark.parametrize("seed", range(12))
def test_the_pieces_of_a_patch_are_its_prominent_peaks(plain, seed):
    # random fields of a few bumps and noise: as many pieces as prominent peaks (brute force)
    rng = np.random.default_rng(seed)  # one field per seed
    grid = plain.grid
    normal = _bump_field(grid, rng, (1, 5), 3.0)
    # distinct values: the brute force and the merge tree order ties alike only by chance
    normal += 1e-9 * rng.standard_normal(grid.size)
    core = np.zeros(grid.size, np.int64)
    kept = search.contact_cores(normal, 0.2, plain._adjacent, core)
    core = np.where(kept[core], core, 0)
    for separation in (0.3, 0.6, 0.9):
        pieces = np.zeros(grid.size, np.int64)
        count = search._separate(normal, core, separation, plain._adjacent, pieces)
        assert count == pieces.max() == _prominent_peaks(grid, normal, 0.2, separation), separation
        # each piece lies within one core patch and is connected
        for k in range(1, count + 1):
            assert len(set(core[pieces == k])) == 1
            image = (pieces == k).reshape(grid.shape)
            assert ndimage.label(image, structure=np.ones((3, 3)))[1] == 1


def test_light_pieces_and_noise_all_over_the_skin_join_their_neighbours(plain):
    grid = plain.grid
    x, y = (grid.positions / grid.pitch).T
    # two bumps 4 pitches apart, their dip deep enough to split them
    pair = lambda second: np.maximum(np.exp(-((x + 2) ** 2 + y ** 2) / 1.0),  # noqa: E731
                                     second * np.exp(-((x - 2) ** 2 + y ** 2) / 1.0))
    assert _labels(plain, pair(0.8))[0].max() == 2
    # the same second bump with a quarter of the first's core load or less joins it
    assert _labels(plain, pair(0.35))[0].max() == 1
    assert search.SEPARATE_MASS == 0.25
    # more bumps that could stand apart than a hand makes: noise, and touching ones join as before
    bumps = [np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 0.6) for cx, cy in
             ((-6, -2), (-3, -2), (0, -2), (3, -2), (6, -2), (-6, 2), (-3, 2), (0, 2), (3, 2), (6, 2))]
    field = np.max(bumps[:search.SEPARATE_MOST], axis=0)
    assert _labels(plain, field)[0].max() == search.SEPARATE_MOST
    field = np.max(bumps, axis=0)
    assert _labels(plain, field)[0].max() < len(bumps)
    assert _labels(plain, field)[0].max() == _labels(plain, field, separation=0.0)[0].max()



def _saddle_by_level_sets(grid, values, cores, p, q):
    # brute force: the highest level at which p's and q's cores share a component of {v >= level}
    image, structure = values.reshape(grid.shape), np.ones((3, 3))
    for level in np.sort(values)[::-1]:
        parts = ndimage.label(image >= level, structure=structure)[0].ravel()
        if set(parts[cores == p]) & set(parts[cores == q]) - {0}:
            return level
    return -np.inf


@pytest.mark.parametrize("seed", range(6))
def test_the_saddle_of_two_cores_is_the_highest_level_a_path_between_them_keeps_to(plain, seed):
    rng = np.random.default_rng(seed)  # one field per seed
    grid = plain.grid
    values = _bump_field(grid, rng, 4, 2.0)
    cores = np.zeros(grid.size, np.int64)
    count = search._components(np.where(values > 0.3 * values.max(), 0, -1), *plain._adjacent, cores)
    saddle = search._saddles(values, cores, count, plain._adjacent)
    assert saddle.shape == (count + 1, count + 1)
    for p_ in range(1, count + 1):
        for q in range(p_ + 1, count + 1):
            assert saddle[p_, q] == saddle[q, p_] == _saddle_by_level_sets(grid, values, cores, p_, q)


def test_touching_contacts_stay_apart_by_the_dip_between_them_not_by_the_frames_peak(plain):
    grid = plain.grid
    x, y = (grid.positions / grid.pitch).T
    bump = lambda cx, cy, height, width=1.0: height * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / width)  # noqa: E731
    # a tall contact far off, and two lower ones 3 pitches apart whose grown regions touch: the
    # lower's peak (0.3) is under threshold / separation (1/3) of the frame's, but the dip between
    # them sinks to nearly nothing, far below 0.6 of it
    apart = np.maximum.reduce([bump(6, 3, 1.0), bump(-5, -1, 0.45), bump(-2, -1, 0.3)])
    labels, _ = _labels(plain, apart)
    assert labels.max() == 3
    assert labels[np.argmin(np.hypot(x + 5, y + 1))] != labels[np.argmin(np.hypot(x + 2, y + 1))]
    # the same two with a ridge between them that stays above 0.6 of the lower peak: one contact
    ridge = 0.2 * np.exp(-((y + 1) ** 2) / 0.3) * ((x >= -5) & (x <= -2))
    labels, _ = _labels(plain, np.maximum(apart, ridge))
    assert labels.max() == 2
    assert labels[np.argmin(np.hypot(x + 5, y + 1))] == labels[np.argmin(np.hypot(x + 2, y + 1))]


def test_a_hole_holding_load_in_a_contact_joins_it(plain):
    grid = plain.grid
    x, y = (grid.positions / grid.pitch).T
    r = np.hypot(x + 2, y)
    # a ring of load (a flat punch's rim on a thin layer) around a centre under the threshold; the
    # centre's nodes within a pitch of the hole's middle are beyond the margin of the ring
    middle = r <= 1.0
    for centre, joins in ((0.1, True), (-0.1, False)):
        normal = np.where(r <= 3.3, 1.0, -0.01)
        normal[r <= 2.1] = centre
        labels, near = _labels(plain, normal)
        assert labels.max() == 1 == near.shape[1]
        assert (labels[middle] == 1).all() if joins else (labels[middle] == 0).all()
    # a ring open to the skin's outer nodes encloses nothing: its middle on the border stays out
    normal = np.where(np.hypot(x + 7, y) <= 2.3, 1.0, -0.01)
    normal[np.hypot(x + 7, y) <= 1.1] = 0.1
    labels, _ = _labels(plain, normal)
    assert labels.max() == 1 and labels[np.isclose(x, -7) & np.isclose(y, 0)] == 0
    # a gap enclosed by two contacts belongs to neither
    pair = np.maximum(np.where((np.abs(x + 3) <= 1) & (np.abs(y) <= 3), 1.0, -0.01),
                      np.where((np.abs(x - 1) <= 1) & (np.abs(y) <= 3), 0.9, -0.01))
    pair[(np.abs(x + 1) <= 0.1) & (np.abs(y) <= 3)] = 0.1  # the gap between them, under the threshold
    labels, _ = _labels(plain, pair, separation=0.6)
    assert labels.max() == 2


def _lattice_field(low):
    # one tall narrow load and a lattice of broad low bumps (``low`` of its peak) 4 pitches apart,
    # each touching its neighbours once grown, on a 24 x 24 grid of unit pitch
    n = 24
    ix, iy = np.meshgrid(np.arange(n), np.arange(n))
    positions = np.column_stack([ix.ravel(), iy.ravel()]).astype(float)
    x, y = positions.T
    field = np.full(n * n, -0.01)
    for cx in range(2, n, 4):
        for cy in range(2, n, 4):
            field = np.maximum(field, low * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 4.0))
    return positions, np.maximum(field, np.exp(-((x - 12) ** 2 + (y - 12) ** 2) / 0.3))


@pytest.mark.parametrize("low", [0.26, 0.30, 0.34, 0.6])
def test_bumps_all_over_the_skin_join_whatever_sets_them_apart(low):
    # pieces a deep dip sets apart count towards SEPARATE_MOST as the tall ones do: a lattice of
    # low bumps (36 of them) is noise, not 36 touches, below threshold / separation (1/3) too
    positions, field = _lattice_field(low)
    tree = cKDTree(positions)
    adjacent, margin, near = (neighbours_within(tree, d) for d in (1.5, 1.0001, 3.0001))
    labels, _ = contact_labels(field, 0.2, 0.6, positions, adjacent, margin, near, np.zeros(field.size, bool))
    assert labels.max() == 1


@pytest.mark.parametrize("jitter", [0.0, 0.05, 0.1])
def test_a_hole_is_filled_on_a_layout_whose_nodes_are_off_place(jitter):
    # the outline is where a node's neighbours leave a side open, not where it has fewer of them:
    # with nodes a tenth of a pitch off place, diagonal neighbours fall out of reach inside too
    rng = np.random.default_rng(4)  # fixed layouts
    ix, iy = np.meshgrid(np.arange(15), np.arange(15))
    for _ in range(5):
        positions = np.column_stack([ix.ravel(), iy.ravel()]).astype(float)
        positions += rng.uniform(-jitter, jitter, positions.shape)
        r = np.hypot(*(positions - 7).T)
        field = np.where(r <= 4.3, 1.0, -0.01)
        field[r <= 3.1] = 0.1  # a rim above the threshold around a middle below it
        tree = cKDTree(positions)
        adjacent, margin, near = (neighbours_within(tree, d) for d in (1.5, 1.0001, 3.0001))
        labels, _ = contact_labels(field, 0.2, 0.6, positions, adjacent, margin, near,
                                   np.zeros(field.size, bool))
        assert labels.max() == 1 and (labels[r <= 4.3] == 1).all()
        # the skin's own border is the outline: the background around the ring stays out
        assert (labels[r > 5.5] == 0).all()

def test_a_node_between_two_contacts_goes_to_the_nearer(plain):
    grid = plain.grid
    x = grid.positions[:, 0] / grid.pitch
    normal = np.where(np.abs(grid.positions[:, 1]) < 1e-9, 0.0, -1.0)
    normal[np.isclose(x, -2)] = 1.0  # two single-node cores on the middle row, 3 pitches apart
    normal[np.isclose(x, 1)] = 1.0
    normal = np.where(np.abs(grid.positions[:, 1]) < 1e-9, normal, -1.0)
    r = DenseSolver(plain.grid, kernel="cell", region_margin=2)
    labels, _ = _labels(r, normal)
    left, right = labels[np.isclose(x, -2) & (normal > 0)][0], labels[np.isclose(x, 1) & (normal > 0)][0]
    assert left != right
    row = np.abs(grid.positions[:, 1]) < 1e-9
    # grown by 2 pitches the two regions overlap: each node goes to the nearer core, and neither region
    # takes the other's core
    assert labels[row & np.isclose(x, -1)][0] == left and labels[row & np.isclose(x, 0)][0] == right
    assert labels[row & np.isclose(x, -4)][0] == left and labels[row & np.isclose(x, 3)][0] == right


def _reach(solver, labels, count):
    # brute force: a sensor is near a contact when it is within reach of one of its nodes
    indptr, indices = solver._near
    reach = np.zeros((labels.size, count), bool)
    for i in np.flatnonzero(labels):
        reach[indices[indptr[i]:indptr[i + 1]], labels[i] - 1] = True
    return reach


@pytest.fixture(scope="module")
def square():
    return DenseSolver(SensorGrid.regular(15, 15, 1e-3, 1e-3), kernel="cell")


@pytest.mark.parametrize("angle", [0.0, 0.5, 1.2, -2.0])
def test_an_elongated_contact_is_halved_across_its_long_axis(square, angle):
    grid = square.grid
    x, y = (grid.positions / grid.pitch).T
    u, v = np.cos(angle) * x + np.sin(angle) * y, -np.sin(angle) * x + np.cos(angle) * y
    long_one = np.exp(-(u ** 2 / 10.0 + v ** 2 / 1.2))  # about 3 times as long as wide, centred inside
    round_one = np.exp(-((x - 5) ** 2 + (y - 2) ** 2) / 1.5)
    on_border = np.exp(-((x + 7) ** 2 + 3 * (y + 1) ** 2) / 2.0)  # elongated too, but on the left column
    normal = long_one + round_one + on_border - 0.05  # a little negative load, which weighs nothing
    labels = np.zeros(grid.size, np.int64)
    labels[long_one > 0.1], labels[round_one > 0.1], labels[on_border > 0.1] = 1, 2, 3
    at_edge = np.array([(labels == k)[grid.border].any() for k in (1, 2, 3)])
    assert list(at_edge) == [False, False, True]
    halved, near = halved_labels(normal, labels, at_edge, grid.positions, 1.5, square._near)
    # the first contact's nodes on either side of the line through its centre of (positive) load
    # across its long axis (the principal axis of the load's second moments)
    mine = np.flatnonzero(labels == 1)
    w = np.clip(normal[mine], 0, None)
    centre = w @ grid.positions[mine] / w.sum()
    offset = grid.positions[mine] - centre
    axis = np.linalg.eigh((offset * w[:, None]).T @ offset)[1][:, 1]
    assert abs(abs(axis @ [np.cos(angle), np.sin(angle)]) - 1) < 0.05  # the load's own long axis
    beyond = offset @ axis > 0  # (the axis's sign is either)
    halves = {frozenset(np.flatnonzero(halved == 1)), frozenset(np.flatnonzero(halved == 4))}
    assert halves == {frozenset(mine[beyond]), frozenset(mine[~beyond])}
    assert 0.3 < beyond.mean() < 0.7
    # the round contact and the one on the border stay whole, nothing else moves
    np.testing.assert_array_equal(halved[labels != 1], labels[labels != 1])
    np.testing.assert_array_equal(near, _reach(square, halved, 4))


def test_no_contact_long_enough_is_halved(plain):
    grid = plain.grid
    x, y = (grid.positions / grid.pitch).T
    normal = np.exp(-(x ** 2 / 6.0 + y ** 2 / 1.5))  # second moments 4 : 1 where positive
    labels = (normal > 0.1).astype(np.int64)
    tiny = np.zeros(grid.size, np.int64)
    tiny[np.argsort(-normal)[:3]] = 1  # three nodes: too few to halve, however long
    for elongation, given in ((1.5, tiny), (2.5, labels), (np.inf, labels)):
        halved, near = halved_labels(normal, given, np.array([False]), grid.positions, elongation, plain._near)
        np.testing.assert_array_equal(halved, given)
        np.testing.assert_array_equal(near, _reach(plain, given, 1))
    assert halved_labels(normal, labels, np.array([False]), grid.positions, 1.5, plain._near)[1].shape[1] == 2

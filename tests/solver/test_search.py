"""Tests of solver/search.py: the compiled, warm-started Lawson-Hanson NNLS against scipy."""

import numpy as np
import pytest
from scipy import sparse
from scipy.optimize import nnls

import solver.search as search
from solver import Reconstructor, RegionSolver, SensorGrid, loads
from solver.search import contact_labels, load_patches, template_misfit


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


def test_after_warm_up_a_recorded_frame_compiles_nothing():
    # recordings and the live board hand over read-only frames; numba compiles a function again
    # for each new kind of array, which on the app's first solve cost 0.18 s (found in review)
    compiled = {name: f for name, f in vars(search).items() if hasattr(f, "signatures")}
    before = {name: len(f.signatures) for name, f in compiled.items()}
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    x, y = grid.positions.T
    for kernel in ("layer", "cell", "point"):
        r = Reconstructor(grid, kernel=kernel)
        frame = (r.matrix[:, 2 * grid.size:] @ np.exp(-(x ** 2 + y ** 2) / (2 * 3e-3 ** 2))).reshape(grid.shape)
        frame.setflags(write=False)
        for parameters in ({}, dict(shear_ratio=0.2, shear_direction=0.3), dict(shear_direction=0.3),
                           dict(shear_ratio=0.2), dict(shear_ratio=0.2, shear_direction=0.3, exact=False)):
            assert r.solve(frame, **parameters).contacts, (kernel, parameters)
    # the large-skin path finds its windows on the frame itself
    large = SensorGrid.regular(32, 32, 2e-3, 2e-3)
    frame = loads.simulate(large, loads.hertz((1e-3, -2e-3), 4e-3, 1.0, shear_ratio=0.2)).stress
    assert not frame.flags.writeable
    assert RegionSolver(large).solve(frame).contacts
    assert {name: len(f.signatures) for name, f in compiled.items()} == before


@pytest.mark.parametrize("threshold", [1.0, 2.0])
def test_no_contact_when_nothing_is_above_the_threshold(threshold):
    r = Reconstructor(SensorGrid.regular(4, 4, 1e-3, 1e-3), kernel="cell")
    normal = np.linspace(0.1, 1.0, 16)
    labels, near = contact_labels(normal, threshold, r._adjacent, r._margin, r._near)
    assert labels.shape == (16,) and not labels.any() and near.shape == (16, 0)
    labels, near = contact_labels(normal, 0.95, r._adjacent, r._margin, r._near)  # the peak node alone
    assert labels.max() == 1 and near.shape == (16, 1) and near[15, 0]

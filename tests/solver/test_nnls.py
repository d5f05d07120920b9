import numpy as np
import pytest
from scipy.optimize import nnls

from solver.nnls import nnls_gram


@pytest.mark.parametrize("seed", range(40))
def test_matches_scipy_nnls_cold_and_warm(seed):
    rng = np.random.default_rng(seed)  # one random problem per seed
    m, r = rng.integers(3, 60), rng.integers(1, 30)
    A = rng.standard_normal((m, r))
    b = rng.standard_normal(m)
    reference, _ = nnls(A, b)
    objective = lambda v: np.sum((A @ v - b) ** 2)  # noqa: E731
    for passive in (None, rng.random(r) < 0.5, np.ones(r, dtype=bool)):
        g, support = nnls_gram(A.T @ A, A.T @ b, passive=passive)
        assert np.all(g >= 0)
        np.testing.assert_array_equal(support, g > 0)
        assert objective(g) <= objective(reference) + 1e-10 * (b @ b)
        # KKT: gradient non-positive on the zero set, zero on the support
        w = A.T @ (b - A @ g)
        assert np.all(w[~support] <= 1e-8 * np.abs(A.T @ b).max())
        np.testing.assert_allclose(w[support], 0, atol=1e-8 * np.abs(A.T @ b).max())


def test_empty_problem():
    g, support = nnls_gram(np.zeros((0, 0)), np.zeros(0))
    assert g.shape == (0,) and support.shape == (0,)


def test_shape_mismatch_is_reported():
    with pytest.raises(ValueError, match=r"gram must have shape \(3, 3\) to match rhs, got \(2, 2\)"):
        nnls_gram(np.eye(2), np.ones(3))

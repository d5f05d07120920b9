"""Non-negative least squares, warm-started: ``argmin_{g >= 0} |A g - b|``.

The contact fit solves many NNLS problems that differ only a little from
the previous one (the next Gauss-Newton trial, the shrunk parameters), on
more sub-cell columns than sensors. Lawson and Hanson's active-set method
fits that case when it can start from a guessed positive set and update the
Cholesky factor of that set's Gram matrix as columns come and go: adding a
column costs one triangular solve, removing one a sweep of Givens
rotations, where solving each set afresh costs a factorization.
``scipy.optimize.nnls`` has neither a warm start nor updates, so this module
compiles the method with numba; scipy stays the fallback for the degenerate
problems the updated factor cannot hold (``docs/efficiency.md`` has the
measurements that justify the compiled code).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.optimize import lsq_linear, nnls

__all__ = ["nonnegative_fit"]

# Columns whose remaining norm after projecting out the set's columns is below this fraction
# of their own norm are taken as dependent: the factor could not stay positive definite.
_DEPENDENT = 1e-12


def nonnegative_fit(matrix, stress, *, support=None, max_swaps=None):
    """``argmin_{g >= 0} |matrix g - stress|``, warm-started from a guessed support.

    Parameters
    ----------
    matrix : (R, n) ndarray
    stress : (R,) ndarray
    support : (n,) ndarray of bool, optional
        The guessed positive set; it is not modified. Default: none (a cold
        start from the empty set).
    max_swaps : int, optional
        Changes of the positive set tried before falling back to
        ``scipy.optimize.nnls``. Default ``3 n + 10`` (a cold start on the
        contact fit's problems needs about ``0.7 n``).

    Returns
    -------
    g : (n,) ndarray
        The minimizer, ``g >= 0``.
    """
    n = matrix.shape[1]
    columns = np.ascontiguousarray(matrix.T, dtype=float)  # column j contiguous: columns[j]
    b = np.ascontiguousarray(stress, dtype=float)
    guess = np.zeros(n, dtype=bool) if support is None else np.array(support, dtype=bool)
    g = np.zeros(n)
    factor, index = workspace(columns)
    steps, _ = lawson_hanson(columns, b, guess, 3 * n + 10 if max_swaps is None else int(max_swaps), g,
                             factor, index)
    if steps >= 0:
        return g
    try:
        return nnls(matrix, stress, maxiter=30 * max(n, 1))[0]
    except RuntimeError:
        return lsq_linear(matrix, stress, bounds=(0.0, np.inf), method="bvls").x


@numba.njit(cache=True, fastmath={"reassoc", "contract"}, inline="always")
def _dot(x, y):
    # reassociation lets LLVM vectorize the sum; these are the method's inner products
    total = 0.0
    for r in range(x.shape[0]):
        total += x[r] * y[r]
    return total


@numba.njit(cache=True)
def _append(factor, k, gram, diagonal):
    # Border the k x k lower factor with a column whose Gram entries with the set are ``gram``:
    # row k is L^-1 gram and the new diagonal what is left of the column's squared norm.
    for i in range(k):
        total = gram[i]
        for j in range(i):
            total -= factor[i, j] * factor[k, j]
        factor[k, i] = total / factor[i, i]
    rest = diagonal
    for j in range(k):
        rest -= factor[k, j] * factor[k, j]
    if rest <= _DEPENDENT * diagonal:
        return False
    factor[k, k] = np.sqrt(rest)
    return True


@numba.njit(cache=True)
def _remove(factor, k, p):
    # Drop row and column p of the k x k factor: the rows below move up and are then lower
    # Hessenberg; Givens rotations on column pairs (i, i + 1) make them triangular again.
    for i in range(p, k - 1):
        for j in range(i + 2):
            factor[i, j] = factor[i + 1, j]
    for i in range(p, k - 1):
        a, b = factor[i, i], factor[i, i + 1]
        radius = np.hypot(a, b)
        c, s = a / radius, b / radius
        for t in range(i, k - 1):
            x, y = factor[t, i], factor[t, i + 1]
            factor[t, i] = c * x + s * y
            factor[t, i + 1] = c * y - s * x
    for i in range(k):
        factor[i, k - 1] = 0.0
        factor[k - 1, i] = 0.0


@numba.njit(cache=True)
def _solve(factor, k, rhs, z):
    # (L L^T) z = rhs by two triangular solves
    for i in range(k):
        total = rhs[i]
        for j in range(i):
            total -= factor[i, j] * z[j]
        z[i] = total / factor[i, i]
    for i in range(k - 1, -1, -1):
        total = z[i]
        for j in range(i + 1, k):
            total -= factor[j, i] * z[j]
        z[i] = total / factor[i, i]


@numba.njit(cache=True)
def workspace(columns):
    """The factor and set buffers of :func:`lawson_hanson` for ``columns`` (n, R)."""
    size = min(columns.shape[0], columns.shape[1])
    return np.zeros((size + 1, size + 1)), np.empty(size + 1, np.int64)


@numba.njit(cache=True)
def lawson_hanson(columns, b, free, max_steps, g, factor, index):
    # Lawson-Hanson from the guessed set ``free`` (changed in place: the final set); the
    # answer goes to g, the set's Cholesky factor to factor[:k, :k] and its columns to
    # index[:k]. Returns (changes of the set made, k); the changes are -1 when the method
    # stopped short of the optimum (a full set, or more than max_steps changes): g is then
    # feasible, not optimal. A column dependent on the set never enters it.
    n, rows = columns.shape
    size = min(rows, n)
    gram = np.empty(size + 1)
    rhs = np.empty(size + 1)
    z = np.empty(size + 1)
    correlation = np.empty(n)                     # A^T b
    norm2 = np.empty(n)
    barred = np.zeros(n, np.bool_)
    largest = 0.0
    for j in range(n):
        g[j] = 0.0
        correlation[j] = _dot(columns[j], b)
        norm2[j] = _dot(columns[j], columns[j])
        largest = max(largest, abs(correlation[j]))
    tolerance = 1e-10 * n * largest
    k = 0
    guess = np.flatnonzero(free)
    free[:] = False
    if 0 < guess.size <= size:
        # the guessed set's factor at once (BLAS and LAPACK) unless one of its columns depends
        # on the others; then column by column below, which leaves such columns out
        block = columns[guess]
        try:
            lower = np.linalg.cholesky(block @ block.T)
            independent = True
            for i in range(guess.size):
                independent &= lower[i, i] ** 2 > _DEPENDENT * norm2[guess[i]]
            if independent:
                k = guess.size
                factor[:k, :k] = lower
                index[:k] = guess
                free[guess] = True
        except Exception:  # not positive definite
            pass
    if k == 0:
        for j in guess:
            if k < size:
                for i in range(k):
                    gram[i] = _dot(columns[index[i]], columns[j])
                if _append(factor, k, gram, norm2[j]):
                    index[k] = j
                    free[j] = True
                    k += 1
    steps = 0
    # a guessed set: drop the variables its least-squares solution does not keep positive
    while k > 0:
        for i in range(k):
            rhs[i] = correlation[index[i]]
        _solve(factor, k, rhs, z)
        dropped = False
        for i in range(k - 1, -1, -1):
            if z[i] <= 0:
                dropped = True
                free[index[i]] = False
                _remove(factor, k, i)
                for t in range(i, k - 1):
                    index[t] = index[t + 1]
                k -= 1
        if not dropped:
            for i in range(k):
                g[index[i]] = z[i]
            break
        steps += 1
        if steps > max_steps:
            return -1, k
    while True:
        # optimal on the set: the variable outside it with the steepest descent enters
        residual = b.copy()
        for i in range(k):
            residual -= g[index[i]] * columns[index[i]]
        while True:
            entering = -1
            best = tolerance
            for j in range(n):
                if not free[j] and not barred[j]:
                    slope = _dot(columns[j], residual)
                    if slope > best:
                        best, entering = slope, j
            if entering < 0:
                return steps, k
            if k >= size:
                return -1, k
            for i in range(k):
                gram[i] = _dot(columns[index[i]], columns[entering])
            if _append(factor, k, gram, norm2[entering]):
                break
            barred[entering] = True
        steps += 1
        if steps > max_steps:
            return -1, k
        index[k] = entering
        free[entering] = True
        k += 1
        # least squares on the set; while a variable is not positive, step from the current g
        # (feasible) towards it until the first variable reaches zero, and drop those at zero
        while True:
            for i in range(k):
                rhs[i] = correlation[index[i]]
            _solve(factor, k, rhs, z)
            blocking = -1
            step = 1.0
            for i in range(k):
                if z[i] <= 0:
                    current = g[index[i]]
                    ratio = current / max(current - z[i], 1e-300)
                    if blocking < 0 or ratio < step:
                        step, blocking = ratio, i
            if blocking < 0:
                for i in range(k):
                    g[index[i]] = z[i]
                break
            steps += 1
            if steps > max_steps:
                return -1, k
            for i in range(k):
                current = g[index[i]]
                g[index[i]] = current + step * (z[i] - current)
            g[index[blocking]] = 0.0
            for i in range(k - 1, -1, -1):
                if g[index[i]] <= 0:
                    g[index[i]] = 0.0
                    free[index[i]] = False
                    _remove(factor, k, i)
                    for t in range(i, k - 1):
                        index[t] = index[t + 1]
                    k -= 1

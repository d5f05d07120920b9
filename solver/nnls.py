"""Non-negative least squares in Gram form, warm-startable.

The contact-fit search solves many small NNLS problems whose matrices differ
only slightly from one candidate to the next. Working on the Gram matrix
``H = A^T A`` (``r x r``) instead of ``A`` (``m x r``) and starting from the
previous active set makes each solve a handful of small Cholesky solves.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

__all__ = ["nnls_gram"]


_potrf = scipy.linalg.lapack.dpotrf
_potrs = scipy.linalg.lapack.dpotrs


def _solve_spd(matrix, rhs):
    # LAPACK directly: these systems are tiny and called often, so wrapper
    # overhead would dominate.
    factor, info = _potrf(matrix, lower=1, clean=0)
    if info == 0:
        solution, info = _potrs(factor, rhs, lower=1)
        if info == 0:
            return solution
    return np.linalg.lstsq(matrix, rhs, rcond=None)[0]


def nnls_gram(gram, rhs, *, passive=None, tol=None, max_iterations=None):
    """Solve ``min_{g >= 0} |A g - b|^2`` given ``gram = A^T A`` and ``rhs = A^T b``.

    Lawson-Hanson active-set method on the normal equations.

    Parameters
    ----------
    gram : (r, r) ndarray
        Symmetric positive semi-definite ``A^T A``.
    rhs : (r,) ndarray
        ``A^T b``.
    passive : (r,) ndarray of bool, optional
        Warm start: the variables expected to be positive (for instance the
        solution of a neighbouring problem). Default: none.
    tol : float, optional
        Optimality tolerance on the gradient ``rhs - gram @ g``. Default
        ``1e-10 * max(|rhs|) * r``.
    max_iterations : int, optional
        Outer iterations. Default ``3 r``.

    Returns
    -------
    g : (r,) ndarray
        The minimizer, ``g >= 0``.
    passive : (r,) ndarray of bool
        Where ``g > 0``.
    """
    r = rhs.shape[0]
    if gram.shape != (r, r):
        raise ValueError(f"gram must have shape ({r}, {r}) to match rhs, got {gram.shape}")
    g = np.zeros(r)
    if r == 0:
        return g, np.zeros(0, dtype=bool)
    if tol is None:
        tol = 1e-10 * float(np.abs(rhs).max(initial=0.0)) * r
    if max_iterations is None:
        max_iterations = 3 * r
    free = np.zeros(r, dtype=bool) if passive is None else np.array(passive, dtype=bool)

    # Warm start: solve on the guessed set and drop variables until all are
    # positive, which gives a feasible point on a face of the orthant.
    while free.any():
        z = _solve_spd(gram[np.ix_(free, free)], rhs[free])
        if np.all(z > 0):
            g[free] = z
            break
        idx = np.flatnonzero(free)
        free[idx[z <= 0]] = False

    for _ in range(max_iterations):
        # KKT: the gradient w = A^T (b - A g) must be <= 0 on the active (zero) set.
        w = rhs - gram @ g
        w[free] = -np.inf
        j = int(np.argmax(w))
        if w[j] <= tol:
            break
        free[j] = True
        while True:
            idx = np.flatnonzero(free)
            z = _solve_spd(gram[np.ix_(idx, idx)], rhs[idx])
            if np.all(z > 0):
                g[:] = 0.0
                g[idx] = z
                break
            # Step from g towards z until the first variable reaches zero.
            negative = np.flatnonzero(z <= 0)
            current = g[idx]
            ratios = current[negative] / (current[negative] - z[negative])
            k = int(np.argmin(ratios))
            g[idx] = current + ratios[k] * (z - current)
            g[idx[negative[k]]] = 0.0
            leaving = idx[g[idx] <= 0]
            g[leaving] = 0.0
            free[leaving] = False
            if not free.any():
                break
    return g, g > 0

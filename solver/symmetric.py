"""The inverse of a symmetric positive (semi-)definite matrix, Tikhonov-damped when ill-conditioned.

``Cz`` and ``C C^T`` of a dense skin are inverted once per geometry
(:class:`solver.inverse.DenseSolver`); a solve is then one product with the
inverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .arrays import read_only

__all__ = ["SymmetricInverse"]


@dataclass(frozen=True)
class SymmetricInverse:
    """Inverse of a symmetric positive (semi-)definite matrix, damped if needed.

    Attributes
    ----------
    inverse : (n, n) ndarray
        ``(A + lambda I)^-1``, symmetric, read-only (the identity for an
        all-zero matrix, whose equations say nothing).
    shift : float
        ``lambda`` added to the diagonal before inverting (0 when the matrix
        was well enough conditioned).
    condition : float
        1-norm condition estimate of the matrix actually inverted.
    condition_undamped : float
        The same for the matrix as given (``inf`` when it was numerically
        singular).
    """

    inverse: np.ndarray
    shift: float
    condition: float
    condition_undamped: float

    @classmethod
    def of(cls, matrix: np.ndarray, *, max_condition: float) -> SymmetricInverse:
        # Tikhonov damping: (A + lambda I) with lambda = |A|_1 / max_condition
        # bounds cond(A + lambda I) by about max_condition + 1 and leaves the
        # well-conditioned cases exact (lambda = 0).
        norm = float(np.linalg.norm(matrix, 1)) if matrix.size else 0.0
        if norm == 0.0:
            return cls(read_only(np.eye(matrix.shape[0])), 0.0, 1.0, 1.0)
        undamped, shift = math.inf, 0.0
        try:
            factor = scipy.linalg.cholesky(matrix, lower=True, check_finite=False)
            undamped = _condition_from_cholesky(factor, norm)
        except np.linalg.LinAlgError:
            pass
        condition = undamped
        if undamped > max_condition:
            shift = norm / max_condition
            factor = scipy.linalg.cholesky(matrix + shift * np.eye(matrix.shape[0]), lower=True,
                                           check_finite=False)
            condition = _condition_from_cholesky(factor, norm + shift)
        # The inverse itself, not the factor: a product with it costs a fifth of LAPACK's two
        # triangular solves on one right-hand side (6 against 25 us at m = 256, measured), and
        # with the condition bounded by max_condition its rounding is that of the solves.
        inverse, info = scipy.linalg.lapack.dpotri(np.asfortranarray(factor), lower=1, overwrite_c=1)
        if info != 0:
            raise ValueError(f"dpotri failed with info={info}")
        return cls(read_only(_symmetric_from_lower(inverse)), shift, condition, undamped)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``(A + lambda I)^-1 rhs`` for ``rhs`` of shape ``(n,)`` or ``(n, k)``."""
        return self.inverse @ rhs


def _symmetric_from_lower(lower: np.ndarray) -> np.ndarray:
    # copy the lower triangle onto the upper one in blocks (np.tril(a) + np.tril(a, -1).T
    # makes three full temporaries: 1.2 s at n = 4096)
    n, block = lower.shape[0], 256
    for start in range(0, n, block):
        stop = min(start + block, n)
        diagonal = lower[start:stop, start:stop]
        diagonal[...] = np.tril(diagonal) + np.tril(diagonal, -1).T
        lower[start:stop, stop:] = lower[stop:, start:stop].T
    return lower


def _condition_from_cholesky(lower: np.ndarray, norm: float) -> float:
    rcond, info = scipy.linalg.lapack.dpocon(lower, norm, uplo="L")
    # rcond is an estimate: clamp the rounding that can put it a hair above 1
    return math.inf if rcond <= 0 else max(1.0, 1.0 / rcond)

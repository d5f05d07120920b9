"""Products with the stress matrix by FFT on a regular grid: any skin size in bounded memory.

Every kernel depends only on the offset between a sensor and a node, so on a
regular ``ny x nx`` grid ``Cz`` is block-Toeplitz: ``Cz f`` is the 2-D
convolution of the force image with the kernel on the ``(2ny-1, 2nx-1)``
offsets (:func:`solver.kernels.stress_matrix` builds the dense matrix from the
same table). A circular convolution of size at least ``2n - 1`` per axis
reproduces it exactly (no offset wraps into the part read), so a product
costs two FFTs of about ``2ny x 2nx`` and the operator takes ``O(m)`` memory:
a 128x128 skin's dense ``Cz`` would take 2 GB, its transform 0.5 MB.

:class:`NormalConvolution` solves the normal-only problem ``Cz f = b`` by
conjugate gradients on these products (``Cz`` is symmetric positive
definite), damped like :class:`solver.symmetric.SymmetricInverse` when the
layer is too thick for the grid. It is the large-skin path's answer for a
load too broad for the contact fit's budget (:class:`solver.RegionSolver`).
:class:`StressConvolution` does the same for the whole ``C = [Cx | Cy | Cz]``
(``Cx`` and ``Cy`` are odd, so ``C^T`` correlates: it convolves with the
flipped tables) and gives the paper's exact member ``x = y + C+ (b - C y)``
of a template ``y`` by conjugate gradients on ``C C^T``: the large-skin
path's answer for such a load when the shear parameters are given.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft
from scipy.sparse.linalg import LinearOperator, cg

from .checks import real_number, whole_number
from .geometry import SensorGrid
from .kernels import KERNELS, offset_tables

__all__ = ["NormalConvolution", "StressConvolution"]


class NormalConvolution:
    """``Cz`` of a regular grid as a convolution, and the normal-only solve with it.

    Parameters
    ----------
    grid : SensorGrid
        A regular grid.
    kernel : {"layer", "cell", "point"}, optional
        Stress kernel (:mod:`solver.kernels`). Default "layer".
    max_condition : float, optional
        Largest condition accepted undamped, as :class:`~solver.inverse.DenseSolver`'s;
        the condition is estimated from the kernel's transform (the
        eigenvalues of the circulant that embeds ``Cz``). Default 100.

    Attributes
    ----------
    shift : float
        ``lambda`` added to ``Cz`` (0 when well enough conditioned), pascals per newton.
    condition : float
        Condition estimate of the operator solved (damping included).
    """

    def __init__(self, grid: SensorGrid, *, kernel: str = "layer", max_condition: float = 100.0):
        self.grid, self.kernel, self._size, tables = _set_up(grid, kernel, max_condition)
        table = tables[2]
        self._transform = scipy.fft.rfft2(table, s=self._size)
        # Symmetric (every kernel is even): the circulant's eigenvalues are the real transform
        # of the table centred on offset 0; Cz is a principal block of that circulant, so its
        # eigenvalues lie between the circulant's (interlacing): an estimate from outside.
        spectrum = scipy.fft.rfft2(_centred(table, grid.shape, self._size)).real
        self.shift, self.condition = _damped(spectrum, max_condition)

    def apply(self, forces: np.ndarray) -> np.ndarray:
        """``Cz f``: the sensor stress of normal node forces ``forces`` (m,), newtons -> pascals."""
        transform = scipy.fft.rfft2(np.asarray(forces, dtype=float).reshape(self.grid.shape), s=self._size)
        return _read(transform * self._transform, self.grid.shape, self._size)

    def solve(self, stress: np.ndarray, *, tolerance: float = 1e-8, max_iterations: int = 500):
        """Normal-only forces: ``(Cz + lambda I) f = b`` by conjugate gradients.

        Parameters
        ----------
        stress : (m,) ndarray
            Sensor stress, pascals.
        tolerance : float, optional
            Relative residual at which to stop. Default 1e-8.
        max_iterations : int, optional
            At most this many products. Default 500.

        Returns
        -------
        forces : (m,) ndarray
            Normal force per node, newtons.
        iterations : int
            Products taken.
        """
        b = np.asarray(stress, dtype=float).ravel()
        return _conjugate_gradients(lambda f: self.apply(f) + self.shift * f, b, tolerance, max_iterations)


class StressConvolution:
    """``C = [Cx | Cy | Cz]`` of a regular grid as convolutions, and the exact member with it.

    Parameters
    ----------
    grid : SensorGrid
        A regular grid.
    kernel : {"layer", "cell", "point"}, optional
        Stress kernel (:mod:`solver.kernels`). Default "layer".
    max_condition : float, optional
        As :class:`~solver.inverse.DenseSolver`'s: ``C C^T`` is damped when its
        condition estimate exceeds ``max_condition ** 2`` (the dense path's
        rule). The estimate is that of the circulant embedding: it bounds the
        largest eigenvalue from above, the smallest only approximately.
        Default 100.

    Attributes
    ----------
    shift : float
        ``lambda`` added to ``C C^T`` (0 when well enough conditioned), (pascals per newton)^2.
    condition : float
        Condition estimate of ``C C^T + lambda I``.
    """

    def __init__(self, grid: SensorGrid, *, kernel: str = "layer", max_condition: float = 100.0):
        self.grid, self.kernel, self._size, tables = _set_up(grid, kernel, max_condition)
        self._forward = [scipy.fft.rfft2(table, s=self._size) for table in tables]
        # C^T correlates with the table: a convolution with the table flipped (offset d -> -d)
        self._backward = [scipy.fft.rfft2(table[::-1, ::-1], s=self._size) for table in tables]
        # the circulant embedding C C^T's symbol: sum over components of |K_c|^2
        spectrum = sum(np.abs(scipy.fft.rfft2(_centred(table, grid.shape, self._size))) ** 2
                       for table in tables)
        self.shift, self.condition = _damped(spectrum, max_condition ** 2)

    def apply(self, forces: np.ndarray) -> np.ndarray:
        """``C x``: the sensor stress of node forces ``forces`` (m, 3), newtons -> pascals."""
        shape = self.grid.shape
        x = np.asarray(forces, dtype=float).reshape(-1, 3)
        transform = sum(scipy.fft.rfft2(x[:, c].reshape(shape), s=self._size) * self._forward[c]
                        for c in range(3))
        return _read(transform, shape, self._size)

    def apply_transpose(self, stress: np.ndarray) -> np.ndarray:
        """``C^T v`` as node forces (m, 3) of a stress-like vector ``stress`` (m,)."""
        shape = self.grid.shape
        transform = scipy.fft.rfft2(np.asarray(stress, dtype=float).reshape(shape), s=self._size)
        return np.stack([_read(transform * self._backward[c], shape, self._size) for c in range(3)], axis=1)

    def member(self, template: np.ndarray, stress: np.ndarray, *, tolerance: float = 1e-8,
               max_iterations: int = 500):
        """The member of the exact family closest to a template: ``x = y + C^T w``.

        ``(C C^T + lambda I) w = b - C y`` by conjugate gradients, so
        ``C x - b = -lambda w`` (zero undamped), as
        :meth:`solver.inverse.DenseSolver.solve` gives it on a dense skin.

        Parameters
        ----------
        template : (m, 3) ndarray
            ``y``, newtons.
        stress : (m,) ndarray
            ``b``, pascals.
        tolerance : float, optional
            Relative residual of the solve for ``w`` at which to stop. Default 1e-8.
        max_iterations : int, optional
            At most this many products with ``C C^T``. Default 500.

        Returns
        -------
        forces : (m, 3) ndarray
            Newtons.
        iterations : int
            Products taken.
        """
        y = np.asarray(template, dtype=float)
        b = np.asarray(stress, dtype=float)
        if y.shape != (self.grid.size, 3) or b.shape != (self.grid.size,):
            raise ValueError(f"template must be ({self.grid.size}, 3) and stress ({self.grid.size},), got "
                             f"{np.shape(template)} and {np.shape(stress)}")
        w, iterations = _conjugate_gradients(
            lambda v: self.apply(self.apply_transpose(v)) + self.shift * v, b - self.apply(y), tolerance,
            max_iterations)
        return y + self.apply_transpose(w), iterations


def _set_up(grid, kernel, max_condition):
    # the arguments checked, the FFT size and the kernel's (x, y, z) tables on the offsets
    if not isinstance(grid, SensorGrid) or not grid.is_regular:
        raise ValueError("grid must be a regular SensorGrid (the convolution needs translation "
                         "invariance)")
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    real_number("max_condition", max_condition, rule="a finite number > 1",
                valid=lambda v: math.isfinite(v) and v > 1)
    ny, nx = grid.shape
    size = (scipy.fft.next_fast_len(2 * ny - 1, real=True), scipy.fft.next_fast_len(2 * nx - 1, real=True))
    # the kernel on the offsets, sensor minus node: offset (0, 0) at index (ny-1, nx-1)
    return grid, kernel, size, offset_tables(grid, kernel, 1, "uniform")[0]


def _damped(spectrum, limit):
    # Tikhonov damping from an operator's eigenvalue estimates, as SymmetricInverse damps: none
    # when their ratio is within ``limit``, else lambda = largest / limit. Returns (lambda, the
    # damped operator's condition estimate).
    largest, smallest = float(spectrum.max()), float(spectrum.min())
    undamped = largest / smallest if smallest > 0 else math.inf
    shift = 0.0 if undamped <= limit else largest / limit
    return shift, (largest + shift) / (smallest + shift) if smallest + shift > 0 else math.inf


def _centred(table, shape, size):
    # the table in a circulant of ``size``, offset (0, 0) at index (0, 0)
    ny, nx = shape
    centred = np.zeros(size)
    centred[:2 * ny - 1, :2 * nx - 1] = table
    return np.roll(centred, (1 - ny, 1 - nx), axis=(0, 1))


def _read(transform, shape, size):
    # the sensors' part of a circular convolution given by its transform
    ny, nx = shape
    return scipy.fft.irfft2(transform, s=size)[ny - 1:2 * ny - 1, nx - 1:2 * nx - 1].ravel()


def _conjugate_gradients(product, rhs, tolerance, max_iterations):
    # scipy's CG on a symmetric positive definite operator given by its product; counts the products
    real_number("tolerance", tolerance, rule="in (0, 1)", valid=lambda v: 0 < v < 1)
    max_iterations = whole_number("max_iterations", max_iterations, low=1)
    count = [0]

    def counted(v):
        count[0] += 1
        return product(v)

    operator = LinearOperator((rhs.size, rhs.size), matvec=counted, dtype=float)
    solution, _ = cg(operator, rhs, rtol=tolerance, atol=0.0, maxiter=max_iterations)
    return solution, count[0]

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
definite), damped like :class:`solver.inverse.SymmetricInverse` when the
layer is too thick for the grid. It is the large-skin path's answer for a
load too broad for the contact fit's budget (:class:`solver.RegionSolver`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft
from scipy.sparse.linalg import LinearOperator, cg

from .checks import real_number, whole_number
from .geometry import SensorGrid
from .kernels import KERNELS, _offset_tables

__all__ = ["NormalConvolution"]


class NormalConvolution:
    """``Cz`` of a regular grid as a convolution, and the normal-only solve with it.

    Parameters
    ----------
    grid : SensorGrid
        A regular grid.
    kernel : {"layer", "cell", "point"}, optional
        Stress kernel (:mod:`solver.kernels`). Default "layer".
    max_condition : float, optional
        Largest condition accepted undamped, as :class:`~solver.Reconstructor`'s;
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
        if not isinstance(grid, SensorGrid) or not grid.is_regular:
            raise ValueError("grid must be a regular SensorGrid (the convolution needs translation "
                             "invariance)")
        if kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
        real_number("max_condition", max_condition, rule="a finite number > 1",
                    valid=lambda v: math.isfinite(v) and v > 1)
        self.grid, self.kernel = grid, kernel
        ny, nx = grid.shape
        self._size = (scipy.fft.next_fast_len(2 * ny - 1, real=True),
                      scipy.fft.next_fast_len(2 * nx - 1, real=True))
        # the kernel on the offsets, sensor minus node: offset (0, 0) at index (ny-1, nx-1)
        table = _offset_tables(grid, kernel, 1, "uniform")[0][2]
        self._transform = scipy.fft.rfft2(table, s=self._size)
        # Symmetric (every kernel is even): the circulant's eigenvalues are the real transform
        # of the table centred on offset 0; Cz is a principal block of that circulant, so its
        # eigenvalues lie between the circulant's (interlacing): an estimate from outside.
        centred = np.zeros(self._size)
        centred[:2 * ny - 1, :2 * nx - 1] = table
        centred = np.roll(centred, (1 - ny, 1 - nx), axis=(0, 1))  # offset (0, 0) at index (0, 0)
        spectrum = scipy.fft.rfft2(centred).real
        largest, smallest = float(spectrum.max()), float(spectrum.min())
        undamped = largest / smallest if smallest > 0 else math.inf
        self.shift = 0.0 if undamped <= max_condition else largest / max_condition
        self.condition = ((largest + self.shift) / (smallest + self.shift) if smallest + self.shift > 0
                          else math.inf)

    def apply(self, forces: np.ndarray) -> np.ndarray:
        """``Cz f``: the sensor stress of normal node forces ``forces`` (m,), newtons -> pascals."""
        ny, nx = self.grid.shape
        image = np.asarray(forces, dtype=float).reshape(ny, nx)
        full = scipy.fft.irfft2(scipy.fft.rfft2(image, s=self._size) * self._transform, s=self._size)
        return full[ny - 1:2 * ny - 1, nx - 1:2 * nx - 1].ravel()

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
        real_number("tolerance", tolerance, rule="in (0, 1)", valid=lambda v: 0 < v < 1)
        max_iterations = whole_number("max_iterations", max_iterations, low=1)
        b = np.asarray(stress, dtype=float).ravel()
        m = self.grid.size
        count = [0]

        def product(f):
            count[0] += 1
            return self.apply(f) + self.shift * f

        operator = LinearOperator((m, m), matvec=product, dtype=float)
        forces, _ = cg(operator, b, rtol=tolerance, atol=0.0, maxiter=max_iterations)
        return forces, count[0]

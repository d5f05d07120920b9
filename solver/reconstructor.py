"""The one way to a solver: :class:`Reconstructor`, for a skin of any size and any quality setting.

It chooses the engine: a :class:`~solver.inverse.DenseSolver` of the whole
skin up to ``DENSE_LIMIT`` sensors (or an irregular skin), else a
:class:`~solver.region.RegionSolver` that solves each contact on its window
(a load too broad for a window by convolution over the whole skin); with a
quality setting, the engine that setting builds. No path allocates the dense
matrices of a large skin. This module sits above every engine: they never
import it.
"""

from __future__ import annotations

from dataclasses import replace

from .arguments import check_options
from .checks import shown
from .geometry import SensorGrid
from .inverse import DenseSolver
from .quality import Configuration
from .region import DENSE_LIMIT, RegionSolver
from .results import Reconstruction

__all__ = ["Reconstructor"]


class Reconstructor:
    """Contact forces from a skin's normal stress readings: the solver of a skin.

    Parameters
    ----------
    grid : SensorGrid
        Sensor layout and layer thickness, any size.
    quality : solver.quality.Configuration, optional
        A quality setting (one of :data:`solver.quality.CONFIGURATIONS`, a
        viewer preset ...): its kernel, path, sub-cells, search and damping.
        None (default): the standard solve.
    **options
        Tuning arguments of :class:`~solver.inverse.DenseSolver` (``kernel``,
        ``max_condition``, ``max_shear_ratio`` ...), all checked before any
        matrix is built. With ``quality``, ``kernel`` replaces the setting's
        and the others are passed to
        :meth:`~solver.quality.Configuration.build`.

    Attributes
    ----------
    grid : SensorGrid
    kernel : str
    engine : DenseSolver, RegionSolver or a quality setting's solver
        What solves (its own attributes, such as a dense solver's matrices,
        are for measurements and tests).

    Raises
    ------
    ValueError, TypeError
        For a bad argument, naming it (:func:`solver.arguments.check_options`).
    """

    def __init__(self, grid: SensorGrid, *, quality: Configuration | None = None, **options):
        if quality is not None:
            if not isinstance(quality, Configuration):
                raise ValueError("quality must be a solver.quality.Configuration or None, got "
                                 f"{shown(quality)}")
            others = {k: v for k, v in options.items() if k != "kernel"}
            self.engine = replace(quality, kernel=options.get("kernel", quality.kernel)).build(grid, **others)
        else:
            check_options(grid, **options)
            dense = grid.size <= DENSE_LIMIT or not grid.is_regular
            self.engine = DenseSolver(grid, **options) if dense else RegionSolver(grid, **options)
        self.grid, self.kernel = grid, self.engine.kernel

    def solve(self, stress, *, shear_ratio: float | None = None, shear_direction: float | None = None,
              exact: bool | None = None) -> Reconstruction:
        """Three-component forces of every contact, each with its own shear parameters.

        Parameters
        ----------
        stress : (m,) or (ny, nx) ndarray
            Sensor stress, pascals, compression positive.
        shear_ratio : float or None, optional
            ``mu >= 0`` for every contact. None: each contact's own, chosen by
            the efficiency functional.
        shear_direction : float or None, optional
            ``theta`` in radians. None: chosen by the efficiency functional.
        exact : bool or None, optional
            True: the member of the exact family ``C x = b`` closest to the
            fitted template; False: the fitted load itself. Default None: the
            quality setting's path, else False when both parameters are
            automatic and True otherwise (:meth:`DenseSolver.solve`).

        Returns
        -------
        Reconstruction
        """
        return self.engine.solve(stress, shear_ratio=shear_ratio, shear_direction=shear_direction,
                                 exact=exact)

    def solve_normal(self, stress) -> Reconstruction:
        """Normal forces only (``Cz f = b``, damped on thick layers).

        Parameters
        ----------
        stress : (m,) or (ny, nx) ndarray
            Sensor stress, pascals.

        Returns
        -------
        Reconstruction
        """
        return self.engine.solve_normal(stress)

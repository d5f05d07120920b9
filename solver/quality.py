"""Quality settings: how to build a solver.

A :class:`Configuration` is one way to reconstruct (kernel, path, sub-cells and
their profile, search resolution, regularization, region of interest) and builds its solver
for a grid. :data:`CONFIGURATIONS` are the settings the speed/accuracy
measurement (:mod:`measurement.tradeoff`) compares and the viewer's quality
presets are picked from; :class:`solver.Reconstructor` ``(grid, quality=...)``
builds one.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

from .arguments import check_arguments
from .checks import one_of
from .efficiency import ContactFit
from .geometry import SensorGrid
from .inverse import DenseSolver
from .region import DENSE_LIMIT, RegionSolver

__all__ = ["Configuration", "CONFIGURATIONS", "PATHS"]

PATHS = ("fit", "exact", "normal", "region")

# DenseSolver arguments a configuration sets itself: build() takes any other (max_shear_ratio ...)
_SET = ("kernel", "max_condition", "subdivision", "profile", "efficiency")
# a configuration's defaults are the solver's: written once, in the signatures
_SOLVER = inspect.signature(DenseSolver).parameters
_SEARCH = inspect.signature(ContactFit).parameters


@dataclass(frozen=True)
class Configuration:
    """One way to reconstruct.

    Attributes
    ----------
    name : str
    kernel : {"layer", "cell", "point"}
        Stress kernel (:mod:`solver.kernels`); "layer" is the skin as built,
        "cell" and "point" the paper's half-space kernels.
    path : {"fit", "exact", "normal", "region"}
        ``fit``: the fitted compressive, friction-shaped load of every contact
        (the automatic answer of :meth:`solver.inverse.DenseSolver.solve`);
        ``exact``: the member of the exact solution family at the fitted
        parameters (the paper's answer); ``normal``: normal forces only;
        ``region``: ``fit`` on one window per contact.
    subdivision : int
        Sub-cells per side of each node's cell in the contact fit (1: the
        whole cell, the previous profile).
    profile : {"bilinear", "uniform"}
        The load over each sub-cell in the contact fit (a bilinear hat, or
        uniform; :class:`~solver.inverse.DenseSolver`). Without sub-cells (the
        point kernel, ``subdivision`` 1, a layer thinner than half a
        sub-cell) there is nothing to shape; the setting is kept as given.
    iterations : int
        Gauss-Newton iterations of the automatic search (its resolution).
    tolerance : float
        Stopping tolerance of the search.
    max_condition : float
        Regularization: largest condition accepted undamped (thick layers).
    """

    name: str
    kernel: str = _SOLVER["kernel"].default
    path: str = "fit"
    subdivision: int = _SOLVER["subdivision"].default
    profile: str = _SOLVER["profile"].default
    iterations: int = _SEARCH["max_iterations"].default
    tolerance: float = _SEARCH["tolerance"].default
    max_condition: float = _SOLVER["max_condition"].default

    def __post_init__(self):
        one_of("path", self.path, PATHS)
        # the solver's own rules, so a configuration is refused when made, not when built
        check_arguments(kernel=self.kernel, subdivision=self.subdivision, profile=self.profile,
                        max_condition=self.max_condition)

    def build(self, grid: SensorGrid, **options):
        """The engine :class:`solver.Reconstructor` uses for this setting on ``grid``: an object
        with ``solve(stress, *, shear_ratio=None, shear_direction=None, exact=None)``,
        ``solve_normal(stress)``, ``grid`` and ``kernel``.

        ``options`` are further :class:`~solver.inverse.DenseSolver` arguments
        (``max_shear_ratio`` ...), checked as the solver checks them; those the
        configuration sets itself (kernel, max_condition, subdivision,
        profile, efficiency) are refused: change the configuration instead.
        """
        clash = sorted(set(options) & set(_SET))
        if clash:
            raise ValueError(f"options must not set what the configuration sets ({', '.join(_SET)}), "
                             f"got {', '.join(clash)}")
        efficiency = ContactFit(max_iterations=self.iterations, tolerance=self.tolerance)
        options = dict(options, kernel=self.kernel, max_condition=self.max_condition,
                       subdivision=self.subdivision, profile=self.profile, efficiency=efficiency)
        if self.path == "region":
            return RegionSolver(grid, **options)
        # On a large regular skin the whole skin's dense matrices would not fit (64x64: 1.6 GB,
        # 128x128: 24 GB): the setting's path runs on each contact's window instead.
        large = grid.size > DENSE_LIMIT and grid.is_regular
        return _Configured((RegionSolver if large else DenseSolver)(grid, **options), self.path)


class _Configured:
    # an engine (a DenseSolver, or a RegionSolver on a large skin) whose solve takes the path
    def __init__(self, reconstructor, path: str):
        self.reconstructor, self.path = reconstructor, path
        self.grid, self.kernel = reconstructor.grid, reconstructor.kernel

    def solve(self, stress, *, shear_ratio=None, shear_direction=None, exact=None):
        # the path's answer; ``exact`` given overrides the path's choice of member
        if self.path == "normal":
            return self.reconstructor.solve_normal(stress)
        return self.reconstructor.solve(stress, shear_ratio=shear_ratio, shear_direction=shear_direction,
                                        exact=self.path == "exact" if exact is None else exact)

    def solve_normal(self, stress):
        return self.reconstructor.solve_normal(stress)


CONFIGURATIONS = (
    Configuration("normal only", path="normal"),
    Configuration("point, exact", kernel="point", path="exact"),
    Configuration("cell, fit", kernel="cell"),
    Configuration("layer, whole-cell profile", subdivision=1),
    Configuration("layer, coarse search", iterations=2, tolerance=1e-2),
    Configuration("layer, fit"),
    Configuration("layer, exact", path="exact"),
    Configuration("layer, exact, weak damping", path="exact", max_condition=1e4),
    Configuration("layer, exact, strong damping", path="exact", max_condition=30.0),
    Configuration("layer, region of interest", path="region"),
)

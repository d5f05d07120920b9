"""The checks of a solver's arguments: tuning options, a solve's parameters, a frame of stress.

Each names the argument, the rule and what it received (``ValueError``), or
the argument a solver does not take (``TypeError``), before any matrix is
built or any product made.
"""

from __future__ import annotations

import math

import numpy as np

from .checks import one_of, optional_flag, real_number, whole_number
from .geometry import SensorGrid
from .kernels import KERNELS, PROFILES

__all__ = ["check_options", "check_arguments", "check_parameters", "check_stress", "MAX_STRESS"]


def check_options(grid, **options):
    """Check the tuning arguments of :class:`DenseSolver` given, before any matrix is built.

    Only the arguments given are checked: the defaults are :class:`DenseSolver`'s own.

    Raises
    ------
    ValueError
        Naming the argument, the rule and what was received.
    TypeError
        For an argument :class:`DenseSolver` does not take.
    """
    if not isinstance(grid, SensorGrid):
        raise ValueError(f"grid must be a SensorGrid, got {type(grid).__name__}")
    check_arguments(**options)


def check_arguments(**options):
    """:func:`check_options` without a grid: the rules of the arguments given, and nothing else."""
    for name, value in options.items():
        if name not in _OPTION_CHECKS:
            raise TypeError(f"Reconstructor got an unexpected keyword argument {name!r}")
        _OPTION_CHECKS[name](name, value)


_OPTION_CHECKS = {
    "kernel": lambda name, value: one_of(name, value, KERNELS),
    "max_condition": lambda name, value: real_number(name, value, rule="a finite number > 1",
                                                     valid=lambda v: math.isfinite(v) and v > 1),
    "max_shear_ratio": lambda name, value: real_number(name, value, rule="finite and >= 0",
                                                       valid=lambda v: math.isfinite(v) and v >= 0),
    "region_threshold": lambda name, value: real_number(name, value, rule="in (0, 1)",
                                                        valid=lambda v: 0 < v < 1),
    "region_margin": lambda name, value: whole_number(name, value, low=0, unit="of pitches "),
    "separation": lambda name, value: real_number(name, value, rule="in [0, 1]", valid=lambda v: 0 <= v <= 1),
    "subdivision": lambda name, value: whole_number(name, value, low=1, high=4),
    "profile": lambda name, value: one_of(name, value, PROFILES),
    "reach": lambda name, value: real_number(name, value, rule="finite and >= 0 thicknesses",
                                             valid=lambda v: math.isfinite(v) and v >= 0),
    "fit_budget": lambda name, value: whole_number(name, value, low=1, unit="of nodes "),
    # any object with ``choose`` (solver.efficiency); what it is, is its own affair
    "efficiency": lambda name, value: None,
}


def check_parameters(shear_ratio, shear_direction, exact):
    """Check the arguments of a solve: the shear parameters (each a real number or None) and ``exact``.

    Returns
    -------
    exact : bool
        ``exact``, or its default: True when a parameter is given (the
        sliders), False when both are automatic.

    Raises
    ------
    ValueError
        Naming the argument, the rule and what was received.
    """
    if shear_ratio is not None:
        real_number("shear_ratio", shear_ratio, rule="finite and >= 0 (or None)",
                    valid=lambda v: math.isfinite(v) and v >= 0)
    if shear_direction is not None:
        real_number("shear_direction", shear_direction, rule="finite radians (or None)", valid=math.isfinite)
    exact = optional_flag("exact", exact)
    if exact is None:
        exact = shear_ratio is not None or shear_direction is not None
    return exact


# The largest sensor stress a solve takes, pascals: far above any reading (1e12 Pa is a thousand
# times the strength of steel), far enough below the float limit that the solve's sums of squares
# cannot overflow (a frame holding 1e308 Pa made every one of them inf).
MAX_STRESS = 1e100


def check_stress(stress, grid: SensorGrid) -> np.ndarray:
    """``stress`` as a flat ``(m,)`` float array for ``grid``; ValueError says what is wrong with it.

    Every value must be finite and at most :data:`MAX_STRESS` in magnitude.
    """
    m = grid.size
    if np.iscomplexobj(stress):
        raise ValueError("stress must be real pascals, got complex values")
    try:
        b = np.asarray(stress, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"stress must be numeric, got {type(stress).__name__}") from None
    if b.size != m or (b.ndim == 2 and b.shape != tuple(grid.shape)) or b.ndim > 2:
        raise ValueError(
            f"stress must have shape ({m},) or {tuple(grid.shape)} for this grid, got {b.shape}"
        )
    b = b.ravel()
    # one pass for the usual frame: NaN fails the comparison, inf and huge values exceed it
    if np.abs(b).max(initial=0.0) <= MAX_STRESS:
        return b
    bad = ~np.isfinite(b)
    if bad.any():
        kinds = sorted({"NaN" if np.isnan(v) else "inf" for v in b[bad]})
        raise ValueError(
            f"stress must be finite, got {' and '.join(kinds)} at taxel(s) "
            f"{np.flatnonzero(bad)[:10].tolist()}"
        )
    huge = np.abs(b) > MAX_STRESS
    if huge.any():
        raise ValueError(f"stress must be at most {MAX_STRESS:g} Pa in magnitude, got {b[huge][0]:g} at "
                         f"taxel(s) {np.flatnonzero(huge)[:10].tolist()}")
    return b

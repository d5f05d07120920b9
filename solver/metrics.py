"""Error measures of reconstructed forces against known truth.

All take ``forces`` and ``truth`` of shape ``(m, 3)`` (Fx, Fy, Fz in newtons).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .checks import one_of

__all__ = [
    "Errors", "compare", "normal_total_error", "tangential_total_error",
    "direction_error", "field_error",
]


def _pair(forces, truth):
    forces = np.asarray(forces, dtype=float)
    truth = np.asarray(truth, dtype=float)
    if forces.shape != truth.shape or forces.ndim != 2 or forces.shape[1] != 3:
        raise ValueError(
            f"forces and truth must both have shape (m, 3), got {forces.shape} and {truth.shape}"
        )
    return forces, truth


def normal_total_error(forces, truth) -> float:
    """Relative error of the total normal force, ``|sum Fz - sum Fz*| / |sum Fz*|``."""
    forces, truth = _pair(forces, truth)
    reference = abs(truth[:, 2].sum())
    if reference == 0:
        return math.nan
    return float(abs(forces[:, 2].sum() - truth[:, 2].sum()) / reference)


def tangential_total_error(forces, truth) -> float:
    """Error of the total tangential force vector relative to the total force magnitude.

    ``|sum Ft - sum Ft*| / |sum F*|`` with ``Ft = (Fx, Fy)``: 0.1 means the
    resultant shear is off by 10% of the contact force, in size or direction.
    """
    forces, truth = _pair(forces, truth)
    reference = np.linalg.norm(truth.sum(0))
    if reference == 0:
        return math.nan
    return float(np.linalg.norm(forces[:, :2].sum(0) - truth[:, :2].sum(0)) / reference)


def direction_error(forces, truth) -> float:
    """Angle between estimated and true resultant shear, degrees in [0, 180].

    ``nan`` when the truth has no resultant shear; 180 when the truth has
    shear and the estimate none.
    """
    forces, truth = _pair(forces, truth)
    true_shear = truth[:, :2].sum(0)
    estimate = forces[:, :2].sum(0)
    if np.linalg.norm(true_shear) == 0:
        return math.nan
    if np.linalg.norm(estimate) == 0:
        return 180.0
    angle = math.atan2(estimate[1], estimate[0]) - math.atan2(true_shear[1], true_shear[0])
    return float(abs(math.degrees(math.remainder(angle, 2 * math.pi))))


def field_error(forces, truth, component: str = "all") -> float:
    """Relative L2 error of the nodal field: ``|F - F*| / |F*|``.

    Parameters
    ----------
    component : {"all", "normal", "tangential"}
        Which components enter (``tangential`` is still relative to the whole ``|F*|``).
    """
    forces, truth = _pair(forces, truth)
    columns = {"all": slice(0, 3), "normal": slice(2, 3), "tangential": slice(0, 2)}
    one_of("component", component, tuple(columns))
    reference = np.linalg.norm(truth)
    if reference == 0:
        return math.nan
    c = columns[component]
    return float(np.linalg.norm(forces[:, c] - truth[:, c]) / reference)


@dataclass(frozen=True)
class Errors:
    """All error measures of one reconstruction (see the functions of this module)."""

    normal_total: float
    tangential_total: float
    direction_deg: float
    field: float

    def as_dict(self) -> dict:
        return dict(normal_total=self.normal_total, tangential_total=self.tangential_total,
                    direction_deg=self.direction_deg, field=self.field)


def compare(forces, truth) -> Errors:
    """Every measure at once."""
    return Errors(normal_total_error(forces, truth), tangential_total_error(forces, truth),
                  direction_error(forces, truth), field_error(forces, truth))

"""What a solve returns: :class:`Reconstruction`, the forces of one frame, and its :class:`Contact` s.

Frozen, their arrays read-only: a result may be shared between threads and kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Reconstruction", "Contact", "shear_direction_of"]


@dataclass(frozen=True)
class Contact:
    """One contact of a frame and its own parameters.

    Attributes
    ----------
    nodes : (m,) ndarray of bool
        The contact's region on the skin (the nodes allowed to carry its load).
    shear_ratio : float
        Tangential over normal force of its template load (dimensionless).
    shear_direction : float
        Radians from +x in ``(-pi, pi]``.
    evidence : float
        F statistic of its shear against a shear-free load, from the sensors
        near it (``nan`` when the shear ratio was given).
    shear_detected : bool
        Whether the automatic search kept shear on it.
    at_edge : bool
        Its region touches the skin's border: part of its stress field is not
        sensed, so its shear is less certain than an inner contact's.
    total_force : (3,) ndarray
        Its resultant (Fx, Fy, Fz), newtons.
    centre : (2,) ndarray
        Where its compressive normal load is centred (the ``Fz``-weighted mean
        of its nodes' positions over ``Fz > 0``), metres.
    identity : int
        Its number while it persists from frame to frame
        (:class:`solver.tracking.ContactTracker`, from 1); 0 when the frame was
        solved on its own.
    """

    nodes: np.ndarray
    shear_ratio: float
    shear_direction: float
    evidence: float
    shear_detected: bool
    at_edge: bool
    total_force: np.ndarray
    centre: np.ndarray
    identity: int = 0


@dataclass(frozen=True)
class Reconstruction:
    """Reconstructed surface forces of one frame.

    Attributes
    ----------
    forces : (m, 3) ndarray
        Force per node (Fx, Fy, Fz), newtons; ``Fz > 0`` presses into the skin.
    shear_ratio : float
        Tangential over normal force of the template load of the largest
        contact (dimensionless); every contact's own is in ``contacts``.
    shear_direction : float
        Its direction, radians from +x in ``(-pi, pi]``.
    efficiency : float
        Value of the efficiency functional at the chosen parameters (``nan``
        on the normal-only path).
    residual : float
        ``|C x - b| / |b|`` (0 for an all-zero frame). The exact member
        reports ``lambda |w| / |b|`` (``lambda`` the damping, 0 undamped), its
        value in exact arithmetic: the inverse's rounding, up to about
        ``max_condition^2`` times 1e-16, is not in it (1e-12 at the default).
    condition : float
        Condition estimate of the matrix inverted for this solve
        (``C C^T`` for three components, ``Cz`` for normal only), damping included.
    regularized : bool
        Whether Tikhonov damping entered the answer because the layer is too
        thick for the grid (the condition exceeded the reconstructor's limit).
    normal_only : bool
        True when the tangential components were not reconstructed.
    shear_detected : bool
        Whether the automatic search kept shear on any contact (False when
        the parameters were given).
    exact : bool
        True when the forces are the member of the exact family ``C x = b``;
        False when they are the fitted compressive load (automatic solves).
    region : (m,) ndarray of bool
        Nodes allowed to carry load (every contact's region).
    contacts : tuple of Contact
        Every contact with its own parameters, largest normal force first.
    fallback : str
        Why the answer is a cheaper member than the solver's accurate path,
        and which; empty when it took the accurate path (a load too broad for
        the contact fit's budget gets the normal-only answer, or with given
        parameters the paper's template from it).
    """

    forces: np.ndarray
    shear_ratio: float
    shear_direction: float
    efficiency: float
    residual: float
    condition: float
    regularized: bool
    normal_only: bool
    shear_detected: bool
    region: np.ndarray
    exact: bool = True
    contacts: tuple = ()
    fallback: str = ""

    @property
    def total_force(self) -> np.ndarray:
        """(3,) ndarray: sum of the nodal forces, newtons."""
        return self.forces.sum(axis=0)


def shear_direction_of(x: float, y: float, fallback: float = 0.0) -> float:
    """The direction of the pair ``(x, y)``, radians in ``(-pi, pi]``; ``fallback`` (wrapped) for
    ``(0, 0)``, whose direction says nothing: a slider's or a preset's, kept as set."""
    if x == 0 and y == 0:
        return math.remainder(fallback, 2 * math.pi) if fallback != -math.pi else math.pi
    angle = math.atan2(y, x)
    return math.pi if angle == -math.pi else angle

"""Normal stress on the rigid base of an elastic layer: the skin as it is built.

A skin is an elastomer layer of thickness ``h`` and Poisson ratio ``nu``
perfectly bonded to a rigid hull (zero displacement at ``z = h``); the sensors
sit on the hull and read ``T33`` there. The half-space kernels of
:mod:`solver.kernels` ignore the hull; this module solves the layer exactly.

In wavenumber space a surface traction of wavevector ``k`` excites only the
P-SV part of the field (the SH part carries no ``sigma_zz``). With the
scaled state ``s = [k u_r, k u_z, sigma_rz, sigma_zz] / mu`` the Navier
equations become ``ds/dzeta = A(nu) s`` in ``zeta = k z``, with ``A`` written
in the stiffness form, regular up to and including ``nu = 0.5``. ``A`` has
eigenvalues ``-1`` and ``+1``, each a Jordan block of two, so every solution
is a combination of ``e^{-zeta} (I + (A + I) zeta) m`` (decaying from the
surface) and ``e^{zeta - kh} (I + (A - I)(zeta - kh)) n`` (decaying from the
base): written that way no term grows, and the 4x4 boundary problem (given
tractions at ``zeta = 0``, zero displacement at ``zeta = kh``) stays well
conditioned at any ``kh``. Its base ``sigma_zz`` gives the transfer functions

    T33(k) = G_n(kh) p(k) - i G_t(kh) (k . q(k)) / |k|

for a normal pressure ``p`` and a tangential traction ``q``. The half-space
has ``G_n = (1 + kh) e^{-kh}`` and ``G_t = kh e^{-kh}``; equilibrium fixes
``G_n(0) = 1`` (all of the load reaches the base) and ``G_t'(0) = 1`` (a
tangential force ``Q`` puts a first moment ``Q h`` of base stress and no net
force). ``T33`` does not depend on Young's modulus.

Real space by Hankel transforms of the transfer functions, tabulated once per
``nu`` in units of ``h`` (so one table serves every thickness and grid):

- ``F(r)``, the share of a normal point load carried by the base within
  radius ``r``: ``F = r int G_n J1(k r) dk``;
- ``Psi(r)``, a potential of the tangential kernel,
  ``T33 = d/dx Psi(|x - x_load|)``: ``Psi = -(1/2pi) int G_t J0(k r) dk``.

A node's force spread uniformly over its square cell then reduces, by the
divergence theorem, to line integrals over the cell's four edges of these
smooth, bounded functions (Gauss-Legendre panels no longer than ``h / 2``):
no singular integrand, any ``h / pitch``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg
from scipy.interpolate import CubicSpline
from scipy.special import j0, j1

from .arrays import read_only
from .geometry import check_poisson_ratio

__all__ = ["transfer", "LayerTable", "table", "layer_point_stress", "EDGE_PANEL",
           "transfer_table"]

# Tables reach this many thicknesses from the load; beyond it the base stress
# of a bonded layer has decayed below 1e-9 of its peak at any nu (it decays
# exponentially, unlike the half-space's algebraic tail).
REACH = 30.0
_STEP = 0.02              # table spacing, thicknesses (cubic spline: 2e-7 of the peak)
_WAVENUMBER_MAX = 40.0    # G_n, G_t ~ kh e^{-kh}: below 1e-15 of their peak beyond
_WAVENUMBER_PANEL = 0.25  # 8-point Gauss-Legendre panels: J(k r) at r = REACH h is resolved
EDGE_PANEL = 0.5          # cell-edge quadrature panels (solver.kernels), thicknesses


def _system_matrix(nu: float) -> np.ndarray:
    # d/dzeta of [k u_r, k u_z, sigma_rz, sigma_zz] / mu (stiffness form):
    #   u_r' = sigma_rz - u_z
    #   u_z' = nu/(1-nu) u_r + (1-2nu)/(2(1-nu)) sigma_zz
    #   sigma_rz' = 2/(1-nu) u_r - nu/(1-nu) sigma_zz
    #   sigma_zz' = sigma_rz
    # No 1/(1-2nu): incompressible layers are a regular case.
    c = 1.0 - nu
    return np.array([[0.0, -1.0, 1.0, 0.0],
                     [nu / c, 0.0, 0.0, (1.0 - 2.0 * nu) / (2.0 * c)],
                     [2.0 / c, 0.0, 0.0, -nu / c],
                     [0.0, 0.0, 1.0, 0.0]])


def transfer(kh, poisson_ratio: float, *, depth: float = 1.0):
    """Transfer functions of a bonded layer: ``T33`` at a depth per unit surface traction.

    Parameters
    ----------
    kh : array_like
        Wavenumber times the layer thickness, >= 0.
    poisson_ratio : float
        ``nu`` in [0, 0.5].
    depth : float, optional
        Where ``T33`` is read, as a fraction of the thickness in (0, 1];
        1 (default) is the rigid base, where the sensors are.

    Returns
    -------
    normal, tangential : ndarray
        ``G_n`` and ``G_t`` with the shape of ``kh`` (dimensionless; see the
        module notes for the sign convention).
    """
    nu = check_poisson_ratio(poisson_ratio)
    if not (math.isfinite(depth) and 0.0 < depth <= 1.0):
        raise ValueError(f"depth must be a fraction of the thickness in (0, 1], got {depth!r}")
    kh = np.asarray(kh, dtype=float)
    if np.any(~np.isfinite(kh)) or np.any(kh < 0):
        raise ValueError("kh must be finite and >= 0")
    a = _system_matrix(nu)
    eye = np.eye(4)
    down = scipy.linalg.null_space((a + eye) @ (a + eye))   # (4, 2): decaying from the surface
    up = scipy.linalg.null_space((a - eye) @ (a - eye))     # (4, 2): decaying from the base
    down_slope, up_slope = (a + eye) @ down, (a - eye) @ up

    def modes(zeta):
        # (..., 4, 4): the four independent solutions evaluated at zeta.
        rise = zeta - kh
        first = np.exp(-zeta)[..., None, None] * (down + zeta[..., None, None] * down_slope)
        second = np.exp(rise)[..., None, None] * (up + rise[..., None, None] * up_slope)
        return np.concatenate([first, second], axis=-1)

    surface, base = modes(np.zeros_like(kh)), modes(kh)
    # Rows: sigma_rz and sigma_zz given at the surface, u_r = u_z = 0 at the base.
    system = np.concatenate([surface[..., 2:4, :], base[..., 0:2, :]], axis=-2)
    rhs = np.zeros(kh.shape + (4, 2))
    rhs[..., 0, 0] = 1.0   # unit sigma_rz at the surface: the tangential load
    rhs[..., 1, 1] = 1.0   # unit sigma_zz at the surface: the normal load
    coefficients = np.linalg.solve(system, rhs)
    reading = modes(depth * kh)[..., 3, :]          # sigma_zz at the requested depth
    response = np.einsum("...j,...jc->...c", reading, coefficients)
    # A pressure p is sigma_zz = -p at the surface and compression T33 = -sigma_zz:
    # the two signs cancel. A traction q along +x is sigma_xz = -q, i.e. i q in the
    # scaled P-SV variable, which with T33 = -sigma_zz gives -i G_t.
    return response[..., 1], response[..., 0]


def _wavenumber_nodes():
    nodes, weights = np.polynomial.legendre.leggauss(8)
    edges = np.arange(0.0, _WAVENUMBER_MAX + 1e-9, _WAVENUMBER_PANEL)
    mid, half = (edges[:-1] + edges[1:]) / 2, np.diff(edges) / 2
    return (mid[:, None] + half[:, None] * nodes).ravel(), (half[:, None] * weights).ravel()


@dataclass(frozen=True)
class LayerTable:
    """Real-space base-stress functions of a bonded layer, in units of its thickness.

    All radii ``u`` are in thicknesses; for a layer of thickness ``h`` a
    radius ``r`` is ``u = r / h``. Beyond ``reach`` the functions take their
    far values (``F = 1``, everything else 0).

    Attributes
    ----------
    poisson_ratio : float
    reach : float
        Tabulated range, thicknesses.
    radius : (k,) ndarray
        Tabulation radii ``u``.
    carried_over_area : (k,) ndarray
        ``F(u) / u^2``: share of a unit normal load carried within radius
        ``u``, over ``u^2`` (bounded: ``pi`` times the peak of the kernel at 0).
    potential : (k,) ndarray
        ``psi(u)`` with ``T33 = d/dx [psi(|x| / h) / h]`` per newton of
        tangential force along +x.
    normal_point : (k,) ndarray
        ``h^2 T33`` under a unit normal point force (the layer's Boussinesq).
    tangential_point : (k,) ndarray
        ``h^2 T33 / cos(phi)`` under a unit tangential point force (its Cerruti).
    """

    poisson_ratio: float
    reach: float
    radius: np.ndarray
    carried_over_area: np.ndarray
    potential: np.ndarray
    normal_point: np.ndarray
    tangential_point: np.ndarray

    @classmethod
    def compute(cls, poisson_ratio: float) -> LayerTable:
        nu = check_poisson_ratio(poisson_ratio)
        kappa, weight = _wavenumber_nodes()
        normal, tangential = transfer(kappa, nu)
        u = np.arange(0.0, REACH + _STEP / 2, _STEP)
        arg = np.outer(u, kappa)
        bessel0, bessel1 = j0(arg), j1(arg)
        # F(u) / u^2 = (1/u) int G_n J1(k u) dk, with J1(k u) / u -> k / 2 at u = 0
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(u[:, None] > 0, bessel1 / u[:, None], kappa / 2)
        carried = ratio @ (normal * weight)
        potential = -(bessel0 @ (tangential * weight)) / (2.0 * np.pi)
        normal_point = bessel0 @ (normal * kappa * weight) / (2.0 * np.pi)
        tangential_point = bessel1 @ (tangential * kappa * weight) / (2.0 * np.pi)
        return cls(nu, REACH, read_only(u), read_only(carried), read_only(potential),
                   read_only(normal_point), read_only(tangential_point))

    def __post_init__(self):
        # Splines are derived state: built once, kept beside the table.
        for name in ("carried_over_area", "potential", "normal_point", "tangential_point"):
            object.__setattr__(self, f"_{name}", CubicSpline(self.radius, getattr(self, name)))

    def _evaluate(self, name: str, u, far):
        u = np.asarray(u, dtype=float)
        out = np.empty_like(u)
        inside = u <= self.reach
        out[inside] = getattr(self, f"_{name}")(u[inside])
        out[~inside] = far(u[~inside])
        return out

    def carried(self, u):
        """``F(u) / u^2`` at radii ``u`` (thicknesses)."""
        return self._evaluate("carried_over_area", u, lambda v: 1.0 / (v * v))

    def tangential_potential(self, u):
        """``psi(u)`` at radii ``u`` (thicknesses)."""
        return self._evaluate("potential", u, np.zeros_like)

    def point_stress(self, u):
        """``h^2 T33`` under unit normal and tangential point forces at radii ``u``.

        Returns
        -------
        normal, tangential : ndarray
            The tangential value is per ``cos(phi)``, ``phi`` measured from the force.
        """
        return (self._evaluate("normal_point", u, np.zeros_like),
                self._evaluate("tangential_point", u, np.zeros_like))


@lru_cache(maxsize=8)
def transfer_table(poisson_ratio: float):
    """(Cached) ``kh`` from 0 to 40 in steps of 0.005 with ``G_n`` and ``G_t`` there (read-only)."""
    kh = np.linspace(0.0, 40.0, 8001)
    return tuple(read_only(a) for a in (kh, *transfer(kh, poisson_ratio)))


@lru_cache(maxsize=8)
def table(poisson_ratio: float) -> LayerTable:
    """The (cached) :class:`LayerTable` of ``nu``: about 0.5 s once per Poisson ratio."""
    return LayerTable.compute(check_poisson_ratio(poisson_ratio))


def layer_point_stress(dx, dy, thickness: float, poisson_ratio: float):
    """``T33`` on the base per newton of a point force on the surface.

    Parameters
    ----------
    dx, dy : ndarray
        Sensor position minus load position, metres (broadcast together).
    thickness : float
        Layer thickness ``h``, metres.
    poisson_ratio : float
        ``nu`` in [0, 0.5].

    Returns
    -------
    kx, ky, kz : ndarray
        Pascals per newton of force along x, y and z (z into the skin).
    """
    tab = table(check_poisson_ratio(poisson_ratio))
    dx, dy = np.broadcast_arrays(np.asarray(dx, float), np.asarray(dy, float))
    r = np.hypot(dx, dy)
    u = r / thickness
    scale = 1.0 / (thickness * thickness)
    normal, radial = tab.point_stress(u)
    kz, radial = scale * normal, scale * radial
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_phi = np.where(r > 0, dx / r, 0.0)
        sin_phi = np.where(r > 0, dy / r, 0.0)
    return radial * cos_phi, radial * sin_phi, kz

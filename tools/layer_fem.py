"""Finite-element reference for the base stress of a bonded elastomer layer.

The skin is an elastic layer of thickness ``h`` and Poisson ratio ``nu``,
perfectly bonded to a rigid base at ``z = h``; ``z`` points into the layer
and the loaded free surface is ``z = 0``. A total force of one newton is
spread uniformly over a ``width x width`` square patch centred on the origin,
either normal (pressing in, ``+z``) or tangential (along ``+x``). The model
returns ``T33``, the normal stress on the base with compression positive, in
pascals per newton: the quantity the sensors read and the quantity
:func:`solver.kernels.layer_force_stress` gives in closed/tabulated form.

Discretisation
--------------
* Triquadratic hexahedra (``skfem.ElementHex2``) on a tensor mesh of one
  quadrant, graded from the patch outwards; the patch edges are mesh lines so
  the load is represented exactly.
* Selective reduced integration: the shear term ``2 mu eps(u):eps(v)`` uses
  3x3x3 Gauss points, the volumetric term ``lambda div(u) div(v)`` uses 2x2x2,
  which keeps the element free of volumetric locking up to ``nu ~ 0.49``.
* Symmetry: a normal load is even in ``x`` and ``y`` (``u_x = 0`` on
  ``x = 0``, ``u_y = 0`` on ``y = 0``); a load along ``x`` is odd in ``x``
  for ``u_y, u_z`` (``u_y = u_z = 0`` on ``x = 0``) and even in ``y``
  (``u_y = 0`` on ``y = 0``). Lateral faces at ``x, y = width/2 + extent*h``
  are traction free by default; the layer's response decays like
  ``exp(-r/h)``, and at the default extent of ``4 h`` clamping them instead,
  or moving them out to ``6 h``, changes the base stress within ``3 h`` of
  the patch centre by < 1 % of the peak (0.03-0.4 % for a normal load; the
  coarse far elements' own discretisation error is of the same size).
* Base stress recovery from the reactions ``R = K u - f`` of the clamped base
  z-dofs, turned into a traction field by the base-facet mass matrix
  (``M t = R``, the variationally consistent flux). This is equilibrated by
  construction and far more accurate than ``sigma_zz`` from the displacement
  gradient, kept as ``recovery="gradient"`` for comparison: with reduced
  integration the pressure part of the gradient stress is noisy, and at
  ``width = h`` it misses by 3-8 % of the peak at ``nu = 0.3`` and 30-50 %
  at ``nu = 0.45`` on the default mesh, where the reactions are within 1 %.

Everything is solved in units of ``h`` with a unit Young's modulus (``T33``
does not depend on it) and scaled back to SI at the end.

Run ``python -m tools.layer_fem --fine`` for the reference table quoted in
the docs.
"""

from __future__ import annotations

import argparse
import functools
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
from skfem import Basis, BilinearForm, ElementHex2, FacetBasis, MeshHex, asm

__all__ = ["LOADS", "LayerSolution", "solve_layer", "base_stress", "base_profile", "main"]

LOADS = ("normal", "tangential")

_TOL = 1e-9  # geometric tolerance in units of h


@dataclass(frozen=True)
class LayerSolution:
    """Base stress of one FEM solve, stored as the quadrant's Q2 nodal field.

    Attributes
    ----------
    thickness, width, poisson_ratio : float
        Layer thickness ``h`` (m), patch side (m) and Poisson ratio.
    load : str
        ``"normal"`` (force along +z) or ``"tangential"`` (force along +x).
    x_nodes, y_nodes : ndarray, shape (nx,), (ny,)
        Base Q2 node coordinates of the quadrant ``x, y >= 0`` (metres),
        vertices and edge midpoints, increasing.
    t33 : ndarray, shape (nx, ny)
        ``T33`` (compression positive) at those nodes, pascals per newton.
    elements, dofs : int
        Hexahedra and displacement unknowns of the quadrant model.
    seconds : float
        Wall time of the solve (assembly, factorisation, recovery).
    """

    thickness: float
    width: float
    poisson_ratio: float
    load: str
    x_nodes: np.ndarray
    y_nodes: np.ndarray
    t33: np.ndarray
    elements: int
    dofs: int
    seconds: float

    @property
    def extent(self) -> float:
        """Half side of the modelled square (m); points beyond it are rejected."""
        return float(self.x_nodes[-1])

    def __call__(self, x, y) -> np.ndarray:
        """``T33`` at base points, pascals per newton.

        Parameters
        ----------
        x, y : array_like
            Base positions relative to the patch centre, metres (broadcast
            together); any sign, symmetry supplies the other quadrants.

        Returns
        -------
        ndarray
            ``T33`` with the broadcast shape of ``x`` and ``y``.
        """
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        ax, ay = np.abs(x), np.abs(y)
        if np.any(ax > self.extent * (1 + 1e-12)) or np.any(ay > self.extent * (1 + 1e-12)):
            raise ValueError(f"points beyond the modelled extent {self.extent:.3g} m")
        value = _interpolate_q2(self.x_nodes, self.y_nodes, self.t33, ax.ravel(), ay.ravel()).reshape(x.shape)
        if self.load == "tangential":
            # u_z is odd in x for a load along x, and so is T33
            value = np.sign(x) * value
        return value

    def integrals(self) -> tuple[float, float, float]:
        """Resultants of the base stress over the whole base (both signs of x, y).

        Returns
        -------
        total, moment_x, moment_y : float
            ``int T33 dA`` (N per N of load), ``int x T33 dA`` and
            ``int y T33 dA`` (m per N of load). Equilibrium requires
            ``(1, 0, 0)`` for the normal load and ``(0, h, 0)`` for the
            tangential one (the couple of the load at ``z = 0`` about the
            base is taken by compression ahead of the load).
        """
        # 3-point Gauss per Q2 interval integrates the Q2 field times x exactly
        g, wg = np.polynomial.legendre.leggauss(3)
        xv, yv = self.x_nodes[::2], self.y_nodes[::2]
        xq = ((xv[:-1] + xv[1:]) / 2 + np.outer(g, np.diff(xv) / 2)).T.ravel()
        yq = ((yv[:-1] + yv[1:]) / 2 + np.outer(g, np.diff(yv) / 2)).T.ravel()
        wx = np.outer(np.diff(xv) / 2, wg).ravel()
        wy = np.outer(np.diff(yv) / 2, wg).ravel()
        field = _interpolate_q2(self.x_nodes, self.y_nodes, self.t33, *np.meshgrid(xq, yq, indexing="ij"))
        quadrant = wx @ field @ wy
        first_x = (wx * xq) @ field @ wy
        if self.load == "normal":
            # even in x and y: four equal quadrants, no first moments
            return 4.0 * quadrant, 0.0, 0.0
        # odd in x, even in y: the quadrants cancel, the x-moments add
        return 0.0, 4.0 * first_x, 0.0


def _interpolate_q2(xn, yn, values, x, y):
    # Tensor-product quadratic Lagrange interpolation of a nodal field on a
    # rectilinear grid whose even nodes are element vertices and odd nodes
    # edge midpoints (the base face of the Q2 hexahedra).
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    shape = x.shape
    x, y = x.ravel(), y.ravel()

    def locate(nodes, p):
        verts = nodes[::2]
        e = np.clip(np.searchsorted(verts, p, side="right") - 1, 0, len(verts) - 2)
        xi = (p - verts[e]) / (verts[e + 1] - verts[e])
        shape_fns = np.stack([2 * (xi - 0.5) * (xi - 1), -4 * xi * (xi - 1), 2 * xi * (xi - 0.5)])
        return 2 * e, shape_fns

    ex, lx = locate(xn, x)
    ey, ly = locate(yn, y)
    out = np.zeros(x.shape)
    for i in range(3):
        for j in range(3):
            out += lx[i] * ly[j] * values[ex + i, ey + j]
    return out.reshape(shape)


def _grown(length, first, ratio, cap):
    # Nodes 0..length with sizes growing geometrically from `first` by `ratio`
    # up to `cap`, all scaled so that they end exactly at `length`.
    sizes, size = [], first
    while sum(sizes) < length - _TOL:
        sizes.append(size)
        size = min(size * ratio, cap)
    if len(sizes) > 1 and sum(sizes) - length > sizes[-1] / 2:
        sizes.pop()  # overshoot by more than half an element: drop it, stretch the rest
    sizes = np.array(sizes) * length / sum(sizes)
    return np.concatenate([[0.0], np.cumsum(sizes)])


def _mesh_nodes(aspect, refinement, extent):
    # Nodal lines in units of h for a patch of side `aspect` h: lateral (x and
    # y alike) and through the depth. The stresses are singular along the
    # patch edges on the surface (traction jump), so the elements are smallest
    # there, in both the lateral and the depth direction: elongated elements
    # next to the edge pollute the base reactions below it (tested: 10-30 %
    # errors at the base under the edge of a tangential patch with 4:1
    # elements). Under the patch they stay that small, to resolve the peak at
    # the centre; outside they grow towards the far faces. Refinement r
    # divides the sizes by r and takes the r-th root of the growth ratio.
    half = aspect / 2
    edge = min(aspect / 4, 0.125) / refinement
    ratio = 1.5 ** (1.0 / refinement)
    inside = half - _grown(half, edge, ratio, max(edge, 0.125 / refinement))[::-1]
    inside[0] = 0.0
    outside = half + _grown(extent, edge, ratio, 0.75 / refinement)
    lateral = np.concatenate([inside, outside[1:]])
    depth = _grown(1.0, edge, ratio, 0.5 / refinement)
    return lateral, depth


@functools.lru_cache(maxsize=16)
def _solve_nondimensional(aspect, nu, load, refinement, extent, lateral, recovery):
    if load not in LOADS:
        raise ValueError(f"load must be one of {LOADS}, not {load!r}")
    if not 0.0 <= nu < 0.5:
        raise ValueError("poisson_ratio must lie in [0, 0.5)")
    start = time.perf_counter()
    half = aspect / 2
    xs, zs = _mesh_nodes(aspect, refinement, extent)
    mesh = MeshHex.init_tensor(xs, xs, zs)
    elem = ElementHex2()
    full = Basis(mesh, elem, intorder=4)  # 3x3x3 Gauss: exact for the affine Q2 stiffness
    reduced = Basis(mesh, elem, intorder=2)  # 2x2x2 Gauss for the volumetric term
    n = full.N

    # Scalar derivative matrices S[p, q][i, j] = int d_p phi_i d_q phi_j (i: test).
    # Assembling these nine scalar forms and combining them into the vector
    # stiffness is ~20x faster than skfem's vector form evaluation for Hex2.
    grads_full = {(p, q): asm(BilinearForm(lambda u, v, w, p=p, q=q: v.grad[p] * u.grad[q]), full)
                  for p in range(3) for q in range(3)}
    grads_red = {(p, q): asm(BilinearForm(lambda u, v, w, p=p, q=q: v.grad[p] * u.grad[q]), reduced)
                 for p in range(3) for q in range(3)}
    mu = 1.0 / (2.0 * (1.0 + nu))
    lam = nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    laplace = grads_full[0, 0] + grads_full[1, 1] + grads_full[2, 2]
    # block (test component a, trial component b) of
    # int 2 mu eps(u):eps(v) + lam div(u) div(v); unknowns ordered [u_x; u_y; u_z]
    stiffness = sp.bmat([[mu * ((a == b) * laplace + grads_full[b, a]) + lam * grads_red[a, b]
                          for b in range(3)] for a in range(3)]).tocsr()

    X, Y, Z = full.doflocs
    # load: uniform traction of 1/aspect^2 (one newton over the whole patch) on
    # the quadrant of the patch; the patch edges are mesh lines
    patch = mesh.facets_satisfying(
        lambda p: (p[2] < _TOL) & (p[0] < half + _TOL) & (p[1] < half + _TOL))
    mass = asm(BilinearForm(lambda u, v, w: u * v), FacetBasis(mesh, elem, facets=patch))
    shape_integrals = mass @ np.ones(n)
    force = np.zeros(3 * n)
    component = 2 if load == "normal" else 0
    force[component * n:(component + 1) * n] = shape_integrals / aspect**2

    on_base = np.isclose(Z, 1.0)
    fixed = np.zeros((3, n), dtype=bool)
    fixed[:, on_base] = True
    if load == "normal":
        fixed[0, np.isclose(X, 0.0)] = True
    else:
        fixed[1:, np.isclose(X, 0.0)] = True
    fixed[1, np.isclose(Y, 0.0)] = True
    if lateral == "clamped":
        fixed[:, np.isclose(X, xs[-1]) | np.isclose(Y, xs[-1])] = True
    elif lateral != "free":
        raise ValueError("lateral must be 'free' or 'clamped'")
    free = ~fixed.ravel()

    displacement = np.zeros(3 * n)
    k_free = stiffness[free][:, free].tocsc()
    # minimum-degree ordering on A^T + A suits this symmetric matrix: ~5x less
    # fill and time than SuperLU's default COLAMD
    lu = spl.splu(k_free, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
    displacement[free] = lu.solve(force[free])

    # base field: Q2 nodes of the base face, as a tensor grid
    base_nodes = np.flatnonzero(on_base)
    # vertices interleaved with edge midpoints; dof locations carry rounding
    # noise, so they are matched to this grid by nearest index
    nodes = np.empty(2 * len(xs) - 1)
    nodes[::2], nodes[1::2] = xs, (xs[:-1] + xs[1:]) / 2
    column = np.rint(np.interp(X[base_nodes], nodes, np.arange(len(nodes)))).astype(int)
    row = np.rint(np.interp(Y[base_nodes], nodes, np.arange(len(nodes)))).astype(int)
    base_facets = mesh.facets_satisfying(lambda p: p[2] > 1.0 - _TOL)
    base_basis = FacetBasis(mesh, elem, facets=base_facets)
    mass = asm(BilinearForm(lambda u, v, w: u * v), base_basis)[base_nodes][:, base_nodes]
    if recovery == "reaction":
        # reaction on the body from the base, z-component, at the base nodes
        rhs = (stiffness @ displacement - force)[2 * n + base_nodes]
    elif recovery == "gradient":
        ux, uy, uz = (base_basis.interpolate(displacement[c * n:(c + 1) * n]) for c in range(3))
        sigma_zz = lam * (ux.grad[0] + uy.grad[1] + uz.grad[2]) + 2 * mu * uz.grad[2]
        rhs = asm(BilinearForm(lambda u, v, w: w["s"] * u * v), base_basis, s=sigma_zz) @ np.ones(n)
        rhs = rhs[base_nodes]
    else:
        raise ValueError("recovery must be 'reaction' or 'gradient'")
    keep = np.ones(len(base_nodes), dtype=bool)
    if load == "tangential":
        # T33 is odd in x: zero on x = 0. The quadrant's reaction there is only
        # half of a pair that cancels in the full model, so it is dropped.
        keep = ~np.isclose(X[base_nodes], 0.0)
    traction = np.zeros(len(base_nodes))
    traction[keep] = spl.spsolve(mass[keep][:, keep].tocsc(), rhs[keep])
    t33 = np.full((len(nodes), len(nodes)), np.nan)
    # compression positive: T33 = -sigma_zz = -(traction of the base on the body)_z
    t33[column, row] = -traction
    assert not np.isnan(t33).any(), "base dofs do not fill the Q2 grid"
    return nodes, nodes.copy(), t33, mesh.nelements, int(free.sum()), time.perf_counter() - start


def solve_layer(thickness: float, width: float, poisson_ratio: float, load: str = "normal",
                refinement: float = 1, extent: float = 4.0, lateral: str = "free",
                recovery: str = "reaction") -> LayerSolution:
    """Solve the bonded layer under a one-newton uniform square patch load.

    Parameters
    ----------
    thickness : float
        Layer thickness ``h``, metres.
    width : float
        Side of the square patch, metres.
    poisson_ratio : float
        Poisson ratio of the layer, ``0 <= nu < 0.5`` (accurate to ~0.49).
    load : {"normal", "tangential"}
        Force along +z (pressing in) or along +x.
    refinement : float
        Mesh refinement level; element sizes scale as ``1/refinement``. At
        ``width = h``: 1 gives 576 elements, ~14k unknowns, ~2 s and agrees
        with the converged field within ~1 % of the peak; 2 gives ~110k
        unknowns (minutes). Non-integer levels are allowed.
    extent : float
        Modelled distance beyond the patch edge, in thicknesses.
    lateral : {"free", "clamped"}
        Condition on the far lateral faces.
    recovery : {"reaction", "gradient"}
        Base stress from the base reactions (default) or from the
        displacement gradient, both projected onto the Q2 base field.

    Returns
    -------
    LayerSolution
        Callable as ``solution(x, y)`` for ``T33`` in pascals per newton.
    """
    aspect = float(width) / float(thickness)
    x_nodes, y_nodes, t33, elements, dofs, seconds = _solve_nondimensional(
        aspect, float(poisson_ratio), load, float(refinement), float(extent), lateral, recovery)
    # lengths scale with h; stress per newton scales with 1/h^2
    return LayerSolution(thickness=float(thickness), width=float(width), poisson_ratio=float(poisson_ratio),
                         load=load, x_nodes=x_nodes * thickness, y_nodes=y_nodes * thickness,
                         t33=t33 / thickness**2, elements=elements, dofs=dofs, seconds=seconds)


def base_stress(thickness: float, width: float, poisson_ratio: float, load: str = "normal",
                points=None, refinement: float = 1, **options):
    """``T33`` on the base at given points, or along the x axis.

    Parameters
    ----------
    thickness, width, poisson_ratio, load, refinement
        As for :func:`solve_layer`.
    points : array_like, shape (m, 2), optional
        Base positions ``(x, y)`` relative to the patch centre, metres.
    **options
        ``extent``, ``lateral`` and ``recovery`` of :func:`solve_layer`.

    Returns
    -------
    ndarray, shape (m,)
        ``T33`` (compression positive) in pascals per newton, if ``points``
        is given; otherwise the tuple ``(x, t33)`` of :func:`base_profile`.
    """
    solution = solve_layer(thickness, width, poisson_ratio, load, refinement, **options)
    if points is None:
        return base_profile(solution)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    return solution(points[:, 0], points[:, 1])


def base_profile(solution: LayerSolution):
    """``T33`` along the positive x axis at the mesh's base nodes.

    Parameters
    ----------
    solution : LayerSolution

    Returns
    -------
    x, t33 : ndarray, shape (nx,)
        Offsets from the patch centre (m) and ``T33`` there (Pa per N).
    """
    return solution.x_nodes.copy(), solution.t33[:, 0].copy()


def _boussinesq_peak(thickness):
    # point load on a half-space: sigma_zz = 3 P / (2 pi h^2) below the load
    return 3.0 / (2.0 * np.pi * thickness**2)


def main(argv=None):
    """Print a reference table of base stresses (``python -m tools.layer_fem``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--thickness", type=float, default=1.5e-3, help="layer thickness h, m")
    parser.add_argument("--width", type=float, default=1.5e-3, help="patch side, m")
    parser.add_argument("--nu", type=float, nargs="+", default=[0.3, 0.45], help="Poisson ratios")
    parser.add_argument("--refinement", type=float, default=1.0, help="mesh refinement level")
    parser.add_argument("--fine", action="store_true",
                        help="reference mesh: refinement 2, ~110k unknowns, minutes a solve, ~6 GB")
    args = parser.parse_args(argv)
    refinement = 2.0 if args.fine else args.refinement
    h, w = args.thickness, args.width
    offsets = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0])  # in thicknesses, along +x
    print(f"bonded layer h = {h * 1e3:g} mm, square patch {w * 1e3:g} mm, 1 N; "
          f"T33 on the base in kPa per N (compression positive); refinement {refinement}")
    print(f"Boussinesq half-space point load, peak 3P/(2 pi h^2) = {_boussinesq_peak(h) / 1e3:.2f} kPa/N")
    header = "  ".join(f"{o:>6.2f}h" for o in offsets)
    print(f"{'nu':>5} {'load':>10} {'peak':>8} {'at x/h':>6} | {header} | {'elements':>8} {'dofs':>7} "
          f"{'time s':>6} {'total':>7} {'mom/h':>7}")
    for nu in args.nu:
        for load in LOADS:
            sol = solve_layer(h, w, nu, load, refinement)
            x, t33 = base_profile(sol)
            peak = np.argmax(np.abs(t33))
            values = sol(offsets * h, 0.0) / 1e3
            total, moment, _ = sol.integrals()
            row = "  ".join(f"{v:7.3f}" for v in values)
            print(f"{nu:5.2f} {load:>10} {t33[peak] / 1e3:8.3f} {x[peak] / h:6.3f} | {row} | "
                  f"{sol.elements:8d} {sol.dofs:7d} {sol.seconds:6.1f} {total:7.4f} {moment / h:7.4f}")


if __name__ == "__main__":
    main()

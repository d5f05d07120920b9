"""Efficiency functionals: which member of the exact solution family is eligible.

Every ``x(mu, theta) = C+ b + (I - C+ C) y(mu, theta)`` fits the data exactly,
so a functional must reward physical admissibility, not fit. A functional here
is an object with a ``name`` and a method
``choose(frame, *, shear_ratio=None, shear_direction=None) -> Choice`` that
returns the shear parameters (the given ones, or the maximizer over the free
ones), the compressive normal profile ``g`` of the template load and the value
of the functional. :class:`solver.Reconstructor` takes any such object.

Chosen: :class:`ContactFit` (see its notes and ``docs/efficiency.md`` for the
measured comparison). Kept for comparison: :class:`Admissibility` (penalties
on the linear family, the DESIGN's first sketch) and :class:`NoShear` (the
baseline that never reports shear).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .nnls import nnls_gram

__all__ = ["Frame", "Choice", "ContactFit", "Admissibility", "NoShear", "FUNCTIONALS"]


@dataclass(frozen=True, eq=False)
class Frame:
    """What a functional may look at for one frame.

    Attributes
    ----------
    stress : (m,) ndarray
        Sensor stress ``b``, pascals.
    normal : (m,) ndarray
        Normal-only solution ``Cz^-1 b``, newtons.
    region : (m,) ndarray of bool
        Contact region (see :meth:`solver.Reconstructor.contact_region`).
    matrix : (m, 3m) ndarray
        ``C = [Cx | Cy | Cz]``.
    max_shear_ratio : float
        Upper bound for the shear ratio search.
    project_null : callable or None
        ``y -> (I - C+ C) y`` for ``(3m,)`` or ``(3m, k)`` arrays.
    apply_pinv : callable or None
        ``b -> C+ b``.
    gram : (3m, 3m) ndarray or None
        ``C^T C`` when the reconstructor keeps it (small grids); otherwise the
        region's Gram blocks are formed per frame.
    """

    stress: np.ndarray
    normal: np.ndarray
    region: np.ndarray
    matrix: np.ndarray
    max_shear_ratio: float
    project_null: object = None
    apply_pinv: object = None
    gram: np.ndarray | None = None

    @cached_property
    def region_index(self) -> np.ndarray:
        return np.flatnonzero(self.region)

    @cached_property
    def region_gram(self):
        """Gram blocks of the region's columns, for the contact-fit NNLS problems.

        Returns
        -------
        blocks : dict of (r, r) ndarray
            ``blocks["ab"] = Ca_R^T Cb_R`` for ``ab`` in xx, yy, zz, xz, yz, xy.
        stack : (6, r, r) ndarray
            The terms of ``A(s)^T A(s)`` for the coefficients
            ``(1, sx, sy, sx^2, sx sy, sy^2)``.
        products : (3, r) ndarray
            ``Cx_R^T b``, ``Cy_R^T b``, ``Cz_R^T b``.
        """
        m = self.stress.size
        idx = self.region_index
        r = idx.size
        columns = np.concatenate([idx, idx + m, idx + 2 * m])
        if self.gram is not None:
            full = self.gram.take(columns, axis=0).take(columns, axis=1)
            products = (self.stress @ self.matrix)[columns].reshape(3, r)
        else:
            selected = self.matrix.take(columns, axis=1)
            full = selected.T @ selected
            products = (self.stress @ selected).reshape(3, r)
        x, y, z = slice(0, r), slice(r, 2 * r), slice(2 * r, 3 * r)
        blocks = {"xx": full[x, x], "yy": full[y, y], "zz": full[z, z],
                  "xz": full[x, z], "yz": full[y, z], "xy": full[x, y]}
        # A(s)^T A(s) = sum_k c_k(s) stack[k] with c = (1, sx, sy, sx^2, sx sy, sy^2)
        stack = np.stack([blocks["zz"], blocks["xz"] + blocks["xz"].T, blocks["yz"] + blocks["yz"].T,
                          blocks["xx"], blocks["xy"] + blocks["xy"].T, blocks["yy"]])
        return blocks, products, stack


@dataclass(frozen=True)
class Choice:
    """Parameters and template profile chosen for one frame.

    Attributes
    ----------
    shear_x, shear_y : float
        ``mu cos(theta)`` and ``mu sin(theta)``.
    profile : (m,) ndarray
        Compressive normal profile ``g`` of the template load, newtons.
    efficiency : float
        Value of the functional at the chosen parameters.
    shear_detected : bool
        True when automatic search kept a non-zero shear.
    """

    shear_x: float
    shear_y: float
    profile: np.ndarray
    efficiency: float
    shear_detected: bool = False


def _fixed_pair(shear_ratio, shear_direction):
    return shear_ratio * math.cos(shear_direction), shear_ratio * math.sin(shear_direction)


class ContactFit:
    """How well a compressive, friction-shaped load on the contact region explains the data.

    For a pair ``s = mu (cos theta, sin theta)`` the template load is
    ``Fz = g``, ``(Fx, Fy) = s g`` with ``g >= 0`` on the contact region only.
    Its best fit to the data is a non-negative least-squares problem

        rho(s) = min_{g >= 0} | (Cz_R + sx Cx_R + sy Cy_R) g - b |^2

    and the efficiency is ``E(s) = 1 - sqrt(rho(s)) / |b|`` (1: explained
    exactly). With more sensors than region nodes and ``g >= 0``, a wrong
    shear leaves a residual: the shear signature (compression ahead of the
    load, relief behind it) cannot be mimicked by a compressive normal load.

    The maximization is continuous: Gauss-Newton on the free parameters, with
    the profile eliminated (variable projection: each step solves the
    linearized problem for ``g`` on its current support and the parameter
    step together, then re-solves the NNLS at the new parameters and halves
    the step until the residual drops). A found shear is kept only when it
    explains the data significantly better than no shear: the F statistic
    ``((rho(0) - rho(s)) / k) / (rho(s) / dof)`` (``k`` free parameters,
    ``dof`` sensors minus loaded nodes minus ``k``) must exceed
    ``significance``. On shear-free loads of the standard set at 1% noise its
    median is 1.2 and 65% fall below 2; on shear ratio 0.2 and 0.4, 19% and
    2% do (``docs/efficiency.md``).

    Parameters
    ----------
    significance : float, optional
        F-statistic threshold for keeping shear. Default 2.
    model_error : float, optional
        Floor of the misfit standard deviation in the F statistic, relative
        to the peak stress: the cell kernel's own error on continuous loads,
        which would otherwise read as significant shear on clean data.
        Default 0.008: with it the median false shear ratio on shear-free
        loads is 0 at 0%, 0.3% and 1% noise (without it, 0.05 on clean data).
    max_iterations : int, optional
        Gauss-Newton iterations. Default 12.
    tolerance : float, optional
        Stop when a step changes the parameters by less (shear ratio units or
        radians), or lowers the residual by less than a tenth of this
        fraction. Default 1e-3: far below the statistical error at 1% noise,
        and a change of about 0.02 in the F statistic.
    """

    name = "contact_fit"

    def __init__(self, *, significance: float = 2.0, model_error: float = 0.008,
                 max_iterations: int = 12, tolerance: float = 1e-3):
        if not (math.isfinite(significance) and significance >= 0):
            raise ValueError(f"significance must be finite and >= 0, got {significance!r}")
        if int(max_iterations) < 0:
            raise ValueError(f"max_iterations must be >= 0, got {max_iterations!r}")
        self.significance = float(significance)
        if not (math.isfinite(model_error) and model_error >= 0):
            raise ValueError(f"model_error must be finite and >= 0, got {model_error!r}")
        self.model_error = float(model_error)
        self.max_iterations = int(max_iterations)
        if not tolerance > 0:
            raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
        self.tolerance = float(tolerance)

    @staticmethod
    def _system(frame: Frame, sx: float, sy: float):
        # A(s) = Cz + sx Cx + sy Cy on the region: A^T A and A^T b from the Gram blocks.
        _, prod, stack = frame.region_gram
        gram = np.tensordot(np.array([1.0, sx, sy, sx * sx, sx * sy, sy * sy]), stack, axes=1)
        return gram, prod[2] + sx * prod[0] + sy * prod[1]

    def fit(self, frame: Frame, shear_x: float, shear_y: float, *, passive=None):
        """Best compressive profile at ``s`` and its squared residual.

        Parameters
        ----------
        passive : (r,) ndarray of bool, optional
            Warm start for the NNLS active set.

        Returns
        -------
        profile : (r,) ndarray
            ``g`` on the region nodes, newtons.
        rho : float
            Squared residual ``|A(s) g - b|^2``, pascals squared.
        """
        bb = float(frame.stress @ frame.stress)
        if frame.region_index.size == 0:
            return np.zeros(0), bb
        gram, rhs = self._system(frame, shear_x, shear_y)
        if passive is None:
            passive = frame.normal[frame.region_index] > 0
        g, _ = nnls_gram(gram, rhs, passive=passive)
        # at the optimum g^T H g = g^T A^T b on the support, so rho = b.b - g.(A^T b)
        return g, max(bb - float(g @ rhs), 0.0)

    def choose(self, frame: Frame, *, shear_ratio=None, shear_direction=None) -> Choice:
        norm = float(np.linalg.norm(frame.stress))
        mu_max = frame.max_shear_ratio
        if shear_ratio is not None and shear_direction is not None:
            s = _fixed_pair(shear_ratio, shear_direction)
            g, rho = self.fit(frame, *s)
            return self._choice(frame, s, g, rho, norm, detected=False)

        # Parametrize the free parameters p -> s(p) with Jacobian ds/dp (2, k).
        if shear_ratio is None and shear_direction is None:
            def shear(p):
                mu = math.hypot(p[0], p[1])
                return (p[0], p[1]) if mu <= mu_max else (p[0] * mu_max / mu, p[1] * mu_max / mu)

            def jacobian(p):
                return np.eye(2)
            starts = [np.zeros(2)]
        elif shear_ratio is None:
            c, s_ = math.cos(shear_direction), math.sin(shear_direction)

            def shear(p):
                mu = min(max(p[0], 0.0), mu_max)
                return (mu * c, mu * s_)

            def jacobian(p):
                return np.array([[c], [s_]])
            starts = [np.zeros(1)]
        else:
            mu = shear_ratio

            def shear(p):
                return (mu * math.cos(p[0]), mu * math.sin(p[0]))

            def jacobian(p):
                return np.array([[-mu * math.sin(p[0])], [mu * math.cos(p[0])]])
            # theta alone is periodic and may have several local optima: scan first.
            starts = [np.array([t]) for t in np.linspace(-math.pi, math.pi, 12, endpoint=False)]

        scanned = []
        for start in starts:
            g_start, rho_start = self.fit(frame, *shear(start))
            scanned.append((rho_start, start, g_start))
        rho0, _, g0 = scanned[0]  # the first start is the shear-free load when mu is free
        rho, p, g = min(scanned, key=lambda item: item[0])
        p, g, rho = self._gauss_newton(frame, p, g, rho, shear, jacobian)
        s = shear(p)
        if shear_ratio is None:
            # Keep shear only when it is significant against a shear-free load.
            dof = frame.stress.size - int(np.count_nonzero(g)) - len(p)
            gain = rho0 - rho
            # The misfit of the kernel's model of a continuous load acts as noise
            # that does not shrink with the sensor noise: floor the variance.
            floor = (self.model_error * float(np.abs(frame.stress).max())) ** 2
            variance = max(rho / dof, floor) if dof > 0 else math.inf
            significant = gain > 0 and (variance <= 0 or (gain / len(p)) / variance > self.significance)
            if not significant:
                return self._choice(frame, (0.0, 0.0), g0, rho0, norm, detected=False)
        return self._choice(frame, s, g, rho, norm, detected=shear_ratio is None)

    def _gauss_newton(self, frame, p, g, rho, shear, jacobian):
        # Linearize A(s + ds) g' ~ A(s) g' + ds_x Cx g + ds_y Cy g and solve for
        # (g' on the support, dp) together through the normal equations, all
        # from the region's Gram blocks.
        G, prod, _ = frame.region_gram
        for _ in range(self.max_iterations):
            support = g > 0
            if not support.any():
                break
            sx, sy = shear(p)
            gram, rhs = self._system(frame, sx, sy)
            # A^T Cx g and A^T Cy g (r,), then the sensitivities' own products
            at_cx = (G["xz"].T + sx * G["xx"] + sy * G["xy"].T) @ g
            at_cy = (G["yz"].T + sx * G["xy"] + sy * G["yy"]) @ g
            jac = jacobian(p)
            k = jac.shape[1]
            cross = np.column_stack([at_cx[support], at_cy[support]]) @ jac
            sens = np.array([[g @ G["xx"] @ g, g @ G["xy"] @ g],
                             [g @ G["xy"] @ g, g @ G["yy"] @ g]])
            n = int(support.sum())
            normal = np.empty((n + k, n + k))
            normal[:n, :n] = gram[np.ix_(support, support)]
            normal[:n, n:] = cross
            normal[n:, :n] = cross.T
            normal[n:, n:] = jac.T @ sens @ jac
            right = np.concatenate([rhs[support], jac.T @ np.array([g @ prod[0], g @ prod[1]])])
            try:
                step = np.linalg.solve(normal, right)[n:]
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(normal, right, rcond=None)[0][n:]
            for _halving in range(6):
                trial = p + step
                g_trial, rho_trial = self.fit(frame, *shear(trial), passive=support)
                if rho_trial < rho:
                    break
                step = step / 2
            else:
                break
            converged = (np.max(np.abs(step)) < self.tolerance
                         or rho - rho_trial < self.tolerance * 0.1 * rho)
            p, g, rho = trial, g_trial, rho_trial
            if converged:
                break
        return p, g, rho

    def _choice(self, frame, s, g_region, rho, norm, *, detected):
        profile = np.zeros(frame.stress.size)
        profile[frame.region_index] = g_region
        efficiency = 1.0 if norm == 0 else 1.0 - math.sqrt(max(rho, 0.0)) / norm
        return Choice(float(s[0]), float(s[1]), profile, efficiency, detected)


class NoShear:
    """Baseline: never report shear; the template is the shear-free contact fit."""

    name = "no_shear"

    def choose(self, frame: Frame, *, shear_ratio=None, shear_direction=None) -> Choice:
        return ContactFit().choose(frame, shear_ratio=shear_ratio or 0.0,
                                   shear_direction=shear_direction or 0.0)


class Admissibility:
    """Penalties on the linear family with a fixed profile (the DESIGN's first sketch).

    With ``g`` the positive part of the normal-only solution, the family is
    ``x = a0 + sx a1 + sy a2`` (three vectors per frame), evaluated on a grid of
    pairs in one matrix product. The efficiency is minus the squared sum of
    tension (``Fz < 0``), friction-cone violation (``|Ft| > mu Fz``) and force
    outside the contact region, relative to ``|g|^2``.

    Parameters
    ----------
    ratios, directions : int, optional
        Grid resolution of the search. Defaults 31 and 72.
    """

    name = "admissibility"

    def __init__(self, *, ratios: int = 31, directions: int = 72):
        self.ratios = int(ratios)
        self.directions = int(directions)

    def choose(self, frame: Frame, *, shear_ratio=None, shear_direction=None) -> Choice:
        m = frame.stress.size
        g = np.maximum(frame.normal, 0.0) * frame.region
        zeros = np.zeros(m)
        a0 = frame.apply_pinv(frame.stress) + frame.project_null(np.concatenate([zeros, zeros, g]))
        a12 = frame.project_null(np.column_stack([np.concatenate([g, zeros, zeros]),
                                                  np.concatenate([zeros, g, zeros])]))
        mus = (np.linspace(0, frame.max_shear_ratio, self.ratios) if shear_ratio is None
               else np.array([shear_ratio]))
        thetas = (np.linspace(-math.pi, math.pi, self.directions, endpoint=False)
                  if shear_direction is None else np.array([shear_direction]))
        mu, theta = (a.ravel() for a in np.meshgrid(mus, thetas))
        sx, sy = mu * np.cos(theta), mu * np.sin(theta)
        x = a0[:, None] + a12 @ np.vstack([sx, sy])
        fx, fy, fz = x[:m], x[m:2 * m], x[2 * m:]
        outside = ~frame.region
        tension = np.minimum(fz, 0.0)
        cone = np.maximum(np.hypot(fx, fy) - mu * np.maximum(fz, 0.0), 0.0)
        penalty = ((tension**2).sum(0) + (cone**2).sum(0)
                   + (fx[outside]**2 + fy[outside]**2 + fz[outside]**2).sum(0))
        scale = max(float(g @ g), 1e-300)
        best = int(np.argmin(penalty))
        return Choice(float(sx[best]), float(sy[best]), g, -float(penalty[best]) / scale,
                      bool(mu[best] > 0) and shear_ratio is None)


FUNCTIONALS = {f.name: f for f in (ContactFit, Admissibility, NoShear)}

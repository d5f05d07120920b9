"""Reconstruction of 3-component surface forces from normal stress readings.

The method (Seminara, Capurro, Valle): with ``C = [Cx | Cy | Cz]`` of shape
``(m, 3m)`` every exact solution of ``C x = b`` is

    x(mu, theta) = C+ b + (I - C+ C) y(mu, theta),
    y = [mu cos(theta) g ; mu sin(theta) g ; g],

the data-consistent force field closest to a friction-shaped compressive load
``y``. ``C+ = C^T (C C^T)^-1`` comes from one Cholesky factor per geometry; the
projector is applied as ``y - C+ (C y)`` and never formed. The shear ratio
``mu`` and direction ``theta`` are either given (the GUI sliders) or chosen by
maximizing an efficiency functional (:mod:`solver.efficiency`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .arrays import read_only
from .efficiency import ContactFit, Frame
from .geometry import SensorGrid
from .kernels import KERNELS, stress_matrix

__all__ = ["Reconstructor", "Reconstruction", "SymmetricFactor"]

# Largest grid (sensors) for which C^T C (3m x 3m) is kept: beyond it, forming
# it costs more set-up time than the per-frame region Gram blocks ever save.
GRAM_LIMIT = 400


@dataclass(frozen=True)
class SymmetricFactor:
    """Cholesky factor of a symmetric positive (semi-)definite matrix, damped if needed.

    Attributes
    ----------
    shift : float
        ``lambda`` added to the diagonal before factoring (0 when the matrix
        was well enough conditioned).
    condition : float
        1-norm condition estimate of the matrix actually factored.
    condition_undamped : float
        The same for the matrix as given (``inf`` when it was numerically
        singular).
    """

    factor: np.ndarray
    shift: float
    condition: float
    condition_undamped: float

    def __post_init__(self):
        # LAPACK wants column-major storage; converting once here saves a full
        # copy of the factor on every solve.
        object.__setattr__(self, "factor", np.asfortranarray(self.factor))

    @classmethod
    def of(cls, matrix: np.ndarray, *, max_condition: float) -> SymmetricFactor:
        # Tikhonov damping: (A + lambda I) with lambda = |A|_1 / max_condition
        # bounds cond(A + lambda I) by about max_condition + 1 and leaves the
        # well-conditioned cases exact (lambda = 0).
        norm = float(np.linalg.norm(matrix, 1)) if matrix.size else 0.0
        if norm == 0.0:
            return cls(np.eye(matrix.shape[0]), 0.0, 1.0, 1.0)
        undamped = math.inf
        try:
            factor = scipy.linalg.cholesky(matrix, lower=True, check_finite=False)
            undamped = _condition_from_cholesky(factor, norm)
            if undamped <= max_condition:
                return cls(factor, 0.0, undamped, undamped)
        except np.linalg.LinAlgError:
            pass
        shift = norm / max_condition
        damped = matrix + shift * np.eye(matrix.shape[0])
        factor = scipy.linalg.cholesky(damped, lower=True, check_finite=False)
        return cls(factor, shift, _condition_from_cholesky(factor, norm + shift), undamped)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        # LAPACK potrs directly: cho_solve's checks cost more than the solve on small grids.
        solution, info = scipy.linalg.lapack.dpotrs(self.factor, rhs, lower=1)
        if info != 0:
            raise ValueError(f"dpotrs failed with info={info}")
        return solution


def _condition_from_cholesky(lower: np.ndarray, norm: float) -> float:
    rcond, info = scipy.linalg.lapack.dpocon(lower, norm, uplo="L")
    # rcond is an estimate: clamp the rounding that can put it a hair above 1
    return math.inf if rcond <= 0 else max(1.0, 1.0 / rcond)


@dataclass(frozen=True)
class Reconstruction:
    """Reconstructed surface forces of one frame.

    Attributes
    ----------
    forces : (m, 3) ndarray
        Force per node (Fx, Fy, Fz), newtons; ``Fz > 0`` presses into the skin.
    shear_ratio : float
        Tangential over normal force of the template load (dimensionless).
    shear_direction : float
        Direction of the tangential load, radians from +x in ``(-pi, pi]``.
    efficiency : float
        Value of the efficiency functional at the chosen parameters (``nan``
        on the normal-only path).
    residual : float
        ``|C x - b| / |b|`` (0 for an all-zero frame).
    condition : float
        Condition estimate of the matrix factored for this solve
        (``C C^T`` for three components, ``Cz`` for normal only), damping included.
    regularized : bool
        Whether Tikhonov damping was applied because the layer is too thick
        for the grid (the condition exceeded the reconstructor's limit).
    normal_only : bool
        True when the tangential components were not reconstructed.
    shear_detected : bool
        Whether the automatic search found shear that explains the data
        better than a shear-free load (False when the parameters were given).
    region : (m,) ndarray of bool
        Nodes allowed to carry the template load (the contact region).
    contacts : tuple of solver.region.Contact
        Per-contact solutions when the skin was solved contact by contact
        (:class:`solver.region.RegionSolver`); empty otherwise.
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
    contacts: tuple = ()

    @property
    def total_force(self) -> np.ndarray:
        """(3,) ndarray: sum of the nodal forces, newtons."""
        return self.forces.sum(axis=0)


class Reconstructor:
    """Contact forces from normal stress readings, for one sensor geometry.

    Everything that depends only on the geometry (the stress matrix, the
    Cholesky factors of ``Cz`` and ``C C^T``, the neighbourhoods used to grow
    contact regions) is computed once here; :meth:`solve` then costs a few
    matrix-vector products plus a small search.

    Parameters
    ----------
    grid : SensorGrid
        Sensor layout and layer thickness.
    kernel : {"layer", "cell", "point"}, optional
        Stress kernel (see :mod:`solver.kernels`). Default "layer": the
        grid's elastomer bonded to a rigid hull, with its Poisson ratio;
        "cell" and "point" are the paper's half-space kernels.
    max_condition : float, optional
        Largest condition number of ``Cz`` and of ``C`` accepted undamped;
        beyond it Tikhonov damping keeps the forces bounded (thick layers,
        ``h / pitch`` above about 1.7). Default 100: on a 16x16 Hertzian
        contact with 1% noise at ``h / pitch = 3`` the field error is 0.9 of
        ``|F|`` with it, 5.2 with 1e3 and 23 with 1e4 (total normal error
        1.3%, 5.9%, 7.9%).
    max_shear_ratio : float, optional
        Upper bound of the automatic shear-ratio search. Default 1.5.
    region_threshold : float, optional
        Fraction of the peak normal-only force above which a node is loaded.
        Default 0.2.
    region_margin : int, optional
        Pitches by which the contact region grows around the loaded nodes.
        Default 1. (Threshold and margin were chosen by measured accuracy on
        the standard set; 5% grown by ``h/pitch + 1`` rings let in more noise:
        see ``docs/efficiency.md``.)
    efficiency : object, optional
        The efficiency functional (see :mod:`solver.efficiency`). Default
        :class:`solver.efficiency.ContactFit`.
    """

    def __init__(self, grid: SensorGrid, *, kernel: str = "layer", max_condition: float = 100.0,
                 max_shear_ratio: float = 1.5, region_threshold: float = 0.2,
                 region_margin: int = 1,
                 efficiency=None):
        if not isinstance(grid, SensorGrid):
            raise ValueError(f"grid must be a SensorGrid, got {type(grid).__name__}")
        if kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
        if not (math.isfinite(max_condition) and max_condition > 1):
            raise ValueError(f"max_condition must be a finite number > 1, got {max_condition!r}")
        if not (math.isfinite(max_shear_ratio) and max_shear_ratio >= 0):
            raise ValueError(f"max_shear_ratio must be finite and >= 0, got {max_shear_ratio!r}")
        self.grid = grid
        self.kernel = kernel
        self.max_condition = float(max_condition)
        self.max_shear_ratio = float(max_shear_ratio)
        self.efficiency = ContactFit() if efficiency is None else efficiency
        m = grid.size
        self.matrix = stress_matrix(grid, kernel)
        self.matrix.setflags(write=False)
        # Cz = cz^T is symmetric positive definite (every kernel is even in the offset): one
        # Cholesky factor serves the normal-only path.
        self._normal = SymmetricFactor.of(self.matrix[:, 2 * m:], max_condition=self.max_condition)
        # C+ = C^T (C C^T)^-1; cond(C C^T) = cond(C)^2.
        self._gram = SymmetricFactor.of(self.matrix @ self.matrix.T, max_condition=self.max_condition**2)
        # Small grids keep C^T C so each frame's contact fit only gathers its blocks.
        self._column_gram = self.matrix.T @ self.matrix if m <= GRAM_LIMIT else None
        # Contact regions: connected patches of the normal-only solution, grown
        # by a margin.
        tree = cKDTree(grid.positions)
        self._adjacent = _within(tree, 1.5 * grid.pitch)
        if not 0 < region_threshold < 1:
            raise ValueError(f"region_threshold must be in (0, 1), got {region_threshold!r}")
        if isinstance(region_margin, bool) or int(region_margin) != region_margin or region_margin < 0:
            raise ValueError(f"region_margin must be a whole number of pitches >= 0, got {region_margin!r}")
        self.region_threshold = float(region_threshold)
        self.region_margin = int(region_margin)
        self._margin = _within(tree, self.region_margin * grid.pitch * 1.0001)
        self._disk = None
        if grid.is_regular:
            k = self.region_margin
            oy, ox = np.mgrid[-k:k + 1, -k:k + 1]
            self._disk = ox * ox + oy * oy <= k * k * 1.0001

    # -- linear algebra of the solution family ---------------------------------

    def apply_pinv(self, stress: np.ndarray) -> np.ndarray:
        """``C+ b`` for ``b`` of shape ``(m,)`` or ``(m, k)``; result ``(3m,)`` or ``(3m, k)``."""
        return self.matrix.T @ self._gram.solve(stress)

    def project_null(self, forces: np.ndarray) -> np.ndarray:
        """``(I - C+ C) y`` for ``y`` of shape ``(3m,)`` or ``(3m, k)``, without forming the projector."""
        return forces - self.apply_pinv(self.matrix @ forces)

    # -- public solves ----------------------------------------------------------

    def solve_normal(self, stress) -> Reconstruction:
        """Normal-only forces ``Fz = Cz^-1 b`` (pressure-only view).

        Parameters
        ----------
        stress : (m,) or (ny, nx) ndarray
            Sensor stress, pascals, compression positive.
        """
        b = check_stress(stress, self.grid)
        m = self.grid.size
        fz = self._normal.solve(b)
        forces = np.zeros((m, 3))
        forces[:, 2] = fz
        return Reconstruction(
            forces=read_only(forces), shear_ratio=0.0, shear_direction=0.0, efficiency=math.nan,
            residual=self._residual(np.concatenate([np.zeros(2 * m), fz]), b),
            condition=self._normal.condition, regularized=self._normal.shift > 0,
            normal_only=True, shear_detected=False, region=read_only(fz > 0, bool))

    def solve(self, stress, *, shear_ratio: float | None = None,
              shear_direction: float | None = None, constrained: bool = False) -> Reconstruction:
        """Three-component forces: the member of the exact solution family at ``(mu, theta)``.

        When both parameters are chosen automatically and the data shows no
        shear signature (the efficiency functional keeps no shear), the answer
        is the normal-only solution, and the result says so
        (``normal_only=True``, ``shear_detected=False``).

        Parameters
        ----------
        stress : (m,) or (ny, nx) ndarray
            Sensor stress, pascals, compression positive.
        shear_ratio : float or None, optional
            ``mu >= 0``. None: chosen by maximizing the efficiency functional.
        shear_direction : float or None, optional
            ``theta`` in radians. None: chosen by maximizing the efficiency functional.
        constrained : bool, optional
            Return the compressive, friction-shaped load the efficiency
            functional fitted at the chosen parameters (normal forces >= 0 on
            the contact region, tangential = shear x normal) instead of the
            exact solution closest to it. It does not satisfy ``C x = b``
            exactly (the residual says how far); on the standard set it trades
            normal-total accuracy for tangential accuracy. Default False.

        Returns
        -------
        Reconstruction
        """
        b = check_stress(stress, self.grid)
        for name, value in (("shear_ratio", shear_ratio), ("shear_direction", shear_direction)):
            if value is not None and not isinstance(value, (int, float, np.integer, np.floating)):
                raise ValueError(f"{name} must be a real number (or None), got {type(value).__name__}")
        if shear_ratio is not None and not (math.isfinite(shear_ratio) and shear_ratio >= 0):
            raise ValueError(f"shear_ratio must be finite and >= 0 (or None), got {shear_ratio!r}")
        if shear_direction is not None and not math.isfinite(shear_direction):
            raise ValueError(f"shear_direction must be finite radians (or None), got {shear_direction!r}")
        frame = self._frame(b)
        choice = self.efficiency.choose(frame, shear_ratio=shear_ratio,
                                        shear_direction=shear_direction)
        shear_x, shear_y = choice.shear_x, choice.shear_y
        g = choice.profile
        m = self.grid.size
        automatic = shear_ratio is None and shear_direction is None
        if automatic and not choice.shear_detected and not constrained:
            # no shear signature: the normal-only path, and the result says so
            normal = self.solve_normal(b)
            return replace(normal, efficiency=choice.efficiency,
                           region=read_only(frame.region, bool))
        # x = y + C+ (b - C y): the exact solution closest to the template y.
        template = np.concatenate([shear_x * g, shear_y * g, g])
        x = template if constrained else template + self.apply_pinv(b - self.matrix @ template)
        ratio = math.hypot(shear_x, shear_y)
        if ratio > 0:
            direction = math.atan2(shear_y, shear_x)
        else:
            direction = 0.0 if shear_direction is None else math.remainder(shear_direction, 2 * math.pi)
        if direction == -math.pi:
            direction = math.pi
        return Reconstruction(
            forces=read_only(x.reshape(3, m).T), shear_ratio=ratio, shear_direction=direction,
            efficiency=choice.efficiency, residual=self._residual(x, b),
            condition=self._gram.condition, regularized=self._gram.shift > 0,
            normal_only=False, shear_detected=choice.shear_detected,
            region=read_only(frame.region, bool))

    # -- helpers ------------------------------------------------------------------

    @property
    def condition(self) -> float:
        """Condition estimate of ``C C^T`` as factored (damping included)."""
        return self._gram.condition

    def contact_region(self, normal: np.ndarray) -> np.ndarray:
        """Nodes that may carry contact load, from a normal-only solution.

        The core is every node above ``region_threshold`` of the peak; of its connected patches
        only those holding at least 5% of the largest patch's force are kept
        (isolated noise spikes of the inversion are dropped); the result is
        grown by ``region_margin`` pitches.
        """
        peak = normal.max() if normal.size else 0.0
        if not peak > 0:
            return np.zeros(normal.size, dtype=bool)
        if self._disk is not None:
            # Regular grid: the same operations on the image, much cheaper.
            image = normal.reshape(self.grid.shape)
            core = image > self.region_threshold * peak
            labels, count = ndimage.label(core, structure=np.ones((3, 3)))
            mass = ndimage.sum_labels(image, labels, index=np.arange(1, count + 1))
            kept = np.isin(labels, 1 + np.flatnonzero(mass >= 0.05 * mass.max()))
            if self.region_margin == 0:
                return kept.ravel()
            return ndimage.binary_dilation(kept, structure=self._disk).ravel()
        core = np.flatnonzero(normal > self.region_threshold * peak)
        count, labels = connected_components(self._adjacent[core][:, core], directed=False)
        mass = np.bincount(labels, weights=normal[core], minlength=count)
        keep = np.zeros(normal.size, dtype=np.int8)
        keep[core[mass[labels] >= 0.05 * mass.max()]] = 1
        return np.asarray(self._margin @ keep).ravel() > 0

    def _frame(self, b: np.ndarray) -> Frame:
        normal = self._normal.solve(b)
        region = self.contact_region(normal)
        return Frame(stress=b, normal=normal, region=region, matrix=self.matrix,
                     max_shear_ratio=self.max_shear_ratio, project_null=self.project_null,
                     apply_pinv=self.apply_pinv, gram=self._column_gram)

    def _residual(self, x: np.ndarray, b: np.ndarray) -> float:
        norm = np.linalg.norm(b)
        if norm == 0:
            return 0.0
        return float(np.linalg.norm(self.matrix @ x - b) / norm)


def check_stress(stress, grid: SensorGrid) -> np.ndarray:
    """``stress`` as a flat ``(m,)`` float array for ``grid``; ValueError says what is wrong with it."""
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
    bad = ~np.isfinite(b)
    if bad.any():
        kinds = sorted({"NaN" if np.isnan(v) else "inf" for v in b[bad]})
        raise ValueError(
            f"stress must be finite, got {' and '.join(kinds)} at taxel(s) "
            f"{np.flatnonzero(bad)[:10].tolist()}"
        )
    return b


def _within(tree: cKDTree, distance: float):
    # Sparse boolean adjacency of nodes closer than ``distance`` (self included).
    pairs = tree.sparse_distance_matrix(tree, distance, output_type="coo_matrix").tocsr()
    return (pairs + sparse.identity(tree.n, format="csr")).astype(bool).astype(np.int8)

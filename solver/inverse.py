"""Reconstruction of 3-component surface forces from normal stress readings.

The method (Seminara, Capurro, Valle): with ``C = [Cx | Cy | Cz]`` of shape
``(m, 3m)`` every exact solution of ``C x = b`` is

    x(mu, theta) = C+ b + (I - C+ C) y(mu, theta),
    y = [mu cos(theta) g ; mu sin(theta) g ; g],

the data-consistent force field closest to a friction-shaped compressive load
``y``. ``C+ = C^T (C C^T)^-1`` comes from one inverse of ``C C^T`` per geometry; the
projector is applied as ``y - C+ (C y)`` and never formed. The shear ratio
``mu`` and direction ``theta`` are either given (the GUI sliders) or chosen by
maximizing an efficiency functional (:mod:`solver.efficiency`), which fits a
compressive, friction-shaped load to every contact with its own parameters.
With automatic parameters that fitted load is the answer: it has no tension,
no load outside the contacts and totals that do not depend on the skin around
them (the exact member spreads every sensor's noise into the totals).
"""

from __future__ import annotations

import copy
import math

import numpy as np
from scipy.spatial import cKDTree

from .arguments import check_options, check_parameters, check_stress
from .arrays import read_only
from .efficiency import ContactFit
from .geometry import SensorGrid, neighbours_within, patch_links
from .kernels import stress_matrix
from .results import Contact, Reconstruction, shear_direction_of
from .search import contact_labels, contact_reach, faint_cores, halved_labels, template_misfit
from .seen_frame import WHOLE_CELLS, SeenFrame, noise_level
from .symmetric import SymmetricInverse
from .threads import one_blas_thread

__all__ = ["DenseSolver"]

# Beyond the fit's budget there is no load decision: a contact is reported when its normal-only
# total stands this many noise deviations out (chosen on the load-decision frames of seeds 1 to
# 3, judged on 11 to 13: measurement.validation --load-decision).
BROAD_EVIDENCE = 10.0
# A patch whose two peaks are parted by a dip shallower than ``separation`` (two contacts that
# touch: the normal-only solution's dip 0.65 to 0.69 of the peaks for two Hertz contacts side by
# side, h / pitch 1) is tried split at this separation too, and kept split where the fit says so
# (DenseSolver._split_if_better; docs/efficiency.md).
SPLIT_SEPARATION = 0.75
# A contact with no such dip whose load spreads this many times as far along its long axis as across
# it is tried halved across that axis, under the same test. Random touching pinches kept as two
# contacts with opposite shears were the same from 1.1 to 1.8 (89 of 120), fewer at 2.2 (83); no
# single contact was split at any of them, ellipses of aspect 1.5 to 2.5 included (seeds 101 and
# 202; docs/efficiency.md). An elongated contact costs a second fit.
SPLIT_ELONGATION = 1.5
# A broad light load beside a sharp one (a palm beside a fingertip) carries less per node than
# ``region_threshold`` of the frame's peak: the patches of the normal-only solution above this
# fraction of the peak whose core holds less than half their load are candidates
# (solver.search.faint_cores), contacts when their normal-only total stands BROAD_EVIDENCE noise
# deviations out (noise's candidates reached 8.3 on the load-decision frames of seeds 1 to 3, on
# 32x32 skins under 10% noise; light loads 3.5 to 55 on the beside scenes' tuning set at 1%, those
# under 10 at h / pitch 1.5; docs/efficiency.md).
FAINT_LEVEL = 0.05
# A patch picked for standing above a level has nodes that, under noise alone, average about one to
# one and a half noise deviations each (a normal distribution's tail): its total's evidence grows as
# the square root of its size (152 nodes of noise on a 32x32 skin at 10% read 14 deviations). A light
# load's nodes stand out each: a candidate also needs this many deviations per square root of its
# nodes (noise's candidates reached 1.94, the light loads kept at BROAD_EVIDENCE 2.37 and more: the
# load-decision frames of seeds 1 to 3, a load on a 32x32 skin under 10% and 20% noise, the beside
# scenes' tuning set).
FAINT_NODE_EVIDENCE = 2.0


def _relative(misfit: np.ndarray, b: np.ndarray) -> float:
    # |C x - b| / |b|, 0 for an all-zero frame
    norm = b @ b
    return 0.0 if norm == 0 else math.sqrt((misfit @ misfit) / norm)


class DenseSolver:
    """Contact forces from normal stress readings, for one sensor geometry.

    Everything that depends only on the geometry (the stress matrices, the
    inverses of ``Cz`` and ``C C^T``, the neighbourhoods used to grow
    contact regions) is computed once here; :meth:`solve` then costs a few
    matrix-vector products plus a small search on the contacts.

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
        beyond it Tikhonov damping keeps the exact solutions bounded (thick
        layers, ``h / pitch`` above about 1.7). Default 100: on a 16x16
        Hertzian contact with 1% noise at ``h / pitch = 3`` the field error is
        0.9 of ``|F|`` with it, 5.2 with 1e3 and 23 with 1e4.
    max_shear_ratio : float, optional
        Upper bound of the automatic shear-ratio search. Default 1.5.
    region_threshold : float, optional
        Fraction of the peak normal-only force above which a node is loaded.
        Default 0.2. A light load whose nodes all stay below it (a palm
        beside a fingertip) is found on its own scale where it stands out of
        the noise (:meth:`faint_contacts`).
    region_margin : int, optional
        Pitches by which the contact region grows around the loaded nodes.
        Default 1. A node within the margin of two contacts goes to the
        nearer one: contacts that touch stay two.
    separation : float, optional
        Two peaks of one loaded patch are two contacts when the highest path
        between them sinks to at most this fraction of the lower peak
        (:func:`solver.search.contact_labels`): a pinch, or two fingers a
        pitch or two apart. 0 never splits a patch. Default 0.6. Not used
        where the normal-only solve is damped (thick layers): there every
        patch is one contact. With automatic parameters a patch is also
        tried split at :data:`SPLIT_SEPARATION` (two contacts that touch),
        or, with no such dip, halved across its long axis when it is
        :data:`SPLIT_ELONGATION` times as long as wide, and kept split where
        the fit says so (:meth:`solver.efficiency.ContactFit.split_evidence`).
    subdivision : int, optional
        The contact fit splits each node's cell into ``s x s`` sub-cells so
        that a contact edge inside a cell is not read as shear (regular grids
        with the layer or cell kernel and ``pitch / s <= 2 h``; 1 otherwise).
        Default 2 (3 and 4 uniform sub-cells measured worse: the extra
        freedom absorbs the shear signature). The answer stays one force per
        node (the sum of its sub-cells).
    profile : {"bilinear", "uniform"}, optional
        The load over each sub-cell in the contact fit
        (:func:`solver.kernels.stress_matrix`): a bilinear hat reaching the
        neighbouring sub-cells' centres, so the fitted load is continuous
        (default), or uniform over the sub-cell. Ignored with whole cells.
    reach : float, optional
        The contact fit and its statistics use the sensors within ``reach``
        layer thicknesses plus one pitch of a contact. Default 2 (the layer
        kernel falls below 1% of its peak there).
    fit_budget : int, optional
        Most nodes the sub-cell contact fit takes on (all contacts of a
        frame together). A broader load (a palm, an untared board) gets a
        cheaper answer, said in :attr:`Reconstruction.fallback`: up to
        :data:`~solver.seen_frame.WHOLE_CELLS` times as many nodes, the same fit on whole cells;
        beyond, with automatic parameters the normal-only answer, with given
        ones the paper's template from its positive part. Not on layers
        thick enough to damp the normal-only solve: there only the fit tells
        load from noise, whatever it costs. Default 160
        (CPU, 2-core Xeon VM, ``docs/efficiency.md``): the sub-cell fit of
        139 nodes took 35 ms, of 234 nodes 123 ms, of most of a 32x32 skin
        3.6 s; the whole-cell fit of 234 nodes 25 ms, of 355 nodes 67 ms.
    efficiency : object, optional
        The efficiency functional (see :mod:`solver.efficiency`). Default
        :class:`solver.efficiency.ContactFit`.
    """

    def __init__(self, grid: SensorGrid, *, kernel: str = "layer", max_condition: float = 100.0,
                 max_shear_ratio: float = 1.5, region_threshold: float = 0.2,
                 region_margin: int = 1, separation: float = 0.6, subdivision: int = 2,
                 profile: str = "bilinear", reach: float = 2.0, fit_budget: int = 160, efficiency=None):
        check_options(grid, kernel=kernel, max_condition=max_condition, max_shear_ratio=max_shear_ratio,
                      region_threshold=region_threshold, region_margin=region_margin,
                      separation=separation, subdivision=subdivision, profile=profile, reach=reach,
                      fit_budget=fit_budget)
        self.grid = grid
        self.kernel = kernel
        self.max_condition = float(max_condition)
        self.max_shear_ratio = float(max_shear_ratio)
        self.region_threshold = float(region_threshold)
        self.region_margin = int(region_margin)
        self.separation = float(separation)
        self.reach = float(reach)
        self.fit_budget = int(fit_budget)
        self.efficiency = ContactFit() if efficiency is None else efficiency
        # (SeenFrame, choice, its parameters) of the last frame fitted
        self._recent = None
        # Sub-cells need translation invariance and a kernel that spreads the force over a
        # cell, and a layer thick enough to tell them apart: under a layer thinner than half
        # a sub-cell each sensor sees only its sub-cells' shared corner, and the fit exploits
        # loads that cancel there (at h / pitch = 0.2 it invents a shear ratio of 0.5).
        self.subdivision = int(subdivision)
        if not grid.is_regular or kernel == "point" or grid.pitch / subdivision > 2 * grid.thickness:
            self.subdivision = 1
        m = grid.size
        self.matrix = stress_matrix(grid, kernel)
        self.matrix.setflags(write=False)
        # the columns as contiguous rows (3 s^2 m, m), without a copy (stress_matrix stores by
        # column): the contact fit and the exact member's template read whole columns. Read-only
        # whichever matrix they come from: numba compiles a function once per kind of array.
        self.profile = profile
        self._fit_columns = (self.matrix if self.subdivision == 1 else
                             stress_matrix(grid, kernel, subdivision=self.subdivision, profile=profile)).T
        self._fit_columns.setflags(write=False)
        # Cz = cz^T is symmetric positive definite (every kernel is even in the offset): one
        # inverse serves the normal-only path.
        self._normal = SymmetricInverse.of(self.matrix[:, 2 * m:], max_condition=self.max_condition)
        # C+ = C^T (C C^T)^-1; cond(C C^T) = cond(C)^2.
        self._gram = SymmetricInverse.of(self.matrix @ self.matrix.T, max_condition=self.max_condition**2)
        # Contact regions: connected patches of the normal-only solution, grown by a margin;
        # the neighbourhoods as (indptr, indices) of their CSR matrices (solver.search).
        tree = cKDTree(grid.positions)
        self._adjacent = patch_links(grid, tree)
        self._neighbours = neighbours_within(tree, 2.5 * grid.pitch)
        self._margin = neighbours_within(tree, self.region_margin * grid.pitch * 1.0001)
        self._rings = math.ceil(self.reach * grid.thickness / grid.pitch) + 1
        self._near = neighbours_within(tree, self._rings * grid.pitch * 1.0001)

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

    @one_blas_thread()
    def solve(self, stress, *, shear_ratio: float | None = None,
              shear_direction: float | None = None, exact: bool | None = None) -> Reconstruction:
        """Three-component forces of every contact, each with its own shear parameters.

        The efficiency functional fits a compressive, friction-shaped load to
        each contact (:class:`solver.efficiency.ContactFit`). With automatic
        parameters the answer is that fitted load: compressive, zero outside
        the contacts, its totals independent of the skin around the contacts,
        and shear only where the data shows it. With given parameters (the
        sliders) it is the paper's answer: the member of the exact family
        ``C x = b`` closest to the fitted template at ``(mu, theta)``.

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
            True: the exact member ``x = y + C+ (b - C y)``; False: the fitted
            load ``y`` itself. Default None: False when both parameters are
            automatic, True otherwise.

        Returns
        -------
        Reconstruction
        """
        b = check_stress(stress, self.grid)
        exact = check_parameters(shear_ratio, shear_direction, exact)
        m = self.grid.size
        direction = 0.0 if shear_direction is None else float(shear_direction)
        # A slider moves the parameters on the frame shown: its contacts and fit matrices are
        # kept from the last solve of that frame, and the fit starts from the last profile (the
        # same parameters again give the same choice, not one equal up to rounding). Another
        # frame starts its fit from the last one's set (playback and live mode: the frame
        # before), with given parameters and in the automatic search alike: that changes the
        # answer by rounding, or by about 2e-9 of the peak force where the profile is not
        # unique (ContactFit.choose).
        key, parameters = b.tobytes(), (shear_ratio, shear_direction)
        recent = self._recent
        if recent is not None and recent[0].key == key:
            seen, start, solved_for = recent
        else:
            seen, solved_for = self._frame(b, like=None if recent is None else recent[0]), None
            start = None if recent is None else recent[1]
        if seen.over:
            return self._beyond_budget(b, seen, shear_ratio, shear_direction, exact, direction)
        if seen.frame is None:  # nothing compressive anywhere: no contact to fit
            return self._without_contact(b, exact, direction)
        if solved_for == parameters:
            choice = start
        else:
            choice = self.efficiency.choose(seen.frame, shear_ratio=shear_ratio,
                                            shear_direction=shear_direction, start=start)
            if solved_for is None and shear_ratio is None and shear_direction is None:
                seen, choice = self._split_if_better(b, seen, choice)
        # one tuple, replaced whole: solves on other threads read either the old or the new one
        self._recent = (seen, choice, parameters)
        # the answer stays one force per node: the sum of its sub-cells
        g = np.bincount(seen.frame.column_node, weights=choice.profile, minlength=m)
        # a patch the compressive fit gives no load (tension read through a damped inverse
        # on a thick layer) is not a contact
        loaded = seen.weights @ g > 0
        if not loaded.any():
            return self._without_contact(b, exact, direction)
        misfit = b.copy()
        template = template_misfit(self.matrix.T, seen.labels, choice.shear, g, misfit)
        if exact:
            # x = y + C^T w with (C C^T + lambda I) w = b - C y, so C x - b = -lambda w: the
            # residual needs no product with C
            w = self._gram.solve(misfit)
            x = template + self.matrix.T @ w
            misfit = self._gram.shift * w
        else:
            x = template
        forces = x.reshape(3, m).T
        contacts = self._contacts(seen, forces, loaded, choice.shear, choice.evidence, choice.shear_detected,
                                  direction)
        # a view: the frame's arrays are shared by its results, and a view of a read-only
        # array cannot be made writable again
        region = seen.region.view() if loaded.all() else read_only(
            np.concatenate([[False], loaded])[seen.labels], bool)
        main = contacts[0]
        return Reconstruction(
            forces=read_only(forces), shear_ratio=main.shear_ratio, shear_direction=main.shear_direction,
            efficiency=choice.efficiency, residual=_relative(misfit, b),
            condition=self._gram.condition, regularized=exact and self._gram.shift > 0,
            normal_only=False, shear_detected=any(c.shear_detected for c in contacts),
            region=region, exact=bool(exact), contacts=tuple(contacts), fallback=seen.fallback)

    def _contacts(self, seen, forces, loaded, shear, evidence, detected, direction):
        # every loaded contact with its pair, totals and centre, largest normal force first
        totals = seen.weights @ forces  # (K, 3)
        pushed = seen.weights * np.clip(forces[:, 2], 0.0, None)
        # where nothing of a contact presses (the exact member may pull), its nodes' middle
        pushed = np.where(pushed.sum(axis=1, keepdims=True) > 0, pushed, seen.weights)
        centres = (pushed @ self.grid.positions) / pushed.sum(axis=1, keepdims=True)
        contacts = []
        for k in loaded.nonzero()[0]:
            sx, sy = shear[k]
            contacts.append(Contact(
                nodes=seen.nodes[k], shear_ratio=math.hypot(sx, sy),
                shear_direction=shear_direction_of(sx, sy, direction), evidence=float(evidence[k]),
                shear_detected=bool(detected[k]), at_edge=bool(seen.at_edge[k]),
                total_force=read_only(totals[k]), centre=read_only(centres[k])))
        contacts.sort(key=lambda c: -c.total_force[2])
        return contacts

    def _beyond_budget(self, b, seen, shear_ratio, shear_direction, exact, direction):
        # A load broader than the fit's budget: the normal-only answer (automatic), or the paper's
        # member with the template y = [mu cos(theta) g; mu sin(theta) g; g], g the positive part
        # of the normal-only solution on the contacts (given parameters).
        m = self.grid.size
        fz = self._normal.solve(b)
        why = (f"the contacts cover {seen.over} nodes, more than the contact fit's budget of "
               f"{WHOLE_CELLS * self.fit_budget} ({WHOLE_CELLS} x fit_budget)")
        K = seen.nodes.shape[0]
        if shear_ratio is None and shear_direction is None:
            forces = np.zeros((m, 3))
            forces[:, 2] = fz
            shear = np.zeros((K, 2))
            misfit = self.matrix[:, 2 * m:] @ fz - b
            kind, exact, normal_only, condition = "normal only", True, True, self._normal
        else:
            ratio = 0.0 if shear_ratio is None else float(shear_ratio)
            g = np.where(seen.region, np.clip(fz, 0.0, None), 0.0)
            y = np.concatenate([ratio * math.cos(direction) * g, ratio * math.sin(direction) * g, g])
            shear = np.tile([ratio * math.cos(direction), ratio * math.sin(direction)], (K, 1))
            misfit = b - self.matrix @ y
            if exact:
                w = self._gram.solve(misfit)
                y = y + self.matrix.T @ w
                misfit = self._gram.shift * w
            forces = y.reshape(3, m).T
            kind, normal_only, condition = "the template of the normal-only solution", False, self._gram
        # No fit, so no load decision: a contact must stand out of the noise on its own. Its
        # normal-only total F_k = w_k^T Cz^-1 b has the noise deviation sigma |Cz^-1 w_k|, sigma
        # the sensors' own (solver.seen_frame.noise_level).
        sigma = noise_level(b, self.grid)
        spread = np.linalg.norm(self._normal.solve(seen.weights.T), axis=0)  # (K,)
        with np.errstate(divide="ignore", invalid="ignore"):
            loaded = seen.weights @ fz >= BROAD_EVIDENCE * sigma * spread
        region = read_only(np.concatenate([[False], loaded])[seen.labels], bool)
        contacts = self._contacts(seen, forces, loaded, shear, np.full(K, math.nan), np.zeros(K, bool),
                                  direction) if K else []
        main = contacts[0] if contacts else None
        return Reconstruction(
            forces=read_only(forces), shear_ratio=main.shear_ratio if main else 0.0,
            shear_direction=main.shear_direction if main else shear_direction_of(0, 0, direction),
            efficiency=math.nan, residual=_relative(misfit, b), condition=condition.condition,
            regularized=exact and condition.shift > 0, normal_only=normal_only, shear_detected=False,
            region=region, exact=bool(exact), contacts=tuple(contacts),
            fallback=f"{kind}: {why}")

    def _without_contact(self, b, exact, direction):
        # no compressive load anywhere: the exact answer is the normal-only one, the fitted one zero
        m = self.grid.size
        forces = np.zeros((m, 3))
        if exact:
            forces[:, 2] = self._normal.solve(b)
        return Reconstruction(
            forces=read_only(forces), shear_ratio=0.0, shear_direction=shear_direction_of(0, 0, direction),
            efficiency=math.nan, residual=self._residual(forces.T.ravel(), b),
            condition=self._gram.condition, regularized=exact and self._gram.shift > 0,
            normal_only=False, shear_detected=False, region=read_only(np.zeros(m, bool), bool),
            exact=bool(exact))

    # -- helpers ------------------------------------------------------------------

    def sibling(self) -> DenseSolver:
        """A reconstructor sharing this one's matrices, with its own last-frame state.

        :class:`~solver.region.RegionSolver` gives each window of a frame its
        own: two windows of one shape would otherwise replace each other's
        last frame, and a slider move or the next frame would start from the
        other contact's fit.
        """
        twin = copy.copy(self)  # what it shares depends only on the geometry: no solve writes it
        twin._recent = None
        return twin

    @property
    def condition(self) -> float:
        """Condition estimate of ``C C^T`` as inverted (damping included)."""
        return self._gram.condition

    def _split_if_better(self, b, seen, choice):
        # A patch whose dip between two peaks is shallower than ``separation`` (two contacts that
        # touch: a pinch closed on itself) is one contact, fitted with one pair, and opposite shears
        # cancel. Split at SPLIT_SEPARATION instead, it is kept split where the fit explains the same
        # sensors better by more than the extra pairs would by chance (ContactFit.split_evidence).
        if getattr(self.efficiency, "split_evidence", None) is None or self._normal.shift != 0 \
                or self.separation >= SPLIT_SEPARATION:
            return seen, choice
        labels, near = self.contact_labels(seen.normal, separation=SPLIT_SEPARATION, faint=seen.faint)
        if near.shape[1] <= seen.frame.contacts:
            # no dip even at SPLIT_SEPARATION (a pinch closed so far that its two loads make one
            # plateau): an elongated contact is tried halved across its long axis
            labels, near = halved_labels(seen.normal, seen.labels, seen.at_edge, self.grid.positions,
                                         SPLIT_ELONGATION, self._near)
            if near.shape[1] <= seen.frame.contacts:
                return seen, choice
        evidence, split, split_choice = self._split_test(b, seen, choice, labels, near)
        if evidence >= self.efficiency.min_split_evidence:
            return split, split_choice
        return seen, choice

    def _split_test(self, b, seen, choice, labels, near):
        # (F, the split frame, its automatic choice): F nan where the split is not comparable
        split = self._seen(b, seen.normal, labels, near, seen.faint)
        if split.frame is None or split.frame.contacts <= seen.frame.contacts or not np.array_equal(
                split.frame.stress, seen.frame.stress):  # another budget's answer, or other sensors
            return math.nan, split, None
        if split.at_edge.any():
            # half a border contact's stress field is off the skin: a split there was taken for a
            # shear ratio of 1.3 beside a contact at the border (the scenes' tuning set)
            return math.nan, split, None
        # from this frame's own choice: the same columns, so its shear-free fit (which does not
        # depend on how the columns are grouped into contacts) starts on its optimal set
        split_choice = self.efficiency.choose(split.frame, start=choice)
        extra = split.frame.contacts - seen.frame.contacts
        return self.efficiency.split_evidence(choice, split.frame, split_choice, extra), split, split_choice

    def split_statistic(self, stress, labels) -> float:
        """How much better the frame's automatic fit is with its contacts as ``labels`` say.

        The F statistic the automatic solve keeps a split by
        (:meth:`solver.efficiency.ContactFit.split_evidence`, kept at ``min_split_evidence`` and
        above): ``labels`` against the solver's own contacts, on the same sensors. For
        measurements: a split the solver does not try (another axis, another cut) is scored as
        it would score its own.

        Parameters
        ----------
        stress : (m,) or (ny, nx) ndarray
            Sensor stress, pascals.
        labels : (m,) ndarray of int
            Contact 1..K of each node, 0 outside every contact: more contacts than the solver
            finds, on the nodes it finds.

        Returns
        -------
        float
            ``nan`` where the split is not comparable: no contact found, other nodes or other
            sensors, a contact on the skin's border, or a damped layer.

        Raises
        ------
        ValueError
            For ``stress`` or ``labels`` of the wrong size, or labels not numbering contacts from 1.
        """
        b = check_stress(stress, self.grid)
        labels = np.asarray(labels)
        if (labels.shape != (self.grid.size,) or not np.issubdtype(labels.dtype, np.integer)
                or labels.min() < 0):
            raise ValueError(f"labels must be {self.grid.size} whole numbers >= 0 (the grid's nodes), got "
                             f"shape {labels.shape} of {labels.dtype}")
        count = int(labels.max())
        if set(np.unique(labels[labels > 0])) != set(range(1, count + 1)):
            raise ValueError(f"labels must number the contacts 1 to K with none left out, got "
                             f"{sorted(set(np.unique(labels[labels > 0]).tolist()))}")
        seen = self._frame(b)
        if seen.frame is None or self._normal.shift != 0 or not np.array_equal(labels > 0, seen.labels > 0):
            return math.nan
        labels = labels.astype(np.int64)
        choice = self.efficiency.choose(seen.frame)
        return self._split_test(b, seen, choice, labels, contact_reach(labels, count, self._near))[0]

    def contact_labels(self, normal: np.ndarray, *, separation: float | None = None,
                       faint: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Separate contacts of a normal-only solution, and the sensors near each.

        :func:`solver.search.contact_labels` with this reconstructor's
        ``region_threshold``, ``region_margin``, ``separation`` and reach.

        Parameters
        ----------
        normal : (m,) ndarray
            Normal-only force of each node, newtons.
        separation : float or None, optional
            Instead of the reconstructor's ``separation``.
        faint : (m,) ndarray of bool or None, optional
            Cores of loads below ``region_threshold`` of the peak that are
            contacts all the same (:meth:`faint_contacts`). Default none.

        Returns
        -------
        labels : (m,) ndarray of int
            Contact 1..K of each node, 0 outside every contact.
        near : (m, K) ndarray of bool
            The sensors within the fit's reach of each contact.

        Raises
        ------
        ValueError
            If ``faint`` is not one boolean per node.
        """
        # a damped normal-only solve (a thick layer) blurs two loads into one and turns noise into
        # bumps: there every patch is one contact (split, single contacts came apart into pieces
        # given the largest shear ratio: measurement.cases.load_decision_frames, h / pitch 2 to 5)
        if separation is None:
            separation = self.separation
        if self._normal.shift != 0:
            separation = 0.0
        m = self.grid.size
        faint = np.zeros(m, bool) if faint is None else np.asarray(faint)
        if faint.shape != (m,) or faint.dtype != bool:
            raise ValueError(f"faint must be {m} booleans (one per node), got shape {faint.shape} of "
                             f"{faint.dtype}")
        faint = np.array(faint)  # writable: numba compiles apart for read-only arrays
        return contact_labels(np.ascontiguousarray(normal, dtype=float), self.region_threshold,
                              separation, self.grid.positions, self._adjacent, self._margin, self._near,
                              faint)

    def faint_contacts(self, stress: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """The cores of loads too light per node for ``region_threshold`` that are load, not noise.

        A broad light load beside a sharp one (a palm beside a fingertip, a
        flat object beside a cone) carries less per node than
        ``region_threshold`` of the frame's peak. The candidates of
        :func:`solver.search.faint_cores` (patches above :data:`FAINT_LEVEL`
        of the peak) are kept where their normal-only total stands
        :data:`BROAD_EVIDENCE` noise deviations out, and
        :data:`FAINT_NODE_EVIDENCE` times the square root of their nodes
        (a patch of noise picked for standing high grows its total's
        evidence with its size; a load's nodes stand out each). None where the
        normal-only solve is damped (thick layers: there a real load's total
        stands out no more than noise's).

        Parameters
        ----------
        stress : (m,) ndarray
            Sensor stress, pascals (its noise is read from it:
            :func:`solver.seen_frame.noise_level`).
        normal : (m,) ndarray
            Its normal-only solution, newtons.

        Returns
        -------
        (m,) ndarray of bool
            The kept candidates' nodes (``contact_labels``' ``faint``).
        """
        labels = np.empty(self.grid.size, np.int64)
        normal = np.ascontiguousarray(normal, dtype=float)
        if self._normal.shift != 0 or faint_cores(normal, self.region_threshold, FAINT_LEVEL, self._adjacent,
                                                  labels) == 0:
            return np.zeros(self.grid.size, bool)
        weights = (labels == np.arange(1, labels.max() + 1)[:, None]).astype(float)  # (J, m)
        # a total's deviation under independent sensor noise sigma: sigma |Cz^-1 w|
        spread = noise_level(stress, self.grid) * np.linalg.norm(self._normal.solve(weights.T), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            evidence = (weights @ normal) / spread
        kept = (evidence >= BROAD_EVIDENCE) & (evidence >= FAINT_NODE_EVIDENCE * np.sqrt(weights.sum(axis=1)))
        return np.concatenate([[False], kept])[labels]

    def _frame(self, b: np.ndarray, *, like: SeenFrame | None = None) -> SeenFrame:
        # The frame's contacts, and the contact fit's view of it (SeenFrame.of; ``like`` the frame
        # solved before, whose view it shares where its contacts cover the same nodes)
        normal = self._normal.solve(b)
        faint = self.faint_contacts(b, normal)
        return self._seen(b, normal, *self.contact_labels(normal, faint=faint), faint, like=like)

    def _seen(self, b, normal, labels, near, faint, *, like=None) -> SeenFrame:
        return SeenFrame.of(b, normal, labels, near, faint, grid=self.grid, normal_inverse=self._normal,
                            fit_budget=self.fit_budget, fit_columns=self._fit_columns,
                            subdivision=self.subdivision, whole_columns=self.matrix.T,
                            max_shear_ratio=self.max_shear_ratio, neighbours=self._neighbours, like=like)

    def _residual(self, x: np.ndarray, b: np.ndarray) -> float:
        return _relative(self.matrix @ x - b, b)

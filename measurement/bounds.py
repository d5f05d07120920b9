"""What the data allow: the Cramér-Rao bound of a contact's shear, and the shear decision it permits.

The contact fit estimates a profile of normal forces and a shear ``(s_x, s_y)``
(tangential over normal traction, the same everywhere in the contact). Any
unbiased estimator of the shear from one frame has a covariance at least the
inverse of the Fisher information, where the profile is a nuisance: whatever
part of the shear's signature a change of the profile can also explain is
lost. The bound depends on how freely the profile may vary; here it is one
force per sub-cell (``subdivision`` per pitch along each axis), on the sub-cells
the true contact loads, with the model's own layer kernel.

The decision at that bound: the Wald test on ``s^T I s`` (the most powerful test
that treats every shear direction alike), which is chi-square with 2 degrees of
freedom on shear-free loads and non-central with ``lambda = s^T I s`` on loads
with shear ``s``. Its threshold fixes the share of shear-free loads given shear;
the share of sheared loads it misses follows.

These are the figures of an unbiased estimate with the model's own physics,
no model error and the support known. A decision that shrinks the estimate
(as the contact fit's does), a prior on the shear's size, or a profile more
constrained than the bound's (the fit's non-negative profile is sparse) is not
bound by them: they say what a free profile leaves to decide on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2, ncx2

from solver import loads
from solver.arrays import read_only
from solver.checks import real_number, whole_number
from solver.kernels import stress_matrix, subcell_offsets

from .tables import Column, format_table, value

__all__ = ["ShearBound", "shear_bounds", "contact_bounds", "miss_probability", "decision_bound",
           "format_decision_bound"]

_SAMPLES = 8        # profile samples per sub-cell along each axis when integrating the true load


@dataclass(frozen=True)
class ShearBound:
    """The Cramér-Rao bound of one contact's shear.

    Attributes
    ----------
    information : (2, 2) ndarray
        Fisher information of ``(s_x, s_y)`` with the profile as a nuisance, read-only.
    shear : (2,) ndarray
        The contact's true ``(s_x, s_y)``, read-only.
    profile : (m s^2,) ndarray
        The contact's true normal force on each sub-cell, newtons, in the
        order of :func:`solver.kernels.stress_matrix`'s columns, read-only;
        the loaded ones are the free forces.
    """

    information: np.ndarray
    shear: np.ndarray
    profile: np.ndarray

    def __post_init__(self):
        for name in ("information", "shear", "profile"):
            object.__setattr__(self, name, read_only(getattr(self, name)))
        if self.information.shape != (2, 2) or self.shear.shape != (2,):
            raise ValueError(f"information must be (2, 2) and shear (2,), got {self.information.shape} "
                             f"and {self.shear.shape}")

    @property
    def profile_size(self) -> int:
        """Free profile forces (loaded sub-cells)."""
        return int(np.count_nonzero(self.profile))

    @property
    def ratio_sd(self) -> float:
        """The bound's standard deviation of the shear ratio along its worst direction (inf when the
        data do not determine the shear at all)."""
        smallest = float(np.linalg.eigvalsh(self.information)[0])
        return 1.0 / math.sqrt(smallest) if smallest > 0 else math.inf

    def miss(self, ratio: float | None = None, *, false_rate: float) -> float:
        """The share of loads the Wald test at ``false_rate`` misses (:func:`miss_probability`).

        Parameters
        ----------
        ratio : float, optional
            Shear ratio of the loads, along the true direction (along +x when
            the contact has no shear). Default: the true ratio.
        false_rate : float
            Share of shear-free loads the test gives shear, in (0, 1).

        Returns
        -------
        float
        """
        norm = float(np.hypot(*self.shear))
        direction = self.shear / norm if norm > 0 else np.array([1.0, 0.0])
        size = norm if ratio is None else ratio
        return miss_probability(self.information, size * direction, false_rate=false_rate)

    def ideal_errors(self, *, samples: int = 4000, rng=0) -> tuple[float, float]:
        """The median errors of an unbiased shear estimate at the bound.

        Parameters
        ----------
        samples : int, optional
            Gaussian draws of the estimate. Default 4000.
        rng : int or numpy.random.Generator, optional
            Seed or generator of the draws. Default 0 (every call the same).

        Returns
        -------
        tangential : float
            Median of the total tangential force's error over ``|F|``, as
            :func:`solver.metrics.tangential_total_error` measures it.
        direction : float
            Median error of the shear's direction, degrees (nan without shear;
            90, that of a direction drawn at random, when the data do not
            determine the shear).
        """
        samples = whole_number("samples", samples, low=1)
        ratio = float(np.hypot(*self.shear))
        if not np.isfinite(self.ratio_sd):
            return math.inf, math.nan if ratio == 0 else 90.0
        errors = np.random.default_rng(rng).multivariate_normal(
            np.zeros(2), np.linalg.inv(self.information), size=samples)
        # |F_t - F_t*| / |F*| = |ds| F_z / (F_z sqrt(1 + mu^2)) for one contact of uniform ratio; the
        # estimate's own error in F_z (s F_z's other factor) moves this by under 1% at these noises
        tangential = float(np.median(np.hypot(*errors.T))) / math.sqrt(1.0 + ratio * ratio)
        if ratio == 0:
            return tangential, math.nan
        estimate = self.shear + errors
        turn = np.arctan2(estimate[:, 1], estimate[:, 0]) - math.atan2(self.shear[1], self.shear[0])
        return tangential, math.degrees(float(np.median(np.abs(np.angle(np.exp(1j * turn))))))


def shear_bounds(frames, *, subdivision: int = 1) -> list[ShearBound]:
    """The bound of each one-contact frame's shear.

    Parameters
    ----------
    frames : sequence of solver.loads.SimulatedFrame
        Frames of one contact each, with their noise (relative to the peak
        clean stress, as :func:`solver.loads.simulate` adds it).
    subdivision : int, optional
        Profile sub-cells per pitch along each axis, each a uniform load: 1 is
        one force per node, 2 the contact fit's sub-cells without its hats.
        Default 1.

    Returns
    -------
    list of ShearBound
    """
    subdivision = whole_number("subdivision", subdivision, low=1)
    frames = list(frames)
    for k, frame in enumerate(frames):
        if len(frame.contacts) != 1:
            raise ValueError(f"frames must have one contact each, frame {k} has {len(frame.contacts)}")
        if not frame.noise > 0:
            raise ValueError(f"frames must have noise > 0 (the bound scales with it), frame {k} has "
                             f"{frame.noise!r}")
    matrices = {}
    out = []
    for frame in frames:
        grid = frame.grid
        if grid.key not in matrices:
            matrices[grid.key] = stress_matrix(grid, "layer", subdivision=subdivision)
        out.extend(_bounds(frame, matrices[grid.key], subdivision, [frame.forces[:, 2].sum()]))
    return out


def contact_bounds(frame, *, subdivision: int = 1, totals=None) -> list[ShearBound]:
    """The bound of the shear of each contact of a frame of several, all of them estimated at once.

    Every contact's profile and every other contact's shear are nuisances:
    what of a contact's shear signature they can also explain is lost. Where
    the contacts' stresses overlap (a pitch or two apart) this bound is wider
    than that of the contact alone (:func:`shear_bounds` of a frame of it only),
    which takes its neighbours as known; far apart the two agree.

    Parameters
    ----------
    frame : solver.loads.SimulatedFrame
        A frame of one or more contacts, with its noise (relative to the peak
        clean stress of the whole frame, as :func:`solver.loads.simulate` adds it).
    subdivision : int, optional
        As for :func:`shear_bounds`. Default 1.
    totals : sequence of float, optional
        Each contact's normal force on the skin as the simulator puts it there
        alone, newtons (a caller that simulated each contact alone already has
        them); default: simulated here.

    Returns
    -------
    list of ShearBound
        One per contact, in the order of ``frame.contacts``; its information
        is that of the contact's shear with every other unknown profiled out.
    """
    subdivision = whole_number("subdivision", subdivision, low=1)
    if not frame.contacts:
        raise ValueError("frame must hold at least one contact, got none")
    if not frame.noise > 0:
        raise ValueError(f"frame must have noise > 0 (the bound scales with it), got {frame.noise!r}")
    grid = frame.grid
    # each contact's load on the skin as the simulator puts it there alone (the frame holds the sum)
    if totals is None:
        totals = ([frame.forces[:, 2].sum()] if len(frame.contacts) == 1 else
                  [loads.simulate(grid, contact).forces[:, 2].sum() for contact in frame.contacts])
    elif len(totals) != len(frame.contacts):
        raise ValueError(f"totals must give one force per contact ({len(frame.contacts)}), got {len(totals)}")
    return _bounds(frame, stress_matrix(grid, "layer", subdivision=subdivision), subdivision, totals)


def _bounds(frame, matrix, subdivision, totals):
    grid = frame.grid
    m, cells = grid.size, subdivision * subdivision
    width = grid.pitch / subdivision
    # sub-cell centres in the matrix's column order (q * m + j)
    offsets = subcell_offsets(grid.pitch, subdivision)
    x = (grid.positions[None, :, 0] + offsets[:, 0, None]).ravel()
    y = (grid.positions[None, :, 1] + offsets[:, 1, None]).ravel()
    fx, fy, fz = (matrix[:, c * m * cells:(c + 1) * m * cells] for c in range(3))
    shears, profiles, nuisances, signatures = [], [], [], []
    for contact, total in zip(frame.contacts, totals, strict=True):
        profile = loads.cell_forces(contact, x, y, width, _SAMPLES)
        # the load on the skin as the simulator put it there (a contact over the edge loses the rest)
        profile *= total / profile.sum()
        loaded = profile > 0
        shear = contact.shear_ratio * np.array([math.cos(contact.shear_direction),
                                                math.sin(contact.shear_direction)])
        # stress = (Cz + s_x Cx + s_y Cy) p: derivatives in the free profile forces and in the shear
        nuisances.append(fz[:, loaded] + shear[0] * fx[:, loaded] + shear[1] * fy[:, loaded])
        signatures.append(np.column_stack([fx @ profile, fy @ profile]))
        shears.append(shear)
        profiles.append(profile)
    sigma = frame.noise * np.abs(frame.clean_stress).max()
    out = []
    for k in range(len(frame.contacts)):
        # Information of contact k's shear with every profile and the other shears profiled out: the
        # part of its signature none of them explains (the Schur complement, through an orthonormal
        # basis of their columns rather than the inverse of an ill-conditioned Gram matrix).
        others = np.column_stack(nuisances + [s for j, s in enumerate(signatures) if j != k])
        basis, singular, _ = np.linalg.svd(others, full_matrices=False)
        basis = basis[:, singular > singular[0] * 1e-12]
        unexplained = signatures[k] - basis @ (basis.T @ signatures[k])
        out.append(ShearBound(unexplained.T @ unexplained / sigma**2, shears[k], profiles[k]))
    return out


def miss_probability(information, shear, *, false_rate: float) -> float:
    """The share of loads with ``shear`` that the Wald test at ``false_rate`` calls shear-free.

    Parameters
    ----------
    information : (2, 2) ndarray
        Fisher information of the shear (:attr:`ShearBound.information`).
    shear : (2,) ndarray
        ``(s_x, s_y)`` of the loads.
    false_rate : float
        Share of shear-free loads the test gives shear, in (0, 1).

    Returns
    -------
    float
        ``P(chi2_2(lambda) <= t)``, ``lambda = s^T I s`` and ``t`` the ``1 - false_rate``
        quantile of ``chi2_2``.
    """
    false_rate = real_number("false_rate", false_rate, rule="in (0, 1)", valid=lambda r: 0 < r < 1)
    information = np.asarray(information, dtype=float)
    if information.shape != (2, 2) or not np.isfinite(information).all():
        raise ValueError(f"information must be a finite (2, 2) array, got {information!r}")
    shear = np.asarray(shear, dtype=float)
    if shear.shape != (2,) or not np.isfinite(shear).all():
        raise ValueError(f"shear must be 2 finite numbers, got {shear!r}")
    threshold = chi2.ppf(1.0 - false_rate, 2)
    noncentrality = float(shear @ information @ shear)
    if noncentrality <= 0:
        return 1.0 - false_rate
    return float(ncx2.cdf(threshold, 2, noncentrality))


def decision_bound(draws, *, false_rates=(1 / 12, 2 / 12, 4 / 12), subdivision: int = 1) -> list[dict]:
    """The Wald test's counts at the bound, over the draws of a shear decision curve.

    Parameters
    ----------
    draws : sequence of list of measurement.cases.Case
        Draws of :func:`~measurement.cases.standard_cases` (12 shear-free
        loads and 24 with shear ratio 0.2 or 0.4 each), as
        :func:`measurement.validation.decision_draws` makes them.
    false_rates : sequence of float, optional
        Shares of shear-free loads the test gives shear.
    subdivision : int, optional
        The profile's sub-cells per pitch (:func:`shear_bounds`). Default 1.

    Returns
    -------
    list of dict
        Per false rate: ``false`` (expected count of 12 per draw), ``missed``
        (expected count of 24 per draw), ``none_missed`` (the chance that a
        draw misses none, mean over the draws) and ``missed_by_thickness``
        (the expected share of the loads with shear ratio 0.2 missed, per
        ``h / pitch``).
    """
    if not draws:
        raise ValueError("draws must hold at least one draw, got none")
    cases = [case for cases in draws for case in cases]
    draw = np.repeat(np.arange(len(draws)), [len(cases) for cases in draws])
    bounds = shear_bounds([case.frame for case in cases], subdivision=subdivision)
    ratio = np.array([c.shear_ratio for c in cases])
    thickness = np.array([c.thickness_ratio for c in cases])
    out = []
    for rate in false_rates:
        miss = np.array([b.miss(false_rate=rate) if c.shear_ratio > 0 else np.nan
                         for b, c in zip(bounds, cases, strict=True)])
        out.append(dict(
            false_rate=rate, false=float(np.sum(ratio == 0)) * rate / len(draws),
            missed=float(np.nansum(miss)) / len(draws),
            none_missed=float(np.mean([np.prod(1.0 - miss[(draw == d) & (ratio > 0)])
                                       for d in range(len(draws))])),
            missed_by_thickness={h: float(np.mean(miss[(ratio == 0.2) & (thickness == h)]))
                                 for h in np.unique(thickness)}))
    return out


def format_decision_bound(rows) -> str:
    """The rows of :func:`decision_bound`, one line per false rate."""
    if not rows:
        raise ValueError("rows must hold at least one false rate, got none")
    columns = [Column("false of 12", 11, value("false", ".1f")),
               Column("missed of 24", 12, value("missed", ".2f"), gap=3),
               Column("none missed", 11, value("none_missed", ".2f"), gap=3)]
    columns += [Column(f"missed 0.2 h/p {h:g}", 18,
                       lambda r, h=h: f"{r['missed_by_thickness'][h]:.2f}", gap=3)
                for h in rows[0]["missed_by_thickness"]]
    return format_table(rows, columns)

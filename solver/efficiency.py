"""Efficiency functionals: which member of the exact solution family is eligible.

Every ``x(mu, theta) = C+ b + (I - C+ C) y(mu, theta)`` fits the data exactly,
so a functional must reward physical admissibility, not fit. A functional here
is an object with a ``name`` and a method
``choose(frame, *, shear_ratio=None, shear_direction=None, start=None) -> Choice``
that returns the shear parameters of every contact (the given ones, or the
maximizer over the free ones), the compressive normal profile ``g`` of the
template load and the value of the functional; ``start`` is an earlier
choice of the same solver (on this frame after a slider move; in playback
and live mode the frame before; or whatever the solver did last, on any
thread), which may make the work cheaper but must not change the answer
beyond rounding (both types: :mod:`solver.functional`).
:class:`solver.inverse.DenseSolver` takes any such object.

Chosen: :class:`ContactFit` (see its notes and ``docs/efficiency.md`` for the
measured comparison). Kept for comparison: :class:`NoShear`, the baseline
that never reports shear.
"""

from __future__ import annotations

import math

import numpy as np

from . import search
from .checks import real_number, whole_number
from .functional import Choice, FunctionalInput
from .search import (
    BOTH,
    DIRECTION,
    RATIO,
    contact_stress,
    fit_at,
    gauss_newton,
    load_decision,
    misfit_variance,
    near_sums,
    pairs_of,
    scipy_fit,
    shear_evidence,
    workspace,
)

__all__ = ["ContactFit", "NoShear", "FUNCTIONALS"]


class ContactFit:
    """How well a compressive, friction-shaped load on each contact explains the data.

    Contact ``k`` gets its pair ``s_k = mu_k (cos theta_k, sin theta_k)``; the
    template load on its sub-cells is ``Fz = g``, ``(Fx, Fy) = s_k g`` with
    ``g >= 0``. Its best fit to the sensors near the contacts is a
    non-negative least-squares problem

        rho(s) = min_{g >= 0} | (Sz + Sx diag(sx) + Sy diag(sy)) g - b |^2

    and the efficiency is ``E = 1 - sqrt(rho) / |b|`` on those sensors (1:
    explained exactly). A wrong shear leaves a residual: the shear signature
    (compression ahead of the load, relief behind it) cannot be mimicked by a
    compressive normal load on a compact region.

    The maximization is Gauss-Newton on the free parameters with the profile
    eliminated (variable projection): each step solves the problem
    linearized in ``s`` for ``g`` on its current support and the parameter
    step together, then re-solves the NNLS at the new parameters (warm: one
    Cholesky solve while the support holds) and halves the step until the
    residual drops.

    **Shear decision.** For each contact the F statistic

        F_k = ((rho0_k - rho_k) / p) / max(rho_k / dof_k, (model_error * peak_k)^2)

    compares the residual on the sensors near the contact with no shear
    (``rho0_k``) and with the found shear (``rho_k``); ``p`` free parameters,
    ``dof_k`` those sensors minus the positive sub-cells minus ``p``,
    ``peak_k`` the largest stress there. The found ratio is then shrunk by
    the evidence, ``mu_k <- mu_k max(0, 1 - shrinkage / F_k)`` (the
    positive-part James-Stein factor): weak evidence gives a small ratio, no
    evidence none, strong evidence keeps it. Both constants were chosen on
    the tuning set (:func:`measurement.cases.tuning_cases`) and are judged on
    the validation set (``docs/efficiency.md``).

    **Load decision.** Load the data cannot tell from noise is not reported.
    Each patch ``P`` of a contact's fitted load (its connected pieces, gaps
    of one node bridged) explains the stress ``A_P g_P``; were it noise
    fitted by ``n_P`` positive sub-cells, ``chi2_P = |A_P g_P|^2 / variance``
    (``variance`` the contact's as above, without the shear parameters)
    would be about ``n_P``, give or take ``sqrt(2 n_P)``. A patch is kept when

        L_P = (chi2_P - n_P) / sqrt(2 n_P) >= min_load_evidence

    and a contact left without load is not reported. Only the automatic
    search decides: with a parameter given, the answer is by default the
    exact member, which puts all the data back anyway (with ``exact=False``
    the template keeps its noise patches). Without the decision the damped
    normal-only solve
    of a thick layer turns noise into regions over which the fit scatters
    small loads, and pure noise makes contacts (``docs/efficiency.md``).

    Parameters
    ----------
    shrinkage : float, optional
        ``c`` of the shrinkage factor. Default 2.
    model_error : float, optional
        Floor of the misfit standard deviation relative to the local peak
        stress: the sub-cell model's own error on continuous loads. Default
        0.002.
    max_iterations : int, optional
        Gauss-Newton iterations. Default 12.
    tolerance : float, optional
        Stop when a step changes the parameters by less (shear ratio units),
        or lowers the residual by less than a tenth of this fraction.
        Default 1e-3.
    min_load_evidence : float, optional
        Smallest load evidence ``L_P`` of a reported patch of load, in
        deviations of ``chi2``. Default 10 (chosen on seeds 1 to 3 of the
        load-decision frames, :func:`measurement.cases.load_decision_frames`;
        judged on seeds 11 to 13). ``-inf`` keeps every patch (0 still drops
        those that explain less than noise would).
    min_split_evidence : float, optional
        Smallest :meth:`split_evidence` for which a patch of two peaks with a
        shallow dip between them (two contacts that touch) is fitted as two
        contacts instead of one. Default 10 (chosen on the scenes' tuning
        set, touching pinches and random single contacts; judged on other
        seeds and the validation sets: ``docs/efficiency.md``). ``inf``:
        never.
    """

    name = "contact_fit"

    def __init__(self, *, shrinkage: float = 2.0, model_error: float = 0.002,
                 max_iterations: int = 12, tolerance: float = 1e-3, min_load_evidence: float = 10.0,
                 min_split_evidence: float = 10.0):
        self.shrinkage = real_number("shrinkage", shrinkage, rule="finite and >= 0",
                                     valid=lambda v: math.isfinite(v) and v >= 0)
        self.model_error = real_number("model_error", model_error, rule="finite and >= 0",
                                       valid=lambda v: math.isfinite(v) and v >= 0)
        self.max_iterations = whole_number("max_iterations", max_iterations, low=0)
        self.tolerance = real_number("tolerance", tolerance, rule="finite and > 0",
                                     valid=lambda v: math.isfinite(v) and v > 0)
        self.min_load_evidence = real_number("min_load_evidence", min_load_evidence,
                                             rule="a number below inf (-inf keeps every patch)",
                                             valid=lambda v: not math.isnan(v) and v < math.inf)
        self.min_split_evidence = real_number("min_split_evidence", min_split_evidence,
                                              rule="a number, inf to never split",
                                              valid=lambda v: not math.isnan(v))

    # -- the profile at given parameters ---------------------------------------------

    def fit(self, frame: FunctionalInput, shear: np.ndarray, *, support=None):
        """Best compressive profile at the pairs ``shear`` (K, 2) and its residual vector.

        Returns
        -------
        profile : (n,) ndarray
            ``g`` on the columns, newtons.
        residual : (R,) ndarray
            ``A(s) g - b``, pascals.
        """
        zt = frame.fit_z.T
        n, rows = zt.shape
        free = np.zeros(n, bool) if support is None else np.array(support, dtype=bool)
        g, residual, columns = np.zeros(n), np.empty(rows), np.empty((n, rows))
        steps, _, _ = fit_at(frame.fit_x.T, frame.fit_y.T, zt, frame.column_contact, frame.stress,
                           np.asarray(shear, dtype=float), free, g, residual, *workspace(zt), columns)
        if steps < 0:  # stopped short of the optimum (solver.search.lawson_hanson)
            g = scipy_fit(columns.T, frame.stress)
            residual = columns.T @ g - frame.stress
        return g, residual

    # -- the search ------------------------------------------------------------------------

    def choose(self, frame: FunctionalInput, *, shear_ratio=None, shear_direction=None, start=None) -> Choice:
        groups = independent_groups(frame)
        if len(groups) > 1:
            # contacts that share no sensor are separate problems: each costs a fraction of the
            # joint one (the NNLS's work grows with its columns times its positive set), and each
            # starts from its own sub-cells' positive set of the earlier choice
            return _joined(frame, [(group, self.choose(part, shear_ratio=shear_ratio,
                                                       shear_direction=shear_direction, start=start))
                                   for group, part in groups])
        K = frame.contacts
        if shear_ratio is not None and shear_direction is not None:
            # given parameters (a slider move, or playback at fixed sliders): the fit starts from
            # the earlier choice's positive set, which the minimizer does not depend on
            shear = np.empty((K, 2))
            shear[:, 0] = shear_ratio * math.cos(shear_direction)
            shear[:, 1] = shear_ratio * math.sin(shear_direction)
            g, residual = self.fit(frame, shear, support=_guess(frame, start))
            return self._choice(frame, shear, g, residual, np.full(K, math.nan), np.zeros(K, bool),
                                decide=False)

        # Free parameters p (K, k) -> pairs s (K, 2): both free, the ratio alone, the direction alone
        ratio = 0.0 if shear_ratio is None else float(shear_ratio)
        angle = 0.0 if shear_direction is None else float(shear_direction)
        mode = BOTH if shear_ratio is None and shear_direction is None else (
            RATIO if shear_ratio is None else DIRECTION)
        direction = np.array([math.cos(angle), math.sin(angle)])

        def pairs(p):
            s = np.empty((K, 2))
            pairs_of(p, mode, direction, ratio, frame.max_shear_ratio, s)
            return s
        if mode == DIRECTION:
            # theta alone is periodic with several local optima: start from the best of a scan
            scan = [np.full((K, 1), t) for t in np.linspace(-math.pi, math.pi, 12, endpoint=False)]
            fits = [self.fit(frame, pairs(p)) for p in scan]
            best = min(range(len(scan)), key=lambda i: float(np.sum(fits[i][1] ** 2)))
            first, guess = scan[best], fits[best][0] > 0
        else:
            # With the ratio free the search's first fit has no shear; it starts from the earlier
            # choice's shear-free positive set (in playback and live mode the frame before's). The
            # minimizer does not depend on it where it is unique: the answer matches a cold
            # start's to rounding, and on a contact with more sub-cells than sensors near it to
            # about 2e-9 of the peak force (docs/efficiency.md).
            first = np.zeros((K, 2 if mode == BOTH else 1))
            guess = _guess(frame, start, shear_free=True)
        p, g, residual, g0, residual0, _ = gauss_newton(
            frame.fit_x.T, frame.fit_y.T, frame.fit_z.T, frame.column_contact, frame.stress, mode, direction,
            ratio, frame.max_shear_ratio, first, guess, self.max_iterations, self.tolerance)
        if shear_ratio is not None:  # only the direction was free: nothing to decide
            return self._choice(frame, pairs(p), g, residual, np.full(K, math.nan), np.zeros(K, bool),
                                decide=False)

        # Soft decision from the sensors near each contact (module notes).
        k = p.shape[1]
        near = frame.row_contact
        rho = near_sums(residual * residual, near)
        variance = self._variance(frame, g, residual, k)
        gain = near_sums(residual0 * residual0, near) - rho
        evidence = shear_evidence(frame.stress, near, gain, variance, k)
        if K > 1:
            # Contacts fitted together: the gain from no shear anywhere to the found shear, on the
            # sensors near one contact, is partly its neighbours' (their shear's signature reaches
            # those sensors). Each contact's own gain is that of its shear alone: its load refitted
            # with no shear on the sensors near it, the other contacts' fitted loads held. A
            # contact is not refitted where the joint gain is no evidence already (its own gain is
            # the smaller part), nor where no contact sharing its sensors shows evidence (the gain
            # there is its own). Counted jointly, 8 of 18 shear-free contacts of the noise-free
            # validation scenes were given shear; so, none.
            shown = evidence > self.shrinkage
            shared = (near.T.astype(np.int64) @ near.astype(np.int64)) > 0
            np.fill_diagonal(shared, False)
            refit = np.flatnonzero(shown & (shared & shown).any(axis=1))
            if refit.size:
                explained = contact_stress(frame.fit_x.T, frame.fit_y.T, frame.fit_z.T, frame.column_contact,
                                           pairs(p), g, K)
                total = explained.sum(axis=0)
                for c in refit:
                    gain[c] = self._shear_free_misfit(frame, total - explained[c], g0, c) - rho[c]
            evidence = shear_evidence(frame.stress, near, gain, variance, k)
        with np.errstate(divide="ignore", invalid="ignore"):
            keep = np.where(evidence > 0, np.maximum(0.0, 1.0 - self.shrinkage / evidence), 0.0)
        p = p * keep[:, None]
        if np.all(keep == 0):
            g, residual = g0, residual0
        elif np.any(keep < 1):
            g, residual = self.fit(frame, pairs(p), support=g > 0)
        return self._choice(frame, pairs(p), g, residual, evidence, keep > 0, shear_free=g0)

    def split_evidence(self, merged: Choice, split_frame: FunctionalInput, split: Choice,
                       extra: int) -> float:
        """F statistic of a frame's contacts split into ``extra`` more, on the same sensors.

        ``F = ((rho_merged - rho_split) / (2 extra)) / max(rho_split / dof, (model_error * peak)^2)``:
        the misfits ``rho = |A g - b|^2`` of the two automatic choices, each extra contact's
        pair two parameters, ``dof`` the sensors less the split fit's positive sub-cells and
        pairs, ``peak`` the largest stress. About 1 where the split explains only noise.

        Parameters
        ----------
        merged : Choice
            The automatic choice of the frame with fewer contacts.
        split_frame : FunctionalInput
            The frame with ``extra`` more contacts, on the same sensors.
        split : Choice
            Its automatic choice.
        extra : int
            Contacts more, at least 1.
        """
        rows = split_frame.stress.size
        dof = rows - np.count_nonzero(split.profile > 0) - 2 * split_frame.contacts
        floor = (self.model_error * float(np.abs(split_frame.stress).max(initial=0.0))) ** 2
        variance = max(split.residual ** 2 / dof if dof > 0 else math.inf, floor)
        if not variance > 0:
            return 0.0
        return (merged.residual ** 2 - split.residual ** 2) / (2 * extra) / variance

    @staticmethod
    def _shear_free_misfit(frame, held, g0, c):
        # |residual|^2 near contact c with its load refitted without shear (warm from the
        # shear-free fit's set) and every other contact's load as fitted (``held`` (R,), the
        # stress of their fitted loads): a small NNLS on c's columns and the sensors near it
        mine, rows = frame.column_contact == c, frame.row_contact[:, c]
        b = frame.stress[rows] - held[rows]
        columns = np.ascontiguousarray(frame.fit_z.T[mine][:, rows])
        profile = np.zeros(columns.shape[0])
        steps, _ = search.lawson_hanson(columns, b, g0[mine] > 0, 3 * profile.size + 10, profile,
                                        *workspace(columns))
        if steps < 0:  # stopped short of the optimum
            profile = scipy_fit(columns.T, b)
        left = columns.T @ profile - b
        return float(left @ left)

    def _variance(self, frame, g, residual, parameters):
        # misfit variance near each contact (K,); infinite where no freedom is left
        return misfit_variance(frame.stress, residual, frame.row_contact, frame.column_contact, g, parameters,
                               self.model_error, np.inf)

    def _choice(self, frame, shear, g, residual, evidence, detected, *, decide=True, shear_free=None):
        # the load decision (class notes) when the search was free, then the functional's value
        shear = np.asarray(shear, float)
        load_evidence = np.full(frame.contacts, math.nan)
        if decide:
            g, residual, load_evidence = self._load_decision(frame, shear, g, residual)
        norm = math.sqrt(frame.stress @ frame.stress)
        misfit = math.sqrt(residual @ residual)
        efficiency = 1.0 if norm == 0 else 1.0 - misfit / norm
        return Choice(shear, g, efficiency, evidence, detected, misfit, load_evidence, frame.column_id,
                      shear_free)

    def _load_decision(self, frame, shear, g, residual):
        # (class notes) compiled: solver.search.load_decision
        return load_decision(frame.fit_x.T, frame.fit_y.T, frame.fit_z.T, frame.column_contact,
                             frame.column_node, shear, g, residual, *frame.neighbours, frame.stress,
                             frame.row_contact, self.model_error, self.min_load_evidence)


def independent_groups(frame: FunctionalInput) -> list:
    """The frame's contacts in groups that share no sensor, each as a frame of its own.

    Contacts whose sensors near them
    (:attr:`~solver.functional.FunctionalInput.row_contact`) overlap, directly
    or through others, are one group: their fits are coupled. Between groups the
    columns' stress on the other group's sensors is beyond the fit's reach (below
    1% of its peak with the default reach), and is left out.

    Returns
    -------
    list of (contacts, FunctionalInput)
        ``contacts`` (k,) the group's contacts in ``frame``, in order; one item
        holding ``frame`` itself when every contact is in one group.
    """
    near = frame.row_contact
    K = near.shape[1]
    if K < 2:
        return [(np.arange(K), frame)]
    shared = (near.T.astype(np.int64) @ near.astype(np.int64)) > 0  # (K, K), true on the diagonal
    # each contact's group: the smallest contact linked to it, spread until nothing changes (a few
    # contacts: cheaper than a graph library's checks of its input)
    label = np.arange(K)
    while True:
        spread = np.array([label[shared[c]].min() for c in range(K)])
        if np.array_equal(spread, label):
            break
        label = spread
    first = np.unique(label)
    if first.size == 1:
        return [(np.arange(K), frame)]
    groups = []
    for g in first:
        contacts = np.flatnonzero(label == g)
        rows = near[:, contacts].any(axis=1)
        columns = np.flatnonzero(np.isin(frame.column_contact, contacts))
        renumber = np.zeros(K, np.intp)
        renumber[contacts] = np.arange(contacts.size)
        fit_x, fit_y, fit_z = (_block(a, rows, columns) for a in (frame.fit_x, frame.fit_y, frame.fit_z))
        groups.append((contacts, FunctionalInput(
            stress=frame.stress[rows], fit_x=fit_x, fit_y=fit_y, fit_z=fit_z,
            column_contact=renumber[frame.column_contact[columns]],
            row_contact=np.ascontiguousarray(near[rows][:, contacts]),
            max_shear_ratio=frame.max_shear_ratio, column_node=frame.column_node[columns],
            neighbours=frame.neighbours, column_id=frame.column_id[columns])))
    return groups


def _block(fit, rows, columns):
    # the (R, n) block of a fit matrix whose transpose is C-contiguous, as the numba kernels read it
    return np.ascontiguousarray(fit.T[columns][:, rows]).T


def _joined(frame, parts):
    # one choice for the frame from those of its independent groups; the residual and the
    # efficiency over all its sensors (a group's load reaches the others' faintly)
    K, n = frame.contacts, frame.column_id.size
    shear, profile = np.zeros((K, 2)), np.zeros(n)
    evidence, detected, load_evidence = np.zeros(K), np.zeros(K, bool), np.zeros(K)
    shear_free = None if parts[0][1].shear_free is None else np.zeros(n)
    where = np.empty(n, np.intp)
    where[:] = -1
    for contacts, choice in parts:
        columns = np.flatnonzero(np.isin(frame.column_contact, contacts))
        shear[contacts] = choice.shear
        profile[columns] = choice.profile
        evidence[contacts], detected[contacts] = choice.evidence, choice.shear_detected
        load_evidence[contacts] = choice.load_evidence
        if shear_free is not None:
            shear_free[columns] = choice.shear_free
    on = profile > 0
    weighted = profile[on]
    along = shear[frame.column_contact[on]]
    residual = (frame.fit_z[:, on] @ weighted + frame.fit_x[:, on] @ (along[:, 0] * weighted)
                + frame.fit_y[:, on] @ (along[:, 1] * weighted) - frame.stress)
    norm = math.sqrt(frame.stress @ frame.stress)
    misfit = math.sqrt(residual @ residual)
    return Choice(shear, profile, 1.0 if norm == 0 else 1.0 - misfit / norm, evidence, detected, misfit,
                  load_evidence, frame.column_id, shear_free)


def _guess(frame, start, *, shear_free=False):
    # the positive set of an earlier choice's profile (or of its shear-free one, when it has
    # one) on this frame's columns, through the sub-cells' skin-wide ids; empty without one
    if start is None:
        return np.zeros(frame.column_id.size, bool)
    profile = start.shear_free if shear_free and start.shear_free is not None else start.profile
    if start.column_id is frame.column_id:  # a slider move: the same frame's columns
        return profile > 0
    ids = start.column_id[profile > 0]
    on = np.zeros(max(ids.max(initial=-1), frame.column_id.max(initial=-1)) + 1, bool)
    on[ids] = True
    return on[frame.column_id]


class NoShear:
    """Baseline: never report shear; the template is the shear-free contact fit."""

    name = "no_shear"

    def choose(self, frame: FunctionalInput, *, shear_ratio=None, shear_direction=None, start=None) -> Choice:
        return ContactFit().choose(frame, shear_ratio=shear_ratio or 0.0,
                                   shear_direction=shear_direction or 0.0, start=start)


FUNCTIONALS = {f.name: f for f in (ContactFit, NoShear)}

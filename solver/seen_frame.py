"""A frame as a dense solve sees it: its contacts, and the contact fit's view of them (:class:`SeenFrame`).

:class:`solver.inverse.DenseSolver` finds a frame's contacts in its
normal-only solution and keeps them, with the fit's matrices, for slider
moves on that frame. The contact fit's budget is applied here: over it, a
frame's weakest contacts are left out and the fit takes whole cells instead
of sub-cells; beyond :data:`WHOLE_CELLS` times it there is no fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import read_only
from .functional import FunctionalInput
from .geometry import SensorGrid
from .search import fit_view, laplacian_noise

__all__ = ["SeenFrame", "noise_level", "WHOLE_CELLS", "NOISE_EVIDENCE"]

# The contact fit takes whole cells instead of sub-cells for loads of up to this many times
# DenseSolver's fit_budget nodes; beyond, the normal-only answer (DenseSolver.fit_budget).
WHOLE_CELLS = 2
# Over the fit's budget, contacts whose normal-only total is within this many noise deviations
# of zero are noise and left out of the fit (same sets: noise contacts on 32x32 skins reached 4.7,
# a 1 N load under 20% noise 3.3).
NOISE_EVIDENCE = 1.0


def noise_level(b: np.ndarray, grid: SensorGrid) -> float:
    # The sensors' noise deviation, from one frame: the layer smooths every load over about its
    # thickness, so on a regular grid the 5-point Laplacian of the stress is noise (variance 20
    # sigma^2) but for a few edges, which the median's robust deviation ignores; elsewhere the
    # robust deviation of the stress itself (an overestimate where a load covers the skin).
    if grid.is_regular and min(grid.shape) >= 3:
        # a copy: numba compiles apart for the read-only frames of a recording
        return float(laplacian_noise(np.array(b, dtype=float).reshape(grid.shape)))
    return 1.4826 * float(np.median(np.abs(b - np.median(b))))


@dataclass(frozen=True, eq=False)
class SeenFrame:
    # A frame as the last solve saw it, kept for slider moves on it: what the contact fit
    # looks at, and what every result of the frame repeats.
    key: bytes             # the stress's bytes
    frame: FunctionalInput | None    # the contact fit's view; None without a compressive contact
    normal: np.ndarray     # (m,) read-only: the normal-only solution its contacts were found in
    labels: np.ndarray     # (m,) int, read-only: contact 1..K of each node, 0 outside every contact
    nodes: np.ndarray      # (K, m) bool, read-only: each contact's region (Contact.nodes)
    weights: np.ndarray    # (K, m) float, read-only: the same, to sum each contact's forces in one product
    at_edge: np.ndarray    # (K,) bool, read-only: the region touches the skin's border
    region: np.ndarray     # (m,) bool, read-only: every contact's nodes
    faint: np.ndarray      # (m,) bool, read-only: cores of light loads (DenseSolver.faint_contacts)
    over: int = 0          # the contacts' nodes when more than the fit's budget (then no frame)
    fallback: str = ""     # why the fit takes whole cells instead of sub-cells, if it does
    near: np.ndarray | None = None   # (m, K) bool, read-only: the sensors near each contact

    @classmethod
    def of(cls, b: np.ndarray, normal: np.ndarray, labels: np.ndarray, near: np.ndarray, faint: np.ndarray, *,
           grid: SensorGrid,
           normal_inverse, fit_budget: int, fit_columns: np.ndarray, subdivision: int,
           whole_columns: np.ndarray, max_shear_ratio: float, neighbours: tuple,
           like: SeenFrame | None = None) -> SeenFrame:
        """The frame's contacts, and the contact fit's view of it.

        The view: sub-cell columns of every contact's region and the sensors
        near the contacts.

        Parameters
        ----------
        b : (m,) ndarray
            Sensor stress, pascals.
        normal : (m,) ndarray
            Its normal-only solution (``normal_inverse.solve(b)``), newtons.
        labels, near : ndarray
            Its contacts (:meth:`solver.inverse.DenseSolver.contact_labels`).
        faint : (m,) ndarray of bool
            The cores of light loads they were found with
            (:meth:`solver.inverse.DenseSolver.faint_contacts`), kept for the
            frame's other labellings.
        grid : SensorGrid
        normal_inverse : SymmetricInverse
            The inverse of ``Cz`` (:class:`solver.symmetric.SymmetricInverse`).
        fit_budget : int
            :class:`~solver.inverse.DenseSolver`'s ``fit_budget``.
        fit_columns : (3 s^2 m, m) ndarray
            The sub-cell stress matrix's columns as rows (``s`` the subdivision).
        subdivision : int
            ``s``, 1 for whole cells.
        whole_columns : (3m, m) ndarray
            The whole-cell stress matrix's columns as rows.
        max_shear_ratio : float
        neighbours : tuple of two ndarrays of int
            :attr:`solver.functional.FunctionalInput.neighbours`.
        like : SeenFrame or None, optional
            A frame seen before with the same skin and settings (in playback
            and live mode the frame before): where this frame's contacts
            cover the same nodes with the same sensors near them, its view
            shares that frame's matrices (the same arrays as gathered anew).
        """
        m = grid.size
        # A damped normal-only solve (a thick layer) turns noise into contacts whose totals say
        # nothing (a real 1 N load at 1% noise read 3.6 deviations): there only the fit's load
        # decision tells load from noise, whatever it costs, and the budget does not apply.
        budget = fit_budget if normal_inverse.shift == 0 else m
        left_out = 0
        if np.count_nonzero(labels) > budget and near.shape[1] > 0:
            # Over the budget: contacts whose normal-only total does not stand NOISE_EVIDENCE noise
            # deviations out are noise (a noisy frame on a large skin covers it with small ones),
            # and of the rest the fit takes the strongest that its budget holds (the load
            # decision then tells load from noise among them); the others are left out.
            weights = (labels == np.arange(1, near.shape[1] + 1)[:, None]).astype(float)
            evidence = (weights @ normal) / (noise_level(b, grid)
                                             * np.linalg.norm(normal_inverse.solve(weights.T), axis=0))
            kept = evidence >= NOISE_EVIDENCE
            order = np.argsort(-evidence)
            held = np.cumsum(weights.sum(axis=1)[order]) <= WHOLE_CELLS * budget
            if held[0]:  # else one load is broader than the budget: the normal-only answer
                kept[order[~held]] = False
                left_out = int(np.count_nonzero(evidence >= NOISE_EVIDENCE) - np.count_nonzero(kept))
            labels = np.concatenate([[0], np.cumsum(kept) * kept])[labels]
            near = np.ascontiguousarray(near[:, kept])
        covered = int(np.count_nonzero(labels))
        source, cells, fallback = fit_columns, subdivision ** 2, []
        if covered > budget and cells > 1:
            # whole cells: a quarter of the columns, the same compressive, friction-shaped fit
            source, cells = whole_columns, 1
            fallback.append(f"whole-cell fit: the contacts cover {covered} nodes, more than the sub-cell "
                            f"fit's budget of {fit_budget} (fit_budget)")
        if left_out:
            fallback.append(f"{left_out} contact(s) of weaker evidence left out: the fit's budget of "
                            f"{WHOLE_CELLS * budget} nodes ({WHOLE_CELLS} x fit_budget) held the strongest")
        fallback = "; ".join(fallback)
        if (like is not None and like.frame is not None and like.fallback == fallback
                and np.array_equal(labels, like.labels) and np.array_equal(near, like.near)):
            # A contact that has not moved a node since (playback and live mode, mostly): the same
            # columns and rows, only the stress on them is new (the gather is a third of a
            # one-contact frame's set-up)
            shared = like.frame
            frame = FunctionalInput(
                stress=b[np.flatnonzero(near.any(axis=1))], fit_x=shared.fit_x, fit_y=shared.fit_y,
                fit_z=shared.fit_z, column_contact=shared.column_contact, row_contact=shared.row_contact,
                column_node=shared.column_node, max_shear_ratio=max_shear_ratio, neighbours=neighbours,
                column_id=shared.column_id)
            return cls(key=b.tobytes(), frame=frame, normal=read_only(normal), labels=like.labels,
                       nodes=like.nodes, weights=like.weights, at_edge=like.at_edge, region=like.region,
                       faint=read_only(faint, bool), fallback=fallback, near=like.near)
        nodes = labels == np.arange(1, near.shape[1] + 1)[:, None]  # (K, m)
        # read-only: a frame's contacts are shared with the frames after it that cover the same nodes
        seen = dict(key=b.tobytes(), normal=read_only(normal), labels=read_only(labels, np.int64),
                    nodes=read_only(nodes, bool), weights=read_only(nodes, float),
                    at_edge=read_only((nodes & grid.border).any(axis=1), bool),
                    region=read_only(labels > 0, bool), faint=read_only(faint, bool),
                    near=read_only(near, bool))
        if near.shape[1] == 0:
            return cls(frame=None, **seen)
        if covered > WHOLE_CELLS * budget:
            return cls(frame=None, over=covered, **seen)
        seen["fallback"] = fallback
        stress, fit, contact, node, column_id, row_contact = fit_view(b, labels, near, source, cells)
        fit, n = fit.T, column_id.size  # (R, 3n), each column contiguous
        frame = FunctionalInput(stress=stress, fit_x=fit[:, :n], fit_y=fit[:, n:2 * n], fit_z=fit[:, 2 * n:],
                                column_contact=contact, row_contact=row_contact, column_node=node,
                                max_shear_ratio=max_shear_ratio, neighbours=neighbours, column_id=column_id)
        return cls(frame=frame, **seen)

"""What an efficiency functional looks at and what it returns: :class:`FunctionalInput` and :class:`Choice`.

A functional (:mod:`solver.efficiency`) is given the :class:`FunctionalInput` of one
frame, the contact fit's view of it, and returns its :class:`Choice`: the
shear parameters of every contact and the template's compressive profile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FunctionalInput", "Choice"]

@dataclass(frozen=True, eq=False)
class FunctionalInput:
    """What a functional may look at for one frame.

    The contact fit works on the sensors near the contacts (``rows``) and on
    the sub-cells of the contact region's nodes (the columns): each node's
    cell is split into ``s x s`` sub-cells (:func:`solver.kernels.stress_matrix`
    with ``subdivision``), each carrying a bilinear hat by default
    (``profile``), so neither a contact edge inside a cell nor a smooth
    contact's slope is mistaken for shear.

    Attributes
    ----------
    stress : (R,) ndarray
        Sensor stress ``b`` on the rows, pascals.
    fit_x, fit_y, fit_z : (R, n) ndarray
        Stress on the rows per newton along x, y, z on each sub-cell column.
    column_contact : (n,) ndarray of int
        Contact (0 to K-1) of each column.
    row_contact : (R, K) ndarray of bool
        Rows near each contact (its local statistics).
    max_shear_ratio : float
        Upper bound for the shear ratio search.
    column_node : (n,) ndarray of int
        Skin node (0 to m-1) of each column.
    column_id : (n,) ndarray of int
        The column's sub-cell on the whole skin (``q m + node`` for sub-cell
        ``q``): the same sub-cell has the same id in every frame.
    neighbours : tuple of two ndarrays of int
        ``(indptr, indices)`` of the CSR matrix linking nodes within 2.5
        pitches, so a patch of load may have gaps of one node, straight or
        diagonal (the load decision's patches).
    """

    stress: np.ndarray
    fit_x: np.ndarray
    fit_y: np.ndarray
    fit_z: np.ndarray
    column_contact: np.ndarray
    row_contact: np.ndarray
    max_shear_ratio: float
    column_node: np.ndarray
    neighbours: tuple
    column_id: np.ndarray

    @property
    def contacts(self) -> int:
        return self.row_contact.shape[1]


@dataclass(frozen=True)
class Choice:
    """Parameters and template profile chosen for one frame.

    Attributes
    ----------
    shear : (K, 2) ndarray
        ``mu (cos theta, sin theta)`` of every contact.
    profile : (n,) ndarray
        Compressive normal profile ``g`` on the columns, newtons.
    efficiency : float
        Value of the functional at the chosen parameters.
    evidence : (K,) ndarray
        F statistic of each contact's shear against a shear-free load
        (``nan`` when the shear ratio was given).
    shear_detected : (K,) ndarray of bool
        Where the automatic search kept a non-zero shear.
    residual : float
        ``|A g - b|`` on the rows, pascals.
    load_evidence : (K,) ndarray
        Load evidence ``L`` of each contact's strongest patch kept (class
        notes of :class:`~solver.efficiency.ContactFit`; 0 when none was kept, ``nan`` when a
        parameter was given).
    column_id : (n,) ndarray of int
        The frame's :attr:`FunctionalInput.column_id`.
    shear_free : (n,) ndarray or None
        The best compressive profile with no shear, where the automatic
        search starts (None when none was fitted), newtons: the next
        frame's search starts from its positive set.
    """

    shear: np.ndarray
    profile: np.ndarray
    efficiency: float
    evidence: np.ndarray
    shear_detected: np.ndarray
    residual: float
    load_evidence: np.ndarray
    column_id: np.ndarray
    shear_free: np.ndarray | None = None

"""The rows of the time plots: what each shows of a series, and how its curves are cut. No Qt.

One row per quantity of :class:`~tactile_viewer.model.series.Quantities`
(:data:`ROWS`) and, with truth, per group of
:class:`~tactile_viewer.model.series.TruthErrors` (:data:`ERROR_ROWS`); the
contacts drawn with curves of their own (:func:`contacts_drawn`); the data of
a curve, cut where an angle wraps or the frames stop for an outage
(:func:`curve_data`). The Qt widgets that draw them:
:mod:`tactile_viewer.qt.time_plot_stack`.
"""

from __future__ import annotations

import numpy as np

from .series import Series

__all__ = ["ROWS", "ERROR_ROWS", "FIRST_ROWS", "TIPS", "ANGLE_TICKS", "MAX_CONTACT_CURVES", "OUTAGE",
           "contacts_drawn", "curve_data"]

# the rows shown at first: three plots and the time axis fit the dock's first height at 1280x800
# (all eight rows did not: 2.3 of them showed, and no time axis); the Rows button shows the others,
# the errors against a recording's truth among them
FIRST_ROWS = ("fz", "tangential", "direction")
MAX_CONTACT_CURVES = 8  # contacts drawn with curves of their own (those present on the most frames)

# (key, axis label, unit, the plotted value of a Quantities) of each row; the labels are short: a
# row is a few centimetres high and its label runs along its side (the tooltips spell them out)
ROWS = (
    ("fz", "Fz", "mN", lambda q: q.fz * 1e3),
    ("tangential", "|Ft|", "mN", lambda q: q.tangential * 1e3),
    ("direction", "dir", "°", lambda q: np.degrees(q.direction)),
    ("shear_ratio", "|Ft|/Fz", "", lambda q: q.shear_ratio),
    ("centroid_x", "x", "mm", lambda q: q.centroid_x * 1e3),
    ("centroid_y", "y", "mm", lambda q: q.centroid_y * 1e3),
)
# (key, axis label, unit, ((curve name, the plotted value of a TruthErrors), ...)): with truth only
ERROR_ROWS = (
    ("error", "error", "%", (("Fz, % of |Fz*|", lambda e: e.normal * 100),
                             ("Ft, % of |F*|", lambda e: e.tangential * 100))),
    ("direction_error", "dir err", "°", (("Ft direction", lambda e: e.direction_deg),)),
)
TIPS = {
    "fz": "Total normal force (sum of Fz over the nodes), mN",
    "tangential": "Size of the total tangential force |sum (Fx, Fy)|, mN",
    "direction": "Direction of the total tangential force, degrees from +x (none where there is no shear)",
    "shear_ratio": "Total tangential over total normal force",
    "centroid_x": "x of the contact centroid (where the compressive load is centred), mm",
    "centroid_y": "y of the contact centroid, mm",
    "error": "Errors against the truth: total Fz in % of the true Fz; total tangential force in % of the "
             "true |F|",
    "direction_error": "Angle between the estimated and the true total tangential force, degrees",
}
# the direction's ticks: the quarters marked, labelled every half turn (five labels overlapped in a
# row 45 px high)
ANGLE_TICKS = [[(v, str(v)) for v in (-180, 0, 180)], [(-90, ""), (90, "")]]


def _broken(x, y, jump=180.0):
    # an angle wraps (-180 deg is 180 deg): the curve is cut where it jumps, not drawn across the plot
    cut = np.flatnonzero(np.abs(np.diff(y)) > jump) + 1
    if not cut.size:
        return x, y
    return np.insert(x, cut, (x[cut - 1] + x[cut]) / 2), np.insert(y, cut, np.nan)


# A pause between two frames this many times the usual one is an outage (a board unplugged, frames
# lost): the curves are not drawn across it.
OUTAGE = 5.0


def _outages_cut(x, y):
    # the curve is cut where time jumps by OUTAGE times the median step (a straight line across an
    # outage would show values nobody measured)
    if len(x) < 3:
        return x, y
    steps = np.diff(x)
    usual = float(np.median(steps))
    cut = np.flatnonzero(steps > OUTAGE * usual) + 1 if usual > 0 else np.zeros(0, int)
    if not cut.size:
        return x, y
    return np.insert(x, cut, (x[cut - 1] + x[cut]) / 2), np.insert(np.asarray(y, float), cut, np.nan)


def curve_data(x, y, wrap: bool = False) -> tuple:
    """``(x, y)`` of a curve, cut (nan) across outages and, for an angle (``wrap``), where it wraps."""
    if wrap:
        x, y = _broken(x, y)
    return _outages_cut(x, y)


def contacts_drawn(series: Series) -> tuple:
    """The ``(identity, Quantities)`` of the contacts drawn with curves of their own, by identity.

    None for a single contact (its curves would repeat the totals); of more than
    :data:`MAX_CONTACT_CURVES`, those present on the most frames.
    """
    contacts = series.contacts if len(series.contacts) > 1 else ()
    if len(contacts) > MAX_CONTACT_CURVES:
        present = sorted(contacts, key=lambda pair: -np.count_nonzero(np.isfinite(pair[1].fz)))
        contacts = tuple(sorted(present[:MAX_CONTACT_CURVES], key=lambda pair: pair[0]))
    return contacts

"""The status line of a solved frame and its tooltip: where, how fast, the parameters, the forces.

No Qt: the window sets these texts on its status bar's label.
"""

from __future__ import annotations

import math

from ..model.solved import Solved
from ..model.viewer_model import ViewerModel

__all__ = ["status_text", "status_details", "STATUS_CONTACTS"]

# contacts named on the status line; the rest are in its tooltip
STATUS_CONTACTS = 3


def status_text(solved: Solved, model: ViewerModel) -> str:
    """The status line of a solved frame: where, how fast, the parameters, the forces.

    Short enough for a 1280 px window with several contacts and the taxel
    read-out beside it; the fit's figures and every contact are in
    :func:`status_details` (the line's tooltip).
    """
    r = solved.result
    total = r.total_force
    if r.fallback:
        # a load too broad for the accurate path within its budget: what the solver did, in short
        shear = f"cheaper answer: {r.fallback.split(':', 1)[0]}"
    elif r.normal_only:
        shear = "normal only"  # the fast preset
    else:
        mode = "auto" if solved.auto else "manual"
        contacts = r.contacts if len(r.contacts) > 1 else ()
        if not contacts:
            shear = (f"{mode}: no shear signature" if solved.auto and not r.shear_detected else
                     f"{mode}: mu {r.shear_ratio:.2f}, theta {math.degrees(r.shear_direction):+.0f} deg")
        else:
            named = "; ".join(_contact_text(c, k) for k, c in enumerate(contacts[:STATUS_CONTACTS]))
            more = len(contacts) - STATUS_CONTACTS
            shear = f"{mode}: {named}" + (f"; {more} more" if more > 0 else "")
    where = (f"seq {solved.frame}" if solved.frame >= 0 else "live") if model.live \
        else f"frame {solved.frame} (of 0-{len(model.recording) - 1})"
    return (f"{where}  t {solved.time:.3f} s  |  {solved.solve_ms:.2f} ms  |  {shear}  |  "
            f"Fz {total[2] * 1e3:.1f} mN  Ft {math.hypot(total[0], total[1]) * 1e3:.1f} mN")


def _contact_text(contact, k: int) -> str:
    number = contact.identity or k + 1
    if contact.shear_ratio == 0:
        return f"#{number} no shear"
    return f"#{number} mu {contact.shear_ratio:.2f} {math.degrees(contact.shear_direction):+.0f} deg"


def status_details(solved: Solved) -> str:
    """The status line's tooltip: every contact, the fit's figures in words, a cheaper answer's reason."""
    r = solved.result
    lines = []
    if r.fallback:
        lines.append(f"Cheaper answer: {r.fallback}")
    for k, contact in enumerate(r.contacts):
        fz = contact.total_force[2]
        lines.append(f"{_contact_text(contact, k)}, Fz {fz * 1e3:.1f} mN"
                     + (" (on the skin's edge)" if contact.at_edge else ""))
    if math.isfinite(r.efficiency):
        lines.append(f"efficiency {r.efficiency:.3f}: how much of the sensor stress the fitted contact load "
                     "explains (1: all of it)")
    else:
        lines.append("efficiency: none (no contact load was fitted: a normal-only answer or an empty frame)")
    lines.append(f"residual {r.residual:.1e}: the sensor stress the forces shown leave unexplained, "
                 "relative to the stress")
    lines.append(f"condition {r.condition:.3g}: how much the inversion can amplify sensor noise"
                 + (" (damped: the layer is thick for its pitch)" if r.regularized else ""))
    return "\n".join(lines)

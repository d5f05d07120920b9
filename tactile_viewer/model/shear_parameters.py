"""The shear parameters a frame is solved with: what Auto found, and the rule for leaving Auto.

No Qt. Auto picks, per contact, the shear ratio and direction of the
efficiency maximum; moving a parameter slider switches Auto off
(:meth:`~tactile_viewer.model.viewer_model.ViewerModel.set_parameters`). The
rule: leaving Auto starts from what Auto found on the frame shown, not from
manual values set long before (unticking Auto made the shear of a contact drop
from 401 to 3 mN); the value the user moved replaces its part of it.
"""

from __future__ import annotations

import math

__all__ = ["MAX_SHEAR_RATIO", "auto_found", "leave_auto"]

MAX_SHEAR_RATIO = 1.5  # the slider's end; the automatic search uses the same bound


def auto_found(last, manual: tuple[float, float]) -> tuple[float, float]:
    """The parameters Auto shows (those of the frame's largest contact), or ``manual``.

    ``last`` is the :class:`~tactile_viewer.model.solved.Solved` frame shown
    while Auto is on (None otherwise); a frame solved in manual mode found
    nothing, and ``manual`` ``(shear_ratio, shear_direction)`` is kept.
    """
    if last is None or not last.auto:
        return manual
    return (min(float(last.result.shear_ratio), MAX_SHEAR_RATIO),
            math.remainder(float(last.result.shear_direction), 2 * math.pi))


def leave_auto(found: tuple[float, float], *, shear_ratio: float | None = None,
               shear_direction: float | None = None) -> tuple[float, float]:
    """The manual ``(shear_ratio, shear_direction)`` after a slider moved: those given, else ``found``.

    Both values are checked before either is used; the direction is wrapped to
    ``[-pi, pi]`` radians.

    Raises
    ------
    ValueError
        A ratio outside ``[0, MAX_SHEAR_RATIO]`` or a direction that is not finite.
    """
    ratio, direction = found
    if shear_ratio is not None:
        if not (math.isfinite(shear_ratio) and 0 <= shear_ratio <= MAX_SHEAR_RATIO):
            raise ValueError(f"shear_ratio must be in [0, {MAX_SHEAR_RATIO}], got {shear_ratio!r}")
        ratio = float(shear_ratio)
    if shear_direction is not None:
        if not math.isfinite(shear_direction):
            raise ValueError(f"shear_direction must be finite radians, got {shear_direction!r}")
        direction = math.remainder(float(shear_direction), 2 * math.pi)
    return ratio, direction

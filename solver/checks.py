"""Argument checks shared by the solver's public entry points.

Each raises ``ValueError`` naming the argument, the rule and what was received.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["shown", "real", "real_number", "whole_number", "optional_flag", "one_of"]


def shown(value) -> str:
    """``repr`` of what the user wrote (numpy scalars print as "np.float64(0.7)"; the user wrote 0.7)."""
    return repr(value.item()) if isinstance(value, np.generic) else repr(value)


def real(value) -> float | None:
    """``value`` as a float if it is a real number (not a bool, not text), else None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except OverflowError:  # an int beyond any float (10**400) is no usable number either
        return None


def real_number(name: str, value, *, rule: str, valid) -> float:
    """``value`` as a float when it is a real number with ``valid(value)`` true.

    ``rule`` completes "``name`` must be ..." in the error message.
    """
    number = real(value)
    if number is None or math.isnan(number) or not valid(number):
        raise ValueError(f"{name} must be {rule}, got {shown(value)}")
    return number


def whole_number(name: str, value, *, low: int, high: int | None = None, unit: str = "") -> int:
    """``value`` as an int when it is a whole number in ``[low, high]`` (a float like 2.0 counts).

    ``unit`` (with a trailing space) names what is counted: "of pitches ".
    """
    number = real(value)
    if number is None or not math.isfinite(number) or number != int(number) or number < low \
            or (high is not None and number > high):
        bound = f">= {low}" if high is None else f"from {low} to {high}"
        raise ValueError(f"{name} must be a whole number {unit}{bound}, got {shown(value)}")
    return int(number)


def optional_flag(name: str, value) -> bool | None:
    """``value`` when it is True, False or None."""
    if value is None or isinstance(value, (bool, np.bool_)):
        return None if value is None else bool(value)
    raise ValueError(f"{name} must be True, False or None, got {shown(value)}")


def one_of(name: str, value, choices: tuple):
    """``value`` when it is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value

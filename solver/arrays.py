"""The one helper every result type uses to store its arrays."""

from __future__ import annotations

import numpy as np

__all__ = ["read_only"]


def read_only(array, dtype=float) -> np.ndarray:
    """A read-only copy of ``array`` as ``dtype`` (results are immutable, their arrays too)."""
    array = np.array(array, dtype=dtype)
    array.setflags(write=False)
    return array

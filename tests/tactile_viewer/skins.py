"""Small skins and helpers shared by the layout, recording and serial-source tests."""

import time

import numpy as np
import pytest

from solver import SensorGrid

NU, TAXEL = 0.45, 1e-3  # a material that is not the default, so that dropping it shows


def grid32():
    return SensorGrid.regular(3, 2, 2e-3, 1.5e-3)  # six taxels, two rows of three


def grid_with_material():
    return SensorGrid.regular(3, 2, 2e-3, 1.5e-3, poisson_ratio=NU, sensor_size=TAXEL)


def frames_for(n, seed):
    return np.random.default_rng(seed).normal(1e3, 300, size=(n, 6))


def wait_for(predicate, timeout=5.0, what="condition"):
    """Poll ``predicate`` until true; fail with ``what`` after ``timeout`` seconds (no bare sleeps)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.002)

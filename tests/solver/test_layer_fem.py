"""The layer kernel against a finite-element model of the bonded layer (tools/layer_fem.py).

The model (scikit-fem, triquadratic hexahedra, the volumetric term at reduced order so
nu = 0.45 does not lock, base stress recovered from the base reactions) shares nothing with
the kernel but the problem statement: a layer of thickness h bonded to a rigid base, a
uniform square patch load on its free surface.
"""

import functools

import numpy as np
import pytest

from solver.kernels import layer_force_stress
from tools.layer_fem import solve_layer

H = 1.5e-3      # thickness, m
WIDTH = 1.5e-3  # patch side = pitch, m


@functools.cache
def fem(nu, load):
    return solve_layer(H, WIDTH, nu, load)


def base_points():
    # along x through the peak, and off axis, out to 3 thicknesses
    x = np.linspace(-3 * H, 3 * H, 25)
    line = np.column_stack([x, np.zeros_like(x)])
    off = np.column_stack([x, np.full_like(x, 0.8 * H)])
    return np.vstack([line, off])


@pytest.mark.parametrize("nu", [0.3, 0.45])
@pytest.mark.parametrize("load", ["normal", "tangential"])
def test_layer_kernel_matches_finite_elements(nu, load):
    points = base_points()
    measured = fem(nu, load)(points[:, 0], points[:, 1])
    kx, _, kz = layer_force_stress(points[:, 0], points[:, 1], H, WIDTH, nu)
    kernel = kz if load == "normal" else kx
    # measured 0.3% / 0.5% (normal) and 0.6% / 0.9% (tangential) of the peak at nu 0.3 / 0.45
    assert np.abs(measured - kernel).max() <= 0.03 * np.abs(kernel).max()


@pytest.mark.parametrize("nu", [0.3, 0.45])
def test_finite_element_model_is_in_equilibrium(nu):
    # the model's own check: 1 N through the base under a normal load; a first
    # moment h under a tangential one (compression ahead of the load; its zero
    # net force holds by the model's antisymmetry)
    total, _, _ = fem(nu, "normal").integrals()
    assert total == pytest.approx(1.0, abs=0.01)
    _, moment, _ = fem(nu, "tangential").integrals()
    assert moment == pytest.approx(H, rel=0.02)

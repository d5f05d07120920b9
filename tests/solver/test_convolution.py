"""Tests of solver/convolution.py: Cz by FFT against the dense matrix, and its normal-only solve."""

import math

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid
from solver.convolution import NormalConvolution
from solver.kernels import stress_matrix


@pytest.mark.parametrize("kernel", ["layer", "cell", "point"])
@pytest.mark.parametrize("shape", [(7, 11), (12, 12), (1, 9), (9, 1)])
def test_the_convolution_is_the_dense_product(kernel, shape):
    ny, nx = shape
    grid = SensorGrid.regular(nx, ny, 1.5e-3, 1.5e-3, poisson_ratio=0.49)
    cz = stress_matrix(grid, kernel)[:, 2 * grid.size:]
    forces = np.random.default_rng(3).random((grid.size, 4))  # fixed seed: four force fields
    operator = NormalConvolution(grid, kernel=kernel)
    for f in forces.T:
        np.testing.assert_allclose(operator.apply(f), cz @ f, rtol=0, atol=1e-12 * np.abs(cz @ f).max())


@pytest.mark.parametrize("thickness_ratio", [0.5, 1.0, 1.5])
def test_the_solve_is_the_normal_only_answer(thickness_ratio):
    grid = SensorGrid.regular(13, 10, 1.5e-3, thickness_ratio * 1.5e-3, poisson_ratio=0.49)
    dense = Reconstructor(grid)
    operator = NormalConvolution(grid)
    assert operator.shift == 0 and dense._normal.shift == 0
    b = np.random.default_rng(5).normal(100.0, 30.0, grid.size)  # fixed seed
    forces, iterations = operator.solve(b, tolerance=1e-10)
    expected = dense.solve_normal(b).forces[:, 2]
    np.testing.assert_allclose(forces, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
    # Cz f = b, and far fewer products than unknowns on a well-conditioned layer
    np.testing.assert_allclose(operator.apply(forces), b, rtol=0, atol=1e-9 * np.abs(b).max())
    assert iterations < grid.size / 2
    # the condition estimate of the circulant that embeds Cz bounds Cz's own from outside
    assert np.linalg.cond(dense.matrix[:, 2 * grid.size:]) <= operator.condition * 1.0001


def test_a_thick_layer_is_damped_to_its_condition_bound():
    grid = SensorGrid.regular(10, 10, 1.5e-3, 3 * 1.5e-3)
    operator = NormalConvolution(grid, max_condition=100.0)
    cz = stress_matrix(grid, "layer")[:, 2 * grid.size:]
    assert np.linalg.cond(cz) > 1000
    # damped as SymmetricInverse damps: the estimate from outside stays near the bound, the
    # operator's own condition below the estimate
    damped = cz + operator.shift * np.eye(grid.size)
    assert operator.shift > 0 and np.linalg.cond(damped) <= operator.condition <= 1.1 * 100.0
    b = np.random.default_rng(6).normal(50.0, 10.0, grid.size)  # fixed seed
    forces, _ = operator.solve(b, tolerance=1e-10)
    expected = np.linalg.solve(damped, b)
    np.testing.assert_allclose(forces, expected, rtol=0, atol=1e-7 * np.abs(expected).max())


def test_bad_arguments_are_refused():
    grid = SensorGrid.regular(4, 4, 1e-3, 1e-3)
    irregular = SensorGrid(grid.positions, grid.thickness, grid.pitch, (grid.size,))
    with pytest.raises(ValueError, match="grid must be a regular SensorGrid"):
        NormalConvolution(irregular)
    with pytest.raises(ValueError, match="kernel must be one of .* got 'gauss'"):
        NormalConvolution(grid, kernel="gauss")
    with pytest.raises(ValueError, match="max_condition must be a finite number > 1, got 1"):
        NormalConvolution(grid, max_condition=1)
    operator = NormalConvolution(grid)
    with pytest.raises(ValueError, match="tolerance must be in \\(0, 1\\), got 0"):
        operator.solve(np.ones(16), tolerance=0)
    with pytest.raises(ValueError, match="max_iterations must be a whole number >= 1, got 0"):
        operator.solve(np.ones(16), max_iterations=0)
    assert math.isfinite(operator.condition)

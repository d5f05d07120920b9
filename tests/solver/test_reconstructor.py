"""Tests of solver/reconstructor.py: the one way to a solver, for any skin and any setting."""

import re
from pathlib import Path

import numpy as np
import pytest

import solver
from solver import Configuration, Reconstructor, SensorGrid, loads
from solver.inverse import DenseSolver
from solver.region import RegionSolver

README = Path(__file__).resolve().parents[2] / "README.md"


def five_lines():
    # the README's "The solver in five lines", as a reader copies it
    text = README.read_text(encoding="utf-8")
    block = re.search(r"## The solver in five lines\n\n```python\n(.*?)```", text, re.S).group(1)
    assert len(block.strip().splitlines()) == 5
    return block


@pytest.mark.parametrize("n", [16, 128])
def test_the_readme_s_five_lines_run_unchanged_on_any_skin(n, capsys):
    # only the skin's size changed: 16x16 solves densely, 128x128 contact by contact (its dense
    # C would take 6 GiB, C C^T's inverse 2 GiB more: it once failed with a 24 GB MemoryError)
    code = five_lines().replace("SensorGrid.regular(16, 16,", f"SensorGrid.regular({n}, {n},")
    assert f"regular({n}, {n}," in code
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    result, frame = scope["result"], scope["frame"]
    assert isinstance(scope["Reconstructor"](scope["grid"]).engine, DenseSolver if n == 16 else RegionSolver)
    # the contact of 1 N with shear ratio 0.3 along x, as the layer data give it
    np.testing.assert_allclose(result.total_force, frame.forces.sum(axis=0), atol=0.06)
    assert result.shear_ratio == pytest.approx(0.3, abs=0.06)
    assert len(capsys.readouterr().out.split()) >= 4  # it printed


def test_one_entry_point_is_exported():
    assert solver.Reconstructor is Reconstructor
    assert not hasattr(solver, "make_solver") and not hasattr(solver, "RegionSolver")
    assert "Reconstructor" in solver.__all__ and "DenseSolver" not in solver.__all__


@pytest.mark.parametrize("configuration", [Configuration("fit"), Configuration("exact", path="exact"),
                                           Configuration("region", path="region")], ids=lambda c: c.name)
def test_every_setting_answers_the_one_solve_signature(configuration):
    grid = SensorGrid.regular(10, 10, 1.5e-3, 1.5e-3)
    frame = loads.simulate(grid, loads.hertz((0, 0), 3e-3, 1.0, shear_ratio=0.3), noise=0.01, rng=3)  # fixed seed
    made = Reconstructor(grid, quality=configuration)
    automatic = made.solve(frame.stress)
    fitted = made.solve(frame.stress, shear_ratio=0.3, shear_direction=0.0, exact=False)
    member = made.solve(frame.stress, shear_ratio=0.3, shear_direction=0.0, exact=True)
    assert member.exact and not fitted.exact
    # the exact member fits the data; the fitted template does not, exactly
    assert member.residual < 1e-6 < fitted.residual
    # the setting's own path when exact is not given: the exact setting gives the exact member
    assert automatic.exact == (configuration.path == "exact")
    assert made.solve_normal(frame.stress).normal_only


@pytest.mark.parametrize("configuration", solver.quality.CONFIGURATIONS, ids=lambda c: c.name)
def test_every_setting_solves_a_large_skin_window_by_window(configuration):
    # 64x64: a setting's dense engine would need the whole skin's matrices (1.6 GB); it runs its
    # path on each contact's window instead, and answers as it does on a 16x16 skin
    answers = []
    for n in (16, 64):
        grid = SensorGrid.regular(n, n, 1.5e-3, 1.5e-3)
        frame = loads.simulate(grid, loads.hertz((0, 0), 3e-3, 1.0, shear_ratio=0.3), noise=0.0)
        made = Reconstructor(grid, quality=configuration)
        engine = made.engine.reconstructor if configuration.path != "region" else made.engine
        assert isinstance(engine, RegionSolver if n == 64 else type(engine))
        answers.append((made.solve(frame.stress), made.solve(frame.stress, shear_ratio=0.3, shear_direction=0.0)))
    (small, small_given), (large, large_given) = answers
    assert isinstance(engine, RegionSolver)
    assert large.normal_only == small.normal_only == (configuration.path == "normal")
    np.testing.assert_allclose(large.total_force, small.total_force, atol=0.02)
    # the given shear is applied alike (or, normal only, ignored alike)
    np.testing.assert_allclose(large_given.total_force, small_given.total_force, atol=0.02)

"""Quality settings (solver/quality.py) and Reconstructor(grid, quality=...): one factory."""

from dataclasses import replace

import numpy as np
import pytest

import solver
from measurement.cases import default_cases
from solver import Reconstructor, SensorGrid
from solver.inverse import DenseSolver
from solver.kernels import stress_matrix
from solver.quality import CONFIGURATIONS, PATHS, Configuration
from solver.region import RegionSolver

GRID = SensorGrid.regular(8, 8, 2e-3, 2e-3)


@pytest.fixture(scope="module")
def cases():
    return default_cases(GRID, noises=(0.01,))


def test_a_bad_path_is_rejected():
    with pytest.raises(ValueError, match=r"path must be one of \('fit', 'exact', 'normal', 'region'\)"):
        Configuration("x", path="fast")


def test_the_normal_path_reconstructs_no_shear(cases):
    built = Configuration("n", path="normal").build(GRID)
    result = built.solve(cases[2].frame.stress)
    assert result.normal_only and not np.abs(result.forces[:, :2]).any()
    region = Configuration("r", path="region").build(GRID).solve_normal(cases[2].frame.stress)
    assert region.normal_only and not np.abs(region.forces[:, :2]).any()


def test_the_settings_are_distinct_and_exported():
    assert solver.Configuration is Configuration
    assert len({c.name for c in CONFIGURATIONS}) == len(CONFIGURATIONS)
    assert {c.path for c in CONFIGURATIONS} == set(PATHS)


@pytest.mark.parametrize("configuration", CONFIGURATIONS, ids=lambda c: c.name)
@pytest.mark.parametrize("kernel", ["cell", None])
def test_the_reconstructor_builds_what_the_setting_builds(configuration, kernel, cases):
    # the viewer's quality path: replace(configuration, kernel=kernel).build(grid)
    options = {} if kernel is None else {"kernel": kernel}
    made = Reconstructor(GRID, quality=configuration, **options)
    direct = replace(configuration, kernel=kernel or configuration.kernel).build(GRID)
    assert type(made.engine) is type(direct) and made.grid is GRID
    assert made.kernel == (kernel or configuration.kernel)
    assert isinstance(made.engine, RegionSolver) == (configuration.path == "region")
    stress = cases[7].frame.stress
    np.testing.assert_allclose(made.solve(stress).forces, direct.solve(stress).forces, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("path", ["fit", "region"])
def test_the_setting_s_profile_reaches_the_contact_fit(path):
    # the fit's columns are those of the profile the configuration names, on either path
    for profile in ("bilinear", "uniform"):
        made = Configuration("p", path=path, profile=profile).build(GRID)
        reconstructor = made.reconstructor if path == "fit" else made.reconstructor(6, 6)
        assert reconstructor.profile == profile
        expected = stress_matrix(reconstructor.grid, "layer", subdivision=2, profile=profile).T
        np.testing.assert_array_equal(reconstructor._fit_columns, expected)
    with pytest.raises(ValueError, match=r"profile must be one of \('uniform', 'bilinear'\), got 'cubic'"):
        Configuration("p", profile="cubic")


@pytest.mark.parametrize("setting, message", [
    (dict(kernel="fem"), r"kernel must be one of \('layer', 'cell', 'point'\), got 'fem'"),
    (dict(subdivision=0), r"subdivision must be a whole number from 1 to 4, got 0"),
    (dict(max_condition=1.0), r"max_condition must be a finite number > 1, got 1.0"),
])
def test_a_configuration_the_solver_would_refuse_is_refused_when_made(setting, message):
    with pytest.raises(ValueError, match=message):
        Configuration("bad", **setting)


def test_without_quality_the_standard_solver_is_made():
    assert isinstance(Reconstructor(GRID, quality=None, kernel="cell").engine, DenseSolver)


@pytest.mark.parametrize("quality, shown", [("fast", "'fast'"), (1, "1"), (CONFIGURATIONS, r"\(Configuration")])
def test_quality_must_be_a_configuration(quality, shown):
    with pytest.raises(ValueError, match=rf"quality must be a solver\.quality\.Configuration or None, got {shown}"):
        Reconstructor(GRID, quality=quality)


def test_further_options_reach_the_setting_s_solver():
    fit = Reconstructor(GRID, quality=Configuration("fit"), max_shear_ratio=0.8)
    assert fit.engine.reconstructor.max_shear_ratio == 0.8
    region = Reconstructor(GRID, quality=Configuration("r", path="region"), max_shear_ratio=0.8)
    assert region.engine.reconstructor(4, 4).max_shear_ratio == 0.8
    # unset, the solver's own default: what Reconstructor gives without quality
    assert Reconstructor(GRID, quality=Configuration("fit")).engine.reconstructor.max_shear_ratio \
        == Reconstructor(GRID).engine.max_shear_ratio
    with pytest.raises(ValueError, match=r"max_shear_ratio must be finite and >= 0, got -1"):
        Reconstructor(GRID, quality=Configuration("fit"), max_shear_ratio=-1)


@pytest.mark.parametrize("option", ["max_condition", "subdivision", "profile", "efficiency"])
def test_what_the_setting_sets_is_not_overridden(option):
    with pytest.raises(ValueError, match=rf"options must not set what the configuration sets "
                                         rf"\(kernel, max_condition, subdivision, profile, efficiency\), "
                                         rf"got {option}"):
        Reconstructor(GRID, quality=Configuration("fit"), **{option: 1})

"""The simulated sets (measurement/cases.py): one Case type, what each set covers, fixed seeds."""

import math

import numpy as np
import pytest

from measurement.cases import (
    SHAPES,
    Case,
    default_cases,
    standard_contact,
    tuning_cases,
)
from solver import SensorGrid

GRID = SensorGrid.regular(8, 8, 2e-3, 2e-3)


# -- the accuracy sets ------------------------------------------------------------------------------


def test_standard_set_covers_what_the_bar_names(standard_set):
    cases = standard_set
    assert len(cases) == 36
    assert {c.shape for c in cases} == {"hertz", "cone", "flat_punch", "ellipse"}
    assert {c.thickness_ratio for c in cases} == {0.5, 1.0, 1.5}
    assert {c.shear_ratio for c in cases} == {0.0, 0.2, 0.4}
    assert all(c.frame.grid.shape == (16, 16) and c.frame.noise == 0.01 for c in cases)
    # directions spread round the circle
    directions = np.array([c.shear_direction for c in cases])
    assert np.ptp(directions) > 5.5


def test_layer_set_covers_what_the_issue_names(layer_noisy):
    assert len(layer_noisy) == 48
    assert {c.thickness_ratio for c in layer_noisy} == {0.5, 1.0, 1.5, 2.0}
    assert {c.shape for c in layer_noisy} == {"hertz", "cone", "flat_punch", "ellipse"}
    assert all(c.frame.medium == "layer" and c.frame.grid.poisson_ratio == 0.5 for c in layer_noisy)


def test_the_validation_set_is_not_the_tuning_set(validation_set):
    tuning, validation = tuning_cases(), validation_set()  # validation_cases() of conftest.py
    assert {c.thickness_ratio for c in tuning} == {0.5, 1.0, 1.5}
    assert {c.thickness_ratio for c in validation} == {0.6, 1.0, 1.4}
    # 12 shear-free loads, 24 with shear, on layer data
    assert sum(c.shear_ratio == 0 for c in validation) == 12 and len(validation) == 36
    assert all(c.frame.medium == "layer" for c in tuning + validation)
    assert not np.array_equal(tuning[12].frame.stress, validation[12].frame.stress)


# -- the speed/accuracy cases of one geometry ------------------------------------------------------


@pytest.fixture(scope="module")
def cases():
    return default_cases(GRID, noises=(0.01,))


def test_default_cases_cover_shapes_ratios_and_noise(cases):
    assert len(cases) == 4 * 5
    assert {c.name.split()[0] for c in cases} == {"hertz", "cone", "flat_punch", "ellipse"}
    assert sorted({c.shear_ratio for c in cases}) == [0.0, 0.2, 0.4]
    again = default_cases(GRID, noises=(0.01,))
    np.testing.assert_array_equal(cases[3].frame.stress, again[3].frame.stress)  # fixed seed


def test_one_case_type_for_every_set(cases, standard_set):
    assert all(type(c) is Case for c in cases + standard_set)
    # the speed/accuracy cases carry what the accuracy sets carry
    assert [c.shape for c in cases] == [c.name.split()[0] for c in cases]
    assert {c.thickness_ratio for c in cases} == {1.0}
    assert all(c.frame.grid is GRID and c.frame.noise == 0.01 for c in cases)
    assert all(-math.pi <= c.shear_direction <= math.pi for c in cases)
    noises = {c.name.split("noise=")[1] for c in default_cases(GRID)}
    assert noises == {"0.3%", "1%"}


def test_a_bad_shape_is_rejected():
    with pytest.raises(ValueError, match=r"shape must be one of \('hertz', 'cone', 'flat_punch', 'ellipse'\), got 'sphere'"):
        standard_contact("sphere", (0.0, 0.0), 2e-3, np.random.default_rng(0))
    assert SHAPES == ("hertz", "cone", "flat_punch", "ellipse")

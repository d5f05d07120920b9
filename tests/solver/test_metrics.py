"""solver.metrics on hand-made forces whose errors are known exactly."""

import math

import numpy as np
import pytest

from solver import metrics


def truth():
    """1 N normal over four nodes, shear 0.3 N along +x (0.3 of the normal force everywhere)."""
    f = np.zeros((4, 3))
    f[:, 2] = [0.1, 0.4, 0.4, 0.1]
    f[:, 0] = 0.3 * f[:, 2]
    return f


def rotated(forces, degrees):
    """The tangential part of every node turned by ``degrees`` about z."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    out = forces.copy()
    out[:, 0] = c * forces[:, 0] - s * forces[:, 1]
    out[:, 1] = s * forces[:, 0] + c * forces[:, 1]
    return out


# -- normal_total_error ---------------------------------------------------------------------------

@pytest.mark.parametrize("factor, expected", [(1.1, 0.1), (0.9, 0.1), (1.0, 0.0), (0.0, 1.0), (3.0, 2.0)])
def test_normal_total_error(factor, expected):
    estimate = truth()
    estimate[:, 2] *= factor
    assert metrics.normal_total_error(estimate, truth()) == pytest.approx(expected, abs=1e-15)


def test_normal_total_error_looks_at_the_total_only():
    estimate = truth()
    estimate[:, 2] = [0.25, 0.25, 0.25, 0.25]  # redistributed, same 1 N in total
    estimate[:, :2] = 7.0  # tangential forces are not its business
    assert metrics.normal_total_error(estimate, truth()) == pytest.approx(0.0, abs=1e-15)
    # relative to |sum Fz*|, also when the truth pulls (tension)
    assert metrics.normal_total_error(-1.2 * truth(), -truth()) == pytest.approx(0.2)


# -- tangential_total_error -----------------------------------------------------------------------

def test_tangential_error_relative_to_the_total_force():
    reference = math.hypot(0.3, 1.0)  # |sum F*|
    no_shear = truth()
    no_shear[:, 0] = 0.0
    assert metrics.tangential_total_error(no_shear, truth()) == pytest.approx(0.3 / reference)
    turned = rotated(truth(), 90)  # (0, 0.3) against (0.3, 0): |(-0.3, 0.3)|
    assert metrics.tangential_total_error(turned, truth()) == pytest.approx(0.3 * math.sqrt(2) / reference)
    doubled = truth()
    doubled[:, 0] *= 2
    assert metrics.tangential_total_error(doubled, truth()) == pytest.approx(0.3 / reference)
    wrong_normal = truth()
    wrong_normal[:, 2] *= 5  # the normal force does not enter the numerator
    assert metrics.tangential_total_error(wrong_normal, truth()) == pytest.approx(0.0, abs=1e-15)


def test_tangential_error_of_a_shear_free_truth_is_finite():
    free = truth()
    free[:, :2] = 0.0
    assert metrics.tangential_total_error(truth(), free) == pytest.approx(0.3)  # 0.3 N over 1 N


# -- direction_error --------------------------------------------------------------------------------

@pytest.mark.parametrize("degrees, expected", [
    (0, 0), (90, 90), (-90, 90), (45, 45), (180, 180), (-180, 180), (270, 90), (-135, 135), (359, 1),
])
def test_direction_error_of_rotated_shear(degrees, expected):
    assert metrics.direction_error(rotated(truth(), degrees), truth()) == pytest.approx(expected, abs=1e-9)


def test_direction_error_wraps_across_the_negative_x_axis():
    # truth at +170 degrees, estimate at -170 degrees: 20 apart, not 340
    base = truth()
    assert metrics.direction_error(rotated(base, -170), rotated(base, 170)) == pytest.approx(20.0)


def test_direction_error_ignores_magnitude_and_uses_the_resultant():
    assert metrics.direction_error(2.5 * truth(), truth()) == pytest.approx(0.0, abs=1e-12)
    # two nodes pushing along +y and -x of unequal size: resultant (-0.1, 0.2) vs +x truth
    estimate = truth()
    estimate[:, :2] = 0.0
    estimate[0, 1] = 0.2
    estimate[1, 0] = -0.1
    expected = math.degrees(math.atan2(0.2, -0.1))
    assert metrics.direction_error(estimate, truth()) == pytest.approx(expected)


def test_direction_error_without_shear():
    none = truth()
    none[:, :2] = 0
    # truth sheared, estimate not: the worst answer
    assert metrics.direction_error(none, truth()) == 180.0
    # truth without shear: undefined
    assert math.isnan(metrics.direction_error(truth(), none))
    assert math.isnan(metrics.direction_error(none, none))


# -- field_error --------------------------------------------------------------------------------------

def test_field_error_and_its_components():
    estimate = truth()
    estimate[1, 2] += 0.1   # normal error 0.1
    estimate[2, 1] += 0.05  # tangential error 0.05
    reference = np.linalg.norm(truth())
    assert metrics.field_error(estimate, truth()) == pytest.approx(math.hypot(0.1, 0.05) / reference)
    assert metrics.field_error(estimate, truth(), "all") == metrics.field_error(estimate, truth())
    assert metrics.field_error(estimate, truth(), "normal") == pytest.approx(0.1 / reference)
    # tangential is still relative to the whole |F*|
    assert metrics.field_error(estimate, truth(), "tangential") == pytest.approx(0.05 / reference)
    assert metrics.field_error(truth(), truth()) == 0.0


def test_field_error_sees_what_the_totals_miss():
    swapped = truth()[[1, 0, 3, 2]]  # same totals, load moved between nodes
    assert metrics.normal_total_error(swapped, truth()) == pytest.approx(0.0, abs=1e-15)
    assert metrics.direction_error(swapped, truth()) == pytest.approx(0.0, abs=1e-12)
    difference = np.linalg.norm(swapped - truth()) / np.linalg.norm(truth())
    assert metrics.field_error(swapped, truth()) == pytest.approx(difference) and difference > 0.5


# -- compare ------------------------------------------------------------------------------------------

def test_compare_gathers_every_measure():
    estimate = rotated(truth(), 90)
    estimate[:, 2] *= 1.1
    errors = metrics.compare(estimate, truth())
    assert errors.normal_total == pytest.approx(0.1)
    assert errors.direction_deg == pytest.approx(90.0)
    assert errors.tangential_total == metrics.tangential_total_error(estimate, truth())
    assert errors.field == metrics.field_error(estimate, truth())
    assert errors.as_dict() == dict(normal_total=errors.normal_total, tangential_total=errors.tangential_total,
                                    direction_deg=errors.direction_deg, field=errors.field)


def test_inputs_may_be_nested_lists():
    assert metrics.normal_total_error([[0, 0, 1.1]], [[0, 0, 1.0]]) == pytest.approx(0.1)


# -- nan cases ------------------------------------------------------------------------------------------

def test_zero_truth_gives_nan():
    zero = np.zeros((3, 3))
    for estimate in (zero, np.ones((3, 3))):
        errors = metrics.compare(estimate, zero)
        assert all(math.isnan(v) for v in errors.as_dict().values()), errors
        for component in ("all", "normal", "tangential"):
            assert math.isnan(metrics.field_error(estimate, zero, component))


def test_shear_only_truth():
    # no normal force at all: the normal total error is undefined, the others are not
    push = np.zeros((2, 3))
    push[:, 0] = 0.5
    assert math.isnan(metrics.normal_total_error(push, push))
    assert metrics.tangential_total_error(push, push) == 0.0
    assert metrics.direction_error(push, push) == 0.0


def test_nan_in_the_estimate_propagates():
    estimate = truth()
    estimate[0] = np.nan
    errors = metrics.compare(estimate, truth())
    assert all(math.isnan(v) for v in errors.as_dict().values()), errors


# -- shape errors -----------------------------------------------------------------------------------

@pytest.mark.parametrize("forces, reference", [
    (np.zeros((4, 3)), np.zeros((3, 3))),
    (np.zeros((4, 2)), np.zeros((4, 2))),
    (np.zeros(12), np.zeros(12)),
    (np.zeros((2, 4, 3)), np.zeros((2, 4, 3))),
    (np.zeros((3, 4)), np.zeros((4, 3))),
], ids=["rows", "two-components", "flat", "frames", "transposed"])
@pytest.mark.parametrize("function", [
    metrics.normal_total_error, metrics.tangential_total_error, metrics.direction_error,
    metrics.field_error, metrics.compare,
], ids=lambda f: f.__name__)
def test_shapes_are_checked(function, forces, reference):
    message = (r"forces and truth must both have shape \(m, 3\), got "
               + re_shape(forces.shape) + " and " + re_shape(reference.shape))
    with pytest.raises(ValueError, match=message):
        function(forces, reference)


def re_shape(shape):
    return str(shape).replace("(", r"\(").replace(")", r"\)")


@pytest.mark.parametrize("component", ["shear", "z", "", "ALL"])
def test_unknown_component_is_rejected(component):
    with pytest.raises(ValueError, match=rf"component must be one of \('all', 'normal', 'tangential'\), got '{component}'"):
        metrics.field_error(truth(), truth(), component)

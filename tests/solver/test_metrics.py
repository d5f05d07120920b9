import math

import numpy as np
import pytest

from solver import metrics


def truth():
    f = np.zeros((4, 3))
    f[:, 2] = [0.1, 0.4, 0.4, 0.1]  # 1 N normal
    f[:, 0] = 0.3 * f[:, 2]         # shear 0.3 along +x
    return f


def test_normal_total_error():
    estimate = truth()
    estimate[:, 2] *= 1.1
    assert metrics.normal_total_error(estimate, truth()) == pytest.approx(0.1)


def test_tangential_error_relative_to_the_total_force():
    estimate = truth()
    estimate[:, 0] = 0.0
    expected = 0.3 / math.hypot(0.3, 1.0)
    assert metrics.tangential_total_error(estimate, truth()) == pytest.approx(expected)


def test_direction_error():
    rotated = truth()
    rotated[:, 1], rotated[:, 0] = rotated[:, 0], 0.0
    assert metrics.direction_error(rotated, truth()) == pytest.approx(90.0)
    reversed_ = truth()
    reversed_[:, 0] *= -1
    assert metrics.direction_error(reversed_, truth()) == pytest.approx(180.0)
    none = truth()
    none[:, :2] = 0
    assert metrics.direction_error(none, truth()) == 180.0
    assert math.isnan(metrics.direction_error(truth(), none))


def test_field_error_and_compare():
    estimate = truth()
    estimate[1, 2] += 0.1
    expected = 0.1 / np.linalg.norm(truth())
    assert metrics.field_error(estimate, truth()) == pytest.approx(expected)
    assert metrics.field_error(estimate, truth(), "tangential") == 0
    errors = metrics.compare(estimate, truth())
    assert errors.normal_total == pytest.approx(0.1) and errors.field == pytest.approx(expected)
    assert set(errors.as_dict()) == {"normal_total", "tangential_total", "direction_deg", "field"}


def test_zero_truth_gives_nan():
    zero = np.zeros((3, 3))
    assert math.isnan(metrics.normal_total_error(zero, zero))
    assert math.isnan(metrics.tangential_total_error(zero, zero))
    assert math.isnan(metrics.field_error(zero, zero))


def test_shapes_and_component_are_checked():
    with pytest.raises(ValueError, match=r"forces and truth must both have shape \(m, 3\), got \(4, 3\) and \(3, 3\)"):
        metrics.compare(truth(), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="component must be one of .* got 'shear'"):
        metrics.field_error(truth(), truth(), "shear")

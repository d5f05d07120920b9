"""The shear parameters (no Qt): what Auto found, and the rule for leaving Auto when a slider moves."""

import math
from types import SimpleNamespace

import pytest

from solver import SensorGrid, loads
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.shear_parameters import MAX_SHEAR_RATIO, auto_found, leave_auto
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.source import RecordingSource


def shown(auto, ratio, direction):
    # the parts of a Solved frame the rule reads
    return SimpleNamespace(auto=auto, result=SimpleNamespace(shear_ratio=ratio, shear_direction=direction))


def test_auto_found_is_the_frames_parameters_bounded_and_wrapped():
    assert auto_found(shown(True, 0.4, 0.5), (0.1, 0.2)) == (0.4, 0.5)
    ratio, direction = auto_found(shown(True, 2.0, 1.5 * math.pi), (0.1, 0.2))
    assert ratio == MAX_SHEAR_RATIO and direction == pytest.approx(-0.5 * math.pi)


def test_auto_found_keeps_the_manual_values_when_nothing_was_found():
    assert auto_found(None, (0.1, 0.2)) == (0.1, 0.2)  # Auto off, or no frame solved yet
    assert auto_found(shown(False, 0.4, 0.5), (0.1, 0.2)) == (0.1, 0.2)  # solved with manual values


def test_leaving_auto_starts_from_what_auto_found_and_takes_the_value_moved():
    assert leave_auto((0.4, 0.5), shear_ratio=0.7) == (0.7, 0.5)
    assert leave_auto((0.4, 0.5), shear_direction=-1.0) == (0.4, -1.0)
    assert leave_auto((0.4, 0.5)) == (0.4, 0.5)
    assert leave_auto((0.4, 0.5), shear_direction=2 * math.pi + 0.25)[1] == pytest.approx(0.25)


@pytest.mark.parametrize(("changes", "message"), [
    (dict(shear_ratio=MAX_SHEAR_RATIO + 1e-9), r"shear_ratio must be in \[0, 1.5\]"),
    (dict(shear_ratio=-0.1), r"shear_ratio must be in \[0, 1.5\]"),
    (dict(shear_ratio=0.5, shear_direction=math.nan), "shear_direction must be finite radians"),
])
def test_leaving_auto_checks_both_values(changes, message):
    with pytest.raises(ValueError, match=message):
        leave_auto((0.4, 0.5), **changes)


def test_a_moved_slider_leaves_auto_with_the_model_open_and_does_nothing_without():
    closed = ViewerModel()
    closed.move_parameters(shear_ratio=0.7)
    assert closed.auto and closed.shear_ratio == 0.0  # nothing open: nothing set
    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3)
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0, shear_ratio=0.4, shear_direction=0.5))
    model = ViewerModel()
    model.set_source(RecordingSource(Recording(grid, [frame.stress], [0.0])), ViewerModel.build(grid, "layer"))
    found = model.solve().result
    model.move_parameters(shear_ratio=0.7)
    assert not model.auto and model.shear_ratio == 0.7
    assert model.shear_direction == pytest.approx(math.remainder(found.shear_direction, 2 * math.pi))

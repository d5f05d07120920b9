"""The stacked time plots alone, under Xvfb: curves of a series, rows shown, cursors, lost frames, seeking."""

import math

import numpy as np
import pytest


def series(truth=False, contacts=0):
    from tactile_viewer.model.series import Quantities, Series, TruthErrors

    t = np.arange(5) * 0.1
    q = Quantities(*(np.arange(5.0) + k for k in range(6)))
    errors = TruthErrors(*np.zeros((3, 5))) if truth else None
    return Series(np.arange(5), t, q, q if truth else None, errors,
                  contacts=tuple((i, q) for i in range(1, contacts + 1)))


@pytest.fixture
def stack(qtbot):
    from tactile_viewer.qt.time_plot_stack import TimePlotStack

    made = TimePlotStack({"fz", "tangential"})
    qtbot.addWidget(made)
    return made


def test_a_series_is_drawn_on_the_rows_shown(stack):
    drawn = series()
    stack.draw(drawn)
    np.testing.assert_array_equal(stack.curves["fz"].xData, drawn.t)
    np.testing.assert_allclose(stack.curves["fz"].yData, drawn.estimate.fz * 1e3)
    layout = stack.ci
    assert [key for key, plot in stack.plots.items() if plot in layout.items] == ["fz", "tangential"]
    assert stack.plots["tangential"].getAxis("bottom").isVisible()
    stack.show_rows({"fz", "error"})  # an error row only beside a truth
    assert [key for key, plot in stack.plots.items() if plot in layout.items] == ["fz"]
    stack.draw(series(truth=True))
    assert stack.plots["error"] in layout.items and stack.truth_curves["fz"] in stack.plots["fz"].items


def test_several_contacts_have_curves_of_their_own(stack):
    stack.draw(series(contacts=1))
    assert stack.contact_curves == {}
    stack.draw(series(contacts=2))
    assert sorted(stack.contact_curves) == [1, 2]
    stack.draw(series())
    assert stack.contact_curves == {}


def test_cursors_lost_frames_and_seeking(stack, qtbot):
    stack.move_cursors(0.2)
    assert all(c.value() == pytest.approx(0.2) for c in stack.cursors)
    stack.move_cursors(math.nan)
    assert not any(c.isVisible() for c in stack.cursors)
    marks = stack.lost_marks
    stack.mark_lost([(0.1, 0.2)])
    assert len(marks) == len(stack.plots) and all(mark in plot.items for plot, mark in marks)
    stack.mark_lost(())
    assert stack.lost_marks is marks and marks == []
    cursor = stack.cursors[1]
    cursor.setValue(0.3)
    with qtbot.waitSignal(stack.seek_requested, timeout=1000) as blocker:
        cursor.sigDragged.emit(cursor)
    assert blocker.args == [pytest.approx(0.3)]
    assert all(other.value() == pytest.approx(0.3) for other in stack.cursors)

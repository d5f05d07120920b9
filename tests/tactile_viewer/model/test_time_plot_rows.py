"""The rows of the time plots (no Qt): curves cut across outages and wrapped angles, the contacts drawn."""

import numpy as np
import pytest

from tactile_viewer.model.series import Quantities, Series
from tactile_viewer.model.time_plot_rows import (
    ERROR_ROWS,
    FIRST_ROWS,
    MAX_CONTACT_CURVES,
    OUTAGE,
    ROWS,
    TIPS,
    _outages_cut,
    contacts_drawn,
    curve_data,
)


def test_curves_are_not_drawn_across_an_outage():
    # a board at 100 Hz, unplugged for a second: no straight line across the second nobody measured
    t = np.r_[np.arange(10) * 0.01, 1.09 + np.arange(5) * 0.01]
    y = np.arange(15.0)
    x, cut = _outages_cut(t, y)
    assert np.isnan(cut).sum() == 1 and np.flatnonzero(np.isnan(cut)).tolist() == [10]
    assert x[10] == pytest.approx((t[9] + t[10]) / 2)
    np.testing.assert_array_equal(cut[~np.isnan(cut)], y)
    # frames a little late are no outage
    steady = np.cumsum(np.r_[0.0, np.full(9, 0.01), 0.01 * (OUTAGE - 0.5), np.full(4, 0.01)])
    assert not np.isnan(_outages_cut(steady, y)[1]).any()
    assert _outages_cut(t[:2], y[:2])[1].tolist() == [0.0, 1.0]


def test_an_angle_is_cut_where_it_wraps():
    t = np.arange(4) * 0.01
    x, y = curve_data(t, np.array([170.0, 179.0, -179.0, -170.0]), wrap=True)
    assert np.flatnonzero(np.isnan(y)).tolist() == [2] and x[2] == pytest.approx((t[1] + t[2]) / 2)
    assert not np.isnan(curve_data(t, np.array([170.0, 179.0, -179.0, -170.0]))[1]).any()


def test_every_row_has_a_tip_and_the_first_rows_are_rows():
    keys = [key for key, *_ in (*ROWS, *ERROR_ROWS)]
    assert sorted(TIPS) == sorted(keys) and set(FIRST_ROWS) <= set(keys)


def quantities(fz):
    fz = np.asarray(fz, dtype=float)
    return Quantities(fz, fz, fz, fz, fz, fz)


def test_contacts_drawn_are_none_for_one_and_those_present_most_of_many():
    one = Series([0, 1], [0.0, 0.1], quantities([1.0, 2.0]), contacts=((1, quantities([1.0, 2.0])),))
    assert contacts_drawn(one) == ()
    many = tuple((i, quantities([1.0, 1.0] if i % 2 else [np.nan, 1.0]))
                 for i in range(1, MAX_CONTACT_CURVES + 3))
    drawn = contacts_drawn(Series([0, 1], [0.0, 0.1], quantities([1.0, 2.0]), contacts=many))
    identities = [i for i, _ in drawn]
    assert len(identities) == MAX_CONTACT_CURVES and identities == sorted(identities)
    # those on both frames (odd identities) first, then the first of those on one frame
    assert identities == [1, 2, 3, 4, 5, 6, 7, 9]

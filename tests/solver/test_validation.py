"""Accuracy on finely integrated loads (never the inversion kernel itself)."""

import numpy as np
import pytest

from solver import Reconstructor
from solver.validation import evaluate, format_table, standard_cases, summarize


@pytest.fixture(scope="module")
def cases():
    # 16x16; Hertz, cone, flat punch, uniform ellipse; shear ratio 0, 0.2, 0.4 in
    # golden-angle directions; h/pitch 0.5, 1, 1.5; 1% noise; seed fixed in standard_cases
    return standard_cases()


def test_standard_set_covers_what_the_bar_names(cases):
    assert len(cases) == 36
    assert {c.shape for c in cases} == {"hertz", "cone", "flat_punch", "ellipse"}
    assert {c.thickness_ratio for c in cases} == {0.5, 1.0, 1.5}
    assert {c.shear_ratio for c in cases} == {0.0, 0.2, 0.4}
    assert all(c.frame.grid.shape == (16, 16) and c.frame.noise == 0.01 for c in cases)
    # directions spread round the circle
    directions = np.array([c.shear_direction for c in cases])
    assert np.ptp(directions) > 5.5


@pytest.mark.parametrize("kernel, normal_bar", [("cell", 0.03), ("point", 0.08)])
def test_medians_over_the_standard_set_meet_the_bar(cases, kernel, normal_bar, capsys):
    rows = evaluate(cases, lambda grid: Reconstructor(grid, kernel=kernel))
    with capsys.disabled():
        print(f"\n{kernel} kernel, automatic parameters, 1% noise\n{format_table(rows)}")
    s = summarize(rows)
    assert s["normal_total"] <= normal_bar
    assert s["tangential_total"] <= 0.12
    assert s["direction_deg"] <= 15.0
    # no shear invented on the shear-free half of the set
    assert s["false_shear"] == 0.0


def test_shear_search_does_not_bias_the_normal_total(cases):
    auto = summarize(evaluate(cases, lambda grid: Reconstructor(grid)))
    shear_free = summarize(evaluate(cases, lambda grid: Reconstructor(grid),
                                    solve=lambda r, b: r.solve(b, shear_ratio=0.0, shear_direction=0.0)))
    assert abs(auto["normal_total"] - shear_free["normal_total"]) < 0.005


def test_cell_kernel_keeps_the_normal_total_at_thin_layers(cases):
    thin = [c for c in cases if c.thickness_ratio == 0.5]
    point = summarize(evaluate(thin, lambda g: Reconstructor(g, kernel="point")))
    cell = summarize(evaluate(thin, lambda g: Reconstructor(g, kernel="cell")))
    assert cell["normal_total"] < 0.03 < point["normal_total"]

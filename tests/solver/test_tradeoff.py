"""The speed/accuracy measurement (solver/tradeoff.py): configurations, front, presets, outputs."""

import csv
import math

import numpy as np
import pytest

from solver import SensorGrid
from solver import tradeoff as t

GRID = SensorGrid.regular(8, 8, 2e-3, 2e-3)


def fake(name, ms, tangential, normal=0.01):
    return t.Measurement(name=name, setup_s=0.01, frame_ms=ms, peak_mib=1.0, normal_total=normal,
                         tangential_total=tangential, direction_deg=10.0, false_shear=0.0,
                         configuration=t.Configuration(name))


def test_the_front_keeps_only_undominated_points():
    points = [fake("a", 0.1, 0.20), fake("b", 1.0, 0.06), fake("c", 2.0, 0.05), fake("d", 1.5, 0.08),
              fake("e", 3.0, 0.05)]
    assert [m.name for m in t.pareto(points)] == ["a", "b", "c"]  # d is beaten by b, e by c


def test_presets_come_from_the_front():
    points = [fake("a", 0.1, 0.20), fake("b", 1.0, 0.061), fake("c", 2.0, 0.05), fake("d", 1.5, 0.08)]
    chosen = t.presets(points)
    assert chosen["fast"].name == "a" and chosen["accurate"].name == "c"
    # balanced: the fastest front point within 25% of the most accurate's error (0.071 <= 1.25 * 0.06)
    assert chosen["balanced"].name == "b"


@pytest.fixture(scope="module")
def cases():
    return t.default_cases(GRID, noises=(0.01,))


def test_default_cases_cover_shapes_ratios_and_noise(cases):
    assert len(cases) == 4 * 5
    assert {c.name.split()[0] for c in cases} == {"hertz", "cone", "flat_punch", "ellipse"}
    assert sorted({c.shear_ratio for c in cases}) == [0.0, 0.2, 0.4]
    again = t.default_cases(GRID, noises=(0.01,))
    np.testing.assert_array_equal(cases[3].frame.stress, again[3].frame.stress)  # fixed seed


@pytest.mark.parametrize("configuration", t.CONFIGURATIONS, ids=lambda c: c.name)
def test_every_configuration_measures(configuration, cases):
    m = t.measure(configuration, GRID, cases[:6], repeat=1)
    assert m.setup_s > 0 and m.frame_ms > 0 and m.peak_mib > 0
    assert 0 <= m.normal_total < 0.2 and 0 <= m.false_shear <= 1
    if configuration.path == "normal":
        assert math.isnan(m.direction_deg) and m.tangential_total > 0.1  # no shear reconstructed


def test_the_normal_path_reconstructs_no_shear(cases):
    solver = t.Configuration("n", path="normal").build(GRID)
    result = solver.solve(cases[2].frame.stress)
    assert result.normal_only and not np.abs(result.forces[:, :2]).any()
    region = t.Configuration("r", path="region").build(GRID).solve_normal(cases[2].frame.stress)
    assert region.normal_only and not np.abs(region.forces[:, :2]).any()


def test_table_and_csv(tmp_path, cases):
    ms = [t.measure(c, GRID, cases[:4], repeat=1) for c in t.CONFIGURATIONS[:3]]
    table = t.format_table(ms)
    assert all(m.name in table for m in ms) and "fast" in table
    path = t.write_csv(ms, tmp_path / "out.csv")
    rows = list(csv.DictReader(path.open()))
    assert [r["configuration"] for r in rows] == [m.name for m in ms]
    assert float(rows[1]["frame_ms"]) == pytest.approx(ms[1].frame_ms, rel=1e-3)
    assert {r["preset"] for r in rows} >= {"fast"}


def test_a_large_skin_is_solved_through_windows():
    row = t.large_skin(48, frames=4)
    assert row["m"] == 48 * 48 and row["windows_factored"] >= 1
    assert row["normal_total"] < 0.02 and row["region_frame_ms"] > 0
    assert "48x48" in t.format_large([row])


def test_a_bad_path_is_rejected():
    with pytest.raises(ValueError, match=r"path must be one of \('fit', 'exact', 'normal', 'region'\)"):
        t.Configuration("x", path="fast")

"""The speed/accuracy measurement (measurement/tradeoff.py): measurements, front, presets, outputs."""

import csv
import math

import pytest

from measurement import tradeoff as t
from measurement.cases import default_cases
from solver import SensorGrid
from solver.quality import CONFIGURATIONS, Configuration

GRID = SensorGrid.regular(8, 8, 2e-3, 2e-3)


def fake(name, ms, tangential, normal=0.01):
    return t.Measurement(name=name, setup_s=0.01, frame_ms=ms, frame_cpu_ms=1.5 * ms, peak_mib=1.0,
                         normal_total=normal, tangential_total=tangential, direction_deg=10.0,
                         false_shear=0.0, configuration=Configuration(name))


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
    return default_cases(GRID, noises=(0.01,))


@pytest.mark.parametrize("configuration", CONFIGURATIONS, ids=lambda c: c.name)
def test_every_configuration_measures(configuration, cases):
    m = t.measure(configuration, GRID, cases[:6], repeat=1)
    assert m.setup_s > 0 and m.frame_ms > 0 and m.frame_cpu_ms > 0 and m.peak_mib > 0
    assert 0 <= m.normal_total < 0.2 and 0 <= m.false_shear <= 1
    if configuration.path == "normal":
        assert math.isnan(m.direction_deg) and m.tangential_total > 0.1  # no shear reconstructed


def test_table_and_csv(tmp_path, cases):
    ms = [t.measure(c, GRID, cases[:4], repeat=1) for c in CONFIGURATIONS[:3]]
    table = t.format_measurements(ms)
    assert all(m.name in table for m in ms) and "fast" in table
    path = t.write_csv(ms, tmp_path / "out.csv")
    rows = list(csv.DictReader(path.open()))
    assert [r["configuration"] for r in rows] == [m.name for m in ms]
    assert [(r["subdivision"], r["profile"]) for r in rows] == [
        (str(m.configuration.subdivision), m.configuration.profile) for m in ms]
    assert float(rows[1]["frame_ms"]) == pytest.approx(ms[1].frame_ms, rel=1e-3)
    assert float(rows[1]["frame_cpu_ms"]) == pytest.approx(ms[1].frame_cpu_ms, rel=1e-3)
    assert {r["preset"] for r in rows} >= {"fast"}


def test_the_table_marks_the_front_and_names_the_presets():
    points = [fake("a", 0.1, 0.20), fake("b", 1.0, 0.061), fake("c", 2.0, 0.05), fake("d", 1.5, 0.08)]
    lines = t.format_measurements(points).splitlines()
    assert lines[0].split() == ["configuration", "set-up", "s", "frame", "ms", "CPU", "ms", "peak", "MiB", "normal", "tang",
                                "dir", "deg", "false", "mu", "front"]
    assert lines[1].endswith("1.00%  20.0%    10.0       0%  * fast")
    # a: set-up 0.01 s, wall 0.1 ms, CPU 0.15 ms, 1 MiB
    assert lines[1].split()[1:5] == ["0.010", "0.10", "0.15", "1.0"]
    assert lines[2].endswith("* balanced") and lines[3].endswith("* accurate")
    assert lines[4].endswith("0%")  # d: off the front
    assert len({line.index("%") for line in lines[1:]}) == 1  # the columns line up


def test_a_large_skin_is_solved_through_windows():
    row = t.large_skin(48, frames=4)
    assert row["m"] == 48 * 48 and row["windows_factored"] >= 1
    assert row["normal_total"] < 0.02 and row["region_frame_ms"] > 0
    assert "48x48" in t.format_large([row])

"""``tactile-tradeoff`` end to end on a small geometry: table, CSV and PNG."""

import csv

import pytest
import pyvista as pv

from solver.kernels import KERNELS
from solver.quality import CONFIGURATIONS, Configuration
from tactile_viewer.cli.tactile_tradeoff import main, on_kernel


def test_the_tool_writes_table_csv_and_plot(tmp_path, capsys):
    assert main(["--nx", "8", "--ny", "8", "--noise", "0.01", "--repeat", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    # "balanced" may be the same configuration as "fast" or "accurate", and is then labelled as that one
    assert "configuration" in out and "normal only" in out and "fast" in out and "accurate" in out
    assert f"nu 0.5, point sensors; kernel {KERNELS[0]}" in out  # the geometry and kernel measured
    rows = list(csv.DictReader((tmp_path / "tradeoff.csv").open()))
    assert len(rows) == len(CONFIGURATIONS) and sum(int(r["pareto"]) for r in rows) >= 2
    image = pv.read(tmp_path / "tradeoff.png")
    assert image.dimensions[:2] == (1200, 800)
    pixels = image.point_data[image.point_data.keys()[0]]
    assert pixels.std() > 10  # not a blank picture


def test_bad_arguments_exit_with_a_message(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--pitch", "0"])
    assert exit_info.value.code == 2 and "pitch" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--noise", "1.5"])
    assert "--noise levels must be in [0, 1)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--poisson-ratio", "0.7"])
    assert "poisson_ratio must be a finite number in [0, 0.5], got 0.7" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--sensor-size", "0.01"])
    assert "sensor_size must be at most the pitch" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--kernel", "spline"])
    assert "invalid choice: 'spline'" in capsys.readouterr().err


@pytest.mark.parametrize("kernel", KERNELS)
def test_configurations_move_to_the_kernel_asked(kernel):
    default = Configuration("x").kernel
    moved = on_kernel(CONFIGURATIONS, kernel)
    names = [c.name for c in moved]
    assert len(set(names)) == len(names)  # nothing measured twice
    for c in CONFIGURATIONS:
        if c.kernel == default:  # follows --kernel, and its name says so
            twin = next(m for m in moved if m.path == c.path and m.iterations == c.iterations
                        and m.subdivision == c.subdivision
                        and m.max_condition == c.max_condition and m.kernel == kernel)
            assert twin.name == (kernel + c.name[len(default):] if c.name.startswith(default + ",") else c.name)
        elif c.kernel != kernel:  # a comparison on another kernel stays
            assert c in moved
    unnamed = [(c.kernel, c.path, c.subdivision, c.iterations, c.tolerance, c.max_condition) for c in moved]
    assert len(set(unnamed)) == len(unnamed)  # and a comparison that became a repeat is dropped


def test_the_configurations_own_kernel_leaves_them_alone():
    assert on_kernel(CONFIGURATIONS, Configuration("x").kernel) == list(CONFIGURATIONS)


def test_the_plot_leaves_room_around_every_point():
    # the slowest point was cut in half by the right edge; markers on one spot hid each other
    import math

    from measurement.tradeoff import Measurement, error_of
    from tactile_viewer.cli.tactile_tradeoff import chart_of

    points = [(0.06, 0.2), (1.0, 0.06), (6.0, 0.023), (6.1, 0.023)]  # the last two almost coincide
    measurements = [Measurement(f"c{k}", 0.01, ms, ms, 3.0, 0.0, error, 5.0, 0.0, CONFIGURATIONS[k])
                    for k, (ms, error) in enumerate(points)]
    chart = chart_of(measurements)
    low, high = chart.x_axis.range
    assert math.log10(points[0][0] / low) >= 0.2 and math.log10(high / points[-1][0]) >= 0.2
    bottom, top = chart.y_axis.range
    assert bottom == 0 and top > 100 * max(error_of(m) for m in measurements) * 1.1
    sizes = [plot.GetMarkerSize() for plot in chart.plots("scatter")]
    assert sizes == sorted(sizes, reverse=True) and sizes[-1] < sizes[-2]  # the later, smaller, on top

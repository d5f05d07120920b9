"""tactile-tradeoff: measure speed against accuracy for a geometry; table, CSV and plot.

The measurements are :mod:`measurement.tradeoff`'s; this module adds the command
line and draws the time-against-error plot with its Pareto front (a pyvista
chart, rendered off screen).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from measurement import tradeoff as measured
from measurement.cases import default_cases
from measurement.timing import machine
from solver.kernels import KERNELS
from solver.quality import CONFIGURATIONS, Configuration

from ..model.captions import KERNEL_HELP, geometry_text
from .skin_options import add_skin_arguments, skin_grid

__all__ = ["plot", "on_kernel", "main"]


def on_kernel(configurations, kernel: str) -> list:
    """The configurations measured on ``kernel``.

    Those on the solver's default kernel move to ``kernel`` (a name that
    starts with the old kernel's, such as "cell, exact", is renamed to match);
    those that exist to compare another kernel keep it, unless they would now
    repeat a moved one.

    Parameters
    ----------
    configurations : iterable of solver.quality.Configuration
    kernel : str
        One of :data:`solver.kernels.KERNELS`.

    Returns
    -------
    list of solver.quality.Configuration
    """
    default = next(f.default for f in dataclasses.fields(Configuration) if f.name == "kernel")
    moved, compared = [], []
    for c in configurations:
        if c.kernel == default:
            name = kernel + c.name[len(default):] if c.name.startswith(default + ",") else c.name
            moved.append(dataclasses.replace(c, name=name, kernel=kernel))
        else:
            compared.append(c)
    # e.g. "point, exact" is "cell, exact" moved to --kernel point: measure it once
    unnamed = {dataclasses.replace(c, name="") for c in moved}
    repeats = {c.name for c in compared if dataclasses.replace(c, name="") in unnamed}
    out = []
    for c in configurations:  # in the solver's order, which the table and the plot follow
        if c.kernel == default:
            out.append(moved.pop(0))
        elif c.name not in repeats:
            out.append(c)
    return out


def plot(measurements, path, *, title="", size=(1200, 800)) -> Path:
    """Median frame time (log axis) against error, one marker per configuration, the front as a line."""
    import pyvista as pv

    chart = chart_of(measurements, title=title)
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    try:
        plotter.set_background("white")
        plotter.add_chart(chart)
        plotter.screenshot(str(path))
    finally:
        plotter.close()
    return Path(path)


def chart_of(measurements, *, title=""):
    """The pyvista chart :func:`plot` draws."""
    import pyvista as pv

    chart = pv.Chart2D(
        x_label="median time per frame (ms, log scale)",
        y_label="median error: tangential + normal total (% of |F|)",
    )
    chart.title = title
    colours = [
        "#1f77b4",
        "#ff7f0e",
        "#2ca02c",
        "#d62728",
        "#9467bd",
        "#8c564b",
        "#e377c2",
        "#7f7f7f",
        "#bcbd22",
        "#17becf",
    ]
    markers = ["o", "s", "d", "x", "+"]
    named = {m.name: label for label, m in measured.presets(measurements).items()}
    # larger markers first, smaller on top: configurations that land on one spot all stay visible
    sizes = np.linspace(22, 8, max(len(measurements), 2))
    for k, m in enumerate(measurements):
        label = m.name + (f" ({named[m.name]})" if m.name in named else "")
        chart.scatter(
            [m.frame_ms],
            [100 * measured.error_of(m)],
            color=colours[k % len(colours)],
            size=float(sizes[k]),
            style=markers[k % len(markers)],
            label=label,
        )
    front = measured.pareto(measurements)
    chart.line(
        [m.frame_ms for m in front],
        [100 * measured.error_of(m) for m in front],
        color="black",
        width=2.0,
        style="--",
        label="Pareto front",
    )
    chart.x_axis.log_scale = True
    # room around the points: the slowest and the most accurate are not cut by the frame
    times = [m.frame_ms for m in measurements]
    errors = [100 * measured.error_of(m) for m in measurements]
    chart.x_axis.range = [min(times) / 1.6, max(times) * 1.6]
    chart.y_axis.range = [0.0, max(errors) * 1.12 or 1.0]
    chart.legend_visible = True
    return chart


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tactile-tradeoff", description=__doc__.splitlines()[0])
    add_skin_arguments(parser)
    parser.add_argument("--kernel", choices=KERNELS, default=KERNELS[0], help=KERNEL_HELP)
    parser.add_argument(
        "--noise",
        type=float,
        nargs="+",
        default=[0.003, 0.01],
        help="noise levels, standard deviation over the peak stress",
    )
    parser.add_argument("--repeat", type=int, default=3, help="runs per frame (the fastest counts)")
    parser.add_argument("--out", type=Path, default=Path("tradeoff"), help="folder for the CSV and PNG")
    parser.add_argument(
        "--large",
        type=int,
        nargs="*",
        metavar="N",
        help="also measure N x N skins through the region solver (e.g. --large 64 128); "
        "skins up to 64 also time the full set-up",
    )
    args = parser.parse_args(argv)
    grid = skin_grid(parser, args)
    if any(not 0 <= n < 1 for n in args.noise):
        parser.error(f"--noise levels must be in [0, 1), got {args.noise}")
    cases = default_cases(grid, noises=tuple(args.noise))
    print(
        f"{machine()}\n{geometry_text(grid)}; kernel {args.kernel}; {len(cases)} cases "
        f"(noise {', '.join(f'{100 * n:g}%' for n in args.noise)})",
        flush=True,
    )
    results = measured.measure_all(
        grid,
        on_kernel(CONFIGURATIONS, args.kernel),
        cases=cases,
        repeat=args.repeat,
        progress=lambda m: print(f"  measured {m.name}", file=sys.stderr, flush=True),
    )
    print(measured.format_measurements(results))
    args.out.mkdir(parents=True, exist_ok=True)
    table = measured.write_csv(results, args.out / "tradeoff.csv")
    figure = plot(
        results,
        args.out / "tradeoff.png",
        title=f"{args.nx}x{args.ny} skin, h/pitch {args.thickness / args.pitch:g}",
    )
    print(f"wrote {table} and {figure}")
    if args.large:
        rows = []
        for n in args.large:
            print(f"  measuring {n}x{n}", file=sys.stderr, flush=True)
            rows.append(measured.large_skin(n, full=n <= 64))
        print("large skins: one Hertzian contact (1 N, shear 0.3) circling, 30 frames, 1% noise")
        print(measured.format_large(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Speed against accuracy: measure quality settings on simulated cases of one geometry.

Each :class:`solver.quality.Configuration` is one way to reconstruct (kernel,
path, search resolution, regularization, region of interest). :func:`measure`
times its set-up and its per-frame solves, tracks its peak memory, and scores
it with :mod:`solver.metrics` against finely integrated truth
(:func:`measurement.cases.default_cases`); :func:`pareto` keeps the
configurations no other beats on both time and error; :func:`presets` names
the front's fastest, most accurate and best-balanced points. No plotting here
(``tactile-tradeoff`` draws): numpy and scipy only.
"""

from __future__ import annotations

import csv
import math
import time
import tracemalloc
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from solver import Reconstructor, loads, metrics
from solver.geometry import SensorGrid
from solver.inverse import DenseSolver
from solver.quality import CONFIGURATIONS, Configuration
from solver.region import RegionSolver

from .cases import default_cases
from .tables import DIRECTION, NORMAL, TANGENTIAL, Column, format_table, value
from .timing import fastest_in_rounds

__all__ = ["Measurement", "measure", "measure_all", "error_of", "pareto", "BALANCED_SLACK",
           "presets", "preset_front", "format_measurements", "write_csv", "large_skin", "format_large"]



@dataclass(frozen=True)
class Measurement:
    """What one configuration cost and how accurate it was (medians over the cases)."""

    name: str
    setup_s: float
    frame_ms: float
    frame_cpu_ms: float  # beside the wall time: the machine is shared
    peak_mib: float
    normal_total: float
    tangential_total: float
    direction_deg: float
    false_shear: float
    configuration: Configuration = field(repr=False, compare=False)


def measure(
    configuration: Configuration, grid: SensorGrid, cases, *, repeat: int = 3, memory: bool = True
) -> Measurement:
    """Set-up time, median per-frame time (fastest of ``repeat`` runs per frame, in rounds over
    all the cases: :func:`measurement.timing.fastest_in_rounds`), peak memory of set-up plus a few
    solves (traced separately: tracing slows numpy), and median errors."""
    setup = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        solver = Reconstructor(grid, quality=configuration)
        setup = min(setup, time.perf_counter() - start)
    times, cpu, results = fastest_in_rounds(solver.solve, [case.frame.stress for case in cases], repeat)
    rows = [(case.shear_ratio, result.shear_ratio, metrics.compare(result.forces, case.frame.forces))
            for case, result in zip(cases, results, strict=True)]
    del solver
    peak = math.nan
    if memory:
        tracemalloc.start()
        try:
            traced = Reconstructor(grid, quality=configuration)
            for case in cases[:4]:
                traced.solve(case.frame.stress)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    # a normal-only answer has no shear direction to score
    sheared = [e.direction_deg for ratio, _, e in rows if ratio >= 0.2 and configuration.path != "normal"]
    free = [found for ratio, found, _ in rows if ratio == 0]
    return Measurement(
        name=configuration.name,
        setup_s=setup,
        frame_ms=1e3 * float(np.median(times)),
        frame_cpu_ms=1e3 * float(np.median(cpu)),
        peak_mib=peak / 2**20,
        normal_total=float(np.median([e.normal_total for _, _, e in rows])),
        tangential_total=float(np.median([e.tangential_total for _, _, e in rows])),
        direction_deg=float(np.median(sheared)) if sheared else math.nan,
        false_shear=float(np.mean([f > 0 for f in free])) if free else math.nan,
        configuration=configuration,
    )


def measure_all(
    grid: SensorGrid, configurations=CONFIGURATIONS, cases=None, *, repeat: int = 3, progress=None,
    memory: bool = True,
) -> list[Measurement]:
    """:func:`measure` for each configuration; ``progress(measurement)`` after each.

    ``memory=False`` skips the peak-memory pass: tracemalloc is process-wide and
    starting or stopping it while other threads allocate through numpy has
    crashed CPython 3.11 here (a worker thread of the viewer measuring presets
    while the serial reader ran).
    """
    cases = default_cases(grid) if cases is None else cases
    out = []
    for configuration in configurations:
        out.append(measure(configuration, grid, cases, repeat=repeat, memory=memory))
        if progress is not None:
            progress(out[-1])
    return out


def error_of(m: Measurement) -> float:
    """The accuracy figure the front is drawn on: median tangential error plus median normal error,
    both relative to |F| (the shear is what the method adds; the normal total must not suffer)."""
    return m.tangential_total + m.normal_total


def pareto(measurements) -> list[Measurement]:
    """Measurements no other is both faster and more accurate than, fastest first."""
    front = [
        m
        for m in measurements
        if not any(
            (o.frame_ms <= m.frame_ms and error_of(o) < error_of(m))
            or (o.frame_ms < m.frame_ms and error_of(o) <= error_of(m))
            for o in measurements
        )
    ]
    return sorted(front, key=lambda m: m.frame_ms)


BALANCED_SLACK = 0.25  # how much more error than the most accurate the balanced preset may have


def preset_front(grid: SensorGrid) -> dict[str, Measurement]:
    """The quality presets of ``grid``: every configuration measured once on 1% noise cases.

    What the viewer's quality selector offers; a plain function of the geometry,
    so that it can run in another process.
    """
    cases = default_cases(grid, noises=(0.01,))
    return presets(measure_all(grid, cases=cases, repeat=1, memory=False))


def presets(measurements) -> dict[str, Measurement]:
    """From the measured front: ``fast`` (its fastest point), ``accurate`` (its most accurate) and
    ``balanced`` (its fastest point within ``BALANCED_SLACK`` of the most accurate's error)."""
    front = pareto(measurements)
    accurate = min(front, key=error_of)
    balanced = next(m for m in front if error_of(m) <= (1 + BALANCED_SLACK) * error_of(accurate))
    return {"fast": front[0], "balanced": balanced, "accurate": accurate}


def format_measurements(measurements) -> str:
    """One line per measurement; ``*`` marks the front, and the presets are named."""
    front = {m.name for m in pareto(measurements)}
    named = {m.name: label for label, m in presets(measurements).items()}
    columns = (
        Column("configuration", 30, value("name"), align="<"),
        Column("set-up s", 8, value("setup_s", ".3f")),
        Column("frame ms", 8, value("frame_ms", ".2f")),
        Column("CPU ms", 6, value("frame_cpu_ms", ".2f")),
        Column("peak MiB", 8, value("peak_mib", ".1f")),
        NORMAL,
        TANGENTIAL,
        DIRECTION,
        Column("false mu", 8, value("false_shear", ".0f", scale=100, unit="%")),
        Column("front", 0, lambda m: ("*" if m.name in front else "")
               + (f" {named[m.name]}" if m.name in named else ""), align="<", gap=2),
    )
    return format_table(measurements, columns)


def write_csv(measurements, path) -> Path:
    path = Path(path)
    front = {m.name for m in pareto(measurements)}
    named = {m.name: label for label, m in presets(measurements).items()}
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            [
                "configuration",
                "kernel",
                "path",
                "subdivision",
                "profile",
                "iterations",
                "tolerance",
                "max_condition",
                "setup_s",
                "frame_ms",
                "frame_cpu_ms",
                "peak_mib",
                "normal_total",
                "tangential_total",
                "direction_deg",
                "false_shear",
                "pareto",
                "preset",
            ]
        )
        for m in measurements:
            c = asdict(m.configuration)
            writer.writerow(
                [
                    m.name,
                    c["kernel"],
                    c["path"],
                    c["subdivision"],
                    c["profile"],
                    c["iterations"],
                    c["tolerance"],
                    c["max_condition"],
                    f"{m.setup_s:.6f}",
                    f"{m.frame_ms:.4f}",
                    f"{m.frame_cpu_ms:.4f}",
                    f"{m.peak_mib:.3f}",
                    f"{m.normal_total:.6f}",
                    f"{m.tangential_total:.6f}",
                    f"{m.direction_deg:.3f}",
                    f"{m.false_shear:.4f}",
                    int(m.name in front),
                    named.get(m.name, ""),
                ]
            )
    return path


def large_skin(n: int, *, frames: int = 30, full: bool = False, seed: int = 5) -> dict:
    """Cost on an ``n x n`` skin (pitch 2 mm, h/pitch 1) of a Hertzian contact circling with turning
    shear: the region solver's set-up, first frame (factoring its window) and median frame time, the
    windows it factored, its median errors; with ``full``, the full reconstructor's set-up time."""
    pitch = 2e-3
    grid = SensorGrid.regular(n, n, pitch, pitch)
    rng = np.random.default_rng(seed)  # fixed seed: the same frames every run
    radius = 0.3 * (n // 2) * pitch
    contacts = [
        loads.hertz(
            (radius * math.cos(a), radius * math.sin(a)),
            2.5 * pitch,
            1.0,
            shear_ratio=0.3,
            shear_direction=math.remainder(a + 1.0, 2 * math.pi),
        )
        for a in np.linspace(0, 2 * math.pi, frames, endpoint=False)
    ]
    simulated = [loads.simulate(grid, c, noise=0.01, rng=rng) for c in contacts]
    out = dict(n=n, m=grid.size, dense_matrix_gib=grid.size * 3 * grid.size * 8 / 2**30)
    start = time.perf_counter()
    solver = RegionSolver(grid)
    out["region_setup_s"] = time.perf_counter() - start
    times, errors = [], []
    for frame in simulated:
        start = time.perf_counter()
        result = solver.solve(frame.stress)
        times.append(time.perf_counter() - start)
        errors.append(metrics.compare(result.forces, frame.forces))
    out.update(
        region_first_ms=1e3 * times[0],
        region_frame_ms=1e3 * float(np.median(times[1:])),
        windows_factored=solver.factorizations,
        normal_total=float(np.median([e.normal_total for e in errors])),
        tangential_total=float(np.median([e.tangential_total for e in errors])),
        direction_deg=float(np.median([e.direction_deg for e in errors])),
    )
    if full:
        start = time.perf_counter()
        DenseSolver(grid)
        out["full_setup_s"] = time.perf_counter() - start
    return out


_LARGE = (
    Column("skin", 7, lambda r: f"{r['n']:>3}x{r['n']:<3}"),
    Column("dense C", 10, value("dense_matrix_gib", ".2f", unit=" GiB")),
    Column("full set-up", 11, lambda r: f"{r['full_setup_s']:.2f} s" if "full_setup_s" in r else "-"),
    Column("region set-up", 13, value("region_setup_s", ".4f", unit=" s")),
    Column("first frame", 11, value("region_first_ms", ".1f", unit=" ms")),
    Column("frame", 8, value("region_frame_ms", ".2f", unit=" ms")),
    Column("windows", 7, value("windows_factored", "d")),
    NORMAL,
    TANGENTIAL,
    DIRECTION,
)


def format_large(rows) -> str:
    """One line per :func:`large_skin` row."""
    return format_table(rows, _LARGE)

"""Speed against accuracy: measure solver configurations on simulated cases of one geometry.

Each :class:`Configuration` is one way to reconstruct (kernel, path, search
resolution, regularization, region of interest). :func:`measure` times its
set-up and its per-frame solves, tracks its peak memory, and scores it with
:mod:`solver.metrics` against finely integrated truth; :func:`pareto` keeps the
configurations no other beats on both time and error; :func:`presets` names
the front's fastest, most accurate and best-balanced points. No plotting here
(``tactile-tradeoff`` draws): numpy and scipy only.
"""

from __future__ import annotations

import csv
import math
import os
import platform
import time
import tracemalloc
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import loads, metrics
from .efficiency import ContactFit
from .geometry import SensorGrid
from .inverse import Reconstructor
from .region import RegionSolver
from .validation import SHAPES, standard_contact

__all__ = ["machine", "preset_front",
    "Configuration",
    "Measurement",
    "CONFIGURATIONS",
    "default_cases",
    "measure",
    "measure_all",
    "pareto",
    "presets",
    "format_table",
    "write_csv",
]

PATHS = ("fit", "exact", "normal", "region")



def machine() -> str:
    """One line naming the machine a measurement ran on: CPU, cores, numpy, Python."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, numpy {np.__version__}, python {platform.python_version()}"


@dataclass(frozen=True)
class Configuration:
    """One way to reconstruct.

    Attributes
    ----------
    name : str
    kernel : {"layer", "cell", "point"}
        Stress kernel (:mod:`solver.kernels`); "layer" is the skin as built,
        "cell" and "point" the paper's half-space kernels.
    path : {"fit", "exact", "normal", "region"}
        ``fit``: the fitted compressive, friction-shaped load of every contact
        (the automatic answer of :meth:`solver.Reconstructor.solve`);
        ``exact``: the member of the exact solution family at the fitted
        parameters (the paper's answer); ``normal``: normal forces only;
        ``region``: ``fit`` on one window per contact.
    subdivision : int
        Sub-cells per side of each node's cell in the contact fit (1: the
        whole cell, the previous profile).
    iterations : int
        Gauss-Newton iterations of the automatic search (its resolution).
    tolerance : float
        Stopping tolerance of the search.
    max_condition : float
        Regularization: largest condition accepted undamped (thick layers).
    """

    name: str
    kernel: str = "layer"
    path: str = "fit"
    subdivision: int = 2
    iterations: int = 12
    tolerance: float = 1e-3
    max_condition: float = 100.0

    def __post_init__(self):
        if self.path not in PATHS:
            raise ValueError(f"path must be one of {PATHS}, got {self.path!r}")

    def build(self, grid: SensorGrid):
        """A solver for ``grid``: an object with ``solve(stress, shear_ratio=, shear_direction=)``,
        ``solve_normal(stress)``, ``grid`` and ``kernel``."""
        efficiency = ContactFit(max_iterations=self.iterations, tolerance=self.tolerance)
        options = dict(kernel=self.kernel, max_condition=self.max_condition, subdivision=self.subdivision,
                       efficiency=efficiency)
        if self.path == "region":
            return RegionSolver(grid, **options)
        return _Configured(Reconstructor(grid, **options), self.path)


class _Configured:
    # a Reconstructor whose solve takes the configuration's path
    def __init__(self, reconstructor: Reconstructor, path: str):
        self.reconstructor, self.path = reconstructor, path
        self.grid, self.kernel = reconstructor.grid, reconstructor.kernel

    def solve(self, stress, *, shear_ratio=None, shear_direction=None):
        if self.path == "normal":
            return self.reconstructor.solve_normal(stress)
        return self.reconstructor.solve(
            stress,
            shear_ratio=shear_ratio,
            shear_direction=shear_direction,
            exact=self.path == "exact",
        )

    def solve_normal(self, stress):
        return self.reconstructor.solve_normal(stress)


CONFIGURATIONS = (
    Configuration("normal only", path="normal"),
    Configuration("point, exact", kernel="point", path="exact"),
    Configuration("cell, fit", kernel="cell"),
    Configuration("layer, whole-cell profile", subdivision=1),
    Configuration("layer, coarse search", iterations=2, tolerance=1e-2),
    Configuration("layer, fit"),
    Configuration("layer, exact", path="exact"),
    Configuration("layer, exact, weak damping", path="exact", max_condition=1e4),
    Configuration("layer, exact, strong damping", path="exact", max_condition=30.0),
    Configuration("layer, region of interest", path="region"),
)


@dataclass(frozen=True)
class Case:
    """One simulated frame with its truth."""

    name: str
    shear_ratio: float
    frame: loads.SimulatedFrame


def default_cases(grid: SensorGrid, *, noises=(0.003, 0.01), seed: int = 11) -> list[Case]:
    """Hertzian and non-Hertzian single contacts (Hertz, cone, flat punch, ellipse), shear ratio 0,
    0.2 and 0.4 in varied directions, at each noise level (standard deviation over the peak stress).
    Contacts are 2.5 pitches across (the punch 2) near the skin's centre, 1 N."""
    rng = np.random.default_rng(seed)  # fixed seed: every configuration scores the very same frames
    pitch = grid.pitch
    cases = []
    for noise in noises:
        for shape in SHAPES:
            for ratio in (0.0, 0.2, 0.2, 0.4, 0.4):
                direction = rng.uniform(-math.pi, math.pi)
                centre = tuple(rng.uniform(-pitch, pitch, size=2))
                contact = standard_contact(shape, centre, pitch, rng, shear_ratio=ratio,
                                           shear_direction=direction)
                frame = loads.simulate(grid, contact, noise=noise, rng=rng)
                cases.append(Case(f"{shape} mu={ratio:g} noise={100 * noise:g}%", ratio, frame))
    return cases


@dataclass(frozen=True)
class Measurement:
    """What one configuration cost and how accurate it was (medians over the cases)."""

    name: str
    setup_s: float
    frame_ms: float
    peak_mib: float
    normal_total: float
    tangential_total: float
    direction_deg: float
    false_shear: float
    configuration: Configuration = field(repr=False, compare=False)


def measure(
    configuration: Configuration, grid: SensorGrid, cases, *, repeat: int = 3, memory: bool = True
) -> Measurement:
    """Set-up time, median per-frame time (fastest of ``repeat`` runs per frame: the machine is
    shared), peak memory of set-up plus a few solves (traced separately: tracing slows numpy),
    and median errors."""
    setup = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        solver = configuration.build(grid)
        setup = min(setup, time.perf_counter() - start)
    times, rows = [], []
    for case in cases:
        best = math.inf
        for _ in range(repeat):
            start = time.perf_counter()
            result = solver.solve(case.frame.stress)
            best = min(best, time.perf_counter() - start)
        times.append(best)
        rows.append((case.shear_ratio, result.shear_ratio, metrics.compare(result.forces, case.frame.forces)))
    del solver
    peak = math.nan
    if memory:
        tracemalloc.start()
        try:
            traced = configuration.build(grid)
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


def format_table(measurements) -> str:
    front = {m.name for m in pareto(measurements)}
    named = {m.name: label for label, m in presets(measurements).items()}
    lines = [
        f"{'configuration':<30} {'set-up s':>8} {'frame ms':>8} {'peak MiB':>8} {'normal':>7} "
        f"{'tang':>6} {'dir deg':>7} {'false mu':>8}  front"
    ]
    for m in measurements:
        mark = ("*" if m.name in front else "") + (f" {named[m.name]}" if m.name in named else "")
        lines.append(
            f"{m.name:<30} {m.setup_s:8.3f} {m.frame_ms:8.2f} {m.peak_mib:8.1f} "
            f"{100 * m.normal_total:6.2f}% {100 * m.tangential_total:5.1f}% {m.direction_deg:7.1f} "
            f"{100 * m.false_shear:7.0f}%  {mark}"
        )
    return "\n".join(lines)


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
                "iterations",
                "tolerance",
                "max_condition",
                "setup_s",
                "frame_ms",
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
                    c["iterations"],
                    c["tolerance"],
                    c["max_condition"],
                    f"{m.setup_s:.6f}",
                    f"{m.frame_ms:.4f}",
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
        Reconstructor(grid)
        out["full_setup_s"] = time.perf_counter() - start
    return out


def format_large(rows) -> str:
    lines = [
        f"{'skin':>7} {'dense C':>8} {'full set-up':>11} {'region set-up':>13} {'first frame':>11} "
        f"{'frame':>8} {'windows':>7} {'normal':>7} {'tang':>6} {'dir deg':>7}"
    ]
    for r in rows:
        full = f"{r['full_setup_s']:9.2f} s" if "full_setup_s" in r else f"{'-':>11}"
        lines.append(
            f"{r['n']:>3}x{r['n']:<3} {r['dense_matrix_gib']:6.2f} GiB {full} {r['region_setup_s']:11.4f} s "
            f"{r['region_first_ms']:8.1f} ms {r['region_frame_ms']:5.2f} ms {r['windows_factored']:7d} "
            f"{100 * r['normal_total']:6.2f}% {100 * r['tangential_total']:5.1f}% {r['direction_deg']:7.1f}"
        )
    return "\n".join(lines)

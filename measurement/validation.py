"""Accuracy: reconstructions of the simulated sets (:mod:`measurement.cases`) scored against their truth.

Used by the accuracy tests, the functional comparison (``python -m
measurement.validation``) and the benchmarks, so all of them measure the same thing.
"""

from __future__ import annotations

import argparse
import inspect
import math
import time

import numpy as np

from solver import Reconstructor, loads, metrics
from solver.efficiency import FUNCTIONALS, ContactFit
from solver.inverse import DenseSolver
from solver.kernels import KERNELS, PROFILES

from .bounds import decision_bound, format_decision_bound, shear_bounds
from .cases import (
    DECISION_SEEDS,
    LOAD_TUNING_SEEDS,
    LOAD_VALIDATION_SEEDS,
    layer_cases,
    load_decision_frames,
    standard_cases,
    tuning_cases,
    validation_cases,
)
from .tables import DIRECTION, NORMAL, TANGENTIAL, Column, format_table, value

__all__ = ["evaluate", "summarize", "counts", "false_shear", "MISMATCH_MEDIA", "mismatch", "load_decision",
           "decision_draws", "decision_curve", "against_bound", "format_against_bound", "format_cases",
           "format_mismatch", "format_summary", "format_load_decision", "format_decision_curve", "main"]


def evaluate(cases, make_reconstructor, *, solve=None):
    """Score reconstructions of every case.

    Parameters
    ----------
    cases : list of measurement.cases.Case
    make_reconstructor : callable
        ``grid -> Reconstructor`` (called once per distinct grid).
    solve : callable, optional
        ``(reconstructor, stress) -> Reconstruction``; default ``r.solve(stress)``.

    Returns
    -------
    list of dict
        One row per case: its description, the errors and the solve time in ms.
    """
    solve = solve or (lambda r, b: r.solve(b))
    cache = {}
    rows = []
    for case in cases:
        grid = case.frame.grid
        key = grid.key
        if key not in cache:
            cache[key] = make_reconstructor(case.frame.grid)
        reconstructor = cache[key]
        start = time.perf_counter()
        result = solve(reconstructor, case.frame.stress)
        elapsed = time.perf_counter() - start
        errors = metrics.compare(result.forces, case.frame.forces)
        rows.append(dict(case=case.name, shape=case.shape, thickness_ratio=case.thickness_ratio,
                         true_ratio=case.shear_ratio, ratio=result.shear_ratio,
                         true_direction=math.degrees(case.shear_direction),
                         direction=math.degrees(result.shear_direction), ms=elapsed * 1e3,
                         **errors.as_dict()))
    return rows


def summarize(rows) -> dict:
    """Medians over the set: normal and tangential total errors over all cases,
    direction error over cases with shear ratio >= 0.2, false shear on shear-free cases."""
    normal = np.median([r["normal_total"] for r in rows])
    tangential = np.median([r["tangential_total"] for r in rows])
    sheared = [r["direction_deg"] for r in rows if r["true_ratio"] >= 0.2]
    free = [r["ratio"] for r in rows if r["true_ratio"] == 0]
    return dict(normal_total=float(normal), tangential_total=float(tangential),
                direction_deg=float(np.median(sheared)) if sheared else math.nan,
                false_shear=float(np.median(free)) if free else math.nan,
                ms=float(np.median([r["ms"] for r in rows])))


def false_shear(rows) -> dict:
    """Shear found on the shear-free cases: how many got any, their mean and largest ratio."""
    free = [r["ratio"] for r in rows if r["true_ratio"] == 0]
    return dict(count=sum(f > 0 for f in free), cases=len(free),
                mean=float(np.mean(free)) if free else math.nan,
                largest=float(max(free)) if free else math.nan)


def counts(rows) -> dict:
    """Decisions over a set: shear reported on shear-free loads, missed on loads with shear >= 0.2."""
    found = false_shear(rows)
    sheared = [r for r in rows if r["true_ratio"] >= 0.2]
    return dict(false=found["count"], free=found["cases"],
                missed=sum(r["ratio"] == 0 for r in sheared), sheared=len(sheared))


# data media of the mismatch table: (label, medium, Poisson ratio)
MISMATCH_MEDIA = (("half-space", "halfspace", 0.5), ("layer nu=0.45", "layer", 0.45),
                  ("layer nu=0.5", "layer", 0.5))


def mismatch(*, noise: float = 0.01, kernels=("point", "cell", "layer"),
             media=MISMATCH_MEDIA) -> list[dict]:
    """Every kernel on data of every medium (:func:`~measurement.cases.layer_cases`): medians,
    false shear, conditions.

    Returns one row per (medium, kernel) with the :func:`summarize` medians, the
    :func:`false_shear` counts and ``condition``, the undamped 1-norm condition
    estimate of ``C`` (square root of that of ``C C^T``) per ``h / pitch``.
    """
    out = []
    for label, medium, nu in media:
        cases = layer_cases(noise=noise, medium=medium, poisson_ratio=nu)
        for kernel in kernels:
            made = {}

            def make(grid, kernel=kernel, made=made):
                made[grid.thickness / grid.pitch] = DenseSolver(grid, kernel=kernel)
                return made[grid.thickness / grid.pitch]

            rows = evaluate(cases, make)
            conditions = {ratio: math.sqrt(r._gram.condition_undamped) for ratio, r in sorted(made.items())}
            out.append(dict(medium=label, kernel=kernel, noise=noise, **summarize(rows),
                            false=false_shear(rows), condition=conditions))
    return out


# -- tables ----------------------------------------------------------------------------------------

_CASES = (
    Column("case", 40, value("case"), align="<"),
    Column("mu", 5, value("true_ratio", ".2f")),
    Column("mu est", 6, value("ratio", ".2f")),
    Column("dir err", 7, value("direction_deg", ".1f")),
    NORMAL,
    TANGENTIAL,
    Column("ms", 6, value("ms", ".2f")),
)


def load_decision(seeds, *, min_load_evidence: float | None = None) -> dict:
    """How the load decision does on :func:`measurement.cases.load_decision_frames`.

    Returns, per kind of frame, the frames with exactly one contact, with
    none, and the median and largest normal-total error (for noise alone:
    the frames that report any contact).
    """
    options = {} if min_load_evidence is None else dict(min_load_evidence=min_load_evidence)
    results, solvers = {}, {}
    for seed in seeds:
        for grid, kind, stress in load_decision_frames(seed):
            key = (grid.shape, grid.thickness)
            if key not in solvers:
                solvers[key] = Reconstructor(grid, efficiency=ContactFit(**options))
            result = solvers[key].solve(stress)
            results.setdefault(kind, []).append((len(result.contacts), float(result.total_force[2])))
    summary = {}
    for kind, rows in results.items():
        contacts = np.array([r[0] for r in rows])
        error = np.abs(np.array([r[1] for r in rows]) - 1.0)
        summary[kind] = dict(frames=len(rows), one=int(np.sum(contacts == 1)),
                             none=int(np.sum(contacts == 0)), median=float(np.median(error)),
                             worst=float(error.max()))
    return summary


def decision_draws(seeds=DECISION_SEEDS, *, noise: float = 0.01) -> list[list]:
    """Draws of the tuning set's kind: :func:`~measurement.cases.standard_cases` of each seed
    (12 shear-free loads and 24 with shear ratio 0.2 or 0.4, ``h / pitch`` 0.5, 1, 1.5)."""
    return [standard_cases(seed=seed, noise=noise) for seed in seeds]


def decision_curve(draws, *, shrinkages=(0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)) -> list[dict]:
    """How the shear decision trades false shear for missed shear, over draws of the tuning set's kind.

    A contact keeps shear exactly when its evidence ``F`` exceeds the
    shrinkage ``c`` (the factor ``1 - c / F`` is positive), so one solve per
    case scores every ``c``.

    Parameters
    ----------
    draws : sequence of list of measurement.cases.Case
        The draws (:func:`decision_draws`), each scored apart.
    shrinkages : sequence of float, optional
        The shrinkages ``c`` scored.

    Returns
    -------
    list of dict
        Per shrinkage: ``false`` and ``missed`` (mean and largest count per
        draw, of 12 and of 24), and ``missed_by_thickness`` (the share of
        loads with shear ratio 0.2 missed, per ``h / pitch``) with
        ``false_by_thickness`` (the share of shear-free loads given shear).
    """
    if not draws:
        raise ValueError("draws must hold at least one draw, got none")
    evidence = []  # (draw, h / pitch, true shear ratio, F of the largest contact)
    solvers = {}
    for draw, cases in enumerate(draws):
        for case in cases:
            grid = case.frame.grid
            if grid.key not in solvers:
                solvers[grid.key] = Reconstructor(grid)
            result = solvers[grid.key].solve(case.frame.stress)
            found = result.contacts[0].evidence if result.contacts else 0.0
            evidence.append((draw, case.thickness_ratio, case.shear_ratio, found))
    draw, thickness, ratio, found = (np.array(column) for column in zip(*evidence, strict=True))
    out = []
    for c in shrinkages:
        false = [int(np.sum((found > c) & (ratio == 0) & (draw == d))) for d in range(len(draws))]
        missed = [int(np.sum((found <= c) & (ratio >= 0.2) & (draw == d))) for d in range(len(draws))]
        out.append(dict(
            shrinkage=c, false_mean=float(np.mean(false)), false_max=max(false),
            missed_mean=float(np.mean(missed)), missed_max=max(missed),
            false_by_thickness={h: float(np.mean(found[(ratio == 0) & (thickness == h)] > c))
                                for h in np.unique(thickness)},
            missed_by_thickness={h: float(np.mean(found[(ratio == 0.2) & (thickness == h)] <= c))
                                 for h in np.unique(thickness)}))
    return out


def against_bound(cases, rows, bounds) -> list[dict]:
    """Measured errors against what the data allow, per ``h / pitch``.

    Parameters
    ----------
    cases : list of measurement.cases.Case
        One contact each.
    rows : list of dict
        :func:`evaluate`'s rows of ``cases``, in the same order.
    bounds : list of measurement.bounds.ShearBound
        :func:`measurement.bounds.shear_bounds` of ``cases``' frames, in the
        same order (they do not depend on the solver: one list serves every
        functional scored on the cases).

    Returns
    -------
    list of dict
        Per ``h / pitch``, over the loads with shear ratio >= 0.2: the
        medians of the tangential and direction errors measured
        (``tangential``, ``direction``) and of an unbiased estimate at the
        Cramér-Rao bound with one free force per node (``bound_tangential``,
        ``bound_direction``; :meth:`measurement.bounds.ShearBound.ideal_errors`).
    """
    if not len(cases) == len(rows) == len(bounds):
        raise ValueError(f"rows and bounds must cover every case, got {len(rows)} rows and {len(bounds)} "
                         f"bounds for {len(cases)} cases")
    sheared = [(case, row, bound) for case, row, bound in zip(cases, rows, bounds, strict=True)
               if case.shear_ratio >= 0.2]
    ideal = [bound.ideal_errors() for _, _, bound in sheared]
    out = []
    for ratio in sorted({case.thickness_ratio for case, _, _ in sheared}):
        part = [k for k, (case, _, _) in enumerate(sheared) if case.thickness_ratio == ratio]
        out.append(dict(
            thickness_ratio=ratio, loads=len(part),
            tangential=float(np.median([sheared[k][1]["tangential_total"] for k in part])),
            direction=float(np.median([sheared[k][1]["direction_deg"] for k in part])),
            bound_tangential=float(np.median([ideal[k][0] for k in part])),
            bound_direction=float(np.median([ideal[k][1] for k in part]))))
    return out


def format_against_bound(rows) -> str:
    """The rows of :func:`against_bound`, one line per ``h / pitch``."""
    return format_table(rows, (
        Column("h/p", 5, value("thickness_ratio", "g")),
        Column("loads", 5, value("loads")),
        Column("tangential", 10, value("tangential", ".1f", scale=100, unit="%")),
        Column("bound", 6, value("bound_tangential", ".1f", scale=100, unit="%")),
        Column("direction", 9, value("direction", ".1f", unit="d"), gap=3),
        Column("bound", 6, value("bound_direction", ".1f", unit="d")),
    ))


def format_decision_curve(curve) -> str:
    """The rows of :func:`decision_curve`, one line per shrinkage."""
    columns = [Column("c", 4, value("shrinkage", "g")),
               Column("false of 12: mean", 17, value("false_mean", ".1f"), gap=2),
               Column("max", 3, value("false_max")),
               Column("missed of 24: mean", 18, value("missed_mean", ".1f"), gap=2),
               Column("max", 3, value("missed_max"))]
    columns += [Column(f"false/missed 0.2 h/p {h:g}", 23,
                       lambda r, h=h: f"{r['false_by_thickness'][h]:.2f}/{r['missed_by_thickness'][h]:.2f}",
                       gap=3)
                for h in curve[0]["false_by_thickness"]]
    return format_table(curve, columns)


def format_load_decision(summary) -> str:
    lines = ["frames      one contact  none  total error median  worst"]
    for kind, row in summary.items():
        if kind == "noise":
            reporting = row["frames"] - row["none"]
            lines.append(f"{'noise alone':11} {reporting:>4} of {row['frames']:<3} report a contact")
            continue
        lines.append(f"{kind:11} {row['one']:>4} of {row['frames']:<3} {row['none']:>4}  "
                     f"{100 * row['median']:17.1f}%  {100 * row['worst']:5.1f}%")
    return "\n".join(lines)


def format_cases(rows) -> str:
    """One line per case of :func:`evaluate`, then the :func:`summarize` medians."""
    return format_table([*rows, dict(case="median", **summarize(rows))], _CASES)


def format_mismatch(rows) -> str:
    """The rows of :func:`mismatch`: medians, false shear and conditions per medium and kernel."""
    columns = [
        Column("data", 14, value("medium"), align="<"),
        Column("kernel", 6, value("kernel"), align="<"),
        NORMAL,
        TANGENTIAL,
        DIRECTION,
        Column("false shear", 15,
               lambda r: f"{r['false']['count']}/{r['false']['cases']} max {r['false']['largest']:.2f}"),
    ]
    columns += [Column(f"cond h/p={ratio:g}", 12, lambda r, ratio=ratio: f"{r['condition'][ratio]:.3g}")
                for ratio in rows[0]["condition"]]
    return format_table(rows, columns)


_SUMMARY = (
    Column("functional", 15, value("functional"), align="<"),
    Column("normal", 8, value("normal_total", ".2f", scale=100, unit="%")),
    Column("tangential", 10, value("tangential_total", ".1f", scale=100, unit="%")),
    Column("direction", 9, value("direction_deg", ".1f", unit="d")),
    Column("false shear", 11, lambda r: f"{r['false']:>6}/{r['free']:<4}"),
    Column("missed", 6, lambda r: f"{r['missed']:>3}/{r['sheared']:<2}"),
    Column("ms", 7, value("ms", ".2f")),
)


def format_summary(rows, *, header: bool = True) -> str:
    """One line per functional: the :func:`summarize` medians and the :func:`counts` of its rows,
    given as dicts with ``functional`` and both (``header=False``: the lines alone)."""
    return format_table(rows, _SUMMARY, header=header)


def main(argv=None):
    parser = argparse.ArgumentParser(description="Score the efficiency functionals and kernels "
                                                 "on the standard accuracy set.")
    parser.add_argument("--noise", type=float, default=0.01)
    parser.add_argument("--kernel", choices=KERNELS, default=KERNELS[0],
                        help="layer: elastomer bonded to a rigid hull (default); cell, point: half-space")
    parser.add_argument("--profile", choices=PROFILES,
                        help="the contact fit's load on each sub-cell: bilinear hats (default) or uniform; "
                             "for the validation and tuning sets")
    parser.add_argument("--medium", choices=loads.MEDIA, default="layer",
                        help="physics of the simulated data (default layer)")
    parser.add_argument("--functional", choices=sorted(FUNCTIONALS), action="append")
    parser.add_argument("--set", choices=("validation", "tuning"), default="validation",
                        help="validation: nothing was tuned on it (default); tuning: the constants "
                             "were chosen on it")
    parser.add_argument("--cases", action="store_true", help="print the per-case table too")
    parser.add_argument("--by-thickness", action="store_true",
                        help="below each functional's line, the same medians and counts per h/p")
    parser.add_argument("--against-bound", action="store_true",
                        help="per h/p, the sheared loads' tangential and direction medians beside those of "
                             "an unbiased estimate at the Cramer-Rao bound (one free force per node)")
    parser.add_argument("--mismatch", action="store_true",
                        help="every kernel on half-space and layer data (the physics set, h/p 0.5 to 2)")
    parser.add_argument("--load-decision", action="store_true",
                        help="load or noise: one Hertz load under 1%%, 10%% and 20%% noise and noise alone, "
                             "16x16 and 32x32, h/p 0.5 to 5")
    parser.add_argument("--decision-curve", action="store_true",
                        help="false against missed shear for each shrinkage, over 10 draws of the tuning "
                             "set's kind (seeds 100-109), then the Wald test's counts at the Cramer-Rao "
                             "bound")
    args = parser.parse_args(argv)
    if args.profile is not None and (args.decision_curve or args.load_decision or args.mismatch):
        parser.error("--profile applies to the validation and tuning sets, not to --decision-curve, "
                     "--load-decision or --mismatch (they use the solver's default profile)")
    profile = args.profile or inspect.signature(DenseSolver).parameters["profile"].default
    if args.decision_curve:
        print(f"shear decision, seeds {DECISION_SEEDS[0]}-{DECISION_SEEDS[-1]}: 16x16, h/p 0.5 1 1.5, layer "
              f"data, noise {args.noise:g}; shear kept when F > c (default c = {ContactFit().shrinkage:g})")
        draws = decision_draws(DECISION_SEEDS, noise=args.noise)
        print(format_decision_curve(decision_curve(draws)))
        print("\nthe Wald test at the Cramer-Rao bound on the same loads: an unbiased shear with one free "
              "force per node, support known, the model's own physics, no model error (measurement.bounds)")
        print(format_decision_bound(decision_bound(draws)))
        return
    if args.load_decision:
        seeds = LOAD_VALIDATION_SEEDS if args.set == "validation" else LOAD_TUNING_SEEDS
        print(f"load decision, {args.set} seeds {seeds}: 16x16 and 32x32, h/p 0.5 1 2 3 5, layer data")
        print(format_load_decision(load_decision(seeds)))
        return
    if args.mismatch:
        print(f"physics set: 48 cases per medium, 16x16, noise {args.noise:g}, automatic parameters")
        print(format_mismatch(mismatch(noise=args.noise)))
        return
    cases = (validation_cases if args.set == "validation" else tuning_cases)(noise=args.noise,
                                                                             medium=args.medium)
    print(f"{args.set} set: {len(cases)} cases, 16x16, {args.medium} data, noise {args.noise:g}, "
          f"kernel {args.kernel}, {profile} sub-cells")
    print(format_summary([]))
    bounds = shear_bounds([case.frame for case in cases]) if args.against_bound else None
    for name in args.functional or sorted(FUNCTIONALS):
        functional = FUNCTIONALS[name]
        rows = evaluate(cases, lambda g, f=functional: Reconstructor(
            g, kernel=args.kernel, profile=profile, efficiency=f()))
        if args.cases:
            print(format_cases(rows))
        print(format_summary([dict(functional=name, **summarize(rows), **counts(rows))], header=False))
        if args.against_bound:
            print(f"  loads with shear ratio >= 0.2, medians: {name} against an unbiased estimate at the "
                  "Cramer-Rao bound (one free force per node, support known, no model error)")
            table = format_against_bound(against_bound(cases, rows, bounds))
            print("\n".join("  " + line for line in table.splitlines()))
        if args.by_thickness:
            # the medians pool the thicknesses; a thin layer is where the sub-cell model errs most
            for ratio in sorted({r["thickness_ratio"] for r in rows}):
                part = [r for r in rows if r["thickness_ratio"] == ratio]
                print(format_summary([dict(functional=f"  h/p {ratio:g}", **summarize(part), **counts(part))],
                                     header=False))


if __name__ == "__main__":
    main()

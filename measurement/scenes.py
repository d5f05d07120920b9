"""Scenes of several contacts: pinches, close pairs, three contacts, contacts at the edge.

One contact alone is scored by :mod:`measurement.validation`. A hand's skin sees
more: two fingers pinching (each shearing towards the other), contacts a pitch
or two apart, three at once, one at the border, a light broad load beside a
sharp one. :func:`scene_cases` makes such
frames with the layer's physics (:func:`solver.loads.simulate`, independent of
the reconstruction kernels) and keeps each contact's own true forces, so
:func:`evaluate` scores every contact on its own: the reconstructed forces of a
node count for the true contact that loads it (or, where none does, whose load
is nearest), and each true contact is matched to the reconstructed contact
that carries most of its nodes' force.

Sets: :data:`TUNING_SEED` is the one thresholds may be chosen on;
:data:`VALIDATION_SEED` (other positions, sizes, gaps and noise) is the one
accuracy is judged on. ``python -m measurement.scenes`` prints the per-case
table, the medians and the decision counts beside the Cramér-Rao bound's.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from solver import Reconstructor, loads
from solver.checks import one_of, real_number
from solver.efficiency import ContactFit
from solver.geometry import SensorGrid

from .bounds import contact_bounds
from .tables import Column, format_table, print_report, value

__all__ = ["ContactScene", "KINDS", "STANDARD_KINDS", "TUNING_SEED", "VALIDATION_SEED", "scene_cases",
           "evaluate", "summarize", "format_scenes", "format_summary", "decision_curve",
           "format_decision_curve", "main"]

KINDS = ("pinch", "two", "three", "edge", "beside")
# The kinds a set holds unless others are asked for: the tables of docs/efficiency.md were measured
# on them. "beside" (a light broad load beside a sharp one, added 2026-11-28) is drawn when asked
# for, so that those tables stay comparable.
STANDARD_KINDS = KINDS[:4]
TUNING_SEED = 5
VALIDATION_SEED = 41
_SHAPES = ("hertz", "cone", "flat_punch")
_RATIOS = (0.0, 0.2, 0.4)
# the false rate at which the Wald test at the bound is read: the bar's 3 of every 20
_FALSE_RATE = 3 / 20


@dataclass(frozen=True)
class ContactScene:
    """One simulated frame of several contacts, with each contact's own truth.

    Attributes
    ----------
    name : str
        What the scene is, for tables ("pinch h/p=1 gap=2").
    kind : str
        One of :data:`KINDS`.
    thickness_ratio : float
        Layer thickness over pitch.
    gap : float
        Smallest edge-to-edge distance between two of its contacts, pitches.
    frame : solver.loads.SimulatedFrame
        The sensor data (noise included) and the true forces of all contacts.
    truths : tuple of (m, 3) ndarray
        Each contact's true nodal forces alone, newtons (they sum to ``frame.forces``).
    """

    name: str
    kind: str
    thickness_ratio: float
    gap: float
    frame: loads.SimulatedFrame
    truths: tuple


def _contact(shape, center, radius, force, ratio, direction):
    make = {"hertz": loads.hertz, "cone": loads.cone, "flat_punch": loads.flat_punch}[shape]
    return make(center, radius, force, shear_ratio=ratio, shear_direction=direction)


def _place(kind, pitch, half, rng):
    # (shape, centre, radius, force, ratio, direction) of each contact, and the smallest gap
    radius = lambda: rng.uniform(1.6, 2.4) * pitch  # noqa: E731
    shape = lambda: _SHAPES[rng.integers(len(_SHAPES))]  # noqa: E731
    force = lambda: rng.uniform(0.6, 1.2)  # noqa: E731
    angle = lambda: rng.uniform(-math.pi, math.pi)  # noqa: E731
    if kind == "pinch":
        # two fingers closing: each shears towards the other
        gap = float(rng.integers(1, 6))
        axis = angle()
        r1, r2 = radius(), radius()
        middle = rng.uniform(-pitch, pitch, 2)
        u = np.array([math.cos(axis), math.sin(axis)])
        c1 = middle - u * (r1 + gap * pitch / 2)
        c2 = middle + u * (r2 + gap * pitch / 2)
        return [(shape(), c1, r1, force(), 0.3, axis),
                (shape(), c2, r2, force(), 0.3, math.remainder(axis + math.pi, 2 * math.pi))], gap
    if kind == "beside":
        # a light broad load (flat punch or Hertz) beside a sharp one (a cone): a palm or a flat
        # object beside a fingertip, whose nodes each carry a small part of the cone's peak node
        for _ in range(1000):
            sharp, broad = radius(), rng.uniform(2.0, 3.5) * pitch
            gap = rng.uniform(1.0, 5.0) * pitch
            first = rng.uniform(-half + sharp + pitch / 2, half - sharp - pitch / 2, 2)
            towards = angle()
            second = first + (sharp + gap + broad) * np.array([math.cos(towards), math.sin(towards)])
            if np.all(np.abs(second) <= half - broad - pitch / 2):
                ratio = lambda: _RATIOS[rng.integers(len(_RATIOS))]  # noqa: E731
                light = ("flat_punch", "hertz")[rng.integers(2)]
                return [("cone", first, sharp, rng.uniform(0.8, 1.2), ratio(), angle()),
                        (light, second, broad, rng.uniform(0.3, 0.7), ratio(), angle())], gap / pitch
        raise RuntimeError("no beside scene fits the skin")  # pragma: no cover - 1000 draws never all fail
    count = 3 if kind == "three" else 2
    for _ in range(1000):
        radii = [radius() for _ in range(count)]
        if kind == "edge":
            # the first contact's centre within a pitch of the border
            side = rng.integers(4)
            along, depth = rng.uniform(-half + 3 * pitch, half - 3 * pitch), half - rng.uniform(0, pitch)
            first = np.array([[depth, along], [-depth, along], [along, depth], [along, -depth]][side])
        else:
            first = rng.uniform(-half + radii[0] + pitch, half - radii[0] - pitch, 2)
        centres = [first]
        for r in radii[1:]:
            # the next one at a gap of 1 to 8 pitches from one already placed
            anchor = rng.integers(len(centres))
            gap = rng.integers(1, 9) * pitch
            direction = angle()
            centres.append(centres[anchor] + (radii[anchor] + gap + r) * np.array(
                [math.cos(direction), math.sin(direction)]))
        inside = all(np.all(np.abs(c) <= half - (0 if kind == "edge" and k == 0 else r + pitch / 2))
                     for k, (c, r) in enumerate(zip(centres, radii, strict=True)))
        gaps = [np.linalg.norm(centres[i] - centres[j]) - radii[i] - radii[j]
                for i in range(count) for j in range(i + 1, count)]
        if inside and min(gaps) >= 0.99 * pitch:
            return [(shape(), c, r, force(), _RATIOS[rng.integers(len(_RATIOS))], angle())
                    for c, r in zip(centres, radii, strict=True)], min(gaps) / pitch
    raise RuntimeError(f"no {kind} scene fits the skin")  # pragma: no cover - 1000 draws never all fail


def scene_cases(*, seed: int = VALIDATION_SEED, noise: float = 0.01, kinds=STANDARD_KINDS, repeats: int = 3,
                thickness_ratios=(0.5, 1.0, 1.5), n: int = 16, pitch: float = 1.5e-3,
                poisson_ratio: float = 0.49) -> list[ContactScene]:
    """Scenes of every kind on an ``n x n`` skin of the bonded layer.

    Parameters
    ----------
    seed : int, optional
        The set: :data:`TUNING_SEED` or :data:`VALIDATION_SEED` (default).
    noise : float, optional
        Sensor noise relative to the peak clean stress. Default 0.01.
    kinds : sequence of str, optional
        Any of :data:`KINDS`. Default :data:`STANDARD_KINDS`.
    repeats : int, optional
        Scenes of each kind per thickness. Default 3.
    thickness_ratios : sequence of float, optional
        Layer thickness over pitch. Default 0.5, 1 and 1.5.
    n, pitch, poisson_ratio : optional
        The skin: 16 x 16, 1.5 mm, 0.49.

    Returns
    -------
    list of ContactScene
    """
    for kind in kinds:
        one_of("kinds", kind, KINDS)
    real_number("noise", noise, rule="finite and >= 0", valid=lambda v: math.isfinite(v) and v >= 0)
    # seed fixed: every run scores the very same frames
    rng = np.random.default_rng(seed)
    half = (n - 1) / 2 * pitch
    scenes = []
    for ratio_h in thickness_ratios:
        grid = SensorGrid.regular(n, n, pitch, ratio_h * pitch, poisson_ratio=poisson_ratio)
        for kind in kinds:
            for _ in range(repeats):
                placed, gap = _place(kind, pitch, half, rng)
                contacts = [_contact(*p) for p in placed]
                frame = loads.simulate(grid, contacts, noise=noise, rng=rng)
                truths = tuple(loads.simulate(grid, c).forces for c in contacts)
                name = f"{kind} h/p={ratio_h:g} gap={gap:.1f}"
                scenes.append(ContactScene(name, kind, ratio_h, gap, frame, truths))
    return scenes


def _owners(grid, truths):
    # the true contact each node's force counts for: the one loading it most, else the nearest load
    magnitude = np.array([np.linalg.norm(t, axis=1) for t in truths])  # (K, m)
    owner = np.argmax(magnitude, axis=0)
    free = magnitude.max(axis=0) <= 1e-9 * magnitude.max()
    if free.any():
        distance = np.full((len(truths), grid.size), np.inf)
        for k in range(len(truths)):
            loaded = magnitude[k] > 1e-9 * magnitude.max()
            distance[k] = cKDTree(grid.positions[loaded]).query(grid.positions)[0]
        owner[free] = np.argmin(distance[:, free], axis=0)
    return owner


def evaluate(scenes, make_solver=None, *, solve=None, bounds: bool = True) -> list[dict]:
    """Score every contact of every scene on its own.

    Parameters
    ----------
    scenes : list of ContactScene
    make_solver : callable, optional
        ``grid -> solver`` (once per distinct grid). Default the
        :class:`~solver.Reconstructor` of the grid.
    solve : callable, optional
        ``(solver, stress) -> Reconstruction``; default ``solver.solve(stress)``.
    bounds : bool, optional
        Also give each contact's figures at its Cramér-Rao bound (all the
        frame's contacts estimated at once: :func:`measurement.bounds.contact_bounds`):
        the miss probability of the Wald test
        (false rate 3 of 20) and an unbiased estimate's median errors.
        Default True.

    Returns
    -------
    list of dict
        One row per true contact: the scene, the true and reconstructed shear,
        the tangential error over ``|F|``, the direction error (degrees, true
        ratio >= 0.2), the normal total error, ``ms`` and ``cpu_ms`` of the
        solve, the shear evidence ``F`` of the reconstructed contact it is
        matched to (nan when none), and at the bound (nan when ``bounds`` is False): the Wald
        test's miss probability (``bound_miss``) and an unbiased estimate's
        median errors (``bound_tangential``, ``bound_direction``).
    """
    make_solver = make_solver or Reconstructor
    solve = solve or (lambda s, b: s.solve(b))
    made, rows = {}, []
    for scene in scenes:
        grid = scene.frame.grid
        if grid.key not in made:
            made[grid.key] = make_solver(grid)
        solver = made[grid.key]
        start, cpu = time.perf_counter(), time.process_time()
        result = solve(solver, scene.frame.stress)
        ms, cpu_ms = (time.perf_counter() - start) * 1e3, (time.process_time() - cpu) * 1e3
        owner = _owners(grid, scene.truths)
        at_bound = _at_bound(scene) if bounds else [(math.nan,) * 3] * len(scene.truths)
        for k, truth in enumerate(scene.truths):
            contact = scene.frame.contacts[k]
            mine = owner == k
            total, true_total = result.forces[mine].sum(axis=0), truth.sum(axis=0)
            size = float(np.linalg.norm(true_total))
            # the reconstructed contact carrying most of this one's nodes' normal force
            carried = [float(np.clip(result.forces[c.nodes & mine, 2], 0, None).sum())
                       for c in result.contacts]
            found = result.contacts[int(np.argmax(carried))] if carried and max(carried) > 0 else None
            ratio = found.shear_ratio if found is not None else 0.0
            turn = math.atan2(total[1], total[0]) - math.atan2(true_total[1], true_total[0])
            rows.append(dict(
                case=scene.name, kind=scene.kind, thickness_ratio=scene.thickness_ratio, gap=scene.gap,
                contact=k, true_ratio=contact.shear_ratio, ratio=ratio,
                true_direction=math.degrees(contact.shear_direction),
                direction=math.degrees(found.shear_direction) if found is not None else math.nan,
                tangential_total=float(np.linalg.norm(total[:2] - true_total[:2])) / size,
                direction_deg=(abs(math.degrees(math.remainder(turn, 2 * math.pi)))
                               if contact.shear_ratio > 0 else math.nan),
                normal_total=abs(total[2] - true_total[2]) / true_total[2],
                evidence=found.evidence if found is not None else math.nan,
                contacts_found=len(result.contacts), bound_miss=at_bound[k][0],
                bound_tangential=at_bound[k][1], bound_direction=at_bound[k][2], ms=ms, cpu_ms=cpu_ms))
    return rows


def _at_bound(scene):
    # each contact at its Cramer-Rao bound (every contact's profile and the other contacts' shears
    # estimated from the same data: measurement.bounds.contact_bounds): the Wald test's miss
    # probability (nan without shear) and an unbiased estimate's median tangential and direction
    # errors (measurement.bounds.ShearBound.ideal_errors)
    frame = scene.frame
    if not frame.noise > 0:
        return [(0.0 if c.shear_ratio > 0 else math.nan, 0.0, 0.0 if c.shear_ratio > 0 else math.nan)
                for c in frame.contacts]
    out = []
    for contact, bound in zip(frame.contacts, _bounds(scene), strict=True):
        miss = bound.miss(false_rate=_FALSE_RATE) if contact.shear_ratio > 0 else math.nan
        out.append((miss, *bound.ideal_errors()))
    return out


def _bounds(scene):
    # every contact's bound, all estimated at once (measurement.bounds.contact_bounds); each contact's
    # own load was simulated alone when the scene was made: not simulated again
    return contact_bounds(scene.frame, totals=[truth[:, 2].sum() for truth in scene.truths])


def summarize(rows) -> dict:
    """Medians and counts over the contacts of a set.

    ``tangential`` and ``direction`` are medians (direction over true ratio >=
    0.2); ``false`` counts shear-free contacts given shear, ``missed`` contacts
    of true ratio >= 0.2 given none; ``bound_missed`` is the expected count the
    Wald test at the bound misses, ``bound_tangential`` and ``bound_direction``
    the medians of an unbiased estimate at the bound (every contact's
    profile and the other shears estimated with it: what the data allow);
    ``pinch_tangential`` the median over the pinches' contacts and
    ``pinch_zero`` how many of them got no shear.
    """
    free = [r for r in rows if r["true_ratio"] == 0]
    sheared = [r for r in rows if r["true_ratio"] >= 0.2]
    pinch = [r for r in rows if r["kind"] == "pinch"]
    median = lambda values: float(np.median(values)) if values else math.nan  # noqa: E731
    return dict(
        contacts=len(rows), tangential=median([r["tangential_total"] for r in rows]),
        direction=median([r["direction_deg"] for r in sheared]),
        normal=median([r["normal_total"] for r in rows]),
        false=sum(r["ratio"] > 0 for r in free), free=len(free),
        missed=sum(r["ratio"] == 0 for r in sheared), sheared=len(sheared),
        bound_missed=float(np.nansum([r["bound_miss"] for r in sheared])),
        bound_tangential=median([r["bound_tangential"] for r in rows]),
        bound_direction=median([r["bound_direction"] for r in sheared]),
        pinch_tangential=median([r["tangential_total"] for r in pinch]),
        pinch_zero=sum(r["ratio"] == 0 for r in pinch), pinches=len(pinch),
        cpu_ms=median([r["cpu_ms"] for r in rows]),
        cpu_p95=float(np.percentile([r["cpu_ms"] for r in rows], 95)) if rows else math.nan)


_ROWS = (
    Column("case", 26, value("case"), align="<"),
    Column("k", 2, value("contact")),
    Column("mu", 5, value("true_ratio", ".2f")),
    Column("mu est", 6, value("ratio", ".2f")),
    Column("tangential %", 12, lambda r: f"{100 * r['tangential_total']:.1f}"),
    Column("dir deg", 7, value("direction_deg", ".1f")),
    Column("bound %", 7, lambda r: f"{100 * r['bound_tangential']:.1f}"),
    Column("normal %", 8, lambda r: f"{100 * r['normal_total']:.2f}"),
    Column("found", 5, value("contacts_found")),
    Column("CPU ms", 7, value("cpu_ms", ".2f")),
)


def format_scenes(rows) -> str:
    """One line per contact."""
    return format_table(rows, _ROWS)


def format_summary(summary: dict) -> str:
    """The medians and counts of :func:`summarize`, one line each."""
    s = summary
    return "\n".join([
        f"contacts: {s['contacts']}",
        f"tangential (median, % of |F|): {100 * s['tangential']:.1f}" + (
            "" if math.isnan(s["bound_tangential"]) else
            f"  (an unbiased estimate at the bound: {100 * s['bound_tangential']:.1f})"),
        f"direction (median, deg, ratio >= 0.2): {s['direction']:.1f}" + (
            "" if math.isnan(s["bound_direction"]) else f"  (at the bound: {s['bound_direction']:.1f})"),
        f"normal total (median, %): {100 * s['normal']:.2f}",
        f"shear on shear-free: {s['false']} of {s['free']}",
        f"missed (ratio >= 0.2): {s['missed']} of {s['sheared']}  "
        f"(Wald test at the bound, false rate 3/20: {s['bound_missed']:.1f} expected)",
        f"pinches: tangential {100 * s['pinch_tangential']:.1f}% median, "
        f"no shear on {s['pinch_zero']} of {s['pinches']}",
        f"solve CPU ms: median {s['cpu_ms']:.2f}, p95 {s['cpu_p95']:.2f}",
    ])


def decision_curve(scenes, *, shrinkages=(1.0, 1.5, 2.0, 3.0, 4.0, 6.0)) -> list[dict]:
    """How the shear decision trades false for missed shear on scenes of several contacts.

    A contact keeps shear exactly when its evidence ``F`` exceeds the
    shrinkage ``c`` (:class:`~solver.efficiency.ContactFit`). Unlike a lone
    contact's, the evidence of contacts that share sensors depends on ``c``
    itself (which of them have their own gain refitted), so every scene is
    solved again with each ``c``. Beside each count: the Wald test at the
    Cramér-Rao bound at the false rate the solver reached
    (:func:`measurement.bounds.contact_bounds`; one free force per node,
    support known), and the median ``F`` of the shear-free contacts (a
    calibrated ``F`` with two parameters has a median of about 0.7 and
    exceeds 2 on about 13% of them).

    Parameters
    ----------
    scenes : list of ContactScene
        With noise (the bound scales with it).
    shrinkages : sequence of float, optional
        The shrinkages ``c`` scored, each > 0.

    Returns
    -------
    list of dict
        Per shrinkage: ``false`` of ``free`` (shear-free contacts given
        shear), ``missed`` of ``sheared`` (ratio >= 0.2 given none),
        ``bound_missed`` (the expected count the Wald test at the bound misses
        at the false rate ``false / free``, kept within half a contact of 0 and 1) and
        ``free_evidence`` (the median ``F`` of the shear-free contacts).

    Raises
    ------
    ValueError
        For no scenes, a scene without noise, or no shrinkage or one not > 0.
    """
    scenes = list(scenes)
    if not scenes:
        raise ValueError("scenes must hold at least one scene, got none")
    if not all(scene.frame.noise > 0 for scene in scenes):
        raise ValueError("scenes must have noise > 0 (the bound scales with it), got a noise-free scene")
    shrinkages = [real_number("shrinkages", c, rule="> 0", valid=lambda v: v > 0) for c in shrinkages]
    if not shrinkages:
        raise ValueError("shrinkages must hold at least one shrinkage, got none")
    # the bound of every contact once: the Wald test's miss at any false rate comes from it
    bounds = [bound for scene in scenes for bound in _bounds(scene)]
    out = []
    for c in shrinkages:
        rows = evaluate(scenes, lambda grid, c=c: Reconstructor(grid, efficiency=ContactFit(shrinkage=c)),
                        bounds=False)
        counts = {key: value for key, value in summarize(rows).items() if key in ("false", "free", "missed",
                                                                                  "sheared")}
        false, free = counts["false"], counts["free"]
        rate = min(max(false, 0.5), free - 0.5) / free if free else math.nan
        out.append(dict(
            shrinkage=c, **counts,
            bound_missed=float(sum(b.miss(false_rate=rate) for r, b in zip(rows, bounds, strict=True)
                                   if r["true_ratio"] >= 0.2)) if free else math.nan,
            free_evidence=float(np.median([r["evidence"] for r in rows if r["true_ratio"] == 0]))
            if free else math.nan))
    return out


def format_decision_curve(curve) -> str:
    """The rows of :func:`decision_curve`, one line per shrinkage."""
    return format_table(curve, (
        Column("c", 4, value("shrinkage", "g")),
        Column("shear on shear-free", 19, lambda r: f"{r['false']} of {r['free']}", gap=2),
        Column("missed", 10, lambda r: f"{r['missed']} of {r['sheared']}", gap=2),
        Column("Wald test at the bound: missed", 30, value("bound_missed", ".1f"), gap=2),
        Column("median F, shear-free", 20, value("free_evidence", ".2f"), gap=2)))


def main(argv=None):
    """``python -m measurement.scenes [--set tuning|validation] [--noise N] [--kinds ...] [--seeds ...]
    [--decision-curve]``."""
    parser = argparse.ArgumentParser(prog="python -m measurement.scenes",
                                     description="Per-contact accuracy on scenes of several contacts.")
    parser.add_argument("--set", choices=("validation", "tuning"), default="validation",
                        help="validation (seed 41, nothing tuned on it; default) or tuning (seed 5)")
    parser.add_argument("--noise", type=float, default=0.01,
                        help="relative to the peak stress (default 0.01)")
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(STANDARD_KINDS),
                        help=f"default {' '.join(STANDARD_KINDS)}")
    parser.add_argument("--repeats", type=int, default=3, help="scenes of each kind per thickness")
    parser.add_argument("--quiet", action="store_true", help="the summary only")
    parser.add_argument("--decision-curve", action="store_true",
                        help="false against missed shear for each shrinkage c (every scene solved again "
                             "with each), beside the Wald test at the Cramer-Rao bound at the same false "
                             "rate")
    parser.add_argument("--seeds", type=int, nargs="+", metavar="SEED",
                        help="the scenes of these seeds instead of the set's (for --decision-curve over "
                             "more scenes than one set holds)")
    args = parser.parse_args(argv)
    if args.decision_curve and not args.noise > 0:
        parser.error("--decision-curve needs --noise > 0 (the bound scales with it)")
    seeds = args.seeds or [VALIDATION_SEED if args.set == "validation" else TUNING_SEED]
    scenes = [scene for seed in seeds
              for scene in scene_cases(seed=seed, noise=args.noise, kinds=args.kinds, repeats=args.repeats)]
    name = f"{args.set} set (seed {seeds[0]})" if not args.seeds else f"seeds {' '.join(map(str, seeds))}"
    if args.decision_curve:
        print(f"shear decision, {name}: {len(scenes)} scenes, noise {args.noise:g}; shear kept when F > c "
              f"(default c = {ContactFit().shrinkage:g})")
        print(format_decision_curve(decision_curve(scenes)))
        return
    rows = evaluate(scenes, bounds=args.noise > 0)
    print_report(format_scenes(rows), f"{name}, noise {args.noise:g}",
                 format_summary(summarize(rows)), quiet=args.quiet)


if __name__ == "__main__":
    main()

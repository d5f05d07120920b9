"""One contact squeezed or stretched: does the data show its halves' opposite shears?

A finger that squeezes the skin under it (or stretches it) loads one connected patch whose two
halves shear towards each other (or apart). No pair (ratio, direction) describes that: the
template's one pair per contact cancels to no shear at all. The solver represents such a load
as two contacts, each with its own pair, where it halves an elongated contact across its long
axis and the split test keeps the halves (:func:`solver.search.halved_labels`,
:meth:`solver.inverse.DenseSolver.split_statistic`); a round contact is never tried halved.

:func:`squeeze_cases` makes such frames with the layer's physics (:func:`solver.loads.simulate`,
the load's ``squeeze``, independent of the reconstruction kernels): round Hertz contacts, and
elliptical ones twice as long as wide along the squeeze or across it, squeezed (0.3 each way),
stretched (-0.3) or neither (the control). :func:`evaluate` scores, per frame:

- what the solver reports: contacts found, and whether two of them shear towards each other (away
  for a stretch) along the squeeze's axis;
- the split test's statistic for the contact halved across the squeeze's own axis (an oracle: the
  true axis, which the solver does not know), against the level the solver keeps a split at.
  Where even that does not reach the level, the two-pair template cannot tell the squeeze from
  no squeeze in this frame's data; where it does and the solver reports one contact, a template
  with more parameters could.

``python -m measurement.squeeze [--noise N] [--seed S]`` prints the table and the counts per
shape. Nothing is tuned on these frames.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from solver import loads
from solver.checks import real_number
from solver.geometry import SensorGrid
from solver.inverse import DenseSolver

from .tables import Column, format_table, print_report, value

__all__ = ["SqueezeCase", "SHAPES", "SQUEEZES", "squeeze_cases", "evaluate", "summarize", "format_cases",
           "format_summary", "main"]

SHAPES = ("round", "long", "wide")  # Hertz; an ellipse 2:1 along the squeeze's axis; across it
SQUEEZES = (0.3, -0.3, 0.0)  # squeezed, stretched, neither
SEED = 61


@dataclass(frozen=True)
class SqueezeCase:
    """One simulated frame of one squeezed (or stretched) contact.

    Attributes
    ----------
    name : str
        For tables ("long h/p=1 squeeze=0.3").
    shape : str
        One of :data:`SHAPES`.
    squeeze : float
        Tangential over normal traction of each half towards the other (negative: apart).
    axis : float
        The squeeze's axis, radians from +x.
    frame : solver.loads.SimulatedFrame
    """

    name: str
    shape: str
    squeeze: float
    axis: float
    frame: loads.SimulatedFrame


def squeeze_cases(*, seed: int = SEED, noise: float = 0.01, repeats: int = 2,
                  thickness_ratios=(0.5, 1.0, 1.5), n: int = 16, pitch: float = 1.5e-3,
                  poisson_ratio: float = 0.49) -> list[SqueezeCase]:
    """Squeezed, stretched and plain contacts of every shape on an ``n x n`` skin of the bonded layer.

    Each: centre within 1.5 pitches of the skin's middle, the longer semi-axis 2.5 to 3.5 pitches,
    0.6 to 1.2 N, the squeeze's axis in any direction, no shear.

    Parameters
    ----------
    seed : int, optional
        Default :data:`SEED`. Fixed: every run scores the very same frames.
    noise : float, optional
        Sensor noise relative to the peak clean stress. Default 0.01.
    repeats : int, optional
        Frames of each shape and squeeze per thickness. Default 2.
    thickness_ratios : sequence of float, optional
        Layer thickness over pitch. Default 0.5, 1 and 1.5.
    n, pitch, poisson_ratio : optional
        The skin: 16 x 16, 1.5 mm, 0.49.

    Returns
    -------
    list of SqueezeCase
    """
    real_number("noise", noise, rule="finite and >= 0", valid=lambda v: math.isfinite(v) and v >= 0)
    rng = np.random.default_rng(seed)
    cases = []
    for ratio_h in thickness_ratios:
        grid = SensorGrid.regular(n, n, pitch, ratio_h * pitch, poisson_ratio=poisson_ratio)
        for shape in SHAPES:
            for squeeze in SQUEEZES:
                for _ in range(repeats):
                    axis = rng.uniform(-math.pi, math.pi)
                    centre = tuple(rng.uniform(-1.5, 1.5, 2) * pitch)
                    length, force = rng.uniform(2.5, 3.5) * pitch, rng.uniform(0.6, 1.2)
                    kw = dict(squeeze=squeeze, squeeze_direction=axis)
                    if shape == "round":
                        load = loads.hertz(centre, length, force, **kw)
                    else:  # the long semi-axis along the squeeze's axis, or across it
                        angle = axis if shape == "long" else axis + math.pi / 2
                        load = loads.ellipse(centre, (length, length / 2), force, angle=angle, **kw)
                    frame = loads.simulate(grid, load, noise=noise, rng=rng)
                    name = f"{shape} h/p={ratio_h:g} squeeze={squeeze:g}"
                    cases.append(SqueezeCase(name, shape, squeeze, axis, frame))
    return cases


def _halves_shear_right(result, case) -> bool:
    # two contacts, each sheared (ratio > 0.1) within 45 deg of towards the other along the axis
    # (away from it for a stretch)
    if len(result.contacts) != 2 or case.squeeze == 0:
        return False
    u = np.array([math.cos(case.axis), math.sin(case.axis)])
    first, second = sorted(result.contacts, key=lambda c: float(c.centre @ u))
    sign = 1.0 if case.squeeze > 0 else -1.0
    return all(c.shear_ratio > 0.1
               and sign * side * math.cos(c.shear_direction - case.axis) > math.cos(math.pi / 4)
               for c, side in ((first, 1.0), (second, -1.0)))


def evaluate(cases, *, solvers=None) -> list[dict]:
    """Per case: ``found`` (contacts), ``halves`` (two contacts shearing as the load does),
    ``ratio`` (the largest contact's), ``statistic`` (the split test's F for the contact halved
    across the true axis through its centre of normal-only load; nan where not comparable) and
    ``kept_at`` (the level a split is kept at)."""
    solvers = {} if solvers is None else solvers
    rows = []
    for case in cases:
        grid = case.frame.grid
        if grid.key not in solvers:
            solvers[grid.key] = DenseSolver(grid)
        solver = solvers[grid.key]
        result = solver.solve(case.frame.stress)
        statistic = math.nan
        if len(result.contacts) == 1:
            # the oracle's halves: the contact's nodes cut across the squeeze's true axis through
            # their centre of normal-only load
            nodes = result.contacts[0].nodes
            normal = np.clip(solver.solve_normal(case.frame.stress).forces[:, 2], 0, None) * nodes
            if normal.sum() > 0:
                centre = normal @ grid.positions / normal.sum()
                u = np.array([math.cos(case.axis), math.sin(case.axis)])
                labels = nodes.astype(np.int64)
                labels[nodes & ((grid.positions - centre) @ u > 0)] = 2
                statistic = solver.split_statistic(case.frame.stress, labels)
        rows.append(dict(case=case.name, shape=case.shape, squeeze=case.squeeze, found=len(result.contacts),
                         halves=_halves_shear_right(result, case), ratio=result.contacts[0].shear_ratio
                         if result.contacts else math.nan, statistic=statistic,
                         kept_at=solver.efficiency.min_split_evidence))
    return rows


def summarize(rows) -> dict:
    """Per shape: ``squeezed`` frames (squeeze or stretch), ``halves`` of them the solver reports
    as two contacts shearing as the load does, ``detectable`` of them whose oracle statistic reaches
    the level kept at (or which the solver split already), and ``split_plain`` plain contacts (no
    squeeze) the solver reports as more than one."""
    out = {}
    for shape in SHAPES:
        mine = [r for r in rows if r["shape"] == shape]
        squeezed = [r for r in mine if r["squeeze"] != 0]
        out[shape] = dict(
            squeezed=len(squeezed), halves=sum(r["halves"] for r in squeezed),
            detectable=sum(r["found"] == 2 or r["statistic"] >= r["kept_at"] for r in squeezed),
            plain=len(mine) - len(squeezed),
            split_plain=sum(r["found"] > 1 for r in mine if r["squeeze"] == 0))
    return out


_ROWS = (
    Column("case", 27, value("case"), align="<"),
    Column("found", 5, value("found")),
    Column("two halves", 10, lambda r: "yes" if r["halves"] else "no"),
    Column("ratio", 5, value("ratio", ".2f")),
    Column("F halved on the true axis", 25, value("statistic", ".1f")),
)


def format_cases(rows) -> str:
    """One line per frame."""
    return format_table(rows, _ROWS)


def format_summary(summary: dict) -> str:
    """The counts of :func:`summarize`, one line per shape."""
    return "\n".join(
        f"{shape}: squeezed or stretched {s['squeezed']}: reported as two halves shearing so {s['halves']}, "
        f"the data tell it with two pairs (F halved on the true axis >= the split level) {s['detectable']}; "
        f"plain contacts split {s['split_plain']} of {s['plain']}" for shape, s in summary.items())


def main(argv=None):
    """``python -m measurement.squeeze [--noise N] [--seed S] [--quiet]``."""
    parser = argparse.ArgumentParser(prog="python -m measurement.squeeze",
                                     description="Squeezed and stretched contacts: what the solver reports, "
                                                 "what the data hold.")
    parser.add_argument("--noise", type=float, default=0.01,
                        help="relative to the peak stress (default 0.01)")
    parser.add_argument("--seed", type=int, default=SEED, help=f"the frames (default {SEED})")
    parser.add_argument("--quiet", action="store_true", help="the summary only")
    args = parser.parse_args(argv)
    rows = evaluate(squeeze_cases(seed=args.seed, noise=args.noise))
    print_report(format_cases(rows), f"seed {args.seed}, noise {args.noise:g}",
                 format_summary(summarize(rows)), quiet=args.quiet)


if __name__ == "__main__":
    main()

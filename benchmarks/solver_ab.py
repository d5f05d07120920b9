"""The solver of the working tree against the solver of a commit, timed in one process:
``python -m benchmarks.solver_ab REV [--contacts 1 2 3] [--frames 20] [--rounds 5] [--given] [--moving]``.

On a shared virtual machine two runs of the same code a few minutes apart differ
by up to a quarter (``docs/efficiency.md``), more than most speed changes. So a
change is timed against the code before it in one process, solve by solve: the
``solver`` package of commit ``REV`` (``git archive``, kept in the temporary
folder under its commit id, so its numba cache survives between runs) is loaded
beside the working tree's under another name, each builds its own
:class:`solver.Reconstructor` of the bench's skin, and both solve the same
frames (:func:`measurement.bench.contact_frames`: one, two and three contacts on
16x16 at 1% noise; with ``--moving`` the same kinds of contacts in motion, frames in
order as playback and a live board give them,
:func:`measurement.bench.moving_contact_frames`) in rounds over all frames, alternating which goes first
from frame to frame, so that a hiccup of the machine falls on both alike.

Prints per contact count the CPU time per automatic solve (or per solve at
given parameters, ``--given``), median and 95th percentile, of each, the ratio
of the medians and the median of the per-solve ratios (this tree's over the
commit's, each frame and round paired), and how far apart the two answers'
forces are (relative to the frame's largest force): a speed change that changes
the answers says so here.

Needs ``git`` and the repository this tree is in. One untimed round first
(numba compiles the commit's package on its first run: a minute).
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

from measurement.bench import contact_frames, moving_contact_frames
from measurement.timing import machine

__all__ = ["solver_at", "paired_times", "compare", "main"]

ROOT = Path(__file__).resolve().parents[1]


def solver_at(revision: str, *, root=ROOT, cache=None):
    """The ``solver`` package of a commit, imported as ``solver_<commit id>``.

    Parameters
    ----------
    revision : str
        Anything ``git rev-parse`` takes (``HEAD~1``, a branch, a commit id).
    root : path-like
        The repository. Default: the one this file is in.
    cache : path-like or None
        Where the commit's files are kept (``<cache>/<commit id>/solver``);
        default the temporary folder's ``tactile-solver-ab``.

    Returns
    -------
    module
        The package; its ``__file__`` lies under ``cache``.

    Raises
    ------
    ValueError
        When ``revision`` is not a commit of the repository, or the commit has
        no ``solver`` package.
    """
    found = subprocess.run(["git", "-C", str(root), "rev-parse", "--verify", "--quiet",
                            f"{revision}^{{commit}}"], capture_output=True, text=True)
    if found.returncode != 0:
        raise ValueError(f"revision must name a commit of {root}, got {revision!r}")
    commit = found.stdout.strip()
    folder = Path(cache if cache is not None else Path(tempfile.gettempdir()) / "tactile-solver-ab") / commit
    if not (folder / "solver" / "__init__.py").is_file():
        archive = subprocess.run(["git", "-C", str(root), "archive", "--format=tar", commit, "solver"],
                                 capture_output=True)
        if archive.returncode != 0:
            raise ValueError(f"commit {commit[:12]} has no solver package: {archive.stderr.decode().strip()}")
        folder.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(folder, filter="data")
    name = f"solver_{commit[:12]}"
    if name in sys.modules:
        return sys.modules[name]
    # the package's own imports are relative: under this name it is a package of its own
    spec = importlib.util.spec_from_file_location(name, folder / "solver" / "__init__.py",
                                                  submodule_search_locations=[str(folder / "solver")])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def paired_times(solve_a, solve_b, items, rounds):
    """CPU seconds of ``solve_a(item)`` and ``solve_b(item)``, every item in every round, alternating.

    Within a round each goes through the items in order (as a recording plays:
    each solve follows that solver's solve of the item before); which of the two
    solves an item first alternates from item to item and round to round.

    Returns
    -------
    a, b : (rounds, len(items)) ndarray
        Process CPU seconds of each solve.
    answers : list of (result_a, result_b)
        The first round's results, per item.
    """
    a = np.empty((rounds, len(items)))
    b = np.empty((rounds, len(items)))
    answers = []
    for run in range(rounds):
        for k, item in enumerate(items):
            order = ((a, solve_a), (b, solve_b)) if (run + k) % 2 == 0 else ((b, solve_b), (a, solve_a))
            pair = {}
            for times, solve in order:
                start = time.process_time()
                pair[id(times)] = solve(item)
                times[run, k] = time.process_time() - start
            if run == 0:
                answers.append((pair[id(a)], pair[id(b)]))
    return a, b, answers


def compare(tree, base, *, contacts=(1, 2, 3), frames=20, rounds=5, given=False, moving=False, label="base",
            out=None):
    """Time two solver packages on the bench's frames, alternating (module notes); print a line per count.

    Parameters
    ----------
    tree, base : module
        Two ``solver`` packages (this tree's, and :func:`solver_at`'s).
    moving : bool
        The frames of contacts in motion, in order (:func:`~measurement.bench.moving_contact_frames`)
        instead of unrelated ones.
    label : str
        How ``base`` is named in the lines.

    Returns
    -------
    dict of int to dict
        Per contact count: ``tree`` and ``base`` (CPU ms, every solve), ``ratio``
        (of the medians), ``paired`` (median of the per-solve ratios) and
        ``apart`` (the answers' largest force difference over the peak force).
    """
    out = sys.stdout if out is None else out
    parameters = dict(shear_ratio=0.3, shear_direction=np.radians(30.0)) if given else {}
    results = {}
    for count in contacts:
        grid, stress = (moving_contact_frames if moving else contact_frames)(count, frames)
        skin = dict(nx=grid.shape[1], ny=grid.shape[0], pitch=grid.pitch, thickness=grid.thickness,
                    poisson_ratio=grid.poisson_ratio)  # each package's own SensorGrid, of the same skin
        ours = tree.Reconstructor(tree.SensorGrid.regular(**skin))
        theirs = base.Reconstructor(base.SensorGrid.regular(**skin))

        def solve_ours(b, solver=ours):
            return solver.solve(b, **parameters)

        def solve_theirs(b, solver=theirs):
            return solver.solve(b, **parameters)
        paired_times(solve_ours, solve_theirs, stress, 1)  # untimed: compilation, caches
        a, b, answers = paired_times(solve_ours, solve_theirs, stress, rounds)
        apart = max(float(np.max(np.abs(x.forces - y.forces)) / max(np.max(np.abs(y.forces)), 1e-300))
                    for x, y in answers)
        a_ms, b_ms = 1e3 * a.ravel(), 1e3 * b.ravel()
        results[count] = dict(tree=a_ms, base=b_ms, ratio=float(np.median(a_ms) / np.median(b_ms)),
                              paired=float(np.median(a_ms / b_ms)), apart=apart)
        print(f"{count} contact{'s' if count > 1 else ' '}: this tree median {np.median(a_ms):.3f} "
              f"p95 {np.percentile(a_ms, 95):.3f}; {label} median {np.median(b_ms):.3f} "
              f"p95 {np.percentile(b_ms, 95):.3f}; ratio of medians {results[count]['ratio']:.3f}, "
              f"median paired ratio {results[count]['paired']:.3f}; forces apart at most {apart:.1e} "
              "of the peak", file=out, flush=True)
    return results


def _parser():
    parser = argparse.ArgumentParser(prog="python -m benchmarks.solver_ab",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("revision", metavar="REV", help="the commit to compare with (HEAD: the last commit)")
    parser.add_argument("--contacts", type=int, nargs="+", default=[1, 2, 3], choices=[1, 2, 3],
                        help="contacts per frame, each count timed on its own frames (default 1 2 3)")
    parser.add_argument("--frames", type=int, default=20, help="frames per contact count (default 20)")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds over all frames (default 5)")
    parser.add_argument("--given", action="store_true",
                        help="solve at given parameters (ratio 0.3, direction 30 deg) instead of automatic")
    parser.add_argument("--moving", action="store_true",
                        help="contacts in motion, frames solved in order (as playback and a live board)")
    return parser


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.frames < 1 or args.rounds < 1:
        parser.error(f"--frames and --rounds must be at least 1, got {args.frames} and {args.rounds}")
    try:
        base = solver_at(args.revision)
    except ValueError as exc:
        parser.error(str(exc))
    import solver as tree

    kind = "solve at given parameters" if args.given else "automatic solve"
    frames = "frames of contacts in motion, in order" if args.moving else "frames"
    print(f"machine: {machine()}")
    print(f"this tree's solver ({Path(tree.__file__).parent}) against {args.revision} ({base.__name__}), "
          f"CPU ms per {kind}, {args.rounds} rounds of {args.frames} {frames}, alternating:", flush=True)
    compare(tree, base, contacts=args.contacts, frames=args.frames, rounds=args.rounds, given=args.given,
            moving=args.moving, label=args.revision)
    return 0


if __name__ == "__main__":
    sys.exit(main())

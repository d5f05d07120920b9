"""Solver benchmarks: ``python -m solver.bench`` (``make bench``).

Prints, for every kernel, the median per-frame ``solve`` time, wall and CPU,
on an n x n skin (default 16; automatic parameters cold, after another frame
and in playback, given parameters, a slider move, normal only) beside the
dense-product floor measured in the same run, and the set-up time of
:class:`solver.Reconstructor` for larger grids against ``numpy.linalg.pinv``
of the same ``(m, 3m)`` matrix, as a ratio from the same run.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from . import layer, loads
from .geometry import SensorGrid
from .inverse import Reconstructor
from .kernels import KERNELS, stress_matrix

__all__ = ["machine", "fastest_in_rounds", "per_frame", "layer_tables", "setup", "main"]


def machine() -> str:
    """One line naming the machine a measurement ran on: CPU, cores, numpy, Python."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, numpy {np.__version__}, python {platform.python_version()}"


def _median_ms(fn, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def fastest_in_rounds(call, items, repeat, *, before=None):
    """Each item's fastest of ``repeat`` timed calls, wall and CPU, taken in rounds over all items.

    A round calls ``call(item)`` on every item in turn, so no call follows one
    on the same item (a solver keeps the last frame's work for slider moves);
    the fastest of the rounds is kept per item, since this machine is a shared
    VM whose hiccups would otherwise dominate.

    Parameters
    ----------
    call : callable
        ``item -> result``, the work timed.
    items : sequence
    repeat : int
        Rounds.
    before : callable, optional
        ``item -> None``, called before each timed call, not timed.

    Returns
    -------
    wall, cpu : (len(items),) ndarray
        Seconds.
    results : list
        What ``call`` returned for each item in the first round.
    """
    wall = np.full((repeat, len(items)), np.inf)
    cpu = np.full((repeat, len(items)), np.inf)
    results = []
    for run in range(repeat):
        for k, item in enumerate(items):
            if before is not None:
                before(item)
            start_cpu = time.process_time()
            start = time.perf_counter()
            result = call(item)
            wall[run, k] = time.perf_counter() - start
            cpu[run, k] = time.process_time() - start_cpu
            if run == 0:
                results.append(result)
    return wall.min(axis=0), cpu.min(axis=0), results


def per_frame(n=16, frames=40, kernel="layer", repeat=5):
    """Median over frames of the solve time on simulated Hertzian frames with 1% noise.

    Each frame's fastest of ``repeat`` solves is kept (:func:`fastest_in_rounds`).
    ``slider`` is a slider move: the frame just solved, solved again at
    parameters one step away. ``playback`` is the automatic solve of a
    recording's frames in order (a contact sliding 0.05 mm and turning its
    shear by 0.01 rad per frame, the same noise): each frame after the one
    before it, as in playback and live mode. ``cold`` is the automatic solve by
    a solver that has solved nothing before (the first frame after opening a
    recording): no last frame to start from.

    Parameters
    ----------
    n : int, optional
        The skin is ``n x n``, pitch and thickness 2 mm. Default 16.
    frames : int, optional
        Noisy frames per median. Default 40.
    kernel : {"layer", "cell", "point"}, optional
        Default "layer".
    repeat : int, optional
        Runs per frame, the fastest kept. Default 5.

    Returns
    -------
    dict of str to float
        Milliseconds, wall (``auto``, ``cold``, ``playback``, ``given``,
        ``slider``, ``normal`` and ``floor``, two dense ``(3m, m)``
        matrix-vector products) and CPU (the same keys ending ``_cpu``).
    """
    grid = SensorGrid.regular(n, n, 2e-3, 2e-3)
    rng = np.random.default_rng(0)  # fixed seed: the same frames every run
    stress = [loads.simulate(grid, loads.hertz(tuple(rng.uniform(-2e-3, 2e-3, 2)), 5e-3, 1.0,
                                               shear_ratio=0.3 * (k % 2), shear_direction=0.4 * k),
                             noise=0.01, rng=rng).stress for k in range(frames)]
    sliding = [loads.simulate(grid, loads.hertz((-1e-3 + 5e-5 * k, 0.5e-3), 5e-3, 1.0, shear_ratio=0.3,
                                                shear_direction=0.4 + 0.01 * k), noise=0.01, rng=rng).stress
               for k in range(frames)]
    r = Reconstructor(grid, kernel=kernel)
    matrix = np.ascontiguousarray(r.matrix.T)  # (768, 256) at 16x16

    def slider(b, step=[0]):  # noqa: B006 - a counter kept between calls
        step[0] += 1
        return r.solve(b, shear_ratio=0.3 + 0.01 * (step[0] % 2), shear_direction=0.5)

    fresh = [None]

    def forget(b):  # a solver sharing r's matrices that has solved nothing (not timed)
        fresh[0] = r.sibling()

    out = {}
    for label, call, before, sequence in (
            ("auto", lambda b: r.solve(b), None, stress),
            ("cold", lambda b: fresh[0].solve(b), forget, stress),
            ("playback", lambda b: r.solve(b), None, sliding),
            ("given", lambda b: r.solve(b, shear_ratio=0.3, shear_direction=0.5), None, stress),
            ("slider", slider, slider, stress),
            ("normal", lambda b: r.solve_normal(b), None, stress),
            # the floor: two dense (3m, m) matrix-vector products, as in one exact solve (C y and
            # C^T w)
            ("floor", lambda b: matrix.T @ (matrix @ b), None, stress)):
        wall, cpu, _ = fastest_in_rounds(call, sequence, repeat, before=before)
        out[label] = 1e3 * float(np.median(wall))
        out[label + "_cpu"] = 1e3 * float(np.median(cpu))
    return out


def layer_tables(poisson_ratio=0.45):
    """Seconds to compute the layer kernel's Hankel tables of one Poisson ratio (uncached).

    Parameters
    ----------
    poisson_ratio : float, optional
        Default 0.45.

    Returns
    -------
    float
        Seconds, wall.
    """
    start = time.perf_counter()
    layer.LayerTable.compute(poisson_ratio)
    return time.perf_counter() - start


def setup(n, *, pinv=True, repeat=1, kernel="layer"):
    """Set-up seconds for an n x n grid: our factorization and, optionally, numpy pinv.

    The layer kernel's Hankel tables are cached per Poisson ratio: the first
    set-up of a process pays for them too (:func:`layer_tables`).

    Parameters
    ----------
    n : int
        The skin is ``n x n``, pitch and thickness 2 mm.
    pinv : bool, optional
        Also time ``numpy.linalg.pinv`` of the stress matrix. Default True.
    repeat : int, optional
        Set-ups timed, the median kept. Default 1.
    kernel : {"layer", "cell", "point"}, optional
        Default "layer".

    Returns
    -------
    ours : float
        Seconds to build :class:`~solver.Reconstructor`.
    reference : float or None
        Seconds of ``numpy.linalg.pinv``, None without ``pinv``.
    """
    grid = SensorGrid.regular(n, n, 2e-3, 2e-3)
    ours = _median_ms(lambda: Reconstructor(grid, kernel=kernel), repeat) / 1e3
    reference = None
    if pinv:
        C = stress_matrix(grid, kernel)
        start = time.perf_counter()
        np.linalg.pinv(C)
        reference = time.perf_counter() - start
    return ours, reference


def main(argv=None):
    """The command ``python -m solver.bench``: prints the timings (module notes).

    Parameters
    ----------
    argv : list of str, optional
        The arguments; default ``sys.argv[1:]``.
    """
    parser = argparse.ArgumentParser(
        prog="python -m solver.bench",
        description="Solver timings: per-frame solves against the dense-product floor, and set-up.")
    parser.add_argument("--sizes", type=int, nargs="*", default=[32, 64],
                        help="skins (n x n) whose set-up is timed (default 32 64; none: skip)")
    parser.add_argument("--no-pinv", action="store_true", help="skip numpy.linalg.pinv (90 s at 64x64)")
    parser.add_argument("--skin", type=int, default=16,
                        help="n of the n x n skin solved per frame (default 16)")
    parser.add_argument("--frames", type=int, default=40, help="noisy frames per median (default 40)")
    args = parser.parse_args(argv)
    if args.skin < 4 or args.frames < 1:
        parser.error(f"--skin must be at least 4 and --frames at least 1, got {args.skin} and {args.frames}")
    if any(n < 1 for n in args.sizes):
        parser.error(f"--sizes must be at least 1 each, got {' '.join(map(str, args.sizes))}")
    print(f"machine: {machine()}")
    print(f"layer tables (once per Poisson ratio): {layer_tables():.3f} s")
    for kernel in KERNELS:
        t = per_frame(n=args.skin, frames=args.frames, kernel=kernel)
        print(f"{args.skin}x{args.skin} {kernel:5} solve median wall (CPU) ms: "
              f"auto {t['auto']:.3f} ({t['auto_cpu']:.3f}), "
              f"auto cold {t['cold']:.3f} ({t['cold_cpu']:.3f}), "
              f"auto in playback {t['playback']:.3f} ({t['playback_cpu']:.3f}), "
              f"given parameters {t['given']:.3f} ({t['given_cpu']:.3f}), slider move {t['slider']:.3f} "
              f"({t['slider_cpu']:.3f}), normal only {t['normal']:.3f} "
              f"({t['normal_cpu']:.3f}); dense-product floor {t['floor']:.3f} ({t['floor_cpu']:.3f}), "
              f"auto / floor {t['auto'] / t['floor']:.1f}x")
    for n in args.sizes:
        ours, ref = setup(n, pinv=not args.no_pinv)
        cell, _ = setup(n, pinv=False, kernel="cell")
        line = f"{n}x{n} set-up: Reconstructor {ours:.2f} s (cell kernel {cell:.2f} s)"
        if ref is not None:
            line += f", numpy.linalg.pinv {ref:.2f} s, ratio pinv/ours {ref / ours:.1f}x"
        print(line, flush=True)


if __name__ == "__main__":
    main()

"""Solver benchmarks: ``python -m measurement.bench`` (``make bench``).

Prints, for every kernel, the median per-frame ``solve`` time, wall and CPU,
on an n x n skin (default 16; automatic parameters cold, after another frame
and in playback, given parameters, a slider move, normal only) beside the
dense-product floor measured in the same run, and the set-up time of
:class:`solver.inverse.DenseSolver` for larger grids against ``numpy.linalg.pinv``
of the same ``(m, 3m)`` matrix, as a ratio from the same run.

Then the frames of several contacts (:func:`multi_contact`: one, two and three
contacts on a 16x16 skin of the bonded layer, ``--contacts``; each frame
unrelated to the one before, as a touch's first frame), the same counts in
motion (:func:`moving_contacts`: frames in order, each solve starting from the
frame before's, as in playback and live mode; ``--moving-frames``), and the broad
press (:func:`broad_press`: one load over most of the skin, ``--press-sizes``,
32x32 by default; 64x64 takes minutes and gigabytes), each as the median and
95th percentile of every timed automatic solve, wall and CPU.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import resource
import time
import tracemalloc

import numpy as np

from solver import layer, loads
from solver.geometry import SensorGrid
from solver.inverse import DenseSolver
from solver.kernels import KERNELS, stress_matrix
from solver.reconstructor import Reconstructor
from solver.threads import one_blas_thread

from .timing import fastest_in_rounds, machine, median_ms, spread, timed_in_rounds

__all__ = ["per_frame", "contact_frames", "multi_contact", "moving_contact_frames", "moving_contacts",
           "press_frames", "broad_press", "layer_tables", "setup", "main"]

# the skin of the multi-contact frames and of the broad press: pitch 1.5 mm, h / pitch 1, nu 0.49
PITCH = 1.5e-3
POISSON_RATIO = 0.49
CONTACT_COUNTS = (1, 2, 3)
_CONTACT_SEED = 29  # fixed seeds: the same frames every run
_PRESS_SEED = 64
# _QUIET: the frames are made on one BLAS thread. After a product on several, OpenBLAS's idle
# threads spin for about 0.1 s, and a solve timed then is charged with their CPU at the kernel's
# tick (4 ms): the one-contact CPU p95 read 4.8 ms where the wall p95 was 1.0 (2026-11-28).
# A broad press's set-up is timed on every thread (as the window builds it); then a pause.
_SPIN_S = 0.3


def _skin(n):
    return SensorGrid.regular(n, n, PITCH, PITCH, poisson_ratio=POISSON_RATIO)


def _rss_mb():
    # the process's peak resident set so far (Linux reports kilobytes)
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def per_frame(n=16, frames=40, kernel="layer", repeat=5):
    """Median over frames of the solve time on simulated Hertzian frames with 1% noise.

    Each frame's fastest of ``repeat`` solves is kept (:func:`~measurement.timing.fastest_in_rounds`).
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
    with one_blas_thread():  # (_QUIET)
        stress = [loads.simulate(grid, loads.hertz(tuple(rng.uniform(-2e-3, 2e-3, 2)), 5e-3, 1.0,
                                                   shear_ratio=0.3 * (k % 2), shear_direction=0.4 * k),
                                 noise=0.01, rng=rng).stress for k in range(frames)]
        sliding = [loads.simulate(grid, loads.hertz((-1e-3 + 5e-5 * k, 0.5e-3), 5e-3, 1.0, shear_ratio=0.3,
                                                    shear_direction=0.4 + 0.01 * k),
                                  noise=0.01, rng=rng).stress for k in range(frames)]
        r = DenseSolver(grid, kernel=kernel)
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


_SHAPES = (loads.hertz, loads.cone, loads.flat_punch)
_RATIOS = (0.0, 0.2, 0.4)


def _placed(count, half, rng):
    # ``count`` contacts of radius 1.6 to 2.4 pitches, a pitch or more apart and inside the skin
    for _ in range(1000):
        radii = rng.uniform(1.6, 2.4, count) * PITCH
        centres = [rng.uniform(-half + r + PITCH, half - r - PITCH, 2) for r in radii]
        if all(np.linalg.norm(centres[i] - centres[j]) >= radii[i] + radii[j] + PITCH
               for i in range(count) for j in range(i + 1, count)):
            return [_SHAPES[rng.integers(len(_SHAPES))](
                tuple(c), r, rng.uniform(0.6, 1.2), shear_ratio=_RATIOS[rng.integers(len(_RATIOS))],
                shear_direction=rng.uniform(-math.pi, math.pi)) for c, r in zip(centres, radii, strict=True)]
    raise ValueError(f"{count} contacts of 1.6 to 2.4 pitches do not fit apart on a skin of half-width "
                     f"{half / PITCH:g} pitches")


def _check_frames(count, frames, n):
    if count < 1 or frames < 1:
        raise ValueError(f"count and frames must be at least 1, got {count} and {frames}")
    if n < 8:
        raise ValueError(f"n must be at least 8 (a contact of 2.4 pitches and a pitch around it), got {n}")


def contact_frames(count, frames, *, n=16, seed=_CONTACT_SEED):
    """Noisy frames of ``count`` separate contacts on an ``n x n`` skin of the bonded layer.

    Pitch 1.5 mm, thickness one pitch, Poisson ratio 0.49; each frame places
    its contacts anew (Hertz, cone or flat punch of radius 1.6 to 2.4 pitches,
    0.6 to 1.2 N, shear ratio 0, 0.2 or 0.4 in any direction, a pitch or more
    apart) and draws its own 1% noise (:func:`solver.loads.simulate`), from a
    fixed seed: the same frames every run.

    Parameters
    ----------
    count : int
        Contacts per frame, at least 1.
    frames : int
        Frames, at least 1.
    n : int, optional
        At least 8. Default 16.
    seed : int, optional

    Returns
    -------
    grid : SensorGrid
    stress : list of (n * n,) ndarray
        Pascals.

    Raises
    ------
    ValueError
        For fewer than one contact or frame, a skin under 8 x 8, or contacts
        that do not fit apart on it.
    """
    _check_frames(count, frames, n)
    grid = _skin(n)
    rng = np.random.default_rng([seed, count])
    half = (n - 1) / 2 * PITCH
    with one_blas_thread():  # no BLAS threads left spinning into the solves timed next (_QUIET)
        return grid, [loads.simulate(grid, _placed(count, half, rng), noise=0.01, rng=rng).stress
                      for _ in range(frames)]


def multi_contact(counts=CONTACT_COUNTS, *, n=16, frames=20, repeat=5):
    """Automatic solves of frames of one, two and three contacts (:func:`contact_frames`).

    The solver is :class:`solver.Reconstructor` of the skin (the viewer's). One
    untimed round over the frames first (compilation, caches), then
    ``repeat`` timed rounds over all frames (:func:`~measurement.timing.timed_in_rounds`: no solve
    follows one of the same frame).

    Parameters
    ----------
    counts : sequence of int, optional
        Contacts per frame, each timed on its own frames. Default 1, 2, 3.
    n : int, optional
        The skin is ``n x n``. Default 16.
    frames : int, optional
        Frames per count. Default 20.
    repeat : int, optional
        Timed rounds. Default 5.

    Returns
    -------
    dict of int to dict
        Per count: ``wall``, ``wall_p95``, ``cpu``, ``cpu_p95`` (milliseconds,
        median and 95th percentile over every timed solve), ``fastest`` and
        ``fastest_cpu`` (median over frames of each frame's fastest, as
        :func:`per_frame`), ``solves`` (timed), ``frames`` and ``found`` (the
        median count of contacts the solver found per frame).
    """
    out = {}
    for count in counts:
        wall, cpu, found = _solved_in_rounds(*contact_frames(count, frames, n=n), repeat)
        out[count] = dict(spread(wall, cpu), fastest=1e3 * float(np.median(wall.min(axis=0))),
                          fastest_cpu=1e3 * float(np.median(cpu.min(axis=0))), solves=wall.size,
                          frames=frames, found=found)
    return out


def _solved_in_rounds(grid, stress, repeat):
    # automatic solves of the frames by the skin's Reconstructor: one untimed round (compilation,
    # caches), then ``repeat`` timed rounds (timed_in_rounds); the median contacts found a frame
    with one_blas_thread():  # (_QUIET) its factorization too
        solver = Reconstructor(grid)
    found = [len(solver.solve(b).contacts) for b in stress]
    wall, cpu, _ = timed_in_rounds(solver.solve, stress, repeat)
    return wall, cpu, float(np.median(found))



def moving_contact_frames(count, frames, *, n=16, seed=_CONTACT_SEED):
    """Frames in order of ``count`` contacts in motion, as playback and a live board give them.

    The contacts are placed as in :func:`contact_frames` (their own draw of
    the same kinds), then each circles its place at half a pitch, one turn
    over the frames from a phase of its own (about 0.02 mm a frame at 200
    frames: a finger moving 2 mm/s on a 100 Hz board), so that the last frame
    leads into the first again; 1% noise drawn anew each frame.

    Parameters
    ----------
    count, frames, n, seed
        As :func:`contact_frames`.

    Returns
    -------
    grid : SensorGrid
    stress : list of (n * n,) ndarray
        Pascals, in order.
    """
    _check_frames(count, frames, n)
    grid = _skin(n)
    rng = np.random.default_rng([seed, count, 1])
    placed = _placed(count, (n - 1) / 2 * PITCH, rng)
    phases = rng.uniform(0, 2 * math.pi, count)
    out = []
    with one_blas_thread():  # (_QUIET)
        for k in range(frames):
            turn = 2 * math.pi * k / frames
            moved = [dataclasses.replace(c, center=(c.center[0] + 0.5 * PITCH * math.cos(turn + a),
                                                    c.center[1] + 0.5 * PITCH * math.sin(turn + a)))
                     for c, a in zip(placed, phases, strict=True)]
            out.append(loads.simulate(grid, moved, noise=0.01, rng=rng).stress)
    return grid, out


def moving_contacts(counts=CONTACT_COUNTS, *, n=16, frames=100, repeat=3):
    """Automatic solves of contacts in motion, each frame after the one before it.

    :func:`moving_contact_frames` solved in order by one
    :class:`solver.Reconstructor`, as the viewer's playback and live mode
    solve them: each solve starts from the frame before's (where
    :func:`multi_contact`'s frames are unrelated, the worst case of a touch's
    first frame). One untimed turn, then ``repeat`` timed turns.

    Returns
    -------
    dict of int to dict
        Per count: ``wall``, ``wall_p95``, ``cpu``, ``cpu_p95`` (milliseconds),
        ``solves``, ``frames`` and ``found`` (median contacts found a frame).
    """
    out = {}
    for count in counts:
        wall, cpu, found = _solved_in_rounds(*moving_contact_frames(count, frames, n=n), repeat)
        out[count] = dict(spread(wall, cpu), solves=wall.size, frames=frames, found=found)
    return out

def press_frames(n, frames, *, seed=_PRESS_SEED):
    """Noisy frames of a broad press on an ``n x n`` skin of the bonded layer.

    One Hertzian load of radius 0.4 of the skin's side (half of it is
    loaded), its centre within a pitch of the middle, mean pressure 6 to 9
    kPa, shear ratio 0.2 in any direction on every other frame, 1% noise,
    fixed seed. Pitch 1.5 mm, thickness one pitch, Poisson ratio 0.49.

    Returns
    -------
    grid : SensorGrid
    stress : list of (n * n,) ndarray
    """
    if n < 2 or frames < 1:
        raise ValueError(f"n must be at least 2 and frames at least 1, got {n} and {frames}")
    grid = _skin(n)
    rng = np.random.default_rng([seed, n])
    radius = 0.4 * (n - 1) * PITCH
    stress = []
    with one_blas_thread():  # (_QUIET)
        for k in range(frames):
            force = rng.uniform(6e3, 9e3) * math.pi * radius**2
            contact = loads.hertz(tuple(rng.uniform(-PITCH, PITCH, 2)), radius, force,
                                  shear_ratio=0.2 * (k % 2), shear_direction=rng.uniform(-math.pi, math.pi))
            stress.append(loads.simulate(grid, contact, noise=0.01, rng=rng).stress)
    return grid, stress


# The parameters a broad press is also solved with (a slider set by hand).
GIVEN_RATIO, GIVEN_DIRECTION = 0.2, 0.5


def broad_press(n, *, frames=3, memory=True):
    """Set-up, automatic solves and peak memory of a broad press (:func:`press_frames`) on ``n x n``.

    The solver is :class:`solver.Reconstructor` of the skin (a dense
    :class:`~solver.inverse.DenseSolver` up to 32x32, the region solver beyond);
    the layer tables of its Poisson ratio are computed before, not counted.
    Each frame is solved once, in order, so no solve follows one of the same
    frame; the first solve is also given alone (it meets the solver new, as
    the first frame of a recording does). Memory, two ways: the process's
    peak resident set (``getrusage``) before the set-up and after the last
    solve (a stage that raises the peak shows its own; an earlier, larger
    stage hides it), and, in a second, untimed pass with a new solver, the
    peak that ``tracemalloc`` traces (numpy's arrays and Python's objects,
    not numba's or BLAS's own buffers) over the set-up and the first solve
    (with ``memory=False`` this pass is skipped).

    Returns
    -------
    dict
        ``setup`` and ``setup_cpu`` (s), ``first`` and ``first_cpu`` (s),
        ``wall``, ``wall_p95``, ``cpu``, ``cpu_p95`` (s, median and 95th
        percentile over all the solves, the first included), ``solves``,
        ``found`` (median contacts found), ``solver`` (its class name),
        ``fallbacks`` (solves that took a cheaper member than the accurate
        path, ``Reconstruction.fallback``) and ``fallback`` (the first one's
        note, empty without), ``rss_before`` and ``rss_peak`` (MB),
        ``traced_peak`` (MB, NaN without ``memory``), ``given`` and
        ``given_cpu`` (s, median over the frames of a solve with the
        parameters given, :data:`GIVEN_RATIO` and :data:`GIVEN_DIRECTION`,
        after the automatic ones: a slider set by hand).
    """
    grid, stress = press_frames(n, frames)
    layer.table(POISSON_RATIO)
    rss_before = _rss_mb()
    start_cpu, start = time.process_time(), time.perf_counter()
    solver = Reconstructor(grid)
    setup_wall, setup_cpu = time.perf_counter() - start, time.process_time() - start_cpu
    time.sleep(_SPIN_S)  # (_QUIET) the set-up's BLAS threads idle before the solves are timed
    wall, cpu, results = timed_in_rounds(solver.solve, stress, 1)
    given_wall, given_cpu, _ = timed_in_rounds(
        lambda b: solver.solve(b, shear_ratio=GIVEN_RATIO, shear_direction=GIVEN_DIRECTION), stress, 1)
    rss_peak, traced, kind = _rss_mb(), math.nan, type(solver.engine).__name__
    if memory:
        del solver  # its matrices are not counted twice
        tracemalloc.start()
        try:
            Reconstructor(grid).solve(stress[0])
            traced = tracemalloc.get_traced_memory()[1] / 2**20
        finally:
            tracemalloc.stop()
    return dict(spread(wall, cpu, scale=1.0), setup=setup_wall, setup_cpu=setup_cpu, first=float(wall[0, 0]),
                first_cpu=float(cpu[0, 0]), solves=wall.size,
                found=float(np.median([len(r.contacts) for r in results])), solver=kind,
                fallbacks=sum(bool(getattr(r, "fallback", "")) for r in results),
                fallback=next((r.fallback for r in results if getattr(r, "fallback", "")), ""),
                rss_before=rss_before, rss_peak=rss_peak, traced_peak=traced,
                given=float(np.median(given_wall)), given_cpu=float(np.median(given_cpu)))


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
        Seconds to build :class:`~solver.inverse.DenseSolver`.
    reference : float or None
        Seconds of ``numpy.linalg.pinv``, None without ``pinv``.
    """
    grid = SensorGrid.regular(n, n, 2e-3, 2e-3)
    ours = median_ms(lambda: DenseSolver(grid, kernel=kernel), repeat) / 1e3
    reference = None
    if pinv:
        C = stress_matrix(grid, kernel)
        start = time.perf_counter()
        np.linalg.pinv(C)
        reference = time.perf_counter() - start
    return ours, reference


def main(argv=None):
    """The command ``python -m measurement.bench``: prints the timings (module notes).

    Parameters
    ----------
    argv : list of str, optional
        The arguments; default ``sys.argv[1:]``.
    """
    parser = argparse.ArgumentParser(
        prog="python -m measurement.bench",
        description="Solver timings: per-frame solves against the dense-product floor, and set-up.")
    parser.add_argument("--sizes", type=int, nargs="*", default=[32, 64],
                        help="skins (n x n) whose set-up is timed (default 32 64; none: skip)")
    parser.add_argument("--no-pinv", action="store_true", help="skip numpy.linalg.pinv (90 s at 64x64)")
    parser.add_argument("--skin", type=int, default=16,
                        help="n of the n x n skin solved per frame (default 16)")
    parser.add_argument("--frames", type=int, default=40, help="noisy frames per median (default 40)")
    parser.add_argument("--kernels", nargs="*", choices=KERNELS, default=list(KERNELS),
                        help="kernels solved per frame on the Hertz frames (default all; none: skip)")
    parser.add_argument("--contacts", type=int, nargs="*", default=list(CONTACT_COUNTS),
                        help="contacts per frame of the 16x16 multi-contact frames, each 1 to 3 "
                             "(default 1 2 3; none: skip)")
    parser.add_argument("--contact-frames", type=int, default=20,
                        help="frames per contact count, each timed in 5 rounds (default 20)")
    parser.add_argument("--moving-frames", type=int, default=100,
                        help="frames of one turn of the contacts in motion, per contact count (default "
                             "100; 0: skip)")
    parser.add_argument("--press-sizes", type=int, nargs="*", default=[32],
                        help="skins (n x n) solved under a broad press (default 32; 64 takes minutes and "
                             "gigabytes; none: skip)")
    parser.add_argument("--press-frames", type=int, default=3,
                        help="broad-press frames per skin, each solved once (default 3)")
    args = parser.parse_args(argv)
    if args.skin < 4 or args.frames < 1:
        parser.error(f"--skin must be at least 4 and --frames at least 1, got {args.skin} and {args.frames}")
    if any(n < 1 for n in args.sizes):
        parser.error(f"--sizes must be at least 1 each, got {' '.join(map(str, args.sizes))}")
    if any(count not in CONTACT_COUNTS for count in args.contacts):
        parser.error(f"--contacts must be 1, 2 or 3 each, got {' '.join(map(str, args.contacts))}")
    if args.moving_frames < 0:
        parser.error(f"--moving-frames must be 0 or more, got {args.moving_frames}")
    if args.contact_frames < 1:
        parser.error(f"--contact-frames must be at least 1, got {args.contact_frames}")
    if any(n < 8 for n in args.press_sizes):
        parser.error(f"--press-sizes must be at least 8 each, got {' '.join(map(str, args.press_sizes))}")
    if args.press_frames < 1:
        parser.error(f"--press-frames must be at least 1, got {args.press_frames}")
    print(f"machine: {machine()}")
    print(f"layer tables (once per Poisson ratio): {layer_tables():.3f} s")
    for kernel in args.kernels:
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
        line = f"{n}x{n} set-up: DenseSolver {ours:.2f} s (cell kernel {cell:.2f} s)"
        if ref is not None:
            line += f", numpy.linalg.pinv {ref:.2f} s, ratio pinv/ours {ref / ours:.1f}x"
        print(line, flush=True)
    skin = "pitch 1.5 mm, h/pitch 1, nu 0.49, layer kernel, 1% noise"
    if args.contacts:
        print(f"16x16 multi-contact frames ({skin}; Reconstructor; per count its own frames, each placed "
              f"and noised anew, one untimed round, then 5 rounds over all frames):", flush=True)
    for count in args.contacts:
        t = multi_contact([count], frames=args.contact_frames)[count]
        print(f"16x16 {count} contact{'s' if count > 1 else ' '} automatic solve ms, {t['solves']} solves of "
              f"{t['frames']} frames: wall median {t['wall']:.3f} p95 {t['wall_p95']:.3f}, "
              f"CPU median {t['cpu']:.3f} p95 {t['cpu_p95']:.3f}; each frame's fastest, median "
              f"{t['fastest']:.3f} ({t['fastest_cpu']:.3f}); contacts found, median {t['found']:g}",
              flush=True)
    if args.contacts and args.moving_frames:
        print(f"16x16 contacts in motion ({skin}; each circling its place at half a pitch, one turn over "
              f"{args.moving_frames} frames solved in order, as playback and a live board; one untimed turn, "
              f"then 3):", flush=True)
    for count in args.contacts if args.moving_frames else ():
        t = moving_contacts([count], frames=args.moving_frames)[count]
        print(f"16x16 {count} contact{'s' if count > 1 else ' '} in motion, automatic solve ms, "
              f"{t['solves']} solves: wall median {t['wall']:.3f} p95 {t['wall_p95']:.3f}, "
              f"CPU median {t['cpu']:.3f} p95 {t['cpu_p95']:.3f}; contacts found, median {t['found']:g}",
              flush=True)
    for n in args.press_sizes:
        print(f"{n}x{n} broad press ({skin}; a Hertzian load of radius 0.4 of the side; "
              f"{args.press_frames} frames, each solved once): running ...", flush=True)
        t = broad_press(n, frames=args.press_frames)
        print(f"{n}x{n} broad press: set-up ({t['solver']}) {t['setup']:.2f} s (CPU {t['setup_cpu']:.2f} s); "
              f"first solve {t['first']:.3f} s (CPU {t['first_cpu']:.3f} s); automatic solve s, "
              f"{t['solves']} solves: wall median {t['wall']:.3f} p95 {t['wall_p95']:.3f}, CPU median "
              f"{t['cpu']:.3f} p95 {t['cpu_p95']:.3f}; contacts found, median {t['found']:g}; "
              f"cheaper fallback on {t['fallbacks']} of {t['solves']}{': ' if t['fallback'] else ''}"
              f"{t['fallback']}; given parameters ({GIVEN_RATIO}, {GIVEN_DIRECTION} rad) median "
              f"{t['given']:.3f} s (CPU {t['given_cpu']:.3f} s); "
              f"peak RSS {t['rss_peak']:.0f} MB ({t['rss_before']:.0f} MB before its set-up); traced peak of "
              f"set-up and first solve (tracemalloc, untimed pass) {t['traced_peak']:.0f} MB", flush=True)


if __name__ == "__main__":
    main()

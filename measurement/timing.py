"""How a timing is taken: the machine line, timed calls in rounds, and their median and spread.

The solver's timings (:mod:`measurement.bench`) and the trade-off
(:mod:`measurement.tradeoff`) time their work with these; they and the
viewer's benchmarks name the machine they ran on (:func:`machine`).
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

__all__ = ["machine", "median_ms", "fastest_in_rounds", "timed_in_rounds", "spread"]


def machine() -> str:
    """One line naming the machine a measurement ran on: CPU, cores, numpy, Python."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, numpy {np.__version__}, python {platform.python_version()}"


def median_ms(fn, repeat):
    # the median of ``repeat`` timed calls of ``fn()``, milliseconds wall
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
    wall, cpu, results = timed_in_rounds(call, items, repeat, before=before)
    return wall.min(axis=0), cpu.min(axis=0), results


def timed_in_rounds(call, items, repeat, *, before=None):
    """Every one of ``repeat`` timed calls on each item, wall and CPU, taken in rounds over all items.

    As :func:`fastest_in_rounds` (same arguments), but every timing is kept,
    for medians and percentiles over all of them.

    Returns
    -------
    wall, cpu : (repeat, len(items)) ndarray
        Seconds, ``[round, item]``; CPU is the process's (``time.process_time``).
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
    return wall, cpu, results


def spread(wall, cpu, scale=1e3):
    # median and 95th percentile over every timing, wall and CPU (milliseconds by default)
    wall, cpu = scale * np.ravel(wall), scale * np.ravel(cpu)
    return dict(wall=float(np.median(wall)), wall_p95=float(np.percentile(wall, 95)),
                cpu=float(np.median(cpu)), cpu_p95=float(np.percentile(cpu, 95)))

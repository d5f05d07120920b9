"""What the time-plot dock costs the window: ``python -m benchmarks.time_plots_cost`` (under Xvfb).

Measures, in the real window on a bundled sample, in one run: without the dock,
with the dock docked at the bottom (the scene is then smaller) and with the dock
floating beside the window (the scene keeps its size), in interleaved rounds (a
the window's own dock, hidden, docked and floating in turn), medians over the rounds:

- frame slider to rendered frame: wall time from setting the frame slider to
  the swap of the repaint that shows the frame (median and 90th percentile),
  and the process's CPU time over the same span (all threads: the solve too);
- playback: distinct frames put on screen per wall-clock second while playing
  a looped recording at 1x (the recording's 30 fps is the ceiling) and at 4x
  (the display's own ceiling), and the process's CPU time per frame drawn;
- the dock's own cost per frame change: moving its cursors to the next frame
  and repainting what they crossed, until that paint is done (median wall and
  CPU milliseconds; no solve, no scene render).

The dock's series is complete before its rows are measured: during playback
it only moves its cursor. It needs a display: ``xvfb-run -a python -m
benchmarks.time_plots_cost`` on a headless machine.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.viewer_speed import _open_window, _run_events, _wait
from measurement.timing import machine

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "hertz_shear_turning.npz"


def slider_latencies(window, count):
    """``(wall ms, CPU ms)`` lists from setting the frame slider to the render that shows the frame."""
    slider = window.playback.frame_slider
    frames = slider.maximum() + 1
    walls, cpus = [], []
    for k in range(count):
        target = (slider.value() + 7 + k % 5) % frames  # always another frame: each move renders
        cpu, start = time.process_time(), time.perf_counter()
        slider.setValue(target)
        walls.append(1e3 * (_wait(window.rendered) - start))
        cpus.append(1e3 * (time.process_time() - cpu))
        assert window.model.frame == target
    return walls, cpus


def playback(window, app, speed_index, seconds):
    """``(frames drawn per second, CPU ms per frame drawn)`` while playing looped for ``seconds``."""
    drawn = []
    slot = lambda: drawn.append(time.perf_counter())  # noqa: E731
    window.rendered.connect(slot)
    window.playback.loop_box.setChecked(True)
    window.playback.speed_box.setCurrentIndex(speed_index)
    cpu, start = time.process_time(), time.perf_counter()
    window.playback.set_playing(True)
    _run_events(seconds)  # as the app waits for events: a loop of processEvents counted its own spinning
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
    window.playback.set_playing(False)
    window.rendered.disconnect(slot)
    _settle(app)
    return len(drawn) / elapsed, 1e3 * cpu / max(len(drawn), 1), 100 * cpu / elapsed


def cursor_cost(dock, count=200):
    """Medians ``(wall ms, CPU ms)`` of moving the dock's cursor to another frame and repainting it.

    What the dock adds to every frame of playback: moving its cursor lines (nothing else moves) and
    the repaint of the strips they crossed, until that paint is done. Alone, as measured here, the
    repaint is one of its own; in playback it joins the repaint of the frame (the lines move with the
    frame's result).
    """
    from PyQt6 import QtCore

    class Paints(QtCore.QObject):
        # a paint is no signal of its own: the filter makes one; the loop it ends quits once the
        # paint is done (a quit takes effect when the event being delivered returns)
        painted = QtCore.pyqtSignal()

        def eventFilter(self, watched, event):  # noqa: N802
            if event.type() == QtCore.QEvent.Type.Paint:
                self.painted.emit()
            return False

    paints = Paints()
    viewport = dock.graphics.viewport()
    viewport.installEventFilter(paints)
    t = dock.model.recording.t
    walls, cpus = [], []
    try:
        for k in range(count):
            cpu, start = time.process_time(), time.perf_counter()
            dock._move_lines(float(t[(dock.model.frame + 1 + k) % len(t)]))
            try:
                _wait(paints.painted, timeout=1.0)  # waiting for events, as the app does
            except TimeoutError:  # the plots were not repainted (not exposed): no figure, not a hang
                return math.nan, math.nan
            walls.append(1e3 * (time.perf_counter() - start))
            cpus.append(1e3 * (time.process_time() - cpu))
    finally:
        viewport.removeEventFilter(paints)
    dock._move_lines(float(t[dock.model.frame]))
    return float(np.median(walls)), float(np.median(cpus))


def _settle(app, rounds=20):
    for _ in range(rounds):
        app.processEvents()


CONFIGURATIONS = ("without the dock", "dock docked", "dock floating")


def measure(window, app, count, seconds, dock=None):
    """One configuration's figures: the scene's size, slider latencies, playback rates, the dock's work."""
    from tactile_viewer.qt.playback_panel import SPEEDS

    _settle(app)
    walls, cpus = slider_latencies(window, count)
    rates = {speed: playback(window, app, SPEEDS.index(speed), seconds) for speed in (1.0, 4.0)}
    return dict(scene=tuple(window.plotter.window_size), wall=walls, cpu=cpus, playback=rates,
                cursor=cursor_cost(dock) if dock is not None else None)


def row(label, figures, out):
    """One line of the table: medians over every round of ``figures`` (a list of :func:`measure`'s)."""
    width, height = figures[0]["scene"]
    walls = np.concatenate([f["wall"] for f in figures])
    cpus = np.concatenate([f["cpu"] for f in figures])
    rates = " ".join(
        f" {np.median([f['playback'][s][0] for f in figures]):6.1f} "
        f"{np.median([f['playback'][s][1] for f in figures]):6.1f} "
        f"{np.median([f['playback'][s][2] for f in figures]):5.0f}" for s in (1.0, 4.0))
    cursor = [f["cursor"] for f in figures if f["cursor"] is not None]
    cursor = (f"{np.median([c[0] for c in cursor]):6.2f} {np.median([c[1] for c in cursor]):6.2f}" if cursor
              else f"{'-':>6} {'-':>6}")
    print(f"{label:<22} {width:>4}x{height:<4} {np.median(walls):7.1f} {np.percentile(walls, 90):6.1f} "
          f"{np.median(cpus):7.1f}  {rates}  {cursor}", file=out)
    out.flush()


def run(path=SAMPLE, *, count=40, seconds=5.0, rounds=3, size=(1280, 820), out=None):
    out = sys.stdout if out is None else out
    app, window = _open_window(path, size, "benchmarks.time_plots_cost")
    from tactile_viewer.qt.time_plots import TimePlotsDock

    recording = window.model.recording
    print(f"machine: {machine()}", file=out)
    shape = f"{recording.grid.shape[1]}x{recording.grid.shape[0]}"
    print(f"{Path(path).name}: {shape} grid, {len(recording)} frames; {rounds} rounds, each without the "
          f"dock, docked and floating; per round {count} frame-slider moves and {seconds:g} s of playback "
          "per speed", file=out)
    print("medians over the rounds; CPU: the whole process's, all threads (the solver's too)", file=out)
    results = {label: [] for label in CONFIGURATIONS}
    measure(window, app, 10, 1.0)  # warm-up, not counted: first renders and solves are slower
    dock = window.time_plots  # the window's own dock (View > Time plots shows and hides it)
    assert isinstance(dock, TimePlotsDock)
    for _ in range(rounds):
        # interleaved: a machine whose load changes during the run weighs on every configuration alike
        dock.setFloating(False)
        dock.hide()  # a hidden dock solves and draws nothing
        _settle(app, 50)
        results["without the dock"].append(measure(window, app, count, seconds))
        dock.show()
        if dock.series is None or not dock.series.complete:
            _wait(dock.computed, timeout=120)  # then complete: from here on only the cursor moves
        _settle(app, 50)
        results["dock docked"].append(measure(window, app, count, seconds, dock))
        dock.setFloating(True)  # the scene gets its size back
        dock.resize(size[0], 400)
        dock.move(window.x(), window.y() + size[1])
        _settle(app, 50)
        results["dock floating"].append(measure(window, app, count, seconds, dock))
    print(f"{'':<22} {'scene':>9} {'slider to frame':>22}   {'playback 1x':>18}  {'playback 4x':>18}  "
          f"{'dock: cursor step':>17}", file=out)
    rate = f"{'fps':>6} {'CPU ms':>6} {'CPU%':>5}"
    step = f"{'wall ms':>6} {'CPU ms':>6}"
    print(f"{'':<22} {'px':>9} {'wall ms':>7} {'p90':>6} {'CPU ms':>7}   {rate}  {rate}  {step}", file=out)
    for label in CONFIGURATIONS:
        row(label, results[label], out)
    window.close()
    app.processEvents()
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.time_plots_cost",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("recording", nargs="?", default=str(SAMPLE))
    parser.add_argument("--count", type=int, default=40, help="frame-slider moves per measurement")
    parser.add_argument("--seconds", type=float, default=5.0, help="playback time per speed")
    parser.add_argument("--rounds", type=int, default=3, help="times each configuration is measured")
    args = parser.parse_args(argv)
    run(args.recording, count=args.count, seconds=args.seconds, rounds=args.rounds)


if __name__ == "__main__":
    main()

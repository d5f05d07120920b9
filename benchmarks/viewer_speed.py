"""Viewer benchmark: ``python -m benchmarks.viewer_speed`` (``make bench`` runs it under Xvfb).

Measures, in the real window (``QtInteractor``, whatever OpenGL the display offers):

- slider to rendered frame: time from moving the shear-ratio or shear-direction
  slider to the end of the render that shows the re-solved frame (manual
  parameters), and from stepping a frame to its render (automatic parameters);
- playback frame rate: distinct frames drawn per second of wall clock while
  playing a looped recording at 1x (the recording's own 30 fps is the ceiling)
  and at 4x (120 recording frames per second: the display's own ceiling), and
  how many times the window was composed per frame drawn (1 at best);
- serial decoder throughput (frames per second, 256 values, binary and text);
- with ``--live SECONDS``: the window on ``tactile-sim`` at 1 kHz through a
  pseudo-terminal, recording everything: frames lost in the recording, display
  frame rate, CPU use of the viewer and of the simulator;
- solves in the window against a plain loop (``--solve-samples``, by default
  the two- and three-contact samples): the window's own automatic solve times
  during 1x looped playback (``Solved.solve_ms``, wall, and the worker
  thread's CPU time of the same solves) against the same frames solved in
  order by a solver of the same settings in a plain loop of the same process,
  with the other core idle and with it busy (a spinning process), as medians,
  95th percentiles and the ratio in-window / plain.

It needs a display: under a headless machine run it through ``xvfb-run -a``.
"""

from __future__ import annotations

import argparse
import atexit
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from measurement.timing import machine

SAMPLES = Path(__file__).resolve().parents[1] / "sample_data"
SAMPLE = SAMPLES / "hertz_shear_turning.npz"
SOLVE_SAMPLES = (SAMPLES / "two_contacts.npz", SAMPLES / "three_contacts.npz")
LOADS = ("idle", "busy")


_APP = []  # the one QApplication, kept alive between measurements (a second one cannot start)


def _application():
    from PyQt6 import QtWidgets

    if not _APP:
        _APP.append(QtWidgets.QApplication.instance() or QtWidgets.QApplication(sys.argv[:1]))
    return _APP[0]


def _own_settings():
    """Settings of the benchmark's own, unless ``TACTILE_VIEWER_CONFIG`` names some; the folder.

    The window is then laid out as a fresh install lays it out (the time plots docked), whatever
    the user last did, and nothing a benchmark moves (``time_plots_cost`` floats the dock) is left
    in the user's settings. The folder goes when the process ends.
    """
    if "TACTILE_VIEWER_CONFIG" not in os.environ:
        folder = tempfile.mkdtemp(prefix="tactile-benchmark-settings-")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        os.environ["TACTILE_VIEWER_CONFIG"] = folder
    return Path(os.environ["TACTILE_VIEWER_CONFIG"])


def _open_window(path, size, program):
    """``(app, window)``: the viewer's window at ``size`` showing ``path``'s first frame.

    ``program`` names the benchmark in the error when there is no display.
    """
    os.environ.setdefault("QT_API", "pyqt6")
    _own_settings()
    from tactile_viewer.qt.main_window import MainWindow

    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise SystemExit(f"{program} needs a display: run it as `xvfb-run -a python -m {program}` on a "
                         "headless machine")
    app = _application()
    window = MainWindow()
    window.resize(*size)
    window.show()
    window.open(path)
    _wait(window.ready, timeout=60)
    return app, window


def _wait(signal, timeout=10.0):
    """Run the event loop until ``signal`` fires once; returns the time it fired."""
    fired = []
    record = lambda *_: fired.append(time.perf_counter())  # noqa: E731
    signal.connect(record)  # before the loop's quit: connected slots are called in order
    try:
        _run_events(timeout, quit_on=signal)
    finally:
        signal.disconnect(record)
    if not fired:
        raise TimeoutError(f"no {signal} within {timeout} s")
    return fired[0]


def _run_events(seconds, *, until=None, quit_on=None):
    """Run the event loop as the app's own does, waiting for events (a loop calling
    ``processEvents`` keeps a core busy, and took it from the solves timed beside it): for
    ``seconds``, or sooner until ``until()`` is true (asked every 5 ms) or ``quit_on`` fires."""
    from PyQt6 import QtCore

    loop = QtCore.QEventLoop()
    QtCore.QTimer.singleShot(int(1e3 * seconds), loop.quit)
    if until is not None:
        check = QtCore.QTimer()
        check.timeout.connect(lambda: until() and loop.quit())
        check.start(5)
    if quit_on is not None:
        quit_on.connect(loop.quit)
    try:
        loop.exec()
    finally:
        if quit_on is not None:
            quit_on.disconnect(loop.quit)


def latencies(window, action, count):
    """Median-ready list of ms from ``action(k)`` to the render that shows it."""
    times = []
    for k in range(count):
        start = time.perf_counter()
        action(k)
        times.append(1e3 * (_wait(window.rendered) - start))
    return times


def playback_rate(window, speed_index, seconds):
    """``(frames drawn a second, compositions per frame drawn)`` while playing (looped).

    ``rendered`` fires when a solved frame's repaint is swapped to the window, so solves overtaken
    before a paint do not count. A composition is any swap of the window (the 3-D view is a
    ``QOpenGLWidget``: Qt composes the whole window through OpenGL whenever any widget repaints,
    about 13 ms each under software rendering); 1 is the least a frame can cost.
    """
    drawn, swaps = [], []
    slot = lambda: drawn.append(time.perf_counter())  # noqa: E731
    swapped = lambda: swaps.append(time.perf_counter())  # noqa: E731
    window.rendered.connect(slot)
    window.plotter.interactor.frameSwapped.connect(swapped)
    window.playback.loop_box.setChecked(True)
    window.playback.speed_box.setCurrentIndex(speed_index)
    window.playback.set_playing(True)
    start = time.perf_counter()
    _run_events(seconds)
    elapsed = time.perf_counter() - start
    window.playback.set_playing(False)
    window.rendered.disconnect(slot)
    window.plotter.interactor.frameSwapped.disconnect(swapped)
    return len(drawn) / elapsed, len(swaps) / max(len(drawn), 1)


def run(path=SAMPLE, *, count=40, seconds=5.0, size=(1280, 820), out=None):
    out = sys.stdout if out is None else out
    app, window = _open_window(path, size, "benchmarks.viewer_speed")
    from tactile_viewer.qt.playback_panel import SPEEDS

    for _ in range(20):  # let the layout settle before timing
        app.processEvents()
    renderer = next((line.split(":", 1)[1].strip() for line in window.plotter.ren_win.ReportCapabilities()
                     .splitlines() if line.startswith("OpenGL renderer string")), "unknown")
    width, height = window.plotter.window_size
    recording = window.model.recording
    print(f"machine: {machine()}", file=out)
    print(f"OpenGL: {renderer}; scene {width}x{height} px; {Path(path).name}: "
          f"{recording.grid.shape[1]}x{recording.grid.shape[0]} grid, {len(recording)} frames", file=out)

    panel = window.parameters
    ratio = latencies(window, lambda k: panel.ratio_slider.setValue(10 + (k * 37) % 130), count)
    direction = latencies(window, lambda k: panel.direction_slider.setValue(-170 + (k * 47) % 340),
                          count)
    window.parameters.auto_box.setChecked(True)
    _wait(window.rendered)
    stepped = latencies(window, lambda k: window.playback.step(1 if (k // 10) % 2 == 0 else -1), count)
    print(f"{'slider to rendered frame':<42} {'median ms':>9} {'p90 ms':>7}", file=out)
    rows = (("shear ratio slider (manual)", ratio), ("shear direction slider (manual)", direction),
            ("frame step (auto parameters)", stepped))
    for label, times in rows:
        print(f"  {label:<40} {np.median(times):9.1f} {np.percentile(times, 90):7.1f}", file=out)
    print(f"playback over {seconds:g} s, looped", file=out)
    rates, compositions = {}, {}
    for speed in (1.0, 4.0):
        rates[speed], compositions[speed] = playback_rate(window, SPEEDS.index(speed), seconds)
        print(f"  {speed:g}x ({30 * speed:g} recording frames/s): {rates[speed]:5.1f} frames drawn "
              f"per second, {compositions[speed]:.2f} window compositions per frame", file=out)
    solves = window.model.worker_stats()
    window.close()
    app.processEvents()
    return dict(ratio=ratio, direction=direction, step=stepped, playback=rates, compositions=compositions,
                recording_fps=(len(recording) - 1) / float(recording.t[-1] - recording.t[0]), solves=solves)


def decoder_throughput(count=256, frames=20000, chunk=4096, out=None):
    """Frames per second each decoder turns bytes into frames (``count`` values, ``chunk``-byte reads)."""
    from tactile_viewer.sources.protocol import encode_binary, encode_text, make_decoder

    out = sys.stdout if out is None else out
    rng = np.random.default_rng(0)  # fixed seed: the same stream every run
    values = rng.uniform(0, 50, (200, count)).astype(np.float32)
    rates = {}
    for fmt, encode in (("binary", lambda k, v: encode_binary(k, v)), ("text", lambda k, v: encode_text(v))):
        stream = b"".join(encode(k, values[k % len(values)]) for k in range(frames))
        for size in (chunk, 16 * chunk):
            decoder = make_decoder(fmt, count)
            start = time.perf_counter()
            decoded = sum(len(decoder.feed(stream[i:i + size])) for i in range(0, len(stream), size))
            elapsed = time.perf_counter() - start
            assert decoded == frames, (fmt, decoded)
            rates[fmt, size] = frames / elapsed
            print(f"  {fmt:6s} decoder, {count} values, {size // 1024:2d} KiB reads: {frames / elapsed:8.0f} "
                  f"frames/s ({len(stream) / elapsed / 2**20:.0f} MiB/s)", file=out)
    return rates


def live(seconds=60.0, rate=1000.0, fmt="binary", out=None):
    """The window on a simulated board through a pseudo-terminal: recording loss, display rate, CPU."""
    import subprocess
    import tempfile

    from tactile_viewer.io.files import load
    from tactile_viewer.qt.main_window import MainWindow

    out = sys.stdout if out is None else out
    app = _application()
    folder = Path(tempfile.mkdtemp(prefix="tactile-bench-"))
    command = [sys.executable, "-m", "tactile_viewer.cli.tactile_sim", "--rate", f"{rate:g}", "--format", fmt,
               "--link", str(folder / "board"), "--layout", str(folder / "layout.json")]
    board = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    board.stdout.readline()
    window = MainWindow()
    window.resize(1280, 820)
    window.show()
    try:
        if not window.live_panel.connect_live(str(folder / "board"), folder / "layout.json", fmt=fmt):
            raise SystemExit("could not connect to the simulated board")
        def flowing():
            return window.live_panel.reader is not None and window.live_panel.reader.stats.received >= 10
        _run_events(60, until=flowing)  # the board computes its contact first
        if not flowing():
            raise SystemExit("no frames from the simulated board")
        drawn, solved = [], []
        window.rendered.connect(lambda: drawn.append(time.perf_counter()))  # on screen, not just solved
        window.model.solved.connect(lambda result: solved.append(result.frame))
        window.live_panel.start_recording(folder / "live.mcap")
        received = window.live_panel.reader.stats.received
        cpu, start = time.process_time(), time.perf_counter()
        _run_events(seconds)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
        received = window.live_panel.reader.stats.received - received
        path = window.live_panel.stop_recording()
        board.terminate()
        _, sim_report = board.communicate(timeout=10)
        sim_cpu = os.times().children_user + os.times().children_system
        recording = load(path)
        sequence = recording.sequence()
        gaps = int(np.sum(np.diff(sequence) - 1))
        print(f"{seconds:g} s at {rate:g} Hz, {fmt}, {recording.grid.size} values per frame, "
              "pseudo-terminal:", file=out)
        print(f"  recorded {len(recording)} frames, sequence gaps {gaps}, repeats "
              f"{int(np.sum(np.diff(sequence) <= 0))}; "
              f"reader lost {window.live_panel.reader.stats.lost}",
              file=out)
        print(f"  display: {len(drawn) / elapsed:.1f} frames on screen per second, "
              f"{len(solved) / elapsed:.1f} solved ({received} received, "
              f"{received / elapsed:.0f} per second)", file=out)
        print(f"  CPU: viewer {100 * cpu / elapsed:.0f}% of one core (all threads), "
              f"simulator {100 * sim_cpu / elapsed:.0f}%", file=out)
        print(f"  simulator: {sim_report.strip()}", file=out)
    finally:
        window.close()
        app.processEvents()
        if board.poll() is None:
            board.terminate()
    return dict(recorded=len(recording), gaps=gaps, display_fps=len(drawn) / elapsed)


def busy_core():
    """A process spinning on a core until the caller ends it (``terminate``, then ``wait``), or ends
    itself (a benchmark killed on the way left two spinning for 10 minutes)."""
    spin = ("import os\nparent = os.getppid()\nwhile os.getppid() == parent:\n"
            "    for _ in range(1000000):\n        pass")
    return subprocess.Popen([sys.executable, "-c", spin])


def _window_solves(window, seconds):
    # the window's own automatic solves during 1x looped playback: each delivered frame's solve_ms
    # (wall, the model's) and stress, and the worker thread's CPU time of every solve it ran
    from tactile_viewer.qt.playback_panel import SPEEDS

    solver, solved, cpu = window.model.reconstructor, [], []
    original = solver.solve

    def timed(*args, **kwargs):  # on the worker thread: its own CPU time (the solve runs there alone)
        start = time.thread_time()
        try:
            return original(*args, **kwargs)
        finally:
            cpu.append(1e3 * (time.thread_time() - start))

    slot = solved.append
    solver.solve = timed  # the instance's own attribute: the class is left alone
    window.model.solved.connect(slot)
    try:
        window.playback.loop_box.setChecked(True)
        window.playback.speed_box.setCurrentIndex(SPEEDS.index(1.0))
        window.playback.set_playing(True)
        _run_events(seconds)
        window.playback.set_playing(False)
        _run_events(10, until=lambda: window.model.wait_idle(0))
        _run_events(0.1)  # the last result's delivery
    finally:
        window.model.solved.disconnect(slot)
        del solver.solve
    return ([s.solve_ms for s in solved if s.auto], cpu,
            [s.stress for s in solved if s.auto])


def _plain_solves(solver, stress):
    # the same frames in the same order, solved one after another on this thread
    wall, cpu = [], []
    for b in stress:
        start_cpu, start = time.thread_time(), time.perf_counter()
        solver.solve(b)
        wall.append(1e3 * (time.perf_counter() - start))
        cpu.append(1e3 * (time.thread_time() - start_cpu))
    return wall, cpu


def _stats(values):
    values = np.asarray(values, dtype=float)
    if not values.size:
        return dict(n=0, median=float("nan"), p95=float("nan"))
    return dict(n=int(values.size), median=float(np.median(values)), p95=float(np.percentile(values, 95)))


def solve_comparison(path, *, seconds=5.0, loads=LOADS, size=(1280, 820), wait_presets=True, out=None):
    """Automatic solve times in the window during playback against a plain loop of the same frames.

    Opens ``path`` in a window of ``size``; unless ``wait_presets`` is
    False, waits until the window has measured its quality presets (a
    separate process that takes a core for seconds). Then for each load in
    ``loads`` (``"idle"``: nothing else started; ``"busy"``: a spinning
    process, :func:`busy_core`, runs throughout): ``seconds`` of 1x looped
    playback with automatic parameters, timed by the window (``solve_ms`` of
    each delivered result, wall; the worker thread's CPU time of each solve),
    then the delivered frames again, in their order, solved in a plain loop
    on this thread by a solver of the window's settings
    (``ViewerModel.build``; its own last-frame state), wall and this thread's
    CPU time.

    Returns
    -------
    dict of str to dict
        Per load: ``window``, ``window_cpu``, ``plain``, ``plain_cpu`` (each
        ``n``, ``median``, ``p95`` in ms) and ``ratio``, ``ratio_p95``,
        ``ratio_cpu`` (in-window over plain, medians and 95th percentiles).
    """
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.qt.presets import PRESET_LIMIT

    out = sys.stdout if out is None else out
    for load in loads:
        if load not in LOADS:
            raise ValueError(f"loads must be among {', '.join(LOADS)}, got {load!r}")
    if not seconds > 0:
        raise ValueError(f"seconds must be > 0, got {seconds!r}")
    app, window = _open_window(path, size, "benchmarks.viewer_speed")
    results = {}
    try:
        model = window.model
        grid = model.grid
        settled = "not waited for"
        if wait_presets and grid.size <= PRESET_LIMIT:
            try:
                _wait(window.presets.measured, timeout=300)
                settled = "measured before"
            except TimeoutError:
                settled = "still measuring after 300 s"
        window.parameters.auto_box.setChecked(True)
        for _ in range(20):
            app.processEvents()
        plain = ViewerModel.build(grid, model.kernel, model.configuration)
        recording = model.recording
        print(f"{Path(path).name}: {grid.shape[1]}x{grid.shape[0]} grid, {len(recording)} frames; solves "
              f"in the window (1x looped playback, {seconds:g} s, automatic parameters) against the same "
              f"frames in a plain loop ({type(plain).__name__}, {model.kernel} kernel); quality presets "
              f"{settled}",
              file=out)
        print(f"  {'load':<5} {'where':<7} {'solves':>6} {'wall median':>11} {'p95':>7} "
              f"{'CPU median':>10} {'p95':>7}  (ms)", file=out)
        for load in loads:
            spinner = busy_core() if load == "busy" else None
            try:
                if spinner is not None:
                    time.sleep(0.5)  # the spinner has started
                window_ms, window_cpu, stress = _window_solves(window, seconds)
                plain_ms, plain_cpu = _plain_solves(plain, stress)
            finally:
                if spinner is not None:
                    spinner.terminate()
                    spinner.wait(10)
            r = dict(window=_stats(window_ms), window_cpu=_stats(window_cpu), plain=_stats(plain_ms),
                     plain_cpu=_stats(plain_cpu))
            r["ratio"] = r["window"]["median"] / r["plain"]["median"]
            r["ratio_p95"] = r["window"]["p95"] / r["plain"]["p95"]
            r["ratio_cpu"] = r["window_cpu"]["median"] / r["plain_cpu"]["median"]
            results[load] = r
            for where, wall, cpu in (("window", r["window"], r["window_cpu"]),
                                     ("plain", r["plain"], r["plain_cpu"])):
                print(f"  {load:<5} {where:<7} {wall['n']:6d} {wall['median']:11.2f} {wall['p95']:7.2f} "
                      f"{cpu['median']:10.2f} {cpu['p95']:7.2f}", file=out)
            print(f"  {load:<5} window / plain: wall median {r['ratio']:.2f}x, p95 {r['ratio_p95']:.2f}x; "
                  f"CPU median {r['ratio_cpu']:.2f}x", file=out)
    finally:
        window.close()
        app.processEvents()
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.viewer_speed",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("recording", nargs="?", default=str(SAMPLE))
    parser.add_argument("--count", type=int, default=40, help="slider moves per measurement")
    parser.add_argument("--seconds", type=float, default=5.0, help="playback time per speed")
    parser.add_argument("--live", type=float, metavar="SECONDS", default=0.0,
                        help="also run the live mode this long at 1 kHz through a pseudo-terminal")
    parser.add_argument("--solve-samples", nargs="*", default=[str(p) for p in SOLVE_SAMPLES],
                        help="recordings whose solves in the window are timed against a plain loop "
                             "(default the two- and three-contact samples; none: skip)")
    parser.add_argument("--solve-seconds", type=float, default=5.0,
                        help="playback time per recording and load for those solves (default 5)")
    parser.add_argument("--loads", nargs="+", choices=LOADS, default=list(LOADS),
                        help="the other core idle, busy (a spinning process) or both (default)")
    args = parser.parse_args(argv)
    if not args.solve_seconds > 0:
        parser.error(f"--solve-seconds must be > 0, got {args.solve_seconds:g}")
    missing = [name for name in args.solve_samples if not Path(name).is_file()]
    if missing:
        parser.error(f"--solve-samples: no such file: {', '.join(missing)}")
    print("serial decoders")
    decoder_throughput()
    run(args.recording, count=args.count, seconds=args.seconds)
    for sample in args.solve_samples:
        solve_comparison(sample, seconds=args.solve_seconds, loads=args.loads)
    if args.live:
        live(args.live)


if __name__ == "__main__":
    main()

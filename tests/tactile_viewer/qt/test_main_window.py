"""The real window under Xvfb: samples, sliders, Auto, errors, exports, playback, closing."""

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from tactile_viewer.io.files import load
from tactile_viewer.io.forces import load_forces
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.force_tables import reconstruct_frames

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"

NAMES = ["hertz_static.npz", "hertz_shear_turning.npz", "flat_punch_shear.npz", "two_contacts.npz"]


def arrow_points(window):
    return np.array(window.scene.arrows.points, copy=True)


@pytest.mark.parametrize("name", NAMES)
def test_window_opens_on_each_sample(window, qtbot, name):
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / name)
    assert window.model.last is not None and window.model.last.frame == 0
    assert window.scene.arrows.n_points > 0
    assert name in window.windowTitle()
    # frames are numbered from 0 everywhere: window, exports, sidecars, --frame, --report
    assert "frame 0 (of 0-" in window.status.text() and "efficiency" in window.status.toolTip()
    assert window.playback.time_label.text().startswith("frame 0 (of 0-")


def test_moving_either_slider_changes_the_arrows(opened, qtbot):
    before = arrow_points(opened)
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.parameters.ratio_slider.setValue(80)
    assert not opened.model.auto and not opened.parameters.auto_box.isChecked()
    assert opened.model.shear_ratio == pytest.approx(0.8)
    assert opened.parameters.ratio_spin.value() == pytest.approx(0.8)
    after_ratio = arrow_points(opened)
    assert after_ratio.shape != before.shape or not np.allclose(after_ratio, before)
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.parameters.direction_slider.setValue(-90)
    assert opened.model.last.result.shear_direction == pytest.approx(-math.pi / 2)
    after_direction = arrow_points(opened)
    assert after_direction.shape != after_ratio.shape or not np.allclose(after_direction, after_ratio)


class Held:
    """The window's solver, held ``seconds`` per solve (longer than the window's settle time)."""

    def __init__(self, inner, seconds):
        import threading

        self.inner, self.grid, self.kernel, self.seconds = inner, inner.grid, inner.kernel, seconds
        self.running = threading.Event()

    def solve(self, stress, **kwargs):
        import time

        self.running.set()
        time.sleep(self.seconds)
        return self.inner.solve(stress, **kwargs)

    def solve_normal(self, stress):
        return self.inner.solve_normal(stress)


def test_a_slider_drag_solves_only_the_latest_value(opened, qtbot):
    model = opened.model
    with qtbot.waitSignal(opened.ready, timeout=20000):
        model.set_source(model.source, Held(model.reconstructor, 0.5))
    solved = []
    model.solved.connect(solved.append)
    for value in range(10, 60, 5):  # ten moves, each faster than a solve
        opened.parameters.ratio_slider.setValue(value)
    qtbot.waitUntil(lambda: bool(solved) and solved[-1].result.shear_ratio == pytest.approx(0.55), timeout=5000)
    # each move waits at most the window's settle time (0.03 s) for its solve, so the ten moves take
    # about 0.3 s: the worker solves the first and the newest, perhaps one in between, never all ten
    assert len(solved) <= 3 and model.worker_stats()["dropped"] >= 7


def test_the_window_keeps_responding_while_a_solve_runs(opened, qtbot):
    import time

    from PyQt6 import QtCore

    model = opened.model
    # The time plots' background series pass is kept out of this test, which is about the solve:
    # with it running, the GUI thread stalls for up to 160 ms at a time on this 2-core VM (seen on
    # de78a2d in 2 of 4 quiet runs, and in every run since the per-contact series; open work).
    opened.time_plots.hide()
    held = Held(model.reconstructor, 1.0)
    with qtbot.waitSignal(opened.ready, timeout=20000):
        model.set_source(model.source, held)
    held.running.clear()
    ticks = []
    timer = QtCore.QTimer(interval=10)
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    timer.start()
    try:
        opened.playback.step(1)
        assert held.running.wait(5)
        start = time.perf_counter()
        qtbot.waitUntil(lambda: model.last.frame == 1, timeout=5000)
    finally:
        timer.stop()
    during = [t for t in ticks if start <= t <= start + 1.0]
    # A GUI thread blocked by the solve would not tick during it. One that is free still stops
    # while it draws the 3-D view: a render takes 70 to 100 ms under Xvfb's software GL on this
    # 2-core VM (sampled: the GUI thread inside paintGL while the timer was silent), which failed
    # 2 of 7 runs of a 0.2 s hold. So the hold is 1 s, and at least a quarter of its 100 ticks.
    assert len(during) >= 25, ticks
    assert model.last.frame == 1


def test_auto_moves_the_sliders_to_the_maximum(opened, qtbot):
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.parameters.ratio_slider.setValue(0)
    assert opened.parameters.ratio_slider.value() == 0
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.parameters.auto_box.setChecked(True)
    found = opened.model.last.result
    assert found.shear_detected and found.shear_ratio > 0.2  # the sample has 0.4
    assert opened.parameters.ratio_slider.value() == round(found.shear_ratio * 100)
    assert opened.parameters.direction_slider.value() == round(math.degrees(found.shear_direction))


def test_a_malformed_file_shows_the_error_and_keeps_the_state(opened, tmp_path):
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"definitely not an archive")
    shown = opened.model.recording
    assert not opened.open(bad)
    assert opened.model.recording is shown
    assert "broken.npz" in opened.errors.take()[0][1]
    mismatched = tmp_path / "short.csv"
    mismatched.write_text("# nx=4\n# ny=4\n# pitch=0.002\n# thickness=0.002\n0.0, 1, 2, 3\n")
    assert not opened.open(mismatched)
    assert "declares a 4x4 grid (16 taxels) but its frames have 3 values each" in opened.errors.take()[0][1]
    assert opened.model.recording is shown and opened.scene.arrows.n_points > 0


def overflowing_csv(path, units):
    # a 4x4 recording whose frame 2 holds 1e308 in one taxel: beyond a float once in pascals (kPa),
    # or finite but overflowing every product the solver makes with it (Pa)
    rows = ["# nx=4", "# ny=4", "# pitch=0.002", "# thickness=0.002", f"# units={units}"]
    for k in range(5):
        values = [1.0] * 16
        if k == 2:
            values[3] = 1e308
        rows.append(", ".join(map(repr, [0.01 * k, *values])))
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.series
def test_a_recording_whose_values_overflow_leaves_the_window_working(opened, qtbot, tmp_path):
    # In kPa the value is no number once in pascals: the file is refused, naming frame and taxel.
    shown = opened.model.recording
    assert not opened.open(overflowing_csv(tmp_path / "kpa.csv", "kPa"))
    assert "frame 2 taxel 3 is not a finite number in pascals" in opened.errors.take()[-1][1]
    assert opened.model.recording is shown
    # In Pa it is finite: the window shows the recording (its display scales from the frames that
    # stay finite), and the next recording opens as any other (it failed with "list.remove(x): x
    # not in list" on every later open: the old source was dropped before the scales were made)
    with qtbot.waitSignal(opened.ready, timeout=20000):
        assert opened.open(overflowing_csv(tmp_path / "pa.csv", "Pa"))
    assert opened.model.recording is not shown and opened.model.grid.size == 16
    assert np.isfinite(opened.model.display.arrow_scale) and opened.model.display.arrow_scale > 0
    # the frame itself: refused by the solver, said in the status bar; the time plots leave it out
    with qtbot.waitSignal(opened.model.solve_failed, timeout=10000) as failed:
        opened.model.set_frame(2)
    assert "stress must be at most 1e+100 Pa in magnitude, got 1e+308 at taxel(s) [3]" in failed.args[0]
    qtbot.waitUntil(lambda: "refused by the solver" in opened.time_plots.status.text(), timeout=20000)
    assert "4 frames" in opened.time_plots.status.text() and "first frame 2" in opened.time_plots.status.text()
    with qtbot.waitSignal(opened.ready, timeout=20000):
        assert opened.open(Path(__file__).resolve().parents[3] / "sample_data" / "hertz_static.npz")
    assert opened.model.grid.size == 256 and not opened.errors  # no dialog: the status bar said it
    assert [r.getMessage() for r in opened.errors.take_logged()] == ["solve of frame 2 failed"]


def test_a_recording_cut_short_says_so_when_it_opens(window, qtbot, tmp_path):
    # it opened with no word that its end was lost
    cut = tmp_path / "cut.csv"
    cut.write_text("# nx=2\n# ny=2\n# pitch=0.002\n# thickness=0.002\n0.0, 1, 2, 3, 4\n0.1, 1, 2, 3, 4\n0.2, 1, 2")
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(cut)
    assert "Recording cut short: cut.csv ends at its last complete chunk or row" in window.statusBar().currentMessage()
    assert len(window.model.recording) == 2


def test_a_damaged_recording_says_what_is_lost_when_it_opens(window, qtbot, tmp_path):
    from tests.tactile_viewer.io.test_mcap_reader import chunk_positions, flipped, tared_recording

    path = tmp_path / "damaged.mcap"
    tared_recording(path)
    position = chunk_positions(path)[1]
    flipped(path, position, 0x20)
    flipped(path, position + 200)  # chunk 1 unreadable, found through its record, its frames lost
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(path)
    assert window.statusBar().currentMessage() == (
        f"Warning: Recording damaged: damaged.mcap: frames 6 to 10 as recorded (5 frames, t 0.600 to 1.000 s) "
        f"are lost: their chunk at byte {position} is damaged")
    assert window.windowTitle() == "tactile-viewer - damaged.mcap (damaged)" and len(window.model.recording) == 25


def read_png(path):
    image = pv.read(path)
    name = image.point_data.keys()[0]
    dims = image.dimensions
    return np.asarray(image.point_data[name]).reshape(dims[1], dims[0], -1)


@pytest.mark.parametrize("scale", [1, 2])
def test_screenshot_export_has_the_size_asked_and_is_not_blank(opened, tmp_path, scale):
    path = opened.exports.export_screenshot(tmp_path / "shot.png", scale=scale)
    pixels = read_png(path)
    width, height = opened.plotter.window_size
    assert pixels.shape[:2] == (height * scale, width * scale)
    assert pixels[..., :3].std() > 10  # not one flat colour
    sidecar = json.loads(path.with_name(path.name + ".view.json").read_text())
    assert sidecar["frame"] == 0 and sidecar["recording"].endswith("hertz_shear_turning.npz")
    assert sidecar["scale"] == scale and sidecar["mode"] == "auto"
    assert sidecar["poisson_ratio"] == 0.5 and sidecar["sensor_size"] == 0.0  # the sample's material


@pytest.mark.series
def test_a_window_image_shows_the_scene_the_time_plots_and_the_controls(opened, qtbot, tmp_path):
    from PyQt6 import QtCore

    plots = opened.time_plots
    qtbot.waitUntil(lambda: plots.series is not None and len(plots.series.frame) == len(opened.model.recording),
                    timeout=30000)
    path = opened.exports.export_screenshot(tmp_path / "window.png", window=True)
    pixels = read_png(path)
    ratio = opened.devicePixelRatioF()
    assert pixels.shape[:2] == (round(opened.height() * ratio), round(opened.width() * ratio))
    # the scene's region is drawn (not a black or blank GL hole), and so is the plots' region
    for widget in (opened.plotter.interactor, plots.graphics):
        top_left = widget.mapTo(opened, QtCore.QPoint(0, 0))
        region = pixels[top_left.y():top_left.y() + widget.height(), top_left.x():top_left.x() + widget.width(), :3]
        assert region.std() > 10, type(widget).__name__
    sidecar = json.loads(path.with_name(path.name + ".view.json").read_text())
    assert sidecar["content"] == "window" and sidecar["frame"] == 0
    with pytest.raises(ValueError, match="a window image is taken as shown: scale must be 1"):
        opened.exports.export_screenshot(tmp_path / "big.png", window=True, scale=2)
    assert not (tmp_path / "big.png").exists()


def test_screenshot_honours_the_transparent_option(opened, tmp_path):
    solid = read_png(opened.exports.export_screenshot(tmp_path / "solid.png"))
    clear = read_png(opened.exports.export_screenshot(tmp_path / "clear.png", transparent=True))
    assert clear.shape[2] == 4 and clear[0, 0, 3] == 0  # the corner is background
    assert solid.shape[2] == 3 or solid[0, 0, 3] == 255


def test_force_export_round_trips(opened, qtbot, tmp_path):
    recording = opened.model.recording
    for suffix in (".npz", ".csv"):
        path = tmp_path / f"all{suffix}"
        with qtbot.waitSignal(opened.tasks.finished, timeout=30000):
            opened.exports.export_forces(path, whole=True)
        back = load_forces(path)
        expected = reconstruct_frames(recording, opened.model.reconstructor)
        assert back["forces"].shape == (len(recording), recording.grid.size, 3)
        np.testing.assert_allclose(back["forces"], expected.forces, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(back["shear_ratio"], expected.shear_ratio, rtol=1e-6, atol=1e-9)
    with qtbot.waitSignal(opened.tasks.finished, timeout=30000):
        opened.exports.export_forces(tmp_path / "one.npz", whole=False)
    one = load_forces(tmp_path / "one.npz")
    np.testing.assert_allclose(one["forces"][0], opened.model.last.result.forces, rtol=1e-9, atol=1e-15)


def test_playback_advances(opened, qtbot):
    frames = []
    opened.model.frame_changed.connect(frames.append)
    opened.playback.speed_box.setCurrentIndex(2)  # 1x: 60 frames over 2 s
    opened.playback.set_playing(True)
    qtbot.waitUntil(lambda: len(frames) >= 5, timeout=10000)
    opened.playback.set_playing(False)
    assert frames == sorted(frames) and frames[-1] > 4
    # a frame due while the last was being drawn is taken (and the slider moved) with the next paint
    qtbot.waitUntil(lambda: opened.playback.frame_slider.value() == opened.model.frame, timeout=5000)


@pytest.mark.parametrize("slow", [False, True])
def test_while_playing_the_slider_moves_with_the_frame_drawn_and_paused_at_once(opened, qtbot, slow):
    # playing, a frame taken moves the slider only with its result, in that frame's repaint (moved
    # before the solve, it cost the window a repaint of its own on every frame). Slow: each solve
    # outlasts the window's wait for it, so the next frame is taken before its result is drawn (as
    # on a loaded machine): the slider still shows each frame drawn.
    if slow:
        solver, solve = opened.model.reconstructor, opened.model.reconstructor.solve

        def slowly(*args, **kwargs):
            time.sleep(0.06)
            return solve(*args, **kwargs)
        solver.solve = slowly  # the instance's own attribute, gone with the window's solver
    slider = opened.playback.frame_slider
    at_take, at_solved = [], []
    opened.model.frame_changed.connect(lambda index: at_take.append((index, slider.value())))
    opened.model.solved.connect(lambda solved: at_solved.append((solved.frame, slider.value())))
    opened.playback.speed_box.setCurrentIndex(2)  # 1x
    opened.playback.set_playing(True)
    qtbot.waitUntil(lambda: len(at_solved) >= 5 and len(at_take) >= 5, timeout=10000)
    playing = list(at_take)
    opened.playback.set_playing(False)
    assert all(value != index for index, value in playing)  # not yet moved when the frame is taken
    assert all(value == frame for frame, value in at_solved)  # moved with its result
    # paused: the frame the recording stopped at is taken, even one that waited for the last paint
    assert opened.model.current.index == opened.model.frame == slider.value()
    # paused, a step moves it at once, before the solve (slow: also when the pause came while a
    # frame waited for the last result's paint; that step once took no frame until the paint)
    at_take.clear()
    target = (opened.model.frame + 7) % len(opened.model.recording)
    opened.model.set_frame(target)
    assert at_take == [(target, target)]
    qtbot.waitUntil(lambda: opened.model.last.frame == target, timeout=10000)
    assert slider.value() == target


def test_a_hidden_window_goes_on_solving_playback(opened, qtbot):
    # a frame waits for the last result's paint (pace), and a hidden or minimized window paints
    # nothing: before, playback (and a live board, with its forces published over LSL) stopped solving
    # at the first frame while the window was hidden
    solved = []
    opened.hide()
    opened.model.solved.connect(lambda result: solved.append(result.frame))
    opened.playback.speed_box.setCurrentIndex(2)  # 1x
    opened.playback.set_playing(True)
    qtbot.waitUntil(lambda: len(set(solved)) >= 5, timeout=10000)
    opened.playback.set_playing(False)
    assert solved == sorted(solved)
    opened.show()
    with qtbot.waitSignal(opened.rendered, timeout=5000):  # shown again, it draws
        opened.playback.step(1)


def test_step_and_kernel_switch(opened, qtbot):
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.playback.step(3)
    assert opened.model.frame == 3
    with qtbot.waitSignal(opened.ready, timeout=20000):
        opened.parameters.kernel_box.setCurrentText("point")
    assert opened.model.kernel == "point" and opened.model.reconstructor.kernel == "point"


def test_display_toggles(opened, qtbot):
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.display_panel.threshold_spin.setValue(1e5)  # hide every arrow
    assert opened.scene.arrows.n_points == 0
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        opened.display_panel.map_box.setCurrentIndex(1)
    assert opened.model.display.map == "stress"
    np.testing.assert_allclose(opened.scene._map.cell_data["kPa"], opened.model.last.stress / 1e3)


def test_closing_the_window_leaks_no_plotter(qtbot, no_plotter_leak):
    from tactile_viewer.qt.main_window import MainWindow

    win = MainWindow()
    qtbot.addWidget(win)
    win.show()
    with qtbot.waitSignal(win.ready, timeout=20000):
        win.show_recording(load(SAMPLES / "hertz_static.npz"))
    win.close()


def test_an_irregular_layout_is_drawn_taxel_by_taxel(window, qtbot):
    from solver import SensorGrid, loads
    from tactile_viewer.io.recording import Recording

    # a 6x6 grid with every other row shifted by half a pitch (a staggered skin)
    pitch = 2e-3
    ix, iy = np.meshgrid(np.arange(6), np.arange(6))
    positions = np.column_stack([(ix + 0.5 * (iy % 2)).ravel(), iy.ravel()]) * pitch
    grid = SensorGrid(positions - positions.mean(axis=0), pitch, pitch, (36,))
    contact = loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0, shear_ratio=0.3))
    recording = Recording(grid, np.stack([contact.stress] * 3), [0.0, 0.1, 0.2], description="staggered")
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.show_recording(recording)
    assert window.scene._map.n_cells == 36
    centres = window.scene._map.cell_centers().points[:, :2] / 1e3
    np.testing.assert_allclose(centres, grid.positions, atol=1e-12)
    assert window.scene.arrows.n_points > 0


def test_looped_playback_wraps_to_the_start(opened, qtbot):
    frames = []
    opened.model.frame_changed.connect(frames.append)
    opened.playback.loop_box.setChecked(True)
    opened.playback.speed_box.setCurrentIndex(4)  # 4x: the 2 s sample lasts 0.5 s
    opened.playback.set_playing(True)
    qtbot.waitUntil(lambda: any(b < a for a, b in zip(frames, frames[1:], strict=False)), timeout=10000)
    assert opened.playback.play_button.isChecked()  # still playing after the wrap
    opened.playback.set_playing(False)


@pytest.mark.presets
def test_a_settled_geometry_s_presets_are_measured_by_themselves(window, qtbot):
    # no call: once a recording of a small skin has been shown a second, its presets are measured
    # in the background and offered in the quality box
    with qtbot.waitSignal(window.presets.measured, timeout=90000):
        with qtbot.waitSignal(window.ready, timeout=20000):
            assert window.open(Path(__file__).resolve().parents[3] / "sample_data" / "hertz_static.npz")
    assert window.parameters.quality_box.count() > 1


def test_quality_presets_are_measured_for_the_geometry_and_applied(opened, qtbot):
    with qtbot.waitSignal(opened.presets.measured, timeout=60000):
        opened.presets.measure()
    labels = [opened.parameters.quality_box.itemText(k) for k in range(opened.parameters.quality_box.count())]
    assert labels[0].startswith("standard") and [label.split(":")[0] for label in labels[1:]] == [
        "fast", "balanced", "accurate"]
    assert all("ms/frame" in label and "% of |F|" in label for label in labels[1:])
    fast = opened.parameters.quality_box.itemData(1)
    with qtbot.waitSignal(opened.ready, timeout=20000):
        opened.parameters.quality_box.setCurrentIndex(1)
    assert opened.model.configuration == fast
    panel = opened.parameters
    if fast.path == "normal":  # measured: the normal-only path is the front's fastest point
        assert opened.model.last.result.normal_only
        # it cannot honour the shear controls: they are disabled and the panel says why
        assert not panel.ratio_slider.isEnabled() and not panel.auto_box.isEnabled()
        assert panel.shear_note.isVisible() and "solves normal forces only" in panel.shear_note.text()
    with qtbot.waitSignal(opened.ready, timeout=20000):
        opened.parameters.quality_box.setCurrentIndex(0)
    assert opened.model.configuration is None
    assert panel.ratio_slider.isEnabled() and panel.auto_box.isEnabled() and not panel.shear_note.isVisible()


def test_separate_contacts_are_reported_each_with_its_parameters(window, qtbot):
    from solver import SensorGrid, loads
    from solver.quality import Configuration
    from tactile_viewer.io.recording import Recording

    grid = SensorGrid.regular(40, 40, 2e-3, 2e-3)
    contacts = [loads.hertz((-20e-3, -20e-3), 5e-3, 1.0, shear_ratio=0.4, shear_direction=0.5),
                loads.hertz((20e-3, 20e-3), 5e-3, 1.0, shear_ratio=0.4, shear_direction=-2.0)]
    stress = loads.simulate(grid, contacts).stress
    window.model.configuration = Configuration("region of interest", path="region")
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.show_recording(Recording(grid, np.stack([stress, stress]), [0.0, 0.1]))
    result = window.model.last.result
    assert len(result.contacts) == 2
    directions = sorted(round(math.degrees(c.shear_direction)) for c in result.contacts)
    assert abs(directions[0] - math.degrees(-2.0)) < 10 and abs(directions[1] - math.degrees(0.5)) < 10
    assert "#1 mu" in window.status.text() and "#2 mu" in window.status.text()


def test_the_status_line_fits_a_1280_px_window_with_three_contacts(window, qtbot):
    # with two contacts it was cut at the right edge; "efficiency nan" showed on the fast preset and
    # empty frames; efficiency, residual and condition were jargon without a word of explanation
    window.resize(1280, 800)
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "three_contacts.npz")
    qtbot.waitUntil(lambda: len(window.model.last.result.contacts) == 3, timeout=10000)
    text, tip = window.status.text(), window.status.toolTip()
    assert "#1 " in text and "#2 " in text and "#3 " in text and "nan" not in text
    room = window.statusBar().width() - window.readout_label.sizeHint().width()
    assert window.status.fontMetrics().horizontalAdvance(text) < room, (text, room)
    assert "efficiency" in tip and "explains" in tip and "residual" in tip and "condition" in tip
    assert tip.count(" mN") >= 3  # every contact, with its force
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.show_recording(Recording(window.model.grid, np.zeros((2, window.model.grid.size)), [0.0, 0.1]))
    assert "nan" not in window.status.text() and "efficiency: none" in window.status.toolTip()


def test_kernels_come_from_the_solver_with_its_default_first(window):
    from solver.kernels import KERNELS

    assert [window.parameters.kernel_box.itemText(k) for k in range(window.parameters.kernel_box.count())] == list(KERNELS)
    assert window.parameters.kernel_box.currentText() == KERNELS[0] == window.model.kernel
    assert "layer: elastomer layer bonded to a rigid hull" in window.parameters.kernel_box.toolTip()


def test_the_geometry_shown_names_poisson_ratio_and_taxel_size(window, qtbot):
    from solver import SensorGrid
    from tactile_viewer.io.recording import Recording

    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3, poisson_ratio=0.45, sensor_size=1e-3)
    r2 = (grid.positions**2).sum(axis=1)
    stress = 5e3 * np.exp(-r2 / (3e-3) ** 2)  # a smooth press in the middle, pascals
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.show_recording(Recording(grid, np.stack([stress, stress]), [0.0, 0.1], description="soft"))
    assert window.parameters.geometry_label.text() == "6x5 taxels, pitch 2 mm, thickness 2 mm, nu 0.45, taxel 1 mm"
    assert window.model.reconstructor.grid.poisson_ratio == 0.45  # solved on the recording's material


@pytest.mark.parametrize("where", ["missing folder", "file as folder"])
def test_a_screenshot_that_cannot_be_written_is_reported(opened, tmp_path, where, monkeypatch):
    from PyQt6 import QtWidgets

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    target = (tmp_path / "gone" / "shot.png") if where == "missing folder" else (blocker / "shot.png")
    with pytest.raises(OSError, match="the folder does not exist"):
        opened.exports.export_screenshot(target)
    # through the menu's slot: reported, not raised (an exception there used to end the app)
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda self: QtWidgets.QDialog.DialogCode.Accepted)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(target), "")))
    opened.exports.screenshot_dialog()
    assert opened.errors.take()[-1] == ("Cannot save screenshot", f"{target}: the folder does not exist")
    assert not target.exists()


def test_leaving_auto_from_one_slider_keeps_the_other_as_shown(opened, qtbot):
    panel = opened.parameters
    found = opened.model.last.result  # Auto is on after opening
    assert opened.model.auto and panel.direction_spin.value() == pytest.approx(
        math.degrees(found.shear_direction), abs=0.05)
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        panel.ratio_slider.setValue(round(found.shear_ratio * 100) + 5)
    # the direction the user saw is the one solved, not an old manual value they could not see
    assert not opened.model.auto
    assert opened.model.shear_direction == pytest.approx(found.shear_direction)
    assert opened.model.last.result.shear_direction == pytest.approx(found.shear_direction)
    assert panel.direction_spin.value() == pytest.approx(math.degrees(found.shear_direction), abs=0.05)


def test_unticking_auto_starts_from_what_auto_found(opened, qtbot):
    # it jumped to the manual values set before (0 and 0 deg for a newcomer): the shear fell from
    # 401 to 3 mN on the screen
    panel, model = opened.parameters, opened.model
    found = model.last.result
    assert model.auto and found.shear_ratio > 0.2 and (model.shear_ratio, model.shear_direction) == (0.0, 0.0)
    with qtbot.waitSignal(opened.rendered, timeout=5000):
        panel.auto_box.setChecked(False)
    assert not model.auto
    assert (model.shear_ratio, model.shear_direction) == (pytest.approx(found.shear_ratio),
                                                          pytest.approx(found.shear_direction))
    shown = model.last.result
    assert not model.last.auto and shown.shear_ratio == pytest.approx(found.shear_ratio)
    tangential = lambda r: math.hypot(*r.total_force[:2])  # noqa: E731
    assert tangential(shown) == pytest.approx(tangential(found), rel=0.1)
    assert panel.ratio_slider.value() == round(found.shear_ratio * 100)


def test_closing_while_a_recording_is_factored_leaves_nothing_running(window, qtbot):
    import threading

    window.show_recording(load(SAMPLES / "hertz_static.npz"))  # factoring runs in a task
    window.close()
    qtbot.waitUntil(lambda: not window.tasks.tasks, timeout=20000)  # the task's result arrives after the close
    assert window.model.recording is None
    assert not [t for t in threading.enumerate() if t.name == "tactile-solver" and t.is_alive()]


def test_a_screenshot_before_any_frame_is_refused_cleanly(window, tmp_path):
    with pytest.raises(ValueError, match="no frame has been reconstructed yet"):
        window.exports.export_screenshot(tmp_path / "early.png")
    assert not (tmp_path / "early.png").exists()


def test_a_quality_preset_does_not_follow_the_user_to_another_geometry(opened, qtbot):
    from solver import SensorGrid
    from solver.quality import Configuration
    from tactile_viewer.io.recording import Recording

    opened.model.configuration = Configuration("normal only", path="normal")  # measured on the sample
    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3)
    stress = 5e3 * np.exp(-(grid.positions**2).sum(axis=1) / (3e-3) ** 2)
    with qtbot.waitSignal(opened.ready, timeout=20000):
        opened.show_recording(Recording(grid, np.stack([stress, stress]), [0.0, 0.1]))
    assert opened.model.configuration is None and not opened.model.last.result.normal_only
    assert opened.parameters.quality_box.count() == 1  # no presets of another skin on offer


def test_a_passing_message_is_shown_over_the_status_line(opened, qtbot, tmp_path):
    path = opened.exports.export_screenshot(tmp_path / "shot.png")
    bar = opened.statusBar()
    assert bar.currentMessage() == f"saved {path}"
    qtbot.waitUntil(lambda: not opened.status.isVisible(), timeout=2000)  # the message, not under it
    bar.clearMessage()
    qtbot.waitUntil(opened.status.isVisible, timeout=2000)  # then the solve's status line again


def test_a_window_screenshot_leaves_the_layout_of_the_same_stem_alone(opened, tmp_path, monkeypatch):
    from PyQt6 import QtWidgets

    # the tester's case: board.png's sidecar was board.json, and overwrote the sensor layout
    layout = tmp_path / "board.json"
    layout.write_bytes(b'{"nx": 16, "ny": 16, "pitch": 0.002, "thickness": 0.002}\n')
    before = layout.read_bytes()
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda self: QtWidgets.QDialog.DialogCode.Accepted)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(tmp_path / "board.png"), "")))
    opened.exports.screenshot_dialog()
    assert opened.errors == []
    assert layout.read_bytes() == before
    assert read_png(tmp_path / "board.png")[..., :3].std() > 10
    sidecar = json.loads((tmp_path / "board.png.view.json").read_text())
    assert sidecar["tactile_viewer_sidecar"] == 1 and sidecar["frame"] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.json", "board.png", "board.png.view.json"]


def test_a_window_screenshot_replaces_its_own_earlier_sidecar(opened, tmp_path):
    from tactile_viewer.io.sidecar import sidecar_path

    first = opened.exports.export_screenshot(tmp_path / "shot.png", scale=1)
    assert json.loads(sidecar_path(first).read_text())["scale"] == 1
    again = opened.exports.export_screenshot(tmp_path / "shot.png", scale=2)
    assert json.loads(sidecar_path(again).read_text())["scale"] == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png", "shot.png.view.json"]


def test_a_window_screenshot_keeps_the_image_but_not_an_unrelated_sidecar_name(opened, tmp_path, monkeypatch):
    import re

    from PyQt6 import QtWidgets

    from tactile_viewer.io.sidecar import SidecarConflict

    image = tmp_path / "board.png"
    foreign = tmp_path / "board.png.view.json"
    foreign.write_bytes(b"board 7: recalibrated on Tuesday\n")
    before = foreign.read_bytes()
    found = (rf"{re.escape(str(foreign))}: the sidecar of board\.png was not written: a sidecar replaces only "
             r"an earlier sidecar \(a JSON object with the key 'tactile_viewer_sidecar'\), and this file is not JSON")
    with pytest.raises(SidecarConflict, match=f"^{found}$"):
        opened.exports.export_screenshot(image)
    assert foreign.read_bytes() == before
    assert read_png(image)[..., :3].std() > 10  # the image asked for is written
    image.unlink()
    # through the menu: the image is saved, the sidecar skipped, and the message says both
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda self: QtWidgets.QDialog.DialogCode.Accepted)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(image), "")))
    opened.exports.screenshot_dialog()
    title, text = opened.errors.take()[-1]
    assert title == "Screenshot saved without its sidecar"
    assert re.fullmatch(f"{re.escape(str(image))} was saved; {found}", text), text
    assert foreign.read_bytes() == before
    assert read_png(image)[..., :3].std() > 10


def test_a_png_name_added_to_the_name_picked_never_replaces_a_file(opened, tmp_path, monkeypatch):
    from PyQt6 import QtWidgets

    # "board" picked: the save dialog asked about "board", not about the board.png the export would write
    unrelated = tmp_path / "board.png"
    unrelated.write_bytes(b"not ours\n")
    picked = tmp_path / "board"
    with pytest.raises(FileExistsError, match=r"not replaced: the image would be board\.png \(the name picked, "
                                              r"ending in '\.png'\), which exists and is not the file picked"):
        opened.exports.export_screenshot(picked)
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda self: QtWidgets.QDialog.DialogCode.Accepted)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName", staticmethod(lambda *a, **k: (str(picked), "")))
    opened.exports.screenshot_dialog()
    assert opened.errors.take()[-1] == ("Cannot save screenshot",
                                 f"{picked}: not replaced: the image would be board.png (the name picked, "
                                 "ending in '.png'), which exists and is not the file picked")
    assert unrelated.read_bytes() == b"not ours\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.png"]
    # a free name: saved under it, the sidecar after the full image name
    assert opened.exports.export_screenshot(tmp_path / "fresh") == tmp_path / "fresh.png"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.png", "fresh.png", "fresh.png.view.json"]
    # a case variant of the ending is a derived name too (pyvista writes only ".png")
    (tmp_path / "shout.png").write_bytes(b"not ours either\n")
    with pytest.raises(FileExistsError, match=r"the image would be shout\.png .* not the file picked"):
        opened.exports.export_screenshot(tmp_path / "shout.PNG")
    assert (tmp_path / "shout.png").read_bytes() == b"not ours either\n"


def test_the_tare_of_a_live_recording_is_retaken_and_cleared_from_the_menu(window, qtbot, tmp_path):
    from tactile_viewer.io.files import load
    from tactile_viewer.io.mcap_writer import Recorder
    from tactile_viewer.io.recording import StressCalibration, Tare

    sample = load(SAMPLES / "hertz_shear_turning.npz")
    path = tmp_path / "take.mcap"
    offset = np.full(sample.grid.size, 500.0)  # pascals of a board's zero
    recorder = Recorder(path, sample.grid, dtype="float64",
                        calibration=StressCalibration("Pa", 1.0, 0.0, (Tare(0, offset),)))
    for k in range(10):
        recorder.add(k, float(sample.t[k]), np.asarray(sample.frames[k]) + offset)
    recorder.close()
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(path)
    assert all(action.isEnabled() for action in window.tare_actions.values())
    np.testing.assert_allclose(window.model.last.stress, sample.frames[0], atol=1e-9)
    with qtbot.waitSignal(window.model.solved, timeout=10000):
        window.tare_actions["clear"].trigger()
    np.testing.assert_allclose(window.model.last.stress, sample.frames[0] + offset, atol=1e-9)
    assert "showing no tare; the file keeps its raw values" in window.statusBar().currentMessage()
    with qtbot.waitSignal(window.model.solved, timeout=10000):
        window.tare_actions["here"].trigger()
    np.testing.assert_allclose(window.model.last.stress, sample.frames[0] - sample.frames[:10].mean(axis=0),
                               atol=1e-9)
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "hertz_static.npz")  # stresses only: nothing to re-tare
    assert not any(action.isEnabled() for action in window.tare_actions.values())


def test_a_long_no_data_banner_wraps_instead_of_widening_the_window(opened, qtbot):
    opened.resize(1280, 760)
    qtbot.wait(50)
    width = opened.width()
    banner = opened.live_panel.banner
    banner.setText("NO DATA: no frame for 12.3 s (reconnecting: [Errno 2] could not open port "
                   "/dev/serial/by-id/usb-Arduino_LLC_Arduino_Leonardo_if00-port0: No such file or directory)")
    banner.show()
    qtbot.wait(100)
    assert opened.width() == width and banner.width() <= width
    assert banner.height() > banner.fontMetrics().height() * 1.5  # wrapped onto several lines


def test_the_arrow_scale_set_by_the_user_survives_a_kernel_change(opened, qtbot):
    panel = opened.display_panel
    panel.scale_spin.setValue(panel.scale_spin.value() * 2.5)
    chosen = opened.model.display.arrow_scale
    kernel = next(k for k in ("cell", "point", "layer") if k != opened.model.kernel)
    with qtbot.waitSignal(opened.model.solved, timeout=30000):
        opened.parameters.kernel_box.setCurrentText(kernel)
    qtbot.waitUntil(lambda: opened.model.kernel == kernel, timeout=30000)
    assert opened.model.display.arrow_scale == chosen
    assert panel.scale_spin.value() == pytest.approx(chosen * 1e3)


def test_a_normal_only_preset_disables_the_shear_controls_and_says_why(opened, qtbot):
    from solver.quality import Configuration

    panel = opened.parameters
    with qtbot.waitSignal(opened.model.solved, timeout=30000):
        opened._rebuild(opened.model.kernel, Configuration("normal only", path="normal"))
    assert opened.model.last.result.normal_only
    assert not any(c.isEnabled() for c in (panel.auto_box, panel.ratio_slider, panel.ratio_spin,
                                           panel.direction_slider, panel.direction_spin))
    assert panel.shear_note.isVisible()
    assert panel.shear_note.text().startswith("The 'normal only' preset solves normal forces only")
    assert "normal only" in opened.status.text()


def test_the_window_fits_a_1280x800_screen_and_remembers_its_size(window, qtbot):
    from tactile_viewer.qt.main_window import MainWindow

    screen = window.screen().availableGeometry()
    assert (screen.width(), screen.height()) == (1280, 800)  # pytest-xvfb's screen (pyproject.toml)
    window.live_panel.show()  # the tallest the controls get
    qtbot.wait(100)
    bar = window.statusBar()
    bottom = bar.mapToGlobal(bar.rect().bottomLeft()).y()
    assert bar.isVisible() and bottom <= screen.bottom() and window.frameGeometry().height() <= 800
    window.resize(1100, 720)
    window.close()  # saves the size, as at the end of a session
    again = MainWindow()
    qtbot.addWidget(again)
    assert (again.width(), again.height()) == (1100, 720)
    again.close()


@pytest.mark.parametrize(("screen", "size"), [((1280, 800), (1280, 760)), ((1920, 1080), (1536, 918)),
                                              ((2560, 1400), (2048, 1190)), ((1024, 600), (1024, 560))])
def test_the_first_size_takes_most_of_a_large_screen_and_all_of_a_small_one(screen, size):
    # before: 1280x760 on every screen larger than a laptop's
    from tactile_viewer.qt.main_window import first_size

    assert first_size(*screen) == size


def test_a_long_status_line_and_a_taxel_read_out_do_not_widen_the_window(opened, qtbot):
    from PyQt6 import QtWidgets

    width = opened.width()
    opened.readout_label.setText("taxel 255 (x 15.0 mm, y 15.0 mm): stress 12.34 kPa, Fx +1.23 Fy -4.56 Fz 78.90 mN")
    opened.status.setText("frame 30 (of 0-44)  " + "contact 1: mu 0.20, theta +120; " * 20)
    opened.statusBar().layout().activate()  # the layout as the next paint would have it
    QtWidgets.QApplication.processEvents()
    assert opened.width() == width and opened.frameGeometry().width() <= 1280
    assert opened.readout_label.isVisible() and opened.readout_label.width() >= opened.readout_label.sizeHint().width()


def in_view(window, widget):
    from PyQt6 import QtCore

    # shown, and wholly inside the window and inside whatever scroll area holds it, as placed now
    if not widget.isVisible():
        return False
    top_left = widget.mapTo(window, QtCore.QPoint(0, 0))
    inside = window.rect().contains(QtCore.QRect(top_left, widget.size()))
    return inside and widget.visibleRegion().boundingRect().size() == widget.size()


def test_at_1280x800_the_timeline_and_every_control_are_in_view_unscrolled(opened, qtbot):
    from PyQt6 import QtCore, QtWidgets

    # before: Play and the frame slider sat under the controls column, 863 px in a 703 px viewport
    opened.resize(1280, 760)  # a 1280x800 screen less a title bar
    qtbot.waitUntil(lambda: opened.height() == 760, timeout=5000)
    scroll = opened._controls
    while not isinstance(scroll, QtWidgets.QScrollArea):
        scroll = scroll.parentWidget()
    assert scroll.verticalScrollBar().maximum() == 0  # the column needs no scrolling
    for widget in (opened.playback.play_button, opened.playback.frame_slider, opened.playback.time_label,
                   opened.parameters.auto_box, opened.display_panel.ids_box, opened.contacts_panel.table):
        assert in_view(opened, widget), widget
    # the contacts table takes the height left: three rows at least, whole
    table = opened.contacts_panel.table
    assert table.viewport().height() >= 3 * table.verticalHeader().defaultSectionSize()
    # the timeline sits under the scene
    scene = opened.plotter.interactor
    assert opened.playback.mapTo(opened, QtCore.QPoint(0, 0)).y() >= scene.mapTo(opened, QtCore.QPoint(0, 0)).y() + scene.height()


def out_of_reach(window):
    """The controls column's panels and controls that cannot be brought wholly into its view, and why.

    The column scrolls only up and down: it must be no wider than its view. Each panel and control
    is scrolled to (``ensureWidgetVisible``, as the keyboard focus does) and must then lie wholly
    inside the view; the contacts table must show all its columns and three rows.
    """
    from PyQt6 import QtCore, QtWidgets

    column = window._controls
    scroll = column
    while not isinstance(scroll, QtWidgets.QScrollArea):
        scroll = scroll.parentWidget()
    viewport = scroll.viewport()
    kinds = (QtWidgets.QGroupBox, QtWidgets.QAbstractButton, QtWidgets.QComboBox, QtWidgets.QAbstractSpinBox,
             QtWidgets.QSlider, QtWidgets.QLabel, QtWidgets.QTableWidget)
    table = window.contacts_panel.table
    problems = []
    if scroll.horizontalScrollBar().maximum() > 0:  # hidden, so the column's right edge would be cut off
        problems.append(("column wider than its view", column.width(), viewport.width()))
    for widget in column.findChildren(QtWidgets.QWidget):
        inside_table = table.isAncestorOf(widget)  # its own scroll bars and corner button
        if not isinstance(widget, kinds) or inside_table or not widget.isVisibleTo(column):
            continue
        scroll.ensureWidgetVisible(widget, 0, 0)
        QtWidgets.QApplication.processEvents()
        placed = QtCore.QRect(widget.mapTo(viewport, QtCore.QPoint(0, 0)), widget.size())
        if widget.width() <= 0 or widget.height() <= 0 or not viewport.rect().contains(placed):
            problems.append((type(widget).__name__, widget.objectName() or getattr(widget, "text", str)(),
                             placed, viewport.rect()))
    scroll.verticalScrollBar().setValue(0)
    header = table.horizontalHeader()
    if header.length() > table.viewport().width() or table.horizontalScrollBar().maximum() > 0:
        problems.append(("contacts table columns", header.length(), table.viewport().width()))
    if table.viewport().height() < 3 * table.verticalHeader().defaultSectionSize():
        problems.append(("contacts table rows", table.viewport().height()))
    return problems


@pytest.mark.parametrize("case", ["maximised", "first size, normal-only preset"])
def test_at_1280x800_every_control_of_the_column_can_be_scrolled_into_view_whole(window, qtbot, case):
    # before: the contacts table scrolled sideways at every size (its note column kept 100 px, 17 px
    # more than was left), its scroll bar over its third row; and when the column scrolled (the first
    # size on a 1280x800 screen, with a preset's note) its scroll bar covered the right 14 px of it
    from PyQt6 import QtCore

    from solver.quality import Configuration

    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "two_contacts.npz")
    with qtbot.waitSignal(window.model.solved, timeout=10000):
        window.model.set_frame(4)  # two contacts, one with a note
    table = window.contacts_panel.table
    assert table.rowCount() == 2
    notes = [table.item(row, table.columnCount() - 1) for row in range(2)]
    assert [(n.text(), n.toolTip()) for n in notes if n.text()] == [("no shear", "no shear")]  # whole if elided
    screen = window.screen().availableGeometry()
    assert (screen.width(), screen.height()) == (1280, 800)  # pytest-xvfb's screen (pyproject.toml)
    if case == "maximised":
        size = screen.size()  # no window manager under Xvfb: maximised is the screen's available size
    else:
        size = QtCore.QSize(1280, 760)  # what a 1280x800 screen opens the window at (first_size)
        with qtbot.waitSignal(window.model.solved, timeout=30000):
            window._rebuild(window.model.kernel, Configuration("normal only", path="normal"))
        assert window.parameters.shear_note.isVisible()  # the tallest the column gets
    window.resize(size)
    qtbot.waitUntil(lambda: window.size() == size, timeout=5000)
    qtbot.wait(100)  # the dock's layout follows the column's scroll bar
    assert out_of_reach(window) == []


def test_dragging_the_column_narrower_stops_at_its_widest_control(window, qtbot):
    # before: the dock's separator squeezed the column to 300 px, its right 130 px out of reach
    from PyQt6 import QtCore, QtWidgets

    window.resize(1280, 800)
    qtbot.waitUntil(lambda: window.height() == 800, timeout=5000)
    dock = window.findChild(QtWidgets.QDockWidget, "controls")
    window.resizeDocks([dock], [300], QtCore.Qt.Orientation.Horizontal)  # as a drag of the separator
    qtbot.wait(100)
    assert out_of_reach(window) == []


def test_at_1280x800_the_longest_contact_note_is_shown_whole(opened, qtbot):
    # before: "edge, no shear" was elided at this size: the note column had 80 px of the 96 it needs
    from PyQt6 import QtWidgets

    from tactile_viewer.qt.contacts_panel import COLUMNS

    opened.resize(1280, 760)  # a 1280x800 screen less a title bar
    qtbot.waitUntil(lambda: opened.height() == 760, timeout=5000)
    qtbot.wait(100)  # the dock's layout follows the column's scroll bar
    table = opened.contacts_panel.table
    margin = 2 * table.style().pixelMetric(QtWidgets.QStyle.PixelMetric.PM_FocusFrameHMargin) + 2
    needed = table.fontMetrics().horizontalAdvance("edge, no shear") + margin
    assert table.horizontalHeader().sectionSize(len(COLUMNS) - 1) >= needed

"""The time-plot dock in the real window under Xvfb: curves, the cursor, click to seek, truth, exports, live."""

import math
from pathlib import Path

import numpy as np
import pytest

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
SAMPLE = SAMPLES / "hertz_shear_turning.npz"
FRAMES = 60  # of the sample

pytestmark = pytest.mark.series  # every test here needs the series the dock solves


@pytest.fixture
def dock(window):
    """The window's own dock; its errors reach the window's error dialog (recorded by the fixture)."""
    from tactile_viewer.qt.time_plots import TimePlotsDock

    made = window.time_plots
    assert isinstance(made, TimePlotsDock) and made.parent() is window
    made.errors = window.errors
    return made


def show(window, dock, qtbot, recording=None):
    """Open the sample (or show ``recording``) and wait until its whole series is drawn."""
    with qtbot.waitSignals([window.ready, dock.computed], timeout=30000):
        assert window.open(SAMPLE) if recording is None else window.show_recording(recording)


@pytest.fixture
def shown(window, dock, qtbot):
    show(window, dock, qtbot)
    return dock


def legend_names(plot):
    return [label.text for _, label in plot.legend.items]


def click_at(qtbot, dock, key, x):
    """A real left click on plot ``key`` at time ``x`` (half way up its view)."""
    from PyQt6 import QtCore

    box = dock.graphics.plots[key].getViewBox()
    # the view follows new curves when it is next painted
    qtbot.waitUntil(lambda: box.viewRange()[0][0] <= x <= box.viewRange()[0][1], timeout=5000)
    (_, _), (low, high) = box.viewRange()
    scene = box.mapViewToScene(QtCore.QPointF(x, (low + high) / 2))
    point = dock.graphics.mapFromScene(scene)
    assert dock.graphics.viewport().visibleRegion().contains(point), "the plot is scrolled out of view"
    qtbot.mouseClick(dock.graphics.viewport(), QtCore.Qt.MouseButton.LeftButton, pos=point)


def lines_at(dock, t):
    return dock.lines_time == t and all(cursor.isVisible() and cursor.value() == pytest.approx(t, abs=1e-12)
                                        for cursor in dock.graphics.cursors)


def test_the_curves_fill_in_with_one_point_per_frame(window, shown):
    recording = window.model.recording
    series = shown.series
    assert series.complete and len(series) == FRAMES and series.mode == "auto"
    np.testing.assert_array_equal(shown.graphics.curves["fz"].xData, recording.t)
    np.testing.assert_allclose(shown.graphics.curves["fz"].yData, series.estimate.fz * 1e3)
    np.testing.assert_allclose(shown.graphics.curves["centroid_x"].yData, series.estimate.centroid_x * 1e3)
    # the frame on screen is the series' frame: the same solver, the same parameters
    last = window.model.last
    assert series.estimate.fz[last.frame] == pytest.approx(last.result.forces[:, 2].sum(), rel=1e-12)
    assert "60 frames" in shown.status.text() and "Auto" in shown.status.text()
    assert shown.csv_button.isEnabled() and shown.png_button.isEnabled() and not shown.errors


def test_partial_series_are_drawn_while_solving(window, dock, qtbot):
    from tactile_viewer.io.files import load
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.sources.source import RecordingSource

    class Slow:
        """The sample's solver, 20 ms a frame: the 60-frame series takes over a second."""

        def __init__(self, inner):
            self.inner, self.grid, self.kernel = inner, inner.grid, inner.kernel

        def solve(self, stress, **kwargs):
            import time

            time.sleep(0.02)
            return self.inner.solve(stress, **kwargs)

        def solve_normal(self, stress):
            return self.inner.solve_normal(stress)

    recording = load(SAMPLE)
    solver = Slow(ViewerModel.build(recording.grid, "layer"))
    window.model.set_source(RecordingSource(recording), solver)
    qtbot.waitUntil(lambda: dock.series is not None and 0 < len(dock.series) < FRAMES, timeout=10000)
    assert not dock.series.complete and "solving" in dock.status.text()
    assert len(dock.graphics.curves["fz"].xData) == len(dock.series)
    # a partial series is not exported
    assert not dock.csv_button.isEnabled() and dock.export_csv("unused.csv") is None
    refused = dock.errors.take()
    assert refused[0][0] == "Series not complete" and "frames): export it when it is complete" in refused[0][1]
    with qtbot.waitSignal(dock.computed, timeout=30000):
        pass
    assert len(dock.graphics.curves["fz"].xData) == FRAMES


def test_the_cursor_follows_steps_and_playback(window, shown, qtbot):
    model = window.model
    t = model.recording.t
    assert shown.cursor_time == t[0] and lines_at(shown, t[0])
    with qtbot.waitSignal(model.frame_changed, timeout=5000):
        window.playback.step(3)
    assert shown.cursor_time == t[3]
    # the lines move with the frame's result, in the repaint that draws it
    qtbot.waitUntil(lambda: lines_at(shown, t[3]), timeout=5000)
    assert model.last.frame == 3
    drawn = []
    shown.drawn.connect(lambda: drawn.append(True))
    # where the cursor is as each frame is taken, read in the signal itself: by the time a wait for
    # the signal returns, the event loop may have drawn that frame and taken the next
    taken = []
    model.frame_changed.connect(lambda index: taken.append((index, model.frame, shown.cursor_time)))
    window.playback.speed_box.setCurrentIndex(2)  # 1x
    window.playback.set_playing(True)
    for _ in range(5):
        with qtbot.waitSignal(window.rendered, timeout=5000):
            pass
        assert lines_at(shown, model.last.time)  # at the frame on screen
    window.playback.set_playing(False)
    assert len(taken) >= 4
    assert all(frame == index and cursor == t[index] for index, frame, cursor in taken), taken
    assert not drawn  # playback moves the cursor only: the curves are not drawn again


def test_a_click_on_a_plot_seeks_to_the_nearest_frame(window, shown, qtbot):
    model = window.model
    t = model.recording.t
    with qtbot.waitSignal(model.frame_changed, timeout=5000) as blocker:
        click_at(qtbot, shown, "tangential", t[40] + 0.3 * (t[41] - t[40]))
    assert blocker.args == [40] and model.frame == 40 and shown.cursor_time == t[40]
    qtbot.waitUntil(lambda: lines_at(shown, t[40]), timeout=5000)
    with qtbot.waitSignal(model.frame_changed, timeout=5000) as blocker:
        click_at(qtbot, shown, "fz", t[12] - 0.4 * (t[12] - t[11]))
    assert model.frame == 12
    qtbot.waitUntil(lambda: model.last.frame == 12, timeout=5000)
    # dragging a cursor shows the frame under it; the other cursors follow it
    cursor = shown.graphics.cursors[2]
    cursor.setValue(t[25] + 0.01)
    with qtbot.waitSignal(model.frame_changed, timeout=5000):
        cursor.sigDragged.emit(cursor)
    assert model.frame == 25
    assert all(other.value() == t[25] + 0.01 for other in shown.graphics.cursors)  # at once, under the mouse
    qtbot.waitUntil(lambda: lines_at(shown, t[25]), timeout=5000)  # then at the frame drawn


def test_a_double_click_undoes_a_zoom(window, shown, qtbot):
    from PyQt6 import QtCore

    box = shown.graphics.plots["fz"].getViewBox()
    qtbot.waitUntil(lambda: box.viewRange()[0][1] > 0, timeout=5000)
    whole = box.viewRange()[0]
    box.scaleBy((0.2, 0.2))  # as the wheel does
    shown.graphics.plots["tangential"].getViewBox().scaleBy((0.3, 0.3))
    qtbot.waitUntil(lambda: box.viewRange()[0][1] - box.viewRange()[0][0] < 0.5 * (whole[1] - whole[0]),
                    timeout=5000)
    x = (box.viewRange()[0][0] + box.viewRange()[0][1]) / 2
    (_, _), (low, high) = box.viewRange()
    point = shown.graphics.mapFromScene(box.mapViewToScene(QtCore.QPointF(x, (low + high) / 2)))
    # a double click as the window system sends it: press, release, double-click (the second press), release
    view, left = shown.graphics.viewport(), QtCore.Qt.MouseButton.LeftButton
    qtbot.mouseClick(view, left, pos=point)
    qtbot.mouseDClick(view, left, pos=point)
    qtbot.mouseRelease(view, left, pos=point)
    qtbot.waitUntil(lambda: box.viewRange()[0] == pytest.approx(whole, rel=1e-6), timeout=5000)
    other = shown.graphics.plots["tangential"].getViewBox()
    qtbot.waitUntil(lambda: other.viewRange()[0] == pytest.approx(whole, rel=1e-6), timeout=5000)


def test_the_truth_is_drawn_beside_the_estimate_only_when_the_recording_has_one(window, shown, qtbot):
    from dataclasses import replace

    from tactile_viewer.model.time_plot_rows import ERROR_ROWS, FIRST_ROWS, ROWS

    layout = shown.graphics.ci
    series = shown.series
    assert series.truth is not None
    for key, *_ in ROWS:
        assert shown.graphics.truth_curves[key] in shown.graphics.plots[key].items
    np.testing.assert_allclose(shown.graphics.truth_curves["fz"].yData, window.model.recording.truth_forces[:, :, 2].sum(1) * 1e3)
    assert legend_names(shown.graphics.plots["fz"]) == ["estimate", "truth"]
    for key, *_ in ERROR_ROWS:
        assert (shown.graphics.plots[key] in layout.items) == (key in FIRST_ROWS)
    shown.show_rows(direction_error=True)
    assert shown.graphics.plots["direction_error"] in layout.items
    np.testing.assert_allclose(shown.graphics.error_curves["error"][0].yData, series.errors.normal * 100)
    np.testing.assert_allclose(shown.graphics.error_curves["direction_error"][0].yData, series.errors.direction_deg)

    show(window, shown, qtbot, replace(window.model.recording, truth_forces=None))
    assert shown.series.truth is None and len(shown.series) == FRAMES
    for key, *_ in ROWS:
        assert shown.graphics.truth_curves[key] not in shown.graphics.plots[key].items
    for key, *_ in ERROR_ROWS:
        assert shown.graphics.plots[key] not in layout.items
    assert legend_names(shown.graphics.plots["fz"]) == ["estimate"]
    # one time axis, under the lowest plot shown
    assert shown.graphics.plots["direction"].getAxis("bottom").isVisible()
    assert not shown.graphics.plots["fz"].getAxis("bottom").isVisible()
    shown.show_rows(centroid_y=True)
    assert shown.graphics.plots["centroid_y"].getAxis("bottom").isVisible()
    assert not shown.graphics.plots["direction"].getAxis("bottom").isVisible()


def test_each_contact_has_curves_of_its_own_when_there_are_several(window, shown, qtbot):
    from dataclasses import replace

    from solver import loads
    from tactile_viewer.io.files import load
    from tactile_viewer.model.time_plot_rows import ROWS

    assert shown.series.identities == (1,) and shown.graphics.contact_curves == {}  # one contact: the totals say it
    assert legend_names(shown.graphics.plots["fz"]) == ["estimate", "truth"]
    two = load(SAMPLES / "two_contacts.npz")
    # the sample's second press comes at frame 4: before it, the first press alone
    alone = loads.simulate(two.grid, loads.hertz((-7e-3, -5e-3), 3.5e-3, 0.6, shear_ratio=0.3), noise=0.01,
                           rng=0)  # fixed seed
    frames, truth = np.array(two.frames), np.array(two.truth_forces)
    frames[:4], truth[:4] = alone.stress, alone.forces
    show(window, shown, qtbot, replace(two, frames=frames, truth_forces=truth))
    series = shown.series
    assert series.identities == (1, 2) and sorted(shown.graphics.contact_curves) == [1, 2]
    for identity in (1, 2):
        quantities = series.contact(identity)
        for key, *_ in ROWS:
            assert shown.graphics.contact_curves[identity][key] in shown.graphics.plots[key].items
        np.testing.assert_allclose(shown.graphics.contact_curves[identity]["fz"].yData, quantities.fz * 1e3)
        np.testing.assert_allclose(shown.graphics.contact_curves[identity]["centroid_x"].yData,
                                   quantities.centroid_x * 1e3)
    second = shown.graphics.contact_curves[2]["fz"].yData
    assert np.isnan(second[:4]).all() and not np.isnan(second[4:]).any()  # not there before it comes
    assert legend_names(shown.graphics.plots["fz"]) == ["estimate", "truth", "#1", "#2"]
    # the contacts table numbers the frame drawn as the curves do (both followed from frame 0)
    last = window.model.last
    for contact in last.result.contacts:
        assert series.contact(contact.identity).fz[last.frame] == pytest.approx(contact.total_force[2],
                                                                                rel=1e-6)
    show(window, shown, qtbot)  # one contact again: its curves go, from the legend too
    assert shown.graphics.contact_curves == {} and legend_names(shown.graphics.plots["fz"]) == ["estimate", "truth"]


def test_new_parameters_solve_a_new_series_and_auto_again_is_kept(window, shown, qtbot):
    model = window.model
    with qtbot.waitSignal(shown.computed, timeout=30000):
        window.parameters.ratio_slider.setValue(30)
    series = shown.series
    assert series.mode == "manual" and series.shear_ratio == pytest.approx(model.shear_ratio)
    assert series.shear_direction == pytest.approx(model.shear_direction)
    qtbot.waitUntil(lambda: not model.solving, timeout=5000)
    last = model.last
    assert series.estimate.fz[last.frame] == pytest.approx(last.result.forces[:, 2].sum(), rel=1e-12)
    with qtbot.waitSignal(shown.computed, timeout=30000):
        window.parameters.auto_box.setChecked(True)
    assert shown.series.mode == "auto"


def test_csv_and_png_exports(window, shown, qtbot, tmp_path):
    from PyQt6 import QtGui

    from tactile_viewer.model.series import CSV_MARKER, Series

    written = shown.export_csv(tmp_path / "series.csv")
    assert written == tmp_path / "series.csv"
    text = written.read_text()
    assert text.startswith(f"# {CSV_MARKER}\n") and f"# source={SAMPLE}\n" in text
    back = Series.from_csv(written)
    np.testing.assert_array_equal(back.t, shown.series.t)
    np.testing.assert_allclose(back.estimate.fz, shown.series.estimate.fz, rtol=1e-14)
    np.testing.assert_allclose(back.truth.tangential, shown.series.truth.tangential, rtol=1e-14)

    png = shown.export_png(tmp_path / "plots.png")
    image = QtGui.QImage(str(png))
    assert not image.isNull()
    assert (image.width(), image.height()) == (shown.graphics.width(), shown.graphics.height())
    pixels = np.array([[image.pixelColor(x, y).getRgb()[:3] for x in range(0, image.width(), 2)]
                       for y in range(0, image.height(), 2)])
    colours = {tuple(p) for p in pixels.reshape(-1, 3)}
    from tactile_viewer.qt.time_plot_stack import ESTIMATE_PEN, TRUTH_PEN

    for pen in (ESTIMATE_PEN, TRUTH_PEN):  # the estimate's and the truth's curves are in the image
        assert pen.color().getRgb()[:3] in colours

    assert shown.export_png(tmp_path / "missing" / "plots.png") is None
    assert shown.export_csv(tmp_path / "missing" / "series.csv") is None
    refused = shown.errors.take()
    assert [title for title, _ in refused] == ["Cannot save the plots", "Cannot save the series"]
    assert str(tmp_path / "missing" / "series.csv") in refused[1][1]
    assert window.isVisible()  # the window goes on


def test_nothing_to_export_before_a_recording(dock):
    assert dock.series is None and not dock.csv_button.isEnabled()
    assert dock.export_csv("series.csv") is None
    assert dock.errors.take() == [("Nothing to export", "no series has been solved yet")]


def test_a_live_source_draws_the_frames_solved_so_far(window, qtbot):
    from PyQt6 import QtCore

    from solver import SensorGrid, loads
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.qt.time_plots import TimePlotsDock
    from tactile_viewer.sources.source import Source, SourceFrame

    class Stream(Source):
        live = True

    dock = TimePlotsDock(window.model, window.tasks, window, live_span=0.27)
    window.addDockWidget(QtCore.Qt.DockWidgetArea.BottomDockWidgetArea, dock)
    grid = SensorGrid.regular(8, 8, 2e-3, 2e-3)
    stream = Stream("tcp://lab:9000", grid)
    stream.start()
    window.model.set_source(stream, ViewerModel.build(grid, "layer"))
    times = np.arange(12) * 0.05
    for k, t in enumerate(times):
        frame = loads.simulate(grid, [loads.hertz((0.0, 0.0), 3e-3, 0.5 + 0.05 * k)])
        with qtbot.waitSignal(window.model.solved, timeout=5000):
            stream._publish([SourceFrame(frame.stress, float(t), k)])
        assert dock.cursor_time == t and lines_at(dock, t)
    # the rolling window: the frames of the last 0.27 s, drawn at the next refresh
    qtbot.waitUntil(lambda: dock.series is not None and len(dock.series) and dock.series.frame[-1] == 11,
                    timeout=5000)
    np.testing.assert_array_equal(dock.series.frame, np.arange(6, 12))
    np.testing.assert_array_equal(dock.graphics.curves["fz"].xData, times[6:])
    assert dock.series.truth is None and dock.series.mode == "as shown" and "live" in dock.status.text()
    # a click does not seek a live source
    click_at(qtbot, dock, "fz", times[8])
    assert window.model.last.frame == 11


def test_a_failed_series_is_reported_and_the_window_goes_on(window, dock, qtbot):
    from tactile_viewer.io.files import load
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.sources.source import RecordingSource

    class Failing:
        """Solves the frames the window shows; fails on frame 5 in the series' thread."""

        def __init__(self, inner, bad):
            self.inner, self.grid, self.kernel, self.bad = inner, inner.grid, inner.kernel, bad

        def solve(self, stress, **kwargs):
            import threading

            if threading.current_thread().name != "tactile-solver" and np.array_equal(stress, self.bad):
                raise RuntimeError("the solver broke")
            return self.inner.solve(stress, **kwargs)

        def solve_normal(self, stress):
            return self.inner.solve_normal(stress)

    recording = load(SAMPLE)
    solver = Failing(ViewerModel.build(recording.grid, "layer"), recording.frames[5])
    with qtbot.waitSignal(window.ready, timeout=10000):
        window.model.set_source(RecordingSource(recording), solver)
    qtbot.waitUntil(lambda: bool(dock.errors), timeout=10000)
    assert dock.errors.take() == [("Time plots", "solving the series failed: the solver broke")]
    assert "could not be solved" in dock.status.text()
    assert window.isVisible() and not math.isnan(dock.cursor_time)


def test_the_cursor_moves_when_the_frames_solve_fails(window, shown, qtbot):
    from tactile_viewer.sources.source import RecordingSource

    class Broken:
        """The window's solver, failing on frame 7 where the window solves it."""

        def __init__(self, inner, bad):
            self.inner, self.grid, self.kernel, self.bad = inner, inner.grid, inner.kernel, bad

        def solve(self, stress, **kwargs):
            import threading

            if threading.current_thread().name == "tactile-solver" and np.array_equal(stress, self.bad):
                raise RuntimeError("no result")
            return self.inner.solve(stress, **kwargs)

        def solve_normal(self, stress):
            return self.inner.solve_normal(stress)

    model = window.model
    recording = model.recording
    with qtbot.waitSignals([window.ready, shown.computed], timeout=30000):
        model.set_source(RecordingSource(recording), Broken(model.reconstructor, recording.frames[7]))
    with qtbot.waitSignal(model.solve_failed, timeout=5000):
        model.set_frame(7)
    assert model.last.frame == 0  # nothing drawn for frame 7: the lines still wait for it
    qtbot.waitUntil(lambda: lines_at(shown, recording.t[7]), timeout=5000)
    assert [r.getMessage() for r in window.errors.take_logged()] == ["solve of frame 7 failed"]


def test_at_1280x800_the_rows_shown_and_their_time_axis_are_in_view(window, shown, qtbot):
    # before: all 8 rows were stacked, 80 px each, in a 190 px dock: 2.3 of them in view and no time axis
    from tests.tactile_viewer.qt.test_main_window import in_view

    window.resize(1280, 760)
    qtbot.waitUntil(lambda: window.height() == 760, timeout=5000)
    view = shown.graphics.parentWidget().parentWidget()  # the scroll area's viewport and the area
    assert view.verticalScrollBar().maximum() == 0
    # (the plots' own view: the scroll area around it covers it whole)
    assert in_view(window, shown.graphics.viewport()) and in_view(window, shown.rows_button)
    lowest = shown.graphics.plots["direction"]
    assert lowest.getAxis("bottom").isVisible()
    assert shown.graphics.rect().contains(shown.graphics.mapFromScene(lowest.getAxis("bottom").sceneBoundingRect())
                                          .boundingRect())
    # the Rows menu shows and hides; one row always stays
    shown.row_actions["centroid_x"].trigger()
    assert shown.graphics.plots["centroid_x"] in shown.graphics.ci.items and "centroid_x" in shown.rows_shown
    shown.show_rows(fz=False, tangential=False, direction=False, centroid_x=False)
    assert shown.rows_shown == {"fz"} and shown.row_actions["fz"].isChecked()
    shown.show_rows(shear_ratio=True)
    # the next window shows the rows chosen last
    from tactile_viewer.qt.main_window import MainWindow

    again = MainWindow()
    qtbot.addWidget(again)
    assert again.time_plots.rows_shown == {"fz", "shear_ratio"}
    assert again.time_plots.row_actions["shear_ratio"].isChecked()
    again.close()
    with pytest.raises(ValueError, match=r"rows must be among .*, got \['speed'\]"):
        shown.show_rows(speed=True)


def test_frames_a_damaged_file_lost_are_shaded_on_every_row(window, qtbot, tmp_path):
    # before: a damaged recording opened with no mark where its frames were missing
    from tests.tactile_viewer.io.test_mcap_reader import chunk_positions, flipped, tared_recording

    path = tmp_path / "damaged.mcap"
    tared_recording(path)
    position = chunk_positions(path)[1]
    flipped(path, position, 0x20)
    flipped(path, position + 200)  # frames 6 to 10 (t 0.6 to 1.0 s) lost
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(path)
    dock = window.time_plots
    assert window.model.recording.lost_spans == (pytest.approx((0.6, 1.0)),)
    assert len(dock.graphics.lost_marks) == len(dock.graphics.plots)
    for plot, mark in dock.graphics.lost_marks:
        assert mark in plot.items and mark.getRegion() == pytest.approx((0.6, 1.0)) and not mark.movable
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "hertz_static.npz")
    assert dock.graphics.lost_marks == []


def test_an_empty_window_says_where_the_plots_come_from_instead_of_empty_axes(window, qtbot):
    # before: axes from 0 to 1 and a legend of nothing
    dock = window.time_plots
    assert dock.placeholder.isVisible() and "File > Open" in dock.placeholder.text()
    assert not dock.graphics.isVisible()
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(SAMPLES / "hertz_static.npz")
    assert dock.graphics.isVisible() and not dock.placeholder.isVisible()


def test_at_1280x800_the_legend_is_above_the_curves_and_the_direction_labels_apart(window, dock, qtbot):
    # before: the legend lay over the Fz curves (and cut off below "estimate" in a row 45 px high),
    # and the direction's five labels overlapped
    from PyQt6 import QtGui

    from tactile_viewer.io.files import load
    from tactile_viewer.model.time_plot_rows import ANGLE_TICKS

    window.resize(1280, 760)  # a 1280x800 screen less a title bar
    qtbot.waitUntil(lambda: window.height() == 760, timeout=5000)
    show(window, dock, qtbot, load(SAMPLES / "three_contacts.npz"))
    qtbot.wait(100)  # laid out
    plot = dock.graphics.plots["fz"]
    legend = plot.legend
    assert legend_names(plot) == ["estimate", "truth", "#1", "#2", "#3"]
    names = legend.sceneBoundingRect()
    assert legend.isVisible() and names.top() >= 0  # in view, whole
    assert names.bottom() <= plot.getViewBox().sceneBoundingRect().top() + 1  # above the curves
    assert not any(names.intersects(other.getViewBox().sceneBoundingRect()) for other in dock.graphics.plots.values()
                   if other.scene() is not None)
    label_height = max(label.boundingRect().height() for _, label in legend.items)
    assert names.height() < 1.5 * label_height  # one line
    direction = dock.graphics.plots["direction"].getViewBox()
    (_, _), (low, high) = direction.viewRange()
    labelled = sorted(value for value, _ in ANGLE_TICKS[0])
    apart = min(b - a for a, b in zip(labelled, labelled[1:], strict=False)) / (high - low) * direction.height()
    axis = dock.graphics.plots["direction"].getAxis("left")
    assert apart > QtGui.QFontMetrics(axis.font()).height()


def test_at_1280x800_the_rows_axis_names_stand_apart(window, dock, qtbot):
    # before: "|Ft| mN" and "dir deg", each written along a row about 45 px high, touched their
    # neighbours' names
    from tactile_viewer.io.files import load

    window.resize(1280, 760)  # a 1280x800 screen less a title bar
    qtbot.waitUntil(lambda: window.height() == 760, timeout=5000)
    show(window, dock, qtbot, load(SAMPLES / "three_contacts.npz"))
    qtbot.wait(100)  # laid out
    labels = [plot.getAxis("left").label for plot in dock.graphics.plots.values()
              if plot.scene() is not None and plot.isVisible()]
    # each name's text: its box less the text document's margin on every side
    names = sorted(((rect := label.sceneBoundingRect()).top() + (margin := label.document().documentMargin()),
                    rect.bottom() - margin) for label in labels)
    assert len(names) >= 3  # Fz, |Ft| and the direction at least
    gaps = [below[0] - above[1] for above, below in zip(names, names[1:], strict=False)]
    assert min(gaps) >= 4, gaps

"""The taxel read-out over the real window (Xvfb): hovering, throttling, pinning, new frames.

The mouse is put on a node's taxel through the renderer's own world-to-display
transform (not the scene's lookup), and the text read back is compared with
the model's last solve.
"""

import re
import time
from pathlib import Path

import numpy as np
import pytest
from PyQt6 import QtCore

from tactile_viewer.qt.hover import TaxelReadout
from tactile_viewer.render.meshes import MM
from tactile_viewer.render.taxel_readout import taxel_text

LINE = re.compile(r"taxel (\d+) \(x (\S+) mm, y (\S+) mm\): stress (\S+) kPa, "
                  r"Fx (\S+) Fy (\S+) Fz (\S+) mN(  \(pinned\))?")


def widget_point(window, node) -> QtCore.QPoint:
    """Where a node's taxel centre is in the scene's widget: logical pixels from its top left."""
    renderer = window.plotter.renderer
    x, y = window.model.grid.positions[node] * MM
    renderer.SetWorldPoint(x, y, 0.0, 1.0)
    renderer.WorldToDisplay()
    shown_x, shown_y, _ = renderer.GetDisplayPoint()
    widget = window.plotter.interactor
    ratio = widget.devicePixelRatioF()
    return QtCore.QPoint(round(shown_x / ratio), round(widget.height() - 1 - shown_y / ratio))


def check_line(text, window, node, *, pinned=False):
    """``text`` is node's line with the model's last values (to the digits shown)."""
    match = LINE.fullmatch(text)
    assert match, text
    assert int(match[1]) == node and bool(match[8]) == pinned
    solved, grid = window.model.last, window.model.grid
    x, y, stress, fx, fy, fz = map(float, match.groups()[1:7])
    np.testing.assert_allclose((x, y), grid.positions[node] * MM, rtol=0, atol=0.051)
    assert stress == pytest.approx(solved.stress[node] / 1e3, abs=0.0051)
    np.testing.assert_allclose((fx, fy, fz), solved.result.forces[node] * 1e3, rtol=0, atol=0.0051)


@pytest.fixture
def readout(opened):
    """The window's own read-out (its text is the status bar's right-hand label)."""
    assert isinstance(opened.readout, TaxelReadout)
    return opened.readout


def loaded_nodes(window, count=2):
    """The most pressed taxels, far enough apart (a few pitches) to be told apart on screen."""
    fz = window.model.last.result.forces[:, 2]
    positions = window.model.grid.positions
    chosen = []
    for node in np.argsort(fz)[::-1]:
        if all(np.linalg.norm(positions[node] - positions[c]) > 3 * window.model.grid.pitch for c in chosen):
            chosen.append(int(node))
        if len(chosen) == count:
            return chosen
    return chosen + [0]


def test_hovering_a_taxel_reads_out_its_number_and_values(opened, qtbot, readout):
    widget = opened.plotter.interactor
    (node,) = loaded_nodes(opened, 1)
    assert opened.model.last.result.forces[node, 2] > 0
    with qtbot.waitSignal(readout.text_changed, timeout=5000) as signal:
        qtbot.mouseMove(widget, widget_point(opened, node))
    (text,) = signal.args
    assert text == taxel_text(opened.model.last, opened.model.grid, node)
    check_line(text, opened, node)
    assert opened.readout_label.text() == text  # shown in the status bar
    # off the skin (the widget's corner): no read-out
    with qtbot.waitSignal(readout.text_changed, timeout=5000) as signal:
        qtbot.mouseMove(widget, QtCore.QPoint(3, 3))
    assert signal.args == [""] and readout.node is None
    assert not opened.errors


def test_the_read_out_follows_the_view(opened, qtbot, readout):
    # the Top view (orthographic) puts the taxels elsewhere on screen: the lookup follows the camera
    widget = opened.plotter.interactor
    opened.display_panel.view("top")
    qtbot.waitUntil(lambda: opened.model.display.in_plane)
    first, second = loaded_nodes(opened)
    for node in (first, second):
        with qtbot.waitSignal(readout.text_changed, timeout=5000) as signal:
            qtbot.mouseMove(widget, widget_point(opened, node))
        check_line(signal.args[0], opened, node)


def test_moves_are_looked_up_at_most_once_per_interval_and_nothing_is_rendered(opened, qtbot, readout,
                                                                                monkeypatch):
    widget = opened.plotter.interactor
    first, last = loaded_nodes(opened)
    qtbot.mouseMove(widget, widget_point(opened, first))
    qtbot.wait(100)
    lookups, renders = [], []
    node_at = opened.scene.node_at
    monkeypatch.setattr(opened.scene, "node_at", lambda x, y: lookups.append((x, y)) or node_at(x, y))
    tag = opened.plotter.ren_win.AddObserver("StartEvent", lambda *_: renders.append(1))
    try:
        start = time.perf_counter()
        a, b = widget_point(opened, first), widget_point(opened, last)
        for step in np.linspace(0, 1, 30):  # a quick sweep from one taxel to the other
            qtbot.mouseMove(widget, QtCore.QPoint(round(a.x() + step * (b.x() - a.x())),
                                                  round(a.y() + step * (b.y() - a.y()))))
        qtbot.waitUntil(lambda: readout.node == last, timeout=5000)
        elapsed = time.perf_counter() - start
        qtbot.wait(100)
    finally:
        opened.plotter.ren_win.RemoveObserver(tag)
    assert 1 <= len(lookups) <= elapsed / 0.040 + 2  # throttled: not one lookup per move
    assert renders == []  # reading the scene draws nothing
    check_line(readout.text, opened, last)


def test_a_click_pins_the_taxel_and_its_line_follows_the_frames(opened, qtbot, readout):
    widget = opened.plotter.interactor
    node, other = loaded_nodes(opened)
    left = QtCore.Qt.MouseButton.LeftButton
    with qtbot.waitSignal(readout.text_changed, timeout=5000) as signal:
        qtbot.mouseClick(widget, left, pos=widget_point(opened, node))
    assert readout.pinned
    check_line(signal.args[0], opened, node, pinned=True)
    # moving over another taxel leaves the pinned one
    qtbot.mouseMove(widget, widget_point(opened, other))
    qtbot.wait(150)
    check_line(readout.text, opened, node, pinned=True)
    # a new frame: the same taxel, its new values
    before = readout.text
    frame = opened.model.frame
    with qtbot.waitSignal(readout.text_changed, timeout=20000):
        opened.model.set_frame(frame + 10)
    assert opened.model.last.frame == frame + 10
    assert readout.text != before
    check_line(readout.text, opened, node, pinned=True)
    # a click off the skin lets it go
    with qtbot.waitSignal(readout.text_changed, timeout=5000) as signal:
        qtbot.mouseClick(widget, left, pos=QtCore.QPoint(3, 3))
    assert signal.args == [""] and not readout.pinned
    assert not opened.errors


def test_a_drag_turns_the_camera_and_pins_nothing(opened, qtbot, readout):
    widget = opened.plotter.interactor
    node, _ = loaded_nodes(opened)
    start = widget_point(opened, node)
    left = QtCore.Qt.MouseButton.LeftButton
    position = np.array(opened.plotter.camera.position)
    qtbot.mousePress(widget, left, pos=start)
    for dx in (5, 15, 30):
        qtbot.mouseMove(widget, start + QtCore.QPoint(dx, 0))
    qtbot.mouseRelease(widget, left, pos=start + QtCore.QPoint(30, 0))
    qtbot.wait(100)
    assert not readout.pinned
    assert not np.allclose(opened.plotter.camera.position, position)  # the event reached the scene


def test_a_new_recording_clears_a_pinned_read_out(opened, qtbot, readout):
    widget = opened.plotter.interactor
    node, _ = loaded_nodes(opened)
    with qtbot.waitSignal(readout.text_changed, timeout=5000):
        qtbot.mouseClick(widget, QtCore.Qt.MouseButton.LeftButton, pos=widget_point(opened, node))
    assert readout.pinned
    with qtbot.waitSignal(opened.ready, timeout=20000):
        assert opened.open(Path(__file__).resolve().parents[3] / "sample_data" / "two_contacts.npz")
    assert readout.text == "" and not readout.pinned


def test_a_failing_lookup_is_logged_once_and_the_window_goes_on(opened, qtbot, readout, monkeypatch):
    widget = opened.plotter.interactor
    node, other = loaded_nodes(opened)

    def broken(x, y):
        raise RuntimeError("lookup broke")

    monkeypatch.setattr(opened.scene, "node_at", broken)
    for target in (node, other, node):
        qtbot.mouseMove(widget, widget_point(opened, target))
        qtbot.wait(80)
    logged = [r.getMessage() for r in opened.errors.take_logged()]
    assert logged == ["taxel read-out failed (later failures are not logged)"]  # once
    assert not opened.errors and opened.isVisible()

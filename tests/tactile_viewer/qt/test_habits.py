"""What a lab user expects of a desktop tool: recent files, the last folder, the view kept between runs,
drag and drop, keyboard shortcuts, tooltips, help; and the per-contact table (issue 13)."""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from PyQt6 import QtCore, QtGui, QtWidgets

from tactile_viewer.qt.preferences import RECENT_MAX, RecentFiles, window_settings

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"


def open_sample(window, qtbot, path):
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(path)


def recent_entries(window):
    window._fill_recent()
    return [a.toolTip() for a in window.recent_menu.actions() if a.toolTip().endswith((".npz", ".csv", ".mcap"))]


# -- recent files and the last folder -------------------------------------------------------


def test_recent_files_list_the_recordings_opened_newest_first_and_reopen(window, qtbot, tmp_path):
    first, second = tmp_path / "a.npz", tmp_path / "b.npz"
    shutil.copy(SAMPLES / "hertz_static.npz", first)
    shutil.copy(SAMPLES / "two_contacts.npz", second)
    assert not window.recent_menu.isEnabled()  # nothing opened yet
    open_sample(window, qtbot, first)
    open_sample(window, qtbot, second)
    open_sample(window, qtbot, first)  # again: moves to the top, listed once
    assert recent_entries(window) == [str(first.resolve()), str(second.resolve())]
    assert window.recent_menu.isEnabled()
    window._fill_recent()
    entry = next(a for a in window.recent_menu.actions() if a.toolTip() == str(second.resolve()))
    with qtbot.waitSignal(window.ready, timeout=20000):
        entry.trigger()
    assert window.model.path == second


def test_a_recent_file_that_is_gone_says_so_and_leaves_the_list(window, qtbot, tmp_path):
    gone = tmp_path / "gone.npz"
    shutil.copy(SAMPLES / "hertz_static.npz", gone)
    open_sample(window, qtbot, gone)
    gone.unlink()
    window._fill_recent()  # as when the menu opens
    entry = next(a for a in window.recent_menu.actions() if a.toolTip() == str(gone.resolve()))
    entry.trigger()
    refused = window.errors.take()
    assert refused and refused[-1][0] == "Cannot open recording"
    assert recent_entries(window) == []
    assert window.model.path == gone  # what was shown stays


def test_the_recent_list_is_bounded_and_can_be_cleared(tmp_path, window):
    recent = RecentFiles()
    for k in range(RECENT_MAX + 3):
        recent.add(tmp_path / f"r{k}.npz")
    paths = recent.paths()
    assert len(paths) == RECENT_MAX and paths[0].name == f"r{RECENT_MAX + 2}.npz"
    recent.clear()
    assert recent.paths() == []


def test_the_open_dialog_starts_in_the_folder_last_opened_from(window, qtbot, tmp_path, monkeypatch):
    folder = tmp_path / "takes"
    folder.mkdir()
    shutil.copy(SAMPLES / "hertz_static.npz", folder / "take.npz")
    open_sample(window, qtbot, folder / "take.npz")
    asked = []
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName",
                        staticmethod(lambda parent, title, start, *a, **k: asked.append(start) or ("", "")))
    window.open_dialog()
    assert asked == [str(folder.resolve())]


# -- the view between runs -------------------------------------------------------------------


def test_view_settings_survive_a_restart_but_each_source_gets_its_own_scales(window, qtbot):
    from tactile_viewer.qt.main_window import MainWindow

    open_sample(window, qtbot, SAMPLES / "hertz_static.npz")
    window.display_panel.map_box.setCurrentIndex(1)  # sensor stress
    window.display_panel.arrows_box.setChecked(False)
    window.display_panel.range_box.setChecked(False)
    window.model.set_display(arrow_scale=0.123)  # a scale: the next source gets its own
    window.playback.speed_box.setCurrentIndex(3)  # 2x
    window.playback.loop_box.setChecked(True)
    window.close()  # saved, as at the end of a session
    again = MainWindow()
    qtbot.addWidget(again)
    try:
        d = again.model.display
        assert (d.map, d.arrows, d.auto_range) == ("stress", False, False)
        assert again.display_panel.map_box.currentIndex() == 1 and not again.display_panel.arrows_box.isChecked()
        assert again.playback.speed == 2.0 and again.playback.loop_box.isChecked()
        with qtbot.waitSignal(again.ready, timeout=20000):
            again.open(SAMPLES / "hertz_static.npz")
        assert again.model.display.arrow_scale != pytest.approx(0.123)
        assert again.model.display.map == "stress"
    finally:
        again.close()


def test_a_damaged_settings_file_is_ignored_value_by_value(window, qtbot, caplog):
    from tactile_viewer.qt.main_window import MainWindow

    window_settings().update({
        "view/map": "bogus",           # Display refuses it
        "view/arrows": "maybe",        # not a bool
        "view/resultant": False,       # fine
        "view/playback_speed": "fast",
        "geometry": "garbage",         # not what Qt saved: the default size
        "docks": [1, 2],
    })
    again = MainWindow()
    qtbot.addWidget(again)
    try:
        d = again.model.display
        assert (d.map, d.arrows, d.resultant) == ("pressure", True, False)
        assert again.playback.speed == 1.0
        assert "view.map" in caplog.text and "view.arrows" in caplog.text
        assert "ignoring geometry" in caplog.text and "ignoring docks" in caplog.text
        assert again.time_plots.isVisibleTo(again)  # the default layout
    finally:
        again.close()


@pytest.mark.parametrize("content", [
    # the line that made Qt's own settings abort the app at every start (exit 134): in the old
    # file, which is no longer read
    ("window.ini", b"[General]\nrecent_files=@Variant(\\0\\0\\0\\t\\x7f\\xff\\xff\\xff)\n"),
    ("window.json", b"[" * 100000 + b"]" * 100000),                # nested past the parser's depth
    ("window.json", b'{"recent_files": ' + b'"x", ' * 300000 + b"}"),  # over 1 MB
    ("window.json", b"\xff\xfe not text"),
    ("window.json", b'{"recent_files": {"a": 1}, "last_folder": 7, "geometry": "@@@"}'),
], ids=["qt-variant", "deep", "huge", "binary", "wrong-types"])
def test_no_settings_file_keeps_the_window_from_opening(qtbot, caplog, content, monkeypatch, tmp_path):
    from tactile_viewer.qt.main_window import MainWindow

    monkeypatch.setenv("TACTILE_VIEWER_CONFIG", str(tmp_path))
    name, data = content
    (tmp_path / name).write_bytes(data)
    window = MainWindow()
    qtbot.addWidget(window)
    try:
        window.show()
        qtbot.waitExposed(window)
        assert recent_entries(window) == [] and window.model.display == type(window.model.display)()
        if name == "window.json":
            assert "settings: ignoring" in caplog.text
    finally:
        window.close()
    # and what the window keeps from now on reads back
    assert json.loads((tmp_path / "window.json").read_text())["view/map"] == "pressure"


# -- drag and drop -----------------------------------------------------------------------------


KEEP = []  # an event does not own its mime data: it must outlive the event


def drop_event(kind, path, window):
    mime = QtCore.QMimeData()
    mime.setUrls([QtCore.QUrl.fromLocalFile(str(path))])
    KEEP.append(mime)
    point = QtCore.QPointF(window.rect().center())
    if kind == "enter":
        return QtGui.QDragEnterEvent(point.toPoint(), QtCore.Qt.DropAction.CopyAction, mime,
                                     QtCore.Qt.MouseButton.LeftButton, QtCore.Qt.KeyboardModifier.NoModifier)
    return QtGui.QDropEvent(point, QtCore.Qt.DropAction.CopyAction, mime, QtCore.Qt.MouseButton.LeftButton,
                            QtCore.Qt.KeyboardModifier.NoModifier)


def test_a_recording_dropped_on_the_window_opens(window, qtbot):
    path = SAMPLES / "two_contacts.npz"
    enter = drop_event("enter", path, window)
    window.dragEnterEvent(enter)
    assert enter.isAccepted()
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.dropEvent(drop_event("drop", path, window))
    assert window.model.path == path


def test_a_file_that_is_not_a_recording_is_not_taken(window, tmp_path):
    other = tmp_path / "notes.txt"
    other.write_text("hello")
    enter = drop_event("enter", other, window)
    enter.setAccepted(True)
    window.dragEnterEvent(enter)
    assert not enter.isAccepted()
    drop = drop_event("drop", other, window)
    window.dropEvent(drop)
    assert not drop.isAccepted() and not window.model.is_open


# -- keys ---------------------------------------------------------------------------------------


def press(window, qtbot, key):
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    qtbot.keyClick(window, key)


def test_keys_step_jump_play_and_toggle_auto(opened, qtbot):
    last = len(opened.model.recording) - 1
    opened.plotter.interactor.setFocus()  # keys reach the window whatever has the focus
    with qtbot.waitSignal(opened.model.frame_changed, timeout=5000):
        press(opened, qtbot, QtCore.Qt.Key.Key_Right)
    assert opened.model.frame == 1
    with qtbot.waitSignal(opened.model.frame_changed, timeout=5000):
        press(opened, qtbot, QtCore.Qt.Key.Key_End)
    assert opened.model.frame == last
    with qtbot.waitSignal(opened.model.frame_changed, timeout=5000):
        press(opened, qtbot, QtCore.Qt.Key.Key_Left)
    assert opened.model.frame == last - 1
    with qtbot.waitSignal(opened.model.frame_changed, timeout=5000):
        press(opened, qtbot, QtCore.Qt.Key.Key_Home)
    assert opened.model.frame == 0
    press(opened, qtbot, QtCore.Qt.Key.Key_Space)
    assert opened.playback.play_button.isChecked()
    press(opened, qtbot, QtCore.Qt.Key.Key_Space)
    assert not opened.playback.play_button.isChecked()
    assert opened.model.auto
    press(opened, qtbot, QtCore.Qt.Key.Key_A)
    assert not opened.model.auto and not opened.parameters.auto_box.isChecked()
    press(opened, qtbot, QtCore.Qt.Key.Key_A)
    assert opened.model.auto


def test_a_text_field_keeps_its_keys(opened, qtbot):
    spin = opened.parameters.ratio_spin
    opened.activateWindow()
    qtbot.waitUntil(opened.isActiveWindow, timeout=5000)
    spin.setFocus()
    qtbot.waitUntil(spin.hasFocus, timeout=5000)
    qtbot.keyClick(spin.lineEdit(), QtCore.Qt.Key.Key_End)
    qtbot.keyClick(spin.lineEdit(), QtCore.Qt.Key.Key_A)  # typed into the field, not Auto's key
    assert opened.model.frame == 0 and opened.model.auto


def select_all_of(window, qtbot, spin):
    """Focus ``spin`` in the active window and select its text with Ctrl+A, as a user does; its line edit."""
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=5000)
    spin.setFocus()
    qtbot.waitUntil(spin.hasFocus, timeout=5000)
    edit = spin.lineEdit()
    qtbot.keyClick(edit, QtCore.Qt.Key.Key_A, QtCore.Qt.KeyboardModifier.ControlModifier)
    return edit


# every numeric field, the model value it sets (SI), and what is typed
TYPED = [
    ("parameters", "ratio_spin", "0.8", 0.8, lambda m: m.shear_ratio),
    ("parameters", "ratio_spin", "1.2", 1.2, lambda m: m.shear_ratio),
    ("parameters", "direction_spin", "-45", -45.0, lambda m: math.degrees(m.shear_direction)),
    ("display_panel", "scale_spin", "25", 25.0, lambda m: 1e3 * m.display.arrow_scale),
    ("display_panel", "threshold_spin", "1.5", 1.5, lambda m: 1e3 * m.display.threshold),
    ("display_panel", "range_spin", "12.5", 12.5, lambda m: m.display.range_max / 1e3),
    ("display_panel", "arrow_range_spin", "300", 300.0, lambda m: 1e3 * m.display.arrow_range_max),
    ("display_panel", "gain_spin", "3.5", 3.5, lambda m: m.display.in_plane_gain),
]


@pytest.mark.parametrize("panel, name, typed, value, read", TYPED, ids=[f"{t[1]}={t[2]}" for t in TYPED])
def test_a_number_typed_into_a_field_is_the_number_used(opened, qtbot, panel, name, typed, value, read):
    # Real keys, as a user types them: select all, the digits one by one, Enter. The model's value
    # was written back into the box after each key (0.8 became 0.00: the "0" reformatted the box to
    # "0.00", the "." stepped over its point, the "8" was refused).
    spin = getattr(getattr(opened, panel), name)
    if name == "range_spin":
        opened.display_panel.range_box.setChecked(False)
    if name == "arrow_range_spin":
        opened.display_panel.arrow_range_box.setChecked(False)
    if name == "gain_spin":
        opened.display_panel.in_plane_box.setChecked(True)
    edit = select_all_of(opened, qtbot, spin)
    qtbot.keyClicks(edit, typed)
    qtbot.keyClick(edit, QtCore.Qt.Key.Key_Return)
    assert spin.value() == pytest.approx(value)
    assert read(opened.model) == pytest.approx(value)
    if panel == "parameters":
        # the number typed is the one solved, and Auto is off
        assert not opened.model.auto
        qtbot.waitUntil(lambda: opened.model.last is not None and not opened.model.last.auto, timeout=10000)
        got = opened.model.last.result
        assert (got.shear_ratio if name == "ratio_spin" else math.degrees(got.shear_direction)) == \
            pytest.approx(value)


def test_auto_frames_arriving_while_a_number_is_typed_leave_it_alone(opened, qtbot):
    # in Auto every solved frame shows its parameters in the fields; not over a half-typed number
    spin, model = opened.parameters.ratio_spin, opened.model
    assert model.auto
    edit = select_all_of(opened, qtbot, spin)
    qtbot.keyClicks(edit, "0.")
    opened.playback.play_button.setChecked(True)
    for _ in range(3):  # Auto's frames go on arriving
        with qtbot.waitSignal(model.solved, timeout=10000):
            pass
    assert model.auto and edit.text() == "0."
    opened.playback.play_button.setChecked(False)
    qtbot.keyClicks(edit, "8")
    qtbot.keyClick(edit, QtCore.Qt.Key.Key_Return)
    assert not model.auto and model.shear_ratio == pytest.approx(0.8) and spin.value() == pytest.approx(0.8)


def test_playback_keys_do_nothing_without_a_recording(window, qtbot):
    assert not any(a.isEnabled() for a in window.playback_actions.values())
    assert not window.auto_action.isEnabled()


# -- tooltips and help ----------------------------------------------------------------------------


def test_every_control_says_what_it_does(opened):
    kinds = (QtWidgets.QAbstractButton, QtWidgets.QAbstractSlider, QtWidgets.QComboBox,
             QtWidgets.QAbstractSpinBox, QtWidgets.QTableWidget)
    def inside_a_view(widget):  # a table's own parts (corner button, scroll bars)
        parent = widget.parentWidget()
        while parent is not None:
            if isinstance(parent, QtWidgets.QAbstractItemView):
                return True
            parent = parent.parentWidget()
        return False

    silent = [w for kind in kinds for w in opened.findChildren(kind)
              if any(part.isAncestorOf(w) for part in (opened._controls, opened.playback, opened.live_panel))
              and not w.toolTip() and not inside_a_view(w)]
    assert silent == [], [(type(w).__name__, getattr(w, "text", lambda: "")()) for w in silent]


def test_help_names_the_keys_and_about_names_the_versions(window, monkeypatch):
    import numpy

    box = window.show_help()
    assert box.isVisible() and not box.isModal()
    for key in ("Space", "Home", "End", "Left", "0 deg = +x"):
        assert key in box.text()
    box.close()
    shown = []
    monkeypatch.setattr(QtWidgets.QMessageBox, "about", staticmethod(lambda parent, title, text: shown.append(text)))
    window.show_about()
    assert "tactile-viewer 0.1.0" in shown[0] and f"numpy {numpy.__version__}" in shown[0]


# -- the contacts table ------------------------------------------------------------------------------


def test_the_contacts_table_lists_each_contact_with_its_own_resultant_and_parameters(window, qtbot):
    open_sample(window, qtbot, SAMPLES / "two_contacts.npz")
    with qtbot.waitSignal(window.model.solved, timeout=10000):
        window.model.set_frame(len(window.model.recording) // 2)
    last = window.model.last
    contacts = last.result.contacts
    table = window.contacts_panel.table
    assert len(contacts) == 2 and table.rowCount() == 2
    for row, (contact, centroid) in enumerate(zip(contacts, last.contact_centroids, strict=True)):
        cells = [table.item(row, c).text() for c in range(table.columnCount())]
        assert cells[0] == str(contact.identity) and contact.identity in (1, 2)  # its number over time
        assert float(cells[1]) == pytest.approx(contact.total_force[2] * 1e3, abs=0.051)
        assert float(cells[2]) == pytest.approx(math.hypot(*contact.total_force[:2]) * 1e3, abs=0.051)
        assert float(cells[3]) == pytest.approx(contact.shear_ratio, abs=0.0051)
        assert float(cells[5]) == pytest.approx(centroid[0] * 1e3, abs=0.051)
    # two contacts, two places: the table does not show one centre for both
    assert table.item(0, 5).text() != table.item(1, 5).text() or table.item(0, 6).text() != table.item(1, 6).text()


def test_the_contacts_table_tells_its_view_once_a_frame_and_its_columns_fit_the_new_numbers(window, qtbot):
    open_sample(window, qtbot, SAMPLES / "two_contacts.npz")
    with qtbot.waitSignal(window.model.solved, timeout=10000):
        window.model.set_frame(len(window.model.recording) // 2)
    panel, table = window.contacts_panel, window.contacts_panel.table
    changes = []
    table.model().dataChanged.connect(lambda first, last, roles: changes.append(
        (first.row(), first.column(), last.row(), last.column())))
    last = window.model.last
    # a frame whose first contact presses 1000 times harder: wider numbers in the force columns
    from dataclasses import replace as replaced

    heavy = replaced(last.result, contacts=[replaced(last.result.contacts[0],
                                                     total_force=1000 * last.result.contacts[0].total_force),
                                            *last.result.contacts[1:]])
    panel.follow(replaced(last, result=heavy))
    assert changes == [(0, 0, 1, table.columnCount() - 1)]  # one change, every cell
    QtWidgets.QApplication.processEvents()
    text = table.item(0, 1).text()
    assert float(text) == pytest.approx(1000 * last.result.contacts[0].total_force[2] * 1e3, rel=1e-3)
    # the view followed: the column is as wide as its widest number
    assert table.horizontalHeader().sectionSize(1) >= table.fontMetrics().horizontalAdvance(text)


def test_a_normal_only_solve_lists_the_whole_frame(opened, qtbot):
    from solver.quality import Configuration

    with qtbot.waitSignal(opened.model.solved, timeout=30000):
        opened._rebuild(opened.model.kernel, Configuration("normal only", path="normal"))
    table = opened.contacts_panel.table
    assert table.rowCount() == 1
    assert table.item(0, 0).text() == "all" and table.item(0, 7).text() == "normal only"
    total = opened.model.last.result.total_force
    assert float(table.item(0, 1).text()) == pytest.approx(total[2] * 1e3, abs=0.051)


def test_each_contact_centroid_is_over_its_own_nodes():
    from solver import Reconstructor, SensorGrid, loads
    from tactile_viewer.model.solved import Solved

    grid = SensorGrid.regular(16, 16, 2e-3, 2e-3, poisson_ratio=0.5)
    # two separate contacts (finely integrated, independent of the solver's kernel): each centroid
    # lies at its own contact, the frame's between them
    frame = loads.simulate(grid, [loads.hertz((-7e-3, -5e-3), 3.5e-3, 0.6),
                                  loads.hertz((7e-3, 6e-3), 4e-3, 0.4)])
    solved = Solved.of(grid, frame.stress, Reconstructor(grid).solve(frame.stress))
    centres = sorted(tuple(c * 1e3) for c in solved.contact_centroids)
    np.testing.assert_allclose(centres, [(-7, -5), (7, 6)], atol=0.5)
    assert abs(solved.centroid[0] * 1e3) < 4  # the whole load's centre is between them

"""ROS 2 bags in the window: File > Open, the dialog that picks the topic, field and layout, drops, refusals."""

import numpy as np
import pytest
from PyQt6 import QtWidgets

from tactile_viewer.qt.bag_dialog import RECORDING_FILTER, BagDialog
from tactile_viewer.qt.preferences import RecentFiles
from tests.tactile_viewer.qt.test_habits import drop_event
from tests.tactile_viewer.written_bags import (
    SKIN_TYPE,
    T0_NS,
    layout_file,
    multiarray,
    skin_frames,
    skin_message,
    write_bag,
)

F64 = "std_msgs/msg/Float64MultiArray"


@pytest.fixture
def lab_bag(tmp_path):
    """A bag of a 3x2 skin (stamped, 8 frames) and a 4-value wrist force sensor, and the skin's layout."""
    frames = skin_frames(8, seed=21)  # fixed seed
    messages = []
    for k in range(8):
        log = T0_NS + 20_000_000 * k
        messages += [("/skin", SKIN_TYPE, log, skin_message(frames[k], log - 1_000_000)),
                     ("/wrist/force", F64, log, multiarray(np.arange(4.0), F64))]
    layout_path, layout = layout_file(tmp_path)
    return write_bag(tmp_path / "lab", messages, storage="sqlite3"), layout_path, layout.to_pascals(frames)


def press_open(dialog):
    dialog.buttons.button(QtWidgets.QDialogButtonBox.StandardButton.Open).click()


def test_file_open_takes_a_bag_through_the_dialog(window, qtbot, lab_bag, monkeypatch):
    bag, layout_path, pascals = lab_bag
    chosen = []
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName",
                        staticmethod(lambda parent, title, start, kinds: chosen.append(kinds)
                                     or (str(bag / "metadata.yaml"), "")))

    def answer(dialog):
        assert isinstance(dialog, BagDialog)
        assert [dialog.field_box.itemText(k) for k in range(dialog.field_box.count())] == [
            "/skin pressures (lab_msgs/msg/SkinFrame: 8 messages of 6 values)",
            "/wrist/force data (std_msgs/msg/Float64MultiArray: 8 messages of 4 values)"]
        press_open(dialog)  # no layout yet: said in the dialog, which stays open
        assert dialog.message.text() == "choose the sensor layout file (JSON) of the skin the bag recorded"
        dialog.layout_edit.setText(str(layout_path))
        dialog.field_box.setCurrentIndex(1)  # the wrong topic: said too
        press_open(dialog)
        assert dialog.message.text() == (
            f"{bag}: topic '/wrist/force' field 'data': no message can be a frame: 8 of 8 messages left out: "
            "4 values, not the layout's 6")
        assert dialog.result() == 0 and dialog.recording is None
        dialog.field_box.setCurrentIndex(0)
        press_open(dialog)
        return dialog.result()

    monkeypatch.setattr(QtWidgets.QDialog, "exec", answer)
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.open_dialog()
    assert chosen == [RECORDING_FILTER] and "metadata.yaml" in RECORDING_FILTER and "*.db3" in RECORDING_FILTER
    np.testing.assert_array_equal(window.model.recording.frames, pascals)
    np.testing.assert_allclose(window.model.recording.t, np.arange(8) * 0.02, atol=1e-12)
    assert window.windowTitle() == "tactile-viewer - lab"
    assert RecentFiles().paths()[0] == bag.resolve()


def test_the_dialog_remembers_the_last_layout_topic_and_field(qtbot, lab_bag):
    bag, layout_path, _ = lab_bag
    from tactile_viewer.io.ros2_bag import array_topics

    fields = array_topics(bag)
    first = BagDialog(bag, fields)
    qtbot.addWidget(first)
    assert first.layout_edit.text() == "" and first.field_box.currentIndex() == 0
    first.layout_edit.setText(str(layout_path))
    press_open(first)
    assert first.result() == 1 and len(first.recording) == 8
    again = BagDialog(bag, list(reversed(fields)))  # the remembered field is found where it is now
    qtbot.addWidget(again)
    assert again.layout_edit.text() == str(layout_path) and again.field_box.currentText().startswith("/skin ")
    # what the command line gives comes before what was remembered
    given = BagDialog(bag, fields, layout="other.json", topic="/wrist/force")
    qtbot.addWidget(given)
    assert given.layout_edit.text() == "other.json" and given.field_box.currentIndex() == 1


def test_with_nothing_given_or_remembered_the_longest_array_is_offered_first(qtbot, lab_bag):
    bag, _, _ = lab_bag
    from tactile_viewer.io.ros2_bag import array_topics

    fields = list(reversed(array_topics(bag)))  # the wrist's 4 values listed before the skin's 6
    dialog = BagDialog(bag, fields)
    qtbot.addWidget(dialog)
    assert dialog.field_box.currentIndex() == 1 and dialog.field_box.currentText().startswith("/skin ")


def test_cancelling_the_dialog_keeps_what_was_shown(opened, lab_bag, monkeypatch):
    shown = opened.model.recording
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda dialog: QtWidgets.QDialog.DialogCode.Rejected)
    assert not opened.open(lab_bag[0])
    assert opened.model.recording is shown and opened.errors == []


def test_a_bag_given_its_layout_opens_without_asking(window, qtbot, lab_bag, monkeypatch):
    # as tactile-viewer BAG --layout FILE does: the layout's 6 taxels pick the skin's topic
    bag, layout_path, pascals = lab_bag
    monkeypatch.setattr(QtWidgets.QDialog, "exec", lambda dialog: pytest.fail("the dialog was shown"))
    with qtbot.waitSignal(window.ready, timeout=20000):
        assert window.open(bag, layout=str(layout_path))
    np.testing.assert_array_equal(window.model.recording.frames, pascals)


def test_a_layout_that_fits_no_single_topic_opens_the_dialog_with_it(window, lab_bag, tmp_path, monkeypatch):
    bag, _, _ = lab_bag
    other, _ = layout_file(tmp_path, nx=5, ny=1)  # 5 taxels: neither topic's size
    asked = []

    def answer(dialog):
        asked.append((dialog.layout_edit.text(), dialog.field_box.currentText()))
        return QtWidgets.QDialog.DialogCode.Rejected
    monkeypatch.setattr(QtWidgets.QDialog, "exec", answer)
    assert window.open(bag, layout=str(other)) is False
    assert asked == [(str(other), "/skin pressures (lab_msgs/msg/SkinFrame: 8 messages of 6 values)")]
    assert window.errors == [] and not window.model.is_open


def test_a_dropped_bag_folder_opens_through_the_dialog(window, qtbot, lab_bag, monkeypatch):
    bag, layout_path, pascals = lab_bag
    enter = drop_event("enter", bag, window)
    window.dragEnterEvent(enter)
    assert enter.isAccepted()

    def answer(dialog):
        dialog.layout_edit.setText(str(layout_path))
        press_open(dialog)
        return dialog.result()
    monkeypatch.setattr(QtWidgets.QDialog, "exec", answer)
    with qtbot.waitSignal(window.ready, timeout=20000):
        window.dropEvent(drop_event("drop", bag, window))
    np.testing.assert_array_equal(window.model.recording.frames, pascals)


def test_a_bag_that_cannot_be_read_is_reported_and_the_window_goes_on(window, tmp_path):
    broken = tmp_path / "broken.db3"
    broken.write_bytes(b"not a database")
    assert not window.open(broken)
    ((title, text),) = window.errors.take()
    assert title == "Cannot open recording" and text.startswith(f"{broken}: not a readable ROS 2 bag (")
    assert not window.model.is_open

"""Live mode end to end: tactile-sim on a real pseudo-terminal, the window reading it."""

import numpy as np
import pytest

from tactile_viewer.io.files import load

# The window's reader, starved for over the board's default half second by a loaded machine (the
# window's start-up beside another test suite), made the board drop frames, as a board does when its
# host does not read: the tests below count lost frames as the reader's, so their board waits longer.
PATIENT = ("--drop-after", "5")


@pytest.fixture
def live(window, board, qtbot):
    """The window connected to a 200 Hz binary board with some garbage on the line."""
    board.start("--rate", "200", "--garbage", "0.1", "--seed", "5", *PATIENT)
    assert window.live_panel.connect_live(str(board.link), board.layout, fmt="binary")
    qtbot.waitUntil(lambda: window.model.live and window.model.last is not None, timeout=20000)
    return window


def test_the_window_shows_live_frames(live, qtbot):
    first = live.model.last.frame
    # the render signalled next may be of the frame just taken as the first: wait for a later frame
    qtbot.waitUntil(lambda: live.model.last.frame > first, timeout=5000)
    with qtbot.waitSignal(live.rendered, timeout=5000):
        pass
    assert live.model.last.frame > first  # sequence numbers move on
    assert live.model.last.stress.max() > 1e3  # kPa on the wire, pascals on screen
    assert live.status.text().startswith("seq ")
    assert live.scene.arrows.n_points > 0
    assert not live.playback.isEnabled() and live.live_panel.isVisible()
    qtbot.waitUntil(lambda: "fps" in live.live_panel.status.text(), timeout=3000)
    assert "lost 0" in live.live_panel.status.text()


def test_a_hidden_window_goes_on_solving_live_frames(live, qtbot):
    # no paint comes while hidden: each result counts as shown once the window has taken it (before,
    # the board's frames waited for a paint and nothing more was solved or published)
    live.hide()
    solved = []
    live.model.solved.connect(lambda result: solved.append(result.frame))
    qtbot.waitUntil(lambda: len(set(solved)) >= 10, timeout=10000)
    assert solved == sorted(solved)


def test_injected_garbage_is_counted_and_no_frame_is_lost(live, qtbot):
    reader = live.live_panel.reader
    qtbot.waitUntil(lambda: reader.decoder.skipped_bytes > 0 and reader.stats.received > 200, timeout=10000)
    assert reader.stats.lost == 0 and reader.stats.out_of_order == 0
    qtbot.waitUntil(lambda: "skipped" in live.live_panel.status.text(), timeout=3000)


def test_a_disconnect_shows_no_data_and_a_reconnect_recovers(live, board, qtbot):
    reader = live.live_panel.reader
    board.stop()
    qtbot.waitUntil(lambda: live.live_panel.banner.isVisible(), timeout=5000)
    assert "NO DATA" in live.live_panel.banner.text() and reader.state == "reconnecting"
    before = reader.stats.received
    board.start("--rate", "200", *PATIENT, wait=False)  # the window's reader is the only one on the port
    # the restarted board computes its contact first (seconds under load), then streams
    qtbot.waitUntil(lambda: reader.reconnects == 1 and reader.stats.received > before + 50, timeout=60000)
    qtbot.waitUntil(lambda: not live.live_panel.banner.isVisible(), timeout=3000)
    with qtbot.waitSignal(live.rendered, timeout=5000):
        pass
    assert reader.stats.lost == 0  # a restarted board's new numbering is not a gap


def test_a_1khz_recording_has_every_frame(window, board, qtbot, tmp_path):
    board.start("--rate", "1000", "--seed", "9", *PATIENT)
    assert window.live_panel.connect_live(str(board.link), board.layout)
    qtbot.waitUntil(lambda: window.live_panel.reader is not None and window.live_panel.reader.stats.received > 100, timeout=20000)
    reader = window.live_panel.reader
    # frames the board dropped before the recording (the window's start-up starving the reader for
    # over half a second on a loaded machine, as a board drops them when its host does not read)
    # are not the recording's: it is judged from its first frame on
    lost_before = reader.stats.lost
    assert window.live_panel.start_recording(tmp_path / "live.mcap")
    recorder = reader.recorder
    qtbot.waitUntil(lambda: recorder.written >= 2000, timeout=20000)  # flushed every second
    path = window.live_panel.stop_recording()
    recording = load(path)
    assert len(recording) >= 2000
    np.testing.assert_array_equal(np.diff(recording.sequence()), 1)  # no gap, no repeat
    assert recording.grid.shape == (16, 16) and np.all(np.diff(recording.t) >= 0)
    assert reader.stats.lost == lost_before and reader.failures == 0


def test_recording_text_frames_while_the_display_skips(window, board, qtbot, tmp_path):
    board.start("--rate", "500", "--format", "text")
    assert window.live_panel.connect_live(str(board.link), board.layout, fmt="text")
    qtbot.waitUntil(lambda: window.live_panel.reader is not None and window.live_panel.reader.stats.received > 50, timeout=20000)
    drawn = []
    window.model.solved.connect(drawn.append)
    assert window.live_panel.start_recording(tmp_path / "live.mcap")
    qtbot.waitUntil(lambda: window.live_panel.reader.recorder.written >= 500, timeout=20000)
    received_while = window.live_panel.reader.stats.received
    path = window.live_panel.stop_recording()
    recording = load(path)
    assert len(recording) >= 500
    np.testing.assert_array_equal(np.diff(recording.sequence()), 1)  # text frames are numbered on arrival
    assert recording.frames.raw_dtype == np.float64  # as text sent them
    assert len(drawn) < received_while  # the display skipped frames; the recorder did not
    assert window.live_panel.reader.failures == 0


def test_a_port_that_cannot_be_opened_is_reported_and_changes_nothing(opened, tmp_path, board):
    board.start("--rate", "50")
    shown = opened.model.recording
    assert not opened.live_panel.connect_live(str(tmp_path / "no-such-device"), board.layout)
    refused = opened.errors.take()
    assert refused and "no-such-device" in refused[-1][1]
    assert opened.model.recording is shown and not opened.model.live and opened.live_panel.reader is None


def test_a_bad_layout_is_reported(window, tmp_path, board):
    board.start("--rate", "50")
    bad = tmp_path / "bad.json"
    bad.write_text('{"nx": 4}')
    assert not window.live_panel.connect_live(str(board.link), bad)
    refused = window.errors.take()
    assert "bad.json" in refused[-1][1] and "missing" in refused[-1][1]
    assert window.live_panel.reader is None


def test_opening_a_recording_disconnects(live, qtbot):
    from pathlib import Path

    reader = live.live_panel.reader
    with qtbot.waitSignal(live.ready, timeout=20000):
        live.open(Path(__file__).resolve().parents[3] / "sample_data" / "hertz_static.npz")
    assert live.live_panel.reader is None and reader.state == "stopped" and not live.model.live
    assert live.playback.isEnabled() and not live.live_panel.isVisible()


def test_the_connect_dialog_remembers_and_checks(qtbot, tmp_path, monkeypatch):
    from tactile_viewer.qt.connect_dialog import ConnectDialog

    layout = tmp_path / "layout.json"
    layout.write_text("{}")
    dialog = ConnectDialog()
    qtbot.addWidget(dialog)
    dialog.port_box.setEditText("")
    dialog._accept()
    assert "choose a port" in dialog.message.text() and dialog.result() == 0
    dialog.port_box.setEditText("socket://localhost:7777")
    for typed in ("fast", "0", "-5", "2147483648", "9" * 5000):
        dialog.baud_box.setEditText(typed)
        dialog._accept()
        assert f"baud rate must be a whole number from 1 to 2147483647, got {typed!r}" in dialog.message.text()
        assert dialog.result() == 0
    dialog.baud_box.setEditText("921600")
    dialog.layout_edit.setText(str(tmp_path / "missing.json"))
    dialog._accept()
    assert "does not exist" in dialog.message.text()
    dialog.layout_edit.setText(str(layout))
    dialog.format_box.setCurrentText("text")
    dialog._accept()
    assert dialog.result() == 1
    again = ConnectDialog()
    qtbot.addWidget(again)
    chosen = again.connection()
    assert (chosen.url, chosen.baudrate, chosen.fmt, chosen.layout) == (
        "socket://localhost:7777", 921600, "text", str(layout))


def test_exporting_the_live_frame_on_screen(live, qtbot, tmp_path):
    # "Export forces of this frame" in live mode used to end the app (no recording to read)
    from tactile_viewer.io.forces import load_forces

    shown = live.model.last
    with qtbot.waitSignal(live.tasks.finished, timeout=30000):
        live.exports.export_forces(tmp_path / "live.npz", whole=False)
    assert live.errors == []
    back = load_forces(tmp_path / "live.npz")
    assert back["forces"].shape == (1, live.model.grid.size, 3)
    assert int(back["frames"][0]) == shown.frame and float(back["t"][0]) == pytest.approx(shown.time)
    np.testing.assert_array_equal(back["forces"][0], shown.result.forces)  # what was on screen


def test_a_recording_that_fails_to_close_is_reported_and_live_goes_on(live, qtbot, tmp_path):
    assert live.live_panel.start_recording(tmp_path / "full.mcap")
    qtbot.waitUntil(lambda: live.live_panel.reader.recorder.added > 0, timeout=5000)

    def full_disk():
        raise OSError(28, "No space left on device")
    live.live_panel.reader.recorder.close = full_disk
    assert live.live_panel.stop_recording() is None
    refused = live.errors.take()
    assert refused and refused[-1][0] == "Recording not completed"
    assert "No space left on device" in refused[-1][1] and "the live view goes on" in refused[-1][1]
    seen = live.model.last.frame
    qtbot.waitUntil(lambda: live.model.last.frame > seen, timeout=5000)  # still live


def test_disconnect_keeps_the_last_frame_and_disables_what_needs_a_connection(live, qtbot, tmp_path):
    panel = live.live_panel
    enabled = lambda: {name: button.isEnabled() for name, button in panel.buttons.items()}  # noqa: E731
    assert enabled() == dict(tare=True, record=True, stop_recording=False, disconnect=True)
    assert panel.start_recording(tmp_path / "take.mcap")
    assert enabled()["stop_recording"] and panel.actions["stop_recording"].isEnabled()
    reader = panel.reader
    recorded = reader.published
    qtbot.waitUntil(lambda: reader.published > recorded + 5, timeout=5000)
    panel.disconnect_live()
    assert reader.state == "stopped" and reader.recorder is None and (tmp_path / "take.mcap").exists()
    assert not any(enabled().values()) and not any(a.isEnabled() for a in panel.actions.values())
    assert "stopped" in panel.status.text() and not panel.banner.isVisible()
    assert live.windowTitle().endswith("(disconnected)") and "live:" not in live.windowTitle()
    qtbot.wait(300)  # a frame solved before the stop may still arrive; after it, nothing new
    shown = live.model.last
    qtbot.wait(500)  # two status ticks later: still stopped, the last frame still shown
    assert live.model.last is shown and shown.frame <= reader.stats.last_seq
    assert not panel.banner.isVisible() and "stopped" in panel.status.text()


def test_a_live_source_of_another_kind_shows_without_the_boards_statistics(window, qtbot):
    # a new kind of live source is one Source subclass; the panel shows what it can of it
    from solver import SensorGrid
    from tactile_viewer.model.viewer_model import ViewerModel
    from tactile_viewer.sources.source import Source, SourceFrame

    class Stream(Source):
        live = True

    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3)
    stream = Stream("tcp://lab:9000", grid)
    stream.start()
    window.model.set_source(stream, ViewerModel.build(grid, "layer"))
    stream._publish([SourceFrame(np.full(grid.size, 1e3), 0.0, 3)])
    qtbot.waitUntil(lambda: window.model.last is not None, timeout=5000)
    window.live_panel.follow()
    qtbot.wait(300)  # the panel's status ticks
    assert window.live_panel.reader is None and window.model.last.frame == 3
    assert "live: tcp://lab:9000" in window.windowTitle()


def test_the_recording_indicator_shows_while_recording_and_both_rates_are_shown(live, qtbot, tmp_path):
    panel = live.live_panel
    assert not panel.recording_indicator.isVisible()
    assert panel.start_recording(tmp_path / "take.mcap")
    qtbot.waitUntil(lambda: panel.recording_indicator.isVisible(), timeout=5000)
    qtbot.waitUntil(lambda: "REC take.mcap" in panel.recording_indicator.text(), timeout=5000)
    qtbot.waitUntil(lambda: panel.display_rate() > 0, timeout=5000)
    assert "fps received" in panel.status.text() and "fps on screen" in panel.status.text()
    # a pseudo-terminal has no USB identity: the panel says what that means for recordings
    assert "device identity unknown" in panel.status.text() and "recordings end at a reconnection" in panel.status.text()
    panel.stop_recording()
    qtbot.waitUntil(lambda: not panel.recording_indicator.isVisible(), timeout=5000)


def test_a_recording_in_progress_shows_in_the_title_and_the_live_bar_in_view(live, qtbot, tmp_path):
    # before: the live counters, REC and the buttons sat below the controls column's fold (1,056 px
    # in a 703 px viewport) and nothing else said a recording ran
    from tests.tactile_viewer.qt.test_main_window import in_view

    live.resize(1280, 760)
    qtbot.waitUntil(lambda: live.height() == 760, timeout=5000)
    assert live.windowTitle() == f"tactile-viewer - live: {live.live_panel.reader.label}"
    assert live.live_panel.start_recording(tmp_path / "take.mcap")
    qtbot.waitUntil(lambda: live.windowTitle().endswith(" - \u25cf REC take.mcap"), timeout=3000)
    qtbot.waitUntil(lambda: live.live_panel.recording_indicator.isVisible(), timeout=3000)
    for widget in (live.live_panel.status, live.live_panel.recording_indicator, *live.live_panel.buttons.values()):
        assert in_view(live, widget), widget
    assert not live.playback.isVisible()  # a board has no timeline: the live bar takes its place
    live.live_panel.stop_recording()
    qtbot.waitUntil(lambda: live.windowTitle() == f"tactile-viewer - live: {live.live_panel.reader.label}",
                    timeout=3000)
    assert not live.live_panel.recording_indicator.isVisible()


def test_the_connect_dialog_lists_a_running_simulator_with_its_layout(qtbot, board):
    # before: 320 px wide, and a pseudo-terminal or its link was in no list: the path had to be typed
    from tactile_viewer.qt.connect_dialog import ConnectDialog, available_ports

    board.start("--rate", "50", "--format", "text", "--scene", "two")
    listed = {device: (description, facts) for device, description, facts in available_ports()}
    assert str(board.link) in listed
    description, facts = listed[str(board.link)]
    assert description.startswith("tactile-sim, scene two, text, on /dev/pts/")
    assert facts["layout"] == str(board.layout.resolve())
    dialog = ConnectDialog()
    qtbot.addWidget(dialog)
    assert dialog.minimumWidth() >= 560
    index = next(i for i in range(dialog.port_box.count()) if dialog.port_box.itemData(i)[0] == str(board.link))
    dialog.port_box.setCurrentIndex(index)
    dialog.port_box.activated.emit(index)  # as a click in the list does
    chosen = dialog.connection()
    assert (chosen.url, chosen.fmt, chosen.layout) == (str(board.link), "text", str(board.layout.resolve()))
    board.stop()  # its note goes with it
    assert str(board.link) not in [device for device, *_ in available_ports()]

"""Live > Connect to an LSL stream and Live > Publish over LSL, in the real window (qtbot)."""

import uuid

import numpy as np
import pylsl
import pytest
from PyQt6 import QtCore

from solver import SensorGrid, loads
from tactile_viewer.io.layout import SensorLayout, save_layout
from tactile_viewer.qt.lsl_connect_dialog import LslConnectDialog
from tactile_viewer.sources.lsl import describe_layout
from tactile_viewer.sources.lsl_inlet import LslSource

GRID = SensorGrid.regular(6, 5, 2e-3, 2e-3)


def press_kpa():
    """A sheared press on GRID in kPa, as a board would send it (fixed seed: its noise)."""
    contact = loads.hertz((0.3e-3, 0.2e-3), 2.5e-3, 0.8, shear_ratio=0.3, shear_direction=0.5)
    return (loads.simulate(GRID, [contact], noise=0.005, rng=np.random.default_rng(32)).stress / 1e3
            ).astype(np.float32)


@pytest.fixture
def board(qtbot):
    """A plain pylsl outlet of GRID in kPa, described, that sends a frame every 20 ms on a Qt timer."""
    name = f"window-board-{uuid.uuid4().hex[:10]}"  # no test ever sees another's stream
    info = pylsl.StreamInfo(name, "Tactile", GRID.size, 50, pylsl.cf_float32, f"{name}-id")
    describe_layout(info.desc(), SensorLayout(GRID, "kPa"))
    streams = {"outlet": pylsl.StreamOutlet(info)}
    sample = press_kpa()
    timer = QtCore.QTimer(interval=20)
    timer.timeout.connect(lambda: "outlet" in streams and streams["outlet"].push_sample(sample))
    timer.start()
    yield name, streams  # the test may take the outlet away: the stream is gone
    timer.stop()


def chosen_stream(qtbot, name, *, layout_file=None):
    """The dialog's search for ``name``: its list, and what it returns when accepted."""
    dialog = LslConnectDialog(timeout=0.5)
    qtbot.addWidget(dialog)
    dialog.name_edit.setText(name)
    with qtbot.waitSignal(dialog.searched, timeout=10000) as searched:
        dialog.search()
    assert searched.args == [1] and dialog.stream_list.count() == 1
    assert name in dialog.stream_list.item(0).text() and "30 float32 channels, 50 Hz" in dialog.stream_list.item(0).text()
    if layout_file is not None:
        dialog.layout_edit.setText(str(layout_file))
        dialog.from_file.setChecked(True)
    dialog._accept()
    assert dialog.result() == LslConnectDialog.DialogCode.Accepted
    return dialog.connection()


def test_the_window_reads_an_lsl_stream_and_publishes_its_forces(window, board, qtbot):
    name, _streams = board
    chosen = chosen_stream(qtbot, name)
    assert chosen.layout == ""  # from the stream's description
    assert window.live_panel.connect_lsl(chosen.stream, None)
    qtbot.waitUntil(lambda: window.model.live and window.model.last is not None, timeout=20000)
    reader = window.live_panel.reader
    assert isinstance(reader, LslSource) and reader.layout.units == "kPa"
    assert window.model.last.stress.max() > 1e3  # kPa on the wire, pascals on screen
    qtbot.waitUntil(lambda: "received" in window.live_panel.status.text(), timeout=3000)
    # Live > Publish over LSL, with the stress
    window.live_panel.publish_actions["publish_stress"].setChecked(True)
    window.live_panel.publish_actions["publish"].setChecked(True)
    publishing = window.live_panel.publishing
    assert publishing.enabled and publishing.stress
    qtbot.waitUntil(lambda: publishing.outlet is not None, timeout=5000)
    found = pylsl.resolve_bypred(f"name='{publishing.name}' and type='TactileForce'", minimum=1, timeout=5)
    inlet = pylsl.StreamInlet(found[0], recover=False)
    info = inlet.info(timeout=5)
    inlet.open_stream(timeout=5)
    assert info.channel_count() == 3 * GRID.size and info.get_channel_labels()[2] == "node0_Fz"
    samples = []
    qtbot.waitUntil(lambda: samples.extend(inlet.pull_chunk()[0]) or len(samples) >= 3, timeout=10000)
    forces = np.reshape(samples[-1], (-1, 3))
    assert forces[:, 2].sum() == pytest.approx(0.8, rel=0.1)  # the press's normal total, newtons
    qtbot.waitUntil(lambda: "frames published as" in window.live_panel.status.text(), timeout=3000)
    window.live_panel.publish_actions["publish"].setChecked(False)
    assert publishing.outlet is None and not publishing.enabled


def test_the_layout_may_come_from_a_file(window, board, qtbot, tmp_path):
    name, _streams = board
    layout_file = save_layout(SensorLayout(GRID, "kPa", gain=2.0), tmp_path / "board.json")
    chosen = chosen_stream(qtbot, name, layout_file=layout_file)
    assert window.live_panel.connect_lsl(chosen.stream, chosen.layout)
    qtbot.waitUntil(lambda: window.live_panel.reader is not None, timeout=20000)  # its solver is built first
    assert window.live_panel.reader.layout.gain[0] == 2.0


def test_a_stream_of_another_size_is_an_error_and_the_window_goes_on(window, board, qtbot, tmp_path):
    name, _streams = board
    small = save_layout(SensorLayout(SensorGrid.regular(4, 4, 2e-3, 2e-3)), tmp_path / "small.json")
    chosen = chosen_stream(qtbot, name, layout_file=small)
    assert not window.live_panel.connect_lsl(chosen.stream, chosen.layout)
    (title, text), = window.errors.take()
    assert title == "Cannot connect"
    assert "the stream has 30 channels but the layout describes 16 taxels" in text
    assert not window.model.live


def test_the_dialog_says_when_nothing_is_found_and_what_is_missing(qtbot):
    dialog = LslConnectDialog(timeout=0.3)
    qtbot.addWidget(dialog)
    dialog.name_edit.setText(f"nobody-{uuid.uuid4().hex}")
    with qtbot.waitSignal(dialog.searched, timeout=10000) as searched:
        dialog.search()
    assert searched.args == [0] and "no stream found" in dialog.message.text()
    dialog._accept()
    assert dialog.result() != LslConnectDialog.DialogCode.Accepted
    assert dialog.message.text() == "search, then choose a stream from the list"
    with pytest.raises(ValueError, match="search, then choose a stream"):
        dialog.connection()


def test_no_data_when_the_stream_goes_away_and_the_frame_stays(window, board, qtbot):
    name, streams = board
    assert window.live_panel.connect_lsl(chosen_stream(qtbot, name).stream)
    qtbot.waitUntil(lambda: window.model.live and window.model.last is not None, timeout=20000)
    received = window.live_panel.reader.stats.received
    del streams["outlet"]  # the board's program ends
    qtbot.waitUntil(lambda: window.live_panel.banner.isVisible(), timeout=10000)
    banner = window.live_panel.banner.text()
    assert banner.startswith("NO DATA") and "reconnecting" in banner
    assert window.live_panel.reader.stats.received >= received  # the frames counted stay counted
    assert window.model.last.stress.max() > 1e3  # the last frame stays on screen


def test_an_outlet_that_cannot_be_made_is_an_error_and_unchecks_publishing(window, monkeypatch, board, qtbot):
    from tactile_viewer.model import force_publishing

    def refused(*_args, **_kwargs):
        raise RuntimeError("liblsl: could not open a port")

    name, _streams = board
    assert window.live_panel.connect_lsl(chosen_stream(qtbot, name).stream)
    qtbot.waitUntil(lambda: window.live_panel.reader is not None, timeout=20000)
    monkeypatch.setattr(force_publishing, "ForceOutlet", refused)
    window.live_panel.publish_actions["publish"].setChecked(True)
    assert window.errors.take() == [("Cannot publish over LSL", "liblsl: could not open a port")]
    assert not window.live_panel.publish_actions["publish"].isChecked()
    assert not window.live_panel.publishing.enabled

"""Live > Connect to an LSL stream and Live > Publish over LSL, in the real window (qtbot)."""

import threading
import uuid

import numpy as np
import pylsl
import pytest
from PyQt6 import QtCore

from solver import SensorGrid, loads
from tactile_viewer.io.layout import SensorLayout, save_layout
from tactile_viewer.qt import live_panel
from tactile_viewer.qt.lsl_connect_dialog import LslConnectDialog
from tactile_viewer.sources.lsl import describe_layout
from tactile_viewer.sources.lsl_inlet import FoundStream, LslSource, StreamNotFound

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


def connected(qtbot, window, stream, layout=None) -> bool:
    """Live > Connect to an LSL stream: the attempt starts at once; its outcome (``lsl_connected``)."""
    with qtbot.waitSignal(window.live_panel.lsl_connected, timeout=10000) as outcome:
        assert window.live_panel.connect_lsl(stream, layout)
    return outcome.args[0]


class Held:
    """An LslSource whose construction (the inlet's network wait) is held until :attr:`release` is set."""

    def __init__(self, monkeypatch):
        self.entered, self.release, self.made, self.closed = threading.Event(), threading.Event(), [], []
        held = self

        class HeldSource(LslSource):
            def __init__(self, *args, **kwargs):
                held.entered.set()
                assert held.release.wait(10), "the test never released the connection"
                super().__init__(*args, **kwargs)
                held.made.append(self)

            def _close(self, inlet):
                held.closed.append(inlet)
                super()._close(inlet)

        monkeypatch.setattr(live_panel, "LslSource", HeldSource)


@pytest.fixture
def held(window, monkeypatch):
    """The window's LSL connections held (:class:`Held`); released before the window closes at the end."""
    holding = Held(monkeypatch)
    yield holding
    holding.release.set()  # a test that failed midway must not hold the window's close for 10 s


def test_the_window_reads_an_lsl_stream_and_publishes_its_forces(window, board, qtbot):
    name, _streams = board
    chosen = chosen_stream(qtbot, name)
    assert chosen.layout == ""  # from the stream's description
    assert connected(qtbot, window, chosen.stream, None)
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
    assert connected(qtbot, window, chosen.stream, chosen.layout)
    qtbot.waitUntil(lambda: window.live_panel.reader is not None, timeout=20000)  # its solver is built first
    assert window.live_panel.reader.layout.gain[0] == 2.0


def test_a_stream_of_another_size_is_an_error_and_the_window_goes_on(window, board, qtbot, tmp_path):
    name, _streams = board
    small = save_layout(SensorLayout(SensorGrid.regular(4, 4, 2e-3, 2e-3)), tmp_path / "small.json")
    chosen = chosen_stream(qtbot, name, layout_file=small)
    assert not connected(qtbot, window, chosen.stream, chosen.layout)
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
    assert connected(qtbot, window, chosen_stream(qtbot, name).stream)
    qtbot.waitUntil(lambda: window.model.live and window.model.last is not None, timeout=20000)
    received = window.live_panel.reader.stats.received
    del streams["outlet"]  # the board's program ends
    # the banner comes after 1 s of silence; under load liblsl may say the stream is lost later
    shown = window.live_panel.banner
    qtbot.waitUntil(lambda: shown.isVisible() and "reconnecting" in shown.text(), timeout=10000)
    banner = shown.text()
    assert banner.startswith("NO DATA") and "reconnecting" in banner
    assert window.live_panel.reader.stats.received >= received  # the frames counted stay counted
    assert window.model.last.stress.max() > 1e3  # the last frame stays on screen


def test_an_outlet_that_cannot_be_made_is_an_error_and_unchecks_publishing(window, monkeypatch, board, qtbot):
    from tactile_viewer.model import force_publishing

    def refused(*_args, **_kwargs):
        raise RuntimeError("liblsl: could not open a port")

    name, _streams = board
    assert connected(qtbot, window, chosen_stream(qtbot, name).stream)
    qtbot.waitUntil(lambda: window.live_panel.reader is not None, timeout=20000)
    monkeypatch.setattr(force_publishing, "ForceOutlet", refused)
    window.live_panel.publish_actions["publish"].setChecked(True)
    assert window.errors.take() == [("Cannot publish over LSL", "liblsl: could not open a port")]
    assert not window.live_panel.publish_actions["publish"].isChecked()
    assert not window.live_panel.publishing.enabled


def test_connecting_leaves_the_window_responsive_and_refuses_a_second_connection(window, board, held,
                                                                                 qtbot):
    name, _streams = board
    stream = chosen_stream(qtbot, name).stream
    panel = window.live_panel
    assert panel.connect_lsl(stream)  # returns while the inlet still waits for the network
    assert f"connecting to lsl:{name} ..." in window.statusBar().currentMessage()
    assert held.entered.wait(5) and not held.made
    ticks = []
    QtCore.QTimer.singleShot(0, lambda: ticks.append("tick"))
    qtbot.waitUntil(lambda: bool(ticks), timeout=2000)  # the GUI thread's event loop runs meanwhile
    assert not held.made
    assert not panel.connect_actions["lsl"].isEnabled() and not panel.connect_actions["connect"].isEnabled()
    with qtbot.assertNotEmitted(panel.lsl_connected):
        assert not panel.connect_lsl(stream)  # one connection at a time: refused, said
    assert f"still connecting to lsl:{name}" in window.statusBar().currentMessage()
    with qtbot.waitSignal(panel.lsl_connected, timeout=10000) as outcome:
        held.release.set()
    assert outcome.args == [True] and len(held.made) == 1
    assert panel.connect_actions["lsl"].isEnabled() and panel.connect_actions["connect"].isEnabled()
    qtbot.waitUntil(lambda: panel.reader is held.made[0], timeout=20000)  # its solver is built first
    assert panel.reader.state != "stopped" and window.model.live


def test_a_stream_gone_since_the_search_is_an_error_once_the_attempt_ends(window, qtbot, monkeypatch):
    def gone(stream, layout):
        raise StreamNotFound(f"stream {stream.name!r} did not answer within 2 s")

    monkeypatch.setattr(live_panel, "LslSource", gone)
    stream = FoundStream("gone-board", "Tactile", GRID.size, "float32", 50.0, "gone-id", "host", "uid", None)
    assert not connected(qtbot, window, stream)
    assert window.errors.take() == [("Cannot connect", "lsl:gone-board: stream 'gone-board' did not answer "
                                                       "within 2 s")]
    assert not window.model.live and window.live_panel.reader is None
    assert window.live_panel.connect_actions["lsl"].isEnabled()  # the next attempt may start


def test_closing_the_window_while_connecting_waits_and_closes_the_late_source(window, board, held,
                                                                             qtbot):
    name, _streams = board
    stream = chosen_stream(qtbot, name).stream
    panel = window.live_panel
    assert panel.connect_lsl(stream)
    assert held.entered.wait(5)
    task = panel._connecting.task
    threading.Timer(0.2, held.release.set).start()  # the inlet answers while the window closes
    with qtbot.waitSignal(panel.lsl_connected, timeout=5000) as outcome:
        window.close()  # returns once the attempt has ended
    assert outcome.args == [False]
    assert task.isFinished() and len(held.made) == 1
    late = held.made[0]
    assert late.state == "stopped" and len(held.closed) == 1  # its inlet closed, no reader left
    assert not [t for t in threading.enumerate() if t.name == f"source lsl:{name}" and t.is_alive()]
    qtbot.wait(50)  # the attempt's own result, queued before the close, is dropped
    assert window.live_panel.reader is None and not window.errors

"""ForcePublishing (tactile_viewer/model/force_publishing.py): the model's live forces read by plain pylsl inlets."""

import time
import uuid

import numpy as np
import pylsl
import pytest

from solver import SensorGrid, loads
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.io.recording import Recording
from tactile_viewer.model.force_publishing import ForcePublishing
from tactile_viewer.model.viewer_model import ViewerModel
from tactile_viewer.sources.lsl import describe_layout
from tactile_viewer.sources.lsl_inlet import LslSource, find_streams
from tactile_viewer.sources.source import RecordingSource

TIMEOUT = 5.0  # the most any wait may take on a loaded machine
GRID = SensorGrid.regular(5, 4, 2e-3, 2e-3)


def wait_until(condition, what):
    deadline = time.monotonic() + TIMEOUT
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


def press():
    """One frame of a sheared press on GRID, pascals (fixed seed: its noise)."""
    contact = loads.hertz((0.5e-3, 0.0), 2.5e-3, 0.8, shear_ratio=0.3, shear_direction=0.4)
    return loads.simulate(GRID, [contact], noise=0.005, rng=np.random.default_rng(32)).stress


def inlet_on(name, stream_type, ready):
    found = pylsl.resolve_bypred(f"name='{name}' and type='{stream_type}'", minimum=1, timeout=TIMEOUT)
    assert found, f"{name} {stream_type} not on the network"
    inlet = pylsl.StreamInlet(found[0], recover=False)
    inlet.open_stream(timeout=TIMEOUT)
    wait_until(ready, f"{stream_type} to have a consumer")
    return inlet


def connected_board():
    """A plain outlet of GRID's stresses in pascals (its layout described) and a started LslSource on it."""
    name = f"board-{uuid.uuid4().hex[:10]}"  # no test ever sees another's stream
    info = pylsl.StreamInfo(name, "Tactile", GRID.size, 0, pylsl.cf_float32, "")
    describe_layout(info.desc(), SensorLayout(GRID))
    board = pylsl.StreamOutlet(info)
    source = LslSource(find_streams(name=name, timeout=0.5)[0])
    source.start()
    wait_until(board.have_consumers, "the source to connect")
    return name, board, source


@pytest.fixture(scope="module")
def reconstructor():
    return ViewerModel.build(GRID, "layer")


@pytest.fixture
def live(reconstructor):
    """A model showing an LslSource that reads a plain outlet of GRID's stresses in pascals."""
    _name, board, source = connected_board()
    model = ViewerModel()
    model.set_source(source, reconstructor)
    publishing = ForcePublishing(model, name=f"forces-{uuid.uuid4().hex[:10]}")
    yield board, model, publishing
    publishing.stop()
    model.close()


def receive(board, model, sample):
    before = model.source.stats.received
    board.push_sample(sample.astype(np.float32))
    wait_until(lambda: model.source.stats.received > before, "the frame")
    return model.solve()


def test_every_solved_live_frame_goes_out_stamped_with_its_receive_time(live):
    board, model, publishing = live
    publishing.start(stress=True)
    forces_in = inlet_on(publishing.name, "TactileForce", publishing.outlet.have_consumers)
    stress_in = inlet_on(publishing.name, "Tactile", lambda: publishing.outlet.have_consumers(stress=True))
    sent = press()
    pushed_at = pylsl.local_clock()
    first = receive(board, model, sent)
    model.set_parameters(shear_ratio=0.2)  # the same frame solved again: not published twice
    model.set_auto(False)
    model.solve()
    second = receive(board, model, 0.5 * sent)
    forces, stamps = forces_in.pull_chunk(timeout=TIMEOUT, max_samples=2, min_samples=2)
    stress, stress_stamps = stress_in.pull_chunk(timeout=TIMEOUT, max_samples=2, min_samples=2)
    assert len(forces) == 2 and publishing.published == 2 and publishing.failures == 0
    np.testing.assert_allclose(np.reshape(forces[0], (-1, 3)), first.result.forces, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(np.reshape(forces[1], (-1, 3)), second.result.forces, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(stress[0], sent, rtol=1e-6, atol=1e-3)
    # the receive time on LSL's clock: after the push, before the solve ended, as the frames' own spacing
    assert pushed_at < stamps[0] < pylsl.local_clock()
    assert stamps[1] - stamps[0] == pytest.approx(second.time - first.time, abs=1e-6)
    assert list(stress_stamps) == list(stamps)
    assert "LSL: 2 frames published" in publishing.status() and "TactileForce + Tactile" in publishing.status()


def test_another_board_of_the_same_shape_gets_an_outlet_named_after_it(live, reconstructor):
    board, model, publishing = live
    publishing.start()
    receive(board, model, press())
    first = publishing.outlet
    assert first.source_id == f"{publishing.name}:{model.source.url}:{GRID.size}"
    name, other, source = connected_board()
    model.set_source(source, reconstructor)
    receive(other, model, press())
    assert publishing.outlet is not first and first.closed
    assert publishing.outlet.source_id == f"{publishing.name}:lsl:{name}:{GRID.size}"
    assert publishing.published == 2


def test_stopping_withdraws_the_streams(live):
    _board, _model, publishing = live
    publishing.start()
    assert find_streams(name=publishing.name, timeout=0.5)
    publishing.stop()
    assert publishing.outlet is None and publishing.status() == ""
    assert find_streams(name=publishing.name, timeout=0.5) == []


def test_a_failed_push_is_counted_and_said_once_and_publishing_goes_on(live, monkeypatch, caplog):
    board, model, publishing = live
    messages = []
    model.message.connect(lambda *args: messages.append(args))
    publishing.start()
    monkeypatch.setattr(publishing.outlet, "push", lambda *a, **k: (_ for _ in ()).throw(ValueError("wire cut")))
    receive(board, model, press())
    receive(board, model, 0.5 * press())
    assert publishing.failures == 2 and publishing.published == 0
    assert messages == [("warning", "LSL publishing failed", messages[0][2])] and "wire cut" in messages[0][2]
    assert "2 not published: wire cut" in publishing.status()
    caplog.clear()  # the traceback was logged on purpose


def test_recordings_played_back_are_not_published(reconstructor):
    model = ViewerModel()
    recording = Recording(GRID, np.array([press(), press()]), np.array([0.0, 0.1]))
    model.set_source(RecordingSource(recording), reconstructor)
    publishing = ForcePublishing(model, name=f"forces-{uuid.uuid4().hex[:10]}")
    publishing.start()
    model.solve()
    assert publishing.outlet is None and publishing.published == 0
    assert "once a live board shows" in publishing.status()
    model.close()


def test_options_are_checked(reconstructor):
    model = ViewerModel()
    with pytest.raises(ValueError, match="name must be a non-empty string, got ''"):
        ForcePublishing(model, name="")
    with pytest.raises(ValueError, match="stress must be True or False, got 'yes'"):
        ForcePublishing(model).start(stress="yes")

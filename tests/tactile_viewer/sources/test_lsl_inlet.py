"""LslSource (tactile_viewer/sources/lsl_inlet.py): plain pylsl outlets read as a live board."""

import time
import uuid

import numpy as np
import pylsl
import pytest

from solver import SensorGrid
from tactile_viewer.io.files import load
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.sources.lsl import describe_layout
from tactile_viewer.sources.lsl_inlet import LslSource, SampleDecoder, find_streams

RESOLVE_S = 0.5  # seconds a test listens for its stream's announcement
TIMEOUT = 5.0  # the most any wait may take on a loaded machine

GRID = SensorGrid.regular(4, 3, 0.004, 0.003)


def unique():
    return f"lsl-inlet-{uuid.uuid4().hex[:10]}"  # no test ever sees another's stream


def plain_outlet(name, *, channels=12, source_id="rig-1", layout=None, fmt=pylsl.cf_float32, rate=100.0):
    """A plain pylsl outlet of the type a tactile stream has, its layout in the description when given."""
    info = pylsl.StreamInfo(name, "Tactile", channels, rate, fmt, source_id)
    if layout is not None:
        describe_layout(info.desc(), layout)
    return pylsl.StreamOutlet(info)


def found(name):
    streams = find_streams(name=name, timeout=RESOLVE_S)
    assert len(streams) == 1, streams
    return streams[0]


def wait_until(condition, what):
    deadline = time.monotonic() + TIMEOUT
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


@pytest.fixture
def streaming():
    """A started LslSource on a plain outlet whose description declares a kPa layout; both closed after."""
    made = []

    def make(**options):
        name = unique()
        outlet = plain_outlet(name, layout=SensorLayout(GRID, "kPa", offset=1.0), **options)
        source = LslSource(found(name))
        source.start()
        wait_until(outlet.have_consumers, "the source to connect")
        made.append(source)
        return outlet, source
    yield make
    for source in made:
        source.stop()


def test_find_streams_lists_a_stream_with_what_lsl_announces():
    name = unique()
    outlet = plain_outlet(name)  # noqa: F841 (announced while it lives)
    stream = found(name)
    assert (stream.name, stream.type, stream.channel_count, stream.channel_format, stream.nominal_rate,
            stream.source_id) == (name, "Tactile", 12, "float32", 100.0, "rig-1")
    assert stream.url == f"lsl:{name}" and "12 float32 channels, 100 Hz" in stream.describe()
    assert find_streams(name=name, stream_type="EEG", timeout=RESOLVE_S) == []


def test_our_source_reads_a_plain_outlet_values_calibration_and_statistics(streaming):
    outlet, source = streaming()
    assert source.grid.key == GRID.key and source.layout.units == "kPa"  # from the description
    assert source.label == f"{source.url} (Tactile, 12 channels)"
    rng = np.random.default_rng(7)  # fixed seed: reproducible samples
    sent = rng.uniform(0, 20, size=(30, 12)).astype(np.float32)
    outlet.push_chunk(sent)
    wait_until(lambda: source.stats.received == 30, "30 frames")
    frame = source.take_latest()
    np.testing.assert_allclose(frame.raw, sent[-1], rtol=1e-7)
    np.testing.assert_allclose(frame.stress, (sent[-1].astype(float) - 1.0) * 1e3, rtol=1e-6)
    assert frame.index is None  # LSL numbers no samples
    stats = source.stats.snapshot(source.now())
    assert (stats.received, stats.lost, stats.out_of_order) == (30, 0, 0) and source.published == 30
    assert source.rejected() == {} and source.state == "connected"


def test_a_layout_file_overrides_the_description(tmp_path):
    name = unique()
    outlet = plain_outlet(name)  # noqa: F841 (no description at all)
    layout = SensorLayout(GRID.replace(thickness=0.002), "Pa")
    source = LslSource(found(name), layout)
    source.stop()
    assert source.grid.thickness == 0.002



def test_a_source_stopped_before_it_started_closes_the_inlet_it_opened():
    # the window's connection made after the window closed is stopped unstarted: no consumer stays
    name = unique()
    outlet = plain_outlet(name, layout=SensorLayout(GRID, "kPa"))
    source = LslSource(found(name))
    wait_until(outlet.have_consumers, "the constructor's inlet to connect")
    source.stop()
    wait_until(lambda: not outlet.have_consumers(), "the inlet to close")
    assert source.state == "stopped"


def test_nan_and_wrong_count_samples_are_counted_never_handed_on(streaming):
    outlet, source = streaming()
    bad = np.full((1, 12), 3.0, dtype=np.float32)
    bad[0, 5] = np.nan
    outlet.push_chunk(bad)
    outlet.push_sample(np.full(12, 2.0, np.float32))
    wait_until(lambda: source.stats.received == 1, "the good frame")
    assert source.rejected() == {"non-finite value": 1}
    assert source.take_latest().raw[0] == 2.0
    # a sample of another length cannot come over a stream of fixed width: the decoder counts it all the same
    decoder = SampleDecoder(12)
    assert decoder.feed((np.ones((2, 11)), np.zeros(2))) == []
    assert decoder.rejected == {"wrong value count": 2} and decoder.wrong_sizes == {11: 2}


def test_a_stream_of_another_channel_count_is_refused_by_name():
    name = unique()
    outlet = plain_outlet(name, channels=16)  # noqa: F841
    with pytest.raises(ValueError, match="the stream has 16 channels but the layout describes 12 taxels"):
        LslSource(found(name), SensorLayout(GRID))


def test_a_stream_without_layout_asks_for_a_file():
    name = unique()
    outlet = plain_outlet(name)  # noqa: F841
    with pytest.raises(ValueError, match=f"stream '{name}': the stream's description has no <layout> "
                                         "element; choose a layout file"):
        LslSource(found(name))


def test_a_stream_of_text_is_refused():
    name = unique()
    outlet = plain_outlet(name, fmt=pylsl.cf_string)  # noqa: F841
    with pytest.raises(ValueError, match=f"stream '{name}' sends string channels"):
        LslSource(found(name), SensorLayout(GRID))


def test_no_data_when_the_stream_stops_and_the_frames_recorded_stay(streaming, tmp_path):
    outlet, source = streaming()
    source.start_recording(tmp_path / "lsl.mcap")
    outlet.push_chunk(np.ones((20, 12), dtype=np.float32))
    wait_until(lambda: source.stats.received == 20, "20 frames")
    del outlet  # the stream goes away
    wait_until(lambda: source.state == "reconnecting", "the loss to show")
    assert source.error
    assert source.stats.snapshot(source.now()).silence > 0  # the live bar's NO DATA reads this
    assert source.stop_recording() is not None
    recording = load(tmp_path / "lsl.mcap")
    assert len(recording) == 20
    np.testing.assert_allclose(recording.frames[19], np.zeros(12))  # 1 kPa raw minus the 1 kPa offset


def test_a_stream_that_comes_back_with_its_source_id_is_read_again(streaming):
    outlet, source = streaming(source_id="same-rig")
    name = source.stream.name
    del outlet
    wait_until(lambda: source.state == "reconnecting", "the loss")
    again = plain_outlet(name, source_id="same-rig")
    wait_until(lambda: source.state == "connected" and again.have_consumers(), "the reconnection")
    again.push_sample(np.full(12, 4.0, np.float32))
    wait_until(lambda: source.stats.received == 1, "a frame after the reconnection")
    assert source.reconnects == 1 and source.same_device_known and source.identity_notice == ""


def test_find_streams_checks_its_timeout():
    with pytest.raises(ValueError, match="timeout must be a positive finite number of seconds, got 0"):
        find_streams(timeout=0)


def test_the_source_wants_a_found_stream():
    with pytest.raises(TypeError, match="stream must be a FoundStream"):
        LslSource("lsl:board", SensorLayout(GRID))


def test_any_pylsl_error_while_reading_is_a_loss_the_reader_survives(streaming, monkeypatch):
    outlet, source = streaming(source_id="glitchy-rig")
    real_read = LslSource._read
    raised = []

    def read_once_failing(self, inlet):
        if not raised:
            raised.append(True)
            raise pylsl.util.InternalError("an internal error in liblsl")  # neither LostError nor a timeout
        return real_read(self, inlet)
    monkeypatch.setattr(LslSource, "_read", read_once_failing)
    wait_until(lambda: raised and source.reconnects == 1 and source.state == "connected", "the reconnection")
    assert source._thread.is_alive()
    outlet.push_sample(np.full(12, 4.0, np.float32))
    wait_until(lambda: source.stats.received == 1, "a frame after the error")

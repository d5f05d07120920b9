"""ForceOutlet and the <layout> description (tactile_viewer/sources/lsl.py), read by plain pylsl inlets."""

import time
import uuid

import numpy as np
import pylsl
import pytest

from solver import SensorGrid
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.sources.lsl import (
    ForceOutlet,
    clock_offset,
    describe_layout,
    layout_from_description,
)

TIMEOUT = 5.0  # seconds any single LSL wait may take on a loaded machine


def unique(prefix="lsl-test"):
    return f"{prefix}-{uuid.uuid4().hex[:10]}"  # no test ever sees another's stream


def plain_inlet(name, stream_type, outlet):
    """A plain pylsl inlet on the stream ``name`` of ``stream_type``, connected before anything is pushed."""
    found = pylsl.resolve_bypred(f"name='{name}' and type='{stream_type}'", minimum=1, timeout=TIMEOUT)
    assert found, f"{name} {stream_type} not resolved"
    inlet = pylsl.StreamInlet(found[0], recover=False)
    info = inlet.info(timeout=TIMEOUT)
    inlet.open_stream(timeout=TIMEOUT)
    deadline = time.monotonic() + TIMEOUT
    while not outlet.have_consumers(stress=stream_type == "Tactile") and time.monotonic() < deadline:
        time.sleep(0.01)
    return inlet, info


def pull(inlet, count):
    samples, stamps = [], []
    deadline = time.monotonic() + TIMEOUT
    while len(samples) < count and time.monotonic() < deadline:
        chunk, times = inlet.pull_chunk(timeout=0.2)
        samples += chunk
        stamps += times
    return np.array(samples), np.array(stamps)


@pytest.fixture
def grid():
    # 4x3 on a 3 mm pitch, moved off the default place so the positions must travel in the description
    regular = SensorGrid.regular(4, 3, 0.003, 0.002, poisson_ratio=0.45, sensor_size=0.001)
    return regular.replace(positions=regular.positions + [0.01, -0.002])


def test_a_plain_inlet_reads_our_forces_labels_units_values_and_stamps(grid):
    name = unique()
    rng = np.random.default_rng(32)  # fixed seed: reproducible forces
    forces = rng.normal(scale=0.05, size=(5, grid.size, 3))
    stamps = pylsl.local_clock() - 1.0 + np.arange(5) * 0.001  # receive times on LSL's clock
    with ForceOutlet(grid, name=name, source_id="board-7") as outlet:
        inlet, info = plain_inlet(name, "TactileForce", outlet)
        assert info.channel_count() == 3 * grid.size == 36
        assert info.channel_format() == pylsl.cf_float32
        assert info.source_id() == "board-7"
        labels = info.get_channel_labels()
        assert labels[:4] == ["node0_Fx", "node0_Fy", "node0_Fz", "node1_Fx"] and labels[-1] == "node11_Fz"
        assert set(info.get_channel_units()) == {"newtons"} and set(info.get_channel_types()) == {"Force"}
        for frame, stamp in zip(forces, stamps, strict=True):
            outlet.push(frame, stamp=float(stamp))
        values, received = pull(inlet, 5)
    assert values.shape == (5, 36)
    # float32 on the wire: node k's Fx, Fy, Fz at channels 3k, 3k+1, 3k+2
    np.testing.assert_allclose(values.reshape(5, grid.size, 3), forces, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(received, stamps, rtol=0, atol=1e-9)  # stamps as given, no re-stamping
    assert outlet.closed and outlet.pushed == 5
    # the node positions and the skin travel with the stream
    described = layout_from_description(info.desc())
    np.testing.assert_allclose(described.grid.positions, grid.positions, rtol=0, atol=1e-15)
    assert described.grid.shape == (3, 4)
    assert (described.grid.pitch, described.grid.thickness, described.grid.poisson_ratio,
            described.grid.sensor_size) == (0.003, 0.002, 0.45, 0.001)


def test_the_stress_stream_is_in_pascals_beside_the_forces(grid):
    name = unique()
    stress = np.linspace(-500.0, 12e3, grid.size)
    with ForceOutlet(grid, name=name, stress=True) as outlet:
        inlet, info = plain_inlet(name, "Tactile", outlet)
        assert info.channel_count() == grid.size and info.source_id() == ""
        assert info.get_channel_labels() == [f"taxel{k}" for k in range(grid.size)]
        assert set(info.get_channel_units()) == {"pascals"}
        layout = layout_from_description(info.desc())
        assert layout.units == "Pa" and np.all(layout.gain == 1) and np.all(layout.offset == 0)
        outlet.push(np.zeros((grid.size, 3)), stamp=123.5, stress=stress)
        outlet.push(np.zeros((grid.size, 3)), stamp=124.0)  # forces alone: no stress sample
        values, received = pull(inlet, 1)
        later, _ = inlet.pull_chunk(timeout=0.2)  # the forces-only frame sent no stress
    np.testing.assert_allclose(values[0], stress, rtol=1e-6)
    assert received.tolist() == [123.5] and later == []


def test_a_source_id_names_the_stress_stream_apart(grid):
    with ForceOutlet(grid, name=unique(), source_id="rig", stress=True) as outlet:
        assert outlet.force_info.source_id() == "rig" and outlet.stress_info.source_id() == "rig/stress"
        assert outlet.publishes_stress


@pytest.mark.parametrize("call, match", [
    (lambda o, g: o.push(np.zeros((g.size, 2)), stamp=1.0), r"forces must have shape \(12, 3\).*got \(12, 2\)"),
    (lambda o, g: o.push(np.full((g.size, 3), np.nan), stamp=1.0), "forces must be finite"),
    (lambda o, g: o.push(np.zeros((g.size, 3)), stamp=float("nan")), "stamp must be a positive finite.*nan"),
    (lambda o, g: o.push(np.zeros((g.size, 3)), stamp=-1.0), "stamp must be a positive finite.*-1.0"),
    (lambda o, g: o.push(np.zeros((g.size, 3)), stamp=1.0, stress=np.zeros(g.size)),
     "stress given, but the outlet publishes none"),
])
def test_push_checks_its_input(grid, call, match):
    with ForceOutlet(grid, name=unique()) as outlet:
        with pytest.raises(ValueError, match=match):
            call(outlet, grid)
        assert outlet.pushed == 0


def test_push_checks_the_stress(grid):
    with ForceOutlet(grid, name=unique(), stress=True) as outlet:
        with pytest.raises(ValueError, match=r"stress must have shape \(12,\).*got \(11,\)"):
            outlet.push(np.zeros((grid.size, 3)), stamp=1.0, stress=np.zeros(11))
        with pytest.raises(ValueError, match="stress must be finite"):
            outlet.push(np.zeros((grid.size, 3)), stamp=1.0, stress=np.full(grid.size, np.inf))


def test_a_closed_outlet_refuses_frames(grid):
    outlet = ForceOutlet(grid, name=unique())
    outlet.close()
    outlet.close()  # again: nothing
    with pytest.raises(ValueError, match="the outlet is closed"):
        outlet.push(np.zeros((grid.size, 3)), stamp=1.0)
    assert not outlet.have_consumers()


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(name=""), ValueError, "name must be a non-empty string, got ''"),
    (dict(stress=1), ValueError, "stress must be True or False, got 1"),
    (dict(source_id=3), ValueError, "source_id must be a string or None, got 3"),
    (dict(nominal_rate=-1), ValueError, r"nominal_rate must be a finite number of hertz >= 0.*got -1"),
])
def test_outlet_options_are_checked(grid, kwargs, error, match):
    with pytest.raises(error, match=match):
        ForceOutlet(grid, **kwargs)


def test_the_outlet_wants_a_grid():
    with pytest.raises(TypeError, match="grid must be a SensorGrid, got ndarray"):
        ForceOutlet(np.zeros((4, 2)))


def info_with(layout_children):
    """A StreamInfo whose description holds ``<layout>`` with the given (name, text) children."""
    info = pylsl.StreamInfo(unique(), "Tactile", 6, 0, pylsl.cf_float32, "")
    element = info.desc().append_child("layout")
    for key, text in layout_children:
        element.append_child_value(key, text)
    return info


def test_a_layout_reads_back_as_written_calibration_included():
    grid = SensorGrid.regular(3, 2, 0.004, 0.005)
    layout = SensorLayout(grid, "kPa", gain=np.linspace(0.9, 1.1, 6), offset=2.5)
    info = pylsl.StreamInfo(unique(), "Tactile", 6, 0, pylsl.cf_float32, "")
    describe_layout(info.desc(), layout)
    read = layout_from_description(info.desc())
    assert read.units == "kPa" and read.grid.key == grid.key
    np.testing.assert_array_equal(read.gain, layout.gain)
    np.testing.assert_array_equal(read.offset, np.full(6, 2.5))


def test_the_urdf_tactile_names_rows_and_cols_are_read():
    layout = layout_from_description(info_with([("cols", "3"), ("rows", "2"), ("pitch", "0.004"),
                                                ("thickness", "0.002"), ("gain", "1, 2, 3, 4, 5, 6")]).desc())
    assert layout.grid.shape == (2, 3) and layout.gain.tolist() == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("children, match", [
    ([], "<layout>: missing 'nx', 'ny', 'pitch', 'thickness'"),
    ([("nx", "3"), ("ny", "2"), ("pitch", "4 mm"), ("thickness", "0.002")],
     r"<layout> <pitch>: expected numbers, got '4 mm'"),
    ([("nx", "3.5"), ("ny", "2"), ("pitch", "0.004"), ("thickness", "0.002")],
     r"<layout> <nx>: expected a whole number, got '3.5'"),
    ([("nx", "3"), ("ny", "2"), ("pitch", "0.004 0.005"), ("thickness", "0.002")],
     r"<layout> <pitch>: expected one number"),
    ([("taxels", "3"), ("positions", "0 0 1"), ("pitch", "0.004"), ("thickness", "0.002")],
     r"<positions> must hold x y pairs, got 3 numbers"),
    ([("nx", "3"), ("ny", "2"), ("pitch", "0.004"), ("thickness", "0.002"), ("units", "psi")],
     "<layout>: units must be one of"),
    ([("nx", "3"), ("ny", "2"), ("pitch", "0.004"), ("thickness", "0.002"), ("gain", "1 2")],
     r"<layout>: gain must .*6"),
])
def test_a_wrong_layout_description_is_named(children, match):
    with pytest.raises(ValueError, match=match):
        layout_from_description(info_with(children).desc())


def test_a_description_without_layout_says_so():
    info = pylsl.StreamInfo(unique(), "Tactile", 6, 0, pylsl.cf_float32, "")
    with pytest.raises(ValueError, match="the stream's description has no <layout> element"):
        layout_from_description(info.desc())


def test_clock_offset_maps_a_receive_clock_onto_lsls():
    origin = time.perf_counter()
    offset = clock_offset(lambda: time.perf_counter() - origin)
    # a reading of the receive clock plus the offset is LSL's clock at that instant (both monotonic)
    # (the closest of five tries: a thread switch between the two readings on a busy machine widens one)
    misses = [abs((time.perf_counter() - origin) + offset - pylsl.local_clock()) for _ in range(5)]
    assert min(misses) < 0.001

"""Foxglove MCAP files (tactile_viewer/io/foxglove_mcap.py), read back with the mcap reader and its protobuf
decoder (mcap-protobuf-support, which decodes with the schemas the file carries), no Qt."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from solver import SensorGrid
from tactile_viewer.io.forces import ForceTable
from tactile_viewer.io.foxglove_mcap import METADATA_NAME, TOPICS, readable_scales, write_foxglove
from tactile_viewer.io.ros2_message import FRAME_ID

START = 1_764_000_000.25  # UNIX seconds of t = 0


def read_back(path) -> dict:
    """Everything in the file as the other side reads it: schemas, messages decoded, metadata, statistics."""
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        messages = {topic: [] for topic in schemas}
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding in ("protobuf", "jsonschema")
            messages[channel.topic].append(message)
        handle.seek(0)
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        decoded = {topic: [] for topic in schemas}
        for _, channel, _, proto in reader.iter_decoded_messages(
                topics=[t for t, s in schemas.items() if s.encoding == "protobuf"]):
            decoded[channel.topic].append(proto)
        for topic, schema in schemas.items():
            if schema.encoding == "jsonschema":
                decoded[topic] = [json.loads(m.data) for m in messages[topic]]
        handle.seek(0)
        metadata = {m.name: m.metadata for m in make_reader(handle).iter_metadata()}
    return dict(schemas=schemas, messages=messages, decoded=decoded, metadata=metadata,
                statistics=summary.statistics)


def rotated_x(orientation) -> np.ndarray:
    """+x turned by a decoded quaternion: v + 2w (q x v) + 2 q x (q x v)."""
    q = np.array([orientation.x, orientation.y, orientation.z])
    v = np.array([1.0, 0.0, 0.0])
    return v + 2 * orientation.w * np.cross(q, v) + 2 * np.cross(q, np.cross(q, v))


def arrow_vectors(arrows) -> tuple[np.ndarray, np.ndarray]:
    """The tails and the vectors (direction times shaft plus head) of decoded arrows."""
    tails = np.array([[a.pose.position.x, a.pose.position.y, a.pose.position.z] for a in arrows])
    vectors = np.array([rotated_x(a.pose.orientation) * (a.shaft_length + a.head_length) for a in arrows])
    return tails.reshape(-1, 3), vectors.reshape(-1, 3)


def table_of(grid: SensorGrid, frames, *, seed: int) -> ForceTable:
    """A force table with random forces and two contacts that swap slots (fixed ``seed``)."""
    rng = np.random.default_rng(seed)
    count = len(frames)
    forces = rng.normal(0, 0.01, size=(count, grid.size, 3))
    forces[:, :, 2] += 0.02
    forces[0, 0] = 0.0  # a node without force: an arrow of no length
    identity = np.array([[1, 2]] * count)
    identity[-1] = (2, 0)  # the last frame: contact 2 alone
    contact_force = rng.normal(0, 0.1, size=(count, 2, 3)) + [0, 0, 0.5]
    contact_force[-1, 1] = np.nan
    centre = rng.uniform(-2e-3, 2e-3, size=(count, 2, 2))
    centre[-1, 1] = np.nan
    return ForceTable(forces=forces, frames=np.asarray(frames), t=np.asarray(frames) / 100.0,
                      shear_ratio=np.r_[np.full(count - 1, 0.3), np.nan], shear_direction=np.full(count, 0.5),
                      efficiency=np.zeros(count), residual=np.zeros(count), condition=np.ones(count),
                      positions=grid.positions, shape=tuple(grid.shape), pitch=grid.pitch,
                      thickness=grid.thickness, kernel="layer", mode="auto", source="takes/press.npz",
                      contact_identity=identity, contact_force=contact_force, contact_centre=centre)


@pytest.fixture(scope="module")
def grid():
    return SensorGrid.regular(5, 4, 2e-3, 2e-3)


@pytest.fixture(scope="module")
def written(grid, tmp_path_factory):
    """Frames 1, 2, 4 and 5 of a six-frame recording (frames 0 and 3 refused), written and read back."""
    stress = np.random.default_rng(3).normal(2e3, 500, size=(6, grid.size))  # fixed seed
    table = replace(table_of(grid, [1, 2, 4, 5], seed=5),
                    fallback=["", "solved by the faster member while the stream was 120 frames behind", "", ""])
    path = tmp_path_factory.mktemp("fox") / "press.mcap"
    steps = []
    export = write_foxglove(path, table, stress, start_time=START, arrow_scale=0.05, resultant_scale=0.01,
                            refused=[(0, "stress must be finite"), (3, "too large")],
                            progress=lambda done, total: steps.append((done, total)))
    return dict(table=table, stress=stress, export=export, back=read_back(path), steps=steps, path=path)


def test_one_message_per_frame_on_each_topic_with_foxglove_schemas(written):
    back, export = written["back"], written["export"]
    assert {t: s.name for t, s in back["schemas"].items()} == {
        TOPICS["stress"]: "foxglove.Grid", TOPICS["pressure"]: "foxglove.Grid",
        TOPICS["forces"]: "foxglove.SceneUpdate", TOPICS["contacts"]: "tactile_viewer.ContactTotals"}
    by_schema = {}
    for topic, messages in back["messages"].items():
        by_schema[back["schemas"][topic].name] = by_schema.get(back["schemas"][topic].name, 0) + len(messages)
    assert by_schema == {"foxglove.Grid": 8, "foxglove.SceneUpdate": 4, "tactile_viewer.ContactTotals": 4}
    assert export.frames == 4 and export.messages == dict.fromkeys(TOPICS.values(), 4)
    assert back["statistics"].message_count == 16
    assert written["steps"][-1] == (4, 4)


def test_stamps_are_the_frames_times(written):
    expected = [round((START + t) * 1e9) for t in written["table"].t]
    for topic, messages in written["back"]["messages"].items():
        assert [m.log_time for m in messages] == expected, topic
        assert [m.publish_time for m in messages] == expected, topic
    for proto in written["back"]["decoded"][TOPICS["stress"]]:
        assert proto.frame_id == FRAME_ID
    stamps = [p.timestamp.seconds * 10**9 + p.timestamp.nanos for p in written["back"]["decoded"][TOPICS["stress"]]]
    assert stamps == expected
    scene_stamps = [e.timestamp.seconds * 10**9 + e.timestamp.nanos
                    for p in written["back"]["decoded"][TOPICS["forces"]] for e in p.entities]
    assert scene_stamps == [s for s in expected for _ in range(2)]
    json_stamps = [m["timestamp"]["sec"] * 10**9 + m["timestamp"]["nsec"]
                   for m in written["back"]["decoded"][TOPICS["contacts"]]]
    assert json_stamps == expected


def test_grid_cells_hold_the_stress_and_the_pressure(written, grid):
    table, stress = written["table"], written["stress"]
    for name, topic in (("stress", TOPICS["stress"]), ("pressure", TOPICS["pressure"])):
        for row, proto in enumerate(written["back"]["decoded"][topic]):
            assert proto.column_count == 5 and proto.row_stride == 20 and proto.cell_stride == 4
            assert (proto.cell_size.x, proto.cell_size.y) == (grid.pitch, grid.pitch)
            assert [(f.name, f.offset) for f in proto.fields] == [(name, 0)]
            # the corner is the first taxel's cell corner: cell (ix, iy) is centred on node iy * nx + ix
            corner = (proto.pose.position.x, proto.pose.position.y)
            assert corner == pytest.approx(tuple(grid.positions[0] - grid.pitch / 2), abs=1e-12)
            cells = np.frombuffer(proto.data, "<f4")
            expected = stress[table.frames[row]] if name == "stress" else table.forces[row, :, 2] / grid.pitch**2
            np.testing.assert_array_equal(cells, expected.astype("<f4"))


def test_node_arrows_are_the_node_forces_scaled_and_end_on_their_nodes(written, grid):
    table = written["table"]
    for row, proto in enumerate(written["back"]["decoded"][TOPICS["forces"]]):
        nodes = next(e for e in proto.entities if e.id == "nodes")
        assert len(nodes.arrows) == grid.size
        assert {kv.key: kv.value for kv in nodes.metadata} == {"metres_per_newton": "0.05"}
        tails, vectors = arrow_vectors(nodes.arrows)
        forces = table.forces[row]
        # drawn (Fx, Fy, -Fz) * 0.05 m/N: a press points down into the skin, z out of it
        np.testing.assert_allclose(vectors / 0.05, forces * [1, 1, -1], rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(tails + vectors, np.column_stack([grid.positions, np.zeros(grid.size)]),
                                   rtol=0, atol=1e-12)
    first = next(e for e in written["back"]["decoded"][TOPICS["forces"]][0].entities if e.id == "nodes").arrows[0]
    assert first.shaft_length == 0 and first.head_length == 0 and first.pose.orientation.w == 1


def test_resultants_and_totals_are_the_contacts_of_the_table(written):
    table = written["table"]
    colours = {}
    for row, (proto, totals) in enumerate(zip(written["back"]["decoded"][TOPICS["forces"]],
                                              written["back"]["decoded"][TOPICS["contacts"]], strict=True)):
        contacts = next(e for e in proto.entities if e.id == "contacts")
        slots = np.flatnonzero(table.contact_identity[row])
        tails, vectors = arrow_vectors(contacts.arrows)
        np.testing.assert_allclose(vectors / 0.01, table.contact_force[row, slots] * [1, 1, -1], rtol=1e-6)
        np.testing.assert_allclose((tails + vectors)[:, :2], table.contact_centre[row, slots], atol=1e-12)
        assert [t.text.split()[0] for t in contacts.texts] == [f"#{k}" for k in table.contact_identity[row, slots]]
        for identity, arrow in zip(table.contact_identity[row, slots], contacts.arrows, strict=True):
            colour = (arrow.color.r, arrow.color.g, arrow.color.b)
            assert colours.setdefault(int(identity), colour) == colour  # a contact keeps its colour
        assert totals["frame"] == table.frames[row] and totals["t"] == table.t[row]
        assert totals["contact_count"] == len(slots)
        assert [c["identity"] for c in totals["contacts"]] == table.contact_identity[row, slots].tolist()
        np.testing.assert_allclose([[c["fx"], c["fy"], c["fz"]] for c in totals["contacts"]],
                                   table.contact_force[row, slots], rtol=1e-15)
        np.testing.assert_allclose([[c["x"], c["y"]] for c in totals["contacts"]],
                                   table.contact_centre[row, slots], rtol=1e-15)
        total = table.forces[row].sum(axis=0)
        assert [totals["total"][k] for k in ("fx", "fy", "fz")] == pytest.approx(total, rel=1e-12)
    assert colours[1] != colours[2]
    assert written["back"]["decoded"][TOPICS["contacts"]][-1]["shear_ratio"] is None  # nan: JSON has none


def test_the_metadata_names_the_source_scales_and_the_frames_left_out(written):
    meta = written["back"]["metadata"][METADATA_NAME]
    assert meta["source"] == "takes/press.npz" and meta["kernel"] == "layer" and meta["frames"] == "4"
    assert meta["refused_frames"] == "2" and meta["refused"] == "0: stress must be finite, 3: too large"
    assert meta["fallback_frames"] == "1"  # a frame off the accurate path, named with why
    assert meta["fallback"] == "2: solved by the faster member while the stream was 120 frames behind"
    assert float(meta["arrow_scale_m_per_N"]) == 0.05 and float(meta["resultant_scale_m_per_N"]) == 0.01
    assert written["export"].refused == ((0, "stress must be finite"), (3, "too large"))


def test_an_irregular_layout_is_a_point_cloud(tmp_path):
    positions = np.random.default_rng(8).uniform(-5e-3, 5e-3, size=(7, 2))  # fixed seed
    grid = SensorGrid(positions, 2e-3, 2e-3, (7,))
    table = table_of(grid, [0, 1, 2], seed=9)
    stress = np.random.default_rng(4).normal(1e3, 100, size=(3, 7))  # fixed seed
    back = read_back(write_foxglove(tmp_path / "irregular.mcap", table, stress).path)
    assert back["schemas"][TOPICS["stress"]].name == "foxglove.PointCloud"
    for row, proto in enumerate(back["decoded"][TOPICS["stress"]]):
        assert [(f.name, f.offset) for f in proto.fields] == [("x", 0), ("y", 4), ("z", 8), ("stress", 12)]
        points = np.frombuffer(proto.data, "<f4").reshape(7, 4)
        np.testing.assert_array_equal(points[:, :2], positions.astype("<f4"))
        np.testing.assert_array_equal(points[:, 3], stress[row].astype("<f4"))


def test_a_moved_rectangle_of_taxels_is_still_a_grid(tmp_path):
    grid = SensorGrid.regular(3, 2, 2e-3, 2e-3)
    grid = grid.replace(positions=grid.positions + [0.01, -0.02])
    table = table_of(grid, [0, 1], seed=2)
    back = read_back(write_foxglove(tmp_path / "moved.mcap", table, np.ones((2, 6))).path)
    proto = back["decoded"][TOPICS["pressure"]][0]
    assert back["schemas"][TOPICS["pressure"]].name == "foxglove.Grid"
    assert (proto.pose.position.x, proto.pose.position.y) == pytest.approx((0.01 - 3e-3, -0.02 - 2e-3))


def test_default_scales_make_the_largest_node_force_three_pitches_long(written, tmp_path, grid):
    table = written["table"]
    arrow_scale, resultant_scale = readable_scales(table)
    assert arrow_scale * np.linalg.norm(table.forces, axis=-1).max() == pytest.approx(3 * grid.pitch)
    width = 4 * grid.pitch + grid.pitch
    assert resultant_scale * np.nanmax(np.linalg.norm(table.contact_force, axis=-1)) == pytest.approx(width / 2)
    export = write_foxglove(tmp_path / "default.mcap", table, written["stress"])
    assert (export.arrow_scale, export.resultant_scale) == (arrow_scale, resultant_scale)
    assert export.refused == ()
    assert read_back(export.path)["metadata"][METADATA_NAME]["refused_frames"] == "0"


@pytest.mark.parametrize(("options", "message"), [
    (dict(arrow_scale=0.0), r"^arrow_scale must be metres per newton, finite and > 0, got 0.0$"),
    (dict(resultant_scale=math.nan), r"^resultant_scale must be metres per newton, finite and > 0, got nan$"),
    (dict(arrow_scale="big"), r"^arrow_scale must be metres per newton, finite and > 0, got 'big'$"),
    (dict(start_time=math.inf), r"^start_time must be finite UNIX seconds, got inf$"),
    (dict(stress=np.ones((6, 19))), r"^stress must be the recording's \(N, 20\) frames, N above every frame of "
                                    r"the table \(up to 5\), got shape \(6, 19\)$"),
    (dict(stress=np.ones((5, 20))), r"^stress must be .* got shape \(5, 20\)$"),
])
def test_bad_options_are_refused_and_nothing_is_written(written, tmp_path, options, message):
    with pytest.raises(ValueError, match=message):
        write_foxglove(tmp_path / "bad.mcap", written["table"], options.pop("stress", written["stress"]), **options)
    assert list(tmp_path.iterdir()) == []


def test_a_failure_while_writing_leaves_no_file_and_keeps_the_old_one(written, tmp_path):
    path = tmp_path / "kept.mcap"
    path.write_bytes(b"an earlier file")

    def stop(done, total):
        raise KeyboardInterrupt("stopped")

    with pytest.raises(KeyboardInterrupt, match="stopped"):
        write_foxglove(path, written["table"], written["stress"], progress=stop)
    assert [p.name for p in tmp_path.iterdir()] == ["kept.mcap"] and path.read_bytes() == b"an earlier file"

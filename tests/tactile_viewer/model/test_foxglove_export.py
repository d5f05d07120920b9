"""A recording solved and written for Foxglove (tactile_viewer/model/foxglove_export.py), and the batch path
(tactile-batch --format foxglove), read back with the mcap reader and its protobuf decoder. No Qt."""

import numpy as np
import pytest

from tactile_viewer.io.files import load, save
from tactile_viewer.io.forces import load_forces
from tactile_viewer.io.foxglove_mcap import METADATA_NAME, TOPICS
from tactile_viewer.io.mcap_writer import Recorder
from tactile_viewer.io.recording import Recording, RecordingError
from tactile_viewer.model import foxglove_export
from tactile_viewer.model.batch import BatchSettings, plan_file
from tactile_viewer.model.batch_engines import JoblibEngine, run_batch
from tactile_viewer.model.batch_inputs import find_recordings, is_finished
from tactile_viewer.model.force_tables import reconstruct_frames
from tactile_viewer.model.foxglove_export import export_foxglove, force_file_ending, save_force_file
from tactile_viewer.model.worker import Cancelled
from tests.tactile_viewer.io.test_foxglove_mcap import arrow_vectors, read_back

RECEIVED = 1_764_000_000.5  # UNIX seconds frame 0 of the live recording was received


def node_forces(back) -> np.ndarray:
    """``(T, m, 3)`` node forces drawn in a file, unscaled by the scale it states, as (Fx, Fy, Fz)."""
    frames = []
    for proto in back["decoded"][TOPICS["forces"]]:
        nodes = next(e for e in proto.entities if e.id == "nodes")
        scale = float(next(kv.value for kv in nodes.metadata if kv.key == "metres_per_newton"))
        frames.append(arrow_vectors(nodes.arrows)[1] / scale * [1, 1, -1])
    return np.array(frames)


def test_every_frame_is_the_solvers_and_stamped_with_its_time(recording, reconstructor, tmp_path):
    steps = []
    export = export_foxglove(recording, reconstructor, tmp_path / "take.mcap", source="takes/sliding.npz",
                             progress=lambda done, total: steps.append((done, total)))
    expected = reconstruct_frames(recording, reconstructor)
    back = read_back(export.path)
    assert export.frames == 4 and export.messages == dict.fromkeys(TOPICS.values(), 4) and export.refused == ()
    np.testing.assert_allclose(node_forces(back), expected.forces, rtol=1e-6, atol=1e-9)
    # no receive clock (an NPZ): the times from 1970
    assert [m.log_time for m in back["messages"][TOPICS["stress"]]] == [round(t * 1e9) for t in recording.t]
    cells = [np.frombuffer(p.data, "<f4") for p in back["decoded"][TOPICS["stress"]]]
    np.testing.assert_array_equal(cells, np.asarray(recording.frames).astype("<f4"))
    totals = back["decoded"][TOPICS["contacts"]]
    identity = expected.contact_identity
    assert [[c["identity"] for c in m["contacts"]] for m in totals] == [r[r > 0].tolist() for r in identity]
    assert back["metadata"][METADATA_NAME]["source"] == "takes/sliding.npz"
    assert steps[0] == (1, 8) and steps[-1] == (8, 8)  # the solving, then the writing


def test_a_frame_the_solver_refuses_is_left_out_and_named(recording, reconstructor, tmp_path):
    frames = np.array(recording.frames)
    frames[2, 5] = 1e200  # beyond any stress a solve takes
    damaged = Recording(recording.grid, frames, recording.t, description="one bad frame")
    export = export_foxglove(damaged, reconstructor, tmp_path / "bad.mcap", shear_ratio=0.2, shear_direction=0.5)
    assert export.frames == 3 and [k for k, _ in export.refused] == [2]
    assert "stress must be at most" in export.refused[0][1]
    back = read_back(export.path)
    assert [m["frame"] for m in back["decoded"][TOPICS["contacts"]]] == [0, 1, 3]
    assert all(len(m) == 3 for m in back["messages"].values())
    assert back["metadata"][METADATA_NAME]["refused_frames"] == "1"
    expected = reconstruct_frames(damaged, reconstructor, [0, 1, 3], shear_ratio=0.2, shear_direction=0.5)
    np.testing.assert_allclose(node_forces(back), expected.forces, rtol=1e-6, atol=1e-9)


def test_nothing_is_written_when_no_frame_can_be_solved(recording, reconstructor, tmp_path):
    hopeless = Recording(recording.grid, np.full((2, recording.grid.size), 1e200), [0.0, 0.1])
    with pytest.raises(ValueError, match=r"^no frame of the recording could be solved \(2 refused: frame 0: "
                                         r"stress must be at most"):
        export_foxglove(hopeless, reconstructor, tmp_path / "none.mcap")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("path", "options", "message"), [
    ("take.mcap", dict(shear_ratio=-1.0, shear_direction=0.0), r"^shear_ratio must be finite and >= 0"),
    ("take.npz", {}, r"^path must end in \.mcap \(Foxglove opens MCAP files by their ending\), got '.*take\.npz'$"),
])
def test_bad_arguments_are_refused_before_solving(recording, reconstructor, tmp_path, path, options, message):
    with pytest.raises(ValueError, match=message):
        export_foxglove(recording, reconstructor, tmp_path / path, **options)
    assert list(tmp_path.iterdir()) == []


def test_cancelling_while_writing_leaves_no_file(recording, reconstructor, tmp_path):
    with pytest.raises(Cancelled, match="cancelled after writing 4 of 4 frames"):
        export_foxglove(recording, reconstructor, tmp_path / "stop.mcap",
                        progress=lambda done, total: done <= total // 2)  # stops once the writing reports
    assert list(tmp_path.iterdir()) == []


def test_output_endings_and_the_force_formats_still_written_by_ending(recording, reconstructor, tmp_path):
    assert [force_file_ending(f) for f in ("npz", "csv", "foxglove")] == [".npz", ".csv", ".mcap"]
    with pytest.raises(ValueError, match=r"^--format must be one of \('npz', 'csv', 'foxglove'\), got 'h5'$"):
        force_file_ending("h5")
    table = reconstruct_frames(recording, reconstructor)
    written = save_force_file(table, tmp_path / "forces.npz", source="x")
    np.testing.assert_array_equal(load_forces(written)["forces"], table.forces)


@pytest.fixture(scope="module")
def live_take(recording, tmp_path_factory):
    """The sliding contact as a live MCAP recording, received from RECEIVED on at 20 Hz."""
    path = tmp_path_factory.mktemp("live") / "sliding.mcap"
    recorder = Recorder(path, recording.grid, dtype="float64", flush_interval=0.1)
    for k in range(len(recording)):
        recorder.add(k, RECEIVED + recording.t[k], recording.frames[k])
    recorder.close()
    return path


def test_the_batch_writes_what_the_window_exports(recording, reconstructor, live_take, tmp_path):
    (tmp_path / "in").mkdir()
    npz = save(recording, tmp_path / "in" / "sliding.npz")
    inputs = find_recordings([str(npz), str(live_take)], tmp_path / "out", "foxglove")
    assert [i.output.name for i in inputs] == ["sliding.npz.forces.mcap", "sliding.mcap.forces.mcap"]
    plans = [plan_file(i, BatchSettings(), 3) for i in inputs]
    outcomes = run_batch(plans, JoblibEngine(1))
    assert [o.status for o in outcomes] == ["written", "written"]
    for batch_input in inputs:
        source = load(batch_input.path)
        window = read_back(export_foxglove(source, reconstructor, tmp_path / "window.mcap").path)
        back = read_back(batch_input.output)
        np.testing.assert_allclose(node_forces(back), node_forces(window), rtol=1e-6, atol=1e-9)
        for ours, theirs in zip(back["decoded"][TOPICS["contacts"]], window["decoded"][TOPICS["contacts"]],
                                strict=True):
            assert [c["identity"] for c in ours["contacts"]] == [c["identity"] for c in theirs["contacts"]]
            np.testing.assert_allclose([[c[k] for k in ("fx", "fy", "fz", "x", "y")] for c in ours["contacts"]],
                                       [[c[k] for k in ("fx", "fy", "fz", "x", "y")] for c in theirs["contacts"]],
                                       rtol=1e-6, atol=1e-9)
        stamps = [m.log_time for m in back["messages"][TOPICS["pressure"]]]
        assert stamps == [m.log_time for m in window["messages"][TOPICS["pressure"]]]
        assert is_finished(batch_input, BatchSettings())
    live = read_back(inputs[1].output)
    assert [m.log_time for m in live["messages"][TOPICS["forces"]]] == \
        [round((RECEIVED + t) * 1e9) for t in load(live_take).t]


def test_a_recording_gone_before_its_foxglove_file_is_written_fails_alone(recording, tmp_path, monkeypatch):
    (tmp_path / "in").mkdir()
    paths = [save(recording, tmp_path / "in" / name) for name in ("kept.npz", "gone.npz")]

    def reading(path):
        if str(path).endswith("gone.npz"):
            raise RecordingError(f"{path}: cannot be read")
        return load(path)

    monkeypatch.setattr(foxglove_export, "load", reading)
    inputs = find_recordings([str(p) for p in paths], tmp_path / "out", "foxglove")
    outcomes = {o.input.path.name: o for o in run_batch([plan_file(i, BatchSettings(), 4) for i in inputs],
                                                         JoblibEngine(1))}
    assert outcomes["kept.npz"].status == "written"
    assert (outcomes["gone.npz"].status, outcomes["gone.npz"].reason) == (
        "failed", f"cannot write {tmp_path / 'out' / 'gone.npz.forces.mcap'}: {paths[1]}: cannot be read")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["kept.npz.forces.mcap",
                                                                     "kept.npz.forces.mcap.batch.json"]

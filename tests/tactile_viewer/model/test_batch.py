"""Batch reconstruction (no Qt): chunks, the viewer's export equalled field by field, failures, reruns."""

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from solver.quality import CONFIGURATIONS
from tactile_viewer.io.files import load, save
from tactile_viewer.io.forces import load_forces, save_forces
from tactile_viewer.io.mcap_writer import Recorder
from tactile_viewer.io.recording import Recording, RecordingError
from tactile_viewer.io.sidecar import write_sidecar
from tactile_viewer.model import batch, batch_inputs
from tactile_viewer.model.batch import (
    BatchSettings,
    plan_chunks,
    plan_file,
    settings_from_preset,
    settings_from_view,
)
from tactile_viewer.model.batch_engines import DaskEngine, JoblibEngine, check_scheduler, run_batch
from tactile_viewer.model.batch_inputs import BatchInput, find_recordings, is_finished, record_path
from tactile_viewer.model.force_tables import reconstruct_frames
from tactile_viewer.model.viewer_model import ViewerModel

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
STANDARD = BatchSettings()  # the default: the standard solve, automatic parameters, layer kernel


def viewer_export(path, tmp_path, settings=STANDARD, *, solver=None) -> dict:
    """What File > Export forces of the whole recording writes (source: the path, as the window's label).

    ``solver``: the viewer's solver for the recording (default: one built now).
    """
    recording = load(path)
    configuration = None if settings.preset is None else next(c for c in CONFIGURATIONS
                                                               if c.name == settings.preset)
    solver = solver or ViewerModel.build(recording.grid, settings.kernel, configuration)
    table = reconstruct_frames(recording, solver, shear_ratio=settings.shear_ratio,
                               shear_direction=settings.shear_direction)
    return load_forces(save_forces(table, tmp_path / "viewer.npz", source=str(path)))


def solve_files(paths, out, *, settings=STANDARD, chunk=7, engine=None, fmt="npz"):
    """Plan and run ``paths`` (the files must be readable); the outcomes by input path."""
    inputs = find_recordings([str(p) for p in paths], out, fmt)
    plans = [plan_file(i, settings, chunk) for i in inputs]
    outcomes = run_batch(plans, engine or JoblibEngine(1))
    return {o.input.path: o for o in outcomes}


def assert_equal_exports(written: dict, expected: dict):
    assert sorted(written) == sorted(expected)
    for key in expected:
        np.testing.assert_array_equal(written[key], expected[key], err_msg=key, strict=True)


@pytest.fixture(scope="module")
def small_mcap(tmp_path_factory):
    """Twenty frames of three contacts as a live recording, about three frames a chunk."""
    recording = load(SAMPLES / "three_contacts.npz")
    path = tmp_path_factory.mktemp("mcap") / "three.mcap"
    recorder = Recorder(path, recording.grid, dtype="float64", flush_interval=0.1)
    for k in range(20):
        recorder.add(k, k / 30, recording.frames[k])
    recorder.close()
    return path


def test_chunks_cover_every_frame_once_in_order():
    assert plan_chunks(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert plan_chunks(8, 4) == [(0, 4), (4, 8)]
    assert plan_chunks(3, 2000) == [(0, 3)]
    assert plan_chunks(0, 5) == []
    with pytest.raises(ValueError, match=r"^--chunk must be a whole number of frames >= 1, got 0$"):
        plan_chunks(10, 0)
    with pytest.raises(ValueError, match=r"^--chunk must be a whole number of frames >= 1, got 2.5$"):
        plan_chunks(10, 2.5)


@pytest.fixture(params=["npz", "mcap"])
def sample(request, small_mcap):
    """A bundled sample (45 frames, two contacts) and a small MCAP (20 frames, three contacts)."""
    return SAMPLES / "two_contacts.npz" if request.param == "npz" else small_mcap


def test_the_batch_writes_the_viewers_whole_recording_export(tmp_path, sample):
    # the frames in chunks of 7 solved apart, numbered in the parent: the viewer's file, field by field, to
    # the bit, with the solver's set-up of this process (one made in another rounds otherwise: see below)
    outcome = solve_files([sample], tmp_path / "out", chunk=7)[sample]
    assert (outcome.status, outcome.frames, outcome.reason) == ("written", len(load(sample)), "")
    written = load_forces(tmp_path / "out" / f"{sample.name}.forces.npz")
    expected = viewer_export(sample, tmp_path, solver=batch.solver_for(STANDARD, load(sample).grid))
    assert_equal_exports(written, expected)
    assert written["contact_identity"].max() >= 2  # contacts followed across the chunks
    assert str(written["source"]) == str(sample) and str(written["mode"]) == "auto"


def test_the_assembled_table_is_reconstruct_frames_field_by_field(tmp_path):
    path = SAMPLES / "two_contacts.npz"
    plan = plan_file(BatchInput(path, tmp_path / "x.npz"), STANDARD, 10)
    results = [r for task in plan.tasks() for r in batch.solve_chunk(task).results]
    table = batch.assemble_table(plan, results)
    recording = load(path)
    expected = reconstruct_frames(recording, batch.solver_for(STANDARD, recording.grid))
    for item in dataclasses.fields(table):
        if item.name != "source":  # the export's source is the path (the window's label); this one the description
            np.testing.assert_array_equal(getattr(table, item.name), getattr(expected, item.name),
                                          err_msg=item.name, strict=True)
    assert table.source == str(path)


def test_two_processes_give_the_viewers_export_to_rounding(tmp_path, small_mcap):
    # each process makes its own set-up, whose products round by its thread count: the same contacts and
    # numbers, the forces and figures equal to rounding
    outcome = solve_files([small_mcap], tmp_path / "out", chunk=6, engine=JoblibEngine(2))[small_mcap]
    assert outcome.status == "written", outcome.reason
    written = load_forces(tmp_path / "out" / "three.mcap.forces.npz")
    expected = viewer_export(small_mcap, tmp_path)
    assert sorted(written) == sorted(expected)
    for key, value in expected.items():
        if value.dtype.kind == "f":
            np.testing.assert_allclose(written[key], value, rtol=1e-9, atol=1e-12, err_msg=key, strict=True)
        else:
            np.testing.assert_array_equal(written[key], value, err_msg=key, strict=True)
    assert written["contact_identity"].max() >= 2


def test_a_dask_cluster_gives_the_same_file(tmp_path):
    path = SAMPLES / "two_contacts.npz"
    engine = DaskEngine.local(1, processes=False)  # its worker is a thread of this process: the same set-up
    try:
        assert engine.description == "Dask cluster started here, 1 worker"
        outcome = solve_files([path], tmp_path / "out", chunk=10, engine=engine)[path]
    finally:
        engine.close()
    assert outcome.status == "written", outcome.reason
    assert_equal_exports(load_forces(tmp_path / "out" / "two_contacts.npz.forces.npz"),
                         viewer_export(path, tmp_path, solver=batch.solver_for(STANDARD, load(path).grid)))


def test_a_preset_and_given_parameters_are_the_viewers(tmp_path):
    recording = load(SAMPLES / "two_contacts.npz")
    path = tmp_path / "short.npz"
    save(Recording(recording.grid, recording.frames[:12], recording.t[:12], description="short"), path)
    preset = BatchSettings(preset="layer, coarse search")
    outcome = solve_files([path], tmp_path / "preset", settings=preset, chunk=5)[path]
    assert outcome.status == "written", outcome.reason
    assert_equal_exports(load_forces(tmp_path / "preset" / "short.npz.forces.npz"),
                         viewer_export(path, tmp_path, preset, solver=batch.solver_for(preset, recording.grid)))
    given = BatchSettings(kernel="cell", shear_ratio=0.3, shear_direction=math.radians(30))
    outcome = solve_files([path], tmp_path / "given", settings=given, chunk=5)[path]
    assert outcome.status == "written", outcome.reason
    written = load_forces(tmp_path / "given" / "short.npz.forces.npz")
    assert (str(written["mode"]), str(written["kernel"])) == ("manual", "cell")
    assert_equal_exports(written, viewer_export(path, tmp_path, given,
                                                solver=batch.solver_for(given, recording.grid)))


def test_settings_from_a_preset_keep_its_kernel_unless_one_is_given():
    assert settings_from_preset(None) == BatchSettings("layer")
    assert settings_from_preset("point, exact") == BatchSettings("point", "point, exact")
    assert settings_from_preset("point, exact", "layer").kernel == "layer"
    assert settings_from_preset(None).fields() == {"kernel": "layer", "preset": None, "mode": "auto",
                                                   "shear_ratio": None, "shear_direction": None,
                                                   "max_shear_ratio": 1.5}
    with pytest.raises(ValueError, match=r"^--preset must be one of 'normal only', .*, got 'fastest'$"):
        settings_from_preset("fastest")
    with pytest.raises(ValueError, match=r"^kernel must be one of \('layer', 'cell', 'point'\), got 'hertz'$"):
        BatchSettings("hertz")
    with pytest.raises(ValueError, match=r"^shear_ratio must be in \[0, 1.5\], got 2.0$"):
        BatchSettings(shear_ratio=2.0, shear_direction=0.0)


def test_settings_from_a_screenshots_sidecar(tmp_path):
    shown = dict(recording="x.npz", frame=3, t=0.1, kernel="cell", poisson_ratio=0.5, sensor_size=0.0)
    manual = write_sidecar(tmp_path / "a.png", **shown, mode="manual", shear_ratio=0.3, shear_direction_deg=30.0)
    settings = settings_from_view(manual)
    assert (settings.kernel, settings.mode, settings.shear_ratio) == ("cell", "manual", 0.3)
    assert settings.shear_direction == pytest.approx(math.radians(30), abs=1e-15)
    assert settings_from_view(manual, "point").kernel == "point"
    auto = write_sidecar(tmp_path / "b.png", **shown, mode="auto", shear_ratio=0.1, shear_direction_deg=5.0)
    assert settings_from_view(auto) == BatchSettings("cell")
    other = tmp_path / "other.json"
    other.write_text('{"kernel": "layer"}')
    with pytest.raises(ValueError, match=r"other.json: not a view sidecar: a sidecar is a JSON object with "
                                         r"the key 'tactile_viewer_sidecar'"):
        settings_from_view(other)
    other.write_text("[1, 2")
    with pytest.raises(ValueError, match=r"other.json: not a view sidecar: it is not JSON"):
        settings_from_view(other)
    with pytest.raises(ValueError, match=r"^--view .*missing.json: cannot read the view sidecar: No such file"):
        settings_from_view(tmp_path / "missing.json")
    bad = write_sidecar(tmp_path / "c.png", **(shown | {"kernel": "hertz"}), mode="auto")
    with pytest.raises(ValueError, match=r"c.png.view.json: 'kernel' must be one of \('layer', 'cell', "
                                         r"'point'\), got 'hertz'$"):
        settings_from_view(bad)
    half = write_sidecar(tmp_path / "d.png", **shown, mode="manual", shear_ratio=0.3)
    with pytest.raises(ValueError, match=r"^--view .*d.png.view.json: 'shear_ratio' and 'shear_direction_deg' "
                                         r"must be given together \(fixed parameters\) or both be None "
                                         r"\(automatic\), got 0.3 and None$"):
        settings_from_view(half)


def test_folders_give_their_recordings_and_outputs_keep_the_subfolders(tmp_path):
    data = tmp_path / "data"
    for name in ("a.npz", "sub/b.csv", "sub/deep/c.mcap", ".hidden.npz", ".cache/d.npz", "notes.txt",
                 "a.npz.forces.npz", "out/old.npz"):
        (data / name).parent.mkdir(parents=True, exist_ok=True)
        (data / name).write_bytes(b"")
    single = tmp_path / "e.NPZ"
    single.write_bytes(b"")
    found = find_recordings([data, single, data / "a.npz"], data / "out", "csv")
    assert [(i.path, i.output) for i in found] == [
        (data / "a.npz", data / "out" / "a.npz.forces.csv"),
        (data / "sub" / "b.csv", data / "out" / "sub" / "b.csv.forces.csv"),
        (data / "sub" / "deep" / "c.mcap", data / "out" / "sub" / "deep" / "c.mcap.forces.csv"),
        (single, data / "out" / "e.NPZ.forces.csv")]
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "a.npz").write_bytes(b"")
    with pytest.raises(ValueError, match=r"^INPUT: .*data/a.npz and .*other/a.npz would both be written to "
                                         r".*out/a.npz.forces.npz: give them in separate runs"):
        find_recordings([data, tmp_path / "other"], tmp_path / "out", "npz")
    with pytest.raises(ValueError, match=r"^INPUT must be a recording file or a folder, got '.*nope.npz' "
                                         r"\(no such file or folder\)$"):
        find_recordings([tmp_path / "nope.npz"], tmp_path / "out", "npz")
    with pytest.raises(ValueError, match=r"^INPUT must be a recording \(.mcap, .npz, .csv\), a ROS 2 bag \(a "
                                         r"folder with metadata.yaml, a .db3\) or a folder, got '.*notes.txt'$"):
        find_recordings([data / "notes.txt"], tmp_path / "out", "npz")
    with pytest.raises(ValueError, match=r"^INPUT: no recording \(.mcap, .npz, .csv\) or ROS 2 bag in .*other$"):
        (tmp_path / "other" / "a.npz").unlink()
        find_recordings([tmp_path / "other"], tmp_path / "out", "npz")
    with pytest.raises(ValueError, match=r"^--format must be one of \('npz', 'csv', 'foxglove'\), got 'h5'$"):
        find_recordings([data], tmp_path / "out", "h5")


def test_a_failing_file_is_reported_and_the_others_are_written(tmp_path):
    recording = load(SAMPLES / "two_contacts.npz")
    good, huge, damaged = tmp_path / "good.npz", tmp_path / "huge.npz", tmp_path / "damaged.npz"
    save(Recording(recording.grid, recording.frames[:8], recording.t[:8]), good)
    frames = np.array(recording.frames[:12])
    frames[9, 5] = 1e200  # readable, but beyond what a solve takes: the task with frame 9 fails
    save(Recording(recording.grid, frames, recording.t[:12]), huge)
    damaged.write_bytes(b"PK\x03\x04 not an archive")
    with pytest.raises(RecordingError, match=r"damaged.npz"):
        plan_file(BatchInput(damaged, tmp_path / "out" / "x.npz"), BatchSettings(), 4)
    outcomes = solve_files([good, huge], tmp_path / "out", chunk=4)
    assert outcomes[good].status == "written"
    assert outcomes[huge].status == "failed"
    assert outcomes[huge].reason == ("frames 8 to 11: ValueError: stress must be at most 1e+100 Pa in "
                                     "magnitude, got 1e+200 at taxel(s) [5]")
    # nothing of the failed file: no output, no record, no temporary file
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["good.npz.forces.npz",
                                                                     "good.npz.forces.npz.batch.json"]


def test_a_write_that_fails_leaves_no_output_and_no_record(tmp_path, monkeypatch):
    path = tmp_path / "short.npz"
    recording = load(SAMPLES / "two_contacts.npz")
    save(Recording(recording.grid, recording.frames[:4], recording.t[:4]), path)

    def full_disk(table, output, *, source="", **bag):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(batch_inputs, "save_force_file", full_disk)
    outcome = solve_files([path], tmp_path / "out", chunk=2)[path]
    assert (outcome.status, outcome.reason) == ("failed", f"cannot write {tmp_path / 'out' / 'short.npz.forces.npz'}"
                                                          ": No space left on device")
    assert list((tmp_path / "out").iterdir()) == []


def test_a_finished_output_is_skipped_until_its_input_or_settings_change(tmp_path):
    path = tmp_path / "short.npz"
    recording = load(SAMPLES / "two_contacts.npz")
    save(Recording(recording.grid, recording.frames[:4], recording.t[:4]), path)
    settings = BatchSettings()
    (batch_input,) = find_recordings([path], tmp_path / "out", "npz")
    assert not is_finished(batch_input, settings)
    solve_files([path], tmp_path / "out", chunk=3)
    record = json.loads(record_path(batch_input.output).read_text())
    assert record == {"tactile_batch": 1, "source": str(path), "source_bytes": path.stat().st_size,
                      "source_mtime_ns": path.stat().st_mtime_ns, "settings": settings.fields(), "frames": 4,
                      "output_bytes": batch_input.output.stat().st_size}
    assert is_finished(batch_input, settings)
    assert not is_finished(batch_input, BatchSettings("point"))
    assert not is_finished(batch_input, BatchSettings(shear_ratio=0.2, shear_direction=0.0))
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))  # the recording changed
    assert not is_finished(batch_input, settings)
    solve_files([path], tmp_path / "out", chunk=3)
    assert is_finished(batch_input, settings)
    with open(batch_input.output, "ab") as handle:  # the output is not the one the record names
        handle.write(b"x")
    assert not is_finished(batch_input, settings)
    solve_files([path], tmp_path / "out", chunk=3)
    record_path(batch_input.output).unlink()  # an output without its record is written again
    assert not is_finished(batch_input, settings)


def test_a_file_changed_after_planning_is_not_solved(tmp_path):
    path = tmp_path / "short.npz"
    recording = load(SAMPLES / "two_contacts.npz")
    save(Recording(recording.grid, recording.frames[:4], recording.t[:4]), path)
    plan = plan_file(BatchInput(path, tmp_path / "out.npz"), BatchSettings(), 4)
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    outcome = batch.solve_chunk(plan.tasks()[0])
    assert outcome.results == ()
    assert outcome.error == f"frames 0 to 3: {path}: the file changed since it was planned (size or time)"


def test_a_broken_engine_fails_the_files_left(tmp_path):
    path = tmp_path / "short.npz"
    recording = load(SAMPLES / "two_contacts.npz")
    save(Recording(recording.grid, recording.frames[:4], recording.t[:4]), path)

    class Broken:
        description = "a broken engine"

        def outcomes(self, tasks):
            raise RuntimeError("a worker process was killed")
            yield

    (plan,) = [plan_file(i, BatchSettings(), 2) for i in find_recordings([path], tmp_path / "out", "npz")]
    (outcome,) = run_batch([plan], Broken())
    assert (outcome.status, outcome.reason) == ("failed", "the engine stopped (a broken engine): RuntimeError: "
                                                          "a worker process was killed")


def test_engines_refuse_bad_arguments():
    with pytest.raises(ValueError, match=r"^--workers must be a whole number of processes >= 1, got 0$"):
        JoblibEngine(0)
    with pytest.raises(ValueError, match=r"^--scheduler must be 'local' or a scheduler's address "
                                         r"\(tcp\|tls\|inproc\|ucx\|ws\|wss://host:port\), got 'http://x:1'$"):
        check_scheduler("http://x:1")
    assert check_scheduler("tcp://10.0.0.1:8786") == "tcp://10.0.0.1:8786"
    with pytest.raises(OSError, match=r"^--scheduler tcp://127.0.0.1:9: no Dask scheduler answered within 1 s"):
        DaskEngine.connect("tcp://127.0.0.1:9", timeout=1)

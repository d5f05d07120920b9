"""ROS 2 bags in a batch (no Qt): the viewer's export of the bag field by field, one decoding per process,
the bag's options in the output's record, folders walked for bags, failures named."""

import collections
import dataclasses
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from tactile_viewer.io.files import load
from tactile_viewer.io.forces import load_forces, save_forces
from tactile_viewer.io.layout import SensorLayout, save_layout
from tactile_viewer.io.recording import RecordingError
from tactile_viewer.io.ros2_bag import bag_location
from tactile_viewer.model import batch
from tactile_viewer.model.batch import BatchSettings, plan_file
from tactile_viewer.model.batch_engines import BatchCollector, DaskEngine, JoblibEngine, run_batch
from tactile_viewer.model.batch_inputs import BagOptions, find_recordings, is_finished, record_path
from tactile_viewer.model.force_tables import reconstruct_frames
from tests.tactile_viewer.written_bags import STORE, T0_NS, frames_bag, storage_file, write_bag

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
STANDARD = BatchSettings()
F64 = "std_msgs/msg/Float64MultiArray"


@pytest.fixture(scope="module")
def skin(tmp_path_factory):
    """The two-contact sample's skin as a layout file (Pa, gain 1, offset 0: a message's values are its stresses)
    and its first 18 frames."""
    recording = load(SAMPLES / "two_contacts.npz")
    layout = save_layout(SensorLayout(recording.grid), tmp_path_factory.mktemp("skin") / "skin.json")
    return layout, np.asarray(recording.frames[:18])


def skin_bag(skin, path, *, storage="mcap", count=18):
    """A bag folder of ``count`` frames of the skin as Float64MultiArray messages (the values exactly)."""
    return frames_bag(path, skin[1][:count], storage=storage, kind=F64)[0]


def viewer_export(path, layout, tmp_path) -> dict:
    """What File > Export forces writes for the bag opened with ``layout`` (source: its path)."""
    recording = load(path, layout=layout)
    table = reconstruct_frames(recording, batch.solver_for(STANDARD, recording.grid))
    return load_forces(save_forces(table, tmp_path / "viewer.npz", source=str(path)))


def assert_equal_exports(written: dict, expected: dict):
    assert sorted(written) == sorted(expected)
    for key in expected:
        np.testing.assert_array_equal(written[key], expected[key], err_msg=key, strict=True)


def planned(paths, out, options, *, chunk=5):
    inputs = find_recordings([str(p) for p in paths], out, "npz", bag=options)
    return inputs, [plan_file(i, STANDARD, chunk) for i in inputs]


@pytest.mark.parametrize("given", ["mcap folder", "sqlite3 folder", "metadata.yaml", "bare .db3",
                                   "another program's .mcap"])
def test_a_bag_is_written_as_the_viewers_export_of_it(tmp_path, skin, given):
    storage = "sqlite3" if given in ("sqlite3 folder", "bare .db3") else "mcap"
    bag = skin_bag(skin, tmp_path / "run1", storage=storage)
    if given.startswith("bare") or given.startswith("another"):
        path = Path(shutil.copy(storage_file(bag), tmp_path / f"take{storage_file(bag).suffix}"))
    else:
        path = bag / "metadata.yaml" if given == "metadata.yaml" else bag
    options = BagOptions.from_layout_file(skin[0])
    (batch_input,), plans = planned([path], tmp_path / "out", options)
    source = bag_location(path)
    assert (batch_input.path, batch_input.bag) == (source, options)
    assert batch_input.output == tmp_path / "out" / f"{source.name}.forces.npz"
    assert [task.bag for task in plans[0].tasks()] == [options] * 4  # 18 frames in chunks of 5
    (outcome,) = run_batch(plans, JoblibEngine(1))
    assert (outcome.status, outcome.frames, outcome.reason) == ("written", 18, "")
    written = load_forces(batch_input.output)
    assert_equal_exports(written, viewer_export(source, skin[0], tmp_path))
    assert written["contact_identity"].max() >= 1  # contacts followed across the chunks
    assert str(written["source"]) == str(source)


def test_one_process_decodes_each_bag_once(tmp_path, skin, monkeypatch):
    opened = collections.Counter()

    def counted(path, **options):
        opened[path] += 1
        return load(path, **options)
    monkeypatch.setattr(batch, "load", counted)
    bags = [skin_bag(skin, tmp_path / name) for name in ("a", "b")]
    _, plans = planned(bags, tmp_path / "out", BagOptions.from_layout_file(skin[0]), chunk=3)
    tasks = [task for plan in plans for task in plan.tasks()]
    outcomes = list(JoblibEngine(1).outcomes(tasks))
    # the planning decoded each bag, and the tasks of this process took it as kept: 6 chunks each
    assert opened == {str(bag): 1 for bag in bags}
    assert len(outcomes) == 12 and all(o.error == "" and o.opened_by == 0 for o in outcomes)


def test_each_worker_process_decodes_a_bag_at_most_once(tmp_path, skin):
    bags = [skin_bag(skin, tmp_path / name) for name in ("a", "b")]
    _, plans = planned(bags, tmp_path / "out", BagOptions.from_layout_file(skin[0]), chunk=3)
    collector = BatchCollector(plans)
    tasks = [task for plan in plans for task in plan.tasks()]
    outcomes = list(JoblibEngine(2).outcomes(tasks))
    openings = collections.Counter((o.opened_by, o.task.path) for o in outcomes if o.opened_by)
    assert os.getpid() not in {pid for pid, _ in openings}  # solved in the worker processes
    assert set(openings.values()) == {1} and {path for _, path in openings} == {str(b) for b in bags}
    assert len(openings) <= 4  # two processes, two bags
    written = [collector.take(o) for o in outcomes]
    assert sorted(o.status for o in written if o is not None) == ["written", "written"]
    for bag, plan in zip(bags, plans, strict=True):
        # each process makes its own solver set-up, whose products round by its thread count
        expected = viewer_export(bag, skin[0], tmp_path)
        got = load_forces(plan.input.output)
        for key, value in expected.items():
            if value.dtype.kind == "f":
                np.testing.assert_allclose(got[key], value, rtol=1e-9, atol=1e-12, err_msg=key, strict=True)
            else:
                np.testing.assert_array_equal(got[key], value, err_msg=key, strict=True)


def test_a_dask_cluster_gives_the_same_file(tmp_path, skin):
    bag = skin_bag(skin, tmp_path / "run1", count=12)
    _, plans = planned([bag], tmp_path / "out", BagOptions.from_layout_file(skin[0]))
    engine = DaskEngine.local(1, processes=False)  # its worker is a thread of this process: the same set-up
    try:
        (outcome,) = run_batch(plans, engine)
    finally:
        engine.close()
    assert outcome.status == "written", outcome.reason
    assert_equal_exports(load_forces(tmp_path / "out" / "run1.forces.npz"), viewer_export(bag, skin[0], tmp_path))


def test_the_record_names_the_bags_options_and_a_rerun_with_others_is_not_finished(tmp_path, skin):
    bag = skin_bag(skin, tmp_path / "run1", count=6)
    options = BagOptions.from_layout_file(skin[0])
    (batch_input,), plans = planned([bag], tmp_path / "out", options)
    run_batch(plans, JoblibEngine(1))
    record = json.loads(record_path(batch_input.output).read_text())
    layout = Path(skin[0])
    assert record["bag"] == {"layout": str(layout), "layout_bytes": layout.stat().st_size,
                             "layout_mtime_ns": layout.stat().st_mtime_ns, "topic": None, "field": None}
    assert record["frames"] == 6 and record["source"] == str(bag)
    assert is_finished(batch_input, STANDARD)
    for other in (dataclasses.replace(options, topic="/skin/pressure"), dataclasses.replace(options, field="data"),
                  BagOptions.from_layout_file(shutil.copy(layout, tmp_path / "same_skin.json"))):
        assert not is_finished(dataclasses.replace(batch_input, bag=other), STANDARD)
    assert not is_finished(batch_input, BatchSettings("point"))
    os.utime(storage_file(bag), ns=(0, storage_file(bag).stat().st_mtime_ns + 10**9))  # the bag changed
    assert not is_finished(batch_input, STANDARD)


def test_an_edited_layout_makes_the_output_stale(tmp_path, skin):
    layout = Path(shutil.copy(skin[0], tmp_path / "skin.json"))
    bag = skin_bag(skin, tmp_path / "run1", count=4)
    (batch_input,), plans = planned([bag], tmp_path / "out", BagOptions.from_layout_file(layout))
    run_batch(plans, JoblibEngine(1))
    assert is_finished(batch_input, STANDARD)
    os.utime(layout, ns=(0, layout.stat().st_mtime_ns + 10**9))
    (again,) = find_recordings([bag], tmp_path / "out", "npz", bag=BagOptions.from_layout_file(layout))
    assert not is_finished(again, STANDARD)


def test_a_folder_walk_takes_bag_folders_whole_and_loose_db3_and_foreign_mcap_files(tmp_path, skin):
    data = tmp_path / "data"
    (data / "day2").mkdir(parents=True)
    skin_bag(skin, data / "run1", count=2)
    skin_bag(skin, data / "day2" / "run2", storage="sqlite3", count=2)
    shutil.copy(storage_file(skin_bag(skin, tmp_path / "x", storage="sqlite3", count=2)), data / "loose.db3")
    shutil.copy(storage_file(skin_bag(skin, tmp_path / "y", count=2)), data / "foreign.mcap")
    shutil.copy(SAMPLES / "two_contacts.npz", data / "ours.npz")
    (data / "notes.txt").write_text("not a recording")
    options = BagOptions.from_layout_file(skin[0])
    found = find_recordings([data, data / "run1" / "metadata.yaml"], data / "out", "csv", bag=options)
    assert [(i.path, i.output, i.bag) for i in found] == [
        (data / "day2" / "run2", data / "out" / "day2" / "run2.forces.csv", options),
        (data / "foreign.mcap", data / "out" / "foreign.mcap.forces.csv", options),
        (data / "loose.db3", data / "out" / "loose.db3.forces.csv", options),
        (data / "ours.npz", data / "out" / "ours.npz.forces.csv", None),  # it carries its own layout
        (data / "run1", data / "out" / "run1.forces.csv", options)]  # once: its metadata.yaml is the bag too
    with pytest.raises(ValueError, match=r"^--layout is needed: INPUT holds 4 ROS 2 bags \(.*run2, "
                                         r".*foreign.mcap, .*loose.db3 and 1 more\), whose values become stresses "
                                         r"through the skin's sensor layout file$"):
        find_recordings([data], data / "out", "npz")
    with pytest.raises(ValueError, match=r"^--layout is needed: INPUT holds 1 ROS 2 bag \(.*run1\)"):
        find_recordings([data / "run1"], data / "out", "npz")
    assert [i.bag for i in find_recordings([data / "ours.npz"], data / "out", "npz", bag=options)] == [None]


def test_bag_options_are_checked_before_any_work(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"nx": 4}')
    with pytest.raises(ValueError, match=r"^--layout: .*bad.json"):
        BagOptions.from_layout_file(bad)
    with pytest.raises(ValueError, match=r"^--layout: .*missing.json"):
        BagOptions.from_layout_file(tmp_path / "missing.json")
    with pytest.raises(ValueError, match=r"^--topic must be a non-empty name, got ''$"):
        BagOptions.from_layout_file(bad, topic="")
    with pytest.raises(ValueError, match=r"^--field must be a non-empty name, got 3$"):
        BagOptions.from_layout_file(bad, field=3)


def test_a_bag_that_cannot_be_read_is_named_and_the_others_are_solved(tmp_path, skin):
    good = skin_bag(skin, tmp_path / "good", count=4)
    too_small = frames_bag(tmp_path / "small", skin[1][:3, :200], kind=F64)[0]  # 200 values, not 256
    chatter = write_bag(tmp_path / "chatter", [("/chatter", "std_msgs/msg/String", T0_NS, STORE.types["std_msgs/msg/String"](data="hello"))])
    inputs = find_recordings([good, too_small, chatter], tmp_path / "out", "npz",
                             bag=BagOptions.from_layout_file(skin[0]))
    with pytest.raises(RecordingError, match=r"small: topic '/skin/pressure' field 'data': no message can be a "
                                             r"frame: 3 of 3 messages left out: 200 values, not the layout's 256$"):
        plan_file(inputs[1], STANDARD, 5)
    with pytest.raises(RecordingError, match=r"chatter: no topic whose messages hold an array of numbers .*; the "
                                             r"bag's topics: /chatter \(std_msgs/msg/String\)$"):
        plan_file(inputs[2], STANDARD, 5)
    (outcome,) = run_batch([plan_file(inputs[0], STANDARD, 5)], JoblibEngine(1))
    assert outcome.status == "written"

"""The forces a stream published, spooled to disk (tactile_viewer/model/force_log.py): the viewer's force table
of the frames kept, memory that does not grow with the take, a full disk counted and said, the spool removed."""

import errno
import threading
import tracemalloc
from dataclasses import replace

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.io.forces import load_forces, save_forces
from tactile_viewer.model import force_log
from tactile_viewer.model.force_log import ForceLog
from tactile_viewer.model.force_tables import contact_arrays
from tactile_viewer.sources.source import SourceFrame

GRID = SensorGrid.regular(6, 5, 2e-3, 2e-3)


@pytest.fixture(scope="module")
def frames():
    """Eight frames of two sheared Hertz presses closing in (noise with a fixed seed, 5)."""
    rng = np.random.default_rng(5)
    stresses = [loads.simulate(GRID, [loads.hertz((-x, 0.0), 2.5e-3, 1.0, shear_ratio=0.3, shear_direction=0.0),
                                      loads.hertz((x, 0.0), 2.5e-3, 0.7, shear_ratio=0.3, shear_direction=np.pi)],
                               noise=0.01, rng=rng).stress for x in np.linspace(4.5e-3, 3e-3, 8)]
    return [SourceFrame(stress, 0.001 * k, k) for k, stress in enumerate(stresses)]


@pytest.fixture(scope="module")
def results(frames):
    solver = Reconstructor(GRID)
    return [solver.solve(f.stress) for f in frames]


@pytest.fixture
def log(tmp_path):
    made = ForceLog(GRID, kernel="layer", mode="auto", source="socket://board",
                    spool_beside=tmp_path / "take.forces.npz")
    yield made
    made.close()


def test_the_log_is_the_viewers_force_table_of_the_frames_published(frames, results, log, tmp_path):
    kept = [0, 1, 3, 4, 5, 7]  # frames 2 and 6 skipped by the stream
    for k in kept:
        log.add(frames[k], results[k])
    table = log.table()
    assert len(log) == 6 and table.frames.tolist() == kept and table.t.tolist() == [frames[k].t for k in kept]
    assert table.forces.dtype == np.float32 and not table.forces.flags.writeable
    np.testing.assert_allclose(table.forces, [results[k].forces for k in kept], rtol=1e-6, atol=1e-9)
    for name in ("shear_ratio", "shear_direction", "efficiency", "residual", "condition"):
        assert getattr(table, name).tolist() == [getattr(results[k], name) for k in kept], name
    # the contacts: what the viewer's table makes of the same results, followed over the same frames
    assert max(len(results[k].contacts) for k in kept) == 2
    identity, force, centre = contact_arrays([results[k] for k in kept])
    assert table.contact_identity.shape == identity.shape
    assert set(table.contact_identity[0]) == {1, 2}  # numbered from 1, kept over the skipped frames
    assert table.contact_identity.tolist() == [[1, 2]] * 6 or table.contact_identity.tolist() == [[2, 1]] * 6
    np.testing.assert_array_equal(table.contact_force, force)
    np.testing.assert_array_equal(table.contact_centre, centre)
    # and read from each result itself, slot by slot (both sides above go through contact_slots)
    for row, k in enumerate(kept):
        contacts = results[k].contacts
        for slot in range(table.contact_identity.shape[1]):
            if slot < len(contacts):
                np.testing.assert_array_equal(table.contact_force[row, slot], contacts[slot].total_force)
                np.testing.assert_array_equal(table.contact_centre[row, slot], contacts[slot].centre)
            else:
                assert table.contact_identity[row, slot] == 0
                assert np.isnan(table.contact_force[row, slot]).all()
                assert np.isnan(table.contact_centre[row, slot]).all()
    for suffix in ("npz", "csv"):
        saved = load_forces(save_forces(table, tmp_path / f"take.forces.{suffix}"))
        np.testing.assert_allclose(saved["forces"], table.forces, rtol=1e-6)
        assert saved["frames"].tolist() == kept
        np.testing.assert_array_equal(saved["contact_identity"], table.contact_identity)
        np.testing.assert_allclose(saved["contact_force"], table.contact_force, rtol=1e-8)


def test_the_spool_is_hidden_beside_the_force_file_and_removed_on_close(frames, results, tmp_path):
    log = ForceLog(GRID, kernel="layer", mode="auto", spool_beside=tmp_path / "take.forces.npz")
    log.add(frames[0], results[0])
    log.flush()
    assert log.spool.parent == tmp_path and log.spool.name.startswith(".take.forces.npz.")
    assert (log.spool / "forces").stat().st_size == 12 * GRID.size
    log.close()
    assert list(tmp_path.iterdir()) == []


def test_memory_does_not_grow_with_the_frames_kept(frames, results, log):
    # warm first: the tracker's numbering (identities past the cached small ints) and numpy's caches
    for k in range(2000):
        log.add(frames[k % 8], results[k % 8])
    log.flush()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for k in range(1000):
            log.add(frames[k % 8], results[k % 8])
        log.flush()
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    # kept in memory, 1000 frames would take 1000 * 12 * 30 bytes of forces alone (360 kB)
    assert len(log) == 3000 and grown < 20_000, grown


def test_a_full_disk_keeps_the_frames_written_and_counts_the_rest(frames, results, log, monkeypatch):
    written = force_log._write_all
    calls = []

    def filling(descriptor, data):
        calls.append(len(data))
        if len(calls) == 3 * 3 + 2:  # the fourth frame's row: its forces and contacts went in
            raise OSError(errno.ENOSPC, "No space left on device")
        written(descriptor, data)
    monkeypatch.setattr(force_log, "_write_all", filling)
    for frame, result in zip(frames, results, strict=True):
        log.add(frame, result)
    log.flush()
    assert (len(log), log.left_out, log.unwritten, log.behind) == (3, 5, 5, 0)
    assert log.failure.errno == errno.ENOSPC
    assert log.reason() == "5 after a write failed: No space left on device"
    table = log.table()  # the frames kept, whole: the fourth frame's forces on disk are not read
    assert table.frames.tolist() == [0, 1, 2] and table.forces.shape == (3, GRID.size, 3)
    assert table.contact_identity.shape[0] == 3


def test_publishing_never_waits_for_the_disk_frames_beyond_the_queue_are_counted(frames, results, tmp_path,
                                                                              monkeypatch):
    written = force_log._write_all
    inside, go_on = threading.Event(), threading.Event()

    def stalled(descriptor, data):  # the kernel's write-back holds the first write
        inside.set()
        assert go_on.wait(10)
        written(descriptor, data)
    monkeypatch.setattr(force_log, "_write_all", stalled)
    log = ForceLog(GRID, kernel="layer", mode="auto", spool_beside=tmp_path / "f.npz", queue_frames=2)
    try:
        log.add(frames[0], results[0])
        assert inside.wait(10)  # the writer holds frame 0; two frames may wait behind it
        for k in range(1, 8):
            log.add(frames[k], results[k])  # returns at once: it never waits for the writer
        assert log.behind == 5 and len(log) == 0
        go_on.set()
        table = log.table()
        assert table.frames.tolist() == [0, 1, 2] and log.left_out == 5 and log.unwritten == 0
        assert log.reason() == "5 while the disk fell 2 frames behind"
    finally:
        go_on.set()
        log.close()
    assert not log.spool.exists()


def test_a_defect_in_the_writer_is_counted_and_never_hangs_the_log(frames, results, log, monkeypatch):
    def broken(descriptor, data):
        raise ValueError("a defect")
    monkeypatch.setattr(force_log, "_write_all", broken)
    for k in range(3):
        log.add(frames[k], results[k])
    log.flush()  # returns: the writer counted the frames and goes on
    assert (len(log), log.unwritten) == (0, 3) and str(log.failure) == "a defect"


def test_the_queue_must_hold_a_frame(tmp_path):
    with pytest.raises(ValueError, match="queue_frames must be a whole number >= 1, got 0"):
        ForceLog(GRID, kernel="layer", mode="auto", spool_beside=tmp_path / "f.npz", queue_frames=0)
    assert list(tmp_path.iterdir()) == []


def test_an_empty_log_has_no_table(log):
    with pytest.raises(ValueError, match="no frame was published: there are no forces to write"):
        log.table()


def test_a_spool_that_cannot_be_made_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        ForceLog(GRID, kernel="layer", mode="auto", spool_beside=tmp_path / "no such folder" / "f.npz")


def test_a_spool_left_behind_is_recovered_as_the_same_table(frames, results, log, tmp_path, kill_log):
    kept = [0, 2, 3, 5]
    why = "solved by the faster member (the whole-cell fit) while the stream was 120 frames behind"
    for k in kept:
        log.add(frames[k], replace(results[k], fallback=why) if k == 3 else results[k])
    expected = log.table()
    assert expected.fallback.tolist() == ["", "", why, ""]
    spool = kill_log(log)
    assert force_log.leftover_spools(tmp_path / "take.forces.npz") == [spool]
    assert force_log.leftover_spools(tmp_path / "other.forces.npz") == []
    table, target = force_log.recover(spool)
    assert target == tmp_path / "take.forces.npz"
    for name in ("forces", "frames", "t", "shear_ratio", "shear_direction", "efficiency", "residual", "condition",
                 "positions", "contact_identity", "contact_force", "contact_centre", "fallback"):
        np.testing.assert_array_equal(getattr(table, name), getattr(expected, name), err_msg=name)
    for name in ("shape", "pitch", "thickness", "kernel", "mode", "source", "poisson_ratio", "sensor_size"):
        assert getattr(table, name) == getattr(expected, name), name
    save_forces(table, tmp_path / "recovered.forces.npz")
    assert load_forces(tmp_path / "recovered.forces.npz")["frames"].tolist() == kept


def test_a_frame_cut_short_by_the_end_is_not_recovered(frames, results, log, kill_log):
    for k in range(3):
        log.add(frames[k], results[k])
    spool = kill_log(log)
    # killed in the middle of the fourth frame: its forces and contacts written, its row half
    with open(spool / "forces", "ab") as f:
        f.write(np.asarray(results[3].forces, np.float32).tobytes())
    with open(spool / "contacts", "ab") as f:
        f.write(np.array([[3, 1, 0.1, 0.2, 0.3, 0.0, 0.0]]).tobytes())
    with open(spool / "rows", "ab") as f:
        f.write(np.zeros(3).tobytes())
    table, _ = force_log.recover(spool)
    assert table.frames.tolist() == [0, 1, 2] and table.forces.shape == (3, GRID.size, 3)
    assert table.contact_identity.shape[0] == 3 and np.all(table.contact_identity > 0)


def test_what_is_not_a_readable_spool_is_refused(tmp_path, log, kill_log):
    with pytest.raises(ValueError, match="is not a force spool: it has no about.json"):
        force_log.recover(tmp_path)
    (tmp_path / "about.json").write_text("{not json")
    with pytest.raises(ValueError, match="is not a spool's description"):
        force_log.recover(tmp_path)
    (tmp_path / "about.json").write_text('{"version": 7}')
    with pytest.raises(ValueError, match="a spool of version 1 or 2 was expected, got 7"):
        force_log.recover(tmp_path)
    spool = kill_log(log)  # nothing published
    with pytest.raises(ValueError, match="holds no whole frame"):
        force_log.recover(spool)

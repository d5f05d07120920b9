"""Force exports and screenshot sidecars (tactile_viewer/io/forces.py, io/sidecar.py, model/force_tables.py), without Qt."""

import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.io import forces as forces_module
from tactile_viewer.io import sidecar
from tactile_viewer.io.forces import CONTACT_COLUMNS, CSV_COLUMNS, ForceTable, load_forces, save_forces
from tactile_viewer.io.recording import Recording
from tactile_viewer.io.sidecar import (
    SIDECAR_MARKER,
    SidecarConflict,
    check_sidecar,
    sidecar_path,
    write_sidecar,
)
from tactile_viewer.model.force_tables import contact_slots, force_table, reconstruct_frames
from tactile_viewer.model.worker import Cancelled


@pytest.fixture(scope="module")
def recording():
    grid = SensorGrid.regular(6, 5, 2e-3, 2e-3)
    rng = np.random.default_rng(11)  # fixed seed: the same noisy frames every run
    frames = [loads.simulate(grid, loads.hertz((0.4e-3 * k, 0.0), 3e-3, 0.5 + 0.1 * k, shear_ratio=0.3,
                                               shear_direction=0.5 * k), noise=0.01, rng=rng).stress
              for k in range(4)]
    return Recording(grid, np.array(frames), [0.0, 0.05, 0.1, 0.15], description="four presses")


@pytest.fixture(scope="module")
def reconstructor(recording):
    return Reconstructor(recording.grid)


def test_reconstructed_frames_are_the_solver_results(recording, reconstructor):
    table = reconstruct_frames(recording, reconstructor, [3, 1])
    for row, k in enumerate([3, 1]):
        expected = reconstructor.solve(recording.frames[k])
        # the automatic search starts from the previous frame's answer, so the same frame solved
        # after another one agrees to rounding, not to the bit
        peak = np.abs(expected.forces).max()
        np.testing.assert_allclose(table.forces[row], expected.forces, rtol=0, atol=1e-8 * peak)
        assert table.shear_ratio[row] == pytest.approx(expected.shear_ratio, rel=1e-8, abs=1e-12)
        assert table.residual[row] == pytest.approx(expected.residual, rel=1e-8)
        assert table.condition[row] == expected.condition
    np.testing.assert_array_equal(table.frames, [3, 1])
    np.testing.assert_array_equal(table.t, recording.t[[3, 1]])
    assert table.mode == "auto" and table.kernel == reconstructor.kernel and table.shape == (5, 6)
    assert table.poisson_ratio == 0.5 and table.sensor_size == 0.0  # the grid's defaults
    with pytest.raises(ValueError, match="read-only"):
        table.forces[0, 0, 0] = 1.0


def test_given_parameters_are_used_on_every_frame(recording, reconstructor):
    table = reconstruct_frames(recording, reconstructor, shear_ratio=0.25, shear_direction=-1.0)
    assert table.mode == "manual" and len(table.frames) == len(recording)
    np.testing.assert_allclose(table.shear_ratio, 0.25)
    np.testing.assert_allclose(table.shear_direction, -1.0)
    # every member of the family explains the data: C x = b
    for row in range(len(recording)):
        x = np.concatenate([table.forces[row, :, 0], table.forces[row, :, 1], table.forces[row, :, 2]])
        np.testing.assert_allclose(reconstructor.engine.matrix @ x, recording.frames[row], rtol=1e-8,
                                   atol=1e-8 * np.abs(recording.frames[row]).max())


def test_progress_is_reported_and_can_cancel(recording, reconstructor):
    seen = []
    reconstruct_frames(recording, reconstructor, progress=lambda done, total: seen.append((done, total)))
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    with pytest.raises(Cancelled, match="cancelled after 2 of 4 frames"):
        reconstruct_frames(recording, reconstructor, progress=lambda done, total: done < 2)


@pytest.mark.parametrize("frames", [[4], [-1], [0, 9]])
def test_frames_outside_the_recording_are_rejected(recording, reconstructor, frames):
    with pytest.raises(ValueError, match=r"frames must be in \[0, 3\], got"):
        reconstruct_frames(recording, reconstructor, frames)


@pytest.mark.parametrize("name", ["forces.npz", "forces.csv"])
@pytest.mark.parametrize("earlier", [False, True])
def test_a_failed_force_export_leaves_no_partial_file(recording, reconstructor, tmp_path, monkeypatch, name,
                                                       earlier):
    # the disk fills halfway through the write: nothing of it stays, and an earlier file of that name
    # is as it was (an empty NPZ that np.load opened was left before)
    table = reconstruct_frames(recording, reconstructor, [0, 1])
    path = tmp_path / name
    if earlier:
        path.write_bytes(b"the earlier export")

    def full_disk(handle, *args, **kwargs):
        handle.write(b"PK\x03\x04 half an archive" if "b" in getattr(handle, "mode", "b") else "0,0.0,0,half a row")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(np, "savez_compressed", full_disk)
    monkeypatch.setattr(np, "savetxt", full_disk)  # the CSV's node rows, written a piece at a time
    with pytest.raises(OSError, match="No space left on device"):
        save_forces(table, path)
    assert [p.name for p in tmp_path.iterdir()] == ([name] if earlier else [])
    if earlier:
        assert path.read_bytes() == b"the earlier export"


@pytest.mark.parametrize("name", ["forces.npz", "forces.csv", "UPPER.NPZ", "Mixed.Csv"])
def test_saved_forces_read_back(recording, reconstructor, tmp_path, name):
    table = reconstruct_frames(recording, reconstructor, [0, 2, 3])
    path = save_forces(table, tmp_path / name, source="lab/run1.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no extra suffix appended
    back = load_forces(path)
    np.testing.assert_array_equal(back["frames"], [0, 2, 3])
    np.testing.assert_allclose(back["t"], table.t, atol=1e-6)
    np.testing.assert_allclose(back["forces"], table.forces, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(back["shear_ratio"], table.shear_ratio, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(back["shear_direction"], table.shear_direction, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("name", ["forces.npz", "forces.csv"])
def test_force_exports_name_the_poisson_ratio_and_sensor_size(recording, tmp_path, name):
    # the forces depend on the material they were solved with: the export must say which
    grid = recording.grid.replace(poisson_ratio=0.45, sensor_size=1e-3)
    soft = Recording(grid, recording.frames, recording.t, description="soft skin")
    table = reconstruct_frames(soft, Reconstructor(grid, kernel="point"), [0])
    assert table.poisson_ratio == 0.45 and table.sensor_size == 1e-3
    path = save_forces(table, tmp_path / name)
    if name.endswith(".npz"):
        back = load_forces(path)
        assert float(back["poisson_ratio"]) == 0.45 and float(back["sensor_size"]) == 1e-3
        assert float(back["thickness"]) == 2e-3 and str(back["kernel"]) == "point"
    else:
        lines = path.read_text().splitlines()
        header = {line[2:].split("=", 1)[0]: line.split("=", 1)[1] for line in lines if line.startswith("#")}
        assert float(header["poisson_ratio"]) == 0.45 and float(header["sensor_size"]) == 1e-3


def test_csv_export_has_its_header_and_columns(recording, reconstructor, tmp_path):
    table = reconstruct_frames(recording, reconstructor, [1])
    path = save_forces(table, tmp_path / "one.csv", source="a\nmulti-line source")
    lines = path.read_text().splitlines()
    header = {line[2:].split("=", 1)[0]: line.split("=", 1)[1] for line in lines if line.startswith("#")}
    assert header["source"] == "a multi-line source" and header["mode"] == "auto"
    assert header["nx"] == "6" and header["ny"] == "5" and float(header["pitch"]) == 2e-3
    names = next(line for line in lines if not line.startswith("#"))
    assert tuple(names.split(",")) == CSV_COLUMNS
    rows = [line.split(",") for line in lines if line[0].isdigit()]
    assert len(rows) == recording.grid.size  # one row per node
    node = 7
    assert float(rows[node][3]) == pytest.approx(recording.grid.positions[node, 0])
    assert float(rows[node][7]) == pytest.approx(table.forces[0, node, 2], rel=1e-8)


@pytest.fixture(scope="module")
def two_fingers():
    """Two Hertzian presses (0.8 N left, 0.5 N right) sliding towards each other over four frames."""
    grid = SensorGrid.regular(14, 8, 2e-3, 2e-3)
    frames = [loads.simulate(grid, [loads.hertz((-6e-3 + 0.5e-3 * k, 0.0), 3e-3, 0.8),
                                    loads.hertz((6e-3 - 0.5e-3 * k, 0.0), 3e-3, 0.5, shear_ratio=0.3)],
                             noise=0.005, rng=k).stress for k in range(4)]
    recording = Recording(grid, np.array(frames), [0.0, 0.05, 0.1, 0.15], description="two fingers")
    return recording, Reconstructor(grid)


@pytest.mark.parametrize("name", ["fingers.npz", "fingers.csv"])
def test_per_contact_totals_are_exported_and_read_back(two_fingers, tmp_path, name):
    recording, solver = two_fingers
    table = reconstruct_frames(recording, solver)
    # each frame's contacts, largest first, numbered as they persist: the left one 1, the right one 2
    assert table.contact_identity.shape == (4, 2)
    np.testing.assert_array_equal(table.contact_identity, [[1, 2]] * 4)
    for row in range(4):
        result = solver.solve(recording.frames[row])
        for slot, contact in enumerate(result.contacts):
            np.testing.assert_allclose(table.contact_force[row, slot], contact.total_force, rtol=1e-6,
                                       atol=1e-9)
            np.testing.assert_allclose(table.contact_centre[row, slot], contact.centre, atol=1e-9)
    assert table.contact_centre[0, 0, 0] == pytest.approx(-6e-3, abs=0.5e-3)
    assert table.contact_force[:, 0, 2] == pytest.approx([0.8] * 4, rel=0.05)
    back = load_forces(save_forces(table, tmp_path / name))
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # one file, contacts inside it
    np.testing.assert_array_equal(back["contact_identity"], table.contact_identity)
    np.testing.assert_allclose(back["contact_force"], table.contact_force, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(back["contact_centre"], table.contact_centre, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(back["forces"], table.forces, rtol=1e-8, atol=1e-15)


def test_contact_records_fill_their_frames_slots_in_order_and_leave_the_rest_empty():
    # frames 0 (two contacts), 1 (none), 2 (one), 3 (none, after the last record)
    records = np.array([[0, 4, 0.1, 0.2, 1.0, 1e-3, 2e-3],
                        [0, 7, 0.0, 0.0, 0.5, 3e-3, 4e-3],
                        [2, 7, -0.1, 0.0, 0.6, 5e-3, 6e-3]])
    identity, force, centre = contact_slots(records, 4)
    assert identity.tolist() == [[4, 7], [0, 0], [7, 0], [0, 0]]
    np.testing.assert_array_equal(force[0], records[:2, 2:5])
    np.testing.assert_array_equal(force[2, 0], records[2, 2:5])
    np.testing.assert_array_equal(centre[2, 0], records[2, 5:7])
    assert np.isnan(force[1]).all() and np.isnan(force[2, 1]).all() and np.isnan(centre[3]).all()
    empty = contact_slots(np.empty((0, 7)), 2)
    assert [a.shape for a in empty] == [(2, 0), (2, 0, 3), (2, 0, 2)]


def test_an_npz_export_from_before_the_contacts_reads_back_with_none(two_fingers, tmp_path):
    recording, solver = two_fingers
    table = reconstruct_frames(recording, solver, [1, 2])
    path = save_forces(table, tmp_path / "fingers.npz")
    with np.load(path, allow_pickle=False) as data:
        old = {k: data[k] for k in data.files if not k.startswith("contact_")}
    assert set(old) >= {"forces", "frames", "t"}
    np.savez(tmp_path / "old.npz", **old)  # as written before the per-contact arrays existed
    back = load_forces(tmp_path / "old.npz")
    assert back["contact_identity"].shape == (2, 0) and back["contact_identity"].dtype == np.int64
    assert back["contact_force"].shape == (2, 0, 3) and back["contact_centre"].shape == (2, 0, 2)
    np.testing.assert_array_equal(back["frames"], [1, 2])
    np.testing.assert_allclose(back["forces"], table.forces, rtol=1e-8, atol=1e-15)


@pytest.mark.parametrize("name", ["fingers.npz", "fingers.csv"])
def test_each_frames_fallback_is_exported_and_read_back(two_fingers, tmp_path, name):
    recording, solver = two_fingers
    table = reconstruct_frames(recording, solver, [1, 2, 3])
    assert table.fallback.tolist() == ["", "", ""]  # every frame took the accurate path
    why = "solved by the faster member (the whole-cell fit) while the stream was 120 frames behind, again"
    marked = replace(table, fallback=["", why, ""])
    back = load_forces(save_forces(marked, tmp_path / name))
    assert back["fallback"].tolist() == ["", why, ""]  # a comma in the text survives the CSV
    with pytest.raises(ValueError, match=r"fallback must be \(T,\) for the T = 3 frames, got shape \(2,\)"):
        replace(table, fallback=["", why])


def test_an_npz_export_from_before_the_fallbacks_reads_back_with_none(two_fingers, tmp_path):
    recording, solver = two_fingers
    path = save_forces(reconstruct_frames(recording, solver, [1, 2]), tmp_path / "fingers.npz")
    with np.load(path, allow_pickle=False) as data:
        np.savez(tmp_path / "old.npz", **{k: data[k] for k in data.files if k != "fallback"})
    assert load_forces(tmp_path / "old.npz")["fallback"].tolist() == ["", ""]


def test_csv_contacts_are_hash_marked_lines_that_node_readers_skip(two_fingers, tmp_path):
    recording, solver = two_fingers
    table = reconstruct_frames(recording, solver, [1, 2])
    path = save_forces(table, tmp_path / "fingers.csv")
    # a reader that skips "#" lines sees the node table alone, as before the section existed
    nodes = np.loadtxt(path, delimiter=",", skiprows=_first_data_line(path))
    assert nodes.shape == (2 * recording.grid.size, len(CSV_COLUMNS))
    lines = path.read_text().splitlines()
    header = {line[2:].split("=", 1)[0]: line.split("=", 1)[1] for line in lines if line.startswith("#")}
    assert header["contact_columns"].split(",") == list(CONTACT_COLUMNS)
    rows = np.array([line.split("=", 1)[1].split(",") for line in lines if line.startswith("# contact=")],
                    dtype=float)
    assert rows.shape == (4, len(CONTACT_COLUMNS))  # two frames, two contacts each
    np.testing.assert_array_equal(rows[:, 0], [1, 1, 2, 2])  # frame
    np.testing.assert_array_equal(rows[:, 2], [1, 2, 1, 2])  # identity
    np.testing.assert_allclose(rows[:, 3:6], table.contact_force.reshape(-1, 3), rtol=1e-8)
    np.testing.assert_allclose(rows[:, 6:8], table.contact_centre.reshape(-1, 2), rtol=1e-8)


def test_frames_solved_alone_are_numbered_when_tabled(two_fingers):
    recording, solver = two_fingers
    results = [solver.solve(recording.frames[k]) for k in range(3)]
    assert {c.identity for r in results for c in r.contacts} == {0}
    table = force_table(results, [0, 1, 2], recording.t[:3], recording.grid, solver=solver, mode="auto")
    np.testing.assert_array_equal(table.contact_identity, [[1, 2]] * 3)
    with pytest.raises(ValueError, match=r"contact_identity, contact_force and contact_centre must be \(T, K\)"):
        ForceTable(**{**table.__dict__, "contact_centre": np.zeros((3, 2, 3))})


def _first_data_line(path):
    with open(path) as handle:
        return next(number for number, line in enumerate(handle) if not line.startswith("#")) + 1


def test_an_unknown_export_type_is_rejected(recording, reconstructor, tmp_path):
    table = reconstruct_frames(recording, reconstructor, [0])
    with pytest.raises(ValueError, match=r"out\.xlsx: unknown export type '\.xlsx', expected \.npz or \.csv"):
        save_forces(table, tmp_path / "out.xlsx")
    assert not (tmp_path / "out.xlsx").exists()


def test_the_sidecar_names_what_the_image_shows(tmp_path):
    path = write_sidecar(tmp_path / "shot.png", recording="rec.npz", frame=3, shear_ratio=0.2,
                         condition=math.inf, display={"map": "pressure"})
    assert path == tmp_path / "shot.png.view.json" == sidecar_path(tmp_path / "shot.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png.view.json"]  # the image is not touched
    info = json.loads(path.read_text())
    assert info == {SIDECAR_MARKER: 1, "recording": "rec.npz", "frame": 3, "shear_ratio": 0.2,
                    "condition": None, "display": {"map": "pressure"}}
    assert next(iter(info)) == "tactile_viewer_sidecar"  # the marker leads


@pytest.mark.parametrize("image", ["board.png", "board.PNG", "board.v2.png", "board"])
def test_the_sidecar_name_keeps_the_image_name_whole(tmp_path, image):
    assert sidecar_path(tmp_path / image) == tmp_path / f"{image}.view.json"


def test_a_sidecar_never_takes_the_name_of_a_file_of_the_same_stem(tmp_path):
    # the tester's case: board.png's sidecar used to be board.json, the sensor layout
    layout = tmp_path / "board.json"
    layout.write_bytes(b'{"nx": 4, "ny": 4, "pitch": 0.002}\n')
    before = layout.read_bytes()
    path = write_sidecar(tmp_path / "board.png", frame=1)
    assert path == tmp_path / "board.png.view.json"
    assert layout.read_bytes() == before
    assert json.loads(path.read_text())["frame"] == 1


def test_an_earlier_sidecar_of_ours_is_replaced(tmp_path):
    first = write_sidecar(tmp_path / "shot.png", frame=1, display={"map": "pressure"})
    assert check_sidecar(tmp_path / "shot.png") == first  # ours: free to replace
    second = write_sidecar(tmp_path / "shot.png", frame=7)
    assert second == first
    assert json.loads(second.read_text()) == {SIDECAR_MARKER: 1, "frame": 7}  # all of it replaced


FOREIGN = {
    "text": (lambda p: p.write_bytes(b"my notes\n"), "is not JSON"),
    "binary": (lambda p: p.write_bytes(b"\xff\xfe\x00PNG"), "is not JSON"),
    "JSON list": (lambda p: p.write_bytes(b"[1, 2]\n"), "is a JSON list, not an object"),
    "JSON without the marker": (lambda p: p.write_bytes(b'{"frame": 3, "scale": 1}\n'),
                                "is JSON without that key"),
    "large": (lambda p: p.write_bytes(b" " * (2 << 20)), "has 2097152 bytes, more than any sidecar"),
}


@pytest.mark.parametrize("kind", list(FOREIGN))
def test_an_unrelated_file_of_the_sidecar_name_is_never_modified(tmp_path, kind):
    make, found = FOREIGN[kind]
    foreign = tmp_path / "shot.png.view.json"
    make(foreign)
    before = foreign.read_bytes()
    expected = rf"^{re.escape(str(foreign))}: the sidecar of shot\.png was not written: .*'tactile_viewer_sidecar'.*{found}$"
    with pytest.raises(SidecarConflict, match=expected) as caught:
        check_sidecar(tmp_path / "shot.png")
    assert caught.value.path == foreign and caught.value.image == tmp_path / "shot.png"
    with pytest.raises(SidecarConflict, match=expected):
        write_sidecar(tmp_path / "shot.png", frame=3)
    assert foreign.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png.view.json"]  # nothing written beside it


@pytest.mark.parametrize("kind", ["folder", "link to nothing"])
def test_a_folder_or_a_broken_link_of_the_sidecar_name_is_left_alone(tmp_path, kind):
    taken = tmp_path / "shot.png.view.json"
    if kind == "folder":
        taken.mkdir()
    else:
        taken.symlink_to(tmp_path / "nowhere")
    with pytest.raises(SidecarConflict, match=rf"^{re.escape(str(taken))}: .* this file is a {kind}$"):
        write_sidecar(tmp_path / "shot.png", frame=3)
    assert not (tmp_path / "nowhere").exists()  # the link was not followed to create its target
    assert taken.is_dir() if kind == "folder" else taken.is_symlink()


def test_a_file_that_appears_during_the_check_is_not_overwritten(tmp_path, monkeypatch):
    image = tmp_path / "shot.png"
    checked = sidecar._foreign

    def appears(path):
        found = checked(path)  # free when checked...
        path.write_bytes(b"someone else's\n")  # ...taken before the write
        return found

    monkeypatch.setattr(sidecar, "_foreign", appears)
    with pytest.raises(SidecarConflict, match=r"shot\.png\.view\.json: .* appeared while the sidecar was being written"):
        write_sidecar(image, frame=3)
    assert sidecar_path(image).read_bytes() == b"someone else's\n"


def test_the_marker_is_not_taken_from_the_caller(tmp_path):
    with pytest.raises(TypeError, match="'tactile_viewer_sidecar' is written by write_sidecar"):
        write_sidecar(tmp_path / "shot.png", tactile_viewer_sidecar=0)
    assert not list(tmp_path.iterdir())


def test_a_csv_written_in_pieces_is_the_csv_written_at_once(recording, reconstructor, tmp_path, monkeypatch):
    # a long take is formatted CSV_FRAMES_PER_PIECE frames at a time: the same text as one piece
    table = reconstruct_frames(recording, reconstructor)
    whole = save_forces(table, tmp_path / "whole.csv").read_text()
    monkeypatch.setattr(forces_module, "CSV_FRAMES_PER_PIECE", 1)
    pieces = save_forces(table, tmp_path / "pieces.csv").read_text()
    assert len(table.frames) == 4 and pieces == whole
    assert load_forces(tmp_path / "pieces.csv")["frames"].tolist() == table.frames.tolist()

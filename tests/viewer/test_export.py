"""Force exports and screenshot sidecars (tactile_viewer/export.py), without Qt."""

import json
import math

import numpy as np
import pytest

from solver import Reconstructor, SensorGrid, loads
from tactile_viewer.export import (
    CSV_COLUMNS,
    load_forces,
    reconstruct_frames,
    save_forces,
    write_sidecar,
)
from tactile_viewer.recording import Recording
from tactile_viewer.worker import Cancelled


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
        np.testing.assert_array_equal(table.forces[row], expected.forces)
        assert table.shear_ratio[row] == expected.shear_ratio
        assert table.residual[row] == expected.residual and table.condition[row] == expected.condition
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
        np.testing.assert_allclose(reconstructor.matrix @ x, recording.frames[row], rtol=1e-8,
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


def test_an_unknown_export_type_is_rejected(recording, reconstructor, tmp_path):
    table = reconstruct_frames(recording, reconstructor, [0])
    with pytest.raises(ValueError, match=r"out\.xlsx: unknown export type '\.xlsx', expected \.npz or \.csv"):
        save_forces(table, tmp_path / "out.xlsx")
    assert not (tmp_path / "out.xlsx").exists()


def test_the_sidecar_names_what_the_image_shows(tmp_path):
    path = write_sidecar(tmp_path / "shot.png", recording="rec.npz", frame=3, shear_ratio=0.2,
                         condition=math.inf, display={"map": "pressure"})
    assert path == tmp_path / "shot.json"
    info = json.loads(path.read_text())
    assert info == {"recording": "rec.npz", "frame": 3, "shear_ratio": 0.2, "condition": None,
                    "display": {"map": "pressure"}}

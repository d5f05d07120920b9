"""``tactile-viewer --screenshot``: the image, its sidecar, and the files beside them left alone."""

import json
import re
import subprocess
import sys
from pathlib import Path

from tactile_viewer.io.sidecar import SIDECAR_MARKER, sidecar_path

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"


def run_screenshot(out, *options):
    return subprocess.run(
        [sys.executable, "-m", "tactile_viewer", str(SAMPLES / "flat_punch_shear.npz"), *options,
         "--screenshot", str(out)],
        capture_output=True, text=True, timeout=120)


def test_command_line_screenshot_renders_saves_and_exits(tmp_path):
    out = tmp_path / "figure.png"
    done = run_screenshot(out, "--frame", "20", "--shear-ratio", "0.3", "--shear-direction", "30", "--scale", "2")
    assert done.returncode == 0, done.stderr
    assert out.stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figure.png", "figure.png.view.json"]
    sidecar = json.loads(sidecar_path(out).read_text())
    assert sidecar[SIDECAR_MARKER] == 1
    assert sidecar["frame"] == 20 and sidecar["mode"] == "manual"
    assert abs(sidecar["shear_ratio"] - 0.3) < 1e-9 and abs(sidecar["shear_direction_deg"] - 30) < 1e-6
    assert sidecar["scale"] == 2
    assert sidecar["poisson_ratio"] == 0.5 and sidecar["sensor_size"] == 0.0  # the material solved with


def screenshot_here(out, *options):
    """``tactile-viewer --screenshot`` in this process (the command itself runs in the test above)."""
    from tactile_viewer.cli.tactile_viewer import main

    return main([str(SAMPLES / "flat_punch_shear.npz"), *options, "--size", "320x240", "--screenshot", str(out)])


def test_a_screenshot_leaves_the_layout_of_the_same_stem_alone_and_replaces_its_own_sidecar(tmp_path, capsys):
    # the tester's case: board.png's sidecar was board.json, and overwrote the sensor layout
    layout = tmp_path / "board.json"
    layout.write_bytes(b'{"nx": 16, "ny": 16, "pitch": 0.002, "thickness": 0.002}\n')
    before = layout.read_bytes()
    out = tmp_path / "board.png"
    for frame in ("3", "5"):  # the second run replaces the first one's sidecar
        assert screenshot_here(out, "--frame", frame) == 0, capsys.readouterr().err
        assert layout.read_bytes() == before
        assert json.loads((tmp_path / "board.png.view.json").read_text())["frame"] == int(frame)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.json", "board.png", "board.png.view.json"]


def test_a_screenshot_refuses_to_overwrite_an_unrelated_file_of_the_sidecar_name(tmp_path, capsys):
    out = tmp_path / "board.png"
    foreign = tmp_path / "board.png.view.json"
    foreign.write_bytes(b'{"notes": "calibration of board 7"}\n')
    before = foreign.read_bytes()
    assert screenshot_here(out, "--frame", "3") != 0  # refused, not raised (no traceback)
    err = capsys.readouterr().err
    assert re.search(rf"^tactile-viewer: {re.escape(str(foreign))}: the sidecar of board\.png was not written: "
                     r".*'tactile_viewer_sidecar'.* is JSON without that key$", err, re.MULTILINE), err
    assert "Traceback" not in err
    assert foreign.read_bytes() == before


def test_a_top_screenshot_lays_the_arrows_flat_as_the_windows_top_view(tmp_path, monkeypatch):
    # Display.seen_from: --camera top draws in-plane arrows, as the window's Top button does; iso 3-D ones
    from tactile_viewer.cli.tactile_viewer import main
    from tactile_viewer.model import display as model

    cameras = []
    seen_from = model.Display.seen_from
    monkeypatch.setattr(model.Display, "seen_from", lambda self, camera: (cameras.append(camera),
                                                                          seen_from(self, camera))[1])
    for camera, in_plane in (("top", True), ("iso", False)):
        out = tmp_path / f"{camera}.png"
        assert main([str(SAMPLES / "flat_punch_shear.npz"), "--frame", "20", "--size", "320x240",
                     "--camera", camera, "--screenshot", str(out)]) == 0
        assert json.loads(sidecar_path(out).read_text())["display"]["in_plane"] is in_plane
    assert cameras == ["top", "iso"]  # the rule's one place decided it

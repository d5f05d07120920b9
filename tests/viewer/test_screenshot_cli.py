import json
import subprocess
import sys
from pathlib import Path

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"


def test_command_line_screenshot_renders_saves_and_exits(tmp_path):
    out = tmp_path / "figure.png"
    done = subprocess.run(
        [sys.executable, "-m", "tactile_viewer", str(SAMPLES / "flat_punch_shear.npz"), "--frame", "20",
         "--shear-ratio", "0.3", "--shear-direction", "30", "--screenshot", str(out), "--scale", "2"],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert out.stat().st_size > 10_000
    sidecar = json.loads(out.with_suffix(".json").read_text())
    assert sidecar["frame"] == 20 and sidecar["mode"] == "manual"
    assert abs(sidecar["shear_ratio"] - 0.3) < 1e-9 and abs(sidecar["shear_direction_deg"] - 30) < 1e-6
    assert sidecar["scale"] == 2
    assert sidecar["poisson_ratio"] == 0.5 and sidecar["sensor_size"] == 0.0  # the material solved with

"""tactile-batch end to end: folders in, force files out, progress and summary, reruns, failures, errors."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tactile_viewer.cli.tactile_batch import ProgressLine, main, summary
from tactile_viewer.io.files import load, save
from tactile_viewer.io.forces import load_forces
from tactile_viewer.io.recording import Recording
from tactile_viewer.io.sidecar import write_sidecar

ROOT = Path(__file__).resolve().parents[3]
SAMPLES = ROOT / "sample_data"
SUMMARY = re.compile(r"^tactile-batch: (\d+) files? written, (\d+) skipped, (\d+) failed; (\d+) frames in "
                     r"[\d.]+ s wall \([\d.]+ frames/s; (.*)\)$")


@pytest.fixture
def data(tmp_path):
    """A folder of two short recordings (NPZ, and CSV in a sub-folder) of two contacts: 10 and 6 frames."""
    recording = load(SAMPLES / "two_contacts.npz")
    folder = tmp_path / "data"
    (folder / "day2").mkdir(parents=True)
    save(Recording(recording.grid, recording.frames[:10], recording.t[:10], description="first"),
         folder / "first.npz")
    save(Recording(recording.grid, recording.frames[20:26], recording.t[20:26], description="second"),
         folder / "day2" / "second.csv")
    return folder


def test_a_folder_is_written_then_skipped_on_a_rerun(data, tmp_path, capsys):
    out = tmp_path / "out"
    assert main([str(data), "--out", str(out), "--workers", "1", "--chunk", "4"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [  # in the order of the paths: day2/ before first.npz
        f"wrote {out / 'day2' / 'second.csv.forces.npz'} (6 frames of {data / 'day2' / 'second.csv'})",
        f"wrote {out / 'first.npz.forces.npz'} (10 frames of {data / 'first.npz'})"]
    err = captured.err.splitlines()
    assert err[0].startswith("frames 0/16 (0%), 0.0 frames/s, left unknown")
    assert re.fullmatch(r"frames 16/16 \(100%\), [\d.]+ frames/s, left 0:00:00", err[-2])
    assert SUMMARY.match(err[-1]).groups() == ("2", "0", "0", "16", "joblib, 1 worker (this process)")
    first = load_forces(out / "first.npz.forces.npz")
    assert first["forces"].shape == (10, 256, 3) and str(first["source"]) == str(data / "first.npz")
    assert main([str(data), "--out", str(out), "--workers", "1"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [
        f"skipped {data / 'day2' / 'second.csv'}: {out / 'day2' / 'second.csv.forces.npz'} is finished "
        "(same input and settings)",
        f"skipped {data / 'first.npz'}: {out / 'first.npz.forces.npz'} is finished (same input and settings)"]
    assert SUMMARY.match(captured.err.splitlines()[-1]).groups() == ("0", "2", "0", "0", "nothing to solve")
    # other settings are another output's: written again
    assert main([str(data), "--out", str(out), "--workers", "1", "--kernel", "point"]) == 0
    assert SUMMARY.match(capsys.readouterr().err.splitlines()[-1]).groups()[:3] == ("2", "0", "0")
    assert str(load_forces(out / "first.npz.forces.npz")["kernel"]) == "point"


def test_foxglove_files_carry_every_frame_of_each_recording(data, tmp_path, capsys):
    from tests.tactile_viewer.io.test_foxglove_mcap import read_back

    out = tmp_path / "out"
    assert main([str(data), "--out", str(out), "--workers", "1", "--format", "foxglove"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"wrote {out / 'day2' / 'second.csv.forces.mcap'} (6 frames of {data / 'day2' / 'second.csv'})",
        f"wrote {out / 'first.npz.forces.mcap'} (10 frames of {data / 'first.npz'})"]
    back = read_back(out / "first.npz.forces.mcap")
    counts = {}
    for topic, messages in back["messages"].items():
        counts[back["schemas"][topic].name] = counts.get(back["schemas"][topic].name, 0) + len(messages)
    assert counts == {"foxglove.Grid": 20, "foxglove.SceneUpdate": 10, "tactile_viewer.ContactTotals": 10}
    cells = [np.frombuffer(p.data, "<f4") for p in back["decoded"]["/tactile/stress"]]
    np.testing.assert_array_equal(cells, np.asarray(load(data / "first.npz").frames).astype("<f4"))


def test_a_damaged_file_is_named_and_the_others_are_written(data, tmp_path, capsys):
    (data / "broken.npz").write_bytes(b"PK\x03\x04 cut short")
    frames = np.array(load(data / "first.npz").frames)
    frames[7, 0] = 1e200  # read, then refused by the solve
    save(Recording(load(data / "first.npz").grid, frames, np.arange(10) / 30), data / "huge.npz")
    out = tmp_path / "out"
    assert main([str(data), "--out", str(out), "--workers", "1", "--chunk", "4", "--format", "csv"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert f"tactile-batch: failed: {data / 'broken.npz'}: {data / 'broken.npz'}: not a readable NPZ archive " \
           "(File is not a zip file)" in err
    assert (f"tactile-batch: failed: {data / 'huge.npz'}: frames 4 to 7: ValueError: stress must be at most "
            "1e+100 Pa in magnitude, got 1e+200 at taxel(s) [0]") in err
    assert SUMMARY.match(err[-1]).groups()[:4] == ("2", "0", "2", "16")
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "day2", "day2/second.csv.forces.csv", "day2/second.csv.forces.csv.batch.json",
        "first.npz.forces.csv", "first.npz.forces.csv.batch.json"]
    assert load_forces(out / "first.npz.forces.csv")["forces"].shape == (10, 256, 3)


def test_the_settings_of_a_screenshots_sidecar(data, tmp_path, capsys):
    view = write_sidecar(tmp_path / "shot.png", recording="x", frame=0, kernel="cell", mode="manual",
                         shear_ratio=0.25, shear_direction_deg=-45.0)
    out = tmp_path / "out"
    assert main([str(data / "first.npz"), "--out", str(out), "--view", str(view), "--workers", "1"]) == 0
    written = load_forces(out / "first.npz.forces.npz")
    assert (str(written["kernel"]), str(written["mode"])) == ("cell", "manual")
    np.testing.assert_array_equal(written["shear_ratio"], np.full(10, 0.25))
    assert "written" in capsys.readouterr().err


def test_the_command_runs_as_a_module_on_two_processes(data, tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "tactile_viewer.cli.tactile_batch", str(data / "first.npz"),
                           str(data / "day2"), "--out", str(out), "--workers", "2", "--chunk", "3"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT,
                          env=os.environ | {"PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, done.stderr
    assert SUMMARY.match(done.stderr.splitlines()[-1]).groups() == ("2", "0", "0", "16",
                                                                    "joblib, 2 worker processes (loky)")
    assert load_forces(out / "second.csv.forces.npz")["forces"].shape == (6, 256, 3)


@pytest.mark.parametrize(("options", "message"), [
    (["--chunk", "0"], "tactile-batch: error: --chunk must be a whole number of frames >= 1, got 0"),
    (["--workers", "0"], "tactile-batch: error: --workers must be a whole number of processes >= 1, got 0"),
    (["--workers", "2", "--scheduler", "tcp://h:1"], "--workers applies to joblib and --scheduler local, not "
                                                      "to the cluster at tcp://h:1 (its workers are the cluster's), "
                                                      "got --workers 2"),
    (["--preset", "fastest"], "argument --preset: invalid choice: 'fastest'"),
    (["--kernel", "hertz"], "argument --kernel: invalid choice: 'hertz'"),
    (["--preset", "cell, fit", "--view", "a.view.json"], "argument --view: not allowed with argument --preset"),
])
def test_bad_options_are_refused_before_any_work(data, tmp_path, capsys, options, message):
    with pytest.raises(SystemExit) as done:
        main([str(data), "--out", str(tmp_path / "out"), *options])
    assert done.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("options", "message"), [
    (["--scheduler", "http://h:1"], "tactile-batch: --scheduler must be 'local' or a scheduler's address "
                                    "(tcp|tls|inproc|ucx|ws|wss://host:port), got 'http://h:1'"),
    (["--view", "missing.view.json"], "tactile-batch: --view missing.view.json: cannot read the view sidecar: "
                                      "No such file or directory"),
])
def test_bad_settings_are_refused_before_any_work(data, tmp_path, capsys, options, message, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([str(data), "--out", "out", *options]) == 2
    assert capsys.readouterr().err == message + "\n"
    assert not (tmp_path / "out").exists()


def test_bad_inputs_and_outputs_are_named(data, tmp_path, capsys):
    assert main([str(tmp_path / "nope"), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == (f"tactile-batch: INPUT must be a recording file or a folder, got "
                                       f"'{tmp_path / 'nope'}' (no such file or folder)\n")
    (tmp_path / "taken").write_text("")
    assert main([str(data), "--out", str(tmp_path / "taken")]) == 2
    assert capsys.readouterr().err == f"tactile-batch: --out must be a folder, got '{tmp_path / 'taken'}' (a file)\n"


def test_an_unreachable_scheduler_is_named(data, tmp_path, capsys, monkeypatch):
    from tactile_viewer.model import batch_engines

    monkeypatch.setattr(batch_engines, "CONNECT_TIMEOUT", 0.5)
    assert main([str(data), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert capsys.readouterr().err.startswith("tactile-batch: --scheduler tcp://127.0.0.1:9: no Dask scheduler "
                                              "answered within 0.5 s")


def test_bags_and_recordings_in_one_folder(data, tmp_path, capsys):
    from tests.tactile_viewer.written_bags import frames_bag, layout_file, skin_frames

    layout, _ = layout_file(tmp_path)  # a 3 x 2 skin: gain 2 (raw - 0.5) kPa
    frames_bag(data / "take1", skin_frames(9), storage="sqlite3")
    frames_bag(data / "wrong_skin", skin_frames(4, taxels=7))
    out = tmp_path / "out"
    run = [str(data), "--out", str(out), "--layout", str(layout), "--workers", "1", "--chunk", "4"]
    assert main(run) == 1
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [
        f"wrote {out / 'day2' / 'second.csv.forces.npz'} (6 frames of {data / 'day2' / 'second.csv'})",
        f"wrote {out / 'first.npz.forces.npz'} (10 frames of {data / 'first.npz'})",
        f"wrote {out / 'take1.forces.npz'} (9 frames of {data / 'take1'})"]
    assert (f"tactile-batch: failed: {data / 'wrong_skin'}: {data / 'wrong_skin'}: topic '/skin/pressure' field "
            "'data': no message can be a frame: 4 of 4 messages left out: 7 values, not the layout's 6"
            ) in captured.err.splitlines()
    assert SUMMARY.match(captured.err.splitlines()[-1]).groups()[:4] == ("3", "0", "1", "25")
    written = load_forces(out / "take1.forces.npz")
    assert written["forces"].shape == (9, 6, 3) and str(written["source"]) == str(data / "take1")
    # a rerun skips what is finished; other bag options are another output for the bags only
    (data / "wrong_skin").rename(tmp_path / "wrong_skin")
    assert main(run) == 0
    assert SUMMARY.match(capsys.readouterr().err.splitlines()[-1]).groups()[:3] == ("0", "3", "0")
    assert main([*run, "--topic", "/skin/pressure", "--field", "data"]) == 0
    captured = capsys.readouterr()
    assert f"wrote {out / 'take1.forces.npz'} (9 frames of {data / 'take1'})" in captured.out.splitlines()
    assert SUMMARY.match(captured.err.splitlines()[-1]).groups()[:3] == ("1", "2", "0")


def test_a_bag_for_foxglove(tmp_path, capsys):
    from tests.tactile_viewer.io.test_foxglove_mcap import read_back
    from tests.tactile_viewer.written_bags import frames_bag, layout_file, skin_frames

    layout_path, layout = layout_file(tmp_path)
    raw = skin_frames(5, seed=8)  # fixed seed
    bag = frames_bag(tmp_path / "take1", raw)[0]
    out = tmp_path / "out"
    assert main([str(bag / "metadata.yaml"), "--out", str(out), "--layout", str(layout_path), "--workers", "1",
                 "--format", "foxglove"]) == 0
    assert capsys.readouterr().out == f"wrote {out / 'take1.forces.mcap'} (5 frames of {bag})\n"
    back = read_back(out / "take1.forces.mcap")
    cells = [np.frombuffer(p.data, "<f4") for p in back["decoded"]["/tactile/stress"]]
    np.testing.assert_array_equal(cells, layout.to_pascals(raw.astype(np.float64)).astype("<f4"))
    assert len(back["decoded"]["/tactile/forces"]) == 5


def test_bag_options_are_refused_or_noted(data, tmp_path, capsys):
    from tests.tactile_viewer.written_bags import frames_bag, layout_file, skin_frames

    frames_bag(tmp_path / "take1", skin_frames(3))
    assert main([str(tmp_path / "take1"), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == (f"tactile-batch: --layout is needed: INPUT holds 1 ROS 2 bag "
                                       f"({tmp_path / 'take1'}), whose values become stresses through the skin's "
                                       "sensor layout file\n")
    assert main([str(data), "--out", str(tmp_path / "out"), "--topic", "/skin"]) == 2
    assert capsys.readouterr().err == ("tactile-batch: --topic and --field choose what a ROS 2 bag is read from: "
                                       "give --layout too (got --topic /skin, --field None)\n")
    assert main([str(data), "--out", str(tmp_path / "out"), "--layout", str(tmp_path / "none.json")]) == 2
    assert capsys.readouterr().err.startswith(f"tactile-batch: --layout: {tmp_path / 'none.json'}")
    assert not (tmp_path / "out").exists()
    # recordings of ours carry their layout: a layout given for none is said and the run goes on
    layout, _ = layout_file(tmp_path)
    assert main([str(data / "first.npz"), "--out", str(tmp_path / "out"), "--layout", str(layout),
                 "--workers", "1"]) == 0
    assert ("tactile-batch: note: --layout, --topic and --field are unused: no input is a ROS 2 bag (recordings "
            "of this viewer carry their own layout)") in capsys.readouterr().err.splitlines()


class Terminal:
    """A stream that says it is a terminal and keeps what was written."""

    def __init__(self):
        self.text = ""

    def isatty(self):
        return True

    def write(self, text):
        self.text += text

    def flush(self):
        pass


def test_the_progress_line_is_rewritten_in_place_at_most_four_times_a_second():
    clock = iter([0.0, 0.0, 0.1, 0.3, 0.35, 0.4])
    stream = Terminal()
    line = ProgressLine(stream, clock=lambda: next(clock))  # starts at 0.0
    line.update(0, 100, force=True)  # 0.0
    line.update(10, 100)  # 0.1: held back
    line.update(60, 100)  # 0.3: shown
    line.update(70, 100)  # 0.35: held back
    line.say("tactile-batch: failed: x: why")
    line.show_last()  # 0.4: the last counts
    line.end()
    assert stream.text == ("\rframes 0/100 (0%), 0.0 frames/s, left unknown\x1b[K"
                           "\rframes 60/100 (60%), 200.0 frames/s, left 0:00:00\x1b[K\n"
                           "tactile-batch: failed: x: why\n"
                           "\rframes 70/100 (70%), 175.0 frames/s, left 0:00:00\x1b[K\n")


def test_the_summary_counts_files_and_frames():
    from tactile_viewer.model.batch import FileOutcome
    from tactile_viewer.model.batch_inputs import BatchInput

    one = BatchInput(Path("a.npz"), Path("out/a.npz.forces.npz"))
    outcomes = [FileOutcome(one, "written", 300), FileOutcome(one, "skipped"), FileOutcome(one, "failed", 50, "x")]
    assert summary(outcomes, wall=2.0, engine="joblib") == (
        "tactile-batch: 1 file written, 1 skipped, 1 failed; 300 frames in 2.0 s wall (150.0 frames/s; joblib)")

"""tactile-viewer on a ROS 2 bag: BAG --layout FILE [--topic T] [--field F] with --info, --report, --screenshot."""

import re
from pathlib import Path

import numpy as np
import pytest

from tactile_viewer.cli.tactile_viewer import main
from tactile_viewer.io.files import load
from tactile_viewer.io.layout import SensorLayout, save_layout
from tests.tactile_viewer.written_bags import multiarray, write_bag

SAMPLES = Path(__file__).resolve().parents[3] / "sample_data"
F64 = "std_msgs/msg/Float64MultiArray"
T0_NS = 1_700_000_000_000_000_000


@pytest.fixture
def sample_bag(tmp_path):
    """The static Hertz sample's frames (pascals) as a bag, beside a 4-value topic, and the sample's layout."""
    sample = load(SAMPLES / "hertz_static.npz")
    logged = T0_NS + np.round(sample.t * 1e9).astype(np.int64)
    messages = [("/skin/stress", F64, int(log), multiarray(frame, F64))
                for log, frame in zip(logged, sample.frames, strict=True)]
    messages += [("/wrist", F64, int(log), multiarray(np.zeros(4), F64)) for log in logged]
    bag = write_bag(tmp_path / "hertz_bag", messages, storage="mcap")
    layout = save_layout(SensorLayout(sample.grid), tmp_path / "skin16.json")
    return bag, layout


def frame_lines(text):
    # a frame's line: frame, t, Fz, Ft, mu, theta, efficiency (not the errors against truth, nor the solve time)
    return [line.split()[:7] for line in text.splitlines() if re.match(r"\s+\d+\s+\d\.\d{3}\s", line)]


def test_report_of_a_bag_equals_the_report_of_the_recording_it_carries(sample_bag, capsys):
    bag, layout = sample_bag
    assert main([str(SAMPLES / "hertz_static.npz"), "--report"]) == 0
    expected = frame_lines(capsys.readouterr().out)
    # the layout's 256 taxels choose /skin/stress over /wrist's 4 values
    assert main([str(bag), "--layout", str(layout), "--report"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{bag}: 30 frames, 16x16 taxels") and len(expected) == 30
    assert frame_lines(out) == expected


def test_info_of_a_bag_says_what_it_holds(sample_bag, capsys):
    bag, layout = sample_bag
    assert main([str(bag), "--layout", str(layout), "--topic", "/skin/stress", "--field", "data", "--info"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[:2] == ["frames 30", "span 0.967 s"]
    assert "first received 2023-11-14 22:13:20.000 UTC (1700000000.000000 s)" in lines
    assert "damage none found" in lines and "cut short no" in lines


def test_a_screenshot_of_a_bag(sample_bag, tmp_path, capsys):
    bag, layout = sample_bag
    out = tmp_path / "bag.png"
    assert main([str(bag), "--layout", str(layout), "--screenshot", str(out), "--frame", "3", "--size", "320x240"]) == 0
    assert out.stat().st_size > 1000 and capsys.readouterr().out.startswith(f"saved {out} (frame 3,")


@pytest.mark.parametrize("options, message", [
    ([], r"hertz_bag: a ROS 2 bag needs the sensor layout file of its skin"),
    (["--topic", "/nowhere"], r"hertz_bag: no topic '/nowhere'; the bag's topics: /skin/stress \(std_msgs/msg/"
                              r"Float64MultiArray\), /wrist \(std_msgs/msg/Float64MultiArray\)"),
    (["--topic", "/wrist"], r"hertz_bag: topic '/wrist' field 'data': no message can be a frame: 30 of 30 "
                            r"messages left out: 4 values, not the layout's 256"),
    (["--field", "layout"], r"hertz_bag: no topic has a numeric array field 'layout'"),
])
def test_a_bag_that_cannot_open_as_asked_exits_2_saying_why(sample_bag, capsys, options, message):
    bag, layout = sample_bag
    layout_option = [] if not options else ["--layout", str(layout)]
    assert main([str(bag), *layout_option, *options, "--info"]) == 2
    assert re.search(message, capsys.readouterr().err)


def test_bag_options_are_refused_for_a_recording_and_without_one(sample_bag, capsys):
    _, layout = sample_bag
    assert main([str(SAMPLES / "hertz_static.npz"), "--layout", str(layout), "--info"]) == 2
    assert "hertz_static.npz: not a ROS 2 bag: a layout, topic and field are for bags" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["--layout", str(layout)])
    assert info.value.code == 2
    assert "--layout, --topic and --field go with a ROS 2 bag given as RECORDING" in capsys.readouterr().err

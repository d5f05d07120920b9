"""The viewer benchmark runs end to end (its figures are measured, never asserted)."""

import io
import re

from benchmarks import viewer_speed as bench


def test_the_viewer_benchmark_measures_what_it_says(qapp, no_plotter_leak):
    out = io.StringIO()
    result = bench.run(count=3, seconds=0.5, out=out)
    text = out.getvalue()
    assert "OpenGL:" in text and "16x16 grid" in text
    rows = re.findall(r"^\s+(shear ratio|shear direction|frame step).*?\s(\d+\.\d)\s+(\d+\.\d)$", text, re.M)
    assert [name for name, _, _ in rows] == ["shear ratio", "shear direction", "frame step"]
    # one latency per action, each ending at a render that followed a solve of that action
    assert [len(result[k]) for k in ("ratio", "direction", "step")] == [3, 3, 3]
    assert result["solves"]["done"] >= 9
    # playback follows the recording's clock: it never draws more distinct frames than the clock
    # delivers (the recording's own rate times the speed), whatever the display could do
    for speed, rate in result["playback"].items():
        assert rate <= speed * result["recording_fps"] * 1.1 + 2 / 0.5, (speed, rate)
    rates = re.findall(r"^\s+(\d)x .*?(\d+\.\d) frames drawn per second$", text, re.M)
    assert [speed for speed, _ in rates] == ["1", "4"]


def test_the_decoder_benchmark_decodes_every_frame():
    out = io.StringIO()
    rates = bench.decoder_throughput(frames=300, out=out)
    assert set(rates) == {("binary", 4096), ("binary", 65536), ("text", 4096), ("text", 65536)}
    assert out.getvalue().count("frames/s") == 4


def test_the_live_benchmark_records_without_gaps(qapp, no_plotter_leak):
    out = io.StringIO()
    result = bench.live(seconds=1.5, rate=500, out=out)
    assert result["gaps"] == 0 and result["recorded"] >= 500
    assert "sequence gaps 0" in out.getvalue() and "CPU: viewer" in out.getvalue()

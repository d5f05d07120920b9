"""The viewer benchmark runs end to end (its figures are measured, never asserted)."""

import io
import re

from tactile_viewer import bench


def test_the_viewer_benchmark_prints_latencies_and_frame_rates(qapp, no_plotter_leak):
    out = io.StringIO()
    bench.run(count=3, seconds=0.3, out=out)
    text = out.getvalue()
    assert "OpenGL:" in text and "16x16 grid" in text
    latencies = re.findall(r"^\s+(shear ratio|shear direction|frame step).*?\s(\d+\.\d)\s+(\d+\.\d)$", text, re.M)
    assert len(latencies) == 3 and all(float(median) > 0 for _, median, _ in latencies)
    rates = re.findall(r"^\s+(\d)x .*?(\d+\.\d) frames drawn per second$", text, re.M)
    assert [speed for speed, _ in rates] == ["1", "4"] and all(float(r) > 0 for _, r in rates)


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

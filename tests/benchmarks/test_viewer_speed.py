"""The viewer benchmark runs end to end (its figures are measured, never asserted)."""

import io
import re

import pytest

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
    rates = re.findall(r"^\s+(\d)x .*?(\d+\.\d) frames drawn per second, (\d+\.\d\d) window compositions "
                       r"per frame$", text, re.M)
    assert [speed for speed, _, _ in rates] == ["1", "4"]
    # every frame drawn was composed at least once (a frame is on screen only through a composition)
    assert all(result["compositions"][speed] >= 1 for speed in (1.0, 4.0)), result["compositions"]


def test_the_decoder_benchmark_decodes_every_frame():
    out = io.StringIO()
    rates = bench.decoder_throughput(frames=300, out=out)
    assert set(rates) == {("binary", 4096), ("binary", 65536), ("text", 4096), ("text", 65536)}
    assert out.getvalue().count("frames/s") == 4


def test_the_live_benchmark_records_without_gaps(qapp, no_plotter_leak):
    out = io.StringIO()
    result = bench.live(seconds=1.5, rate=500, out=out)
    # about 750 frames on an idle machine; how many arrive in 1.5 s of wall clock is the machine's speed
    # (177 at load 4), which tests do not assert: enough for "no gap" to mean something
    assert result["gaps"] == 0 and result["recorded"] >= 100
    assert "sequence gaps 0" in out.getvalue() and "CPU: viewer" in out.getvalue()


def test_the_solve_comparison_times_the_window_against_a_plain_loop_idle_and_busy(qapp, no_plotter_leak):
    out = io.StringIO()
    result = bench.solve_comparison(bench.SOLVE_SAMPLES[0], seconds=0.5, wait_presets=False, out=out)
    text = out.getvalue()
    assert text.startswith("two_contacts.npz: 16x16 grid, 45 frames; solves in the window")
    assert list(result) == ["idle", "busy"]
    for load, r in result.items():
        assert set(r) == {"window", "window_cpu", "plain", "plain_cpu", "ratio", "ratio_p95", "ratio_cpu"}
        # the plain loop solves the very frames the window delivered, as many
        assert r["window"]["n"] >= 1 and r["plain"]["n"] == r["window"]["n"] == r["plain_cpu"]["n"]
        assert r["window_cpu"]["n"] >= r["window"]["n"]  # the worker may have solved frames it then dropped
        rows = re.findall(rf"^  {load}\s+(window|plain)\s+(\d+)(?:\s+\d+\.\d\d){{4}}$", text, re.M)
        assert [where for where, _ in rows] == ["window", "plain"]
        assert re.search(rf"^  {load}\s+window / plain: wall median \d+\.\d\dx, p95 \d+\.\d\dx; "
                         rf"CPU median \d+\.\d\dx$", text, re.M)


def test_the_busy_core_spins_until_ended():
    spinner = bench.busy_core()
    try:
        assert spinner.poll() is None
    finally:
        spinner.terminate()
        spinner.wait(10)
    assert spinner.poll() is not None


@pytest.mark.parametrize("arguments, message", [
    (dict(loads=("idle", "hot")), r"loads must be among idle, busy, got 'hot'"),
    (dict(seconds=0), r"seconds must be > 0, got 0"),
])
def test_the_solve_comparison_refuses_what_it_cannot_measure(arguments, message):
    # refused before any window opens
    with pytest.raises(ValueError, match=message):
        bench.solve_comparison(bench.SOLVE_SAMPLES[1], **arguments)


@pytest.mark.parametrize("arguments, message", [
    (["--solve-seconds", "0"], r"--solve-seconds must be > 0, got 0"),
    (["--solve-samples", "nowhere.npz"], r"--solve-samples: no such file: nowhere.npz"),
    (["--loads", "warm"], r"argument --loads: invalid choice: 'warm'"),
])
def test_the_command_refuses_bad_solve_options(arguments, message, capsys):
    with pytest.raises(SystemExit):
        bench.main(arguments)
    assert re.search(message, capsys.readouterr().err)


def test_a_benchmark_window_has_settings_of_its_own_unless_told(monkeypatch, tmp_path):
    # the user's own settings (a floated dock, other rows) must neither shape the figures nor be
    # changed by a benchmark
    monkeypatch.delenv("TACTILE_VIEWER_CONFIG")
    folder = bench._own_settings()
    assert folder.is_dir() and folder.name.startswith("tactile-benchmark-settings-")
    assert bench.os.environ["TACTILE_VIEWER_CONFIG"] == str(folder)
    assert bench._own_settings() == folder  # one folder per process
    monkeypatch.setenv("TACTILE_VIEWER_CONFIG", str(tmp_path))
    assert bench._own_settings() == tmp_path  # given: used as it is

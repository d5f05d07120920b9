"""``python -m measurement.bench``: the solve timings beside the dense-product floor of the same run."""

import re

import numpy as np
import pytest

from measurement import bench


def test_per_frame_times_every_path_wall_and_cpu():
    # a small skin and few frames: what is checked is what is measured, not how fast
    times = bench.per_frame(n=6, frames=2, repeat=1)
    paths = ("auto", "cold", "playback", "given", "slider", "normal", "floor")
    assert set(times) == {p + suffix for p in paths for suffix in ("", "_cpu")}
    assert all(value > 0 for value in times.values())


def test_the_command_prints_each_kernel_against_the_floor(capsys):
    # the multi-contact frames and the broad press are left out here (empty lists) and tested below
    bench.main(["--skin", "6", "--frames", "2", "--sizes", "8", "--no-pinv", "--contacts", "--press-sizes"])
    out = capsys.readouterr().out
    assert out.startswith("machine: ")
    lines = [line for line in out.splitlines() if "solve median wall (CPU) ms" in line]
    assert [line.split()[1] for line in lines] == ["layer", "cell", "point"]
    for line in lines:
        for path in ("auto", "auto cold", "auto in playback", "given parameters", "slider move",
                     "normal only", "dense-product floor"):
            assert re.search(rf"{path} [0-9.]+ \([0-9.]+\)", line), (path, line)
        assert re.search(r"auto / floor [0-9.]+x$", line)
    assert re.search(r"^8x8 set-up: DenseSolver [0-9.]+ s \(cell kernel [0-9.]+ s\)$", out, re.M)
    assert "contact" not in out and "broad press" not in out


@pytest.mark.parametrize("arguments, message", [
    (["--skin", "3"], r"--skin must be at least 4 and --frames at least 1, got 3 and 40"),
    (["--frames", "0"], r"--skin must be at least 4 and --frames at least 1, got 16 and 0"),
    (["--sizes", "32", "0"], r"--sizes must be at least 1 each, got 32 0"),
    (["--contacts", "1", "4"], r"--contacts must be 1, 2 or 3 each, got 1 4"),
    (["--contacts", "0"], r"--contacts must be 1, 2 or 3 each, got 0"),
    (["--contact-frames", "0"], r"--contact-frames must be at least 1, got 0"),
    (["--moving-frames", "-1"], r"--moving-frames must be 0 or more, got -1"),
    (["--press-sizes", "32", "4"], r"--press-sizes must be at least 8 each, got 32 4"),
    (["--press-frames", "0"], r"--press-frames must be at least 1, got 0"),
    (["--kernels", "fem"], r"argument --kernels: invalid choice: 'fem'"),
])
def test_the_command_refuses_a_skin_or_frame_count_it_cannot_time(arguments, message, capsys):
    with pytest.raises(SystemExit):
        bench.main(arguments)
    assert re.search(message, capsys.readouterr().err)


def test_contact_frames_are_fixed_and_each_frame_is_its_own():
    grid, frames = bench.contact_frames(2, 3)
    assert grid.shape == (16, 16) and grid.pitch == bench.PITCH and grid.thickness == bench.PITCH
    assert grid.poisson_ratio == bench.POISSON_RATIO
    assert len(frames) == 3 and all(b.shape == (256,) for b in frames)
    # fixed seed: the same frames every run; other positions and noise frame to frame
    _, again = bench.contact_frames(2, 2)
    assert all(np.array_equal(a, b) for a, b in zip(frames, again, strict=False))
    assert not np.allclose(frames[0], frames[1])


@pytest.mark.parametrize("arguments, message", [
    (dict(count=0, frames=1), r"count and frames must be at least 1, got 0 and 1"),
    (dict(count=1, frames=0), r"count and frames must be at least 1, got 1 and 0"),
    (dict(count=1, frames=1, n=6), r"n must be at least 8 .*got 6"),
    (dict(count=3, frames=1, n=8), r"3 contacts of 1.6 to 2.4 pitches do not fit apart"),
])
def test_contact_frames_refuse_what_cannot_be_placed(arguments, message):
    with pytest.raises(ValueError, match=message):
        bench.contact_frames(**arguments)


def test_multi_contact_times_each_count_wall_and_cpu_median_and_p95():
    times = bench.multi_contact([1, 2], frames=2, repeat=2)
    assert list(times) == [1, 2]
    for t in times.values():
        assert set(t) == {"wall", "wall_p95", "cpu", "cpu_p95", "fastest", "fastest_cpu", "solves", "frames",
                          "found"}
        assert t["solves"] == 4 and t["frames"] == 2
        assert all(t[k] > 0 for k in ("wall", "wall_p95", "cpu", "fastest"))
        assert t["wall_p95"] >= t["wall"] and t["cpu_p95"] >= t["cpu"]



def test_moving_contact_frames_follow_each_other_and_close_their_turn():
    grid, frames = bench.moving_contact_frames(2, 8)
    assert grid.shape == (16, 16) and len(frames) == 8
    _, again = bench.moving_contact_frames(2, 8)
    assert all(np.array_equal(a, b) for a, b in zip(frames, again, strict=True))  # fixed seed
    # the contacts move a little each frame, and the last frame leads into the first: the stress
    # changes from a frame to the next by much less than between two unrelated frames
    step = [np.linalg.norm(frames[(k + 1) % 8] - frames[k]) for k in range(8)]
    _, unrelated = bench.contact_frames(2, 2)
    assert max(step) < 0.5 * np.linalg.norm(unrelated[1] - unrelated[0])
    with pytest.raises(ValueError, match=r"count and frames must be at least 1, got 1 and 0"):
        bench.moving_contact_frames(1, 0)
    with pytest.raises(ValueError, match=r"n must be at least 8 .*got 6"):
        bench.moving_contact_frames(1, 2, n=6)


def test_moving_contacts_time_each_count_in_order():
    times = bench.moving_contacts([2], frames=3, repeat=2)
    t = times[2]
    assert set(t) == {"wall", "wall_p95", "cpu", "cpu_p95", "solves", "frames", "found"}
    assert t["solves"] == 6 and t["frames"] == 3 and t["found"] == 2
    assert t["wall_p95"] >= t["wall"] > 0 and t["cpu_p95"] >= t["cpu"]

def test_press_frames_load_most_of_the_skin():
    grid, frames = bench.press_frames(12, 2)
    assert grid.shape == (12, 12) and len(frames) == 2
    for b in frames:
        # half the side loaded: most sensors feel it
        assert np.mean(b > 0.05 * b.max()) > 0.4
    with pytest.raises(ValueError, match=r"n must be at least 2 and frames at least 1, got 8 and 0"):
        bench.press_frames(8, 0)


def test_broad_press_gives_set_up_solves_and_peak_memory():
    t = bench.broad_press(8, frames=2)
    assert set(t) == {"wall", "wall_p95", "cpu", "cpu_p95", "setup", "setup_cpu", "first", "first_cpu",
                      "solves", "found", "solver", "fallbacks", "fallback", "rss_before", "rss_peak", "traced_peak",
                      "given", "given_cpu"}
    assert t["solves"] == 2 and t["solver"] == "DenseSolver"
    assert 0 <= t["fallbacks"] <= 2 and isinstance(t["fallback"], str)
    assert bool(t["fallback"]) == (t["fallbacks"] > 0)
    assert t["setup"] > 0 and t["first"] > 0 and t["wall_p95"] >= t["wall"] and t["given"] > 0
    assert t["rss_peak"] >= t["rss_before"] > 0 and t["traced_peak"] > 0
    assert np.isnan(bench.broad_press(8, frames=1, memory=False)["traced_peak"])


def test_the_command_prints_the_multi_contact_frames_and_the_broad_press(capsys):
    bench.main(["--kernels", "--sizes", "--contacts", "1", "3", "--contact-frames", "2", "--press-sizes", "8",
                "--press-frames", "2", "--moving-frames", "2"])
    out = capsys.readouterr().out
    assert out.startswith("machine: ")
    assert "solve median wall (CPU) ms" not in out and "set-up: DenseSolver" not in out
    x = r"[0-9.]+"  # a number
    lines = re.findall(rf"^16x16 (\d) contacts? +automatic solve ms, 10 solves of 2 frames: wall median {x} "
                       rf"p95 {x}, CPU median {x} p95 {x}; each frame's fastest, median {x} \({x}\); "
                       rf"contacts found, median {x}$", out, re.M)
    assert lines == ["1", "3"]
    moving = re.findall(rf"^16x16 (\d) contacts? +in motion, automatic solve ms, 6 solves: wall median {x} "
                        rf"p95 {x}, CPU median {x} p95 {x}; contacts found, median {x}$", out, re.M)
    assert moving == ["1", "3"]
    assert re.search(rf"^8x8 broad press: set-up \(DenseSolver\) {x} s \(CPU {x} s\); first solve {x} s "
                     rf"\(CPU {x} s\); automatic solve s, 2 solves: wall median {x} p95 {x}, CPU median {x} "
                     rf"p95 {x}; contacts found, median {x}; cheaper fallback on [0-2] of 2(: .+)?; "
                     rf"given parameters \(0.2, 0.5 rad\) median {x} s \(CPU {x} s\); "
                     rf"peak RSS {x} MB \({x} MB before its set-up\); traced peak of set-up and first solve "
                     rf"\(tracemalloc, untimed pass\) {x} MB$", out, re.M)

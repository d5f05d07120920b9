"""``python -m solver.bench``: the solve timings beside the dense-product floor of the same run."""

import re

import numpy as np
import pytest

from solver import bench


def test_the_machine_is_one_line():
    line = bench.machine()
    assert "\n" not in line and "cores, numpy" in line


def test_per_frame_times_every_path_wall_and_cpu():
    # a small skin and few frames: what is checked is what is measured, not how fast
    times = bench.per_frame(n=6, frames=2, repeat=1)
    paths = ("auto", "cold", "playback", "given", "slider", "normal", "floor")
    assert set(times) == {p + suffix for p in paths for suffix in ("", "_cpu")}
    assert all(value > 0 for value in times.values())


def test_the_command_prints_each_kernel_against_the_floor(capsys):
    bench.main(["--skin", "6", "--frames", "2", "--sizes", "8", "--no-pinv"])
    out = capsys.readouterr().out
    assert out.startswith("machine: ")
    lines = [line for line in out.splitlines() if "solve median wall (CPU) ms" in line]
    assert [line.split()[1] for line in lines] == ["layer", "cell", "point"]
    for line in lines:
        for path in ("auto", "auto cold", "auto in playback", "given parameters", "slider move",
                     "normal only", "dense-product floor"):
            assert re.search(rf"{path} [0-9.]+ \([0-9.]+\)", line), (path, line)
        assert re.search(r"auto / floor [0-9.]+x$", line)
    assert re.search(r"^8x8 set-up: Reconstructor [0-9.]+ s \(cell kernel [0-9.]+ s\)$", out, re.M)


@pytest.mark.parametrize("arguments, message", [
    (["--skin", "3"], r"--skin must be at least 4 and --frames at least 1, got 3 and 40"),
    (["--frames", "0"], r"--skin must be at least 4 and --frames at least 1, got 16 and 0"),
    (["--sizes", "32", "0"], r"--sizes must be at least 1 each, got 32 0"),
])
def test_the_command_refuses_a_skin_or_frame_count_it_cannot_time(arguments, message, capsys):
    with pytest.raises(SystemExit):
        bench.main(arguments)
    assert re.search(message, capsys.readouterr().err)


def test_fastest_in_rounds_calls_every_item_once_per_round_and_keeps_the_first_results():
    calls, prepared = [], []
    wall, cpu, results = bench.fastest_in_rounds(lambda item: calls.append(item) or item * 10, ["a", "b", "c"], 3,
                                           before=prepared.append)
    # rounds over all the items: no call follows one on the same item
    assert calls == ["a", "b", "c"] * 3
    assert prepared == calls
    assert results == ["a" * 10, "b" * 10, "c" * 10]
    assert wall.shape == cpu.shape == (3,)
    assert np.all(wall >= 0) and np.all(np.isfinite(wall)) and np.all(cpu >= 0)

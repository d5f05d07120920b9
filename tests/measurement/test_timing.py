"""How a timing is taken: the machine line and timed calls in rounds."""

import numpy as np

from measurement import timing


def test_the_machine_is_one_line():
    line = timing.machine()
    assert "\n" not in line and "cores, numpy" in line


def test_fastest_in_rounds_calls_every_item_once_per_round_and_keeps_the_first_results():
    calls, prepared = [], []
    wall, cpu, results = timing.fastest_in_rounds(lambda item: calls.append(item) or item * 10, ["a", "b", "c"], 3,
                                            before=prepared.append)
    # rounds over all the items: no call follows one on the same item
    assert calls == ["a", "b", "c"] * 3
    assert prepared == calls
    assert results == ["a" * 10, "b" * 10, "c" * 10]
    assert wall.shape == cpu.shape == (3,)
    assert np.all(wall >= 0) and np.all(np.isfinite(wall)) and np.all(cpu >= 0)


def test_timed_in_rounds_keeps_every_timing_round_by_round():
    calls = []
    wall, cpu, results = timing.timed_in_rounds(lambda item: calls.append(item) or -item, [1, 2], 3)
    assert calls == [1, 2] * 3 and results == [-1, -2]
    assert wall.shape == cpu.shape == (3, 2)
    assert np.all(np.isfinite(wall)) and np.all(wall >= 0) and np.all(cpu >= 0)

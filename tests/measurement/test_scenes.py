"""Tests of measurement/scenes.py: scenes of several contacts, each contact scored on its own."""

import math

import numpy as np
import pytest

from measurement.bounds import contact_bounds
from measurement.scenes import (
    KINDS,
    STANDARD_KINDS,
    TUNING_SEED,
    VALIDATION_SEED,
    decision_curve,
    evaluate,
    format_decision_curve,
    format_scenes,
    format_summary,
    main,
    scene_cases,
    summarize,
)


@pytest.fixture(scope="module")
def pinches():
    # noise-free pinches of the validation set at h/p 1 (nothing was tuned on seed 41)
    return scene_cases(seed=VALIDATION_SEED, noise=0.0, kinds=("pinch",), thickness_ratios=(1.0,))


def test_scenes_are_what_they_say(pinches):
    assert TUNING_SEED != VALIDATION_SEED
    scenes = scene_cases(seed=TUNING_SEED, repeats=1, thickness_ratios=(0.5,))
    assert [s.kind for s in scenes] == list(STANDARD_KINDS) == list(KINDS[:4])
    beside = scene_cases(seed=TUNING_SEED, repeats=4, thickness_ratios=(1.0,), kinds=("beside",))
    for scene in beside:
        # a cone, and a broader, lighter load beside it
        sharp, broad = scene.frame.contacts
        assert sharp.shape == "cone" and broad.shape in ("flat_punch", "hertz")
        assert broad.semi_axes[0] >= 2.0 * scene.frame.grid.pitch and broad.force < sharp.force
    scenes += beside
    for scene in scenes + pinches:
        frame = scene.frame
        # each contact's own truth sums to the frame's, and contacts keep at least a pitch apart
        np.testing.assert_allclose(sum(scene.truths), frame.forces, rtol=0, atol=1e-12)
        assert scene.gap >= 0.99 and len(scene.truths) == len(frame.contacts) == (3 if scene.kind == "three" else 2)
    for scene in pinches:
        a, b = scene.frame.contacts
        towards = np.subtract(b.center, a.center)
        # each shears at 0.3 towards the other
        assert a.shear_ratio == b.shear_ratio == 0.3
        assert math.cos(a.shear_direction - math.atan2(towards[1], towards[0])) == pytest.approx(1.0)
        assert math.cos(b.shear_direction - math.atan2(-towards[1], -towards[0])) == pytest.approx(1.0)


def test_a_pinch_comes_out_as_two_contacts_with_opposite_shears(pinches):
    rows = evaluate(pinches, bounds=False)
    assert len(rows) == 2 * len(pinches) == 6
    for row in rows:
        # noise-free, measured 0.4% and under 1 deg at most; before the contacts were kept
        # apart, the merged pair's opposite shears cancelled (no shear on 2 of 18 noise-free)
        assert row["contacts_found"] == 2 and row["ratio"] > 0.2, row
        assert row["tangential_total"] <= 0.02 and row["direction_deg"] <= 3.0, row
    summary = summarize(rows)
    assert summary["pinch_zero"] == 0 and summary["pinches"] == 6 and summary["missed"] == 0
    text = format_scenes(rows) + "\n" + format_summary(summary)
    assert "pinch h/p=1" in text and "pinches: tangential" in text


def test_counts_and_the_bound_beside_them():
    rows = [dict(kind="two", true_ratio=0.0, ratio=0.05, tangential_total=0.1, direction_deg=math.nan,
                 normal_total=0.01, bound_miss=math.nan, bound_tangential=0.04, bound_direction=math.nan,
                 cpu_ms=1.0),
            dict(kind="pinch", true_ratio=0.3, ratio=0.0, tangential_total=0.2, direction_deg=180.0,
                 normal_total=0.02, bound_miss=0.25, bound_tangential=0.06, bound_direction=9.0,
                 cpu_ms=2.0),
            dict(kind="pinch", true_ratio=0.3, ratio=0.3, tangential_total=0.0, direction_deg=1.0,
                 normal_total=0.0, bound_miss=0.5, bound_tangential=0.08, bound_direction=7.0,
                 cpu_ms=3.0)]
    s = summarize(rows)
    assert (s["false"], s["free"], s["missed"], s["sheared"]) == (1, 1, 1, 2)
    assert s["bound_missed"] == pytest.approx(0.75) and s["pinch_zero"] == 1 and s["pinches"] == 2
    assert s["tangential"] == pytest.approx(0.1) and s["direction"] == pytest.approx(90.5)
    # the bound's medians: tangential over every contact, direction over the sheared ones
    assert s["bound_tangential"] == pytest.approx(0.06) and s["bound_direction"] == pytest.approx(8.0)


def test_the_decision_curve_counts_what_a_solver_with_each_shrinkage_decides():
    # two-contact scenes of the tuning set at h/p 1, 1% noise
    scenes = scene_cases(seed=TUNING_SEED, kinds=("two",), repeats=3, thickness_ratios=(1.0,))
    low, high = decision_curve(scenes, shrinkages=(0.5, 8.0))
    assert [row["shrinkage"] for row in (low, high)] == [0.5, 8.0]
    from solver import Reconstructor
    from solver.efficiency import ContactFit

    rows = evaluate(scenes, lambda grid: Reconstructor(grid, efficiency=ContactFit(shrinkage=8.0)), bounds=False)
    free = [r for r in rows if r["true_ratio"] == 0]
    sheared = [r for r in rows if r["true_ratio"] >= 0.2]
    assert (high["false"], high["free"]) == (sum(r["ratio"] > 0 for r in free), len(free))
    assert (high["missed"], high["sheared"]) == (sum(r["ratio"] == 0 for r in sheared), len(sheared))
    assert high["free_evidence"] == pytest.approx(np.median([r["evidence"] for r in free]))
    # a larger shrinkage gives shear less often: fewer false, more missed, and the bound at its lower
    # false rate misses more
    assert low["false"] >= high["false"] and low["missed"] <= high["missed"] and low["missed"] < high["missed"]
    assert 0 <= low["bound_missed"] <= high["bound_missed"] <= high["sheared"]
    # the bound's count is the Wald test's at the false rate reached (half a contact from 0 and 1)
    rate = min(max(high["false"], 0.5), high["free"] - 0.5) / high["free"]
    bounds = [b for scene in scenes
              for b in contact_bounds(scene.frame, totals=[t[:, 2].sum() for t in scene.truths])]
    expected = sum(b.miss(false_rate=rate) for r, b in zip(rows, bounds, strict=True) if r["true_ratio"] >= 0.2)
    assert high["bound_missed"] == pytest.approx(expected)
    table = format_decision_curve([low, high]).splitlines()
    assert len(table) == 3 and "Wald test at the bound" in table[0]
    assert f"{high['false']} of {high['free']}" in table[2]
    with pytest.raises(ValueError, match="scenes must hold at least one scene, got none"):
        decision_curve([])
    with pytest.raises(ValueError, match="scenes must have noise > 0"):
        decision_curve(scene_cases(seed=TUNING_SEED, noise=0.0, kinds=("two",), repeats=1,
                                   thickness_ratios=(1.0,)))
    with pytest.raises(ValueError, match="shrinkages must be > 0, got 0"):
        decision_curve(scenes, shrinkages=(0,))
    with pytest.raises(ValueError, match="shrinkages must hold at least one shrinkage, got none"):
        decision_curve(scenes, shrinkages=())


def test_the_command_prints_the_decision_curve(capsys, monkeypatch):
    import measurement.scenes as scenes

    seen = {}

    def curve(scenes_given, **options):
        seen["count"] = len(scenes_given)
        return [dict(shrinkage=2.0, false=3, free=20, missed=5, sheared=60, bound_missed=4.5, free_evidence=0.8)]

    monkeypatch.setattr(scenes, "decision_curve", curve)
    main(["--decision-curve", "--seeds", "5", "6", "--kinds", "two", "--repeats", "1"])
    out = capsys.readouterr().out
    # two seeds, one scene per thickness (three) each
    assert seen["count"] == 6
    assert "seeds 5 6: 6 scenes" in out and "3 of 20" in out and "4.5" in out
    with pytest.raises(SystemExit):
        main(["--decision-curve", "--noise", "0"])
    assert "--decision-curve needs --noise > 0" in capsys.readouterr().err


def test_bad_arguments_are_refused(capsys):
    with pytest.raises(ValueError, match="kinds must be one of .* got 'palm'"):
        scene_cases(kinds=("palm",))
    with pytest.raises(ValueError, match="noise must be finite and >= 0, got -0.1"):
        scene_cases(noise=-0.1)
    with pytest.raises(SystemExit):
        main(["--kinds", "palm"])
    assert "invalid choice: 'palm'" in capsys.readouterr().err

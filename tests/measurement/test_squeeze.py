"""Tests of measurement/squeeze.py: one contact squeezed or stretched, what the solver and the data say."""

import math

import numpy as np
import pytest

from measurement.squeeze import (
    SHAPES,
    SQUEEZES,
    evaluate,
    format_cases,
    format_summary,
    main,
    squeeze_cases,
    summarize,
)


@pytest.fixture(scope="module")
def noise_free():
    # one frame of each shape and squeeze at h/p 1, noise-free
    return squeeze_cases(noise=0.0, repeats=1, thickness_ratios=(1.0,))


def test_cases_are_what_they_say(noise_free):
    assert [(c.shape, c.squeeze) for c in noise_free] == [(s, q) for s in SHAPES for q in SQUEEZES]
    for case in noise_free:
        (load,) = case.frame.contacts
        assert load.squeeze == case.squeeze and load.squeeze_direction == case.axis and load.shear_ratio == 0
        axes = load.semi_axes
        assert (axes[0] == axes[1]) == (case.shape == "round")
        if case.shape != "round":  # 2:1, the long semi-axis along the squeeze's axis or across it
            assert axes[0] == pytest.approx(2 * axes[1])
            across = abs(math.cos(load.angle - case.axis)) < 1e-9
            assert across == (case.shape == "wide")
        # a squeeze (or stretch) has no net tangential force, to the sub-cell lattice's rounding of
        # its halves (a uniform ellipse's sharp rim: 0.6% of one half's)
        np.testing.assert_allclose(case.frame.forces[:, :2].sum(0), 0, atol=0.01 * abs(case.squeeze) * load.force)


def test_a_long_contact_squeezed_along_its_length_is_two_halves_and_a_plain_one_is_one(noise_free):
    rows = evaluate(noise_free)
    by = {(r["shape"], r["squeeze"]): r for r in rows}
    squeezed = by[("long", 0.3)]
    assert squeezed["found"] == 2 and squeezed["halves"] and math.isnan(squeezed["statistic"])
    for shape in SHAPES:
        plain = by[(shape, 0.0)]
        assert plain["found"] == 1 and not plain["halves"] and plain["statistic"] < plain["kept_at"]
    # a round contact is never tried halved, yet halved on the true axis the data show the squeeze
    round_squeezed = by[("round", 0.3)]
    assert round_squeezed["found"] == 1 and round_squeezed["statistic"] >= round_squeezed["kept_at"]
    summary = summarize(rows)
    assert summary["long"]["halves"] >= 1 and summary["long"]["squeezed"] == 2
    assert all(s["split_plain"] == 0 and s["plain"] == 1 for s in summary.values())
    assert "long: squeezed or stretched 2" in format_summary(summary)
    assert format_cases(rows).splitlines()[0].startswith("case")


def test_cases_refuse_bad_noise():
    with pytest.raises(ValueError, match="noise must be finite and >= 0, got nan"):
        squeeze_cases(noise=math.nan)


def test_main_prints_the_summary(capsys, monkeypatch):
    import measurement.squeeze as squeeze

    monkeypatch.setattr(squeeze, "squeeze_cases", lambda **kw: squeeze_cases(
        noise=kw["noise"], seed=kw["seed"], repeats=1, thickness_ratios=(1.0,)))
    main(["--noise", "0", "--quiet"])
    out = capsys.readouterr().out
    assert out.startswith("seed 61, noise 0\n") and "round: squeezed or stretched 2" in out

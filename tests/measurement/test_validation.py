"""Accuracy on finely integrated loads (never the inversion kernel itself): measurement/validation.py
scoring the solver on the sets of measurement/cases.py (their coverage: test_cases.py)."""

import math
import re

import numpy as np
import pytest

from measurement.cases import LOAD_VALIDATION_SEEDS, layer_cases, standard_cases
from measurement.validation import (
    counts,
    decision_curve,
    evaluate,
    format_cases,
    format_decision_curve,
    format_load_decision,
    format_mismatch,
    load_decision,
    mismatch,
    summarize,
)
from solver import Reconstructor, SensorGrid, loads
from solver.efficiency import ContactFit

# standard_set (the standard set on half-space data), layer_noisy (the physics set, 1% noise) and
# validation_set (the validation set by noise) are session fixtures of conftest.py


@pytest.mark.parametrize("kernel, normal_bar", [("cell", 0.03), ("point", 0.08)])
# half-space kernels on half-space data; the fit's constants were tuned for the layer kernel
def test_medians_over_the_standard_set_meet_the_bar(standard_set, kernel, normal_bar, capsys):
    rows = evaluate(standard_set, lambda grid: Reconstructor(grid, kernel=kernel))
    with capsys.disabled():
        print(f"\n{kernel} kernel, automatic parameters, 1% noise\n{format_cases(rows)}")
    s = summarize(rows)
    # measured: cell 0.66%, 10.4%, 15.9 deg; point 5.0%, 7.0%, 10.8 deg
    assert s["normal_total"] <= normal_bar
    assert s["tangential_total"] <= 0.12
    assert s["direction_deg"] <= 20.0
    assert s["false_shear"] == 0.0


def test_the_fit_keeps_the_normal_total_of_the_exact_solution(standard_set):
    # the automatic answer is the compressive fit, not C^-1 b: its normal total stays
    # within the noise of the exact one (measured 2.4% against 0.84%, layer kernel on
    # half-space data, where the kernel's physics is wrong)
    auto = summarize(evaluate(standard_set, lambda grid: Reconstructor(grid)))
    exact = summarize(evaluate(standard_set, lambda grid: Reconstructor(grid),
                               solve=lambda r, b: r.solve(b, shear_ratio=0.0, shear_direction=0.0)))
    assert auto["normal_total"] < 0.03 and exact["normal_total"] < 0.03


def test_cell_kernel_keeps_the_normal_total_at_thin_layers(standard_set):
    thin = [c for c in standard_set if c.thickness_ratio == 0.5]
    point = summarize(evaluate(thin, lambda g: Reconstructor(g, kernel="point")))
    cell = summarize(evaluate(thin, lambda g: Reconstructor(g, kernel="cell")))
    assert cell["normal_total"] < 0.03 < point["normal_total"]


# -- the bonded layer: the inverse crime avoided ---------------------------------------------------
# Layer data come from the transfer functions by FFT convolution of the finely sampled
# load (solver.loads), the layer kernel from Hankel tables and edge integrals
# (solver.kernels): two paths. The set (measurement.cases.layer_cases) has its own seed
# and h/pitch 2: nothing was tuned on it.


@pytest.fixture(scope="module")
def layer_clean():
    return layer_cases(noise=0.0)


@pytest.fixture(scope="module")
def half_space_noisy():
    return layer_cases(noise=0.01, medium="halfspace")


def test_layer_kernel_on_layer_data_meets_the_bar(layer_noisy, capsys):
    rows = evaluate(layer_noisy, lambda grid: Reconstructor(grid, kernel="layer"))
    with capsys.disabled():
        print(f"\nlayer kernel on layer data (nu 0.5), 1% noise\n{format_cases(rows)}")
    s = summarize(rows)
    # measured 0.64%, 3.2%, 8.4 deg (uniform sub-cells: 0.61%, 3.7%, 8.2 deg)
    assert s["normal_total"] <= 0.02
    assert s["tangential_total"] <= 0.09
    assert s["direction_deg"] <= 10.0


def test_layer_kernel_on_clean_layer_data_finds_the_shear(layer_clean):
    s = summarize(evaluate(layer_clean, lambda grid: Reconstructor(grid, kernel="layer")))
    # measured 0.05%, 0.10%, 0.06 deg (uniform sub-cells: 0.04%, 0.08%, 0.06 deg)
    assert s["tangential_total"] <= 0.005
    assert s["direction_deg"] <= 1.0


@pytest.mark.slow
def test_half_space_kernels_miss_the_shear_of_a_real_skin(capsys):
    rows = mismatch(noise=0.01)
    with capsys.disabled():
        print(f"\nkernels against data media, 1% noise\n{format_mismatch(rows)}")
    table = {(r["medium"], r["kernel"]): r for r in rows}
    for medium in ("layer nu=0.45", "layer nu=0.5"):
        layer, cell = table[medium, "layer"], table[medium, "cell"]
        # measured 3.2-3.6% against 14.4-15.9%: the half-space physics is the error
        assert 3 * layer["tangential_total"] < cell["tangential_total"]
        # equilibrium keeps the normal totals of both
        assert cell["normal_total"] < 0.03 and layer["normal_total"] < 0.03
    # conditions reported per thickness, growing with it
    conditions = list(table["layer nu=0.5", "layer"]["condition"].values())
    assert conditions == sorted(conditions) and conditions[0] >= 1


# -- tuned on one set, judged on another (measurement.cases.tuning_cases / validation_cases) ------


@pytest.fixture(scope="module")
def validation_solvers():
    made = {}

    def make(grid):
        if grid.thickness not in made:  # one solver per thickness, shared by the noise levels
            made[grid.thickness] = Reconstructor(grid)
        return made[grid.thickness]
    return make


@pytest.mark.parametrize("noise, tangential_bar, direction_bar", [(0.01, 0.09, 10.0), (0.003, 0.03, 5.0),
                                                                 (0.0, 0.005, 1.0)])
def test_accuracy_on_the_validation_set(validation_solvers, validation_set, noise, tangential_bar, direction_bar,
                                       capsys):
    # ContactFit's shrinkage and model_error were chosen on tuning_cases (seed 7, h/p 0.5, 1,
    # 1.5); this set has seed 31, h/p 0.6, 1.0, 1.4, other sizes and positions.
    cases = validation_set(noise)
    rows = evaluate(cases, validation_solvers)
    decided = counts(rows)
    with capsys.disabled():
        print(f"\nvalidation set, layer kernel and data, noise {noise:g}\n{format_cases(rows)}\n"
              f"shear reported on {decided['false']} of {decided['free']} shear-free loads, "
              f"missed on {decided['missed']} of {decided['sheared']} with shear ratio >= 0.2")
    s = summarize(rows)
    # measured: 1%: 0.69%, 3.3%, 4.9 deg; 0.3%: 0.16%, 1.2%, 2.1 deg; clean 0.11%, 0.1%, 0.2 deg
    assert s["normal_total"] <= 0.02
    assert s["tangential_total"] <= tangential_bar
    assert s["direction_deg"] <= direction_bar
    # measured false 1, 1, 0 of 12; missed 2 (1%: a Hertz at h/p 0.6 and a cone at 1.0, where the
    # signature of a 0.2 shear is within the noise), 0, 0 of 24
    assert decided["free"] == 12 and decided["false"] <= 2
    assert decided["missed"] <= (2 if noise == 0.01 else 0)


@pytest.mark.slow
def test_the_load_decision_tells_load_from_noise_on_its_validation_seeds(capsys):
    # min_load_evidence was chosen on LOAD_TUNING_SEEDS; these frames come from other seeds
    summary = load_decision(LOAD_VALIDATION_SEEDS)
    with capsys.disabled():
        print(f"\nload decision, validation seeds {LOAD_VALIDATION_SEEDS}\n{format_load_decision(summary)}")
    # measured: noise alone 0 of 30 report a contact; at 1% one contact in 30 of 30, total error
    # median 0.3%, worst 1.1%; at 10% noise one contact in 30 of 30; at 20% in 27 of 30 and none in
    # 3: on the 32x32 skin at h/p 1 the noise's contacts join the load into one broader than the
    # fit's budget (Reconstructor.fit_budget), whose normal-only answer does not stand out of
    # that noise (30 of 30 with the budget off). The third (2026-11-28) sat at 319 of the budget's
    # 320 nodes reading 2.19 N for 1 N; the holes that hold load in a contact's region now join it
    # (search._fill_holes) and take it past the budget. The median total error at 20% fell from
    # 23.1% to 16.1% with that change.
    assert summary["noise"]["none"] == summary["noise"]["frames"] == 30
    assert summary["1%"]["one"] == 30 and summary["1%"]["worst"] <= 0.02
    assert summary["snr10"]["none"] == 0 and summary["snr10"]["one"] >= 28
    assert summary["snr5"]["none"] <= 3 and summary["snr5"]["one"] >= 27


def test_the_decision_curve_counts_what_solvers_with_each_shrinkage_decide():
    # one solve per case scores every shrinkage c (shear kept exactly when F > c): the counts must
    # be those of solvers built with that shrinkage
    cases = standard_cases(seed=100)
    curve = decision_curve([cases], shrinkages=(1.0, 3.0))
    for row in curve:
        c = row["shrinkage"]
        rows = evaluate(cases, lambda grid, c=c: Reconstructor(grid, efficiency=ContactFit(shrinkage=c)))
        decided = counts(rows)
        assert (row["false_mean"], row["missed_mean"]) == (decided["false"], decided["missed"]), c
        assert row["false_max"] == decided["false"] and row["missed_max"] == decided["missed"]
        missed = [r for r in rows if r["true_ratio"] == 0.2 and r["thickness_ratio"] == 0.5]
        assert row["missed_by_thickness"][0.5] == sum(r["ratio"] == 0 for r in missed) / len(missed)
    # measured on this draw: c = 1 gives shear to more shear-free loads than c = 3, and misses fewer
    assert curve[0]["false_mean"] > curve[1]["false_mean"] and curve[0]["missed_mean"] < curve[1]["missed_mean"]
    table = format_decision_curve(curve).splitlines()
    assert len(table) == 3 and table[0].split()[:2] == ["c", "false"] and table[1].split()[0] == "1"
    with pytest.raises(ValueError, match="draws must hold at least one draw, got none"):
        decision_curve([])


@pytest.mark.parametrize("direction", [0.0, math.pi / 2, math.pi], ids=["inward", "along", "outward"])
def test_contacts_on_the_edge_do_not_over_read_their_shear(direction):
    # Hertz centred on the border column of a 16x16 skin (h = pitch): half its stress field is
    # off the skin. Measured (docs/efficiency.md): clean ratio 0.92-1.00 of the truth,
    # direction within 0.7 deg; at 1% noise median ratio 0.00 (inward), 0.74 (along), 1.16
    # (outward): the relief half of an inward shear's signature is not sensed, so the soft
    # decision drops it; it no longer reads high (1.3-1.7 times before the per-contact fit).
    pitch = 2e-3
    grid = SensorGrid.regular(16, 16, pitch, pitch)
    solver = Reconstructor(grid)
    edge = grid.positions[:, 0].min()
    contact = loads.hertz((edge, 0.3 * pitch), 2.5 * pitch, 1.0, shear_ratio=0.3, shear_direction=direction)
    clean = solver.solve(loads.simulate(grid, contact).stress).contacts
    assert len(clean) == 1 and clean[0].at_edge
    assert clean[0].shear_ratio == pytest.approx(0.3, rel=0.1)
    assert abs(math.remainder(clean[0].shear_direction - direction, 2 * math.pi)) < math.radians(3)
    ratios = []
    for seed in range(100, 106):  # fixed seeds: the same noise every run
        found = solver.solve(loads.simulate(grid, contact, noise=0.01, rng=seed).stress).contacts
        assert found[0].at_edge
        ratios.append(found[0].shear_ratio / 0.3)
    assert np.median(ratios) <= 1.25


# -- the command line: python -m measurement.validation ---------------------------------------------


def test_the_command_prints_the_medians_per_thickness(capsys):
    from measurement.validation import main

    tangential = {}
    for profile in ("bilinear", "uniform"):
        main(["--functional", "contact_fit", "--by-thickness", "--noise", "0", "--profile", profile])
        lines = capsys.readouterr().out.splitlines()
        assert len(lines) == 6 and lines[0].endswith(f"kernel layer, {profile} sub-cells")
        assert lines[2].startswith("contact_fit")
        # 12 cases per thickness: 4 shear-free, 8 sheared
        for line, ratio in zip(lines[3:], ("0.6", "1", "1.4"), strict=True):
            assert re.fullmatch(rf"  h/p {ratio} +\d+\.\d\d% +\d+\.\d% +\d+\.\dd +\d+/4 +\d+/8 +\d+\.\d\d", line)
        tangential[profile] = [float(line.split()[3].rstrip("%")) for line in lines[3:]]
    # measured noise-free tangential: bilinear 0.3%, 0.1%, 0.1%; uniform 0.7%, 0.1%, 0.1%. The thin
    # layer errs most, and least with hats: a uniform sub-cell's staircase reads as shear there.
    assert tangential["bilinear"][0] > tangential["bilinear"][2]
    assert tangential["bilinear"][0] < tangential["uniform"][0]


def test_the_command_prints_the_summary_and_the_cases(capsys):
    from measurement.validation import main

    main(["--functional", "contact_fit", "--cases"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "validation set: 36 cases, 16x16, layer data, noise 0.01, kernel layer, bilinear sub-cells"
    assert lines[1].split() == ["functional", "normal", "tangential", "direction", "false", "shear", "missed", "ms"]
    assert lines[2].split()[:2] == ["case", "mu"] and lines[39].startswith("median")
    assert len(lines) == 41
    # the summary line: the medians, then the counts of 12 shear-free and 24 sheared loads
    assert re.fullmatch(r"contact_fit +\d+\.\d\d% +\d+\.\d% +\d+\.\dd +\d+/12 +\d+/24 +\d+\.\d\d", lines[40])


def test_the_command_prints_the_decision_curve_beside_the_ideal_tests_bound(capsys, monkeypatch):
    from measurement import validation

    monkeypatch.setattr(validation, "DECISION_SEEDS", (100,))  # one draw: the layout, not the figures
    validation.main(["--decision-curve"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("shear decision, seeds 100-100: 16x16")
    assert len(lines) == 2 + 8 + 2 + 4
    assert lines[11].startswith("the Wald test at the Cramer-Rao bound on the same loads")
    assert lines[12].split()[:6] == ["false", "of", "12", "missed", "of", "24"]
    # the Wald test at 1, 2 and 4 false of 12: fewer missed as it allows more false
    missed = [float(line.split()[1]) for line in lines[13:]]
    assert [line.split()[0] for line in lines[13:]] == ["1.0", "2.0", "4.0"]
    assert missed[0] > missed[1] > missed[2]


def test_the_command_prints_the_sheared_loads_medians_beside_the_bounds(validation_set, capsys):
    from measurement.bounds import shear_bounds
    from measurement.validation import against_bound, main

    main(["--functional", "contact_fit", "--against-bound", "--noise", "0.003"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[3].startswith("  loads with shear ratio >= 0.2, medians: contact_fit against an unbiased")
    assert lines[4].split() == ["h/p", "loads", "tangential", "bound", "direction", "bound"]
    assert len(lines) == 8
    for line, ratio in zip(lines[5:], ("0.6", "1", "1.4"), strict=True):
        assert re.fullmatch(rf" +{ratio} +8 +\d+\.\d% +\d+\.\d% +\d+\.\dd +\d+\.\dd", line)
    # the medians are of each thickness's sheared loads, the measured ones from the scored rows
    cases = [c for c in validation_set(0.003) if c.thickness_ratio == 1.4]
    rows = evaluate(cases, lambda g: Reconstructor(g))
    table, = against_bound(cases, rows, shear_bounds([c.frame for c in cases]))
    sheared = [r for r in rows if r["true_ratio"] >= 0.2]
    assert table["loads"] == 8
    assert table["tangential"] == np.median([r["tangential_total"] for r in sheared])
    assert table["direction"] == np.median([r["direction_deg"] for r in sheared])
    assert 0 < table["bound_tangential"] < 0.05 and 0 < table["bound_direction"] < 5
    with pytest.raises(ValueError, match="rows and bounds must cover every case, got 11 rows and 12 bounds "
                                         "for 12 cases"):
        against_bound(cases, rows[:-1], shear_bounds([c.frame for c in cases]))


@pytest.mark.parametrize("mode", ["--decision-curve", "--load-decision", "--mismatch"])
def test_the_command_rejects_a_profile_where_it_would_not_apply(mode, capsys):
    from measurement.validation import main

    with pytest.raises(SystemExit):
        main([mode, "--profile", "uniform"])
    assert "--profile applies to the validation and tuning sets, not to --decision-curve" in capsys.readouterr().err

"""Spec 004 §6 E1 ``skytrack study ab-range`` (P1; R3 tracker, §3.3 C closed forms, R21 seeding, R23 outputs, R24 options)."""

import json
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.filters import alpha_beta_gains as gains
from skytrack.studies.maneuver import ab_range
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from study_cli import claims_of, invoke_study, study_outputs

ALPHAS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
RULES = ["benedict-bordner", "kalata"]
G0 = 9.80665
RUNS = 50  # the spec's minimum for asserts


def study(*args):
    return invoke_study("ab-range", *args)


def small_config(tmp_path, name="small.yaml", **study_params):
    """A reduced grid so that option tests stay fast."""
    params = {"alphas": [0.1, 0.4, 0.9], "load_factors": [0, 6], "gain_rules": ["benedict-bordner"], **study_params}
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"study": params}))
    return path


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    """Default parameters at the minimum run count of the asserts, with --check."""
    return study_outputs(tmp_path_factory, "ab-range", "--runs", str(RUNS), "--check")


def test_truth_is_the_exact_piecewise_polynomial():
    sc = ab_range.RangeScenario.from_params(ab_range.PARAMS)
    assert sc.scans == 300 and sc.end_scan == 150
    A = 4 * G0
    rng, rate = sc.truth([0.0, A])
    t = sc.time
    assert np.allclose(rng[0], 30000 - 600 * t, rtol=0, atol=1e-9)
    assert np.allclose(rate[0], -600)
    k10, k15 = 100, 150
    assert rng[1, k10] == pytest.approx(30000 - 6000) and rate[1, k10] == pytest.approx(-600)
    assert rng[1, k15] == pytest.approx(30000 - 9000 + A * 12.5) and rate[1, k15] == pytest.approx(-600 + 5 * A)
    assert rng[1, -1] == pytest.approx(30000 - 18000 + A * 12.5 + 5 * A * 15)
    assert rate[1, -1] == pytest.approx(-600 + 5 * A)
    # the rate is the derivative of the range (central differences exact for a quadratic, away from the joints)
    inside = slice(k10 + 1, k15)
    assert np.allclose((rng[1, 2:] - rng[1, :-2])[inside.start - 1:inside.stop - 1] / (2 * sc.period), rate[1, inside], atol=1e-7)


def test_errors_of_a_run_come_from_its_own_generator():
    """R21: run r's errors are those of default_rng(SeedSequence(seed).spawn(runs)[r]), scenario first."""
    scen3, noise3 = ab_range.draw_errors(7, 3, 300, 2, 50)
    scen5, noise5 = ab_range.draw_errors(7, 5, 300, 2, 50)
    rng = np.random.default_rng(np.random.SeedSequence(7).spawn(5)[1])
    assert np.array_equal(scen5[1], rng.standard_normal(300))
    assert np.array_equal(noise5[1], rng.standard_normal((2, 50)))
    assert np.array_equal(scen3, scen5[:3]) and np.array_equal(noise3, noise5[:3])


def test_asserts_hold_at_fifty_runs(full):
    payload, claims = claims_of(full)
    assert payload["study"] == "ab-range" and payload["options"]["runs"] == RUNS and payload["asserts_passed"] is True
    noise = claims["E1-noise-variance"]
    assert noise["kind"] == "assert" and noise["verdict"] is True
    ratios = noise["measured"]["ratio"]
    assert set(ratios) == set(RULES) and all(len(v) == len(ALPHAS) for v in ratios.values())
    assert 0 < noise["measured"]["max_abs_deviation"] <= 0.05
    assert noise["measured"]["scans_per_run"] == 16 * 400
    lag = claims["E1-lag"]
    assert lag["verdict"] is True and lag["measured"]["n"] == [1, 2, 3, 4, 5, 6, 7, 8] and lag["measured"]["scans"] == 400
    # 400 scans of a contraction with modulus sqrt(1 - alpha) <= 0.95 leave the steady state far below 1 %
    assert lag["measured"]["worst"] < 1e-6
    shape = claims["E1-loss-u-shape"]
    assert shape["verdict"] is True
    cases = shape["measured"]["cases"]
    assert set(cases) == {f"{rule} n={n}" for rule in RULES for n in range(4, 9)}
    for case in cases.values():
        # alpha = 0.1 at n >= 4: the predicted lag A T^2/beta >= 74 m is more than twice the 3-sigma gate (31 m)
        assert case["loss_smallest_alpha"] >= 0.95
        assert case["loss_largest_alpha"] - case["min_loss"] >= 0.05 and case["min_loss"] <= 0.2
        assert 0.3 <= case["alpha_min_loss"] <= 0.6


def test_reports_best_alpha_and_manoeuvre_gains(full):
    _, claims = claims_of(full)
    best = claims["E1-best-alpha"]
    assert best["kind"] == "report" and best["verdict"] is None
    for rule in RULES:
        per_n = best["measured"][rule]
        assert set(per_n) == {f"n={n}" for n in range(9)}
        # noise only: the RMS grows with alpha (closed form 2.7 m at 0.1, 3.9 m at 0.2)
        assert per_n["n=0"]["alpha_min_rms"] == 0.1 and per_n["n=0"]["min_loss"] == 0.0
        assert per_n["n=8"]["alpha_min_rms"] >= 0.3 and per_n["n=8"]["alpha_min_loss"] >= 0.3
        assert per_n["n=8"]["alpha_min_loss"] in per_n["n=8"]["alphas_at_min_loss"]
    man = claims["E1-maneuver-gains"]
    assert man["kind"] == "report"
    bb = man["measured"]["benedict-bordner"]
    assert bb["alphas"] == ALPHAS
    # the detector rescues the smallest gain from the lag-driven loss ...
    assert bb["loss_fixed"]["n=8"][0] == 1.0 and bb["loss_maneuver"]["n=8"][0] < 1.0
    assert bb["loss_maneuver"]["n=4"][0] < bb["loss_fixed"]["n=4"][0] - 0.3
    # ... but its false alarms cost tracks without any manoeuvre at alpha >= 0.3
    assert sum(bb["loss_maneuver"]["n=0"][2:]) > sum(bb["loss_fixed"]["n=0"][2:])
    assert all(rate > 0 for rate in bb["detection_rate_maneuver"]["n=0"][2:])
    assert all(0 < f < 0.5 for f in bb["maneuver_scan_fraction"]["n=0"])
    assert bb["maneuver_scan_fraction"]["n=8"][0] > bb["maneuver_scan_fraction"]["n=0"][0]


def test_summary_rows_and_closed_forms(full):
    """summary.csv holds 10 significant digits: closed forms compared to 1e-8."""
    summary = pd.read_csv(full / SUMMARY_NAME)
    assert set(summary["part"]) == {"sweep", "noise-only", "lag"}
    sweep = summary[summary["part"] == "sweep"]
    assert len(sweep) == len(RULES) * 2 * len(ALPHAS) * 9 and set(sweep["gains"]) == {"fixed", "maneuver"}
    bb = sweep[sweep["rule"] == "benedict-bordner"]
    assert np.allclose(bb["beta"], bb["alpha"] ** 2 / (2 - bb["alpha"]), rtol=1e-8)
    kal = sweep[sweep["rule"] == "kalata"]
    assert np.allclose(kal["beta"], 2 * (2 - kal["alpha"]) - 4 * np.sqrt(1 - kal["alpha"]), rtol=1e-9)
    expected = (1 - sweep["alpha"]) * sweep["n"] * G0 * 0.01 / sweep["beta"]
    assert np.allclose(sweep["lag_filtered_closed_form_m"], expected, rtol=1e-8)
    assert np.allclose(sweep["runs_kept"], np.round(RUNS * (1 - sweep["loss_rate"])))
    # 5 s of acceleration reach the steady lag once (1 - alpha)^(k/2) has decayed (alpha >= 0.3: 0.84^50 ~ 2e-4)
    fixed = sweep[(sweep["gains"] == "fixed") & (sweep["alpha"] >= 0.3) & (sweep["n"] > 0)]
    assert np.allclose(fixed["noise_free_error_accel_end_m"], fixed["lag_filtered_closed_form_m"], rtol=1e-3)
    # the Monte Carlo mean error estimates the noise-free error (linear filter) within 5 standard errors
    ratio = gains.variance_ratios(fixed["alpha"].to_numpy(), fixed["beta"].to_numpy()).filtered_position
    se = 10.0 * np.sqrt(ratio / RUNS)
    assert np.all(np.abs(fixed["mean_error_accel_end_m"] - fixed["noise_free_error_accel_end_m"]) <= 5 * se)
    noise = summary[summary["part"] == "noise-only"]
    assert len(noise) == len(RULES) * len(ALPHAS)
    closed = 100.0 * gains.variance_ratios(noise["alpha"].to_numpy(), noise["beta"].to_numpy()).filtered_position
    assert np.allclose(noise["range_error_variance_closed_form_m2"], closed, rtol=1e-8)
    assert np.allclose(noise["variance_ratio"], noise["range_error_variance_m2"] / closed, rtol=1e-8)
    lag = summary[summary["part"] == "lag"]
    assert len(lag) == len(RULES) * len(ALPHAS) * 8 and (lag["lag_relative_error"] < 1e-6).all()
    # the gate half-width is g sqrt(S0) with S0 = sigma_v^2 (1 + predicted ratio)
    row = sweep.iloc[0]
    s0 = 100.0 * (1 + gains.variance_ratios(row["alpha"], row["beta"]).predicted_position)
    assert row["gate_halfwidth_m"] == pytest.approx(3 * math.sqrt(s0), rel=1e-8)


def test_timeseries_agree_with_the_summary(full):
    series = pd.read_parquet(full / TIMESERIES_NAME)
    assert set(series["series"]) == {"range_error"}
    assert set(series["quantity"]) == {"mean_error_m", "rms_error_m", "lost_fraction"}
    summary = pd.read_csv(full / SUMMARY_NAME)
    row = summary[(summary["part"] == "sweep") & (summary["rule"] == "benedict-bordner") & (summary["gains"] == "fixed")
                  & (summary["alpha"] == 0.3) & (summary["n"] == 8)].iloc[0]
    lost = series[(series["filter"] == "benedict-bordner alpha=0.30") & (series["case"] == "n=8")
                  & (series["quantity"] == "lost_fraction")]
    assert len(lost) == 300 and lost["t_rel"].iloc[0] == pytest.approx(-9.9)
    assert lost["value"].iloc[-1] == pytest.approx(row["loss_rate"]) and lost["value"].is_monotonic_increasing
    rms = series[(series["filter"] == "benedict-bordner alpha=0.30") & (series["case"] == "n=8")
                 & (series["quantity"] == "rms_error_m")]["value"].to_numpy()
    assert math.sqrt(np.mean(rms**2)) == pytest.approx(row["rms_range_m"], rel=1e-9)


def test_figures_draw_what_they_say(full):
    figures = {f["file"]: f for f in json.loads((full / FIGURES_NAME).read_text())}
    assert set(figures) == {"ab_range_noise.png", "ab_range_lag.png", "ab_range_loss.png", "ab_range_tradeoff.png"}
    for name, figure in figures.items():
        assert (full / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            if len(ax["labels"]) > 1:
                assert set(ax["labels"]) <= set(ax["legend"])
    noise = figures["ab_range_noise.png"]["axes"]
    assert [ax["ylabel"] for ax in noise] == ["RMS filtered range error [m]", "RMS range-rate error [m/s]"]
    assert noise[0]["labels"] == [f"{rule}: {kind}" for rule in RULES for kind in ("closed form", "measured")]
    lag = figures["ab_range_lag.png"]["axes"]
    assert [ax["title"] for ax in lag] == [f"{rule} gains" for rule in RULES]
    assert lag[0]["labels"] == [f"n = {n}" for n in range(1, 9)] + ["range gate g sqrt(S0) on the residual"]
    assert lag[0]["lines"] == 2 * 8 + 1  # closed form and noise-free dots per n, and the gate
    loss = figures["ab_range_loss.png"]["axes"]
    assert [ax["title"] for ax in loss] == ["benedict-bordner: fixed gains", "kalata: fixed gains",
                                            "benedict-bordner: maneuver_gains='kalata'", "kalata: maneuver_gains='kalata'"]
    assert all(ax["ylabel"] == "range acceleration n [g0]" for ax in loss)
    tradeoff = figures["ab_range_tradeoff.png"]["axes"]
    assert all(ax["labels"] == [f"n = {n}" for n in range(9)] for ax in tradeoff)


def test_same_seed_same_outputs(tmp_path):
    """R21: the same seed gives identical outputs; another seed other numbers."""
    config = small_config(tmp_path)
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "3"), (b, "3"), (c, "4")):
        result = study("--quick", "--runs", "4", "--seed", seed, "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()
    payload, claims = claims_of(a)
    assert payload["options"]["quick"] is True and payload["options"]["params"]["noise_segments"] == 4
    assert claims["E1-noise-variance"]["measured"]["scans_per_run"] == 4 * 400


def test_check_exits_non_zero_when_an_assert_fails(tmp_path):
    config = small_config(tmp_path, loss_margin=2.0)
    result = study("--runs", "3", "--config", str(config), "--out", str(tmp_path / "x"))
    assert result.exit_code == 0 and "E1-loss-u-shape" in result.output and "FAIL" in result.output
    result = study("--runs", "3", "--config", str(config), "--out", str(tmp_path / "y"), "--check")
    assert result.exit_code == 1
    payload, claims = claims_of(tmp_path / "y")
    assert payload["asserts_passed"] is False and claims["E1-loss-u-shape"]["verdict"] is False
    assert set(claims["E1-loss-u-shape"]["measured"]["cases"]) == {"benedict-bordner n=6"}


def test_an_assert_without_cases_fails_and_says_so(tmp_path):
    config = small_config(tmp_path, load_factors=[0, 2])
    result = study("--runs", "3", "--config", str(config), "--out", str(tmp_path / "x"), "--check")
    assert result.exit_code == 1
    _, claims = claims_of(tmp_path / "x")
    assert claims["E1-loss-u-shape"]["verdict"] is False and "no load factor n >= 4" in claims["E1-loss-u-shape"]["measured"]["note"]


@pytest.mark.parametrize("args, message", [
    (["--scenario", "default"], "--scenario does not apply to ab-range"),
    (["--filters", "kf-cv"], "--filters does not apply to ab-range"),
    (["--runs", "0"], "--runs must be a positive integer"),
])
def test_bad_options_name_themselves(tmp_path, args, message):
    result = study(*args, "--out", str(tmp_path))
    assert result.exit_code == 2 and message in result.output


@pytest.mark.parametrize("config, message", [
    ({"turn_g": [3]}, "key(s) ['turn_g'] do not apply to ab-range"),
    ({"study": {"alphas": [0.5, 1.2]}}, "study parameter alphas must be"),
    ({"study": {"gain_rules": ["benedict-bordner", "fading"]}}, "study parameter gain_rules must be"),
    ({"study": {"noise_warmup_scans": 500}}, "study parameter noise_warmup_scans"),
    ({"study": {"accel_start_s": 28.0}}, "accel_start_s + accel_duration_s must not exceed duration_s"),
    ({"study": {"alpha": 0.3}}, "unknown parameter(s) ['alpha']"),
])
def test_bad_config_names_the_parameter(tmp_path, config, message):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(config))
    result = study("--config", str(path), "--out", str(tmp_path))
    assert result.exit_code == 2 and message in result.output

"""Spec 004 §6 E2 ``skytrack study kf-gains`` end to end (R21 determinism, R23 outputs, R24 options, --check)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME, TIMING_NAME
from study_cli import claims_of, invoke_study, study_outputs

FILTERS = {"kf-cv", "kf-ca", "kf-singer", "kf-dwpa", "alpha-beta-gamma"}


def study(*args):
    return invoke_study("kf-gains", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "kf-gains", "--quick", "--runs", "100", "--check")


def test_claims_and_verdicts(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "kf-gains" and payload["options"]["runs"] == 100 and payload["asserts_passed"] is True
    assert {c["kind"] for c in claims.values()} == {"assert", "report"}
    identical = claims["E2a-gains-identical"]
    assert identical["verdict"] is True and max(identical["measured"]["max_abs_deviation"].values()) <= 1e-12
    converge = claims["E2a-gains-converge"]["measured"]
    assert set(converge) == {"kf-cv", "kf-ca", "kf-singer"}
    assert all(v["final_relative_deviation"] <= 1e-6 and v["converged_scan"] >= 2 for v in converge.values())
    spread = claims["E2a-polar-gain-spread"]
    assert spread["kind"] == "report" and spread["verdict"] is None
    assert all(0 < v["final_relative_sd"] < 0.1 for v in spread["measured"].values())  # data-dependent R: gains differ
    equal = claims["E2b-gains-equal"]["measured"]
    assert equal["vs_dare"] <= 1e-9 and equal["vs_kf_last_scan"] <= 1e-9
    # TV8 numbers: lambda = sigma_w T^2 / sigma_v = 10 / 50 lies between the table's 0.1 and 0.5 rows
    assert 0.604758751248 < equal["alpha_beta_gamma_x"][0] < 0.795373662666
    rms = claims["E2b-rms-equal"]["measured"]
    assert abs(rms["ratio_pos"] - 1) <= 0.02 and rms["converged_scan"] > 2
    turns = claims["E2c-kf-cv-turn-peak"]["measured"]["turns"]
    assert len(turns) == 3 and all(v["ratio"] >= 5 for v in turns.values())
    assert claims["E2c-kf-cv-turn-peak"]["verdict"] is True


def test_summary_timeseries_and_timing(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    assert set(summary["filter"]) == FILTERS and set(summary["basis"]) == {"all", "kept"}
    assert len(summary) == 3 * len(FILTERS) * 2  # cases x filters x bases (metrics from the gating-off run)
    for column in ("e_pre_pos", "e_peak_pos", "t_peak_pos", "settle_peak_pos", "settle_end_pos", "e_pre_vel", "nees_mean",
                   "nees_in_band", "loss_rate_off", "loss_rate_on", "madds_per_update", "containment"):
        assert column in summary.columns
    rows = summary[summary["basis"] == "all"]
    # TV19 band for 100 runs of the 6-dimensional position+velocity NEES
    assert np.allclose(rows["nees_band_low"], 5.340186, atol=1e-6) and np.allclose(rows["nees_band_high"], 6.697692, atol=1e-6)
    cv = rows[rows["filter"] == "kf-cv"]
    assert (cv["loss_rate_off"] == 1.0).all() and (cv["e_peak_pos"] / cv["e_pre_pos"] >= 5).all()
    assert (summary[(summary["filter"] == "kf-cv") & (summary["basis"] == "kept")]["runs_basis"] == 0).all()
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    assert list(series.columns) == ["series", "case", "filter", "basis", "onset", "t", "t_rel", "quantity", "value"]
    assert set(series["series"]) == {"aligned", "gain"}
    gains = series[(series["series"] == "gain") & (series["basis"] == "cartesian") & (series["filter"] == "kf-ca")]
    assert set(gains["quantity"]) == {"gain_x_pos", "gain_x_vel", "gain_x_acc"}
    timing = pd.read_csv(quick / TIMING_NAME)
    assert (timing["us_per_update"] > 0).all() and (timing["madds_per_update"] > 0).all()


def test_figures_draw_what_they_say(quick):
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"kf_gains_history.png", "kf_gains_abg.png", "kf_gains_turn_rms.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])  # distinct colours
            if len(ax["labels"]) > 1:
                assert set(ax["labels"]) <= set(ax["legend"])
    history = figures["kf_gains_history.png"]["axes"]
    assert [ax["title"] for ax in history] == ["kf-cv", "kf-ca", "kf-singer"] * 2
    assert all(ax["lines"] == 3 and ax["collections"] == 1 for ax in history)
    assert "polar radar, 5-95 %" in history[0]["legend"]
    turn = figures["kf_gains_turn_rms.png"]["axes"]
    assert [ax["labels"] for ax in turn] == [[f"kf-cv, default n={n}" for n in (3, 5, 7)]] * 2
    abg = figures["kf_gains_abg.png"]["axes"]
    assert abg[1]["legend"] == ["alpha-beta-gamma (Kalata DWPA)", "KF-DWPA", "KF gain converged (1e-6)"]


def test_same_seed_same_outputs(tmp_path):
    """R21: same seed, identical outputs (wall times live apart in timing.csv); another seed, other numbers."""
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "gating": ["off", "on"]}))
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "4"), (b, "4"), (c, "5")):
        assert study("--runs", "4", "--seed", seed, "--config", str(config), "--out", str(out)).exit_code == 0
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()


def test_check_exit_code_and_config(tmp_path):
    config = tmp_path / "strict.yaml"
    config.write_text(yaml.safe_dump({"study": {"peak_ratio": 1e6}, "turn_g": [3], "gating": ["off"]}))
    result = study("--runs", "3", "--config", str(config), "--out", str(tmp_path / "x"))
    assert result.exit_code == 0 and "E2c-kf-cv-turn-peak" in result.output and "FAIL" in result.output
    result = study("--runs", "3", "--config", str(config), "--out", str(tmp_path / "y"), "--check")
    assert result.exit_code == 1
    payload, claims = claims_of(tmp_path / "y")
    assert payload["asserts_passed"] is False and claims["E2c-kf-cv-turn-peak"]["verdict"] is False
    summary = pd.read_csv(tmp_path / "y" / SUMMARY_NAME)
    assert set(summary["n"]) == {3.0} and set(summary["loss_rate_on"].isna()) == {True}


@pytest.mark.parametrize("args, message", [
    (["--filters", "kf-cv,kf-nope"], "unknown filter 'kf-nope'"),
    (["--scenario", "loop"], "neither a named scenario"),
    (["--runs", "0"], "--runs must be a positive integer"),
])
def test_bad_options_name_themselves(tmp_path, args, message):
    result = study(*args, "--out", str(tmp_path))
    assert result.exit_code == 2 and message in result.output


def test_bad_config_names_the_key(tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"study": {"peak": 3}}))
    result = study("--config", str(config), "--out", str(tmp_path))
    assert result.exit_code == 2 and "unknown parameter(s) ['peak']" in result.output
    config.write_text(yaml.safe_dump({"filters": {"kf-x": {"kind": "kalman", "motion": {"model": "dwna", "sigma": 2}}}}))
    result = study("--config", str(config), "--out", str(tmp_path))
    assert result.exit_code == 2 and "unknown key(s) ['sigma']" in result.output


def test_scenario_file_filters_and_truth_file(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump({"name": "short-4g", "legs": [
        {"type": "straight", "duration_s": 30}, {"type": "turn", "g": 4, "direction": "right", "turn_deg": 120},
        {"type": "straight", "duration_s": 30}]}))
    result = study("--runs", "3", "--scenario", str(scenario), "--filters", "kf-cv,kf-singer", "--out", str(tmp_path / "s"))
    assert result.exit_code == 0, result.output
    _, claims = claims_of(tmp_path / "s")
    assert set(claims["E2a-gains-converge"]["measured"]) == {"kf-cv", "kf-singer"}
    assert list(claims["E2c-kf-cv-turn-peak"]["measured"]["turns"]) == ["short-4g onset 0"]
    summary = pd.read_csv(tmp_path / "s" / SUMMARY_NAME)
    truth = summary.loc[0, "t_onset"]
    assert truth == 30.0
    # the same trajectory as a recorded truth file: onset detected by the |a_perp| > 1 g0 rule
    from skytrack.studies.maneuver.scenarios import load_scenario_file

    case = load_scenario_file(scenario)
    frame = pd.DataFrame({"time": case.truth.time, "target_id": "A"})
    frame[["x", "y", "z"]] = case.truth.position
    frame.to_csv(tmp_path / "truth.csv", index=False)
    result = study("--runs", "3", "--truth", str(tmp_path / "truth.csv"), "--out", str(tmp_path / "t"))
    assert result.exit_code == 0, result.output
    _, claims = claims_of(tmp_path / "t")
    [(label, turn)] = claims["E2c-kf-cv-turn-peak"]["measured"]["turns"].items()
    assert label == "A/0 onset 0" and turn["ratio"] >= 5
    onset = pd.read_csv(tmp_path / "t" / SUMMARY_NAME)["t_onset"].iloc[0]
    assert abs(onset - 30.0) <= 2.0


def test_study_help_stays_light():
    """R24 commands are registered without importing numpy & co (skytrack --help stays fast)."""
    import subprocess
    import sys

    code = ("import json, sys\nfrom skytrack.cli.main import app\n"
            "try:\n    app(['study', 'kf-gains', '--help'], standalone_mode=False)\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = json.loads(done.stdout.strip().splitlines()[-1])
    assert "--runs" in done.stdout and "--truth" in done.stdout and "--check" in done.stdout
    assert not [m for m in loaded if m.split(".")[0] in ("numpy", "pandas", "scipy", "matplotlib", "pyarrow")]

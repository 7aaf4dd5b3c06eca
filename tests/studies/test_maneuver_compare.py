"""Spec 004 §6 E3 ``skytrack study maneuver-compare`` end to end (asserts i-iv, P5-P7 reports, sweeps, figures, R21, R24)."""

import json
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.studies.maneuver.maneuver_compare import FAMILIES, detection_stats, onset_scan
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME, TIMING_NAME
from skytrack.studies.maneuver.scenarios import named_cases
from study_cli import claims_of, invoke_study, study_outputs

SWEEP = {"vd", "vd-sigma-ca-2", "vd-sigma-ca-4", "vd-sigma-ca-16", "ie", "ie-p-fa-0.001"}
CASES = ["default n=3", "default n=5", "default n=7"]


def study(*args):
    return invoke_study("maneuver-compare", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "maneuver-compare", "--quick", "--runs", "50", "--check")


def test_asserts_hold_with_their_numbers(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "maneuver-compare" and payload["options"]["runs"] == 50 and payload["asserts_passed"] is True
    imm = claims["E3-i-imm"]["measured"]
    assert set(imm) == set(CASES)
    for values in imm.values():
        # KF-CV (sigma_w = 1) is far behind a 3-7 g turn; the IMM follows it
        assert values["imm_peak_m"] < 200 < 1000 < values["kf_cv_peak_m"]
        assert values["imm_e_pre_m"] < values["pseudo_noise_e_pre_m"]
    loss = claims["E3-ii-kf-cv-loss"]["measured"]
    assert loss["n"] == 5 and loss["kf_cv_loss_rate_on"] >= 0.5
    for claim in ("E3-iii-vd-delay", "E3-iv-ie-delay"):
        assert claims[claim]["verdict"] is True
        for values in claims[claim]["measured"].values():
            assert 0 <= values["median_delay_scans"] <= 6 and values["detected_fraction"] >= 0.9
    # VD re-filters its window s = round(1 / (1 - rho)) = 5 scans at a detection in a turn
    assert all(v["refiltered_scans_mean"] == 5.0 for v in claims["E3-iii-vd-delay"]["measured"].values())


def test_reports_p5_p7_and_sweeps(quick):
    _, claims = claims_of(quick)
    assert all(claims[c]["kind"] == "report" and claims[c]["verdict"] is None
               for c in ("E3-P5-vd-vs-ie", "E3-P6-vd-bank-imm", "E3-P7-vd-transient", "E3-sensitivity"))
    p5 = claims["E3-P5-vd-vs-ie"]["measured"]
    for values in p5.values():
        assert values["vd_over_ie_e_man"] == pytest.approx(values["vd"]["e_man_pos"] / values["ie"]["e_man_pos"])
        assert values["vd"]["e_post_pos"] > 0 and values["ie"]["e_post_pos"] > 0
    assert set(claims["E3-P6-vd-bank-imm"]["measured"]["default n=5"]) >= {"vd", "static-bank", "imm-cv-ca", "imm-full"}
    sweep = claims["E3-sensitivity"]["measured"]
    assert set(sweep) == SWEEP
    # before its first declaration VD runs its CV model, which sigma_ca does not enter: the runs with a
    # false declaration before onset are the same for every sigma_ca
    early = {label: [sweep[label][c]["false_before_onset_fraction"] for c in CASES] for label in SWEEP if label.startswith("vd")}
    assert len({tuple(v) for v in early.values()}) == 1
    # a stricter P_fa cannot add false detections before onset in the same runs
    for case in CASES:
        assert sweep["ie-p-fa-0.001"][case]["false_before_onset_fraction"] <= sweep["ie"][case]["false_before_onset_fraction"]
    scope = claims["E3-scope"]["measured"]
    assert scope["other_cases"] == [] and set(scope["filters"]) == set(FAMILIES)


def test_summary_timeseries_and_timing(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    assert set(summary["filter"]) == set(FAMILIES) | SWEEP and set(summary["case"]) == set(CASES)
    assert len(summary) == len(set(FAMILIES) | SWEEP) * 3 * 2  # filters x cases x bases
    for column in ("e_pre_pos", "e_peak_pos", "e_man_pos", "settle_peak_pos", "settle_end_pos", "nees_mean", "nees_in_band",
                   "containment", "loss_rate_off", "loss_rate_on", "madds_per_update"):
        assert column in summary.columns
    rows = summary[summary["basis"] == "all"].set_index(["filter", "case"])
    assert rows["loss_rate_on"].notna().all() and (rows["madds_per_update"] > 0).all()
    member = rows.loc["set-membership"]
    assert member["containment"].between(0, 1).all() and member["nees_mean"].isna().all()
    assert rows.drop(index="set-membership", level=0)["containment"].isna().all()
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    aligned = series[(series["filter"] == "imm-cv-ca") & (series["quantity"] == "rms_pos") & (series["basis"] == "all")]
    assert aligned["t_rel"].min() == pytest.approx(-20.0) and aligned["t_rel"].max() <= 60.0
    timing = pd.read_csv(quick / TIMING_NAME)
    assert (timing["us_per_update"] > 0).all() and set(FAMILIES) <= set(timing["filter"])


def test_figures_draw_what_they_say(quick):
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"maneuver_compare_rms_default.png", "maneuver_compare_bars.png",
                            "maneuver_compare_sensitivity.png", "maneuver_compare_detection.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            if len(ax["labels"]) > 1:
                assert set(ax["labels"]) <= set(ax["legend"])
    rms = figures["maneuver_compare_rms_default.png"]["axes"]
    assert len(rms) == 6 and {"kf-cv", "vd", "ie", "imm-cv-ca", "static-bank"} <= set(rms[0]["labels"])
    assert [ax["ylabel"] for ax in rms[:2]] == ["RMS position error [m]", "RMS velocity error [m/s]"]
    bars = figures["maneuver_compare_bars.png"]["axes"]
    assert [ax["xlabel"] for ax in bars] == ["peak RMS position error e_peak [m]", "pre-manoeuvre RMS e_pre [m]",
                                             "multiply-adds per update"]
    sensitivity = figures["maneuver_compare_sensitivity.png"]["axes"]
    assert sensitivity[0]["labels"] == ["vd-sigma-ca-2", "vd-sigma-ca-4", "vd", "vd-sigma-ca-16", "imm-cv-ca"]


def _fake_run(runs, scans, events):
    diagnostics = [[] for _ in range(scans)]
    for k, channel, rows, values in events:
        diagnostics[k].append((channel, np.asarray(rows), {key: np.asarray(v) for key, v in values.items()}))
    return SimpleNamespace(runs=runs, diagnostics=diagnostics)


def test_detection_delay_from_recorder_events():
    case = named_cases("default", turn_g=(5.0,))[0]
    k_on = onset_scan(case, case.maneuvers[0][0])
    assert case.truth.time[k_on] == pytest.approx(40.0)
    run = _fake_run(4, case.scans, [
        (10, "switch", [1], {"mode": [1], "refiltered": [5]}),            # false alarm of run 1
        (k_on + 3, "switch", [0, 1], {"mode": [1, 1], "refiltered": [5, 4]}),
        (k_on + 5, "switch", [0], {"mode": [0], "refiltered": [0]}),     # a return to CV is no declaration
        (k_on + 7, "switch", [2, 0], {"mode": [1, 1], "refiltered": [5, 5]}),
    ])
    stats = detection_stats(run, case, "switch", 60.0, "mode")
    assert stats["delay"].tolist() == [3.0, 3.0, 7.0, np.inf]
    assert stats["early"].tolist() == [False, True, False, False]
    assert stats["after"].tolist() == [2, 1, 1, 0]
    assert stats["refiltered"][:3].tolist() == [5.0, 4.0, 5.0] and np.isnan(stats["refiltered"][3])


def test_other_scenario_keeps_the_default_cases_for_the_asserts(tmp_path):
    result = study("--scenario", "vertical", "--filters", "kf-cv,imm-cv-ca", "--runs", "4", "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    summary = pd.read_csv(tmp_path / SUMMARY_NAME)
    assert set(summary["case"]) == set(CASES) | {"vertical"}
    assert set(summary[summary["case"] == "vertical"]["filter"]) == {"kf-cv", "imm-cv-ca"}
    # the claims' filters are added on the default scenario
    assert {"pseudo-noise", "static-bank", "imm-full", "vd", "ie"} <= set(summary[summary["case"] == "default n=5"]["filter"])
    _, claims = claims_of(tmp_path)
    assert claims["E3-scope"]["measured"]["other_cases"] == ["vertical"]
    figures = {f["file"]: f for f in json.loads((tmp_path / FIGURES_NAME).read_text())}
    scenario = figures["maneuver_compare_rms_scenarios.png"]["axes"]
    assert [ax["title"] for ax in scenario] == ["vertical: RMS position error", "vertical: RMS velocity error"]
    assert scenario[0]["labels"] == ["kf-cv", "imm-cv-ca"] and scenario[0]["xlabel"] == "time [s]"


def test_same_seed_same_outputs(tmp_path):
    """R21: same seed, identical outputs (wall times live apart in timing.csv); another seed, other numbers."""
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "study": {"extra_scenarios": [], "sigma_ca_sweep": [8],
                                                                "ie_p_fa_sweep": [0.01]}}))
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "4"), (b, "4"), (c, "5")):
        result = study("--runs", "4", "--seed", seed, "--config", str(config), "--filters", "kf-cv,pseudo-noise,imm-cv-ca",
                       "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()
    _, claims = claims_of(a)
    assert set(claims["E3-i-imm"]["measured"]) == {"default n=5"}
    assert set(claims["E3-sensitivity"]["measured"]) == {"vd", "ie"}


def test_missing_turn_for_the_loss_assert_fails_and_says_so(tmp_path):
    config = tmp_path / "n3.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [3], "gating": ["off", "on"], "study": {"sigma_ca_sweep": [8], "ie_p_fa_sweep": [0.01]}}))
    result = study("--runs", "3", "--config", str(config), "--filters", "kf-cv", "--out", str(tmp_path / "x"), "--check")
    assert result.exit_code == 1
    _, claims = claims_of(tmp_path / "x")
    loss = claims["E3-ii-kf-cv-loss"]
    assert loss["verdict"] is False and "no case with n = 5" in loss["measured"]["note"]


def test_bad_extra_scenario_names_the_option(tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"study": {"extra_scenarios": ["loop"]}}))
    result = study("--config", str(config), "--runs", "2", "--out", str(tmp_path))
    assert result.exit_code == 2 and "study.extra_scenarios" in result.output and "'loop'" in result.output

"""Spec 004 §6 E6 ``skytrack study adaptive-qr`` (P10; §3.3 F, K, L, R8, R13, R14, R20-R24)."""

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.studies.maneuver.adaptive_qr import FILTERS, q_equivalent, r_ratio, settle_scans
from skytrack.studies.maneuver.filters import CATALOG, FilterSetting
from skytrack.studies.maneuver.measurements import simulate_measurements
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from skytrack.studies.maneuver.runner import RunOptions, run_filter
from skytrack.studies.maneuver.scenarios import named_cases
from study_cli import claims_of, invoke_study, study_outputs

ASSERTS = {"E6-r-hat-at-onset", "E6-rms-falls-by-onset", "E6-peak-without-ie", "E6-peak-with-ie"}
REPORTS = {"E6-error-reduction", "E6-q-hat-settling", "E6-sage-husa-divergence", "E6-cost", "E6-structured-loss-in-turn"}
FILTER_LABELS = {"kf-misspecified", "adaptive", "adaptive-sage-husa", "adaptive-cov-matching", "adaptive-ie", "ie",
                 "ie-misspecified", "adaptive-no-gate"}


def study(*args):
    return invoke_study("adaptive-qr", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "adaptive-qr", "--quick", "--runs", "16", "--check")


def test_asserts_hold_with_their_numbers(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "adaptive-qr" and payload["asserts_passed"] is True and payload["options"]["runs"] == 16
    assert set(claims) == ASSERTS | REPORTS
    assert all(claims[i]["kind"] == "assert" and claims[i]["verdict"] is True for i in ASSERTS)
    assert all(claims[i]["kind"] == "report" for i in REPORTS)
    case = "adaptive-qr n=5"
    ratio = claims["E6-r-hat-at-onset"]["measured"][case]
    assert ratio["t_on_s"] == 60.0 and all(0.6 <= r <= 1.4 for r in ratio["mean_ratio_xyz"])
    rms = claims["E6-rms-falls-by-onset"]["measured"][case]
    assert rms["rms_t_on"] < rms["rms_t0_plus_5"]
    peak = claims["E6-peak-without-ie"]["measured"][case]
    assert peak["ratio"] == pytest.approx(peak["peak"] / peak["rms_t_on"]) and peak["ratio"] >= 3
    ie = claims["E6-peak-with-ie"]["measured"][case]
    assert ie["peak_adaptive"] == peak["peak"] and ie["fraction"] <= 0.5


def test_reports(quick):
    _, claims = claims_of(quick)
    case = "adaptive-qr n=5"
    reduction = claims["E6-error-reduction"]["measured"][case]
    assert set(reduction) == FILTER_LABELS
    assert reduction["kf-misspecified"]["vs_kf_misspecified_at_t_on"] == 0.0
    # input estimation with the mis-specified start is the mis-specified KF until its first detection
    assert reduction["ie-misspecified"]["rms_t_on"] == pytest.approx(reduction["kf-misspecified"]["rms_t_on"], rel=1e-6)
    settle = claims["E6-q-hat-settling"]["measured"][case]
    assert set(settle) == {"adaptive", "adaptive-sage-husa", "adaptive-cov-matching", "adaptive-ie", "adaptive-no-gate"}
    for entry in settle.values():
        assert entry["settle_scans_mean"] >= -1 and len(entry["r_ratio_t_on_xyz"]) == 3
    divergence = claims["E6-sage-husa-divergence"]["measured"][case]
    assert {"runs_lost_before_onset", "r_ratio_mean_window_end", "q_projection_median_case_end"} <= set(divergence)
    cost = claims["E6-cost"]["measured"]
    assert cost["kf-misspecified"]["relative_to_kf_cv"] == 1.0
    assert cost["adaptive"]["relative_to_kf_cv"] > 1.0
    assert cost["adaptive-ie"]["madds_per_update"] > cost["ie"]["madds_per_update"] > cost["adaptive"]["madds_per_update"]
    loss = claims["E6-structured-loss-in-turn"]["measured"][case]
    assert 0 <= loss["adapted_fraction_in_window"] < loss["adapted_fraction_before_onset"] <= 1
    assert loss["median_nis_in_window"] > 11.34  # beyond the 99 % NIS gate of 3 components: adaptation stops


def test_summary_series_and_figures(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    assert set(summary["filter"]) == FILTER_LABELS and set(summary["case"]) == {"adaptive-qr n=5"}
    assert set(summary["gating"]) == {"off"}
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    assert {"rms_pos", "rms_vel"} <= set(series["quantity"])
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"adaptive_qr_rms.png", "adaptive_qr_histories.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            assert set(ax["labels"]) <= set(ax["legend"])
    histories = figures["adaptive_qr_histories.png"]["axes"]
    assert histories[0]["labels"][:3] == ["adaptive, x", "adaptive, y", "adaptive, z"]
    assert "adaptive-sage-husa (median over runs)" in histories[1]["labels"]


def test_history_helpers_on_recorded_runs():
    """Without adaptation (warm-up beyond the case) R-hat stays R0 = 4 R of the first update and the full Q-hat
    stays q0 Q_unit, so the helpers return 4 and 25 exactly."""
    case = named_cases("default", turn_g=(5.0,))[0]
    meas = simulate_measurements(case, 3, 1, "polar")
    for spec in (replace(CATALOG["adaptive"], options={**CATALOG["adaptive"].options, "warmup": 1000}),
                 replace(FILTERS["adaptive-sage-husa"], options={**FILTERS["adaptive-sage-husa"].options, "warmup": 1000})):
        filt, _ = spec.build(FilterSetting(case.dt, meas.R[0]))
        run = run_filter(filt, case, meas, label=spec.label, options=RunOptions(record=True))
        q = q_equivalent(run, spec, case.dt)
        assert np.isnan(q[:2]).all() and np.allclose(q[2:], 25.0, rtol=1e-12)
        ratio = r_ratio(run, meas.R)
        if spec.options["variant"] == "structured":
            assert np.allclose(ratio[2], 4.0, rtol=1e-12)  # R0 from the plot of the first update
            R0 = 4.0 * np.diagonal(meas.R[2], axis1=-2, axis2=-1)
            assert np.allclose(ratio[-1], R0 / np.diagonal(meas.R[-1], axis1=-2, axis2=-1), rtol=1e-12)


def test_settle_scans():
    values = np.array([25.0, 10.0, 3.0, 1.4, 0.9, 1.2, 1.0])
    assert settle_scans(values, 0, 6, 0.5) == 3  # from index 3 on within [0.5, 1.5]
    assert settle_scans(values, 0, 6, 0.05) == 6
    assert settle_scans(np.ones(5), 0, 4, 0.5) == 0
    assert settle_scans(np.array([1.0, np.nan]), 0, 1, 0.5) == -1


def test_same_seed_same_outputs(tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"study": {"turn_g": [7], "straight_s": 40}}))
    filters = "kf-misspecified,adaptive,adaptive-ie,adaptive-sage-husa"
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "2"), (b, "2"), (c, "3")):
        result = study("--runs", "4", "--seed", seed, "--filters", filters, "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()


def test_check_fails_a_stricter_assert(tmp_path):
    config = tmp_path / "strict.yaml"
    config.write_text(yaml.safe_dump({"study": {"turn_g": [5], "ie_peak_fraction": 0.001}}))
    result = study("--runs", "3", "--filters", "kf-misspecified,adaptive,adaptive-ie", "--config", str(config),
                   "--out", str(tmp_path / "x"), "--check")
    assert result.exit_code == 1
    _, claims = claims_of(tmp_path / "x")
    assert claims["E6-peak-with-ie"]["verdict"] is False and claims["E6-peak-without-ie"]["verdict"] is True


def test_claims_need_their_filters(tmp_path):
    result = study("--runs", "2", "--filters", "kf-misspecified,adaptive", "--out", str(tmp_path))
    assert result.exit_code == 2 and "needs ['adaptive-ie']" in result.output

"""Spec 004 §6 E4 ``skytrack study ie-bank`` end to end (claims, R22 MAC model cross-check, R21 determinism, --check)."""

import json
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.core import linalg
from skytrack.filters.registry import build_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.polynomial import dwpa
from skytrack.studies.maneuver.ie_bank import stop_improving
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME, TIMING_NAME
from study_cli import claims_of, invoke_study, study_outputs

QUICK_WINDOWS = [1, 2, 5, 20]


def study(*args):
    return invoke_study("ie-bank", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "ie-bank", "--quick", "--check")


def ie_madds_per_update(window: int, rows: int = 4, scans: int = 25) -> float:
    """Multiply-adds per predict + innovate + update of IE with detection disabled and a full bank,
    counted here directly on noise-free straight flight (independent of the study's runner)."""
    filt = build_filter("input-estimation", dwpa(3, 8.0), window=window, threshold=math.inf)
    model = ConvertedPositionModel(3, 3)
    x = np.zeros((rows, 9))
    x[:, [0, 3, 6]] = [-10_000.0, 40_000.0, 6_000.0]
    x[:, 1] = 250.0
    state = filt.initiate(x, np.broadcast_to(np.eye(9) * 100.0, (rows, 9, 9)).copy())
    R = np.broadcast_to(np.diag([3600.0, 625.0, 3600.0]), (rows, 3, 3)).copy()
    for k in range(1, scans + 1):
        z = x[:, [0, 3, 6]] + np.array([250.0 * k, 0.0, 0.0])
        if k == scans:
            with linalg.counting() as ops:
                pred = filt.predict(state, np.ones(rows))
                filt.update(pred, z, filt.innovate(pred, z, model, {"R": R}))
            return ops.madds / rows
        pred = filt.predict(state, np.ones(rows))
        state, _ = filt.update(pred, z, filt.innovate(pred, z, model, {"R": R}))
    raise AssertionError("unreachable")


def test_cost_claims_affine_in_window_and_above_kf_cv(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "ie-bank" and payload["options"]["runs"] == 8 and payload["asserts_passed"] is True
    affine = claims["E4-mac-affine"]
    assert affine["verdict"] is True and affine["kind"] == "assert"
    m = affine["measured"]
    assert sorted(int(w) for w in m["madds_per_update"]) == QUICK_WINDOWS
    assert m["max_rel_residual"] <= 1e-12 and m["max_spread_over_full_bank_scans"] == 0.0 and m["slope"] > 0
    # the line of the claim matches the multiply-adds counted here independently for two other bank sizes
    for window in (3, 7):
        assert ie_madds_per_update(window) == pytest.approx(m["intercept"] + m["slope"] * window, rel=1e-12)
    versus = claims["E4-mac-vs-kf-cv"]
    assert versus["verdict"] is True and versus["measured"]["ie"] == m["madds_per_update"]["20"]
    assert versus["measured"]["ie"] > versus["measured"]["kf-cv"] > 0
    detection = claims["E4-mac-detection"]["measured"]["madds_per_update"]
    # solving the hypotheses every scan costs extra multiply-adds for every bank size
    assert all(detection[w] > m["madds_per_update"][w] for w in detection)


def test_accuracy_claims_and_summary(quick):
    _, claims = claims_of(quick)
    accuracy = claims["E4-accuracy"]
    assert accuracy["kind"] == "report" and accuracy["verdict"] is None
    assert set(accuracy["measured"]) == {"default n=3", "default n=5", "default n=7"}
    for per_window in accuracy["measured"].values():
        assert sorted(int(w) for w in per_window) == QUICK_WINDOWS
        for row in per_window.values():
            assert 0.0 <= row["detection_probability"] <= 1.0 and 0.0 <= row["false_runs_rate"] <= 1.0
            assert row["e_peak_pos"] >= row["e_man_pos"] > 0
            assert row["delay_median_scans"] is None or 0 <= row["delay_median_scans"] <= 30
    knee = claims["E4-stop-improving"]["measured"]
    assert knee["windows"] == QUICK_WINDOWS and set(knee["largest"]) == {"e_peak_pos", "e_man_pos", "delay_median_scans"}
    assert all(v in QUICK_WINDOWS for case in knee["by_case"].values() for v in case.values() if v is not None)
    summary = pd.read_csv(quick / SUMMARY_NAME)
    table = summary[summary["table"] == "ie_bank"]
    assert len(table) == 3 * len(QUICK_WINDOWS)
    assert set(table["filter"]) == {f"ie-w{w}" for w in QUICK_WINDOWS}
    metrics = summary[summary["table"].isna()]
    # metrics come from the gating-off run; both gating modes ran (their loss rates are attached)
    assert set(metrics["basis"]) == {"all", "kept"} and metrics["loss_rate_on"].notna().all()
    timing = pd.read_csv(quick / TIMING_NAME)
    costs = timing[timing["case"] == "no manoeuvre"]
    assert {f"ie-w{w}-no-detection" for w in QUICK_WINDOWS} <= set(costs["filter"])
    assert not costs["recorded"].any() and (costs["us_per_update"] > 0).all()


def test_figures_draw_what_they_say(quick):
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"ie_bank_accuracy.png", "ie_bank_rms.png"}
    accuracy = figures["ie_bank_accuracy.png"]["axes"]
    assert len(accuracy) == 6
    for ax in accuracy:
        assert ax["xlabel"] == "bank size N_w" and ax["ylabel"]
        assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
    assert accuracy[0]["labels"] == ["default n=3", "default n=5", "default n=7"]
    assert accuracy[5]["labels"][0] == "IE, detection disabled" and "KF-CV" in accuracy[5]["legend"]
    assert accuracy[5]["labels"][1].startswith("affine fit 4341 + 657 N_w")
    rms = figures["ie_bank_rms.png"]["axes"]
    assert {label.split(",")[0] for label in rms[0]["labels"]} == {"ie-w1", "ie-w5", "ie-w20"}


def test_stop_improving_rule():
    windows = [1, 2, 5, 10, 20]
    assert stop_improving(windows, [100, 90, 80, 79, 78.5], 0.05) == 5
    assert stop_improving(windows, [100, 90, 80, 79, 70], 0.05) == 20  # a late improvement counts
    assert stop_improving(windows, [100, 100, 100, 100, 100], 0.05) == 1
    assert stop_improving(windows, [math.nan, 90, 87, 86, 87], 0.05) == 2
    assert stop_improving(windows, [math.nan, 90, 85, 86, 87], 0.05) == 5  # 85 < 0.95 x 90
    assert stop_improving(windows, [math.nan] * 5, 0.05) is None


def test_same_seed_same_outputs_and_check_failure(tmp_path):
    """R21: same seed, identical outputs (wall times live apart in timing.csv); a failing assert makes --check exit 1."""
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "gating": ["off"], "study": {"windows": [2, 5], "reference_window": 5,
                                                                                    "straight_s": 20}}))
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        result = study("--runs", "3", "--seed", "4", "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    _, claims = claims_of(a)
    assert claims["E4-mac-affine"]["verdict"] is False  # two bank sizes cannot show a line: the assert says so
    strict = tmp_path / "strict.yaml"
    strict.write_text(yaml.safe_dump({"turn_g": [5], "gating": ["on"],
                                      "study": {"windows": [1, 2, 5], "straight_s": 30, "affine_rtol": -1.0}}))
    result = study("--runs", "2", "--config", str(strict), "--out", str(tmp_path / "c"), "--check")
    assert result.exit_code == 1 and "E4-mac-affine" in result.output
    # gating "on" only in the config: the gating-off runs the detection metrics come from still run
    _, claims = claims_of(tmp_path / "c")
    assert set(claims["E4-accuracy"]["measured"]["default n=5"]) == {"1", "2", "5"}


@pytest.mark.parametrize("values, message", [
    ({"windows": [0, 5]}, "N_w values must be integers >= 1"),
    ({"straight_s": 10}, "--config study.straight_s"),
    ({"bank": 3}, "unknown parameter(s) ['bank']"),
])
def test_bad_configuration_names_the_parameter(tmp_path, values, message):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "gating": ["off"], "study": values}))
    result = study("--runs", "2", "--config", str(config), "--out", str(tmp_path / "x"))
    assert result.exit_code == 2 and message in result.output

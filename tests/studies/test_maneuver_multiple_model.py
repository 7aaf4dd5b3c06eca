"""Spec 004 §6 E7 ``skytrack study multiple-model`` end to end (literal switch-off assert, reports, figures, R21, R24)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.studies.maneuver.multiple_model import DEFAULT_FILTERS, active_state, member_events
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from study_cli import claims_of, invoke_study, study_outputs

CASES = ["default n=3", "default n=5", "default n=7"]
LITERAL = [f for f in DEFAULT_FILTERS if f.startswith("bank-literal-")]


def study(*args):
    return invoke_study("multiple-model", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "multiple-model", "--quick", "--runs", "50", "--check")


def test_literal_switch_off_assert(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "multiple-model" and payload["options"]["runs"] == 50 and payload["asserts_passed"] is True
    measured = claims["E7-literal-switch-off"]["measured"]
    assert list(measured) == CASES
    for values in measured.values():
        assert values["cv_off_in_window"] >= 0.9 and values["any_off_before_onset"] <= 0.1
        # the divergence sum over W = 5 scans crosses its threshold a few scans into the turn
        assert 1 <= values["cv_off_delay_median_scans"] <= 10


def test_switching_reports_follow_the_bank_rules(quick):
    _, claims = claims_of(quick)
    switching = claims["E7-switching"]["measured"]
    effect = claims["E7-floor-reenable"]["measured"]
    for case in CASES:
        for label in LITERAL:
            members = switching[case][label]["members"]
            # literal mode: permanent switch-off, every member at most once, never re-enabled
            assert all(m["reenables_per_run"] == 0 and m["switch_offs_per_run"] <= 1 for m in members.values())
        # CT modes at a fixed +-11.2 deg/s diverge on the first straight leg: gone before the turn in every run
        ct = {k: v for k, v in switching[case]["bank-literal-cv-ct"]["members"].items() if k.startswith("CT")}
        assert len(ct) == 2 and all(v["switched_off_before_onset"] == 1.0 for v in ct.values())
        assert switching[case]["bank-literal-cv-ct"]["members"]["CV"]["switch_offs_per_run"] == 0  # never the last one
        literal, improved = effect[case]["bank-literal-cv-ca-singer"], effect[case]["bank-improved-cv-ca-singer"]
        assert literal["cv_active_at_end"] <= 0.02 and literal["reenables_per_run"] == 0
        assert improved["cv_active_at_end"] >= 0.9 and improved["reenables_per_run"] > 0
    # once the CV member is back, the improved bank returns to a lower error after the turn than the literal one
    n5 = effect["default n=5"]
    assert n5["bank-improved-cv-ca-singer"]["e_post_pos"] < 0.85 * n5["bank-literal-cv-ca-singer"]["e_post_pos"]


def test_model_set_reports(quick):
    _, claims = claims_of(quick)
    table = claims["E7-model-sets"]["measured"]
    assert list(table) == CASES and set(table["default n=5"]) == set(DEFAULT_FILTERS)
    for values in table["default n=5"].values():
        assert {"e_pre_pos", "e_man_pos", "e_peak_pos", "e_post_pos", "settle_peak_pos", "loss_rate_on"} <= set(values)
    best = claims["E7-best-set"]["measured"]["default n=5"]
    assert best["imm_by_e_man"].startswith("imm-") and best["improved_bank_by_e_man"].startswith("bank-improved-")
    # the 5 g turn is the CT modes' design rate: an IMM with them beats the cv-ca IMM over the turn
    n5 = table["default n=5"]
    assert n5["imm-cv-ct"]["e_man_pos"] < n5["imm-cv-ca"]["e_man_pos"]
    assert claims["E7-scope"]["measured"]["other_cases"] == []


def test_summary_series_and_figures(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    assert set(summary["filter"]) == set(DEFAULT_FILTERS) and set(summary["case"]) == set(CASES)
    assert summary["loss_rate_on"].notna().all()
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    assert {"aligned", "model_probability", "active_fraction"} <= set(series["series"])
    mu = series[(series["series"] == "model_probability") & (series["case"] == "default n=5")
                & (series["filter"] == "imm-cv-ca")].pivot(index="t", columns="quantity", values="value").dropna()
    assert list(mu.columns) == ["mu CA", "mu CV"] and np.allclose(mu.sum(axis=1), 1.0)
    active = series[(series["series"] == "active_fraction") & (series["filter"] == "imm-cv-ca")]
    assert active.empty  # an IMM switches nothing off
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {*(f"multiple_model_probabilities_default-n-{n}.png" for n in (3, 5, 7)),
                            "multiple_model_switching.png", "multiple_model_rms.png", "multiple_model_table.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            if len(ax["labels"]) > 1:
                assert set(ax["labels"]) <= set(ax["legend"])
    probabilities = figures["multiple_model_probabilities_default-n-5.png"]["axes"]
    assert len(probabilities) == 12  # 4 sets x (literal bank, improved bank, IMM)
    assert probabilities[0]["title"] == "literal bank, cv-ca-singer" and probabilities[0]["labels"] == ["CV", "CA", "Singer"]
    switching = figures["multiple_model_switching.png"]["axes"]
    assert [ax["title"] for ax in switching] == [f"{c}: {v}" for c in CASES for v in
                                                 ("bank-literal-cv-ca-singer", "bank-floor-only", "bank-improved-cv-ca-singer")]


def test_member_events_and_active_state():
    class Run:
        diagnostics = [[], [("switch_off", np.array([0, 1]), {"member": np.array([0, 2]), "scan": np.array([1, 1])})],
                       [("model_probabilities", np.array([0, 1]), {"mu": np.ones((2, 3)) / 3})],
                       [("reenable", np.array([0]), {"member": np.array([0]), "scan": np.array([3])}),
                        ("switch_off", np.array([1]), {"member": np.array([1]), "scan": np.array([3])})]]

    offs, ons = member_events(Run, "switch_off"), member_events(Run, "reenable")
    assert offs == [(1, 0, 0), (1, 1, 2), (3, 1, 1)] and ons == [(3, 0, 0)]
    state = active_state(4, 2, 3, offs, ons)
    assert state[0].all()
    assert state[1].tolist() == [[False, True, True], [True, True, False]]
    assert state[3].tolist() == [[True, True, True], [True, False, False]]


def test_truth_file_and_same_seed(tmp_path):
    """Recorded trajectories (--truth) go through the same analysis; R21: same seed, identical outputs."""
    from skytrack.studies.maneuver.scenarios import named_cases

    case = named_cases("weave")[0]
    frame = pd.DataFrame({"time": case.truth.time, "target_id": "A"})
    frame[["x", "y", "z"]] = case.truth.position
    frame.to_csv(tmp_path / "truth.csv", index=False)
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5]}))
    outs = [tmp_path / "a", tmp_path / "b"]
    for out in outs:
        result = study("--runs", "4", "--seed", "3", "--truth", str(tmp_path / "truth.csv"), "--config", str(config),
                       "--filters", "bank-improved-cv-ca-singer,imm-cv-ca", "--out", str(out))
        assert result.exit_code == 0, result.output
    a, b = outs
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    summary = pd.read_csv(a / SUMMARY_NAME)
    assert set(summary["case"]) == {"default n=5", "A/0"}
    recorded = summary[(summary["case"] == "A/0") & (summary["basis"] == "all")]
    assert set(recorded["filter"]) == {"bank-improved-cv-ca-singer", "imm-cv-ca"} and recorded["onset"].nunique() == 4
    # the literal bank is added on the default scenario for the assert
    assert "bank-literal-cv-ca-singer" in set(summary[summary["case"] == "default n=5"]["filter"])
    figures = {f["file"] for f in json.loads((a / FIGURES_NAME).read_text())}
    assert "multiple_model_probabilities_a-0.png" in figures

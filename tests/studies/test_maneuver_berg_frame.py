"""Spec 004 §6 E5 ``skytrack study berg-frame`` end to end (claims, TV17, independent 9x9 KF, R21 determinism, --check)."""

import json
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.filters.berg import SPEC_CHANNELS
from skytrack.studies.maneuver.berg_frame import CHANNELS, STUDY_FILTERS, tv17_identity
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME, TIMING_NAME
from study_cli import claims_of, invoke_study, study_outputs

FILTERS = {"berg-full", "berg-frame", "berg-frame-no-rotation", "berg-frame-no-jerk", "berg-full-no-jerk", "kf-singer"}
CASES = ["default n=3", "default n=5", "default n=7", "vertical"]


def study(*args):
    return invoke_study("berg-frame", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "berg-frame", "--quick", "--check")


def test_channels_are_the_spec_values_passed_explicitly():
    assert tuple(CHANNELS.values()) == SPEC_CHANNELS
    for spec in STUDY_FILTERS.values():
        assert tuple(tuple(spec.options[name]) for name in ("tangential", "normal", "binormal")) == SPEC_CHANNELS
    assert STUDY_FILTERS["berg-frame-no-rotation"].options["block_rotation"] is False
    assert STUDY_FILTERS["berg-full-no-jerk"].options["mean_jerk"] is False


def test_asserts_mac_and_tv17(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "berg-frame" and payload["options"]["runs"] == 8 and payload["asserts_passed"] is True
    mac = claims["E5-mac"]
    assert mac["verdict"] is True and set(mac["measured"]["madds_per_update"]) == set(CASES)
    for per_case in mac["measured"]["madds_per_update"].values():
        assert set(per_case) == FILTERS
        assert per_case["berg-frame"] * 1.5 <= per_case["berg-full"]
        # dropping the block rotation or the mean jerk saves their multiply-adds
        assert per_case["berg-frame-no-rotation"] < per_case["berg-frame"] and per_case["berg-frame-no-jerk"] < per_case["berg-frame"]
    assert mac["measured"]["min_ratio"] >= 1.5
    tv17 = claims["E5-tv17-identity"]
    assert tv17["verdict"] is True and tv17["measured"]["scans"] == 30
    assert max(tv17["measured"]["x_rel_diff"], tv17["measured"]["P_rel_diff"]) <= 1e-9
    assert tv17["measured"]["P_moved_from_P0"] > 0.5  # the identity is not trivial


def test_tv17_identity_fails_for_different_models():
    """The identity check sees a difference when the two filters do not share the model."""
    other = STUDY_FILTERS["berg-frame"].__class__(
        "frame-other", "berg-frame", STUDY_FILTERS["berg-frame"].motion,
        {**STUDY_FILTERS["berg-frame"].options, "normal": (15.0, 20.0)})
    result = tv17_identity(STUDY_FILTERS["berg-full"], other, 30)
    assert result["P_rel_diff"] > 1e-3


def test_reports_ratios_costs_and_loss_investigation(quick):
    _, claims = claims_of(quick)
    ratios = claims["E5-rms-ratio"]
    assert ratios["kind"] == "report" and set(ratios["measured"]) == set(CASES)
    for per_case in ratios["measured"].values():
        assert set(per_case) == {"berg-frame / berg-full", "berg-frame-no-jerk / berg-full-no-jerk"}
        entry = per_case["berg-frame / berg-full"]
        assert 0.2 < entry["whole_case_pos"] < 5 and 0.2 < entry["manoeuvre_pos"] < 5
    losses = claims["E5-berg-full-losses"]["measured"]
    assert losses["case"] == "default n=5"
    assert set(losses["by_tangential_sigma"]) == {f"{k} sigma_t={s}" for k in ("berg-full", "berg-frame") for s in (3, 40)}
    # berg-full is the §3.3 M recursion (written out independently in the study)
    assert losses["berg_full_vs_independent_kf"]["max_rel_diff_x"] <= 1e-9
    assert losses["berg_full_vs_independent_kf"]["runs"] == 2
    # the turn's mean jerk is -a_n^2/|v| on the tangential channel (TV17: -9.617038422 at 5 g, 250 m/s)
    assert losses["turn_mean_jerk_tangential_mps3"] == pytest.approx(-9.617038422, abs=1e-8)
    assert losses["tangential_channel_accel_variance_per_scan"] == pytest.approx(9.0 * (1 - math.exp(-2 / 60)), rel=1e-12)
    table = losses["by_tangential_sigma"]
    # a wide tangential channel makes berg-full consistent (NEES far below the sigma_t = 3 value)
    assert table["berg-full sigma_t=40"]["nees_mean"] < table["berg-full sigma_t=3"]["nees_mean"]
    timing = pd.read_csv(quick / TIMING_NAME)
    ratio_rows = timing[timing["filter"] == "berg-full / berg-frame"]
    assert list(ratio_rows["case"]) == CASES
    assert np.allclose(ratio_rows["madds_per_update"], 4964 / 769, rtol=0.2) and (ratio_rows["us_per_update"] > 0).all()


def test_summary_and_figures(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    main = summary[summary["filter"].isin(FILTERS)]
    assert set(main["case"]) == set(CASES) and set(main["filter"]) == FILTERS
    assert main["loss_rate_on"].notna().all() and main["loss_rate_off"].notna().all()
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"berg_frame_cost.png", "berg_frame_rms.png", "berg_frame_tangential.png"}
    for figure in figures.values():
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
    rms = figures["berg_frame_rms.png"]["axes"]
    assert [ax["title"] for ax in rms] == CASES and set(rms[0]["labels"]) == FILTERS
    cost = figures["berg_frame_cost.png"]["axes"]
    assert cost[0]["ylabel"] == "multiply-adds per update (R22 a)" and "equal error" in cost[2]["legend"]
    tangential = figures["berg_frame_tangential.png"]["axes"]
    assert tangential[0]["labels"] == ["berg-full, gating off", "berg-full, gating on", "berg-frame, gating off",
                                       "berg-frame, gating on"]


def test_same_seed_same_outputs_and_scenario_option(tmp_path):
    """R21: same seed, identical outputs; --scenario replaces the default cases (no vertical added)."""
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"gating": ["off"], "study": {"tangential_sigmas": [3], "independent_runs": 1}}))
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        result = study("--runs", "3", "--seed", "4", "--scenario", "vertical", "--filters", "berg-frame,kf-singer",
                       "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    _, claims = claims_of(a)
    # berg-full and berg-frame always run (the asserts need them); the investigation builds its own 5 g case
    assert set(claims["E5-mac"]["measured"]["madds_per_update"]) == {"vertical"}
    assert set(claims["E5-mac"]["measured"]["madds_per_update"]["vertical"]) == {"berg-full", "berg-frame", "kf-singer"}
    assert claims["E5-berg-full-losses"]["measured"]["case"] == "default n=5"


def test_check_exit_code_and_gating_on_only(tmp_path):
    """A failing assert makes --check exit 1; with the config's gating "on" only, the gating-off runs the costs
    and ratios come from still run."""
    config = tmp_path / "strict.yaml"
    config.write_text(yaml.safe_dump({"gating": ["on"], "study": {"mac_ratio": 100.0, "tangential_sigmas": [3],
                                                                  "independent_runs": 1, "extra_scenarios": []}}))
    result = study("--runs", "2", "--scenario", "vertical", "--config", str(config), "--out", str(tmp_path / "x"), "--check")
    assert result.exit_code == 1 and "E5-mac" in result.output
    _, claims = claims_of(tmp_path / "x")
    assert claims["E5-mac"]["verdict"] is False and claims["E5-tv17-identity"]["verdict"] is True
    assert claims["E5-mac"]["measured"]["min_ratio"] == pytest.approx(4964 / 769, rel=0.2)
    summary = pd.read_csv(tmp_path / "x" / SUMMARY_NAME)
    assert summary["loss_rate_on"].notna().all() and summary["loss_rate_off"].notna().all()

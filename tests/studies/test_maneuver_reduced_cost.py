"""Spec 004 §6 E8 ``skytrack study reduced-cost`` end to end (MAC asserts, TV10, degradation table, sensor placement,
R21 determinism, --check)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from skytrack.studies.maneuver.reduced_cost import place_sensor, tv10_identity
from skytrack.studies.maneuver.scenarios import named_cases
from study_cli import claims_of, invoke_study, study_outputs

QUICK_FILTERS = ["kf-singer", "per-axis", "transformed-gain", "pcg-1", "pcg-5", "pcg-offline-1", "pcg-offline-5",
                 "alpha-beta-gamma"]


def study(*args):
    return invoke_study("reduced-cost", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "reduced-cost", "--quick", "--check")


def test_place_sensor_sets_the_slant_range_along_the_line_of_sight():
    case = named_cases("default", turn_g=(5.0,))[0]
    start = case.truth.position[0]
    for range_km in (40.0, 150.0):
        moved = place_sensor(case, range_km)
        sensor = np.array(moved.sensor.position)
        assert np.linalg.norm(start - sensor) == pytest.approx(1e3 * range_km, rel=1e-12)
        assert sensor[2] == 0.0 and moved.label == f"default n=5, sensor {range_km:g} km"
        # the sensor lies on the horizontal line from the original radar through the start
        assert abs(start[0] * sensor[1] - start[1] * sensor[0]) <= 1e-9 * np.linalg.norm(start[:2]) ** 2
        assert moved.params["sensor_range_km"] == range_km and np.array_equal(moved.truth.position, case.truth.position)
    with pytest.raises(ValueError, match="sensor_ranges_km"):
        place_sensor(case, 5.0)  # below the target's 6 km height


def test_tv10_identity_numbers():
    tv10 = tv10_identity()
    assert max(tv10["pcg_vs_kf_x"], tv10["pcg_vs_kf_P"], tv10["pcg_vs_short_form_x"], tv10["pcg_vs_short_form_P"]) <= 1e-12
    assert tv10["pcg_vs_table_k8_abs"] <= 1e-8


def test_mac_asserts_and_identity(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "reduced-cost" and payload["options"]["runs"] == 8 and payload["asserts_passed"] is True
    coupled = claims["E8-cost-cartesian"]["measured"]["madds_per_update"]["kf-singer"]
    assert coupled > 0
    for claim, label in (("E8-mac-per-axis", "per-axis"), ("E8-mac-transformed", "transformed-gain")):
        measured = claims[claim]["measured"]
        assert claims[claim]["verdict"] is True and measured["coupled"] == coupled
        assert 0 < measured["madds_per_update"] < coupled
        assert measured["madds_per_update"] == claims["E8-cost-cartesian"]["measured"]["madds_per_update"][label]
    offline = claims["E8-mac-pcg-offline"]
    assert offline["verdict"] is True and set(offline["measured"]["madds_per_update"]) == {"pcg-offline-1", "pcg-offline-5"}
    # online cost of the schedule: the state update alone, far below the mean that includes the schedule's construction
    for label, value in offline["measured"]["madds_per_update"].items():
        assert 0 < offline["measured"]["online_median_per_scan"][label] < value < coupled
    identity = claims["E8-tv10-identity"]
    assert identity["verdict"] is True and identity["measured"]["max_study_runs"] <= 1e-9
    assert set(identity["measured"]["study_runs_polar"]) == {"40 km", "150 km"}
    assert identity["measured"]["tv10"]["pcg_vs_kf_P"] <= 1e-12


def test_degradation_table_and_coupling(quick):
    _, claims = claims_of(quick)
    degradation = claims["E8-degradation"]
    assert degradation["kind"] == "report"
    table = degradation["measured"]["table"]
    assert set(table) == {"40 km", "150 km"}
    for rows in table.values():
        assert list(rows) == QUICK_FILTERS
        assert rows["kf-singer"]["rms_ratio"] == 1.0 and rows["kf-singer"]["mac_saving"] == 0.0
        assert rows["pcg-1"]["rms_ratio"] == pytest.approx(1.0, abs=1e-9)
        for row in rows.values():
            assert row["mac_ratio"] == pytest.approx(row["madds_per_update"] / rows["kf-singer"]["madds_per_update"], rel=1e-12)
            assert row["rms_pos"] > 0 and row["nees_mean"] > 0
        # the polar radar's R changes with every plot: the offline schedule is rebuilt and costs more than the KF
        assert rows["pcg-offline-1"]["mac_ratio"] > 1
    # range-stretched cross-range errors: the converted R is far more coupled at 150 km
    coupling = degradation["measured"]["r_coupling"]
    assert coupling["150 km"]["median_max_abs_correlation"] > 0.7 > coupling["40 km"]["median_max_abs_correlation"]
    assert coupling["150 km"]["median_cross_range_over_range_sd"] == pytest.approx(150e3 * 1.5e-3 / 25, rel=0.05)
    assert table["150 km"]["kf-singer"]["rms_pos"] > 2 * table["40 km"]["kf-singer"]["rms_pos"]
    summary = pd.read_csv(quick / SUMMARY_NAME)
    rows = summary[summary["table"] == "degradation"]
    assert len(rows) == 2 * len(QUICK_FILTERS) and set(rows["sensor_range"]) == {"40 km", "150 km"}
    metrics = summary[summary["table"].isna()]
    assert set(metrics["gating"]) == {"off"} and metrics["loss_rate_on"].isna().all()
    assert {c for c in metrics["case"]} == {f"default n={n}, sensor {r} km" for n in (3, 5, 7) for r in (40, 150)}


def test_figures_draw_what_they_say(quick):
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"reduced_cost_scatter.png", "reduced_cost_pcg.png", "reduced_cost_rms_40km.png",
                            "reduced_cost_rms_150km.png"}
    for name, figure in figures.items():
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
    for range_km in (40, 150):  # the 5 g turn only
        rms = figures[f"reduced_cost_rms_{range_km}km.png"]
        assert rms["title"].endswith(f"default n=5, sensor {range_km} km")
        assert rms["axes"][0]["labels"] == ["kf-singer", "per-axis", "transformed-gain", "pcg-5", "alpha-beta-gamma"]
    scatter = figures["reduced_cost_scatter.png"]["axes"]
    assert [ax["title"] for ax in scatter] == ["sensor at 40 km", "sensor at 150 km"] * 2
    assert all(ax["labels"] == QUICK_FILTERS for ax in scatter)
    assert scatter[0]["xlabel"] == "MACs per update / coupled KF's"
    pcg = figures["reduced_cost_pcg.png"]["axes"]
    assert "offline, fixed Cartesian R" in pcg[1]["labels"] and "coupled KF" in pcg[1]["legend"]


def test_same_seed_same_outputs_and_check_failure(tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "study": {"sweep_N": [1, 2], "sensor_ranges_km": [150]}}))
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        result = study("--runs", "3", "--seed", "4", "--filters", "kf-singer,pcg-2", "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a / TIMESERIES_NAME), pd.read_parquet(b / TIMESERIES_NAME))
    _, claims = claims_of(a)
    # the filters the asserts need always run; --filters adds to them
    assert set(claims["E8-degradation"]["measured"]["table"]["150 km"]) == {
        "kf-singer", "per-axis", "transformed-gain", "pcg-1", "pcg-offline-1", "pcg-offline-2", "pcg-2"}
    strict = tmp_path / "strict.yaml"
    strict.write_text(yaml.safe_dump({"turn_g": [5], "study": {"sweep_N": [1], "sensor_ranges_km": [40],
                                                               "identity_rtol": -1.0}}))
    result = study("--runs", "2", "--config", str(strict), "--out", str(tmp_path / "c"), "--check")
    assert result.exit_code == 1 and "E8-tv10-identity" in result.output


@pytest.mark.parametrize("values, message", [
    ({"sweep_N": [0]}, "sweep_N: values must be integers >= 1"),
    ({"sensor_ranges_km": [3]}, "3 km is not reachable"),
])
def test_bad_configuration_names_the_parameter(tmp_path, values, message):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [5], "study": values}))
    result = study("--runs", "2", "--config", str(config), "--out", str(tmp_path / "x"))
    assert result.exit_code == 2 and message in result.output

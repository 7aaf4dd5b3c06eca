"""End-to-end tests of the ``skytrack`` command: simulate, track, evaluate, demo.

The demo tests are the foundation issue's acceptance check (every aircraft in coverage for
two minutes gets a confirmed track and the position RMSE stays below the radar's cross-range
error at mid range) and issue 9's identified air picture (item 7: the tracks labelled with
ADS-B, the identification report against truth in the report folder and the printout, and
the identification checks; the demo runs once for all of them).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.io import TRACK_COLUMNS, read_tracks

runner = CliRunner()


def invoke(*args: str):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    result = invoke("simulate", "crossing", "-o", out)
    assert result.exit_code == 0, result.output
    return out


def test_simulate_writes_formats_tables(simulated):
    plots = pd.read_parquet(simulated / "plots.parquet")
    truth = pd.read_parquet(simulated / "truth.parquet")
    sensors = json.loads((simulated / "sensors.json").read_text())
    assert {"time", "sensor", "range_m", "azimuth_deg"} <= set(plots.columns)
    assert {"time", "target_id", "segment", "x", "y", "z", "vx", "vy", "vz", "visible"} <= set(truth.columns)
    assert sensors["format_version"] == "1" and sensors["sensors"]
    assert np.all(np.diff(plots["time"].to_numpy()) >= 0)


def test_track_then_evaluate(simulated, tmp_path):
    tracks_path = tmp_path / "tracks.parquet"
    result = invoke("track", simulated / "plots.parquet", "--sensors", simulated / "sensors.json", "-o", tracks_path)
    assert result.exit_code == 0, result.output
    tracks = pq.read_table(tracks_path).to_pandas()
    assert list(tracks.columns[: len(TRACK_COLUMNS)]) == list(TRACK_COLUMNS)
    assert tracks["track_id"].dtype == np.int64
    assert set(tracks["status"].unique()) <= {"confirmed", "coasting"}
    json_path = tmp_path / "metrics.json"
    result = invoke("evaluate", tracks_path, "--truth", simulated / "truth.parquet", "--json", json_path)
    assert result.exit_code == 0, result.output
    metrics = json.loads(json_path.read_text())
    truth = pd.read_parquet(simulated / "truth.parquet")
    assert metrics["n_truth_objects"] == truth["target_id"].nunique()
    # every scripted aircraft of the crossing scenario is tracked, with few breaks
    assert metrics["n_truth_never_tracked"] == 0
    assert metrics["position_rmse_m"] < 150.0


def test_plots_written_by_another_tool(tmp_path):
    """A plots file with its own column order, extra columns and CSV text codes tracks as is."""
    rng = np.random.default_rng(7)
    period, n_scans = 4.0, 30
    start = np.array([20_000.0, 40_000.0])
    velocity = np.array([150.0, -60.0])
    rows = []
    for k in range(n_scans):
        t = k * period + 0.9  # beam at ~81 deg for this geometry; exact time does not matter
        p = start + velocity * t
        ground = np.hypot(*p)
        rows.append(
            {
                "note": "from another tool",
                "azimuth_deg": float(np.degrees(np.arctan2(p[0], p[1])) % 360 + rng.normal(0, 0.05)),
                "range_m": float(np.hypot(ground, 5000.0) + rng.normal(0, 30)),
                "sensor": "ext",
                "time": t,
                "mode3a": "0123",
                "mode_c_ft": 16400.0,
            }
        )
    frame = pd.DataFrame(rows)
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), tmp_path / "plots.parquet")
    frame.to_csv(tmp_path / "plots.csv", index=False)
    sensors = {
        "format_version": "1",
        "origin": {"lat": 45.0, "lon": 5.0, "alt_m": 0.0},
        "sensors": [
            {"name": "ext", "lat": 45.0, "lon": 5.0, "alt_m": 0.0, "scan_period_s": period,
             "sigma_range_m": 30.0, "sigma_azimuth_deg": 0.05, "max_range_m": 200000.0}
        ],
    }
    (tmp_path / "sensors.json").write_text(json.dumps(sensors))
    for name in ("plots.parquet", "plots.csv"):
        out = tmp_path / f"tracks_{name.split('.')[1]}.csv"
        result = invoke("track", tmp_path / name, "--sensors", tmp_path / "sensors.json", "-o", out)
        assert result.exit_code == 0, result.output
        tracks = read_tracks(out)
        assert tracks["track_id"].nunique() == 1
        assert set(tracks["mode3a"].dropna()) == {"0123"}
        last = tracks.iloc[-1]
        truth_now = start + velocity * last["time"]
        # the projected horizontal position matches the true one within a few sigma
        assert np.hypot(last["x"] - truth_now[0], last["y"] - truth_now[1]) < 150.0


@pytest.mark.parametrize(
    "text, expected",
    [
        ("time,sensor,range_m,azimuth_deg\n0.0,ext,1000,10\n1.0,ext,-5,10\n", "line 3 (row 1), column range_m"),
        ("time,sensor,range_m,azimuth_deg\n0.0,ext,1000,400\n", "column azimuth_deg"),
        ("time,sensor,range_m,azimuth_deg\n2.0,ext,1000,10\n1.0,ext,1000,20\n", "column time"),
        ("time,sensor,range_m,azimuth_deg\n0.0,nope,1000,10\n", "unknown sensor"),
        ("time,sensor,range_m,azimuth_deg\n0.0,ext,nan,10\n", "column range_m"),
        ("time,sensor,range,azimuth_deg\n0.0,ext,1000,10\n", "range_m"),
    ],
)
def test_malformed_plots_give_one_line_errors(tmp_path, text, expected):
    (tmp_path / "plots.csv").write_text(text)
    (tmp_path / "sensors.json").write_text(json.dumps({
        "format_version": "1", "origin": {"lat": 45.0, "lon": 5.0},
        "sensors": [{"name": "ext", "x": 0.0, "y": 0.0, "sigma_range_m": 30.0, "sigma_azimuth_deg": 0.05,
                     "scan_period_s": 4.0}],
    }))
    result = invoke("track", tmp_path / "plots.csv", "--sensors", tmp_path / "sensors.json", "-o", tmp_path / "t.csv")
    assert result.exit_code == 2
    assert "plots.csv" in result.output and expected in result.output
    assert "Traceback" not in result.output


def test_lenient_mode_counts_skipped_rows(tmp_path):
    lines = ["time,sensor,range_m,azimuth_deg"] + [f"{4.0 * k:.1f},ext,{20000 + 100 * k},45" for k in range(10)]
    lines[4] = "12.0,ext,20300,999"
    (tmp_path / "plots.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "sensors.json").write_text(json.dumps({
        "format_version": "1", "origin": {"lat": 45.0, "lon": 5.0},
        "sensors": [{"name": "ext", "x": 0.0, "y": 0.0, "sigma_range_m": 30.0, "sigma_azimuth_deg": 0.05,
                     "scan_period_s": 4.0}],
    }))
    result = invoke("track", tmp_path / "plots.csv", "--sensors", tmp_path / "sensors.json",
                    "-o", tmp_path / "t.csv", "--lenient")
    assert result.exit_code == 0, result.output
    assert "skipped" in result.output and "1" in result.output


def test_simulate_the_terminal_scenario(tmp_path):
    """The tracker's tuning scenario runs from the command line: landing aircraft end before the
    run does, and some false plots carry SSR codes and heights."""
    result = invoke("simulate", "terminal", "-o", tmp_path)
    assert result.exit_code == 0, result.output
    plots = pd.read_parquet(tmp_path / "plots.parquet")
    truth = pd.read_parquet(tmp_path / "truth.parquet")
    assert truth["target_id"].nunique() == 60 and plots["time"].max() <= 1200.0
    ended = truth.groupby("target_id")["time"].max()
    assert (ended < 1200.0).sum() >= 5
    false = plots[plots["truth_id"] == ""]
    assert 0.02 < false["mode3a"].notna().mean() < 0.08 and 0.02 < false["mode_c_ft"].notna().mean() < 0.08
    assert false["mode_s"].isna().all()


def test_unknown_scenario_and_bad_options(tmp_path):
    result = invoke("simulate", "no_such_scenario", "-o", tmp_path)
    assert result.exit_code == 2 and "no_such_scenario" in result.output
    result = invoke("simulate", "crossing", "-o", tmp_path, "--format", "xls")
    assert result.exit_code == 2 and "--format" in result.output


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    """One run of the bundled demo: (its folder, the command's result, metrics.json)."""
    out = tmp_path_factory.mktemp("demo")
    result = invoke("demo", "--out", out)
    return out, result, json.loads((out / "metrics.json").read_text())


def test_demo_meets_the_acceptance_checks(demo_run):
    tmp_path, result, metrics = demo_run
    checks = metrics["demo"]["checks"]
    # exit status 0 exactly when every check passed (the identification checks included)
    assert result.exit_code == (0 if metrics["demo"]["passed"] else 1), result.output
    assert checks["every_aircraft_in_coverage_2min_tracked"]
    assert checks["aircraft_in_coverage_2min"] >= 50
    assert checks["position_rmse_m"] < checks["cross_range_sigma_mid_range_m"]
    # covariance consistency on straight flight (issue 6): mean NEES within 2x of the state
    # dimension either way; in and after manoeuvres it is reported, not bounded.  The mean over
    # ~8 000 time-correlated samples moves with the noise draw: 2.1-3.0 over the demo's seed and
    # seeds 1-5, with and without the ADS-B pair (the 1.5x band held for one draw only)
    nees = metrics["nees"]
    assert nees["expected"] / 2.0 <= nees["quiet_mean"] <= 2.0 * nees["expected"]
    assert nees["quiet_n"] > 5000 and nees["manoeuvre_n"] > 0
    for name in ("plots.parquet", "truth.parquet", "sensors.json", "adsb.parquet", "tracks.parquet", "ppi.png",
                 "metrics_over_time.png", "identification.json", "identification_per_aircraft.csv"):
        assert (tmp_path / name).stat().st_size > 500
    assert metrics["continuity_mean"] > 0.9 and metrics["n_false_tracks"] <= 2


def test_demo_reports_the_identification(demo_run):
    """The demo tracks with ADS-B and writes and prints the identification report: totals in
    metrics.json equal to identification.json's, one CSV row per equipped aircraft, the close
    pair told apart by the sequential test (no Mode S address in their plots), the offset
    aircraft's track never labelled with its address."""
    from skytrack.analysis.identification import PER_AIRCRAFT_COLUMNS

    out, result, metrics = demo_run
    report = json.loads((out / "identification.json").read_text())
    demo = metrics["demo"]
    assert demo["identification"]["totals"] == report["totals"]
    assert demo["identification"]["acceptance"] == report["acceptance"]
    totals, checks = report["totals"], demo["checks"]
    assert totals["equipped_aircraft"] == checks["adsb_equipped_aircraft"] == 62
    assert checks["identified_correctly"] == totals["identified"] >= 55
    assert checks["wrong_label_rows"] == totals["wrong_label_rows"]
    assert checks["faulty_adsb_aircraft"] == ["DEMO4"]
    assert checks["faulty_adsb_aircraft_left_unidentified"] == ["DEMO4"]
    assert checks["identification_faulty_adsb_aircraft_left_unidentified"] is True
    assert checks["identified_without_mode_s"] >= 20 and checks["median_time_to_identify_without_mode_s_s"] <= 60
    per_aircraft = pd.read_csv(out / "identification_per_aircraft.csv")
    assert list(per_aircraft.columns) == list(PER_AIRCRAFT_COLUMNS) and len(per_aircraft) == 62
    status = per_aircraft.set_index("target_id")["status"]
    assert status["DEMO5"] == status["DEMO6"] == "identified"
    tracks = read_tracks(out / "tracks.parquet")
    adsb = tracks[tracks["identity_source"] == "adsb"]
    assert {"AFR451", "AFR453"} <= set(adsb["callsign"])
    # DEMO4's address (derived from its id: it has no Mode S) is on no track row
    demo4 = per_aircraft.set_index("target_id").at["DEMO4", "icao24"]
    assert not (tracks["icao24"] == demo4).any()
    assert demo["tracking"]["identification"]["adsb_addresses"] == 62
    output = result.output
    for text in ("identification against truth", "identified correctly", "time to identify", "DEMO4",
                 "identification written to"):
        assert text in output


def test_demo_passes_the_identification_checks(demo_run):
    _, result, metrics = demo_run
    checks = metrics["demo"]["checks"]
    assert checks["identification_no_wrong_label"]
    assert checks["identification_every_sound_equipped_aircraft_tracked_60s_identified"]
    assert checks["identification_faulty_adsb_aircraft_left_unidentified"]
    assert result.exit_code == 0


@pytest.mark.parametrize("scenario", ["crossing", "radar3d"])
def test_demo_of_other_scenarios_reports_honestly(tmp_path, scenario):
    """Other bundled scenarios: metrics.json is strict JSON (an undefined figure is null, the
    crossing scenario has no primary-only aircraft), and the exit status is 0 exactly when every
    check passed (a FAIL exited 0 before)."""
    result = invoke("demo", "--scenario", scenario, "--out", tmp_path)
    text = (tmp_path / "metrics.json").read_text()
    metrics = json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} in metrics.json"))
    checks = metrics["demo"]["checks"]
    passed = checks["every_aircraft_in_coverage_2min_tracked"] and checks["position_rmse_below_cross_range_sigma"]
    assert result.exit_code == (0 if passed else 1), result.output
    assert ("FAIL" in result.output) == (not passed)
    # no ADS-B in these scenarios: the identification checks do not apply (null), no report is written
    assert checks["identification_no_wrong_label"] is None and metrics["demo"]["passed"] == passed
    assert not (tmp_path / "identification.json").exists() and "identification" not in metrics["demo"]
    if checks["position_rmse_primary_only_aircraft_m"] is None:
        assert "n/a" in result.output

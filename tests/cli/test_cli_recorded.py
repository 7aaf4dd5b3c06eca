"""``skytrack simulate`` on recorded traffic: the bundled recording end to end, --trajectories
with a radar-only scenario, --start/--duration, the printed cleaning counts, input errors."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.io import read_adsb, read_sensors, read_truth

runner = CliRunner()

RADAR_ONLY = {
    "origin": {"lat": 48.86, "lon": 2.50},
    "duration_s": 600.0,
    "sensors": [
        {"name": "radar1", "lat": 48.86, "lon": 2.50, "alt_m": 30.0, "scan_period_s": 4.0, "sigma_range_m": 40.0,
         "sigma_azimuth_deg": 0.07, "max_range_m": 250000.0, "p_detection": 1.0, "clutter_per_scan": 0.0},
    ],
}


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


def one_line_error(result) -> str:
    """The error line (a progress bar may stand before it when the simulation had started)."""
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip() and not line.startswith("simulate ")]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.fixture(scope="module")
def swiss(tmp_path_factory):
    out = tmp_path_factory.mktemp("swiss")
    result = invoke("simulate", "recorded_switzerland", "--duration", 300, "-o", out)
    assert result.exit_code == 0, result.output
    return out, result.output


def test_bundled_recording_end_to_end(swiss):
    out, output = swiss
    sensors = read_sensors(out / "sensors.json")
    assert sensors.epoch_utc == "2018-08-01T11:20:00Z"
    truth = read_truth(out / "truth.parquet")
    plots = pd.read_parquet(out / "plots.parquet")
    adsb = read_adsb(out / "adsb.parquet", sensors=sensors)
    segments = set(truth["target_id"])
    # every truth id is a segment id <icao24>-<k>, and every true plot belongs to one
    assert all(tid.rsplit("-", 1)[1].isdigit() and len(tid.rsplit("-", 1)[0]) == 6 for tid in segments)
    true_plots = plots[plots["truth_id"] != ""]
    assert set(true_plots["truth_id"]) <= segments and len(set(true_plots["truth_id"])) >= 30
    assert (true_plots["mode_s"] == true_plots["truth_id"].str[:6]).all()
    assert set(adsb["truth_id"]) <= segments and adsb["time"].between(0.0, 300.0).all()
    # the cleaning counts of the whole recording are printed
    assert "rows read" in output and "52293 (428 aircraft)" in output
    assert "removed: stale position" in output and "gaps cut" in output


def test_trajectories_file_with_a_radar_only_scenario(tmp_path):
    t = 1633608000.0 + np.arange(0.0, 301.0, 1.0)
    lat = 48.9 + np.degrees(200.0 * (t - t[0]) / 6_371_008.8)
    states = pd.DataFrame({
        "timestamp": pd.to_datetime(t, unit="s", utc=True), "icao24": "abc123", "callsign": "TEST1",
        "latitude": lat, "longitude": 2.6, "altitude": 30000.0, "groundspeed": 200.0 / (1852.0 / 3600.0),
        "track": 0.0, "vertical_rate": 0.0, "squawk": "2345", "onground": False,
    })
    states_path = tmp_path / "states.csv"
    states.to_csv(states_path, index=False)
    scenario_path = tmp_path / "radar.yaml"
    scenario_path.write_text(yaml.safe_dump(RADAR_ONLY))
    out = tmp_path / "out"
    result = invoke("simulate", "--scenario", scenario_path, "--trajectories", states_path,
                    "--start", "2021-10-07T12:00:30Z", "--duration", 120, "-o", out, "--format", "csv")
    assert result.exit_code == 0, result.output
    assert json.loads((out / "sensors.json").read_text())["epoch_utc"] == "2021-10-07T12:00:30Z"
    plots = pd.read_csv(out / "plots.csv", dtype={"mode3a": str})
    assert set(plots["truth_id"]) == {"abc123-1"} and set(plots["mode3a"]) == {"2345"}
    assert plots["time"].between(0.0, 120.0).all() and len(plots) == 30
    truth = pd.read_csv(out / "truth.csv")
    assert truth["time"].max() == 120.0 and set(truth["target_id"]) == {"abc123-1"}
    # a number places time 0 that many seconds after the first time stamp
    result = invoke("simulate", scenario_path, "--trajectories", states_path, "--start", 30, "--duration", 60, "-o", out)
    assert result.exit_code == 0, result.output
    assert json.loads((out / "sensors.json").read_text())["epoch_utc"] == "2021-10-07T12:00:30Z"


def test_input_errors_are_one_line(tmp_path):
    scenario_path = tmp_path / "radar.yaml"
    scenario_path.write_text(yaml.safe_dump(RADAR_ONLY))
    line = one_line_error(invoke("simulate", scenario_path, "--start", 30, "-o", tmp_path / "o"))
    assert "--start places recorded traffic" in line
    line = one_line_error(invoke("simulate", scenario_path, "--trajectories", tmp_path / "none.parquet", "-o", tmp_path / "o"))
    assert "none.parquet: file not found" in line
    bad = tmp_path / "bad.csv"
    pd.DataFrame({"timestamp": [1.0], "icao24": ["abc123"], "latitude": [48.0]}).to_csv(bad, index=False)
    line = one_line_error(invoke("simulate", scenario_path, "--trajectories", bad, "-o", tmp_path / "o"))
    assert "bad.csv: missing required column(s) of the traffic state-vector layout: longitude" in line
    line = one_line_error(invoke("simulate", scenario_path, "--scenario", scenario_path, "-o", tmp_path / "o"))
    assert "give the scenario once" in line
    line = one_line_error(invoke("simulate", "recorded_paris", "--start", "2030-01-01T00:00:00Z", "-o", tmp_path / "o"))
    assert "no recorded aircraft in the window 2030-01-01T00:00:00Z" in line

"""``skytrack identify tracks`` end to end (spec 001 R13, R14; issue 9 acceptance, scaled down).

Small versions of the bundled scenarios (fewer aircraft, 200-240 s) are simulated, tracked with
``skytrack track`` and identified with ``skytrack identify tracks``:

* radar plots + ADS-B (``adsb_identification``: the pair 1 km apart, the aircraft whose ADS-B is
  2 km off, manoeuvring and unequipped aircraft): no track row gets a wrong label, the offset
  aircraft is left unidentified, every sound equipped aircraft tracked for 60 s is identified,
  and the printed report says so;
* radar tracks + another radar's tracks (``two_radars``): no wrong pair, every object both radars
  track for 60 s is paired within 60 s (:attr:`PairScore.passed`); ``--fuse`` moves the labelled
  rows to the pair's joint estimate and leaves the others alone;
* radar tracks + an interrogator's tracks (``radar_interrogator``, ``--source iff``): the same, and
  the fused rows are closer to the aircraft than the 2-D radar's own track (RMSE);
* errors: a tracks file without its reports names ``--reports``; plots without ``--sensors`` say
  so; both exit with code 2.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from skytrack.app.simulate import write_simulation
from skytrack.cli.main import app
from skytrack.sim import load_scenario, simulate
from skytrack.sim.scenario import bundled_scenario_path

runner = CliRunner()

#: the aircraft kept from adsb_identification: the close pair, the offset aircraft, manoeuvring,
#: straight and unequipped ones
ADSB_KEEP = ("PAIR1", "PAIR2", "OFS1", "AFR101", "KLM401", "SWR701", "DLH302", "GA1", "MIL1")


def _simulate(name: str, folder: Path, *, duration_s: float, traffic: int | None = None,
              keep: tuple[str, ...] | None = None) -> Path:
    document = yaml.safe_load(bundled_scenario_path(name).read_text())
    document["duration_s"] = duration_s
    if traffic is not None:
        document["traffic"]["count"] = traffic
    if keep is not None:
        document["targets"] = [t for t in document["targets"] if t["id"] in keep]
    write_simulation(simulate(load_scenario(document)), folder)
    return folder


def _invoke(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def _ok(result) -> None:
    assert result.exit_code == 0, result.output + (str(result.exception) if result.exception else "")


def _track(folder: Path, sensor: str) -> Path:
    out = folder / f"{sensor}.parquet"
    _ok(_invoke("track", folder / "plots.parquet", "--sensors", folder / "sensors.json", "--sensor", sensor,
                "--reports", "-o", out))
    return out


@pytest.fixture(scope="module")
def adsb_run(tmp_path_factory):
    folder = _simulate("adsb_identification", tmp_path_factory.mktemp("adsb"), duration_s=240.0, keep=ADSB_KEEP)
    result = _invoke("identify", "tracks", folder / "plots.parquet", folder / "adsb.parquet", "--sensors",
                     folder / "sensors.json", "--truth", folder / "truth.parquet", "-o", folder / "identified.parquet",
                     "--json", folder / "summary.json")
    _ok(result)
    return result, json.loads((folder / "summary.json").read_text()), folder


@pytest.fixture(scope="module")
def two_radars(tmp_path_factory):
    folder = _simulate("two_radars", tmp_path_factory.mktemp("two"), duration_s=200.0, traffic=6)
    return folder, _track(folder, "radar_west"), _track(folder, "radar_east")


def test_adsb_flow_labels_no_track_wrongly_and_leaves_the_offset_aircraft_unidentified(adsb_run):
    result, summary, _ = adsb_run
    report = summary["report"]
    assert summary["other_kind"] == "adsb"
    assert report["totals"]["wrong_label_rows"] == 0
    faulty = {row["target_id"]: row for row in report["adsb_faulty"]}
    assert set(faulty) == {"OFS1"} and faulty["OFS1"]["left_unidentified"]
    assert faulty["OFS1"]["adsb_offset_m"] == pytest.approx(2000.0, abs=10.0)  # the 2 km fault, 10 m reports
    assert report["totals"]["sound_identified"] == report["totals"]["sound_tracked_long_enough"] >= 5
    assert report["passed"]
    # the printed report: the acceptance verdicts and the faulty aircraft's finding
    assert "no track row has a wrong label" in result.output
    assert "OFS1: faulty ADS-B" in result.output and "left unidentified" in result.output


def test_adsb_flow_writes_labelled_tracks_and_the_decided_pairs(adsb_run):
    _, summary, folder = adsb_run
    tracks = pd.read_parquet(folder / "identified.parquet")
    labelled = tracks[tracks["icao24"].notna()]
    assert len(labelled) == summary["labelled_rows"] > 0
    assert set(labelled["identity_source"]) == {"adsb"}
    assert labelled["identity_p"].between(0.0, 1.0).all()
    pairs = pd.read_parquet(summary["pairs_file"])
    assert len(pairs) == summary["pair_rows"] == summary["labelled_rows"]


def test_radar_to_radar_pairs_every_object_and_none_wrongly(two_radars):
    folder, west, east = two_radars
    result = _invoke("identify", "tracks", west, east, "--sensors", folder / "sensors.json", "--truth",
                     folder / "truth.parquet", "-o", folder / "west_id.parquet", "--json", folder / "west_id.json")
    _ok(result)
    summary = json.loads((folder / "west_id.json").read_text())
    totals = summary["report"]["totals"]
    assert summary["other_kind"] == "radar"
    assert totals["wrong_pair_rows"] == 0
    assert totals["objects_paired"] == totals["objects_both"] >= 5
    assert summary["report"]["passed"] and "pass: no wrong pair" in result.output


def test_fuse_moves_only_the_paired_rows(two_radars):
    folder, west, east = two_radars
    _ok(_invoke("identify", "tracks", west, east, "--sensors", folder / "sensors.json", "--fuse",
                "-o", folder / "fused.parquet"))
    raw, fused = pd.read_parquet(west), pd.read_parquet(folder / "fused.parquet")
    pairs = pd.read_parquet(folder / "fused.pairs.parquet")
    paired = pd.MultiIndex.from_frame(fused[["time", "track_id"]]).isin(
        pd.MultiIndex.from_frame(pairs[["time", "track_id"]]))
    assert paired.sum() > 0
    moved = (fused["x"].to_numpy() != raw["x"].to_numpy()) | (fused["y"].to_numpy() != raw["y"].to_numpy())
    assert np.array_equal(moved, paired)
    assert np.array_equal(fused["var_x"].to_numpy() != raw["var_x"].to_numpy(), paired)
    unpaired = ~paired
    pd.testing.assert_frame_equal(fused[unpaired].drop(columns=["icao24", "callsign", "identity_source", "identity_p"]),
                                  raw[unpaired].drop(columns=["icao24", "callsign", "identity_source", "identity_p"]),
                                  check_dtype=False)


def _distance_to_nearest_aircraft(tracks: pd.DataFrame, truth: pd.DataFrame) -> np.ndarray:
    """Horizontal distance (m) of every track row to the nearest truth aircraft at the row's time."""
    distance = np.full(len(tracks), np.inf)
    t = tracks["time"].to_numpy()
    for _, path in truth.groupby("target_id"):
        inside = (t >= path["time"].min()) & (t <= path["time"].max())
        x = np.interp(t, path["time"], path["x"])
        y = np.interp(t, path["time"], path["y"])
        distance = np.where(inside, np.minimum(distance, np.hypot(tracks["x"] - x, tracks["y"] - y)), distance)
    return distance


def test_radar_to_interrogator_pairs_every_object_and_none_wrongly(tmp_path):
    folder = _simulate("radar_interrogator", tmp_path, duration_s=200.0, traffic=6)
    radar, interrogator = _track(folder, "radar"), _track(folder, "interrogator")
    result = _invoke("identify", "tracks", radar, interrogator, "--source", "iff", "--sensors",
                     folder / "sensors.json", "--truth", folder / "truth.parquet", "-o", folder / "id.parquet",
                     "--json", folder / "id.json")
    _ok(result)
    summary = json.loads((folder / "id.json").read_text())
    totals = summary["report"]["totals"]
    assert summary["other_kind"] == "iff"
    assert totals["wrong_pair_rows"] == 0
    # the interrogator hears only transponder aircraft: fewer objects than the radar tracks
    truth_ids = set(pd.read_parquet(folder / "plots.parquet").query("sensor == 'interrogator'")["truth_id"]) - {""}
    assert totals["objects_paired"] == totals["objects_both"] >= len(truth_ids) - 2
    assert summary["report"]["passed"]
    # fused with the interrogator's replies (20 m, 0.04 deg, Mode C heights), the radar's paired rows
    # come closer to the aircraft than its own track: the 2-D radar has no height, so its ground
    # range is off by up to h^2 / 2r (several hundred metres)
    _ok(_invoke("identify", "tracks", radar, interrogator, "--source", "iff", "--sensors", folder / "sensors.json",
                "--fuse", "-o", folder / "fused.parquet"))
    own, fused = pd.read_parquet(radar), pd.read_parquet(folder / "fused.parquet")
    truth = pd.read_parquet(folder / "truth.parquet")
    paired = (fused["x"] != own["x"]).to_numpy()
    own_error = _distance_to_nearest_aircraft(own[paired], truth)
    fused_error = _distance_to_nearest_aircraft(fused[paired], truth)
    assert np.sqrt(np.mean(fused_error ** 2)) < np.sqrt(np.mean(own_error ** 2))  # 231 m against 349 m


def test_a_tracks_file_without_reports_names_the_reports_option(two_radars, tmp_path):
    folder, west, east = two_radars
    bare = tmp_path / "bare.parquet"
    shutil.copy(east, bare)
    result = _invoke("identify", "tracks", west, bare, "-o", tmp_path / "out.parquet")
    assert result.exit_code == 2
    assert "bare.parquet: no track reports beside it" in result.output and "--reports" in result.output


def test_plots_without_sensors_are_refused(adsb_run, tmp_path):
    _, _, folder = adsb_run
    result = _invoke("identify", "tracks", folder / "plots.parquet", folder / "adsb.parquet",
                     "-o", tmp_path / "out.parquet")
    assert result.exit_code == 2
    assert "holds plots: give --sensors" in result.output

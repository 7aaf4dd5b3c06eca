"""ASTERIX output of the pipelines (issue 11 item 2): ``track ... -o tracks.ast`` (CAT062) decoded with
libasterix against the Parquet tracks of the same run."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from skytrack.app.run import run_tracking
from skytrack.app.simulate import run_simulation, write_simulation
from skytrack.io import read_sensors, read_tracks
from skytrack.io.asterix.cat062 import time_of_day_at_epoch
from skytrack.io.asterix.cat062_read import decode_cat062
from skytrack.io.tracks import read_tracks_metadata


@pytest.fixture(scope="module")
def crossing(tmp_path_factory):
    out = tmp_path_factory.mktemp("crossing")
    paths = write_simulation(run_simulation("crossing", seed=5), out, "parquet")
    sensors = json.loads(paths["sensors"].read_text())
    sensors["system"] = {"sac": 25, "sic": 201}
    paths["sensors"].write_text(json.dumps(sensors))
    return paths


def _libasterix_records(data: bytes) -> list:
    """Every record of ``data`` parsed by libasterix itself (independently of skytrack's decoder)."""
    import asterix.generated as gen
    from asterix.base import Bits, RawDatablock

    blocks = RawDatablock.parse(Bits.from_bytes(data))
    assert not isinstance(blocks, ValueError)
    records = []
    for block in blocks:
        assert block.get_category() == 62
        parsed = gen.Cat_062_1_21.cv_uap.parse(block.get_raw_records())
        assert not isinstance(parsed, ValueError)
        records.extend(parsed)
    return records


def test_tracks_ast_decodes_to_the_parquet_tracks_within_the_cat062_resolutions(crossing, tmp_path):
    parquet = run_tracking(crossing["plots"], crossing["sensors"], tmp_path / "tracks.parquet", chunk_rows=150)
    asterix = run_tracking(crossing["plots"], crossing["sensors"], tmp_path / "tracks.ast", chunk_rows=150)
    want = read_tracks(tmp_path / "tracks.parquet")
    assert asterix.track_rows == parquet.track_rows == len(want) > 100
    data = (tmp_path / "tracks.ast").read_bytes()

    # libasterix alone: one record per row, track numbers, position (0.5 m) and time (1/128 s)
    records = _libasterix_records(data)
    assert len(records) == len(want)
    sensors = read_sensors(crossing["sensors"])
    epoch_tod = time_of_day_at_epoch(sensors.epoch_utc)
    assert epoch_tod == 8 * 3600.0
    numbers = np.array([r.get_item("040").as_uint() for r in records])
    assert (numbers == want["track_id"].to_numpy() % 65536).all()
    x = np.array([r.get_item("100").variation.get_item("X").variation.content.as_quantity("m") for r in records])
    assert np.abs(x - want["x"].to_numpy()).max() <= 0.25 + 1e-9
    tod = np.array([r.get_item("070").variation.content.as_quantity("s") for r in records])
    assert np.abs(tod - epoch_tod - want["time"].to_numpy()).max() <= 1 / 256 + 1e-9
    sac_sic = {(r.get_item("010").variation.get_item("SAC").as_uint(), r.get_item("010").variation.get_item("SIC").as_uint())
               for r in records}
    assert sac_sic == {(25, 201)}

    # every column skytrack writes, decoded by libasterix (and the numpy engine reads the same)
    got = decode_cat062(data, time_of_day_at_epoch_s=epoch_tod, origin=sensors.origin, engine="libasterix")
    fast = decode_cat062(data, time_of_day_at_epoch_s=epoch_tod, origin=sensors.origin, engine="numpy")
    pd.testing.assert_frame_equal(fast, got, check_dtype=False)
    tolerances = {"time": 1 / 256, "x": 0.25, "y": 0.25, "vx": 0.125, "vy": 0.125, "lat": 90 / 2**25,
                  "lon": 90 / 2**25, "alt_m": 12.5 * 0.3048}  # 2-D: alt_m is the Mode C height, I062/136 (1/4 FL)
    for name, tolerance in tolerances.items():
        error = np.abs(got[name].to_numpy(float) - want[name].to_numpy(float))
        assert np.isnan(error).sum() == want[name].isna().sum() == 0 and error.max() <= tolerance + 1e-9, name
    for name in ("status", "mode3a"):
        assert [None if pd.isna(v) else v for v in got[name]] == [None if pd.isna(v) else v for v in want[name]], name
    assert want["mode3a"].notna().any() and set(want["status"]) == {"confirmed", "coasting"}
    assert (got["track_id"].to_numpy() == want["track_id"].to_numpy()).all()  # < 65 536 here
    std = np.sqrt(want["var_x"].to_numpy())
    assert np.abs(np.sqrt(got["var_x"].to_numpy()) - np.minimum(std, 32767.5)).max() <= 0.25 + 1e-9

    # the run metadata Parquet keeps inside the file is in the sidecar tracks.ast.meta.json
    assert read_tracks_metadata(tmp_path / "tracks.ast") == read_tracks_metadata(tmp_path / "tracks.parquet")
    assert (tmp_path / "tracks.ast.meta.json").exists()
    # identity events beside it stay a table
    assert asterix.identity_events_file == str(tmp_path / "tracks.identity.parquet")

    # read_tracks (and so skytrack evaluate) takes tracks.ast: the same table within the CAT062 resolutions,
    # the same GOSPA within what those resolutions move it (positions 0.25 m)
    from skytrack.analysis import evaluate
    from skytrack.io import read_truth

    read_back = read_tracks(tmp_path / "tracks.ast")
    assert len(read_back) == len(want) and np.abs(read_back["time"].to_numpy() - want["time"].to_numpy()).max() <= 1 / 256
    truth = read_truth(crossing["truth"], sensors=sensors)
    gospa = [evaluate(table, truth, horizontal=True).summary["gospa_mean_m"] for table in (want, read_back)]
    assert gospa[1] == pytest.approx(gospa[0], abs=0.5)


def _simulate(tmp_path, fmt: str, scenario: str = "adsb_identification", duration: str = "60"):
    from typer.testing import CliRunner

    from skytrack.cli.main import app

    out = tmp_path / fmt
    result = CliRunner().invoke(app, ["simulate", scenario, "--seed", "4", "--duration", duration, "--format", fmt,
                                      "-o", str(out)])
    assert result.exit_code == 0, result.output
    return out


def test_simulate_asterix_decodes_to_the_parquet_plots_after_quantisation(tmp_path):
    from skytrack.io import read_adsb, read_plots
    from skytrack.io.asterix import decode_asterix

    asterix, parquet = _simulate(tmp_path, "asterix"), _simulate(tmp_path, "parquet")
    assert sorted(p.name for p in asterix.iterdir()) == ["plots.ast", "sensors.json", "truth.parquet"]
    sensors = read_sensors(asterix / "sensors.json")
    radar = sensors.sensors[0]
    pair = (radar.sac, radar.sic) if hasattr(radar, "sac") else (radar.extra["sac"], radar.extra["sic"])
    assert pair == (0, 1) and sensors.extra["adsb_station"] == {"sac": 0, "sic": 101}
    epoch_tod = time_of_day_at_epoch(sensors.epoch_utc)
    decoded = decode_asterix((asterix / "plots.ast").read_bytes(), strict=True, origin=sensors.origin,
                             sensor_names={pair: radar.name})

    want = read_plots(parquet / "plots.parquet")
    want = want.iloc[np.argsort(want["time"].to_numpy(), kind="stable")].reset_index(drop=True)
    got = decoded.plots_frame()
    assert len(got) == len(want) > 100 and set(got["sensor"]) == {radar.name}
    assert np.abs(got["time"] - epoch_tod - want["time"]).max() <= 1 / 256 + 1e-9
    assert np.abs(got["range_m"] - want["range_m"]).max() <= 1852 / 512 + 1e-9
    azimuth_error = np.abs((got["azimuth_deg"] - want["azimuth_deg"] + 180) % 360 - 180)
    assert azimuth_error.max() <= 360 / 2**17 + 1e-9
    has_c = want["mode_c_ft"].notna()
    assert (got["mode_c_ft"].notna() == has_c).all() and has_c.any()
    assert np.abs(got["mode_c_ft"][has_c] - want["mode_c_ft"][has_c]).max() <= 12.5
    for name in ("mode3a", "mode_s"):
        assert [None if pd.isna(v) else v for v in got[name]] == [None if pd.isna(v) else v for v in want[name]], name

    # one north marker per revolution over the simulated minute: phase + k * period
    markers = decoded.north_marker_times()[pair] - epoch_tod
    expected = radar.scan_phase_s + radar.scan_period_s * np.arange(np.ceil((60 - radar.scan_phase_s) / radar.scan_period_s
                                                                            + 1e-12))
    expected = expected[expected >= 0]
    assert markers.size == expected.size and np.abs(markers - expected).max() <= 1 / 256 + 1e-9

    # CAT021: the ADS-B reports of the Parquet run, to the items' resolutions
    adsb_want = read_adsb(parquet / "adsb.parquet", sensors=sensors)
    adsb_want = adsb_want.iloc[np.argsort(adsb_want["time"].to_numpy(), kind="stable")].reset_index(drop=True)
    adsb_got = pd.DataFrame(decoded.adsb)
    assert len(adsb_got) == len(adsb_want) > 100
    assert np.abs(adsb_got["time"] - epoch_tod - adsb_want["time"]).max() <= 1 / 256 + 1e-9
    for name in ("lat", "lon"):
        assert np.abs(adsb_got[name] - adsb_want[name]).max() <= 90 / 2**30 + 1e-12, name
    assert np.abs(adsb_got["alt_m"] - adsb_want["alt_m"]).max() <= 3.125 * 0.3048 + 1e-9
    assert list(adsb_got["icao24"]) == list(adsb_want["icao24"])


def test_simulate_asterix_refuses_plots_that_cat048_cannot_carry(tmp_path):
    result = run_simulation("radar3d", seed=1, duration=20)
    with pytest.raises(ValueError, match=r"sensor \w+ \(radar-3d\): the CAT048 plots written carry no elevation"):
        write_simulation(result, tmp_path, "asterix")
    assert not (tmp_path / "plots.ast").exists()


def test_a_run_without_tracks_leaves_an_empty_cat062_file_and_its_metadata(crossing, tmp_path):
    plots = pd.read_parquet(crossing["plots"]).iloc[:3]
    plots.to_parquet(tmp_path / "few.parquet")
    summary = run_tracking(tmp_path / "few.parquet", crossing["sensors"], tmp_path / "tracks.ast")
    assert summary.track_rows == 0 and summary.no_tracks_reason
    assert (tmp_path / "tracks.ast").read_bytes() == b""
    assert len(decode_cat062(b"")) == 0
    assert read_tracks_metadata(tmp_path / "tracks.ast")["input_plots"] == 3


def test_3d_tracks_carry_a_geometric_altitude(tmp_path):
    paths = write_simulation(run_simulation("radar3d", seed=2, duration=90), tmp_path / "sim", "parquet")
    run_tracking(paths["plots"], paths["sensors"], tmp_path / "tracks.parquet")
    run_tracking(paths["plots"], paths["sensors"], tmp_path / "tracks.ast")
    want = read_tracks(tmp_path / "tracks.parquet")
    sensors = read_sensors(paths["sensors"])
    got = decode_cat062((tmp_path / "tracks.ast").read_bytes(), origin=sensors.origin,
                        time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc))
    assert len(got) == len(want) > 20 and want["z"].notna().all()
    assert np.abs(got["alt_m"] - want["alt_m"]).max() <= 3.125 * 0.3048 + 1e-9  # I062/130, 6.25 ft
    # z from the decoded lat/lon/alt_m: the altitude's half LSB, and ~1e-5 m from the position's
    assert np.abs(got["z"] - want["z"]).max() <= 3.125 * 0.3048 + 1e-3
    assert np.abs(got["vz"] - want["vz"]).max() <= 3.125 * 0.3048 / 60 + 1e-9  # I062/220, 6.25 ft/min
    std_z = np.minimum(np.sqrt(want["var_z"]), 255 * 6.25 * 0.3048)
    assert np.abs(np.sqrt(got["var_z"]) - std_z).max() <= 3.125 * 0.3048 + 1e-9

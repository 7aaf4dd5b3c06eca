"""CAT021 ADS-B reports in the live feed label the tracks of skytrack serve (skytrack.service.live_adsb)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from skytrack.io.asterix.cat021 import encode_cat021_blocks
from skytrack.io.asterix.recording import encode_recording
from skytrack.service.frames import STATUS_IDENTIFIED, decode_frame
from skytrack.service.live_adsb import adsb_table
from skytrack.service.pipeline import LivePipeline, sensor_sac_sic, time_of_day_at_epoch
from skytrack.tracker import Tracker


@pytest.fixture(scope="module")
def scene_with_adsb():
    from skytrack.sim import load_scenario, scale_traffic, simulate

    scenario = scale_traffic(load_scenario("demo"), 8)
    scenario = dataclasses.replace(scenario, traffic=dataclasses.replace(scenario.traffic, start_time_s=(0.0, 0.0)),
                                   duration_s=150.0, seed=11)
    result = simulate(scenario)
    return result.sensors, result.plots, result.adsb


def _feed(sensors, plots, adsb, seconds_per_datagram=2.0):
    """Radar and ADS-B datagrams in time order, one of each kind per ``seconds_per_datagram``."""
    epoch = time_of_day_at_epoch(sensors.epoch_utc)
    out = []
    for start in np.arange(0.0, float(plots["time"].max()) + seconds_per_datagram, seconds_per_datagram):
        radar = plots[(plots["time"] >= start) & (plots["time"] < start + seconds_per_datagram)]
        reports = adsb[(adsb["time"] >= start) & (adsb["time"] < start + seconds_per_datagram)]
        if len(reports):
            out.append(encode_cat021_blocks(reports, (0, 101), time_of_day_at_epoch_s=epoch, origin=sensors.origin))
        if len(radar):
            out.append(encode_recording(radar, sensor_sac_sic(sensors), time_of_day_at_epoch_s=epoch))
    return out


def test_feed_adsb_labels_tracks_with_callsigns(scene_with_adsb):
    sensors, plots, adsb = scene_with_adsb
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=2.0)
    labels, frames = {}, []
    for k, datagram in enumerate(_feed(sensors, plots, adsb)):
        pipeline.ingest([datagram], [float(k)], now_wall=float(k))
        for out in pipeline.step(now_wall=float(k)):
            labels.update(out.changed_labels)
            frames.append(out)
    assert pipeline.counters["adsb_reports"] == len(adsb) == pipeline.counters["adsb_reports_used"]
    assert pipeline.counters["adsb_reports_late"] == 0
    # the labeller keeps only the reports it has not read: bounded however long the feed runs
    assert len(pipeline.labeler.other.time) < 0.1 * len(adsb)
    callsigns = {label["callsign"] for label in labels.values() if label["callsign"]}
    truth_callsigns = set(adsb["callsign"].dropna())
    assert len(callsigns) >= 5 and callsigns <= truth_callsigns
    last = decode_frame(frames[-1].frame)
    assert (last["status"] & STATUS_IDENTIFIED).sum() >= 5


def test_adsb_reports_older_than_what_was_read_are_late(scene_with_adsb):
    sensors, plots, adsb = scene_with_adsb
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=2.0)
    feed = _feed(sensors, plots[plots["time"] < 60], adsb[adsb["time"] < 60])
    for k, datagram in enumerate(feed):
        pipeline.ingest([datagram], [float(k)], now_wall=float(k))
        pipeline.step(now_wall=float(k))
    read = pipeline.labeler.other_next
    assert read > 0 or pipeline.counters["adsb_reports_used"] > 0
    old = adsb[adsb["time"] < 10].iloc[:5]
    old_datagram = encode_cat021_blocks(old, (0, 101), time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc),
                                        origin=sensors.origin)
    pipeline.ingest([old_datagram], [99.0], now_wall=99.0)
    assert pipeline.counters["adsb_reports_late"] == 5


def test_adsb_table_from_decoded_columns(scene_with_adsb):
    sensors, _, _ = scene_with_adsb
    origin = sensors.origin
    columns = {"icao24": np.array(["abc123", None, "def456"], object), "lat": np.array([origin.lat, 48.0, np.nan]),
               "lon": np.array([origin.lon, 2.0, 2.0]), "alt_m": np.array([1000.0, 900.0, 800.0]),
               "nacp": np.array([8.0, np.nan, 9.0]), "callsign": np.array(["AFR1", None, None], object)}
    table = adsb_table(columns, np.array([1.0, 2.0, 3.0]), origin)
    assert len(table) == 1  # no address, no position: left out
    row = table.iloc[0]
    assert (row["time"], row["icao24"], row["callsign"]) == (1.0, "abc123", "AFR1")
    assert abs(row["x"]) < 1e-6 and abs(row["y"]) < 1e-6
    assert row["sigma_m"] == pytest.approx(92.6 / 2.4477, rel=1e-3)  # NACp 8: EPU 92.6 m
    assert isinstance(table, pd.DataFrame)


def test_a_checkpoint_keeps_the_live_labeller(scene_with_adsb, tmp_path):
    from skytrack.app.checkpoint import load_checkpoint, save_checkpoint

    sensors, plots, adsb = scene_with_adsb
    feed = _feed(sensors, plots, adsb)
    half = len(feed) // 2
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=2.0)
    for k, datagram in enumerate(feed[:half]):
        pipeline.ingest([datagram], [float(k)], now_wall=float(k))
        pipeline.step(now_wall=float(k))
    save_checkpoint(tmp_path / "c.npz", pipeline.tracker, pipeline.labeler)
    tracker, labeler = load_checkpoint(tmp_path / "c.npz", sensors)
    assert labeler is not None and len(labeler.other.time) == len(pipeline.labeler.other.time)
    resumed = LivePipeline(sensors, tracker, window_s=2.0, labeler=labeler)
    labels = {}
    for k, datagram in enumerate(feed[half:], start=half):
        resumed.ingest([datagram], [float(k)], now_wall=float(k))
        for out in resumed.step(now_wall=float(k)):
            labels.update(out.changed_labels)
    assert resumed.counters["adsb_reports_late"] == 0 and resumed.counters["tracker_errors"] == 0
    assert len({label["callsign"] for label in labels.values() if label["callsign"]}) >= 5

"""The service's tracking side (skytrack.service.reorder, skytrack.service.pipeline): reorder buffer, late plots,
datagrams to frames, SAC/SIC and time-of-day mapping."""

from __future__ import annotations

import numpy as np
import pytest

from skytrack.core.plots import PlotBatch
from skytrack.io.asterix.recording import encode_recording
from skytrack.service.frames import STATUS_CONFIRMED, decode_frame
from skytrack.service.pipeline import LivePipeline, local_velocity, sensor_sac_sic, time_of_day_at_epoch
from skytrack.service.reorder import ReorderBuffer
from skytrack.service.replay import scan_blocks
from skytrack.tracker import Tracker


def _batch(times, sensors) -> PlotBatch:
    n = len(times)
    empty = PlotBatch.empty()
    return PlotBatch(np.asarray(times, float), np.asarray(sensors, np.int16), np.full(n, 1e4), np.zeros(n),
                     np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan), np.full(n, -1, np.int32),
                     np.full(n, -1, np.int32), np.full(n, -1, np.int8), np.full((n, 6), np.nan),
                     np.arange(n, dtype=empty.row.dtype))


def test_reorder_releases_in_time_order_and_counts_late_plots():
    buffer = ReorderBuffer(n_sensors=2, window_s=2.0)
    assert buffer.add(_batch([10.0, 9.0, 11.5], [0, 1, 0]), 100.0, now_wall=100.0) == 0
    released, received = buffer.release(now_wall=100.0)
    # newest 11.5, window 2 s: plots before 9.5 go
    assert released.time.tolist() == [9.0] and received.tolist() == [100.0]
    assert buffer.add(_batch([9.2, 12.5, 10.5], [1, 1, 0]), 101.0, now_wall=101.0) == 1  # 9.2 < 9.5: late
    assert buffer.late_per_sensor.tolist() == [0, 1]
    released, received = buffer.release(now_wall=101.0)
    assert released.time.tolist() == [10.0] and released.sensor.tolist() == [0]  # before 12.5 - 2
    assert buffer.released_until == 10.5
    # the feed goes quiet: after idle_flush_s (max(window, 1 s)) of wall time everything is released, in order
    assert len(buffer.release(now_wall=102.5)[0]) == 0
    released, received = buffer.release(now_wall=103.5)
    assert released.time.tolist() == [10.5, 11.5, 12.5] and received.tolist() == [101.0, 100.0, 101.0]
    assert buffer.add(_batch([12.4, 12.5], [0, 0]), 104.0, now_wall=104.0) == 1  # 12.5 itself may still come
    assert buffer.late == 2 and buffer.released_total == 5 and len(buffer) == 1


def test_reorder_window_must_be_non_negative():
    with pytest.raises(ValueError, match="reorder window must be >= 0"):
        ReorderBuffer(1, -1.0)


def test_sac_sic_default_and_given(small_scene):
    sensors, _ = small_scene
    assert sensor_sac_sic(sensors) == {"radar1": (0, 1)}
    radar = sensors.sensors[0]
    radar.sac, radar.sic = 25, 7  # sensors.json's optional sac/sic fields
    try:
        assert sensor_sac_sic(sensors) == {"radar1": (25, 7)}
    finally:
        radar.sac = radar.sic = None
    assert time_of_day_at_epoch("2021-10-07T12:00:00Z") == 43200.0
    assert time_of_day_at_epoch("2021-10-07T23:59:30.5+00:00") == 86370.5 and time_of_day_at_epoch(None) == 0.0


def _datagrams(plots, sensors, records_per_block=20) -> list[bytes]:
    data = encode_recording(plots, sensor_sac_sic(sensors), max_records_per_block=records_per_block,
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc))
    starts = scan_blocks(np.frombuffer(data, np.uint8)).block_starts
    ends = np.append(starts[1:], len(data))
    return [data[a:b] for a, b in zip(starts, ends)]


def _run(sensors, datagrams, per_tick=3) -> tuple[LivePipeline, list]:
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=8.0)
    frames = []
    for k in range(0, len(datagrams), per_tick):
        pipeline.ingest(datagrams[k:k + per_tick], [float(k)] * per_tick, now_wall=float(k))
        frames += pipeline.step(now_wall=float(k))
    frames += pipeline.step(now_wall=1e9)  # idle: the rest is released
    return pipeline, frames


def test_out_of_order_datagrams_within_the_window_track_as_in_order(small_scene):
    sensors, plots = small_scene
    datagrams = _datagrams(plots, sensors)
    in_order, frames = _run(sensors, datagrams)
    # swap neighbouring datagrams (each spans well under the 8 s window)
    shuffled = list(datagrams)
    for k in range(0, len(shuffled) - 1, 2):
        shuffled[k], shuffled[k + 1] = shuffled[k + 1], shuffled[k]
    swapped, frames_swapped = _run(sensors, shuffled)
    assert in_order.counters["plots_late"] == swapped.counters["plots_late"] == 0
    assert in_order.counters["plots_tracked"] == swapped.counters["plots_tracked"] == len(plots)
    assert len(frames) == len(frames_swapped) > 20
    for a, b in zip(frames, frames_swapped):
        fa, fb = decode_frame(a.frame), decode_frame(b.frame)
        assert fa["t_s"] == fb["t_s"]
        np.testing.assert_array_equal(fa["track_id"], fb["track_id"])
        np.testing.assert_array_equal(fa["lat_deg"], fb["lat_deg"])


def test_frames_show_the_aircraft_moving(small_scene):
    sensors, plots = small_scene
    pipeline, frames = _run(sensors, _datagrams(plots, sensors))
    last = decode_frame(frames[-1].frame)
    # the scene's aircraft in coverage are all tracked by the end (15 in the truth, some may be out of coverage)
    assert 10 <= last["n"] <= 20 and (last["status"] & STATUS_CONFIRMED).all()
    assert pipeline.confirmed_tracks >= last["n"]
    # a track in two frames 8 s apart moved by its velocity (within 15 m/s x 8 s)
    by_time = {decode_frame(f.frame)["t_s"]: decode_frame(f.frame) for f in frames}
    t1 = last["t_s"] - 8.0
    earlier = by_time[t1]
    common = np.intersect1d(earlier["track_id"], last["track_id"])
    assert len(common) >= 8
    i0 = np.searchsorted(earlier["track_id"], common) if np.all(np.diff(earlier["track_id"]) > 0) else \
        np.array([np.flatnonzero(earlier["track_id"] == c)[0] for c in common])
    i1 = np.array([np.flatnonzero(last["track_id"] == c)[0] for c in common])
    north_m = (last["lat_deg"][i1].astype(float) - earlier["lat_deg"][i0]) * 111_200.0
    predicted = 8.0 * (earlier["vn_mps"][i0] + last["vn_mps"][i1]) / 2
    assert np.median(np.abs(north_m - predicted)) < 120.0
    speeds = np.hypot(last["ve_mps"], last["vn_mps"])
    # the random traffic flies 110-250 m/s; the scripted aircraft include slower ones
    assert 110 <= np.median(speeds) <= 250 and np.all((speeds > 30) & (speeds < 320))
    # Mode 3/A: the scene's aircraft all have transponders
    assert (last["mode3a"] != 0xFFFF).mean() > 0.8


def test_unknown_sac_sic_and_damaged_datagrams_are_counted(small_scene):
    sensors, plots = small_scene
    head = plots.iloc[:40]
    good = _datagrams(head, sensors)
    foreign = encode_recording(head.assign(sensor="other"), {"other": (9, 9)}, max_records_per_block=40)
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=2.0)
    pipeline.ingest([foreign], [0.0], now_wall=0.0)
    assert pipeline.counters["plots_unknown_sensor"] == 40 and dict(pipeline.unknown_sac_sic) == {"9/9": 40}
    pipeline.ingest([good[0][:-5]], [0.0], now_wall=0.0)  # a truncated block
    assert pipeline.counters["decode_problems"] >= 1 and sum(pipeline.problems.values()) >= 1


def test_local_velocity_turns_north_at_a_distant_track():
    # a track due east of the origin by 10 deg of longitude, flying common-frame north (+y):
    # its own north is tilted, so east-west stays ~0 and the speed is kept
    ve, vn, vu = local_velocity(np.array([0.0]), np.array([200.0]), np.array([np.nan]), np.array([45.0]),
                                np.array([10.0]), 45.0, 0.0)
    assert np.hypot(ve, vn)[0] == pytest.approx(200.0, rel=2e-3)
    assert vn[0] > 195.0 and np.isnan(vu[0])
    ve, vn, vu = local_velocity(np.array([100.0]), np.array([0.0]), np.array([5.0]), np.array([45.0]),
                                np.array([0.0]), 45.0, 0.0)
    assert (ve[0], vn[0], vu[0]) == pytest.approx((100.0, 0.0, 5.0), abs=1e-9)


def test_cat021_reports_in_the_feed_are_counted(small_scene):
    import pandas as pd

    from skytrack.io.asterix.cat021 import cat021_blocks, encode_cat021

    sensors, plots = small_scene
    adsb = pd.DataFrame({"time": [1.0, 2.0, 3.0], "icao24": ["4ca7b5", "4ca7b5", "3c6a01"],
                         "lat": [48.9, 48.91, 49.0], "lon": [2.5, 2.51, 2.6], "alt_m": [9000.0, 9001.0, 7000.0]})
    blocks = cat021_blocks(encode_cat021(adsb, (0, 101)))
    pipeline = LivePipeline(sensors, Tracker(sensors), window_s=2.0)
    pipeline.ingest([b"".join(blocks) if isinstance(blocks, list) else blocks] + _datagrams(plots.iloc[:10], sensors),
                    [0.0, 0.0], now_wall=0.0)
    assert pipeline.counters["adsb_reports"] == 3 and pipeline.counters["plots_received"] == 10
    assert pipeline.counters["decode_problems"] == 0

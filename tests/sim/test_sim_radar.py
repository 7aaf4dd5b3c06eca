"""Rotating radars: beam-crossing times, detection statistics, noise, SSR, clutter, frames, merging."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pymap3d
import pytest
from scipy.stats import chi2, chisquare, kstest

from sim_builders import noise_free, radar, ring_of_targets, scenario, target
from skytrack.sim import PLOT_COLUMNS, beam_azimuth_deg, load_scenario, scan_index, simulate
from skytrack.sim.radar import polar_view


def run(data, **kw):
    return simulate(load_scenario(data), **kw)


def target_rows(result, plots: pd.DataFrame) -> np.ndarray:
    index = {name: i for i, name in enumerate(result.trajectories.ids)}
    return np.array([index[name] for name in plots["truth_id"]], dtype=int)


def true_polar(result, plots: pd.DataFrame, sensor_name: str):
    """Noise-free range, azimuth, elevation (rad) and range rate of each target plot at its time."""
    state = result.trajectories.state(target_rows(result, plots), plots["time"].to_numpy())
    position = np.stack([state["x"], state["y"], state["z"]], axis=1)
    velocity = np.stack([state["vx"], state["vy"], state["vz"]], axis=1)
    r, az, el, rdot, _ = polar_view(result.sensors[sensor_name], position, velocity)
    return r, az, el, rdot, state


def angle_difference_deg(a, b):
    return (np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0


def binomial_band(observed, n, p, sigmas=4.0) -> bool:
    return abs(observed - n * p) <= sigmas * math.sqrt(n * p * (1.0 - p))


def test_plot_columns_types_and_order():
    result = run(scenario(ring_of_targets(6, mode3a="1234"), sensors=[radar(clutter_per_scan=5.0)], duration_s=40.0))
    plots = result.plots
    assert tuple(plots.columns) == PLOT_COLUMNS
    assert plots["time"].is_monotonic_increasing
    assert plots["time"].dtype == np.float64 and plots["scan"].dtype == np.int64
    assert plots["elevation_deg"].isna().all() and plots["range_rate_mps"].isna().all() and plots["iff"].isna().all()
    assert ((plots["azimuth_deg"] >= 0) & (plots["azimuth_deg"] < 360)).all() and (plots["range_m"] >= 0).all()
    assert set(plots["truth_id"]) == {""} | {f"r{i:03d}" for i in range(6)}
    assert (plots["sensor"] == "radar1").all()


@pytest.mark.parametrize("phase", [0.0, 1.3])
def test_plot_time_is_when_the_beam_crosses_the_target(phase):
    targets = ring_of_targets(12, range_m=8000.0, speed_mps=250.0) + [target("far", x=-150000.0, y=90000.0, heading_deg=45.0)]
    result = run(scenario(targets, sensors=[noise_free(scan_phase_s=phase)], duration_s=60.0))
    plots = result.plots
    sensor = result.sensors["radar1"]
    r, az, _, _, _ = true_polar(result, plots, "radar1")
    beam = beam_azimuth_deg(sensor, plots["time"])
    assert np.abs(angle_difference_deg(np.degrees(az), beam)).max() < 1e-5
    assert np.abs(angle_difference_deg(plots["azimuth_deg"], beam)).max() < 1e-5
    np.testing.assert_allclose(plots["range_m"], r, rtol=1e-12)
    expected_scan = np.floor((plots["time"] - phase) / 4.0) - math.floor(-phase / 4.0)
    np.testing.assert_array_equal(plots["scan"], expected_scan)
    np.testing.assert_array_equal(scan_index(sensor, plots["time"]), plots["scan"])


@pytest.mark.parametrize("phase", [0.0, 2.9])
def test_targets_crossing_north_are_seen_exactly_once_per_revolution(phase):
    # passes 5 km north of the radar clockwise: azimuth sweeps 297 -> 0 -> 63 deg during the run
    clockwise = target("cw", x=-10000.0, y=5000.0, heading_deg=90.0, speed_mps=250.0, alt_m=3000.0)
    # crosses north the other way round, 4 km out
    anticlockwise = target("acw", x=6000.0, y=4000.0, heading_deg=270.0, speed_mps=200.0, alt_m=3000.0)
    result = run(scenario([clockwise, anticlockwise], sensors=[noise_free(scan_phase_s=phase)], duration_s=80.0))
    for name in ("cw", "acw"):
        plots = result.plots[result.plots.truth_id == name]
        assert (plots.azimuth_deg > 340).any() and (plots.azimuth_deg < 20).any()
        # successive crossings are T / (1 -+ T * angular rate / 360 deg) apart: never a lost or a
        # doubled revolution, also across north (the angular rate is at most 3.6 deg/s here)
        times = np.concatenate([[0.0], plots["time"].to_numpy(), [80.0]])
        gaps = np.diff(times)
        assert gaps[1:-1].min() > 4.0 / (1 + 4.0 * 3.6 / 360.0) - 1e-6
        assert gaps.max() < 4.0 / (1 - 4.0 * 3.6 / 360.0) + 1e-6
    # a revolution number is north to north: crossing north with the beam skips one scan
    # number, against the beam gives two plots with the same scan number, as with a real antenna
    cw_scans = result.plots[result.plots.truth_id == "cw"].scan.to_numpy()
    acw_scans = result.plots[result.plots.truth_id == "acw"].scan.to_numpy()
    assert sorted(set(np.diff(cw_scans))) == [1, 2] and list(np.diff(cw_scans)).count(2) == 1
    assert sorted(set(np.diff(acw_scans))) == [0, 1] and list(np.diff(acw_scans)).count(0) == 1


def test_empirical_detection_probability_within_a_binomial_band():
    targets = ring_of_targets(40)
    all_crossings = run(scenario(targets, sensors=[radar(p_detection=1.0)], duration_s=300.0))
    n = len(all_crossings.plots)
    assert 40 * 74 <= n <= 40 * 75  # targets flying clockwise lose a fraction of a revolution
    detected = run(scenario(targets, sensors=[radar(p_detection=0.8)], duration_s=300.0))
    assert binomial_band(len(detected.plots), n, 0.8)
    assert set(zip(detected.plots.truth_id, detected.plots.scan)) <= set(zip(all_crossings.plots.truth_id, all_crossings.plots.scan))


def test_clutter_count_is_poisson_and_uniform_in_area():
    lam, scans = 30.0, 100
    sensor = radar(clutter_per_scan=lam, max_range_m=200000.0, clutter_distribution="area")
    result = run(scenario([], sensors=[sensor], duration_s=4.0 * scans))
    clutter = result.plots
    assert (clutter["truth_id"] == "").all()
    assert clutter[["mode3a", "mode_c_ft", "mode_s"]].isna().all().all()
    complete = clutter[clutter.scan < scans]
    per_scan = complete.groupby("scan").size().reindex(range(scans), fill_value=0).to_numpy()
    total = per_scan.sum()
    assert abs(total - lam * scans) < 4.0 * math.sqrt(lam * scans)
    dispersion = np.sum((per_scan - lam) ** 2) / lam  # ~ chi-square(scans) for Poisson counts
    assert chi2.ppf(1e-4, scans) < dispersion < chi2.ppf(1 - 1e-4, scans)
    inner = (complete.range_m < 200000.0 / math.sqrt(2.0)).sum()
    assert binomial_band(inner, total, 0.5)
    assert binomial_band((complete.azimuth_deg < 90.0).sum(), total, 0.25)
    assert complete.range_m.max() <= 200000.0
    beam = beam_azimuth_deg(result.sensors["radar1"], clutter["time"])
    assert np.abs(angle_difference_deg(clutter["azimuth_deg"], beam)).max() < 1e-9


@pytest.mark.parametrize("distribution", [{}, {"clutter_distribution": "range"}], ids=["default", "range"])
def test_clutter_uniform_in_range_and_azimuth_is_dense_near_the_radar(distribution):
    """``clutter_distribution: range``, the default: range uniform on [0, max_range] (half the
    plots within half the range, a quarter of the area), azimuth uniform, still following the
    beam.  Uniformity: chi-square of a 20-bin range histogram and Kolmogorov-Smirnov, p > 1e-3."""
    scans = 100
    sensor = radar(clutter_per_scan=30.0, max_range_m=200000.0, **distribution)
    assert load_scenario(scenario([], sensors=[sensor])).radar_params["radar1"].clutter_distribution == "range"
    result = run(scenario([], sensors=[sensor], duration_s=4.0 * scans))
    complete = result.plots[result.plots.scan < scans]
    total = len(complete)
    fraction = complete.range_m.to_numpy() / 200000.0
    assert chisquare(np.histogram(fraction, bins=20, range=(0.0, 1.0))[0]).pvalue > 1e-3
    assert kstest(fraction, "uniform").pvalue > 1e-3
    assert binomial_band((complete.range_m < 100000.0).sum(), total, 0.5)
    assert binomial_band((complete.range_m < 20000.0).sum(), total, 0.1)  # 1 % of the area, 10 % of the plots
    assert binomial_band((complete.azimuth_deg < 90.0).sum(), total, 0.25)
    beam = beam_azimuth_deg(result.sensors["radar1"], result.plots["time"])
    assert np.abs(angle_difference_deg(result.plots["azimuth_deg"], beam)).max() < 1e-9


def test_measurement_noise_has_the_configured_standard_deviations():
    sensor = radar(type="radar-3d", sigma_range_m=40.0, sigma_azimuth_deg=0.07, sigma_elevation_deg=0.2, sigma_range_rate_mps=1.5)
    result = run(scenario(ring_of_targets(40), sensors=[sensor], duration_s=200.0))
    plots = result.plots
    r, az, el, rdot, _ = true_polar(result, plots, "radar1")
    residuals = {
        40.0: plots["range_m"].to_numpy() - r,
        0.07: angle_difference_deg(plots["azimuth_deg"], np.degrees(az)),
        0.2: plots["elevation_deg"].to_numpy() - np.degrees(el),
        1.5: plots["range_rate_mps"].to_numpy() - rdot,
    }
    k = len(plots)
    assert 40 * 49 <= k <= 40 * 50
    for sigma, e in residuals.items():
        statistic = np.sum(np.asarray(e) ** 2) / sigma**2  # chi-square with k degrees of freedom
        assert chi2.ppf(1e-4, k) < statistic < chi2.ppf(1 - 1e-4, k), sigma
        assert abs(np.mean(e)) < 4.0 * sigma / math.sqrt(k)


def test_range_rate_is_the_radial_velocity_positive_opening():
    sensor = noise_free(type="radar-3d", sigma_elevation_deg=0.0, sigma_range_rate_mps=0.0)
    away = target("away", x=0.0, y=30000.0, heading_deg=0.0, speed_mps=200.0, alt_m=1000.0)
    toward = target("toward", x=40000.0, y=0.0, heading_deg=270.0, speed_mps=150.0, alt_m=1000.0)
    result = run(scenario([away, toward], sensors=[sensor], duration_s=40.0))
    plots = result.plots
    _, _, el, rdot, _ = true_polar(result, plots, "radar1")
    np.testing.assert_allclose(plots["range_rate_mps"], rdot, atol=1e-9)
    np.testing.assert_allclose(plots["elevation_deg"], np.degrees(el), atol=1e-9)
    assert (plots[plots.truth_id == "away"].range_rate_mps.between(195.0, 200.0)).all()
    assert (plots[plots.truth_id == "toward"].range_rate_mps.between(-150.0, -145.0)).all()


def test_secondary_radar_replies():
    equipped = ring_of_targets(30, mode3a="2345", alt_m=7777.0)
    for i, t in enumerate(equipped[:10]):
        t["icao24"] = f"abc{i:03x}"
        t["legs"] = [{"type": "climb", "rate_mps": 9.1, "duration_s": 300}]
    silent = [target("nt", transponder=False)]
    result = run(scenario(equipped + silent, sensors=[radar(p_mode3a=0.7, p_mode_c=0.6)], duration_s=200.0))
    plots = result.plots
    replies = plots[plots.truth_id.str.startswith("r")]
    n = len(replies)
    assert binomial_band(replies.mode3a.notna().sum(), n, 0.7)
    assert binomial_band(replies.mode_c_ft.notna().sum(), n, 0.6)
    assert set(replies.mode3a.dropna()) == {"2345"}
    # Mode C: barometric height in feet rounded to 100 ft
    with_c = replies[replies.mode_c_ft.notna()]
    _, _, _, _, state = true_polar(result, with_c, "radar1")
    feet = state["alt_m"] / 0.3048
    assert (np.remainder(with_c.mode_c_ft, 100.0) == 0).all()
    assert np.abs(with_c.mode_c_ft.to_numpy() - feet).max() <= 50.0
    assert with_c.mode_c_ft.nunique() > 20  # the climbers cross many 100 ft levels
    # Mode S address on every plot of the aircraft that have one, nowhere else
    for name, group in replies.groupby("truth_id"):
        if int(name[1:]) < 10:
            assert (group.mode_s == f"abc{int(name[1:]):03x}").all()
        else:
            assert group.mode_s.isna().all()
    no_transponder = plots[plots.truth_id == "nt"]
    assert len(no_transponder) > 0 and no_transponder[["mode3a", "mode_c_ft", "mode_s"]].isna().all().all()


def test_a_sensor_away_from_the_origin_measures_in_its_own_frame():
    east = noise_free(name="east", lat=48.86, lon=4.55, alt_m=100.0)  # ~150 km east of the origin
    slow = {"id": "slow", "range_m": 60000.0, "azimuth_deg": 10.0, "sensor": "east", "alt_m": 6000.0, "speed_mps": 1.0, "heading_deg": 0.0}
    other = target("other", x=100000.0, y=80000.0, heading_deg=200.0)
    result = run(scenario([slow, other], sensors=[noise_free(), east], duration_s=30.0))
    plots = result.plots[result.plots.sensor == "east"]
    _, _, _, _, state = true_polar(result, plots, "east")
    # independent check: pymap3d's azimuth/elevation/range from the sensor's geodetic position
    az, _, slant = pymap3d.geodetic2aer(state["lat"], state["lon"], state["alt_m"], 48.86, 4.55, 100.0)
    assert np.abs(angle_difference_deg(plots["azimuth_deg"], az)).max() < 1e-6
    np.testing.assert_allclose(plots["range_m"], slant, rtol=1e-9)
    first = plots[plots.truth_id == "slow"].iloc[0]
    assert abs(angle_difference_deg(first.azimuth_deg, 10.0)) < 0.01  # where the target was placed
    sensor = result.sensors["east"]
    naive = np.degrees(np.arctan2(state["x"] - sensor.x, state["y"] - sensor.y)) % 360.0
    assert np.abs(angle_difference_deg(naive, az)).min() > 1.0  # the meridian convergence is ~1.5 deg here


def test_coverage_limits_min_elevation_and_radar_horizon():
    # 30 m antenna, 300 m target: horizon 4.12 km (sqrt(30) + sqrt(300)) = 94 km
    near = target("near", x=0.0, y=80000.0, alt_m=300.0, speed_mps=1.0, heading_deg=90.0)
    beyond = target("beyond", x=0.0, y=-100000.0, alt_m=300.0, speed_mps=1.0, heading_deg=90.0)
    low = target("low", x=30000.0, y=0.0, alt_m=1500.0, speed_mps=1.0, heading_deg=0.0)  # elevation ~2.5 deg
    sensors = [radar(min_elevation_deg=-1.0), radar(name="high", min_elevation_deg=3.0)]
    result = run(scenario([near, beyond, low], sensors=sensors, duration_s=20.0))
    seen = result.plots.groupby(["sensor", "truth_id"]).size()
    assert seen.get(("radar1", "near"), 0) == 5 and seen.get(("radar1", "beyond"), 0) == 0
    assert seen.get(("radar1", "low"), 0) == 5 and seen.get(("high", "low"), 0) == 0
    visible = result.truth.groupby("target_id").visible.all()
    assert visible["near"] and not visible["beyond"] and visible["low"]


def test_several_radars_are_merged_in_time_order():
    sensors = [radar(), radar(name="east", lat=None, lon=None, x=120000.0, y=0.0, scan_period_s=5.0, scan_phase_s=1.7, clutter_per_scan=3.0)]
    result = run(scenario(ring_of_targets(10, range_m=80000.0), sensors=sensors, duration_s=100.0))
    plots = result.plots
    assert plots["time"].is_monotonic_increasing
    per_sensor = plots[plots.truth_id != ""].groupby("sensor").size()
    assert 10 * 24 <= per_sensor["radar1"] <= 10 * 25 and 10 * 19 <= per_sensor["east"] <= 10 * 20
    east = plots[plots.sensor == "east"]
    assert east.scan.min() == 0 and east.scan.max() == 20  # 1.7 + 5 k: revolution -1 relabelled 0
    assert (plots.sensor.iloc[:-1].to_numpy() != plots.sensor.iloc[1:].to_numpy()).sum() > 50  # interleaved


def test_same_seed_gives_identical_output_and_rng_changes_only_the_sensors():
    data = scenario(ring_of_targets(8, mode3a="1200"), sensors=[radar(p_detection=0.7, clutter_per_scan=10.0, p_mode_c=0.5)], duration_s=60.0)
    data["traffic"] = {"count": 20, "region": {"type": "rectangle", "x_m": [-5e4, 5e4], "y_m": [-5e4, 5e4]}, "alt_m": [1000, 9000], "speed_mps": [100, 200], "maneuver_fraction": 0.5}
    a, b = run(data), run(data)
    pd.testing.assert_frame_equal(a.plots, b.plots)
    pd.testing.assert_frame_equal(a.truth, b.truth)
    c = run(data, rng=np.random.default_rng(123))
    pd.testing.assert_frame_equal(a.truth, c.truth)
    assert len(a.plots) != len(c.plots) or not np.array_equal(a.plots.range_m, c.plots.range_m)


def test_progress_is_reported_up_to_completion():
    seen = []
    run(scenario(ring_of_targets(5), duration_s=20.0), progress=seen.append)
    assert seen[-1] == 1.0 and all(0.0 < f <= 1.0 for f in seen) and seen == sorted(seen)

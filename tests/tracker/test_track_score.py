"""Track score, clutter map and SSR evidence (skytrack.tracker.evidence, skytrack.tracker.clutter_map).

Kernels against their numpy references, the learned clutter density against the simulated one,
Wald's thresholds, and the false-track rate the thresholds are derived from.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.sim import load_scenario, simulate
from skytrack.tracker import Tracker, TrackerConfig
from skytrack.tracker.clutter_map import ClutterMap, log_density_at, observe_kernel
from skytrack.tracker.evidence import ScoreConfig, count_codes, ssr_log_ratio, ssr_log_ratio_reference


def _map(**kw) -> ClutterMap:
    options = dict(max_range_m=100_000.0, prior_per_scan=10.0, range_cells=16, azimuth_cells=8, prior_scans=10.0,
                   memory_scans=20.0, dim=2, elevation_span_deg=20.0)
    options.update(kw)
    return ClutterMap(**options)


def test_clutter_map_kernels_equal_the_numpy_reference():
    rng = np.random.default_rng(1)
    compiled, reference = _map(), _map()
    for _ in range(40):
        count = int(rng.integers(0, 60))
        r = rng.uniform(0, 130_000.0, count)  # some beyond the map: counted in its last ring
        az = rng.uniform(-7.0, 7.0, count)  # any turn
        r[:2], az[2:4] = np.nan, np.nan
        stage = rng.integers(-1, 3, count).astype(np.int8)
        observe_kernel(r, az, stage, 0.25, compiled.grid, compiled.params, compiled.log_area)
        reference.observe(r, az, stage, 0.25)
    np.testing.assert_allclose(compiled.counts, reference.counts, rtol=1e-12)
    np.testing.assert_allclose(compiled.params[0], reference.params[0], rtol=1e-12)
    r, az = rng.uniform(0, 130_000.0, 500), rng.uniform(-7.0, 7.0, 500)
    looked_up = np.array([log_density_at(r[j], az[j], compiled.grid, compiled.params, compiled.log_area)
                          for j in range(500)])
    np.testing.assert_allclose(looked_up, reference.log_density(r, az), rtol=1e-12)


def test_forgetting_survives_the_scale_being_folded_back():
    """The counts are stored divided by the forgetting scale; when the scale gets tiny it is
    folded into the counts, which must not change any density."""
    clutter_map = _map(memory_scans=1.0)
    stage = np.array([-1], np.int8)
    for _ in range(300):  # exp(-300) < 1e-100: at least one fold
        observe_kernel(np.array([5_000.0]), np.array([0.1]), stage, 1.0, clutter_map.grid, clutter_map.params,
                       clutter_map.log_area)
    # a plot every scan in one cell, memory 1 scan: counts -> 1 / (1 - e^-1), exposure -> the same
    steady = 1.0 / (1.0 - math.exp(-1.0))
    assert clutter_map.counts[0, 0] == pytest.approx(steady, rel=1e-9)
    assert clutter_map.params[0] == pytest.approx(steady, rel=1e-9)


def test_prior_density_is_the_sensors_clutter_spread_uniformly_in_range_and_azimuth():
    clutter_map = _map()
    r = np.array([3_000.0, 50_000.0, 97_000.0])
    area = 0.5 * ((np.floor(r / 6250.0) + 1) ** 2 - np.floor(r / 6250.0) ** 2) * 6250.0**2 * (2 * np.pi / 8)
    np.testing.assert_allclose(clutter_map.log_density(r, np.zeros(3)), np.log(10.0 / 128 / area), rtol=1e-12)
    assert clutter_map.total_rate() == pytest.approx(10.0)


def test_learned_density_follows_clutter_that_is_uniform_in_range():
    """500 scans of 40 false plots per scan, uniform in range and azimuth, against a prior of 1
    per scan: the learned density per range ring is the true one, 40 / (R * 2 pi r), within 15 %
    (about 5 standard errors of the ring counts)."""
    rng = np.random.default_rng(7)
    clutter_map = _map(prior_per_scan=1.0, memory_scans=1e9)
    for _ in range(500):
        count = rng.poisson(40)
        stage = np.full(count, -1, np.int8)
        clutter_map.observe(rng.uniform(0, 100_000.0, count), rng.uniform(0, 2 * np.pi, count), stage, 1.0)
    assert clutter_map.total_rate() == pytest.approx(40.0, rel=0.02)
    mid = (np.arange(16) + 0.5) * 6250.0
    learned = np.exp(clutter_map.log_density(mid, np.full(16, 1.0)))
    ring_mean = np.exp([np.log(np.exp(clutter_map.log_density(np.full(8, m), np.linspace(0.2, 6.0, 8)))).mean()
                        for m in mid])
    truth = 40.0 / (100_000.0 * 2 * np.pi * mid)
    np.testing.assert_allclose(ring_mean[1:], truth[1:], rtol=0.15)
    assert learned[0] > 10 * learned[-1]  # dense near the radar


def test_ssr_ratio_kernel_equals_the_reference_and_rewards_matching_codes():
    rng = np.random.default_rng(3)
    n = 400
    plot_code = rng.choice([-1, 0o1234, 0o4321], n)
    track_code = rng.choice([-1, 0o1234], n)
    plot_alt = np.where(rng.random(n) < 0.3, np.nan, rng.uniform(3000, 3400, n))
    track_alt = np.where(rng.random(n) < 0.3, np.nan, 3200.0)
    dt = rng.uniform(0, 12, n)
    config = ScoreConfig()
    ssr = config.ssr_parameters(np.array([100.0, 90.0, 85.0, 100.0, 3.0, 2.0]))
    compiled = np.array([ssr_log_ratio(plot_code[j], plot_alt[j], track_code[j], track_alt[j], dt[j], ssr)
                         for j in range(n)])
    np.testing.assert_allclose(compiled, ssr_log_ratio_reference(plot_code, plot_alt, track_code, track_alt, dt, ssr),
                               rtol=1e-12, atol=1e-12)
    no_height = np.isnan(plot_alt) & np.isnan(track_alt)
    same = no_height & (plot_code == track_code) & (track_code >= 0)
    other = no_height & (plot_code >= 0) & (plot_code != track_code) & (track_code >= 0)
    # same code: ln(q_t (1 - eps) 4096 / q_c) with q_t = 0.9, q_c = 0.03
    np.testing.assert_allclose(compiled[same], math.log(0.9 * 0.99 * 4096 / 0.03))
    np.testing.assert_allclose(compiled[other], math.log(0.9 * 0.01 / 0.03))
    # unknown track code and height: no evidence either way
    assert np.all(compiled[(track_code < 0) & np.isnan(track_alt)] == 0.0)
    assert np.all(ScoreConfig(ssr=False).ssr_parameters(np.ones(6)) == 0.0)


def test_code_counts_learn_targets_from_confirmed_plots_and_false_from_unused_ones():
    counts = np.zeros(6)
    stage = np.array([0, 1, 2, -1, -1, -1], np.int8)
    count_codes(stage, np.array([5, -1, 7, 3, -1, -1]), np.array([1.0, 2.0, 3.0, np.nan, np.nan, 4.0]), counts)
    np.testing.assert_array_equal(counts, [2, 1, 2, 3, 1, 1])


def test_wald_thresholds_follow_the_stated_false_track_rate():
    config = ScoreConfig(false_tracks_per_hour=2.0, p_reject_true=0.05)
    confirm, drop = config.thresholds(clutter_per_scan=30.0, scan_period_s=4.0)
    alpha = 2.0 * 4.0 / (3600.0 * 30.0)
    assert confirm == pytest.approx(math.log(0.95 / alpha))
    assert drop == pytest.approx(math.log(0.05 / (1 - alpha)))
    with pytest.raises(ValueError, match="track_logic"):
        ScoreConfig(track_logic="sometimes")


@pytest.fixture(scope="module")
def clutter_hour():
    doc = {"name": "clutter-only", "origin": {"lat": 48.86, "lon": 2.5}, "duration_s": 3600, "seed": 3,
           "sensors": [{"name": "r", "lat": 48.86, "lon": 2.5, "alt_m": 30, "scan_period_s": 4.0,
                        "sigma_range_m": 40, "sigma_azimuth_deg": 0.07, "max_range_m": 250000, "p_detection": 0.9,
                        "clutter_per_scan": 30.0, "clutter_distribution": "range"}]}
    return simulate(load_scenario(doc))


def test_false_track_rate_stays_within_the_stated_one(clutter_hour):
    """One hour of 30 false plots per scan, dense near the radar: at a stated 1 false track per
    hour, at most 3 are confirmed (Wald's bound is conservative; P(Poisson(1) > 3) = 2 %); the
    3-of-4 rule on the same plots confirms more, and a stated 20 per hour more than 1 per hour."""
    def confirmed(config):
        tracker = Tracker(clutter_hour.sensors, config)
        tracker.run(clutter_hour.plots)
        return tracker.stats["tracks_confirmed"]

    strict = confirmed(TrackerConfig(false_tracks_per_hour=1.0))
    assert strict <= 3
    assert confirmed(TrackerConfig(track_logic="m-of-n")) > strict + 5
    assert confirmed(TrackerConfig(false_tracks_per_hour=200.0)) > strict

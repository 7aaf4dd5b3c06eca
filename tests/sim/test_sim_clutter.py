"""False plots: clutter patches (Poisson per revolution, uniform in range and azimuth, sectors
through north), random SSR replies on false plots, and the validation of their keys.

Statistical checks use fixed seeds: counts within 4 sigma of their Poisson or binomial mean,
distributions by Kolmogorov-Smirnov or chi-square tests at p > 1e-3.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2, chisquare, kstest
from sim_builders import radar, ring_of_targets, scenario

from skytrack.sim import (
    ScenarioError,
    beam_azimuth_deg,
    load_scenario,
    scan_index,
    simulate,
)

SCANS = 500

NEAR = {"range_m": [5000.0, 20000.0], "azimuth_deg": [350.0, 20.0], "per_scan": 8.0}  # through north
FAR = {"range_m": [60000.0, 80000.0], "azimuth_deg": [100.0, 130.0], "per_scan": 5.0}


def run(data, **kw):
    return simulate(load_scenario(data), **kw)


def angle_difference_deg(a, b):
    return (np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0


def within_poisson(count, mean, sigmas=4.0) -> bool:
    return abs(count - mean) <= sigmas * math.sqrt(mean)


def within_binomial(count, n, p, sigmas=4.0) -> bool:
    return abs(count - n * p) <= sigmas * math.sqrt(n * p * (1.0 - p))


@pytest.fixture(scope="module")
def patches_only():
    """Two patches and no other clutter, SCANS complete revolutions."""
    sensor = radar(clutter_patches=[NEAR, FAR])
    result = run(scenario([], sensors=[sensor], duration_s=4.0 * SCANS))
    return result, result.plots[result.plots.scan < SCANS]


def in_patch(plots: pd.DataFrame, patch: dict) -> np.ndarray:
    (near, far), (start, end) = patch["range_m"], patch["azimuth_deg"]
    offset = (plots.azimuth_deg.to_numpy() - start) % 360.0
    return (plots.range_m.to_numpy() >= near) & (plots.range_m.to_numpy() <= far) & (offset <= (end - start) % 360.0)


def test_patch_plots_are_false_plots_inside_their_patches(patches_only):
    _, plots = patches_only
    near, far = in_patch(plots, NEAR), in_patch(plots, FAR)
    assert len(plots) > 0 and (near | far).all() and not (near & far).any()
    assert (plots.truth_id == "").all()
    assert plots[["mode3a", "mode_c_ft", "mode_s"]].isna().all().all()  # no SSR on false plots by default


@pytest.mark.parametrize("patch", [NEAR, FAR], ids=["near", "far"])
def test_patch_counts_are_poisson_per_revolution(patches_only, patch):
    _, plots = patches_only
    mine = plots[in_patch(plots, patch)]
    mean = patch["per_scan"]
    per_scan = mine.groupby("scan").size().reindex(range(SCANS), fill_value=0).to_numpy()
    assert within_poisson(per_scan.sum(), mean * SCANS)
    dispersion = np.sum((per_scan - mean) ** 2) / mean  # ~ chi-square(SCANS) for Poisson counts
    assert chi2.ppf(1e-4, SCANS) < dispersion < chi2.ppf(1 - 1e-4, SCANS)


@pytest.mark.parametrize("patch", [NEAR, FAR], ids=["near", "far"])
def test_patch_plots_are_uniform_in_range_and_azimuth(patches_only, patch):
    _, plots = patches_only
    mine = plots[in_patch(plots, patch)]
    (near, far), (start, end) = patch["range_m"], patch["azimuth_deg"]
    assert kstest((mine.range_m - near) / (far - near), "uniform").pvalue > 1e-3
    width = (end - start) % 360.0
    assert kstest(((mine.azimuth_deg - start) % 360.0) / width, "uniform").pvalue > 1e-3


def test_a_patch_through_north_covers_both_sides_of_north(patches_only):
    _, plots = patches_only
    mine = plots[in_patch(plots, NEAR)]
    west_of_north = (mine.azimuth_deg >= 350.0).sum()
    assert within_binomial(west_of_north, len(mine), 10.0 / 30.0)
    assert ((mine.azimuth_deg >= 350.0) | (mine.azimuth_deg <= 20.0)).all()


def test_patch_plots_come_when_the_beam_crosses_their_azimuth(patches_only):
    result, _ = patches_only
    plots, sensor = result.plots, result.sensors["radar1"]
    assert np.abs(angle_difference_deg(plots.azimuth_deg, beam_azimuth_deg(sensor, plots.time))).max() < 1e-9
    np.testing.assert_array_equal(plots.scan, scan_index(sensor, plots.time))
    assert plots.time.between(0.0, 4.0 * SCANS).all()


def test_patch_plots_of_a_3d_radar_get_elevation_and_range_rate_like_other_false_plots():
    sensor = radar(type="radar-3d", sigma_elevation_deg=0.2, sigma_range_rate_mps=1.5, clutter_patches=[FAR],
                   clutter_elevation_deg=[1.0, 4.0], clutter_range_rate_mps=[-50.0, 50.0])
    plots = run(scenario([], sensors=[sensor], duration_s=200.0)).plots
    assert len(plots) > 100
    assert plots.elevation_deg.between(1.0, 4.0).all() and plots.range_rate_mps.between(-50.0, 50.0).all()
    assert kstest((plots.elevation_deg - 1.0) / 3.0, "uniform").pvalue > 1e-3


def test_patches_and_false_plot_replies_leave_the_other_plots_unchanged():
    """They draw their random numbers after the coverage-wide clutter: a scenario keeps its plots."""
    base = radar(clutter_per_scan=20.0, p_detection=0.8, p_mode_c=0.7)
    targets = ring_of_targets(6, mode3a="1234")
    before = run(scenario(targets, sensors=[base], duration_s=120.0)).plots
    extended = radar(clutter_per_scan=20.0, p_detection=0.8, p_mode_c=0.7, clutter_patches=[NEAR], clutter_p_mode3a=0.5)
    after = run(scenario(targets, sensors=[extended], duration_s=120.0)).plots
    assert len(after) > len(before)
    key = ["time", "range_m", "azimuth_deg", "truth_id"]
    merged = before[key].merge(after[key], how="left", on=key, indicator=True)
    assert (merged["_merge"] == "both").all()
    pd.testing.assert_frame_equal(before[before.truth_id != ""].reset_index(drop=True),
                                  after[after.truth_id != ""].reset_index(drop=True))


def test_false_plots_carry_random_mode3a_and_mode_c_with_the_given_probabilities():
    sensor = radar(clutter_per_scan=50.0, clutter_p_mode3a=0.3, clutter_p_mode_c=0.2, clutter_patches=[FAR])
    targets = ring_of_targets(4, mode3a="1234", alt_m=7000.0)
    plots = run(scenario(targets, sensors=[sensor], duration_s=400.0)).plots
    false = plots[plots.truth_id == ""]
    n = len(false)
    assert n > 4000
    with_code, with_c = false.mode3a.notna(), false.mode_c_ft.notna()
    assert within_binomial(with_code.sum(), n, 0.3) and within_binomial(with_c.sum(), n, 0.2)
    assert within_binomial((with_code & with_c).sum(), n, 0.06)  # drawn independently
    assert false.mode_s.isna().all()
    # Mode 3/A: text of 4 octal digits, uniform over 0000-7777 (chi-square over the 8 first digits)
    codes = false.mode3a.dropna()
    assert codes.str.fullmatch(r"[0-7]{4}").all()
    values = codes.map(lambda c: int(c, 8)).to_numpy()
    assert chisquare(np.bincount(values // 512, minlength=8)).pvalue > 1e-3
    assert values.min() < 0o100 and values.max() > 0o7700
    # Mode C: whole hundreds of feet, uniform over 0-45 000 ft
    feet = false.mode_c_ft.dropna().to_numpy()
    assert (np.remainder(feet, 100.0) == 0.0).all() and feet.min() >= 0.0 and feet.max() <= 45000.0
    assert kstest(feet / 45000.0, "uniform").pvalue > 1e-3
    # the targets' own replies are untouched
    replies = plots[plots.truth_id != ""]
    assert (replies.mode3a == "1234").all()
    assert np.abs(replies.mode_c_ft - 7000.0 / 0.3048).max() <= 50.0


def error_of(data) -> str:
    with pytest.raises(ScenarioError) as info:
        load_scenario(data)
    return str(info.value)


@pytest.mark.parametrize(
    ("sensor_keys", "expected"),
    [
        ({"clutter_patches": {"range_m": [0, 1]}}, "sensors[0].clutter_patches: must be a list, got"),
        ({"clutter_patches": [{"range_m": [5000, 9000], "azimuth_deg": [0, 90]}]},
         "sensors[0].clutter_patches[0].per_scan: required key is missing"),
        ({"clutter_patches": [NEAR, {**FAR, "per_scan": -1}]}, "sensors[0].clutter_patches[1].per_scan: must be >= 0, got -1"),
        ({"clutter_patches": [{**FAR, "weight": 2}]}, "sensors[0].clutter_patches[0].weight: unknown key; known keys here: range_m, azimuth_deg, per_scan"),
        ({"clutter_patches": [{**FAR, "range_m": [80000, 60000]}]},
         "sensors[0].clutter_patches[0].range_m: low must be <= high, got [80000, 60000]"),
        ({"clutter_patches": [{**FAR, "range_m": [7000, 7000]}]},
         "sensors[0].clutter_patches[0].range_m: must be [low, high] with low < high, got [7000, 7000]"),
        ({"clutter_patches": [{**FAR, "range_m": [-5, 7000]}]}, "sensors[0].clutter_patches[0].range_m[0]: must be >= 0, got -5"),
        ({"clutter_patches": [{**FAR, "range_m": [200000, 260000]}]},
         "sensors[0].clutter_patches[0].range_m: must lie within the instrumented range [0, 250000] (max_range_m), got [200000, 260000]"),
        ({"clutter_patches": [{**FAR, "azimuth_deg": [10, 400]}]}, "sensors[0].clutter_patches[0].azimuth_deg[1]: must be <= 360, got 400"),
        ({"clutter_patches": [{**FAR, "azimuth_deg": 30}]}, "sensors[0].clutter_patches[0].azimuth_deg: must be a [from, to] pair of degrees, got 30"),
        ({"clutter_patches": [{**FAR, "azimuth_deg": [30, 30]}]}, "sensors[0].clutter_patches[0].azimuth_deg: is an empty sector [30, 30]"),
        ({"clutter_patches": [{**FAR, "azimuth_deg": ["north", 30]}]}, "sensors[0].clutter_patches[0].azimuth_deg[0]: must be a number, got 'north'"),
        ({"clutter_p_mode3a": 1.5}, "sensors[0].clutter_p_mode3a: must be <= 1, got 1.5"),
        ({"clutter_p_mode_c": -0.1}, "sensors[0].clutter_p_mode_c: must be >= 0, got -0.1"),
    ],
)
def test_clutter_key_errors_name_the_key_path(sensor_keys, expected):
    assert expected in error_of(scenario([], sensors=[radar(**sensor_keys)]))


def test_clutter_keys_parse_and_default():
    params = load_scenario(scenario([], sensors=[radar()])).radar_params["radar1"]
    assert params.clutter_patches == () and params.clutter_p_mode3a == 0.0 and params.clutter_p_mode_c == 0.0
    sensor = radar(clutter_patches=[NEAR, {**FAR, "azimuth_deg": [0, 360]}], clutter_p_mode3a=0.05, clutter_p_mode_c=0.1)
    params = load_scenario(scenario([], sensors=[sensor])).radar_params["radar1"]
    near, everywhere = params.clutter_patches
    assert near.range_m == (5000.0, 20000.0) and near.azimuth_deg == (350.0, 20.0) and near.width_deg == 30.0
    assert everywhere.width_deg == 360.0 and near.per_scan == 8.0
    assert (params.clutter_p_mode3a, params.clutter_p_mode_c) == (0.05, 0.1)

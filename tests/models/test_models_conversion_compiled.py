"""The compiled plot placement equals the numpy reference (models.conversion.convert_plots),
for 2-D plots at a height (including heights above the slant range) and 3-D plots."""

from __future__ import annotations

import numpy as np
import pytest

from skytrack.geo.polar import EARTH_RADIUS_M
from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.models.conversion import convert_plots
from skytrack.models.conversion_kernels import convert_2d_batch, convert_3d_batch


@pytest.fixture
def radars():
    common = dict(sigma_range_m=40.0, sigma_azimuth_deg=0.07, scan_period_s=4.0)
    return SensorSet(Origin(48.86, 2.5, 30.0), [
        Sensor("r2", type="radar-2d", lat=49.2, lon=3.0, alt_m=120.0, **common),
        Sensor("r3", type="radar-3d", lat=48.5, lon=2.1, alt_m=60.0, sigma_elevation_deg=0.2, **common),
    ]).sensors


def test_2d_compiled_placement_equals_the_reference(radars):
    radar = radars[0]
    rng = np.random.default_rng(3)
    count = 500
    r = rng.uniform(500.0, 250e3, count)
    az = rng.uniform(0, 2 * np.pi, count)
    height = rng.uniform(0.0, 12e3, count)
    height[:20] = r[:20] + 1000.0  # above the slant range: placed over the radar
    sigma_h = rng.uniform(30.0, 3000.0, count)
    reference = convert_plots(radar, r, az, np.full(count, np.nan), height, sigma_h, np.full((count, 6), np.nan))
    position, covariance, consistent = convert_2d_batch(
        r, az, height, sigma_h**2, radar.alt_m, EARTH_RADIUS_M, radar.sigma_range_m**2, radar.sigma_azimuth_rad**2,
        np.ascontiguousarray(radar.rotation), np.asarray(radar.position, dtype=float))
    assert (~consistent[:20]).all() and consistent.sum() > 400
    np.testing.assert_array_equal(consistent, reference.consistent)
    np.testing.assert_allclose(position, reference.position, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(covariance, reference.covariance, rtol=1e-9, atol=1e-6)


def test_3d_compiled_placement_equals_the_reference(radars):
    radar = radars[1]
    rng = np.random.default_rng(4)
    count = 300
    r, az, el = rng.uniform(500.0, 2e5, count), rng.uniform(0, 2 * np.pi, count), rng.uniform(0, 0.5, count)
    reference = convert_plots(radar, r, az, el, np.zeros(count), np.ones(count), np.full((count, 6), np.nan))
    position, covariance, consistent = convert_3d_batch(
        r, az, el, radar.sigma_range_m**2, radar.sigma_azimuth_rad**2, radar.sigma_elevation_rad**2,
        np.ascontiguousarray(radar.rotation), np.asarray(radar.position, dtype=float))
    assert consistent.all()
    np.testing.assert_allclose(position, reference.position, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(covariance, reference.covariance, rtol=1e-9, atol=1e-6)

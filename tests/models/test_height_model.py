"""The bounded height model of 2-D plots without Mode C (skytrack.models.height)."""

import math

import numpy as np
import pytest

from skytrack.geo.polar import EARTH_RADIUS_M
from skytrack.models.height import REFRACTION_K, bounded_height
from skytrack.tracker.scan import GeometryConfig


def test_bounds_are_the_horizon_and_the_maximum_elevation():
    r = np.array([3_000.0, 50_000.0])
    height, sigma = bounded_height(r, 20.0, 30.0, 1e9, 1.0)
    k_r = REFRACTION_K * EARTH_RADIUS_M
    low = np.sqrt(r**2 + (k_r + 20.0) ** 2) - k_r
    a = EARTH_RADIUS_M + 20.0
    high = np.sqrt(r**2 + a**2 + 2 * r * a * 0.5) - EARTH_RADIUS_M
    np.testing.assert_allclose(height, 0.5 * (low + high), rtol=1e-12)
    np.testing.assert_allclose(sigma, (high - low) / math.sqrt(12), rtol=1e-12)
    # near the radar: about r sin(30 deg) / 2 above the antenna, never above the slant range
    assert height[0] == pytest.approx(20.0 + 0.25 * 3000.0, rel=0.01)


def test_ceiling_caps_the_upper_bound_and_the_horizon_wins_beyond_it():
    height, sigma = bounded_height(np.array([200_000.0, 600_000.0]), 0.0, 30.0, 13_700.0, 30.0)
    low = math.sqrt(200_000.0**2 + (REFRACTION_K * EARTH_RADIUS_M) ** 2) - REFRACTION_K * EARTH_RADIUS_M
    assert height[0] == pytest.approx(0.5 * (low + 13_700.0))
    # 600 km: the horizon height (~21 km) is above the ceiling: the plot sits at the ceiling
    assert height[1] == 13_700.0 and sigma[1] == 30.0
    # absurd ranges do not overflow
    absurd, spread = bounded_height(np.array([1e308, np.inf]), 0.0, 30.0, 13_700.0, 30.0)
    assert np.all(absurd == 13_700.0) and np.all(spread == 30.0)


def test_geometry_uses_a_fixed_default_only_when_given():
    r = np.array([10_000.0])
    fixed = GeometryConfig(default_altitude_m=6000.0, default_altitude_sigma_m=500.0).assumed_heights(r, 0.0)
    assert fixed[0][0] == 6000.0 and fixed[1][0] == 500.0
    bounded = GeometryConfig().assumed_heights(r, 0.0)
    assert bounded[0][0] < 10_000.0 * math.sin(math.radians(30.0))
    with pytest.raises(ValueError, match="max_elevation_deg"):
        GeometryConfig(max_elevation_deg=0.0)

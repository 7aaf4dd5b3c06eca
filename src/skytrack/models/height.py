"""Heights of 2-D radar plots without Mode C: the bounded height model.

A 2-D radar measures slant range and azimuth only; to place a plot on the ground plane the
tracker needs the target's height.  With Mode C it is known (to the 100 ft rounding).
Without it, a single default height is wrong in two ways: near the radar a default above the
slant range collapses the plot onto the antenna with an enormous covariance (the plots that
made the false tracks of issue 6), and far out it claims a precision it does not have.

The bounded model says what the radar does know: at slant range ``r`` the target is between

* the lowest height the beam reaches at that range — elevation 0 on the 4/3-Earth
  refraction model, ``h_lo = sqrt(r^2 + (k R + h_s)^2) - k R`` (``k = 4/3``, ``h_s`` the
  antenna height), since below the radar horizon nothing is seen; and
* the height at the highest elevation the radar's beam covers, ``max_elevation_deg``, on the
  geometric sphere, capped at the aircraft ceiling ``max_altitude_m``:
  ``h_hi = min(sqrt(r^2 + (R + h_s)^2 + 2 r (R + h_s) sin e_max) - R, ceiling)``.

Where ``h_lo`` is above the ceiling (beyond the range at which the horizon reaches it) the
plot is placed at the ceiling.  The plot is placed at the middle of ``[h_lo, h_hi]`` with the standard deviation of a uniform
distribution over it, ``(h_hi - h_lo) / sqrt(12)`` (never below ``min_sigma_m``); the
conversion carries that spread into the plot's range uncertainty through the projection's
derivative.  The placed height never exceeds the slant range, so no plot lands on the antenna.

:func:`radar_horizon_m` is the same horizon as a ground distance, for the tracker's coverage test.
"""

from __future__ import annotations

import math

import numpy as np

from skytrack.geo.polar import EARTH_RADIUS_M

#: effective Earth radius factor of the standard-atmosphere radar horizon
REFRACTION_K = 4.0 / 3.0


def bounded_height(slant_range_m: np.ndarray, sensor_alt_m: float, max_elevation_deg: float,
                   max_altitude_m: float, min_sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Height (m above the ellipsoid) and its standard deviation for plots at ``slant_range_m``."""
    r = np.asarray(slant_range_m, dtype=float)
    # hypot: no overflow for absurd ranges (they are placed at the ceiling, like any plot
    # whose lowest possible height is above it)
    low = np.minimum(np.hypot(r, REFRACTION_K * EARTH_RADIUS_M + sensor_alt_m) - REFRACTION_K * EARTH_RADIUS_M,
                     max_altitude_m)
    geometric = EARTH_RADIUS_M + sensor_alt_m
    e_max = math.radians(max_elevation_deg)
    # r^2 + g^2 + 2 r g sin(e) = (r + g sin e)^2 + (g cos e)^2
    high = np.hypot(r + geometric * math.sin(e_max), geometric * math.cos(e_max)) - EARTH_RADIUS_M
    high = np.maximum(np.minimum(high, max_altitude_m), low)
    return 0.5 * (low + high), np.maximum((high - low) / math.sqrt(12.0), min_sigma_m)


def radar_horizon_m(sensor_alt_m, target_alt_m) -> np.ndarray:
    """Ground distance (m) to the 4/3-Earth radar horizon: the sum of both tangent lengths on the
    enlarged sphere; infinite where the target height is unknown (NaN)."""
    r_eff = REFRACTION_K * EARTH_RADIUS_M
    hs = np.maximum(np.asarray(sensor_alt_m, dtype=float), 0.0)
    ht = np.asarray(target_alt_m, dtype=float)
    known = np.isfinite(ht)
    ht = np.maximum(np.where(known, ht, 0.0), 0.0)
    return np.where(known, np.sqrt(2.0 * r_eff * hs + hs * hs) + np.sqrt(2.0 * r_eff * ht + ht * ht), np.inf)

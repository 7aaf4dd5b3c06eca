"""Radar polar coordinates in a sensor's local ENU frame, vectorised over arrays.

* azimuth ``az`` is clockwise from the sensor's north, in [0, 2*pi);
* elevation ``el`` is above the sensor's horizontal plane;
* range rate is positive when the target recedes (spec 000, R8):
  ``rdot = (p - p_s) . (v - v_s) / r`` for a sensor at ``p_s`` moving with ``v_s``.

``slant_to_local`` is the 2-D radar projection of FORMATS.md: a slant range with a
known target height is placed on the sphere approximation
``r^2 = (a - b)^2 + 4ab sin^2(phi/2)``, ``a = R + h_radar``, ``b = R + h``,
with ``phi`` the Earth-central angle between radar and target.
"""

from __future__ import annotations

import numpy as np

#: Mean Earth radius (IUGG R1 of WGS84) used by the sphere approximation of FORMATS.md.
EARTH_RADIUS_M = 6_371_008.8

_BELOW_TWO_PI = np.nextafter(2.0 * np.pi, 0.0)


def wrap_angle(angle):
    """Wrap angles (rad) to (-pi, pi]."""
    wrapped = np.remainder(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    # remainder maps +pi to -pi; keep the interval half-open on the left as documented
    return np.where(wrapped == -np.pi, np.pi, wrapped)


def azimuth_of(x, y):
    """Azimuth clockwise from north of the direction (x east, y north), in [0, 2 pi).

    ``np.remainder`` of a tiny negative angle rounds to exactly 2 pi; it becomes the
    largest double below 2 pi, which keeps it west of north.
    """
    az = np.remainder(np.arctan2(x, y), 2.0 * np.pi)
    return np.where(az >= 2.0 * np.pi, _BELOW_TWO_PI, az)


def cartesian_to_polar(x, y, z, vx=None, vy=None, vz=None):
    """Sensor-local Cartesian position (and optional relative velocity) to polar.

    Returns ``(r, az, el)`` or ``(r, az, el, rdot)`` when a velocity is given.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    z = np.asarray(z, dtype=float)
    ground = np.hypot(x, y)
    r = np.sqrt(ground * ground + z * z)
    az = azimuth_of(x, y)
    el = np.arctan2(z, ground)
    if vx is None:
        return r, az, el
    with np.errstate(invalid="ignore", divide="ignore"):
        rdot = (x * np.asarray(vx) + y * np.asarray(vy) + z * np.asarray(vz)) / r
    return r, az, el, rdot


def polar_to_cartesian(r, az, el=0.0):
    """Polar (range, azimuth clockwise from north, elevation) to sensor-local ENU."""
    r = np.asarray(r, dtype=float)
    az = np.asarray(az, dtype=float)
    el = np.asarray(el, dtype=float)
    ground = r * np.cos(el)
    return ground * np.sin(az), ground * np.cos(az), r * np.sin(el)


def slant_to_local(r, az, target_alt_m, sensor_alt_m, earth_radius_m=EARTH_RADIUS_M, jacobian=False):
    """Place a 2-D radar plot (slant range, azimuth) at a known height on the sphere model.

    Returns sensor-local ENU ``(x, y, z)`` arrays and a boolean ``consistent`` array that is
    False where the slant range is shorter than the height difference (then the plot is put
    straight above/below the radar).  With ``jacobian=True`` also returns ``J[..., 3, 3]``,
    the derivative of (x, y, z) with respect to (r, az, target height).
    """
    r = np.asarray(r, dtype=float)
    az = np.asarray(az, dtype=float)
    h = np.asarray(target_alt_m, dtype=float)
    a = earth_radius_m + np.asarray(sensor_alt_m, dtype=float)
    b = earth_radius_m + h
    s = (r * r - (a - b) ** 2) / (4.0 * a * b)
    consistent = (s >= 0.0) & (s <= 1.0)
    s = np.clip(s, 0.0, 1.0)
    phi = 2.0 * np.arcsin(np.sqrt(s))
    sin_phi, cos_phi = np.sin(phi), np.cos(phi)
    ground = b * sin_phi
    up = b * cos_phi - a
    sin_az, cos_az = np.sin(az), np.cos(az)
    x, y = ground * sin_az, ground * cos_az
    if not jacobian:
        return x, y, up, consistent
    # d(phi)/dr and d(phi)/db from d(sin^2(phi/2)) = (1/2) sin(phi) d(phi)
    half_sin = np.maximum(0.5 * sin_phi, 1e-12)
    dphi_dr = (r / (2.0 * a * b)) / half_sin
    dphi_db = (-(b - a) / (2.0 * a * b) - s / b) / half_sin
    dground_dr = b * cos_phi * dphi_dr
    dground_db = sin_phi + b * cos_phi * dphi_db
    dup_dr = -b * sin_phi * dphi_dr
    dup_db = cos_phi - b * sin_phi * dphi_db
    J = np.zeros(r.shape + (3, 3))
    J[..., 0, 0] = dground_dr * sin_az
    J[..., 0, 1] = ground * cos_az
    J[..., 0, 2] = dground_db * sin_az
    J[..., 1, 0] = dground_dr * cos_az
    J[..., 1, 1] = -ground * sin_az
    J[..., 1, 2] = dground_db * cos_az
    J[..., 2, 0] = dup_dr
    J[..., 2, 2] = dup_db
    return x, y, up, consistent, J

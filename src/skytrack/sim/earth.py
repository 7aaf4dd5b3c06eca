"""Earth geometry the simulator needs on top of :mod:`skytrack.geo`.

Aircraft fly at a height above the WGS84 ellipsoid (``alt_m``) while their horizontal
motion is written in the common ENU frame (x east, y north).  The point with a given
ENU ``(x, y)`` and height ``h`` has an ENU ``z`` below ``h`` by roughly
``d^2 / (2 R)`` (FORMATS.md, "Frame"); :func:`place_at_height` finds it exactly with a
Newton iteration on latitude/longitude around the exact forward conversion
(pymap3d's geodetic2enu).  :func:`vertical_velocity` gives the ENU
``vz`` that keeps the height rate equal to ``v . n_up`` (the geodetic height gradient is
the ellipsoid normal), and :func:`radar_horizon_range` is the 4/3-Earth radar horizon.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d

from skytrack.geo.polar import EARTH_RADIUS_M
from skytrack.geo.sensors import Origin, Sensor
from skytrack.geo.wgs84 import enu_rotation, geodetic_to_enu

WGS84_A = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)

#: effective Earth radius factor of the standard-atmosphere radar horizon
REFRACTION_K = 4.0 / 3.0

#: horizontal residual (m) at which the Newton placement stops
_PLACEMENT_TOLERANCE_M = 1e-4
_PLACEMENT_MAX_ITERATIONS = 8


def _curvature_radii(lat_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meridian (M) and prime-vertical (N) radii of curvature of WGS84."""
    s2 = np.sin(lat_rad) ** 2
    w = np.sqrt(1.0 - WGS84_E2 * s2)
    return WGS84_A * (1.0 - WGS84_E2) / w**3, WGS84_A / w


def _axes_ecef(lat_rad, lon_rad, which: str) -> np.ndarray:
    """ECEF unit vectors ``[..., 3]`` of the local ``east``, ``north`` or ``up`` direction."""
    if which == "east":
        return np.stack([-np.sin(lon_rad), np.cos(lon_rad), np.zeros_like(lon_rad)], axis=-1)
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    if which == "north":
        return np.stack([-sl * co, -sl * so, cl], axis=-1)
    return np.stack([cl * co, cl * so, sl], axis=-1)


def local_axes(lat_deg, lon_deg, origin: Origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """East, north and up unit vectors at (lat, lon), expressed in the origin's ENU frame ``[..., 3]``."""
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    lon = np.radians(np.asarray(lon_deg, dtype=float))
    rot_t = enu_rotation(origin.lat, origin.lon).T
    return tuple(_axes_ecef(lat, lon, which) @ rot_t for which in ("east", "north", "up"))


def _spherical_guess(x, y, h, origin: Origin) -> tuple[np.ndarray, np.ndarray]:
    """Latitude/longitude (rad) of the ENU point on a sphere: within ~0.5 % of the distance."""
    lat0, lon0 = math.radians(origin.lat), math.radians(origin.lon)
    m0, n0 = _curvature_radii(np.array(lat0))
    radius = math.sqrt(float(m0) * float(n0))
    delta = np.arctan2(np.hypot(x, y), radius + h)
    bearing = np.arctan2(x, y)
    sin_lat = math.sin(lat0) * np.cos(delta) + math.cos(lat0) * np.sin(delta) * np.cos(bearing)
    lat = np.arcsin(np.clip(sin_lat, -1.0, 1.0))
    lon = lon0 + np.arctan2(np.sin(bearing) * np.sin(delta) * math.cos(lat0), np.cos(delta) - math.sin(lat0) * sin_lat)
    return lat, lon


def place_at_height(x, y, alt_m, origin: Origin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ENU ``z``, latitude, longitude (deg) and local up vector of the point at ENU ``(x, y)`` and height ``alt_m``.

    Chord-Newton iteration on (lat, lon) from a spherical first guess: the horizontal
    residual of the exact forward conversion (pymap3d) is mapped to local east/north
    displacements through the 2x2 horizontal part of the local axes at the first guess,
    then to angles through the WGS84 radii of curvature.  The residual shrinks by ~1e-4
    per step (2-3 steps at 300 km from the origin).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    h = np.broadcast_to(np.asarray(alt_m, dtype=float), x.shape)
    lat, lon = _spherical_guess(x, y, h, origin)
    rot = enu_rotation(origin.lat, origin.lon)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    # horizontal components (origin frame) of the local east and north unit vectors
    east_x = -so * rot[0, 0] + co * rot[0, 1]
    east_y = -so * rot[1, 0] + co * rot[1, 1]
    north_x = -sl * co * rot[0, 0] - sl * so * rot[0, 1] + cl * rot[0, 2]
    north_y = -sl * co * rot[1, 0] - sl * so * rot[1, 1] + cl * rot[1, 2]
    det = east_x * north_y - north_x * east_y
    m, n = _curvature_radii(lat)
    lat_step = 1.0 / ((m + h) * det)
    lon_step = 1.0 / ((n + h) * cl * det)
    lat0, lon0 = math.radians(origin.lat), math.radians(origin.lon)
    for _ in range(_PLACEMENT_MAX_ITERATIONS):
        e, nn, u = pymap3d.geodetic2enu(lat, lon, h, lat0, lon0, origin.alt_m, deg=False)
        rx, ry = x - e, y - nn
        if rx.size == 0 or max(np.max(np.abs(rx)), np.max(np.abs(ry))) < _PLACEMENT_TOLERANCE_M:
            break
        lat = lat + (east_x * ry - east_y * rx) * lat_step
        lon = lon + (rx * north_y - ry * north_x) * lon_step
    else:  # pragma: no cover - only for points thousands of km from the origin
        raise ValueError("placing points at height did not converge (points too far from the origin?)")
    up = _axes_ecef(lat, lon, "up") @ rot.T
    return np.asarray(u), np.degrees(lat), np.degrees(lon), up


def vertical_velocity(vx, vy, alt_rate, up: np.ndarray) -> np.ndarray:
    """ENU ``vz`` such that the height rate ``v . n_up`` equals ``alt_rate`` for horizontal ENU ``(vx, vy)``."""
    return (np.asarray(alt_rate) - np.asarray(vx) * up[..., 0] - np.asarray(vy) * up[..., 1]) / up[..., 2]


def radar_horizon_range(sensor_alt_m, target_alt_m, k: float = REFRACTION_K) -> np.ndarray:
    """Ground distance (m) to the radar horizon on a k-times-enlarged sphere (sum of both tangent lengths)."""
    r_eff = k * EARTH_RADIUS_M
    hs = np.maximum(np.asarray(sensor_alt_m, dtype=float), 0.0)
    ht = np.maximum(np.asarray(target_alt_m, dtype=float), 0.0)
    return np.sqrt(2.0 * r_eff * hs + hs * hs) + np.sqrt(2.0 * r_eff * ht + ht * ht)


def sensor_relative_positions(sensor: Sensor, origin: Origin, ground_range_m, azimuth_deg, alt_m) -> tuple[np.ndarray, np.ndarray]:
    """Common-frame (x, y) of points at ground range / azimuth in a sensor's own frame and height ``alt_m``."""
    ground = np.atleast_1d(np.asarray(ground_range_m, dtype=float))
    az = np.radians(np.atleast_1d(np.asarray(azimuth_deg, dtype=float)))
    alt = np.broadcast_to(np.asarray(alt_m, dtype=float), ground.shape)
    sensor_origin = Origin(sensor.lat, sensor.lon, sensor.alt_m)
    _, lat, lon, _ = place_at_height(ground * np.sin(az), ground * np.cos(az), alt, sensor_origin)
    x, y, _ = geodetic_to_enu(lat, lon, alt, origin.lat, origin.lon, origin.alt_m)
    return np.asarray(x), np.asarray(y)

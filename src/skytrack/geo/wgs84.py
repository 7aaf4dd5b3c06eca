"""Exact WGS84 conversions between geodetic coordinates and a local ENU frame.

The conversions themselves are pymap3d's (vectorised over numpy arrays); this module
only fixes the conventions used throughout skytrack (degrees at the edges, metres,
ENU = x east, y north, z up) and adds the ECEF->ENU rotation needed to relate the
local frames of two sensors.
"""

from __future__ import annotations

import numpy as np
import pymap3d


def geodetic_to_enu(lat_deg, lon_deg, alt_m, origin_lat_deg, origin_lon_deg, origin_alt_m):
    """Geodetic (deg, deg, m above ellipsoid) to ENU metres around the origin."""
    e, n, u = pymap3d.geodetic2enu(
        np.asarray(lat_deg, dtype=float),
        np.asarray(lon_deg, dtype=float),
        np.asarray(alt_m, dtype=float),
        origin_lat_deg,
        origin_lon_deg,
        origin_alt_m,
    )
    return np.asarray(e), np.asarray(n), np.asarray(u)


def enu_to_geodetic(x, y, z, origin_lat_deg, origin_lon_deg, origin_alt_m):
    """ENU metres around the origin to geodetic (deg, deg, m above ellipsoid)."""
    lat, lon, alt = pymap3d.enu2geodetic(
        np.asarray(x, dtype=float),
        np.asarray(y, dtype=float),
        np.asarray(z, dtype=float),
        origin_lat_deg,
        origin_lon_deg,
        origin_alt_m,
    )
    return np.asarray(lat), np.asarray(lon), np.asarray(alt)


def enu_rotation(lat_deg: float, lon_deg: float) -> np.ndarray:
    """Rotation matrix taking ECEF vectors to the ENU frame at (lat, lon); rows are E, N, U."""
    lat = np.radians(lat_deg)
    lon = np.radians(lon_deg)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    return np.array(
        [
            [-so, co, 0.0],
            [-sl * co, -sl * so, cl],
            [cl * co, cl * so, sl],
        ]
    )

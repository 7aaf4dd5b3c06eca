"""Position and velocity conversions used when reading tables (vectorised).

- WGS84 geodetic <-> the origin's ENU frame, exactly (``skytrack.geo.wgs84``).
- A velocity given in the local ENU frame of the point itself (ground speed and track,
  vertical rate) rotated into the origin's ENU frame: ``v = R(origin) R(point)^T v_local``
  with ``R`` the ECEF -> ENU rotation, so that far from the origin "north" is still the
  aircraft's north.
- Finite-difference velocity along each trajectory segment (central differences inside,
  one-sided at the ends), for truth without reported velocity.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.geo.wgs84 import enu_rotation, enu_to_geodetic, geodetic_to_enu

FT_TO_M = 0.3048
KNOT_TO_MPS = 1852.0 / 3600.0
FT_PER_MIN_TO_MPS = FT_TO_M / 60.0


def enu_from_geodetic(lat: np.ndarray, lon: np.ndarray, alt_m: np.ndarray, origin: Origin) -> np.ndarray:
    """Positions ``[N, 3]`` in the origin's ENU frame."""
    x, y, z = geodetic_to_enu(lat, lon, alt_m, origin.lat, origin.lon, origin.alt_m)
    return np.column_stack([np.atleast_1d(x), np.atleast_1d(y), np.atleast_1d(z)]).astype(np.float64)


def geodetic_from_enu(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: Origin) -> np.ndarray:
    """``[N, 3]`` columns lat, lon, alt_m of ENU points (NaN stays NaN)."""
    lat, lon, alt = enu_to_geodetic(x, y, z, origin.lat, origin.lon, origin.alt_m)
    return np.column_stack([np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(alt)]).astype(np.float64)


def local_to_origin_velocity(lat: np.ndarray, lon: np.ndarray, v_local: np.ndarray, origin: Origin) -> np.ndarray:
    """Rotate velocities ``[N, 3]`` from each point's own ENU frame to the origin's."""
    phi = np.radians(lat)
    lam = np.radians(lon)
    sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
    ve, vn, vu = v_local[:, 0], v_local[:, 1], v_local[:, 2]
    # R(point)^T v: the rows of R are the E, N, U unit vectors in ECEF
    ecef = np.column_stack(
        [
            -sl * ve - sp * cl * vn + cp * cl * vu,
            cl * ve - sp * sl * vn + cp * sl * vu,
            cp * vn + sp * vu,
        ]
    )
    return ecef @ enu_rotation(origin.lat, origin.lon).T


def finite_difference_velocity(
    time: np.ndarray, positions: np.ndarray, groups: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity ``[N, k]`` by differences within each group (rows in any order).

    Returns the velocities and a mask of the rows alone in their group, whose velocity
    is unknown and set to 0.
    """
    n = len(time)
    if n == 0:
        return np.zeros_like(positions, dtype=np.float64), np.zeros(0, dtype=bool)
    order = np.lexsort((time, groups))
    t = time[order]
    p = positions[order]
    g = groups[order]
    same_as_next = np.zeros(n, dtype=bool)
    same_as_next[:-1] = g[1:] == g[:-1]
    same_as_prev = np.zeros(n, dtype=bool)
    same_as_prev[1:] = same_as_next[:-1]
    index = np.arange(n)
    before = np.where(same_as_prev, index - 1, index)
    after = np.where(same_as_next, index + 1, index)
    dt = t[after] - t[before]
    with np.errstate(invalid="ignore", divide="ignore"):
        v = (p[after] - p[before]) / dt[:, None]
    v[dt <= 0] = 0.0
    out = np.empty_like(v)
    out[order] = v
    isolated = np.empty(n, dtype=bool)
    isolated[order] = ~same_as_prev & ~same_as_next
    return out, isolated


def group_codes(*keys: pd.Series | np.ndarray) -> tuple[np.ndarray, list[tuple]]:
    """Integer codes 0..G-1 of the distinct combinations of ``keys`` (-1 where a key is null).

    Also returns, for each code, the tuple of key values it stands for.
    """
    n = len(keys[0])
    combined = np.zeros(n, dtype=np.int64)
    valid = np.ones(n, dtype=bool)
    for key in keys:
        codes, uniques = pd.factorize(key, use_na_sentinel=True)
        codes = np.asarray(codes, dtype=np.int64)
        valid &= codes >= 0
        combined = combined * (len(uniques) + 1) + (codes + 1)
    codes, _ = pd.factorize(combined)
    codes = np.where(valid, np.asarray(codes, dtype=np.int64), -1)
    # renumber the valid combinations densely
    valid_codes, first_rows, dense = np.unique(codes[valid], return_index=True, return_inverse=True)
    result = np.full(n, -1, dtype=np.int64)
    result[valid] = dense
    rows = np.flatnonzero(valid)[first_rows]
    arrays = [np.asarray(k.to_numpy() if isinstance(k, pd.Series) else k) for k in keys]
    labels = [tuple(a[r] for a in arrays) for r in rows]
    return result, labels

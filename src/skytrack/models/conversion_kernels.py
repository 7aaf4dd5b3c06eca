"""Compiled plot placement (numba, cached): the formulas of :func:`skytrack.geo.polar.slant_to_local`
and :func:`skytrack.models.conversion.convert_plots` for one plot at a time, without temporaries.

* :func:`place_2d` — a 2-D plot at a known height on the sphere model: common-frame position and
  covariance ``rot^T J diag(var) J^T rot``; a height above the slant range puts the plot over
  the radar with a horizontal spread of its range;

The 3 x 3 products are written out on scalars: with small arrays and loops numba kept them in
memory and a placement cost about 0.2 us; on scalars it costs a seventh of that.
* :func:`convert_2d_batch` / :func:`convert_3d_batch` — whole batches of one ground radar.

:func:`skytrack.models.conversion.convert_plots` is the numpy reference they are tested against.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def place_2d(r, az, height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, pos_out, cov_out):
    """A 2-D plot at a known height: common-frame position and covariance (sphere model), written
    to ``pos_out`` [3] and ``cov_out`` [3, 3]; returns whether the height is consistent with the
    slant range."""
    a = earth + sensor_alt
    b = earth + height
    s = (r * r - (a - b) ** 2) / (4.0 * a * b)
    consistent = s >= 0.0 and s <= 1.0
    s = min(max(s, 0.0), 1.0)
    # phi = 2 asin(sqrt(s)), so sin(phi) = 2 sqrt(s (1 - s)) and cos(phi) = 1 - 2 s: no trigonometry
    sin_phi = 2.0 * np.sqrt(s * (1.0 - s))
    cos_phi = 1.0 - 2.0 * s
    ground = b * sin_phi
    sin_az = np.sin(az)
    cos_az = np.cos(az)
    x, y, z = ground * sin_az, ground * cos_az, b * cos_phi - a
    if not consistent:
        # the height exceeds the slant range: the plot is somewhere within r of the radar
        spread = r * r + var_r
        _write(x, y, z, spread, 0.0, 0.0, spread, 0.0, var_h + var_r, rot, origin, pos_out, cov_out)
        return consistent
    half_sin = max(0.5 * sin_phi, 1e-12)
    dphi_dr = (r / (2.0 * a * b)) / half_sin
    dphi_db = (-(b - a) / (2.0 * a * b) - s / b) / half_sin
    dground_dr = b * cos_phi * dphi_dr
    dground_db = sin_phi + b * cos_phi * dphi_db
    # J = d(x, y, z) / d(range, azimuth, height); J[2, 1] = 0
    j00, j01, j02 = dground_dr * sin_az, ground * cos_az, dground_db * sin_az
    j10, j11, j12 = dground_dr * cos_az, -ground * sin_az, dground_db * cos_az
    j20, j22 = -b * sin_phi * dphi_dr, cos_phi - b * sin_phi * dphi_db
    _write_propagated(x, y, z, j00, j01, j02, j10, j11, j12, j20, j22, var_r, var_az, var_h, rot, origin, pos_out,
                      cov_out)
    return consistent


@njit(cache=True, nogil=True, error_model="numpy")
def convert_2d_batch(r, az, height, var_h, sensor_alt, earth, var_r, var_az, rot, origin):
    count = len(r)
    position = np.empty((count, 3))
    covariance = np.empty((count, 3, 3))
    consistent = np.empty(count, np.bool_)
    for k in range(count):
        consistent[k] = place_2d(r[k], az[k], height[k], sensor_alt, earth, var_r, var_az, var_h[k], rot, origin,
                                 position[k], covariance[k])
    return position, covariance, consistent


@njit(cache=True, nogil=True, error_model="numpy")
def convert_3d_batch(r, az, el, var_r, var_az, var_el, rot, origin):
    count = len(r)
    position = np.empty((count, 3))
    covariance = np.empty((count, 3, 3))
    consistent = np.empty(count, np.bool_)
    for k in range(count):
        cos_el, sin_el = np.cos(el[k]), np.sin(el[k])
        sin_az, cos_az = np.sin(az[k]), np.cos(az[k])
        rk = r[k]
        ground = rk * cos_el
        consistent[k] = np.isfinite(el[k])
        # J = d(x, y, z) / d(range, azimuth, elevation); J[2, 1] = 0
        j00, j01, j02 = cos_el * sin_az, rk * cos_el * cos_az, -rk * sin_el * sin_az
        j10, j11, j12 = cos_el * cos_az, -rk * cos_el * sin_az, -rk * sin_el * cos_az
        j20, j22 = sin_el, rk * cos_el
        _write_propagated(ground * sin_az, ground * cos_az, rk * sin_el, j00, j01, j02, j10, j11, j12, j20, j22,
                          var_r, var_az, var_el, rot, origin, position[k], covariance[k])
    return position, covariance, consistent


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _write_propagated(x, y, z, j00, j01, j02, j10, j11, j12, j20, j22, v0, v1, v2, rot, origin, pos_out, cov_out):
    """:func:`_write` of the covariance ``J diag(v0, v1, v2) J^T`` of a Jacobian with ``J[2, 1] = 0``
    (range, azimuth and a third measured or assumed coordinate)."""
    _write(x, y, z,
           j00 * j00 * v0 + j01 * j01 * v1 + j02 * j02 * v2,
           j00 * j10 * v0 + j01 * j11 * v1 + j02 * j12 * v2,
           j00 * j20 * v0 + j02 * j22 * v2,
           j10 * j10 * v0 + j11 * j11 * v1 + j12 * j12 * v2,
           j10 * j20 * v0 + j12 * j22 * v2,
           j20 * j20 * v0 + j22 * j22 * v2,
           rot, origin, pos_out, cov_out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _write(x, y, z, c00, c01, c02, c11, c12, c22, rot, origin, pos_out, cov_out):
    """Local position (x, y, z) and symmetric covariance (upper triangle c..) into the common
    frame: ``pos = local rot + origin``, ``cov = rot^T C rot``."""
    if _is_identity(rot):  # a radar at the origin of the common frame: nothing to rotate
        pos_out[0], pos_out[1], pos_out[2] = x + origin[0], y + origin[1], z + origin[2]
        cov_out[0, 0], cov_out[0, 1], cov_out[0, 2] = c00, c01, c02
        cov_out[1, 0], cov_out[1, 1], cov_out[1, 2] = c01, c11, c12
        cov_out[2, 0], cov_out[2, 1], cov_out[2, 2] = c02, c12, c22
        return
    for j in range(3):
        pos_out[j] = x * rot[0, j] + y * rot[1, j] + z * rot[2, j] + origin[j]
    for i in range(3):
        # row i of rot^T C: sum_k rot[k, i] C[k, :]
        a0 = rot[0, i] * c00 + rot[1, i] * c01 + rot[2, i] * c02
        a1 = rot[0, i] * c01 + rot[1, i] * c11 + rot[2, i] * c12
        a2 = rot[0, i] * c02 + rot[1, i] * c12 + rot[2, i] * c22
        for j in range(i, 3):
            value = a0 * rot[0, j] + a1 * rot[1, j] + a2 * rot[2, j]
            cov_out[i, j] = value
            cov_out[j, i] = value


@njit(cache=True, nogil=True, inline="always")
def _is_identity(rot):
    for i in range(3):
        for j in range(3):
            if rot[i, j] != (1.0 if i == j else 0.0):
                return False
    return True

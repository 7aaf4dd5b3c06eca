"""Compiled plot placement (numba, cached): the formulas of :func:`skytrack.geo.polar.slant_to_local`
and :func:`skytrack.models.conversion.convert_plots` for one plot at a time, without temporaries.

* :func:`place_2d` — a 2-D plot at a known height on the sphere model: common-frame position and
  covariance ``rot^T J diag(var) J^T rot``; a height above the slant range puts the plot over
  the radar with a horizontal spread of its range;
* :func:`convert_2d_batch` / :func:`convert_3d_batch` — whole batches of one ground radar.

:func:`skytrack.models.conversion.convert_plots` is the numpy reference they are tested against.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def place_2d(r, az, height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, pos_out, cov_out, work):
    """A 2-D plot at a known height: common-frame position and covariance (sphere model).

    ``work`` is a ``[4, 3, 3]`` scratch array of the caller (no allocation per plot)."""
    a = earth + sensor_alt
    b = earth + height
    s = (r * r - (a - b) ** 2) / (4.0 * a * b)
    consistent = s >= 0.0 and s <= 1.0
    s = min(max(s, 0.0), 1.0)
    phi = 2.0 * np.arcsin(np.sqrt(s))
    sin_phi = np.sin(phi)
    cos_phi = np.cos(phi)
    ground = b * sin_phi
    up = b * cos_phi - a
    sin_az = np.sin(az)
    cos_az = np.cos(az)
    J = work[0]
    local_cov = work[1]
    tmp = work[2]
    local = work[3, 0]
    var = work[3, 1]
    local[0] = ground * sin_az
    local[1] = ground * cos_az
    local[2] = up
    half_sin = max(0.5 * sin_phi, 1e-12)
    dphi_dr = (r / (2.0 * a * b)) / half_sin
    dphi_db = (-(b - a) / (2.0 * a * b) - s / b) / half_sin
    dground_dr = b * cos_phi * dphi_dr
    dground_db = sin_phi + b * cos_phi * dphi_db
    J[0, 0] = dground_dr * sin_az
    J[0, 1] = ground * cos_az
    J[0, 2] = dground_db * sin_az
    J[1, 0] = dground_dr * cos_az
    J[1, 1] = -ground * sin_az
    J[1, 2] = dground_db * cos_az
    J[2, 0] = -b * sin_phi * dphi_dr
    J[2, 1] = 0.0
    J[2, 2] = cos_phi - b * sin_phi * dphi_db
    var[0] = var_r
    var[1] = var_az
    var[2] = var_h
    if consistent:
        _rotate(local, J, var, rot, origin, local_cov, tmp, pos_out, cov_out)
        return consistent
    # the height exceeds the slant range: the plot is somewhere within r of the radar
    for i in range(3):
        for j in range(3):
            J[i, j] = 0.0
    spread = r * r + var_r
    J[0, 0] = J[1, 1] = 1.0
    J[2, 2] = 1.0
    var[0] = var[1] = spread
    var[2] = var_h + var_r
    _rotate(local, J, var, rot, origin, local_cov, tmp, pos_out, cov_out)
    return consistent


@njit(cache=True, nogil=True, error_model="numpy")
def convert_2d_batch(r, az, height, var_h, sensor_alt, earth, var_r, var_az, rot, origin):
    count = len(r)
    position = np.empty((count, 3))
    covariance = np.empty((count, 3, 3))
    consistent = np.empty(count, np.bool_)
    work = np.empty((4, 3, 3))
    for k in range(count):
        consistent[k] = place_2d(r[k], az[k], height[k], sensor_alt, earth, var_r, var_az, var_h[k], rot, origin,
                                 position[k], covariance[k], work)
    return position, covariance, consistent


@njit(cache=True, nogil=True, error_model="numpy")
def convert_3d_batch(r, az, el, var_r, var_az, var_el, rot, origin):
    count = len(r)
    position = np.empty((count, 3))
    covariance = np.empty((count, 3, 3))
    consistent = np.empty(count, np.bool_)
    local = np.empty(3)
    J = np.empty((3, 3))
    local_cov = np.empty((3, 3))
    tmp = np.empty((3, 3))
    var = np.empty(3)
    var[0] = var_r
    var[1] = var_az
    var[2] = var_el
    for k in range(count):
        cos_el, sin_el = np.cos(el[k]), np.sin(el[k])
        sin_az, cos_az = np.sin(az[k]), np.cos(az[k])
        ground = r[k] * cos_el
        local[0] = ground * sin_az
        local[1] = ground * cos_az
        local[2] = r[k] * sin_el
        consistent[k] = np.isfinite(el[k])
        J[0, 0] = cos_el * sin_az
        J[0, 1] = r[k] * cos_el * cos_az
        J[0, 2] = -r[k] * sin_el * sin_az
        J[1, 0] = cos_el * cos_az
        J[1, 1] = -r[k] * cos_el * sin_az
        J[1, 2] = -r[k] * sin_el * cos_az
        J[2, 0] = sin_el
        J[2, 1] = 0.0
        J[2, 2] = r[k] * cos_el
        _rotate(local, J, var, rot, origin, local_cov, tmp, position[k], covariance[k])
    return position, covariance, consistent


@njit(cache=True, nogil=True, error_model="numpy")
def _rotate(local, J, var, rot, origin, local_cov, tmp, pos_out, cov_out):
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += J[i, k] * var[k] * J[j, k]
            local_cov[i, j] = acc
    for j in range(3):
        acc = 0.0
        for k in range(3):
            acc += local[k] * rot[k, j]
        pos_out[j] = acc + origin[j]
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += rot[k, i] * local_cov[k, j]
            tmp[i, j] = acc
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += tmp[i, k] * rot[k, j]
            cov_out[i, j] = acc

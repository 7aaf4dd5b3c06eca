"""The one plot-to-position conversion: radar plots as common-frame positions with covariance.

The tracker, the report figures and the spec 000 code all place plots through
:func:`convert_plots`, computed for a whole batch of plots (or of candidate pairs) at once:

* 2-D radar: the slant range is put on the sphere model of FORMATS.md at the target's
  height (Mode C, else the track's last Mode C, else a configured default) with
  :func:`skytrack.geo.polar.slant_to_local`; the height uncertainty enters the
  covariance through the derivative of the projection.
* 3-D radar: (range, azimuth, elevation) to sensor-local ENU.

An airborne radar (``radar-airborne``) measures from the platform position of each plot
(``platform_x/y/z`` columns); its axes are the common frame's turned by
``north_offset_deg``, and its height above the ellipsoid is taken as the platform's ENU
``z`` (the Earth's curvature over the platform's distance from the origin is neglected).

A 2-D plot whose assumed height exceeds its slant range cannot be placed; it is put
above the radar with a horizontal spread of its slant range (the tracker counts them).

In both cases the covariance is ``J diag(sigma^2) J^T`` (``J`` the conversion Jacobian)
rotated into the common frame.  With azimuth errors of a tenth of a degree the
conversion bias ``r sigma_az^2 / 2`` is centimetres, far below the range noise, so the
linear update on converted positions matches an EKF on polar measurements; the
Doppler range rate, when present, is added as one nonlinear EKF component
(spec 000 R9: position plus velocity measurement).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.geo.polar import polar_to_cartesian, slant_to_local
from skytrack.geo.sensors import Sensor


@dataclass
class ConvertedPlots:
    """Common-frame positions ``[K, 3]``, covariances ``[K, 3, 3]`` and consistency flags."""

    position: np.ndarray
    covariance: np.ndarray
    consistent: np.ndarray

    def take(self, rows) -> "ConvertedPlots":
        return ConvertedPlots(self.position[rows], self.covariance[rows], self.consistent[rows])

    @staticmethod
    def concat(parts: list["ConvertedPlots"]) -> "ConvertedPlots":
        return ConvertedPlots(np.concatenate([p.position for p in parts]),
                              np.concatenate([p.covariance for p in parts]),
                              np.concatenate([p.consistent for p in parts]))

    @staticmethod
    def empty() -> "ConvertedPlots":
        return ConvertedPlots(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, dtype=bool))


def sensor_positions(sensor: Sensor, platform: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sensor position and velocity per plot ``[K, 3]`` (platform columns for a moving sensor)."""
    count = len(platform)
    if sensor.is_moving:
        if np.isnan(platform[:, :3]).any():
            raise ValueError(f"sensor {sensor.name!r} is airborne: plots need platform_x/y/z columns")
        return platform[:, :3], np.nan_to_num(platform[:, 3:])
    return np.broadcast_to(sensor.position, (count, 3)), np.zeros((count, 3))


def place_plots(sensor: Sensor, range_m: np.ndarray, azimuth: np.ndarray, elevation: np.ndarray,
                altitude_m: np.ndarray, platform: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Common-frame positions ``[K, 3]`` of plots, without covariance (figures, quick looks).

    A plot with a finite ``elevation`` (rad) is placed in polar coordinates; any other at its
    ``altitude_m`` on the sphere model (:func:`~skytrack.geo.polar.slant_to_local`).  Returns the
    positions and the ``consistent`` flags of the sphere placement (True for polar plots).
    """
    count = len(range_m)
    platform = np.full((count, 6), np.nan) if platform is None else platform
    positions, _ = sensor_positions(sensor, platform)
    local = np.empty((count, 3))
    consistent = np.ones(count, dtype=bool)
    polar = np.isfinite(elevation)
    if polar.any():
        local[polar] = np.column_stack(polar_to_cartesian(range_m[polar], azimuth[polar], elevation[polar]))
    sphere = ~polar
    if sphere.any():
        sensor_alt = positions[sphere, 2] if sensor.is_moving else (sensor.alt_m or 0.0)
        x, y, z, ok = slant_to_local(range_m[sphere], azimuth[sphere], altitude_m[sphere], sensor_alt)
        local[sphere] = np.column_stack([x, y, z])
        consistent[sphere] = ok
    return local @ sensor.rotation + positions, consistent


def convert_plots(
    sensor: Sensor,
    range_m: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    altitude_m: np.ndarray,
    altitude_sigma_m: np.ndarray,
    platform: np.ndarray,
) -> ConvertedPlots:
    """Convert plots of one sensor to common-frame positions with covariance."""
    sigma_r = sensor.sigma_range_m
    sigma_az = sensor.sigma_azimuth_rad
    positions, _ = sensor_positions(sensor, platform)
    if sensor.is_3d:
        x, y, z = polar_to_cartesian(range_m, azimuth, elevation)
        consistent = np.isfinite(elevation)
        cos_el, sin_el = np.cos(elevation), np.sin(elevation)
        sin_az, cos_az = np.sin(azimuth), np.cos(azimuth)
        J = np.zeros(range_m.shape + (3, 3))
        J[:, 0, 0] = cos_el * sin_az
        J[:, 0, 1] = range_m * cos_el * cos_az
        J[:, 0, 2] = -range_m * sin_el * sin_az
        J[:, 1, 0] = cos_el * cos_az
        J[:, 1, 1] = -range_m * cos_el * sin_az
        J[:, 1, 2] = -range_m * sin_el * cos_az
        J[:, 2, 0] = sin_el
        J[:, 2, 2] = range_m * cos_el
        variances = np.column_stack(
            [np.full_like(range_m, sigma_r**2), np.full_like(range_m, sigma_az**2),
             np.full_like(range_m, sensor.sigma_elevation_rad**2)]
        )
    else:
        sensor_alt = sensor.alt_m if not sensor.is_moving else positions[:, 2]
        x, y, z, consistent, J = slant_to_local(range_m, azimuth, altitude_m, sensor_alt, jacobian=True)
        variances = np.column_stack(
            [np.full_like(range_m, sigma_r**2), np.full_like(range_m, sigma_az**2), np.square(altitude_sigma_m)]
        )
    local_cov = (J * variances[:, None, :]) @ np.swapaxes(J, -1, -2)
    if not sensor.is_3d and not consistent.all():
        # the height exceeds the slant range: the plot is somewhere within r of the radar
        bad = ~consistent
        spread = np.square(range_m[bad]) + sigma_r**2
        local_cov[bad] = 0.0
        local_cov[bad, 0, 0] = local_cov[bad, 1, 1] = spread
        local_cov[bad, 2, 2] = np.square(altitude_sigma_m[bad]) + sigma_r**2
    rot = sensor.rotation
    position = np.column_stack([x, y, z]) @ rot + positions
    covariance = rot.T @ local_cov @ rot
    return ConvertedPlots(position, covariance, consistent)

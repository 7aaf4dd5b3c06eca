"""Recorded trajectories as study truth (spec 004 R19): truth file -> ENU -> smoothing spline -> scans.

The file is read with :func:`skytrack.io.read_truth` (docs/formats.md "truth": ``time`` +
``target_id`` + ENU ``x, y, z`` or WGS84 ``lat, lon, alt_m``; OpenSky state vectors too).
Each (``target_id``, ``segment``) is one trajectory.  Positions are taken in the ENU frame
of the radar, which sits at the frame's origin:

* a file with ``x, y, z`` is used as is (the radar at its ENU origin) unless ``origin`` is
  given;
* a geodetic-only file is converted with the given ``origin``; without one, the positions are
  converted in the ENU frame of the recording's mean position and each trajectory is then
  translated so that the radar (the origin) sits :data:`DEFAULT_RADAR_OFFSET_M` south of the
  trajectory's own mean horizontal position, at height 0 (the studies' default geometry, a
  target about 40 km from the radar; a translation keeps the kinematics exact).

Per axis a cubic smoothing spline (:func:`scipy.interpolate.make_smoothing_spline`, penalty
chosen by generalised cross-validation unless ``smoothing_lam`` is given) is fitted to the
positions against time; its value, first and second derivatives are the position, velocity
and acceleration truth, resampled every ``dt`` from the segment's first sample.  Manoeuvres
are then detected with :func:`skytrack.studies.maneuver.segments.maneuver_segments`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.interpolate import make_smoothing_spline

from skytrack.geo.sensors import Origin
from skytrack.io.tables import load_table
from skytrack.io.truth import read_truth
from skytrack.studies.maneuver.segments import SPEC_RULE, ManeuverRule, maneuver_segments
from skytrack.studies.maneuver.trajectory import Kinematics

#: default distance of the radar south of a geodetic-only recording's mean position (m)
DEFAULT_RADAR_OFFSET_M = 40_000.0
#: a smoothing spline needs at least this many samples
MIN_SAMPLES = 5


@dataclass(frozen=True)
class RecordedTrajectory:
    """One recorded (target, segment): resampled truth and its detected manoeuvres."""

    label: str
    truth: Kinematics
    maneuvers: list[tuple[float, float]]
    start_time: float  # time of the first sample in the file's time scale (s)


def mean_origin(path: str | Path) -> Origin:
    """The mean recorded latitude and longitude, at height 0."""
    frame, _ = load_table(path)
    for lat_name, lon_name in (("lat", "lon"), ("latitude", "longitude")):
        if lat_name in frame.columns and lon_name in frame.columns:
            lat = pd.to_numeric(frame[lat_name], errors="coerce").to_numpy(dtype=float)
            lon = pd.to_numeric(frame[lon_name], errors="coerce").to_numpy(dtype=float)
            ok = np.isfinite(lat) & np.isfinite(lon)
            if ok.any():
                return Origin(float(np.mean(lat[ok])), float(np.mean(lon[ok])), 0.0)
    raise ValueError(f"{path}: no lat/lon positions to place a default radar origin; give recorded.origin in --config")


def _has_enu(path: str | Path) -> bool:
    frame, _ = load_table(path)
    return {"x", "y", "z"} <= set(map(str, frame.columns))


def smooth_kinematics(time: np.ndarray, position: np.ndarray, dt: float, lam: float | None = None) -> Kinematics:
    """Per-axis smoothing spline of ``position[K, 3]`` against ``time`` resampled every ``dt`` from ``time[0]``.

    Returned times are relative to ``time[0]``.
    """
    t = np.asarray(time, dtype=float)
    if t.size < MIN_SAMPLES:
        raise ValueError(f"a recorded segment needs at least {MIN_SAMPLES} samples, got {t.size}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt}")
    rel = t - t[0]
    grid = np.arange(0.0, rel[-1] + 1e-9, dt)
    out = np.empty((3, grid.size, 3))
    for axis in range(3):
        spline = make_smoothing_spline(rel, np.asarray(position[:, axis], dtype=float), lam=lam)
        out[0, :, axis] = spline(grid)
        out[1, :, axis] = spline.derivative(1)(grid)
        out[2, :, axis] = spline.derivative(2)(grid)
    return Kinematics(grid, out[0], out[1], out[2])


def load_recorded(
    path: str | Path,
    dt: float,
    *,
    origin: Origin | None = None,
    rule: ManeuverRule = SPEC_RULE,
    smoothing_lam: float | None = None,
    min_duration_s: float = 60.0,
    max_trajectories: int | None = None,
) -> list[RecordedTrajectory]:
    """The recorded trajectories of a truth file, resampled at ``dt`` (module docstring).

    Segments shorter than ``min_duration_s`` or with fewer than :data:`MIN_SAMPLES` samples
    are skipped; at most ``max_trajectories`` (in file order) are kept.
    """
    place_radar = origin is None and not _has_enu(path)
    if place_radar:
        origin = mean_origin(path)
    truth = read_truth(path, origin=origin)
    out: list[RecordedTrajectory] = []
    for (target, segment), rows in truth.groupby(["target_id", "segment"], sort=False):
        rows = rows.sort_values("time")
        t = rows["time"].to_numpy(dtype=float)
        if t.size < MIN_SAMPLES or t[-1] - t[0] < min_duration_s:
            continue
        position = rows[["x", "y", "z"]].to_numpy(dtype=float)
        if place_radar:
            centre = position.mean(axis=0)
            position = position - np.array([centre[0], centre[1] - DEFAULT_RADAR_OFFSET_M, 0.0])
        kin = smooth_kinematics(t, position, dt, smoothing_lam)
        out.append(RecordedTrajectory(f"{target}/{segment}", kin, maneuver_segments(kin.time, kin.velocity, kin.acceleration, rule),
                                      float(t[0])))
        if max_trajectories is not None and len(out) >= max_trajectories:
            break
    if not out:
        raise ValueError(f"{path}: no trajectory of at least {MIN_SAMPLES} samples and {min_duration_s:g} s")
    return out

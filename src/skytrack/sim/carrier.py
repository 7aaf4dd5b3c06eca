"""Airborne radars of the simulator: the carrier's flight and the plots measured from it
(spec 003 §2.3 measurement function h, R17; issue 8 item 1).

A ``radar-airborne`` sensor flies with its carrier, whose start and legs are a target's
(scenario key ``carrier``, flown by :func:`skytrack.sim.trajectories.build_trajectories`;
Singer legs draw from the scenario seed's ``carriers`` stream).  The carrier is not a
target: it has no truth rows and no plots.

Scans: one time stamp per scan, ``t_k = scan_phase_s + k scan_period_s`` within
[0, duration_s] and the carrier's flight (R17).  Each target alive at ``t_k`` is measured
from the carrier's position ``p_o`` and velocity ``v_o`` at ``t_k`` in the radar's axes
(the common frame's, turned by ``north_offset_deg``; stabilised angles, §2.2):
with ``Δ = p - p_o``, ``Δv = v - v_o``,

    range_m = |Δ|,  azimuth = atan2(Δe, Δn) mod 2π,  elevation = atan2(Δu, hypot(Δe, Δn)),
    range_rate = Δ·Δv / |Δ|  (positive opening),

plus independent Gaussian noise (elevation only with ``sigma_elevation_deg``, range rate only
with ``sigma_range_rate_mps``).  Coverage: range <= ``max_range_m``, elevation >=
``min_elevation_deg`` (default -90 for an airborne radar) and the 4/3-Earth radar horizon of
the carrier's and the target's heights.  Detection is Bernoulli(``p_detection``) per target
and scan; every detected target gives its own plot (perfect resolution).  SSR (Mode 3/A,
Mode C, Mode S) as for a ground radar (:mod:`skytrack.sim.radar`).

Clutter: Poisson(``clutter_per_scan``) false plots per scan, uniform in azimuth, in range
(``clutter_distribution``) and in ``clutter_elevation_deg`` / ``clutter_range_rate_mps``.

Every plot carries the carrier's state at its time in the ``platform_x``, ``platform_y``,
``platform_z``, ``platform_vx``, ``platform_vy``, ``platform_vz`` columns (FORMATS.md).  The
plots of a scan (targets and false plots) are emitted in a random order drawn from the
sensor stream (R17).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.core.plots import PLATFORM_COLUMNS
from skytrack.geo.sensors import Origin, Sensor
from skytrack.sim.radar import _clutter_secondary, in_coverage, measured_plots, polar_view
from skytrack.sim.spec import RadarSimParams, TargetSpec
from skytrack.sim.trajectories import TrajectorySet, build_trajectories


@dataclass
class Carriers:
    """The flights of the airborne radars' carriers: one trajectory per airborne sensor."""

    trajectories: TrajectorySet
    index: dict[str, int]  # sensor name -> trajectory index

    def __contains__(self, sensor_name: str) -> bool:
        return sensor_name in self.index

    def state(self, sensor_name: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position ``[K, 3]``, velocity ``[K, 3]`` (common ENU) and height above the ellipsoid ``[K]``."""
        t = np.asarray(t, dtype=float)
        state = self.trajectories.state(np.full(t.shape, self.index[sensor_name], dtype=np.int64), t)
        position = np.stack([state["x"], state["y"], state["z"]], axis=-1)
        velocity = np.stack([state["vx"], state["vy"], state["vz"]], axis=-1)
        return position, velocity, state["alt_m"]

    def legs_end_time(self, sensor_name: str) -> float:
        """End of the carrier's last scripted leg: afterwards it flies straight and level."""
        return float(self.trajectories.legs_end_time[self.index[sensor_name]])

    def end_time(self, sensor_name: str) -> float:
        return float(self.trajectories.end_time[self.index[sensor_name]])


def build_carriers(specs: dict[str, TargetSpec], duration_s: float, origin: Origin, rng: np.random.Generator) -> Carriers | None:
    """Fly the carriers (``specs``: sensor name -> carrier) over [0, duration_s]; None without any."""
    if not specs:
        return None
    names = list(specs)
    trajectories = build_trajectories([specs[name] for name in names], duration_s, origin, rng)
    return Carriers(trajectories, {name: k for k, name in enumerate(names)})


def scan_times(sensor: Sensor, end_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Times ``scan_phase_s + k scan_period_s`` in [0, end_s] and their scan numbers (scan 0 is
    the one in progress at t = 0, as for a rotating radar)."""
    period, phase = sensor.scan_period_s, sensor.scan_phase_s
    first, last = math.ceil(-phase / period), math.floor((end_s - phase) / period)
    k = np.arange(first, last + 1)
    return phase + k * period, (k - math.floor(-phase / period)).astype(np.int64)


def airborne_plots(
    sensor: Sensor,
    params: RadarSimParams,
    carriers: Carriers,
    traj: TrajectorySet,
    duration_s: float,
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Target and false plots of one airborne radar as plot columns plus the platform columns,
    each scan's plots in a random order (see the module docstring)."""
    times, scans = scan_times(sensor, min(duration_s, carriers.end_time(sensor.name)))
    n_targets = len(traj)
    target = np.tile(np.arange(n_targets, dtype=np.int64), times.size)
    scan_of = np.repeat(np.arange(times.size), n_targets)
    time = times[scan_of]
    alive = (time >= traj.start_time[target]) & (time <= traj.end_time[target])
    target, scan_of, time = target[alive], scan_of[alive], time[alive]
    state = traj.state(target, time)
    position = np.stack([state["x"], state["y"], state["z"]], axis=1)
    velocity = np.stack([state["vx"], state["vy"], state["vz"]], axis=1)
    own_position, own_velocity, own_alt = carriers.state(sensor.name, time)
    r, az, el, rdot, ground = polar_view(sensor, position, velocity, own_position, own_velocity)
    covered = in_coverage(sensor, r, el, ground, state["alt_m"], own_alt)
    detected = covered & (rng.random(time.size) < sensor.p_detection)
    columns = measured_plots(sensor, params, traj, rng, target, time, scans[scan_of], (r, az, el, rdot), detected,
                             state["alt_m"])
    false = _airborne_clutter(sensor, params, times, scans, rng)
    merged = {key: np.concatenate([columns[key], false[key]]) for key in columns}
    platform_position, platform_velocity, _ = carriers.state(sensor.name, merged["time"])
    platform = np.concatenate([platform_position, platform_velocity], axis=1)
    merged.update({name: platform[:, k] for k, name in enumerate(PLATFORM_COLUMNS)})
    # a scan's plots in random order (R17): the tie-breaking key of the time sort is random
    order = np.lexsort((rng.random(merged["time"].size), merged["scan"]))
    return {key: values[order] for key, values in merged.items()}


def _airborne_clutter(sensor: Sensor, params: RadarSimParams, times: np.ndarray, scans: np.ndarray,
                      rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Poisson(clutter_per_scan) false plots per scan, uniform in azimuth, range (or area),
    elevation and range-rate intervals."""
    per_scan = rng.poisson(sensor.clutter_per_scan, times.size)
    which = np.repeat(np.arange(times.size), per_scan)
    n = which.size
    # columns: range fraction, azimuth (turns), elevation fraction, range-rate fraction
    draws = rng.random((n, 4))
    fraction = draws[:, 0] if params.clutter_distribution == "range" else np.sqrt(draws[:, 0])
    columns = {
        "time": times[which],
        "range_m": sensor.max_range_m * fraction,
        "azimuth_deg": 360.0 * draws[:, 1],
        "scan": scans[which],
        "elevation_deg": np.full(n, np.nan),
        "range_rate_mps": np.full(n, np.nan),
    }
    if sensor.sigma_elevation_deg is not None:
        low, high = params.clutter_elevation_deg
        columns["elevation_deg"] = low + (high - low) * draws[:, 2]
    if sensor.sigma_range_rate_mps is not None:
        low, high = params.clutter_range_rate_mps
        columns["range_rate_mps"] = low + (high - low) * draws[:, 3]
    columns.update(_clutter_secondary(params, n, rng))
    columns.update({"mode_s": np.full(n, None, dtype=object), "truth_id": np.full(n, "", dtype=object)})
    return columns

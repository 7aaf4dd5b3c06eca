"""Rotating surveillance radars: coverage, beam-crossing times, detections, noise, SSR, clutter.

Antenna: the beam points north (the sensor's own north) at ``scan_phase_s + k scan_period_s``
and turns clockwise at ``360 deg / scan_period_s``.  Scan numbers count revolutions
(north to north), scan 0 being the one in progress at t = 0.  As with a real antenna, a
target crossing north in the beam's direction skips one scan number and a target crossing
north against it is seen twice with the same scan number; successive plots of a target
are always ``T / (1 - T * angular rate)`` apart.

Plot time: the beam crosses a target when ``(t - phase) / T - a(t)`` is an integer ``m``,
``a(t)`` being the target's azimuth in turns, unwrapped continuously along its trajectory
(so that targets near north are neither lost nor seen twice per revolution).  Each
crossing is first placed by linear interpolation between truth samples, then refined by
the fixed-point iteration ``t <- phase + T (m + a(t))`` on the exact trajectory, all
crossings of a sensor at once.  The iteration contracts by the ratio of the target's
angular rate to the beam's, so it converges in a few steps except for targets passing
almost over the radar.

Measurements are taken in the sensor's own frame (``Sensor.to_local``): slant range,
azimuth, elevation (radar-3d) and range rate ``p . v / r`` (when ``sigma_range_rate_mps`` is
set), plus independent Gaussian noise.  Coverage: range <= ``max_range_m``, elevation >=
``min_elevation_deg`` and ground distance within the 4/3-Earth radar horizon.  Detection is
Bernoulli(``p_detection``) per crossing in coverage.  SSR: transponder targets answer with
Mode 3/A (probability ``p_mode3a``) and Mode C (``p_mode_c``; height in feet rounded to
100 ft), and a target with an address always gives its Mode S address.

Clutter (false plots, ``truth_id`` ""): Poisson(``clutter_per_scan``) per revolution over
the disc of radius ``max_range_m``, uniform in range and azimuth (``clutter_distribution``
``range``, the default: dense near the radar) or uniform in area (``area``), plus Poisson(``per_scan``) per revolution in each clutter
patch, uniform in range and azimuth inside it.  Each false plot is timed by the beam
crossing of its azimuth.  A false plot carries a random Mode 3/A code (uniform over
0000-7777) with probability ``clutter_p_mode3a`` and a random Mode C height (uniform over
0-45 000 ft, rounded to 100 ft as the targets' are) with probability ``clutter_p_mode_c``;
never a Mode S address.  Random numbers for patches and false-plot SSR are drawn only
when a sensor has them, so the false plots of a sensor without them do not change.

Interrogator (``secondary_only``; spec 001's system З, issue 9): a secondary-surveillance or
IFF interrogator has no primary echo, so only targets that reply give plots.
:func:`radar_plots` takes the ``replying`` targets; a beam crossing in coverage gives a plot
with probability ``p_detection`` (the reply probability, which is also what the tracker reads
as this sensor's P_D), with the sensor's own range and azimuth noise and the replies' Mode 3/A,
Mode C and Mode S.  Its false plots are false replies (fruit, ``clutter_per_scan`` and patches),
drawn as a primary radar's false plots are.  The simulator gives an interrogator a random
stream of its own, so adding one to a scenario leaves the other sensors' plots unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.geo.polar import cartesian_to_polar
from skytrack.geo.sensors import Sensor
from skytrack.sim.earth import radar_horizon_range
from skytrack.sim.spec import RadarSimParams
from skytrack.sim.trajectories import TrajectorySet

FEET_PER_METRE = 1.0 / 0.3048
MODE_C_STEP_FT = 100.0
#: highest random Mode C height of a false plot (ft)
CLUTTER_MODE_C_MAX_FT = 45000.0
#: every Mode 3/A code as text, indexed by its value: false plots draw codes by index
MODE3A_CODES = np.array([f"{code:04o}" for code in range(8**4)], dtype=object)
#: beam-crossing time tolerance (s) and iteration cap of the fixed-point refinement
CROSSING_TOLERANCE_S = 1e-7
CROSSING_MAX_ITERATIONS = 30

#: order and names of the plot columns (FORMATS.md, plots)
PLOT_COLUMNS = (
    "time", "sensor", "range_m", "azimuth_deg", "scan", "elevation_deg", "range_rate_mps",
    "mode3a", "mode_c_ft", "mode_s", "iff", "truth_id",
)


@dataclass
class TruthSamples:
    """Truth rows of all targets, sorted by (target, time); what the radars interpolate from."""

    target: np.ndarray  # [R] int
    time: np.ndarray
    position: np.ndarray  # [R, 3] common ENU
    velocity: np.ndarray  # [R, 3]


def polar_view(sensor: Sensor, position: np.ndarray, velocity: np.ndarray | None = None,
               sensor_position: np.ndarray | None = None, sensor_velocity: np.ndarray | None = None):
    """Range, azimuth, elevation (rad) [, range rate] and ground distance in the sensor's own frame.

    ``sensor_position`` / ``sensor_velocity`` ``[K, 3]``: where a moving sensor (an airborne
    radar's carrier) is at each row; the range rate is then relative to it."""
    local = sensor.to_local(position, sensor_position)
    ground = np.hypot(local[:, 0], local[:, 1])
    if velocity is None:
        r, az, el = cartesian_to_polar(local[:, 0], local[:, 1], local[:, 2])
        return r, az, el, None, ground
    relative = velocity if sensor_velocity is None else velocity - sensor_velocity
    v = relative @ sensor.rotation.T
    r, az, el, rdot = cartesian_to_polar(local[:, 0], local[:, 1], local[:, 2], v[:, 0], v[:, 1], v[:, 2])
    return r, az, el, rdot, ground


def in_coverage(sensor: Sensor, r, el, ground, target_alt_m, sensor_alt_m=None) -> np.ndarray:
    """Inside max range, above the minimum elevation and within the radar horizon
    (``sensor_alt_m``: the height of a moving sensor at each row)."""
    return (
        (r <= sensor.max_range_m)
        & (el >= math.radians(sensor.min_elevation_deg))
        & (ground <= radar_horizon_range(sensor.alt_m if sensor_alt_m is None else sensor_alt_m, target_alt_m))
    )


def beam_azimuth_deg(sensor: Sensor, t) -> np.ndarray:
    """Direction of the beam (deg clockwise from the sensor's north) at time ``t``."""
    return 360.0 * np.remainder((np.asarray(t, dtype=float) - sensor.scan_phase_s) / sensor.scan_period_s, 1.0)


def scan_index(sensor: Sensor, t) -> np.ndarray:
    """Revolution number of time ``t``; scan 0 is the revolution in progress at t = 0."""
    period, phase = sensor.scan_period_s, sensor.scan_phase_s
    return (np.floor((np.asarray(t, dtype=float) - phase) / period) - math.floor(-phase / period)).astype(np.int64)


def _unwrapped_azimuth_turns(az_turns: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Azimuth in turns made continuous along each target's rows (rows sorted by target)."""
    if az_turns.size == 0:
        return az_turns
    jumps = np.concatenate([[0.0], -np.round(np.diff(az_turns))])
    offset = np.cumsum(jumps)
    first = np.flatnonzero(np.concatenate([[True], target[1:] != target[:-1]]))
    counts = np.diff(np.append(first, az_turns.size))
    return az_turns + offset - np.repeat(offset[first], counts)


@dataclass
class _Crossings:
    target: np.ndarray
    label: np.ndarray  # integer m of (t - phase)/T - a(t) = m
    time: np.ndarray
    azimuth_ref: np.ndarray  # unwrapped azimuth (turns) near the solution
    row: np.ndarray  # truth row just before the crossing


def _enumerate_crossings(sensor: Sensor, truth: TruthSamples) -> _Crossings:
    """All beam crossings of every target, placed by linear interpolation between truth rows."""
    _, az, _, _, _ = polar_view(sensor, truth.position)
    a = _unwrapped_azimuth_turns(az / (2.0 * math.pi), truth.target)
    g = (truth.time - sensor.scan_phase_s) / sensor.scan_period_s - a
    same = truth.target[1:] == truth.target[:-1]
    floor_g = np.floor(g)
    count = np.where(same, np.maximum(floor_g[1:] - floor_g[:-1], 0.0), 0.0).astype(np.int64)
    row = np.repeat(np.arange(count.size), count)
    within = np.arange(row.size) - np.repeat(np.cumsum(count) - count, count)
    label = floor_g[row] + 1.0 + within
    fraction = np.clip((label - g[row]) / (g[row + 1] - g[row]), 0.0, 1.0)
    time = truth.time[row] + fraction * (truth.time[row + 1] - truth.time[row])
    azimuth_ref = a[row] + fraction * (a[row + 1] - a[row])
    return _Crossings(truth.target[row], label, time, azimuth_ref, row)


def _refine_crossing_times(sensor: Sensor, traj: TrajectorySet, truth: TruthSamples, c: _Crossings) -> np.ndarray:
    """Fixed-point iteration t <- phase + T (m + a(t)) on the exact trajectory."""
    t = c.time.copy()
    active = np.arange(t.size)
    z0, vz0, t0 = truth.position[c.row, 2], truth.velocity[c.row, 2], truth.time[c.row]
    for _ in range(CROSSING_MAX_ITERATIONS):
        if active.size == 0:
            break
        ta = t[active]
        x, y, _, _, _, _ = traj.evaluate(c.target[active], ta)
        # z moves by vz over a fraction of a truth step: linear is exact to millimetres here
        z = z0[active] + vz0[active] * (ta - t0[active])
        _, az, _, _, _ = polar_view(sensor, np.stack([x, y, z], axis=1))
        turns = az / (2.0 * math.pi)
        turns += np.round(c.azimuth_ref[active] - turns)
        t_new = sensor.scan_phase_s + sensor.scan_period_s * (c.label[active] + turns)
        t[active] = t_new
        active = active[np.abs(t_new - ta) > CROSSING_TOLERANCE_S]
    return t


def radar_plots(
    sensor: Sensor, params: RadarSimParams, traj: TrajectorySet, truth: TruthSamples, rng: np.random.Generator,
    replying: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Target plots of one rotating radar as plot columns (unsorted, see PLOT_COLUMNS).

    ``replying`` ``[n_targets]`` bool: an interrogator's targets that answer (the others give
    no plot); None = a primary radar, which sees every target."""
    crossings = _enumerate_crossings(sensor, truth)
    time = _refine_crossing_times(sensor, traj, truth, crossings)
    target = crossings.target
    alive = (time >= traj.start_time[target]) & (time <= traj.end_time[target])
    time, target = time[alive], target[alive]
    state = traj.state(target, time)
    position = np.stack([state["x"], state["y"], state["z"]], axis=1)
    velocity = np.stack([state["vx"], state["vy"], state["vz"]], axis=1)
    r, az, el, rdot, ground = polar_view(sensor, position, velocity)
    detected = in_coverage(sensor, r, el, ground, state["alt_m"]) & (rng.random(time.size) < sensor.p_detection)
    if replying is not None:
        detected &= replying[target]
    return measured_plots(sensor, params, traj, rng, target, time, scan_index(sensor, time), (r, az, el, rdot),
                          detected, state["alt_m"])


def measured_plots(sensor: Sensor, params: RadarSimParams, traj: TrajectorySet, rng: np.random.Generator,
                   target: np.ndarray, time: np.ndarray, scan: np.ndarray, polar: tuple, detected: np.ndarray,
                   alt_m: np.ndarray) -> dict[str, np.ndarray]:
    """Plot columns of the ``detected`` (target, time) samples: the true ``polar`` view (range,
    azimuth, elevation, range rate) plus the sensor's noise (elevation when it measures it,
    range rate when it has a sigma), the secondary replies and the truth id."""
    r, az, el, rdot = polar
    index = np.flatnonzero(detected)
    n = index.size
    target = target[index]
    noise = rng.standard_normal((n, 4))
    columns = {
        "time": time[index],
        "range_m": np.maximum(r[index] + sensor.sigma_range_m * noise[:, 0], 0.0),
        "azimuth_deg": np.remainder(np.degrees(az[index]) + sensor.sigma_azimuth_deg * noise[:, 1], 360.0),
        "scan": scan[index],
        "elevation_deg": np.full(n, np.nan),
        "range_rate_mps": np.full(n, np.nan),
    }
    if sensor.is_3d:
        columns["elevation_deg"] = np.degrees(el[index]) + sensor.sigma_elevation_deg * noise[:, 2]
    if sensor.sigma_range_rate_mps is not None:
        columns["range_rate_mps"] = rdot[index] + sensor.sigma_range_rate_mps * noise[:, 3]
    columns.update(_secondary(params, traj, target, alt_m[index], rng))
    columns["truth_id"] = traj.ids[target]
    return columns


def _secondary(params: RadarSimParams, traj: TrajectorySet, target: np.ndarray, alt_m: np.ndarray, rng) -> dict[str, np.ndarray]:
    """Mode 3/A, Mode C and Mode S replies of the detected targets."""
    draws = rng.random((target.size, 2))
    transponder = traj.transponder[target]
    code = traj.mode3a[target]
    with_code = transponder & (draws[:, 0] < params.p_mode3a) & np.not_equal(code, None)
    mode3a = np.where(with_code, code, None)
    with_c = transponder & (draws[:, 1] < params.p_mode_c)
    mode_c = np.where(with_c, MODE_C_STEP_FT * np.round(alt_m * FEET_PER_METRE / MODE_C_STEP_FT), np.nan)
    mode_s = np.where(transponder, traj.icao24[target], None)
    return {"mode3a": mode3a, "mode_c_ft": mode_c, "mode_s": mode_s}


def clutter_plots(sensor: Sensor, params: RadarSimParams, duration_s: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """False plots of one radar over [0, duration_s]: the coverage-wide clutter, then the
    clutter patches, each plot at the time the beam crosses its azimuth (see the module docstring)."""
    period, phase = sensor.scan_period_s, sensor.scan_phase_s
    first, last = math.floor(-phase / period), math.floor((duration_s - phase) / period)
    revolutions = np.arange(first, last + 1)
    per_scan = rng.poisson(sensor.clutter_per_scan, revolutions.size)
    revolution = np.repeat(revolutions, per_scan)
    # columns: range fraction, azimuth (turns), elevation fraction, range-rate fraction
    draws = rng.random((revolution.size, 4))
    fraction = draws[:, 0] if params.clutter_distribution == "range" else np.sqrt(draws[:, 0])
    range_m = sensor.max_range_m * fraction
    turns, spread = draws[:, 1], draws[:, 2:]
    if params.clutter_patches:
        patch_revolution, patch_range, patch_turns, patch_spread = _patch_clutter(params.clutter_patches, revolutions, rng)
        revolution = np.concatenate([revolution, patch_revolution])
        range_m = np.concatenate([range_m, patch_range])
        turns = np.concatenate([turns, patch_turns])
        spread = np.concatenate([spread, patch_spread])
    n = revolution.size
    time = phase + period * (revolution + turns)
    columns = {
        "time": time,
        "range_m": range_m,
        "azimuth_deg": 360.0 * turns,
        "scan": (revolution - first).astype(np.int64),
        "elevation_deg": np.full(n, np.nan),
        "range_rate_mps": np.full(n, np.nan),
    }
    if sensor.is_3d:
        low, high = params.clutter_elevation_deg
        columns["elevation_deg"] = low + (high - low) * spread[:, 0]
    if sensor.sigma_range_rate_mps is not None:
        low, high = params.clutter_range_rate_mps
        columns["range_rate_mps"] = low + (high - low) * spread[:, 1]
    keep = (time >= 0.0) & (time <= duration_s)
    columns = {k: v[keep] for k, v in columns.items()}
    m = int(keep.sum())
    columns.update(_clutter_secondary(params, m, rng))
    columns.update({"mode_s": np.full(m, None, dtype=object), "truth_id": np.full(m, "", dtype=object)})
    return columns


def _patch_clutter(patches, revolutions: np.ndarray, rng: np.random.Generator):
    """Revolution, range, azimuth (turns) and [elevation, range-rate] fractions of the patches' false plots."""
    counts = rng.poisson([patch.per_scan for patch in patches], (revolutions.size, len(patches))).ravel()
    revolution = np.repeat(np.repeat(revolutions, len(patches)), counts)
    which = np.repeat(np.tile(np.arange(len(patches)), revolutions.size), counts)
    near = np.array([patch.range_m[0] for patch in patches])[which]
    far = np.array([patch.range_m[1] for patch in patches])[which]
    start = np.array([patch.azimuth_deg[0] / 360.0 for patch in patches])[which]
    width = np.array([patch.width_deg / 360.0 for patch in patches])[which]
    draws = rng.random((which.size, 4))
    # a sector through north ([350, 20]) runs past 1 turn and wraps to the start of the revolution
    turns = np.remainder(start + width * draws[:, 1], 1.0)
    return revolution, near + (far - near) * draws[:, 0], turns, draws[:, 2:]


def _clutter_secondary(params: RadarSimParams, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Random Mode 3/A codes and Mode C heights on false plots (garbled or fruit replies)."""
    mode3a = np.full(n, None, dtype=object)
    mode_c = np.full(n, np.nan)
    if params.clutter_p_mode3a > 0.0:
        with_code = rng.random(n) < params.clutter_p_mode3a
        mode3a = np.where(with_code, MODE3A_CODES[rng.integers(0, MODE3A_CODES.size, n)], None)
    if params.clutter_p_mode_c > 0.0:
        with_c = rng.random(n) < params.clutter_p_mode_c
        feet = rng.uniform(0.0, CLUTTER_MODE_C_MAX_FT, n)
        mode_c = np.where(with_c, MODE_C_STEP_FT * np.round(feet / MODE_C_STEP_FT), np.nan)
    return {"mode3a": mode3a, "mode_c_ft": mode_c}

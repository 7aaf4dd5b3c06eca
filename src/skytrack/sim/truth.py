"""Truth sampling: every target every ``truth_sample_s`` (plus its exact start and end instants).

Rows follow FORMATS.md "truth": time, target_id, segment, x, y, z, vx, vy, vz, lat, lon,
alt_m, visible.  ``visible`` is true when at least one sensor covers the target
(:func:`skytrack.sim.radar.in_coverage`).  A target that lands ends at touchdown (its
last row).  After its last leg a target is ended at the first sample where it is outside
every sensor's maximum range and opening from every sensor: flying straight it cannot
come back, so it has left the coverage for good.  An airborne radar judges from its
carrier's position at the sample time, and only once the carrier too flies its last
straight leg (the relative motion is then a straight line as well).
Sampling is vectorised over all (target, time) rows, in chunks to bound memory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.geo.sensors import SensorSet
from skytrack.sim.carrier import Carriers
from skytrack.sim.radar import TruthSamples, in_coverage, polar_view
from skytrack.sim.trajectories import TrajectorySet

#: rows evaluated per chunk (memory ~ 1 kB per row in flight)
CHUNK_ROWS = 500_000
#: two sample instants closer than this (s) are the same instant
_SAME_INSTANT_S = 1e-9


@dataclass
class TruthTable:
    samples: TruthSamples
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray
    visible: np.ndarray


def sample_times(start: np.ndarray, end: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """(target index, time) of every row: the start, the multiples of ``step`` inside, and the end."""
    first_k = np.floor(start / step + _SAME_INSTANT_S) + 1.0
    last_k = np.ceil(end / step - _SAME_INSTANT_S) - 1.0
    inner = np.maximum(last_k - first_k + 1.0, 0.0).astype(np.int64)
    has_end = end > start + _SAME_INSTANT_S
    count = 1 + inner + has_end
    target = np.repeat(np.arange(start.size), count)
    position = np.arange(target.size) - np.repeat(np.cumsum(count) - count, count)
    time = (np.repeat(first_k, count) + position - 1.0) * step
    is_start = position == 0
    time[is_start] = start[target[is_start]]
    is_end = has_end[target] & (position == count[target] - 1)
    time[is_end] = end[target[is_end]]
    return target, time


def sample_truth(traj: TrajectorySet, sensors: SensorSet, step: float, progress=None,
                 carriers: Carriers | None = None) -> TruthTable:
    """Sample all trajectories; ends targets that left the coverage (updates ``traj.end_time``).

    ``carriers``: the flights of the airborne radars (required when there are any)."""
    target, time = sample_times(traj.start_time, traj.end_time, step)
    n = target.size
    position = np.empty((n, 3))
    velocity = np.empty((n, 3))
    lat, lon, alt = np.empty(n), np.empty(n), np.empty(n)
    visible = np.zeros(n, dtype=bool)
    gone = np.ones(n, dtype=bool)  # outside every max range and opening from every sensor
    n_chunks = max(1, math.ceil(n / CHUNK_ROWS))
    for chunk in range(n_chunks):
        rows = slice(chunk * CHUNK_ROWS, min(n, (chunk + 1) * CHUNK_ROWS))
        state = traj.state(target[rows], time[rows])
        position[rows] = np.stack([state["x"], state["y"], state["z"]], axis=1)
        velocity[rows] = np.stack([state["vx"], state["vy"], state["vz"]], axis=1)
        lat[rows], lon[rows], alt[rows] = state["lat"], state["lon"], state["alt_m"]
        for sensor in sensors.sensors:
            if sensor.is_moving:
                own_position, own_velocity, own_alt = carriers.state(sensor.name, time[rows])
                r, _, el, rdot, ground = polar_view(sensor, position[rows], velocity[rows], own_position, own_velocity)
                visible[rows] |= in_coverage(sensor, r, el, ground, alt[rows], own_alt)
                straight = time[rows] >= carriers.legs_end_time(sensor.name)
                gone[rows] &= (r > sensor.max_range_m) & (rdot > 0.0) & straight
                continue
            r, _, el, rdot, ground = polar_view(sensor, position[rows], velocity[rows])
            visible[rows] |= in_coverage(sensor, r, el, ground, alt[rows])
            gone[rows] &= (r > sensor.max_range_m) & (rdot > 0.0)
        if progress is not None:
            progress((chunk + 1) / n_chunks)
    keep = _truncate_departed(traj, target, time, gone)
    samples = TruthSamples(target[keep], time[keep], position[keep], velocity[keep])
    return TruthTable(samples, lat[keep], lon[keep], alt[keep], visible[keep])


def _truncate_departed(traj: TrajectorySet, target: np.ndarray, time: np.ndarray, gone: np.ndarray) -> np.ndarray:
    """Rows to keep once each target ends at its first 'gone' sample after its last leg."""
    candidate = np.flatnonzero(gone & (time >= traj.legs_end_time[target]))
    departed, first = np.unique(target[candidate], return_index=True)
    traj.end_time[departed] = time[candidate[first]]
    return time <= traj.end_time[target] + _SAME_INSTANT_S

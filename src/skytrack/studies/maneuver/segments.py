"""Manoeuvre detection on sampled truth (spec 004 R19): onsets and ends of manoeuvre segments.

A sample manoeuvres when its acceleration normal to the velocity, ``|a_perp| = |v x a| / |v|``,
exceeds ``accel_threshold_mps2`` or (when given) its turn rate ``|v x a| / |v|^2`` exceeds
``turn_rate_threshold_rad_s``; optionally also when the acceleration along the velocity
exceeds ``longitudinal_threshold_mps2``.  A segment is a run of consecutive manoeuvring samples
lasting at least ``min_duration_s`` (from its first to its last sample, plus one sample
period); runs separated by at most ``merge_gap_s`` are joined first.  Onset = the first
sample of the segment, end = its last sample.

Two rules are named:

* :data:`SPEC_RULE` — spec 004 R19: ``|a_perp| > 1 g0`` for >= 3 s (fighter-class manoeuvres);
* :data:`AIRLINER_RULE` — recorded airliner traffic: turn rate > 1 deg/s or ``|a_perp| > 0.2 g0``
  for >= 5 s (a standard-rate turn is 3 deg/s at about 0.15-0.3 g).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.studies.maneuver.trajectory import G0


@dataclass(frozen=True)
class ManeuverRule:
    """Thresholds of :func:`maneuver_segments` (see the module docstring)."""

    accel_threshold_mps2: float = 1.0 * G0
    min_duration_s: float = 3.0
    turn_rate_threshold_rad_s: float | None = None
    longitudinal_threshold_mps2: float | None = None
    merge_gap_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.accel_threshold_mps2) and self.accel_threshold_mps2 > 0):
            raise ValueError(f"maneuver rule: accel threshold must be > 0, got {self.accel_threshold_mps2}")
        if not (math.isfinite(self.min_duration_s) and self.min_duration_s >= 0):
            raise ValueError(f"maneuver rule: min_duration_s must be >= 0, got {self.min_duration_s}")
        for name in ("turn_rate_threshold_rad_s", "longitudinal_threshold_mps2"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"maneuver rule: {name} must be > 0 or None, got {value}")
        if not (math.isfinite(self.merge_gap_s) and self.merge_gap_s >= 0):
            raise ValueError(f"maneuver rule: merge_gap_s must be >= 0, got {self.merge_gap_s}")

    @classmethod
    def from_dict(cls, values: dict) -> "ManeuverRule":
        """From config keys ``accel_g``, ``min_duration_s``, ``turn_rate_deg_s``, ``longitudinal_g``, ``merge_gap_s``."""
        known = {"accel_g", "min_duration_s", "turn_rate_deg_s", "longitudinal_g", "merge_gap_s"}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"maneuver_rule: unknown key(s) {unknown}; known: {sorted(known)}")
        turn = values.get("turn_rate_deg_s")
        longitudinal = values.get("longitudinal_g")
        return cls(
            accel_threshold_mps2=float(values.get("accel_g", 1.0)) * G0,
            min_duration_s=float(values.get("min_duration_s", 3.0)),
            turn_rate_threshold_rad_s=None if turn is None else math.radians(float(turn)),
            longitudinal_threshold_mps2=None if longitudinal is None else float(longitudinal) * G0,
            merge_gap_s=float(values.get("merge_gap_s", 0.0)),
        )


SPEC_RULE = ManeuverRule(accel_threshold_mps2=1.0 * G0, min_duration_s=3.0)
AIRLINER_RULE = ManeuverRule(accel_threshold_mps2=0.2 * G0, min_duration_s=5.0,
                             turn_rate_threshold_rad_s=math.radians(1.0))
RULES = {"spec": SPEC_RULE, "airliner": AIRLINER_RULE}


def normal_acceleration(velocity: np.ndarray, acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``|a_perp|`` (m/s^2) and turn rate ``|a_perp| / |v|`` (rad/s) per sample of ``[K, 3]`` arrays."""
    v = np.asarray(velocity, dtype=float)
    a = np.asarray(acceleration, dtype=float)
    speed = np.linalg.norm(v, axis=-1)
    cross = np.linalg.norm(np.cross(v, a), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a_perp = np.where(speed > 0, cross / speed, np.linalg.norm(a, axis=-1))
        rate = np.where(speed > 0, a_perp / speed, 0.0)
    return a_perp, rate


def maneuvering_samples(velocity: np.ndarray, acceleration: np.ndarray, rule: ManeuverRule) -> np.ndarray:
    """Boolean per sample: the rule's thresholds are exceeded."""
    a_perp, rate = normal_acceleration(velocity, acceleration)
    flag = a_perp > rule.accel_threshold_mps2
    if rule.turn_rate_threshold_rad_s is not None:
        flag |= rate > rule.turn_rate_threshold_rad_s
    if rule.longitudinal_threshold_mps2 is not None:
        v = np.asarray(velocity, dtype=float)
        speed = np.linalg.norm(v, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            along = np.abs(np.sum(v * acceleration, axis=-1)) / np.where(speed > 0, speed, np.inf)
        flag |= along > rule.longitudinal_threshold_mps2
    return flag


def maneuver_segments(time, velocity, acceleration, rule: ManeuverRule = SPEC_RULE) -> list[tuple[float, float]]:
    """(onset, end) times of the manoeuvre segments of regularly sampled truth (module docstring)."""
    t = np.asarray(time, dtype=float)
    if t.size == 0:
        return []
    if np.any(np.diff(t) <= 0):
        raise ValueError("maneuver_segments: times must increase strictly")
    period = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    flag = maneuvering_samples(velocity, acceleration, rule)
    runs = _runs(flag)
    merged: list[list[int]] = []
    for first, last in runs:
        if merged and t[first] - t[merged[-1][1]] - period <= rule.merge_gap_s + 1e-9 and rule.merge_gap_s > 0:
            merged[-1][1] = last
        else:
            merged.append([first, last])
    return [(float(t[a]), float(t[b])) for a, b in merged
            if t[b] - t[a] + period >= rule.min_duration_s - 1e-9]


def _runs(flag: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True."""
    padded = np.r_[False, flag, False].astype(np.int8)
    edges = np.diff(padded)
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    return list(zip(starts.tolist(), ends.tolist()))

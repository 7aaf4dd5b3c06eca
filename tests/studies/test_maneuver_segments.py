"""Spec 004 R19 manoeuvre detection: the |a_perp| > 1 g0 for >= 3 s rule, the airliner rule, and recorded truth
(truth file -> ENU -> smoothing spline -> kinematics at T -> onsets)."""

import math

import numpy as np
import pandas as pd
import pytest

from skytrack.geo.sensors import Origin
from skytrack.io.frames import geodetic_from_enu
from skytrack.studies.maneuver.recorded import DEFAULT_RADAR_OFFSET_M, load_recorded, smooth_kinematics
from skytrack.studies.maneuver.scenarios import recorded_cases
from skytrack.studies.maneuver.segments import (
    AIRLINER_RULE,
    SPEC_RULE,
    ManeuverRule,
    maneuver_segments,
    normal_acceleration,
)
from skytrack.studies.maneuver.trajectory import G0, fly, straight, turn

P0 = np.array([-10_000.0, 40_000.0, 6_000.0])


def segments_of(legs, rule, speed=250.0, dt=1.0):
    path = fly(P0, [speed, 0.0, 0.0], legs)
    kin = path.evaluate(np.arange(0.0, path.duration_s + 1e-9, dt))
    return maneuver_segments(kin.time, kin.velocity, kin.acceleration, rule)


def test_spec_rule_finds_the_turn_of_the_default_scenario():
    onset_end = segments_of([straight(40), turn(3.0, 180.0), straight(30)], SPEC_RULE)
    duration = math.pi * 250.0 / (3 * G0)
    assert onset_end == [(40.0, float(math.floor(40.0 + duration)))]


def test_minimum_duration():
    """A run of k samples at period T lasts k T: a 1.5 s turn (samples 20, 21) is too short, a 3 s one is not."""
    short = [straight(20), turn(3.0, duration_s=1.5), straight(20)]
    assert segments_of(short, SPEC_RULE) == []
    assert segments_of(short, ManeuverRule(min_duration_s=2.0)) == [(20.0, 21.0)]
    assert segments_of([straight(20), turn(3.0, duration_s=3.0), straight(20)], SPEC_RULE) == [(20.0, 22.0)]


def test_airliner_rule_uses_turn_rate_or_acceleration():
    gentle = [straight(20), turn(0.15, duration_s=30.0), straight(20)]  # 0.15 g at 100 m/s: 0.84 deg/s
    assert segments_of(gentle, AIRLINER_RULE, speed=100.0) == []
    assert segments_of(gentle, AIRLINER_RULE, speed=60.0) == [(20.0, 49.0)]  # 1.4 deg/s
    firm = [straight(20), turn(0.25, duration_s=30.0), straight(20)]  # 0.25 g at 250 m/s: 0.56 deg/s
    assert segments_of(firm, AIRLINER_RULE, speed=250.0) == [(20.0, 49.0)]
    assert segments_of(firm, SPEC_RULE, speed=250.0) == []


def test_merge_gap_joins_close_turns():
    legs = [straight(10), turn(2.0, duration_s=5.0), straight(2.0), turn(2.0, duration_s=5.0, direction="right"), straight(10)]
    assert segments_of(legs, SPEC_RULE) == [(10.0, 14.0), (17.0, 21.0)]
    assert segments_of(legs, ManeuverRule(merge_gap_s=2.0)) == [(10.0, 21.0)]


def test_normal_acceleration_and_rule_config():
    a_perp, rate = normal_acceleration(np.array([[100.0, 0, 0], [100.0, 0, 0]]), np.array([[3.0, 4.0, 0], [0, 0, 0]]))
    assert np.allclose(a_perp, [4.0, 0.0]) and np.allclose(rate, [0.04, 0.0])
    rule = ManeuverRule.from_dict({"accel_g": 0.2, "turn_rate_deg_s": 1, "min_duration_s": 5})
    assert rule == AIRLINER_RULE
    with pytest.raises(ValueError, match="unknown key"):
        ManeuverRule.from_dict({"accel": 1})


def _truth_file(tmp_path, geodetic_origin: Origin | None = None, noise_m: float = 0.0, step: float = 2.0):
    path = fly(P0, [250.0, 0.0, 0.0], [straight(60), turn(3.0, 180.0), straight(60)])
    t = np.arange(0.0, path.duration_s, step)
    kin = path.evaluate(t)
    xyz = kin.position + noise_m * np.random.default_rng(3).standard_normal(kin.position.shape)
    frame = pd.DataFrame({"time": 1000.0 + t, "target_id": "T1"})
    if geodetic_origin is None:
        frame[["x", "y", "z"]] = xyz
    else:
        geo = geodetic_from_enu(xyz[:, 0], xyz[:, 1], xyz[:, 2], geodetic_origin)
        frame["lat"], frame["lon"], frame["alt_m"] = geo[:, 0], geo[:, 1], geo[:, 2]
    file = tmp_path / "truth.csv"
    frame.to_csv(file, index=False)
    return file, path


def test_smoothing_spline_recovers_kinematics_of_noise_free_samples(tmp_path):
    file, path = _truth_file(tmp_path)
    [item] = load_recorded(file, 1.0)
    assert item.label == "T1/0" and item.start_time == 1000.0
    truth = path.evaluate(item.truth.time)
    error = item.truth.position - truth.position
    assert np.sqrt(np.mean(error**2)) < 0.5 and np.max(np.abs(error)) < 5.0  # largest at the jumps of acceleration
    inside = (np.abs(item.truth.time - 60.0) > 8) & (np.abs(item.truth.time - 60.0 - math.pi * 250 / (3 * G0)) > 8) \
        & (item.truth.time > 8) & (item.truth.time < item.truth.time[-1] - 8)
    assert np.max(np.abs(item.truth.velocity[inside] - truth.velocity[inside])) < 1.0
    assert np.max(np.abs(item.truth.acceleration[inside] - truth.acceleration[inside])) < 1.0  # of a 29.4 m/s^2 turn
    [(onset, end)] = item.maneuvers
    assert abs(onset - 60.0) <= 3.0 and abs(end - (60.0 + math.pi * 250 / (3 * G0))) <= 3.0


def test_noisy_geodetic_recording_with_origin_and_default_origin(tmp_path):
    origin = Origin(47.0, 8.0, 0.0)
    file, path = _truth_file(tmp_path, origin, noise_m=5.0)
    [item] = load_recorded(file, 1.0, origin=origin)
    truth = path.evaluate(item.truth.time)
    assert np.sqrt(np.mean((item.truth.position - truth.position) ** 2)) < 5.0  # smoothed below the noise
    [(onset, _)] = item.maneuvers
    assert abs(onset - 60.0) <= 3.0
    [default] = load_recorded(file, 1.0)  # geodetic only: the radar 40 km south of the mean position
    mean = default.truth.position.mean(axis=0)
    assert mean[1] == pytest.approx(DEFAULT_RADAR_OFFSET_M, abs=200.0) and abs(mean[0]) < 200.0
    [case] = recorded_cases(file, dt=2.0, origin=origin)
    assert case.scenario == "recorded" and case.dt == 2.0 and np.allclose(np.diff(case.truth.time), 2.0)


def test_short_segments_are_skipped(tmp_path):
    file, _ = _truth_file(tmp_path)
    with pytest.raises(ValueError, match="no trajectory"):
        load_recorded(file, 1.0, min_duration_s=1e6)
    with pytest.raises(ValueError, match="at least 5 samples"):
        smooth_kinematics(np.arange(3.0), np.zeros((3, 3)), 1.0)

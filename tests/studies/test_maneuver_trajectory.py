"""Spec 004 R19 scripted scenarios: exact analytic legs, manoeuvre intervals, named scenarios, scenario files."""

import math

import numpy as np
import pytest

from skytrack.studies.maneuver.scenarios import (
    DEFAULT_START_POSITION,
    FIGHTER_RANGE_M,
    named_cases,
    parse_scenario,
)
from skytrack.studies.maneuver.trajectory import G0, Leg, accelerate, fly, pull_up, straight, turn

P0 = np.array([-10_000.0, 40_000.0, 6_000.0])
V0 = np.array([250.0, 0.0, 0.0])


def central_difference(path, t, h=1e-4):
    ahead, back = path.evaluate(t + h), path.evaluate(t - h)
    return (ahead.position - back.position) / (2 * h), (ahead.velocity - back.velocity) / (2 * h)


def test_straight_leg_is_constant_velocity():
    path = fly(P0, V0, [straight(40.0)])
    kin = path.evaluate([0.0, 12.5, 40.0])
    assert np.allclose(kin.position, P0 + np.outer([0.0, 12.5, 40.0], V0), rtol=0, atol=1e-9)
    assert np.all(kin.acceleration == 0) and path.maneuvers() == []


@pytest.mark.parametrize("n", [3.0, 5.0, 7.0])
def test_coordinated_turn_is_exact(n):
    """Left 180 deg turn of n g: constant speed, |a| = n g0, duration pi v / (n g0), lateral offset 2 v^2/(n g0) north."""
    path = fly(P0, V0, [straight(40.0), turn(n, 180.0, "left"), straight(30.0)])
    radius = 250.0**2 / (n * G0)
    duration = math.pi * 250.0 / (n * G0)
    assert path.maneuvers() == [(40.0, pytest.approx(40.0 + duration, rel=1e-12))]
    end = path.evaluate([40.0 + duration])
    assert np.allclose(end.velocity[0], [-250.0, 0.0, 0.0], atol=1e-9)
    assert np.allclose(end.position[0], P0 + [250.0 * 40.0, 2 * radius, 0.0], atol=1e-6)
    t = np.linspace(40.5, 40.0 + duration - 0.5, 25)
    kin = path.evaluate(t)
    assert np.allclose(np.linalg.norm(kin.velocity, axis=1), 250.0, rtol=1e-12)
    assert np.allclose(np.linalg.norm(kin.acceleration, axis=1), n * G0, rtol=1e-12)
    assert np.all(kin.acceleration[:2, 1] > 0)  # a left turn of an eastbound target accelerates north first
    dp, dv = central_difference(path, t)
    assert np.allclose(dp, kin.velocity, atol=1e-5) and np.allclose(dv, kin.acceleration, atol=1e-4)


def test_legs_join_continuously():
    path = fly(P0, V0, [straight(10.0), turn(4.0, 90.0, "right"), pull_up(3.0, duration_s=5.0), accelerate(1.0, 5.0),
                        straight(5.0)])
    for t in path.piece_t1[:-1]:
        a, b = path.evaluate([t - 1e-9]), path.evaluate([t + 1e-9])
        assert np.allclose(a.position, b.position, atol=1e-5) and np.allclose(a.velocity, b.velocity, atol=1e-5)


def test_pull_up_and_longitudinal_acceleration():
    path = fly(P0, V0, [straight(40.0), pull_up(3.0, duration_s=10.0), accelerate(1.0, 10.0), straight(30.0)])
    assert path.maneuvers() == [(40.0, 60.0)]  # consecutive manoeuvre legs are one manoeuvre
    start = path.evaluate([40.0])
    assert np.allclose(start.acceleration[0], [0.0, 0.0, 3.0 * G0], atol=1e-12)
    climb = path.evaluate([50.0])
    angle = 3.0 * G0 / 250.0 * 10.0
    assert np.allclose(climb.velocity[0], 250.0 * np.array([math.cos(angle), 0.0, math.sin(angle)]), atol=1e-9)
    fast = path.evaluate([60.0])
    assert np.linalg.norm(fast.velocity[0]) == pytest.approx(250.0 + G0 * 10.0, rel=1e-12)
    assert np.allclose(np.cross(fast.velocity[0], climb.velocity[0]), 0.0, atol=1e-6)  # direction kept


@pytest.mark.parametrize("kwargs, message", [
    ({"type": "turn", "g": 3, "duration_s": 5, "turn_deg": 90}, "exactly one"),
    ({"type": "turn", "g": 0, "turn_deg": 90}, "g > 0"),
    ({"type": "turn", "g": 3, "turn_deg": 90, "direction": "up"}, "direction"),
    ({"type": "straight"}, "duration_s"),
    ({"type": "loop", "duration_s": 3}, "leg type"),
])
def test_bad_legs_are_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Leg(**kwargs)


def test_named_scenarios_follow_section_6():
    default = named_cases("default")
    assert [c.params["n"] for c in default] == [3.0, 5.0, 7.0]
    assert all(c.dt == 1.0 and c.sensor.sigma_range_m == 25.0 and c.sensor.sigma_azimuth_rad == 1.5e-3 for c in default)
    assert np.allclose(default[0].truth.position[0], DEFAULT_START_POSITION)
    assert np.allclose(default[0].truth.time, np.arange(default[0].scans))
    weave = named_cases("weave")[0]
    assert len(weave.maneuvers) == 4 and np.allclose(np.diff([m[0] for m in weave.maneuvers]),
                                                     math.pi / 2 * 250.0 / (4 * G0) + 10.0)
    fighter = named_cases("fighter")
    assert [c.params["n"] for c in fighter] == [3.0, 5.0, 7.0, 9.0]
    assert fighter[0].dt == 0.1 and fighter[0].sensor.sigma_range_m == 10.0 and fighter[0].sensor.sigma_elevation_rad == 2e-3
    assert np.linalg.norm(fighter[0].truth.position[0]) == pytest.approx(FIGHTER_RANGE_M, rel=1e-12)
    assert named_cases("vertical")[0].maneuvers == [(40.0, 60.0)]
    with pytest.raises(ValueError, match="unknown scenario 'loop'"):
        named_cases("loop")


def test_scenario_file_mapping():
    case = parse_scenario({
        "name": "s-turn", "dt_s": 0.5, "sensor": {"sigma_range_m": 10, "sigma_angle_mrad": 2},
        "start": {"position_m": [0, 30000, 5000], "velocity_mps": [0, -200, 0]},
        "legs": [{"type": "straight", "duration_s": 10}, {"type": "turn", "g": 4, "direction": "right", "duration_s": 6},
                 {"type": "straight", "duration_s": 4}],
    }, "file")
    assert case.label == "s-turn" and case.dt == 0.5 and case.scans == 41
    assert case.sensor.sigma_azimuth_rad == 2e-3 and case.sensor.sigma_range_m == 10
    assert case.maneuvers == [(10.0, 16.0)]
    with pytest.raises(ValueError, match=r"legs\[1\]"):
        parse_scenario({"legs": [{"type": "straight", "duration_s": 1}, {"type": "turn", "g": 4}]}, "x")
    with pytest.raises(ValueError, match="unknown key"):
        parse_scenario({"legs": [{"type": "straight", "duration_s": 1}], "wind": 3}, "x")

"""Trajectories: exact coordinated turns, climbs, accelerations, waypoints, Singer legs, truth table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_builders import radar, scenario, target
from skytrack.geo import Origin, enu_to_geodetic, geodetic_to_enu
from skytrack.models import SingerAxisModel
from skytrack.sim import TRUTH_COLUMNS, load_scenario, simulate
from skytrack.sim.earth import place_at_height, radar_horizon_range
from skytrack.sim.scenario import GRAVITY_MPS2, SingerLeg, TargetSpec
from skytrack.sim.traffic import seed_stream
from skytrack.sim.trajectories import build_trajectories
from skytrack.sim.truth import sample_times

ORIGIN = Origin(48.86, 2.50, 0.0)


def trajectories_of(*targets: TargetSpec, duration_s: float = 300.0, seed: int = 0):
    return build_trajectories(list(targets), duration_s, ORIGIN, np.random.default_rng(seed))


def spec(legs=(), **kw) -> TargetSpec:
    base = dict(id="t", x=1000.0, y=2000.0, alt_m=5000.0, speed_mps=250.0, heading_deg=30.0)
    base.update(kw)
    return TargetSpec(legs=tuple(legs), **base)


def heading_deg(vx, vy):
    return np.degrees(np.arctan2(vx, vy)) % 360.0


@pytest.mark.parametrize(("g", "direction", "turn_deg"), [(3.0, "right", 270.0), (1.5, "left", 90.0), (6.0, "left", 400.0)])
def test_coordinated_turn_is_an_exact_arc_with_the_requested_radius_rate_and_angle(g, direction, turn_deg):
    from skytrack.sim.scenario import StraightLeg, TurnLeg

    speed = 250.0
    traj = trajectories_of(spec([StraightLeg(10.0), TurnLeg(g, direction, turn_deg=turn_deg)], speed_mps=speed))
    rate = g * GRAVITY_MPS2 / speed  # rad/s
    radius = speed**2 / (g * GRAVITY_MPS2)
    duration = math.radians(turn_deg) / rate
    t = np.linspace(10.0, 10.0 + duration, 200)
    x, y, h, vx, vy, _ = traj.evaluate(np.zeros(t.size, dtype=int), t)
    # centre from the start of the turn: a radius to the right (right turn) or left of the heading
    sign = 1.0 if direction == "right" else -1.0
    psi = math.radians(30.0)
    cx, cy = x[0] + sign * radius * math.cos(psi), y[0] - sign * radius * math.sin(psi)
    np.testing.assert_allclose(np.hypot(x - cx, y - cy), radius, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(vx, vy), speed, rtol=1e-12)
    lateral = np.hypot(np.gradient(vx, t), np.gradient(vy, t))
    np.testing.assert_allclose(lateral[1:-1], g * GRAVITY_MPS2, rtol=1e-3)
    turned = np.unwrap(np.radians(heading_deg(vx, vy)))
    np.testing.assert_allclose(sign * (turned - turned[0]), rate * (t - t[0]), atol=1e-9)
    assert abs(sign * (turned[-1] - turned[0]) - math.radians(turn_deg)) < 1e-9
    np.testing.assert_allclose(h, 5000.0)
    # after the turn: straight on the new heading
    x2, y2, _, vx2, vy2, _ = traj.evaluate(np.zeros(2, dtype=int), np.array([10.0 + duration + 1.0, 10.0 + duration + 20.0]))
    np.testing.assert_allclose(heading_deg(vx2, vy2), (30.0 + sign * turn_deg) % 360.0, atol=1e-8)
    assert abs(np.hypot(x2[1] - x2[0], y2[1] - y2[0]) - 19.0 * speed) < 1e-6


def test_turn_given_by_duration_turns_at_the_coordinated_rate():
    from skytrack.sim.scenario import TurnLeg

    traj = trajectories_of(spec([TurnLeg(2.0, "right", duration_s=30.0)], speed_mps=200.0))
    _, _, _, vx, vy, _ = traj.evaluate(np.zeros(2, dtype=int), np.array([0.0, 30.0]))
    turned = (heading_deg(vx[1], vy[1]) - heading_deg(vx[0], vy[0])) % 360.0
    assert abs(turned - math.degrees(30.0 * 2.0 * GRAVITY_MPS2 / 200.0)) < 1e-9


def test_climb_rates_and_levelling_off():
    from skytrack.sim.scenario import ClimbLeg, StraightLeg

    # climb 3000 m at 12 m/s: 10 s -> 260 s; descent at 5 m/s: 260 s -> 300 s; then level
    t = np.array([5.0, 10.0, 60.0, 260.0, 270.0, 299.0, 320.0])
    traj = trajectories_of(spec([StraightLeg(10.0), ClimbLeg(12.0, to_alt_m=8000.0), ClimbLeg(-5.0, duration_s=40.0)]), duration_s=400.0)
    _, _, h, _, _, hdot = traj.evaluate(np.zeros(t.size, dtype=int), t)
    np.testing.assert_allclose(h, [5000.0, 5000.0, 5600.0, 8000.0, 7950.0, 7805.0, 7800.0], atol=1e-9)
    np.testing.assert_allclose(hdot, [0.0, 12.0, 12.0, -5.0, -5.0, -5.0, 0.0])


def test_accelerate_reaches_the_speed_at_the_rate():
    from skytrack.sim.scenario import AccelerateLeg

    traj = trajectories_of(spec([AccelerateLeg(to_speed_mps=150.0, rate_mps2=2.0)], speed_mps=250.0))
    t = np.array([0.0, 25.0, 50.0, 80.0])
    _, _, _, vx, vy, _ = traj.evaluate(np.zeros(4, dtype=int), t)
    np.testing.assert_allclose(np.hypot(vx, vy), [250.0, 200.0, 150.0, 150.0], atol=1e-9)
    np.testing.assert_allclose(heading_deg(vx, vy), 30.0, atol=1e-9)


def test_waypoints_are_passed_exactly_within_the_g_limit():
    from skytrack.sim.scenario import Waypoint, WaypointsLeg

    points = (Waypoint(20000.0, 5000.0, 6000.0), Waypoint(21000.0, 6000.0), Waypoint(0.0, -10000.0, 4000.0))
    max_g, speed = 2.0, 200.0
    traj = trajectories_of(spec([WaypointsLeg(points, max_g)], speed_mps=speed, heading_deg=270.0), duration_s=600.0)
    t = np.arange(0.0, 600.0, 0.005)
    x, y, h, vx, vy, _ = traj.evaluate(np.zeros(t.size, dtype=int), t)
    passes = []
    for p in points:
        d = np.hypot(x - p.x, y - p.y)
        k = int(np.argmin(d))
        assert d[k] <= speed * 0.005, f"waypoint {p} missed by {d[k]} m"
        passes.append(k)
        if p.alt_m is not None:
            assert abs(h[k] - p.alt_m) < 1.0
    assert passes == sorted(passes)
    np.testing.assert_allclose(np.hypot(vx, vy), speed, rtol=1e-12)
    lateral = np.hypot(np.diff(vx), np.diff(vy)) / 0.005
    assert lateral.max() <= max_g * GRAVITY_MPS2 * (1 + 1e-6)
    assert lateral.max() > 0.99 * max_g * GRAVITY_MPS2  # the turns do use the full max_g


def test_singer_legs_follow_the_exact_singer_velocity_increments_and_stay_in_the_speed_band():
    tau, sigma_a, n = 20.0, 4.0, 1500
    leg = SingerLeg(tau, sigma_a, 30.0, speed_range_mps=(50.0, 450.0))
    targets = [spec([leg], id=f"s{i}", speed_mps=250.0) for i in range(n)]
    traj = trajectories_of(*targets, duration_s=40.0, seed=3)
    index = np.arange(n)
    # one 1-s velocity increment per target and axis (independent samples): Var = F12^2 sigma_a^2 + Q22
    _, _, _, vx0, vy0, _ = traj.evaluate(index, np.full(n, 10.0))
    _, _, _, vx1, vy1, _ = traj.evaluate(index, np.full(n, 11.0))
    increments = np.concatenate([vx1 - vx0, vy1 - vy0])
    model = SingerAxisModel(tau, sigma_a, "exact")
    expected = model.F(1.0)[1, 2] ** 2 * sigma_a**2 + model.Q(1.0)[1, 1]
    from scipy.stats import chi2

    k = increments.size
    statistic = np.sum(increments**2) / expected  # zero-mean increments
    assert chi2.ppf(1e-4, k) < statistic < chi2.ppf(1 - 1e-4, k)
    # positions and velocities are continuous at the nodes (cubic Hermite links)
    eps = 1e-9
    before = traj.evaluate(index, np.full(n, 17.0 - eps))
    after = traj.evaluate(index, np.full(n, 17.0 + eps))
    for a, b in zip(before, after):
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_singer_speed_band_is_enforced_at_the_nodes():
    leg = SingerLeg(30.0, 15.0, 120.0, speed_range_mps=(180.0, 220.0))
    targets = [spec([leg], id=f"s{i}", speed_mps=200.0) for i in range(50)]
    traj = trajectories_of(*targets, duration_s=150.0, seed=5)
    t = np.arange(0.0, 121.0)
    ids = np.repeat(np.arange(50), t.size)
    _, _, _, vx, vy, _ = traj.evaluate(ids, np.tile(t, 50))
    speed = np.hypot(vx, vy)
    assert speed.min() >= 180.0 - 1e-9 and speed.max() <= 220.0 + 1e-9
    assert (speed > 219.0).any() and (speed < 181.0).any()  # the band is actually reached


def test_truth_rows_are_consistent_with_wgs84_and_their_velocity():
    data = scenario([target(legs=[{"type": "climb", "rate_mps": 10, "duration_s": 30}, {"type": "turn", "g": 2, "direction": "left", "turn_deg": 90}])], duration_s=90.0)
    result = simulate(load_scenario(data))
    truth = result.truth
    assert tuple(truth.columns) == TRUTH_COLUMNS
    assert truth["time"].tolist() == list(np.arange(0.0, 91.0))
    e, n, u = geodetic_to_enu(truth.lat, truth.lon, truth.alt_m, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    np.testing.assert_allclose(e, truth.x, atol=1e-4)
    np.testing.assert_allclose(n, truth.y, atol=1e-4)
    np.testing.assert_allclose(u, truth.z, atol=1e-4)
    # z is below the altitude by the Earth's curvature (45 km from the origin: ~160 m)
    assert ((truth.alt_m - truth.z) > 100.0).all()
    # vz is the derivative of z: compare with a central difference of the exact trajectory
    t = np.array([5.0, 20.0, 50.0])
    d = 1e-3
    plus = result.trajectories.state(np.zeros(3, dtype=int), t + d)
    minus = result.trajectories.state(np.zeros(3, dtype=int), t - d)
    mid = result.trajectories.state(np.zeros(3, dtype=int), t)
    np.testing.assert_allclose((plus["z"] - minus["z"]) / (2 * d), mid["vz"], atol=1e-4)
    # the climb rate plus the curvature term -(p . v) / R of flying away from the origin
    assert abs(mid["vz"][0] - (10.0 - mid["x"][0] * mid["vx"][0] / 6.37e6)) < 0.01


def test_place_at_height_matches_the_inverse_conversion_far_from_the_origin():
    rng = np.random.default_rng(4)
    x, y, h = rng.uniform(-4e5, 4e5, 1000), rng.uniform(-4e5, 4e5, 1000), rng.uniform(0, 15000, 1000)
    z, lat, lon, up = place_at_height(x, y, h, ORIGIN)
    lat2, lon2, h2 = enu_to_geodetic(x, y, z, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    np.testing.assert_allclose(h2, h, atol=1e-3)
    np.testing.assert_allclose(lat2, lat, atol=1e-9)
    np.testing.assert_allclose(lon2, lon, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(up, axis=1), 1.0)


def test_radar_horizon_is_the_sum_of_tangent_lengths_on_the_four_thirds_earth():
    r = 4.0 / 3.0 * 6_371_008.8
    expected = math.sqrt((r + 30.0) ** 2 - r**2) + math.sqrt((r + 10000.0) ** 2 - r**2)
    assert abs(float(radar_horizon_range(30.0, 10000.0)) - expected) < 1e-6
    assert abs(expected - 4120.0 * (math.sqrt(30.0) + 100.0)) < 1000.0  # textbook 4.12 (sqrt(h1) + sqrt(h2)) km


def test_sample_times_include_start_end_and_grid():
    target, time = sample_times(np.array([0.0, 2.5, 7.0]), np.array([3.0, 6.2, 7.0]), 1.0)
    assert target.tolist() == [0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 2]
    assert time.tolist() == [0.0, 1.0, 2.0, 3.0, 2.5, 3.0, 4.0, 5.0, 6.0, 6.2, 7.0]


def test_target_leaving_coverage_ends_and_one_entering_does_not():
    sensors = [radar(max_range_m=50000.0)]
    outbound = target("out", x=0.0, y=40000.0, heading_deg=0.0, speed_mps=250.0)
    inbound = target("in", x=0.0, y=-80000.0, heading_deg=0.0, speed_mps=250.0, alt_m=10000.0)
    late_leg = target("leg", x=0.0, y=45000.0, heading_deg=0.0, legs=[{"type": "straight", "duration_s": 100}])
    result = simulate(load_scenario(scenario([outbound, inbound, late_leg], sensors=sensors, duration_s=200.0)))
    ends = result.targets.set_index("target_id")["end_time"]
    # slant range sqrt(y^2 + (9000 - 30 - y^2 / 2R)^2), y = 40 km + 250 t, passes 50 km at t = 36.9 s
    y = 40000.0 + 250.0 * np.arange(60.0)
    slant = np.hypot(y, 9000.0 - 30.0 - y**2 / (2 * 6.37e6))
    assert int(np.argmax(slant > 50000.0)) == 37
    assert ends["out"] == 37.0
    assert ends["in"] == 200.0
    assert ends["leg"] == 100.0  # leaves during its leg; ends at the first sample after the leg
    out_rows = result.truth[result.truth.target_id == "out"]
    assert out_rows.time.max() == 37.0 and not out_rows.visible.iloc[-1] and out_rows.visible.iloc[0]
    assert result.plots[result.plots.truth_id == "out"].time.max() <= 37.0


def test_singer_trajectories_depend_on_the_scenario_seed_only():
    data = scenario([target(legs=[{"type": "singer", "tau_s": 10, "sigma_a_mps2": 5, "duration_s": 60}])], duration_s=60.0)
    a = simulate(load_scenario(data), rng=np.random.default_rng(1)).truth
    b = simulate(load_scenario(data), rng=np.random.default_rng(2)).truth
    c = simulate(load_scenario({**data, "seed": 9})).truth
    np.testing.assert_array_equal(a[["x", "y"]].to_numpy(), b[["x", "y"]].to_numpy())
    assert not np.allclose(a.x.to_numpy(), c.x.to_numpy())
    assert isinstance(seed_stream(1, "motion"), np.random.Generator)

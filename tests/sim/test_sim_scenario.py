"""Scenario loading: validation errors name the key path; defaults; bundled scenarios; traffic."""

from __future__ import annotations

import re

import numpy as np
import pytest

from sim_builders import radar, scenario, target
from skytrack.geo import Sensor, SensorSet
from skytrack.sim import ScenarioError, bundled_scenarios, load_scenario, scale_traffic, simulate
from skytrack.sim.scenario import TurnLeg
from skytrack.sim.spec import LandLeg
from skytrack.sim.traffic import allowed_mode3a_codes


def error_of(data) -> str:
    with pytest.raises(ScenarioError) as info:
        load_scenario(data)
    return str(info.value)


def test_minimal_scenario_gets_documented_defaults():
    s = load_scenario(scenario([target()]))
    assert s.truth_sample_s == 1.0 and s.seed == 1 and s.traffic is None
    sensor = s.sensors["radar1"]
    assert isinstance(s.sensors, SensorSet) and isinstance(sensor, Sensor)
    assert sensor.scan_phase_s == 0.0 and sensor.sigma_range_rate_mps is None
    assert s.radar_params["radar1"].p_mode3a == 1.0
    assert s.targets[0].transponder is False


def test_negative_turn_load_names_the_full_key_path():
    t = [target("a"), target("b"), target("c"), target("d", legs=[{"type": "straight", "duration_s": 5}, {"type": "turn", "g": -2, "direction": "left", "turn_deg": 90}])]
    assert error_of(scenario(t)) == "scenario: targets[3].legs[1].g: must be > 0, got -2"


def test_yaml_file_errors_name_the_file(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text(
        "origin: {lat: 48.0, lon: 2.0}\nduration_s: 60\nsensors:\n"
        "  - {name: r, lat: 48.0, lon: 2.0, scan_period_s: 4, sigma_range_m: 40, sigma_azimuth_deg: 0.1, max_range_m: 250e3}\n"
        "targets:\n  - {id: a, x: 0, y: 1000, alt_m: 1000, speed_mps: 100, heading_deg: 0,\n"
        "     legs: [{type: climb, rate_mps: 5, duration_s: -3}]}\n"
    )
    with pytest.raises(ScenarioError, match=re.escape(f"{path}: targets[0].legs[0].duration_s: must be > 0, got -3")):
        load_scenario(path)


def test_unknown_keys_are_rejected_with_the_known_ones():
    message = error_of(scenario([target(legs=[{"type": "turn", "g": 2, "direction": "left", "turn_deg": 90, "bank_deg": 30}])]))
    assert message.startswith("scenario: targets[0].legs[0].bank_deg: unknown key; known keys here: ")
    assert "g, direction, duration_s, turn_deg" in message
    message = error_of(scenario([target()], durations_s=5))
    assert "(top level)" not in message and "durations_s: unknown key" in message and "duration_s" in message


@pytest.mark.parametrize(
    ("patch", "expected"),
    [
        ({"sensors": [radar(type="radar-4d")]}, "sensors[0].type: must be one of radar-2d, radar-3d, radar-airborne, got 'radar-4d'"),
        ({"sensors": [radar(p_detection=1.5)]}, "sensors[0].p_detection: must be <= 1, got 1.5"),
        ({"sensors": [radar(sigma_elevation_deg=0.2)]}, "sensors[0].sigma_elevation_deg: is only allowed for type radar-3d"),
        ({"sensors": [radar(type="radar-3d")]}, "sensors[0].sigma_elevation_deg: required key is missing"),
        ({"sensors": [radar(north_offset_deg=3.0)]}, "sensors[0].north_offset_deg: is derived from the sensor position"),
        ({"sensors": [radar(), radar()]}, "sensors[1].name: sensor name 'radar1' is used twice"),
        ({"targets": [target(mode3a=7000)]}, "targets[0].mode3a: must be a quoted string of 4 octal digits"),
        ({"targets": [target(mode3a="7800")]}, "targets[0].mode3a: must be 4 octal digits (0-7), got '7800'"),
        ({"targets": [target(icao24="xyz")]}, "targets[0].icao24: must be 6 hexadecimal digits"),
        ({"targets": [target(transponder=False, mode3a="1200")]}, "targets[0].transponder: is false but mode3a/icao24 is given"),
        ({"targets": [target(lat=48.0)]}, "targets[0]: give the position as exactly one of x/y, lat/lon or range_m/azimuth_deg/sensor (got x/y and lat/lon)"),
        ({"targets": [{"id": "a", "range_m": 1000, "azimuth_deg": 10, "sensor": "nope", "alt_m": 1, "speed_mps": 1, "heading_deg": 0}]}, "targets[0].sensor: unknown sensor 'nope'; sensors: radar1"),
        ({"targets": [target(speed_mps="fast")]}, "targets[0].speed_mps: must be a number, got 'fast'"),
        ({"targets": [target(start_time_s=120)]}, "targets[0].start_time_s: must be < 120, got 120"),
        ({"targets": [target(legs=[{"type": "loop"}])]}, "targets[0].legs[0].type: must be one of straight, turn, climb, accelerate, singer, waypoints, land, got 'loop'"),
        ({"targets": [target(legs=[{"type": "turn", "g": 2, "direction": "left"}])]}, "targets[0].legs[0]: a turn needs exactly one of duration_s or turn_deg"),
        ({"targets": [target(legs=[{"type": "turn", "g": 2, "direction": "up", "turn_deg": 9}])]}, "targets[0].legs[0].direction: must be one of left, right, got 'up'"),
        ({"targets": [target(legs=[{"type": "waypoints", "max_g": 2, "points": [{"x": 1}]}])]}, "targets[0].legs[0].points[0].y: required key is missing"),
        ({"targets": [target(), target()]}, "target id 't1' is used twice"),
        ({"duration_s": 0}, "duration_s: must be > 0, got 0"),
        ({"origin": {"lat": 95, "lon": 0}}, "origin.lat: must be <= 90, got 95"),
    ],
)
def test_validation_messages(patch, expected):
    data = scenario([target()])
    data.update(patch)
    with pytest.raises(ScenarioError) as info:
        load_scenario(data).all_targets()
    assert expected in str(info.value)


def test_yaml_duplicate_key_and_syntax_errors_give_line(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text("duration_s: 60\nduration_s: 70\n")
    with pytest.raises(ScenarioError, match=r"dup.yaml: line 2, column 1: found duplicated key 'duration_s'"):
        load_scenario(path)
    path.write_text("duration_s: [60\n")
    with pytest.raises(ScenarioError, match=r"dup.yaml: line \d+, column \d+"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="cannot read scenario file"):
        load_scenario(tmp_path / "missing.yaml")


def test_numbers_in_exponent_notation_and_yaml_timestamps_are_accepted(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(
        "origin: {lat: 48.0, lon: 2.0}\nduration_s: 6e1\nepoch_utc: 2021-10-07T12:00:00Z\nsensors:\n"
        "  - {name: r, lat: 48.0, lon: 2.0, scan_period_s: 4, sigma_range_m: 40, sigma_azimuth_deg: 0.1, max_range_m: 250e3}\n"
    )
    s = load_scenario(path)
    assert s.duration_s == 60.0 and s.sensors["r"].max_range_m == 250000.0
    assert s.epoch_utc == "2021-10-07T12:00:00Z" == s.sensors.epoch_utc
    assert s.name == "s"


def test_turn_leg_parsed_and_sensor_given_in_enu_gets_exact_geodetic_position():
    s = load_scenario(
        scenario(
            [target(legs=[{"type": "turn", "g": 2.5, "direction": "right", "duration_s": 20}])],
            sensors=[radar(), radar(name="east", lat=None, lon=None, x=120000.0, y=5000.0, alt_m=400.0)],
        )
    )
    assert s.targets[0].legs == (TurnLeg(2.5, "right", 20.0, None),)
    east = s.sensors["east"]
    from skytrack.geo import geodetic_to_enu

    e, n, u = geodetic_to_enu(east.lat, east.lon, east.alt_m, 48.86, 2.50, 0.0)
    assert abs(e - 120000.0) < 1e-4 and abs(n - 5000.0) < 1e-4 and abs(u - east.z) < 1e-4
    assert east.z < 400.0 - 1000.0  # Earth curvature: 120 km away the ellipsoid is ~1.1 km below the plane


def test_sensor_defaults_apply_unless_overridden():
    data = scenario(sensors=[{"name": "a", "lat": 48.86, "lon": 2.5}, {"name": "b", "x": 1000, "y": 0, "p_detection": 0.5}])
    data["sensor_defaults"] = {k: v for k, v in radar().items() if k not in ("name", "lat", "lon", "alt_m", "type")}
    data["sensor_defaults"]["p_detection"] = 0.8
    s = load_scenario(data)
    assert s.sensors["a"].p_detection == 0.8 and s.sensors["b"].p_detection == 0.5
    assert s.sensors["b"].scan_period_s == 4.0


def traffic_section(**overrides) -> dict:
    base = {
        "count": 400,
        "region": {"type": "annulus", "sensor": "radar1", "min_range_m": 20000, "max_range_m": 150000},
        "alt_m": [1000, 10000],
        "speed_mps": [100, 250],
        "transponder_fraction": 0.9,
        "mode_s_fraction": 0.5,
        "maneuver_fraction": 0.25,
    }
    base.update(overrides)
    return base


def test_traffic_generation_is_seeded_and_honours_fractions_and_region():
    s = load_scenario(scenario(traffic=traffic_section()))
    a, b = s.all_targets(), s.all_targets()
    assert a == b and len(a) == 400
    n = len(a)
    transponder = np.array([t.transponder for t in a])
    mode_s = np.array([t.icao24 is not None for t in a])
    maneuvering = np.array([len(t.legs) > 0 for t in a])
    # binomial 4-sigma bands
    for observed, p, base in ((transponder.sum(), 0.9, n), (maneuvering.sum(), 0.25, n), (mode_s.sum(), 0.5, transponder.sum())):
        assert abs(observed - p * base) < 4.0 * np.sqrt(base * p * (1 - p))
    codes = [t.mode3a for t in a if t.transponder]
    assert len(set(codes)) == len(codes) and not set(codes) & {"7000", "7500", "7600", "7700"}
    assert all(t.mode3a is None for t in a if not t.transponder)
    addresses = [t.icao24 for t in a if t.icao24]
    assert len(set(addresses)) == len(addresses) and all(re.fullmatch(r"[0-9a-f]{6}", x) for x in addresses)
    ground = np.hypot([t.x for t in a], [t.y for t in a])
    assert ground.min() > 20000 - 50 and ground.max() < 150000 + 50
    # uniform in area: the fraction inside the mid-area radius is 1/2 (binomial 4 sigma)
    mid = np.sqrt((20000**2 + 150000**2) / 2)
    assert abs((ground < mid).mean() - 0.5) < 4 * np.sqrt(0.25 / n)
    other_seed = load_scenario(scenario(traffic=traffic_section(), seed=2)).all_targets()
    assert [t.x for t in other_seed] != [t.x for t in a]


def test_unique_mode3a_codes_are_reused_only_when_the_range_is_exhausted():
    s = load_scenario(scenario(traffic=traffic_section(count=30, transponder_fraction=1.0, mode3a_range=["0100", "0117"])))
    codes = [t.mode3a for t in s.all_targets()]
    assert len(allowed_mode3a_codes("0100", "0117")) == 16
    assert len(set(codes[:16])) == 16 and set(codes) == set(allowed_mode3a_codes("0100", "0117"))


def test_scale_traffic_keeps_everything_else():
    s = load_scenario(scenario([target()], traffic=traffic_section(count=10)))
    big = scale_traffic(s, 100)
    assert big.traffic.count == 100 and big.sensors is s.sensors and big.targets == s.targets
    assert len(big.all_targets()) == 101
    with pytest.raises(ScenarioError, match="no traffic section"):
        scale_traffic(load_scenario(scenario([target()])), 5)


def test_bundled_demo_scenario():
    assert {"demo", "two_radars", "radar3d", "crossing", "terminal"} <= set(bundled_scenarios())
    demo = load_scenario("demo")
    targets = demo.all_targets()
    assert len(targets) >= 60
    sensor = demo.sensors.sensors[0]
    assert len(demo.sensors.sensors) == 1 and sensor.type == "radar-2d"
    assert (sensor.scan_period_s, sensor.sigma_range_m, sensor.sigma_azimuth_deg, sensor.max_range_m, sensor.p_detection) == (4.0, 40.0, 0.07, 250000.0, 0.9)
    assert sensor.clutter_per_scan == 20.0 and demo.duration_s == 600.0
    assert 0.15 < np.mean([len(t.legs) > 0 for t in targets]) < 0.4
    # controlled-airspace traffic: all transponder-equipped but the primary-only DEMO3
    assert [t.id for t in targets if not t.transponder] == ["DEMO3"]


@pytest.mark.parametrize("name", ["two_radars", "radar3d", "crossing", "terminal"])
def test_bundled_scenarios_simulate(name):
    s = load_scenario(name)
    result = simulate(s)
    assert set(result.plots["sensor"]) == set(s.sensors.names)
    assert result.truth["target_id"].nunique() == len(s.all_targets())


def test_two_radars_scenario_has_radars_120_km_apart_with_different_scans():
    s = load_scenario("two_radars")
    west, east = s.sensors.sensors
    assert abs(np.hypot(*(east.position[:2] - west.position[:2])) - 120000.0) < 1.0
    assert west.scan_period_s != east.scan_period_s and west.scan_phase_s != east.scan_phase_s


def test_radar3d_scenario_measures_elevation_and_range_rate():
    sensor = load_scenario("radar3d").sensors.sensors[0]
    assert sensor.type == "radar-3d" and sensor.sigma_elevation_deg > 0 and sensor.sigma_range_rate_mps > 0


def test_crossing_scenario_geometry():
    result = simulate(load_scenario("crossing"))
    truth = result.truth.set_index(["target_id", "time"])

    def horizontal(name, t):
        row = truth.loc[(name, t)]
        return np.array([row.x, row.y])

    assert np.linalg.norm(horizontal("CROSS-A", 150.0) - horizontal("CROSS-B", 150.0)) < 1e-6
    assert np.linalg.norm(horizontal("CROSS-C", 150.0) - horizontal("CROSS-D", 150.0)) < 0.01
    for t in (0.0, 100.0, 199.0):
        assert abs(np.linalg.norm(horizontal("PAIR-1", t) - horizontal("PAIR-2", t)) - 600.0) < 0.01


def test_terminal_scenario_has_terminal_traffic_and_a_real_radar_s_false_plots():
    """The tracker's tuning scenario: the demo's radar, landings, departures, clutter patches
    and SSR replies on false plots (counts within 4 sigma of their means)."""
    s = load_scenario("terminal")
    (sensor,) = s.sensors.sensors
    params = s.radar_params[sensor.name]
    assert sensor.type == "radar-2d" and s.duration_s == 1200.0
    assert (sensor.scan_period_s, sensor.sigma_range_m, sensor.sigma_azimuth_deg, sensor.p_detection) == (4.0, 40.0, 0.07, 0.9)
    assert sensor.clutter_per_scan == 30.0 and params.clutter_distribution == "range"
    near, far = sorted(params.clutter_patches, key=lambda patch: patch.range_m)
    assert near.range_m == (5000.0, 20000.0) and far.range_m == (60000.0, 80000.0)
    assert params.clutter_p_mode3a == 0.05 and params.clutter_p_mode_c == 0.05 and params.p_mode_c == 0.9
    traffic = s.traffic
    assert (traffic.maneuver_fraction, traffic.landing_fraction, traffic.departure_fraction) == (0.3, 0.15, 0.15)
    targets = s.all_targets()
    assert len(targets) == 60 and 2 <= sum(not t.transponder for t in targets) <= 8
    landing = {t.id for t in targets if t.legs and isinstance(t.legs[-1], LandLeg)}
    departing = {t.id for t in targets if t.alt_m < traffic.alt_m[0]}
    assert 4 <= len(landing) <= 16 and 4 <= len(departing) <= 16

    result = simulate(s)
    false = result.plots[result.plots.truth_id == ""]
    scans = 1200.0 / 4.0
    expected = (30.0 + near.per_scan + far.per_scan) * scans
    assert abs(len(false) - expected) < 4.0 * np.sqrt(expected)
    for column in ("mode3a", "mode_c_ft"):
        k = false[column].notna().sum()
        assert abs(k - 0.05 * len(false)) < 4.0 * np.sqrt(len(false) * 0.05 * 0.95)
    last = result.truth.sort_values("time").groupby("target_id").last()
    first = result.truth.sort_values("time").groupby("target_id").first()
    touched_down = last.index[(last.alt_m.abs() < 1e-6) & (last.time < 1200.0)]
    assert set(touched_down) <= landing and len(touched_down) >= 5
    assert (first.loc[sorted(departing), "alt_m"] <= 600.0).all()


def test_a_folder_named_like_a_bundled_scenario_does_not_hide_it(tmp_path, monkeypatch):
    from skytrack.sim import load_scenario

    (tmp_path / "demo").mkdir()
    monkeypatch.chdir(tmp_path)
    assert load_scenario("demo").name == "demo"

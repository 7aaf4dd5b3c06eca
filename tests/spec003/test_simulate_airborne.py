"""Spec 003 §2.3, R16-R18 in the main simulator (`skytrack simulate`): an airborne radar on a
carrier flying its own legs, the IFF interrogator of a radar, and the bundled
airborne_crossing scenario end to end.

Geometry is checked noise-free to 1e-9 relative (closed form), the measurement function of
the simulator against the TV3 values, IFF rates within 4 binomial standard errors, and the
IFF stream's independence exactly (bit-identical columns).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pandas as pd
import pytest

from skytrack.core.plots import PLATFORM_COLUMNS
from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.sim import ScenarioError, load_scenario, simulate
from skytrack.sim.radar import polar_view

ORIGIN = {"lat": 50.0, "lon": 10.0, "alt_m": 0.0}
CARRIER = {"x": 0.0, "y": 0.0, "alt_m": 8000.0, "speed_mps": 250.0, "heading_deg": 0.0,
           "legs": [{"type": "straight", "duration_s": 30.0}, {"type": "turn", "g": 2.0, "direction": "right", "turn_deg": 60.0}]}


def airborne_radar(**overrides) -> dict:
    base = {
        "name": "air1",
        "type": "radar-airborne",
        "carrier": copy.deepcopy(CARRIER),
        "scan_period_s": 2.0,
        "sigma_range_m": 30.0,
        "sigma_azimuth_deg": 0.3,
        "sigma_elevation_deg": 0.3,
        "sigma_range_rate_mps": 2.0,
        "max_range_m": 150000.0,
        "p_detection": 1.0,
        "clutter_per_scan": 0.0,
    }
    base.update(overrides)
    return base


def targets() -> list[dict]:
    return [
        {"id": "A", "x": 2000.0, "y": 60000.0, "alt_m": 6000.0, "speed_mps": 250.0, "heading_deg": 185.0,
         "iff": "friend", "mode3a": "1234"},
        {"id": "B", "x": -3000.0, "y": 50000.0, "alt_m": 9000.0, "speed_mps": 220.0, "heading_deg": 100.0,
         "iff": "foe", "mode3a": "5670", "legs": [{"type": "straight", "duration_s": 20.0},
                                                  {"type": "turn", "g": 3.0, "direction": "left", "turn_deg": 90.0},
                                                  {"type": "climb", "rate_mps": 20.0, "duration_s": 20.0}]},
        {"id": "C", "x": 20000.0, "y": 30000.0, "alt_m": 3000.0, "speed_mps": 180.0, "heading_deg": 270.0},
    ]


def scenario(sensor: dict | None = None, target_list: list[dict] | None = None, duration_s: float = 90.0) -> dict:
    return {
        "origin": dict(ORIGIN),
        "duration_s": duration_s,
        "seed": 3,
        "sensors": [sensor or airborne_radar()],
        "targets": targets() if target_list is None else target_list,
    }


def truth_at_plots(result, plots: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    index = pd.Index(result.trajectories.ids).get_indexer(plots["truth_id"].astype(object))
    state = result.trajectories.state(index, plots["time"].to_numpy())
    return (np.column_stack([state["x"], state["y"], state["z"]]),
            np.column_stack([state["vx"], state["vy"], state["vz"]]))


def test_simulator_measurement_function_reproduces_tv3():
    """The simulator's carrier-relative h(x) on the TV3 own-ship and target (ENU)."""
    sensor = SensorSet(Origin(0.0, 0.0), [Sensor("air", type="radar-airborne")]).sensors[0]
    r, az, el, rdot, _ = polar_view(sensor, np.array([[21000.0, 38000.0, 6000.0]]), np.array([[-200.0, 100.0, 5.0]]),
                                    np.array([[1000.0, -2000.0, 8000.0]]), np.array([[50.0, 240.0, 0.0]]))
    assert r[0] == pytest.approx(math.sqrt(2.004e9), rel=1e-9)
    assert az[0] == pytest.approx(0.46364760900, rel=1e-9)
    assert math.degrees(az[0]) == pytest.approx(26.565051177, rel=1e-9)
    assert el[0] == pytest.approx(-0.044691581036, rel=1e-9)
    assert rdot[0] == pytest.approx(-237.00992088, rel=1e-9)


def test_noise_free_plots_are_the_carrier_relative_geometry():
    sensor = airborne_radar(sigma_range_m=0.0, sigma_azimuth_deg=0.0, sigma_elevation_deg=0.0, sigma_range_rate_mps=0.0)
    result = simulate(load_scenario(scenario(sensor)))
    plots = result.plots
    assert list(plots.columns[-6:]) == list(PLATFORM_COLUMNS)
    assert result.sensors.sensors[0].type == "radar-airborne"
    # every target in every scan (P_D 1, in coverage), all plots of a scan at t_k = k T
    assert len(plots) == 3 * 46 and np.array_equal(np.unique(plots["time"]), 2.0 * np.arange(46))
    assert np.array_equal(plots["scan"].to_numpy(), (plots["time"].to_numpy() / 2.0).round().astype(int))
    own_p = plots[list(PLATFORM_COLUMNS[:3])].to_numpy()
    own_v = plots[list(PLATFORM_COLUMNS[3:])].to_numpy()
    # the carrier flies its legs: straight north at 250 m/s for 30 s (closed form), then turns right
    straight = plots["time"].to_numpy() <= 30.0
    assert np.allclose(own_p[straight, :2], np.column_stack([np.zeros(straight.sum()), 250.0 * plots["time"][straight]]), rtol=0, atol=1e-9)
    assert np.allclose(own_v[straight, :2], [0.0, 250.0], rtol=0, atol=1e-9)
    assert np.all(own_v[~straight, 0] > 0.0) and np.allclose(np.hypot(own_v[:, 0], own_v[:, 1]), 250.0, rtol=1e-12)
    position, velocity = truth_at_plots(result, plots)
    delta, delta_v = position - own_p, velocity - own_v
    distance = np.linalg.norm(delta, axis=1)
    ground = np.hypot(delta[:, 0], delta[:, 1])
    np.testing.assert_allclose(plots["range_m"], distance, rtol=1e-9)
    azimuth = np.degrees(np.arctan2(delta[:, 0], delta[:, 1])) % 360.0
    wrapped = (plots["azimuth_deg"].to_numpy() - azimuth + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(wrapped)) <= 1e-9 * 360.0
    np.testing.assert_allclose(plots["elevation_deg"], np.degrees(np.arctan2(delta[:, 2], ground)), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(plots["range_rate_mps"], np.einsum("ij,ij->i", delta, delta_v) / distance, rtol=1e-9)
    # A comes head-on while the carrier flies north: closing at about 500 m/s, a negative range rate
    head_on = (plots["truth_id"] == "A").to_numpy() & straight
    assert np.all(plots.loc[head_on, "range_rate_mps"].between(-500.0, -490.0))


def test_airborne_clutter_plot_order_and_coverage():
    result = simulate(load_scenario(scenario(airborne_radar(clutter_per_scan=5.0, max_range_m=45000.0))))
    plots = result.plots
    false = plots[plots["truth_id"] == ""]
    scans = plots["scan"].nunique()
    assert abs(len(false) - 5.0 * scans) <= 4.0 * math.sqrt(5.0 * scans)
    assert false["range_m"].max() <= 45000.0 and false["elevation_deg"].between(-10.0, 10.0).all()
    assert np.isfinite(false[list(PLATFORM_COLUMNS)].to_numpy()).all()
    # beyond max_range_m from the carrier no target plot; the truth's visible flag agrees
    targets_only = plots[plots["truth_id"] != ""]
    assert targets_only["range_m"].max() <= 45000.0 + 4 * 30.0
    truth = result.truth
    own_p, _, _ = result.carriers.state("air1", truth["time"].to_numpy())
    near = np.linalg.norm(truth[["x", "y", "z"]].to_numpy() - own_p, axis=1) <= 45000.0
    assert np.array_equal(truth["visible"].to_numpy(), near)
    # the plots of a scan come in a random order, not the targets' order
    first_of_scan = plots[plots["truth_id"] != ""].groupby("scan")["truth_id"].first()
    assert first_of_scan.nunique() > 1


def iff_sensor(**iff) -> dict:
    return airborne_radar(iff={"p_reply": 1.0, **iff})


def test_iff_only_on_interrogated_scans_and_replies_are_the_truth():
    windows = [[10.0, 30.0], [60.0, 70.0]]
    result = simulate(load_scenario(scenario(iff_sensor(interrogate=windows))))
    plots = result.plots
    t = plots["time"].to_numpy()
    inside = ((t >= 10.0) & (t <= 30.0)) | ((t >= 60.0) & (t <= 70.0))
    with_iff = plots["truth_id"].isin(["A", "B"]).to_numpy() & inside
    assert np.array_equal(plots["iff"].notna().to_numpy(), with_iff)
    assert np.array_equal(plots["mode3a"].notna().to_numpy(), with_iff)
    replied = plots[with_iff]
    assert (replied["iff"] == replied["truth_id"].map({"A": "friend", "B": "foe"})).all()
    assert (replied["mode3a"] == replied["truth_id"].map({"A": "1234", "B": "5670"})).all()
    # C has no IFF transponder: never a reply; Mode C stays on every transponder plot
    assert plots.loc[plots["truth_id"] == "C", "iff"].isna().all()
    assert plots.loc[plots["truth_id"].isin(["A", "B"]), "mode_c_ft"].notna().all()


def test_iff_leaves_every_other_column_bit_identical():
    plain = simulate(load_scenario(scenario(airborne_radar(clutter_per_scan=3.0))))
    other = [c for c in plain.plots.columns if c not in ("iff", "mode3a")]
    for iff in ({"p_reply": 0.9}, {"p_reply": 0.4, "p_flip": 0.3, "p_code": 0.3, "false_reply_p": 0.5},
                {"interrogate": "never"}, {"interrogate": [[0, 20]]}):
        with_iff = simulate(load_scenario(scenario(airborne_radar(clutter_per_scan=3.0, iff=iff))))
        assert with_iff.plots[other].equals(plain.plots[other])
        assert with_iff.truth.equals(plain.truth)
    assert plain.plots["iff"].isna().all()


def test_iff_rates_in_the_simulator():
    many = [{"id": f"T{k}", "x": 3000.0 * (k - 10), "y": 60000.0, "alt_m": 6000.0, "speed_mps": 200.0,
             "heading_deg": 180.0, "iff": "friend" if k % 2 else "foe", "mode3a": f"{k + 1:04o}"} for k in range(20)]
    many[0]["iff_p_reply"] = 0.2
    sensor = airborne_radar(iff={"p_reply": 0.7, "p_flip": 0.1, "p_code": 0.15}, clutter_per_scan=0.0)
    result = simulate(load_scenario(scenario(sensor, many, duration_s=300.0)))
    plots = result.plots

    def within_4se(hits, trials, p):
        return abs(hits / trials - p) <= 4.0 * math.sqrt(p * (1.0 - p) / trials)

    own = plots["truth_id"] == "T0"
    rest = plots[~own]
    assert within_4se(int(plots.loc[own, "iff"].notna().sum()), int(own.sum()), 0.2)
    assert within_4se(int(rest["iff"].notna().sum()), len(rest), 0.7)
    replied = rest[rest["iff"].notna()]
    number = replied["truth_id"].str[1:].astype(int)
    true_status = np.where(number % 2 == 1, "friend", "foe")
    true_code = number.map(lambda k: f"{k + 1:04o}")
    assert within_4se(int((replied["iff"] != true_status).sum()), len(replied), 0.1)
    corrupted = replied["mode3a"] != true_code
    assert within_4se(int(corrupted.sum()), len(replied), 0.15)
    codes = replied.loc[corrupted, "mode3a"]
    assert codes.str.fullmatch(r"[0-7]{4}").all()


def test_bundled_airborne_crossing_scenario_tracks_end_to_end(tmp_path):
    """simulate -> files -> track: every crossing target is tracked (R17 scenario of the issue)."""
    from skytrack.app.simulate import run_simulation, write_simulation
    from skytrack.io import read_plots, read_sensors
    from skytrack.tracker import Tracker, TrackerConfig

    result = run_simulation("airborne_crossing")
    s = result.scenario
    (sensor,) = s.sensors.sensors
    params = s.radar_params[sensor.name]
    assert sensor.type == "radar-airborne" and params.carrier.speed_mps == 250.0
    assert (sensor.sigma_range_m, sensor.sigma_azimuth_deg, sensor.sigma_elevation_deg, sensor.sigma_range_rate_mps) == (30.0, 0.3, 0.3, 2.0)
    status = {t.id: t.iff for t in s.targets}
    assert sorted(status.values()) == ["foe"] * 3 + ["friend"] * 3
    assert all(status[f"P{k}A"] != status[f"P{k}B"] for k in (1, 2, 3))
    paths = write_simulation(result, tmp_path)
    sensors = read_sensors(paths["sensors"])
    plots = read_plots(paths["plots"], sensors=sensors)
    assert sensors.sensors[0].type == "radar-airborne" and set(PLATFORM_COLUMNS) <= set(plots.columns)
    assert plots["iff"].notna().any()
    tracker = Tracker(sensors, TrackerConfig())
    tracks = tracker.run(plots)
    assert tracks["track_id"].nunique() >= 6


@pytest.mark.parametrize(
    ("sensor", "expected"),
    [
        (airborne_radar(lat=50.0, lon=10.0), "sensors[0].lat: is not allowed for type radar-airborne"),
        ({k: v for k, v in airborne_radar().items() if k != "carrier"}, "sensors[0].carrier: is required for type radar-airborne"),
        (airborne_radar(carrier={**CARRIER, "legs": [{"type": "land", "rate_mps": 5.0}]}), "a carrier does not land"),
        (airborne_radar(carrier={**CARRIER, "iff": "friend"}), "sensors[0].carrier.iff: unknown key"),
        (airborne_radar(iff={"interrogate": "track"}), "sensors[0].iff.interrogate: track (interrogate until"),
        (airborne_radar(iff={"interrogate": [[50, 40]]}), "sensors[0].iff.interrogate[0]: start must be <= end"),
        (airborne_radar(iff={"p_flip": 2}), "sensors[0].iff.p_flip: must be <= 1"),
    ],
)
def test_airborne_and_iff_validation(sensor, expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(scenario(sensor))
    assert expected in str(info.value)


def test_target_iff_keys_validation():
    bad = targets()
    bad[2]["iff_p_reply"] = 0.5
    with pytest.raises(ScenarioError, match=r"targets\[2\].iff_p_reply: needs iff"):
        load_scenario(scenario(target_list=bad))
    bad = targets()
    bad[0]["iff"] = "neutral"
    with pytest.raises(ScenarioError, match=r"targets\[0\].iff: must be one of friend, foe"):
        load_scenario(scenario(target_list=bad))
    relative = targets()[:1]
    relative[0] = {k: v for k, v in relative[0].items() if k not in ("x", "y")}
    relative[0].update(range_m=10000.0, azimuth_deg=10.0, sensor="air1")
    with pytest.raises(ScenarioError, match="is airborne: place positions relative to a ground sensor"):
        load_scenario(scenario(target_list=relative))

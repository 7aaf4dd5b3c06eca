"""Recorded traffic as simulation truth: interpolation accuracy, the ``recorded`` section,
the window, SSR identities, ADS-B reports, and scripted plus recorded targets together."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from sim_builders import ORIGIN, noise_free, radar, scenario, target

from skytrack.geo.sensors import Origin
from skytrack.geo.wgs84 import geodetic_to_enu
from skytrack.io import InputWarning, read_state_vectors
from skytrack.sim import ScenarioError, load_scenario, simulate
from skytrack.sim.cleaning import clean_states
from skytrack.sim.earth import local_axes, place_at_height, vertical_velocity
from skytrack.sim.recorded import sample_path
from skytrack.sim.recorded_motion import segment_trajectories

FRAME = Origin(ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt_m"])
#: 2021-10-07T12:00:00Z
T0 = 1633608000.0


def turning_states(step_s: float, icao24: str = "abc123", n_turn_s: float = 240.0, squawk: str = "4321",
                   t0: float = T0) -> tuple[pd.DataFrame, callable]:
    """State vectors of a level coordinated turn (radius 4 km at 200 m/s, centre 20 km E 30 km N)
    sampled every ``step_s``, with the exact velocities, and the exact ENU position as a function."""
    radius, speed, height = 4000.0, 200.0, 9000.0
    omega = speed / radius

    def exact(t):
        angle = omega * (np.asarray(t) - t0)
        return 20000.0 + radius * np.sin(angle), 30000.0 + radius * np.cos(angle)

    t = t0 + np.arange(0.0, n_turn_s + 1e-9, step_s)
    x, y = exact(t)
    angle = omega * (t - t0)
    vx, vy = speed * np.cos(angle), -speed * np.sin(angle)
    _, lat, lon, up = place_at_height(x, y, np.full(t.size, height), FRAME)
    vz = vertical_velocity(vx, vy, 0.0, up)
    east, north, _ = local_axes(lat, lon, FRAME)
    v = np.column_stack([vx, vy, vz])
    ve, vn = np.sum(v * east, axis=1), np.sum(v * north, axis=1)
    states = pd.DataFrame(
        {
            "time": t, "icao24": pd.array([icao24] * t.size, dtype="str"),
            "callsign": pd.array(["TURN1"] * t.size, dtype="str"), "squawk": pd.array([squawk] * t.size, dtype="str"),
            "onground": np.zeros(t.size, dtype=bool), "lat": lat, "lon": lon, "alt_m": np.full(t.size, height),
            "baro_alt_m": np.full(t.size, height), "geo_alt_m": np.full(t.size, np.nan),
            "groundspeed_mps": np.hypot(ve, vn), "track_deg": np.degrees(np.arctan2(ve, vn)) % 360.0,
            "vertical_rate_mps": np.zeros(t.size),
        }
    )
    return states, exact


def knots_of(states: pd.DataFrame, start: float) -> pd.DataFrame:
    cleaned, _ = clean_states(states)
    return cleaned.assign(time=cleaned["time"] - start)


def trajectories(knots: pd.DataFrame, duration_s: float):
    n = knots["segment_id"].nunique()
    return segment_trajectories(knots, FRAME, duration_s, mode3a=np.full(n, None), icao24=np.full(n, None))


def test_hermite_on_recorded_velocities_follows_a_turn_between_samples():
    # 10 s between samples turns the aircraft by 29 deg: a straight line between them is 124 m off
    states, exact = turning_states(10.0)
    traj = trajectories(knots_of(states, T0), 240.0)
    t = np.arange(0.0, 240.0, 0.5)
    state = traj.state(np.zeros(t.size, dtype=np.int64), t)
    x, y = exact(T0 + t)
    error = np.hypot(state["x"] - x, state["y"] - y)
    assert error.max() < 1.0  # stated tolerance: 1 m between samples 10 s apart in a 3 deg/s turn
    speed = np.hypot(state["vx"], state["vy"])
    np.testing.assert_allclose(speed, 200.0, atol=3.0)
    np.testing.assert_allclose(state["alt_m"], 9000.0, atol=1e-6)


def test_the_curve_passes_through_every_recorded_sample():
    paris = read_state_vectors(sample_path("paris_2021-10-07"))
    window = paris[(paris["time"] >= T0 + 7200.0) & (paris["time"] <= T0 + 7500.0)]
    knots = knots_of(window, T0 + 7200.0)
    traj = trajectories(knots, 300.0)
    index = pd.Series(np.arange(len(traj)), index=traj.ids)[knots["segment_id"]].to_numpy()
    state = traj.state(index, knots["time"].to_numpy())
    x, y, _ = geodetic_to_enu(knots["lat"], knots["lon"], knots["alt_m"], FRAME.lat, FRAME.lon, FRAME.alt_m)
    # stated tolerance: 1e-6 m, i.e. exact up to rounding
    assert np.max(np.hypot(state["x"] - x, state["y"] - y)) < 1e-6
    assert np.max(np.abs(state["alt_m"] - knots["alt_m"].to_numpy())) < 1e-6
    assert np.max(np.abs(state["lat"] - knots["lat"].to_numpy())) < 1e-9


def test_held_out_samples_of_the_paris_recording():
    """Every other sample of the 1 s Paris recording left out and compared with the curve
    through the others.  Stated tolerance: median 20 m, 90 % within 80 m; what is left is
    the recording's own position noise (linear interpolation does no better)."""
    paris = read_state_vectors(sample_path("paris_2021-10-07"))
    cleaned = knots_of(paris[paris["time"] < T0 + 3600.0], T0)
    position = cleaned.groupby("segment_id").cumcount().to_numpy()
    size = cleaned.groupby("segment_id")["time"].transform("size").to_numpy()
    is_knot = (position % 2 == 0) | (position == size - 1)
    knots, held = cleaned[is_knot].reset_index(drop=True), cleaned[~is_knot].reset_index(drop=True)
    traj = trajectories(knots, 3600.0)
    index = pd.Series(np.arange(len(traj)), index=traj.ids)[held["segment_id"]].to_numpy()
    state = traj.state(index, held["time"].to_numpy())
    x, y, _ = geodetic_to_enu(held["lat"], held["lon"], held["alt_m"], FRAME.lat, FRAME.lon, FRAME.alt_m)
    error = np.hypot(state["x"] - x, state["y"] - y)
    assert len(held) > 20000
    assert np.median(error) < 20.0 and np.percentile(error, 90) < 80.0


def recorded_scenario(sensors=None, **recorded) -> dict:
    section = {"start_utc": "2021-10-07T12:00:00Z", **recorded}
    return scenario(sensors=sensors or [noise_free()], duration_s=240.0, recorded=section)


def write_states(tmp_path, states: pd.DataFrame) -> str:
    """Write synthetic SI states in the OpenSky-database layout (SI units, POSIX seconds)."""
    path = tmp_path / "states.parquet"
    states.rename(columns={"lat": "lat", "lon": "lon", "groundspeed_mps": "velocity", "track_deg": "heading",
                           "vertical_rate_mps": "vertrate", "baro_alt_m": "baroaltitude"}).drop(
        columns=["alt_m", "geo_alt_m"]).to_parquet(path)
    return str(path)


def test_a_recorded_turn_gives_plots_with_its_segment_id_and_codes(tmp_path):
    states, _ = turning_states(5.0, squawk="4321")
    path = write_states(tmp_path, states)
    s = load_scenario(recorded_scenario(path=path))
    result = simulate(s, recorded=read_state_vectors(path))
    assert result.truth["target_id"].unique().tolist() == ["abc123-1"]
    plots = result.plots
    assert len(plots) == 60  # 240 s at 4 s a scan, P_D 1, no clutter
    assert set(plots["truth_id"]) == {"abc123-1"}
    assert set(plots["mode_s"]) == {"abc123"} and set(plots["mode3a"]) == {"4321"}
    assert result.sensors.epoch_utc == "2021-10-07T12:00:00Z"
    assert result.targets["callsign"].tolist() == ["TURN1"]
    assert result.recorded.cleaning.rows_read == len(states)


def test_the_window_is_placed_by_start_utc_start_s_or_the_first_sample(tmp_path):
    states, _ = turning_states(5.0, n_turn_s=400.0)
    path = write_states(tmp_path, states)
    cases = [({"start_utc": "2021-10-07T12:01:40Z"}, 100.0), ({"start_s": 100.0, "start_utc": None}, 100.0),
             ({"start_utc": None}, 0.0)]
    for section, offset in cases:
        s = load_scenario(scenario(sensors=[noise_free()], duration_s=200.0, recorded={"path": path, **section}))
        result = simulate(s, recorded=read_state_vectors(path))
        truth = result.truth
        assert truth["time"].min() == 0.0 and truth["time"].max() == 200.0
        # truth at time 0 is the recorded sample of the window's start
        first = states.loc[states["time"] == T0 + offset].iloc[0]
        row = truth.loc[truth["time"] == 0.0].iloc[0]
        assert row["lat"] == pytest.approx(first["lat"], abs=1e-9) and row["lon"] == pytest.approx(first["lon"], abs=1e-9)


def test_a_window_without_recorded_aircraft_is_a_clear_error(tmp_path):
    states, _ = turning_states(5.0)
    path = write_states(tmp_path, states)
    s = load_scenario(recorded_scenario(path=path, start_utc="2021-10-08T00:00:00Z"))
    with pytest.raises(ScenarioError, match=r"no recorded aircraft in the window 2021-10-08T00:00:00Z \+ 240 s "
                                            r"\(the cleaned recording covers 2021-10-07T12:00:00Z to 2021-10-07T12:04:00Z\)"):
        simulate(s, recorded=read_state_vectors(path))


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"sample": "paris_2021-10-07", "path": "x.parquet"}, "recorded.path: give exactly one of path"),
        ({}, "recorded.path: give exactly one of path"),
        ({"path": "no_such_file.parquet"}, "recorded.path: file not found"),
        ({"sample": "mars"}, "recorded.sample: must be one of paris_2021-10-07, switzerland_2018-08-01"),
        ({"sample": "paris_2021-10-07", "start_s": 5, "start_utc": "2021-10-07T12:00:00Z"}, "give at most one of start_utc or start_s"),
        ({"sample": "paris_2021-10-07", "altitude": "radar"}, "recorded.altitude: must be one of auto, geometric, barometric"),
        ({"sample": "paris_2021-10-07", "cleaning": {"max_gap_s": 0}}, r"recorded.cleaning.max_gap_s: must be > 0"),
        ({"sample": "paris_2021-10-07", "cleaning": {"gap": 3}}, "recorded.cleaning.gap: unknown key"),
        ({"sample": "paris_2021-10-07", "speed": 3}, "recorded.speed: unknown key"),
    ],
)
def test_recorded_section_errors_name_the_key(section, message):
    with pytest.raises(ScenarioError, match=message):
        load_scenario(scenario(recorded=section))


def test_start_and_epoch_must_agree():
    with pytest.raises(ScenarioError, match="recorded.start_utc: is 2021-10-07T13:00:00Z but epoch_utc is 2021-10-07T12:00:00Z"):
        load_scenario(scenario(epoch_utc="2021-10-07T12:00:00Z",
                               recorded={"sample": "paris_2021-10-07", "start_utc": "2021-10-07T13:00:00Z"}))
    with pytest.raises(ScenarioError, match="recorded.start_s: the scenario's epoch_utc already places the window"):
        load_scenario(scenario(epoch_utc="2021-10-07T12:00:00Z", recorded={"sample": "paris_2021-10-07", "start_s": 10}))


def test_a_relative_path_is_taken_from_the_scenario_file(tmp_path):
    states, _ = turning_states(5.0)
    write_states(tmp_path, states)
    import yaml

    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(recorded_scenario(path="states.parquet")))
    s = load_scenario(tmp_path / "scenario.yaml")
    assert s.recorded.file == tmp_path / "states.parquet"


def test_the_simulator_asks_for_the_states_of_a_recorded_section():
    s = load_scenario(recorded_scenario(sample="paris_2021-10-07"))
    with pytest.raises(ScenarioError, match="read the file with skytrack.io.read_state_vectors"):
        simulate(s)


def test_scripted_targets_are_unchanged_beside_recorded_traffic(tmp_path):
    states, _ = turning_states(5.0)
    path = write_states(tmp_path, states)
    scripted = scenario(targets=[target()], sensors=[radar(clutter_per_scan=0.0)], duration_s=240.0,
                        epoch_utc="2021-10-07T12:00:00Z")
    alone = simulate(load_scenario(scripted))
    both = simulate(load_scenario({**scripted, "recorded": {"path": path}}), recorded=read_state_vectors(path))
    assert both.targets["target_id"].tolist() == ["t1", "abc123-1"]
    assert both.targets["n_legs"].tolist() == [0, 0]
    mine = both.truth[both.truth["target_id"] == "t1"].reset_index(drop=True)
    pd.testing.assert_frame_equal(mine, alone.truth, check_exact=True)


def test_a_recorded_id_used_by_a_scripted_target_is_refused(tmp_path):
    states, _ = turning_states(5.0)
    path = write_states(tmp_path, states)
    data = scenario(targets=[target(id="abc123-1")], duration_s=240.0, recorded={"path": path})
    with pytest.raises(ScenarioError, match="used by both scripted and recorded traffic: abc123-1"):
        simulate(load_scenario(data), recorded=read_state_vectors(path))


def test_adsb_reports_are_the_recorded_samples_of_the_window(tmp_path):
    states, _ = turning_states(5.0)
    path = write_states(tmp_path, states)
    s = load_scenario(recorded_scenario(path=path, start_utc="2021-10-07T12:00:30Z"))
    adsb = simulate(s, recorded=read_state_vectors(path)).adsb
    expected = states[(states["time"] >= T0 + 30.0) & (states["time"] <= T0 + 270.0)]
    np.testing.assert_array_equal(adsb["time"], expected["time"].to_numpy() - (T0 + 30.0))
    np.testing.assert_array_equal(adsb["lat"], expected["lat"])
    assert set(adsb["truth_id"]) == {"abc123-1"} and set(adsb["icao24"]) == {"abc123"}
    assert adsb["sigma_m"].isna().all()
    np.testing.assert_allclose(np.hypot(adsb["vx"], adsb["vy"]), 200.0, atol=1e-6)

    noisy = simulate(load_scenario(recorded_scenario(path=path, adsb_sigma_m=25.0)), recorded=read_state_vectors(path)).adsb
    clean = simulate(load_scenario(recorded_scenario(path=path)), recorded=read_state_vectors(path)).adsb
    offset = np.concatenate([noisy["x"] - clean["x"], noisy["y"] - clean["y"]])
    assert (noisy["sigma_m"] == 25.0).all() and 15.0 < np.std(offset) < 35.0
    np.testing.assert_allclose(noisy["alt_m"], clean["alt_m"])
    off = simulate(load_scenario(recorded_scenario(path=path, adsb=False)), recorded=read_state_vectors(path))
    assert off.adsb is None


def test_states_without_a_recorded_section_use_the_defaults(tmp_path):
    states, _ = turning_states(5.0)
    path = write_states(tmp_path, states)
    result = simulate(load_scenario(scenario(sensors=[noise_free()], duration_s=100.0)), recorded=read_state_vectors(path))
    assert result.sensors.epoch_utc == "2021-10-07T12:00:00Z"
    assert result.truth["time"].max() == 100.0


@pytest.fixture(scope="module")
def paris_result():
    s = load_scenario("recorded_paris", overrides={"duration_s": 300.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        states = read_state_vectors(s.recorded.file)
    return simulate(s, recorded=states)


def test_bundled_paris_recording_truth_ids_are_the_segments_of_the_window(paris_result):
    result = paris_result
    knots = result.recorded.knots
    alive = knots[(knots["time"] >= 0.0) & (knots["time"] <= 300.0)]["segment_id"].unique()
    truth_ids = set(result.truth["target_id"])
    assert truth_ids == set(result.trajectories.ids) and set(alive) <= truth_ids
    assert len(truth_ids) >= 25
    true_plots = result.plots[result.plots["truth_id"] != ""]
    assert set(true_plots["truth_id"]) <= truth_ids
    # Mode S is the segment's aircraft; Mode 3/A the squawk it reported
    assert (true_plots["mode_s"] == true_plots["truth_id"].str.split("-").str[0]).all()
    squawks = knots.dropna(subset=["squawk"]).groupby("segment_id")["squawk"].agg(lambda s: set(s))
    coded = true_plots.dropna(subset=["mode3a"])
    assert len(coded) > 0.9 * len(true_plots)
    assert all(code in squawks[tid] for tid, code in zip(coded["truth_id"], coded["mode3a"], strict=True))


def test_bundled_swiss_window_keeps_30_aircraft_near_the_radar():
    """The benchmark's precondition (docs/recorded.md, bundled recordings): 11:20-12:00 UTC
    has at least 30 aircraft within 250 km of the radar of recorded_switzerland at every
    10 s instant."""
    s = load_scenario("recorded_switzerland", overrides={"duration_s": 2400.0, "truth_sample_s": 10.0})
    result = simulate(s, recorded=read_state_vectors(s.recorded.file))
    truth = result.truth[result.truth["time"] % 10.0 == 0.0]
    near = truth[np.hypot(truth["x"], truth["y"]) <= 250000.0]
    per_instant = near.groupby("time")["target_id"].nunique()
    assert per_instant.size == 241 and per_instant.min() >= 30
    assert near["visible"].all()

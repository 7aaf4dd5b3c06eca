"""Aircraft that land and take off: the ``land`` leg (truth ends at touchdown), low starts that
climb, the radar horizon on the way down and up, and landing / departing random traffic."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from sim_builders import radar, scenario, target

from skytrack.sim import ScenarioError, load_scenario, simulate
from skytrack.sim.earth import radar_horizon_range
from skytrack.sim.radar import polar_view
from skytrack.sim.spec import ClimbLeg, LandLeg

SCAN_S = 4.0


def run(data, **kw):
    return simulate(load_scenario(data), **kw)


def rows_of(result, name):
    return result.truth[result.truth.target_id == name].sort_values("time")


def beyond_horizon(result, rows) -> np.ndarray:
    """Truth rows whose ground distance from radar1 exceeds the 4/3-Earth radar horizon."""
    sensor = result.sensors["radar1"]
    _, _, _, _, ground = polar_view(sensor, rows[["x", "y", "z"]].to_numpy())
    return ground > radar_horizon_range(sensor.alt_m, rows.alt_m.to_numpy())


def test_land_leg_truth_ends_at_touchdown():
    near = {"x": 0.0, "y": 5000.0, "heading_deg": 90.0, "speed_mps": 30.0}  # within 17 km of the radar throughout
    to_sea_level = target("sea", alt_m=3000.0, **near, legs=[{"type": "straight", "duration_s": 20}, {"type": "land", "rate_mps": 6}])
    to_field = target("field", alt_m=3000.0, **{**near, "y": -5000.0},
                      legs=[{"type": "land", "rate_mps": 4, "field_alt_m": 400}])
    result = run(scenario([to_sea_level, to_field], sensors=[radar(min_elevation_deg=-2.0)], duration_s=1000.0))
    ends = result.targets.set_index("target_id").end_time
    for name, touchdown, field, rate, descent_start in (("sea", 20.0 + 3000.0 / 6.0, 0.0, 6.0, 20.0),
                                                        ("field", 2600.0 / 4.0, 400.0, 4.0, 0.0)):
        rows = rows_of(result, name)
        assert rows.time.iloc[-1] == pytest.approx(touchdown, abs=1e-9)
        assert ends[name] == pytest.approx(touchdown, abs=1e-9)
        assert rows.alt_m.iloc[-1] == pytest.approx(field, abs=1e-6)
        assert (rows.time <= touchdown + 1e-9).all()
        # a steady descent at the rate from the start of the leg
        descending = rows[(rows.time > descent_start) & (rows.time < touchdown)]
        np.testing.assert_allclose(descending.alt_m, 3000.0 - rate * (descending.time - descent_start), atol=1e-6)
        plots = result.plots[result.plots.truth_id == name]
        # seen down to the ground near the radar, never after the touchdown
        assert plots.time.max() <= touchdown
        assert plots.time.max() > touchdown - SCAN_S * 1.01
    assert rows_of(result, "sea").time.tolist() == [float(k) for k in range(521)]  # the touchdown, 520 s, is on the grid
    assert rows_of(result, "field").time.iloc[-2] == 649.0


def test_a_landing_aircraft_far_from_the_radar_drops_below_the_horizon_before_touchdown():
    # 120 km out, descending at 5 m/s from 2000 m: the 30 m antenna's horizon is at ~560-640 m there
    far = target("far", x=0.0, y=120000.0, alt_m=2000.0, speed_mps=100.0, heading_deg=90.0,
                 legs=[{"type": "land", "rate_mps": 5}])
    result = run(scenario([far], sensors=[radar(min_elevation_deg=-5.0)], duration_s=500.0))
    rows = rows_of(result, "far")
    touchdown = 400.0
    assert rows.time.iloc[-1] == pytest.approx(touchdown)
    hidden = beyond_horizon(result, rows)
    t_hidden = rows.time.to_numpy()[np.argmax(hidden)]
    assert hidden.any() and hidden[np.argmax(hidden):].all()  # once below the horizon it stays there
    assert 500.0 < rows.alt_m.to_numpy()[np.argmax(hidden)] < 700.0
    assert not rows.visible.to_numpy()[hidden].any() and rows.visible.to_numpy()[~hidden].all()
    plots = result.plots[result.plots.truth_id == "far"]
    # plots every scan until the horizon, none in the last ~100 s of the descent
    assert t_hidden - SCAN_S * 1.05 < plots.time.max() < t_hidden
    assert t_hidden < touchdown - 90.0


@pytest.mark.parametrize(("distance_m", "hidden_s"), [(10000.0, 0.0), (90000.0, 10.0)])
def test_an_aircraft_can_start_low_and_climb_out(distance_m, hidden_s):
    """Take-off: start_time_s, a 100 m start height and a climb.  Near the radar the first plot
    comes with the first beam crossing; 90 km out only once it has climbed above the horizon."""
    departing = target("dep", x=0.0, y=distance_m, alt_m=100.0, speed_mps=80.0, heading_deg=90.0, start_time_s=60.0,
                       legs=[{"type": "climb", "rate_mps": 10, "to_alt_m": 3000}])
    result = run(scenario([departing], sensors=[radar(min_elevation_deg=-5.0)], duration_s=400.0))
    rows = rows_of(result, "dep")
    assert rows.time.iloc[0] == 60.0 and rows.alt_m.iloc[0] == pytest.approx(100.0)
    hidden = beyond_horizon(result, rows)
    t_seen = rows.time.to_numpy()[np.argmin(hidden)]  # first row above the horizon
    assert t_seen - 60.0 >= hidden_s
    plots = result.plots[result.plots.truth_id == "dep"]
    assert t_seen - 1.0 <= plots.time.min() < t_seen + SCAN_S * 1.01
    height = result.trajectories.state(np.zeros(len(plots), dtype=int), plots.time.to_numpy())["alt_m"]
    climbing = height < 3000.0 - 1e-6
    assert climbing.sum() > 50 and np.all(np.diff(height[climbing]) > 0.0)  # up from plot to plot, then level
    assert np.abs(height[~climbing] - 3000.0).max() < 1e-6 and rows.alt_m.max() == pytest.approx(3000.0)


def traffic(**overrides) -> dict:
    base = {
        "count": 400,
        "region": {"type": "annulus", "sensor": "radar1", "min_range_m": 20000, "max_range_m": 150000},
        "alt_m": [1000, 10000],
        "speed_mps": [100, 250],
        "maneuver_fraction": 0.3,
    }
    base.update(overrides)
    return base


def test_landing_and_departing_traffic_fractions_rates_and_heights():
    plain = load_scenario(scenario(traffic=traffic())).all_targets()
    mixed = load_scenario(scenario(traffic=traffic(landing_fraction=0.2, departure_fraction=0.25,
                                                   landing_rate_mps=[4, 8], departure_alt_m=[300, 500]))).all_targets()
    n = len(mixed)
    landing = [t for t in mixed if t.legs and isinstance(t.legs[-1], LandLeg)]
    departing = [t for t in mixed if t.alt_m <= 500.0]
    for count, p in ((len(landing), 0.2), (len(departing), 0.25)):
        assert abs(count - n * p) <= 4.0 * math.sqrt(n * p * (1 - p))
    assert not {t.id for t in landing} & {t.id for t in departing}
    rates = np.array([t.legs[-1].rate_mps for t in landing])
    assert rates.min() >= 4.0 and rates.max() <= 8.0 and all(t.legs[-1].field_alt_m == 0.0 for t in landing)
    for t in departing:
        climb = t.legs[0]
        assert isinstance(climb, ClimbLeg) and 300.0 <= t.alt_m <= 500.0
        assert 1000.0 <= climb.to_alt_m <= 10000.0 and 5.0 <= climb.rate_mps <= 20.0  # maneuvers.climb_rate_mps default
    # the other draws are untouched: the same aircraft, with a land leg added or a climb-out put first
    for before, after in zip(plain, mixed, strict=True):
        if after in landing:
            assert dataclasses.replace(after, legs=after.legs[:-1]) == before
        elif after in departing:
            assert after.legs[1:] == before.legs and after.legs[0].to_alt_m == before.alt_m
            assert (after.speed_mps, after.heading_deg, after.start_time_s, after.mode3a) == (
                before.speed_mps, before.heading_deg, before.start_time_s, before.mode3a)
            # same ground range and azimuth from the radar, placed at the low start height
            assert 0.0 < math.hypot(after.x - before.x, after.y - before.y) < 300.0
        else:
            assert after == before


def test_landing_traffic_truth_ends_at_each_touchdown():
    data = scenario(traffic=traffic(count=30, landing_fraction=1.0, maneuver_fraction=0.0, alt_m=[1000, 2000]),
                    duration_s=600.0)
    s = load_scenario(data)
    result = simulate(s)
    last = result.truth.sort_values("time").groupby("target_id").last()
    for t in s.all_targets():
        touchdown = t.alt_m / t.legs[-1].rate_mps  # 100-400 s, within the run
        assert last.loc[t.id, "time"] == pytest.approx(touchdown, abs=1e-9)
        assert last.loc[t.id, "alt_m"] == pytest.approx(0.0, abs=1e-6)
    assert result.plots[result.plots.truth_id != ""].groupby("truth_id").time.max().le(last.time.reindex(
        result.plots[result.plots.truth_id != ""].truth_id.unique())).all()


@pytest.mark.parametrize(
    ("patch", "expected"),
    [
        ({"targets": [target(legs=[{"type": "land", "rate_mps": 0}])]}, "targets[0].legs[0].rate_mps: must be > 0, got 0"),
        ({"targets": [target(legs=[{"type": "land"}])]}, "targets[0].legs[0].rate_mps: required key is missing"),
        ({"targets": [target(legs=[{"type": "land", "rate_mps": 5, "to_alt_m": 0}])]}, "targets[0].legs[0].to_alt_m: unknown key"),
        ({"targets": [target(legs=[{"type": "land", "rate_mps": 5}, {"type": "straight", "duration_s": 10}])]},
         "targets[0].legs[0]: a land leg ends the flight (the truth ends at touchdown), so it must be the last leg"),
        ({"targets": [target(alt_m=9000, legs=[{"type": "climb", "rate_mps": 10, "to_alt_m": 4000},
                                               {"type": "land", "rate_mps": 5, "field_alt_m": 5000}])]},
         "targets[0].legs[1].field_alt_m: must be below the height at the start of the leg (4000 m), got 5000"),
        ({"targets": [target(alt_m=300, legs=[{"type": "climb", "rate_mps": -1, "duration_s": 100},
                                              {"type": "land", "rate_mps": 5, "field_alt_m": 250}])]},
         "targets[0].legs[1].field_alt_m: must be below the height at the start of the leg (200 m), got 250"),
        ({"traffic": traffic(landing_fraction=0.6, departure_fraction=0.5)},
         "traffic.departure_fraction: landing_fraction + departure_fraction must be <= 1"),
        ({"traffic": traffic(landing_rate_mps=[0, 5])}, "traffic.landing_rate_mps[0]: must be > 0, got 0"),
        ({"traffic": traffic(departure_fraction=0.1, departure_alt_m=[200, 1500])},
         "traffic.departure_alt_m: must lie below alt_m (departing aircraft climb from it to a height in alt_m), got [200, 1500] with alt_m [1000, 10000]"),
        ({"traffic": traffic(landing_fraction=0.1, alt_m=[0, 3000])}, "traffic.alt_m: must be > 0 when landing_fraction > 0"),
        ({"traffic": traffic(landing_fraction=1.5)}, "traffic.landing_fraction: must be <= 1, got 1.5"),
    ],
)
def test_landing_and_departure_key_errors_name_the_key_path(patch, expected):
    data = scenario([target()])
    data.update(patch)
    with pytest.raises(ScenarioError) as info:
        load_scenario(data)
    assert expected in str(info.value)

"""Issue 9: the simulated interrogator (``secondary_only``), spec 001's system З (secondary radar /
IFF with active reply) next to a primary radar.

Checked: only aircraft that reply give plots (a transponder; an IFF status when the interrogator
has an ``iff`` section), at the reply probability ``p_detection`` (4-sigma binomial band), with the
interrogator's own range and azimuth noise (chi-square band, two-sided 1e-3), false replies (fruit)
as Poisson(``clutter_per_scan``) per revolution (4-sigma band) carrying a random code and height;
scenario errors name the key; the interrogator's random stream is its own: the demo's plots are
bit-identical with an interrogator added and with ``secondary_only: false`` written out.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import stats

from skytrack.sim import ScenarioError, load_scenario, simulate
from skytrack.sim.radar import polar_view
from skytrack.sim.scenario import bundled_scenario_path

ORIGIN = {"lat": 47.40, "lon": 1.90, "alt_m": 0.0}
P_TAIL = 1e-3


def interrogator(**overrides) -> dict:
    base = {"name": "interrogator", "type": "radar-2d", "x": 40000.0, "y": -25000.0, "alt_m": 120.0,
            "scan_period_s": 5.0, "sigma_range_m": 20.0, "sigma_azimuth_deg": 0.04, "max_range_m": 200000.0,
            "min_elevation_deg": -0.5, "p_detection": 0.95, "clutter_per_scan": 0.0, "secondary_only": True}
    base.update(overrides)
    return base


def ring(n: int, **extra) -> list[dict]:
    """n aircraft on a 60 km ring around the interrogator, flying tangentially (always in coverage)."""
    return [{"id": f"A{k:02d}", "range_m": 60000.0, "azimuth_deg": float(az), "sensor": "interrogator",
             "alt_m": 8000.0, "speed_mps": 150.0, "heading_deg": float((az + 90.0) % 360.0), **extra}
            for k, az in enumerate(np.linspace(0.0, 360.0, n, endpoint=False))]


def document(targets, sensors, duration_s=300.0, seed=5) -> dict:
    return {"origin": dict(ORIGIN), "duration_s": duration_s, "seed": seed, "sensors": copy.deepcopy(sensors),
            "targets": copy.deepcopy(targets)}


def binomial_ok(successes: int, n: int, p: float) -> bool:
    return abs(successes - n * p) <= 4.0 * math.sqrt(n * p * (1.0 - p))


# ---------------------------------------------------------------------------- who replies


def test_only_aircraft_with_a_transponder_give_plots_at_the_reply_probability():
    equipped = ring(12, mode3a="2345")
    silent = [{**t, "id": f"N{k:02d}", "azimuth_deg": t["azimuth_deg"] + 15.0, "transponder": False}
              for k, t in enumerate(ring(6))]
    always = simulate(load_scenario(document(equipped + silent, [interrogator(p_detection=1.0)])))
    sometimes = simulate(load_scenario(document(equipped + silent, [interrogator(p_detection=0.7)])))
    for result in (always, sometimes):
        assert set(result.plots["truth_id"]) <= {t["id"] for t in equipped}
    # every crossing of an equipped aircraft answers at p = 1; at 0.7 a binomial share of them
    crossings = len(always.plots)
    assert 12 * 59 <= crossings <= 12 * 61  # 300 s of 5 s scans, every aircraft in coverage
    assert binomial_ok(len(sometimes.plots), crossings, 0.7)
    assert (always.plots["mode3a"] == "2345").all() and always.plots["mode_c_ft"].notna().all()


def test_an_iff_interrogator_also_hears_aircraft_with_an_iff_transponder_only():
    ssr = ring(4, mode3a="1200")
    iff_only = [{**t, "id": f"F{k}", "azimuth_deg": t["azimuth_deg"] + 30.0, "transponder": False, "iff": "friend"}
                for k, t in enumerate(ring(4))]
    plain = simulate(load_scenario(document(ssr + iff_only, [interrogator()], duration_s=100.0)))
    with_iff = simulate(load_scenario(document(ssr + iff_only, [interrogator(iff={"p_reply": 1.0})], duration_s=100.0)))
    assert not plain.plots["truth_id"].str.startswith("F").any()
    heard = with_iff.plots[with_iff.plots["truth_id"].str.startswith("F")]
    assert heard["truth_id"].nunique() == 4 and (heard["iff"] == "friend").all()


def test_replies_carry_the_interrogators_own_noise():
    result = simulate(load_scenario(document(ring(20, mode3a="3000"), [interrogator(p_detection=1.0)], duration_s=400.0)))
    plots = result.plots
    sensor = result.sensors["interrogator"]
    index = pd.Index(result.trajectories.ids).get_indexer(plots["truth_id"])
    state = result.trajectories.state(index, plots["time"].to_numpy())
    position = np.stack([state["x"], state["y"], state["z"]], axis=1)
    r, az, _, _, _ = polar_view(sensor, position)
    range_error = plots["range_m"].to_numpy() - r
    azimuth_error = (plots["azimuth_deg"].to_numpy() - np.degrees(az) + 180.0) % 360.0 - 180.0
    n = len(plots)
    low, high = stats.chi2.ppf(P_TAIL / 2, n), stats.chi2.ppf(1 - P_TAIL / 2, n)
    assert low <= np.sum((range_error / 20.0) ** 2) <= high
    assert low <= np.sum((azimuth_error / 0.04) ** 2) <= high


def test_false_replies_are_fruit_with_a_code_and_a_height():
    result = simulate(load_scenario(document(ring(1, mode3a="0100"), [interrogator(clutter_per_scan=3.0)],
                                             duration_s=1000.0)))
    fruit = result.plots[result.plots["truth_id"] == ""]
    revolutions = 1000.0 / 5.0
    assert abs(len(fruit) - 3.0 * revolutions) <= 4.0 * math.sqrt(3.0 * revolutions)
    assert fruit["mode_s"].isna().all()
    assert fruit["mode3a"].notna().all() and fruit["mode_c_ft"].notna().all()
    assert fruit["mode3a"].nunique() > 0.9 * len(fruit)  # random codes, few repeats among 4096


# ---------------------------------------------------------------------------- scenario errors


@pytest.mark.parametrize("change, message", [
    ({"secondary_only": "yes"}, "sensors[0].secondary_only: must be true or false"),
    ({"sigma_range_rate_mps": 1.0}, "sensors[0].sigma_range_rate_mps: is not allowed with secondary_only"),
])
def test_scenario_errors_name_the_key(change, message):
    with pytest.raises(ScenarioError, match=message.replace("[", r"\[").replace("]", r"\]")):
        load_scenario(document(ring(1), [interrogator(**change)]))


def test_an_airborne_sensor_cannot_be_secondary_only():
    carrier = {"x": 0.0, "y": 0.0, "alt_m": 9000.0, "speed_mps": 200.0, "heading_deg": 90.0}
    airborne = {"name": "awacs", "type": "radar-airborne", "scan_period_s": 10.0, "sigma_range_m": 50.0,
                "sigma_azimuth_deg": 0.2, "max_range_m": 300000.0, "carrier": carrier, "secondary_only": True}
    with pytest.raises(ScenarioError, match=r"sensors\[0\]\.secondary_only: is only available for ground sensors"):
        load_scenario(document([], [airborne]))


# ---------------------------------------------------------------------------- random streams


def _demo_document() -> dict:
    return yaml.safe_load(bundled_scenario_path("demo").read_text())


def _same_frames(a: pd.DataFrame, b: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(a.reset_index(drop=True), b.reset_index(drop=True), check_exact=True)


def test_the_demos_plots_do_not_change_with_an_interrogator_added():
    demo = _demo_document()
    before = simulate(load_scenario(demo))
    names = [s["name"] for s in demo["sensors"]]
    explicit = copy.deepcopy(demo)
    for sensor in explicit["sensors"]:
        sensor["secondary_only"] = False
    _same_frames(simulate(load_scenario(explicit)).plots, before.plots)
    added = copy.deepcopy(demo)
    # first in the list: its draws would come before the demo radar's if it shared their stream
    added["sensors"].insert(0, interrogator(x=30000.0, y=30000.0, clutter_per_scan=2.0))
    after = simulate(load_scenario(added))
    _same_frames(after.plots[after.plots["sensor"].isin(names)], before.plots)
    assert (after.plots["sensor"] == "interrogator").sum() > 0

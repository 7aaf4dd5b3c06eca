"""Issue 9 item 1: simulated ADS-B (skytrack.sim.adsb), the scenario's ``adsb`` section, and
the bundled acceptance scenario.

The reports are spec 001's η_μ ((1): H X + ε, ε ~ N(0, σ² I)); the statistical tests hold
the drawn errors to their stated laws with two-sided 1e-3 tolerances (chi-square for the
sums of squares, a 4-sigma binomial band for the counts), on fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from typer.testing import CliRunner

from skytrack.geo.sensors import Origin
from skytrack.sim import ScenarioError, load_scenario, simulate
from skytrack.sim.adsb import derived_callsign, derived_icao24, simulate_adsb
from skytrack.sim.spec import AdsbAircraftSpec, AdsbSpec

ORIGIN = Origin(48.86, 2.50, 0.0)
SPAN_S = 600.0
P_TAIL = 1e-3  # two-sided probability of a false failure of each statistical check


def straight_truth(count: int = 3, span_s: float = SPAN_S, step_s: float = 1.0) -> pd.DataFrame:
    """Aircraft T0, T1, ... flying straight and level at constant ENU velocity (linear
    interpolation between the rows is then exact)."""
    t = np.arange(0.0, span_s + step_s / 2, step_s)
    rows = []
    for k in range(count):
        x0, y0 = 20_000.0 * (k + 1), -10_000.0 * k
        vx, vy = 150.0 + 10.0 * k, -40.0 * k
        rows.append(pd.DataFrame({
            "time": t, "target_id": f"T{k}", "segment": 0,
            "x": x0 + vx * t, "y": y0 + vy * t, "z": 5000.0, "vx": vx, "vy": vy, "vz": 0.5 * k,
            "alt_m": 5000.0 + 1000.0 * k,
        }))
    return pd.concat(rows, ignore_index=True)


def truth_at(truth: pd.DataFrame, reports: pd.DataFrame, column: str) -> np.ndarray:
    """The straight-line truth of ``column`` at each report's time (exact)."""
    first = truth.groupby("target_id").first()
    rate = {"x": "vx", "y": "vy"}.get(column)
    base = first.loc[reports["truth_id"], column].to_numpy()
    if rate is None:
        return base
    return base + first.loc[reports["truth_id"], rate].to_numpy() * reports["time"].to_numpy()


def run(spec: AdsbSpec, truth: pd.DataFrame | None = None, seed: int = 1, **kwargs):
    truth = straight_truth() if truth is None else truth
    return simulate_adsb(truth, spec, np.random.default_rng(seed), origin=ORIGIN,
                         equipage_rng=np.random.default_rng(99), **kwargs)


def chi_square_band(dof: int) -> tuple[float, float]:
    return stats.chi2.ppf(P_TAIL / 2, dof), stats.chi2.ppf(1 - P_TAIL / 2, dof)


# ---------------------------------------------------------------------------- rate, losses


def test_reports_come_every_interval_from_a_phase_per_aircraft():
    sim = run(AdsbSpec(interval_s=2.0, jitter_s=0.0))
    for _, reports in sim.reports.groupby("truth_id"):
        t = reports["time"].to_numpy()
        np.testing.assert_allclose(np.diff(t), 2.0, atol=1e-9)
        assert 0.0 <= t[0] < 2.0 and t[-1] <= SPAN_S
        assert len(t) == 300  # span 600 s / 2 s, the phase inside the first interval
    phases = sim.reports.groupby("truth_id")["time"].first()
    assert phases.nunique() == 3  # each aircraft its own phase


def test_jitter_moves_times_within_its_bound_and_keeps_them_in_order():
    sim = run(AdsbSpec(interval_s=1.0, jitter_s=0.2))
    gaps = np.concatenate([np.diff(r["time"].to_numpy()) for _, r in sim.reports.groupby("truth_id")])
    assert gaps.min() >= 1.0 - 0.4 - 1e-9 and gaps.max() <= 1.0 + 0.4 + 1e-9
    assert gaps.std() > 0.1  # uniform +-0.2 twice: sd 0.163


def test_report_count_follows_the_binomial_law_of_p_drop():
    p_drop, candidates = 0.2, 3 * 600  # jitter 0: exactly 600 candidate instants per aircraft
    sim = run(AdsbSpec(jitter_s=0.0, p_drop=p_drop))
    expected, sd = candidates * (1 - p_drop), np.sqrt(candidates * p_drop * (1 - p_drop))
    assert abs(len(sim.reports) - expected) < 4.0 * sd
    assert sim.aircraft["reports"].sum() == len(sim.reports)
    # losses change which reports are kept, never the draws of the others
    full = run(AdsbSpec(jitter_s=0.0)).reports.set_index(["truth_id", "time"])
    kept = sim.reports.set_index(["truth_id", "time"])
    pd.testing.assert_frame_equal(kept, full.loc[kept.index])


def test_outages_and_coverage_remove_every_report_they_cover():
    sim = run(AdsbSpec(outages=((100.0, 200.0), (400.0, 410.0))))
    t = sim.reports["time"]
    assert not ((t >= 100) & (t <= 200)).any() and not ((t >= 400) & (t <= 410)).any()
    assert ((t > 200) & (t < 400)).sum() > 3 * 190
    covered = run(AdsbSpec(coverage_m=100_000.0))
    true_range = np.hypot(truth_at(straight_truth(), covered.reports, "x"), truth_at(straight_truth(), covered.reports, "y"))
    assert true_range.max() <= 100_000.0 and true_range.max() > 99_000.0
    assert len(covered.reports) < len(run(AdsbSpec()).reports)


# ---------------------------------------------------------------------------- noise


def test_horizontal_height_and_velocity_noise_have_the_configured_sd():
    """Per axis, sum of squares / sigma^2 ~ chi2(n) with n ~ 6000: a 3 % error in the sd fails."""
    truth = straight_truth(count=10)
    spec = AdsbSpec(sigma_m=10.0, sigma_alt_m=15.0, sigma_velocity_mps=1.5)
    reports = run(spec, truth).reports
    for column, sigma in (("x", 10.0), ("y", 10.0), ("alt_m", 15.0), ("vx", 1.5), ("vy", 1.5), ("vz", 1.5)):
        residual = reports[column].to_numpy() - truth_at(truth, reports, column)
        low, high = chi_square_band(residual.size)
        assert low < np.sum(residual**2) / sigma**2 < high, column
        assert abs(residual.mean()) < 4.0 * sigma / np.sqrt(residual.size), column
    # the axes are drawn independently
    dx, dy = (reports[c].to_numpy() - truth_at(truth, reports, c) for c in ("x", "y"))
    assert abs(np.corrcoef(dx, dy)[0, 1]) < 4.0 / np.sqrt(dx.size)
    assert np.all(reports["sigma_m"] == 10.0) and len(reports) > 5900


def test_positions_are_the_linear_interpolation_of_the_truth_rows():
    truth = pd.DataFrame({"time": [0.0, 10.0, 20.0], "target_id": "A", "x": [0.0, 100.0, 100.0],
                          "y": [0.0, 0.0, 300.0], "alt_m": 1000.0, "vx": 0.0, "vy": 0.0, "vz": 0.0})
    reports = run(AdsbSpec(sigma_m=1e-9, sigma_alt_m=0.0, jitter_s=0.0, velocities=False), truth).reports
    t = reports["time"].to_numpy()
    np.testing.assert_allclose(reports["x"], np.where(t <= 10, 10.0 * t, 100.0), atol=1e-6)
    np.testing.assert_allclose(reports["y"], np.where(t <= 10, 0.0, 30.0 * (t - 10)), atol=1e-6)
    assert reports["vx"].isna().all()
    # z, lat, lon: the point at that (x, y) and height (the frame is a tangent plane)
    assert np.all(reports["z"] < 1000.0) and np.all(reports["alt_m"] == 1000.0)


def test_an_offset_shifts_every_position_of_its_aircraft_only():
    truth = straight_truth()
    sim = run(AdsbSpec(sigma_m=10.0), truth, settings={"T1": AdsbAircraftSpec(offset_m=(2000.0, -500.0))})
    reports = sim.reports
    for target, (dx, dy) in {"T0": (0.0, 0.0), "T1": (2000.0, -500.0), "T2": (0.0, 0.0)}.items():
        rows = reports[reports["truth_id"] == target]
        bound = 4.0 * 10.0 / np.sqrt(len(rows))
        assert abs((rows["x"] - truth_at(truth, rows, "x")).mean() - dx) < bound
        assert abs((rows["y"] - truth_at(truth, rows, "y")).mean() - dy) < bound
    row = sim.aircraft.set_index("target_id").loc["T1"]
    assert row["fault"] == "offset" and (row["offset_x_m"], row["offset_y_m"]) == (2000.0, -500.0)
    assert np.all(reports["sigma_m"] == 10.0)  # the faulty transponder claims its nominal accuracy


# ---------------------------------------------------------------------------- equipage, identity


def test_equipage_is_exactly_the_configured_fraction_and_explicit_settings_win():
    truth = straight_truth(count=10, span_s=30.0)
    aircraft = pd.DataFrame({"target_id": [f"T{k}" for k in range(10)], "transponder": [k != 9 for k in range(10)]})
    settings = {"T0": AdsbAircraftSpec(equipped=False), "T1": AdsbAircraftSpec(equipped=True)}
    sim = run(AdsbSpec(equipage=0.5), truth, aircraft=aircraft, settings=settings)
    equipped = sim.aircraft.set_index("target_id")["equipped"]
    # T1 + round(0.5 x 7 undecided transponder aircraft T2..T8) = 1 + 4
    assert equipped.sum() == 5 and equipped["T1"] and not equipped["T0"] and not equipped["T9"]
    assert set(sim.reports["truth_id"]) == set(equipped.index[equipped])
    again = run(AdsbSpec(equipage=0.5), truth, seed=5, aircraft=aircraft, settings=settings)
    pd.testing.assert_series_equal(again.aircraft.set_index("target_id")["equipped"], equipped)  # seed of the equipage only
    assert run(AdsbSpec(equipage=0.0), truth, settings=settings).aircraft["equipped"].sum() == 1
    assert run(AdsbSpec(equipage=1.0), truth, aircraft=aircraft, settings=settings).aircraft["equipped"].sum() == 8


def test_identities_truth_id_and_faults():
    truth = straight_truth(count=4, span_s=20.0)
    aircraft = pd.DataFrame({"target_id": ["T0", "T1", "T2", "T3"], "icao24": ["3C6A01", None, "abcdef", None],
                             "callsign": ["AFR123", None, "DLH9", None]})
    settings = {"T1": AdsbAircraftSpec(wrong_icao24="abcdef", wrong_callsign=True),
                "T2": AdsbAircraftSpec(no_callsign=True), "T3": AdsbAircraftSpec(wrong_icao24=True)}
    sim = run(AdsbSpec(), truth, aircraft=aircraft, settings=settings)
    table = sim.aircraft.set_index("target_id")
    assert table.loc["T0", "icao24"] == "3c6a01" and table.loc["T0", "callsign"] == "AFR123"
    assert table.loc["T1", "icao24"] == derived_icao24("T1", {"3c6a01", "abcdef"})
    assert table.loc["T1", "callsign"] == "T1"  # the id in capitals
    first = sim.reports.groupby("truth_id").first()
    assert first.loc["T0", "icao24"] == "3c6a01" and first.loc["T0", "callsign"] == "AFR123"
    assert first.loc["T1", "icao24"] == "abcdef"  # wrong identity: another aircraft's address
    assert first.loc["T1", "callsign"] not in set(table["callsign"])
    assert pd.isna(first.loc["T2", "callsign"]) and first.loc["T2", "icao24"] == "abcdef"
    assert first.loc["T3", "icao24"] not in set(table["icao24"]) | {"abcdef"}
    assert table.loc["T1", "fault"] == "wrong_icao24,wrong_callsign" and table.loc["T2", "fault"] == "no_callsign"
    # truth_id is the true target of every report, whatever it transmits
    for target, rows in sim.reports.groupby("truth_id"):
        np.testing.assert_allclose(rows["x"], truth_at(truth, rows, "x"), atol=60.0)
    assert set(sim.reports["truth_id"]) == {"T0", "T1", "T2", "T3"}


def test_derived_identities_are_deterministic_and_distinct():
    used: set[str] = set()
    for k in range(50):
        used.add(derived_icao24(f"AC{k:04d}", used))
    addresses = sorted(used)
    assert len(set(addresses)) == 50 and all(len(a) == 6 for a in addresses)
    assert derived_icao24("AC0001", set()) == derived_icao24("AC0001", set())
    assert derived_icao24("AC0001", {derived_icao24("AC0001", set())}) != derived_icao24("AC0001", set())
    assert derived_callsign("ac-12", set()) == "AC12"
    assert derived_callsign("a-very-long-id", set()).startswith("SKY")
    assert derived_callsign("AC12", {"AC12"}) != "AC12"


# ---------------------------------------------------------------------------- scenario


def small_scenario(**adsb) -> dict:
    scenario = {
        "origin": {"lat": 48.86, "lon": 2.5}, "duration_s": 120, "seed": 3,
        "sensors": [{"name": "r", "lat": 48.86, "lon": 2.5, "scan_period_s": 4, "sigma_range_m": 40,
                     "sigma_azimuth_deg": 0.07, "max_range_m": 200000, "p_detection": 0.9, "clutter_per_scan": 5}],
        "targets": [
            {"id": "A", "x": 30000, "y": 10000, "alt_m": 5000, "speed_mps": 200, "heading_deg": 90, "icao24": "4ca7b5",
             "callsign": "eie12", "adsb": {"offset_m": [2000, 0]}},
            {"id": "B", "x": -40000, "y": 0, "alt_m": 6000, "speed_mps": 180, "heading_deg": 0, "mode3a": "1234"},
        ],
        "traffic": {"count": 6, "region": {"type": "annulus", "sensor": "r", "min_range_m": 20000, "max_range_m": 90000},
                    "alt_m": [2000, 9000], "speed_mps": [120, 220]},
    }
    if adsb is not None:
        scenario["adsb"] = adsb
    return scenario


def test_adsb_leaves_the_radar_plots_of_a_seed_unchanged():
    without = small_scenario()
    del without["adsb"]
    del without["targets"][0]["adsb"]
    base = simulate(load_scenario(without), rng=np.random.default_rng(11))
    for adsb in ({}, {"p_drop": 0.3, "equipage": 0.5, "velocities": False}):
        with_adsb = simulate(load_scenario(small_scenario(**adsb)), rng=np.random.default_rng(11))
        pd.testing.assert_frame_equal(base.plots, with_adsb.plots)
        pd.testing.assert_frame_equal(base.truth, with_adsb.truth)
        assert with_adsb.adsb is not None and len(with_adsb.adsb) > 0
    assert base.adsb is None and base.adsb_aircraft is None


def test_scenario_identities_settings_and_lists():
    result = simulate(load_scenario(small_scenario(unequipped=["T0001"], aircraft={"T0002": {"wrong_icao24": "aaaaaa"}})))
    table = result.adsb_aircraft.set_index("target_id")
    assert table.loc["A", "icao24"] == "4ca7b5" and table.loc["A", "callsign"] == "EIE12"  # the scenario's
    assert table.loc["A", "fault"] == "offset" and table.loc["T0002", "fault"] == "wrong_icao24"
    assert not table.loc["T0001", "equipped"] and table["equipped"].sum() == 7
    assert set(result.adsb["truth_id"]) == set(table.index[table["equipped"]])
    assert (result.adsb.loc[result.adsb["truth_id"] == "T0002", "icao24"] == "aaaaaa").all()
    assert result.targets.set_index("target_id").loc["A", "callsign"] == "EIE12"


@pytest.mark.parametrize(("adsb", "target_adsb", "key"), [
    ({"p_drop": 1.5}, None, "adsb.p_drop"),
    ({"interval_s": 0}, None, "adsb.interval_s"),
    ({"jitter_s": 0.6}, None, "adsb.jitter_s"),
    ({"sigma_m": 0}, None, "adsb.sigma_m"),
    ({"equipage": -0.1}, None, "adsb.equipage"),
    ({"coverage_m": -5}, None, "adsb.coverage_m"),
    ({"outages": [[50, 10]]}, None, "adsb.outages[0]"),
    ({"velocity": True}, None, "adsb.velocity"),
    ({"equipped": ["A"], "unequipped": ["A"]}, None, "adsb.unequipped[0]"),
    ({"aircraft": {"T0001": {"wrong_icao24": "xyz"}}}, None, "adsb.aircraft.T0001.wrong_icao24"),
    ({"aircraft": {"T0001": {"offset_m": [1, "a"]}}}, None, "adsb.aircraft.T0001.offset_m[1]"),
    ({"aircraft": {"A": {"equipped": True}}}, {"equipped": False}, "adsb.aircraft.A"),
    ({}, {"offset_m": 2000}, "targets[0].adsb.offset_m"),
    ({}, {"equipped": False, "offset_m": [1, 0]}, "targets[0].adsb.offset_m"),
    ({}, {"no_callsign": True, "wrong_callsign": "X1"}, "targets[0].adsb.no_callsign"),
    (None, {"equipped": True}, "targets[0].adsb"),
])
def test_scenario_errors_name_the_key(adsb, target_adsb, key):
    scenario = small_scenario(**(adsb or {}))
    if adsb is None:
        del scenario["adsb"]
    if target_adsb is None:
        del scenario["targets"][0]["adsb"]
    else:
        scenario["targets"][0]["adsb"] = target_adsb
    with pytest.raises(ScenarioError) as error:
        load_scenario(scenario)
    assert f"scenario: {key}:" in str(error.value)


def test_unknown_aircraft_and_conflicting_recorded_noise_name_the_key():
    with pytest.raises(ScenarioError, match=r"adsb\.unequipped\[0\]: no target with the id or Mode S address 'NOPE'"):
        simulate(load_scenario(small_scenario(unequipped=["NOPE"])))
    scenario = small_scenario()
    scenario["recorded"] = {"sample": "switzerland_2018-08-01", "adsb_sigma_m": 20}
    with pytest.raises(ScenarioError, match=r"recorded\.adsb_sigma_m: the adsb section"):
        load_scenario(scenario)


def test_recorded_window_accepts_the_adsb_options():
    from skytrack.app.simulate import run_simulation
    from skytrack.io import read_state_vectors

    plain = run_simulation("recorded_switzerland", duration=60)
    address = plain.targets["icao24"].iloc[0]
    scenario = load_scenario("recorded_switzerland", overrides={
        "duration_s": 60,
        "adsb": {"equipage": 0.5, "p_drop": 0.1, "aircraft": {address: {"equipped": True, "offset_m": [2000, 0]}}}})
    result = simulate(scenario, recorded=read_state_vectors(scenario.recorded.file))
    pd.testing.assert_frame_equal(plain.plots, result.plots)
    table = result.adsb_aircraft.set_index("target_id")
    segments = table.index[table["icao24"] == address]  # the key (a Mode S address) sets all its segments
    undecided = len(table) - len(segments)
    assert table["equipped"].sum() == len(segments) + int(np.floor(0.5 * undecided + 0.5))
    assert (table.loc[segments, "fault"] == "offset").all() and table.loc[segments, "equipped"].all()
    # the reports are simulated now (1 s), not the recorded 10 s samples
    assert len(result.adsb) > 3 * len(plain.adsb)
    assert set(result.adsb["callsign"].dropna()) <= set(plain.targets["callsign"].dropna())


# ---------------------------------------------------------------------------- bundled scenario


def test_bundled_identification_scenario_is_what_the_acceptance_needs(tmp_path):
    from skytrack.cli.main import app

    outcome = CliRunner().invoke(app, ["simulate", "adsb_identification", "--out", str(tmp_path)])
    assert outcome.exit_code == 0, outcome.output
    assert "ADS-B reports" in outcome.output and "20 of 25 equipped" in outcome.output
    adsb = pd.read_parquet(tmp_path / "adsb.parquet")
    truth = pd.read_parquet(tmp_path / "truth.parquet")
    assert adsb["truth_id"].nunique() == 20 and truth["target_id"].nunique() == 25
    ranges = np.hypot(truth["x"], truth["y"])
    assert ranges.min() > 20_000 and ranges.max() < 150_000 and truth["time"].max() == 360.0
    x = truth.pivot(index="time", columns="target_id", values="x")
    y = truth.pivot(index="time", columns="target_id", values="y")
    pair = np.hypot(x["PAIR1"] - x["PAIR2"], y["PAIR1"] - y["PAIR2"])
    np.testing.assert_allclose(pair.loc[:180.0], 1000.0, atol=1e-3)
    assert pair.iloc[-1] > 10_000
    assert {"PAIR1", "PAIR2", "OFS1"} <= set(adsb["truth_id"])
    offset = adsb[adsb["truth_id"] == "OFS1"]
    at = truth[truth["target_id"] == "OFS1"].set_index("time")
    dx = offset["x"].to_numpy() - np.interp(offset["time"], at.index, at["x"])
    dy = offset["y"].to_numpy() - np.interp(offset["time"], at.index, at["y"])
    assert abs(dx.mean() - 2000.0) < 5.0 and abs(dy.mean()) < 5.0
    others = {k: v for k, v in ((t, np.hypot(x["OFS1"] + 2000 - x[t], y["OFS1"] - y[t]).min()) for t in x.columns if t != "OFS1")}
    assert min(others.values()) > 5_000  # the offset positions fall on no other aircraft
    plots = pd.read_parquet(tmp_path / "plots.parquet")
    false = plots[plots["truth_id"] == ""]
    assert (false["range_m"] < 25_000).mean() > 2 * 25_000 / 250_000  # clutter denser near the radar
    assert plots["mode_s"].isna().all()  # no Mode S: labels come from the kinematic test only

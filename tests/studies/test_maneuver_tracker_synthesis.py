"""Spec 004 §6 E10 ``skytrack study tracker-synthesis`` (P12): range-rate measurement mode, manoeuvre
libraries and the library-informed IMM, the study end to end (R21, R23, R24)."""

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import skytrack
from skytrack.studies.maneuver.filters import CATALOG, FilterSetting
from skytrack.studies.maneuver.maneuver_library import (
    LIBRARY_DIR,
    SHIPPED,
    DrawSettings,
    draw_case,
    library_imm,
    library_modes,
    library_transition,
    load_library,
    parse_library,
)
from skytrack.studies.maneuver.measurements import DEFAULT_RANGE_RATE_SIGMA, simulate_measurements, true_range_rate
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from skytrack.studies.maneuver.runner import RunOptions, run_filter
from skytrack.studies.maneuver.scenarios import named_cases
from skytrack.studies.maneuver.tracker_synthesis import case_metrics, run_measured
from skytrack.studies.maneuver.trajectory import G0
from study_cli import claims_of, invoke_study, study_outputs

ROOT = Path(__file__).resolve().parents[2]


def study(*args):
    return invoke_study("tracker-synthesis", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "tracker-synthesis", "--quick", "--runs", "12", "--check")


@pytest.fixture(scope="module")
def turn_case():
    return named_cases("default", turn_g=(5.0,))[0]


# ---------------------------------------------------------------------------- measurement mode with range rate
def test_polar_doppler_adds_range_rate_to_the_polar_plots(turn_case):
    polar = simulate_measurements(turn_case, 40, 7, "polar")
    doppler = simulate_measurements(turn_case, 40, 7, "polar_doppler", range_rate_sigma=0.5)
    assert np.array_equal(polar.z, doppler.z) and np.array_equal(polar.R, doppler.R)  # common random numbers
    assert polar.range_rate is None and polar.range_rate_sigma is None
    assert doppler.range_rate.shape == (turn_case.scans, 40) and doppler.range_rate_sigma == 0.5
    truth = true_range_rate(turn_case.truth.position, turn_case.truth.velocity, turn_case.sensor.position)
    # start: (-10 000, 40 000, 6 000) m flying east at 250 m/s, rdot = p . v / |p|
    assert truth[0] == pytest.approx(-10_000 * 250 / math.sqrt(10_000**2 + 40_000**2 + 6_000**2), rel=1e-12)
    error = doppler.range_rate - truth[:, None]
    samples = error.size
    assert abs(error.mean()) <= 4 * 0.5 / math.sqrt(samples)
    assert abs(error.std() / 0.5 - 1) <= 4 / math.sqrt(2 * samples)
    default = simulate_measurements(turn_case, 2, 7, "polar_doppler")
    assert default.range_rate_sigma == DEFAULT_RANGE_RATE_SIGMA
    with pytest.raises(ValueError, match="range_rate_sigma > 0"):
        simulate_measurements(turn_case, 2, 7, "polar_doppler", range_rate_sigma=0.0)


def test_run_measured_without_range_rate_is_the_study_runner(turn_case):
    meas = simulate_measurements(turn_case, 6, 3, "polar_doppler")
    for label in ("kf-ca", "kf-singer"):
        spec = CATALOG[label]
        mine = run_measured(spec, turn_case, meas, range_rate=False)
        filt, _ = spec.build(FilterSetting(turn_case.dt, meas.R[0], turn_case.sensor.position))
        theirs = run_filter(filt, turn_case, meas, label=label, options=RunOptions(gating="off"))
        for name in ("position_error", "velocity_error", "nees", "nis"):
            np.testing.assert_allclose(getattr(mine, name), getattr(theirs, name), rtol=1e-9, atol=1e-9)
        assert np.array_equal(mine.lost, theirs.lost)


def test_range_rate_removes_the_radial_velocity_error(turn_case):
    meas = simulate_measurements(turn_case, 30, 5, "polar_doppler")
    spec = CATALOG["kf-ca"]
    without = case_metrics(turn_case, run_measured(spec, turn_case, meas, range_rate=False), 10.0)
    with_rdot = case_metrics(turn_case, run_measured(spec, turn_case, meas, range_rate=True), 10.0)
    # rdot measures the velocity along the line of sight only (sigma 1 m/s): that part shrinks, the rest stays
    assert with_rdot["rms_radial_vel_mps"] < 0.2 * without["rms_radial_vel_mps"]
    assert with_rdot["rms_cross_vel_mps"] == pytest.approx(without["rms_cross_vel_mps"], rel=0.05)
    assert with_rdot["rms_vel_mps"] < without["rms_vel_mps"]
    with pytest.raises(ValueError, match="range rate needs polar_doppler"):
        run_measured(spec, turn_case, simulate_measurements(turn_case, 2, 5, "polar"), range_rate=True)


# ---------------------------------------------------------------------------- manoeuvre libraries
def test_shipped_libraries_are_package_data():
    shipped = {p.stem for p in LIBRARY_DIR.glob("*.yaml")}
    assert shipped == set(SHIPPED)
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["skytrack"]
    package = Path(skytrack.__file__).parent
    covered = {p.resolve() for pattern in patterns for p in package.glob(pattern)}
    assert all(p.resolve() in covered for p in LIBRARY_DIR.glob("*.yaml"))


def test_library_sets_turn_rates_and_markov_matrix():
    library = load_library("strike")
    assert library.speed_mps == 250.0 and library.chain_probability == 0.3
    modes = library_modes(library)
    names = [m[0] for m in modes]
    assert names[0] == "CV" and len(modes) == 1 + 2 * 2 + 1  # CV, CT +-omega for 4 g and 7 g, CA
    omega_4g = 4.0 * G0 / 250.0
    assert names[1] == f"CT +{math.degrees(omega_4g):.3g} deg/s (4 g)"
    assert modes[1][1].omega == pytest.approx(omega_4g) and modes[2][1].omega == pytest.approx(-omega_4g)
    tau_cv = (3600 - (40 * 15 + 20 * 8 + 10 * 10)) / 70
    assert library.straight_sojourn_s == pytest.approx(tau_cv)
    Pi = library_transition(library, 1.0)
    np.testing.assert_allclose(Pi.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.diag(Pi), [1 - 1 / tau_cv, 1 - 1 / 15, 1 - 1 / 15, 1 - 1 / 8, 1 - 1 / 8, 1 - 1 / 10])
    # CV leaves by frequency: a 4 g turn direction (20/h) twice as often as a 7 g one (10/h)
    assert Pi[0, 1] == pytest.approx(2 * Pi[0, 3]) and Pi[0, 1] == pytest.approx(Pi[0, 2])
    # a manoeuvre ends in CV with 1 - chain, chains into another manoeuvre with chain
    assert Pi[1, 0] == pytest.approx((1 / 15) * 0.7) and Pi[1, 2:].sum() == pytest.approx((1 / 15) * 0.3)
    transport = library_transition(load_library("transport"), 2.0)
    assert transport[1, 2] == 0.0 and transport[1, 0] == pytest.approx(2 / 40)  # no chaining
    imm = library_imm(library, 1.0)
    assert imm.n_modes == 6 and imm.state_dim == 9


@pytest.mark.parametrize("values, message", [
    ({"speed_mps": 200, "maneuvers": [{"type": "turn", "load_g": 2, "duration_s": 10, "per_hour": 5}], "colour": 1},
     "unknown key(s) ['colour']"),
    ({"maneuvers": [{"type": "turn", "load_g": 2, "duration_s": 10, "per_hour": 5}]}, "speed_mps is required"),
    ({"speed_mps": 200, "maneuvers": [{"type": "loop", "load_g": 2, "duration_s": 10, "per_hour": 5}]}, "maneuver type"),
    ({"speed_mps": 200, "maneuvers": [{"type": "turn", "load_g": 2, "duration_s": 10}]}, "missing ['per_hour']"),
    ({"speed_mps": 200, "maneuvers": [{"type": "turn", "load_g": -2, "duration_s": 10, "per_hour": 5}]}, "load_g must be"),
    ({"speed_mps": 200, "maneuvers": [{"type": "turn", "load_g": 2, "duration_s": 100, "per_hour": 40}]},
     "leaving no straight flight"),
    ({"speed_mps": 200, "chain_probability": 1.0,
      "maneuvers": [{"type": "turn", "load_g": 2, "duration_s": 10, "per_hour": 5}]}, "chain_probability"),
    ({"speed_mps": 200, "maneuvers": []}, "non-empty list"),
])
def test_bad_library_names_the_problem(values, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(").replace(")", r"\)")):
        parse_library(values, "x")


def test_drawn_scenarios_are_seeded_and_follow_the_library():
    library = load_library("transport")
    settings = DrawSettings(duration_s=300.0)
    a = draw_case(library, 1, 9, 3, 1.0, settings=settings)
    b = draw_case(library, 1, 9, 3, 1.0, settings=settings)
    c = draw_case(library, 2, 9, 3, 1.0, settings=settings)
    assert a.label == "transport draw 2" and np.array_equal(a.truth.position, b.truth.position)
    assert not np.array_equal(a.truth.position[: min(a.scans, c.scans)], c.truth.position[: min(a.scans, c.scans)])
    assert a.maneuvers and a.maneuvers[0][0] >= settings.lead_s - 1e-9
    speed = np.linalg.norm(a.truth.velocity, axis=1)
    accel = np.linalg.norm(a.truth.acceleration, axis=1) / G0
    # turns of 1.2 g (x 0.8 .. 1.2) and 0.1 g speed changes at about 200 m/s
    assert accel.max() <= 1.2 * 1.2 + 1e-9 and 150 < speed.min() and speed.max() < 250
    assert np.linalg.norm(a.truth.position, axis=1).min() >= settings.min_range_m
    with pytest.raises(ValueError, match="draw index"):
        draw_case(library, 3, 9, 3, 1.0)


# ---------------------------------------------------------------------------- the study
def test_claims_are_reports_with_the_three_parts(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "tracker-synthesis" and payload["asserts_passed"] is True
    assert set(claims) == {"E10-1-range-rate", "E10-2-model-set-per-class", "E10-3-library-informed-imm"}
    assert {c["kind"] for c in claims.values()} == {"report"} and all(c["verdict"] is None for c in claims.values())
    doppler = claims["E10-1-range-rate"]["measured"]
    assert set(doppler) == {f"default n=5 {label}" for label in ("kf-cv", "kf-ca", "kf-singer")}
    for entry in doppler.values():
        assert entry["with_range_rate"]["madds_per_update"] > entry["position_only"]["madds_per_update"]
        assert entry["reduction_rms_radial_vel_mps"] > 0.5
    sets = claims["E10-2-model-set-per-class"]["measured"]
    assert list(sets) == ["cruise", "turn", "weave", "vertical"]
    for entry in sets.values():
        assert set(entry["sets"]) == {"imm-cv-ca", "imm-cv-ct", "imm-full"}
        assert entry["best_by_rms"] == min(entry["sets"], key=lambda s: entry["sets"][s]["rms_pos_m"])
    assert sets["cruise"]["sets"]["imm-cv-ca"]["maneuver_rms_pos_m"] is None  # NaN: no manoeuvre
    # CT is horizontal: the cv-ct set cannot follow the 3 g pull-up of the vertical scenario
    assert sets["vertical"]["sets"]["imm-cv-ct"]["loss_rate"] == 1.0 and sets["vertical"]["best_by_rms"] != "imm-cv-ct"
    library = claims["E10-3-library-informed-imm"]["measured"]
    assert set(library) == {"libraries", "scenarios from strike", "scenarios from transport"}
    assert library["libraries"]["strike"]["modes"] == 6 and library["libraries"]["transport"]["modes"] == 4
    for source in ("strike", "transport"):
        block = library[f"scenarios from {source}"]
        assert set(block) >= {"imm-library-strike", "imm-library-transport", "imm-cv-ca"}
        expected = 1 - block[f"imm-library-{source}"]["rms_pos_m"] / block["imm-cv-ca"]["rms_pos_m"]
        assert block["informed_vs_generic_rms_reduction"] == pytest.approx(expected)
        assert block["cases"] == [f"{source} draw 1"]


def test_summary_series_and_figures(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    expected = {"kf-cv", "kf-ca", "kf-singer", "kf-cv +rdot", "kf-ca +rdot", "kf-singer +rdot", "imm-cv-ca", "imm-cv-ct",
                "imm-full", "imm-library-strike", "imm-library-transport"}
    assert set(summary["filter"]) == expected
    assert set(summary[summary["filter"].str.endswith("+rdot")]["measurement"]) == {"polar_doppler"}
    assert {"cruise", "weave", "vertical", "default n=5", "strike draw 1", "transport draw 1"} <= set(summary["case"])
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    assert "kf-ca +rdot" in set(series["filter"])
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"tracker_synthesis_range_rate.png", "tracker_synthesis_model_sets.png",
                            "tracker_synthesis_library.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            assert set(ax["labels"]) <= set(ax["legend"])
    assert figures["tracker_synthesis_range_rate.png"]["axes"][0]["labels"] == [
        "kf-cv", "kf-cv +rdot", "kf-ca", "kf-ca +rdot", "kf-singer", "kf-singer +rdot"]
    assert figures["tracker_synthesis_library.png"]["axes"][0]["labels"] == [
        "imm-library-strike", "imm-library-transport", "imm-cv-ca"]


def test_same_seed_same_outputs(tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"study": {"model_sets": ["cv-ca", "cv-ct"], "draws": 1, "scenario_duration_s": 120,
                                                "turn_g": [3], "cruise_s": 40}}))
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "2"), (b, "2"), (c, "3")):
        result = study("--runs", "3", "--seed", seed, "--filters", "kf-ca", "--config", str(config), "--out", str(out))
        assert result.exit_code == 0, result.output
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()


@pytest.mark.parametrize("study_params, message", [
    ({"library": "nowhere"}, "neither a shipped library"),
    ({"library": "transport"}, "library and other_library must differ"),
    ({"colour": 1}, "unknown parameter(s) ['colour']"),
])
def test_bad_configuration_names_itself(tmp_path, study_params, message):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"study": {**study_params, "model_sets": ["cv-ca"], "draws": 1, "turn_g": [3],
                                                "cruise_s": 30, "scenario_duration_s": 100}}))
    result = study("--runs", "2", "--filters", "kf-cv", "--config", str(config), "--out", str(tmp_path / "o"))
    assert result.exit_code == 2 and message in result.output

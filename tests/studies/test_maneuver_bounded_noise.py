"""Spec 004 §6 E9 ``skytrack study bounded-noise`` (§3.3 I, R11, R20 containment, R21, R23, R24)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.linalg import solve_discrete_are
from scipy.stats import chi2

from skytrack.studies.maneuver.bounded_noise import position_sizes, reference_specs, set_specs
from skytrack.studies.maneuver.filters import CATALOG
from skytrack.studies.maneuver.measurements import simulate_measurements
from skytrack.studies.maneuver.outputs import CLAIMS_NAME, FIGURES_NAME, SUMMARY_NAME, TIMESERIES_NAME
from skytrack.studies.maneuver.scenarios import named_cases
from skytrack.studies.maneuver.trajectory import G0
from study_cli import claims_of, invoke_study, study_outputs

SETS = {f"{label} ({noise})" for label in ("sm-trace", "sm-det", "sm-constant") for noise in "ab"}
REFS = {f"{label} ({noise})" for label in ("kf-cv", "pseudo-noise") for noise in "ab"}


def study(*args):
    return invoke_study("bounded-noise", *args)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    return study_outputs(tmp_path_factory, "bounded-noise", "--quick", "--runs", "12", "--check")


def test_containment_assert_and_reports(quick):
    payload, claims = claims_of(quick)
    assert payload["study"] == "bounded-noise" and payload["asserts_passed"] is True and payload["options"]["runs"] == 12
    contained = claims["E9-uniform-containment"]
    assert contained["kind"] == "assert" and contained["verdict"] is True
    # --quick runs n = 5 (inside the 7 g bound) and n = 12; only n = 5 enters the assert, with both criteria
    assert set(contained["measured"]) == {"default n=5 sm-trace (a)", "default n=5 sm-det (a)"}
    for entry in contained["measured"].values():
        assert entry["containment"] == 1.0 and entry["scans_outside"] == 0 and entry["bound_violations"] == 0
        assert entry["scans"] == 12 * (named_cases("default", turn_g=(5.0,))[0].scans - 2)  # every scan from scan 2
    assert {c["kind"] for c in claims.values() if c["id"] != "E9-uniform-containment"} == {"report"}
    gaussian = claims["E9-gaussian-containment"]["measured"]
    # the Gaussian error leaves its 3-sigma ball R_b = 9 R with probability P(chi2_3 > 9) = 0.0293
    expected = chi2.sf(9.0, 3)
    for label, row in gaussian.items():
        samples = 12 * (named_cases("default", turn_g=(float(label.split("=")[1]),))[0].scans - 2)
        assert abs(row["measurements_outside_R_b"] - expected) <= 4 * np.sqrt(expected * (1 - expected) / samples) + 0.01
        assert 0.95 <= row["sm-trace (b)"]["containment"] <= 1.0
    violations = claims["E9-violations-vs-n"]["measured"]
    assert len(violations) == 2 * len(SETS)
    for key, row in violations.items():
        if "(a)" in key and "sm-constant" not in key:  # the box bound holds even at 12 g (about sqrt(6) looser)
            assert row["violation_rate"] == 0.0 and row["containment"] == 1.0
    sizes = claims["E9-set-size-vs-kf"]["measured"]["default n=5 (a)"]
    # the set is larger than the KF's 3-sigma ellipsoid of the quiescent CV filter
    assert sizes["sm-trace (a)"]["pre_onset"]["median_size_m"] > sizes["kf-cv (a)"]["pre_onset"]["median_size_m"]
    criteria = claims["E9-trace-vs-det"]["measured"]["default n=5 (a)"]
    # the det criterion minimises the volume: its position volume radius is the smaller one
    assert criteria["sm-det (a)"]["median_volume_radius_m"] < criteria["sm-trace (a)"]["median_volume_radius_m"]
    assert criteria["sm-det (a)"]["madds_per_update"] > 0 and criteria["sm-trace (a)"]["madds_per_update"] > 0


def test_summary_series_and_figures(quick):
    summary = pd.read_csv(quick / SUMMARY_NAME)
    assert set(summary["filter"]) == SETS | REFS
    assert set(summary["measurement"]) == {"cartesian_uniform", "cartesian"}
    uniform = summary[(summary["filter"].isin({"sm-trace (a)", "sm-det (a)"})) & (summary["basis"] == "all")]
    assert (uniform["containment"] == 1.0).all()
    assert summary[summary["filter"].isin(REFS)]["containment"].isna().all()
    series = pd.read_parquet(quick / TIMESERIES_NAME)
    assert {"rms_pos", "containment"} <= set(series["quantity"])
    figures = {f["file"]: f for f in json.loads((quick / FIGURES_NAME).read_text())}
    assert set(figures) == {"bounded_noise_violations.png", "bounded_noise_size.png"}
    for name, figure in figures.items():
        assert (quick / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for ax in figure["axes"]:
            assert ax["xlabel"] and ax["ylabel"]
            assert len({tuple(c) for c in ax["colours"]}) == len(ax["colours"])
            assert set(ax["labels"]) <= set(ax["legend"])
    order = [f"{label} ({noise})" for noise in "ab" for label in ("sm-trace", "sm-det", "sm-constant")]
    assert [ax["labels"] for ax in figures["bounded_noise_violations.png"]["axes"]] == [order, order]
    size = figures["bounded_noise_size.png"]["axes"][0]["labels"]
    assert size == ["sm-trace (a)", "sm-det (a)", "kf-cv (a): 3 sigma", "pseudo-noise (a): 3 sigma"]


def test_position_sizes_match_the_kalman_steady_state():
    """sqrt(tr P_pos) of KF-CV on a fixed Cartesian R: the same in every run and converging to the DARE value."""
    case = named_cases("default", turn_g=(5.0,))[0]
    meas = simulate_measurements(case, 5, 2, "cartesian", 30.0)
    spec = reference_specs([CATALOG["kf-cv"]])["b"]["kf-cv (b)"]
    sizes, volume = position_sizes(spec, case, meas)
    assert np.isnan(sizes[:2]).all() and np.isfinite(sizes[2:]).all()
    assert np.max(np.abs(sizes[2:] - sizes[2:, :1])) <= 1e-9 * sizes[2:].max()
    T, q = case.dt, 1.0
    F = np.array([[1.0, T], [0.0, 1.0]])
    g = np.array([[T**2 / 2], [T]])
    H = np.array([[1.0, 0.0]])
    P_pred = solve_discrete_are(F.T, H.T, q * g @ g.T, np.array([[900.0]]))
    P_filt = P_pred - P_pred @ H.T @ H @ P_pred / (P_pred[0, 0] + 900.0)
    assert sizes[-1, 0] == pytest.approx(np.sqrt(3 * P_filt[0, 0]), rel=1e-6)
    assert volume[-1, 0] == pytest.approx(np.sqrt(P_filt[0, 0]), rel=1e-6)  # isotropic: det^(1/6) = sigma


def test_specs_of_the_two_noise_cases():
    sets = set_specs(7.0)
    assert sets["a"]["sm-trace (a)"].options["r_bound_scale"] == 1.0 and sets["b"]["sm-det (b)"].options["r_bound_scale"] == 9.0
    assert sets["a"]["sm-constant (a)"].options["process_bound"] == "constant"
    assert sets["b"]["sm-det (b)"].options["a_max"] == pytest.approx(7.0 * G0)
    refs = reference_specs([CATALOG["kf-cv"]])
    assert refs["a"]["kf-cv (a)"].r_scale == pytest.approx(0.2) and refs["b"]["kf-cv (b)"].r_scale == 1.0


def test_same_seed_same_outputs(tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [7]}))
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "3"), (b, "3"), (c, "4")):
        assert study("--runs", "3", "--seed", seed, "--config", str(config), "--out", str(out)).exit_code == 0
    for name in (SUMMARY_NAME, CLAIMS_NAME, FIGURES_NAME):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / SUMMARY_NAME).read_bytes() != (c / SUMMARY_NAME).read_bytes()


def test_assert_fails_without_a_turn_inside_the_bound(tmp_path):
    config = tmp_path / "above.yaml"
    config.write_text(yaml.safe_dump({"turn_g": [9]}))
    result = study("--runs", "2", "--config", str(config), "--out", str(tmp_path / "x"), "--check")
    assert result.exit_code == 1
    _, claims = claims_of(tmp_path / "x")
    assert claims["E9-uniform-containment"]["verdict"] is False
    assert "no case with a turn" in claims["E9-uniform-containment"]["measured"]["note"]


def test_bad_parameter_names_itself(tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"study": {"a_max": 7}}))
    result = study("--config", str(config), "--out", str(tmp_path))
    assert result.exit_code == 2 and "unknown parameter(s) ['a_max']" in result.output

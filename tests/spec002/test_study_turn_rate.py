"""Spec 002 §6 E3/E4 ``skytrack study turn-rate-adaptive`` (R11-R14 in a tracking scenario).

Monte Carlo size: the spec's tolerances (ω-RMSE within ×1.5 of the prototype, divergence within ±15
points) are for ≥ 100 runs; these tests use N = 30 runs.  The half-width 0.5 of the RMSE factor is
scaled by the standard-error ratio √(100/N) = 1.83, i.e. a factor 1 + 0.5·√(100/N) = 1.91, and the
divergence band ±15 points likewise to ±27 points.  The entries checked are ones whose deterministic
turn transients dominate or whose 100-run values lie well inside ×1.5 (see the study's report).
"""

import json
import math

import numpy as np
import pandas as pd
import pytest
import typer
from typer.testing import CliRunner

from skytrack.cli.study_turn_rate import register_turn_rate_studies
from skytrack.studies.fuzzy.common import Check
from skytrack.studies.turn_rate import study as turn_rate_study
from skytrack.studies.turn_rate import scenario as sc
from skytrack.studies.turn_rate.figures import PANEL_TITLES, draw_setup
from skytrack.studies.turn_rate.metrics import expected_checks, summarize
from skytrack.studies.turn_rate.simulation import build_filter_for, run_configuration, run_imm, simulate_setup
from skytrack.studies.turn_rate.study import run_summaries

plt = pytest.importorskip("matplotlib.pyplot")

RUNS = 30
SEED = 7
RMSE_TOLERANCE = 1.0 + 0.5 * math.sqrt(100 / RUNS)
DIVERGENCE_TOLERANCE = 15.0 * math.sqrt(100 / RUNS)
CONFIG = {c.key: c for c in sc.CONFIGURATIONS}


@pytest.fixture(scope="module")
def doppler_t4():
    """All five configurations, T = 4 s, pos+ṙ, q_a = 1 (E3)."""
    return {s.key: s for s in run_summaries(RUNS, SEED, (4.0,), ("pos+rdot",), imm=False)}


@pytest.fixture(scope="module")
def doppler_t1():
    configs = [CONFIG[k] for k in ("fixed-0.1", "fixed-0.5", "adaptive-0.8")]
    return {s.key: s for s in run_summaries(RUNS, SEED, (1.0,), ("pos+rdot",), imm=False, configurations=configs)}


def test_truth_follows_the_schedule_with_the_rate_at_the_start_of_each_step():
    times, truth = sc.simulate_truth(4.0)
    assert times[-1] == 272.0 and len(times) == 69
    # row k carries the rate of the step t_{k-1} -> t_k, i.e. ω(t_{k-1})
    np.testing.assert_allclose(truth[1:, 4], sc.turn_rate(times[:-1]), atol=0)
    np.testing.assert_allclose(np.hypot(truth[:, 2], truth[:, 3]), 200.0, rtol=1e-12)
    heading = np.degrees(np.arctan2(truth[:, 3], truth[:, 2]))
    # turn 1: +3°/s over 32 s = 96°; turn 2: −1.5°/s over 60 s = −90°
    assert heading[list(times).index(92.0)] == pytest.approx(96.0, abs=1e-9)
    assert heading[-1] == pytest.approx(6.0, abs=1e-9)
    _, shifted = sc.simulate_truth(4.0, rate_at="end")
    np.testing.assert_allclose(shifted[:, 4], sc.turn_rate(times), atol=0)


def test_fixed_configuration_pins_the_disturbance_variance():
    times, truth, y, v0 = simulate_setup(4.0, "pos+rdot", 5, SEED)
    filt = build_filter_for(CONFIG["fixed-0.5"], "pos+rdot")
    state = filt.initial_state(np.c_[y[0, :, :2], v0, np.zeros(5)], sc.INITIAL_COVARIANCE, V_w0=[[sc.PRESET_V_W0]])
    for k in range(1, 20):
        record = filt.step(state, y[k], 4.0, sc.measurement_noise("pos+rdot"))
        np.testing.assert_allclose(record.V_w[:, 0, 0], (0.5 * sc.DEG) ** 2, rtol=1e-12)


@pytest.mark.parametrize("key, windows", [("fixed-0.1", (0, 1, 3)), ("fixed-0.5", (0, 1, 2, 3, 4)),
                                          ("adaptive-0.8", (0, 1, 2, 3, 4)), ("adaptive-0.95", (0, 1, 2, 3)),
                                          ("literal", (0, 1, 2, 3))])
def test_doppler_t4_omega_rmse_matches_the_prototype(doppler_t4, key, windows):
    measured = doppler_t4[key].omega_rmse
    prototype = np.asarray(sc.PROTOTYPE_OMEGA_RMSE[(4.0, "pos+rdot")][key])
    ratio = measured[list(windows)] / prototype[list(windows)]
    assert np.all((ratio <= RMSE_TOLERANCE) & (ratio >= 1 / RMSE_TOLERANCE)), (key, ratio)


@pytest.mark.parametrize("key", ["fixed-0.1", "fixed-0.5", "adaptive-0.8"])
def test_doppler_t1_omega_rmse_matches_the_prototype(doppler_t1, key):
    ratio = doppler_t1[key].omega_rmse / np.asarray(sc.PROTOTYPE_OMEGA_RMSE[(1.0, "pos+rdot")][key])
    assert np.all((ratio <= RMSE_TOLERANCE) & (ratio >= 1 / RMSE_TOLERANCE)), (key, ratio)


def test_doppler_adaptive_beats_the_best_fixed_on_every_straight_leg(doppler_t1, doppler_t4):
    for group in (doppler_t1, doppler_t4):
        best_fixed = np.minimum(group["fixed-0.1"].omega_rmse, group["fixed-0.5"].omega_rmse)
        straight = list(sc.STRAIGHT_WINDOWS)
        assert np.all(group["adaptive-0.8"].omega_rmse[straight] < best_fixed[straight])
        assert all(s.diverged == 0 for s in group.values())


def test_expected_checks_hold_for_the_doppler_t4_setup(doppler_t4):
    checks = {c.name: c for c in expected_checks(list(doppler_t4.values()))}
    beats = [c for name, c in checks.items() if "every straight leg" in name]
    literal = [c for name, c in checks.items() if "never the best" in name]
    zero = [c for name, c in checks.items() if "divergence" in name]
    assert len(beats) == len(literal) == len(zero) == 1
    assert beats[0].passed and literal[0].passed and zero[0].passed and zero[0].expected == "0 % everywhere"


def test_e4_literal_with_doppler_at_t4_diverges_without_q_dep_and_never_with_it():
    times, truth, y, v0 = simulate_setup(4.0, "pos+rdot", RUNS, SEED)
    without = run_configuration(CONFIG["literal"], 4.0, "pos+rdot", times, truth, y, v0, q_accel=0.0)
    with_q = run_configuration(CONFIG["literal"], 4.0, "pos+rdot", times, truth, y, v0, q_accel=1.0)
    prototype = sc.PROTOTYPE_DIVERGENCE_NO_QDEP[(4.0, "pos+rdot")]["literal"]  # 96 %
    assert abs(100 * without.diverged.mean() - prototype) <= DIVERGENCE_TOLERANCE
    assert without.diverged.mean() > 0.5
    assert with_q.diverged.sum() == 0
    summary = summarize(without, 4.0, "pos+rdot", 0.0)
    assert summary.diverged_pct == pytest.approx(100 * without.diverged.mean())


def test_imm_on_positions_tracks_within_the_spec_position_range():
    times, truth, y, v0 = simulate_setup(4.0, "pos", RUNS, SEED)
    runset = run_imm(4.0, times, truth, y, v0)
    summary = summarize(runset, 4.0, "pos", 1.0)
    assert runset.diverged.sum() == 0
    # the spec's position range 9.7-54 m of the adaptive configurations holds for the IMM too
    assert np.all((summary.position_rmse > 9.7) & (summary.position_rmse < 54.0))
    assert np.all(np.abs(runset.omega_hat) <= 3.0 * sc.DEG + 1e-12)  # Σ μ_j ω_j with ω_j ∈ {0, ±3°/s}


def test_figure_draws_the_truth_the_floor_and_the_rmse_curves(doppler_t4):
    summaries = list(doppler_t4.values())
    fig = draw_setup(summaries, 4.0, "pos+rdot", 1.0)
    try:
        axes = {ax.get_title(): ax for ax in fig.axes}
        assert set(PANEL_TITLES) <= set(axes)
        omega_ax = axes[PANEL_TITLES[0]]
        truth_line = next(line for line in omega_ax.get_lines() if line.get_label() == "truth")
        times, truth = sc.simulate_truth(4.0)
        np.testing.assert_allclose(truth_line.get_xdata(), times)
        np.testing.assert_allclose(truth_line.get_ydata(), truth[:, 4] / sc.DEG)
        sigma_ax = axes[PANEL_TITLES[1]]
        floor = next(line for line in sigma_ax.get_lines() if line.get_label() == "floor σ_min")
        assert floor.get_ydata()[0] == pytest.approx(sc.PRESET_SIGMA_MIN / sc.DEG)
        fixed = next(line for line in sigma_ax.get_lines() if line.get_label() == "fixed 0.5")
        np.testing.assert_allclose(fixed.get_ydata()[1:], 0.5, rtol=1e-9)
        rmse_ax = axes[PANEL_TITLES[2]]
        adaptive = next(line for line in rmse_ax.get_lines() if line.get_label() == "adaptive 0.8")
        np.testing.assert_allclose(adaptive.get_ydata(), doppler_t4["adaptive-0.8"].curves["omega_rmse_t"])
        for ax, unit in zip((omega_ax, sigma_ax, rmse_ax, axes[PANEL_TITLES[3]]), ("°/s", "°/s", "°/s", "[m]")):
            assert unit in ax.get_ylabel()
            assert ax.get_legend() is not None
    finally:
        plt.close(fig)


def study_app() -> typer.Typer:
    app = typer.Typer()
    register_turn_rate_studies(app)

    @app.callback()
    def main():  # a callback keeps "turn-rate-adaptive" a sub-command (typer runs a lone command directly)
        pass

    return app


SHORT_RUN = ["turn-rate-adaptive", "--runs", "8", "--T", "4", "--meas", "pos+rdot", "--no-imm"]


def test_command_writes_tables_figures_and_summary(tmp_path):
    app = study_app()
    runner = CliRunner()
    result = runner.invoke(app, [*SHORT_RUN, "--out", str(tmp_path)], terminal_width=200)
    assert result.exit_code == 0, result.output
    assert "ω-RMSE" in result.output and "PASS" in result.output
    assert "position RMSE [m]" in result.output  # the unit is printed, not read as rich markup
    summary = json.loads((tmp_path / "turn_rate_adaptive.json").read_text())
    assert summary["runs"] == 8 and len(summary["results"]) == 5
    table = pd.read_csv(tmp_path / "turn_rate_adaptive.csv")
    assert len(table) == 25 and set(table["verdict"]) <= {"ok", "off"}
    assert (tmp_path / "turn_rate_T4_pos_rdot_qa1.png").stat().st_size > 10_000


@pytest.mark.parametrize("option, value, message", [("--meas", "sonar", "unknown sonar"), ("--T", "0", "positive"),
                                                     ("--T", "4,x", "comma-separated"), ("--runs", "0", ">= 1"),
                                                     ("--q-dep", "-1", ">= 0"), ("--truth-rate", "middle", "one of"),
                                                     ("--seed", "-1", "non-negative")])
def test_command_rejects_bad_options_with_exit_2(tmp_path, option, value, message):
    result = CliRunner().invoke(study_app(), ["turn-rate-adaptive", option, value, "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert message in result.output
    assert not any(tmp_path.iterdir())  # nothing ran


def test_check_exits_1_when_an_expected_behaviour_fails(tmp_path, monkeypatch):
    monkeypatch.setattr(turn_rate_study, "expected_checks", lambda summaries: [Check("forced", "1", "2", False)])
    app = study_app()
    result = CliRunner().invoke(app, [*SHORT_RUN, "--out", str(tmp_path), "--check"], terminal_width=200)
    assert result.exit_code == 1 and "FAIL" in result.output and "1 expected behaviour(s) failed" in result.output
    assert CliRunner().invoke(app, [*SHORT_RUN, "--out", str(tmp_path)]).exit_code == 0


def test_median_sigma_w_sits_at_the_floor_on_straight_legs_and_jumps_in_turn_1(doppler_t1):
    checks = {c.name: c for c in expected_checks(list(doppler_t1.values()))}
    floor = next(c for name, c in checks.items() if "at the floor on the straight legs" in name)
    turn1 = next(c for name, c in checks.items() if "first 7 s of turn 1" in name)
    assert floor.passed and turn1.passed, (floor.measured, turn1.measured)
    curves = doppler_t1["adaptive-0.8"].curves
    straight = (curves["times"] >= 20) & (curves["times"] < 60)
    np.testing.assert_allclose(curves["median_sigma_w_t"][straight], sc.PRESET_SIGMA_MIN / sc.DEG, rtol=1e-9)

"""Spec 001 §6 studies E1-E4 (``skytrack study ident-potential / ident-np-design / ident-elliptic``).

Each study runs small (Monte Carlo checks are within 4 standard errors of the run's own size, so
they hold for any --trials); the tests check what the figures draw (line data, styles, labels),
the CSV and the JSON summary against TV-1 and the §6 expectations, and the commands' exit codes
(0, 1 under --check when an expected value fails, 2 for a bad option)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.studies.identification import elliptic, np_design, potential_study
from skytrack.studies.identification.common import pyplot

runner = CliRunner()
TRIALS = 20_000


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


# --- E1 / E2 ----------------------------------------------------------------------------------

@pytest.fixture(scope="module", params=[2, 3])
def potential_run(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(f"potential{request.param}")
    return request.param, potential_study.run_potential(out, request.param, trials=TRIALS, seed=3)


def test_e1_e2_all_checks_pass_and_the_summary_holds_tv1(potential_run):
    dim, result = potential_run
    assert all(c.passed for c in result["checks"]), [c for c in result["checks"] if not c.passed]
    summary = json.loads(result["paths"]["json"].read_text())
    assert summary["study"] == "ident-potential" and summary["passed"] is True
    assert summary["options"]["dim"] == dim and summary["options"]["trials"] == TRIALS
    expected_p2 = {2: 0.8646647168, 3: 0.7385358701}[dim]
    assert abs(summary["results"]["p_correct_at_r"]["2"] - expected_p2) <= 1e-9
    assert abs(summary["results"]["p_incorrect_mean_at_r2"] - {2: 0.1737679657, 3: 0.1335843625}[dim]) <= 1e-8
    assert abs(summary["results"]["p_incorrect_at_r"]["A=3"]["2"] - {2: 1.132792e-1, 3: 7.799855e-2}[dim]) <= 1e-7
    designs = summary["results"]["np_design_A4_alpha0.05"]
    assert abs(designs["2d"]["p_correct"] - 0.95760907) <= 1e-7
    if dim == 3:
        assert abs(designs["3d"]["p_correct"] - 0.93125021) <= 1e-7  # E2: 0.9313 vs 0.9576
        assert any(c["name"].startswith("E2: 3-D below 2-D") and c["passed"] for c in summary["checks"])
    mc = pd.read_csv(result["paths"]["mc_csv"])
    assert (mc["trials"] == TRIALS).all() and (mc["z"].abs() <= 4).all()
    assert len(mc) == 7  # same, A = 1..5, uniform A


def test_e1_e2_figure_draws_the_curves_and_the_roc(potential_run):
    dim, result = potential_run
    curves = result["curves"]
    fig = potential_study.plot_potential(curves, dim, potential_study.A_VALUES, (1.0, 6.0))
    try:
        ax_r, ax_roc = fig.axes
        lines = ax_r.get_lines()
        assert [line.get_linestyle() for line in lines] == ["-"] + ["--"] * 5 + [":"]
        assert [line.get_label() for line in lines][:2] == ["P_ПО", "P_НО, A = 1"]
        r = lines[0].get_xdata()
        assert r[0] == 0.0 and r[-1] == 6.0
        np.testing.assert_allclose(lines[0].get_ydata(), stats.chi2.cdf(r ** 2, dim), atol=1e-12)
        at2 = np.flatnonzero(np.isclose(r, 2.0))[0]
        tv1 = {2: [7.309879e-1, 3.964990e-1, 1.132792e-1, 1.472346e-2, 8.007296e-4],
               3: [6.024560e-1, 3.005641e-1, 7.799855e-2, 9.252391e-3, 4.635283e-4]}[dim]
        np.testing.assert_allclose([line.get_ydata()[at2] for line in lines[1:6]], tv1, rtol=1e-6)
        assert abs(lines[6].get_ydata()[at2] - {2: 0.1737679657, 3: 0.1335843625}[dim]) <= 1e-8
        # P_НО(A) falls with A at every r, and stays below P_ПО
        stack = np.array([line.get_ydata() for line in lines[:6]])
        assert np.all(np.diff(stack, axis=0) <= 1e-15)
        # the ROC panel: x = P_НО(A), y = P_ПО, parametric in r
        roc = ax_roc.get_lines()
        np.testing.assert_array_equal(roc[2].get_xdata(), lines[3].get_ydata())
        np.testing.assert_array_equal(roc[2].get_ydata(), lines[0].get_ydata())
        assert roc[-1].get_label().startswith("chance")
        for ax in fig.axes:
            assert "[" in ax.get_xlabel() and "[" in ax.get_ylabel() and ax.get_title()
            assert ax.get_legend() is not None
    finally:
        pyplot().close(fig)
    assert result["paths"]["png"].stat().st_size > 20_000


# --- E3 ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def np_run(tmp_path_factory):
    return np_design.run_np_design(tmp_path_factory.mktemp("np"), 2, trials=TRIALS, seed=4, alpha_points=9)


def test_e3_checks_and_summary(np_run):
    assert all(c.passed for c in np_run["checks"]), [c for c in np_run["checks"] if not c.passed]
    summary = json.loads(np_run["paths"]["json"].read_text())
    assert summary["study"] == "ident-np-design" and summary["passed"] is True
    assert abs(summary["results"]["A=3,alpha=0.01"]["p_correct"] - 0.37768399) <= 1e-7  # §6 E3: 0.378
    np.testing.assert_allclose([summary["results"]["p_correct_at_alpha_0.05"][f"A={a}"] for a in range(2, 7)],
                               [0.275881, 0.717462, 0.957609, 0.997619, 0.999950], atol=1e-6)
    assert abs(summary["results"]["mean,alpha=0.05"]["p_correct"] - 0.44797073) <= 1e-7
    assert 2.0 < summary["results"]["equivalent_offset_alpha_0.05"] < 3.5  # dominated by small separations
    written = pd.read_csv(np_run["paths"]["csv"])
    assert set(written["curve"]) == {"A=2", "A=3", "A=4", "A=5", "A=6", "mean"}
    assert written["alpha"].min() == pytest.approx(1e-4) and written["alpha"].max() == pytest.approx(0.2)


def test_e3_figure_draws_p_correct_against_alpha(np_run):
    table = np_run["table"]
    fig = np_design.plot_np_design(table, 2, (1.0, 6.0))
    try:
        ax_p, ax_r = fig.axes
        lines = [line for line in ax_p.get_lines() if not line.get_label().startswith("_")]  # not the marked point
        assert [line.get_label() for line in lines] == [f"A = {a}" for a in range(2, 7)] + \
            ["uniform Δ ∈ [100, 600] m, σ = 100 m"]
        assert lines[-1].get_linestyle() == ":"
        for line in lines:
            assert np.all(np.diff(line.get_ydata()) > 0)  # monotone trade-off
        a4 = lines[2]
        at = np.flatnonzero(np.isclose(a4.get_xdata(), 0.05))[0]
        assert a4.get_ydata()[at] == pytest.approx(0.95760907, abs=1e-7)
        a3 = lines[1]
        at = np.flatnonzero(np.isclose(a3.get_xdata(), 0.01))[0]
        assert a3.get_ydata()[at] == pytest.approx(0.37768399, abs=1e-7)
        # the averaged design lies between the A = 2 and A = 3 curves at every alpha
        assert np.all(lines[0].get_ydata() < lines[-1].get_ydata()) and np.all(lines[-1].get_ydata() < a3.get_ydata())
        assert ax_p.get_xscale() == "log" and "[" in ax_p.get_xlabel() and "[" in ax_r.get_ylabel()
        np.testing.assert_allclose(ax_r.get_lines()[2].get_ydata()[np.isclose(a4.get_xdata(), 0.05)], 2.51428748,
                                   atol=1e-7)
        assert [t.get_text() for t in fig.legends[0].get_texts()] == [line.get_label() for line in lines]
    finally:
        pyplot().close(fig)


# --- E4 ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def elliptic_run(tmp_path_factory):
    return elliptic.run_elliptic(tmp_path_factory.mktemp("elliptic"), trials=TRIALS, seed=5)


def test_e4_exact_values_and_checks(elliptic_run):
    assert all(c.passed for c in elliptic_run["checks"]), [c for c in elliptic_run["checks"] if not c.passed]
    # quadrature of the distance law (independently: the spec's Monte Carlo values within 4 of its SEs)
    assert elliptic.distance_probability(0.0, 0.0) == pytest.approx(0.9518415, abs=1e-6)
    assert elliptic.distance_probability(0.0, 300.0) == pytest.approx(1.5756e-4, abs=1e-8)
    summary = json.loads(elliptic_run["paths"]["json"].read_text())
    results = summary["results"]
    assert summary["passed"] is True and summary["options"]["trials"] == TRIALS
    assert results["p_correct_0m_x"]["exact"] >= results["p_correct_0m_x"]["circular"]  # the bound holds for P_ПО
    assert results["p_incorrect_150m_y"]["exact"] > results["p_incorrect_150m_y"]["circular"]  # ... not for P_НО
    assert results["p_incorrect_300m_y"]["exact"] < results["p_incorrect_300m_y"]["circular"]
    assert results["p_incorrect_150m_x"]["circular"] == pytest.approx(0.5763207, abs=1e-6)


def test_e4_figure_draws_truth_circular_and_the_normalised_statistic(elliptic_run):
    table = elliptic_run["table"]
    fig = elliptic.plot_elliptic(table)
    try:
        ax_d, ax_n = fig.axes
        lines = {line.get_label(): line for line in ax_d.get_lines()}
        truth_x, truth_y = lines["truth, separation along x"], lines["truth, separation along y"]
        circular = lines["circular formula, σ = σ_x = 100 m"]
        assert circular.get_linestyle() == "--"
        x = truth_x.get_xdata()
        at = {d: np.flatnonzero(np.isclose(x, d))[0] for d in (0.0, 150.0, 300.0)}
        assert truth_x.get_ydata()[at[0.0]] == pytest.approx(0.951841, abs=1e-6)
        assert truth_x.get_ydata()[at[150.0]] == pytest.approx(0.683011, abs=1e-6)
        assert truth_y.get_ydata()[at[150.0]] == pytest.approx(0.740961, abs=1e-6)
        assert truth_x.get_ydata()[at[300.0]] == pytest.approx(0.153308, abs=1e-6)
        assert circular.get_ydata()[at[0.0]] == pytest.approx(0.864665, abs=1e-6)
        assert circular.get_ydata()[at[300.0]] == pytest.approx(0.113279, abs=1e-6)
        markers = lines["Monte Carlo, along x"]
        assert markers.get_linestyle() == "None" and markers.get_marker() == "o"
        assert np.all(np.abs(markers.get_ydata() - np.interp(markers.get_xdata(), x, truth_x.get_ydata()))
                      <= 4.5 * np.sqrt(0.25 / TRIALS))
        normalised = [line for line in ax_n.get_lines() if line.get_label().startswith("ncχ²₂")]
        d = normalised[1].get_xdata()
        np.testing.assert_allclose(normalised[1].get_ydata()[1:], stats.ncx2.cdf(4.0, 2, (d[1:] / 30.0) ** 2), rtol=1e-12)
        for ax in (ax_d, ax_n):
            assert "[m]" in ax.get_xlabel() and "[–]" in ax.get_ylabel() and ax.get_title() and ax.get_legend()
    finally:
        pyplot().close(fig)


# --- the commands -----------------------------------------------------------------------------

def test_study_commands_pass_their_checks(tmp_path):
    result = invoke("study", "ident-potential", "--dim", 3, "--trials", TRIALS, "--out", tmp_path / "e2", "--check")
    assert result.exit_code == 0, result.output
    assert "0.9313" in result.output and "0.9576" in result.output
    result = invoke("study", "ident-np-design", "--alpha-points", 5, "--trials", TRIALS, "--out", tmp_path / "e3",
                    "--check")
    assert result.exit_code == 0, result.output
    assert "0.37768399" in result.output and (tmp_path / "e3" / "ident_np_design_2d_summary.json").exists()
    result = invoke("study", "ident-elliptic", "--trials", TRIALS, "--out", tmp_path / "e4", "--check")
    assert result.exit_code == 0, result.output
    assert "0.951841" in result.output and "0.576321" in result.output
    assert {p.name for p in (tmp_path / "e4").iterdir()} == {"ident_elliptic.csv", "ident_elliptic.png",
                                                             "ident_elliptic_summary.json"}


def test_check_exits_1_when_an_expected_value_fails(tmp_path, monkeypatch):
    monkeypatch.setitem(potential_study.NP_P_CORRECT, 2, 0.9)
    result = invoke("study", "ident-potential", "--dim", 2, "--trials", 1000, "--out", tmp_path, "--check")
    assert result.exit_code == 1
    assert "FAIL" in result.output
    assert json.loads((tmp_path / "ident_potential_2d_summary.json").read_text())["passed"] is False
    assert invoke("study", "ident-potential", "--dim", 2, "--trials", 1000, "--out", tmp_path).exit_code == 0


@pytest.mark.parametrize("args", [["ident-potential", "--dim", "4"], ["ident-potential", "--trials", "0"],
                                  ["ident-np-design", "--alpha-points", "1"], ["ident-elliptic", "--trials", "-5"]])
def test_bad_study_options_exit_2(args, tmp_path):
    result = runner.invoke(app, ["study", *args, "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert sum(line.startswith("error:") for line in result.output.splitlines()) == 1

"""Spec 003 §6 studies E1-E3 (``skytrack study fuzzy-fig2 / fuzzy-regions / fuzzy-gate``, R20):
E1 peaks and the pointwise identity (D2), E2 boundaries equal to TV9's in the CSV, E3 Monte
Carlo within 4 SE of F_chi2_4(gamma + 2 ln Pi) (TV11, D5), what each figure draws, and the CLI
commands with --check."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.core.chi2 import chi2_cdf
from skytrack.studies.fuzzy import fig2, gate, regions
from skytrack.studies.fuzzy.common import pyplot

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


# --- E1 ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def e1(tmp_path_factory):
    out = tmp_path_factory.mktemp("e1")
    return out, fig2.run_fig2(out)


def test_e1_peaks_of_the_density_and_the_membership(e1):
    out, table = e1
    written = pd.read_csv(out / fig2.CSV_NAME)
    for frame in (table, written):
        peaks = dict(zip(frame["sigma"], frame["peak_p"]))
        for sigma, expected in {0.5: 0.797885, 1.0: 0.398942, 2.0: 0.199471}.items():
            assert abs(peaks[sigma] - expected) < 5e-7  # the spec's six decimals
            assert peaks[sigma] == pytest.approx(1.0 / (sigma * math.sqrt(2 * math.pi)), rel=1e-9)
        assert (frame["peak_mu"] == 1.0).all()


def test_e1_membership_is_density_times_sigma_sqrt_2pi_pointwise(e1):
    out, _ = e1
    curves = pd.read_csv(out / fig2.CURVES_CSV_NAME)
    assert set(curves["sigma"]) == {0.5, 1.0, 2.0}
    assert curves["z"].min() == -6.0 and curves["z"].max() == 6.0
    scaled = curves["p"] * curves["sigma"] * math.sqrt(2 * math.pi)
    assert np.allclose(curves["mu"], scaled, rtol=1e-9, atol=0.0)
    # and the membership is the unit-peak Gaussian itself (the CSV holds 12 digits; in memory to 1e-12)
    assert np.allclose(curves["mu"], np.exp(-curves["z"] ** 2 / (2 * curves["sigma"] ** 2)), rtol=1e-9, atol=0.0)
    exact = fig2.fig2_curves()
    assert np.allclose(exact["mu"], np.exp(-exact["z"] ** 2 / (2 * exact["sigma"] ** 2)), rtol=1e-12, atol=0.0)
    assert np.allclose(exact["mu"], exact["p"] * exact["sigma"] * math.sqrt(2 * math.pi), rtol=1e-12, atol=0.0)
    assert all(c.passed for c in fig2.check_fig2(fig2.fig2_table(exact)))


def test_e1_figure_draws_one_labelled_line_per_sigma_in_each_panel():
    fig = fig2.plot_fig2(fig2.fig2_curves())
    try:
        ax_p, ax_mu = fig.axes
        for ax in (ax_p, ax_mu):
            assert [t.get_text() for t in ax.get_legend().get_texts()] == ["σ = 0.5", "σ = 1", "σ = 2"]
            assert len(ax.get_lines()) == 3
            assert ax.get_xlabel() and "[" in ax.get_xlabel() and "[" in ax.get_ylabel() and ax.get_title()
            assert len({tuple(line.get_color()) if not isinstance(line.get_color(), str) else line.get_color()
                        for line in ax.get_lines()}) == 3
        assert max(line.get_ydata().max() for line in ax_mu.get_lines()) == 1.0
        assert [round(line.get_ydata().max(), 6) for line in ax_p.get_lines()] == [0.797885, 0.398942, 0.199471]
        assert {t.get_text() for t in ax_p.texts} == {"peak 0.797885", "peak 0.398942", "peak 0.199471"}
    finally:
        pyplot().close(fig)


# --- E2 ---------------------------------------------------------------------------------------

TV9 = {
    "ml": [("new", "B", -246.558), ("B", "A", -182.186), ("A", "B", 155.826), ("B", "new", 846.558)],
    "fuzzy": [("new", "B", -246.558), ("B", "A", -150.0), ("A", "B", 75.0), ("B", "new", 846.558)],
    "fuzzy-features": [("new", "B", -232.863), ("B", "new", 832.863)],
}


@pytest.fixture(scope="module")
def e2(tmp_path_factory):
    out = tmp_path_factory.mktemp("e2")
    return out, regions.run_regions(out)


def test_e2_boundaries_in_the_csv_equal_tv9(e2):
    out, _ = e2
    written = pd.read_csv(out / regions.CSV_NAME)
    for band, expected in TV9.items():
        rows = written[written["band"] == band].sort_values("x_m")
        assert list(zip(rows["left"], rows["right"])) == [(a, b) for a, b, _ in expected]
        assert np.all(np.abs(rows["x_m"].to_numpy() - [x for _, _, x in expected]) < 1e-3)
        # against the closed forms, to the bisection's 1e-6 m
        assert np.all(np.abs(rows["x_m"] - rows["closed_form_m"]) < 2e-6)


def test_e2_closed_forms():
    gamma = 13.276704135987622
    closed = regions.closed_form_boundaries()
    assert closed["ml"][1] == pytest.approx(-50 * math.sqrt(gamma), rel=1e-12)
    assert closed["ml"][0] == pytest.approx(300 - 150 * math.sqrt(gamma), rel=1e-12)
    x = closed["ml"][2]  # positive root of (x/50)^2 - ((x - 300)/150)^2 = 8 ln 3
    assert (x / 50) ** 2 - ((x - 300) / 150) ** 2 == pytest.approx(8 * math.log(3), rel=1e-12)
    assert closed["fuzzy"][1:3] == pytest.approx([-150.0, 75.0], rel=1e-12)
    assert closed["fuzzy-features"][1] == pytest.approx(300 + 150 * math.sqrt(gamma + 2 * math.log(0.72)), rel=1e-12)


def test_e2_figure_draws_three_bands_coloured_by_choice_with_annotated_boundaries(e2):
    _, table = e2
    fig = regions.plot_regions(table)
    try:
        ax = fig.axes[0]
        assert [t.get_text() for t in ax.get_yticklabels()] == ["fuzzy, with features", "fuzzy, no features", "ml"]
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert len(legend) == 3 and legend[0].startswith("track A") and legend[1].startswith("track B")
        assert legend[2] == "new object"
        bars = ax.patches
        assert len(bars) == 5 + 5 + 3  # segments: ml, fuzzy without features, fuzzy with features
        colours = {tuple(np.round(bar.get_facecolor(), 6)) for bar in bars}
        assert len(colours) == 3
        # band "fuzzy, with features" (y = 0) never shows track A's colour
        colour_a = tuple(np.round(ax.get_legend().legend_handles[0].get_facecolor(), 6))
        features_band = [bar for bar in bars if abs(bar.get_y() + bar.get_height() / 2) < 1e-9]
        assert len(features_band) == 3 and all(tuple(np.round(b.get_facecolor(), 6)) != colour_a for b in features_band)
        annotations = {t.get_text() for t in ax.texts}
        assert {f"{x:.3f}" for rows in TV9.values() for _, _, x in rows} == annotations
        assert "[m]" in ax.get_xlabel() and ax.get_title()
    finally:
        pyplot().close(fig)


# --- E3 ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def e3(tmp_path_factory):
    out = tmp_path_factory.mktemp("e3")
    calls = []
    table = gate.run_gate(out, seed=1, progress=lambda done, total: calls.append((done, total)))
    return out, table, calls


def test_e3_monte_carlo_within_4_se_of_the_curve(e3):
    out, table, calls = e3
    written = pd.read_csv(out / gate.CSV_NAME)
    assert len(written) == 3 * 7 and set(written["p_gate"]) == {0.95, 0.99, 0.999}
    assert (written["samples"] == 400_000).all()
    for row in written.itertuples(index=False):
        curve = chi2_cdf(row.gamma + 2 * math.log(row.product), 4)
        se = math.sqrt(curve * (1 - curve) / row.samples)
        assert row.probability == pytest.approx(curve, rel=1e-9)
        assert abs(row.mc_kept - curve) < 4 * se
    assert calls == [(c, gate.CHUNKS) for c in range(1, gate.CHUNKS + 1)]


def test_e3_tv11_table_and_the_24_percent_statement(e3):
    _, table, _ = e3
    tv11 = table[table["p_gate"] == 0.99]

    def row_of(product):
        rows = tv11[np.isclose(tv11["product"], product, rtol=1e-12)]
        assert len(rows) == 1
        return rows.iloc[0]

    for product, (limit, probability) in gate.TV11_TABLE.items():
        assert row_of(product)["d2_limit"] == pytest.approx(limit, abs=1e-4)
        assert row_of(product)["probability"] == pytest.approx(probability, abs=1e-5)
    flipped = row_of(0.02)
    assert flipped["case"] == "status flipped, code corrupted"
    assert flipped["mu_G"] == pytest.approx(0.2) and flipped["mu_N"] == pytest.approx(0.1)
    # the curve gives 1 - 0.75608 = 0.24392 new objects, the spec's "24 %"; the draws agree with it
    # within 4 SE, and with 24 % to the statement's precision (0.24 itself is about 6 SE away at 4e5 draws)
    assert flipped["new_object_probability"] == pytest.approx(1 - 0.75608, abs=1e-5)
    assert abs(flipped["mc_new_object"] - flipped["new_object_probability"]) < 4 * flipped["se"]
    assert abs(flipped["mc_new_object"] - 0.24) < 0.005
    assert abs(table["mean_mu_coord"].iloc[0] - 0.25) < 0.002  # D6
    assert all(c.passed for c in gate.check_gate(table))


def test_e3_the_same_seed_gives_the_same_table_and_another_seed_other_draws(tmp_path):
    a = gate.gate_table(seed=5, samples=4000, p_gates=(0.99,))
    b = gate.gate_table(seed=5, samples=4000, p_gates=(0.99,))
    c = gate.gate_table(seed=6, samples=4000, p_gates=(0.99,))
    assert a.equals(b)
    assert not np.array_equal(a["mc_kept"], c["mc_kept"])


def test_e3_figure_draws_curve_and_monte_carlo_points_per_gate(e3):
    _, table, _ = e3
    fig = gate.plot_gate(table)
    try:
        ax = fig.axes[0]
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        for p_gate in ("0.95", "0.99", "0.999"):
            assert f"F_χ²₄(γ + 2 ln Π), P_G = {p_gate}" in legend
            assert f"Monte Carlo ±4 SE, P_G = {p_gate}" in legend
        assert len(legend) == 6
        curves = [line for line in ax.get_lines() if line.get_label().startswith("F_χ²₄")]
        assert len(curves) == 3
        points = [c for c in ax.containers if c.get_label().startswith("Monte Carlo")]
        assert [len(c.lines[0].get_xdata()) for c in points] == [7, 7, 7]
        assert ax.get_xscale() == "log" and "Π" in ax.get_xlabel() and "[" in ax.get_ylabel()
        assert any("24.4 %" in t.get_text() for t in ax.texts)
    finally:
        pyplot().close(fig)


# --- CLI --------------------------------------------------------------------------------------

@pytest.mark.parametrize("command, files", [
    ("fuzzy-fig2", (fig2.CSV_NAME, fig2.CURVES_CSV_NAME, fig2.PNG_NAME)),
    ("fuzzy-regions", (regions.CSV_NAME, regions.PNG_NAME)),
    ("fuzzy-gate", (gate.CSV_NAME, gate.PNG_NAME)),
])
def test_cli_commands_pass_their_checks_and_write_files(tmp_path, command, files):
    extra = ("--samples", "40000") if command == "fuzzy-gate" else ()
    result = invoke("study", command, "--out", tmp_path, "--seed", 3, "--check", *extra)
    assert result.exit_code == 0, result.output
    assert "FAIL" not in result.output and "pass" in result.output
    for name in files:
        assert (tmp_path / name).stat().st_size > 0
    assert (tmp_path / files[-1]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_check_exits_1_when_an_expected_value_fails(tmp_path, monkeypatch):
    monkeypatch.setitem(fig2.EXPECTED_PEAKS, 1.0, 0.4)
    result = invoke("study", "fuzzy-fig2", "--out", tmp_path, "--check")
    assert result.exit_code == 1
    assert "FAIL" in result.output
    # without --check the failure is reported, the exit code stays 0
    assert invoke("study", "fuzzy-fig2", "--out", tmp_path).exit_code == 0


def test_cli_gate_rejects_a_bad_gate_probability(tmp_path):
    result = invoke("study", "fuzzy-gate", "--out", tmp_path, "--p-gate", "0.99,1.5")
    assert result.exit_code == 2

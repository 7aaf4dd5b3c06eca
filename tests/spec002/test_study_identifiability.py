"""Spec 002 §6 E1 (``skytrack study ident-example``) and E2 (``skytrack study ident-radar``).

E1 (§3.5, TV1, TV2, TV6): det M = f16² on all 201 × 2 sweep points (1e-12 absolute), κ constant at
1 / √5 − 2 (1e-12 relative) and 0 only at f16 = 0, σ_χ1 = 1 and σ_χ2 = √(f15²+1)/|f16| (1e-12
relative); TV2's timeline (failing k = 2, 6; literal det passes them); TV6 (N_w = 2 recovers a2,
κ = 0.2675472390 to the printed 10 digits).  E2 (R9, R10, R7, R6): along the E3 track the pos σ_χ
is 11.46°/s within 1 % and flat within 0.1 %; ṙ and pos+ṙ give 0.143°/s within 5 % on the
tangential first leg; the peaks are 29°/s (ṙ) and 10.7°/s (pos+ṙ) within 15 % at t = 166 ± 2 s
where ψ = 0.3° ± 0.05°; TV8's 30 cells, its 16 polar cells (κ ± 4 %) and TV9's 3 rows equal the
spec's tables; the built culprit cases name their culprits (Z = {b_rdot} for a Doppler bias with
position only; D = {omega, b_rdot} with Doppler).  Figures: the drawn line data (det curve = f16², flat pos line at 11.46°/s).  The
commands run through a local typer app on which ``register_identifiability_studies`` is called.
"""

import json
import math

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from skytrack.cli.study_identifiability import register_identifiability_studies
from skytrack.studies.identifiability import example, radar_cells, radar_setups, radar_track

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def sweep():
    return example.sweep()


@pytest.fixture(scope="module")
def track():
    table, records = radar_track.precision_along()
    return table, records


def _app():
    app = typer.Typer()
    register_identifiability_studies(app)
    return app


# ------------------------------------------------------------------------------------------- E1


def test_e1_sweep_has_201_points_per_f15_and_det_is_the_parabola(sweep):
    assert len(sweep) == 2 * 201
    assert sorted(set(sweep["f15"])) == [0.0, 2.0]
    assert (sweep["f16"] == 0.0).sum() == 2
    np.testing.assert_allclose(sweep["det"], sweep["f16"] ** 2, rtol=0, atol=1e-12)


@pytest.mark.parametrize("f15, kappa", [(0.0, 1.0), (2.0, math.sqrt(5) - 2)])
def test_e1_kappa_constant_and_zero_only_at_f16_zero(sweep, f15, kappa):
    rows = sweep[sweep["f15"] == f15]
    nonzero = rows[rows["f16"] != 0]
    np.testing.assert_allclose(nonzero["kappa"], kappa, rtol=1e-12)
    at_zero = rows[rows["f16"] == 0].iloc[0]
    assert at_zero["kappa"] == 0.0
    assert at_zero["verdict"] == "not_identifiable" and at_zero["zero_influence"] == "a2"
    assert (rows["verdict_det"] == "not_identifiable").sum() == 1


@pytest.mark.parametrize("f15", [0.0, 2.0])
def test_e1_precision_closed_forms(sweep, f15):
    rows = sweep[(sweep["f15"] == f15) & (sweep["f16"] != 0)]
    np.testing.assert_allclose(rows["sigma_chi2"], np.sqrt(f15**2 + 1) / np.abs(rows["f16"]), rtol=1e-12)
    np.testing.assert_allclose(rows["sigma_chi1"], 1.0, rtol=1e-12)
    assert np.isnan(sweep[(sweep["f15"] == f15) & (sweep["f16"] == 0)]["sigma_chi2"]).all()


def test_e1_tv2_timeline_and_tv6_window():
    timeline, summary = example.tv2_timeline()
    assert summary["float cos"]["failing_svd"] == [2, 6]
    assert summary["float cos"]["global_svd"] == "not_identifiable"
    assert summary["float cos"]["failing_det"] == []  # G5: the literal det misses the rounding zeros
    assert summary["exact zeros"]["failing_det"] == [2, 6]
    rounding = timeline[timeline["variant"] == "float cos"].set_index("k")
    assert rounding.loc[2, "det"] == pytest.approx(3.749399456654644e-33, rel=1e-12)
    assert rounding.loc[6, "det"] == pytest.approx(3.3744595109891873e-32, rel=1e-12)
    np.testing.assert_allclose(rounding.loc[[1, 3, 4, 5, 7, 8], "kappa"], math.sqrt(2) - 1, rtol=1e-12)
    window = example.tv6_window().set_index("window")
    assert window.loc[1, "verdict"] == "not_identifiable" and window.loc[1, "zero_influence"] == "a2"
    assert window.loc[2, "verdict"] == "identifiable"
    assert window.loc[2, "kappa"] == pytest.approx(0.2675472390, abs=5e-11)


def test_e1_figure_draws_det_as_f16_squared_and_sigma2_on_log_axis(sweep):
    fig = example.plot_example(sweep)
    ax_det, ax_kappa, _, ax_s2 = fig.axes
    det_lines = [line for line in ax_det.get_lines() if line.get_label().startswith("f15")]
    assert len(det_lines) == 2
    for line in det_lines:
        f16, det = line.get_data()
        assert len(f16) == 201
        np.testing.assert_allclose(det, np.asarray(f16) ** 2, atol=1e-12)
    kappa_f15_2 = next(line for line in ax_kappa.get_lines() if line.get_label() == "f15 = 2")
    values = np.asarray(kappa_f15_2.get_ydata())
    assert values[np.asarray(kappa_f15_2.get_xdata()) == 0.0] == [0.0]
    assert np.ptp(values[values > 0]) < 1e-12
    assert ax_s2.get_yscale() == "log"
    for ax in fig.axes:
        assert "[" in ax.get_ylabel() and "[" in ax.get_xlabel() and ax.get_title()
        assert ax.get_legend() is not None
    example.pyplot().close(fig)


# ------------------------------------------------------------------------------------------- E2


def test_e2_position_only_precision_is_constant_11_46(track):
    table, records = track
    pos = table["sigma_pos_deg_s"]
    assert len(table) == 272
    assert pos.mean() == pytest.approx(11.46, rel=0.01)
    assert (pos.max() - pos.min()) / pos.mean() < 1e-3
    assert records["pos"].global_verdict == "identifiable"


@pytest.mark.parametrize("name", ["rdot", "pos+rdot"])
def test_e2_doppler_precision_in_tangential_flight_is_0_143(track, name):
    table, _ = track
    first_leg = table[table["t_s"] < 60]
    assert first_leg[f"sigma_{name}_deg_s"].min() == pytest.approx(0.143, rel=0.05)
    # ≈ σ_ṙ/(T v sin ψ) wherever ψ is not tiny
    wide = table[table["psi_deg"] > 5]
    np.testing.assert_allclose(wide[f"sigma_{name}_deg_s"], wide["sigma_rdot_closed_form_deg_s"], rtol=0.05)


@pytest.mark.parametrize("name, peak", [("rdot", 29.0), ("pos+rdot", 10.7)])
def test_e2_precision_peaks_where_line_of_sight_meets_velocity(track, name, peak):
    table, _ = track
    row = table.loc[table[f"sigma_{name}_deg_s"].idxmax()]
    assert row[f"sigma_{name}_deg_s"] == pytest.approx(peak, rel=0.15)
    assert abs(row["t_s"] - 166.0) <= 2.0
    assert row["psi_deg"] == pytest.approx(0.3, abs=0.05)


def test_e2_step_summary_counts_and_global_verdicts(track):
    table, records = track
    summary = radar_track.step_summary(table, records).set_index("set")
    assert list(summary["identifiable"]) == [272, 272, 272]
    assert list(summary["global"]) == ["identifiable"] * 3
    assert summary.loc["rdot", "worst_steps"].startswith("t=167 s")


def test_e2_figure_draws_the_flat_position_line(track):
    table, _ = track
    fig = radar_track.plot_track(table)
    ax_sigma, ax_psi = fig.axes[:2]
    pos_line = next(line for line in ax_sigma.get_lines() if line.get_label().startswith("pos (σ_pos"))
    values = np.asarray(pos_line.get_ydata())
    np.testing.assert_allclose(values, 11.46, rtol=0.01)
    rdot_line = next(line for line in ax_sigma.get_lines() if line.get_label().startswith("ṙ"))
    assert np.max(rdot_line.get_ydata()) == pytest.approx(29.0, rel=0.15)
    assert ax_sigma.get_yscale() == "log"
    assert "°/s" in ax_sigma.get_ylabel() and "[s]" in ax_psi.get_xlabel()
    assert np.min(ax_psi.get_lines()[0].get_ydata()) == pytest.approx(0.3, abs=0.05)
    radar_track.pyplot().close(fig)


def test_e2_tv8_with_its_polar_variant_and_tv9_match_the_spec():
    tv8 = radar_cells.tv8_table()
    assert len(tv8) == 30 and tv8["matches"].all(), tv8[~tv8["matches"]]
    polar = radar_cells.tv8_table(polar=True)
    assert len(polar) == 16 and polar["matches"].all(), polar[~polar["matches"]]
    assert radar_cells.check_polar(polar)[0].passed
    tv9 = radar_cells.tv9_table()
    assert list(tv9["verdict"]) == ["not_identifiable", "weak", "identifiable"]
    assert tv9["matches"].all()


def test_e2_doppler_bias_with_position_only_names_its_culprit():
    record = radar_setups.setup_record("omega,b_rdot", "pos")
    assert record.global_verdict == "not_identifiable"
    assert record.zero_influence_count == {"omega": 0, "b_rdot": 272}
    assert record.checks.messages(0) == ["parameter b_rdot has no influence on the measurements over [t_0, t_1]"]


def test_e2_turn_and_doppler_bias_are_indistinguishable_in_tangential_flight():
    record = radar_setups.setup_record("omega,b_rdot", "pos+rdot")
    assert record.global_verdict == "weak"
    assert record.failing_steps == []
    assert record.checks.indistinguishable_names(0) == ["omega", "b_rdot"]
    assert record.checks.messages(0)[0].startswith("parameters omega, b_rdot act on the measurements")
    assert 1 in record.weak_steps and 167 not in record.weak_steps  # radial at t = 167 s: separable


def test_e2_culprit_checks_pass_and_fail():
    table = radar_setups.setups_table(setups=("omega", "omega,b_rdot"), sets=("pos", "pos+rdot"))
    checks = radar_setups.check_culprits(table)
    assert len(checks) == 4 and all(c.passed for c in checks)
    tampered = table.copy()
    tampered.loc[(tampered["parameters"] == "omega,b_rdot") & (tampered["set"] == "pos"), "Z_culprits"] = ""
    assert not all(c.passed for c in radar_setups.check_culprits(tampered))


# ------------------------------------------------------------------------------------------- CLI


def test_cli_ident_example_check_json_and_files(tmp_path):
    result = CliRunner().invoke(_app(), ["ident-example", "--out", str(tmp_path), "--check", "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.output)
    assert document["study"] == "ident-example" and document["passed"] is True
    assert document["results"]["tv2"]["float cos"]["failing_svd"] == [2, 6]
    for name in ("ident_example.csv", "ident_example_tv2.csv", "ident_example_tv6.csv", "ident_example.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_cli_ident_example_check_exits_1_on_a_failed_expectation(tmp_path, monkeypatch):
    monkeypatch.setattr(example, "TV6_KAPPA", 0.3)
    result = CliRunner().invoke(_app(), ["ident-example", "--out", str(tmp_path), "--check"])
    assert result.exit_code == 1
    assert "FAIL" in result.output and "TV6 N_w = 2" in result.output


def test_cli_ident_radar_prints_tables_and_names_the_culprit(tmp_path):
    result = CliRunner().invoke(_app(), ["ident-radar", "--out", str(tmp_path), "--check"], env={"COLUMNS": "250"})
    assert result.exit_code == 0, result.output
    assert "FAIL" not in result.output and "all 14 expected values hold" in result.output
    assert "parameter b_rdot has no influence on the measurements over [t_0, t_1]" in result.output
    assert "position only" in result.output and "position + Doppler" in result.output
    summary = json.loads((tmp_path / "ident_radar_summary.json").read_text())
    assert summary["passed"] is True and summary["results"]["tv8_matches"] == 30
    assert (tmp_path / "ident_radar.png").stat().st_size > 0


def test_cli_ident_radar_rejects_a_bad_window(tmp_path):
    result = CliRunner().invoke(_app(), ["ident-radar", "--out", str(tmp_path), "--window", "0"])
    assert result.exit_code == 2

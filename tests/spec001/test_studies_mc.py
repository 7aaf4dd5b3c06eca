"""Spec 001 §6 E5-E9: each Monte Carlo study run small — the data its figure draws, its CSV and JSON.

The figures are checked by what they draw (line and bar data against independent recomputations
from the study's draws and from scipy), not only by the files existing.  Small trial counts keep
the file fast; the spec's numbers are tested in test_sequential_mc.py.
"""

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.studies.identification import many_to_many as e9
from skytrack.studies.identification import posterior_calibration as e8
from skytrack.studies.identification import process_noise as e7
from skytrack.studies.identification import quadratic_forms as e6
from skytrack.studies.identification import scenario_tv5 as tv5
from skytrack.studies.identification import sequential_mc as e5


def _summary(output, study: str, trials: int) -> dict:
    """Every file exists; the JSON holds the study, its options and the same verdicts as the checks."""
    for path in output.paths:
        assert path.exists() and path.stat().st_size > 0, path
    document = json.loads(next(p for p in output.paths if p.suffix == ".json").read_text())
    assert document["study"] == study
    assert document["options"]["trials"] == trials
    assert [c["passed"] for c in document["checks"]] == [c.passed for c in output.checks]
    assert document["passed"] == all(c.passed for c in output.checks)
    csv = pd.read_csv(next(p for p in output.paths if p.suffix == ".csv"))
    assert len(csv) == len(output.table)
    return document


def test_e5_sequential_mc(tmp_path):
    out = e5.run_sequential_mc(tmp_path, trials=3000, seed=2)
    document = _summary(out, "ident-sequential-mc", 3000)
    assert [row["case"] for row in document["results"]["cases"]] == list(e5.CASES)
    assert document["results"]["recursive_max_difference"]["statistic"] <= 1e-8
    samples, roc = out.extra["samples"], out.extra["roc"]
    fig = e5.plot_sequential_mc(samples, out.table, roc)
    ax_same, ax_different, ax_roc = fig.axes[:3]
    x, y = ax_same.lines[0].get_data()
    np.testing.assert_allclose(y, stats.chi2.pdf(x, 4), rtol=1e-12)
    tops = ax_same.patches[0].get_xy()[:, 1]  # the step polygon's vertices carry the bar heights
    counts, _ = np.histogram(samples[e5.THETA_1]["statistic"], bins=np.linspace(0, 25, 101), density=True)
    assert max(np.min(np.abs(tops - c)) for c in counts) < 1e-12
    offsets = [case for case in e5.CASES if case != e5.THETA_1]
    for line, case in zip(ax_different.lines, offsets):
        x, y = line.get_data()
        lam = tv5.TV5B[case][0]
        np.testing.assert_allclose(y, stats.ncx2.pdf(x, 4, lam), rtol=1e-5, atol=1e-12)
    theory = ax_roc.lines[0::2][:len(offsets)]
    for line, case in zip(theory, offsets):
        rows = roc[roc["case"] == case]
        x, y = line.get_data()
        np.testing.assert_allclose(y, stats.chi2.cdf(rows["h"], 4), rtol=1e-12)
        np.testing.assert_allclose(x, stats.ncx2.cdf(rows["h"], 4, tv5.TV5B[case][0]), rtol=1e-5, atol=1e-15)
    dots = ax_roc.lines[3]  # the Monte Carlo dots of +100 m
    rows = roc[roc["case"] == "+100 m in x"]
    h = rows["h"].to_numpy()[50]
    assert dots.get_data()[0][50] == pytest.approx(np.mean(samples["+100 m in x"]["statistic"] <= h))
    assert dots.get_data()[1][50] == pytest.approx(np.mean(samples[e5.THETA_1]["statistic"] <= h))


def test_e6_quadratic_forms(tmp_path):
    out = e6.run_quadratic_forms(tmp_path, trials=3000, seed=2)
    _summary(out, "ident-quadratic-forms", 3000)
    table, roc = out.table, out.extra["roc"]
    fig = e6.plot_quadratic_forms(roc, table)
    for ax, case in zip(fig.axes, e6.E6_OFFSETS):
        lam = tv5.TV5B[case][0]
        for k, (statistic, (_, dof, column_incorrect, _)) in enumerate(e6.STATISTICS.items()):
            exact, _, circle, square = ax.lines[4 * k:4 * k + 4]
            h = roc[(roc["case"] == case) & (roc["statistic"] == statistic)]["h"]
            np.testing.assert_allclose(exact.get_data()[1], stats.chi2.cdf(h, dof), rtol=1e-12)
            np.testing.assert_allclose(exact.get_data()[0], stats.ncx2.cdf(h, dof, lam), rtol=1e-5, atol=1e-15)
            # the P_ПО = 0.99 operating point sits at TV-5b's P_НО
            assert circle.get_data()[0][0] == pytest.approx(tv5.TV5B[case][column_incorrect], rel=1e-5)
            assert circle.get_data()[1][0] == 0.99
            assert square.get_data()[0][0] == 0.01


def test_e7_process_noise(tmp_path):
    out = e7.run_process_noise(tmp_path, trials=2000, seed=2, q_values=(0.0, 25.0))
    document = _summary(out, "ident-process-noise", 2000)
    assert len(document["results"]["rows"]) == 6
    table = out.table
    fig = e7.plot_process_noise(table)
    ax_var, ax_coverage, ax_rms = fig.axes[:3]
    exact_var = ax_var.lines[0].get_data()[1]
    np.testing.assert_allclose(exact_var, [8.0, 8.732738], atol=5e-7)  # TV-5c through the drawn line
    np.testing.assert_allclose(ax_coverage.lines[0].get_data()[1], [0.99, 0.989284], atol=5e-7)
    mc_var = ax_var.lines[1].get_data()[1]
    samples = out.extra["samples"]
    np.testing.assert_allclose(mc_var, [samples[q]["exact"].var(ddof=1) for q in (0.0, 25.0)], rtol=1e-12)
    fuse_rms = ax_rms.lines[0].get_data()[1]
    np.testing.assert_allclose(fuse_rms, [np.sqrt(np.mean((samples[q]["fuse"] - samples[q]["exact"]) ** 2))
                                          for q in (0.0, 25.0)], rtol=1e-12)
    assert fuse_rms[0] < 1e-8 < fuse_rms[1]


def test_e8_posterior_calibration(tmp_path):
    out = e8.run_posterior_calibration(tmp_path, trials=4000, seed=2)
    document = _summary(out, "ident-posterior-calibration", 4000)
    samples = out.extra["samples"]
    for variant in e8.VARIANTS:
        assert document["results"]["brier"][variant] == pytest.approx(
            np.mean((samples[variant] - samples["same"]) ** 2), rel=1e-12)
    fig = e8.plot_calibration(out.table, samples, document["results"]["brier"])
    containers = fig.axes[0].containers
    for container, variant in zip(containers, e8.VARIANTS):
        x, y = container.lines[0].get_data()
        p = samples[variant]
        inside = (p >= 0.4) & (p < 0.5)
        k = int(np.argmin(np.abs(np.asarray(x) - p[inside].mean())))
        assert y[k] == pytest.approx(samples["same"][inside].mean(), rel=1e-12)
    assert fig.axes[0].lines[0].get_data()[1].tolist() == [0, 1]  # the diagonal


def test_e9_many_to_many(tmp_path):
    out = e9.run_many_to_many(tmp_path, trials=3, seed=2, sides=(1000.0,))
    document = _summary(out, "ident-many-to-many", 3)
    replay = document["results"]["fuse_vs_replay"]["1000"]
    assert all(v["same_pairs"] and v["max_statistic_difference"] <= 1e-6 for v in replay.values())
    table = out.table
    np.testing.assert_allclose(table[["correct", "wrong", "missed"]].sum(axis=1), 1.0, atol=1e-12)
    assert set(table["pair_init"]) == {"fuse", "replay"}
    fig = e9.plot_many_to_many(table)
    for ax, metric in zip(fig.axes, ("correct", "wrong", "missed")):
        for container, solver in zip(ax.containers, e9.SOLVERS):
            y = np.asarray(container.lines[0].get_data()[1], dtype=float)
            expected = table[(table["pair_init"] == "fuse") & (table["solver"] == solver)][metric]
            np.testing.assert_allclose(y, expected.to_numpy(float))


def test_e9_scenes_never_share_a_pair():
    rng = np.random.default_rng(0)
    states, adsb = e9.draw_scenes(rng, 4, 2000.0)
    identifier = e9.identify(e9.scene_reports(rng, states, adsb), "fuse")
    ids = np.asarray(identifier.track_ids)
    pairs = identifier.pairs
    assert pairs.size == 4 * e9.OBJECTS * e9.ADSB_OBJECTS  # every pair within each scene, none across
    assert np.all(ids[pairs.first[:pairs.size]] // e9.ID_BASE == ids[pairs.second[:pairs.size]] // e9.ID_BASE)


def test_cli_study_runs_and_checks(tmp_path):
    result = CliRunner().invoke(app, ["study", "ident-quadratic-forms", "--trials", "20000", "--out", str(tmp_path),
                                      "--check"])
    assert result.exit_code == 0, result.output
    assert "FAIL" not in result.output and "pass" in result.output
    assert (tmp_path / "ident_quadratic_forms.png").exists()
    bad = CliRunner().invoke(app, ["study", "ident-process-noise", "--trials", "0", "--out", str(tmp_path)])
    assert bad.exit_code == 2

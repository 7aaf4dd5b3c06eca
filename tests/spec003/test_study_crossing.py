"""Study E4 (``skytrack study fuzzy-crossing``): the CI-sized assertions, the CSV and what the figure draws."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.studies.fuzzy.crossing import METHODS, CrossingCase, run_study, sweep_cases
from skytrack.studies.fuzzy.crossing_figure import crossing_figure


def test_fuzzy_crossing_check_holds_the_ci_assertions(tmp_path):
    """Spec 003 §6: (i)-(iv) and Q1-Q5 on 100 runs, seed 1 (the command exits 1 when one fails)."""
    result = CliRunner().invoke(app, ["study", "fuzzy-crossing", "--check", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "fuzzy_crossing.csv")
    assert set(table.method) == set(METHODS)
    assert (table.runs == 100).all()
    always = table[(table.policy == "always") & (table.p_flip == 0) & (table.q == 25) & (table.beta_deg == 5)]
    swap = always.set_index("method").swap
    assert swap["fuzzy-global"] <= 0.05 and swap["crisp"] <= 0.05 and swap["nn"] >= 0.12
    # nn and ml ignore IFF: identical rates in every configuration of the reference geometry
    reference = table[(table.q == 25) & (table.beta_deg == 5)]
    for method in ("nn", "ml"):
        assert reference[reference.method == method][["car", "swap", "broken"]].nunique().max() == 1
    assert (tmp_path / "fuzzy_crossing.png").stat().st_size > 10_000


def test_sweeps_and_options():
    cases = sweep_cases(["S1", "S2", "S3", "S4"])
    assert sum(c.sweep == "S2" for c in cases) == 5 and sum(c.sweep.startswith("S2-") for c in cases) == 8
    assert {(c.beta_deg, c.q) for c in cases if c.sweep == "S3"} == {(b, q) for b in (5, 10, 20, 45) for q in (1, 25)}
    with pytest.raises(ValueError, match="S9"):
        sweep_cases(["S9"])
    result = CliRunner().invoke(app, ["study", "fuzzy-crossing", "--methods", "nn,bogus"])
    assert result.exit_code == 2 and "bogus" in result.output


def test_figure_draws_one_line_per_method_and_the_policy_bars():
    cases = [CrossingCase(policy="always", p_flip=e, p_code=e) for e in (0.0, 0.2)] + [CrossingCase(policy="track")]
    table = run_study(cases, METHODS, 8, 2)
    fig = crossing_figure(table)
    ax_swap, ax_car, ax_policy = fig.axes
    for ax, column in ((ax_swap, "swap"), (ax_car, "car")):
        assert [t.get_text() for t in ax.get_legend().get_texts()] == list(METHODS)
        containers = {c.get_label(): c for c in ax.containers}
        assert list(containers) == list(METHODS)
        for method, container in containers.items():
            rows = table[(table.method == method) & (table.policy == "always")].sort_values("p_flip")
            data_line = container.lines[0]
            assert np.allclose(data_line.get_xdata(), [0.0, 0.2])
            assert np.allclose(data_line.get_ydata(), rows[column])
    heights = [bar.get_height() for bar in ax_policy.patches]
    expected = [table[(table.method == m) & (table.policy == p) & (table.p_flip == 0)].swap.iloc[0]
                for m in METHODS for p in ("track", "always")]
    assert np.allclose(heights, expected)
    assert "policy: track" in [t.get_text() for t in ax_policy.get_xticklabels()]

"""Spec 001 R11: ``skytrack identify potential`` and ``skytrack identify threshold``.

The TV-1 numbers appear in the printed tables (at least 6 significant digits), the CSV holds the
table at full precision, the figure draws P_ПО solid, P_НО dashed and P̄_НО dotted against r, the
circular mode warns (G10), and a bad option is a one-line error with exit code 2."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


def numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"\d+\.\d+(?:e[-+]\d+)?", text)]


def printed(value: float, text: str, tolerance: float, relative: bool = False) -> bool:
    """Some number printed in ``text`` equals ``value`` within the spec's tolerance."""
    limit = tolerance * abs(value) if relative else tolerance
    return any(abs(x - value) <= limit for x in numbers(text))


def test_threshold_p_incorrect_at_an_offset_prints_the_tv1_design():
    result = invoke("identify", "threshold", "--dim", 2, "--p-incorrect", 0.05, "--A", 4)
    assert result.exit_code == 0, result.output
    assert "2.51428748" in result.output and "0.957609" in result.output
    assert "6.32164" in result.output  # r^2
    result = invoke("identify", "threshold", "--dim", 3, "--p-incorrect", 0.01, "--A", 3)
    assert printed(1.21185810, result.output, 1e-7) and printed(0.31046385, result.output, 1e-7)
    assert "1.211858" in result.output and "0.310463" in result.output


def test_threshold_over_a_separation_range_prints_r_h_and_p_correct():
    result = invoke("identify", "threshold", "--dim", 2, "--p-incorrect", 0.05, "--delta-range", 100, 600,
                    "--sigma", 100)
    assert result.exit_code == 0, result.output
    assert printed(1.09009560, result.output, 1e-7) and printed(0.44797073, result.output, 1e-7)
    assert printed(109.0096, result.output, 5e-5)
    result = invoke("identify", "threshold", "--dim", 3, "--p-incorrect", 0.01, "--A-range", 1, 6)
    assert printed(0.78715321, result.output, 1e-7) and printed(0.10807124, result.output, 1e-7)


def test_threshold_p_correct():
    result = invoke("identify", "threshold", "--dim", 2, "--p-correct", 0.99, "--sigma", 50)
    assert result.exit_code == 0, result.output
    assert "9.21034037" in result.output and "3.03485425" in result.output and "151.742712" in result.output


def test_potential_table_holds_the_tv1_values(tmp_path):
    csv = tmp_path / "table.csv"
    result = invoke("identify", "potential", "--dim", 2, "--r", "0.5,1,2,2.5,3,4", "--A", "0,1", "--A", 3,
                    "--delta-range", 100, 600, "--sigma", 100, "--csv", csv)
    assert result.exit_code == 0, result.output
    for value in (0.1175030974, 0.3934693403, 0.8646647168, 0.9560630664, 0.9888910035, 0.9996645374):  # P_ПО
        assert printed(value, result.output, 1e-9), value
    for value in (7.347260e-2, 2.671202e-1, 7.309879e-1, 8.791459e-1, 9.562840e-1, 9.971105e-1,  # A = 1
                  1.699767e-3, 1.082945e-2, 1.132792e-1, 2.461016e-1, 4.325202e-1, 8.034878e-1):  # A = 3
        assert printed(value, result.output, 1e-6, relative=True), value
    assert printed(0.1737679657, result.output, 1e-8)  # averaged over [100, 600] m at r = 2
    assert "0.8646647168" in result.output  # ten significant digits
    table = pd.read_csv(csv)
    assert list(table.columns) == ["r", "h_m", "p_correct", "p_incorrect_A0", "p_incorrect_A1", "p_incorrect_A3",
                                   "p_incorrect_mean"]
    np.testing.assert_allclose(table["h_m"], [50, 100, 200, 250, 300, 400])
    np.testing.assert_allclose(table["p_incorrect_A0"], table["p_correct"], atol=1e-15)
    np.testing.assert_allclose(table["p_incorrect_A3"], [1.699767e-3, 1.082945e-2, 1.132792e-1, 2.461016e-1,
                                                         4.325202e-1, 8.034878e-1], rtol=1e-6)
    assert abs(table["p_incorrect_mean"][2] - 0.1737679657) <= 1e-8


def test_potential_3d_with_metric_inputs_and_the_default_grid():
    result = invoke("identify", "potential", "--dim", 3, "--h", 200, "--sigma-eta", 60, "--sigma-xi", 80,
                    "--delta", 400)
    assert result.exit_code == 0, result.output
    assert printed(0.7385358701, result.output, 1e-9)  # TV-1 3-D, r = 2
    assert printed(9.252391e-3, result.output, 1e-6, relative=True)  # A = 4
    grid = invoke("identify", "potential", "--dim", 3, "--A", 2)
    rows = [line for line in grid.output.splitlines() if re.match(r"^│\s+\d", line)]
    assert [float(row.split("│")[1]) for row in rows] == [0.5 * k for k in range(13)]  # the default grid 0:6:0.5
    assert printed(7.203598e-1, grid.output, 1e-6, relative=True)  # A = 2, r = 3


def test_potential_plot_draws_the_three_line_styles(tmp_path, monkeypatch):
    from skytrack.studies.identification import common

    drawn = {}
    original = common.save_figure

    def keep(fig, path):
        drawn["axes"] = fig.axes[0]
        drawn["lines"] = [(line.get_label(), line.get_linestyle(), line.get_xdata().copy(), line.get_ydata().copy())
                          for line in fig.axes[0].get_lines()]
        return original(fig, path)

    monkeypatch.setattr(common, "save_figure", keep)
    png = tmp_path / "curves.png"
    result = invoke("identify", "potential", "--dim", 2, "--r-grid", "0:4:1", "--A", "1,3", "--A-range", 1, 6,
                    "--plot", png)
    assert result.exit_code == 0, result.output
    assert png.stat().st_size > 10_000
    styles = {label: style for label, style, _, _ in drawn["lines"]}
    assert styles == {"P_ПО": "-", "P_НО, A = 1": "--", "P_НО, A = 3": "--", "P̄_НО, A ∈ [1, 6]": ":"}
    label, _, x, y = drawn["lines"][0]
    assert x[0] == 0.0 and x[-1] == pytest.approx(4.0)
    np.testing.assert_allclose(y, 1.0 - np.exp(-x ** 2 / 2), atol=1e-15)
    _, _, x3, y3 = drawn["lines"][2]
    assert np.interp(2.0, x3, y3) == pytest.approx(0.1132792, abs=2e-3)
    assert "r = h / σ" in drawn["axes"].get_xlabel() and "[–]" in drawn["axes"].get_ylabel()
    assert [t.get_text() for t in drawn["axes"].get_legend().get_texts()] == list(styles)


def test_circular_mode_warns_on_unequal_sigmas():
    result = runner.invoke(app, ["identify", "potential", "--dim", "2", "--h", "200", "--delta", "150",
                                 "--sigma-eta", "100,30", "--sigma-xi", "0,0", "--mode", "circular"])
    assert result.exit_code == 0
    assert "0.8646647168" in result.output and "0.5763207" in result.output
    assert "G10" in result.output  # the warning (stderr is mixed into the output)


@pytest.mark.parametrize("args", [
    ["identify", "threshold", "--dim", "2", "--p-incorrect", "0.05"],
    ["identify", "threshold", "--dim", "2", "--p-incorrect", "0.05", "--p-correct", "0.9", "--A", "1"],
    ["identify", "threshold", "--dim", "2", "--p-incorrect", "0.05", "--delta", "100"],
    ["identify", "threshold", "--dim", "2", "--p-incorrect", "1.5", "--A", "1"],
    ["identify", "threshold", "--dim", "0", "--p-correct", "0.9"],
    ["identify", "potential", "--dim", "2", "--h", "100"],
    ["identify", "potential", "--dim", "2", "--r", "1", "--h", "100", "--sigma", "10"],
    ["identify", "potential", "--dim", "2", "--r-grid", "0:6"],
    ["identify", "potential", "--dim", "2", "--r", "x"],
    ["identify", "potential", "--dim", "2", "--r", "1", "--mode", "elliptic"],
    ["identify", "potential", "--dim", "2", "--h", "200", "--sigma-eta", "100,30", "--sigma-xi", "0,0"],
    ["identify", "potential", "--dim", "3", "--r", "1", "--sigma-eta", "1,2", "--sigma-xi", "1,2"],
])
def test_bad_options_exit_2_with_one_line(args):
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output

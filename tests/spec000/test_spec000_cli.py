"""Spec 000 R15 / §6: ``skytrack study singer-missed`` (CSV, figures, E3, E5, E6, determinism)."""

import struct

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest
import typer
from typer.testing import CliRunner

from skytrack.cli.study import MC_CSV_NAME, study_app
from skytrack.studies.singer_missed import CSV_COLUMNS, CSV_NAME, FIG1_NAME, FIG2_NAME

app = typer.Typer()
app.add_typer(study_app, name="study")
runner = CliRunner()

SMALL = ["--sigma", "100,1000", "--pd", "0.7,0.9,1.0", "--scans", "200", "--runs", "4", "--fig2-pd", "1.0,0.7"]


def run(*args):
    result = runner.invoke(app, ["study", "singer-missed", *args])
    return result


def png_ok(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert width >= 400 and height >= 300
    image = mpimg.imread(path)
    # drawn content: many distinct colours, not a blank canvas
    assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 50
    return True


def test_cli_writes_csv_and_figures(tmp_path):
    result = run(*SMALL, "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / CSV_NAME)
    assert tuple(table.columns) == CSV_COLUMNS
    assert len(table) == 2 * 2 * 3
    assert set(table.discretization) == {"paper"} and set(table.variant) == {"pos", "posvel"}
    assert (table.scans == 200).all() and (table.runs == 4).all() and (table.seed == 0).all()
    assert table.fs11_sd[table.pd < 1].gt(0).all()
    assert png_ok(tmp_path / FIG1_NAME) and png_ok(tmp_path / FIG2_NAME)
    assert "E3 Kalman check" in result.output and "NO" not in result.output
    assert "0.88257939" in result.output  # TV8, pos, sigma = 100 m
    at1 = table[table.pd == 1.0]
    assert np.allclose(at1.fs11_mean, at1.fs11_ss, rtol=0, atol=1e-9)


def test_cli_is_deterministic_for_a_seed(tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    assert run(*SMALL, "--out", str(a), "--seed", "7").exit_code == 0
    assert run(*SMALL, "--out", str(b), "--seed", "7").exit_code == 0
    assert run(*SMALL, "--out", str(c), "--seed", "8").exit_code == 0
    assert (a / CSV_NAME).read_bytes() == (b / CSV_NAME).read_bytes()
    assert (a / CSV_NAME).read_bytes() != (c / CSV_NAME).read_bytes()


def test_cli_exact_discretisation_and_options(tmp_path):
    result = run("--sigma", "300", "--pd", "0.8,1", "--variants", "posvel", "--discretization", "exact", "--dt", "5",
                 "--tau", "30", "--sigma-a", "2", "--sigma-v", "3", "--scans", "100", "--fig1-sigma", "300",
                 "--fig2-pd", "1", "--start", "paper-init", "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / CSV_NAME)
    assert set(table.discretization) == {"exact"} and set(table.variant) == {"posvel"} and len(table) == 2
    assert "E3 Kalman check" not in result.output  # E3 needs the steady start


def test_cli_require_fs11_prints_minimal_pd(tmp_path):
    result = run(*SMALL, "--out", str(tmp_path), "--require-fs11", "1.0", "--require-fes11", "1.5")
    assert result.exit_code == 0, result.output
    assert "E6 minimal P_D with FS11 ≤ 1" in result.output
    assert "E6 minimal P_D with FES11 ≤ 1.5" in result.output
    assert "not reached" in result.output  # pos, sigma = 100 m: FES11 > 1.5 even at P_D = 1


def test_cli_monte_carlo(tmp_path):
    result = run("--sigma", "300", "--pd", "0.8", "--fig1-sigma", "300", "--fig2-pd", "0.8", "--scans", "150",
                 "--monte-carlo", "--mc-runs", "300", "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    assert "E5 Monte Carlo consistency" in result.output
    mc = pd.read_csv(tmp_path / MC_CSV_NAME)
    assert len(mc) == 2
    assert ((mc.ratio_filtered - 1).abs() <= 0.03).all() and ((mc.ratio_extrapolated - 1).abs() <= 0.03).all()


@pytest.mark.parametrize("args,message", [
    (["--sigma", "abc"], "--sigma"),
    (["--pd", "1.5"], "--pd"),
    (["--variants", "pos,speed"], "--variants"),
    (["--discretization", "euler"], "--discretization"),
    (["--scans", "0"], "--scans"),
    (["--start", "cold"], "--start"),
])
def test_cli_rejects_bad_options(tmp_path, args, message):
    result = run(*args, "--out", str(tmp_path))
    assert result.exit_code != 0
    assert message in result.output
    assert not (tmp_path / CSV_NAME).exists()

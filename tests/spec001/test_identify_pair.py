"""Spec 001 R12: ``skytrack identify pair REPORTS`` on the TV-3 reports (TV-3b, TV-4), and the reports
reader of docs/formats.md "identification reports" (R1's errors naming the row)."""

import re

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.io.errors import InputError
from skytrack.io.ident_reports import read_ident_reports, report_measurements

TV3B = {"same": [0, 0, 0.628432, 2.975266, 2.486850, 1.138368, 3.499557, 2.146285],
        "diff": [0, 0, 13.623027, 21.332392, 38.191251, 36.745507, 44.228133, 43.622824]}
DOF = [0, 0, 2, 4, 4, 4, 4, 4]


def _write(tmp_path, tv3, case: str, name: str = "reports.csv", shuffle: bool = False) -> str:
    """The TV-3 reports (the ``tv3`` fixture of conftest.py) as an identification reports file."""
    time, system, z, V = tv3(case)
    frame = pd.DataFrame({"time": time, "system": np.where(system == 1, "eta", "xi"),
                          "track_id": np.where(system == 1, "R1", "A1"), "x": z[:, 0], "y": z[:, 1],
                          "sigma_m": np.sqrt(V[:, 0, 0])})
    if shuffle:
        frame = frame.sample(frac=1.0, random_state=3)
    path = tmp_path / name
    frame.to_csv(path, index=False) if name.endswith(".csv") else frame.to_parquet(path, index=False)
    return str(path)


def _run(*args):
    result = CliRunner().invoke(app, ["identify", "pair", *map(str, args)])
    return result


@pytest.mark.parametrize("case", ["same", "diff"])
def test_tv3b_lambda_after_every_report(tmp_path, tv3, case):
    table = tmp_path / "out.csv"
    result = _run(_write(tmp_path, tv3, case), "--csv", table)
    assert result.exit_code == 0, result.output
    out = pd.read_csv(table)
    np.testing.assert_allclose(out["statistic"], TV3B[case], atol=1e-6)
    assert out["dof"].tolist() == DOF
    assert out["decision"].tolist()[:3] == ["insufficient"] * 3
    assert set(out["decision"].iloc[3:]) == {"same" if case == "same" else "different"}
    np.testing.assert_allclose(out["threshold"].iloc[3:], 13.276704, atol=1e-6)
    # the printed table shows the same sequence, 6 decimals, in the Λ column
    printed = [float(line.split("│")[9]) for line in result.output.splitlines() if re.match(r"^│\s*\d+\s*│", line)]
    np.testing.assert_allclose(printed, TV3B[case], atol=1e-6)


def test_tv3a_final_forms_and_parquet_input(tmp_path, tv3):
    table = tmp_path / "out.csv"
    result = _run(_write(tmp_path, tv3, "diff", "reports.parquet", shuffle=True), "--csv", table)
    assert result.exit_code == 0, result.output
    last = pd.read_csv(table).iloc[-1]
    np.testing.assert_allclose([last.Q_Jeta, last.Q_Jxi, last.Q_eta, last.Q_xi, last.statistic],
                               [42.594312, 9.605811, 4.629800, 3.947500, 43.622824], atol=1e-6)


@pytest.mark.parametrize("case,p_same", [("same", 0.9999742), ("diff", 3.781733e-5)])
def test_tv4_prior_mode_posterior(tmp_path, tv3, case, p_same):
    table = tmp_path / "out.csv"
    result = _run(_write(tmp_path, tv3, case), "--init", "prior", "--x0", "1000,2000,0,0", "--p0-diag", "1e6,1e6,4e4,4e4",
                  "--t0", "0", "--csv", table)
    assert result.exit_code == 0, result.output
    last = pd.read_csv(table).iloc[-1]
    assert last.statistic == pytest.approx({"same": 1.810196, "diff": 43.303269}[case], abs=1e-6)
    assert last.p_same == pytest.approx(p_same, rel=1e-6)
    assert "P(same) (prior)" in result.output


@pytest.mark.parametrize("case,p_same", [("same", 0.9999969397), ("diff", 3.217929e-4)])
def test_tv4_density_mode_posterior(tmp_path, tv3, case, p_same):
    table = tmp_path / "out.csv"
    beta = 1.0 / (1e4 * 1e4 * 400.0 * 400.0)
    result = _run(_write(tmp_path, tv3, case), "--object-density", repr(beta), "--csv", table)
    assert result.exit_code == 0, result.output
    out = pd.read_csv(table)
    assert out["p_same"].iloc[:3].isna().all()  # no posterior before both filters reach full rank
    assert out["p_same"].iloc[-1] == pytest.approx(p_same, rel=1e-6)


def test_threshold_modes(tmp_path, tv3):
    path = _write(tmp_path, tv3, "same")
    table = tmp_path / "out.csv"
    assert _run(path, "--h", "2.5", "--csv", table).exit_code == 0
    out = pd.read_csv(table)
    assert out["decision"].tolist()[3:] == ["different", "same", "same", "different", "same"]
    assert _run(path, "--p-incorrect", "0.01", "--noncentrality", "34.438087", "--csv", table).exit_code == 0
    assert pd.read_csv(table)["threshold"].iloc[-1] == pytest.approx(14.881644, abs=1e-5)  # TV-5b's NP h at λ
    result = _run(path, "--p-correct", "0.9", "--h", "3")
    assert result.exit_code == 2 and "one threshold mode" in result.output
    assert _run(path, "--noncentrality", "3").exit_code == 2


def test_several_tracks_need_a_choice(tmp_path, tv3):
    frame = pd.read_csv(_write(tmp_path, tv3, "same"))
    other = frame[frame["system"] == "xi"].assign(track_id="A2", x=lambda f: f["x"] + 150.0, y=lambda f: f["y"] - 100.0)
    path = tmp_path / "two.csv"
    pd.concat([frame, other]).to_csv(path, index=False)
    result = _run(path)
    assert result.exit_code == 2 and "--track-2" in result.output
    table = tmp_path / "out.csv"
    assert _run(path, "--track-2", "A2", "--csv", table).exit_code == 0
    np.testing.assert_allclose(pd.read_csv(table)["statistic"], TV3B["diff"], atol=1e-6)
    assert _run(path, "--track-2", "A9").exit_code == 2


def test_reader_errors_name_the_row(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,system,x,y,sigma_m\n0,eta,1,2,50\n1,radar,1,2,50\n")
    with pytest.raises(InputError, match=r"line 3 \(row 1\), column system: unknown system 'radar'"):
        read_ident_reports(path)
    result = _run(path)
    assert result.exit_code == 2 and "unknown system" in result.output
    path.write_text("time,system,x,y,var_x,var_y,cov_xy\n0,1,1,2,100,100,0\n1,2,1,2,100,100,200\n")
    with pytest.raises(InputError, match=r"row 1.*not positive definite"):
        read_ident_reports(path)
    path.write_text("time,system,x,y\n0,1,1,2\n")
    with pytest.raises(InputError, match=r"row 0.*no position covariance"):
        read_ident_reports(path)
    path.write_text("time,system,x,y,sigma_m,vx,vy\n0,1,1,2,50,3,4\n")
    with pytest.raises(InputError, match=r"row 0.*no velocity covariance"):
        read_ident_reports(path)
    path.write_text("time,system,x,y,sigma_m\n0,1,1,abc,50\n")
    with pytest.raises(InputError, match=r"\(row 0\), column y: value .abc. is not a number"):
        read_ident_reports(path)


def test_reader_covariances_velocities_and_3d(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("time,system,x,y,z,vx,vy,vz,var_x,var_y,var_z,cov_xy,sigma_m,sigma_v_mps\n"
                    "0,eta,1,2,3,,,,100,200,300,10,,\n"
                    "1,xi,1,2,3,4,5,6,,,,,20,2\n")
    arrays = report_measurements(read_ident_reports(path))
    assert arrays.ndim == 3 and arrays.m.tolist() == [3, 6]
    np.testing.assert_allclose(arrays.V[0, :3, :3], [[100, 10, 0], [10, 200, 0], [0, 0, 300]])
    np.testing.assert_allclose(arrays.V[1], np.diag([400.0] * 3 + [4.0] * 3))
    np.testing.assert_allclose(arrays.z[1], [1, 2, 3, 4, 5, 6])
    assert arrays.system.tolist() == [1, 2]

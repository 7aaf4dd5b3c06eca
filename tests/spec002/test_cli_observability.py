"""Spec 002 R17: ``skytrack observability check`` and ``sequence`` through typer's CliRunner.

TV1 (paper example, f15 = 2: f16 = 0 → not_identifiable with a2 in Z and its R6 message; f16 = 3 →
identifiable, κ = √5 − 2 printed to 10 digits, det 9), one TV8 cell (ct-omega, tangential,
ω + b_ṙ, pos+ṙ → weak, κ 0.005 at 1 %, D = {ω, b_ṙ}), TV2's local/global sequence from an npz
written here (global not_identifiable, failing steps 2 and 6), and the one-line errors (exit 2).
"""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app

runner = CliRunner()

F_TV3 = np.array([[1, 0.5, 0, 0, 2, 3], [0, 1, 0.1, 0, 0.5, 0.7], [0, 0, 1, 0.1, 0.2, 0],
                  [0, 0, 0, 1, 0, 0.4], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1.0]])
H_PAPER = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0]])
H_A = np.array([[0.0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]])
COS = (0.7071067811865476, 6.123233995736766e-17, -0.7071067811865475, -1.0,
       -0.7071067811865477, -1.8369701987210297e-16, 0.7071067811865474, 1.0)


def invoke(*args):
    return runner.invoke(app, ["observability", *args])


def test_tv1_f16_zero_is_not_identifiable_and_names_a2():
    result = invoke("check", "--model", "paper-example", "--f15", "2", "--f16", "0")
    assert result.exit_code == 0, result.output
    assert "not_identifiable" in result.output
    assert "parameter a2 has no influence on the measurements over [t_0, t_1]" in result.output
    record = json.loads(invoke("check", "--f15", "2", "--f16", "0", "--json").output)
    assert record["verdict"] == "not_identifiable"
    assert record["zero_influence"] == ["a2"] and record["kappa"] == 0.0 and record["det"] == 0.0


def test_tv1_f16_three_is_identifiable_with_the_printed_margin():
    result = invoke("check", "--model", "paper-example", "--f15", "2", "--f16", "3")
    assert result.exit_code == 0, result.output
    assert "identifiable" in result.output and "not_identifiable" not in result.output
    assert "0.2360679775" in result.output
    record = json.loads(invoke("check", "--json").output)
    assert record["kappa"] == pytest.approx(np.sqrt(5) - 2, rel=1e-10)
    assert record["det"] == pytest.approx(9.0, rel=1e-12)
    assert record["precision"]["a2"] == pytest.approx(0.7453559925, rel=1e-9)
    assert record["messages"] == []


def test_tv8_ct_omega_doppler_bias_tangential_is_weak():
    args = ("check", "--model", "ct-omega", "--bias", "rdot", "--meas", "pos,rdot",
            "--state", "30000,0,0,200", "--T", "1", "--sigma-pos", "50", "--sigma-rdot", "1")
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    assert "weak" in result.output
    assert "parameters omega, b_rdot act on the measurements in (nearly) the same way" in result.output
    record = json.loads(invoke(*args, "--json").output)
    assert record["verdict"] == "weak"
    assert record["kappa"] == pytest.approx(0.005, rel=0.01)
    assert record["indistinguishable"] == ["omega", "b_rdot"] and record["zero_influence"] == []
    assert record["fewer_channels"] is False


def test_tv2_sequence_from_npz(tmp_path):
    F = np.repeat(F_TV3[None], len(COS), axis=0)
    F[:, 0, 4] = 1.0
    F[:, 0, 5] = COS
    path = tmp_path / "tv2.npz"
    np.savez(path, F=F, H=np.repeat(H_PAPER[None], len(COS), axis=0), h_a=H_A,
             V_eta=np.repeat(np.eye(2)[None], len(COS), axis=0))
    result = invoke("sequence", str(path))
    assert result.exit_code == 0, result.output
    assert "global verdict: not_identifiable" in result.output
    assert "failing steps: 2, 6" in result.output
    assert "k = 2: parameter a2 has no influence on the measurements over [t_1, t_2]" in result.output
    record = json.loads(invoke("sequence", str(path), "--json").output)
    assert [s["verdict"] for s in record["steps"]] == [
        "not_identifiable" if k in (2, 6) else "identifiable" for k in range(1, 9)]
    assert record["failing_steps"] == [2, 6]
    np.savez(path, F=F, h=H_PAPER, h_a=H_A)  # one h for all steps, no V_η
    assert json.loads(invoke("sequence", str(path), "--json").output)["failing_steps"] == [2, 6]


@pytest.mark.parametrize("args, text", [
    (("check", "--model", "kalman"), "--model must be one of"),
    (("check", "--model", "ct-omega", "--meas", "pos,az"), "--meas must be"),
    (("check", "--model", "ct-omega", "--state", "1,2,x,4"), "--state must be comma-separated numbers"),
    (("check", "--model", "ca-accel", "--bias", "z"), "--bias takes distinct channels"),
])
def test_bad_check_options_give_one_line_error_and_exit_2(args, text):
    result = invoke(*args)
    assert result.exit_code == 2
    assert text in result.output
    assert "Traceback" not in result.output


def test_sequence_errors_exit_2(tmp_path):
    result = invoke("sequence", str(tmp_path / "missing.npz"))
    assert result.exit_code == 2 and "no such file" in result.output
    path = tmp_path / "no_ha.npz"
    np.savez(path, F=np.repeat(F_TV3[None], 2, axis=0), H=H_PAPER)
    result = invoke("sequence", str(path))
    assert result.exit_code == 2 and "missing arrays h_a" in result.output

"""The study framework (spec 004 R19-R24) through a minimal study: declaration, context, progress, outputs."""

import json

import pandas as pd
import pytest

from skytrack.studies.maneuver.outputs import jsonable
from skytrack.studies.maneuver.study import StudyDefinition, StudyOptions, run_study


def mini(ctx):
    cases = ctx.cases(turn_g=(4.0,))
    summary, runs = ctx.compare(cases, ctx.filters(), keep=True)
    cv = summary[(summary["filter"] == "kf-cv") & (summary["basis"] == "all")].iloc[0]
    ctx.claim_assert("M-peak", "KF-CV peaks in the turn", "e_peak > e_pre", {"e_peak": cv.e_peak_pos, "e_pre": cv.e_pre_pos},
                     cv.e_peak_pos > cv.e_pre_pos)
    ctx.claim_report("M-runs", "runs kept", {"runs": len(runs), "n": ctx.params["n_extra"]})
    with ctx.figure("mini.png", "mini") as (_, axes):
        for label in ("kf-cv", "kf-ca"):
            run = runs[(cases[0].label, label, "off")]
            axes[0].plot(run.time, run.nis.mean(axis=1), label=label)
        axes[0].set_xlabel("time [s]")
        axes[0].set_ylabel("mean NIS")


DEFINITION = StudyDefinition("mini", "a minimal study", mini, default_runs=5, default_filters=("kf-cv", "kf-ca"),
                             params={"n_extra": 1})


def test_a_minimal_study_writes_every_output(tmp_path):
    calls = []
    result = run_study(DEFINITION, StudyOptions(out=tmp_path, config={"gating": ["off", "on"], "study": {"n_extra": 7}}),
                       progress=lambda description, done, total: calls.append((done, total)))
    assert result.asserts_passed and [c.id for c in result.claims] == ["M-peak", "M-runs"]
    assert calls[-1] == (4, 4) and all(done <= total for done, total in calls)  # 2 filters x 2 gating modes
    payload = json.loads((tmp_path / "claims.json").read_text())
    assert payload["options"]["runs"] == 5 and payload["claims"][1]["measured"] == {"runs": 4, "n": 7}
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert set(summary["filter"]) == {"kf-cv", "kf-ca"} and (summary["n"] == 4.0).all()
    assert ((summary["peak_accel_g"] - 4.0).abs() < 1e-9).all()
    figure = json.loads((tmp_path / "figures.json").read_text())[0]
    assert figure["axes"][0]["legend"] == ["kf-cv", "kf-ca"] and figure["axes"][0]["lines"] == 2


def test_figures_must_label_their_axes(tmp_path):
    def unlabelled(ctx):
        with ctx.figure("bad.png", "bad") as (_, axes):
            axes[0].plot([0, 1], [0, 1])

    with pytest.raises(ValueError, match="x and y labels"):
        run_study(StudyDefinition("bad", "bad", unlabelled), StudyOptions(out=tmp_path))


def test_option_errors_name_the_option(tmp_path):
    with pytest.raises(ValueError, match="--config: unknown key"):
        run_study(DEFINITION, StudyOptions(out=tmp_path, config={"runz": 3}))
    with pytest.raises(ValueError, match="gating"):
        run_study(DEFINITION, StudyOptions(out=tmp_path, config={"gating": ["sometimes"]}))
    with pytest.raises(ValueError, match="maneuver_rule"):
        run_study(DEFINITION, StudyOptions(out=tmp_path, config={"maneuver_rule": "fighter"}))
    with pytest.raises(ValueError, match="--seed"):
        run_study(DEFINITION, StudyOptions(out=tmp_path, seed=-1))


def test_json_values():
    import numpy as np

    assert jsonable({"a": np.float64(np.inf), "b": float("nan"), "c": np.arange(2), "d": np.bool_(True)}) == \
        {"a": "inf", "b": None, "c": [0, 1], "d": True}

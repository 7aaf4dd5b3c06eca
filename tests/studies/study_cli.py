"""Shared helpers of the study tests: ``skytrack study NAME ...`` run in-process, its outputs
for the module-scoped ``quick`` fixtures, and ``claims.json`` read back by claim id."""

from __future__ import annotations

import json

import typer
from typer.testing import CliRunner

from skytrack.cli.study import study_app
from skytrack.studies.maneuver.outputs import CLAIMS_NAME

_app = typer.Typer()
_app.add_typer(study_app, name="study")
_runner = CliRunner()


def invoke_study(name: str, *args):
    """The CliRunner result of ``skytrack study NAME ARGS``."""
    return _runner.invoke(_app, ["study", name, *[str(a) for a in args]])


def study_outputs(tmp_path_factory, name: str, *args):
    """The output folder of ``skytrack study NAME ARGS --out DIR`` (which must exit 0)."""
    out = tmp_path_factory.mktemp(name)
    result = invoke_study(name, *args, "--out", str(out))
    assert result.exit_code == 0, result.output
    return out


def claims_of(out):
    """``claims.json`` of an output folder and its claims by id."""
    payload = json.loads((out / CLAIMS_NAME).read_text())
    return payload, {c["id"]: c for c in payload["claims"]}

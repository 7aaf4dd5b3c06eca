"""``skytrack track --config FILE`` and ``--filter``: the file is the base, options typed on the
command line override it, and the result equals the library run with the same configuration."""

from __future__ import annotations

import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.io import read_sensors
from skytrack.tracker import Tracker, TrackerConfig

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    assert invoke("simulate", "crossing", "-o", out).exit_code == 0
    return out


def _library(simulated, config):
    plots = pd.read_parquet(simulated / "plots.parquet")
    return Tracker(read_sensors(simulated / "sensors.json"), config).run(plots)


def test_config_file_with_a_command_line_override(simulated, tmp_path):
    config_path = tmp_path / "tracker.yaml"
    config_path.write_text("lifecycle:\n  confirm_m: 2\n  confirm_n: 3\n  delete_misses: 3\n"
                           "association:\n  p_gate: 0.999\n")
    out = tmp_path / "tracks.parquet"
    result = invoke("track", simulated / "plots.parquet", "--sensors", simulated / "sensors.json", "-o", out,
                    "--config", config_path, "--delete-misses", 4)
    assert result.exit_code == 0, result.output
    expected = _library(simulated, TrackerConfig(confirm_m=2, confirm_n=3, delete_misses=4, p_gate=0.999))
    written = pd.read_parquet(out)
    assert len(written) == len(expected) > 0
    pd.testing.assert_series_equal(written["track_id"], expected["track_id"], check_names=False)


def test_filter_option_selects_a_registered_family(simulated, tmp_path):
    out = tmp_path / "tracks.parquet"
    result = invoke("track", simulated / "plots.parquet", "--sensors", simulated / "sensors.json", "-o", out,
                    "--filter", "imm")
    assert result.exit_code == 0, result.output
    expected = _library(simulated, TrackerConfig(filter_kind="imm"))
    assert len(pd.read_parquet(out)) == len(expected) > 0


def test_bad_config_and_unknown_filter_are_one_line_errors(simulated, tmp_path):
    config_path = tmp_path / "tracker.yaml"
    config_path.write_text("lifecycle:\n  confirm_k: 2\n")
    common = (simulated / "plots.parquet", "--sensors", simulated / "sensors.json", "-o", tmp_path / "t.parquet")
    result = invoke("track", *common, "--config", config_path)
    assert result.exit_code == 2 and "section lifecycle: unknown key(s) ['confirm_k']" in result.output
    result = invoke("track", *common, "--filter", "nope")
    assert result.exit_code == 2 and "unknown filter kind 'nope'" in result.output

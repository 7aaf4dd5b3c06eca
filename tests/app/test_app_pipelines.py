"""The simulate and evaluate pipelines of skytrack.app (the CLI only parses options and prints)."""

from __future__ import annotations

import json

import pytest

from skytrack.app.evaluate import default_metrics_path, run_evaluation
from skytrack.app.run import run_tracking
from skytrack.app.simulate import run_simulation, write_simulation
from skytrack.io import read_plots


def test_simulate_write_track_and_evaluate(tmp_path):
    result = run_simulation("crossing", seed=3)
    paths = write_simulation(result, tmp_path, "csv")
    assert {p.name for p in paths.values()} == {"plots.csv", "truth.csv", "sensors.json"}
    assert len(read_plots(paths["plots"])) == len(result.plots)
    summary = run_tracking(paths["plots"], paths["sensors"], tmp_path / "tracks.parquet")
    done = run_evaluation(tmp_path / "tracks.parquet", paths["truth"])
    assert done.json_path == default_metrics_path(tmp_path / "tracks.parquet") == tmp_path / "tracks_metrics.json"
    metrics = json.loads(done.json_path.read_text())
    assert metrics == json.loads(json.dumps(done.evaluation.to_dict()))
    assert metrics["n_truth_objects"] == result.truth["target_id"].nunique() and summary.track_rows > 0


def test_write_simulation_refuses_an_unknown_format(tmp_path):
    with pytest.raises(ValueError, match="parquet or csv"):
        write_simulation(run_simulation("crossing"), tmp_path, "xls")

"""The evaluation pipeline: a tracks file against a truth file, metrics written as JSON."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass
class EvaluationRun:
    """The evaluation (:class:`skytrack.analysis.Evaluation`) and where its metrics were written."""

    evaluation: Any
    json_path: Path


def default_metrics_path(tracks_path: str | Path) -> Path:
    """``tracks.parquet`` -> ``tracks_metrics.json`` next to it."""
    tracks_path = Path(tracks_path)
    return tracks_path.with_name(tracks_path.name.split(".")[0] + "_metrics.json")


def run_evaluation(
    tracks_path: str | Path,
    truth_path: str | Path,
    *,
    json_out: str | Path | None = None,
    sensors_path: str | Path | None = None,
    cutoff_m: float = 2000.0,
    order: float = 2.0,
    association_gate_m: float = 2000.0,
    start_time_s: float | None = None,
) -> EvaluationRun:
    """Read tracks and truth (FORMATS.md or OpenSky; ``sensors_path`` gives the origin of the
    latter), evaluate (GOSPA/OSPA, RMSE, NEES, continuity, breaks, swaps, false tracks) and
    write the metrics to ``json_out`` (default: :func:`default_metrics_path`)."""
    from skytrack.analysis import evaluate
    from skytrack.io import read_sensors, read_tracks, read_truth, refuse_overwriting
    from skytrack.io.tracks import read_tracks_metadata

    json_path = Path(json_out) if json_out is not None else default_metrics_path(tracks_path)
    refuse_overwriting(json_path, tracks=tracks_path, truth=truth_path, sensors=sensors_path)
    if start_time_s is None:
        # a tracks file of `skytrack track` knows when its input started
        start_time_s = (read_tracks_metadata(tracks_path) or {}).get("input_time_start_s")
    sensor_set = read_sensors(sensors_path) if sensors_path else None
    evaluation = evaluate(
        read_tracks(tracks_path), read_truth(truth_path, sensors=sensor_set), cutoff_m=cutoff_m, order=order,
        association_gate_m=association_gate_m, start_time_s=start_time_s,
    )
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(evaluation.to_dict(), indent=2, allow_nan=False) + "\n")
    return EvaluationRun(evaluation=evaluation, json_path=json_path)

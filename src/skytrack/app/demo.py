"""The demo pipeline: simulate the bundled demo scenario, track it, evaluate it, report.

The report folder holds the simulated inputs (plots, truth, sensors.json), the tracks,
``metrics.json`` (the evaluation plus the demo's acceptance checks), a PPI picture and
OSPA/GOSPA over time.  The acceptance checks are the ones of the foundation issue: every
aircraft that stays in coverage for 2 minutes gets a confirmed track, and the position
RMSE is below the radar's cross-range measurement error at mid range
(``max_range / 2 * sigma_azimuth``).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skytrack.app.run import ProgressCallback, RunSummary, run_tracking
from skytrack.app.simulate import run_simulation, write_simulation

#: an aircraft counts for the tracking check when it is in coverage this long
COVERAGE_MIN_S = 120.0


@dataclass
class DemoResult:
    """Everything the demo produced (the report folder is ``out``)."""

    out: Path
    checks: dict
    tracking: RunSummary
    evaluation: Any
    """:class:`skytrack.analysis.Evaluation` of the tracks against the truth"""
    elapsed_s: float

    @property
    def metrics_path(self) -> Path:
        return self.out / "metrics.json"


def run_demo(
    out: str | Path, scenario: str | Path = "demo", seed: int | None = None, *,
    progress: ProgressCallback | None = None,
) -> DemoResult:
    """Simulate ``scenario``, track and evaluate it, and write the report folder ``out``."""
    from skytrack.analysis import evaluate, plot_metrics_over_time, plot_ppi
    from skytrack.io import read_tracks
    from skytrack.tracker import TrackerConfig

    started = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result = run_simulation(scenario, seed, progress=progress)
    paths = write_simulation(result, out, "parquet")
    summary = run_tracking(
        paths["plots"], paths["sensors"], out / "tracks.parquet", TrackerConfig(full_covariance=True),
        progress=progress,
    )
    tracks = read_tracks(out / "tracks.parquet")
    evaluation = evaluate(
        tracks, result.truth, start_time_s=float(result.plots["time"].min()), coverage_min_visible_s=COVERAGE_MIN_S
    )
    checks = acceptance_checks(evaluation, result)
    metrics = evaluation.to_dict()
    metrics["demo"] = {"scenario": result.scenario.name, "tracking": summary.to_dict(), "checks": checks}
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, allow_nan=False, default=str) + "\n")
    plot_ppi(result.plots, result.truth, tracks, result.sensors, out / "ppi.png")
    plot_metrics_over_time(evaluation, out / "metrics_over_time.png")
    return DemoResult(out=out, checks=checks, tracking=summary, evaluation=evaluation,
                      elapsed_s=time.perf_counter() - started)


def acceptance_checks(evaluation, result) -> dict:
    """The demo's pass/fail checks, with the numbers behind them."""
    import numpy as np

    radar = next(s for s in result.sensors.sensors if s.is_radar)
    # one plot's error across the line of sight at mid range, in the dimensions tracked: azimuth,
    # and elevation too when a 3-D radar's tracks are compared in 3-D
    angle_sigma_deg = radar.sigma_azimuth_deg
    if radar.is_3d and evaluation.dimension == "3-D" and radar.sigma_elevation_deg:
        angle_sigma_deg = math.hypot(radar.sigma_azimuth_deg, radar.sigma_elevation_deg)
    cross_range = radar.max_range_m / 2.0 * math.radians(angle_sigma_deg)
    rmse = evaluation.summary["position_rmse_m"]
    coverage = evaluation.coverage
    tracked = bool(coverage["tracked"].all()) if len(coverage) else True
    assignments = evaluation.assignments
    with_altitude = _targets_with_mode_c(result)
    in_mode_c = assignments["target_id"].isin(with_altitude)
    rmse_mode_c = float(np.sqrt(np.mean(np.square(assignments.loc[in_mode_c, "distance_m"])))) if in_mode_c.any() else float("nan")
    rmse_primary = float(np.sqrt(np.mean(np.square(assignments.loc[~in_mode_c, "distance_m"])))) if (~in_mode_c).any() else float("nan")
    return {
        "aircraft_in_coverage_2min": int(len(coverage)),
        "aircraft_in_coverage_2min_tracked": int(coverage["tracked"].sum()) if len(coverage) else 0,
        "every_aircraft_in_coverage_2min_tracked": tracked,
        "cross_range_sigma_mid_range_m": cross_range,
        "position_rmse_m": _number_or_none(rmse),
        # null when the scenario has no aircraft of that kind (all with Mode C, or none)
        "position_rmse_mode_c_aircraft_m": _number_or_none(rmse_mode_c),
        "position_rmse_primary_only_aircraft_m": _number_or_none(rmse_primary),
        "position_rmse_below_cross_range_sigma": bool(rmse < cross_range),
    }


def _number_or_none(value: float) -> float | None:
    """JSON has no NaN: an undefined figure is written as null."""
    return None if value is None or math.isnan(value) else float(value)


def _targets_with_mode_c(result) -> set:
    plots = result.plots
    has = plots["mode_c_ft"].notna() & (plots["truth_id"] != "")
    return set(plots.loc[has, "truth_id"].unique())

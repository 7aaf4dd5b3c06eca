"""``skytrack demo``: simulate the bundled demo scenario, track it, evaluate it, report.

The report folder holds the simulated inputs (plots, truth, sensors.json), the tracks,
``metrics.json`` (the evaluation plus the demo's acceptance checks), a PPI picture and
OSPA/GOSPA over time.  The acceptance checks printed at the end are the ones of the
foundation issue: every aircraft that stays in coverage for 2 minutes gets a confirmed
track, and the position RMSE is below the radar's cross-range measurement error at mid
range (``max_range / 2 * sigma_azimuth``).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

COVERAGE_MIN_S = 120.0


def run_demo(out: Path, scenario: str, seed: int | None, *, console: Console, progress_factory, print_evaluation) -> dict:
    from skytrack.analysis import evaluate, plot_metrics_over_time, plot_ppi
    from skytrack.cli.main import _run_simulation, run_tracking
    from skytrack.io import read_tracks, write_plots, write_sensors, write_truth
    from skytrack.tracker import TrackerConfig

    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    result = _run_simulation(scenario, seed)
    write_plots(result.plots, out / "plots.parquet", sensors=result.sensors)
    write_truth(result.truth, out / "truth.parquet")
    write_sensors(result.sensors, out / "sensors.json")
    summary = run_tracking(
        out / "plots.parquet", out / "sensors.json", out / "tracks.parquet", TrackerConfig(full_covariance=True)
    )
    tracks = read_tracks(out / "tracks.parquet")
    evaluation = evaluate(
        tracks, result.truth, start_time_s=float(result.plots["time"].min()), coverage_min_visible_s=COVERAGE_MIN_S
    )
    checks = acceptance_checks(evaluation, result)
    metrics = evaluation.to_dict()
    metrics["demo"] = {"scenario": result.scenario.name, "tracking": _jsonable(summary), "checks": checks}
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, allow_nan=False, default=str) + "\n")
    plot_ppi(result.plots, result.truth, tracks, result.sensors, out / "ppi.png")
    plot_metrics_over_time(evaluation, out / "metrics_over_time.png")
    elapsed = time.perf_counter() - started
    print_evaluation(evaluation, out / "metrics.json")
    _print_checks(console, checks, summary, out, elapsed)
    return checks


def acceptance_checks(evaluation, result) -> dict:
    """The demo's pass/fail checks, with the numbers behind them."""
    radar = next(s for s in result.sensors.sensors if s.is_radar)
    cross_range = radar.max_range_m / 2.0 * math.radians(radar.sigma_azimuth_deg)
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
        "position_rmse_m": rmse,
        "position_rmse_mode_c_aircraft_m": rmse_mode_c,
        "position_rmse_primary_only_aircraft_m": rmse_primary,
        "position_rmse_below_cross_range_sigma": bool(rmse < cross_range),
    }


def _targets_with_mode_c(result) -> set:
    plots = result.plots
    has = plots["mode_c_ft"].notna() & (plots["truth_id"] != "")
    return set(plots.loc[has, "truth_id"].unique())


def _jsonable(summary: dict) -> dict:
    return {k: (str(v) if k == "report" else v) for k, v in summary.items()}


def _print_checks(console: Console, checks: dict, summary: dict, out: Path, elapsed: float) -> None:
    def mark(ok: bool) -> str:
        return "[bold green]PASS[/]" if ok else "[bold red]FAIL[/]"

    table = Table(title="demo summary", show_header=False)
    table.add_row(
        "aircraft in coverage >= 2 min with a confirmed track",
        f"{checks['aircraft_in_coverage_2min_tracked']} / {checks['aircraft_in_coverage_2min']}",
        mark(checks["every_aircraft_in_coverage_2min_tracked"]),
    )
    table.add_row(
        "position RMSE vs cross-range sigma at mid range",
        f"{checks['position_rmse_m']:.1f} m < {checks['cross_range_sigma_mid_range_m']:.1f} m",
        mark(checks["position_rmse_below_cross_range_sigma"]),
    )
    table.add_row(
        "  RMSE: aircraft with Mode C / primary-only",
        f"{checks['position_rmse_mode_c_aircraft_m']:.1f} m / {checks['position_rmse_primary_only_aircraft_m']:.1f} m",
        "",
    )
    rate = summary["plots"] / summary["elapsed_s"] if summary["elapsed_s"] > 0 else float("nan")
    table.add_row("tracking throughput", f"{rate:,.0f} plots/s", "")
    table.add_row("report folder", str(out), f"{elapsed:.1f} s")
    console.print(table)

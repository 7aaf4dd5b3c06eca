"""The demo pipeline: simulate the bundled demo scenario, track it, identify the tracks with
ADS-B, evaluate both against the truth, report.

The report folder holds the simulated inputs (plots, truth, sensors.json and, when the scenario
has ADS-B, adsb.parquet), the tracks, ``metrics.json`` (the evaluation plus the demo's
acceptance checks), a PPI picture with the identified tracks' callsigns and OSPA/GOSPA over
time.  The acceptance checks of the foundation issue: every aircraft that stays in coverage
for 2 minutes gets a confirmed track, and the position RMSE is below the radar's cross-range
measurement error at mid range (``max_range / 2 * sigma_azimuth``).

With ADS-B (issue 9, item 7; spec 001 R13 applied to the tracker through
:func:`skytrack.app.run.run_tracking`'s ``adsb_path``) the tracks carry the ``icao24`` and
``callsign`` the sequential test decides for them, and the report folder also holds
``identification.json`` and ``identification_per_aircraft.csv``
(:func:`skytrack.analysis.identification.identification_report` against the truth).  Three
more checks, those of issue 9's acceptance: no track row has a wrong label; every ADS-B-equipped
aircraft without an ADS-B fault that is tracked for :data:`IDENTIFY_WITHIN_S` is identified
correctly (and keeps its label); every aircraft whose simulated ADS-B has a fault (the demo's
2-km position offset) is left unidentified.
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
#: an ADS-B-equipped aircraft tracked this long must be identified (issue 9: 1 minute)
IDENTIFY_WITHIN_S = 60.0
#: the identification report's files in the report folder
IDENTIFICATION_FILES = ("identification.json", "identification_per_aircraft.csv")
#: the pass/fail checks (the other entries of ``checks`` are the numbers behind them); an
#: identification check is null, not failed, when the scenario has no ADS-B
PASS_FAIL_CHECKS = (
    "every_aircraft_in_coverage_2min_tracked",
    "position_rmse_below_cross_range_sigma",
    "identification_no_wrong_label",
    "identification_every_sound_equipped_aircraft_tracked_60s_identified",
    "identification_faulty_adsb_aircraft_left_unidentified",
)


@dataclass
class DemoResult:
    """Everything the demo produced (the report folder is ``out``)."""

    out: Path
    checks: dict
    tracking: RunSummary
    evaluation: Any
    """:class:`skytrack.analysis.Evaluation` of the tracks against the truth"""
    elapsed_s: float
    identification: Any = None
    """:class:`skytrack.analysis.identification.IdentificationReport` (``None`` without ADS-B)"""

    @property
    def metrics_path(self) -> Path:
        return self.out / "metrics.json"

    @property
    def identification_path(self) -> Path | None:
        return None if self.identification is None else self.out / IDENTIFICATION_FILES[0]

    @property
    def passed(self) -> bool:
        """Whether every pass/fail check that applies passed."""
        return checks_passed(self.checks)


def checks_passed(checks: dict) -> bool:
    """The tracking checks passed, and every identification check passed or does not apply (null)."""
    tracking, identification = PASS_FAIL_CHECKS[:2], PASS_FAIL_CHECKS[2:]
    return (all(checks.get(name) is True for name in tracking)
            and all(checks.get(name) in (True, None) for name in identification))


def run_demo(
    out: str | Path, scenario: str | Path = "demo", seed: int | None = None, *,
    progress: ProgressCallback | None = None,
) -> DemoResult:
    """Simulate ``scenario``, track it (labelling the tracks with its ADS-B, when it has some),
    evaluate it, and write the report folder ``out``."""
    from skytrack.analysis import evaluate, plot_metrics_over_time, plot_ppi
    from skytrack.io import read_tracks
    from skytrack.tracker import TrackerConfig

    started = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result = run_simulation(scenario, seed, progress=progress)
    paths = write_simulation(result, out, "parquet")
    if "adsb" not in paths:  # a previous demo's ADS-B and identification do not belong to this run
        for name in ("adsb.parquet", *IDENTIFICATION_FILES):
            (out / name).unlink(missing_ok=True)
    summary = run_tracking(
        paths["plots"], paths["sensors"], out / "tracks.parquet", TrackerConfig(full_covariance=True),
        progress=progress, adsb_path=paths.get("adsb"),
    )
    tracks = read_tracks(out / "tracks.parquet")
    evaluation = evaluate(
        tracks, result.truth, start_time_s=float(result.plots["time"].min()), coverage_min_visible_s=COVERAGE_MIN_S
    )
    checks = acceptance_checks(evaluation, result)
    identification = None
    if "adsb" in paths:
        identification = identify_against_truth(tracks, result)
        checks.update(identification_checks(identification, result))
        _write_identification(identification, out)
    else:
        checks.update({name: None for name in PASS_FAIL_CHECKS[2:]})
    metrics = evaluation.to_dict()
    metrics["demo"] = {"scenario": result.scenario.name, "tracking": summary.to_dict(), "checks": checks,
                       "passed": checks_passed(checks)}
    if identification is not None:
        metrics["demo"]["identification"] = {"totals": identification.totals,
                                             "acceptance": identification.acceptance,
                                             "findings": list(identification.findings)}
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, allow_nan=False, default=str) + "\n")
    plot_ppi(result.plots, result.truth, tracks, result.sensors, out / "ppi.png")
    plot_metrics_over_time(evaluation, out / "metrics_over_time.png")
    return DemoResult(out=out, checks=checks, tracking=summary, evaluation=evaluation,
                      elapsed_s=time.perf_counter() - started, identification=identification)


def identify_against_truth(tracks, result):
    """The identification report of ``tracks`` against the simulation's truth and ADS-B reports;
    the aircraft's own addresses come from the ADS-B simulation's aircraft table (else from the
    targets), so a wrong transmitted address is judged against the true one."""
    from skytrack.analysis.identification import identification_report

    aircraft = result.adsb_aircraft if result.adsb_aircraft is not None else result.targets
    return identification_report(tracks, result.truth, result.adsb, aircraft=aircraft,
                                 min_tracked_s=IDENTIFY_WITHIN_S)


def identification_checks(report, result) -> dict:
    """Issue 9's acceptance on the demo, with the numbers behind it.  The faulty aircraft are
    those the simulation made faulty (``adsb_aircraft.fault``), so that the check cannot pass
    because the report did not notice a fault."""
    totals = report.totals
    acceptance = report.acceptance
    frame = report.per_aircraft
    faulty = _simulated_faults(result)
    judged = frame[frame["target_id"].isin(faulty)]
    left = set(judged.loc[judged["left_unidentified"].astype(bool), "target_id"])
    # aircraft whose own plots carry no Mode S address are identified by the sequential test alone
    plots = result.plots
    with_mode_s = set(plots.loc[plots["mode_s"].notna(), "truth_id"]) if "mode_s" in plots.columns else set()
    sound = frame[frame["adsb_fault"].isna() & frame["tracked_long_enough"].astype(bool)
                  & ~frame["target_id"].isin(with_mode_s)]
    by_test = sound[sound["status"] == "identified"]["time_to_identify_s"]
    return {
        "adsb_equipped_aircraft": int(totals["equipped_aircraft"]),
        "adsb_equipped_tracked_60s": int(totals["tracked_long_enough"]),
        "adsb_sound_equipped_tracked_60s": int(totals["sound_tracked_long_enough"]),
        "sound_identified_correctly": int(totals["sound_identified"]),
        "identified_correctly": int(totals["identified"]),
        "identified_late_or_unstable": int(totals["late"] + totals["unstable"]),
        "not_identified": int(totals["not_identified"]),
        "wrong_label_rows": int(totals["wrong_label_rows"]),
        "wrong_label_tracks": int(totals["wrong_label_tracks"]),
        "median_time_to_identify_s": _number_or_none(totals["median_time_to_identify_s"]),
        "max_time_to_identify_s": _number_or_none(totals["max_time_to_identify_s"]),
        "adsb_sound_tracked_60s_without_mode_s": int(len(sound)),
        "identified_without_mode_s": int(len(by_test)),
        "median_time_to_identify_without_mode_s_s": _number_or_none(float(by_test.median()) if len(by_test) else None),
        "faulty_adsb_aircraft": sorted(faulty),
        "faulty_adsb_aircraft_left_unidentified": sorted(left),
        "identification_no_wrong_label": bool(acceptance["no track row has a wrong label"]),
        "identification_every_sound_equipped_aircraft_tracked_60s_identified":
            bool(acceptance["every sound equipped aircraft tracked long enough is identified"]),
        # an aircraft the simulation made faulty that the report did not judge (never tracked) passes
        "identification_faulty_adsb_aircraft_left_unidentified":
            left == set(judged["target_id"]) and bool(acceptance["every aircraft with faulty ADS-B is left unidentified"]),
    }


def _simulated_faults(result) -> set:
    aircraft = result.adsb_aircraft
    if aircraft is None or "fault" not in aircraft.columns:
        return set()
    fault = aircraft["fault"].astype("string").fillna("").str.strip()
    return set(aircraft.loc[aircraft["equipped"].astype(bool) & (fault != ""), "target_id"].astype(str))


def _write_identification(report, out: Path) -> None:
    """``identification.json`` (the whole report) and ``identification_per_aircraft.csv``."""
    summary_file, table_file = IDENTIFICATION_FILES
    (out / summary_file).write_text(json.dumps(report.to_dict(), indent=2, allow_nan=False, default=str) + "\n")
    report.per_aircraft.to_csv(out / table_file, index=False)


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

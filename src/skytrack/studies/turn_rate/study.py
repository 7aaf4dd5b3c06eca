"""Driver of spec 002 §6 E3/E4 (``skytrack study turn-rate-adaptive``; R11-R14, gap G11): runs, tables, files.

For every sampling period T and measurement set, the five E3 configurations (R14 preset with fixed
V_w, adaptive λ, literal R13) run on the same simulated data, each as one batched
:class:`~skytrack.filters.adaptive_augmented.AdaptiveAugmentedFilter` (rows = Monte Carlo runs);
spec 004's IMM (cv-ct) runs on the position channels of the position-only setups for comparison.
Writes ``turn_rate_adaptive.csv`` (one row per setup × configuration × window, prototype beside each
figure), ``turn_rate_adaptive_checks.csv``, ``turn_rate_adaptive.json`` (summary) and one PNG per setup.
``q_accel = 0`` is E4 (the paper's G = F h_aᵀ noise only, gap G11).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Callable, Optional

import numpy as np
import pandas as pd

from skytrack.studies.fuzzy.common import Check, checks_frame
from skytrack.studies.turn_rate import scenario as sc
from skytrack.studies.turn_rate.figures import figure_name, setup_figure
from skytrack.studies.turn_rate.metrics import Summary, expected_checks, summarize, table_rows
from skytrack.studies.turn_rate.simulation import run_configuration, run_imm, simulate_setup

CSV_NAME = "turn_rate_adaptive.csv"
CHECKS_NAME = "turn_rate_adaptive_checks.csv"
JSON_NAME = "turn_rate_adaptive.json"

#: progress(label of the configuration just finished)
ProgressCallback = Optional[Callable[[str], None]]


@dataclass
class StudyResult:
    summaries: list[Summary]
    table: pd.DataFrame
    checks: list[Check]
    paths: list[Path] = field(default_factory=list)


def job_count(periods, measurements, imm: bool = True) -> int:
    """Number of progress steps: every configuration of every setup, plus one IMM per period."""
    with_imm = imm and "pos" in measurements
    return len(periods) * (len(measurements) * len(sc.CONFIGURATIONS) + (1 if with_imm else 0))


@dataclass(frozen=True)
class ConfigurationTask:
    """One task (issue 11 item 6): one configuration (``None``: the IMM) on one setup's ``runs`` runs."""

    T: float
    measurement: str
    configuration: Optional[sc.Configuration]
    runs: int
    seed: int
    truth_rate: str
    q_accel: float


@lru_cache(maxsize=2)
def _setup(T: float, measurement: str, runs: int, seed: int, truth_rate: str):
    # every configuration of a setup sees the same draws: a worker that gets several simulates once
    return simulate_setup(T, measurement, runs, seed, truth_rate)


def configuration_task(task: ConfigurationTask) -> Summary:
    """The metrics of one configuration on one setup (pure: the task in, a :class:`Summary` out)."""
    times, truth, measurements_k, velocity0 = _setup(task.T, task.measurement, task.runs, task.seed, task.truth_rate)
    if task.configuration is None:
        runset = run_imm(task.T, times, truth, measurements_k, velocity0)
    else:
        runset = run_configuration(task.configuration, task.T, task.measurement, times, truth, measurements_k,
                                   velocity0, task.q_accel)
    return summarize(runset, task.T, task.measurement, task.q_accel)


def run_summaries(runs: int, seed: int, periods, measurements, q_accel: float = sc.PRESET_Q_ACCEL,
                  truth_rate: str = "start", imm: bool = True, configurations=sc.CONFIGURATIONS,
                  progress: ProgressCallback = None, executor=None) -> list[Summary]:
    """The metrics of every (T, measurement set, configuration); no files.  Every configuration of every
    setup is one :class:`ConfigurationTask` mapped over ``executor`` (``None``: in this process);
    ``progress(label)`` after each."""
    from skytrack.studies.parallel import map_tasks

    tasks = []
    for T in periods:
        for measurement in measurements:
            tasks += [ConfigurationTask(T, measurement, config, runs, seed, truth_rate, q_accel)
                      for config in configurations]
            if imm and measurement == "pos":
                tasks.append(ConfigurationTask(T, measurement, None, runs, seed, truth_rate, q_accel))

    def report(done: int, total: int) -> None:
        if progress is not None and done > 0:
            progress(f"{done}/{total} configurations")

    return map_tasks(configuration_task, tasks, executor, report)


def run_study(out: Path, runs: int = 100, seed: int = 1, periods=(1.0, 4.0), measurements=("pos", "pos+rdot"),
              q_accel: float = sc.PRESET_Q_ACCEL, truth_rate: str = "start", imm: bool = True,
              progress: ProgressCallback = None, executor=None) -> StudyResult:
    """Run E3 (``q_accel = 1``) or E4 (``q_accel = 0``) and write CSV, PNG and JSON to ``out``; the tasks run
    on ``executor`` (any ``concurrent.futures`` executor, ``None``: in this process)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summaries = run_summaries(runs, seed, periods, measurements, q_accel, truth_rate, imm, progress=progress,
                              executor=executor)
    table = pd.DataFrame(table_rows(summaries))
    checks = expected_checks(summaries)
    paths = [out / CSV_NAME, out / CHECKS_NAME, out / JSON_NAME]
    table.to_csv(paths[0], index=False)
    checks_frame(checks).to_csv(paths[1], index=False)
    for T in periods:
        for measurement in measurements:
            group = [s for s in summaries if s.T == T and s.measurement == measurement]
            paths.append(setup_figure(group, T, measurement, q_accel, out / figure_name(T, measurement, q_accel)))
    paths[2].write_text(json.dumps(summary_json(summaries, checks, runs, seed, q_accel, truth_rate), indent=2))
    return StudyResult(summaries, table, checks, paths)


def summary_json(summaries: list[Summary], checks: list[Check], runs: int, seed: int, q_accel: float,
                 truth_rate: str) -> dict:
    def clean(values):
        return [None if not np.isfinite(v) else round(float(v), 6) for v in values]

    return {
        "study": "turn-rate-adaptive", "spec": "002 §6 E3/E4", "runs": runs, "seed": seed, "q_accel_m2_s3": q_accel,
        "truth_rate_at": truth_rate, "windows_s": [list(w) for w in sc.WINDOWS], "window_names": list(sc.WINDOW_NAMES),
        "results": [{"T_s": s.T, "measurement": s.measurement, "configuration": s.key,
                     "omega_rmse_deg_s": clean(s.omega_rmse), "position_rmse_m": clean(s.position_rmse),
                     "diverged_pct": s.diverged_pct,
                     "prototype_omega_rmse_deg_s": sc.prototype_omega_rmse(s.T, s.measurement, s.key, q_accel)
                     if s.key != "imm" else None,
                     "prototype_diverged_pct": sc.prototype_divergence(s.T, s.measurement, s.key, q_accel)
                     if s.key != "imm" else None} for s in summaries],
        "checks": [{"name": c.name, "measured": c.measured, "expected": c.expected, "passed": c.passed}
                   for c in checks],
        "passed": all(c.passed for c in checks),
    }

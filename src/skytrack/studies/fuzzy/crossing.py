"""Study E4 of spec 003 (``skytrack study fuzzy-crossing``): two crossing targets of different
nationality seen by an airborne radar, five association methods, IFF errors and interrogation policies.

A configuration (:class:`CrossingCase`) is the E4 reference scenario
(:func:`skytrack.sim.airborne.crossing_scenario`) with one setting changed; each method is a rule
and a mode of the studies' tracker (:mod:`skytrack.studies.fuzzy.paper_tracker`): ``nn``, ``ml``,
``fuzzy``, ``crisp`` greedy (the paper's plot-by-plot processing) and ``fuzzy-global`` (the fuzzy
rule with one assignment per scan).  Every method of a configuration runs on the same simulated
runs, so their differences are paired.  Results (R19,
:func:`skytrack.analysis.association_metrics.association_metrics`): CAR, swap and broken rates
with binomial standard errors, and CAR's standard error over runs (``car_se_runs``: the plots of
one run are not independent, so this is the honest one for comparisons).

Sweeps (§6): S1 policy in {track, always}; S2 (policy ``always``) p_flip = p_code in {0, 0.05,
0.1, 0.2, 0.3} plus one-factor sweeps of each; S3 beta in {5, 10, 20, 45} deg x q in {1, 25};
S4 ``missing_iff`` in {undetermined, neutral} under policy ``track``; and T, the rows of the spec's
indicative table (policy ``track`` with errors 0 and 0.2, policy ``always`` with errors 0-0.3).  :func:`ci_checks` holds the
spec's CI-sized assertions (i)-(iv) and :func:`qualitative_checks` the expected results Q1-Q5.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from typing import Callable, Iterable

import numpy as np
import pandas as pd

from skytrack.analysis.association_metrics import association_metrics
from skytrack.association.features import FeatureTables
from skytrack.association.identity_rules import RuleConfig
from skytrack.sim.airborne import crossing_scenario
from skytrack.studies.fuzzy.paper_tracker import PaperTracker, PaperTrackerConfig, RunDecisions, RunPlots
from skytrack.studies.fuzzy.runs import IffSettings, SimulatedRuns, simulate_runs

#: method name -> (rule, mode)
METHODS: dict[str, tuple[str, str]] = {
    "nn": ("nn", "greedy"), "ml": ("ml", "greedy"), "fuzzy": ("fuzzy", "greedy"),
    "fuzzy-global": ("fuzzy", "global"), "crisp": ("crisp", "greedy"),
}
SWEEPS = ("S1", "S2", "S3", "S4")
#: sweep names: S1-S4 of §6 and T, the configurations of the spec's indicative table
SWEEP_NAMES = SWEEPS + ("T",)
ERROR_RATES = (0.0, 0.05, 0.1, 0.2, 0.3)


@dataclass(frozen=True)
class CrossingCase:
    """One configuration of E4 (the defaults are the reference scenario of §6)."""

    sweep: str = "reference"
    policy: str = "track"
    p_flip: float = 0.0
    p_code: float = 0.0
    p_reply: float = 0.9
    beta_deg: float = 5.0
    q: float = 25.0
    missing_iff: str = "undetermined"
    d_e: float = 0.0
    dh: float = 0.0

    def simulate(self, runs: int, seed: int) -> SimulatedRuns:
        scenario = crossing_scenario(self.beta_deg, self.d_e, self.dh)
        return simulate_runs(scenario, runs, seed, IffSettings(self.p_reply, self.p_flip, self.p_code))

    def tracker(self, method: str) -> PaperTracker:
        rule, mode = METHODS[method]
        config = RuleConfig(rule=rule, mode=mode, tables=FeatureTables(missing_iff=self.missing_iff))
        return PaperTracker(PaperTrackerConfig(rule=config, q=self.q, iff_policy=self.policy))


def sweep_cases(sweeps: Iterable[str] = SWEEPS, base: CrossingCase = CrossingCase()) -> list[CrossingCase]:
    """The configurations of the named sweeps (duplicates across sweeps are kept once each)."""
    cases: list[CrossingCase] = []
    for name in sweeps:
        if name == "S1":
            cases += [replace(base, sweep=name, policy=p) for p in ("track", "always")]
        elif name == "S2":
            cases += [replace(base, sweep=name, policy="always", p_flip=e, p_code=e) for e in ERROR_RATES]
            cases += [replace(base, sweep=name + "-flip", policy="always", p_flip=e) for e in ERROR_RATES[1:]]
            cases += [replace(base, sweep=name + "-code", policy="always", p_code=e) for e in ERROR_RATES[1:]]
        elif name == "S3":
            cases += [replace(base, sweep=name, beta_deg=b, q=q) for b in (5.0, 10.0, 20.0, 45.0) for q in (1.0, 25.0)]
        elif name == "S4":
            cases += [replace(base, sweep=name, missing_iff=m) for m in ("undetermined", "neutral")]
        elif name == "T":
            cases += [replace(base, sweep=name, policy="track", p_flip=e, p_code=e) for e in (0.0, 0.2)]
            cases += [replace(base, sweep=name, policy="always", p_flip=e, p_code=e) for e in ERROR_RATES]
        else:
            raise ValueError(f"unknown sweep {name!r}; sweeps are {', '.join(SWEEP_NAMES)}")
    return cases


def decisions_metrics(decisions: RunDecisions, runs: SimulatedRuns):
    """R19 metrics of one method's decisions on a batch of runs."""
    valid = runs.plots.valid
    run, scan, slot = np.nonzero(valid)
    return association_metrics(run, scan, runs.truth[valid], decisions.track_id[valid], runs.crossing_scan)


@dataclass(frozen=True)
class CrossingTask:
    """One task of E4 (issue 11 item 6): a method on a configuration's ``runs`` runs drawn from ``seed``.

    ``keep_decisions`` returns the method's :class:`RunDecisions` (the TV13 (c) check);
    ``diagnostic_runs`` > 0 returns R13's per-(plot, hypothesis) rows of the first runs."""

    case: CrossingCase
    method: str
    runs: int
    seed: int
    keep_decisions: bool = False
    diagnostic_runs: int = 0


@dataclass
class CrossingResult:
    """What a :class:`CrossingTask` returns: its table row and, when asked, decisions and R13 rows."""

    row: dict
    decisions: RunDecisions | None = None
    diagnostics: pd.DataFrame | None = None


@lru_cache(maxsize=2)
def _simulated(case: CrossingCase, runs: int, seed: int) -> SimulatedRuns:
    # the methods of a case run on the same draws: a worker that gets several of them simulates once
    return case.simulate(runs, seed)


def crossing_task(task: CrossingTask) -> CrossingResult:
    """Track the task's runs with its method and measure R19 (pure: the task in, a result out)."""
    case, method, runs = task.case, task.method, task.runs
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; methods are {', '.join(METHODS)}")
    simulated = _simulated(case, runs, task.seed)
    decisions = case.tracker(method).run(simulated.plots)
    diagnostics = None
    if task.diagnostic_runs > 0:
        tracker = case.tracker(method)
        tracker.diagnostics = True
        table = tracker.run(first_runs(simulated.plots, min(task.diagnostic_runs, runs))).diagnostics
        if table is not None:
            diagnostics = table.assign(method=method, **asdict(case))
    s = decisions_metrics(decisions, simulated).summary
    row = {**asdict(case), "method": method, "runs": runs, "car": s["car"], "car_se": s["car_se"],
           "car_se_runs": s["car_se_runs"],
           "swap": s["swapped"], "swap_se": s["swapped_se"], "broken": s["broken"],
           "broken_se": s["broken_se"], "interrogated": int(decisions.requested.sum()),
           "degenerate_pairs": decisions.degenerate_pairs}
    return CrossingResult(row, decisions if task.keep_decisions else None, diagnostics)


def run_tasks(tasks: list[CrossingTask], executor=None,
              progress: Callable[[int, int], None] | None = None) -> list[CrossingResult]:
    """Map :func:`crossing_task` over ``executor`` (``None``: in this process); results in task order."""
    from skytrack.studies.parallel import map_tasks

    for task in tasks:
        if task.method not in METHODS:
            raise ValueError(f"unknown method {task.method!r}; methods are {', '.join(METHODS)}")
    return map_tasks(crossing_task, tasks, executor, progress)


def run_case(case: CrossingCase, methods: Iterable[str], runs: int, seed: int,
             progress: Callable[[int], None] | None = None, keep: dict | None = None,
             diagnostic_runs: int = 0, diagnostics: list | None = None, executor=None) -> pd.DataFrame:
    """One row per method: the case's settings, ``runs`` and the R19 rates with their SEs.

    ``keep`` (a dict) receives each method's :class:`RunDecisions` (the TV13 (c) check);
    with ``diagnostic_runs`` > 0 the first that many runs are tracked again with R13's
    per-(plot, hypothesis) rows, appended to ``diagnostics`` with the case and the method.
    The methods are :class:`CrossingTask` s mapped over ``executor``; ``progress(1)`` per method."""
    methods = list(methods)
    tasks = [CrossingTask(case, method, runs, seed, keep is not None,
                          diagnostic_runs if diagnostics is not None else 0) for method in methods]
    step = None if progress is None else (lambda done, total: progress(1) if done else None)
    results = run_tasks(tasks, executor, step)
    for method, result in zip(methods, results):
        if keep is not None:
            keep[method] = result.decisions
        if diagnostics is not None and result.diagnostics is not None:
            diagnostics.append(result.diagnostics)
    return pd.DataFrame([result.row for result in results])


def first_runs(plots: RunPlots, count: int) -> RunPlots:
    """The first ``count`` runs of a batch."""
    per_run = ("z", "valid", "own_p", "own_v", "reply_iff", "reply_code")
    return replace(plots, **{name: getattr(plots, name)[:count] for name in per_run})


def run_study(cases: list[CrossingCase], methods: Iterable[str], runs: int, seed: int,
              progress: Callable[[int, int], None] | None = None, executor=None) -> pd.DataFrame:
    """All cases x methods (every case simulated with the same seed: paired comparisons), one task per
    (case, method) mapped over ``executor``; ``progress(done, total)`` as tasks complete."""
    methods = list(methods)
    tasks = [CrossingTask(case, method, runs, seed) for case in cases for method in methods]
    return pd.DataFrame([result.row for result in run_tasks(tasks, executor, progress)])


def cell(table: pd.DataFrame, method: str, **settings) -> pd.Series:
    """The row of ``method`` in the configuration given by ``settings`` (exactly one must match)."""
    mask = table["method"] == method
    for key, value in settings.items():
        mask &= np.isclose(table[key], value) if isinstance(value, float) else table[key] == value
    rows = table[mask]
    if len(rows) == 0:
        raise KeyError(f"no result for {method} with {settings}")
    return rows.iloc[0]

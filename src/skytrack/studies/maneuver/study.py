"""The study framework of spec 004 §6 (R19-R24): how a study is declared, configured, run and written.

A study is a module ``skytrack/studies/maneuver/<name>.py`` holding ``STUDY = StudyDefinition(...)``
and listed in :data:`skytrack.studies.maneuver.names.STUDY_MODULES`; its ``run(ctx)`` function
gets a :class:`StudyContext` and uses it to

* get the cases (``ctx.cases()``: ``--truth`` recorded trajectories, else ``--scenario`` NAME|FILE,
  else the study's default scenario), measurements (``ctx.measurements``: polar by default, or
  Cartesian with a fixed R) and filters (``ctx.filters(...)``: ``--filters`` else the study's
  default labels, from the catalogue of :mod:`skytrack.studies.maneuver.filters` plus the
  study's and the config file's entries);
* run filters (``ctx.run`` for one (case, filter, gating), ``ctx.compare`` for all
  combinations with the R20 metrics added to the summary and time series);
* state claims (``ctx.claim_assert`` / ``ctx.claim_report``) and draw figures (``ctx.figure``);

then :func:`run_study` writes the R23 outputs.  Progress goes to the ``progress(description,
completed, total)`` callback (the CLI shows a rich bar).

Configuration file (``--config``, YAML; every key optional)::

    runs: 200                 # the CLI's --runs / --seed / --scenario / --filters win
    seed: 1
    scenario: default         # named scenario or scenario file
    dt_s: 1.0                 # scan period of named scenarios
    turn_g: [3, 5, 7]         # n of the default / fighter scenarios
    sensor: {sigma_range_m: 25, sigma_azimuth_mrad: 1.5, sigma_elevation_mrad: 1.5}
    maneuver_rule: spec       # spec | airliner | {accel_g, min_duration_s, turn_rate_deg_s, longitudinal_g, merge_gap_s}
    recorded: {origin: {lat: 47.4, lon: 8.5, alt_m: 0}, max_trajectories: 10, min_duration_s: 60, smoothing_lam: null}
    filters: {my-kf: {kind: kalman, motion: {model: dwna, sigma_w: 2}}}
    metrics: {before_s: 20, after_s: 60, pre_s: 10, settle_fraction: 0.2, settle_scans: 5}
    gating: [off, on]
    study: {...}              # the study's own parameters (its ``params``)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.studies.maneuver import outputs
from skytrack.studies.maneuver.filters import CATALOG, FilterSetting, FilterSpec, resolve_filters
from skytrack.studies.maneuver.measurements import MeasurementSet, simulate_measurements
from skytrack.studies.maneuver.metrics import MetricSettings, evaluate_run
from skytrack.studies.maneuver.runner import GATINGS, FilterRun, RunOptions, run_filter
from skytrack.studies.maneuver.scenarios import (
    NAMED_SCENARIOS,
    Case,
    SensorSpec,
    load_scenario_file,
    named_cases,
    recorded_cases,
)
from skytrack.studies.maneuver.segments import RULES, ManeuverRule

DEFAULT_SEED = 1
CONFIG_KEYS = {"runs", "seed", "scenario", "dt_s", "turn_g", "sensor", "maneuver_rule", "recorded", "filters",
               "metrics", "gating", "study"}
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class StudyDefinition:
    """A study of §6: name, claims of the paper it reproduces, defaults and its ``run(ctx)``.

    ``params`` are the study's own parameters (overridden by the config's ``study`` section,
    and by ``quick_params`` under ``--quick``); ``filters`` adds catalogue entries the study
    needs; ``default_filters`` are the labels run when ``--filters`` is not given.
    """

    name: str
    title: str
    run: Callable[["StudyContext"], None]
    paper_claims: str = ""
    default_runs: int = 200
    quick_runs: int = 8
    default_scenario: str = "default"
    default_filters: tuple[str, ...] = ()
    params: dict = field(default_factory=dict)
    quick_params: dict = field(default_factory=dict)
    filters: dict = field(default_factory=dict)


@dataclass(frozen=True)
class StudyOptions:
    """The R24 command-line options (None: take the config file's value, else the study default)."""

    out: Path
    runs: int | None = None
    seed: int | None = None
    scenario: str | None = None
    truth: Path | None = None
    filters: tuple[str, ...] | None = None
    config: dict = field(default_factory=dict)
    quick: bool = False


def load_config(path: str | Path | None) -> dict:
    """The YAML mapping of ``--config`` (empty without a file); unknown top-level keys are errors."""
    if path is None:
        return {}
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--config: no such file {path}")
    with open(path, encoding="utf-8") as handle:
        values = yaml.safe_load(handle) or {}
    if not isinstance(values, dict):
        raise ValueError(f"--config {path}: expected a mapping at the top level")
    unknown = sorted(set(values) - CONFIG_KEYS)
    if unknown:
        raise ValueError(f"--config {path}: unknown key(s) {unknown}; known: {sorted(CONFIG_KEYS)}")
    return values


@dataclass(frozen=True)
class FilterTask:
    """One filter run of :meth:`StudyContext.compare` as a pure task (issue 11 item 6): the case, its
    simulated measurements (every run of the case), the filter and the runner's options in."""

    case: Case
    meas: MeasurementSet
    spec: FilterSpec
    gating: str
    record: bool


def filter_task(task: FilterTask) -> FilterRun:
    """Run the task's filter on every run of its case (:func:`skytrack.studies.maneuver.runner.run_filter`)."""
    case, spec, meas = task.case, task.spec, task.meas
    filt, _ = spec.build(FilterSetting(case.dt, meas.R[0] * spec.r_scale, case.sensor.position))
    return run_filter(filt, case, meas, label=spec.label, options=RunOptions(gating=task.gating, record=task.record),
                      r_scale=spec.r_scale, initiation=spec.initiation)


@dataclass
class StudyContext:
    """What a study's ``run`` uses (module docstring); collects summary, series, claims and figures.

    With an ``executor`` (any ``concurrent.futures`` executor) :meth:`compare` maps its filter runs
    over it as :class:`FilterTask` s; :meth:`run` always runs here."""

    definition: StudyDefinition
    options: StudyOptions
    progress: Progress | None = None
    executor: object = None
    summary: list = field(default_factory=list)
    series: list = field(default_factory=list)
    timing: list = field(default_factory=list)
    claims: list = field(default_factory=list)
    figures: outputs.FigureLog = field(default_factory=outputs.FigureLog)
    _measurements: dict = field(default_factory=dict)
    _done: int = 0
    _total: int = 0

    def __post_init__(self) -> None:
        config = self.options.config
        unknown = sorted(set(config) - CONFIG_KEYS)
        if unknown:
            raise ValueError(f"--config: unknown key(s) {unknown}; known: {sorted(CONFIG_KEYS)}")
        runs = self.options.runs if self.options.runs is not None else config.get("runs")
        if runs is None:
            runs = self.definition.quick_runs if self.options.quick else self.definition.default_runs
        if int(runs) != runs or runs < 1:
            raise ValueError(f"--runs must be a positive integer, got {runs}")
        self.runs = int(runs)
        seed = self.options.seed if self.options.seed is not None else config.get("seed", DEFAULT_SEED)
        if int(seed) != seed or seed < 0:
            raise ValueError(f"--seed must be a non-negative integer, got {seed}")
        self.seed = int(seed)
        study_params = config.get("study") or {}
        unknown = sorted(set(study_params) - set(self.definition.params))
        if unknown:
            raise ValueError(f"--config study: unknown parameter(s) {unknown} for {self.definition.name}; "
                             f"known: {sorted(self.definition.params)}")
        self.params = {**self.definition.params, **(self.definition.quick_params if self.options.quick else {}), **study_params}
        self.metric_settings = MetricSettings.from_dict(config.get("metrics") or {})
        gating = tuple(config.get("gating") or GATINGS)
        if any(g not in GATINGS for g in gating):
            raise ValueError(f"--config gating: values must be from {GATINGS}, got {list(gating)}")
        self.gatings = gating
        rule = config.get("maneuver_rule", "spec")
        if isinstance(rule, str):
            if rule not in RULES:
                raise ValueError(f"--config maneuver_rule: unknown rule {rule!r}; named: {sorted(RULES)}")
            self.maneuver_rule = RULES[rule]
        else:
            self.maneuver_rule = ManeuverRule.from_dict(dict(rule))
        self.catalog = dict(CATALOG)
        self.catalog.update(self.definition.filters)
        for label, values in (config.get("filters") or {}).items():
            self.catalog[label] = FilterSpec.from_dict(label, values)
        self.out = Path(self.options.out)

    # ------------------------------------------------------------------ inputs
    @property
    def quick(self) -> bool:
        return self.options.quick

    def sensor(self, base: SensorSpec | None = None) -> SensorSpec | None:
        values = self.options.config.get("sensor")
        return SensorSpec.from_dict(values, base) if values else base

    def cases(self, default: str | None = None, turn_g: tuple[float, ...] | None = None) -> list[Case]:
        """``--truth`` trajectories, else the ``--scenario`` (name or file), else ``default`` (the study's)."""
        config = self.options.config
        dt = config.get("dt_s")
        dt = None if dt is None else float(dt)
        if self.options.truth is not None:
            rec = dict(config.get("recorded") or {})
            known = {"origin", "max_trajectories", "min_duration_s", "smoothing_lam"}
            if set(rec) - known:
                raise ValueError(f"--config recorded: unknown key(s) {sorted(set(rec) - known)}; known: {sorted(known)}")
            origin = rec.pop("origin", None)
            return recorded_cases(self.options.truth, dt=dt or 1.0, sensor=self.sensor(SensorSpec()), rule=self.maneuver_rule,
                                  origin=None if origin is None else Origin(**origin), **rec)
        name = self.options.scenario or config.get("scenario") or default or self.definition.default_scenario
        if name in NAMED_SCENARIOS:
            n_values = turn_g if turn_g is not None else config.get("turn_g")
            return named_cases(name, dt=dt, sensor=self.sensor(), turn_g=None if n_values is None else tuple(map(float, n_values)))
        return [load_scenario_file(name, dt=dt, sensor=self.sensor())]

    def measurements(self, case: Case, mode: str = "polar", sigma_m: float | None = None) -> MeasurementSet:
        key = (case.scenario, case.label, mode, sigma_m)
        if key not in self._measurements:
            self._measurements[key] = simulate_measurements(case, self.runs, self.seed, mode, sigma_m)
        return self._measurements[key]

    def spec(self, label: str) -> FilterSpec:
        return resolve_filters([label], self.catalog)[0]

    def filters(self, default: tuple[str, ...] | None = None) -> list[FilterSpec]:
        labels = self.options.filters or (default if default is not None else self.definition.default_filters)
        return resolve_filters(labels, self.catalog)

    # ------------------------------------------------------------------ running
    def expect(self, units: int) -> None:
        """Announce ``units`` more filter runs to the progress display."""
        self._total += int(units)
        self._report("")

    def advance(self, description: str, units: int = 1) -> None:
        """Count ``units`` finished units of work (announced by :meth:`expect`) of a study that runs
        its own loops instead of :meth:`run` / :meth:`compare`, and show ``description``."""
        self._done += int(units)
        self._total = max(self._total, self._done)
        self._report(description)

    def _report(self, description: str) -> None:
        if self.progress is not None:
            self.progress(description, self._done, max(self._total, self._done))

    def run(self, case: Case, spec: FilterSpec, *, gating: str = "off", record: bool = False, mode: str = "polar",
            sigma_m: float | None = None) -> FilterRun:
        """Run one filter on every run of ``case`` (:func:`skytrack.studies.maneuver.runner.run_filter`)."""
        if self._done >= self._total:
            self._total = self._done + 1
        self._report(f"{spec.label} · {case.label} · gating {gating}")
        result = filter_task(FilterTask(case, self.measurements(case, mode, sigma_m), spec, gating, record))
        self._done += 1
        self._report(f"{spec.label} · {case.label} · gating {gating}")
        self._time(result, case, spec, gating, mode, record)
        return result

    def _time(self, result: FilterRun, case: Case, spec: FilterSpec, gating: str, mode: str, record: bool) -> None:
        if gating == "off":
            self.timing.append({"case": case.label, "filter": spec.label, "measurement": mode, "recorded": record,
                                "runs": self.runs, "scans": case.scans, "us_per_update": result.us_per_update,
                                "madds_per_update": result.madds_per_update})

    def _run_all(self, cases: list[Case], specs: list[FilterSpec], gatings: tuple[str, ...], mode: str,
                 sigma_m: float | None, record: bool) -> list[FilterRun]:
        """Every (case, filter, gating) run in this order, on ``self.executor`` when there is one."""
        keys = [(case, spec, g) for case in cases for spec in specs for g in gatings]
        if self.executor is None:
            return [self.run(c, s, gating=g, record=record, mode=mode, sigma_m=sigma_m) for c, s, g in keys]
        from skytrack.studies.parallel import map_tasks

        tasks = [FilterTask(c, self.measurements(c, mode, sigma_m), s, g, record) for c, s, g in keys]
        start = self._done

        def report(done: int, total: int) -> None:
            self._done = start + done
            self._report(f"{done}/{total} filter runs")

        results = map_tasks(filter_task, tasks, self.executor, report)
        for (c, s, g), result in zip(keys, results):
            self._time(result, c, s, g, mode, record)
        return results

    def compare(self, cases: list[Case], specs: list[FilterSpec], *, gatings: tuple[str, ...] | None = None,
                mode: str = "polar", sigma_m: float | None = None, record: bool = False,
                keep: bool = False) -> tuple[pd.DataFrame, dict]:
        """Every filter on every case in each gating mode; R20 metrics added to the outputs.

        Metrics come from the ``off`` run (the loss rate of each mode is attached); returns the
        summary rows of this comparison and, with ``keep``, the runs by (case, filter, gating).
        """
        gatings = tuple(gatings or self.gatings)
        self.expect(len(cases) * len(specs) * len(gatings))
        rows, kept = [], {}
        done = iter(self._run_all(cases, specs, gatings, mode, sigma_m, record))
        for case in cases:
            for spec in specs:
                runs = {g: next(done) for g in gatings}
                loss = {g: float(r.lost.mean()) for g, r in runs.items()}
                main = runs.get("off") or next(iter(runs.values()))
                summary, series = evaluate_run(case, main, self.metric_settings, loss)
                for row in summary:
                    row["measurement"] = mode
                rows.extend(summary)
                self.series.extend(series)
                if keep:
                    kept.update({(case.label, spec.label, g): r for g, r in runs.items()})
        self.summary.extend(rows)
        return pd.DataFrame(rows), kept

    # ------------------------------------------------------------------ outputs
    def add_summary(self, rows) -> None:
        self.summary.extend(rows.to_dict("records") if isinstance(rows, pd.DataFrame) else rows)

    def add_series(self, frame: pd.DataFrame) -> None:
        missing = [c for c in outputs.TIMESERIES_COLUMNS if c not in frame.columns]
        if missing:
            raise ValueError(f"time series frame lacks {missing}")
        self.series.append(frame.loc[:, list(outputs.TIMESERIES_COLUMNS)])

    def claim_assert(self, id: str, description: str, criterion: str, measured: dict, passed: bool, paper: str = "") -> bool:
        """Record an ``assert`` claim; its verdict is ``passed`` unless a measured number is not finite."""
        numbers = [v for v in _flat_numbers(measured)]
        verdict = outputs.finite_verdict(passed, *numbers) if numbers else bool(passed)
        self.claims.append(outputs.Claim(id, "assert", description, measured, criterion, verdict, paper))
        return verdict

    def claim_report(self, id: str, description: str, measured: dict, paper: str = "") -> None:
        self.claims.append(outputs.Claim(id, "report", description, measured, "", None, paper))

    def figure(self, name: str, title: str, nrows: int = 1, ncols: int = 1, **kwargs):
        """``with ctx.figure("x.png", "title") as (fig, axes): ...`` (see :class:`outputs.FigureLog`)."""
        if not name.endswith(".png"):
            raise ValueError(f"figure names end in .png, got {name!r}")
        return self.figures.figure(self.out / name, title, nrows, ncols, **kwargs)

    def series_frame(self) -> pd.DataFrame:
        return pd.concat(self.series, ignore_index=True) if self.series else pd.DataFrame(columns=list(outputs.TIMESERIES_COLUMNS))

    def option_record(self) -> dict:
        return {"runs": self.runs, "seed": self.seed, "quick": self.quick, "scenario": self.options.scenario,
                "truth": self.options.truth, "filters": self.options.filters, "params": self.params}


def _flat_numbers(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _flat_numbers(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            yield from _flat_numbers(v)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield value
    elif hasattr(value, "dtype") and getattr(value, "ndim", 1) == 0:
        yield float(value)


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run_study` wrote and whether every assert passed."""

    out: Path
    claims: list
    paths: dict

    @property
    def asserts_passed(self) -> bool:
        return all(c.verdict for c in self.claims if c.kind == "assert")

    @property
    def failed(self) -> list:
        return [c for c in self.claims if c.kind == "assert" and not c.verdict]


def run_study(definition: StudyDefinition, options: StudyOptions, progress: Progress | None = None,
              executor=None) -> StudyResult:
    """Run a study and write its outputs (R23) into ``options.out``; its filter comparisons run on
    ``executor`` (any ``concurrent.futures`` executor, ``None``: in this process)."""
    ctx = StudyContext(definition, options, progress, executor)
    ctx.out.mkdir(parents=True, exist_ok=True)
    definition.run(ctx)
    out = ctx.out
    paths = {
        "summary": outputs.write_summary(ctx.summary, out / outputs.SUMMARY_NAME),
        "timeseries": outputs.write_timeseries(ctx.series, out / outputs.TIMESERIES_NAME),
        "timing": outputs.write_summary(ctx.timing, out / outputs.TIMING_NAME),
        "claims": outputs.write_claims(definition.name, ctx.option_record(), ctx.claims, out / outputs.CLAIMS_NAME),
        "figures": outputs.write_figure_log(ctx.figures, out / outputs.FIGURES_NAME),
    }
    return StudyResult(out, list(ctx.claims), paths)



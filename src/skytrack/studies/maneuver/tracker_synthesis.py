"""Study E10 ``tracker-synthesis`` of spec 004 §6: the paper's conclusions P12 (1)-(3).  All claims are reports.

(1) Observation and state components: the radar's radial velocity (Doppler range rate) added
    to the converted position measurement (EKF through
    ``ConvertedPositionModel(3, order, range_rate_sigma)``, measurement mode ``polar_doppler``:
    the same polar plots as ``polar`` plus ``rdot`` with sigma ``range_rate_sigma_mps``), for the
    CV, CA and Singer states (catalogue kf-cv, kf-ca, kf-singer; ``--filters`` replaces them) on
    the study's cases (default scenario, n = 3, 5, 7): RMS position and velocity error, peak,
    NEES and loss with and without the range rate.  Both variants run through
    :func:`run_measured` (two-point start, every measurement used, loss on 3 consecutive NIS of
    the full measurement beyond ``chi2_m^-1(0.9999)``), which without range rate reproduces the
    study runner.
(2) Model set per situation: the IMM sets ``cv-ca``, ``cv-ct``, ``full`` (catalogue, m = 3) on the
    scenario classes cruise (straight 120 s), turn (default scenario, ``turn_g``), weave and
    vertical (plus ``--scenario`` / ``--truth`` cases as a class ``given``); the best set per class
    by the RMS position error over the whole case (mean over the class's cases) and by the peak.
(3) Prior (expert) manoeuvre data: the IMM set up from a manoeuvre library
    (:mod:`skytrack.studies.maneuver.maneuver_library`: CT rates omega = n g0 / V, Markov matrix
    from durations and frequencies) against the generic ``imm-cv-ca`` on ``draws`` scenarios drawn
    from the same library and from another one (the shipped ``strike`` and ``transport`` by
    default; the other library's IMM runs too, so the table is symmetric).

Parameters (config ``study`` section): ``range_rate_sigma_mps`` (1), ``turn_g`` ([3, 5, 7]),
``model_sets`` (["cv-ca", "cv-ct", "full"]), ``cruise_s`` (120), ``library`` ("strike"),
``other_library`` ("transport"), ``draws`` (3), ``scenario_duration_s`` (300),
``generic_filter`` ("imm-cv-ca"), ``warmup_s`` (10: whole-case metrics start this long after the
filter's first update, past the two-point start's transient).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd
from scipy.stats import chi2

from skytrack.core import linalg
from skytrack.models.converted import ConvertedPositionModel
from skytrack.studies.maneuver.filters import FilterSetting, FilterSpec
from skytrack.studies.maneuver.maneuver_library import DrawSettings, draw_case, library_imm, library_transition, load_library
from skytrack.studies.maneuver.measurements import MeasurementSet, simulate_measurements
from skytrack.studies.maneuver.metrics import evaluate_run
from skytrack.studies.maneuver.outputs import colours, plot_aligned_rms
from skytrack.studies.maneuver.runner import (
    FIRST_SCAN,
    GATE_PROBABILITY,
    LOSS_SCANS,
    NDIM,
    FilterRun,
    RunOptions,
    quadratic_form,
    run_filter,
    truth_state,
    two_point_initiation,
)
from skytrack.studies.maneuver.scenarios import (
    DEFAULT_START_POSITION,
    DEFAULT_START_VELOCITY,
    Case,
    SensorSpec,
    named_cases,
    scripted_case,
)
from skytrack.studies.maneuver.study import StudyContext, StudyDefinition
from skytrack.studies.maneuver.trajectory import straight

STATE_FILTERS = ("kf-cv", "kf-ca", "kf-singer")
CLASSES = ("cruise", "turn", "weave", "vertical")
PARAMS = {
    "range_rate_sigma_mps": 1.0,
    "turn_g": [3.0, 5.0, 7.0],
    "model_sets": ["cv-ca", "cv-ct", "full"],
    "cruise_s": 120.0,
    "library": "strike",
    "other_library": "transport",
    "draws": 3,
    "scenario_duration_s": 300.0,
    "generic_filter": "imm-cv-ca",
    "warmup_s": 10.0,
}
QUICK_PARAMS = {"turn_g": [5.0], "draws": 1, "scenario_duration_s": 150.0, "cruise_s": 60.0}


# ---------------------------------------------------------------------------- (1) range rate
def run_measured(spec: FilterSpec, case: Case, meas: MeasurementSet, *, range_rate: bool, label: str | None = None,
                 gate_probability: float = GATE_PROBABILITY, loss_scans: int = LOSS_SCANS) -> FilterRun:
    """One filter over every run of ``case`` with position measurements, plus the range rate when
    ``range_rate`` (EKF through :class:`ConvertedPositionModel` with ``range_rate_sigma``).

    The runner's protocol with gating off: two-point start from the positions of scans 0 and 1,
    every measurement used; ``nis`` is the filter's own ``d^2`` of the full measurement and a run is
    lost when it exceeds ``chi2_m^-1(gate_probability)`` on ``loss_scans`` consecutive scans.
    """
    if range_rate and meas.range_rate is None:
        raise ValueError(f"filter {spec.label!r}: range rate needs polar_doppler measurements, got {meas.mode!r}")
    R = meas.R * spec.r_scale
    filt, motion = spec.build(FilterSetting(case.dt, R[0], case.sensor.position))
    order = filt.state_dim // NDIM
    model = ConvertedPositionModel(NDIM, order, range_rate_sigma=meas.range_rate_sigma if range_rate else None)
    runs, scans = meas.runs, meas.scans
    extra = {}
    if range_rate:
        extra = {"has_range_rate": np.ones(runs, dtype=bool), "sensor_position": np.asarray(case.sensor.position, float),
                 "rotation": np.eye(3), "sensor_velocity": np.zeros(3)}
    gate = float(chi2.ppf(gate_probability, model.dim))
    pos = np.arange(NDIM) * order
    pv = np.sort(np.concatenate([pos, pos + 1]))
    truth = truth_state(case, order)
    nan = np.full((scans, runs), np.nan)
    pos_err, vel_err = np.full((scans, runs, NDIM), np.nan), np.full((scans, runs, NDIM), np.nan)
    nees, nis = nan.copy(), nan.copy()
    in_gate, used = np.zeros((scans, runs), bool), np.zeros((scans, runs), bool)
    madds, wall = np.full(scans, np.nan), np.full(scans, np.nan)
    x0, P0 = two_point_initiation(meas.z[0], meas.z[1], R[0], R[1], case.truth.time[1] - case.truth.time[0], order)
    state = filt.initiate(x0, P0)
    for k in range(FIRST_SCAN, scans):
        z = meas.z[k] if not range_rate else np.concatenate([meas.z[k], meas.range_rate[k][:, None]], axis=1)
        started = time.perf_counter()
        with linalg.counting() as ops:
            predicted = filt.predict(state, np.full(runs, case.truth.time[k] - case.truth.time[k - 1]))
            innovation = filt.innovate(predicted, z, model, {"R": R[k], **extra})
            state, _ = filt.update(predicted, z, innovation)
        wall[k] = (time.perf_counter() - started) / runs * 1e6
        madds[k] = ops.madds / runs
        nis[k] = innovation.d2
        in_gate[k] = innovation.d2 <= gate
        used[k] = True
        out = state.estimate()
        err = out.x - truth[k]
        pos_err[k], vel_err[k] = err[:, pos], err[:, pos + 1]
        nees[k] = quadratic_form(err[:, pv], out.P[:, pv[:, None], pv[None, :]])
    lost, loss_scan = _loss(~in_gate, loss_scans)
    return FilterRun(label or spec.label, getattr(filt, "kind", type(filt).__name__), case.label, "off", order, "gaussian",
                     case.truth.time, pos_err, vel_err, nees, nis, np.full((scans, runs), np.nan), in_gate, used,
                     np.full((scans, runs), np.nan), lost, loss_scan, madds, wall, [[] for _ in range(scans)])


def _loss(outside: np.ndarray, loss_scans: int) -> tuple[np.ndarray, np.ndarray]:
    """Per run: lost (``outside`` on ``loss_scans`` consecutive scans from the filter's start) and that scan (-1)."""
    count = np.zeros(outside.shape[1], dtype=np.int64)
    loss_scan = np.full(outside.shape[1], -1, dtype=np.int64)
    for k in range(FIRST_SCAN, outside.shape[0]):
        count = np.where(outside[k], count + 1, 0)
        loss_scan[(count >= loss_scans) & (loss_scan < 0)] = k
    return loss_scan >= 0, loss_scan


def case_metrics(case: Case, run: FilterRun, warmup_s: float) -> dict:
    """Whole-case metrics over all runs, from ``warmup_s`` after the filter's start: RMS position and
    velocity error (root mean square over scans of the per-scan RMS over runs), the radial part of
    the velocity error (along the radar's line of sight), the peak per-scan RMS position error, the
    RMS over the manoeuvre scans (NaN without one), mean NEES and the loss rate."""
    t = case.truth.time
    valid = (np.arange(case.scans) >= FIRST_SCAN) & (t >= t[FIRST_SCAN] + warmup_s - 1e-9)
    man = valid & np.any([(t >= a - 1e-9) & (t <= b + 1e-9) for a, b in case.maneuvers] or [np.zeros_like(valid)], axis=0)
    ms_pos = np.mean(np.sum(run.position_error**2, axis=-1), axis=1)
    ms_vel = np.mean(np.sum(run.velocity_error**2, axis=-1), axis=1)
    los = case.truth.position - np.asarray(case.sensor.position, dtype=float)
    los /= np.linalg.norm(los, axis=-1, keepdims=True)
    ms_radial = np.mean(np.einsum("kri,ki->kr", run.velocity_error, los) ** 2, axis=1)
    nees = run.nees[valid]
    return {"rms_pos_m": float(np.sqrt(ms_pos[valid].mean())), "rms_vel_mps": float(np.sqrt(ms_vel[valid].mean())),
            "rms_radial_vel_mps": float(np.sqrt(ms_radial[valid].mean())),
            "rms_cross_vel_mps": float(np.sqrt(ms_vel[valid].mean() - ms_radial[valid].mean())),
            "peak_pos_m": float(np.sqrt(ms_pos[valid].max())),
            "maneuver_rms_pos_m": float(np.sqrt(ms_pos[man].mean())) if man.any() else math.nan,
            "maneuver_rms_vel_mps": float(np.sqrt(ms_vel[man].mean())) if man.any() else math.nan,
            "nees_mean": float(np.nanmean(nees)) if np.isfinite(nees).any() else math.nan,
            "loss_rate": float(run.lost.mean())}


def _record(ctx: StudyContext, case: Case, run: FilterRun, mode: str) -> list[dict]:
    rows, series = evaluate_run(case, run, ctx.metric_settings, {"off": float(run.lost.mean())})
    for row in rows:
        row["measurement"] = mode
    ctx.add_summary(rows)
    ctx.series.extend(series)
    ctx.timing.append({"case": case.label, "filter": run.label, "measurement": mode, "recorded": False, "runs": run.runs,
                       "scans": case.scans, "us_per_update": run.us_per_update, "madds_per_update": run.madds_per_update})
    return rows


def _onset_metrics(rows: list[dict]) -> dict:
    """R20 e_pre (first onset) and e_peak (largest over the onsets) of the ``all`` basis."""
    rows = [r for r in rows if r["basis"] == "all"]
    onsets = [r for r in rows if r["onset"] >= 0] or rows
    return {"e_pre_pos": onsets[0]["e_pre_pos"], "e_pre_vel": onsets[0]["e_pre_vel"],
            "e_peak_pos": max(r["e_peak_pos"] for r in onsets)}


def _part_doppler(ctx: StudyContext) -> None:
    sigma = float(ctx.params["range_rate_sigma_mps"])
    warmup = float(ctx.params["warmup_s"])
    cases = ctx.cases("default", turn_g=_turn_g(ctx))
    specs = ctx.filters(STATE_FILTERS)
    measured = {}
    for case in cases:
        meas = simulate_measurements(case, ctx.runs, ctx.seed, "polar_doppler", range_rate_sigma=sigma)
        for spec in specs:
            entry = {}
            for with_rdot, name in ((False, spec.label), (True, f"{spec.label} +rdot")):
                run = run_measured(spec, case, meas, range_rate=with_rdot, label=name)
                rows = _record(ctx, case, run, "polar_doppler" if with_rdot else "polar")
                entry["with_range_rate" if with_rdot else "position_only"] = {
                    **case_metrics(case, run, warmup), **_onset_metrics(rows), "madds_per_update": run.madds_per_update}
            a, b = entry["position_only"], entry["with_range_rate"]
            for key in ("rms_pos_m", "rms_vel_mps", "rms_radial_vel_mps", "rms_cross_vel_mps"):
                entry[f"reduction_{key}"] = 1.0 - b[key] / a[key]
            measured[f"{case.label} {spec.label}"] = entry
    ctx.claim_report("E10-1-range-rate", f"observation components: Doppler range rate (sigma {sigma:g} m/s) added to the "
                     f"converted position, per motion state: whole-case RMS from {warmup:g} s (velocity split into the "
                     "radial and cross-range parts), e_pre and peak, NEES, loss, multiply-adds", measured, "P12(1)")
    focus = _focus_case(cases)
    labels = [name for spec in specs for name in (spec.label, f"{spec.label} +rdot")]
    plot_aligned_rms(ctx.figures, ctx.out / "tracker_synthesis_range_rate.png",
                     _aligned(ctx, focus.label, labels), f"E10(1): with and without range rate, {focus.label}", filters=labels)


def _aligned(ctx: StudyContext, case_label: str, filters: list[str]) -> pd.DataFrame:
    frame = ctx.series_frame()
    return frame[(frame["case"] == case_label) & (frame["filter"].isin(filters))]


def _focus_case(cases: list[Case]) -> Case:
    return next((c for c in cases if abs(float(c.params.get("n", 0)) - 5.0) < 1e-9), cases[0])


def _turn_g(ctx: StudyContext):
    config = ctx.options.config
    if ctx.options.truth is not None or ctx.options.scenario is not None or "scenario" in config or "turn_g" in config:
        return None
    return tuple(float(n) for n in ctx.params["turn_g"])


# ---------------------------------------------------------------------------- (2) model set per situation
def scenario_classes(ctx: StudyContext) -> dict[str, list[Case]]:
    """The scenario classes of (2): cruise, turn, weave, vertical (and ``given`` for --scenario / --truth)."""
    config = ctx.options.config
    dt = config.get("dt_s")
    dt = 1.0 if dt is None else float(dt)
    sensor = ctx.sensor(SensorSpec())
    turn_g = config.get("turn_g") or ctx.params["turn_g"]
    classes = {
        "cruise": [scripted_case("cruise", "cruise", DEFAULT_START_POSITION, DEFAULT_START_VELOCITY,
                                 [straight(float(ctx.params["cruise_s"]))], dt, sensor)],
        "turn": named_cases("default", dt=dt, sensor=sensor, turn_g=tuple(float(n) for n in turn_g)),
        "weave": named_cases("weave", dt=dt, sensor=sensor),
        "vertical": named_cases("vertical", dt=dt, sensor=sensor),
    }
    if ctx.options.truth is not None or ctx.options.scenario is not None or "scenario" in config:
        classes["given"] = ctx.cases()
    return classes


def _part_model_sets(ctx: StudyContext) -> None:
    sets = [f"imm-{name}" for name in ctx.params["model_sets"]]
    specs = [ctx.spec(label) for label in sets]
    classes = scenario_classes(ctx)
    warmup = float(ctx.params["warmup_s"])
    measured, table = {}, {}
    for name, cases in classes.items():
        _, kept = ctx.compare(cases, specs, gatings=("off",), keep=True)
        metrics = {(case.label, spec.label): case_metrics(case, kept[(case.label, spec.label, "off")], warmup)
                   for case in cases for spec in specs}
        per_set = {spec.label: _mean_metrics([metrics[(case.label, spec.label)] for case in cases]) for spec in specs}
        best_rms = min(per_set, key=lambda label: per_set[label]["rms_pos_m"])
        best_peak = min(per_set, key=lambda label: per_set[label]["peak_pos_m"])
        per_case = {case.label: min((spec.label for spec in specs), key=lambda label: metrics[(case.label, label)]["rms_pos_m"])
                    for case in cases}
        measured[name] = {"cases": [c.label for c in cases], "sets": per_set, "best_by_rms": best_rms,
                          "best_by_peak": best_peak, "best_by_rms_per_case": per_case}
        table[name] = per_set
    ctx.claim_report("E10-2-model-set-per-class", f"IMM model set per scenario class: whole-case metrics from {warmup:g} s "
                     "(mean over the class's cases; RMS, manoeuvre RMS, peak, NEES, loss); the best set by RMS and by peak",
                     measured, "P12(2)")
    names = list(table)
    palette = colours(len(specs))
    with ctx.figure("tracker_synthesis_model_sets.png", "E10(2): IMM model set per scenario class", 1, 2) as (_, axes):
        x = np.arange(len(names))
        for i, spec in enumerate(specs):
            axes[0].plot(x, [table[n][spec.label]["rms_pos_m"] for n in names], "o-", color=palette[i], label=spec.label)
            axes[1].plot(x, [table[n][spec.label]["peak_pos_m"] for n in names], "o-", color=palette[i], label=spec.label)
        for ax, label in zip(axes, (f"RMS position error from {warmup:g} s [m]", "peak RMS position error [m]")):
            ax.set_xticks(x, names)
            ax.set_xlabel("scenario class")
            ax.set_ylabel(label)


# ---------------------------------------------------------------------------- (3) manoeuvre library
def _libraries(ctx: StudyContext):
    """The study's two manoeuvre libraries (checked before any filter runs)."""
    p = ctx.params
    home, other = load_library(p["library"]), load_library(p["other_library"])
    if home.name == other.name:
        raise ValueError(f"--config study: library and other_library must differ, both are {home.name!r}")
    if int(p["draws"]) != p["draws"] or p["draws"] < 1:
        raise ValueError(f"--config study: draws must be an integer >= 1, got {p['draws']}")
    return home, other


def _part_library(ctx: StudyContext, home, other) -> None:
    p = ctx.params
    draws = int(p["draws"])
    dt = float(ctx.options.config.get("dt_s") or 1.0)
    settings = DrawSettings(duration_s=float(p["scenario_duration_s"]))
    sensor = ctx.sensor(SensorSpec())
    cases = {lib.name: [draw_case(lib, i, ctx.seed, draws, dt, sensor, settings) for i in range(draws)] for lib in (home, other)}
    generic = ctx.spec(str(p["generic_filter"]))
    informed = {f"imm-library-{lib.name}": lib for lib in (home, other)}
    results: dict = {}
    for source, group in cases.items():
        for case in group:
            meas = ctx.measurements(case, "polar")
            for label, lib in informed.items():
                run = run_filter(library_imm(lib, case.dt), case, meas, label=label, options=RunOptions(gating="off"))
                results[(source, case.label, label)] = (run, _record(ctx, case, run, "polar"))
            summary, kept = ctx.compare([case], [generic], gatings=("off",), keep=True)
            results[(source, case.label, generic.label)] = (kept[(case.label, generic.label, "off")],
                                                              summary.to_dict("records"))
    filters = [*informed, generic.label]
    warmup = float(p["warmup_s"])
    measured = {"libraries": {lib.name: _library_summary(lib, dt) for lib in (home, other)}}
    for source, group in cases.items():
        block = {label: _mean_metrics([case_metrics(c, results[(source, c.label, label)][0], warmup) for c in group])
                 for label in filters}
        own = f"imm-library-{source}"
        block["informed_vs_generic_rms_reduction"] = 1.0 - block[own]["rms_pos_m"] / block[generic.label]["rms_pos_m"]
        block["cases"] = [c.label for c in group]
        measured[f"scenarios from {source}"] = block
    ctx.claim_report("E10-3-library-informed-imm", f"IMM set up from a manoeuvre library vs the generic {generic.label}, on "
                     f"scenarios drawn from {home.name} (the library's own) and from {other.name} (a different one); "
                     f"mean over draws of the whole-case metrics from {warmup:g} s (RMS, manoeuvre RMS, peak, NEES, loss)",
                     measured, "P12(3)")
    _plot_library(ctx, cases, filters, results, warmup)


def _mean_metrics(items: list[dict]) -> dict:
    """Mean of each metric over cases (NaN entries skipped; the peak is the largest)."""
    out = {}
    for key in items[0]:
        values = np.array([item[key] for item in items], dtype=float)
        finite = values[np.isfinite(values)]
        out[key] = math.nan if not finite.size else float(finite.max() if key == "peak_pos_m" else finite.mean())
    return out


def _library_summary(library, dt: float) -> dict:
    Pi = library_transition(library, dt)
    return {"speed_mps": library.speed_mps, "straight_sojourn_s": library.straight_sojourn_s,
            "turn_rates_deg_s": [math.degrees(library.turn_rate(m)) for m in library.maneuvers if m.type == "turn"],
            "modes": int(len(Pi)), "pi_diagonal": np.diag(Pi).tolist()}


def _plot_library(ctx, cases, filters, results, warmup: float) -> None:
    palette = colours(len(filters))
    sources = list(cases)
    with ctx.figure("tracker_synthesis_library.png", "E10(3): library-informed IMM vs generic IMM", 1, 1 + len(sources)) as (_, axes):
        x = np.arange(len(sources))
        for i, label in enumerate(filters):
            values = [np.mean([case_metrics(c, results[(s, c.label, label)][0], warmup)["rms_pos_m"] for c in cases[s]])
                      for s in sources]
            axes[0].plot(x, values, "o-", color=palette[i], label=label)
        axes[0].set_xticks(x, [f"from {s}" for s in sources])
        axes[0].set_xlabel("scenarios drawn from library")
        axes[0].set_ylabel(f"RMS position error from {warmup:g} s, mean over draws [m]")
        for ax, source in zip(axes[1:], sources):
            case = cases[source][0]
            for i, label in enumerate(filters):
                run = results[(source, case.label, label)][0]
                ax.plot(case.truth.time, np.sqrt(np.mean(np.sum(run.position_error**2, axis=-1), axis=1)), color=palette[i],
                        label=label)
            for onset, end in case.maneuvers:
                ax.axvspan(onset, end, color="grey", alpha=0.15)
            ax.set_title(case.label)
            ax.set_xlabel("time [s] (shaded: manoeuvres)")
            ax.set_ylabel("RMS position error [m]")
            ax.set_yscale("log")


def run(ctx: StudyContext) -> None:
    libraries = _libraries(ctx)
    _part_doppler(ctx)
    _part_model_sets(ctx)
    _part_library(ctx, *libraries)


STUDY = StudyDefinition(
    name="tracker-synthesis",
    title="E10: tracker synthesis: range rate per state, IMM set per situation, manoeuvre-library IMM",
    run=run,
    paper_claims="P12",
    default_runs=200,
    quick_runs=8,
    default_scenario="default",
    default_filters=STATE_FILTERS,
    params=dict(PARAMS),
    quick_params=dict(QUICK_PARAMS),
)

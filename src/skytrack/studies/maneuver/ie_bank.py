"""Study E4 ``ie-bank`` of spec 004 §6: paper claim P8 (input estimation needs up to 20 parallel Kalman
filters and a likelihood per filter).

The input-estimation filter (§3.3 K, R13: CV quiescent model, DWNA sigma_w = 1, P_fa = 0.01,
Bonferroni) with its onset-time bank of N_w hypotheses for N_w in ``windows`` (1, 2, 5, 10, 15,
20, 30), labels ``ie-w<N_w>``.

Accuracy (report): on the scenario's cases (default: turns of n = 3, 5, 7 g0), both gating modes,
recorded runs (the detections come from the recorder; IE computes its hypotheses whether or not
a recorder listens, so recording does not change its cost): per case and N_w the peak and the mean
RMS position error over the manoeuvre (R20, all runs, gating off), the detection delay (scans
from the manoeuvre onset to the first detection during the manoeuvre; median over the runs that
detect) and the detection probability, and the false-detection rate before the first onset
(fraction of runs with a detection between the filter's start and the onset, and detections per
scan).  ``stop_improving``: per case and accuracy metric, the smallest N_w from which no larger
N_w of the sweep improves the metric by more than ``improvement_tolerance`` (5 %) — the paper
says "up to 20".

Cost (assert, R22 a): multiply-adds per update on a no-manoeuvre case (straight flight of
``straight_s`` seconds from the scenario start, polar radar), unrecorded runs, detection disabled
(``threshold = inf``), over the scans on which the bank is full (from the N_w-th update on), for
every N_w of the sweep and ``reference_window`` (20): ``E4-mac-affine`` — affine in N_w (every
value within ``affine_rtol`` relative of the line through the smallest and the largest N_w) with
a positive slope; ``E4-mac-vs-kf-cv`` — MAC(N_w = 20) > MAC(``kf-cv``) on the same case.  The
cost with detection enabled (hypotheses solved every scan) is reported beside it.

``--filters`` adds catalogue filters to the accuracy comparison (summary rows only).
Parameters (config ``study`` section): ``windows``, ``p_fa`` (0.01), ``bonferroni`` (true),
``reference_window`` (20), ``straight_s`` (60), ``improvement_tolerance`` (0.05), ``affine_rtol`` (1e-9).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from skytrack.studies.maneuver.filters import FilterSpec
from skytrack.studies.maneuver.outputs import colours, plot_aligned_rms
from skytrack.studies.maneuver.runner import FIRST_SCAN, FilterRun
from skytrack.studies.maneuver.scenarios import DEFAULT_START_POSITION, DEFAULT_START_VELOCITY, Case, SensorSpec, scripted_case
from skytrack.studies.maneuver.study import StudyContext, StudyDefinition
from skytrack.studies.maneuver.trajectory import straight

IE, KF_CV = "ie", "kf-cv"
PARAMS = {
    "windows": [1, 2, 5, 10, 15, 20, 30],
    "p_fa": 0.01,
    "bonferroni": True,
    "reference_window": 20,
    "straight_s": 60.0,
    "improvement_tolerance": 0.05,
    "affine_rtol": 1e-9,
}
ACCURACY_METRICS = ("e_peak_pos", "e_man_pos")


def window_label(window: int, detection: bool = True) -> str:
    return f"ie-w{window}" if detection else f"ie-w{window}-no-detection"


def window_spec(base: FilterSpec, window: int, p_fa: float, bonferroni: bool, detection: bool = True) -> FilterSpec:
    options = {**base.options, "window": int(window), "p_fa": float(p_fa), "bonferroni": bool(bonferroni)}
    if not detection:
        options["threshold"] = math.inf
    text = f"input estimation, N_w = {window}, P_fa = {p_fa:g}{', Bonferroni' if bonferroni else ''}"
    return FilterSpec(window_label(window, detection), base.kind, base.motion, options,
                      description=text if detection else f"{text}, detection disabled")


def _windows(ctx: StudyContext) -> list[int]:
    values = ctx.params["windows"]
    windows = sorted({int(w) for w in values})
    if not windows or any(int(w) != w or w < 1 for w in values):
        raise ValueError(f"--config study.windows: N_w values must be integers >= 1, got {values}")
    return windows


def stop_improving(windows: list[int], values: list[float], tolerance: float) -> int | None:
    """Smallest N_w from which no larger N_w improves (lowers) the metric by more than ``tolerance`` relative."""
    for i, w in enumerate(windows):
        if not math.isfinite(values[i]):
            continue
        if all(not math.isfinite(v) or v >= (1.0 - tolerance) * values[i] for v in values[i + 1:]):
            return w
    return None


def detections(run: FilterRun) -> np.ndarray:
    """``[K, runs]`` true where the filter declared a detection (recorded runs)."""
    try:
        scans = run.history("detection", "scan")
    except ValueError:  # no detection in any run
        return np.zeros(run.nis.shape, bool)
    return np.isfinite(scans)


def detection_metrics(case: Case, run: FilterRun) -> list[dict]:
    """Per manoeuvre onset: delay, detection probability; before the first onset: false detections."""
    hits, t = detections(run), case.truth.time
    started = np.arange(case.scans) >= FIRST_SCAN
    out = []
    for i, (onset, end) in enumerate(case.maneuvers):
        during = (t >= onset - 1e-9) & (t <= end + 1e-9)
        first = np.argmax(hits & during[:, None], axis=0)
        detected = (hits & during[:, None]).any(axis=0)
        delays = (t[first[detected]] - onset) / case.dt
        row = {"case": case.label, "filter": run.label, "onset": i, "t_onset": onset,
               "detection_probability": float(detected.mean()),
               "delay_median_scans": float(np.median(delays)) if delays.size else math.nan,
               "delay_mean_scans": float(np.mean(delays)) if delays.size else math.nan}
        if i == 0:
            before = started & (t < onset - 1e-9)
            row["false_runs_rate"] = float(hits[before].any(axis=0).mean()) if before.any() else math.nan
            row["false_per_scan"] = float(hits[before].sum() / (before.sum() * run.runs)) if before.any() else math.nan
            row["quiet_scans"] = int(before.sum())
        out.append(row)
    return out


def no_manoeuvre_case(ctx: StudyContext) -> Case:
    dt = ctx.options.config.get("dt_s")
    return scripted_case("straight", "no manoeuvre", DEFAULT_START_POSITION, DEFAULT_START_VELOCITY,
                         [straight(float(ctx.params["straight_s"]))], 1.0 if dt is None else float(dt),
                         ctx.sensor(SensorSpec()))


def cost_windows_of(ctx: StudyContext, windows: list[int], case: Case) -> list[int]:
    """The bank sizes of the cost part (the sweep and ``reference_window``); ValueError when the
    no-manoeuvre case is too short for a full bank of the largest."""
    reference = ctx.params["reference_window"]
    if int(reference) != reference or reference < 1:
        raise ValueError(f"--config study.reference_window: must be an integer >= 1, got {reference}")
    out = sorted(set(windows) | {int(reference)})
    if case.scans <= FIRST_SCAN + max(out) + 1:
        raise ValueError(f"--config study.straight_s: {ctx.params['straight_s']} s gives {case.scans} scans, fewer than a full "
                         f"bank of N_w = {max(out)} needs ({FIRST_SCAN + max(out) + 2})")
    return out


def full_bank_madds(run: FilterRun, window: int) -> tuple[float, float]:
    """Mean and spread (max - min) of the multiply-adds per update over the scans with a full bank."""
    values = run.madds[FIRST_SCAN + window:]
    values = values[np.isfinite(values)]
    if not values.size:
        return math.nan, math.nan
    return float(values.mean()), float(values.max() - values.min())


# ---------------------------------------------------------------------------- parts
def _accuracy(ctx: StudyContext, windows: list[int]) -> tuple[list[Case], pd.DataFrame]:
    p, base = ctx.params, ctx.spec(IE)
    specs = [window_spec(base, w, p["p_fa"], p["bonferroni"]) for w in windows]
    extra = [ctx.spec(label) for label in (ctx.options.filters or ()) if label not in {s.label for s in specs}]
    cases = ctx.cases()
    # the detection metrics come from the gating-off runs, which therefore always run
    gatings = tuple(dict.fromkeys(("off", *ctx.gatings)))
    summary, runs = ctx.compare(cases, specs + extra, gatings=gatings, record=True, keep=True)
    rows = []
    for case in cases:
        for spec in specs:
            run = runs[(case.label, spec.label, "off")]
            for row in detection_metrics(case, run):
                row["window"] = int(spec.options["window"])
                rows.append(row)
    table = pd.DataFrame(rows)
    if table.empty:
        raise ValueError("ie-bank: the cases have no manoeuvre onset (use a scenario with a manoeuvre)")
    accuracy = summary[(summary["basis"] == "all") & (summary["onset"] >= 0)][["case", "filter", "onset", *ACCURACY_METRICS,
                                                                                "loss_rate_off", "loss_rate_on"]]
    table = table.merge(accuracy, on=["case", "filter", "onset"], how="left")
    ctx.add_summary([{"table": "ie_bank", **r} for r in table.to_dict("records")])
    return cases, table


def _accuracy_claims(ctx: StudyContext, windows: list[int], table: pd.DataFrame) -> dict:
    tol = float(ctx.params["improvement_tolerance"])
    per_case, knees = {}, {}
    for (case, onset), part in table.groupby(["case", "onset"], sort=False):
        part = part.sort_values("window")
        key = case if onset == 0 else f"{case} onset {onset}"
        per_case[key] = {int(r.window): {"e_peak_pos": r.e_peak_pos, "e_man_pos": r.e_man_pos,
                                         "delay_median_scans": r.delay_median_scans, "delay_mean_scans": r.delay_mean_scans,
                                         "detection_probability": r.detection_probability,
                                         **({"false_runs_rate": r.false_runs_rate, "false_per_scan": r.false_per_scan}
                                            if onset == 0 else {}),
                                         "loss_rate_off": r.loss_rate_off, "loss_rate_on": r.loss_rate_on}
                         for r in part.itertuples()}
        knees[key] = {metric: stop_improving(list(part["window"]), list(part[metric]), tol)
                      for metric in (*ACCURACY_METRICS, "delay_median_scans")}
    worst = {metric: max((k[metric] for k in knees.values() if k[metric] is not None), default=None)
             for metric in (*ACCURACY_METRICS, "delay_median_scans")}
    ctx.claim_report("E4-accuracy", "IE accuracy against the bank size N_w: peak and mean manoeuvre RMS position error "
                     "(m, all runs, gating off), median and mean detection delay (scans from onset), detection probability during "
                     "the manoeuvre, false detections before the first onset (fraction of runs; per scan)", per_case, "P8")
    ctx.claim_report("E4-stop-improving", f"the N_w beyond which accuracy stops improving: smallest N_w of the sweep from "
                     f"which no larger N_w lowers the metric by more than {100 * tol:g} % (the paper: 'up to 20'); "
                     "'largest' is the largest over the cases",
                     {"by_case": knees, "largest": worst, "windows": windows}, "P8")
    return per_case


def _cost(ctx: StudyContext, windows: list[int]) -> dict:
    p, base = ctx.params, ctx.spec(IE)
    case = no_manoeuvre_case(ctx)
    reference = int(p["reference_window"])
    cost_windows = cost_windows_of(ctx, windows, case)
    ctx.expect(2 * len(cost_windows) + 1)
    off, on = {}, {}
    for w in cost_windows:
        run = ctx.run(case, window_spec(base, w, p["p_fa"], p["bonferroni"], detection=False))
        off[w] = full_bank_madds(run, w)
        run = ctx.run(case, window_spec(base, w, p["p_fa"], p["bonferroni"]))
        on[w] = full_bank_madds(run, w)
    kf = ctx.run(case, ctx.spec(KF_CV)).madds_per_update
    n = np.array(cost_windows, dtype=float)
    macs = np.array([off[w][0] for w in cost_windows])
    slope = (macs[-1] - macs[0]) / (n[-1] - n[0]) if len(n) > 1 else math.nan
    intercept = macs[0] - slope * n[0]
    residual = float(np.max(np.abs(macs - (intercept + slope * n)) / macs)) if len(n) > 2 else 0.0
    spread = max(off[w][1] for w in cost_windows)
    measured = {"case": case.label, "runs": ctx.runs, "madds_per_update": {w: off[w][0] for w in cost_windows},
                "intercept": intercept, "slope": slope, "max_rel_residual": residual,
                "max_spread_over_full_bank_scans": spread}
    ctx.claim_assert("E4-mac-affine", "IE multiply-adds per update with a full bank and detection disabled are affine in "
                     "N_w with a positive slope (R22 a)", f"every MAC(N_w) within {p['affine_rtol']:g} relative of the "
                     f"line through N_w = {cost_windows[0]} and {cost_windows[-1]}, constant over the full-bank scans, "
                     "slope > 0 (no manoeuvre, unrecorded)", measured,
                     len(n) >= 3 and residual <= p["affine_rtol"] and spread <= p["affine_rtol"] * macs.max() and slope > 0,
                     "P8")
    ctx.claim_assert("E4-mac-vs-kf-cv", f"IE with N_w = {reference} costs more multiply-adds per update than the KF-CV",
                     f"MAC(IE, N_w = {reference}) > MAC({KF_CV}) (no manoeuvre, detection disabled, unrecorded)",
                     {"ie": off[reference][0], KF_CV: kf, "ratio": off[reference][0] / kf}, off[reference][0] > kf, "P8")
    ctx.claim_report("E4-mac-detection", "IE multiply-adds per update with detection enabled (hypotheses solved every scan; "
                     "false-alarm corrections included), full-bank scans of the no-manoeuvre case",
                     {"madds_per_update": {w: on[w][0] for w in cost_windows}, KF_CV: kf}, "P8")
    return {"windows": cost_windows, "off": off, "on": on, "kf": kf, "intercept": intercept, "slope": slope}


def _plot(ctx: StudyContext, windows: list[int], table: pd.DataFrame, cost: dict) -> None:
    first = table[table["onset"] == 0]
    cases = list(dict.fromkeys(first["case"]))
    palette = colours(max(len(cases), 4))
    panels = (("e_peak_pos", "peak RMS position error [m]"), ("e_man_pos", "mean RMS position error over the manoeuvre [m]"),
              ("delay_mean_scans", "mean detection delay [scans]"), ("detection_probability", "detection probability in the manoeuvre"),
              ("false_runs_rate", "runs with a false detection before onset"))
    with ctx.figure("ie_bank_accuracy.png", "E4: input estimation against the bank size N_w", 2, 3,
                    figsize=(19.2, 8.8)) as (_, axes):
        for ax, (column, text) in zip(axes, panels):
            for i, case in enumerate(cases):
                part = first[first["case"] == case].sort_values("window")
                ax.plot(part["window"], part[column], "o-", color=palette[i], label=case)
            ax.set_ylabel(text)
        ax = axes[5]
        w = np.array(cost["windows"], dtype=float)
        ax.plot(w, [cost["off"][int(v)][0] for v in w], "o", color=palette[0], label="IE, detection disabled")
        ax.plot(w, cost["intercept"] + cost["slope"] * w, "-", color=palette[1],
                label=f"affine fit {cost['intercept']:.0f} + {cost['slope']:.0f} N_w")
        ax.plot(w, [cost["on"][int(v)][0] for v in w], "s--", color=palette[2], label="IE, detection enabled")
        ax.axhline(cost["kf"], color=palette[3], linestyle=":", label="KF-CV")
        ax.set_ylabel("multiply-adds per update (no manoeuvre)")
        for ax in axes:
            ax.set_xlabel("bank size N_w")
        for ax in axes[:5]:
            ax.set_xscale("log")
    shown = [window_label(w) for w in windows if w in (min(windows), 5, 20, max(windows))]
    plot_aligned_rms(ctx.figures, ctx.out / "ie_bank_rms.png", ctx.series_frame(),
                     "E4: IE RMS error around the onset for several bank sizes", filters=list(dict.fromkeys(shown)))


def run(ctx: StudyContext) -> None:
    windows = _windows(ctx)
    cost_windows_of(ctx, windows, no_manoeuvre_case(ctx))  # bad configuration fails before the long part
    _, table = _accuracy(ctx, windows)
    _accuracy_claims(ctx, windows, table)
    cost = _cost(ctx, windows)
    _plot(ctx, windows, table, cost)


STUDY = StudyDefinition(
    name="ie-bank",
    title="E4: input estimation, accuracy and cost against the onset-bank size N_w",
    run=run,
    paper_claims="P8",
    default_runs=200,
    quick_runs=8,
    default_scenario="default",
    default_filters=(),
    params=dict(PARAMS),
    quick_params={"windows": [1, 2, 5, 20], "straight_s": 30.0},
)

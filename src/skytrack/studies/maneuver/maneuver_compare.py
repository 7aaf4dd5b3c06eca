"""Study E3 ``maneuver-compare`` of spec 004 §6: every filter family on manoeuvring targets (P5-P7, P11).

Cases.  The default scenario (straight 40 s, n g0 coordinated turn through 180 deg, straight
30 s; n = 3, 5, 7; T = 1 s, polar radar) is always run: the asserts are stated on it.  The
other scenarios (``extra_scenarios``, default ``weave`` and ``vertical``) follow, or the cases of
``--scenario`` / ``--truth`` when given.  The ``fighter`` scenario (T = 0.1 s, ten times the scans,
n = 3, 5, 7, 9) takes about four times as long as the rest of the study together, so it belongs to
the full sweep only: ``study: {extra_scenarios: [weave, vertical, fighter]}`` or ``--scenario fighter``.

Filters (``--filters`` replaces them): one catalogue entry per family of the §6 table
(:data:`FAMILIES`; PCG with N = 5, the N sweep is E8's), each in both gating modes; on the
default scenario the filters the claims need are added when missing.  Per filter, case and onset
the summary holds the R20 metrics (RMS vs time from -20 s to +60 s around onset in
``timeseries.parquet``, e_pre, e_peak, e_man, settling from the peak and from the manoeuvre end,
loss rate with ``gating`` off and on, NEES mean and in-band fraction, containment of the
set-membership filter, MACs per update); ``timing.csv`` has the wall microseconds per update.

Claims on the default scenario (all runs, gating off unless stated):

* assert ``E3-i-imm``: for every n, the IMM (``cv-ca``) peak RMS position error < KF-CV
  (sigma_w = 1) peak, and the IMM e_pre < the pseudo-noise KF's e_pre;
* assert ``E3-ii-kf-cv-loss``: KF-CV loss rate with ``gating="on"`` >= 50 % at n = 5
  (``loss_turn_g``);
* asserts ``E3-iii-vd-delay`` / ``E3-iv-ie-delay``: median detection delay <= 6 scans for every
  n >= 3.  The delay of a run is ``k_det - k_on``: ``k_on`` the scan of the onset time, ``k_det``
  the first scan at or after it (within the metric window) at which the filter declared a
  manoeuvre -- VD: recorder channel ``switch`` with ``mode = 1``, IE: channel ``detection``; a
  run without one counts as never detected (infinite delay);
* reports P5 (VD vs IE: mean RMS over the manoeuvre, peak, settling, and ``e_post``, the mean RMS
  from ``post_delay_s`` = 10 s after the manoeuvre's end to the end of the window), P6 (VD vs
  static bank vs IMM), P7 (VD settling vs IMM, scans re-filtered at VD detections), with the sensitivity sweep
  sigma_ca in ``sigma_ca_sweep`` (2, 4, 8, 16) for VD and P_fa in ``ie_p_fa_sweep`` (0.01, 0.001)
  for IE (detection delays, false detections before onset, IE re-detections after onset);
  consistency (NEES, containment), loss and cost tables of the n = 5 case; the best filters of
  every case by mean manoeuvre RMS.

Figures: RMS position and velocity around the onset for the main families
(``maneuver_compare_rms_default.png``, one row per n; ``maneuver_compare_rms_scenarios.png``
over the whole case for the other scenarios, manoeuvres shaded), peak / e_pre / MACs bars
(``maneuver_compare_bars.png``), the VD sigma_ca and IE P_fa sweeps
(``maneuver_compare_sensitivity.png``) and the distribution of detection delays
(``maneuver_compare_detection.png``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from skytrack.studies.maneuver.outputs import colours
from skytrack.studies.maneuver.runner import FilterRun
from skytrack.studies.maneuver.scenarios import NAMED_SCENARIOS, Case, named_cases
from skytrack.studies.maneuver.study import StudyContext, StudyDefinition

FAMILIES = ("kf-cv", "pseudo-noise", "kf-ca", "kf-singer", "alpha-beta", "alpha-beta-gamma", "per-axis",
            "transformed-gain", "pcg-5", "adaptive", "set-membership", "vd", "ie", "adaptive-ie", "berg-full",
            "berg-frame", "static-bank", "imm-cv-ca", "imm-cv-ct", "imm-full")
KF_CV, PSEUDO, IMM, VD, IE, BANK, IMM_FULL = "kf-cv", "pseudo-noise", "imm-cv-ca", "vd", "ie", "static-bank", "imm-full"
#: filters the claims need on the default scenario (added when --filters leaves them out)
REQUIRED = (KF_CV, PSEUDO, IMM, BANK, IMM_FULL)
#: drawn in the RMS figures when run (more lines would not be readable)
MAIN = ("kf-cv", "pseudo-noise", "kf-ca", "kf-singer", "alpha-beta-gamma", "set-membership", "vd", "ie",
        "adaptive-ie", "berg-frame", "static-bank", "imm-cv-ca", "imm-full")
PARAMS = {
    "extra_scenarios": ["weave", "vertical"],
    "sigma_ca_sweep": [2.0, 4.0, 8.0, 16.0],
    "ie_p_fa_sweep": [0.01, 0.001],
    "max_delay_scans": 6.0,
    "loss_rate_min": 0.5,
    "loss_turn_g": 5.0,
    "plot_cases": 6,
    "post_delay_s": 10.0,
}
QUICK_PARAMS = {"extra_scenarios": []}
STYLES = ("-", "--", "-.", ":")


# ---------------------------------------------------------------------- cases and variants
def default_cases(ctx: StudyContext) -> list[Case]:
    """The named default scenario with the configuration's scan period, sensor and n values."""
    config = ctx.options.config
    dt, turn = config.get("dt_s"), config.get("turn_g")
    return named_cases("default", dt=None if dt is None else float(dt), sensor=ctx.sensor(),
                       turn_g=None if turn is None else tuple(float(v) for v in turn))


def other_cases(ctx: StudyContext, skip: set[str]) -> list[Case]:
    """``--truth`` / ``--scenario`` cases when given, else those of ``extra_scenarios`` (labels in ``skip`` dropped)."""
    names = list(ctx.params["extra_scenarios"])
    bad = [name for name in names if name not in NAMED_SCENARIOS]
    if bad:
        raise ValueError(f"--config study.extra_scenarios: unknown scenario(s) {bad}; named: {', '.join(NAMED_SCENARIOS)}")
    options = ctx.options
    if options.truth is not None or options.scenario or options.config.get("scenario"):
        cases = ctx.cases()
    else:
        cases = [case for name in dict.fromkeys(names) for case in ctx.cases(default=name)]
    return [case for case in cases if case.label not in skip]


def variant(spec, label: str, **options):
    return dataclasses.replace(spec, label=label, options={**spec.options, **options},
                               description=f"{spec.description}; " + ", ".join(f"{k} = {v:g}" for k, v in options.items()))


def sweep_specs(ctx: StudyContext) -> tuple[list, list]:
    """VD variants over ``sigma_ca_sweep`` and IE variants over ``ie_p_fa_sweep``; the catalogue's own value keeps its label."""
    vd, ie = ctx.spec(VD), ctx.spec(IE)
    vds = [vd if math.isclose(s, vd.options.get("sigma_ca", math.nan)) else variant(vd, f"vd-sigma-ca-{s:g}", sigma_ca=float(s))
           for s in ctx.params["sigma_ca_sweep"]]
    ies = [ie if math.isclose(p, ie.options.get("p_fa", math.nan)) else variant(ie, f"ie-p-fa-{p:g}", p_fa=float(p))
           for p in ctx.params["ie_p_fa_sweep"]]
    for group, base in ((vds, vd), (ies, ie)):
        if base not in group:
            group.insert(0, base)
    return vds, ies


# ---------------------------------------------------------------------- detections
def onset_scan(case: Case, onset: float) -> int:
    return int(np.searchsorted(case.truth.time, onset - 1e-9))


def detection_stats(run: FilterRun, case: Case, channel: str, horizon_s: float, mode_key: str | None = None) -> dict:
    """Per run: delay of the first declaration at or after the first onset (scans; inf if none within
    ``horizon_s``), false declarations before onset, declarations after onset, VD re-filtered scans."""
    k_on = onset_scan(case, case.maneuvers[0][0])
    k_end = onset_scan(case, case.maneuvers[0][0] + horizon_s)
    first = np.full(run.runs, -1)
    early = np.zeros(run.runs, bool)
    after = np.zeros(run.runs, int)
    refiltered = np.full(run.runs, np.nan)
    for k, scan in enumerate(run.diagnostics):
        for ch, rows, values in scan:
            if ch != channel:
                continue
            hit = np.ones(len(rows), bool) if mode_key is None else np.asarray(values[mode_key]) == 1
            for i in np.flatnonzero(hit):
                r = rows[i]
                if k < k_on:
                    early[r] = True
                elif k <= k_end:
                    after[r] += 1
                    if first[r] < 0:
                        first[r] = k
                        if "refiltered" in values:
                            refiltered[r] = values["refiltered"][i]
    delay = np.where(first >= 0, first - k_on, np.inf).astype(float)
    return {"delay": delay, "early": early, "after": after, "refiltered": refiltered}


def delay_summary(stats: dict) -> dict:
    delay = stats["delay"]
    out = {"median_delay_scans": float(np.median(delay)), "detected_fraction": float(np.isfinite(delay).mean()),
           "false_before_onset_fraction": float(stats["early"].mean()),
           "declarations_after_onset_mean": float(stats["after"].mean())}
    finite = np.isfinite(stats["refiltered"])
    if finite.any():
        out["refiltered_scans_mean"] = float(stats["refiltered"][finite].mean())
    return out


# ---------------------------------------------------------------------- summary helpers
def main_rows(summary: pd.DataFrame) -> pd.DataFrame:
    return summary[(summary["basis"] == "all") & (summary["onset"] == 0)]


def metric(rows: pd.DataFrame, case: str, label: str, column: str) -> float:
    hit = rows[(rows["case"] == case) & (rows["filter"] == label)]
    return float(hit[column].iloc[0]) if len(hit) else math.nan


def metrics_of(rows: pd.DataFrame, case: str, label: str, columns) -> dict:
    return {column: metric(rows, case, label, column) for column in columns}


def post_level(series: pd.DataFrame, case: Case, label: str, delay_s: float) -> float:
    """Mean RMS position error of the first onset's window from ``delay_s`` after the manoeuvre's end
    (the level a filter returns to after the turn; NaN when the window ends before)."""
    end = case.maneuvers[0][1] - case.maneuvers[0][0]
    part = series[(series["case"] == case.label) & (series["filter"] == label) & (series["quantity"] == "rms_pos")
                  & (series["onset"] == 0) & (series["t_rel"] >= end + delay_s - 1e-9)]
    return float(part["value"].mean()) if len(part) else math.nan


def turn_of(case: Case) -> float:
    return float(case.params.get("n", math.nan))


ACCURACY = ("e_pre_pos", "e_man_pos", "e_peak_pos", "settle_peak_pos", "settle_end_pos", "e_man_vel", "e_peak_vel",
            "loss_rate_off", "loss_rate_on")


# ---------------------------------------------------------------------- claims
def _assert_imm(ctx, rows, cases) -> None:
    measured, ok = {}, True
    for case in cases:
        imm, cv, pseudo = (metrics_of(rows, case.label, f, ("e_pre_pos", "e_peak_pos")) for f in (IMM, KF_CV, PSEUDO))
        measured[case.label] = {"imm_peak_m": imm["e_peak_pos"], "kf_cv_peak_m": cv["e_peak_pos"],
                                "imm_e_pre_m": imm["e_pre_pos"], "pseudo_noise_e_pre_m": pseudo["e_pre_pos"]}
        ok &= imm["e_peak_pos"] < cv["e_peak_pos"] and imm["e_pre_pos"] < pseudo["e_pre_pos"]
    ctx.claim_assert("E3-i-imm", "IMM (cv-ca) beats KF-CV (sigma_w = 1) at the peak and the pseudo-noise KF before onset "
                     "(RMS position, all runs, gating off)", "for every n: IMM e_peak < KF-CV e_peak and IMM e_pre < "
                     "pseudo-noise e_pre", measured, bool(cases) and ok, "P2, P6")


def _assert_loss(ctx, rows, cases) -> None:
    n = float(ctx.params["loss_turn_g"])
    case = next((c for c in cases if math.isclose(turn_of(c), n)), None)
    measured = {"n": n, "runs": ctx.runs}
    if case is None:
        measured["note"] = f"the default scenario has no case with n = {n:g} (config turn_g)"
        rate = math.nan
    else:
        rate = metric(rows, case.label, KF_CV, "loss_rate_on")
        measured.update({"kf_cv_loss_rate_on": rate, "kf_cv_loss_rate_off": metric(rows, case.label, KF_CV, "loss_rate_off")})
    ctx.claim_assert("E3-ii-kf-cv-loss", f"KF-CV (sigma_w = 1) loses the track in the {n:g} g turn with gating on",
                     f"loss rate (gating on) >= {ctx.params['loss_rate_min']:g}", measured,
                     case is not None and rate >= ctx.params["loss_rate_min"], "P2")


def _assert_delay(ctx, claim: str, name: str, stats: dict, cases) -> None:
    limit = float(ctx.params["max_delay_scans"])
    measured = {c.label: delay_summary(stats[c.label]) for c in cases}
    worst = max((v["median_delay_scans"] for v in measured.values()), default=math.nan)
    ctx.claim_assert(claim, f"{name} detects the turn quickly: median delay from onset to the first declaration",
                     f"median delay <= {limit:g} scans for every n >= 3 (never detected = infinite)", measured,
                     bool(cases) and worst <= limit, "P5, P7")


def _reports(ctx, rows, series, cases, vds, ies, vd_stats, ie_stats) -> None:
    p5, p6, p7 = {}, {}, {}
    imms = [label for label in (IMM, IMM_FULL) if label in set(rows["filter"])]
    delay = float(ctx.params["post_delay_s"])

    def accuracy(case, label):
        return {**metrics_of(rows, case.label, label, ACCURACY), "e_post_pos": post_level(series, case, label, delay)}

    for case in cases:
        vd, ie = accuracy(case, VD), accuracy(case, IE)
        p5[case.label] = {"vd": vd, "ie": ie, "vd_over_ie_e_man": vd["e_man_pos"] / ie["e_man_pos"],
                          "vd_over_ie_peak": vd["e_peak_pos"] / ie["e_peak_pos"],
                          "holds_vd_below_ie": bool(vd["e_man_pos"] < ie["e_man_pos"])}
        p6[case.label] = {label: accuracy(case, label) for label in (VD, BANK, *imms)}
        p6[case.label]["vd_over_imm_e_man"] = vd["e_man_pos"] / metric(rows, case.label, IMM, "e_man_pos")
        p7[case.label] = {"vd_settle_peak_s": vd["settle_peak_pos"], "vd_settle_end_s": vd["settle_end_pos"],
                          **{f"{label}_settle_peak_s": metric(rows, case.label, label, "settle_peak_pos") for label in imms},
                          **{f"{label}_settle_end_s": metric(rows, case.label, label, "settle_end_pos") for label in imms},
                          "vd_refiltered_scans_mean": delay_summary(vd_stats[VD][case.label]).get("refiltered_scans_mean", math.nan)}
    ctx.claim_report("E3-P5-vd-vs-ie", "VD vs input estimation: mean RMS over the manoeuvre (e_man), peak, settling, "
                     f"level from {delay:g} s after the manoeuvre (e_post) (position m / s; velocity m/s)", p5, "P5")
    ctx.claim_report("E3-P6-vd-bank-imm", "VD vs static bank vs IMM (cv-ca, full): manoeuvre RMS, peak, settling", p6, "P6")
    ctx.claim_report("E3-P7-vd-transient", "VD transient: settling from the peak and from the manoeuvre end vs IMM; "
                     "scans re-filtered at the detection", p7, "P7")
    sweep = {}
    for specs, stats in ((vds, vd_stats), (ies, ie_stats)):
        for spec in specs:
            sweep[spec.label] = {case.label: {**metrics_of(rows, case.label, spec.label,
                                                           ("e_man_pos", "e_peak_pos", "settle_peak_pos", "e_pre_pos")),
                                              **delay_summary(stats[spec.label][case.label])} for case in cases}
    ctx.claim_report("E3-sensitivity", "VD over sigma_ca and IE over P_fa: manoeuvre RMS, peak, settling, detection delay, "
                     "false detections before onset, declarations after onset (IE re-detects after a turn)", sweep, "P5, P6, P7")


def _table_reports(ctx, summary_all: pd.DataFrame, cases) -> None:
    rows = main_rows(summary_all)
    n = float(ctx.params["loss_turn_g"])
    case = next((c for c in cases if math.isclose(turn_of(c), n)), cases[len(cases) // 2] if cases else None)
    if case is not None:
        part = rows[rows["case"] == case.label].set_index("filter")
        ctx.claim_report("E3-consistency", f"NEES (position+velocity, mean and fraction of window scans in the 95 % band) "
                         f"and containment, {case.label}", {f: {"nees_mean": r.nees_mean, "nees_in_band": r.nees_in_band,
                                                                "containment": r.containment} for f, r in part.iterrows()},
                         "P2, P11")
        ctx.claim_report("E3-loss-and-cost", f"loss rate (gating off / on) and multiply-adds per update, {case.label} "
                         "(wall time per update: timing.csv)", {f: {"loss_off": r.loss_rate_off, "loss_on": r.loss_rate_on,
                                                                   "madds_per_update": r.madds_per_update}
                                                                for f, r in part.iterrows()}, "P4, P8, P9")
    best = {}
    every_onset = summary_all[(summary_all["basis"] == "all") & (summary_all["onset"] >= 0)]
    for label, part in every_onset.groupby("case", sort=False):
        for onset, chunk in part.groupby("onset"):
            kept = chunk[chunk["loss_rate_off"] < 0.5].sort_values("e_man_pos")
            best[f"{label} onset {onset}"] = {r.filter: {"e_man_m": r.e_man_pos, "e_peak_m": r.e_peak_pos,
                                                         "e_pre_m": r.e_pre_pos} for r in kept.head(4).itertuples()}
    ctx.claim_report("E3-ranking", "the four filters with the lowest mean RMS position error over each manoeuvre "
                     "(filters losing >= 50 % of runs with gating off excluded)", best, "P11, P12")


# ---------------------------------------------------------------------- figures
def _aligned(series: pd.DataFrame, case: str, label: str, quantity: str, onset: int | None = 0) -> pd.DataFrame:
    part = series[(series["case"] == case) & (series["filter"] == label) & (series["quantity"] == quantity)]
    return part if onset is None else part[part["onset"] == onset]


def line_style(i: int, count: int):
    """Colour and line style of line ``i`` of ``count``: tab10 hues first, then their light tab20
    partners dashed, so that neighbours in the legend never look alike."""
    if count <= 10:
        return colours(count)[i], "-"
    palette = colours(20)
    order = list(range(0, 20, 2)) + list(range(1, 20, 2))
    return palette[order[i % 20]], STYLES[(i // 10) % len(STYLES)]


def _plot_default(ctx, series, cases, labels) -> None:
    with ctx.figure("maneuver_compare_rms_default.png", "E3: RMS error around the turn onset, default scenario",
                    len(cases), 2, figsize=(14, 4.6 * len(cases))) as (_, axes):
        for row, case in enumerate(cases):
            for col, (quantity, name, unit) in enumerate((("rms_pos", "position", "m"), ("rms_vel", "velocity", "m/s"))):
                ax = axes[2 * row + col]
                for i, label in enumerate(labels):
                    part = _aligned(series, case.label, label, quantity)
                    if not part.empty:
                        colour, style = line_style(i, len(labels))
                        ax.plot(part["t_rel"], part["value"], style, color=colour, label=label)
                ax.axvspan(0.0, case.maneuvers[0][1] - case.maneuvers[0][0], color="0.85", alpha=0.5, zorder=0)
                ax.set_yscale("log")
                ax.set_title(f"{case.label}: RMS {name} error")
                ax.set_xlabel("time from manoeuvre onset [s]")
                ax.set_ylabel(f"RMS {name} error [{unit}]")
                ax.legend(fontsize="x-small", ncol=2)


def _piecewise(series, case: Case, label: str, quantity: str) -> pd.DataFrame:
    """The aligned windows of every onset joined on the case's time axis (each window from its onset
    to the next; the first from its start)."""
    part = _aligned(series, case.label, label, quantity, onset=None)
    if part.empty:
        return part
    pieces = []
    for onset, chunk in part.groupby("onset"):
        pieces.append(chunk if onset <= 0 else chunk[chunk["t_rel"] >= -1e-9])
    out = pd.concat(pieces).drop_duplicates("t", keep="last").sort_values("t")
    return out


def _plot_scenarios(ctx, series, cases, labels) -> None:
    cases = cases[: int(ctx.params["plot_cases"])]
    if not cases:
        return
    with ctx.figure("maneuver_compare_rms_scenarios.png", "E3: RMS position and velocity error, other scenarios "
                    "(manoeuvres shaded)", len(cases), 2, figsize=(14, 4.6 * len(cases))) as (_, axes):
        for row, case in enumerate(cases):
            for col, (quantity, name, unit) in enumerate((("rms_pos", "position", "m"), ("rms_vel", "velocity", "m/s"))):
                ax = axes[2 * row + col]
                for i, label in enumerate(labels):
                    part = _piecewise(series, case, label, quantity)
                    if not part.empty:
                        colour, style = line_style(i, len(labels))
                        ax.plot(part["t"], part["value"], style, color=colour, label=label)
                for onset, end in case.maneuvers:
                    ax.axvspan(onset, end, color="0.85", alpha=0.5, zorder=0)
                ax.set_yscale("log")
                ax.set_title(f"{case.label}: RMS {name} error")
                ax.set_xlabel("time [s]")
                ax.set_ylabel(f"RMS {name} error [{unit}]")
                ax.legend(fontsize="x-small", ncol=2)


def _plot_bars(ctx, rows, case: Case) -> None:
    part = rows[rows["case"] == case.label].sort_values("e_peak_pos", ascending=False)
    if part.empty:
        return
    y = np.arange(len(part))
    palette = colours(3)
    with ctx.figure("maneuver_compare_bars.png", f"E3: peak and pre-manoeuvre RMS position error, cost ({case.label})",
                    1, 3, figsize=(16, 0.32 * len(part) + 2.5)) as (_, axes):
        for ax, column, name, colour in zip(axes, ("e_peak_pos", "e_pre_pos", "madds_per_update"),
                                             ("peak RMS position error e_peak [m]", "pre-manoeuvre RMS e_pre [m]",
                                              "multiply-adds per update"), palette):
            values = part[column].to_numpy(float)
            ax.barh(y, values, color=colour)
            for yi, v in zip(y, values):
                ax.text(v, yi, f" {v:.3g}", va="center", fontsize="x-small")
            ax.set_yticks(y, part["filter"], fontsize="small")
            if column != "e_pre_pos":
                ax.set_xscale("log")
            ax.set_xlabel(name)
            ax.set_ylabel("filter")


def _plot_sensitivity(ctx, series, case: Case, vds, ies) -> None:
    with ctx.figure("maneuver_compare_sensitivity.png", f"E3: VD sigma_ca and IE P_fa sweeps, {case.label}",
                    1, 2, figsize=(14, 4.8)) as (_, axes):
        for ax, specs, title in ((axes[0], vds, "VD, sigma_ca sweep"), (axes[1], ies, "input estimation, P_fa sweep")):
            labels = [s.label for s in specs] + [IMM]
            palette = colours(len(labels))
            for i, label in enumerate(labels):
                part = _aligned(series, case.label, label, "rms_pos")
                if not part.empty:
                    ax.plot(part["t_rel"], part["value"], "--" if label == IMM else "-", color=palette[i], label=label)
            ax.set_yscale("log")
            ax.set_title(title)
            ax.set_xlabel("time from manoeuvre onset [s]")
            ax.set_ylabel("RMS position error [m]")


def _plot_detection(ctx, cases, vd_stats, ie_stats) -> None:
    with ctx.figure("maneuver_compare_detection.png", "E3: detection delay after the turn onset (default scenario)",
                    1, 2, figsize=(13, 4.6)) as (_, axes):
        for ax, stats, name in ((axes[0], vd_stats[VD], "VD (switch to CA)"), (axes[1], ie_stats[IE], "input estimation")):
            palette = colours(len(cases))
            for i, case in enumerate(cases):
                delay = np.sort(stats[case.label]["delay"])
                fraction = np.arange(1, len(delay) + 1) / len(delay)
                finite = np.isfinite(delay)
                ax.step(delay[finite], fraction[finite], where="post", color=palette[i], label=case.label)
            ax.axvline(ctx.params["max_delay_scans"], color="0.3", linestyle=":", label="assert: median <= limit")
            ax.set_title(name)
            ax.set_xlabel("delay from onset to first declaration [scans]")
            ax.set_ylabel("fraction of runs detected")


# ---------------------------------------------------------------------- study
def run(ctx: StudyContext) -> None:
    p = ctx.params
    specs = ctx.filters(FAMILIES)
    defaults = default_cases(ctx)
    others = other_cases(ctx, {c.label for c in defaults})
    vds, ies = sweep_specs(ctx)
    swept = {s.label for s in vds + ies}
    chosen = {s.label for s in specs}
    on_default = [s for s in specs if s.label not in swept] + \
                 [ctx.spec(label) for label in REQUIRED if label not in chosen and label not in swept]
    summary_default, _ = ctx.compare(defaults, on_default)
    summary_sweep, kept = ctx.compare(defaults, vds + ies, record=True, keep=True)
    horizon = ctx.metric_settings.after_s
    vd_stats = {s.label: {c.label: detection_stats(kept[(c.label, s.label, "off")], c, "switch", horizon, "mode")
                          for c in defaults} for s in vds}
    ie_stats = {s.label: {c.label: detection_stats(kept[(c.label, s.label, "off")], c, "detection", horizon)
                          for c in defaults} for s in ies}
    del kept
    summary_others, _ = ctx.compare(others, specs) if others else (pd.DataFrame(), {})

    rows = main_rows(pd.concat([summary_default, summary_sweep], ignore_index=True))
    series = ctx.series_frame()
    series = series[(series["series"] == "aligned") & (series["basis"] == "all")]
    _assert_imm(ctx, rows, defaults)
    _assert_loss(ctx, rows, defaults)
    _assert_delay(ctx, "E3-iii-vd-delay", "VD", vd_stats[VD], defaults)
    _assert_delay(ctx, "E3-iv-ie-delay", "input estimation", ie_stats[IE], defaults)
    _reports(ctx, rows, series, defaults, vds, ies, vd_stats, ie_stats)
    everything = pd.concat([summary_default, summary_sweep, summary_others], ignore_index=True)
    _table_reports(ctx, everything, defaults)
    ctx.claim_report("E3-scope", "what this run covered (the fighter scenario, T = 0.1 s, is in the full sweep only: "
                     "study.extra_scenarios [weave, vertical, fighter] or --scenario fighter)",
                     {"default_cases": [c.label for c in defaults], "other_cases": [c.label for c in others],
                      "filters": [s.label for s in specs], "sweep_filters": sorted(swept), "runs": ctx.runs,
                      "gatings": list(ctx.gatings)}, "")

    ran = set(everything["filter"]) if len(everything) else set()
    labels = [label for label in MAIN if label in ran] or [s.label for s in specs][:10]
    _plot_default(ctx, series, defaults, labels)
    _plot_scenarios(ctx, series, others, [label for label in MAIN if label in {s.label for s in specs}] or
                    [s.label for s in specs][:10])
    n = float(p["loss_turn_g"])
    bar_case = next((c for c in defaults if math.isclose(turn_of(c), n)), defaults[len(defaults) // 2])
    _plot_bars(ctx, main_rows(everything), bar_case)
    _plot_sensitivity(ctx, series, bar_case, vds, ies)
    _plot_detection(ctx, defaults, vd_stats, ie_stats)


STUDY = StudyDefinition(
    name="maneuver-compare",
    title="E3: all filter families on manoeuvring targets (P5-P7, P11)",
    run=run,
    paper_claims="P5, P6, P7, P11",
    default_runs=200,
    quick_runs=8,
    default_scenario="default",
    default_filters=FAMILIES,
    params=dict(PARAMS),
    quick_params=dict(QUICK_PARAMS),
)

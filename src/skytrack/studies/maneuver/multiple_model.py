"""Study E7 ``multiple-model`` of spec 004 §6: static bank vs IMM per model set and scenario (P11, P12(2)).

Filters (§3.3 N, O, R16-R18; ``--filters`` replaces them):

* static bank, literal (``switch_off="permanent"``, ``mu_floor=0``: ``bank-literal-<set>``) and
  improved (the registry defaults: re-enable after ``cooldown`` 20 scans, ``mu_floor`` 1e-3, the
  most probable member never switched off: ``bank-improved-<set>``) for the sets ``cv-ca-singer``
  (the §6 default of the bank), ``cv-ca``, ``cv-ct`` and ``full``; W = 5, P_div = 0.001;
* IMM for the sets ``cv-ca``, ``cv-ct``, ``full`` and ``cv-ca-singer`` (sojourn 20 s in CV, 10 s in
  the other modes);
* ``bank-floor-only``: the default set with the probability floor mu_min = 1e-3 but never
  re-enabled, to separate the effect of mu_min from that of re-enabling.  (Re-enabling without a
  floor is not a variant: a member re-enabled with mu = 0 could never regain weight, so the bank
  refuses ``switch_off="reenable"`` with ``mu_floor=0``.)

Cases: the default scenario (n = 3, 5, 7) always, then ``extra_scenarios`` (``weave``,
``vertical``), or the ``--scenario`` / ``--truth`` cases.  The ``fighter`` scenario (T = 0.1 s, ten
times the scans, four cases) would take about four times the rest of the study, so it is in the
full sweep only (``study: {extra_scenarios: [weave, vertical, fighter]}`` or ``--scenario fighter``).
Every filter runs in both gating modes with the recorder on: the banks' ``model_probabilities``,
``switch_off`` and ``reenable`` channels and the IMM's ``mode_probabilities``.

Claims:

* assert ``E7-literal-switch-off`` (default scenario, every n >= 3): in the literal bank over the
  default set the CV member is switched off at a scan ``k`` with ``k_on <= k <= k_on + 10``
  (``switch_window_scans``) in >= 90 % of runs, and at most 10 % of runs switch any member off
  before ``k_on`` (``k_on`` = scan of the onset time; gating off);
* reports: RMS (pre, manoeuvre, peak, after the last manoeuvre), settling and loss per filter and
  case (``E7-model-sets``); the best IMM set, bank set and filter per case (``E7-best-set``: which
  set suits which situation); the effect of mu_min and re-enabling (``E7-floor-reenable``:
  literal, re-enable only, improved); when members are switched off and re-enabled
  per set (``E7-switching``).

``e_post`` is the mean RMS position error from ``post_delay_s`` (10 s) after the end of the last
manoeuvre to the end of the case: the level a bank returns to (or not) once its CV member is gone.

Figures: mean mu_j(t) of every set for the literal bank, the improved bank and the IMM
(``multiple_model_probabilities_<case>.png``), the fraction of runs in which each member is
active over time for the three switch-off variants of the default set (switch-off and re-enable
times, ``multiple_model_switching.png``), RMS position error over time
(``multiple_model_rms.png``) and tables of manoeuvre RMS and peak per filter and case
(``multiple_model_table.png``).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from skytrack.studies.maneuver.filters import ORDER3, FilterSetting, FilterSpec
from skytrack.studies.maneuver.maneuver_compare import (
    PARAMS as COMPARE_PARAMS,
    _piecewise,
    default_cases,
    line_style,
    main_rows,
    metrics_of,
    onset_scan,
    other_cases,
    turn_of,
)
from skytrack.studies.maneuver.outputs import colours
from skytrack.studies.maneuver.study import StudyContext, StudyDefinition

BANK_SETS = ("cv-ca-singer", "cv-ca", "cv-ct", "full")
IMM_SETS = ("cv-ca", "cv-ct", "full", "cv-ca-singer")
DEFAULT_SET = "cv-ca-singer"
LITERAL = {"switch_off": "permanent", "mu_floor": 0.0}
IMPROVED = {"switch_off": "reenable", "mu_floor": 1e-3}
BANK_OPTIONS = {"window": 5, "p_divergence": 0.001, "cooldown": 20}
LITERAL_DEFAULT, IMPROVED_DEFAULT = f"bank-literal-{DEFAULT_SET}", f"bank-improved-{DEFAULT_SET}"
FLOOR_ONLY = "bank-floor-only"
VARIANTS = (LITERAL_DEFAULT, FLOOR_ONLY, IMPROVED_DEFAULT)


def _bank(label: str, model_set: str, mode: dict, text: str) -> FilterSpec:
    return FilterSpec(label, "static-bank", ORDER3, options={"model_set": model_set, **BANK_OPTIONS, **mode},
                      description=f"static bank {model_set}, {text}, W = 5, P_div = 0.001")


FILTERS: dict[str, FilterSpec] = {s.label: s for s in (
    *[_bank(f"bank-literal-{name}", name, LITERAL, "literal (permanent switch-off, no floor)") for name in BANK_SETS],
    *[_bank(f"bank-improved-{name}", name, IMPROVED, "improved (re-enable after 20 scans, mu_min = 1e-3)")
      for name in BANK_SETS],
    _bank(FLOOR_ONLY, DEFAULT_SET, {"switch_off": "permanent", "mu_floor": 1e-3}, "floor 1e-3, never re-enabled"),
    *[FilterSpec(f"imm-{name}", "imm", ORDER3, options={"model_set": name},
                 description=f"IMM {name} (sojourn CV 20 s, others 10 s)") for name in IMM_SETS if name == DEFAULT_SET],
)}
DEFAULT_FILTERS = (*[f"bank-literal-{n}" for n in BANK_SETS], *[f"bank-improved-{n}" for n in BANK_SETS],
                   FLOOR_ONLY, *[f"imm-{n}" for n in IMM_SETS])
PARAMS = {
    "extra_scenarios": list(COMPARE_PARAMS["extra_scenarios"]),
    "switch_window_scans": 10,
    "switch_rate_min": 0.9,
    "early_rate_max": 0.1,
    "post_delay_s": 10.0,
    "plot_cases": 6,
}
QUICK_PARAMS = {"extra_scenarios": []}
COLUMNS = ("e_pre_pos", "e_man_pos", "e_peak_pos", "settle_peak_pos", "settle_end_pos", "loss_rate_off", "loss_rate_on",
           "nees_mean", "madds_per_update")


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


# ---------------------------------------------------------------------- per run extraction
def member_events(run, channel: str) -> list[tuple[int, int, int]]:
    """``(scan, run, member)`` of every event of a bank channel (``switch_off`` / ``reenable``), in scan order."""
    out = []
    for k, scan in enumerate(run.diagnostics):
        for ch, rows, values in scan:
            if ch == channel:
                out.extend((k, int(r), int(j)) for r, j in zip(rows, values["member"]))
    return out


def active_state(scans: int, runs: int, members: int, offs, ons) -> np.ndarray:
    """``[K, runs, M]`` whether each member is active after each scan's update."""
    change = np.zeros((scans, runs, members), np.int8)
    for k, r, j in offs:
        change[k, r, j] -= 1
    for k, r, j in ons:
        change[k, r, j] += 1
    return (1 + np.cumsum(change, axis=0)) > 0


def after_level(run, case, delay_s: float) -> float:
    """Mean RMS position error from ``delay_s`` after the last manoeuvre's end to the end of the case (NaN without one)."""
    if not case.maneuvers:
        return math.nan
    t = case.truth.time
    scans = (t >= case.maneuvers[-1][1] + delay_s - 1e-9) & (np.arange(len(t)) >= run.first_scan)
    if not scans.any():
        return math.nan
    rms = np.sqrt(np.mean(np.sum(run.position_error[scans] ** 2, axis=-1), axis=1))
    return float(rms.mean())


def analyse(ctx: StudyContext, case, spec, run) -> dict:
    """Probabilities, switch-off / re-enable statistics and the after-manoeuvre level of one recorded run."""
    filt, _ = spec.build(FilterSetting(case.dt, ctx.measurements(case).R[0], case.sensor.position))
    names = list(getattr(filt, "names", ()) or ())
    out = {"names": names, "e_post_pos": after_level(run, case, ctx.params["post_delay_s"])}
    channel = "mode_probabilities" if spec.kind == "imm" else "model_probabilities"
    try:
        mu = run.history(channel, "mu")
    except ValueError:
        mu = None
    if mu is not None:
        mean = np.full((mu.shape[0], mu.shape[2]), np.nan)
        started = np.isfinite(mu).all(axis=(1, 2))
        mean[started] = mu[started].mean(axis=1)
        out["mu"] = mean
    if spec.kind != "static-bank":
        return out
    offs, ons = member_events(run, "switch_off"), member_events(run, "reenable")
    state = active_state(len(run.time), run.runs, len(names), offs, ons)
    out["active"] = state.mean(axis=1)
    k_on = onset_scan(case, case.maneuvers[0][0]) if case.maneuvers else len(run.time)
    window = int(ctx.params["switch_window_scans"])
    cv = names.index("CV") if "CV" in names else 0
    first_cv = np.full(run.runs, -1)
    off_before = np.zeros((run.runs, len(names)), bool)
    for k, r, j in offs:
        off_before[r, j] |= k < k_on
        if j == cv and first_cv[r] < 0:
            first_cv[r] = k
    off_count = np.bincount(np.array([j for _, _, j in offs], dtype=np.int64), minlength=len(names))
    on_count = np.bincount(np.array([j for _, _, j in ons], dtype=np.int64), minlength=len(names))
    per_member = {name: {"switched_off_before_onset": float(off_before[:, j].mean()),
                         "switch_offs_per_run": float(off_count[j] / run.runs),
                         "reenables_per_run": float(on_count[j] / run.runs)} for j, name in enumerate(names)}
    out.update({
        "cv_off_in_window": float(np.mean((first_cv >= k_on) & (first_cv <= k_on + window))),
        "any_off_before_onset": float(off_before.any(axis=1).mean()),
        "cv_active_at_end": float(state[-1, :, cv].mean()),
        "switch_offs_per_run": len(offs) / run.runs,
        "reenables_per_run": len(ons) / run.runs,
        "members": per_member,
    })
    if (first_cv >= k_on).any():
        out["cv_off_delay_median_scans"] = float(np.median(first_cv[first_cv >= k_on] - k_on))
    return out


def _series(case, spec, result) -> list[pd.DataFrame]:
    t = case.truth.time
    t_on = case.maneuvers[0][0] if case.maneuvers else 0.0
    frames = []
    for key, name in (("mu", "model_probability"), ("active", "active_fraction")):
        if key not in result:
            continue
        for j, member in enumerate(result["names"] or range(result[key].shape[1])):
            frames.append(pd.DataFrame({"series": name, "case": case.label, "filter": spec.label, "basis": "mean",
                                        "onset": 0 if case.maneuvers else -1, "t": t, "t_rel": t - t_on,
                                        "quantity": f"{key} {member}", "value": result[key][:, j]}))
    return frames


# ---------------------------------------------------------------------- claims
def _assert_switch_off(ctx, results, cases) -> None:
    p = ctx.params
    measured, ok = {}, bool(cases)
    for case in cases:
        r = results.get((case.label, LITERAL_DEFAULT))
        if r is None:
            measured[case.label] = {"note": f"{LITERAL_DEFAULT} was not run"}
            ok = False
            continue
        measured[case.label] = {"n": turn_of(case), "cv_off_in_window": r["cv_off_in_window"],
                                "any_off_before_onset": r["any_off_before_onset"],
                                "cv_off_delay_median_scans": r.get("cv_off_delay_median_scans", math.nan)}
        ok &= r["cv_off_in_window"] >= p["switch_rate_min"] and r["any_off_before_onset"] <= p["early_rate_max"]
    ctx.claim_assert("E7-literal-switch-off", f"literal static bank ({DEFAULT_SET}): the CV member is switched off "
                     "soon after the turn onset and nothing is switched off before it (default scenario, gating off)",
                     f"for every n >= 3: CV switched off within {p['switch_window_scans']} scans after onset in >= "
                     f"{p['switch_rate_min']:.0%} of runs, any switch-off before onset in <= {p['early_rate_max']:.0%}",
                     measured, ok, "P11")


def _reports(ctx, rows, results, cases, labels) -> None:
    table, best, effect, switching = {}, {}, {}, {}
    for case in cases:
        entry = {}
        for label in labels:
            values = metrics_of(rows, case.label, label, COLUMNS)
            values["e_post_pos"] = results.get((case.label, label), {}).get("e_post_pos", math.nan)
            entry[label] = values
        table[case.label] = entry

        def best_of(prefix, column):
            found = {k: v[column] for k, v in entry.items() if k.startswith(prefix) and math.isfinite(v[column])}
            return min(found, key=found.get) if found else None

        best[case.label] = {"imm_by_e_man": best_of("imm-", "e_man_pos"), "imm_by_peak": best_of("imm-", "e_peak_pos"),
                            "improved_bank_by_e_man": best_of("bank-improved-", "e_man_pos"),
                            "literal_bank_by_e_man": best_of("bank-literal-", "e_man_pos"),
                            "any_by_e_man": best_of("", "e_man_pos"), "any_by_e_post": best_of("", "e_post_pos")}
        effect[case.label] = {}
        for label in VARIANTS:
            r = results.get((case.label, label))
            if r is None:
                continue
            effect[case.label][label] = {
                "e_man_pos": entry.get(label, {}).get("e_man_pos", math.nan), "e_post_pos": r["e_post_pos"],
                "settle_end_pos": entry.get(label, {}).get("settle_end_pos", math.nan),
                "loss_rate_on": entry.get(label, {}).get("loss_rate_on", math.nan),
                "cv_active_at_end": r["cv_active_at_end"], "switch_offs_per_run": r["switch_offs_per_run"],
                "reenables_per_run": r["reenables_per_run"]}
        switching[case.label] = {label: {"any_off_before_onset": r["any_off_before_onset"], "members": r["members"]}
                                 for (c, label), r in results.items() if c == case.label and "members" in r}
    ctx.claim_report("E7-model-sets", "RMS position error (pre-onset, over the manoeuvre, peak, after the last manoeuvre), "
                     "settling, loss and NEES per filter and case", table, "P11, P12")
    ctx.claim_report("E7-best-set", "the model set with the lowest manoeuvre RMS (IMM, improved bank, literal bank) and the "
                     "best filter by manoeuvre RMS and by the level after the manoeuvres, per case", best, "P12")
    ctx.claim_report("E7-floor-reenable", f"effect of mu_min and re-enabling on the {DEFAULT_SET} bank: literal, floor "
                     "mu_min = 1e-3 without re-enabling, improved (floor and re-enabling)", effect, "P11")
    ctx.claim_report("E7-switching", "switch-offs and re-enables per member: fraction of runs switching it off before onset, "
                     "switch-offs and re-enables per run", switching, "P11")


# ---------------------------------------------------------------------- figures
def _shade(ax, case, origin: float = 0.0) -> None:
    for onset, end in case.maneuvers:
        ax.axvspan(onset - origin, end - origin, color="0.85", alpha=0.5, zorder=0)


def _plot_probabilities(ctx, case, results, labels) -> None:
    sets = [name for name in dict.fromkeys((*BANK_SETS, *IMM_SETS))
            if any(f"{kind}{name}" in labels for kind in ("bank-literal-", "bank-improved-", "imm-"))]
    if not sets:
        return
    kinds = (("bank-literal-", "literal bank"), ("bank-improved-", "improved bank"), ("imm-", "IMM"))
    with ctx.figure(f"multiple_model_probabilities_{slug(case.label)}.png", f"E7: mean model probabilities, {case.label} "
                    "(manoeuvres shaded)", len(sets), 3, figsize=(16, 3.4 * len(sets))) as (_, axes):
        for row, name in enumerate(sets):
            for col, (prefix, title) in enumerate(kinds):
                r = results.get((case.label, f"{prefix}{name}"))
                if r is None or "mu" not in r:
                    continue
                ax = axes[3 * row + col]
                palette = colours(r["mu"].shape[1])
                for j, member in enumerate(r["names"]):
                    ax.plot(case.truth.time, r["mu"][:, j], color=palette[j], label=member)
                _shade(ax, case)
                ax.set_ylim(-0.02, 1.02)
                ax.set_title(f"{title}, {name}")
                ax.set_xlabel("time [s]")
                ax.set_ylabel("mean probability mu_j")


def _plot_switching(ctx, cases, results) -> None:
    cases = [c for c in cases if any((c.label, v) in results for v in VARIANTS)][: int(ctx.params["plot_cases"])]
    if not cases:
        return
    with ctx.figure("multiple_model_switching.png", f"E7: fraction of runs with each member active ({DEFAULT_SET} bank; "
                    "drops = switch-offs, rises = re-enables)", len(cases), len(VARIANTS),
                    figsize=(18, 3.4 * len(cases))) as (_, axes):
        for row, case in enumerate(cases):
            for col, label in enumerate(VARIANTS):
                r = results.get((case.label, label))
                if r is None or "active" not in r:
                    continue
                ax = axes[row * len(VARIANTS) + col]
                palette = colours(len(r["names"]))
                for j, member in enumerate(r["names"]):
                    ax.plot(case.truth.time, r["active"][:, j], color=palette[j], label=member)
                _shade(ax, case)
                ax.set_ylim(-0.02, 1.02)
                ax.set_title(f"{case.label}: {label}", fontsize="small")
                ax.set_xlabel("time [s]")
                ax.set_ylabel("fraction of runs active")


def _plot_rms(ctx, series, cases, labels) -> None:
    cases = cases[: int(ctx.params["plot_cases"])]
    groups = (("IMM and the improved default bank", [l for l in labels if l.startswith("imm-")] +
               ([IMPROVED_DEFAULT] if IMPROVED_DEFAULT in labels else [])),
              ("static banks", [l for l in labels if l.startswith("bank-")]))
    groups = [g for g in groups if g[1]]
    if not cases or not groups:
        return
    with ctx.figure("multiple_model_rms.png", "E7: RMS position error (manoeuvres shaded)", len(cases), len(groups),
                    figsize=(8 * len(groups), 4.2 * len(cases))) as (_, axes):
        for row, case in enumerate(cases):
            for col, (title, names) in enumerate(groups):
                ax = axes[row * len(groups) + col]
                for i, label in enumerate(names):
                    part = _piecewise(series, case, label, "rms_pos")
                    if not part.empty:
                        colour, style = line_style(i, len(names))
                        ax.plot(part["t"], part["value"], style, color=colour, label=label)
                _shade(ax, case)
                ax.set_yscale("log")
                ax.set_title(f"{case.label}: {title}", fontsize="small")
                ax.set_xlabel("time [s]")
                ax.set_ylabel("RMS position error [m]")
                ax.legend(fontsize="x-small", ncol=2)


def _plot_table(ctx, rows, cases, labels) -> None:
    case_labels = [c.label for c in cases]
    if not case_labels or not labels:
        return
    with ctx.figure("multiple_model_table.png", "E7: RMS position error per filter and case (colour: ratio to the best "
                    "filter of the case)", 1, 2, figsize=(7 + 1.6 * len(case_labels), 0.42 * len(labels) + 2.5)) as (fig, axes):
        for ax, column, title in ((axes[0], "e_man_pos", "mean over the manoeuvre e_man [m]"),
                                  (axes[1], "e_peak_pos", "peak e_peak [m]")):
            values = np.array([[metrics_of(rows, c, label, (column,))[column] for c in case_labels] for label in labels])
            ratio = values / np.nanmin(values, axis=0, keepdims=True)
            image = ax.imshow(np.log10(np.clip(ratio, 1.0, 100.0)), cmap="viridis_r", aspect="auto", vmin=0.0, vmax=1.0)
            for i in range(len(labels)):
                for j in range(len(case_labels)):
                    ax.text(j, i, f"{values[i, j]:.0f}", ha="center", va="center", fontsize="x-small",
                            color="white" if ratio[i, j] > 3 else "black")
            ax.set_xticks(range(len(case_labels)), case_labels, rotation=30, ha="right", fontsize="small")
            ax.set_yticks(range(len(labels)), labels, fontsize="small")
            ax.set_title(title)
            ax.set_xlabel("case")
            ax.set_ylabel("filter")
            fig.colorbar(image, ax=ax, label="log10 (value / best of the case)")


# ---------------------------------------------------------------------- study
def run(ctx: StudyContext) -> None:
    specs = ctx.filters(DEFAULT_FILTERS)
    defaults = default_cases(ctx)
    others = other_cases(ctx, {c.label for c in defaults})
    chosen = {s.label for s in specs}
    on_default = specs + ([ctx.spec(LITERAL_DEFAULT)] if LITERAL_DEFAULT not in chosen else [])
    results, frames = {}, []
    for case in defaults + others:
        case_specs = on_default if case in defaults else specs
        part, kept = ctx.compare([case], case_specs, record=True, keep=True)
        frames.append(part)
        for spec in case_specs:
            result = analyse(ctx, case, spec, kept[(case.label, spec.label, "off")])
            results[(case.label, spec.label)] = result
            for frame in _series(case, spec, result):
                ctx.add_series(frame)
        del kept
    rows = main_rows(pd.concat(frames, ignore_index=True))
    labels = [s.label for s in specs]
    _assert_switch_off(ctx, results, defaults)
    _reports(ctx, rows, results, defaults + others, labels)
    ctx.claim_report("E7-scope", "what this run covered (the fighter scenario, T = 0.1 s, is in the full sweep only: "
                     "study.extra_scenarios [weave, vertical, fighter] or --scenario fighter)",
                     {"default_cases": [c.label for c in defaults], "other_cases": [c.label for c in others],
                      "filters": labels, "runs": ctx.runs, "gatings": list(ctx.gatings)}, "")
    series = ctx.series_frame()
    series = series[(series["series"] == "aligned") & (series["basis"] == "all")]
    for case in (defaults + others)[: int(ctx.params["plot_cases"])]:
        _plot_probabilities(ctx, case, results, labels)
    _plot_switching(ctx, defaults + others, results)
    _plot_rms(ctx, series, defaults + others, labels)
    _plot_table(ctx, rows, defaults + others, labels)


STUDY = StudyDefinition(
    name="multiple-model",
    title="E7: static bank (literal, improved) vs IMM per model set and scenario (P11, P12)",
    run=run,
    paper_claims="P11, P12",
    default_runs=200,
    quick_runs=8,
    default_scenario="default",
    default_filters=DEFAULT_FILTERS,
    params=dict(PARAMS),
    quick_params=dict(QUICK_PARAMS),
    filters=dict(FILTERS),
)

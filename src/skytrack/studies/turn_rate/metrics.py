"""Metrics, tables and expected-behaviour checks of spec 002 §6 E3/E4 (``skytrack study turn-rate-adaptive``).

* :func:`summarize` — ω-RMSE (°/s) and position RMSE (m) over the non-diverged runs and the samples
  of each of the five windows, divergence fraction (run diverged: position error > 1 km), and
  the time curves of the figures (ω-RMSE(t), position RMSE(t), median √V̂_w(t));
* :func:`table_rows` — one row per (setup, configuration, window) with the prototype number beside
  each figure and the verdict (ratio within ×1.5 for RMSE, ±15 percentage points for divergence);
* :func:`expected_checks` — E3's expected behaviour (Doppler: adaptive λ = 0.8 beats the best fixed
  V_w on every straight leg and in turn 1, within 25 % of it in turn 2; position only: it does not
  beat the tuned fixed V_w on the straight legs; the literal per-step (7) is never the best;
  position RMSE range; median √V̂_w at the floor on straight legs, ≈ 0.8°/s early in turn 1, ≈ 0.36°/s
  after turn 2, no jump at the start of turn 2) and E4's divergence fractions (q_a = 0: the prototype's ±15 points;
  q_a = 1 m²/s³: 0 % everywhere).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.studies.fuzzy.common import Check
from skytrack.studies.turn_rate import scenario as sc


@dataclass
class Summary:
    """Metrics of one configuration on one setup."""

    key: str
    T: float
    measurement: str
    q_accel: float
    omega_rmse: np.ndarray  # [5] °/s
    position_rmse: np.ndarray  # [5] m
    diverged: int
    runs: int
    skipped_mean: float
    curves: dict = field(repr=False, default_factory=dict)

    @property
    def diverged_pct(self) -> float:
        return 100.0 * self.diverged / self.runs


def _rmse(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")


def summarize(runset, T: float, measurement: str, q_accel: float) -> Summary:
    """Window metrics over the kept (non-diverged) runs and the figure curves of one :class:`RunSet`."""
    kept = ~runset.diverged
    masks = sc.window_masks(runset.times)
    omega_error = (runset.omega_hat - runset.omega_true[:, None])[:, kept] / sc.DEG
    position_error = runset.position_error[:, kept]
    omega = np.array([_rmse(omega_error[mask]) for mask in masks])
    position = np.array([_rmse(position_error[mask]) for mask in masks])
    with np.errstate(all="ignore"):
        curves = {
            "omega_rmse_t": np.sqrt(np.nanmean(omega_error**2, axis=1)) if kept.any() else np.full(len(masks[0]), np.nan),
            "position_rmse_t": np.sqrt(np.nanmean(position_error**2, axis=1)) if kept.any()
            else np.full(len(masks[0]), np.nan),
            "median_sigma_w_t": np.nanmedian(runset.sigma_w[:, kept], axis=1) / sc.DEG
            if kept.any() and np.isfinite(runset.sigma_w).any() else np.full(len(masks[0]), np.nan),
            "omega_hat_first_run": runset.omega_hat[:, 0] / sc.DEG,
            "omega_true": runset.omega_true / sc.DEG,
            "times": runset.times,
        }
    return Summary(runset.key, T, measurement, q_accel, omega, position, int(runset.diverged.sum()),
                   len(runset.diverged), float(np.mean(runset.skipped)), curves)


def rmse_verdict(value: float, prototype: float | None) -> str:
    """``ok`` when value/prototype lies in [1/1.5, 1.5], ``off`` otherwise, ``—`` without a prototype."""
    if prototype is None or not np.isfinite(value):
        return "—" if prototype is None else "off"
    ratio = value / prototype
    return "ok" if 1.0 / sc.RMSE_FACTOR <= ratio <= sc.RMSE_FACTOR else "off"


def divergence_verdict(pct: float, prototype: float | None) -> str:
    if prototype is None:
        return "—"
    return "ok" if abs(pct - prototype) <= sc.DIVERGENCE_POINTS else "off"


def table_rows(summaries: list[Summary]) -> list[dict]:
    """Long table: one row per (T, measurement set, configuration, window)."""
    rows = []
    for s in summaries:
        prototype = sc.prototype_omega_rmse(s.T, s.measurement, s.key, s.q_accel) if s.key != "imm" else None
        proto_div = sc.prototype_divergence(s.T, s.measurement, s.key, s.q_accel) if s.key != "imm" else None
        for w, name in enumerate(sc.WINDOW_NAMES):
            proto = None if prototype is None else float(prototype[w])
            rows.append({
                "T_s": s.T, "measurement": s.measurement, "q_accel": s.q_accel, "configuration": s.key,
                "window": name, "window_start_s": sc.WINDOWS[w][0], "window_end_s": sc.WINDOWS[w][1],
                "omega_rmse_deg_s": s.omega_rmse[w], "prototype_omega_rmse_deg_s": proto,
                "ratio": s.omega_rmse[w] / proto if proto else np.nan,
                "verdict": rmse_verdict(s.omega_rmse[w], proto),
                "position_rmse_m": s.position_rmse[w],
                "diverged_pct": s.diverged_pct, "prototype_diverged_pct": proto_div,
                "divergence_verdict": divergence_verdict(s.diverged_pct, proto_div),
                "runs": s.runs, "skipped_steps_mean": s.skipped_mean,
            })
    return rows


def _by(summaries: list[Summary], T: float, measurement: str) -> dict[str, Summary]:
    return {s.key: s for s in summaries if s.T == T and s.measurement == measurement}


def _fmt(values) -> str:
    return "/".join(f"{v:.3f}" for v in values)


def expected_checks(summaries: list[Summary]) -> list[Check]:
    """E3's expected behaviour and E4's divergence fractions for the setups that were run."""
    checks: list[Check] = []
    setups = sorted({(s.T, s.measurement, s.q_accel) for s in summaries})
    for T, measurement, q_accel in setups:
        group = _by(summaries, T, measurement)
        label = f"T={T:g} s, {sc.MEASUREMENT_LABELS[measurement]}, q_a={q_accel:g}"
        if not all(key in group for key in sc.CONFIGURATION_KEYS):
            continue
        checks += _prototype_checks(group, T, measurement, q_accel, label)
        if q_accel != sc.PRESET_Q_ACCEL:
            continue
        best_fixed = np.minimum(group["fixed-0.1"].omega_rmse, group["fixed-0.5"].omega_rmse)
        adaptive = group["adaptive-0.8"].omega_rmse
        straight = list(sc.STRAIGHT_WINDOWS)
        if measurement == "pos+rdot":
            checks.append(Check(
                f"{label}: adaptive λ=0.8 beats the best fixed V_w on every straight leg",
                f"adaptive {_fmt(adaptive[straight])} vs best fixed {_fmt(best_fixed[straight])} °/s",
                "adaptive < best fixed on straight 1, 2, 3 (spec: by 1.2-5.4×)",
                np.all(adaptive[straight] < best_fixed[straight])))
            checks.append(Check(
                f"{label}: adaptive λ=0.8 beats the best fixed V_w in turn 1, within 25 % in turn 2",
                f"turn 1 {adaptive[1]:.3f} vs {best_fixed[1]:.3f}; turn 2 {adaptive[3]:.3f} vs {best_fixed[3]:.3f} °/s",
                "turn 1: adaptive < best fixed; turn 2: adaptive ≤ 1.25 × best fixed",
                adaptive[1] < best_fixed[1] and adaptive[3] <= 1.25 * best_fixed[3]))
        else:
            checks.append(Check(
                f"{label}: adaptive λ=0.8 does not beat the tuned fixed V_w on the straight legs",
                f"adaptive {_fmt(adaptive[straight])} vs best fixed {_fmt(best_fixed[straight])} °/s",
                "adaptive ≥ best fixed on straight 1, 2, 3 (adaptation helps only with strong identifiability)",
                np.all(adaptive[straight] >= best_fixed[straight])))
        table = np.stack([group[key].omega_rmse for key in sc.CONFIGURATION_KEYS])
        literal_best = [sc.WINDOW_NAMES[w] for w in range(len(sc.WINDOWS))
                        if np.nanargmin(table[:, w]) == sc.CONFIGURATION_KEYS.index("literal")]
        checks.append(Check(f"{label}: the literal per-step (7) is never the best",
                            "best in: " + (", ".join(literal_best) or "no window"),
                            "literal not the lowest ω-RMSE in any window", not literal_best))
    checks += _position_range_check(summaries)
    checks += _sigma_w_checks(summaries)
    return checks


def _sigma_w_checks(summaries: list[Summary]) -> list[Check]:
    """E3's √V̂_w behaviour for Doppler, T = 1 s, adaptive λ = 0.8, q_a = 1 (median over the kept runs)."""
    match = [s for s in summaries if s.key == "adaptive-0.8" and s.T == 1.0 and s.measurement == "pos+rdot"
             and s.q_accel == sc.PRESET_Q_ACCEL]
    if not match:
        return []
    curves = match[0].curves
    times, median = curves["times"], curves["median_sigma_w_t"]
    floor = sc.PRESET_SIGMA_MIN / sc.DEG

    def span(start, end):
        return median[(times >= start) & (times < end)]

    straight = np.concatenate([span(*sc.WINDOWS[w]) for w in sc.STRAIGHT_WINDOWS])
    at_floor = float(np.mean(straight <= 1.01 * floor))
    turn1, after2, start2 = span(60.0, 67.0).mean(), span(212.0, 219.0).mean(), span(152.0, 159.0)
    label = "T=1 s, pos+ṙ, adaptive λ=0.8: median √V̂_w"
    factor = sc.RMSE_FACTOR
    return [
        Check(f"{label} at the floor on the straight legs", f"{100 * at_floor:.0f} % of straight-leg samples at σ_min",
              "≥ 90 % of the straight-leg samples at the floor", at_floor >= 0.9),
        Check(f"{label} in the first 7 s of turn 1 (mean over [60, 67) s)", f"{turn1:.2f} °/s",
              f"≈ 0.8 °/s (within ×{factor:g})", 0.8 / factor <= turn1 <= 0.8 * factor),
        Check(f"{label} after the end of turn 2 (mean over [212, 219) s)", f"{after2:.2f} °/s",
              f"≈ 0.36 °/s (within ×{factor:g})", 0.36 / factor <= after2 <= 0.36 * factor),
        Check(f"{label} does not jump at the start of turn 2 ([152, 159) s)",
              f"max {start2.max():.2f} °/s, {int(np.sum(start2 > 1.01 * floor))} samples above the floor",
              "stays at the floor (near-radial geometry)", bool(np.all(start2 <= 1.01 * floor))),
    ]


def _prototype_checks(group: dict[str, Summary], T, measurement, q_accel, label) -> list[Check]:
    checks = []
    proto_rmse = [sc.prototype_omega_rmse(T, measurement, key, q_accel) for key in sc.CONFIGURATION_KEYS]
    if all(p is not None for p in proto_rmse):
        ratios = np.array([group[key].omega_rmse / np.asarray(p) for key, p in zip(sc.CONFIGURATION_KEYS, proto_rmse)])
        inside = (ratios >= 1.0 / sc.RMSE_FACTOR) & (ratios <= sc.RMSE_FACTOR)
        outside = [f"{key} {sc.WINDOW_NAMES[w]} ×{ratios[i, w]:.2f}"
                   for i, key in enumerate(sc.CONFIGURATION_KEYS) for w in range(len(sc.WINDOWS)) if not inside[i, w]]
        checks.append(Check(f"{label}: ω-RMSE within ×{sc.RMSE_FACTOR:g} of the prototype",
                            f"{int(inside.sum())}/{inside.size} inside" + ("; off: " + ", ".join(outside) if outside else ""),
                            f"every entry within ×{sc.RMSE_FACTOR:g} (E3 table)", inside.all()))
    proto_div = [sc.prototype_divergence(T, measurement, key, q_accel) for key in sc.CONFIGURATION_KEYS]
    if all(p is not None for p in proto_div):
        measured = [group[key].diverged_pct for key in sc.CONFIGURATION_KEYS]
        strict = q_accel == sc.PRESET_Q_ACCEL  # E4: "with q_a = 1 m²/s³: 0 % everywhere"
        ok = all(m == 0 for m in measured) if strict else \
            all(abs(m - p) <= sc.DIVERGENCE_POINTS for m, p in zip(measured, proto_div))
        expected = "0 % everywhere" if strict else \
            "/".join(f"{p:.0f}" for p in proto_div) + f" % ± {sc.DIVERGENCE_POINTS:g} points"
        checks.append(Check(f"{label}: divergence fractions (fixed 0.1/0.5, adaptive 0.8/0.95, literal)",
                            "/".join(f"{m:.0f}" for m in measured) + " %", expected, ok))
    return checks


def _position_range_check(summaries: list[Summary]) -> list[Check]:
    preset = [s for s in summaries if s.q_accel == sc.PRESET_Q_ACCEL and s.key != "imm"]
    if not preset:
        return []
    values = np.concatenate([s.position_rmse for s in preset])
    low, high = sc.POSITION_RMSE_RANGE
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    return [Check("position RMSE range over every q_a = 1 configuration and window",
                  f"{lo:.1f}-{hi:.1f} m",
                  f"{low:g}-{high:g} m (prototype), within ×{sc.RMSE_FACTOR:g}: "
                  f"{low / sc.RMSE_FACTOR:.1f}-{high * sc.RMSE_FACTOR:.0f} m",
                  lo >= low / sc.RMSE_FACTOR and hi <= high * sc.RMSE_FACTOR)]

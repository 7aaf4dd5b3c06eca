"""Study E1 ``ab-range`` of spec 004 §6: the paper's α–β range tracker (1)–(4) and claim P1.

The paper's only equations, (1)–(4) of §3.1, in :class:`skytrack.filters.range_tracker.RangeAlphaBeta`
(R3: T explicit, range gate ``|ΔД| <= g √S₀``, loss after L_miss consecutive misses, optional
manoeuvre gains), run on 1-D range measurements this study generates itself: truth
``Д(t) = Д₀ + V₀ t`` (Д₀ = 30 km, V₀ = −600 m/s) with a range acceleration A = n g₀ from
t = 10 s for 5 s (n = 0…8), T = 0.1 s, 30 s, measurements ``Д_и(k) = Д(kT) + σ_v e_k``
(σ_v = 10 m), exact initial values (initialisation ``given``), g = 3, L_miss = 3.  Run r draws
its errors from ``default_rng(SeedSequence(seed).spawn(runs)[r])`` (R21): first the 300 of the
scenario (the same for every n, α and gain rule: common random numbers), then those of the
noise-only segments.

The gains sweep α ∈ {0.1, …, 0.9} with β by Benedict–Bordner ``β = α²/(2 − α)`` and, as a
second curve, on the Kalata DWNA curve ``β = 2(2 − α) − 4√(1 − α)`` (§3.3 C).  Every (rule, α)
runs with fixed gains (the literal method) and with R3's ``maneuver_gains="kalata"``, gate off
(accuracy) and gate on (track loss).

Claims (P1: α, β trade accuracy against robustness to track loss):

* assert ``E1-noise-variance`` — noise-only filtered range error variance (n = 0, gate off) within
  5 % of the closed form ``σ_v² (2α² + 2β − 3αβ)/(α(4 − 2α − β))`` for every rule and α,
  measured on ``noise_segments`` (16) noise-only segments per run of ``noise_scans`` (500)
  scans from exact initial values, the first ``noise_warmup_scans`` (100) of each dropped
  (their start transient decays as (1 − α)^k <= 0.9^100).  The 30-s scenario alone cannot show
  5 % at 50 runs: the error of α = 0.1 is correlated over ~20 scans, so 200 scans of 50 runs
  estimate its variance only to ±5 % (one st. dev.); the segments (6 400 scans per run, run as
  extra rows of one batch) resolve it to about ±1 %;
* assert ``E1-lag`` — noise-free runs with A held for ``lag_scans`` (>= 400) scans from exact
  initial values: the filtered lag (truth − estimate) at the last scan within 1 % of the steady
  state ``(1 − α) A T²/β`` for every rule, α and n >= 1;
* assert ``E1-loss-u-shape`` — fixed gains, gate on, every n >= ``loss_min_n`` (4): the loss
  rate at the smallest α and at the largest α of the sweep each exceed min_α loss by >= 0.05,
  for every rule (the accuracy/robustness compromise: lag breaks lock at small α, noise at large α);
* report ``E1-best-alpha`` — per rule and n, the loss-minimising α (gate on) and the
  RMS-minimising α (filtered range error over all scans and runs, gate off);
* report ``E1-maneuver-gains`` — loss and RMS with ``maneuver_gains`` vs fixed gains per n and
  α, the fraction of runs with a detection and of scans on manoeuvre gains (gate off; at n = 0
  false alarms: the detector's P_fa = 0.01 is per scan, so most 300-scan runs have one).

RMS and loss are reported separately (R20): RMS with the gate off over every run, and with the
gate on over the runs never lost.  Outputs: ``summary.csv`` (part ``sweep``: one row per rule,
gains option, α, n; parts ``noise-only`` and ``lag``), ``timeseries.parquet`` (series
``range_error``: mean and RMS filtered range error, gate off, and the lost fraction, gate on,
vs time, t_rel from the manoeuvre onset), figures ``ab_range_noise.png``, ``ab_range_lag.png``,
``ab_range_loss.png``, ``ab_range_tradeoff.png``.  ``--scenario``, ``--truth``, ``--filters`` and
the scenario keys of ``--config`` do not apply (the study builds its 1-D truth); its parameters
go in the config's ``study`` section (:data:`PARAMS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from skytrack.filters import alpha_beta_gains as gains
from skytrack.filters.range_tracker import RangeAlphaBeta, RangeTrackResult
from skytrack.studies.maneuver.measurements import run_generators
from skytrack.studies.maneuver.outputs import colours
from skytrack.studies.maneuver.study import StudyContext, StudyDefinition

G0 = 9.80665
RULES = ("benedict-bordner", "kalata")
GAINS_OPTIONS = ("fixed", "maneuver")
#: config keys of the framework that E1 uses; the scenario, sensor and filter keys do not apply
USED_CONFIG_KEYS = {"runs", "seed", "study"}
PARAMS = {
    "period_s": 0.1,
    "duration_s": 30.0,
    "sigma_v_m": 10.0,
    "range0_m": 30000.0,
    "range_rate_m_s": -600.0,
    "accel_start_s": 10.0,
    "accel_duration_s": 5.0,
    "load_factors": [0, 1, 2, 3, 4, 5, 6, 7, 8],
    "alphas": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9],
    "gain_rules": list(RULES),
    "gate": 3.0,
    "max_misses": 3,
    "maneuver_gains": "kalata",
    "noise_segments": 16,
    "noise_scans": 500,
    "noise_warmup_scans": 100,
    "noise_tolerance": 0.05,
    "lag_scans": 400,
    "lag_tolerance": 0.01,
    "loss_margin": 0.05,
    "loss_min_n": 4,
}


@dataclass(frozen=True)
class RangeScenario:
    """The 1-D truth of E1: constant range rate, then A = n g₀ for ``accel_duration`` s from ``accel_start``."""

    period: float
    duration: float
    sigma_v: float
    range0: float
    range_rate: float
    accel_start: float
    accel_duration: float

    @classmethod
    def from_params(cls, p: dict) -> "RangeScenario":
        return cls(float(p["period_s"]), float(p["duration_s"]), float(p["sigma_v_m"]), float(p["range0_m"]),
                   float(p["range_rate_m_s"]), float(p["accel_start_s"]), float(p["accel_duration_s"]))

    @property
    def scans(self) -> int:
        """Measurements k = 1 … K (the estimate at k = 0 is the exact initial value)."""
        return int(round(self.duration / self.period))

    @property
    def time(self) -> np.ndarray:
        """``t_k = k T`` for k = 0 … K."""
        return np.arange(self.scans + 1) * self.period

    @property
    def end_scan(self) -> int:
        """Index (into :attr:`time`) of the last scan of the acceleration."""
        return int(round((self.accel_start + self.accel_duration) / self.period))

    def truth(self, acceleration) -> tuple[np.ndarray, np.ndarray]:
        """Exact range and range rate ``[len(acceleration), K + 1]`` (piecewise polynomial, no integration)."""
        A = np.atleast_1d(np.asarray(acceleration, float))[:, None]
        t = self.time[None, :]
        inside = np.clip(t - self.accel_start, 0.0, self.accel_duration)
        after = np.clip(t - self.accel_start - self.accel_duration, 0.0, None)
        rng = self.range0 + self.range_rate * t + A * (0.5 * inside**2 + self.accel_duration * after)
        return rng, self.range_rate + A * inside


def check_params(p: dict) -> None:
    """ValueError naming the study parameter that is out of range."""
    for key in ("period_s", "duration_s", "sigma_v_m", "gate", "accel_duration_s"):
        if not (math.isfinite(float(p[key])) and float(p[key]) > 0):
            raise ValueError(f"ab-range: study parameter {key} must be finite and > 0, got {p[key]}")
    alphas = np.asarray(p["alphas"], float)
    if alphas.ndim != 1 or len(alphas) < 2 or not np.all((alphas > 0) & (alphas < 1)) or np.any(np.diff(alphas) <= 0):
        raise ValueError(f"ab-range: study parameter alphas must be >= 2 increasing values in (0, 1), got {p['alphas']}")
    n = np.asarray(p["load_factors"], float)
    if n.ndim != 1 or not len(n) or np.any(n < 0) or len(set(n.tolist())) != len(n):
        raise ValueError(f"ab-range: study parameter load_factors must be distinct values >= 0, got {p['load_factors']}")
    rules = list(p["gain_rules"])
    if not rules or any(r not in RULES for r in rules) or len(set(rules)) != len(rules):
        raise ValueError(f"ab-range: study parameter gain_rules must be distinct names from {RULES}, got {p['gain_rules']}")
    for key in ("max_misses", "noise_segments", "noise_scans", "lag_scans"):
        if int(p[key]) != p[key] or p[key] < 1:
            raise ValueError(f"ab-range: study parameter {key} must be an integer >= 1, got {p[key]}")
    if int(p["noise_warmup_scans"]) != p["noise_warmup_scans"] or not 0 <= p["noise_warmup_scans"] < p["noise_scans"]:
        raise ValueError(f"ab-range: study parameter noise_warmup_scans must be an integer in [0, noise_scans), "
                         f"got {p['noise_warmup_scans']}")
    if not float(p["accel_start_s"]) + float(p["accel_duration_s"]) <= float(p["duration_s"]):
        raise ValueError("ab-range: study parameters accel_start_s + accel_duration_s must not exceed duration_s")


def beta_of(rule: str, alpha: float) -> float:
    """β of α by Benedict–Bordner or on the Kalata DWNA curve (§3.3 C)."""
    return float(gains.benedict_bordner_beta(alpha) if rule == "benedict-bordner" else gains.kalata_beta_from_alpha(alpha))


def draw_errors(seed: int, runs: int, scans: int, segments: int, noise_scans: int) -> tuple[np.ndarray, np.ndarray]:
    """Standard normal errors ``[runs, scans]`` of the scenario and ``[runs, segments, noise_scans]`` of the
    noise-only segments; run r's come from run r's generator only (R21), the scenario's first."""
    scenario, noise_only = np.empty((runs, scans)), np.empty((runs, segments, noise_scans))
    for r, rng in enumerate(run_generators(seed, runs)):
        scenario[r] = rng.standard_normal(scans)
        noise_only[r] = rng.standard_normal((segments, noise_scans))
    return scenario, noise_only


def _tracker(ctx: StudyContext, sc: RangeScenario, alpha: float, beta: float, *, gating: bool = False,
             maneuver: bool = False) -> RangeAlphaBeta:
    p = ctx.params
    return RangeAlphaBeta(alpha, beta, sc.period, sigma_v=sc.sigma_v, gating=gating, gate=float(p["gate"]),
                          max_misses=int(p["max_misses"]), maneuver_gains=p["maneuver_gains"] if maneuver else None)


def _label(rule: str, alpha: float, option: str) -> str:
    return f"{rule} alpha={alpha:.2f}" + (" + manoeuvre gains" if option == "maneuver" else "")


# ---------------------------------------------------------------------------- sweep
def _take(result: RangeTrackResult, rows: slice) -> RangeTrackResult:
    """The rows ``rows`` of every history of a tracker result."""
    return RangeTrackResult(*(getattr(result, f.name)[rows] for f in fields(result)))


def sweep(ctx: StudyContext, sc: RangeScenario, errors: np.ndarray) -> dict:
    """Every (rule, gains option, α) on all n at once (rows = n-major runs), gate off and on.

    Returns arrays ``[n, α]`` per (rule, option): loss, mean loss time, RMS range / velocity
    (gate off), RMS range of never-lost runs (gate on), kept runs, mean error at the end of the
    acceleration (Monte Carlo mean and noise-free: the same in expectation, the filter being linear),
    detection rate; and the tidy time series.  The noise-free runs ride as extra rows of the
    gate-off batch.
    """
    p = ctx.params
    n_values = np.asarray(p["load_factors"], float)
    alphas = np.asarray(p["alphas"], float)
    runs, n_count = errors.shape[0], len(n_values)
    truth_range, truth_rate = sc.truth(n_values * G0)
    z = (truth_range[:, None, 1:] + sc.sigma_v * errors[None]).reshape(n_count * runs, sc.scans)
    z_off = np.vstack([z, truth_range[:, 1:]])
    mc = slice(0, n_count * runs)
    t = sc.time[1:]
    out, frames = {}, []
    for rule in p["gain_rules"]:
        for option in GAINS_OPTIONS:
            shape = (n_count, len(alphas))
            res = {k: np.full(shape, np.nan) for k in ("loss", "loss_time", "rms", "rms_vel", "rms_kept", "kept", "lag_end",
                                                        "lag_end_noise_free", "peak_mean_error", "detection",
                                                        "maneuver_fraction")}
            for j, alpha in enumerate(alphas):
                beta = beta_of(rule, alpha)
                label = _label(rule, alpha, option)
                both = _tracker(ctx, sc, alpha, beta, maneuver=option == "maneuver").run(z_off, sc.range0, sc.range_rate)
                noise_free = truth_range[:, 1:] - both.range[n_count * runs:]
                off = _take(both, mc)
                ctx.advance(f"{label} · gate off")
                on = _tracker(ctx, sc, alpha, beta, gating=True, maneuver=option == "maneuver").run(z, sc.range0, sc.range_rate)
                ctx.advance(f"{label} · gate on")
                err = truth_range[:, None, 1:] - off.range.reshape(n_count, runs, -1)
                err_vel = truth_rate[:, None, 1:] - off.velocity.reshape(n_count, runs, -1)
                lost = on.lost[:, -1].reshape(n_count, runs)
                lost_scan = on.lost_scan.reshape(n_count, runs)
                err_on = truth_range[:, None, 1:] - on.range.reshape(n_count, runs, -1)
                res["loss"][:, j] = lost.mean(axis=1)
                with np.errstate(invalid="ignore"):
                    res["loss_time"][:, j] = np.where(lost, t[np.maximum(lost_scan, 0)], np.nan).sum(axis=1) / lost.sum(axis=1)
                    kept_sq = np.where(~lost[:, :, None], err_on**2, 0.0).sum(axis=(1, 2))
                    res["rms_kept"][:, j] = np.sqrt(kept_sq / ((~lost).sum(axis=1) * sc.scans))
                res["kept"][:, j] = (~lost).sum(axis=1)
                res["rms"][:, j] = np.sqrt(np.mean(err**2, axis=(1, 2)))
                res["rms_vel"][:, j] = np.sqrt(np.mean(err_vel**2, axis=(1, 2)))
                mean_err = err.mean(axis=1)
                res["lag_end"][:, j] = mean_err[:, sc.end_scan - 1]
                res["lag_end_noise_free"][:, j] = noise_free[:, sc.end_scan - 1]
                res["peak_mean_error"][:, j] = np.abs(mean_err).max(axis=1)
                flags = off.maneuver.reshape(n_count, runs, -1)
                res["detection"][:, j] = flags.any(axis=2).mean(axis=1)
                res["maneuver_fraction"][:, j] = flags.mean(axis=(1, 2))
                rms_t = np.sqrt(np.mean(err**2, axis=1))
                lost_t = on.lost.reshape(n_count, runs, -1).mean(axis=1)
                for i, n in enumerate(n_values):
                    for basis, quantity, values in (("gating off", "mean_error_m", mean_err[i]), ("gating off", "rms_error_m", rms_t[i]),
                                                    ("gating on", "lost_fraction", lost_t[i])):
                        frames.append(pd.DataFrame({"series": "range_error", "case": f"n={n:g}", "filter": label, "basis": basis,
                                                    "onset": 0, "t": t, "t_rel": t - sc.accel_start, "quantity": quantity,
                                                    "value": values}))
            out[(rule, option)] = res
    ctx.add_series(pd.concat(frames, ignore_index=True))
    rows = []
    for (rule, option), res in out.items():
        for j, alpha in enumerate(alphas):
            beta = beta_of(rule, alpha)
            lags = gains.steady_state_lags(alpha, beta, sc.period, 1.0)
            gate_halfwidth = float(p["gate"]) * math.sqrt(_tracker(ctx, sc, alpha, beta, gating=True).gate_variance())
            for i, n in enumerate(n_values):
                rows.append({"part": "sweep", "rule": rule, "gains": option, "alpha": alpha, "beta": beta,
                             "tracking_index": gains.equivalent_tracking_index(alpha, beta), "n": n, "accel_m_s2": n * G0,
                             "runs": runs, "loss_rate": res["loss"][i, j], "mean_loss_time_s": res["loss_time"][i, j],
                             "rms_range_m": res["rms"][i, j], "rms_velocity_m_s": res["rms_vel"][i, j],
                             "rms_range_kept_m": res["rms_kept"][i, j], "runs_kept": int(res["kept"][i, j]),
                             "mean_error_accel_end_m": res["lag_end"][i, j],
                             "noise_free_error_accel_end_m": res["lag_end_noise_free"][i, j], "peak_mean_error_m": res["peak_mean_error"][i, j],
                             "lag_filtered_closed_form_m": n * G0 * lags.filtered_position,
                             "lag_predicted_closed_form_m": n * G0 * lags.predicted_position,
                             "gate_halfwidth_m": gate_halfwidth, "detection_rate": res["detection"][i, j],
                             "maneuver_scan_fraction": res["maneuver_fraction"][i, j]})
    ctx.add_summary(rows)
    return out


# ---------------------------------------------------------------------------- noise-only and lag
def noise_only(ctx: StudyContext, sc: RangeScenario, errors: np.ndarray) -> dict:
    """Steady-state filtered range / velocity error variances of the noise-only segments (n = 0, gate off;
    ``errors[runs, segments, scans]``, each segment from exact initial values, the first
    ``noise_warmup_scans`` dropped) against the closed forms, per rule and α."""
    p = ctx.params
    warm = int(p["noise_warmup_scans"])
    scans = errors.shape[-1]
    t = np.arange(1, scans + 1) * sc.period
    truth = sc.range0 + sc.range_rate * t
    z = truth[None, :] + sc.sigma_v * errors.reshape(-1, scans)
    result, rows = {}, []
    for rule in p["gain_rules"]:
        for alpha in p["alphas"]:
            beta = beta_of(rule, alpha)
            run = _tracker(ctx, sc, alpha, beta).run(z, sc.range0, sc.range_rate)
            ctx.advance(f"noise-only {_label(rule, alpha, 'fixed')}")
            err = truth[None, warm:] - run.range[:, warm:]
            err_vel = sc.range_rate - run.velocity[:, warm:]
            ratios = gains.variance_ratios(alpha, beta, sc.period)
            var, closed = float(np.mean(err**2)), sc.sigma_v**2 * ratios.filtered_position
            var_vel, closed_vel = float(np.mean(err_vel**2)), sc.sigma_v**2 * ratios.velocity
            result[(rule, alpha)] = {"variance": var, "closed_form": closed, "ratio": var / closed,
                                     "rms": math.sqrt(var), "rms_closed_form": math.sqrt(closed),
                                     "rms_velocity": math.sqrt(var_vel), "rms_velocity_closed_form": math.sqrt(closed_vel)}
            rows.append({"part": "noise-only", "rule": rule, "gains": "fixed", "alpha": alpha, "beta": beta, "n": 0.0,
                         "runs": errors.shape[0], "scans_used": errors.shape[1] * (scans - warm), "range_error_variance_m2": var,
                         "range_error_variance_closed_form_m2": closed, "variance_ratio": var / closed,
                         "velocity_error_variance": var_vel, "velocity_error_variance_closed_form": closed_vel})
    ctx.add_summary(rows)
    return result


def held_lags(ctx: StudyContext, sc: RangeScenario) -> dict:
    """Filtered lag at the last of ``lag_scans`` noise-free scans with A = n g₀ from t = 0 (n > 0), exact
    initial values, vs ``(1 − α) A T²/β``: relative errors ``[n]`` per (rule, α)."""
    p = ctx.params
    n_values = np.asarray([n for n in p["load_factors"] if n > 0], float)
    scans = int(p["lag_scans"])
    t = np.arange(1, scans + 1) * sc.period
    A = n_values * G0
    truth = sc.range0 + sc.range_rate * t[None, :] + 0.5 * A[:, None] * t[None, :] ** 2
    result, rows = {}, []
    for rule in p["gain_rules"]:
        for alpha in p["alphas"]:
            beta = beta_of(rule, alpha)
            run = _tracker(ctx, sc, alpha, beta).run(truth, sc.range0, sc.range_rate)
            ctx.advance(f"noise-free lag {_label(rule, alpha, 'fixed')}")
            lag = truth[:, -1] - run.range[:, -1]
            closed = np.asarray(gains.steady_state_lags(alpha, beta, sc.period, A).filtered_position)
            rel = np.abs(lag / closed - 1.0)
            result[(rule, alpha)] = rel
            for n, a, measured, expected, r in zip(n_values, A, lag, closed, rel):
                rows.append({"part": "lag", "rule": rule, "gains": "fixed", "alpha": alpha, "beta": beta, "n": n,
                             "accel_m_s2": a, "scans_used": scans, "lag_m": measured, "lag_closed_form_m": expected,
                             "lag_relative_error": r})
    ctx.add_summary(rows)
    return result


# ---------------------------------------------------------------------------- claims
def _alpha_key(alpha: float) -> str:
    return f"{alpha:.2f}"


def claims(ctx: StudyContext, noise: dict, lags: dict, results: dict) -> None:
    p = ctx.params
    alphas = [float(a) for a in p["alphas"]]
    n_values = [float(n) for n in p["load_factors"]]
    tol = float(p["noise_tolerance"])
    ratios = {rule: {_alpha_key(a): noise[(rule, a)]["ratio"] for a in alphas} for rule in p["gain_rules"]}
    worst = max(abs(v - 1.0) for per in ratios.values() for v in per.values())
    ctx.claim_assert("E1-noise-variance", "noise-only filtered range error variance (n = 0, gate off) equals the closed "
                     "form sigma_v^2 (2a^2 + 2b - 3ab)/(a(4 - 2a - b))",
                     f"|measured / closed form - 1| <= {tol:g} for every rule and alpha",
                     {"ratio": ratios, "max_abs_deviation": worst, "runs": ctx.runs,
                      "scans_per_run": int(p["noise_segments"]) * (int(p["noise_scans"]) - int(p["noise_warmup_scans"]))},
                     worst <= tol, "P1")
    lag_tol = float(p["lag_tolerance"])
    rel = {rule: {_alpha_key(a): float(np.max(lags[(rule, a)])) if len(lags[(rule, a)]) else math.nan for a in alphas}
           for rule in p["gain_rules"]}
    worst_lag = max(v for per in rel.values() for v in per.values())
    measured = {"max_relative_error": rel, "worst": worst_lag, "scans": int(p["lag_scans"]),
                "n": [n for n in n_values if n > 0]}
    if not measured["n"]:
        measured["note"] = "no load factor n > 0 in the sweep: nothing to measure"
    ctx.claim_assert("E1-lag", "filtered range lag of a noise-free run with A held is the steady state (1 - alpha) A T^2/beta",
                     f"relative error at the last of {int(p['lag_scans'])} scans <= {lag_tol:g} for every rule, alpha, n > 0",
                     measured, bool(measured["n"]) and worst_lag <= lag_tol, "P1")
    margin, n_min = float(p["loss_margin"]), float(p["loss_min_n"])
    shape, passed = {}, True
    for rule in p["gain_rules"]:
        loss = results[(rule, "fixed")]["loss"]
        for i, n in enumerate(n_values):
            if n < n_min:
                continue
            low, high, best = float(loss[i, 0]), float(loss[i, -1]), float(loss[i].min())
            shape[f"{rule} n={n:g}"] = {"loss_smallest_alpha": low, "loss_largest_alpha": high, "min_loss": best,
                                        "alpha_min_loss": alphas[int(np.argmin(loss[i]))]}
            passed &= low - best >= margin and high - best >= margin
    measured = {"cases": shape, "alphas": [alphas[0], alphas[-1]], "runs": ctx.runs}
    if not shape:
        measured["note"] = f"no load factor n >= {n_min:g} in the sweep"
    ctx.claim_assert("E1-loss-u-shape", "track loss is U-shaped in alpha (fixed gains, gate on): lag breaks lock at small "
                     "alpha, noise at large alpha", f"for n >= {n_min:g}: loss(smallest alpha) - min loss >= {margin:g} and "
                     f"loss(largest alpha) - min loss >= {margin:g}, every rule", measured, bool(shape) and passed, "P1")
    best = {}
    for rule in p["gain_rules"]:
        res = results[(rule, "fixed")]
        best[rule] = {f"n={n:g}": {"alpha_min_loss": alphas[int(np.argmin(res["loss"][i]))],
                                   "alphas_at_min_loss": [a for a, v in zip(alphas, res["loss"][i]) if v == res["loss"][i].min()],
                                   "min_loss": float(res["loss"][i].min()),
                                   "alpha_min_rms": alphas[int(np.argmin(res["rms"][i]))], "min_rms_m": float(res["rms"][i].min())}
                      for i, n in enumerate(n_values)}
    ctx.claim_report("E1-best-alpha", "loss-minimising alpha (gate on, fixed gains; the smallest of ties) and RMS-minimising "
                     "alpha (filtered range error over all scans and runs, gate off) per n", best, "P1")
    compare = {}
    for rule in p["gain_rules"]:
        fixed, man = results[(rule, "fixed")], results[(rule, "maneuver")]
        compare[rule] = {
            "alphas": alphas,
            **{key: {f"n={n:g}": res[name][i].tolist() for i, n in enumerate(n_values)}
               for key, res, name in (("loss_fixed", fixed, "loss"), ("loss_maneuver", man, "loss"),
                                      ("rms_fixed_m", fixed, "rms"), ("rms_maneuver_m", man, "rms"),
                                      ("detection_rate_maneuver", man, "detection"),
                                      ("maneuver_scan_fraction", man, "maneuver_fraction"))},
            "min_loss_over_alpha": {f"n={n:g}": {"fixed": float(fixed["loss"][i].min()), "maneuver": float(man["loss"][i].min())}
                                    for i, n in enumerate(n_values)},
        }
    ctx.claim_report("E1-maneuver-gains", f"maneuver_gains={p['maneuver_gains']!r} (R3 detector, Kalata gains of 10x the "
                     "nominal index) vs fixed gains: loss (gate on) and RMS range error (gate off) per n over alpha, the rate of "
                     "runs with a manoeuvre detection and the fraction of scans on manoeuvre gains (gate off; at n = 0 "
                     "false alarms: P_fa is per scan)", compare, "P1")


# ---------------------------------------------------------------------------- figures
def _pairs(count: int) -> list[tuple]:
    """Dark/light colour pairs (tab20) for measured/closed-form curves of one rule."""
    import matplotlib

    cmap = matplotlib.colormaps["tab20"]
    return [(cmap(2 * i), cmap(2 * i + 1)) for i in range(count)]


def figures(ctx: StudyContext, sc: RangeScenario, noise: dict, results: dict) -> None:
    p = ctx.params
    alphas = np.asarray(p["alphas"], float)
    n_values = np.asarray(p["load_factors"], float)
    rules = list(p["gain_rules"])
    fine = np.linspace(alphas[0], alphas[-1], 200)
    pairs = _pairs(len(rules))
    with ctx.figure("ab_range_noise.png", f"E1: noise-only errors of the alpha-beta range tracker (sigma_v = {sc.sigma_v:g} m, "
                    f"T = {sc.period:g} s, {ctx.runs} runs)", 1, 2) as (_, axes):
        for (dark, light), rule in zip(pairs, rules):
            fine_beta = np.array([beta_of(rule, a) for a in fine])
            ratios = gains.variance_ratios(fine, fine_beta, sc.period)
            for ax, key, ratio in ((axes[0], "rms", ratios.filtered_position), (axes[1], "rms_velocity", ratios.velocity)):
                ax.plot(fine, sc.sigma_v * np.sqrt(ratio), "-", color=light, label=f"{rule}: closed form")
                ax.plot(alphas, [noise[(rule, a)][key] for a in p["alphas"]], "o", color=dark, label=f"{rule}: measured")
        axes[0].set_ylabel("RMS filtered range error [m]")
        axes[1].set_ylabel("RMS range-rate error [m/s]")
        for ax in axes:
            ax.set_xlabel("alpha")
    _lag_figure(ctx, sc, results)
    _loss_figure(ctx, results)
    palette = colours(len(n_values))
    rule = rules[0]
    fixed = results[(rule, "fixed")]
    with ctx.figure("ab_range_tradeoff.png", f"E1 (P1): accuracy vs robustness, {rule} gains, A = n g0 for "
                    f"{sc.accel_duration:g} s ({ctx.runs} runs)", 1, 2) as (_, axes):
        for i, n in enumerate(n_values):
            axes[0].plot(alphas, fixed["loss"][i], "o-", color=palette[i], label=f"n = {n:g}")
            axes[1].plot(alphas, fixed["rms"][i], "o-", color=palette[i], label=f"n = {n:g}")
        axes[0].set_ylabel("track-loss rate (gate on, fixed gains)")
        axes[1].set_ylabel("RMS filtered range error, gate off [m]")
        axes[1].set_yscale("log")
        for ax in axes:
            ax.set_xlabel("alpha")


def _lag_figure(ctx: StudyContext, sc: RangeScenario, results: dict) -> None:
    p = ctx.params
    alphas = np.asarray(p["alphas"], float)
    n_all = list(np.asarray(p["load_factors"], float))
    n_values = [n for n in n_all if n > 0]
    rules = list(p["gain_rules"])
    fine = np.linspace(alphas[0], alphas[-1], 200)
    palette = colours(len(n_values))
    end = sc.accel_start + sc.accel_duration
    with ctx.figure("ab_range_lag.png", f"E1: filtered range lag vs alpha (lines: steady state (1 - alpha) A T^2/beta; dots: "
                    f"noise-free error at t = {end:g} s, end of the {sc.accel_duration:g}-s acceleration)",
                    1, len(rules)) as (_, axes):
        for ax, rule in zip(axes, rules):
            fine_beta = np.array([beta_of(rule, a) for a in fine])
            lag_unit = gains.steady_state_lags(fine, fine_beta, sc.period, 1.0).filtered_position
            res = results[(rule, "fixed")]
            for k, n in enumerate(n_values):
                i = n_all.index(n)
                ax.plot(fine, n * G0 * lag_unit, "-", color=palette[k], label=f"n = {n:g}")
                ax.plot(alphas, res["lag_end_noise_free"][i], "o", color=palette[k], label="_noise-free run")
            gate = [float(p["gate"]) * math.sqrt(_tracker(ctx, sc, a, beta_of(rule, a), gating=True).gate_variance()) for a in fine]
            ax.plot(fine, gate, "k--", label="range gate g sqrt(S0) on the residual")
            ax.set_yscale("log")
            ax.set_title(f"{rule} gains")
            ax.set_xlabel("alpha")
            ax.set_ylabel("filtered range lag (truth - estimate) [m]")


def _loss_figure(ctx: StudyContext, results: dict) -> None:
    from matplotlib.patches import Rectangle

    p = ctx.params
    alphas = np.asarray(p["alphas"], float)
    n_values = np.asarray(p["load_factors"], float)
    rules = list(p["gain_rules"])
    with ctx.figure("ab_range_loss.png", f"E1 (P1): track-loss rate vs (alpha, n), gate g = {float(p['gate']):g}, "
                    f"L_miss = {int(p['max_misses'])} ({ctx.runs} runs; boxes: loss-minimising alpha)",
                    len(GAINS_OPTIONS), len(rules), figsize=(7.0 * len(rules), 5.0 * len(GAINS_OPTIONS))) as (fig, axes):
        for row, option in enumerate(GAINS_OPTIONS):
            for col, rule in enumerate(rules):
                ax = axes[row * len(rules) + col]
                loss = results[(rule, option)]["loss"]
                image = ax.imshow(loss, origin="lower", aspect="auto", vmin=0.0, vmax=1.0, cmap="viridis")
                for i in range(len(n_values)):
                    for j in range(len(alphas)):
                        ax.text(j, i, f"{loss[i, j]:.2f}", ha="center", va="center", fontsize=7,
                                color="black" if loss[i, j] > 0.6 else "white")
                    best = int(np.argmin(loss[i]))
                    ax.add_patch(Rectangle((best - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="red", linewidth=1.5))
                ax.set_xticks(range(len(alphas)), [f"{a:.1f}" for a in alphas])
                ax.set_yticks(range(len(n_values)), [f"{n:g}" for n in n_values])
                ax.set_xlabel(f"alpha ({rule} beta)")
                ax.set_ylabel("range acceleration n [g0]")
                ax.set_title(f"{rule}: " + ("fixed gains" if option == "fixed" else f"maneuver_gains={p['maneuver_gains']!r}"))
                fig.colorbar(image, ax=ax, label="track-loss rate")


# ---------------------------------------------------------------------------- study
def _reject_inapplicable(ctx: StudyContext) -> None:
    opts = ctx.options
    for flag, value in (("--scenario", opts.scenario), ("--truth", opts.truth), ("--filters", opts.filters)):
        if value is not None:
            raise ValueError(f"{flag} does not apply to ab-range: E1 builds its own 1-D range truth; set its parameters in "
                             f"the config's study section ({', '.join(sorted(PARAMS))})")
    extra = sorted(set(opts.config) - USED_CONFIG_KEYS)
    if extra:
        raise ValueError(f"--config: key(s) {extra} do not apply to ab-range (it uses {sorted(USED_CONFIG_KEYS)}); "
                         "its scenario parameters go in the study section")


def run(ctx: StudyContext) -> None:
    _reject_inapplicable(ctx)
    p = ctx.params
    check_params(p)
    sc = RangeScenario.from_params(p)
    count = len(p["gain_rules"]) * len(p["alphas"])
    ctx.expect(count * (2 * len(GAINS_OPTIONS) + 2))
    errors, noise_errors = draw_errors(ctx.seed, ctx.runs, sc.scans, int(p["noise_segments"]), int(p["noise_scans"]))
    noise = noise_only(ctx, sc, noise_errors)
    lags = held_lags(ctx, sc)
    results = sweep(ctx, sc, errors)
    claims(ctx, noise, lags, results)
    figures(ctx, sc, noise, results)


STUDY = StudyDefinition(
    name="ab-range",
    title="E1: the paper's alpha-beta range tracker, accuracy vs track loss over alpha and range acceleration",
    run=run,
    paper_claims="P1",
    default_runs=200,
    quick_runs=8,
    default_scenario="range-1d",
    params=dict(PARAMS),
    quick_params={"noise_segments": 4},
)

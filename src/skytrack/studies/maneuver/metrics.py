"""Study metrics aligned on manoeuvre onsets (spec 004 R20).

For each filter, case and manoeuvre onset ``t_on`` (window ``[t_on - before_s, t_on + after_s]``,
cut at the next onset and at the end of the case; scans before the filter's start excluded):

* RMS position and velocity error vs time from onset, over the runs of a *basis*: ``all`` runs,
  or ``kept`` = the runs not lost in that run's gating mode (R20: RMS in non-lost runs and the
  loss rate are reported separately);
* ``e_pre`` — mean RMS over the ``pre_s`` (10 s) before onset; ``e_peak`` and its time after
  onset; ``e_man`` — mean RMS over the manoeuvre;
* settling time — from the peak: the first scan after the peak from which the RMS stays
  ``<= e_pre + settle_fraction (e_peak - e_pre)`` for ``settle_scans`` (5) consecutive scans,
  minus the peak time (``inf`` if never within the window); the same counted from the
  manoeuvre end;
* NEES on position+velocity: mean over runs per scan; its mean over the window and the
  fraction of window scans whose mean lies in the two-sided band
  ``[chi2_{N n}^-1(0.025)/N, chi2_{N n}^-1(0.975)/N]`` (N runs of the basis, n = 6);
* containment rate of set estimates (truth inside E(x, P)) over the window;
* track-loss rate of the case (each gating mode run), MACs per update (R22; wall time goes to
  ``timing.csv``), and the manoeuvre's largest normal acceleration ``peak_accel_g`` (|a_perp| / g0).

A case without manoeuvres has one row (``onset = -1``) whose window is the whole case after
the filter's start (no pre/peak split: ``e_pre`` is then the mean over the whole case).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.analysis.metrics import nees_band
from skytrack.studies.maneuver.runner import FilterRun
from skytrack.studies.maneuver.scenarios import Case
from skytrack.studies.maneuver.segments import normal_acceleration
from skytrack.studies.maneuver.trajectory import G0

BASES = ("all", "kept")
NEES_DIM = 6
QUANTITIES = ("pos", "vel")


@dataclass(frozen=True)
class MetricSettings:
    """Windows and thresholds of the R20 metrics (seconds unless stated)."""

    before_s: float = 20.0
    after_s: float = 60.0
    pre_s: float = 10.0
    settle_fraction: float = 0.2
    settle_scans: int = 5
    nees_confidence: float = 0.95

    def __post_init__(self) -> None:
        for name in ("before_s", "after_s", "pre_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"metrics.{name} must be > 0, got {value}")
        if not 0 < self.settle_fraction < 1:
            raise ValueError(f"metrics.settle_fraction must be in (0, 1), got {self.settle_fraction}")
        if int(self.settle_scans) != self.settle_scans or self.settle_scans < 1:
            raise ValueError(f"metrics.settle_scans must be an integer >= 1, got {self.settle_scans}")
        if not 0 < self.nees_confidence < 1:
            raise ValueError(f"metrics.nees_confidence must be in (0, 1), got {self.nees_confidence}")

    @classmethod
    def from_dict(cls, values: dict) -> "MetricSettings":
        known = {"before_s", "after_s", "pre_s", "settle_fraction", "settle_scans", "nees_confidence"}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"metrics: unknown key(s) {unknown}; known: {sorted(known)}")
        return cls(**values)


@dataclass(frozen=True)
class Window:
    """Scans of one onset's window: indices, times relative to onset, manoeuvre end (relative)."""

    onset_index: int
    onset: float
    end: float
    scans: np.ndarray
    t_rel: np.ndarray


def windows(case: Case, first_scan: int, settings: MetricSettings) -> list[Window]:
    """The windows of ``case`` (module docstring)."""
    t = case.truth.time
    valid = np.arange(case.scans) >= first_scan
    if not case.maneuvers:
        scans = np.flatnonzero(valid)
        return [Window(-1, math.nan, math.nan, scans, t[scans])]
    out = []
    for i, (onset, end) in enumerate(case.maneuvers):
        stop = onset + settings.after_s
        if i + 1 < len(case.maneuvers):
            stop = min(stop, case.maneuvers[i + 1][0])
        inside = valid & (t >= onset - settings.before_s - 1e-9) & (t <= stop + 1e-9)
        if i + 1 < len(case.maneuvers):
            inside &= t < case.maneuvers[i + 1][0] - 1e-9
        scans = np.flatnonzero(inside)
        out.append(Window(i, onset, end - onset, scans, t[scans] - onset))
    return out


def rms_series(errors: np.ndarray, runs_mask: np.ndarray) -> np.ndarray:
    """RMS of error vectors ``[K, runs, 3]`` over the selected runs, per scan (NaN for no runs)."""
    if not runs_mask.any():
        return np.full(errors.shape[0], np.nan)
    sq = np.sum(errors[:, runs_mask] ** 2, axis=-1)
    return np.sqrt(np.mean(sq, axis=1))


def settling_time(t_rel: np.ndarray, rms: np.ndarray, start: float, threshold: float, scans: int) -> float:
    """First time >= ``start`` from which ``rms <= threshold`` for ``scans`` consecutive scans, minus ``start``."""
    if not (math.isfinite(start) and math.isfinite(threshold)):
        return math.nan
    ok = rms <= threshold
    for j in np.flatnonzero(t_rel >= start - 1e-9):
        if j + scans <= len(ok) and ok[j:j + scans].all():
            return float(t_rel[j] - start)
    return math.inf


def _quantity_metrics(prefix: str, window: Window, rms: np.ndarray, settings: MetricSettings) -> dict:
    t = window.t_rel
    if window.onset_index < 0:
        value = float(np.nanmean(rms)) if np.isfinite(rms).any() else math.nan
        return {f"e_pre_{prefix}": value, f"e_peak_{prefix}": float(np.nanmax(rms)) if np.isfinite(rms).any() else math.nan,
                f"t_peak_{prefix}": math.nan, f"e_man_{prefix}": math.nan,
                f"settle_peak_{prefix}": math.nan, f"settle_end_{prefix}": math.nan}
    pre = (t >= -settings.pre_s - 1e-9) & (t < -1e-9)
    after = t >= -1e-9
    during = after & (t <= window.end + 1e-9)
    e_pre = float(np.mean(rms[pre])) if pre.any() and np.isfinite(rms[pre]).all() else math.nan
    if after.any() and np.isfinite(rms[after]).any():
        j = np.flatnonzero(after)[np.nanargmax(rms[after])]
        e_peak, t_peak = float(rms[j]), float(t[j])
    else:
        e_peak, t_peak = math.nan, math.nan
    threshold = e_pre + settings.settle_fraction * (e_peak - e_pre)
    return {
        f"e_pre_{prefix}": e_pre,
        f"e_peak_{prefix}": e_peak,
        f"t_peak_{prefix}": t_peak,
        f"e_man_{prefix}": float(np.mean(rms[during])) if during.any() else math.nan,
        f"settle_peak_{prefix}": settling_time(t, rms, t_peak, threshold, settings.settle_scans),
        f"settle_end_{prefix}": settling_time(t, rms, window.end, threshold, settings.settle_scans),
    }


def peak_normal_g(case: Case, window: Window) -> float:
    """Largest ``|a_perp| / g0`` of the truth during the window's manoeuvre (NaN without one)."""
    if window.onset_index < 0:
        return math.nan
    t = case.truth.time
    during = (t >= window.onset - 1e-9) & (t <= window.onset + window.end + 1e-9)
    if not during.any():
        return math.nan
    a_perp, _ = normal_acceleration(case.truth.velocity[during], case.truth.acceleration[during])
    return float(a_perp.max() / G0)


def basis_mask(run: FilterRun, basis: str) -> np.ndarray:
    if basis == "all":
        return np.ones(run.runs, dtype=bool)
    if basis == "kept":
        return ~run.lost
    raise ValueError(f"basis must be one of {BASES}, got {basis!r}")


def evaluate_run(case: Case, run: FilterRun, settings: MetricSettings = MetricSettings(),
                 loss_rates: dict[str, float] | None = None, bases=BASES) -> tuple[list[dict], list[pd.DataFrame]]:
    """Summary rows (one per onset and basis) and aligned time-series rows of one filter run.

    ``loss_rates``: loss rate per gating mode of this filter on this case (default: this run's).
    Time-series frames are tidy: ``(series="aligned", case, filter, basis, onset, t, t_rel, quantity, value)``
    with quantities ``rms_pos``, ``rms_vel``, ``nees``, ``nis``, ``containment``.
    """
    loss_rates = loss_rates if loss_rates is not None else {run.gating: float(run.lost.mean())}
    summary, series = [], []
    for window in windows(case, run.first_scan, settings):
        k = window.scans
        for basis in bases:
            mask = basis_mask(run, basis)
            n_runs = int(mask.sum())
            rms = {q: rms_series(err[k], mask) for q, err in (("pos", run.position_error), ("vel", run.velocity_error))}
            row = {"case": case.label, "scenario": case.scenario, "filter": run.label, "kind": run.kind,
                   "gating": run.gating, "basis": basis, "onset": window.onset_index, "t_onset": window.onset,
                   "maneuver_s": window.end, "peak_accel_g": peak_normal_g(case, window), "runs": run.runs,
                   "runs_basis": n_runs}
            row.update({k_: v for k_, v in case.params.items() if isinstance(v, (int, float, str))})
            for q in QUANTITIES:
                row.update(_quantity_metrics(q, window, rms[q], settings))
            nees_mean = np.nanmean(run.nees[k][:, mask], axis=1) if n_runs and np.isfinite(run.nees[k][:, mask]).any() \
                else np.full(len(k), np.nan)
            low, high = nees_band(n_runs, NEES_DIM, settings.nees_confidence)
            finite = np.isfinite(nees_mean)
            row["nees_mean"] = float(np.mean(nees_mean[finite])) if finite.any() else math.nan
            row["nees_in_band"] = float(np.mean((nees_mean[finite] >= low) & (nees_mean[finite] <= high))) if finite.any() else math.nan
            row["nees_band_low"], row["nees_band_high"] = low, high
            contained = run.contained[k][:, mask]
            row["containment"] = float(np.nanmean(contained)) if np.isfinite(contained).any() else math.nan
            for gating in ("off", "on"):
                row[f"loss_rate_{gating}"] = loss_rates.get(gating, math.nan)
            row["madds_per_update"] = run.madds_per_update
            summary.append(row)
            nis_mean = np.nanmean(run.nis[k][:, mask], axis=1) if n_runs and np.isfinite(run.nis[k][:, mask]).any() \
                else np.full(len(k), np.nan)
            containment = np.nanmean(contained, axis=1) if np.isfinite(contained).any() else np.full(len(k), np.nan)
            for name, values in (("rms_pos", rms["pos"]), ("rms_vel", rms["vel"]), ("nees", nees_mean),
                                 ("nis", nis_mean), ("containment", containment)):
                if np.isfinite(values).any():
                    series.append(pd.DataFrame({
                        "series": "aligned", "case": case.label, "filter": run.label, "basis": basis,
                        "onset": window.onset_index, "t": case.truth.time[k], "t_rel": window.t_rel,
                        "quantity": name, "value": values}))
    return summary, series

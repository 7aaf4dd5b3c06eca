"""Study E7 of spec 002 §6: the disturbance-covariance estimator (eq. 7 as implemented: R12, R13 weighting).

Scene of TV11(c, d): one axis of R3 dynamics (p, v, a), T = 1 s, the acceleration a random walk
a(k) = a(k−1) + w(k−1) with std σ_w per step, measurements y = (p, v) + η with σ = (10 m, 0.5 m/s), truth
x(0) = (0, 100 m/s, 0).  The adaptive filter (:class:`~skytrack.filters.adaptive_augmented.AdaptiveAugmentedFilter`)
starts at x̂ = (y_p(0), y_v(0), 0), P = diag(100, 0.25, 1), V_w0 = 0.01, n_0 = 1, σ_min = 10⁻⁴, and runs
λ ∈ {0.9, 0.99, 0.999, 1} with both weightings of A5.1 (``innovation``, default; ``none``, literal eq. 12).
Seeds form one bank (track i = seed i, its own truth and noise); all settings of a part share the draws.

* part (c): σ_w = 0.5 m/s² (V_w = 0.25), 20 001 measurements; the raw memory V̄ after the last step;
* part (d): σ_w = 0.1 before step 5000, 1.0 after, 10 001 measurements; the seed mean of V̂_w over
  k ∈ [4000, 5000) and [9000, 10 000) (with other lengths: the last fifth of each half).

Expected (TV11): (c) λ = 1, innovation: V̄ in [0.22, 0.28] for every seed, seed mean in [0.24, 0.26]
(≥ 20 seeds); literal weighting: spread across seeds ≥ 10× larger.  (d) λ = 0.999, innovation: [0.008,
0.02] before, [0.93, 1.05] after; λ = 0.99 before ≈ 0.027 (floor clipping of a noisy average, checked
within a factor 1.5).  The spec's checks apply at the spec's lengths; shorter runs are reported only.
:func:`run_bank` is the TV11 long-run simulation (the tests' fixture can use it).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np
import pandas as pd

from skytrack.filters.adaptive_augmented import AdaptiveAugmentedFilter, AdaptiveSettings, LinearMeasurement
from skytrack.models.augmented import linear_model
from skytrack.studies.adaptive_numerics.common import Check, pyplot, within_factor, write_outputs

NAME = "vw_estimator"
F_1D = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
SIGMA_MEAS = np.array([10.0, 0.5])
FORGETTING = (0.9, 0.99, 0.999, 1.0)
WEIGHTINGS = ("innovation", "none")
STEPS_C = 20_001
STEPS_D = 10_001
TRIALS = 20
SIGMA_C = 0.5
SIGMA_D = (0.1, 1.0)
SIGMA_MIN = 1e-4
#: thin the drawn / written medians to every THIN-th step
THIN = 10
Progress = Optional[Callable[[int, int], None]]


def run_bank(n_tracks, n_measurements, sigma_w, seed, progress: Progress = None, **settings):
    """TV11's scene for a bank of ``n_tracks`` seeds: truth x(k) = F(x(k−1) + h_aᵀw(k−1)) (eqs. 3-4),
    y = (p, v) + η.  ``sigma_w(k)`` is the std of w(k−1); ``settings`` override the AdaptiveSettings
    (σ_min = 10⁻⁴, λ = 1, n_0 = 1).  Returns the final bank state and V̂_w per step ``[K−1, N]``."""
    rng = np.random.default_rng(seed)
    model = linear_model("ca-1d", F_1D, ("p", "v", "a"), ("m", "m/s", "m/s^2"), ("a",), [[0.01]])
    options = dict(sigma_min=[SIGMA_MIN], forgetting=1.0, n0=1.0)
    options.update(settings)
    filt = AdaptiveAugmentedFilter(model, LinearMeasurement([[1, 0, 0], [0, 1, 0]]), AdaptiveSettings(**options))
    truth = np.tile([0.0, 100.0, 0.0], (n_tracks, 1))
    y0 = truth[:, :2] + SIGMA_MEAS * rng.standard_normal((n_tracks, 2))
    state = filt.initial_state(np.c_[y0, np.zeros(n_tracks)], np.diag([100, 0.25, 1]), V_w0=[[0.01]])
    noise_cov = np.diag(SIGMA_MEAS**2)
    estimates = np.empty((n_measurements - 1, n_tracks))
    for k in range(1, n_measurements):  # a recursion over time; the bank is vectorised
        truth[:, 2] += sigma_w(k) * rng.standard_normal(n_tracks)
        truth = truth @ F_1D.T
        y = truth[:, :2] + SIGMA_MEAS * rng.standard_normal((n_tracks, 2))
        estimates[k - 1] = filt.step(state, y, 1.0, noise_cov).V_w[:, 0, 0]
        if progress is not None and k % 500 == 0:
            progress(k, n_measurements - 1)
    return state, estimates


@dataclass(frozen=True)
class Part:
    """One TV11 part: its measurements, the σ_w schedule and the step of the switch (None: constant)."""

    name: str
    measurements: int
    switch: int | None

    def sigma_w(self, k) -> float:
        if self.switch is None:
            return SIGMA_C
        return SIGMA_D[0] if k < self.switch else SIGMA_D[1]

    def true_V_w(self, steps: np.ndarray) -> np.ndarray:
        """V_w of w(k−1), the disturbance the estimate after step k refers to."""
        return np.array([self.sigma_w(k) ** 2 for k in steps]) if self.switch else np.full(len(steps), SIGMA_C**2)

    def windows(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """(before, after) windows of (d): [4000, 5000) and [9000, 10 000) at the spec's length."""
        switch, end = self.switch, self.measurements - 1
        return (switch - switch // 5, switch), (end - (end - switch) // 5, end)


def parts(steps_c: int = STEPS_C, steps_d: int = STEPS_D) -> tuple[Part, Part]:
    return Part("c", steps_c, None), Part("d", steps_d, (steps_d - 1) // 2)


def run_study(trials: int = TRIALS, seed: int = 1, steps_c: int = STEPS_C, steps_d: int = STEPS_D,
              forgetting=FORGETTING, weightings=WEIGHTINGS, progress: Progress = None):
    """Every (part, λ, weighting): ``(table, medians)``; the table has one row per configuration, the
    medians frame the seed-median V̂_w every :data:`THIN` steps and the true V_w."""
    rows, medians = [], []
    configs = [(part, lam, w) for part in parts(steps_c, steps_d) for lam in forgetting for w in weightings]
    total = sum(part.measurements - 1 for part, _, _ in configs)
    done = 0
    for index, (part, lam, weighting) in enumerate(configs):
        def step_progress(k, _total, offset=done):
            if progress is not None:
                progress(offset + k, total)

        state, estimates = run_bank(trials, part.measurements, part.sigma_w, [seed, ord(part.name)],
                                    step_progress, forgetting=lam, weighting=weighting)
        done += part.measurements - 1
        if progress is not None:
            progress(done, total)
        steps = np.arange(1, part.measurements)
        row = {"part": part.name, "forgetting": lam, "weighting": weighting, "trials": trials,
               "measurements": part.measurements}
        if part.switch is None:
            final = state.V_bar[:, 0, 0]
            row.update(true_V_w=SIGMA_C**2, final_mean=final.mean(), final_sd=final.std(ddof=1) if trials > 1 else 0.0,
                       final_min=final.min(), final_max=final.max(), ratio=final.mean() / SIGMA_C**2)
        else:
            (b0, b1), (a0, a1) = part.windows()
            before = estimates[(steps >= b0) & (steps < b1)].mean()
            after = estimates[(steps >= a0) & (steps < a1)].mean()
            row.update(true_V_w=SIGMA_D[1] ** 2, window_before=f"[{b0}, {b1})", before_mean=before,
                       before_ratio=before / SIGMA_D[0] ** 2, window_after=f"[{a0}, {a1})", after_mean=after,
                       ratio=after / SIGMA_D[1] ** 2)
        rows.append(row)
        keep = steps % THIN == 0
        medians.append(pd.DataFrame({"part": part.name, "forgetting": lam, "weighting": weighting, "k": steps[keep],
                                     "median_V_w_hat": np.median(estimates[keep], axis=1),
                                     "true_V_w": part.true_V_w(steps[keep])}))
    return pd.DataFrame(rows), pd.concat(medians, ignore_index=True)


def _row(table, part, lam, weighting):
    match = table[(table["part"] == part) & np.isclose(table["forgetting"], lam) & (table["weighting"] == weighting)]
    return None if match.empty else match.iloc[0]


def check_study(table: pd.DataFrame) -> list[Check]:
    """TV11 (c) and (d) where the run has the spec's length (other lengths: no checks)."""
    checks = []
    c_inn, c_none = _row(table, "c", 1.0, "innovation"), _row(table, "c", 1.0, "none")
    if c_inn is not None and c_inn.measurements == STEPS_C:
        checks.append(Check("(c) λ = 1, innovation: V̄ of every seed", f"{c_inn.final_min:.4f} … {c_inn.final_max:.4f}",
                            "[0.22, 0.28]", 0.22 <= c_inn.final_min and c_inn.final_max <= 0.28))
        checks.append(Check(f"(c) λ = 1, innovation: seed mean ({c_inn.trials} seeds)", f"{c_inn.final_mean:.4f}",
                            "[0.24, 0.26] (≥ 20 seeds; prototype 0.2483)", 0.24 <= c_inn.final_mean <= 0.26))
        if c_none is not None:
            ratio = c_none.final_sd / c_inn.final_sd
            checks.append(Check("(c) λ = 1: seed spread literal / innovation", f"{c_none.final_sd:.4f} / "
                                f"{c_inn.final_sd:.4f} = {ratio:.1f}", "≥ 10 (prototype 0.126 / 0.0070)", ratio >= 10))
    d_999, d_99 = _row(table, "d", 0.999, "innovation"), _row(table, "d", 0.99, "innovation")
    if d_999 is not None and d_999.measurements == STEPS_D:
        checks.append(Check("(d) λ = 0.999, innovation: V̂_w over [4000, 5000)", f"{d_999.before_mean:.4f}",
                            "[0.008, 0.02] (true 0.01; prototype 0.0128)", 0.008 <= d_999.before_mean <= 0.02))
        checks.append(Check("(d) λ = 0.999, innovation: V̂_w over [9000, 10000)", f"{d_999.after_mean:.4f}",
                            "[0.93, 1.05] (true 1; prototype 0.991)", 0.93 <= d_999.after_mean <= 1.05))
    if d_99 is not None and d_99.measurements == STEPS_D:
        checks.append(Check("(d) λ = 0.99, innovation: V̂_w over [4000, 5000)", f"{d_99.before_mean:.4f}",
                            "≈ 0.027 (within ×1.5; floor-clipping bias)", within_factor(d_99.before_mean, 0.027, 1.5)))
    return checks


def plot_study(medians: pd.DataFrame):
    """Seed-median V̂_w(t) against the true V_w: rows = parts (c), (d); columns = weightings; log y."""
    plt = pyplot()
    weightings = list(dict.fromkeys(medians["weighting"]))
    fig, axes = plt.subplots(2, len(weightings), figsize=(5.5 * len(weightings), 7.5), squeeze=False)
    colours = plt.get_cmap("viridis")
    lams = sorted(medians["forgetting"].unique())
    for r, part in enumerate(("c", "d")):
        for c, weighting in enumerate(weightings):
            ax = axes[r, c]
            group = medians[(medians["part"] == part) & (medians["weighting"] == weighting)]
            for i, lam in enumerate(lams):
                line = group[np.isclose(group["forgetting"], lam)]
                if len(line):
                    # short memories are noisy: drawn lighter, so that the long ones stay visible on top
                    ax.plot(line["k"], line["median_V_w_hat"], color=colours(i / max(1, len(lams) - 1)), lw=1.0,
                            alpha=0.45 if lam < 0.999 else 1.0, label=f"median V̂_w, λ = {lam:g}")
            if len(group):
                truth = group[np.isclose(group["forgetting"], lams[0])]
                ax.plot(truth["k"], truth["true_V_w"], "k--", lw=1.5, label="true V_w")
                ax.axhline(SIGMA_MIN**2, color="grey", ls=":", lw=1.0, label="floor σ_min² (A5.5)")
            ax.set_yscale("log")
            ax.set_xlabel("step k (T = 1 s) [–]")
            ax.set_ylabel("V_w per step [(m/s²)²]")
            what = "constant σ_w = 0.5 m/s²" if part == "c" else "switch σ_w 0.1 → 1 m/s²"
            ax.set_title(f"TV11({part}) {what}, weighting {weighting}")
            ax.grid(True, which="major", alpha=0.3)
            ax.legend(fontsize="x-small")
    fig.suptitle("E7: the V_w estimator (R12) — seed-median estimate against the truth")
    fig.tight_layout()
    return fig


def run_vw_estimator(out_dir: Path, trials: int = TRIALS, seed: int = 1, steps_c: int = STEPS_C,
                     steps_d: int = STEPS_D, progress: Progress = None):
    """E7: all configurations, checks and outputs; returns ``(table, checks, paths)``."""
    table, medians = run_study(trials, seed, steps_c, steps_d, progress=progress)
    checks = check_study(table)
    paths = write_outputs(out_dir, NAME, table, plot_study(medians), checks,
                          {"trials": trials, "seed": seed, "steps_c": steps_c, "steps_d": steps_d,
                           "forgetting": FORGETTING, "weightings": WEIGHTINGS},
                          extra_tables={"medians": medians})
    return table, checks, paths

"""Study E3 of spec 001 §6: the Neyman-Pearson design trade-off P_ПО(alpha) (R10, TV-1).

For alpha in [1e-4, 0.2] (log grid plus the TV-1 points) the threshold r solving P_НО(A, r) = alpha is
found for A = 2..6, and the one solving P̄_НО(r) = alpha (27c) for a separation uniform on
[100, 600] m with sigma = 100 m (A in [1, 6]); P_ПО(r) is plotted against alpha.  All thresholds of a
curve are solved together by a vectorised bisection (P_НО and P̄_НО increase in r); the TV-1 points
are also solved one by one with :func:`skytrack.identify.design.threshold_for_p_incorrect` (brentq)
and the two must agree.

A Monte Carlo confirmation draws ``trials`` difference vectors and counts, at the thresholds
designed for alpha = 0.01 and 0.05, the frequency of "same" under the own object (P_ПО) and under
the foreign object (P_НО = alpha); each within 4 standard errors.

Expected (§6 E3): a monotone trade-off; at small A a low alpha forces a low P_ПО (A = 3, alpha = 0.01:
P_ПО = 0.378 in 2-D); the averaged design is dominated by the small separations: its equivalent
single offset lies below the middle of the range and its P_ПО below that of the middle offset.

:func:`run_np_design` writes ``ident_np_design_<dim>d.csv``, ``..._mc.csv``, ``.png`` and
``..._summary.json``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import optimize

from skytrack.identify.design import threshold_for_p_incorrect
from skytrack.identify.potential import p_correct, p_incorrect, p_incorrect_mean
from skytrack.studies.identification.common import (
    MC_SIGMAS, Check, Progress, binomial_se, chunk_sizes, pyplot, save_figure, write_summary,
)

A_VALUES = (2.0, 3.0, 4.0, 5.0, 6.0)
SIGMA_M = 100.0
DELTA_RANGE_M = (100.0, 600.0)
ALPHA_RANGE = (1e-4, 0.2)
DEFAULT_ALPHA_POINTS = 61
TV_ALPHAS = (0.001, 0.01, 0.05)
MC_ALPHAS = (0.01, 0.05)
DEFAULT_TRIALS = 400_000
BISECTION_STEPS = 60
MEAN_CURVE = "mean"

#: TV-1: P_ПО at alpha = 0.05 for A = 2..6 (tolerance 1e-6)
TV1_P_CORRECT_AT_005 = {2: (0.275881, 0.717462, 0.957609, 0.997619, 0.999950),
                        3: (0.243213, 0.642414, 0.931250, 0.995155, 0.999877)}
#: TV-1 NP design at (A, alpha): r and P_ПО (tolerance 1e-7); §6 E3 quotes A = 3, alpha = 0.01: 0.378
TV1_DESIGNS = {2: {(3.0, 0.01): (0.97396844, 0.37768399), (5.0, 0.001): (2.06325931, 0.88098664),
                   (4.0, 0.05): (2.51428748, 0.95760907)},
               3: {(3.0, 0.01): (1.21185810, 0.31046385), (5.0, 0.001): (2.20792504, 0.81881239),
                   (4.0, 0.05): (2.66475481, 0.93125021)}}
#: TV-1 averaged designs (Delta in [100, 600] m, sigma = 100 m): alpha -> (r, P_ПО), tolerance 1e-7
TV1_MEAN_DESIGNS = {2: {0.05: (1.09009560, 0.44797073), 0.01: (0.49765900, 0.11647195)},
                    3: {0.05: (1.37930169, 0.40710663), 0.01: (0.78715321, 0.10807124)}}
TOL_R, TOL_P, TOL_P_AT_005, TOL_AGREE = 1e-7, 1e-7, 1e-6, 1e-9


def alpha_grid(points: int = DEFAULT_ALPHA_POINTS) -> np.ndarray:
    """Log grid on ALPHA_RANGE with the TV-1 alphas added."""
    if points < 2:
        raise ValueError(f"alpha grid needs at least 2 points, got {points}")
    grid = np.geomspace(ALPHA_RANGE[0], ALPHA_RANGE[1], points)
    return np.unique(np.concatenate([grid, TV_ALPHAS]))


def _bisect(reached, alphas: np.ndarray, upper: float) -> np.ndarray:
    """r with reached(r) = alphas for every element (reached vectorised, increasing, reached(0) = 0)."""
    low = np.zeros_like(alphas)
    high = np.full_like(alphas, upper)
    while np.any(reached(high) <= alphas):
        high = np.where(reached(high) <= alphas, 2.0 * high, high)
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (low + high)
        below = reached(middle) < alphas
        low = np.where(below, middle, low)
        high = np.where(below, high, middle)
    return 0.5 * (low + high)


def design_curves(dim: int, alphas: np.ndarray, A_values=A_VALUES, A_range=None) -> pd.DataFrame:
    """Long table ``curve, A, alpha, r, l_threshold, p_correct`` (curve = ``A=<a>`` or ``mean``)."""
    alphas = np.asarray(alphas, dtype=float)
    frames = []
    A = np.asarray(A_values, dtype=float)
    if A.size:
        alpha_rows = np.broadcast_to(alphas[None, :], (A.size, alphas.size))
        offsets = np.broadcast_to(A[:, None], alpha_rows.shape)
        r = _bisect(lambda x: np.asarray(p_incorrect(offsets, x, dim)), alpha_rows, A.max() + 8.0 + math.sqrt(dim))
        for k, a in enumerate(A):
            frames.append(pd.DataFrame({"curve": f"A={a:g}", "A": a, "alpha": alphas, "r": r[k]}))
    if A_range is not None:
        r = _bisect(lambda x: np.asarray(p_incorrect_mean(x, A_range[0], A_range[1], dim)), alphas,
                    A_range[1] + 8.0 + math.sqrt(dim))
        frames.append(pd.DataFrame({"curve": MEAN_CURVE, "A": np.nan, "alpha": alphas, "r": r}))
    table = pd.concat(frames, ignore_index=True)
    table["l_threshold"] = table["r"] ** 2
    table["p_correct"] = np.asarray(p_correct(table["r"].to_numpy(), dim))
    return table


def plot_np_design(table: pd.DataFrame, dim: int, A_range=None, sigma_m: float = SIGMA_M):
    """(a) P_ПО against alpha; (b) the designed r against alpha; one line per A, the average dotted."""
    plt = pyplot()
    fig, (ax_p, ax_r) = plt.subplots(1, 2, figsize=(12.0, 5.0))
    curves = [c for c in table["curve"].unique() if c != MEAN_CURVE]
    colours = plt.get_cmap("viridis")(np.linspace(0.1, 0.85, max(len(curves), 1)))
    for colour, name in zip(colours, curves):
        group = table[table["curve"] == name]
        label = f"A = {group['A'].iloc[0]:g}"
        ax_p.plot(group["alpha"], group["p_correct"], color=colour, label=label)
        ax_r.plot(group["alpha"], group["r"], color=colour, label=label)
    if MEAN_CURVE in set(table["curve"]):
        group = table[table["curve"] == MEAN_CURVE]
        label = (f"uniform Δ ∈ [{A_range[0] * sigma_m:g}, {A_range[1] * sigma_m:g}] m, σ = {sigma_m:g} m"
                 if A_range is not None else "uniform Δ")
        ax_p.plot(group["alpha"], group["p_correct"], color="tab:red", linestyle=":", linewidth=2.0, label=label)
        ax_r.plot(group["alpha"], group["r"], color="tab:red", linestyle=":", linewidth=2.0, label=label)
    marked = table[(table["curve"] == "A=3") & np.isclose(table["alpha"], 0.01)]
    if len(marked):
        p = float(marked["p_correct"].iloc[0])
        ax_p.plot([0.01], [p], "o", color="black")
        ax_p.annotate(f"A = 3, α = 0.01: P_ПО = {p:.3f}", (0.01, p), xytext=(-12, 12), textcoords="offset points",
                      fontsize="small", ha="right", bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.85})
    for ax in (ax_p, ax_r):
        ax.set_xscale("log")
        ax.set_xlabel("allowed P_НО = α [–]")
        ax.grid(True, which="both", alpha=0.3)
    ax_p.set_ylabel("P_ПО at the NP threshold [–]")
    ax_p.set_ylim(-0.02, 1.02)
    ax_p.set_title("(a) P_ПО against α")
    ax_r.set_ylabel("NP threshold r = h / σ [–]")
    ax_r.set_title("(b) designed threshold r against α")
    # one legend for both panels, below them: the curves fill both axes
    handles, labels = ax_p.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize="small", frameon=False)
    fig.suptitle(f"E3: Neyman–Pearson design, {dim}-D (P_НО(r) = α, or P̄_НО(r) = α for the uniform separation)")
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return fig


def monte_carlo(dim: int, designs: pd.DataFrame, trials: int, seed: int, A_range=None,
                progress: Progress = None) -> pd.DataFrame:
    """Empirical P_ПО and P_НО at the designed thresholds of ``designs`` (rows ``curve, A, alpha, r``)."""
    chunks = chunk_sizes(trials)
    r2 = designs["r"].to_numpy() ** 2
    is_mean = (designs["curve"] == MEAN_CURVE).to_numpy()
    offsets = np.where(is_mean, 0.0, designs["A"].fillna(0.0).to_numpy())
    same = np.zeros(len(designs))
    different = np.zeros(len(designs))
    for c, (size, child) in enumerate(zip(chunks, np.random.SeedSequence(seed).spawn(len(chunks)))):
        rng = np.random.default_rng(child)
        noise = rng.standard_normal((size, dim))
        rest = np.einsum("ij,ij->i", noise[:, 1:], noise[:, 1:])
        same += np.count_nonzero((np.square(noise[:, 0]) + rest)[:, None] <= r2[None, :], axis=0)
        first = np.broadcast_to(offsets[None, :], (size, len(designs))).copy()
        if A_range is not None and is_mean.any():
            first[:, is_mean] = rng.uniform(A_range[0], A_range[1], size)[:, None]
        different += np.count_nonzero(np.square(noise[:, :1] + first) + rest[:, None] <= r2[None, :], axis=0)
        if progress is not None:
            progress(c + 1, len(chunks))
    table = designs[["curve", "A", "alpha", "r", "p_correct"]].reset_index(drop=True).copy()
    table["mc_p_correct"] = same / trials
    table["mc_p_incorrect"] = different / trials
    table["z_p_correct"] = (table["mc_p_correct"] - table["p_correct"]) / binomial_se(table["p_correct"], trials)
    table["z_p_incorrect"] = (table["mc_p_incorrect"] - table["alpha"]) / binomial_se(table["alpha"], trials)
    table["trials"] = trials
    return table


def _row(table: pd.DataFrame, curve: str, alpha: float) -> pd.Series:
    return table[(table["curve"] == curve) & np.isclose(table["alpha"], alpha, rtol=1e-12, atol=0)].iloc[0]


def equivalent_offset(r: float, alpha: float, dim: int, A_range) -> float:
    """The single offset A whose NP design at alpha gives the same r as the averaged design."""
    return optimize.brentq(lambda a: float(p_incorrect(a, r, dim)) - alpha, A_range[0], A_range[1], xtol=1e-12)


def check_np_design(table: pd.DataFrame, mc: pd.DataFrame, dim: int, A_range=None) -> tuple[list[Check], dict]:
    """The §6 E3 expectations and TV-1's design values; also returns the numbers for the summary."""
    checks, results = [], {}
    monotone = all(np.all(np.diff(g.sort_values("alpha")["p_correct"].to_numpy()) > 0) for _, g in table.groupby("curve"))
    checks.append(Check("monotone trade-off: P_ПО increases with α on every curve", str(monotone), "True", monotone))
    for (A, alpha), (r_expected, p_expected) in TV1_DESIGNS.get(dim, {}).items():
        if f"A={A:g}" not in set(table["curve"]):
            continue
        single = threshold_for_p_incorrect(alpha, dim, A=A)
        row = _row(table, f"A={A:g}", alpha)
        results[f"A={A:g},alpha={alpha:g}"] = {"r": single.r, "p_correct": single.p_correct}
        checks.append(Check(f"TV-1 design {dim}-D, A = {A:g}, α = {alpha:g}", f"r = {single.r:.8f}, P_ПО = {single.p_correct:.8f}",
                            f"r = {r_expected} ± {TOL_R:g}, P_ПО = {p_expected} ± {TOL_P:g}",
                            abs(single.r - r_expected) <= TOL_R and abs(single.p_correct - p_expected) <= TOL_P))
        checks.append(Check(f"curve = brentq at A = {A:g}, α = {alpha:g}", f"|Δr| = {abs(row.r - single.r):.1e}",
                            f"≤ {TOL_AGREE:g}", abs(row.r - single.r) <= TOL_AGREE))
    if dim in TV1_P_CORRECT_AT_005:
        present = [(A, v) for A, v in zip(A_VALUES, TV1_P_CORRECT_AT_005[dim]) if f"A={A:g}" in set(table["curve"])]
        errors = [abs(_row(table, f"A={A:g}", 0.05).p_correct - v) for A, v in present]
        checks.append(Check(f"TV-1 P_ПО at α = 0.05, A = {', '.join(f'{A:g}' for A, _ in present)} ({dim}-D)",
                            ", ".join(f"{_row(table, f'A={A:g}', 0.05).p_correct:.6f}" for A, _ in present),
                            f"{', '.join(f'{v}' for _, v in present)} ± {TOL_P_AT_005:g}",
                            bool(errors) and max(errors) <= TOL_P_AT_005))
    if A_range is not None and MEAN_CURVE in set(table["curve"]):
        for alpha, (r_expected, p_expected) in TV1_MEAN_DESIGNS.get(dim, {}).items():
            design = threshold_for_p_incorrect(alpha, dim, A_range=A_range, sigma=SIGMA_M)
            results[f"mean,alpha={alpha:g}"] = {"r": design.r, "h_m": design.h, "p_correct": design.p_correct}
            checks.append(Check(f"TV-1 averaged design {dim}-D, α = {alpha:g}",
                                f"r = {design.r:.8f} (h = {design.h:.4f} m), P_ПО = {design.p_correct:.8f}",
                                f"r = {r_expected} ± {TOL_R:g}, P_ПО = {p_expected} ± {TOL_P:g}",
                                abs(design.r - r_expected) <= TOL_R and abs(design.p_correct - p_expected) <= TOL_P))
        middle = 0.5 * (A_range[0] + A_range[1])
        mean_row = _row(table, MEAN_CURVE, 0.05)
        a_eq = equivalent_offset(float(mean_row.r), 0.05, dim, A_range)
        results["equivalent_offset_alpha_0.05"] = a_eq
        checks.append(Check("averaged design dominated by small separations: equivalent offset at α = 0.05",
                            f"A_eq = {a_eq:.4f}", f"< middle of the range {middle:g}", a_eq < middle))
        mid_curve = design_curves(dim, table[table["curve"] == MEAN_CURVE]["alpha"].to_numpy(), (middle,))
        mean_p = table[table["curve"] == MEAN_CURVE]["p_correct"].to_numpy()
        below = bool(np.all(mean_p < mid_curve["p_correct"].to_numpy()))
        checks.append(Check(f"averaged P_ПО below that of the middle offset A = {middle:g} at every α", str(below), "True", below))
    for row in mc.itertuples(index=False):
        ok = abs(row.z_p_correct) <= MC_SIGMAS and abs(row.z_p_incorrect) <= MC_SIGMAS
        checks.append(Check(f"Monte Carlo at the design {row.curve}, α = {row.alpha:g} (r = {row.r:.4f})",
                            f"P_ПО {row.mc_p_correct:.5f} (z {row.z_p_correct:+.2f}), P_НО {row.mc_p_incorrect:.5f} "
                            f"(z {row.z_p_incorrect:+.2f}), {row.trials:,} draws",
                            f"{row.p_correct:.5f}, {row.alpha:g} ± {MC_SIGMAS:g} SE", ok))
    return checks, results


def run_np_design(out_dir: Path, dim: int = 2, trials: int = DEFAULT_TRIALS, seed: int = 1,
                  alpha_points: int = DEFAULT_ALPHA_POINTS, progress: Progress = None) -> dict:
    """E3: design curves, Monte Carlo at alpha = 0.01 and 0.05, checks; writes CSVs, PNG, JSON summary."""
    if dim < 1:
        raise ValueError(f"dim must be >= 1, got {dim}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    A_range = (DELTA_RANGE_M[0] / SIGMA_M, DELTA_RANGE_M[1] / SIGMA_M)
    table = design_curves(dim, alpha_grid(alpha_points), A_VALUES, A_range)
    chosen = table[np.isin(np.round(table["alpha"], 12), MC_ALPHAS)]
    mc = monte_carlo(dim, chosen, trials, seed, A_range, progress=progress)
    checks, results = check_np_design(table, mc, dim, A_range)
    stem = f"ident_np_design_{dim}d"
    paths = {"csv": out_dir / f"{stem}.csv", "mc_csv": out_dir / f"{stem}_mc.csv", "png": out_dir / f"{stem}.png",
             "json": out_dir / f"{stem}_summary.json"}
    table.to_csv(paths["csv"], index=False, float_format="%.12g")
    mc.to_csv(paths["mc_csv"], index=False, float_format="%.12g")
    save_figure(plot_np_design(table, dim, A_range, SIGMA_M), paths["png"])
    results["p_correct_at_alpha_0.05"] = {row.curve: row.p_correct for row in table[np.isclose(table["alpha"], 0.05)].itertuples()}
    results["monte_carlo"] = mc.to_dict(orient="records")
    options = {"dim": dim, "trials": trials, "seed": seed, "alpha_points": alpha_points, "alpha_range": list(ALPHA_RANGE),
               "A_values": list(A_VALUES), "sigma_m": SIGMA_M, "delta_range_m": list(DELTA_RANGE_M)}
    write_summary(paths["json"], "ident-np-design", options, results, checks)
    return {"table": table, "monte_carlo": mc, "checks": checks, "results": results, "paths": paths}

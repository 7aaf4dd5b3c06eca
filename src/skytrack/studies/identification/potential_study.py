"""Studies E1 and E2 of spec 001 §6 (the paper's Figs. 1 and 2): potential characteristics vs r.

For ``dim`` = 2 (E1: Rayleigh (27b), Rice (27a)) or 3 (E2: Maxwell (28b), offset sphere (28)), on
r = h / sigma in [0, 6]: P_ПО (solid), P_НО(A) for A = 1..5 (dashed) and P̄_НО (27c) for a separation
uniform on [100, 600] m with sigma = 100 m (dotted), and an ROC panel (P_ПО against P_НО, one line per
A, parametric in r).  All curves come from :mod:`skytrack.identify.potential` (R9).

A Monte Carlo confirmation draws ``trials`` difference vectors per hypothesis (standard normal per
axis; the foreign object offset by A, or by A uniform on the range for the average) and counts the
distances within ``MC_R``; each frequency must lie within 4 standard errors of the closed form.

Expected (§6 E1/E2, TV-1): P_ПО rises from 0 to 1; P_НО(A) rises with r and falls with A; P_НО(0)
= P_ПО; the TV-1 values; in 3-D both probabilities are lower than in 2-D at equal r and A, and at
A = 4, alpha = 0.05 the NP design gives P_ПО = 0.9313 (3-D) against 0.9576 (2-D).

:func:`run_potential` writes ``ident_potential_<dim>d.csv`` (the curves), ``..._mc.csv``, ``.png``
and ``..._summary.json`` to the output folder.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.identify.design import threshold_for_p_incorrect
from skytrack.identify.potential import p_correct, p_incorrect, p_incorrect_mean
from skytrack.studies.identification.common import (
    MC_SIGMAS, Check, Progress, binomial_se, chunk_sizes, pyplot, save_figure, write_summary,
)

A_VALUES = (1.0, 2.0, 3.0, 4.0, 5.0)
SIGMA_M = 100.0
DELTA_RANGE_M = (100.0, 600.0)
#: r = 0, 0.01, ..., 6 (holds the TV-1 columns exactly)
R_GRID = np.arange(0, 601) / 100.0
#: the Monte Carlo confirmation counts distances within this normalised threshold (h = 200 m)
MC_R = 2.0
DEFAULT_TRIALS = 1_000_000

#: TV-1 (spec 001 §5): P_ПО (tolerance 1e-9) and P_НО rows for A = 1..5 (relative tolerance 1e-6)
TV1_R = (0.5, 1.0, 2.0, 2.5, 3.0, 4.0)
TV1_P_CORRECT = {2: (0.1175030974, 0.3934693403, 0.8646647168, 0.9560630664, 0.9888910035, 0.9996645374),
                 3: (0.0308595958, 0.1987480431, 0.7385358701, 0.8999391669, 0.9707091135, 0.9988660157)}
TV1_P_INCORRECT = {
    2: {1: (7.347260e-2, 2.671202e-1, 7.309879e-1, 8.791459e-1, 9.562840e-1, 9.971105e-1),
        2: (1.793063e-2, 8.189230e-2, 3.964990e-1, 6.058961e-1, 7.856379e-1, 9.658652e-1),
        3: (1.699767e-3, 1.082945e-2, 1.132792e-1, 2.461016e-1, 4.325202e-1, 8.034878e-1),
        4: (6.217609e-5, 5.899491e-4, 1.472346e-2, 4.849959e-2, 1.258961e-1, 4.497279e-1),
        5: (8.712740e-7, 1.279102e-5, 8.007296e-4, 4.136749e-3, 1.661633e-2, 1.329502e-1)},
    3: {1: (1.918261e-2, 1.322986e-1, 6.024560e-1, 8.043153e-1, 9.233611e-1, 9.942195e-1),
        2: (4.602888e-3, 3.853592e-2, 3.005641e-1, 5.154344e-1, 7.203598e-1, 9.502544e-1),
        3: (4.251636e-4, 4.766082e-3, 7.799855e-2, 1.911824e-1, 3.670192e-1, 7.606878e-1),
        4: (1.505667e-5, 2.420210e-4, 9.252391e-3, 3.442780e-2, 9.816257e-2, 4.002644e-1),
        5: (2.034749e-7, 4.905425e-6, 4.635283e-4, 2.704005e-3, 1.195194e-2, 1.102611e-1)},
}
#: TV-1: P̄_НО at r = 2 for Delta in [100, 600] m, sigma = 100 m (tolerance 1e-8)
TV1_MEAN_AT_2 = {2: 0.1737679657, 3: 0.1335843625}
#: §6 E2 / TV-1: NP design at A = 4, alpha = 0.05 (tolerance 1e-7)
NP_A, NP_ALPHA = 4.0, 0.05
NP_P_CORRECT = {2: 0.95760907, 3: 0.93125021}
TOL_P_CORRECT, REL_TOL_P_INCORRECT, TOL_MEAN, TOL_NP = 1e-9, 1e-6, 1e-8, 1e-7


def column_name(A: float) -> str:
    return f"p_incorrect_A{A:g}"


def potential_curves(dim: int, r_grid=R_GRID, A_values=A_VALUES, A_range=None) -> pd.DataFrame:
    """Columns ``r, p_correct, p_incorrect_A<a>..., p_incorrect_mean`` (the last only with A_range)."""
    r = np.asarray(r_grid, dtype=float)
    table = {"r": r, "p_correct": np.asarray(p_correct(r, dim))}
    if len(A_values):
        values = np.asarray(p_incorrect(np.asarray(A_values, dtype=float)[None, :], r[:, None], dim))
        for k, A in enumerate(A_values):
            table[column_name(A)] = values[:, k]
    if A_range is not None:
        table["p_incorrect_mean"] = np.asarray(p_incorrect_mean(r, A_range[0], A_range[1], dim))
    return pd.DataFrame(table)


def draw_curves(ax, curves: pd.DataFrame, A_values, mean_label: str | None = None, x: str = "r") -> None:
    """P_ПО solid, P_НО(A) dashed, P̄_НО dotted against column ``x`` on ``ax``, labelled (R11, §6 E1)."""
    colours = pyplot().get_cmap("viridis")(np.linspace(0.1, 0.85, max(len(A_values), 1)))
    ax.plot(curves[x], curves["p_correct"], color="black", linestyle="-", linewidth=2.0, label="P_ПО")
    for colour, A in zip(colours, A_values):
        ax.plot(curves[x], curves[column_name(A)], color=colour, linestyle="--", label=f"P_НО, A = {A:g}")
    if "p_incorrect_mean" in curves:
        ax.plot(curves[x], curves["p_incorrect_mean"], color="tab:red", linestyle=":", linewidth=2.0,
                label=mean_label or "P̄_НО")
    ax.set_ylim(-0.02, 1.02)
    ax.set_ylabel("probability [–]")
    ax.grid(True, alpha=0.3)
    # below the axes: inside, every corner of [0, 6] x [0, 1] holds a curve
    ax.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, frameon=False)


def mean_label(A_range, sigma_m: float | None = None) -> str:
    if sigma_m is None:
        return f"P̄_НО, A ∈ [{A_range[0]:g}, {A_range[1]:g}]"
    return f"P̄_НО, Δ ∈ [{A_range[0] * sigma_m:g}, {A_range[1] * sigma_m:g}] m, σ = {sigma_m:g} m"


def plot_potential(curves: pd.DataFrame, dim: int, A_values=A_VALUES, A_range=None, sigma_m: float | None = SIGMA_M):
    """(a) the probabilities against r; (b) the ROC, P_ПО against P_НО; returns the figure."""
    plt = pyplot()
    fig, (ax_r, ax_roc) = plt.subplots(1, 2, figsize=(11.0, 5.4))
    label = mean_label(A_range, sigma_m) if A_range is not None else None
    draw_curves(ax_r, curves, A_values, label)
    ax_r.set_xlabel("normalised threshold r = h / σ [–]")
    ax_r.set_title(f"(a) P_ПО and P_НО against r, {dim}-D")
    colours = plt.get_cmap("viridis")(np.linspace(0.1, 0.85, max(len(A_values), 1)))
    for colour, A in zip(colours, A_values):
        ax_roc.plot(curves[column_name(A)], curves["p_correct"], color=colour, linestyle="-", label=f"A = {A:g}")
    if "p_incorrect_mean" in curves:
        ax_roc.plot(curves["p_incorrect_mean"], curves["p_correct"], color="tab:red", linestyle=":", linewidth=2.0,
                    label=label)
    ax_roc.plot([0, 1], [0, 1], color="grey", linewidth=0.8, linestyle="-.", label="chance (A = 0)")
    ax_roc.set_xlabel("P_НО, probability of incorrect identification [–]")
    ax_roc.set_ylabel("P_ПО, probability of correct identification [–]")
    ax_roc.set_title("(b) ROC: P_ПО against P_НО (parametric in r)")
    ax_roc.set_xlim(-0.01, 1.01)
    ax_roc.set_ylim(-0.01, 1.01)
    ax_roc.grid(True, alpha=0.3)
    ax_roc.legend(fontsize="small", loc="lower right")
    law = {2: "Rayleigh / Rice", 3: "Maxwell / offset sphere"}.get(dim, f"χ²_{dim} / ncχ²_{dim}")
    figure = {2: "E1 (paper's Fig. 1)", 3: "E2 (paper's Fig. 2)"}.get(dim, "potential characteristics")
    fig.suptitle(f"{figure}: {dim}-D potential characteristics of identification ({law})")
    fig.tight_layout()
    return fig


def monte_carlo(dim: int, trials: int, seed: int, A_values=A_VALUES, A_range=None, r_check: float = MC_R,
                progress: Progress = None) -> pd.DataFrame:
    """Frequencies of ``|difference| <= r_check`` (normalised) under "same", each A and the A_range average.

    Rows ``hypothesis, A, r, exact, monte_carlo, se, z``; chunk c draws with ``SeedSequence(seed).spawn(chunks)[c]``.
    """
    chunks = chunk_sizes(trials)
    A = np.asarray(A_values, dtype=float)
    hits_same = 0
    hits = np.zeros(len(A))
    hits_mean = 0
    for c, (size, child) in enumerate(zip(chunks, np.random.SeedSequence(seed).spawn(len(chunks)))):
        rng = np.random.default_rng(child)
        noise = rng.standard_normal((size, dim))
        hits_same += int(np.count_nonzero(np.einsum("ij,ij->i", noise, noise) <= r_check ** 2))
        rest = np.einsum("ij,ij->i", noise[:, 1:], noise[:, 1:])
        # the direction of the offset does not matter (isotropic noise): put it on the first axis
        hits += np.count_nonzero(np.square(noise[:, :1] + A[None, :]) + rest[:, None] <= r_check ** 2, axis=0)
        if A_range is not None:
            offset = rng.uniform(A_range[0], A_range[1], size)
            hits_mean += int(np.count_nonzero(np.square(noise[:, 0] + offset) + rest <= r_check ** 2))
        if progress is not None:
            progress(c + 1, len(chunks))
    rows = [("same", 0.0, hits_same / trials, float(p_correct(r_check, dim)))]
    rows += [("different", float(a), h / trials, float(p_incorrect(a, r_check, dim))) for a, h in zip(A, hits)]
    if A_range is not None:
        rows.append(("different, uniform A", np.nan, hits_mean / trials,
                     float(p_incorrect_mean(r_check, A_range[0], A_range[1], dim))))
    table = pd.DataFrame(rows, columns=["hypothesis", "A", "monte_carlo", "exact"])
    table.insert(2, "r", r_check)
    table["se"] = binomial_se(table["exact"].to_numpy(), trials)
    table["z"] = (table["monte_carlo"] - table["exact"]) / table["se"]
    table["trials"] = trials
    return table


def _at(curves: pd.DataFrame, r: float, column: str) -> float:
    return float(curves.loc[np.isclose(curves["r"], r, rtol=0, atol=1e-12), column].iloc[0])


def check_potential(curves: pd.DataFrame, mc: pd.DataFrame, dim: int, A_values=A_VALUES,
                    np_designs: dict | None = None) -> list[Check]:
    """The §6 E1/E2 expectations and the TV-1 values on the drawn curves."""
    checks = []
    p_ok = curves["p_correct"].to_numpy()
    checks.append(Check("P_ПО rises from 0 to 1", f"P_ПО(0) = {p_ok[0]:.3g}, P_ПО({curves['r'].iloc[-1]:g}) = "
                        f"{p_ok[-1]:.10f}", "0, > 0.99999, non-decreasing",
                        p_ok[0] == 0.0 and p_ok[-1] > 0.99999 and np.all(np.diff(p_ok) >= 0)))
    zero = np.asarray(p_incorrect(0.0, curves["r"].to_numpy(), dim))
    checks.append(Check("P_НО(A = 0) = P_ПО", f"max |diff| {np.max(np.abs(zero - p_ok)):.1e}", "≤ 1e-12",
                        np.max(np.abs(zero - p_ok)) <= 1e-12))
    bad = [column_name(A) for A in A_values]
    values = curves[bad].to_numpy()
    rising = bool(np.all(np.diff(values, axis=0) >= -1e-15))
    falling = bool(np.all(np.diff(values, axis=1) <= 1e-15)) and bool(np.all(values <= p_ok[:, None] + 1e-15))
    checks.append(Check("P_НО(A) rises with r and falls with A", f"rises: {rising}, falls: {falling}", "both", rising and falling))
    if dim in TV1_P_CORRECT:
        errors = [abs(_at(curves, r, "p_correct") - v) for r, v in zip(TV1_R, TV1_P_CORRECT[dim])]
        checks.append(Check(f"TV-1 P_ПО {dim}-D at r = {', '.join(f'{r:g}' for r in TV1_R)}",
                            f"max |error| {max(errors):.1e}", f"≤ {TOL_P_CORRECT:g}", max(errors) <= TOL_P_CORRECT))
        for A, row in TV1_P_INCORRECT[dim].items():
            if float(A) not in [float(a) for a in A_values]:
                continue
            rel = [abs(_at(curves, r, column_name(A)) / v - 1.0) for r, v in zip(TV1_R, row)]
            checks.append(Check(f"TV-1 P_НО {dim}-D, A = {A}", f"max rel. error {max(rel):.1e}",
                                f"≤ {REL_TOL_P_INCORRECT:g}", max(rel) <= REL_TOL_P_INCORRECT))
    if "p_incorrect_mean" in curves and dim in TV1_MEAN_AT_2:
        value = _at(curves, 2.0, "p_incorrect_mean")
        checks.append(Check(f"TV-1 P̄_НО {dim}-D at r = 2 (Δ ∈ [100, 600] m, σ = 100 m)", f"{value:.10f}",
                            f"{TV1_MEAN_AT_2[dim]} ± {TOL_MEAN:g}", abs(value - TV1_MEAN_AT_2[dim]) <= TOL_MEAN))
    for row in mc.itertuples(index=False):
        what = row.hypothesis if np.isnan(row.A) else f"{row.hypothesis}, A = {row.A:g}"
        checks.append(Check(f"Monte Carlo P(distance ≤ {row.r:g} σ), {what}",
                            f"{row.monte_carlo:.6f} ({row.trials:,} draws, z = {row.z:+.2f})",
                            f"{row.exact:.6f} ± {MC_SIGMAS:g} SE", abs(row.z) <= MC_SIGMAS))
    if np_designs:
        for d, design in sorted(np_designs.items()):
            if d in NP_P_CORRECT:
                checks.append(Check(f"NP design {d}-D, A = {NP_A:g}, α = {NP_ALPHA:g}: P_ПО", f"{design.p_correct:.8f}",
                                    f"{NP_P_CORRECT[d]} ± {TOL_NP:g}", abs(design.p_correct - NP_P_CORRECT[d]) <= TOL_NP))
        if dim == 3 and 2 in np_designs:
            lower = np_designs[3].p_correct < np_designs[2].p_correct
            checks.append(Check("E2: P_ПО lower in 3-D at A = 4, α = 0.05",
                                f"{np_designs[3].p_correct:.4f} vs {np_designs[2].p_correct:.4f}", "0.9313 < 0.9576", lower))
    return checks


def check_lower_than_2d(curves: pd.DataFrame, A_values=A_VALUES) -> Check:
    """E2: at equal r > 0 and A both probabilities are lower in 3-D than in 2-D."""
    planar = potential_curves(2, curves["r"].to_numpy(), A_values)
    positive = curves["r"].to_numpy() > 0
    columns = ["p_correct"] + [column_name(A) for A in A_values]
    margin = (planar.loc[positive, columns].to_numpy() - curves.loc[positive, columns].to_numpy()).min()
    return Check("E2: 3-D below 2-D at equal r > 0 and A (P_ПО and every P_НО)", f"min (2-D − 3-D) = {margin:.2e}",
                 "> 0", margin > 0)


def run_potential(out_dir: Path, dim: int = 2, trials: int = DEFAULT_TRIALS, seed: int = 1,
                  progress: Progress = None) -> dict:
    """E1 (dim 2) / E2 (dim 3): curves, Monte Carlo, checks; writes CSVs, PNG and JSON summary.

    Returns ``{"curves", "monte_carlo", "checks", "designs", "paths"}``.
    """
    if dim not in (2, 3):
        raise ValueError(f"ident-potential reproduces the paper's 2-D and 3-D figures: dim must be 2 or 3, got {dim}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    A_range = (DELTA_RANGE_M[0] / SIGMA_M, DELTA_RANGE_M[1] / SIGMA_M)
    curves = potential_curves(dim, R_GRID, A_VALUES, A_range)
    mc = monte_carlo(dim, trials, seed, A_VALUES, A_range, progress=progress)
    designs = {d: threshold_for_p_incorrect(NP_ALPHA, d, A=NP_A) for d in ((2,) if dim == 2 else (2, 3))}
    checks = check_potential(curves, mc, dim, A_VALUES, designs)
    if dim == 3:
        checks.append(check_lower_than_2d(curves))
    stem = f"ident_potential_{dim}d"
    paths = {"csv": out_dir / f"{stem}.csv", "mc_csv": out_dir / f"{stem}_mc.csv", "png": out_dir / f"{stem}.png",
             "json": out_dir / f"{stem}_summary.json"}
    curves.to_csv(paths["csv"], index=False, float_format="%.12g")
    mc.to_csv(paths["mc_csv"], index=False, float_format="%.12g")
    save_figure(plot_potential(curves, dim, A_VALUES, A_range, SIGMA_M), paths["png"])
    results = {
        "p_correct_at_r": {f"{r:g}": _at(curves, r, "p_correct") for r in TV1_R},
        "p_incorrect_at_r": {f"A={A:g}": {f"{r:g}": _at(curves, r, column_name(A)) for r in TV1_R} for A in A_VALUES},
        "p_incorrect_mean_at_r2": _at(curves, 2.0, "p_incorrect_mean"),
        "np_design_A4_alpha0.05": {f"{d}d": {"r": v.r, "l_threshold": v.l_threshold, "p_correct": v.p_correct}
                                   for d, v in designs.items()},
        "monte_carlo": mc.to_dict(orient="records"),
    }
    options = {"dim": dim, "trials": trials, "seed": seed, "A_values": list(A_VALUES), "sigma_m": SIGMA_M,
               "delta_range_m": list(DELTA_RANGE_M), "r_grid": [0.0, 6.0, 0.01]}
    write_summary(paths["json"], "ident-potential", options, results, checks)
    return {"curves": curves, "monte_carlo": mc, "checks": checks, "designs": designs, "paths": paths}

"""Study E1 of spec 003 §6 (the paper's Fig. 2): Gaussian density vs fuzzy membership in 1-D.

For sigma in {0.5, 1, 2} and z in [-6, 6]: the density p(z) = N(z; 0, sigma^2) of (8) and
the membership mu(z) = exp(-z^2 / 2 sigma^2) of (14).  Both come from the association
layer's log-domain scores (:func:`skytrack.association.identity_rules.score_pairs`, R7) with
n_c = 1, residual z and S = sigma^2.  Expected (§6 E1): the peaks of p are 0.797885,
0.398942, 0.199471; every mu peaks at 1; mu = p sigma sqrt(2 pi) pointwise, which is (D2)
``ln mu_coord = ln p + (n_c ln 2 pi + ln det S) / 2`` with n_c = 1.

:func:`run_fig2` writes ``fuzzy_fig2.csv`` (one row per sigma: peaks and the largest relative
deviation from the identity), ``fuzzy_fig2_curves.csv`` (the drawn curves) and
``fuzzy_fig2.png`` (two panels, one line per sigma).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.association.identity_rules import RuleConfig, coordinate_terms, score_pairs
from skytrack.studies.fuzzy.common import Check, pyplot, save_figure

SIGMAS = (0.5, 1.0, 2.0)
#: z grid [-6, 6] in steps of 0.01 (holds z = 0 exactly)
Z_GRID = np.arange(-600, 601) / 100.0
#: §6 E1: the peaks of p, to the spec's six decimals
EXPECTED_PEAKS = {0.5: 0.797885, 1.0: 0.398942, 2.0: 0.199471}
PEAK_TOLERANCE = 5e-7
IDENTITY_TOLERANCE = 1e-12
CSV_NAME = "fuzzy_fig2.csv"
CURVES_CSV_NAME = "fuzzy_fig2_curves.csv"
PNG_NAME = "fuzzy_fig2.png"


def density_and_membership(z: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``p(z)`` and ``mu(z)`` for residuals ``z`` and variance ``sigma^2`` (n_c = 1), from ln p and ln mu."""
    z = np.asarray(z, dtype=float)
    d2, logdet = coordinate_terms(z[:, None], np.full((len(z), 1, 1), sigma * sigma))
    scores = score_pairs(RuleConfig(rule="fuzzy"), d2, logdet, 1)
    return np.exp(scores.columns["ln_p"]), np.exp(scores.columns["ln_mu_coord"])


def fig2_curves(sigmas=SIGMAS, z: np.ndarray = Z_GRID) -> pd.DataFrame:
    """Long table ``sigma, z, p, mu`` of the drawn curves."""
    frames = []
    for sigma in sigmas:
        p, mu = density_and_membership(z, sigma)
        frames.append(pd.DataFrame({"sigma": float(sigma), "z": z, "p": p, "mu": mu}))
    return pd.concat(frames, ignore_index=True)


def fig2_table(curves: pd.DataFrame) -> pd.DataFrame:
    """One row per sigma: the peaks, the closed-form peak ``1 / (sigma sqrt(2 pi))`` and the largest
    relative deviation of ``mu`` from ``p sigma sqrt(2 pi)`` over the grid."""
    rows = []
    for sigma, group in curves.groupby("sigma", sort=True):
        scaled = group["p"].to_numpy() * sigma * math.sqrt(2.0 * math.pi)
        mu = group["mu"].to_numpy()
        rows.append({"sigma": sigma, "peak_p": group["p"].max(), "peak_p_closed_form": 1.0 / (sigma * math.sqrt(2 * math.pi)),
                     "peak_mu": mu.max(), "z_of_peak": float(group["z"].to_numpy()[np.argmax(mu)]),
                     "max_rel_identity_error": float(np.max(np.abs(mu - scaled) / mu)), "points": len(group)})
    return pd.DataFrame(rows)


def plot_fig2(curves: pd.DataFrame):
    """Two panels, (a) p(z), (b) mu(z), one labelled line per sigma; returns the figure."""
    plt = pyplot()
    fig, (ax_p, ax_mu) = plt.subplots(1, 2, figsize=(9.0, 3.8))
    colours = plt.get_cmap("tab10").colors
    for colour, (sigma, group) in zip(colours, curves.groupby("sigma", sort=True)):
        label = f"σ = {sigma:g}"
        ax_p.plot(group["z"], group["p"], color=colour, label=label)
        ax_mu.plot(group["z"], group["mu"], color=colour, label=label)
        peak = group["p"].max()
        ax_p.annotate(f"peak {peak:.6f}", (0.0, peak), xytext=(16, 0), textcoords="offset points", fontsize="small",
                      color=colour, va="center", bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.85})
    ax_mu.annotate("peak 1 for every σ", (0.0, 1.0), xytext=(0, 8), textcoords="offset points", fontsize="small",
                   ha="center")
    ax_p.set_title("(a) density p(z) = N(z; 0, σ²)")
    ax_p.set_xlabel("residual z [unit of σ]")
    ax_p.set_ylabel("p(z) [1 / unit of σ]")
    ax_mu.set_title("(b) membership μ(z) = exp(−z² / 2σ²)")
    ax_mu.set_xlabel("residual z [unit of σ]")
    ax_mu.set_ylabel("μ(z) [dimensionless]")
    ax_mu.set_ylim(0.0, 1.15)
    for ax in (ax_p, ax_mu):
        ax.legend(fontsize="small", loc="upper left")
        ax.grid(True, alpha=0.3)
    fig.suptitle("E1 (paper's Fig. 2): the density's peak depends on σ, the membership's is 1")
    fig.tight_layout()
    return fig


def run_fig2(out_dir: Path, sigmas=SIGMAS) -> pd.DataFrame:
    """E1: curves, per-sigma table; writes the two CSVs and the PNG to ``out_dir``; returns the table."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    curves = fig2_curves(sigmas)
    table = fig2_table(curves)
    table.to_csv(out_dir / CSV_NAME, index=False, float_format="%.12g")
    curves.to_csv(out_dir / CURVES_CSV_NAME, index=False, float_format="%.12g")
    save_figure(plot_fig2(curves), out_dir / PNG_NAME)
    return table


def check_fig2(table: pd.DataFrame) -> list[Check]:
    """The §6 E1 expectations."""
    checks = []
    for row in table.itertuples(index=False):
        expected = EXPECTED_PEAKS.get(row.sigma)
        if expected is not None:
            checks.append(Check(f"peak of p, σ = {row.sigma:g}", f"{row.peak_p:.7f}", f"{expected} ± {PEAK_TOLERANCE:g}",
                                abs(row.peak_p - expected) <= PEAK_TOLERANCE))
        checks.append(Check(f"peak of μ, σ = {row.sigma:g}", f"{row.peak_mu:.15g}", "1", row.peak_mu == 1.0))
        checks.append(Check(f"μ = p σ √(2π), σ = {row.sigma:g}", f"max rel. error {row.max_rel_identity_error:.2e}",
                            f"≤ {IDENTITY_TOLERANCE:g}", row.max_rel_identity_error <= IDENTITY_TOLERANCE))
    return checks

"""Study E6 of spec 001 §6: four quadratic forms against two (R15, gap G11).

On the TV-5 scenario (Q = 0) the optimal statistic Λ of (20a) — the joint filter's forms minus
the two separate filters' — is compared with the joint-only statistic J = Q_Jη + Q_Jξ (R15,
this spec's reading of the quasi-optimal two-form algorithm of the paper's ref. [3]).  Under
θ = 1, Λ ~ χ²(4) and J ~ χ²(36); under θ = 0 both are non-central with the same λ, so the two
extra forms remove 32 degrees of freedom of pure noise.

For θ = 1 and for the offsets +100 m in x and +10 m/s in v_x, ``trials`` report streams are drawn
and both statistics computed by the vectorised GLS forms (as in E5).  The ROC (P_ПО against P_НО
as the threshold moves) is drawn for both statistics, empirical and exact (χ², ncχ²).

Expected (§6 E6, TV-5b): at P_ПО = 0.99 the false identification rate is 0.0054 (four forms)
against 0.213 (two forms) for +100 m; at P_НО = 0.01, P_ПО is 0.995 against 0.730.  For +10 m/s
(TV-5b): 0.5166 against 0.8806, and 0.3244 against 0.0813.  The exact values are checked against
TV-5b (1e-6 relative, or half a unit of the table's last digit); the Monte Carlo frequencies at
the exact thresholds within 4 binomial SE.  :func:`run_quadratic_forms` writes
``ident_quadratic_forms.csv`` (one row per offset and statistic), ``..._roc.csv``, ``.png`` and
``..._summary.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from skytrack.studies.identification import scenario_tv5 as tv5
from skytrack.studies.identification.common import pyplot
from skytrack.studies.identification.mc_common import (
    Check, Progress, StudyOutput, chunked, finish, within_se,
)
from skytrack.studies.identification.sequential_mc import THETA_1

NAME = "ident_quadratic_forms"
DEFAULT_TRIALS = 200_000
CHUNK = 50_000
E6_OFFSETS = ("+100 m in x", "+10 m/s in vx")
#: statistic -> (sample key, degrees of freedom, TV-5b columns: P_НО at P_ПО = 0.99, P_ПО at P_НО = 0.01)
STATISTICS = {"four forms (Λ)": ("statistic", tv5.DOF, 1, 3),
              "two forms (joint only)": ("J_joint", tv5.JOINT_DOF, 4, 5)}


def simulate(trials: int, seed: int, progress: Progress = None) -> dict[str, dict[str, np.ndarray]]:
    """Λ and J_joint per trial for θ = 1 and the E6 offsets (case i: ``SeedSequence(seed).spawn(3)[i]``)."""
    forms = tv5.quadratic_forms(tv5.TV5_GEOMETRY)
    cases = (THETA_1,) + E6_OFFSETS
    chunks = chunked(trials, CHUNK)
    total, done, out = len(cases) * len(chunks), 0, {}
    for case, child in zip(cases, np.random.SeedSequence(seed).spawn(len(cases))):
        rng = np.random.default_rng(child)
        offset = None if case == THETA_1 else tv5.OFFSETS[case]
        parts = []
        for size in chunks:
            values = tv5.evaluate_forms(tv5.draw_reports(rng, size, tv5.TV5_GEOMETRY, offset), forms)
            parts.append({key: values[key] for key in ("statistic", "J_joint")})
            done += 1
            if progress is not None:
                progress(done, total)
        out[case] = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return out


def operating_points(samples) -> pd.DataFrame:
    """Per offset and statistic: the exact and Monte Carlo P_НО at P_ПО = 0.99 and P_ПО at P_НО = 0.01."""
    rows = []
    for case in E6_OFFSETS:
        lam = tv5.closed_form_noncentrality(tv5.OFFSETS[case])
        spec = tv5.TV5B[case]
        for statistic, (key, dof, spec_incorrect, spec_correct) in STATISTICS.items():
            same, different = samples[THETA_1][key], samples[case][key]
            h_correct = float(stats.chi2.ppf(0.99, dof))
            h_np = float(stats.ncx2.ppf(0.01, dof, lam))
            rows.append({
                "case": case, "statistic": statistic, "dof": dof, "noncentrality": lam, "trials": len(same),
                "h_at_p_correct_099": h_correct, "exact_p_incorrect": float(stats.ncx2.cdf(h_correct, dof, lam)),
                "mc_p_incorrect": float(np.mean(different <= h_correct)), "mc_p_correct": float(np.mean(same <= h_correct)),
                "spec_p_incorrect": spec[spec_incorrect],
                "h_at_p_incorrect_001": h_np, "exact_p_correct_at_np": float(stats.chi2.cdf(h_np, dof)),
                "mc_p_correct_at_np": float(np.mean(same <= h_np)), "mc_p_incorrect_at_np": float(np.mean(different <= h_np)),
                "spec_p_correct_at_np": spec[spec_correct]})
    return pd.DataFrame(rows)


def roc_curves(samples, points: int = 300) -> pd.DataFrame:
    """(P_НО, P_ПО) on a threshold grid per offset and statistic, empirical and exact."""
    frames = []
    for case in E6_OFFSETS:
        lam = tv5.closed_form_noncentrality(tv5.OFFSETS[case])
        for statistic, (key, dof, _, _) in STATISTICS.items():
            h = stats.chi2.ppf(np.linspace(0.0, 0.99999, points), dof)
            same, different = np.sort(samples[THETA_1][key]), np.sort(samples[case][key])
            frames.append(pd.DataFrame({
                "case": case, "statistic": statistic, "h": h,
                "p_correct": np.searchsorted(same, h, side="right") / len(same),
                "p_incorrect": np.searchsorted(different, h, side="right") / len(different),
                "exact_p_correct": stats.chi2.cdf(h, dof), "exact_p_incorrect": stats.ncx2.cdf(h, dof, lam)}))
    return pd.concat(frames, ignore_index=True)


def check_quadratic_forms(table: pd.DataFrame) -> list[Check]:
    """TV-5b's values, the Monte Carlo at the exact thresholds, and four forms better than two."""
    checks = []
    for row in table.itertuples(index=False):
        label = f"{row.case}, {row.statistic}"
        for name, value, spec in (("P_НО at P_ПО = 0.99", row.exact_p_incorrect, row.spec_p_incorrect),
                                  ("P_ПО at P_НО = 0.01", row.exact_p_correct_at_np, row.spec_p_correct_at_np)):
            tolerance = tv5.table_tolerance(spec)
            checks.append(Check(f"{label}: exact {name} (TV-5b)", f"{value:.7g}", f"{spec:.7g} ± {tolerance:.1g}",
                                abs(value - spec) <= tolerance))
        checks.append(within_se(f"{label}: Monte Carlo P_НО at P_ПО = 0.99", row.mc_p_incorrect,
                                row.exact_p_incorrect, row.trials))
        checks.append(within_se(f"{label}: Monte Carlo P_ПО at P_НО = 0.01", row.mc_p_correct_at_np,
                                row.exact_p_correct_at_np, row.trials))
    for case, rows in table.groupby("case", sort=False):
        four, two = rows.iloc[0], rows.iloc[1]
        checks.append(Check(f"{case}: four forms beat two (Monte Carlo, both operating points)",
                            f"P_НО {four.mc_p_incorrect:.4g} vs {two.mc_p_incorrect:.4g}; "
                            f"P_ПО {four.mc_p_correct_at_np:.4g} vs {two.mc_p_correct_at_np:.4g}",
                            "lower P_НО, higher P_ПО",
                            four.mc_p_incorrect < two.mc_p_incorrect and four.mc_p_correct_at_np > two.mc_p_correct_at_np))
    return checks


def plot_quadratic_forms(roc: pd.DataFrame, table: pd.DataFrame):
    """One ROC panel per offset: four and two forms, exact lines and Monte Carlo dots, the operating points."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(E6_OFFSETS), figsize=(13.0, 5.2))
    colours = {"four forms (Λ)": "tab:blue", "two forms (joint only)": "tab:orange"}
    for ax, case in zip(axes, E6_OFFSETS):
        for statistic, colour in colours.items():
            rows = roc[(roc["case"] == case) & (roc["statistic"] == statistic)]
            dof = STATISTICS[statistic][1]
            ax.plot(rows["exact_p_incorrect"], rows["exact_p_correct"], color=colour,
                    label=f"{statistic}: exact (χ²_{dof}, ncχ²_{dof})")
            ax.plot(rows["p_incorrect"], rows["p_correct"], linestyle="none", marker=".", markersize=3, color=colour,
                    label=f"{statistic}: Monte Carlo")
            point = table[(table["case"] == case) & (table["statistic"] == statistic)].iloc[0]
            ax.plot([point.exact_p_incorrect], [0.99], marker="o", markersize=8, markerfacecolor="none", color=colour)
            ax.plot([0.01], [point.exact_p_correct_at_np], marker="s", markersize=8, markerfacecolor="none",
                    color=colour)
        ax.axhline(0.99, color="grey", linewidth=0.6, linestyle=":")
        ax.axvline(0.01, color="grey", linewidth=0.6, linestyle=":")
        ax.set_xscale("log")
        ax.set_xlim(1e-4, 1.0)
        ax.set_ylim(0.0, 1.01)
        ax.set(xlabel="P_НО (false identification) [probability]", ylabel="P_ПО (correct identification) [probability]",
               title=f"object 0 {case} (λ = {table[table['case'] == case]['noncentrality'].iloc[0]:.3f})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small", loc="lower right")
    fig.suptitle("E6: four quadratic forms (Λ, 4 dof) against two (joint filter only, 36 dof) on TV-5; "
                 "circles: P_ПО = 0.99, squares: P_НО = 0.01")
    fig.tight_layout()
    return fig


def run_quadratic_forms(out_dir: Path, trials: int = DEFAULT_TRIALS, seed: int = 1,
                        progress: Progress = None) -> StudyOutput:
    """E6: the Monte Carlo, the operating points, the checks and the files."""
    samples = simulate(trials, seed, progress)
    table = operating_points(samples)
    roc = roc_curves(samples)
    checks = check_quadratic_forms(table)
    paths = finish(out_dir, NAME, table, plot_quadratic_forms(roc, table), {"trials": trials, "seed": seed},
                   {"operating_points": table.to_dict(orient="records")}, checks, {"roc": roc})
    return StudyOutput(table, checks, paths, {"operating_points": table.to_dict(orient="records")}, {"roc": roc})

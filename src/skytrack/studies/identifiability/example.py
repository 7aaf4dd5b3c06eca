"""Study E1 of spec 002 §6 (``skytrack study ident-example``): the paper's example of §3.5.

The 6-state, 2-parameter, 2-measurement example: h measures x1 and x5, the parameters are
a1 = x5, a2 = x6, and G = F h_aᵀ has the columns 5 and 6 of F (eq. 4).  The rest of F is lost in
the source (gap G8); TV3's matrix fills it (f25 = 0.5, f35 = 0.2, f26 = 0.7, f46 = 0.4), which does
not enter S = hG = [[f15, f16], [1, 0]].  Everything is decided by
:func:`skytrack.analysis.identifiability.check_identifiability` (R5, R9) and
:func:`skytrack.analysis.identifiability_sequence.check_sequence` (R7, R8); V_η = I.

* Sweep f16 ∈ [−1, 1] (201 points, step 0.01, f16 = 0 exactly) for f15 ∈ {0, 2}: det M = f16²
  (eq. 14 and §3.5, a parabola), κ constant (1 for f15 = 0, √5 − 2 for f15 = 2) and 0 only at
  f16 = 0, σ_χ1 = 1 and σ_χ2 = √(f15² + 1)/|f16| (TV1's closed forms).
* TV2's timeline (R7, G5): f15 = 1, f16(k−1) = float cos(πk/4), k = 1 … 8: the SVD method fails at
  k = 2, 6 (Z = {a2}), κ = √2 − 1 elsewhere, global not_identifiable; the literal det (det_tol = 0)
  sees 3.7·10⁻³³ and 3.4·10⁻³² ≠ 0 and passes every step; exact zeros fail with both methods.
* TV6 (R8, G6): f16 = 0: N_w = 1 not_identifiable with Z = {a2}; N_w = 2 identifiable,
  κ = 0.2675472390.

:func:`run_example` writes ``ident_example.csv`` (the sweep), ``ident_example_tv2.csv``,
``ident_example_tv6.csv``, ``ident_example.png`` and ``ident_example_summary.json``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.analysis.identifiability import check_identifiability
from skytrack.analysis.identifiability_sequence import check_sequence
from skytrack.studies.identification.common import Check, pyplot, save_figure, write_summary

#: TV3's transition matrix (f15 = 2, f16 = 3); columns 5, 6 hold f_i5, f_i6 (§3.5)
TV3_F = np.array([[1, 0.5, 0, 0, 2, 3], [0, 1, 0.1, 0, 0.5, 0.7], [0, 0, 1, 0.1, 0.2, 0],
                  [0, 0, 0, 1, 0, 0.4], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]], dtype=float)
#: §3.5: h measures x1 and x5 (first row reconstructed, G8); parameters a1 = x5, a2 = x6
PAPER_H = np.array([[1, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0]], dtype=float)
PAPER_HA = np.array([[0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]], dtype=float)
NAMES = ("a1", "a2")

F15_VALUES = (0.0, 2.0)
#: 201 points on [−1, 1] in steps of 0.01, f16 = 0 exactly
F16_GRID = np.arange(-100, 101) / 100.0
#: TV2: the float values of cos(πk/4), k = 1 … 8, as printed in the spec
TV2_C = (0.7071067811865476, 6.123233995736766e-17, -0.7071067811865475, -1.0, -0.7071067811865477,
         -1.8369701987210297e-16, 0.7071067811865474, 1.0)
TV2_DET = {2: 3.749399456654644e-33, 6: 3.3744595109891873e-32}
TV6_KAPPA = 0.2675472390
EXACT_RTOL = 1e-12
#: printed decimals of the spec (κ of TV6 to 10 digits)
PRINTED_ATOL = 5e-10

CSV_NAME = "ident_example.csv"
TV2_CSV_NAME = "ident_example_tv2.csv"
TV6_CSV_NAME = "ident_example_tv6.csv"
PNG_NAME = "ident_example.png"
JSON_NAME = "ident_example_summary.json"


def paper_F(f15, f16) -> np.ndarray:
    """TV3's F with f15, f16 replaced, batched over the broadcast shape of (f15, f16): (K, 6, 6)."""
    f15, f16 = np.broadcast_arrays(np.atleast_1d(np.asarray(f15, float)), np.atleast_1d(np.asarray(f16, float)))
    F = np.repeat(TV3_F[None], f15.size, axis=0)
    F[:, 0, 4] = f15.ravel()
    F[:, 0, 5] = f16.ravel()
    return F


def expected_kappa(f15: float) -> float:
    """κ of S = [[f15, f16], [1, 0]] for f16 ≠ 0: the equilibrated columns' angle depends on f15 only."""
    cosine = abs(f15) / math.hypot(f15, 1.0)
    return math.sqrt((1.0 - cosine) / (1.0 + cosine))


def sweep(f15_values=F15_VALUES, f16=F16_GRID) -> pd.DataFrame:
    """One row per (f15, f16): det M, κ, σ_χ1, σ_χ2, verdicts (R5 svd and literal det) and TV1's closed forms."""
    f15_grid, f16_grid = np.meshgrid(np.asarray(f15_values, float), np.asarray(f16, float), indexing="ij")
    F = paper_F(f15_grid.ravel(), f16_grid.ravel())
    svd = check_identifiability(H=PAPER_H, F=F, h_a=PAPER_HA, noise_cov=np.eye(2), names=NAMES)
    literal = check_identifiability(H=PAPER_H, F=F, h_a=PAPER_HA, noise_cov=np.eye(2), names=NAMES, method="det")
    f15, f16 = f15_grid.ravel(), f16_grid.ravel()
    with np.errstate(divide="ignore"):
        sigma2_expected = np.where(f16 != 0, np.sqrt(f15**2 + 1.0) / np.abs(f16), np.nan)
    return pd.DataFrame({
        "f15": f15, "f16": f16, "det": svd.det, "det_expected": f16**2,
        "kappa": svd.kappa,
        "kappa_expected": np.where(f16 != 0, [expected_kappa(v) for v in f15], 0.0),
        "sigma_chi1": svd.precision[:, 0], "sigma_chi2": svd.precision[:, 1],
        "sigma_chi1_expected": np.where(f16 != 0, 1.0, np.nan), "sigma_chi2_expected": sigma2_expected,
        "verdict": svd.verdicts, "verdict_det": literal.verdicts,
        "zero_influence": [",".join(svd.zero_influence_names(i)) for i in range(len(svd))],
    })


def tv2_timeline(c=TV2_C) -> tuple[pd.DataFrame, dict]:
    """TV2: per-step rows k = 1 … 8 (det, κ, svd and det verdicts, Z) and the R7 global summaries,
    for the rounding zeros and for exact zeros at k = 2, 6."""
    rows, summary = [], {}
    variants = {"float cos": np.asarray(c, float), "exact zeros": np.where(np.abs(c) < 1e-15, 0.0, c)}
    for variant, values in variants.items():
        F = paper_F(1.0, values)
        svd = check_sequence(PAPER_H, F, PAPER_HA, noise_cov=np.eye(2), names=NAMES)
        det = check_sequence(PAPER_H, F, PAPER_HA, noise_cov=np.eye(2), names=NAMES, method="det")
        for i, k in enumerate(svd.steps):
            rows.append({"variant": variant, "k": int(k), "f16": values[i], "det": svd.checks.det[i],
                         "kappa": svd.checks.kappa[i], "verdict_svd": svd.verdicts[i], "verdict_det": det.verdicts[i],
                         "zero_influence": ",".join(svd.checks.zero_influence_names(i))})
        summary[variant] = {"global_svd": svd.global_verdict, "failing_svd": svd.failing_steps,
                            "global_det": det.global_verdict, "failing_det": det.failing_steps,
                            "messages_svd": svd.messages()}
    return pd.DataFrame(rows), summary


def tv6_window() -> pd.DataFrame:
    """TV6: TV3's F with f16 = 0 (two equal steps), N_w = 1 and 2."""
    F = paper_F([2.0, 2.0], [0.0, 0.0])
    rows = []
    for window in (1, 2):
        record = check_sequence(PAPER_H, F, PAPER_HA, noise_cov=np.eye(2), names=NAMES, window=window)
        rows.append({"window": window, "rows": int(record.checks.sensitivity.shape[1]),
                     "verdict": record.verdicts[0], "kappa": record.checks.kappa[0],
                     "zero_influence": ",".join(record.checks.zero_influence_names(0)),
                     "sensitivity": str(np.round(record.checks.sensitivity[0], 12).tolist())})
    return pd.DataFrame(rows)


def plot_example(table: pd.DataFrame):
    """Four panels against f16, one line per f15: det M, κ, σ_χ1 (linear) and σ_χ2 (log, it spans 3 decades)."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10.0, 7.0))
    (ax_det, ax_kappa), (ax_s1, ax_s2) = axes
    colours = plt.get_cmap("tab10").colors
    for colour, (f15, group) in zip(colours, table.groupby("f15", sort=True)):
        label = f"f15 = {f15:g}"
        ax_det.plot(group["f16"], group["det"], color=colour, label=label)
        ax_kappa.plot(group["f16"], group["kappa"], color=colour, label=label)
        ax_s1.plot(group["f16"], group["sigma_chi1"], color=colour, label=label)
        ax_s2.plot(group["f16"], group["sigma_chi2"], color=colour, label=label)
        ax_s2.plot(group["f16"], group["sigma_chi2_expected"], color=colour, linestyle=":", linewidth=2.5,
                   label=f"√(f15²+1)/|f16|, f15 = {f15:g}")
    ax_det.plot(F16_GRID, F16_GRID**2, color="black", linestyle=":", label="f16² (§3.5)")
    ax_det.set_title("det M = det(Gᵀhᵀh G) (eq. 14)")
    ax_det.set_ylabel("det M [dimensionless]")
    ax_kappa.set_title("margin κ (R5); 0 only at f16 = 0")
    ax_kappa.set_ylabel("κ [dimensionless]")
    ax_kappa.set_ylim(-0.05, 1.1)
    ax_s1.set_title("σ_χ1 (R9, V_η = I): a1 is measured directly")
    ax_s1.set_ylabel("σ_χ1 [unit of a1]")
    ax_s1.set_ylim(0.0, 2.0)
    ax_s2.set_title("σ_χ2 (R9, V_η = I)")
    ax_s2.set_ylabel("σ_χ2 [unit of a2]")
    ax_s2.set_yscale("log")
    for ax in axes.ravel():
        ax.set_xlabel("f16 [dimensionless]")
        ax.legend(fontsize="small")
        ax.grid(True, alpha=0.3, which="both")
    fig.suptitle("E1: the paper's example — det = f16², κ set by f15, σ_χ2 = √(f15²+1)/|f16|")
    fig.tight_layout()
    return fig


def check_example(table: pd.DataFrame, timeline: pd.DataFrame, summary: dict, window: pd.DataFrame) -> list[Check]:
    """The §6 E1 expectations (with TV1, TV2, TV6) as pass/fail rows."""
    checks = []
    nonzero = table[table["f16"] != 0]
    at_zero = table[table["f16"] == 0]
    det_error = float(np.max(np.abs(table["det"] - table["det_expected"])))
    checks.append(Check("det M = f16² (201 points × 2)", f"max |det − f16²| = {det_error:.1e}", "≤ 1e-12",
                        det_error <= 1e-12))
    for f15, group in nonzero.groupby("f15"):
        wanted = expected_kappa(f15)
        spread = float(np.max(np.abs(group["kappa"] - wanted)))
        checks.append(Check(f"κ constant for f15 = {f15:g}, f16 ≠ 0",
                            f"{group['kappa'].min():.10f} … {group['kappa'].max():.10f}",
                            f"{wanted:.10f} ({'1' if f15 == 0 else '√5 − 2'}) ± {EXACT_RTOL:g}·κ",
                            spread <= EXACT_RTOL * wanted))
        ratio = group["sigma_chi2"] / group["sigma_chi2_expected"]
        checks.append(Check(f"σ_χ2 = √(f15²+1)/|f16|, f15 = {f15:g}",
                            f"max rel. error {float(np.max(np.abs(ratio - 1))):.1e}",
                            f"≤ {EXACT_RTOL:g}", bool(np.all(np.abs(ratio - 1) <= EXACT_RTOL))))
        sigma1_error = float(np.max(np.abs(group["sigma_chi1"] - 1.0)))
        checks.append(Check(f"σ_χ1 = 1, f15 = {f15:g}", f"max |σ_χ1 − 1| = {sigma1_error:.1e}", f"≤ {EXACT_RTOL:g}",
                            sigma1_error <= EXACT_RTOL))
    zero_ok = bool(np.all(at_zero["kappa"] == 0) and np.all(at_zero["verdict"] == "not_identifiable")
                   and np.all(at_zero["zero_influence"] == "a2") and np.all(nonzero["kappa"] > 0))
    checks.append(Check("κ = 0 only at f16 = 0 (not_identifiable, Z = {a2})",
                        f"κ(0) = {list(at_zero['kappa'])}, Z = {list(at_zero['zero_influence'])}, "
                        f"min κ elsewhere {nonzero['kappa'].min():.4f}", "κ = 0 ⇔ f16 = 0", zero_ok))
    literal_ok = bool(np.all((table["verdict_det"] == "not_identifiable") == (table["f16"] == 0)))
    checks.append(Check("literal det fails only at f16 = 0", f"{(table['verdict_det'] != 'identifiable').sum()} "
                        "failing points", "2 (f16 = 0 for both f15)", literal_ok))

    rounding = timeline[timeline["variant"] == "float cos"]
    ok_steps = rounding[~rounding["k"].isin([2, 6])]
    bad_steps = rounding[rounding["k"].isin([2, 6])]
    kappa_ok = bool(np.all(np.abs(ok_steps["kappa"] - (math.sqrt(2) - 1)) <= EXACT_RTOL))
    checks.append(Check("TV2 local: k = 2, 6 not_identifiable with Z = {a2}, κ = √2 − 1 elsewhere",
                        f"failing {summary['float cos']['failing_svd']}, Z = {list(bad_steps['zero_influence'])}, "
                        f"κ = {ok_steps['kappa'].min():.15f} … {ok_steps['kappa'].max():.15f}",
                        "[2, 6], ['a2', 'a2'], 0.414213562373095",
                        summary["float cos"]["failing_svd"] == [2, 6] and list(bad_steps["zero_influence"]) == ["a2", "a2"]
                        and kappa_ok))
    checks.append(Check("TV2 global (SVD)", summary["float cos"]["global_svd"], "not_identifiable",
                        summary["float cos"]["global_svd"] == "not_identifiable"))
    dets = {int(r.k): r.det for r in bad_steps.itertuples()}
    det_ok = all(abs(dets[k] - v) <= 1e-12 * v for k, v in TV2_DET.items())
    checks.append(Check("TV2 literal det at k = 2, 6", ", ".join(f"{dets[k]:.16g}" for k in (2, 6)),
                        ", ".join(f"{v:.16g}" for v in TV2_DET.values()), det_ok))
    checks.append(Check("TV2 literal det misses k = 2, 6 (G5)",
                        f"failing {summary['float cos']['failing_det']}, global {summary['float cos']['global_det']}",
                        "failing [], global identifiable", summary["float cos"]["failing_det"] == []))
    exact = summary["exact zeros"]
    checks.append(Check("TV2 exact zeros: both methods fail at k = 2, 6",
                        f"svd {exact['failing_svd']}, det {exact['failing_det']}", "[2, 6], [2, 6]",
                        exact["failing_svd"] == [2, 6] and exact["failing_det"] == [2, 6]))
    one, two = window.iloc[0], window.iloc[1]
    checks.append(Check("TV6 N_w = 1", f"{one['verdict']}, Z = {{{one['zero_influence']}}}",
                        "not_identifiable, Z = {a2}", one["verdict"] == "not_identifiable" and one["zero_influence"] == "a2"))
    checks.append(Check("TV6 N_w = 2 recovers a2", f"{two['verdict']}, κ = {two['kappa']:.10f}",
                        f"identifiable, κ = {TV6_KAPPA} (± {PRINTED_ATOL:g})",
                        two["verdict"] == "identifiable" and abs(two["kappa"] - TV6_KAPPA) <= PRINTED_ATOL))
    return checks


def run_example(out_dir: Path) -> dict:
    """E1: sweep, TV2 timeline, TV6 window, checks; writes CSVs, PNG and JSON summary."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    table = sweep()
    timeline, summary = tv2_timeline()
    window = tv6_window()
    checks = check_example(table, timeline, summary, window)
    paths = {"csv": out_dir / CSV_NAME, "tv2": out_dir / TV2_CSV_NAME, "tv6": out_dir / TV6_CSV_NAME,
             "png": out_dir / PNG_NAME, "json": out_dir / JSON_NAME}
    table.to_csv(paths["csv"], index=False, float_format="%.15g")
    timeline.to_csv(paths["tv2"], index=False, float_format="%.17g")
    window.to_csv(paths["tv6"], index=False, float_format="%.12g")
    save_figure(plot_example(table), paths["png"])
    results = {"kappa_by_f15": {f"{f15:g}": float(g.loc[g["f16"] != 0, "kappa"].median())
                                for f15, g in table.groupby("f15")},
               "tv2": summary, "tv6": window.drop(columns="sensitivity").to_dict(orient="records")}
    write_summary(paths["json"], "ident-example", {"f15": list(F15_VALUES), "f16_points": len(F16_GRID)}, results, checks)
    return {"sweep": table, "tv2": timeline, "tv2_summary": summary, "tv6": window, "checks": checks,
            "paths": paths, "results": results}

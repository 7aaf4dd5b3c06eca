"""Study E5 of spec 002 §6: conditioning of gain (6) and of the covariance update (R11 A7, A8).

The paper says V_η regularises the sum hV_xhᵀ + V_η in (6) but that its diagonal may be orders of
magnitude below hV_xhᵀ, so ill-conditioning is not removed.  Here V_x = R diag(ρ, 1) Rᵀ with R the
rotation by 0.3 rad, h = [[1, 0.4], [0.2, 1]], V_η = diag(1, 0.5), ρ = 10⁰, 10², …, 10¹⁴.

* the gain Γ = V_x hᵀ(hV_xhᵀ + V_η)⁻¹ by :func:`skytrack.filters.adaptive_augmented.filter_gain`,
  explicit inverse (R13 literal) and Cholesky solve (default), against an exact reference;
* the update P(k|k) of A8 in the short form (I − ΓH)V_x (the flag kept for this study) and in the
  Joseph form (I − ΓH)V_x(I − ΓH)ᵀ + ΓV_ηΓᵀ, each with both gains.

The reference is exact rational arithmetic (:class:`fractions.Fraction`): the float inputs V_x, h, V_η
are converted exactly and the 2 × 2 products and inverse are rational, so Γ and P are the exact values
for the rounded inputs (no high-precision library needed at run time).

Expected (§6 E5): cond ≈ 1.16ρ; relative gain error of both methods ≈ 10⁻¹⁶·cond (≈ 4·10⁻⁹ at
ρ = 10⁸); the short form with the literal (explicit-inverse) gain loses symmetry (≈ 10⁻⁶ at ρ = 10⁶)
and is indefinite from ρ ≈ 10¹⁰ (λ_min ≈ −1.4·10²); the Joseph form stays PSD with relative error
≤ 2·10⁻⁴ up to ρ = 10¹⁴ with the default Cholesky gain.  Found here (reported, not a spec number):
the Joseph form with the explicit-inverse gain stays PSD but its error grows like (δΓ)²ρ (about
6·10⁻⁵ at ρ = 10¹⁰, 10⁹ at 10¹⁴), and the short form with the Cholesky gain stays positive definite.
Round-off figures are checked within a factor :data:`ROUNDOFF_FACTOR`.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.filters.adaptive_augmented import filter_gain
from skytrack.studies.adaptive_numerics.common import Check, pyplot, within_factor, write_outputs

NAME = "gain_conditioning"
ANGLE = 0.3
OBSERVATION = np.array([[1.0, 0.4], [0.2, 1.0]])
NOISE_COV = np.diag([1.0, 0.5])
EXPONENTS = tuple(range(0, 15, 2))
GAINS = ("explicit", "cholesky")
#: unit round-off scale of the "≈ 10⁻¹⁶·cond" law
ROUNDOFF = 1e-16
#: round-off figures are expected to the order of magnitude: within this factor
ROUNDOFF_FACTOR = 10.0
EXPECTED_COND_RATIO = 1.16
COND_RATIO_TOLERANCE = 0.02  # relative, for ρ ≥ 10²
EXPECTED_GAIN_ERROR_1E8 = 4e-9
EXPECTED_ASYMMETRY_1E6 = 1e-6
EXPECTED_FIRST_INDEFINITE = 1e10
EXPECTED_LAMBDA_MIN_1E10 = -1.4e2
JOSEPH_BOUND = 2e-4


def prior_covariance(rho: float) -> np.ndarray:
    """V_x = R diag(ρ, 1) Rᵀ in floating point (the study's input)."""
    c, s = np.cos(ANGLE), np.sin(ANGLE)
    rotation = np.array([[c, -s], [s, c]])
    return rotation @ np.diag([rho, 1.0]) @ rotation.T


# ---------------------------------------------------------------- exact 2 × 2 rational arithmetic

def _exact(a: np.ndarray) -> list[list[Fraction]]:
    return [[Fraction(float(v)) for v in row] for row in np.asarray(a, float)]


def _mul(a, b):
    return [[sum((a[i][k] * b[k][j] for k in range(len(b))), Fraction(0)) for j in range(len(b[0]))]
            for i in range(len(a))]


def _t(a):
    return [list(row) for row in zip(*a)]


def _sub(a, b):
    return [[x - y for x, y in zip(r, s)] for r, s in zip(a, b)]


def _add(a, b):
    return [[x + y for x, y in zip(r, s)] for r, s in zip(a, b)]


def _inv2(a):
    det = a[0][0] * a[1][1] - a[0][1] * a[1][0]
    return [[a[1][1] / det, -a[0][1] / det], [-a[1][0] / det, a[0][0] / det]]


def _float(a) -> np.ndarray:
    return np.array([[float(v) for v in row] for row in a])


def exact_gain_and_update(Vx: np.ndarray, h: np.ndarray = OBSERVATION, noise_cov: np.ndarray = NOISE_COV):
    """Exact Γ and P(k|k) = (I − Γh)V_x (= the Joseph form, exactly) for the float inputs, rounded once."""
    X, H, R = _exact(Vx), _exact(h), _exact(noise_cov)
    innovation = _add(_mul(_mul(H, X), _t(H)), R)
    gain = _mul(_mul(X, _t(H)), _inv2(innovation))
    identity = [[Fraction(1), Fraction(0)], [Fraction(0), Fraction(1)]]
    return _float(gain), _float(_mul(_sub(identity, _mul(gain, H)), X))


# ---------------------------------------------------------------- the sweep

def short_update(gain, Vx, h=OBSERVATION):
    """A8's short form (I − ΓH)V_x (not symmetrised)."""
    return (np.eye(len(Vx)) - gain @ h) @ Vx


def joseph_update(gain, Vx, h=OBSERVATION, noise_cov=NOISE_COV):
    """A8's Joseph form, as the filter computes it (symmetrised)."""
    reduce = np.eye(len(Vx)) - gain @ h
    P = reduce @ Vx @ reduce.T + gain @ noise_cov @ gain.T
    return 0.5 * (P + P.T)


def _relative(a, b) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def sweep(exponents=EXPONENTS) -> pd.DataFrame:
    """One row per ρ = 10^e: cond, gain errors, and per gain method the two updates' asymmetry,
    smallest eigenvalue (of the symmetric part) and relative error against the exact P."""
    rows = []
    for exponent in exponents:
        rho = 10.0**exponent
        Vx = prior_covariance(rho)
        gain_exact, P_exact = exact_gain_and_update(Vx)
        innovation = OBSERVATION @ Vx @ OBSERVATION.T + NOISE_COV
        row = {"rho": rho, "cond": float(np.linalg.cond(innovation)),
               "lambda_min_exact": float(np.linalg.eigvalsh(0.5 * (P_exact + P_exact.T)).min())}
        row["cond_over_rho"] = row["cond"] / rho
        for method in GAINS:
            gain = filter_gain(Vx[None], OBSERVATION[None], NOISE_COV[None], method)[0][0]
            row[f"gain_error_{method}"] = _relative(gain, gain_exact)
            for form, P in (("short", short_update(gain, Vx)), ("joseph", joseph_update(gain, Vx))):
                row[f"{form}_{method}_asymmetry"] = float(np.abs(P - P.T).max() / np.abs(P_exact).max())
                row[f"{form}_{method}_lambda_min"] = float(np.linalg.eigvalsh(0.5 * (P + P.T)).min())
                row[f"{form}_{method}_error"] = _relative(P, P_exact)
        rows.append(row)
    return pd.DataFrame(rows)


def _at(table: pd.DataFrame, rho: float, column: str) -> float:
    return float(table.loc[np.isclose(table["rho"], rho), column].iloc[0])


def check_sweep(table: pd.DataFrame) -> list[Check]:
    """The §6 E5 expectations (round-off figures within a factor :data:`ROUNDOFF_FACTOR`)."""
    f = ROUNDOFF_FACTOR
    checks = []
    ratios = table.loc[table["rho"] >= 1e2, "cond_over_rho"]
    checks.append(Check("cond(hV_xhᵀ+V_η)/ρ, ρ ≥ 10²", f"{ratios.min():.4f} … {ratios.max():.4f}",
                        f"{EXPECTED_COND_RATIO} ± {COND_RATIO_TOLERANCE:.0%}",
                        bool((abs(ratios / EXPECTED_COND_RATIO - 1) <= COND_RATIO_TOLERANCE).all())))
    for method in GAINS:
        error = _at(table, 1e8, f"gain_error_{method}")
        checks.append(Check(f"gain error ({method}) at ρ = 10⁸", f"{error:.2e}",
                            f"≈ {EXPECTED_GAIN_ERROR_1E8:.0e} (within ×{f:g})",
                            within_factor(error, EXPECTED_GAIN_ERROR_1E8, f)))
        law = table[f"gain_error_{method}"] / (ROUNDOFF * table["cond"])
        checks.append(Check(f"gain error ({method}) / (10⁻¹⁶·cond), all ρ", f"≤ {law.max():.2f}",
                            f"≤ {f:g}", bool((law <= f).all())))
    asymmetry = _at(table, 1e6, "short_explicit_asymmetry")
    checks.append(Check("short form (explicit gain): asymmetry at ρ = 10⁶", f"{asymmetry:.2e}",
                        f"≈ {EXPECTED_ASYMMETRY_1E6:.0e} (within ×{f:g})",
                        within_factor(asymmetry, EXPECTED_ASYMMETRY_1E6, f)))
    negative = table.loc[table["short_explicit_lambda_min"] < 0, "rho"]
    first = float(negative.min()) if len(negative) else float("nan")
    checks.append(Check("short form (explicit gain): first indefinite ρ", f"{first:.0e}",
                        f"{EXPECTED_FIRST_INDEFINITE:.0e} (then indefinite for every larger ρ)",
                        first == EXPECTED_FIRST_INDEFINITE
                        and bool((table.loc[table["rho"] >= first, "short_explicit_lambda_min"] < 0).all())))
    lam = _at(table, 1e10, "short_explicit_lambda_min")
    checks.append(Check("short form (explicit gain): λ_min at ρ = 10¹⁰", f"{lam:.3g}",
                        f"≈ {EXPECTED_LAMBDA_MIN_1E10:.2g} (within ×{f:g})",
                        within_factor(lam, EXPECTED_LAMBDA_MIN_1E10, f)))
    for method in GAINS:
        lam_min = table[f"joseph_{method}_lambda_min"].min()
        checks.append(Check(f"Joseph form ({method} gain) PSD, ρ ≤ 10¹⁴", f"min λ_min = {lam_min:.3g}", "> 0",
                            lam_min > 0))
    error = table["joseph_cholesky_error"].max()
    checks.append(Check("Joseph form (Cholesky gain, default) relative error, ρ ≤ 10¹⁴", f"max {error:.2e}",
                        f"≤ {JOSEPH_BOUND:.0e}", error <= JOSEPH_BOUND))
    return checks


def plot_sweep(table: pd.DataFrame):
    """Four log-scale panels: cond, gain errors, update errors and asymmetry, smallest eigenvalues."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11.0, 8.0))
    rho = table["rho"].to_numpy()
    ax = axes[0, 0]
    ax.loglog(rho, table["cond"], "o-", label="cond(hV_xhᵀ + V_η)")
    ax.loglog(rho, EXPECTED_COND_RATIO * rho, "k--", label="1.16 ρ (spec)")
    ax.set_title("(a) conditioning of the sum in gain (6)")
    ax.set_ylabel("condition number [–]")
    ax = axes[0, 1]
    ax.loglog(rho, table["gain_error_explicit"], "o-", label="explicit inverse (literal, R13)")
    ax.loglog(rho, table["gain_error_cholesky"], "s-", label="Cholesky solve (default)")
    ax.loglog(rho, ROUNDOFF * table["cond"], "k--", label="10⁻¹⁶ · cond")
    ax.set_title("(b) relative gain error ‖Γ − Γ_exact‖/‖Γ_exact‖")
    ax.set_ylabel("relative error [–]")
    ax = axes[1, 0]
    for method, marker in (("explicit", "o"), ("cholesky", "s")):
        ax.loglog(rho, table[f"short_{method}_error"], marker + "-", label=f"short form, {method} gain: rel. error")
        ax.loglog(rho, np.maximum(table[f"short_{method}_asymmetry"], 1e-18), marker + ":",
                  label=f"short form, {method} gain: asymmetry")
        ax.loglog(rho, table[f"joseph_{method}_error"], marker + "--", label=f"Joseph, {method} gain: rel. error")
    ax.axhline(JOSEPH_BOUND, color="k", lw=0.8, ls="--", label="2·10⁻⁴ (spec bound, Joseph)")
    ax.set_title("(c) covariance update P(k|k): error and asymmetry")
    ax.set_ylabel("relative to max|P_exact| [–]")
    ax = axes[1, 1]
    ax.semilogx(rho, table["short_explicit_lambda_min"], "o-", label="short form, explicit gain")
    ax.semilogx(rho, table["short_cholesky_lambda_min"], "s-", label="short form, Cholesky gain")
    ax.semilogx(rho, table["joseph_explicit_lambda_min"], "^--", label="Joseph form, explicit gain")
    ax.semilogx(rho, table["lambda_min_exact"], "k:", label="exact")
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_title("(d) smallest eigenvalue of P(k|k) (symlog)")
    ax.set_ylabel("λ_min [units of V_x]")
    for ax in axes.flat:
        ax.set_xlabel("ρ (largest eigenvalue of V_x) [units of V_x]")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.suptitle("E5: V_η does not remove the ill-conditioning of (6); the Joseph form keeps P(k|k) PSD")
    fig.tight_layout()
    return fig


def run_gain_conditioning(out_dir: Path, exponents=EXPONENTS):
    """E5: the sweep, its checks and outputs; returns ``(table, checks, paths)``."""
    table = sweep(exponents)
    checks = check_sweep(table)
    paths = write_outputs(out_dir, NAME, table, plot_sweep(table), checks,
                          {"angle_rad": ANGLE, "h": OBSERVATION, "V_eta": NOISE_COV, "rho": table["rho"].to_numpy()})
    return table, checks, paths

"""Study E6 of spec 002 §6: the poorly-planned-experiment diagnostic (§3.6, R16) on TV12(b)'s remedies.

A deterministic linear Kalman filter with fixed V_w (100 steps, T = 1 s) on the state
(x, y, v_x, v_y, a_x, a_y[, b_x]) with R3 dynamics, V_w = diag(0.01, 0.01[, 10⁻⁴]), Q_dep = 0,
P(0|0) = diag(10⁶, 10⁶, 100, 100, 1, 1[, 10⁶]); the radar measures (x + b_x, y) with σ = 20 m:

* V0 baseline (the bias b_x is not identifiable: D = {a_x, b_x});
* V1 remedy (1): drop b_x; V2 remedy (2): add an unbiased (x, y) with σ = 10 m;
* V3 remedy (3): prior σ_bx = 10 m (P(0|0) = 100 for b_x).

For each variant: diag P(100|100) (:func:`skytrack.analysis.experiment_quality.covariance_recursion`),
R5 on S (:func:`skytrack.analysis.identifiability.check_identifiability`), and R16's diagnostic
(:func:`~skytrack.analysis.experiment_quality.check_experiment`) in matched and literal mode with its
advice text.  Expected: the TV12(b) table (diag P at 1e−6 relative or half a unit of the printed last
decimal, literal ratio to its printed digits), flagged fraction 1.0 for V0 and 0 for V1-V3 in both
modes.  :func:`remedy_run` is the TV12(b) setup (the tests can import it).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.analysis.experiment_quality import ExperimentQuality, check_experiment, covariance_recursion, culprits_of
from skytrack.analysis.identifiability import check_identifiability
from skytrack.models.augmented import ca_accel
from skytrack.studies.adaptive_numerics.common import Check, pyplot, write_outputs

NAME = "poor_experiment"
STEPS = 100
VARIANTS = ("V0", "V1", "V2", "V3")
DESCRIPTIONS = {"V0": "baseline", "V1": "drop b_x (remedy 1)", "V2": "+ unbiased position σ = 10 m (remedy 2)",
                "V3": "prior σ_bx = 10 m (remedy 3)"}
MODES = ("matched", "literal")


@dataclass(frozen=True)
class ExpectedRow:
    """One row of TV12(b)'s table as printed in the spec."""

    diag: str
    literal_ratio: float
    poorly_planned: bool
    r5_verdict: str
    indistinguishable: tuple[str, ...]


#: spec 002 TV12(b)
TV12B = {
    "V0": ExpectedRow("500153.793 115.859244 5.371313 5.371296 0.107246 0.107246 500037.912", 1250.38, True,
                      "not_identifiable", ("ax", "b_x")),
    "V1": ExpectedRow("115.859244 115.859244 5.371296 5.371296 0.107246 0.107246", 0.2896, False, "identifiable", ()),
    "V2": ExpectedRow("29.047469 28.847335 2.324850 2.324849 0.079815 0.079815 5.003257", 0.0726, False,
                      "identifiable", ()),
    "V3": ExpectedRow("215.859389 115.859244 5.371313 5.371296 0.107246 0.107246 100.000003", 0.5396, False,
                      "not_identifiable", ("ax", "b_x")),
}
DIAG_RTOL = 1e-6


@dataclass(frozen=True)
class RemedyRun:
    """One TV12(b) variant: the model, H, V_η, channel names and P(k|k) for k = 1 … steps."""

    model: object
    H: np.ndarray
    noise_cov: np.ndarray
    channels: tuple[str, ...]
    P: np.ndarray


def remedy_run(variant: str, steps: int = STEPS) -> RemedyRun:
    """The TV12(b) setup of ``variant`` (V0-V3) and its covariance recursion."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, not {variant!r}")
    biased = variant != "V1"
    model = ca_accel(sigma_accel=0.1)
    if biased:
        model = model.with_parameters(["b_x"], ["m"], [1e-4])
    n = model.dim
    H = np.zeros((2, n))
    H[0, 0] = H[1, 1] = 1.0
    if biased:
        H[0, 6] = 1.0  # the radar measures x + b_x
    noise = [400.0, 400.0]
    channels = ["x_radar", "y_radar"]
    if variant == "V2":
        H = np.vstack([H, np.eye(n)[:2]])
        noise += [100.0, 100.0]
        channels += ["x_unbiased", "y_unbiased"]
    P0 = np.diag([1e6, 1e6, 100.0, 100.0, 1.0, 1.0, 1e6][:n])
    if variant == "V3":
        P0[6, 6] = 100.0
    F = model.F(np.zeros(n), 1.0)
    P = covariance_recursion(F, model.V_w, model.h_a, H, np.diag(noise), P0, steps)
    return RemedyRun(model, H, np.diag(noise), tuple(channels), P)


def diagnose(run: RemedyRun):
    """R5 on S (one step, F at 0, T = 1) and R16 in both modes; returns ``(checks_r5, {mode: quality})``."""
    model = run.model
    r5 = check_identifiability(H=run.H, F=model.F(np.zeros(model.dim), 1.0), h_a=model.h_a,
                               noise_cov=run.noise_cov, names=model.parameters)
    units = ["m"] * len(run.channels)
    quality = {mode: check_experiment(run.P, run.noise_cov, components=model.components, state_units=model.units,
                                      measurement_units=units, mode=mode, culprits=culprits_of(r5),
                                      observation=run.H, channels=run.channels)
               for mode in MODES}
    return r5, quality


def printed_match(values, printed: str, rtol: float = DIAG_RTOL) -> bool:
    """Within ``rtol`` relative, or within half a unit of the printed last decimal where the printed value
    has fewer digits than that (0.107246 stands for 0.10724581, 2.6e−6 relative)."""
    texts = printed.split()
    if len(texts) != len(values):
        return False
    for value, text in zip(values, texts):
        decimals = len(text.split(".")[1]) if "." in text else 0
        expected = float(text)
        if abs(value - expected) > max(rtol * abs(expected), 0.5 * 10.0**-decimals * (1 + 1e-9)):
            return False
    return True


def _literal_tolerance(expected: float) -> float:
    """Half a unit of the printed last decimal of TV12(b)'s literal ratio (1250.38, 0.2896, …)."""
    text = f"{expected:g}"
    decimals = len(text.split(".")[1]) if "." in text else 0
    return 0.5 * 10.0**-decimals * 1.2


def run_variants(steps: int = STEPS):
    """All variants: ``(table, per-step frame, {variant: (r5, quality)})``."""
    rows, per_step, results = [], [], {}
    for variant in VARIANTS:
        run = remedy_run(variant, steps)
        r5, quality = diagnose(run)
        results[variant] = (r5, quality)
        row = {"variant": variant, "description": DESCRIPTIONS[variant],
               "diag_P_final": " ".join(f"{v:.9g}" for v in np.diag(run.P[-1])),
               "r5_verdict": r5.verdicts[0], "indistinguishable": ",".join(r5.indistinguishable_names(0)),
               "literal_ratio_final": float(quality["literal"].literal_ratio[-1])}
        for mode in MODES:
            q: ExperimentQuality = quality[mode]
            row[f"{mode}_verdict"] = q.verdict
            row[f"{mode}_flagged_fraction"] = q.flagged_fraction
            row[f"{mode}_culprits"] = ",".join(q.culprit_components)
            row[f"{mode}_advice"] = q.advice or ""
        rows.append(row)
        matched = quality["matched"]
        frame = pd.DataFrame({"variant": variant, "k": matched.steps,
                              "literal_ratio": quality["literal"].literal_ratio,
                              "max_matched_ratio": np.nanmax(matched.component_ratio, axis=1)})
        for i, name in enumerate(run.model.components):
            frame[f"P_{name}"] = run.P[:, i, i]
        per_step.append(frame)
    return pd.DataFrame(rows), pd.concat(per_step, ignore_index=True), results


def check_variants(table: pd.DataFrame) -> list[Check]:
    """TV12(b)'s table and flagged fractions."""
    checks = []
    for row in table.itertuples(index=False):
        expected = TV12B[row.variant]
        diag = [float(v) for v in row.diag_P_final.split()]
        checks.append(Check(f"{row.variant} diag P(100|100)", row.diag_P_final, expected.diag + f" (rel. {DIAG_RTOL:g})",
                            printed_match(diag, expected.diag)))
        tolerance = _literal_tolerance(expected.literal_ratio)
        checks.append(Check(f"{row.variant} literal ratio", f"{row.literal_ratio_final:.6g}",
                            f"{expected.literal_ratio:g} ± {tolerance:.2g}",
                            abs(row.literal_ratio_final - expected.literal_ratio) <= tolerance))
        verdict = "poorly planned experiment" if expected.poorly_planned else "ok"
        fraction = 1.0 if expected.poorly_planned else 0.0
        for mode in MODES:
            measured = f"{getattr(row, f'{mode}_verdict')}, flagged {getattr(row, f'{mode}_flagged_fraction'):.2f}"
            checks.append(Check(f"{row.variant} run verdict ({mode})", measured, f"{verdict}, flagged {fraction:.2f}",
                                getattr(row, f"{mode}_verdict") == verdict
                                and getattr(row, f"{mode}_flagged_fraction") == fraction))
        d_expected = ",".join(expected.indistinguishable)
        checks.append(Check(f"{row.variant} R5 on S", f"{row.r5_verdict}, D = {{{row.indistinguishable}}}",
                            f"{expected.r5_verdict}, D = {{{d_expected}}}",
                            row.r5_verdict == expected.r5_verdict and row.indistinguishable == d_expected))
    return checks


def plot_variants(per_step: pd.DataFrame):
    """Literal ratio and largest matched ratio per step, one line per variant, threshold 10²."""
    plt = pyplot()
    fig, (ax_lit, ax_match) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    for variant, group in per_step.groupby("variant", sort=True):
        label = f"{variant} {DESCRIPTIONS[variant]}"
        ax_lit.semilogy(group["k"], group["literal_ratio"], label=label)
        ax_match.semilogy(group["k"], group["max_matched_ratio"], label=label)
    for ax in (ax_lit, ax_match):
        ax.axhline(100.0, color="k", ls="--", lw=0.8, label="threshold 10^κ_o = 100")
        ax.axvline(20.0, color="grey", ls=":", lw=0.8, label="burn-in (20 steps)")
        ax.set_xlabel("step k (T = 1 s) [–]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small")
    ax_lit.set_title("(a) literal: max|P_ij(k|k)| / max V_η,ll")
    ax_lit.set_ylabel("ratio [–]")
    ax_match.set_title("(b) matched: max_i P_ii(k|k) / r_i (same unit)")
    ax_match.set_ylabel("ratio [–]")
    fig.suptitle("E6 (TV12 b): a poorly planned experiment and its three remedies")
    fig.tight_layout()
    return fig


def run_poor_experiment(out_dir: Path, steps: int = STEPS):
    """E6: table, per-step ratios, checks and outputs; returns ``(table, checks, paths)``."""
    table, per_step, _ = run_variants(steps)
    checks = check_variants(table) if steps == STEPS else []
    paths = write_outputs(out_dir, NAME, table, plot_variants(per_step), checks, {"steps": steps},
                          extra_tables={"steps": per_step})
    return table, checks, paths

"""Study E8 of spec 001 §6: calibration of the posterior P(θ = 1 | ζ) (gap G1, R6).

Geometry of TV-3 (radar at t = 0, 1, 2, 3 s, σ = 50 m; ADS-B at 0.3, 1.3, 2.3, 3.3 s, σ = 20 m),
Q = 0.  Object states at t₀ = 0 are drawn from N(x₀, P₀), x₀ = [1000, 2000, 0, 0],
P₀ = diag(100², 100², 20², 20²).  With probability π = 0.5 both systems observe one object;
otherwise the ADS-B reports come from a second, independent object.  The filters run in prior
mode from the same N(x₀, P₀) at t₀ (R3b), and the posterior is

* with the log-determinants (R6): P = [1 + ((1 − π)/π) exp((Λ + D)/2)]^{-1};
* literal (the paper's (14a) with constant c, ``include_logdet=False``): P = [1 + ((1 − π)/π) e^{Λ/2}]^{-1}.

Prior mode with Q = 0 is a batch Gaussian model: each filter's accumulated innovation form is
r^T S^{-1} r with r = z − X x₀ and S = X P₀ X^T + R of its reports, and D = ln det S_joint −
ln det S_η − ln det S_ξ is a constant.  The ``trials`` draws use these batch forms; the first
:data:`RECURSIVE_RUNS` also go through :class:`~skytrack.identify.sequential.SequentialPairTest`
(``init="prior"``, :meth:`~skytrack.identify.sequential.SequentialPairTest.log_odds` with and
without D), which must agree to 1e-8 in the log-odds.

Expected (§6 E8): with the log-dets the observed frequency of "same" in posterior bins of width 0.1
follows the diagonal (each bin within ±0.04 of its mean posterior; with fewer than 2e5 trials a
bin may also pass within 4 binomial SE) and the Brier score is 0.0435 ± 0.001 (× √(2e5/N)); the
literal posterior is far off: in the bins from 0.1 to 0.9 (lower edges) the observed frequency is
0.81-0.998 (± 0.015 × √(2e5/N)) and its Brier
score ≈ 0.164 (checked ± 0.003 × √(2e5/N)).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.identify.sequential import logistic
from skytrack.studies.identification import scenario_tv5 as tv5
from skytrack.studies.identification.common import pyplot
from skytrack.studies.identification.mc_common import (
    Check, Progress, StudyOutput, chunked, finish, frequency_se, tolerance_scale, within,
)

NAME = "ident_posterior_calibration"
DEFAULT_TRIALS = 200_000
REFERENCE_TRIALS = 200_000
CHUNK = 50_000
RECURSIVE_RUNS = 300
PRIOR_SAME = 0.5
X0 = np.array([1000.0, 2000.0, 0.0, 0.0])
P0_DIAGONAL = np.array([100.0 ** 2, 100.0 ** 2, 20.0 ** 2, 20.0 ** 2])
T0 = 0.0
BINS = np.linspace(0.0, 1.0, 11)
BIN_TOLERANCE = 0.04
BRIER_LOGDET, BRIER_LOGDET_TOLERANCE = 0.0435, 0.001
BRIER_LITERAL, BRIER_LITERAL_TOLERANCE = 0.164, 0.003
#: §6 E8: the literal posterior's observed frequencies in the bins [0.1, 0.2) ... [0.9, 1.0] span 0.81-0.998
LITERAL_RANGE = (0.81, 0.998)
LITERAL_RANGE_TOLERANCE = 0.015
VARIANTS = {"logdet": "with log-determinants (R6)", "literal": "literal (14a), include_logdet=False"}


def prior_forms(geometry: tv5.Geometry = tv5.TV3_GEOMETRY, p0_diagonal=P0_DIAGONAL) -> tuple[np.ndarray, float]:
    """Per-axis A_prior of the prior-mode Λ = Σ_axes r_a^T A_prior r_a, r = z − X x₀, and the constant D
    (``p0_diagonal`` [x, y, vx, vy] with equal x and y entries)."""
    time, system, sigma = geometry.merged()
    p0_axis = np.diag([p0_diagonal[0], p0_diagonal[2]])  # [position, velocity] per axis, same for x and y
    X = np.column_stack([np.ones_like(time), time - T0])
    S_joint = X @ p0_axis @ X.T + np.diag(sigma ** 2)
    A = np.linalg.inv(S_joint)
    logdet = np.linalg.slogdet(S_joint)[1]
    for s in (1, 2):
        mine = np.flatnonzero(system == s)
        S = S_joint[np.ix_(mine, mine)]  # the separate filter's reports: same prior, own noise
        A[np.ix_(mine, mine)] -= np.linalg.inv(S)
        logdet -= np.linalg.slogdet(S)[1]
    return 0.5 * (A + A.T), tv5.NDIM * logdet


def draw_trials(rng: np.random.Generator, trials: int, geometry: tv5.Geometry = tv5.TV3_GEOMETRY):
    """Reports ``[N, R, 2]`` and the truth ``same`` ``[N]``: π = 0.5 one object, else two independent ones."""
    time, system, sigma = geometry.merged()
    first = X0 + rng.standard_normal((trials, 4)) * np.sqrt(P0_DIAGONAL)
    second = X0 + rng.standard_normal((trials, 4)) * np.sqrt(P0_DIAGONAL)
    same = rng.random(trials) < PRIOR_SAME
    second[same] = first[same]
    positions = np.where((system == 1)[None, :, None], tv5.object_positions(first, time),
                         tv5.object_positions(second, time))
    return positions + rng.standard_normal(positions.shape) * sigma[None, :, None], same


def posteriors(z: np.ndarray, A: np.ndarray, D: float, geometry: tv5.Geometry = tv5.TV3_GEOMETRY) -> dict:
    """Λ (all innovations, prior mode) and both posteriors per trial."""
    time = geometry.merged()[0]
    r = z - tv5.object_positions(X0[None, :], time)
    lam = np.einsum("nra,rs,nsa->n", r, A, r, optimize=True)
    prior_logit = np.log(PRIOR_SAME) - np.log1p(-PRIOR_SAME)
    return {"statistic": lam, "logdet": logistic(prior_logit - 0.5 * (lam + D)),
            "literal": logistic(prior_logit - 0.5 * lam),
            "log_odds_logdet": prior_logit - 0.5 * (lam + D), "log_odds_literal": prior_logit - 0.5 * lam}


def recursive_check(z: np.ndarray, batch: dict, geometry: tv5.Geometry = tv5.TV3_GEOMETRY) -> float:
    """Largest |log-odds batch − SequentialPairTest (prior mode)| over both variants."""
    _, test = tv5.recursive_forms(z, geometry, init="prior", x0=X0, P0=np.diag(P0_DIAGONAL), t0=T0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # include_logdet=False warns that it is not calibrated: that is the point
        literal = test.log_odds(PRIOR_SAME, include_logdet=False)
    logdet = test.log_odds(PRIOR_SAME)
    return float(max(np.max(np.abs(logdet - batch["log_odds_logdet"])),
                     np.max(np.abs(literal - batch["log_odds_literal"]))))


def simulate(trials: int, seed: int, progress: Progress = None) -> tuple[dict, float]:
    """Posteriors and truth for every trial (``default_rng(seed)``), and the recursive check."""
    A, D = prior_forms()
    rng = np.random.default_rng(seed)
    parts, difference = [], np.nan
    chunks = chunked(trials, CHUNK)
    for c, size in enumerate(chunks):
        z, same = draw_trials(rng, size)
        values = posteriors(z, A, D)
        if c == 0:
            runs = min(RECURSIVE_RUNS, size)
            difference = recursive_check(z[:runs], {k: v[:runs] for k, v in values.items()})
        parts.append({"same": same, **{k: values[k] for k in ("statistic", "logdet", "literal")}})
        if progress is not None:
            progress(c + 1, len(chunks))
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}, difference


def reliability_table(samples: dict) -> pd.DataFrame:
    """Per variant and bin of width 0.1: trials, mean posterior, observed frequency of "same", its SE."""
    rows = []
    same = samples["same"].astype(float)
    for variant in VARIANTS:
        p = samples[variant]
        index = np.clip(np.digitize(p, BINS) - 1, 0, len(BINS) - 2)
        for b in range(len(BINS) - 1):
            inside = index == b
            n = int(inside.sum())
            observed = float(same[inside].mean()) if n else np.nan
            rows.append({"variant": variant, "bin_low": BINS[b], "bin_high": BINS[b + 1], "trials": n,
                         "mean_posterior": float(p[inside].mean()) if n else np.nan, "observed": observed,
                         "se": float(frequency_se(observed, n)) if n else np.nan})
    return pd.DataFrame(rows)


def brier(samples: dict, variant: str) -> float:
    return float(np.mean((samples[variant] - samples["same"]) ** 2))


def check_calibration(table: pd.DataFrame, scores: dict[str, float], recursive: float, trials: int) -> list[Check]:
    s = tolerance_scale(trials, REFERENCE_TRIALS)
    checks = [Check("batch prior-mode forms = SequentialPairTest log-odds (both variants)",
                    f"max |difference| {recursive:.1e}", "≤ 1e-8", recursive <= 1e-8)]
    rows = table[(table["variant"] == "logdet") & (table["trials"] > 0)]
    worst_excess = -np.inf
    for row in rows.itertuples(index=False):
        allowed = max(BIN_TOLERANCE, 4.0 * row.se)
        worst_excess = max(worst_excess, abs(row.observed - row.mean_posterior) - allowed)
        checks.append(Check(f"with log-dets, bin [{row.bin_low:.1f}, {row.bin_high:.1f}): observed = mean posterior",
                            f"{row.observed:.4f} vs {row.mean_posterior:.4f} ({row.trials} trials)",
                            f"± {BIN_TOLERANCE} (or 4 SE = {4 * row.se:.3f})",
                            abs(row.observed - row.mean_posterior) <= allowed))
    checks.append(within(f"Brier score with log-dets (± {BRIER_LOGDET_TOLERANCE} × {s:.3g})", scores["logdet"],
                         BRIER_LOGDET, BRIER_LOGDET_TOLERANCE * s, digits=4))
    checks.append(within(f"Brier score, literal (≈ {BRIER_LITERAL}, ± {BRIER_LITERAL_TOLERANCE} × {s:.3g})",
                         scores["literal"], BRIER_LITERAL, BRIER_LITERAL_TOLERANCE * s, digits=4))
    middle = table[(table["variant"] == "literal") & (table["bin_low"] >= 0.1 - 1e-9)
                   & (table["trials"] > 0)]
    low, high = middle["observed"].min(), middle["observed"].max()
    slack = LITERAL_RANGE_TOLERANCE * s
    checks.append(Check("literal: observed frequency in the bins from 0.1 to 0.9 (far above the diagonal)",
                        f"{low:.3f}-{high:.3f}", f"{LITERAL_RANGE[0]}-{LITERAL_RANGE[1]} ± {slack:.3g}",
                        abs(low - LITERAL_RANGE[0]) <= slack and abs(high - LITERAL_RANGE[1]) <= slack))
    return checks


def plot_calibration(table: pd.DataFrame, samples: dict, scores: dict[str, float]):
    """(a) reliability diagram: observed frequency of "same" against the mean posterior per bin, both
    variants, with ±4 SE bars and the diagonal; (b) histogram of the posteriors."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(13.0, 5.2))
    colours = {"logdet": "tab:blue", "literal": "tab:red"}
    ax = axes[0]
    ax.plot([0, 1], [0, 1], color="grey", linestyle=":", label="perfect calibration")
    for variant, colour in colours.items():
        rows = table[(table["variant"] == variant) & (table["trials"] > 0)]
        ax.errorbar(rows["mean_posterior"], rows["observed"], yerr=4 * rows["se"], color=colour, marker="o",
                    capsize=3, label=f"{VARIANTS[variant]} (Brier {scores[variant]:.4f})")
    ax.set(xlabel="posterior P(same | reports), bin mean [probability]",
           ylabel="observed frequency of same object [probability]", title="(a) reliability, bins of width 0.1",
           xlim=(0, 1), ylim=(0, 1.02))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="lower right")
    ax = axes[1]
    for variant, colour in colours.items():
        ax.hist(samples[variant], bins=BINS, histtype="step", color=colour, linewidth=1.5, label=VARIANTS[variant])
    ax.set_yscale("log")
    ax.set(xlabel="posterior P(same | reports) [probability]", ylabel="trials per bin [count]",
           title="(b) distribution of the posterior")
    ax.legend(fontsize="small")
    fig.suptitle(f"E8: posterior calibration, TV-3 geometry, π = {PRIOR_SAME}, prior N(x₀, diag(100², 100², 20², 20²)), "
                 f"{len(samples['same']):,} trials")
    fig.tight_layout()
    return fig


def run_posterior_calibration(out_dir: Path, trials: int = DEFAULT_TRIALS, seed: int = 1,
                              progress: Progress = None) -> StudyOutput:
    """E8: the draws, the reliability table, the checks and the files."""
    samples, recursive = simulate(trials, seed, progress)
    table = reliability_table(samples)
    scores = {variant: brier(samples, variant) for variant in VARIANTS}
    checks = check_calibration(table, scores, recursive, trials)
    D = prior_forms()[1]
    results = {"brier": scores, "logdet_difference_D": D, "recursive_max_difference": recursive,
               "bins": table.to_dict(orient="records")}
    paths = finish(out_dir, NAME, table, plot_calibration(table, samples, scores), {"trials": trials, "seed": seed},
                   results, checks)
    return StudyOutput(table, checks, paths, results, {"samples": samples})

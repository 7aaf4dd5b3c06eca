"""Study E7 of spec 001 §6: process noise (gap G5, TV-5c, R8, R13 ``pair_init="fuse"``).

TV-5 scenario under θ = 1; the truth follows the CV model with white-noise acceleration of PSD
q (m²/s³) and every filter uses the same q.  For q ∈ {0, 1, 25, 100, 400}:

* **exact sequential statistic** Λ of (20a): the filters are linear with data-independent gains,
  so Λ = z^T A z (:mod:`~skytrack.studies.identification.scenario_tv5`); under θ = 1 it is
  Σ w_i χ²_1 with w_i the eigenvalues of L^T A L (C = L L^T the reports' covariance).  Its mean
  stays 4, its variance is 2 Σ w_i² and P(Λ ≤ χ²_4(0.99)) comes from Imhof's inversion (TV-5c);
* **pair_init = "fuse"** (R13): the pair's joint filter starts, when both tracks reach full rank
  (t = 1.3 s), from (24) applied to the two track states, with Λ₀ = d^T (P_η + P_ξ)^{-1} d; later
  reports add the joint increment minus the own filter's (:func:`fused_pair_statistics`, the
  identifier's rule with :class:`~skytrack.identify.kalman.FilterBank` rows, checked on TV-7);
* **track_states_test** (R8): literal (25) on the two final track states at t = 9.3 s.

The two approximations are quadratic forms too; their matrices come from the recursive filters by
polarisation (:func:`polarised_matrix`), so they get exact moments and coverage as well.  The
Monte Carlo draws ``trials`` truths and reports per q and evaluates the three forms; the first
:data:`RECURSIVE_RUNS` streams also run through the recursive filters, which must give the same
three values.  Expected: the exact values of TV-5c (E Λ = 4, var Λ and coverage to the table's
digits); the Monte Carlo within var ± 3 %, coverage ± 0.0015 (the spec's tolerances for 2e5 runs,
× √(2e5/N)); fuse and track-state statistics equal to Λ for q = 0 and drifting away as q grows.

:func:`run_process_noise` writes ``ident_process_noise.csv`` (one row per q and statistic), ``.png``
and ``..._summary.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from skytrack.identify.kalman import FilterBank
from skytrack.identify.model import cv_model
from skytrack.identify.single_shot import fuse_information, track_states_test
from skytrack.studies.identification import scenario_tv5 as tv5
from skytrack.studies.identification.common import pyplot
from skytrack.studies.identification.mc_common import (
    Check, Progress, StudyOutput, chunked, finish, tolerance_scale, within,
)

NAME = "ident_process_noise"
Q_VALUES = (0.0, 1.0, 25.0, 100.0, 400.0)
DEFAULT_TRIALS = 200_000
REFERENCE_TRIALS = 200_000
CHUNK = 50_000
RECURSIVE_RUNS = 500
RECURSIVE_TOLERANCE = 1e-6
STATISTICS = ("exact", "fuse", "track_states")
LABELS = {"exact": "sequential Λ (exact)", "fuse": 'pair_init="fuse"', "track_states": "track_states_test (25)"}


def fused_pair_statistics(z: np.ndarray, geometry: tv5.Geometry, q: float) -> dict[str, np.ndarray]:
    """Λ exact (SequentialPairTest), Λ of a pair made by (24) when both tracks reach rank n, and (25)
    on the final track states, for reports ``z`` ``[N, R, 2]`` (one row per trial)."""
    time, system, sigma = geometry.merged()
    model = cv_model(tv5.NDIM, q)
    from skytrack.identify.sequential import SequentialPairTest

    test = SequentialPairTest(model, len(z))
    pair = FilterBank(model, len(z))
    rows = np.arange(len(z))
    fused = np.zeros(len(z))
    made = False
    H = np.eye(tv5.NDIM, model.n)
    for k in range(len(time)):  # one step per report, all trials at once
        V = sigma[k] ** 2 * np.eye(tv5.NDIM)
        own = test.eta if system[k] == 1 else test.xi
        before = own.J.copy()
        test.add(int(system[k]), time[k], z[:, k], V)
        if made:
            pair.predict(rows, time[k])
            fused += pair.update(rows, z[:, k], V, H).quadratic - (own.J - before)
        elif test.eta.full.all() and test.xi.full.all():
            x_eta, P_eta = test.eta.estimate_at(rows, time[k])
            x_xi, P_xi = test.xi.estimate_at(rows, time[k])
            x, _, P = fuse_information(x_eta, P_eta, x_xi, P_xi)
            pair.t[:], pair.x[:], pair.P[:] = time[k], x, P
            pair.full[:], pair.rank[:] = True, model.n
            fused = track_states_test(x_eta, P_eta, x_xi, P_xi)
            made = True
    end = np.full(len(z), time[-1])
    x_eta, P_eta = test.eta.estimate_at(rows, end)
    x_xi, P_xi = test.xi.estimate_at(rows, end)
    return {"exact": test.statistic, "fuse": fused, "track_states": track_states_test(x_eta, P_eta, x_xi, P_xi)}


def polarised_matrix(evaluate, reports: int) -> dict[str, np.ndarray]:
    """Per-axis matrices B of quadratic statistics s(z) = Σ_axes z_a^T B z_a, from s on e_i and e_i + e_j."""
    i, j = np.triu_indices(reports, 1)
    basis = np.zeros((reports + len(i), reports, tv5.NDIM))
    basis[np.arange(reports), np.arange(reports), 0] = 1.0
    basis[reports + np.arange(len(i)), i, 0] = 1.0
    basis[reports + np.arange(len(i)), j, 0] = 1.0
    values = evaluate(basis)
    out = {}
    for key, value in values.items():
        diagonal = value[:reports]
        B = np.diag(diagonal)
        B[i, j] = B[j, i] = 0.5 * (value[reports:] - diagonal[i] - diagonal[j])
        out[key] = B
    return out


def statistic_matrices(q: float, geometry: tv5.Geometry = tv5.TV5_GEOMETRY) -> dict[str, np.ndarray]:
    """The per-axis matrices of the exact, fuse and track-state statistics for process noise ``q``."""
    return polarised_matrix(lambda z: fused_pair_statistics(z, geometry, q), geometry.reports)


def exact_table(matrices: dict[float, dict[str, np.ndarray]], geometry: tv5.Geometry = tv5.TV5_GEOMETRY) -> pd.DataFrame:
    """Mean, variance and P(s ≤ χ²_4(0.99)) of each statistic under θ = 1, from the eigenvalues."""
    time, _, sigma = geometry.merged()
    rows = []
    for q, by_statistic in matrices.items():
        C = tv5.integrated_noise_covariance(time, time, q, float(time.min())) + np.diag(sigma ** 2)
        L = np.linalg.cholesky(C)
        for statistic, B in by_statistic.items():
            w = np.linalg.eigvalsh(L.T @ B @ L)
            w = np.repeat(w[np.abs(w) > 1e-10 * np.abs(w).max()], tv5.NDIM)
            mean, var = tv5.exact_moments(w)
            rows.append({"q": q, "statistic": statistic, "exact_mean": mean, "exact_var": var,
                         "exact_p_le_h99": tv5.imhof_cdf(tv5.H_99, w), "weights": len(w)})
    return pd.DataFrame(rows)


def simulate(matrices, trials: int, seed: int, progress: Progress = None) -> tuple[dict, dict]:
    """The three statistics per trial and q (q index i draws from ``SeedSequence(seed).spawn(n)[i]``), and
    the largest |quadratic form − recursive filters| over the first :data:`RECURSIVE_RUNS` trials."""
    chunks = chunked(trials, CHUNK)
    total, done = len(matrices) * len(chunks), 0
    samples, recursive = {}, {}
    for (q, by_statistic), child in zip(matrices.items(), np.random.SeedSequence(seed).spawn(len(matrices))):
        rng = np.random.default_rng(child)
        parts = []
        for c, size in enumerate(chunks):
            z = tv5.draw_reports(rng, size, tv5.TV5_GEOMETRY, q=q)
            values = {key: np.einsum("nra,rs,nsa->n", z, B, z, optimize=True) for key, B in by_statistic.items()}
            if c == 0:
                runs = min(RECURSIVE_RUNS, size)
                filtered = fused_pair_statistics(z[:runs], tv5.TV5_GEOMETRY, q)
                recursive[q] = max(float(np.max(np.abs(filtered[key] - values[key][:runs]))) for key in filtered)
            parts.append(values)
            done += 1
            if progress is not None:
                progress(done, total)
        samples[q] = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return samples, recursive


def study_table(exact: pd.DataFrame, samples) -> pd.DataFrame:
    """The exact rows with this run's mean, variance, coverage and the RMS difference to the exact Λ."""
    table = exact.copy()
    for column in ("mean", "var", "p_le_h99", "rms_difference", "max_difference"):
        table[column] = np.nan
    for index, row in table.iterrows():
        values = samples[row.q][row.statistic]
        difference = values - samples[row.q]["exact"]
        table.loc[index, ["trials", "mean", "var", "p_le_h99", "rms_difference", "max_difference"]] = (
            len(values), values.mean(), values.var(ddof=1), np.mean(values <= tv5.H_99),
            np.sqrt(np.mean(difference ** 2)), np.max(np.abs(difference)))
    table["trials"] = table["trials"].astype(int)
    return table


def check_process_noise(table: pd.DataFrame, recursive: dict[float, float]) -> list[Check]:
    """TV-5c exact values, the Monte Carlo within the spec's (scaled) tolerances, fuse and (25) vs exact."""
    checks = []
    exact = table[table["statistic"] == "exact"]
    s = tolerance_scale(int(table["trials"].iloc[0]), REFERENCE_TRIALS)
    for row in exact.itertuples(index=False):
        mean, var, probability = tv5.TV5C.get(row.q, (None, None, None))
        if mean is not None:
            checks += [within(f"TV-5c q = {row.q:g}: E Λ (eigenvalues)", row.exact_mean, mean, 1e-9),
                       within(f"TV-5c q = {row.q:g}: var Λ (eigenvalues)", row.exact_var, var, 5e-7),
                       within(f"TV-5c q = {row.q:g}: P(Λ ≤ χ²_4(0.99)) (Imhof)", row.exact_p_le_h99, probability, 5e-7)]
        checks += [within(f"q = {row.q:g}: Monte Carlo var Λ (± 3 % × {s:.3g})", row.var, row.exact_var,
                          0.03 * s, relative=True),
                   within(f"q = {row.q:g}: Monte Carlo P(Λ ≤ h) (± 0.0015 × {s:.3g})", row.p_le_h99,
                          row.exact_p_le_h99, 0.0015 * s)]
    worst = max(recursive.values())
    checks.append(Check("quadratic forms = recursive filters (exact, fuse, (25)), every q",
                        f"max |difference| {worst:.1e}", f"≤ {RECURSIVE_TOLERANCE:g}", worst <= RECURSIVE_TOLERANCE))
    for statistic in ("fuse", "track_states"):
        rows = table[table["statistic"] == statistic].sort_values("q")
        zero = rows[rows["q"] == 0.0]
        if len(zero):
            checks.append(Check(f"{LABELS[statistic]} = Λ at q = 0", f"max |difference| {zero['max_difference'].iloc[0]:.1e}",
                                "≤ 1e-6", zero["max_difference"].iloc[0] <= 1e-6))
        positive = rows[rows["q"] > 0]["rms_difference"].to_numpy()
        checks.append(Check(f"{LABELS[statistic]}: RMS difference to Λ grows with q",
                            ", ".join(f"{v:.3g}" for v in rows["rms_difference"]), "increasing in q",
                            len(positive) < 2 or bool(np.all(np.diff(positive) > 0))))
    return checks


def plot_process_noise(table: pd.DataFrame):
    """(a) var of each statistic against q (exact lines, Monte Carlo markers) with TV-5c; (b) coverage
    of h = χ²_4(0.99); (c) RMS difference of the approximations to the exact Λ."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16.0, 5.0))
    colours = {"exact": "tab:blue", "fuse": "tab:orange", "track_states": "tab:green"}
    qs = np.array(sorted(table["q"].unique()))
    x = np.where(qs > 0, qs, 0.3)  # q = 0 drawn at 0.3 on the log axis
    for statistic, colour in colours.items():
        rows = table[table["statistic"] == statistic].sort_values("q")
        axes[0].plot(x, rows["exact_var"], color=colour, marker="o", label=f"{LABELS[statistic]}: exact")
        axes[0].plot(x, rows["var"], color=colour, linestyle="none", marker="x", markersize=9,
                     label=f"{LABELS[statistic]}: Monte Carlo")
        axes[1].plot(x, rows["exact_p_le_h99"], color=colour, marker="o", label=f"{LABELS[statistic]}: exact")
        axes[1].plot(x, rows["p_le_h99"], color=colour, linestyle="none", marker="x", markersize=9,
                     label=f"{LABELS[statistic]}: Monte Carlo")
        if statistic != "exact":
            axes[2].plot(x, rows["rms_difference"], color=colour, marker="o", label=LABELS[statistic])
    spec_q = [q for q in qs if q in tv5.TV5C]
    spec_x = [q if q > 0 else 0.3 for q in spec_q]
    axes[0].plot(spec_x, [tv5.TV5C[q][1] for q in spec_q], linestyle="none", marker="*", markersize=12,
                 color="black", label="TV-5c var Λ")
    axes[1].plot(spec_x, [tv5.TV5C[q][2] for q in spec_q], linestyle="none", marker="*", markersize=12,
                 color="black", label="TV-5c coverage")
    axes[0].axhline(8.0, color="grey", linestyle=":", label="χ²(4): var 8")
    axes[1].axhline(0.99, color="grey", linestyle=":", label="nominal 0.99")
    axes[0].set(ylabel="variance of the statistic [dimensionless]", title="(a) variance (mean stays 4 for Λ)")
    axes[1].set(ylabel="P(statistic ≤ χ²₄(0.99)) [probability]", title="(b) coverage of h = 13.2767 under θ = 1")
    axes[2].set(ylabel="RMS(approximation − Λ) [dimensionless]", title="(c) distance to the exact statistic")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("process-noise PSD q [m²/s³] (q = 0 drawn at 0.3)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.suptitle("E7: process noise on TV-5, θ = 1 (truth and filters share q)")
    fig.tight_layout()
    return fig


def run_process_noise(out_dir: Path, trials: int = DEFAULT_TRIALS, seed: int = 1, q_values=Q_VALUES,
                      progress: Progress = None) -> StudyOutput:
    """E7: exact distributions, the Monte Carlo, the checks and the files."""
    matrices = {float(q): statistic_matrices(float(q)) for q in q_values}
    samples, recursive = simulate(matrices, trials, seed, progress)
    table = study_table(exact_table(matrices), samples)
    checks = check_process_noise(table, recursive)
    results = {"rows": table.to_dict(orient="records"), "recursive_max_difference": recursive,
               "chi2_4_coverage": float(stats.chi2.cdf(tv5.H_99, tv5.DOF))}
    paths = finish(out_dir, NAME, table, plot_process_noise(table), {"trials": trials, "seed": seed,
                                                                      "q_values": list(q_values)}, results, checks)
    return StudyOutput(table, checks, paths, results, {"samples": samples})

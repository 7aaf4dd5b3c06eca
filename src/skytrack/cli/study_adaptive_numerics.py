"""``skytrack study gain-conditioning / poor-experiment / vw-estimator``: spec 002 §6 E5, E6, E7.

* ``gain-conditioning`` — E5, conditioning of gain (6) and of the covariance update (R11 A7, A8),
  :mod:`skytrack.studies.adaptive_numerics.gain_conditioning`;
* ``poor-experiment`` — E6, the poorly-planned-experiment diagnostic (R16) on TV12(b)'s remedies,
  :mod:`skytrack.studies.adaptive_numerics.poor_experiment`;
* ``vw-estimator`` — E7, the V_w estimator (R12, R13 weighting) on TV11(c, d) over λ and both
  weightings, :mod:`skytrack.studies.adaptive_numerics.vw_estimator`.

Every command takes ``--out`` (CSV + PNG + JSON summary), ``--seed``, ``--trials`` and ``--check`` (exit 1
when an expected value of the spec fails), prints its table and the spec's expected values with
PASS/FAIL.  Only typer and rich are imported at module level; the studies load when a command runs.
Add the commands to a typer app with :func:`register_adaptive_numerics_studies`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

console = Console()
error_console = Console(stderr=True)

OutOption = Annotated[Path, typer.Option("--out", "-o", help="Output folder (CSV, PNG, JSON summary).")]
CheckOption = Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]
NoRandomSeed = Annotated[int, typer.Option("--seed", help="Accepted like every study's; this study draws no random "
                                           "numbers.")]
NoRandomTrials = Annotated[int, typer.Option("--trials", help="Accepted like every study's; this study is "
                                             "deterministic (one run).")]


def _print(table: Table) -> None:
    from skytrack.cli.study_output import print_wide

    print_wide(console, table)


def _fail(message: str) -> None:
    from skytrack.cli.study_verdicts import fail_option

    fail_option(error_console, message)


def _check_deterministic(trials: int) -> None:
    """``--trials`` of a deterministic study: accepted for a uniform command line, but not below 1."""
    if trials < 1:
        _fail(f"--trials must be >= 1, got {trials}")


def _finish(name: str, checks, paths, check: bool) -> None:
    """Print the expected values with PASS/FAIL and the written files; exit 1 under ``--check`` on a failure."""
    from skytrack.cli.study_verdicts import report_failures, verdicts_table

    if checks:
        _print(verdicts_table(f"{name}: expected values (spec 002 §5, §6)", checks,
                              ("expected value", "measured", "spec (tolerance)", "verdict")))
    else:
        console.print("[yellow]no expected values checked (the spec's values hold for its run lengths)[/yellow]")
    console.print("wrote " + ", ".join(str(p) for p in paths))
    report_failures(console, checks, check, all_held=f"all {len(checks)} expected values PASS")


def gain_conditioning(
    out: OutOption = Path("study-gain-conditioning"),
    seed: NoRandomSeed = 1,
    trials: NoRandomTrials = 1,
    check: CheckOption = False,
) -> None:
    """E5: cond of hV_xhᵀ + V_η, gain errors (explicit / Cholesky) and short vs Joseph update, ρ = 10⁰ … 10¹⁴."""
    from skytrack.studies.adaptive_numerics import gain_conditioning as study

    _check_deterministic(trials)
    table, checks, paths = study.run_gain_conditioning(out)
    summary = Table(title="gain-conditioning: V_x = R diag(ρ, 1) Rᵀ, h = [[1, 0.4], [0.2, 1]], V_η = diag(1, 0.5); "
                          "errors against exact rational arithmetic")
    columns = ("ρ", "cond", "cond/ρ", "Γ err explicit", "Γ err Cholesky", "short (explicit Γ) asym",
               "short (explicit Γ) λ_min", "short (Cholesky Γ) λ_min", "Joseph (Cholesky Γ) rel err",
               "Joseph (explicit Γ) rel err", "Joseph λ_min")
    for column in columns:
        summary.add_column(column, justify="right")
    for row in table.itertuples(index=False):
        summary.add_row(f"{row.rho:.0e}", f"{row.cond:.3e}", f"{row.cond_over_rho:.4f}", f"{row.gain_error_explicit:.2e}",
                        f"{row.gain_error_cholesky:.2e}", f"{row.short_explicit_asymmetry:.2e}",
                        f"{row.short_explicit_lambda_min:.3g}", f"{row.short_cholesky_lambda_min:.3g}",
                        f"{row.joseph_cholesky_error:.2e}", f"{row.joseph_explicit_error:.2e}",
                        f"{min(row.joseph_cholesky_lambda_min, row.joseph_explicit_lambda_min):.3g}")
    _print(summary)
    console.print("Round-off figures are checked to their order of magnitude: within a factor "
                  f"{study.ROUNDOFF_FACTOR:g} of the spec's value.")
    _finish("gain-conditioning", checks, paths, check)


def poor_experiment(
    out: OutOption = Path("study-poor-experiment"),
    seed: NoRandomSeed = 1,
    trials: NoRandomTrials = 1,
    check: CheckOption = False,
) -> None:
    """E6: TV12(b) — the R16 diagnostic and its advice for V0 (baseline) and the remedies V1-V3, both modes."""
    from skytrack.studies.adaptive_numerics import poor_experiment as study

    _check_deterministic(trials)
    table, checks, paths = study.run_poor_experiment(out)
    summary = Table(title="poor-experiment: TV12(b), 100 steps, T = 1 s (matched and literal mode of R16)")
    for column in ("variant", "diag P(100|100)", "literal ratio", "matched: verdict (flagged)",
                   "literal: verdict (flagged)", "R5 on S"):
        summary.add_column(column, overflow="fold")
    for row in table.itertuples(index=False):
        r5 = row.r5_verdict + (f", D = {{{row.indistinguishable}}}" if row.indistinguishable else "")
        summary.add_row(f"{row.variant} {row.description}", row.diag_P_final, f"{row.literal_ratio_final:.6g}",
                        f"{row.matched_verdict} ({row.matched_flagged_fraction:.2f})",
                        f"{row.literal_verdict} ({row.literal_flagged_fraction:.2f})", r5)
    _print(summary)
    for row in table.itertuples(index=False):
        for mode in study.MODES:
            advice = getattr(row, f"{mode}_advice") or "no advice: the experiment is not poorly planned."
            console.print(f"[bold]{row.variant} ({mode})[/bold]: {escape(advice)}", soft_wrap=True)
    _finish("poor-experiment", checks, paths, check)


def vw_estimator(
    out: OutOption = Path("study-vw-estimator"),
    seed: Annotated[int, typer.Option("--seed", help="Part (c) draws with default_rng((seed, ord('c'))), (d) with "
                                      "default_rng((seed, ord('d'))); every λ and weighting sees the same draws.")] = 1,
    trials: Annotated[int, typer.Option("--trials", help="Seeds (tracks of one bank) per configuration; TV11 asks "
                                        "≥ 20.")] = 20,
    steps_c: Annotated[int, typer.Option("--steps-c", help="Measurements of part (c) (TV11: 20 001).")] = 20_001,
    steps_d: Annotated[int, typer.Option("--steps-d", help="Measurements of part (d) (TV11: 10 001); the switch is "
                                         "at (steps − 1) // 2.")] = 10_001,
    check: CheckOption = False,
) -> None:
    """E7: V̂_w of R12 over λ ∈ {0.9, 0.99, 0.999, 1} and both weightings on TV11(c) (constant) and (d) (switch)."""
    from skytrack.cli.study_output import run_with_progress
    from skytrack.studies.adaptive_numerics import vw_estimator as study

    if trials < 2:
        _fail(f"--trials must be at least 2 (a spread across seeds), got {trials}")
    if seed < 0:
        _fail(f"--seed must be >= 0 (numpy seeds are non-negative), got {seed}")
    if steps_c < 2 or steps_d < 11:
        _fail("--steps-c must be at least 2 and --steps-d at least 11")
    table, checks, paths = run_with_progress(
        error_console, "vw-estimator", lambda progress: study.run_vw_estimator(
            out, trials=trials, seed=seed, steps_c=steps_c, steps_d=steps_d, progress=progress))
    summary = Table(title=f"vw-estimator: final V̂_w / V_w ({trials} seeds, seed {seed}); (c) V_w = 0.25, "
                          "(d) V_w = 0.01 → 1")
    console.print("(c): the raw memory V̄ after the last step (A5.4, may be negative); (d): the seed mean of "
                  "the output V̂_w over a window after and before the switch.")
    for column in ("part", "λ", "weighting", "(c) final V̄ / (d) V̂_w after", "seed sd", "min … max", "/ V_w",
                   "(d) V̂_w before", "/ 0.01", "TV11 expectation"):
        summary.add_column(column, justify="right")
    expectations = {("c", 1.0, "innovation"): "every seed in [0.22, 0.28], mean in [0.24, 0.26]",
                    ("c", 1.0, "none"): "sd ≥ 10 × innovation's",
                    ("d", 0.999, "innovation"): "before [0.008, 0.02], after [0.93, 1.05]",
                    ("d", 0.99, "innovation"): "before ≈ 0.027"}
    for row in table.itertuples(index=False):
        expected = expectations.get((row.part, row.forgetting, row.weighting), "–")
        if row.part == "c":
            summary.add_row("c", f"{row.forgetting:g}", row.weighting, f"{row.final_mean:.4f}", f"{row.final_sd:.4f}",
                            f"{row.final_min:.3f} … {row.final_max:.3f}", f"{row.ratio:.3f}", "–", "–", expected)
        else:
            summary.add_row("d", f"{row.forgetting:g}", row.weighting, f"{row.after_mean:.4f} {row.window_after}", "–",
                            "–", f"{row.ratio:.3f}", f"{row.before_mean:.4f} {row.window_before}",
                            f"{row.before_ratio:.2f}", expected)
    _print(summary)
    _finish("vw-estimator", checks, paths, check)


def register_adaptive_numerics_studies(app: typer.Typer) -> None:
    """Add the spec 002 §6 studies E5-E7 to the ``skytrack study`` sub-app."""
    app.command("gain-conditioning")(gain_conditioning)
    app.command("poor-experiment")(poor_experiment)
    app.command("vw-estimator")(vw_estimator)

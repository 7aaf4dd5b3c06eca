"""``skytrack study ident-sequential-mc / -quadratic-forms / -process-noise / -posterior-calibration /
-many-to-many``: the Monte Carlo studies E5-E9 of spec 001 §6 (R16).

* ``ident-sequential-mc`` — E5 / R16: Λ on TV-5 under θ = 1 and the TV-5b offsets against χ²(4) and
  ncχ²(4, λ), TV-5a/b values (:mod:`skytrack.studies.identification.sequential_mc`);
* ``ident-quadratic-forms`` — E6: four quadratic forms against two, ROCs for +100 m and +10 m/s
  (:mod:`skytrack.studies.identification.quadratic_forms`);
* ``ident-process-noise`` — E7: q sweep, exact (eigenvalues, Imhof) and Monte Carlo variance and
  coverage, ``pair_init="fuse"`` and ``track_states_test`` against the exact statistic (TV-5c)
  (:mod:`skytrack.studies.identification.process_noise`);
* ``ident-posterior-calibration`` — E8: reliability of P(same) with and without the log-dets (G1)
  (:mod:`skytrack.studies.identification.posterior_calibration`);
* ``ident-many-to-many`` — E9: 30 radar vs 20 ADS-B tracks, global vs greedy assignment
  (:mod:`skytrack.studies.identification.many_to_many`).

Every command takes ``--out``, ``--seed``, ``--trials`` and ``--check``; it writes a CSV, a PNG and a
JSON summary, shows a progress bar, prints a summary table and the spec's expected values with
their verdicts.  With ``--check`` a failed expectation exits with code 1; a bad option exits with
code 2.  Only typer and rich are imported at module level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from skytrack.cli.study_output import print_wide, run_with_progress

console = Console()
error_console = Console(stderr=True)

OutOption = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
SeedOption = Annotated[int, typer.Option("--seed", help="Random seed (numpy SeedSequence).")]
CheckOption = Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _check_trials(trials: int, minimum: int = 2) -> None:
    if trials < minimum:
        _fail(f"--trials must be >= {minimum}, got {trials}")


def _print_wide(table: Table) -> None:
    print_wide(console, table)


def _run_with_progress(label: str, run):
    return run_with_progress(error_console, label, run, "steps")


def _summary(title: str, headers, rows) -> None:
    table = Table(title=escape(title))
    for header in headers:
        table.add_column(escape(header), justify="right")
    for row in rows:
        table.add_row(*(escape(str(cell)) for cell in row))
    _print_wide(table)


def _finish(name: str, output, check: bool) -> None:
    """Print the verdicts and the written files; exit 1 under ``--check`` when one failed."""
    table = Table(title=escape(f"{name}: expected values (spec 001 §5 TV-5, §6)"))
    for column in ("expected value", "measured", "spec", "verdict"):
        table.add_column(column, overflow="fold")
    for c in output.checks:
        table.add_row(escape(c.name), escape(c.measured), escape(c.expected),
                      "[green]pass[/green]" if c.passed else "[red]FAIL[/red]")
    _print_wide(table)
    console.print("wrote " + ", ".join(str(p) for p in output.paths))
    failed = [c.name for c in output.checks if not c.passed]
    if failed:
        console.print(f"[red]{len(failed)} expected value(s) failed: {escape(', '.join(failed))}[/red]")
        if check:
            raise typer.Exit(code=1)


def _g(value, digits: int = 6) -> str:
    if value is None or value != value:
        return "–"
    return f"{value:.{digits}g}"


# --------------------------------------------------------------------------- E5


def ident_sequential_mc(
    out: OutOption = Path("study-ident-sequential-mc"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Report streams per case (θ = 1 and 7 offsets).")] = 100_000,
    check: CheckOption = False,
) -> None:
    """E5 / R16: the sequential test on TV-5 against χ²(4) and ncχ²(4, λ) (spec 001 §6)."""
    from skytrack.studies.identification import sequential_mc as study

    _check_trials(trials)
    output = _run_with_progress("ident-sequential-mc", lambda p: study.run_sequential_mc(out, trials, seed, p))
    rows = [(row.case, _g(row.noncentrality, 8), _g(row.mean, 5), _g(row.exact_mean, 5), _g(row.var, 5),
             _g(row.exact_var, 5), _g(row.p_le_h99), _g(row.exact_p_le_h99, 7), _g(row.p_le_np_h, 4),
             _g(row.ks_pvalue, 3), _g(row.joint_p_le_h99), _g(row.exact_joint_p_le_h99, 7))
            for row in output.table.itertuples(index=False)]
    _summary(f"ident-sequential-mc: Λ on TV-5, {trials:,} runs per case, seed {seed} (h = 13.276704)",
             ("case", "λ", "mean Λ", "4 + λ", "var Λ", "2(4 + 2λ)", "P(Λ ≤ h)", "exact", "P(Λ ≤ NP h)",
              "KS p", "P(J ≤ 58.62)", "exact"), rows)
    _finish("ident-sequential-mc", output, check)


# --------------------------------------------------------------------------- E6


def ident_quadratic_forms(
    out: OutOption = Path("study-ident-quadratic-forms"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Report streams per case (θ = 1, +100 m, +10 m/s).")] = 200_000,
    check: CheckOption = False,
) -> None:
    """E6: four quadratic forms (Λ) against two (joint filter only, R15) on TV-5 (spec 001 §6)."""
    from skytrack.studies.identification import quadratic_forms as study

    _check_trials(trials)
    output = _run_with_progress("ident-quadratic-forms", lambda p: study.run_quadratic_forms(out, trials, seed, p))
    rows = [(row.case, row.statistic, row.dof, _g(row.exact_p_incorrect), _g(row.mc_p_incorrect),
             _g(row.spec_p_incorrect), _g(row.exact_p_correct_at_np), _g(row.mc_p_correct_at_np),
             _g(row.spec_p_correct_at_np)) for row in output.table.itertuples(index=False)]
    _summary(f"ident-quadratic-forms: operating points, {trials:,} runs per case, seed {seed}",
             ("offset", "statistic", "dof", "P_НО at P_ПО=0.99", "Monte Carlo", "spec", "P_ПО at P_НО=0.01",
              "Monte Carlo", "spec"), rows)
    _finish("ident-quadratic-forms", output, check)


# --------------------------------------------------------------------------- E7


def ident_process_noise(
    out: OutOption = Path("study-ident-process-noise"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Report streams per q.")] = 200_000,
    q: Annotated[str, typer.Option("--q", help="Process-noise PSDs q [m²/s³], comma-separated.")] = "0,1,25,100,400",
    check: CheckOption = False,
) -> None:
    """E7: process noise, exact (Imhof) and Monte Carlo var Λ and coverage; fuse and (25) vs exact (TV-5c)."""
    from skytrack.studies.identification import process_noise as study

    _check_trials(trials)
    try:
        q_values = tuple(float(v) for v in q.split(",") if v.strip())
    except ValueError:
        _fail(f"--q expects comma-separated numbers, got {q!r}")
    if not q_values or any(not v >= 0 for v in q_values):
        _fail(f"--q needs values >= 0, got {q!r}")
    output = _run_with_progress("ident-process-noise",
                                lambda p: study.run_process_noise(out, trials, seed, q_values, p))
    rows = [(f"{row.q:g}", study.LABELS[row.statistic], _g(row.exact_mean, 6), _g(row.mean, 5), _g(row.exact_var, 7),
             _g(row.var, 5), _g(row.exact_p_le_h99, 6), _g(row.p_le_h99, 6), _g(row.rms_difference, 3))
            for row in output.table.itertuples(index=False)]
    _summary(f"ident-process-noise: θ = 1 on TV-5, {trials:,} runs per q, seed {seed}",
             ("q [m²/s³]", "statistic", "E (exact)", "mean", "var (exact)", "var", "P(≤ 13.2767) exact",
              "Monte Carlo", "RMS vs Λ"), rows)
    _finish("ident-process-noise", output, check)


# --------------------------------------------------------------------------- E8


def ident_posterior_calibration(
    out: OutOption = Path("study-ident-posterior-calibration"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Trials (one object with probability 0.5).")] = 200_000,
    check: CheckOption = False,
) -> None:
    """E8: calibration of P(same) with the log-determinants (R6) and literal (14a) (gap G1)."""
    from skytrack.studies.identification import posterior_calibration as study

    _check_trials(trials)
    output = _run_with_progress("ident-posterior-calibration",
                                lambda p: study.run_posterior_calibration(out, trials, seed, p))
    table = output.table
    rows = []
    for low in sorted(table["bin_low"].unique()):
        cells = [f"[{low:.1f}, {low + 0.1:.1f})"]
        for variant in study.VARIANTS:
            row = table[(table["variant"] == variant) & (table["bin_low"] == low)].iloc[0]
            cells += [str(row.trials), _g(row.mean_posterior, 4), _g(row.observed, 4)]
        rows.append(cells)
    brier = output.results["brier"]
    _summary(f"ident-posterior-calibration: TV-3 geometry, {trials:,} trials, seed {seed}; Brier with log-dets "
             f"{brier['logdet']:.5f}, literal {brier['literal']:.5f}",
             ("bin", "trials", "mean P (log-dets)", "observed", "trials", "mean P (literal)", "observed"), rows)
    _finish("ident-posterior-calibration", output, check)


# --------------------------------------------------------------------------- E9


def ident_many_to_many(
    out: OutOption = Path("study-ident-many-to-many"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Scenes (30 objects, 20 with ADS-B) per square side.")] = 300,
    sides: Annotated[str, typer.Option("--sides", help="Square sides L [m], comma-separated.")] = "2000,1000,500",
    replay: Annotated[bool, typer.Option("--replay/--no-replay",
                                         help="Also run pair_init='replay' and compare it with 'fuse'.")] = True,
    check: CheckOption = False,
) -> None:
    """E9: many-to-many identification with TrackIdentifier, global vs greedy assignment (spec 001 §6)."""
    from skytrack.studies.identification import many_to_many as study

    _check_trials(trials)
    try:
        side_values = tuple(float(v) for v in sides.split(",") if v.strip())
    except ValueError:
        _fail(f"--sides expects comma-separated numbers, got {sides!r}")
    if not side_values or any(not v > 0 for v in side_values):
        _fail(f"--sides needs values > 0, got {sides!r}")
    output = _run_with_progress("ident-many-to-many",
                                lambda p: study.run_many_to_many(out, trials, seed, side_values, replay, p))
    rows = [(f"{row.side_m:g}", row.pair_init, row.solver, f"{row.correct:.4f} ± {row.correct_se:.4f}",
             f"{row.wrong:.4f} ± {row.wrong_se:.4f}", f"{row.missed:.4f} ± {row.missed_se:.4f}")
            for row in output.table.itertuples(index=False)]
    _summary(f"ident-many-to-many: fractions per ADS-B track (± SE), {trials} scenes per L, seed {seed}",
             ("L [m]", "pair_init", "solver", "correct", "wrong", "missed"), rows)
    _finish("ident-many-to-many", output, check)


def register_mc_studies(app: typer.Typer) -> None:
    """Add the spec 001 Monte Carlo studies E5-E9 to the ``skytrack study`` sub-app."""
    app.command("ident-sequential-mc")(ident_sequential_mc)
    app.command("ident-quadratic-forms")(ident_quadratic_forms)
    app.command("ident-process-noise")(ident_process_noise)
    app.command("ident-posterior-calibration")(ident_posterior_calibration)
    app.command("ident-many-to-many")(ident_many_to_many)

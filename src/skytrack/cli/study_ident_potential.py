"""``skytrack study ident-potential / ident-np-design / ident-elliptic``: spec 001 §6 E1-E4.

* ``ident-potential --dim 2|3`` — E1 / E2, the paper's Figs. 1 and 2: P_ПО, P_НО(A) and P̄_НО
  against r with an ROC panel, TV-1 values and a Monte Carlo confirmation
  (:mod:`skytrack.studies.identification.potential_study`);
* ``ident-np-design`` — E3, the Neyman-Pearson trade-off P_ПО(alpha) for A = 2..6 and for the
  uniform-separation average (:mod:`skytrack.studies.identification.np_design`);
* ``ident-elliptic`` — E4, the elliptical-scattering claim (G10): Monte Carlo (2e6 draws by default)
  and quadrature against the circular formulas (:mod:`skytrack.studies.identification.elliptic`).

Every command takes ``--out``, ``--seed``, ``--trials`` and ``--check``; it writes a CSV, a PNG and a
JSON summary, shows a progress bar for the Monte Carlo draws, prints a summary table and the spec's
expected values with their verdicts.  With ``--check`` a failed expectation exits with code 1; a
bad option exits with code 2.  Only typer and rich are imported at module level.
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
SeedOption = Annotated[int, typer.Option("--seed", help="Seed; chunk c draws with SeedSequence(seed).spawn(chunks)[c].")]
CheckOption = Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _checks_table(checks, title: str) -> Table:
    table = Table(title=escape(title))
    for column in ("expected value", "measured", "spec", "verdict"):
        table.add_column(column, overflow="fold")
    for check in checks:
        table.add_row(escape(check.name), escape(check.measured), escape(check.expected),
                      "[green]pass[/green]" if check.passed else "[red]FAIL[/red]")
    return table


def _finish(name: str, checks, paths: dict, check: bool) -> None:
    """Print the verdicts and the written files; exit 1 under ``--check`` when one failed."""
    console.print(_checks_table(checks, f"{name}: expected values (spec 001 §5 TV-1, §6)"))
    console.print("wrote " + ", ".join(str(p) for p in paths.values()))
    failed = [c.name for c in checks if not c.passed]
    if failed:
        console.print(f"[red]{len(failed)} expected value(s) failed: {escape(', '.join(failed))}[/red]")
        if check:
            raise typer.Exit(code=1)


def _print_wide(table: Table) -> None:
    print_wide(console, table)


def _run_with_progress(label: str, run):
    return run_with_progress(error_console, f"{label} Monte Carlo", run, "chunks")


def _check_trials(trials: int) -> None:
    if trials < 1:
        _fail(f"--trials must be >= 1, got {trials}")


# --------------------------------------------------------------------------- E1 / E2


def ident_potential(
    dim: Annotated[int, typer.Option("--dim", help="2 (E1, the paper's Fig. 1) or 3 (E2, Fig. 2).")] = 2,
    out: OutOption = Path("study-ident-potential"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo draws per hypothesis.")] = 1_000_000,
    check: CheckOption = False,
) -> None:
    """E1/E2: P_ПО, P_НО(A), P̄_НО against r = h/σ, and the ROC (spec 001 §6)."""
    from skytrack.studies.identification import potential_study as study

    if dim not in (2, 3):
        _fail(f"--dim must be 2 or 3 (the paper's two figures), got {dim}")
    _check_trials(trials)
    result = _run_with_progress("ident-potential", lambda progress: study.run_potential(out, dim, trials, seed, progress))
    curves = result["curves"]
    summary = Table(title=f"ident-potential: {dim}-D potential characteristics (σ = {study.SIGMA_M:g} m)")
    columns = ["p_correct"] + [study.column_name(a) for a in study.A_VALUES] + ["p_incorrect_mean"]
    headers = ["r", "P_ПО"] + [f"P_НО(A={a:g})" for a in study.A_VALUES] + ["P̄_НО(Δ∈[100, 600] m)"]
    for header in headers:
        summary.add_column(escape(header), justify="right")
    for r in study.TV1_R:
        row = curves[(curves["r"] - r).abs() < 1e-12].iloc[0]
        summary.add_row(f"{r:g}", *(f"{row[c]:.7g}" for c in columns))
    _print_wide(summary)
    for d, design in sorted(result["designs"].items()):
        console.print(f"NP design {d}-D, A = {study.NP_A:g}, α = {study.NP_ALPHA:g}: r = {design.r:.8f}, "
                      f"P_ПО = {design.p_correct:.8f}")
    _finish(f"ident-potential --dim {dim}", result["checks"], result["paths"], check)


# --------------------------------------------------------------------------- E3


def ident_np_design(
    dim: Annotated[int, typer.Option("--dim", help="Number of compared coordinates (2 as in the spec's E3).")] = 2,
    out: OutOption = Path("study-ident-np-design"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo draws at the α = 0.01 and 0.05 designs.")] = 400_000,
    alpha_points: Annotated[int, typer.Option("--alpha-points", help="Points of the log grid α ∈ [1e-4, 0.2].")] = 61,
    check: CheckOption = False,
) -> None:
    """E3: Neyman–Pearson design, P_ПО against the allowed P_НО = α (spec 001 §6)."""
    import numpy as np

    from skytrack.studies.identification import np_design as study

    if dim < 1:
        _fail(f"--dim must be >= 1, got {dim}")
    if alpha_points < 2:
        _fail(f"--alpha-points must be >= 2, got {alpha_points}")
    _check_trials(trials)
    result = _run_with_progress("ident-np-design",
                                lambda progress: study.run_np_design(out, dim, trials, seed, alpha_points, progress))
    table = result["table"]
    summary = Table(title=f"ident-np-design: P_ПО at the NP threshold, {dim}-D")
    curves = list(dict.fromkeys(table["curve"]))
    summary.add_column("α", justify="right")
    for curve in curves:
        summary.add_column(escape("P_ПО, uniform Δ∈[100, 600] m" if curve == study.MEAN_CURVE else f"P_ПО, {curve}"),
                           justify="right")
    for alpha in (1e-4, 0.001, 0.01, 0.05, 0.1, 0.2):
        rows = table[np.isclose(table["alpha"], alpha, rtol=1e-9, atol=0)]
        if len(rows):
            cells = dict(zip(rows["curve"], rows["p_correct"]))
            summary.add_row(f"{alpha:g}", *(f"{cells[c]:.7g}" for c in curves))
    _print_wide(summary)
    _finish(f"ident-np-design --dim {dim}", result["checks"], result["paths"], check)


# --------------------------------------------------------------------------- E4


def ident_elliptic(
    out: OutOption = Path("study-ident-elliptic"),
    seed: SeedOption = 1,
    trials: Annotated[int, typer.Option("--trials", help="Monte Carlo draws of the estimate difference.")] = 2_000_000,
    check: CheckOption = False,
) -> None:
    """E4: elliptical scattering (σ_x = 100 m, σ_y = 30 m, h = 200 m) against the circular formulas (G10)."""
    from skytrack.studies.identification import elliptic as study

    _check_trials(trials)
    result = _run_with_progress("ident-elliptic", lambda progress: study.run_elliptic(out, trials, seed, progress))
    table = result["table"]
    summary = Table(title=f"ident-elliptic: P(decide 'same') of the distance test ({trials:,} draws, seed {seed})")
    for column in ("Δ [m]", "direction", "truth (quadrature)", "Monte Carlo", "z", "circular, σ = σ_x",
                   "normalised (27): ncχ²₂", "Monte Carlo"):
        summary.add_column(escape(column), justify="right")
    for delta, direction in ((0.0, "x"), (150.0, "x"), (150.0, "y"), (300.0, "x"), (300.0, "y")):
        row = table[(table["direction"] == direction) & ((table["delta_m"] - delta).abs() < 1e-9)].iloc[0]
        summary.add_row(f"{delta:g}", direction, f"{row.exact:.6g}", f"{row.monte_carlo:.6g}", f"{row.z:+.2f}",
                        f"{row.circular:.6g}", f"{row.normalised_exact:.6g}", f"{row.normalised_mc:.6g}")
    _print_wide(summary)
    _finish("ident-elliptic", result["checks"], result["paths"], check)


def register_potential_studies(app: typer.Typer) -> None:
    """Add the spec 001 studies E1-E4 to the ``skytrack study`` sub-app."""
    app.command("ident-potential")(ident_potential)
    app.command("ident-np-design")(ident_np_design)
    app.command("ident-elliptic")(ident_elliptic)

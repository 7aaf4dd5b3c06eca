"""``skytrack study turn-rate-adaptive``: spec 002 §6 E3 (and E4 with ``--q-dep 0``).

Non-stationary turn-rate identification with the adaptive augmented filter (R11-R14): fixed V_w
(σ_w = 0.1, 0.5 °/s per step), adaptive λ = 0.8, 0.95, literal per-step (7) (R13 with the preset's
Q_dep, floor and ceiling), for T ∈ {1, 4} s and position / position + range-rate measurements, every
configuration's runs batched as the rows of one filter; spec 004's IMM (cv-ct) on the position data for
comparison.  Prints per setup the ω-RMSE table with the prototype value and a verdict beside each entry
(×1.5; divergence ±15 points), the position RMSE table, and E3/E4's expected behaviour with PASS/FAIL;
``--check`` exits 1 when one fails, a bad option exits 2.  Writes CSV, PNG and a JSON summary to ``--out``.
Only typer and rich are imported at module level; the study loads when the command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from skytrack.cli.study_output import SchedulerOption, WorkersOption, study_executor

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    from skytrack.cli.study_verdicts import fail_option

    fail_option(error_console, message)


def _parse_periods(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        _fail(f"--T expects comma-separated sampling periods in s, got {text!r}")
    if not values or any(not v > 0 for v in values):
        _fail(f"--T needs positive sampling periods, got {text!r}")
    return values


def _parse_measurements(text: str, known) -> tuple[str, ...]:
    values = tuple(part.strip() for part in text.split(",") if part.strip())
    bad = [v for v in values if v not in known]
    if not values or bad:
        _fail(f"--meas: unknown {', '.join(bad) or '(none given)'}; known: {', '.join(known)}")
    return values


def _verdict_markup(verdict: str) -> str:
    return {"ok": "[green]ok[/green]", "off": "[red]off[/red]"}.get(verdict, verdict)


def _setup_tables(result, T: float, measurement: str, q_accel: float):
    from skytrack.studies.turn_rate import scenario as sc
    from skytrack.studies.turn_rate.figures import LABELS
    from skytrack.studies.turn_rate.metrics import divergence_verdict, rmse_verdict

    group = [s for s in result.summaries if s.T == T and s.measurement == measurement]
    label = f"T = {T:g} s, {sc.MEASUREMENT_LABELS[measurement]}, q_a = {q_accel:g} m²/s³"
    # escaped: rich would read "[m]" as a markup tag and drop the unit
    omega = Table(title=escape(f"ω-RMSE [°/s] (prototype) verdict — {label}"))
    position = Table(title=escape(f"position RMSE [m] — {label}"))
    for table in (omega, position):
        table.add_column("configuration", no_wrap=True)
        for name in sc.WINDOW_NAMES:
            table.add_column(name, justify="right")
        table.add_column("diverged", justify="right")
    for s in group:
        proto = sc.prototype_omega_rmse(T, measurement, s.key, q_accel) if s.key != "imm" else None
        proto_div = sc.prototype_divergence(T, measurement, s.key, q_accel) if s.key != "imm" else None
        cells = []
        for w, value in enumerate(s.omega_rmse):
            p = None if proto is None else proto[w]
            cells.append(f"{value:.3f}" + ("" if p is None else f" ({p:.3f}) {_verdict_markup(rmse_verdict(value, p))}"))
        div = f"{s.diverged_pct:.0f} %" + ("" if proto_div is None else
                                           f" ({proto_div:.0f} %) {_verdict_markup(divergence_verdict(s.diverged_pct, proto_div))}")
        name = LABELS.get(s.key, s.key) + (" (Σμω)" if s.key == "imm" else "")
        omega.add_row(name, *cells, div)
        position.add_row(LABELS.get(s.key, s.key), *(f"{v:.1f}" for v in s.position_rmse), f"{s.diverged_pct:.0f} %")
    return omega, position


def turn_rate_adaptive(
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Output folder (default study-turn-rate-adaptive, "
                                             "…-qdep0 for --q-dep 0).")] = None,
    runs: Annotated[int, typer.Option("--runs", "--trials", help="Monte Carlo runs per configuration (rows of one "
                                      "filter).")] = 100,
    seed: Annotated[int, typer.Option("--seed", help="Seed; the draws of period T use SeedSequence((seed, 1000·T)), "
                                      "shared by every configuration and both measurement sets.")] = 1,
    periods: Annotated[str, typer.Option("--T", help="Sampling periods in s, comma-separated.")] = "1,4",
    meas: Annotated[str, typer.Option("--meas", help="Measurement sets: pos, pos+rdot (comma-separated).")] =
    "pos,pos+rdot",
    q_dep: Annotated[float, typer.Option("--q-dep", help="White-acceleration PSD q_a of Q_dep in m²/s³ (R14: 1; "
                                         "0 = the paper's G = F h_aᵀ noise only: E4).")] = 1.0,
    truth_rate: Annotated[str, typer.Option("--truth-rate", help="ω driving the truth step t_k → t_{k+1}: 'start' = "
                                            "ω(t_k) as E3 says, 'end' = ω(t_{k+1}) (turns one sample earlier; "
                                            "diagnostic).")] = "start",
    imm: Annotated[bool, typer.Option("--imm/--no-imm", help="Run spec 004's IMM (cv-ct) on the position data.")] = True,
    check: Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]
    = False,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """E3/E4 (spec 002 §6): adaptive turn-rate identification vs fixed V_w, literal (7) and an IMM."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from skytrack.cli.study_output import print_wide
    from skytrack.cli.study_verdicts import report_failures, verdicts_table
    from skytrack.studies.turn_rate import scenario as sc
    from skytrack.studies.turn_rate.study import job_count, run_study

    if runs < 1:
        _fail(f"--runs must be >= 1, got {runs}")
    if seed < 0:
        _fail(f"--seed must be >= 0 (numpy seeds are non-negative), got {seed}")
    if not q_dep >= 0:
        _fail(f"--q-dep must be >= 0, got {q_dep}")
    if truth_rate not in sc.TRUTH_RATE_CHOICES:
        _fail(f"--truth-rate must be one of {', '.join(sc.TRUTH_RATE_CHOICES)}, got {truth_rate!r}")
    period_list = _parse_periods(periods)
    measurement_list = _parse_measurements(meas, tuple(sc.MEASUREMENT_SETS))
    if out is None:
        out = Path("study-turn-rate-adaptive" + ("-qdep0" if q_dep == 0 else ""))
    columns = (TextColumn("[bold]turn-rate-adaptive"), TextColumn("{task.description}"), BarColumn(),
               MofNCompleteColumn(), TimeElapsedColumn())
    with study_executor(error_console, workers, scheduler) as executor, \
            Progress(*columns, console=error_console, transient=False) as display:
        task = display.add_task("configurations", total=job_count(period_list, measurement_list, imm))
        result = run_study(out, runs=runs, seed=seed, periods=period_list, measurements=measurement_list,
                           q_accel=q_dep, truth_rate=truth_rate, imm=imm, executor=executor,
                           progress=lambda label: display.update(task, advance=1, description=label))
    for T in period_list:
        for measurement in measurement_list:
            for table in _setup_tables(result, T, measurement, q_dep):
                print_wide(console, table)  # numbers are not squeezed into "0.10…" on a narrow terminal
    console.print(verdicts_table(f"turn-rate-adaptive: expected behaviour (spec 002 §6 E3/E4; {runs} runs, seed {seed})",
                                 result.checks, ("expected behaviour", "measured", "spec", "verdict")))
    console.print("wrote " + ", ".join(str(p) for p in result.paths))
    report_failures(console, result.checks, check, what="expected behaviour(s)",
                    all_held=f"all {len(result.checks)} expected behaviours hold")


def register_turn_rate_studies(app: typer.Typer) -> None:
    """Add ``turn-rate-adaptive`` (spec 002 §6 E3/E4) to the ``skytrack study`` sub-app."""
    app.command("turn-rate-adaptive")(turn_rate_adaptive)

"""``skytrack study fuzzy-*``: the fuzzy plot-association studies of spec 003 §6 (R20).

* ``fuzzy-fig2`` — E1, the paper's Fig. 2 (:mod:`skytrack.studies.fuzzy.fig2`);
* ``fuzzy-regions`` — E2, decision regions along the TV9 line (:mod:`skytrack.studies.fuzzy.regions`);
* ``fuzzy-gate`` — E3, the effective gate, Monte Carlo vs F_χ²₄(γ + 2 ln Π)
  (:mod:`skytrack.studies.fuzzy.gate`);
* ``fuzzy-crossing`` — E4, crossing targets with IFF errors (:mod:`skytrack.studies.fuzzy.crossing`;
  sweeps S1-S4 or list-valued options, ``--methods``; ``--check`` runs the CI-sized configurations
  and holds assertions (i)-(iv) and the expected results Q1-Q5).

Every command takes ``--out`` (output folder), ``--seed`` and ``--check``; it writes a CSV
and a PNG, prints a rich summary table and the spec's expected values with their verdicts,
and shows a progress bar for Monte Carlo draws.  With ``--check`` a failed expectation
exits with code 1; a bad option exits with code 2.  Only typer and rich are imported at
module level (``skytrack --help`` stays fast); the study modules load when a command runs.
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

OutOption = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
CheckOption = Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _float_list(option: str, text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        _fail(f"{option} expects comma-separated numbers, got {text!r}")
    if not values:
        _fail(f"{option} needs at least one value")
    return values


def _checks_table(checks, title: str) -> Table:
    table = Table(title=title)
    for column in ("expected value", "measured", "spec", "verdict"):
        table.add_column(column, overflow="fold")
    for check in checks:
        table.add_row(escape(check.name), escape(check.measured), escape(check.expected),
                      "[green]pass[/green]" if check.passed else "[red]FAIL[/red]")
    return table


def _finish(name: str, checks, paths: list[Path], check: bool) -> None:
    """Print the verdicts and the written files; exit 1 under ``--check`` when one failed."""
    console.print(_checks_table(checks, f"{name}: expected values (spec 003 §5, §6)"))
    console.print("wrote " + ", ".join(str(p) for p in paths))
    failed = [c.name for c in checks if not c.passed]
    if failed:
        console.print(f"[red]{len(failed)} expected value(s) failed: {escape(', '.join(failed))}[/red]")
        if check:
            raise typer.Exit(code=1)


# --------------------------------------------------------------------------- E1 fuzzy-fig2


def fuzzy_fig2(
    out: OutOption = Path("study-fuzzy-fig2"),
    seed: Annotated[int, typer.Option("--seed", help="Accepted like every study's; E1 draws no random numbers.")] = 1,
    check: CheckOption = False,
) -> None:
    """E1 (paper's Fig. 2): Gaussian density vs unit-peak membership for σ = 0.5, 1, 2."""
    from skytrack.studies.fuzzy import fig2

    table = fig2.run_fig2(out)
    summary = Table(title="fuzzy-fig2: density p vs membership μ (n_c = 1)")
    for column in ("σ", "peak of p", "1/(σ√(2π))", "peak of μ", "max |μ − pσ√(2π)| / μ"):
        summary.add_column(column, justify="right")
    for row in table.itertuples(index=False):
        summary.add_row(f"{row.sigma:g}", f"{row.peak_p:.6f}", f"{row.peak_p_closed_form:.6f}", f"{row.peak_mu:.15g}",
                        f"{row.max_rel_identity_error:.1e}")
    console.print(summary)
    _finish("fuzzy-fig2", fig2.check_fig2(table),
            [out / fig2.CSV_NAME, out / fig2.CURVES_CSV_NAME, out / fig2.PNG_NAME], check)


# --------------------------------------------------------------------------- E2 fuzzy-regions


def fuzzy_regions(
    out: OutOption = Path("study-fuzzy-regions"),
    seed: Annotated[int, typer.Option("--seed", help="Accepted like every study's; E2 draws no random numbers.")] = 1,
    check: CheckOption = False,
) -> None:
    """E2: chosen hypothesis along the TV9 line for ml, fuzzy without and with features."""
    from skytrack.studies.fuzzy import regions

    table = regions.run_regions(out)
    summary = Table(title="fuzzy-regions: boundaries along x (P_G = 0.99)")
    for column in ("band", "left | right", "x [m]", "closed form [m]", "error [m]"):
        summary.add_column(column, justify="right")
    for row in table.itertuples(index=False):
        summary.add_row(row.label, f"{row.left} | {row.right}", f"{row.x_m:.3f}", f"{row.closed_form_m:.6f}",
                        f"{row.error_m:.1e}")
    console.print(summary)
    _finish("fuzzy-regions", regions.check_regions(table), [out / regions.CSV_NAME, out / regions.PNG_NAME], check)


# --------------------------------------------------------------------------- E3 fuzzy-gate


def fuzzy_gate(
    out: OutOption = Path("study-fuzzy-gate"),
    seed: Annotated[int, typer.Option("--seed", help="Seed; chunk c draws with SeedSequence(seed).spawn(chunks)[c].")] = 1,
    samples: Annotated[int, typer.Option("--samples", help="Monte Carlo draws of ν ~ N(0, S) (shared by all points).")] = 400_000,
    p_gate: Annotated[str, typer.Option("--p-gate", help="Gate probabilities P_G, comma-separated.")] = "0.95,0.99,0.999",
    check: CheckOption = False,
) -> None:
    """E3: probability of keeping the correct track vs the feature product Π (TV11)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from skytrack.studies.fuzzy import gate

    p_gates = _float_list("--p-gate", p_gate)
    if any(not 0.0 < p < 1.0 for p in p_gates):
        _fail(f"--p-gate values must lie in (0, 1), got {p_gate!r}")
    if samples < gate.CHUNKS:
        _fail(f"--samples must be at least {gate.CHUNKS}, got {samples}")
    columns = (TextColumn("[bold]fuzzy-gate Monte Carlo"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=error_console, transient=False) as display:
        task = display.add_task("draws", total=gate.CHUNKS)
        table = gate.run_gate(out, seed=seed, samples=samples, p_gates=p_gates,
                              progress=lambda done, total: display.update(task, completed=done, total=total))
    summary = Table(title=f"fuzzy-gate: P(correct track kept) vs Π ({samples:,} draws, seed {seed})")
    for column in ("P_G", "case", "Π", "d² limit", "F_χ²₄", "Monte Carlo", "z", "new object"):
        summary.add_column(column, justify="right")
    for row in table.itertuples(index=False):
        summary.add_row(f"{row.p_gate:g}", row.case, f"{row.product:g}", f"{row.d2_limit:.4f}", f"{row.probability:.5f}",
                        f"{row.mc_kept:.5f}", f"{row.z:+.2f}", f"{100 * row.mc_new_object:.2f} %")
    console.print(summary)
    console.print(f"mean exp(−d²/2) = {table['mean_mu_coord'].iloc[0]:.5f} (D6: 0.25)")
    _finish("fuzzy-gate", gate.check_gate(table), [out / gate.CSV_NAME, out / gate.PNG_NAME], check)


# --------------------------------------------------------------------------- E4 fuzzy-crossing

ListOption = Annotated[str | None, typer.Option(help="Comma-separated values (a sweep); default: the reference value.")]


def fuzzy_crossing(
    out: OutOption = Path("study-fuzzy-crossing"),
    seed: Annotated[int, typer.Option("--seed", help="Run i uses SeedSequence(seed).spawn(runs)[i].")] = 1,
    runs: Annotated[int | None, typer.Option("--runs", help="Runs per configuration (default 200; 100 with --check).")] = None,
    methods: Annotated[str, typer.Option("--methods", help="Methods: nn, ml, fuzzy, fuzzy-global, crisp.")] =
    "nn,ml,fuzzy,fuzzy-global,crisp",
    sweeps: Annotated[str, typer.Option("--sweeps", help="Sweeps of spec 003 §6: S1 (policy), S2 (IFF errors), S3 "
                                        "(beta x q), S4 (missing_iff), T (the spec's indicative table); ignored "
                                        "when a list option is given.")] =
    "S1,S2,S3,S4",
    beta_deg: ListOption = None, q: ListOption = None, p_flip: ListOption = None, p_code: ListOption = None,
    p_reply: ListOption = None,
    policy: Annotated[str | None, typer.Option(help="Interrogation policies: track, always, never (comma-separated).")]
    = None,
    missing_iff: Annotated[str | None, typer.Option(help="undetermined and/or neutral (comma-separated).")] = None,
    check: Annotated[bool, typer.Option("--check", help="Run the spec's CI-sized configurations and exit 1 unless "
                                        "assertions (i)-(iv) and Q1-Q5 hold.")] = False,
    diagnostic_runs: Annotated[int, typer.Option("--diagnostic-runs", help="Write spec 003 R13's per-(plot, "
                                                 "hypothesis) scores of the first N runs of every configuration "
                                                 "and method to fuzzy_crossing_pairs.parquet.")] = 0,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """E4: crossing targets of different nationality, IFF errors and interrogation policies (spec 003 §6)."""
    import itertools
    from dataclasses import replace

    import pandas as pd
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from skytrack.studies.fuzzy import crossing, crossing_checks
    from skytrack.studies.fuzzy.crossing_figure import crossing_figure

    method_list = [m.strip() for m in methods.split(",") if m.strip()]
    unknown = [m for m in method_list if m not in crossing.METHODS]
    if unknown or not method_list:
        _fail(f"--methods: unknown {', '.join(unknown) or '(none given)'}; methods are {', '.join(crossing.METHODS)}")
    runs = runs if runs is not None else (100 if check else 200)
    if runs < 1:
        _fail(f"--runs must be >= 1, got {runs}")
    lists = {"beta_deg": beta_deg, "q": q, "p_flip": p_flip, "p_code": p_code, "p_reply": p_reply}
    values = {key: _float_list(f"--{key.replace('_', '-')}", text) for key, text in lists.items() if text}
    for key, text, allowed in (("policy", policy, ("track", "always", "never")),
                               ("missing_iff", missing_iff, ("undetermined", "neutral"))):
        if text:
            values[key] = tuple(v.strip() for v in text.split(",") if v.strip())
            bad = [v for v in values[key] if v not in allowed]
            if bad:
                _fail(f"--{key.replace('_', '-')}: unknown {', '.join(bad)}; allowed: {', '.join(allowed)}")
    if check:
        cases = crossing_checks.check_cases()
        method_list = list(crossing.METHODS)
    elif values:
        keys = list(values)
        cases = [replace(crossing.CrossingCase(sweep="custom"), **dict(zip(keys, combo)))
                 for combo in itertools.product(*(values[k] for k in keys))]
    else:
        try:
            cases = crossing.sweep_cases([s.strip() for s in sweeps.split(",") if s.strip()])
        except ValueError as error:
            _fail(str(error))
    if diagnostic_runs < 0:
        _fail(f"--diagnostic-runs must be >= 0, got {diagnostic_runs}")
    out.mkdir(parents=True, exist_ok=True)
    diagnostic_runs = min(diagnostic_runs, runs)
    tasks = [crossing.CrossingTask(case, method, runs, seed, check, diagnostic_runs)
             for case in cases for method in method_list]
    if check:  # TV13 (c) also across p_reply: the coordinate rules on a run set with p_reply = 0.5
        extra = replace(crossing.CrossingCase(sweep="check"), policy="always", p_reply=0.5)
        tasks += [crossing.CrossingTask(extra, method, runs, seed, True) for method in ("nn", "ml")]
    columns = (TextColumn("[bold]fuzzy-crossing"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with study_executor(error_console, workers, scheduler) as executor, \
            Progress(*columns, console=error_console, transient=False) as display:
        task = display.add_task("runs", total=len(tasks))
        results = crossing.run_tasks(tasks, executor, lambda done, total: display.update(task, completed=done))
    n_main = len(cases) * len(method_list)
    tables = [pd.DataFrame([r.row for r in results[:n_main]])]
    pairs = [r.diagnostics for r in results[:n_main] if r.diagnostics is not None]
    kept: list = []
    for k, case in enumerate(cases):
        part = zip(method_list, results[k * len(method_list):(k + 1) * len(method_list)])
        kept.append((case, {method: r.decisions for method, r in part} if check else {}))
    if check:
        kept.append((crossing.CrossingCase(), {t.method: r.decisions for t, r in zip(tasks[n_main:], results[n_main:])}))
    table = pd.concat(tables, ignore_index=True)
    csv_path, png_path = out / "fuzzy_crossing.csv", out / "fuzzy_crossing.png"
    table.to_csv(csv_path, index=False)
    crossing_figure(table, png_path)
    if pairs:
        pairs_path = out / "fuzzy_crossing_pairs.parquet"
        pd.concat(pairs, ignore_index=True).to_parquet(pairs_path, index=False)
        console.print(f"per-(plot, hypothesis) scores (R13) of the first {diagnostic_runs} runs: {pairs_path}")
    summary = Table(title=f"fuzzy-crossing: CAR / swap / broken ({runs} runs per configuration, seed {seed})")
    for column in ("sweep", "policy", "errors flip/code", "β", "q", "missing IFF", *method_list):
        summary.add_column(column, justify="right")
    settings = ["sweep", "policy", "p_flip", "p_code", "beta_deg", "q", "missing_iff", "p_reply"]
    for _, group in table.groupby(settings, sort=False):
        first = group.iloc[0]
        cells = {row.method: f"{row.car:.3f}/{row.swap:.3f}/{row.broken:.3f}" for row in group.itertuples()}
        summary.add_row(first.sweep, first.policy, f"{first.p_flip:g}/{first.p_code:g}", f"{first.beta_deg:g}",
                        f"{first.q:g}", first.missing_iff, *(cells.get(m, "–") for m in method_list))
    console.print(summary)
    if any(case.sweep in ("T", "check") for case in cases):
        markdown = out / "fuzzy_crossing_table.md"
        markdown.write_text(crossing_checks.indicative_markdown(table, seed))
        console.print(f"the spec's indicative table with this run's cells: {markdown}")
    if check:
        checks = crossing_checks.ci_checks(table, crossing_checks.decisions_identical(kept))
        checks += crossing_checks.qualitative_checks(table)
        _finish("fuzzy-crossing", checks, [csv_path, png_path], check)
    else:
        console.print(f"wrote {csv_path}, {png_path}")


def register_fuzzy_studies(app: typer.Typer) -> None:
    """Add the spec 003 studies to the ``skytrack study`` sub-app."""
    app.command("fuzzy-fig2")(fuzzy_fig2)
    app.command("fuzzy-regions")(fuzzy_regions)
    app.command("fuzzy-gate")(fuzzy_gate)
    app.command("fuzzy-crossing")(fuzzy_crossing)

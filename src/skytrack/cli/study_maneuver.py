"""``skytrack study <name>`` for the manoeuvring-target studies of spec 004 §6 (R24).

One command per entry of :data:`skytrack.studies.maneuver.names.STUDY_MODULES`, all with the
options of R24::

    skytrack study <name> [--runs N] [--seed S] [--scenario NAME|FILE] [--truth FILE]
                          [--filters LIST] [--config FILE] [--out DIR] [--quick] [--check]
                          [--workers N] [--scheduler ADDRESS]

``--workers``/``--scheduler`` (issue 11 item 6) choose where the filter runs of the study's
comparisons (``ctx.compare``) run: in process, a local process pool (default) or a Dask cluster.

The command parses the options, runs :func:`skytrack.studies.maneuver.study.run_study` with a
rich progress bar over the filter runs, prints the claims (assert verdicts and report values)
and the written files.  A bad option or configuration is a one-line error naming it (exit 2);
with ``--check`` a failed assert exits with code 1.  Only typer and rich are imported here at
module level (``skytrack --help`` stays fast); the study modules are imported when a command runs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from skytrack.cli.study_output import SchedulerOption, WorkersOption, study_executor
from skytrack.studies.maneuver.names import STUDY_MODULES

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _labels(text: Optional[str]) -> Optional[tuple[str, ...]]:
    if text is None:
        return None
    labels = tuple(part.strip() for part in text.split(",") if part.strip())
    if not labels:
        _fail("--filters needs at least one filter label")
    return labels


def _value(value, nested: bool = False) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, dict):
        text = ", ".join(f"{k}={_value(v, True)}" for k, v in value.items())
        return f"({text})" if nested else text
    if isinstance(value, list):
        return "[" + ", ".join(_value(v, True) for v in value[:6]) + (", …" if len(value) > 6 else "") + "]"
    return str(value)


def _claims_table(claims: list[dict], name: str) -> Table:
    table = Table(title=f"{name}: claims", show_lines=True)
    for column in ("claim", "kind", "verdict", "measured"):
        table.add_column(column, overflow="fold")
    for claim in claims:
        verdict = {True: "[green]pass[/green]", False: "[red]FAIL[/red]", None: "–"}[claim["verdict"]]
        # measured values are text, not rich markup (lists print as "[...]")
        table.add_row(escape(claim["id"]), claim["kind"], verdict, escape(_value(claim["measured"])[:400]))
    return table


def _make_command(name: str):
    def command(
        runs: Annotated[Optional[int], typer.Option("--runs", help="Monte Carlo runs (default: the study's, e.g. 200; --quick: a few).")] = None,
        seed: Annotated[Optional[int], typer.Option("--seed", help="Seed; run r uses SeedSequence(seed).spawn(runs)[r] (default 1).")] = None,
        scenario: Annotated[Optional[str], typer.Option("--scenario", help="Named scenario (default, weave, vertical, fighter) or a scenario YAML file.")] = None,
        truth: Annotated[Optional[Path], typer.Option("--truth", help="Recorded trajectories (truth file of formats.md: time + ENU or WGS84; OpenSky state vectors).")] = None,
        filters: Annotated[Optional[str], typer.Option("--filters", help="Comma-separated filter labels of the study catalogue.")] = None,
        config: Annotated[Optional[Path], typer.Option("--config", help="YAML configuration (scenario, sensor, filters, metrics, study parameters).")] = None,
        out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Output folder (default: study-<name>).")] = None,
        quick: Annotated[bool, typer.Option("--quick", help="A few runs (smoke test of the study).")] = False,
        check: Annotated[bool, typer.Option("--check", help="Exit with code 1 if an assert claim fails.")] = False,
        workers: WorkersOption = None,
        scheduler: SchedulerOption = None,
    ) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        from skytrack.studies.maneuver.names import load_study
        from skytrack.studies.maneuver.study import StudyOptions, load_config, run_study

        try:
            definition = load_study(name)
            options = StudyOptions(out=out or Path(f"study-{name}"), runs=runs, seed=seed, scenario=scenario, truth=truth,
                                   filters=_labels(filters), config=load_config(config), quick=quick)
        except ValueError as exc:
            _fail(str(exc))
        columns = (TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
        try:
            with study_executor(error_console, workers, scheduler) as executor, \
                    Progress(*columns, console=error_console, transient=False) as display:
                task = display.add_task(name, total=None)

                def progress(description: str, completed: int, total: int) -> None:
                    display.update(task, completed=completed, total=total,
                                   description=f"{name} {description}" if description else name)

                result = run_study(definition, options, progress, executor)
        except (ValueError, FileNotFoundError) as exc:
            _fail(str(exc))
        claims = json.loads(result.paths["claims"].read_text(encoding="utf-8"))["claims"]
        console.print(_claims_table(claims, name))
        console.print("wrote " + ", ".join(str(p) for p in result.paths.values()) + " and the figures listed in figures.json")
        if result.failed:
            console.print(f"[red]{len(result.failed)} assert claim(s) failed: {', '.join(c.id for c in result.failed)}[/red]")
            if check:
                raise typer.Exit(code=1)

    command.__name__ = name.replace("-", "_")
    command.__doc__ = STUDY_MODULES[name][1]
    return command


def register_maneuver_studies(app: typer.Typer) -> None:
    """Add ``skytrack study <name>`` for every spec 004 study to the ``study`` sub-app."""
    for name, (_, help_text) in STUDY_MODULES.items():
        app.command(name, help=help_text)(_make_command(name))

"""Helpers shared by the ``skytrack study`` commands: wide tables, progress bars, and the
``--workers`` / ``--scheduler`` options of the Monte Carlo studies (issue 11 item 6) with the
executor they select (:func:`skytrack.studies.parallel.make_executor`).

Only typer and rich are imported at module level (``skytrack --help`` stays fast).
"""

from __future__ import annotations

import contextlib
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table


def print_wide(console: Console, table: Table) -> None:
    """Print a table without squeezing its numbers when stdout is narrow or a pipe."""
    needed = console.measure(table, options=console.options.update_width(100_000)).maximum
    (console if needed <= console.width else Console(width=needed)).print(table)


def run_with_progress(error_console: Console, label: str, run, steps: str = "steps"):
    """Call ``run(progress)`` under a rich progress bar fed by ``progress(completed, total)``."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn(f"[bold]{escape(label)}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=error_console, transient=False) as display:
        task = display.add_task(steps, total=None)
        return run(lambda done, total: display.update(task, completed=done, total=total))


WorkersOption = Annotated[Optional[int], typer.Option(
    "--workers", help="Worker processes of the local pool (default: one per CPU; 1: in this process). "
    "The numbers do not depend on it.")]
SchedulerOption = Annotated[Optional[str], typer.Option(
    "--scheduler", help="Run the tasks on the Dask cluster of this scheduler address (e.g. tcp://127.0.0.1:8786; "
    "needs skytrack[dask]); wins over --workers.")]


@contextlib.contextmanager
def study_executor(error_console: Console, workers: int | None, scheduler: str | None):
    """The executor of ``--workers``/``--scheduler``; a bad value or an unreachable scheduler exits with code 2."""
    from skytrack.studies.parallel import ExecutorError, make_executor

    try:
        manager = make_executor(workers, scheduler)
        executor = manager.__enter__()
    except ExecutorError as error:
        error_console.print(f"[bold red]error:[/] {escape(str(error))}", highlight=False, soft_wrap=True)
        raise typer.Exit(code=2) from None
    try:
        yield executor
    except BaseException as error:
        if not manager.__exit__(type(error), error, error.__traceback__):
            raise
    else:
        manager.__exit__(None, None, None)

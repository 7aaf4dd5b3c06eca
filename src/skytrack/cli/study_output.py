"""Printing helpers shared by the ``skytrack study ident-*`` commands: wide tables and progress bars.

Only rich is imported at module level (``skytrack --help`` stays fast).
"""

from __future__ import annotations

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

"""Verdict printing shared by the spec 002 §6 study commands (E1-E7: ``ident-example``, ``ident-radar``,
``turn-rate-adaptive``, ``gain-conditioning``, ``poor-experiment``, ``vw-estimator``).

Every §6 study prints its expected values next to the measured ones with PASS/FAIL, exits 1 under
``--check`` when one fails (§6's "--check" convention) and 2 on a bad option.  The checks are
:class:`skytrack.studies.fuzzy.common.Check` rows (``name``, ``measured``, ``expected``, ``passed``).
Only typer and rich are imported (``skytrack --help`` stays fast).
"""

from __future__ import annotations

from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

VERDICT_COLUMNS = ("expected value", "measured", "spec", "verdict")


def fail_option(error_console: Console, message: str) -> NoReturn:
    """Print a bad-option message on stderr and exit with code 2 (typer's usage-error code)."""
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def verdicts_table(title: str, checks, columns=VERDICT_COLUMNS) -> Table:
    """One row per check: name, measured, expected (with its tolerance), PASS/FAIL; long cells fold."""
    table = Table(title=escape(title))
    for column in columns:
        table.add_column(escape(column), overflow="fold")
    for item in checks:
        table.add_row(escape(item.name), escape(item.measured), escape(item.expected),
                      "[green]PASS[/green]" if item.passed else "[red]FAIL[/red]")
    return table


def report_failures(console: Console, checks, check: bool, what: str = "expected value(s)",
                    all_held: str | None = None) -> None:
    """Name the failed checks in red (or print ``all_held`` in green); exit 1 under ``--check`` on a failure."""
    failed = [c.name for c in checks if not c.passed]
    if failed:
        console.print(f"[red]{len(failed)} {what} failed: {escape('; '.join(failed))}[/red]")
    elif all_held:
        console.print(f"[green]{escape(all_held)}[/green]")
    if failed and check:
        raise typer.Exit(code=1)

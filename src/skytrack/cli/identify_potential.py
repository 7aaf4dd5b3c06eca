"""``skytrack identify potential`` and ``threshold`` (spec 001 R11).  Being written (issue 9)."""

from __future__ import annotations

import typer


def register_potential_commands(app: typer.Typer) -> None:
    """Add ``potential`` and ``threshold`` to the ``skytrack identify`` sub-app."""

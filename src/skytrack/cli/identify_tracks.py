"""``skytrack identify tracks``: many-to-many identification of two systems' tracks (spec 001 R13, R14).

System 1 is a radar (its plots with ``--sensors``, or its tracks file written with
``skytrack track --reports``); system 2 is ADS-B reports, or another radar's or an IFF
interrogator's tracks file with its reports.  Writes the identified (and, with ``--fuse``, fused)
tracks, the decided pairs (``NAME.pairs``) and the identity events; with ``--truth`` prints the
identification against truth (correct, wrong and missing identifications, time to identify).
Only typer and rich are imported at module level (:mod:`skytrack.app.identify_run` does the work).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def identify_tracks_command(
    first: Annotated[Path, typer.Argument(help="System 1: radar plots (with --sensors) or a tracks file written with `skytrack track --reports`.")],
    second: Annotated[Path, typer.Argument(help="System 2: ADS-B reports, or another radar's / an interrogator's tracks file with its reports.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Identified tracks of system 1 to write (.parquet or .csv).")],
    sensors: Annotated[Optional[Path], typer.Option("--sensors", help="sensors.json (needed when system 1 is plots, or for geodetic ADS-B).")] = None,
    truth: Annotated[Optional[Path], typer.Option("--truth", help="Truth table: score the identification against it.")] = None,
    source: Annotated[str, typer.Option("--source", help="What system 2's tracks are when they are not ADS-B: radar or iff.")] = "radar",
    fuse: Annotated[bool, typer.Option("--fuse", help="Rows of identified tracks carry the pair's joint (fused) estimate (R14).")] = False,
    q: Annotated[Optional[float], typer.Option("--q", help="Process-noise PSD of the identification model (m^2/s^3).")] = None,
    p_correct: Annotated[Optional[float], typer.Option("--p-correct", help="A new identification needs Lambda below the chi-square quantile of this probability.")] = None,
    gate: Annotated[Optional[float], typer.Option("--gate", help="Coarse pair-creation gate (m).")] = None,
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Write the summary (and the report against truth) as JSON.")] = None,
) -> None:
    """Identify system 1's tracks with system 2 (ADS-B, another radar or an interrogator) by the sequential test."""
    from skytrack.app.identification import AdsbIdentificationConfig
    from skytrack.app.identify_run import identify_tracks, with_settings

    try:
        config = with_settings(AdsbIdentificationConfig(fuse=fuse), q=q, p_correct=p_correct, gate_m=gate)
        summary = identify_tracks(first, second, out, sensors=sensors, truth=truth, config=config, source=source)
    except (ValueError, KeyError, FileNotFoundError) as exc:
        _fail(str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc))
    table = Table(title="identification", show_header=False)
    table.add_row("system 2", summary.other_kind)
    table.add_row("track rows", f"{summary.track_rows} -> {summary.tracks_file}")
    table.add_row("tracks identified", f"{summary.tracks_identified} ({summary.labelled_rows} rows labelled)")
    table.add_row("decided pairs", f"{summary.pair_rows} -> {summary.pairs_file}")
    stats = summary.stats
    table.add_row("reports", f"{stats['radar_reports']} radar, {stats['adsb_reports']} system 2; "
                             f"{stats['pairs_created']} pairs made, {stats['pairs_dropped']} dropped")
    console.print(table)
    for note in summary.notes:
        console.print(f"note: {note}", highlight=False)
    if summary.report is not None:
        if summary.other_kind == "adsb":
            from skytrack.cli.identification_view import identification_table

            console.print(identification_table(summary.report))
        else:
            totals = summary.report.totals
            score = Table(title="pairs against truth", show_header=False)
            for key, value in totals.items():
                score.add_row(key.replace("_", " "), "-" if value is None else f"{value:g}" if isinstance(value, float)
                              else str(value))
            score.add_row("verdict", "pass: no wrong pair, every object paired" if summary.report.passed else "FAIL")
            console.print(score)
    if json_out is not None:
        json_out.write_text(json.dumps(summary.to_dict(), indent=2, default=str))
        console.print(f"wrote {json_out}")


def register_tracks_command(app: typer.Typer) -> None:
    """Add ``tracks`` to the ``skytrack identify`` sub-app."""
    app.command("tracks")(identify_tracks_command)

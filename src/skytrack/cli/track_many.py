"""``skytrack track-many``: track several plots files at once, in parallel (issue 11 item 6).

    skytrack track-many A.parquet B.parquet ... --sensors sensors.json --out-dir tracks/
                        [--config tracker.yaml] [--format parquet|csv] [--lenient] [--reports]
                        [--workers N | --scheduler tcp://HOST:PORT]

Every file is an independent replay (its own tracker) written to ``OUT_DIR/<stem>.tracks.<format>``
by :func:`skytrack.app.track_files.track_files`; the files run on a local process pool (default: one
worker per CPU), in this process (``--workers 1``) or on a Dask cluster (``--scheduler``), with the
same tracks whatever runs them.  One line per file at the end: plots, tracks, track rows, time, or
why it wrote no track.  Only typer and rich are imported at module level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from skytrack.cli.study_output import SchedulerOption, WorkersOption, print_wide, run_with_progress, study_executor

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def track_many(
    plots: Annotated[list[Path], typer.Argument(help="Plots files (.parquet or .csv, FORMATS.md layout), one replay each.")],
    sensors: Annotated[Path, typer.Option("--sensors", help="sensors.json describing the radars (shared by every file).")],
    out_dir: Annotated[Path, typer.Option("--out-dir", "-o", help="Folder of the tracks files (<stem>.tracks.<format>).")],
    config_file: Annotated[Optional[Path], typer.Option("--config", help="Tracker configuration (YAML or JSON, as for "
                                                        "skytrack track --config).")] = None,
    output_format: Annotated[str, typer.Option("--format", help="Tracks files as parquet or csv.")] = "parquet",
    lenient: Annotated[bool, typer.Option(help="Skip and count malformed plot rows instead of stopping.")] = False,
    units_confirmed: Annotated[bool, typer.Option("--units-confirmed", help="Track plots whose values look like km "
                                                  "or radians as metres and degrees all the same.")] = False,
    range_rate_positive_closing: Annotated[bool, typer.Option("--range-rate-positive-closing", help="The plots' "
                                                              "range rates are positive for closing targets.")] = False,
    reports: Annotated[bool, typer.Option("--reports", help="Also write each file's track reports "
                                          "(<stem>.tracks.reports.parquet).")] = False,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Track several plots files, each an independent replay, in parallel (local pool or Dask)."""
    from skytrack.app.track_files import track_files
    from skytrack.studies.parallel import describe_executor
    from skytrack.tracker import TrackerConfig

    try:
        config = TrackerConfig.from_file(config_file) if config_file is not None else None
    except (OSError, ValueError) as error:
        _fail(f"--config {config_file}: {error}")
    options = {"lenient": lenient, "units_confirmed": units_confirmed,
               "range_rate_positive_closing": range_rate_positive_closing, "write_reports": reports}
    error_console.print(f"{len(plots)} file(s); tasks run {describe_executor(workers, scheduler)}", highlight=False)
    with study_executor(error_console, workers, scheduler) as executor:
        try:
            summaries = run_with_progress(
                error_console, "track-many",
                lambda progress: track_files(plots, sensors, out_dir, config, executor=executor, progress=progress,
                                             output_format=output_format, **options),
                steps="files")
        except (ValueError, FileNotFoundError) as error:
            _fail(str(error))
    table = Table(title=f"track-many: {len(summaries)} file(s)")
    for column in ("plots file", "plots", "tracks confirmed", "track rows", "time [s]", "tracks file / why none"):
        table.add_column(column, justify="right" if column in ("plots", "tracks confirmed", "track rows", "time [s]")
                         else "left", overflow="fold")
    for name, summary in zip(plots, summaries):
        where = summary.tracks_file if summary.track_rows else f"none: {summary.no_tracks_reason}"
        table.add_row(escape(str(name)), str(summary.plots), str(summary.stats.get("tracks_confirmed", 0)),
                      str(summary.track_rows), f"{summary.elapsed_s:.2f}", escape(where))
    print_wide(console, table)  # paths are not folded on a narrow terminal


def register_track_many(app: typer.Typer) -> None:
    """Add ``skytrack track-many`` to the top-level app."""
    app.command("track-many")(track_many)

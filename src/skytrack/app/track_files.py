"""Multi-file replays (issue 11 item 6): track several plots files independently, in parallel.

:func:`track_files` maps :func:`skytrack.app.run.run_tracking` over plots files, one pure task per
file (:class:`ReplayTask`: the file, sensors.json, the output path and the tracker options in, the
file's :class:`~skytrack.app.run.RunSummary` out), on any ``concurrent.futures`` executor
(:func:`skytrack.studies.parallel.make_executor`: in process, a local process pool, or a Dask
cluster).  Each file is a separate replay with its own tracker, so the tracks of a file are the
same whatever the executor and whatever the other files.  ``skytrack track-many`` is its command.

Outputs: ``OUT_DIR/<input stem>.tracks.<format>`` per file (beside it the identity events and, with
``write_reports``, the track reports, named as ``skytrack track`` names them).  Two inputs with the
same stem are refused before anything runs (their outputs would overwrite each other).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from skytrack.app.run import RunSummary, run_tracking
from skytrack.studies.parallel import map_tasks

#: output formats of :func:`track_files` (the tracks file's suffix)
OUTPUT_FORMATS = ("parquet", "csv")


@dataclass(frozen=True)
class ReplayTask:
    """One file of :func:`track_files`; every field pickles (a process pool or Dask carries it)."""

    plots: Path
    sensors: Path
    out: Path
    config: object = None  # TrackerConfig or None (the defaults)
    lenient: bool = False
    chunk_rows: int | None = None
    units_confirmed: bool = False
    range_rate_positive_closing: bool = False
    write_reports: bool = False


def replay_task(task: ReplayTask) -> RunSummary:
    """Track one file (pure: the task in, the file's summary out; it writes only the task's outputs)."""
    options = {} if task.chunk_rows is None else {"chunk_rows": task.chunk_rows}
    return run_tracking(task.plots, task.sensors, task.out, task.config, lenient=task.lenient,
                        units_confirmed=task.units_confirmed,
                        range_rate_positive_closing=task.range_rate_positive_closing,
                        write_reports=task.write_reports, **options)


def output_path(plots: str | Path, out_dir: str | Path, output_format: str = "parquet") -> Path:
    """Where :func:`track_files` writes the tracks of ``plots``: ``out_dir/<stem>.tracks.<format>``."""
    if output_format not in OUTPUT_FORMATS:
        raise ValueError(f"output format must be one of {OUTPUT_FORMATS}, got {output_format!r}")
    return Path(out_dir) / f"{Path(plots).stem}.tracks.{output_format}"


def replay_tasks(files: Sequence[str | Path], sensors: str | Path, out_dir: str | Path, config=None, *,
                 output_format: str = "parquet", **options) -> list[ReplayTask]:
    """One :class:`ReplayTask` per file; a missing file or two files with one output name raise ``ValueError``."""
    if not files:
        raise ValueError("no plots file given")
    outputs: dict[Path, Path] = {}
    tasks = []
    for name in files:
        plots = Path(name)
        if not plots.is_file():
            raise ValueError(f"plots file {plots} does not exist")
        out = output_path(plots, out_dir, output_format)
        if out in outputs:
            raise ValueError(f"{outputs[out]} and {plots} would both write {out}: rename one (the output is named "
                             "after the input's stem)")
        outputs[out] = plots
        tasks.append(ReplayTask(plots, Path(sensors), out, config, **options))
    return tasks


def track_files(files: Sequence[str | Path], sensors: str | Path, out_dir: str | Path, config=None, *,
                executor=None, progress: Callable[[int, int], None] | None = None,
                output_format: str = "parquet", **options) -> list[RunSummary]:
    """Track every file of ``files`` with ``sensors`` into ``out_dir`` (created), one task per file on
    ``executor`` (``None``: in this process, one after the other); summaries in the order of ``files``.

    ``options``: ``lenient``, ``chunk_rows``, ``units_confirmed``, ``range_rate_positive_closing``,
    ``write_reports`` of :func:`~skytrack.app.run.run_tracking`; ``progress(done, total)`` as files finish.
    A file that fails raises its error (naming the file) after the running files are cancelled.
    """
    tasks = replay_tasks(files, sensors, out_dir, config, output_format=output_format, **options)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    return map_tasks(replay_task, tasks, executor, progress)

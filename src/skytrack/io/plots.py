"""Radar plots (FORMATS.md "plots"): reader and writer with schema validation.

Checks, each vectorised over all rows: required columns present; numbers where numbers
are expected; no missing or infinite value in ``time``/``range_m``/``azimuth_deg``;
``range_m >= 0``; ``azimuth_deg`` in [0, 360); ``elevation_deg`` in [-90, 90]; optional
numbers finite when present (``mode_c_ft``, ``range_rate_mps``, ``elevation_deg``);
``scan`` integral; ``sensor`` present and, given a :class:`~skytrack.geo.SensorSet`,
known; ``mode3a`` 4 octal digits; ``mode_s`` 6 hex digits (lower-cased); ``iff`` one of
friend/foe/undetermined or null; ``time`` never going backwards within a sensor.

A ``timestamp`` column (datetimes, ISO 8601 text or POSIX seconds) may replace ``time``:
it is converted to seconds since ``epoch_utc`` (from the argument or ``sensors.json``),
or since the earliest timestamp with a warning when no epoch is known.  The
``timestamp`` column is kept as an extra column.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, overload

import numpy as np
import pandas as pd

from skytrack.geo.sensors import SensorSet
from skytrack.io.checks import (
    RowChecks,
    as_float,
    as_int,
    as_string,
    check_identity_columns,
    emit_warnings,
    flag_time_backwards,
    flag_values,
    fmt_value,
    order_columns,
    parse_epoch,
    require_columns,
    time_column,
)
from skytrack.io.errors import ReadReport
from skytrack.io.schema import PLOT_SCHEMA
from skytrack.io.tables import TableSource, iter_parquet, load_table, table_format, write_table


def _validate_plots(
    df: pd.DataFrame,
    source: TableSource,
    sensors: SensorSet | None,
    epoch_utc: object,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    require_columns(df, source, [("time", "timestamp"), "sensor", "range_m", "azimuth_deg"], "plots")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    epoch_text = epoch_utc if epoch_utc is not None else (sensors.epoch_utc if sensors is not None else None)
    epoch = parse_epoch(epoch_text) if epoch_text is not None else None
    time = time_column(df, checks, epoch, report)

    sensor = as_string(df, "sensor", checks, required=True)
    if sensors is not None:
        known = sensors.names
        unknown = (
            ~sensor.isin(known).to_numpy(dtype=bool) & sensor.notna().to_numpy() & (sensor != "").to_numpy(dtype=bool)
        )
        raw = sensor.to_numpy()
        listed = ", ".join(known) or "none"
        checks.flag(
            unknown,
            reason="unknown sensor",
            column="sensor",
            describe=lambda r: f"unknown sensor {fmt_value(raw[r])} (sensors.json has: {listed})",
        )

    range_m = as_float(df, "range_m", checks, required=True)
    flag_values(checks, range_m < 0, range_m, "range_m", "is negative")
    azimuth = as_float(df, "azimuth_deg", checks, required=True)
    flag_values(checks, (azimuth < 0) | (azimuth >= 360), azimuth, "azimuth_deg", "is outside [0, 360)")
    if "elevation_deg" in df.columns:
        elevation = as_float(df, "elevation_deg", checks, required=False)
        flag_values(checks, (elevation < -90) | (elevation > 90), elevation, "elevation_deg", "is outside [-90, 90]")
    for name in ("range_rate_mps", "mode_c_ft"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
    if "scan" in df.columns:
        as_int(df, "scan", checks, nullable=True)
    check_identity_columns(df, checks, report)
    if "truth_id" in df.columns:
        as_string(df, "truth_id", checks, required=False)

    codes, names = pd.factorize(sensor, use_na_sentinel=True)
    flag_time_backwards(
        checks,
        time,
        np.asarray(codes),
        [repr(str(n)) for n in names],
        strict_increase=False,
        group_label="sensor",
    )
    _warn_implausible_units(range_m, azimuth, report)
    df = checks.finish(df, lenient=lenient, report=report)
    return order_columns(df, PLOT_SCHEMA)


#: a table needs this many rows before its value ranges say anything about units
_UNIT_CHECK_MIN_ROWS = 50


def _warn_implausible_units(range_m: np.ndarray, azimuth: np.ndarray, report: ReadReport) -> None:
    """Warn when the values look like another unit than the column name says."""
    if len(range_m) < _UNIT_CHECK_MIN_ROWS:
        return
    largest_range = np.nanmax(np.asarray(range_m, dtype=float), initial=-np.inf)
    if 0 < largest_range < 1000.0:
        report.warn(f"range_m never exceeds {largest_range:g}: are the ranges in kilometres instead of metres?")
    largest_azimuth = np.nanmax(np.asarray(azimuth, dtype=float), initial=-np.inf)
    if 0 < largest_azimuth <= 2 * np.pi:
        report.warn(f"azimuth_deg never exceeds {largest_azimuth:g}: are the azimuths in radians instead of degrees?")


@overload
def read_plots(
    path: str | Path, sensors: SensorSet | None = ..., lenient: Literal[False] = ..., *, epoch_utc: object = ...
) -> pd.DataFrame: ...
@overload
def read_plots(
    path: str | Path, sensors: SensorSet | None = ..., lenient: Literal[True] = ..., *, epoch_utc: object = ...
) -> tuple[pd.DataFrame, ReadReport]: ...


def read_plots(path, sensors=None, lenient=False, *, epoch_utc=None):
    """Read and validate a plots table (.parquet/.pq/.csv/.csv.gz).

    Returns the plots DataFrame (FORMATS.md columns first, extras after); with
    ``lenient=True`` returns ``(plots, report)`` where bad rows were skipped and counted.
    Strict mode raises :class:`~skytrack.io.InputError` at the first bad row and sends
    report warnings (e.g. no epoch for timestamps) through :mod:`warnings`.
    """
    report = ReadReport(file=str(path))
    df, source = load_table(path, lenient=lenient, report=report)
    plots = _validate_plots(df, source, sensors, epoch_utc, lenient, report)
    emit_warnings(report, lenient)
    return (plots, report) if lenient else plots


def iter_plots(path, sensors=None, lenient=False, *, chunk_rows=1_000_000, epoch_utc=None, report=None):
    """Read and validate a plots table chunk by chunk; yields DataFrames of at most ``chunk_rows``.

    Parquet files are streamed (memory bounded by the chunk); CSV files are read whole and
    then handed out in chunks.  Errors name rows of the whole file.  In lenient mode pass a
    :class:`ReadReport` as ``report``: skips of every chunk are added to it.  Time order is
    checked within chunks here; across chunk boundaries the tracker checks it.
    """
    report = report if report is not None else ReadReport(file=str(path))
    if table_format(path) == "parquet":
        kept = 0
        for frame, source in iter_parquet(path, chunk_rows):
            report.rows_read += len(frame)
            plots = _validate_plots(frame, source, sensors, epoch_utc, lenient, report)
            kept += len(plots)
            report.rows_kept = kept  # the validator sets the count of its own chunk
            yield plots
    else:
        plots = read_plots(path, sensors, lenient, epoch_utc=epoch_utc)
        if lenient:
            plots, whole = plots
            report.rows_read += whole.rows_read
            report.rows_kept += whole.rows_kept
            report.skipped.update(whole.skipped)
            report.warnings.extend(whole.warnings)
        for start in range(0, len(plots), chunk_rows):
            yield plots.iloc[start : start + chunk_rows]
        return
    emit_warnings(report, lenient)


def write_plots(df: pd.DataFrame, path: str | Path, *, sensors: SensorSet | None = None) -> Path:
    """Validate ``df`` like :func:`read_plots` (strict) and write it in FORMATS.md order."""
    source = TableSource.for_frame(f"plots to write to {path}")
    report = ReadReport(file=source.display)
    plots = _validate_plots(df.reset_index(drop=True), source, sensors, None, False, report)
    emit_warnings(report, False)
    return write_table(plots, path)

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

from skytrack.core.plots import PLATFORM_COLUMNS, PlotBatch
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
from skytrack.io.errors import InputError, ReadReport
from skytrack.io.asterix.reading import is_asterix_input
from skytrack.io.plot_arrays import MODE_C_RANGE_FT, PlotStream, plot_batch_from_arrow
from skytrack.io.plot_repeats import RepeatedRows
from skytrack.io.time_units import BeamRateCheck
from skytrack.io.schema import PLOT_SCHEMA, TEXT_COLUMNS
from skytrack.io.tables import (
    TableSource,
    chunk_to_frame,
    iter_csv_tables,
    iter_parquet_tables,
    load_table,
    table_format,
    write_table,
)


def _validate_plots(
    df: pd.DataFrame,
    source: TableSource,
    sensors: SensorSet | None,
    epoch_utc: object,
    lenient: bool,
    report: ReadReport,
    stream: PlotStream | None = None,
) -> pd.DataFrame:
    """Check and coerce one table of plots; ``stream`` carries state from earlier chunks of the file."""
    require_columns(df, source, [("time", "timestamp"), "sensor", "range_m", "azimuth_deg"], "plots")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    epoch_text = epoch_utc if epoch_utc is not None else (sensors.epoch_utc if sensors is not None else None)
    epoch = parse_epoch(epoch_text) if epoch_text is not None else None
    if epoch is None and stream is not None:
        epoch = stream.epoch
    time = time_column(df, checks, epoch, report)
    if stream is not None and checks.inferred_epoch is not None:
        stream.epoch = checks.inferred_epoch

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
    if "range_rate_mps" in df.columns:
        as_float(df, "range_rate_mps", checks, required=False)
    platform = {name: as_float(df, name, checks, required=False) for name in PLATFORM_COLUMNS if name in df.columns}
    if sensors is not None:
        _flag_airborne_without_platform(checks, df, sensors, platform)
    if "mode_c_ft" in df.columns:
        mode_c = as_float(df, "mode_c_ft", checks, required=False)
        flag_values(checks, (mode_c < MODE_C_RANGE_FT[0]) | (mode_c > MODE_C_RANGE_FT[1]), mode_c, "mode_c_ft",
                    f"is outside [{MODE_C_RANGE_FT[0]:g}, {MODE_C_RANGE_FT[1]:g}] ft (the Mode C range)")
    if "scan" in df.columns:
        as_int(df, "scan", checks, nullable=True)
    check_identity_columns(df, checks, report)
    if "truth_id" in df.columns:
        as_string(df, "truth_id", checks, required=False)

    codes, names = pd.factorize(sensor, use_na_sentinel=True)
    codes = np.asarray(codes)
    group_names = [repr(str(n)) for n in names]
    if stream is not None:
        _flag_behind_earlier_chunks(checks, time, codes, names, group_names, stream.last_time)
    flag_time_backwards(
        checks,
        time,
        codes,
        group_names,
        strict_increase=False,
        group_label="sensor",
    )
    if stream is None:
        _warn_implausible_units(range_m, azimuth, report)
    else:
        stream.add_units(range_m, azimuth)
    df = order_columns(checks.finish(df, lenient=lenient, report=report), PLOT_SCHEMA)
    if stream is not None and len(df):
        latest = pd.Series(df["time"].to_numpy()).groupby(df["sensor"].to_numpy(dtype=object)).max()
        stream.add_latest(latest.index, latest.to_numpy())
    return df


def _flag_airborne_without_platform(checks: RowChecks, df: pd.DataFrame, sensors: SensorSet,
                                    platform: dict[str, np.ndarray]) -> None:
    """A plot of an airborne radar needs its carrier's position (``platform_x/y/z``)."""
    airborne = [s.name for s in sensors.sensors if s.is_moving]
    if not airborne:
        return
    mine = df["sensor"].isin(airborne).to_numpy()
    known = np.ones(len(df), dtype=bool)
    for name in ("platform_x", "platform_y", "platform_z"):
        known &= np.isfinite(platform[name]) if name in platform else False
    names = df["sensor"].to_numpy(dtype=object)
    checks.flag(mine & ~known, reason="airborne plot without platform position", column="platform_x",
                describe=lambda r: f"sensor {names[r]!r} is airborne: the plot needs platform_x/y/z (the carrier's "
                                   "position)")


def _flag_behind_earlier_chunks(
    checks: RowChecks, time: np.ndarray, codes: np.ndarray, names, group_names: list[str], last_time: dict[str, float]
) -> None:
    """Flag rows earlier than the latest time of their sensor in the earlier chunks.

    Together with :func:`flag_time_backwards` inside the chunk this flags exactly the rows
    a whole-file read flags, with the same message (the time compared with is the larger
    of the earlier chunks' latest and the running maximum inside the chunk).  Call it just
    before :func:`flag_time_backwards`: the rows it flags are then not flagged twice.
    """
    if not last_time:
        return
    carry_of_code = np.array([last_time.get(str(n), -np.inf) for n in names], dtype=float)
    grouped = codes >= 0
    carry = np.full(len(time), -np.inf)
    carry[grouped] = carry_of_code[codes[grouped]]
    eligible = grouped & ~checks.bad_rows() & np.isfinite(time)
    bad = eligible & (time < carry)
    if not bad.any():
        return

    def describe(row: int) -> str:
        before = eligible & (codes == codes[row])
        before[row:] = False
        earlier = max(carry[row], float(np.max(time[before], initial=-np.inf)))
        return (
            f"time {fmt_value(time[row])} is earlier than time {fmt_value(earlier)} "
            f"of an earlier row of sensor {group_names[codes[row]]}"
        )

    checks.flag(bad, reason="time goes backwards within a sensor", column="time", describe=describe)


#: a table needs this many rows before its value ranges say anything about units
_UNIT_CHECK_MIN_ROWS = 50
#: a tracking run stops on suspicious units only after this many plots: a radar's first
#: plots may all be clutter near the antenna
_UNIT_STOP_MIN_ROWS = 1000


def _warn_implausible_units(range_m: np.ndarray, azimuth: np.ndarray, report: ReadReport) -> None:
    """Warn when the values look like another unit than the column name says."""
    whole = PlotStream()
    whole.add_units(range_m, azimuth)
    _warn_units(whole, report)


def _warn_units(seen: PlotStream, report: ReadReport) -> None:
    for problem in _unit_problems(seen):
        report.warn(problem)


def _unit_problems(seen: PlotStream) -> list[str]:
    """What the value ranges seen so far say about units (nothing before enough rows)."""
    if seen.rows < _UNIT_CHECK_MIN_ROWS:
        return []
    problems = []
    if 0 < seen.largest_range < 1000.0:
        problems.append(f"range_m never exceeds {seen.largest_range:g}: are the ranges in kilometres instead of "
                        "metres?")
    if 0 < seen.largest_azimuth <= 2 * np.pi:
        problems.append(f"azimuth_deg never exceeds {seen.largest_azimuth:g}: are the azimuths in radians instead "
                        "of degrees?")
    return problems


@overload
def read_plots(
    path: str | Path, sensors: SensorSet | None = ..., lenient: Literal[False] = ..., *, epoch_utc: object = ...
) -> pd.DataFrame: ...
@overload
def read_plots(
    path: str | Path, sensors: SensorSet | None = ..., lenient: Literal[True] = ..., *, epoch_utc: object = ...
) -> tuple[pd.DataFrame, ReadReport]: ...


def read_plots(path, sensors=None, lenient=False, *, epoch_utc=None):
    """Read and validate a plots table (.parquet/.pq/.csv/.csv.gz), or the CAT048 plots of an
    ASTERIX recording (.ast/.asterix/.pcap; needs ``sensors`` with sac/sic, see
    :mod:`skytrack.io.asterix.reading`).

    Returns the plots DataFrame (FORMATS.md columns first, extras after); with
    ``lenient=True`` returns ``(plots, report)`` where bad rows were skipped and counted.
    Strict mode raises :class:`~skytrack.io.InputError` at the first bad row and sends
    report warnings (e.g. no epoch for timestamps) through :mod:`warnings`.
    """
    report = ReadReport(file=str(path))
    if is_asterix_input(path):
        plots = _asterix_plots(path, sensors, lenient, report)
    else:
        df, source = load_table(path, lenient=lenient, report=report)
        plots = _validate_plots(df, source, sensors, epoch_utc, lenient, report)
    repeated = RepeatedRows()
    repeated.add_frame(plots, 0)
    if repeated.message():
        report.warn(repeated.message())
    emit_warnings(report, lenient)
    return (plots, report) if lenient else plots


def iter_plots(path, sensors=None, lenient=False, *, chunk_rows=1_000_000, epoch_utc=None, report=None):
    """Read and validate a plots table chunk by chunk; yields DataFrames of at most ``chunk_rows``.

    Parquet and CSV files are both streamed: memory is bounded by the chunk, never the
    file.  The chunks are checked as the whole file would be: errors name rows (and CSV
    lines) of the whole file, time must not go backwards within a sensor across chunks
    either, the unit warnings look at the whole file, and when timestamps come without
    an epoch, time counts from the earliest timestamp of the first chunk that has one.
    In lenient mode pass a :class:`ReadReport` as ``report``: the skips of every chunk are
    added to it (counts as for a whole-file read).  Chunks left empty by a lenient read
    are not yielded.  Strict mode raises at the first bad chunk, so the error's count of
    further bad rows covers the rows read so far (malformed CSV lines are counted in the
    whole file).
    """
    yield from _checked_chunks(path, sensors, lenient, chunk_rows, epoch_utc, report, as_batches=False)


def iter_plot_batches(path, sensors: SensorSet, lenient=False, *, chunk_rows=1_000_000, epoch_utc=None,
                      report=None, units_confirmed=False, range_rate_positive_closing=False):
    """:func:`iter_plots` as :class:`~skytrack.core.plots.PlotBatch` chunks: parsed once, in SI
    units with integer identity codes, ready for the tracker (which does not check them again).
    Row numbers count the plots kept (what the tracker's messages refer to).

    Values that look like another unit (ranges all below 1 km, azimuths all within 2 pi over
    the first 1 000 plots or more) stop the reading with an :class:`InputError`, unless
    ``units_confirmed``: tracked as they are, they gave garbage tracks or none.

    A chunk whose every row is good goes from Arrow arrays to the batch directly
    (:mod:`skytrack.io.plot_arrays`); any other chunk is validated as by :func:`iter_plots`.

    ``range_rate_positive_closing``: the file's ``range_rate_mps`` is positive for a closing
    target (some radars' convention); it is negated into skytrack's ``dD/dt`` (spec 003 R2).
    """
    names = sensors.names
    is_3d = [s.is_3d for s in sensors.sensors]
    first_row = 0
    if is_asterix_input(path):
        yield from _asterix_batches(path, sensors, lenient, chunk_rows, report)
        return
    for chunk in _checked_chunks(path, sensors, lenient, chunk_rows, epoch_utc, report, as_batches=True,
                                 stop_on_units=not units_confirmed):
        if isinstance(chunk, PlotBatch):
            chunk.row += first_row
        else:
            chunk = PlotBatch.from_frame(chunk, names, is_3d, str(path), first_row=first_row, check=False)
        if range_rate_positive_closing:
            chunk.range_rate = -chunk.range_rate
        yield chunk
        first_row += len(chunk)


def _checked_chunks(path, sensors, lenient, chunk_rows, epoch_utc, report, *, as_batches: bool,
                    stop_on_units: bool = False):
    """The validated chunks of a plots file: DataFrames, or with ``as_batches`` a
    :class:`PlotBatch` for every chunk the fast path takes (rows numbered from 0) and a
    DataFrame for the others.  ``stop_on_units`` raises on values that look like another unit
    (:func:`_unit_problems`) before the chunk that shows it is handed out."""
    if chunk_rows < 1:
        raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
    report = report if report is not None else ReadReport(file=str(path))
    if table_format(path) == "parquet":
        text = sorted(TEXT_COLUMNS) if as_batches else ()
        chunks = iter_parquet_tables(path, chunk_rows, text_as_dictionary=text)
    else:
        chunks = iter_csv_tables(path, chunk_rows, lenient=lenient, report=report)
    epoch_text = epoch_utc if epoch_utc is not None else (sensors.epoch_utc if sensors is not None else None)
    stream = PlotStream()
    repeated = RepeatedRows()
    beam = BeamRateCheck(sensors)
    kept = 0
    for table, source in chunks:
        report.rows_read += len(table)
        plots = plot_batch_from_arrow(table, sensors, stream) if as_batches and sensors is not None else None
        if plots is not None and epoch_text is not None:
            parse_epoch(epoch_text)  # a bad epoch is an error even when no timestamp needs it
        if plots is None:
            frame = chunk_to_frame(table, source)
            plots = _validate_plots(frame, source, sensors, epoch_utc, lenient, report, stream)
        if beam.wants_more:
            if isinstance(plots, PlotBatch):
                beam.add(np.asarray(sensors.names, dtype=object)[plots.sensor], plots.time, np.degrees(plots.azimuth))
            else:
                beam.add(plots["sensor"].to_numpy(dtype=object), plots["time"].to_numpy(dtype=float),
                         plots["azimuth_deg"].to_numpy(dtype=float))
        if stop_on_units and stream.rows >= _UNIT_STOP_MIN_ROWS and (_unit_problems(stream) or beam.problems()):
            hint = "; ".join(_unit_problems(stream) + beam.problems())
            raise InputError(f"{hint} (FORMATS.md units: metres, degrees, seconds; if the values are right, "
                             "confirm the units: --units-confirmed)", file=str(path))
        if isinstance(plots, PlotBatch):
            repeated.add_batch(plots, sensors.names, kept)
        else:
            repeated.add_frame(plots, kept)
        kept += len(plots)
        report.rows_kept = kept  # the validator sets the count of its own chunk
        report.warnings[:] = dict.fromkeys(report.warnings)  # each chunk repeats conversions' warnings
        if len(plots):
            yield plots
    _warn_units(stream, report)
    for problem in beam.problems():
        report.warn(problem)
    if repeated.message():
        report.warn(repeated.message())
    emit_warnings(report, lenient)


def _asterix_plots(path, sensors: SensorSet | None, lenient: bool, report: ReadReport) -> pd.DataFrame:
    """The CAT048 plots of an ASTERIX recording, validated like a table's rows (numbered in time
    order; ``byte_offset`` locates each record in the file)."""
    from skytrack.io.asterix.reading import read_asterix_input

    if sensors is None:
        raise InputError("ASTERIX plots need sensors.json: its sensors' sac/sic name the sources", file=str(path))
    decoded = read_asterix_input(path, sensors, lenient=lenient, report=report)
    skipped_before = sum(entry.count for entry in report.skipped.values())
    report.rows_read += len(decoded.plots) + skipped_before
    source = TableSource.for_frame(f"{path} (CAT048 plots in time order)")
    plots = _validate_plots(decoded.plots, source, sensors, None, lenient, report)
    report.rows_kept = len(plots)
    return plots


def _asterix_batches(path, sensors: SensorSet, lenient: bool, chunk_rows: int, report: ReadReport | None):
    if chunk_rows < 1:
        raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
    report = report if report is not None else ReadReport(file=str(path))
    plots = _asterix_plots(path, sensors, lenient, report)
    emit_warnings(report, lenient)
    for start in range(0, len(plots), chunk_rows):
        chunk = plots.iloc[start:start + chunk_rows]
        yield PlotBatch.from_frame(chunk, sensors.names, [s.is_3d for s in sensors.sensors], str(path),
                                   first_row=start, check=False)


def write_plots(df: pd.DataFrame, path: str | Path, *, sensors: SensorSet | None = None) -> Path:
    """Validate ``df`` like :func:`read_plots` (strict) and write it in FORMATS.md order."""
    source = TableSource.for_frame(f"plots to write to {path}")
    report = ReadReport(file=source.display)
    plots = _validate_plots(df.reset_index(drop=True), source, sensors, None, False, report)
    emit_warnings(report, False)
    return write_table(plots, path)

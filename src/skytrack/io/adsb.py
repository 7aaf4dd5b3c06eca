"""ADS-B reports (FORMATS.md "adsb"): reader and writer.

Required: ``time`` (or ``timestamp``, converted as for plots), ``icao24`` (6 hex digits,
lower-cased), and a position ``x, y, z`` or ``lat, lon, alt_m``.  Geodetic positions are
converted to the origin's ENU frame (an origin is then required); when both are given,
both are kept as given.  Optional: ``sigma_m`` (> 0), ``callsign``, ``vx, vy, vz``
(finite or null).  The rows are not required to be in time order.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, overload

import pandas as pd

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.io.checks import (
    RowChecks,
    as_float,
    check_identity_columns,
    emit_warnings,
    flag_values,
    order_columns,
    require_columns,
    time_column,
)
from skytrack.io.errors import ReadReport
from skytrack.io.schema import ADSB_SCHEMA
from skytrack.io.tables import TableSource, load_table, write_table
from skytrack.io.truth import (
    POSITION_CHOICES,
    check_geodetic,
    fill_positions,
    frame_defaults,
    require_origin_for_geodetic,
)


def _validate_adsb(
    df: pd.DataFrame,
    source: TableSource,
    origin: Origin | None,
    epoch: pd.Timestamp | None,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    require_columns(df, source, [("time", "timestamp"), "icao24", POSITION_CHOICES], "adsb")
    require_origin_for_geodetic(df, source, origin, "adsb")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    time_column(df, checks, epoch, report)
    for name in ("x", "y", "z"):
        if name in df.columns:
            as_float(df, name, checks, required=True)
    if {"lat", "lon", "alt_m"} <= set(df.columns):
        check_geodetic(df, checks, required=True)
    if "sigma_m" in df.columns:
        sigma = as_float(df, "sigma_m", checks, required=False)
        flag_values(checks, sigma <= 0, sigma, "sigma_m", "is not > 0")
    for name in ("vx", "vy", "vz"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
    check_identity_columns(df, checks, report, required=("icao24",))
    df = checks.finish(df, lenient=lenient, report=report)
    if not {"x", "y", "z"} <= set(df.columns):
        fill_positions(df, origin)
    return order_columns(df, ADSB_SCHEMA)


@overload
def read_adsb(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    lenient: Literal[False] = ...,
) -> pd.DataFrame: ...
@overload
def read_adsb(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    lenient: Literal[True] = ...,
) -> tuple[pd.DataFrame, ReadReport]: ...


def read_adsb(path, *, sensors=None, origin=None, epoch_utc=None, lenient=False):
    """Read and validate ADS-B reports; ``origin``/``epoch_utc`` default to ``sensors``'.

    Returns the reports (always with ``x, y, z``), or ``(reports, report)`` when lenient.
    """
    origin, epoch = frame_defaults(sensors, origin, epoch_utc)
    report = ReadReport(file=str(path))
    df, source = load_table(path, lenient=lenient, report=report)
    adsb = _validate_adsb(df, source, origin, epoch, lenient, report)
    emit_warnings(report, lenient)
    return (adsb, report) if lenient else adsb


def write_adsb(df: pd.DataFrame, path: str | Path, *, origin: Origin | None = None) -> Path:
    """Validate ADS-B reports (strict) and write them in FORMATS.md order."""
    source = TableSource.for_frame(f"adsb to write to {path}")
    report = ReadReport(file=source.display)
    adsb = _validate_adsb(df.reset_index(drop=True), source, origin, None, False, report)
    emit_warnings(report, False)
    return write_table(adsb, path)

"""ADS-B reports (FORMATS.md "adsb"): reader and writer, in three input layouts.

These are the reports η_μ of spec 001's second observation system ((0a), (1): a position
with a Gaussian error of covariance V_η = sigma_m² I per horizontal axis); the
identification (:mod:`skytrack.identify`) takes them from here.

Layouts, told apart by the column names (:func:`adsb_layout`):

``adsb``     FORMATS.md: ``time`` (or ``timestamp``, converted as for plots), ``icao24``
             (6 hex digits, lower-cased), and a position ``x, y, z`` or ``lat, lon,
             alt_m``; geodetic positions are converted to the origin's ENU frame (an origin
             is then required; when both are given, both are kept as given).  Optional:
             ``sigma_m`` (> 0), ``nacp`` (integer 0-11), ``callsign``, ``vx, vy, vz``
             (finite or null), ``truth_id`` (the simulator's target id, kept as text).
``opensky``  the OpenSky database's state vectors (``time``, ``icao24``, ``lat``, ``lon``,
             ``baroaltitude``/``geoaltitude``, ``velocity``, ``heading``, ``vertrate``)
``traffic``  the ``traffic`` library's (``timestamp``, ``latitude``, ``longitude``,
             ``altitude``/``geoaltitude`` in ft, ``groundspeed`` in kt, ``track``,
             ``vertical_rate`` in ft/min)

The two state-vector layouts are read by :func:`skytrack.io.read_state_vectors` (also
JSON lines) and converted: POSIX time to seconds since ``epoch_utc``, the position to the
origin's ENU frame, ground speed / course / vertical rate to an ENU velocity in the
origin's frame (a missing vertical rate counts as level; no ground speed or course: no
velocity).  A row without a position (latitude, longitude or the altitude missing) is an
error naming its row in strict mode, skipped and counted in the read report in lenient
mode; it is never dropped silently.

NACp -> sigma_m (FORMATS.md): the NACp value bounds the estimated position uncertainty
(EPU), the radius that holds the true position with 95 % probability.  For a circular
Gaussian with per-axis sd σ the radius holding 95 % is σ √(-2 ln 0.05) = 2.4477 σ, so
``sigma_m = EPU / 2.4477``; a row with ``nacp`` and no ``sigma_m`` gets that value (NACp 0,
unknown accuracy, gets none).  ``default_sigma_m`` fills what is still missing.
"""

from __future__ import annotations

import csv
import math
import warnings
from pathlib import Path
from typing import Literal, overload

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.io.checks import (
    RowChecks,
    as_float,
    as_string,
    check_identity_columns,
    emit_warnings,
    flag_values,
    order_columns,
    require_columns,
    time_column,
)
from skytrack.io.asterix.reading import is_asterix_input, read_asterix_adsb
from skytrack.io.csv_text import open_text
from skytrack.io.errors import InputError, InputWarning, ReadReport
from skytrack.io.frames import enu_from_geodetic, local_to_origin_velocity
from skytrack.io.schema import ADSB_SCHEMA, STRING_DTYPE
from skytrack.io.state_vectors import JSON_SUFFIXES, OPENSKY_LAYOUT, TRAFFIC_LAYOUT, read_state_vectors
from skytrack.io.tables import TableSource, load_table, table_format, write_table
from skytrack.io.truth import (
    POSITION_CHOICES,
    check_geodetic,
    fill_positions,
    frame_defaults,
    require_origin_for_geodetic,
)

ADSB_LAYOUTS = ("adsb", "opensky", "traffic")
#: per-axis sd over the radius holding 95 % of a circular Gaussian: sqrt(-2 ln 0.05)
EPU95_PER_SIGMA = math.sqrt(-2.0 * math.log(0.05))
#: NACp -> bound on the 95 % horizontal position uncertainty (EPU), metres (DO-260B); 0 = unknown
NACP_EPU_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6, 7: 185.2, 8: 92.6,
              9: 30.0, 10: 10.0, 11: 3.0}


def nacp_sigma_m(nacp) -> np.ndarray:
    """Per-axis sigma (m) of NACp values: EPU / 2.4477 (module docstring); NaN for 0 or null."""
    values = np.asarray(nacp, dtype=float)
    table = np.full(12, np.nan)
    for level, epu in NACP_EPU_M.items():
        table[level] = epu / EPU95_PER_SIGMA
    valid = np.isfinite(values) & (values >= 0) & (values <= 11) & (values == np.round(values))
    return np.where(valid, table[np.where(valid, values, 0).astype(np.int64)], np.nan)


def adsb_layout(columns) -> str:
    """``traffic`` (``latitude``/``longitude``), ``opensky`` (``lat``/``lon`` with a
    ``baroaltitude``/``geoaltitude`` and no ``alt_m``), else ``adsb`` (FORMATS.md)."""
    names = set(map(str, columns))
    if {TRAFFIC_LAYOUT.lat, TRAFFIC_LAYOUT.lon} & names:
        return "traffic"
    if {OPENSKY_LAYOUT.baro, OPENSKY_LAYOUT.geo} & names and "alt_m" not in names and not {"x", "y", "z"} <= names:
        return "opensky"
    return "adsb"


def _header(path: Path) -> list[str] | None:
    """Column names of a Parquet or CSV file; None for JSON (always state vectors)."""
    if path.name.lower().endswith(JSON_SUFFIXES):
        return None
    fmt = table_format(path)
    if not path.is_file():
        raise InputError("file not found", file=str(path))
    try:
        if fmt == "parquet":
            return list(pq.read_schema(path).names)
        with open_text(path) as stream:
            return next((record for record in csv.reader(stream) if record), [])
    except (OSError, EOFError, UnicodeDecodeError, csv.Error, pa.ArrowException):
        return []  # unreadable: the table reader reports it with its own message


def _nacp(df: pd.DataFrame, checks: RowChecks) -> None:
    values = as_float(df, "nacp", checks, required=False)
    flag_values(checks, (values < 0) | (values > 11) | (values != np.round(values)), values, "nacp",
                "is not an integer in 0-11")


def _fill_sigma(df: pd.DataFrame, default_sigma_m: float | None) -> None:
    sigma = df["sigma_m"].to_numpy(dtype=float) if "sigma_m" in df.columns else np.full(len(df), np.nan)
    if "nacp" in df.columns:
        sigma = np.where(np.isnan(sigma), nacp_sigma_m(df["nacp"].to_numpy(dtype=float)), sigma)
    if default_sigma_m is not None:
        sigma = np.where(np.isnan(sigma), default_sigma_m, sigma)
    if "sigma_m" in df.columns or not np.isnan(sigma).all():
        df["sigma_m"] = sigma


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
    if "nacp" in df.columns:
        _nacp(df, checks)
    for name in ("vx", "vy", "vz"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
    if "truth_id" in df.columns:
        as_string(df, "truth_id", checks, required=False)
    check_identity_columns(df, checks, report, required=("icao24",))
    df = checks.finish(df, lenient=lenient, report=report)
    if not {"x", "y", "z"} <= set(df.columns):
        fill_positions(df, origin)
    return order_columns(df, ADSB_SCHEMA)


def _state_vector_reports(
    path: Path,
    header: list[str] | None,
    origin: Origin | None,
    epoch: pd.Timestamp | None,
    altitude: str,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    """OpenSky / traffic state vectors as ADS-B reports (module docstring)."""
    is_csv = header is not None and table_format(path) == "csv"
    source = TableSource(display=str(path), path=path, is_csv=is_csv, n_fields=len(header or []))
    if origin is None:
        raise source.error("converting state vectors to ADS-B reports needs an origin (sensors.json or origin=)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InputWarning)
        states = read_state_vectors(path, altitude=altitude)
    for warning in caught:
        if lenient:
            report.warn(str(warning.message).removeprefix(f"{path}: "))
        else:
            warnings.warn(str(warning.message), InputWarning, stacklevel=4)
    report.rows_read += len(states)
    lat, lon, alt = (states[name].to_numpy(dtype=float) for name in ("lat", "lon", "alt_m"))
    no_position = ~(np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt))
    if no_position.any():
        altitude_column = states.attrs.get("altitude_column", "altitude")
        checks = RowChecks(source, len(states))
        checks.flag(no_position, reason="no position", column=None, describe=lambda r: (
            "no position (latitude, longitude or " + altitude_column + " missing): an ADS-B report needs one"))
        states = checks.finish(states, lenient=lenient, report=report)
        lat, lon, alt = (states[name].to_numpy(dtype=float) for name in ("lat", "lon", "alt_m"))
    report.rows_kept = len(states)
    posix = states["time"].to_numpy(dtype=float)
    if epoch is None:
        start = float(np.min(posix)) if posix.size else 0.0
        report.warn(f"no epoch_utc known (sensors.json has none): time counts from the earliest time stamp "
                    f"{pd.Timestamp(start, unit='s', tz='UTC').isoformat()}")
        time = posix - start
    else:
        time = posix - (epoch - pd.Timestamp("1970-01-01", tz="UTC")) / pd.Timedelta(seconds=1)
    enu = enu_from_geodetic(lat, lon, alt, origin).reshape(-1, 3)
    speed = states["groundspeed_mps"].to_numpy(dtype=float)
    course = np.radians(states["track_deg"].to_numpy(dtype=float))
    climb = np.nan_to_num(states["vertical_rate_mps"].to_numpy(dtype=float), nan=0.0)
    local = np.column_stack([speed * np.sin(course), speed * np.cos(course), climb])
    velocity = local_to_origin_velocity(lat, lon, local, origin).reshape(-1, 3)
    velocity[~(np.isfinite(speed) & np.isfinite(course))] = np.nan
    reports = pd.DataFrame({
        "time": time, "icao24": states["icao24"].to_numpy(), "x": enu[:, 0], "y": enu[:, 1], "z": enu[:, 2],
        "lat": lat, "lon": lon, "alt_m": alt, "sigma_m": np.full(len(states), np.nan),
        "callsign": states["callsign"].to_numpy(), "vx": velocity[:, 0], "vy": velocity[:, 1], "vz": velocity[:, 2],
        "squawk": states["squawk"].to_numpy(), "onground": states["onground"].to_numpy(dtype=bool),
    })
    for name in ("icao24", "callsign", "squawk"):
        reports[name] = reports[name].astype(STRING_DTYPE)
    reports.attrs["layout"] = states.attrs.get("layout", "state vectors")
    return reports


@overload
def read_adsb(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    lenient: Literal[False] = ...,
    default_sigma_m: float | None = ...,
    altitude: str = ...,
) -> pd.DataFrame: ...
@overload
def read_adsb(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    lenient: Literal[True] = ...,
    default_sigma_m: float | None = ...,
    altitude: str = ...,
) -> tuple[pd.DataFrame, ReadReport]: ...


def read_adsb(path, *, sensors=None, origin=None, epoch_utc=None, lenient=False, default_sigma_m=None,
              altitude="auto"):
    """Read and validate ADS-B reports in any of :data:`ADSB_LAYOUTS` (module docstring).

    ``origin``/``epoch_utc`` default to ``sensors``'.  ``default_sigma_m`` (> 0) is the
    ``sigma_m`` of reports that have neither ``sigma_m`` nor a NACp.  ``altitude`` chooses
    the height of state vectors (``auto``, ``geometric``, ``barometric``, as
    :func:`skytrack.io.read_state_vectors`).  Returns the reports (always with ``x, y, z``;
    ``df.attrs["layout"]`` says which layout was read), or ``(reports, report)`` when lenient.
    """
    if default_sigma_m is not None and not (math.isfinite(default_sigma_m) and default_sigma_m > 0.0):
        raise ValueError(f"default_sigma_m must be a finite number > 0, got {default_sigma_m!r}")
    path = Path(path)
    origin, epoch = frame_defaults(sensors, origin, epoch_utc)
    report = ReadReport(file=str(path))
    header = None if is_asterix_input(path) else _header(path)
    layout = "state vectors" if header is None else adsb_layout(header)
    if is_asterix_input(path):  # CAT021 reports (skytrack.io.asterix.reading), checked as a table
        layout = "asterix"
        df = read_asterix_adsb(path, origin=origin, epoch_utc=None if epoch is None else epoch.isoformat(),
                               lenient=lenient, report=report)
        report.rows_read += len(df)
        adsb = _validate_adsb(df, TableSource.for_frame(f"{path} (CAT021 reports)"), origin, epoch, lenient, report)
    elif header is None or layout != "adsb":
        adsb = _state_vector_reports(path, header, origin, epoch, altitude, lenient, report)
        layout = adsb.attrs["layout"]
    else:
        df, source = load_table(path, lenient=lenient, report=report)
        adsb = _validate_adsb(df, source, origin, epoch, lenient, report)
    _fill_sigma(adsb, default_sigma_m)
    adsb = order_columns(adsb, ADSB_SCHEMA)
    adsb.attrs["layout"] = layout
    emit_warnings(report, lenient)
    return (adsb, report) if lenient else adsb


def write_adsb(df: pd.DataFrame, path: str | Path, *, origin: Origin | None = None) -> Path:
    """Validate ADS-B reports (strict) and write them in FORMATS.md order (extras such as
    ``nacp`` and ``truth_id`` after the known columns)."""
    source = TableSource.for_frame(f"adsb to write to {path}")
    report = ReadReport(file=source.display)
    adsb = _validate_adsb(df.reset_index(drop=True), source, origin, None, False, report)
    emit_warnings(report, False)
    return write_table(adsb, path)

"""Reference trajectories (FORMATS.md "truth"), including OpenSky state vectors.

Truth layout: ``time`` (or ``timestamp``), ``target_id``, a position as ``x, y, z`` or
``lat, lon, alt_m`` (converted with the origin), optional ``segment`` (default 0),
``vx, vy, vz`` (default: finite differences along each segment, central inside,
one-sided at the ends), ``visible`` (default True; nulls become True with a warning).
Checks: every number present is finite, lat in [-90, 90], lon in [-180, 180],
``segment`` a non-negative integer, ``time`` strictly increasing within each
(``target_id``, ``segment``) so that the linear interpolation between rows is defined.

OpenSky state-vector layout (recognised by ``icao24``, ``latitude``, ``longitude`` and no
``target_id``): ``timestamp`` or ``time`` (POSIX seconds), altitude from ``geoaltitude``
(GNSS, preferred: ``alt_m`` is a height above the ellipsoid), else ``altitude``
(barometric), in feet as in the ``traffic`` library, or metres when named ``*_m``.
Velocity from ``groundspeed`` (kt), ``track`` (deg) and ``vertical_rate`` (ft/min) in the
aircraft's own ENU frame rotated to the origin's, row by row where reported, else by
finite differences.  Rows are sorted by (icao24, time); repeated (icao24, time) rows keep
the first (counted as a warning); a segment ends at a gap longer than ``max_gap_s``.
``target_id`` is the icao24; other columns (callsign, squawk, onground, ...) are kept.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, overload

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.geo.wgs84 import enu_rotation
from skytrack.io.checks import (
    ICAO24_PATTERN,
    RowChecks,
    as_bool,
    as_float,
    as_int,
    as_string,
    emit_warnings,
    flag_pattern,
    flag_time_backwards,
    flag_values,
    normalise_code,
    order_columns,
    parse_epoch,
    require_columns,
    time_column,
    timestamps_to_seconds,
)
from skytrack.io.errors import ReadReport
from skytrack.io.frames import (
    FT_PER_MIN_TO_MPS,
    FT_TO_M,
    KNOT_TO_MPS,
    enu_from_geodetic,
    finite_difference_velocity,
    geodetic_from_enu,
    group_codes,
    local_to_origin_velocity,
)
from skytrack.io.schema import TRUTH_SCHEMA
from skytrack.io.tables import TableSource, load_table, write_table

DEFAULT_MAX_GAP_S = 60.0
ALTITUDE_COLUMNS = ("geoaltitude", "geoaltitude_m", "altitude", "altitude_m")
POSITION_CHOICES = (("x", "y", "z"), ("lat", "lon", "alt_m"))


def frame_defaults(
    sensors: SensorSet | None, origin: Origin | None, epoch_utc: object
) -> tuple[Origin | None, pd.Timestamp | None]:
    if origin is None and sensors is not None:
        origin = sensors.origin
    if epoch_utc is None and sensors is not None:
        epoch_utc = sensors.epoch_utc
    return origin, (parse_epoch(epoch_utc) if epoch_utc is not None else None)


def is_opensky_layout(columns) -> bool:
    names = set(map(str, columns))
    return "target_id" not in names and {"icao24", "latitude", "longitude"} <= names


def check_geodetic(df: pd.DataFrame, checks: RowChecks, *, required: bool) -> None:
    """lat/lon/alt_m columns as floats with latitude and longitude ranges."""
    lat = as_float(df, "lat", checks, required=required)
    flag_values(checks, (lat < -90) | (lat > 90), lat, "lat", "is outside [-90, 90]")
    lon = as_float(df, "lon", checks, required=required)
    flag_values(checks, (lon < -180) | (lon > 180), lon, "lon", "is outside [-180, 180]")
    as_float(df, "alt_m", checks, required=required)


def fill_positions(df: pd.DataFrame, origin: Origin | None) -> None:
    """Add x/y/z from lat/lon/alt_m or lat/lon/alt_m from x/y/z when one side is absent."""
    has_enu = {"x", "y", "z"} <= set(df.columns)
    has_geo = {"lat", "lon", "alt_m"} <= set(df.columns)
    if origin is None or (has_enu and has_geo):
        return
    if has_geo:
        enu = enu_from_geodetic(df["lat"].to_numpy(), df["lon"].to_numpy(), df["alt_m"].to_numpy(), origin)
        for i, name in enumerate(("x", "y", "z")):
            df[name] = enu[:, i]
    elif has_enu:
        geo = geodetic_from_enu(df["x"].to_numpy(), df["y"].to_numpy(), df["z"].to_numpy(), origin)
        for i, name in enumerate(("lat", "lon", "alt_m")):
            df[name] = geo[:, i]


def require_origin_for_geodetic(df: pd.DataFrame, source: TableSource, origin: Origin | None, table: str) -> None:
    if origin is None and not {"x", "y", "z"} <= set(df.columns):
        raise source.error(
            f"{table} positions are given as lat/lon/alt_m only: an origin (sensors.json) "
            "is needed to convert them to x/y/z"
        )


def _fill_velocity(df: pd.DataFrame, groups: np.ndarray, report: ReadReport) -> None:
    missing = [name for name in ("vx", "vy", "vz") if name not in df.columns]
    if not missing:
        return
    positions = df[["x", "y", "z"]].to_numpy(dtype=np.float64)
    velocity, isolated = finite_difference_velocity(df["time"].to_numpy(), positions, groups)
    for i, name in enumerate(("vx", "vy", "vz")):
        if name in missing:
            df[name] = velocity[:, i]
    if isolated.any():
        report.warn(f"{int(isolated.sum())} segment(s) have a single row: their velocity is unknown and set to 0")


def _validate_truth(
    df: pd.DataFrame,
    source: TableSource,
    origin: Origin | None,
    epoch: pd.Timestamp | None,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    require_columns(df, source, [("time", "timestamp"), "target_id", POSITION_CHOICES], "truth")
    require_origin_for_geodetic(df, source, origin, "truth")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    time = time_column(df, checks, epoch, report)
    target = as_string(df, "target_id", checks, required=True)
    if "segment" in df.columns:
        as_int(df, "segment", checks, nullable=False)
        segment = df["segment"].to_numpy()
        flag_values(checks, segment < 0, segment, "segment", "is negative")
    else:
        df["segment"] = np.zeros(len(df), dtype=np.int64)
    for name in ("x", "y", "z", "vx", "vy", "vz"):
        if name in df.columns:
            as_float(df, name, checks, required=True)
    if {"lat", "lon", "alt_m"} & set(df.columns):
        for name in ("lat", "lon", "alt_m"):
            if name not in df.columns:
                raise source.error(
                    f"has {', '.join(c for c in ('lat', 'lon', 'alt_m') if c in df.columns)} but not {name}"
                )
        check_geodetic(df, checks, required=True)
    if "visible" in df.columns:
        as_bool(df, "visible", checks, default=True, report=report)
    else:
        df["visible"] = np.ones(len(df), dtype=bool)
    for name in ("callsign", "icao24", "squawk"):
        if name in df.columns:
            as_string(df, name, checks, required=False)

    groups, labels = group_codes(target, df["segment"])
    flag_time_backwards(
        checks,
        time,
        groups,
        [f"{str(t)!r} segment {s}" for t, s in labels],
        strict_increase=True,
        group_label="target",
    )
    df = checks.finish(df, lenient=lenient, report=report)
    fill_positions(df, origin)
    groups, _ = group_codes(df["target_id"], df["segment"])
    _fill_velocity(df, groups, report)
    return order_columns(df, TRUTH_SCHEMA)


def _pick_altitude(df: pd.DataFrame, source: TableSource, altitude_column: str | None) -> str:
    if altitude_column is not None:
        if altitude_column not in df.columns:
            raise source.error(
                f"altitude column {altitude_column!r} not found (found: {', '.join(map(str, df.columns))})"
            )
        return altitude_column
    return next(name for name in ALTITUDE_COLUMNS if name in df.columns)


def _validated_opensky(
    df: pd.DataFrame,
    source: TableSource,
    epoch: pd.Timestamp | None,
    altitude_name: str,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    """State vectors with checked columns and ``time`` in seconds since the epoch."""
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    time = timestamps_to_seconds(df, "timestamp" if "timestamp" in df.columns else "time", checks, epoch, report)
    icao24 = as_string(df, "icao24", checks, required=True).str.lower()
    df["icao24"] = icao24
    flag_pattern(checks, icao24, "icao24", ICAO24_PATTERN, "a 24-bit hex address (6 hex digits)")
    lat = as_float(df, "latitude", checks, required=True)
    flag_values(checks, (lat < -90) | (lat > 90), lat, "latitude", "is outside [-90, 90]")
    lon = as_float(df, "longitude", checks, required=True)
    flag_values(checks, (lon < -180) | (lon > 180), lon, "longitude", "is outside [-180, 180]")
    as_float(df, altitude_name, checks, required=True)
    for name in ("groundspeed", "track", "vertical_rate"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
    if "squawk" in df.columns:
        normalise_code(df, "squawk", 4, report)
        as_string(df, "squawk", checks, required=False)
    if "callsign" in df.columns:
        as_string(df, "callsign", checks, required=False)
    df["time"] = time
    return checks.finish(df, lenient=lenient, report=report)


def _sorted_without_repeats(df: pd.DataFrame, report: ReadReport) -> pd.DataFrame:
    """Rows sorted by (icao24, time); a row repeating the previous one's time is dropped."""
    df = df.sort_values(["icao24", "time"], kind="stable").reset_index(drop=True)
    icao24 = df["icao24"].to_numpy()
    time = df["time"].to_numpy()
    repeated = np.zeros(len(df), dtype=bool)
    repeated[1:] = (icao24[1:] == icao24[:-1]) & (time[1:] == time[:-1])
    if repeated.any():
        report.warn(f"{int(repeated.sum())} row(s) repeat the time of the previous row of the same icao24; first kept")
        df = df.loc[~repeated].reset_index(drop=True)
    return df


def _segments(aircraft: np.ndarray, time: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Segment index within each aircraft (rows sorted by aircraft, time): a gap > max_gap_s starts one."""
    n = len(time)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    new_aircraft = np.ones(n, dtype=bool)
    new_aircraft[1:] = aircraft[1:] != aircraft[:-1]
    gap = np.zeros(n, dtype=bool)
    gap[1:] = (time[1:] - time[:-1]) > max_gap_s
    count = np.cumsum(gap & ~new_aircraft)
    first_row_of_aircraft = np.maximum.accumulate(np.where(new_aircraft, np.arange(n), 0))
    return (count - count[first_row_of_aircraft]).astype(np.int64)


def _opensky_to_truth(
    df: pd.DataFrame,
    source: TableSource,
    origin: Origin | None,
    epoch: pd.Timestamp | None,
    max_gap_s: float,
    altitude_column: str | None,
    lenient: bool,
    report: ReadReport,
) -> pd.DataFrame:
    require_columns(
        df, source, [("timestamp", "time"), "icao24", "latitude", "longitude", ALTITUDE_COLUMNS], "OpenSky state-vector"
    )
    if origin is None:
        raise source.error("converting OpenSky state vectors needs an origin (sensors.json or origin=)")
    altitude_name = _pick_altitude(df, source, altitude_column)
    df = _validated_opensky(df, source, epoch, altitude_name, lenient, report)
    df = _sorted_without_repeats(df, report)

    aircraft = np.asarray(pd.factorize(df["icao24"])[0], dtype=np.int64)
    t = df["time"].to_numpy()
    segment = _segments(aircraft, t, max_gap_s)
    alt_m = df[altitude_name].to_numpy() * (1.0 if altitude_name.endswith("_m") else FT_TO_M)
    lat = df["latitude"].to_numpy()
    lon = df["longitude"].to_numpy()
    positions = enu_from_geodetic(lat, lon, alt_m, origin)
    groups = aircraft * (int(segment.max(initial=0)) + 1) + segment
    velocity, isolated = finite_difference_velocity(t, positions, groups)
    velocity, reported = _reported_velocity(df, lat, lon, velocity, origin)
    unknown = isolated & ~reported
    if unknown.any():
        report.warn(
            f"{int(unknown.sum())} segment(s) have a single row and no reported ground speed/track: "
            "their horizontal velocity is unknown and set to 0"
        )

    truth = pd.DataFrame(
        {
            "time": t,
            "target_id": df["icao24"],
            "segment": segment,
            "x": positions[:, 0],
            "y": positions[:, 1],
            "z": positions[:, 2],
            "vx": velocity[:, 0],
            "vy": velocity[:, 1],
            "vz": velocity[:, 2],
            "lat": lat,
            "lon": lon,
            "alt_m": alt_m,
            "visible": np.ones(len(df), dtype=bool),
        }
    )
    consumed = {"time", "latitude", "longitude", altitude_name}
    for name in df.columns:
        if name not in consumed and name not in truth.columns:
            truth[name] = df[name]
    return truth


def _reported_velocity(
    df: pd.DataFrame, lat: np.ndarray, lon: np.ndarray, fd: np.ndarray, origin: Origin
) -> tuple[np.ndarray, np.ndarray]:
    """Replace finite-difference velocity by the reported one where the report has it.

    Returns the velocities and the mask of rows with a reported horizontal velocity.
    """
    n = len(df)
    gs = df["groundspeed"].to_numpy() if "groundspeed" in df.columns else np.full(n, np.nan)
    track = df["track"].to_numpy() if "track" in df.columns else np.full(n, np.nan)
    vrate = df["vertical_rate"].to_numpy() if "vertical_rate" in df.columns else np.full(n, np.nan)
    horizontal = np.isfinite(gs) & np.isfinite(track)
    vertical = np.isfinite(vrate)
    if not (horizontal.any() or vertical.any()):
        return fd, horizontal
    # the finite-difference velocity in each aircraft's own frame, overridden where reported
    r_origin = enu_rotation(origin.lat, origin.lon)
    phi, lam = np.radians(lat), np.radians(lon)
    sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
    # rows E, N, U of each point's ECEF->ENU rotation, stacked [n, 3, 3]
    r_point = np.stack(
        [
            np.column_stack([-sl, cl, np.zeros(n)]),
            np.column_stack([-sp * cl, -sp * sl, cp]),
            np.column_stack([cp * cl, cp * sl, sp]),
        ],
        axis=1,
    )
    fd_local = np.einsum("nij,jk,nk->ni", r_point, r_origin.T, fd)
    speed = gs * KNOT_TO_MPS
    heading = np.radians(track)
    local_v = fd_local.copy()
    local_v[horizontal, 0] = (speed * np.sin(heading))[horizontal]
    local_v[horizontal, 1] = (speed * np.cos(heading))[horizontal]
    local_v[vertical, 2] = (vrate * FT_PER_MIN_TO_MPS)[vertical]
    return local_to_origin_velocity(lat, lon, local_v, origin), horizontal


@overload
def read_truth(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    max_gap_s: float = ...,
    altitude_column: str | None = ...,
    lenient: Literal[False] = ...,
) -> pd.DataFrame: ...
@overload
def read_truth(
    path: str | Path,
    *,
    sensors: SensorSet | None = ...,
    origin: Origin | None = ...,
    epoch_utc: object = ...,
    max_gap_s: float = ...,
    altitude_column: str | None = ...,
    lenient: Literal[True] = ...,
) -> tuple[pd.DataFrame, ReadReport]: ...


def read_truth(
    path,
    *,
    sensors=None,
    origin=None,
    epoch_utc=None,
    max_gap_s=DEFAULT_MAX_GAP_S,
    altitude_column=None,
    lenient=False,
):
    """Read truth (FORMATS.md layout or OpenSky state vectors) as the truth layout.

    ``origin`` and ``epoch_utc`` default to those of ``sensors``.  Returns the truth
    DataFrame, or ``(truth, report)`` with ``lenient=True``.
    """
    origin, epoch = frame_defaults(sensors, origin, epoch_utc)
    report = ReadReport(file=str(path))
    df, source = load_table(path, lenient=lenient, report=report)
    if is_opensky_layout(df.columns):
        truth = _opensky_to_truth(df, source, origin, epoch, max_gap_s, altitude_column, lenient, report)
    else:
        truth = _validate_truth(df, source, origin, epoch, lenient, report)
    emit_warnings(report, lenient)
    return (truth, report) if lenient else truth


def write_truth(df: pd.DataFrame, path: str | Path, *, origin: Origin | None = None) -> Path:
    """Validate ``df`` as truth (strict), fill the documented defaults, write it.

    With an ``origin``, lat/lon/alt_m are added when absent (or x/y/z from them);
    without one, absent lat/lon/alt_m stay absent.
    """
    source = TableSource.for_frame(f"truth to write to {path}")
    report = ReadReport(file=source.display)
    truth = _validate_truth(df.reset_index(drop=True), source, origin, None, False, report)
    emit_warnings(report, False)
    return write_table(truth, path)

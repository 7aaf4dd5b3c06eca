"""Recorded aircraft state vectors (ADS-B, OpenSky) read into SI units.

:func:`read_state_vectors` reads one file in either of the two common layouts, told
apart by their column names (FORMATS.md, "Recorded state vectors"):

``traffic``  the ``traffic`` library's: ``timestamp``, ``icao24``, ``latitude``,
             ``longitude``, ``altitude`` (barometric) and/or ``geoaltitude`` in ft,
             ``groundspeed`` in kt, ``track`` in deg, ``vertical_rate`` in ft/min;
``opensky``  the OpenSky database's: ``time`` (POSIX s), ``icao24``, ``lat``, ``lon``,
             ``baroaltitude``/``geoaltitude`` in m, ``velocity`` in m/s, ``heading`` in
             deg, ``vertrate`` in m/s;

both with optional ``callsign``, ``squawk`` and ``onground``.  Files are Parquet
(``.parquet``/``.pq``), CSV (``.csv``/``.csv.gz``) or JSON (``.jsonl``, ``.ndjson``,
``.json``, each optionally ``.gz``): JSON lines, or one JSON array of records as the
``traffic`` library's sample files hold.

The result has the columns of :data:`STATE_COLUMNS` in SI units, rows in file order
(:func:`skytrack.sim.cleaning.clean_states` sorts them and counts what was out of
order).  Missing values (no position in a row, no speed) stay NaN: recorded data have
them, and cleaning drops or bridges them.  Problems that make the file unusable are one
:class:`~skytrack.io.errors.InputError` naming the file and, where it applies, the row
and column: an unknown layout, a missing required column or one without any value,
text where numbers belong, latitudes or longitudes out of range, negative speeds.
"""

from __future__ import annotations

import gzip
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.io.checks import (
    ICAO24_PATTERN,
    MODE3A_PATTERN,
    RowChecks,
    as_bool,
    as_float,
    as_string,
    emit_warnings,
    flag_pattern,
    flag_values,
    timestamps_to_seconds,
)
from skytrack.io.errors import InputError, ReadReport
from skytrack.io.frames import FT_PER_MIN_TO_MPS, FT_TO_M, KNOT_TO_MPS
from skytrack.io.schema import STRING_DTYPE
from skytrack.io.tables import TableSource, load_table

#: columns of :func:`read_state_vectors`' result, in order
STATE_COLUMNS = (
    "time", "icao24", "callsign", "squawk", "onground", "lat", "lon", "alt_m",
    "baro_alt_m", "geo_alt_m", "groundspeed_mps", "track_deg", "vertical_rate_mps",
)
ALTITUDE_CHOICES = ("auto", "geometric", "barometric")
JSON_SUFFIXES = (".jsonl", ".ndjson", ".json", ".jsonl.gz", ".ndjson.gz", ".json.gz")
#: numeric epochs at or above this are milliseconds: 1e11 POSIX seconds is the year 5138,
#: while pandas' JSON writer (used by the traffic library) stores datetimes in milliseconds
MILLISECOND_EPOCH_THRESHOLD = 1e11

_UNIX_ZERO = pd.Timestamp("1970-01-01", tz="UTC")


@dataclass(frozen=True)
class Layout:
    """Column names of one state-vector layout and the factors that turn its units into SI."""

    name: str
    time: str
    lat: str
    lon: str
    baro: str
    geo: str
    speed: str
    course: str
    climb: str
    altitude_to_m: float
    speed_to_mps: float
    climb_to_mps: float


TRAFFIC_LAYOUT = Layout(
    "traffic", time="timestamp", lat="latitude", lon="longitude", baro="altitude", geo="geoaltitude",
    speed="groundspeed", course="track", climb="vertical_rate",
    altitude_to_m=FT_TO_M, speed_to_mps=KNOT_TO_MPS, climb_to_mps=FT_PER_MIN_TO_MPS,
)
OPENSKY_LAYOUT = Layout(
    "opensky", time="time", lat="lat", lon="lon", baro="baroaltitude", geo="geoaltitude",
    speed="velocity", course="heading", climb="vertrate",
    altitude_to_m=1.0, speed_to_mps=1.0, climb_to_mps=1.0,
)
LAYOUTS = (TRAFFIC_LAYOUT, OPENSKY_LAYOUT)


def _required_text(layout: Layout) -> str:
    return f"{layout.time}, icao24, {layout.lat}, {layout.lon}, {layout.baro} and/or {layout.geo}"


def detect_layout(columns, source: TableSource) -> Layout:
    """The layout whose position columns the table has (``latitude``/``longitude`` or ``lat``/``lon``;
    one of the pair is enough to tell, the other one is then reported missing)."""
    names = set(map(str, columns))
    found = [layout for layout in LAYOUTS if {layout.lat, layout.lon} & names]
    if len(found) == 1:
        return found[0]
    shown = ", ".join(map(str, columns)) or "none"
    if found:
        raise source.error(
            "ambiguous state-vector layout: it has both latitude/longitude (traffic) and lat/lon "
            f"(OpenSky database) columns; keep one pair (found: {shown})"
        )
    raise source.error(
        "unknown state-vector layout: expected the traffic library's columns "
        f"({_required_text(TRAFFIC_LAYOUT)}) or the OpenSky database's ({_required_text(OPENSKY_LAYOUT)}); "
        f"found: {shown}"
    )


# ---------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------


def _is_json(path: Path) -> bool:
    return path.name.lower().endswith(JSON_SUFFIXES)


def _read_json(path: Path) -> tuple[pd.DataFrame, TableSource]:
    """JSON lines, or a JSON array of records; every value kept as parsed (no type guessing)."""
    source = TableSource(display=str(path), path=path)
    if not path.is_file():
        raise InputError("file not found", file=str(path))
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    lines = True
    try:
        with opener(path, "rt", encoding="utf-8-sig") as handle:
            # a JSON array of records (traffic's sample files) or one object per line
            lines = not handle.read(4096).lstrip().startswith("[")
        # dtype=False: digits-only addresses ("393320") and squawks stay text
        df = pd.read_json(path, lines=lines, dtype=False, compression="infer", encoding="utf-8-sig")
    except (ValueError, OSError, EOFError, UnicodeDecodeError) as exc:
        kind = "JSON lines" if lines else "a JSON array of records"
        raise InputError(f"cannot read as {kind}: {exc}", file=str(path)) from None
    if not isinstance(df, pd.DataFrame):  # pragma: no cover - read_json with lines/records gives frames
        raise InputError("the JSON does not hold records", file=str(path))
    return df, source


def _load(path: Path) -> tuple[pd.DataFrame, TableSource]:
    if _is_json(path):
        return _read_json(path)
    try:
        return load_table(path)
    except InputError as exc:
        if "unsupported file extension" in exc.message:
            raise InputError(
                "unsupported file extension for state vectors; use .parquet, .pq, .csv, .csv.gz, "
                ".jsonl, .ndjson or .json (each JSON one optionally .gz)",
                file=str(path),
            ) from None
        raise


# ---------------------------------------------------------------------------------
# columns
# ---------------------------------------------------------------------------------


def _check_not_empty(df: pd.DataFrame, source: TableSource, names: list[str]) -> None:
    """A required column without a single value is an error (NaN-only columns)."""
    for name in names:
        if not df[name].notna().any():
            raise source.error("has no value in any row (a required column)", column=name)


def _altitude_column(df: pd.DataFrame, source: TableSource, layout: Layout, altitude: str) -> tuple[str, str]:
    """The altitude column used as the height, and which kind it is (geometric / barometric)."""
    if altitude not in ALTITUDE_CHOICES:
        raise ValueError(f"altitude must be one of {', '.join(ALTITUDE_CHOICES)}, got {altitude!r}")
    present = {
        "geometric": layout.geo if layout.geo in df.columns and df[layout.geo].notna().any() else None,
        "barometric": layout.baro if layout.baro in df.columns and df[layout.baro].notna().any() else None,
    }
    if altitude == "auto":
        # GNSS height is the closer one to the height above the ellipsoid the simulator uses
        kind = "geometric" if present["geometric"] else "barometric"
    else:
        kind = altitude
    name = layout.geo if kind == "geometric" else layout.baro
    if name not in df.columns:
        raise source.error(f"has no {kind} altitude column {name!r} (found: {', '.join(map(str, df.columns))})")
    _check_not_empty(df, source, [name])
    return name, kind


def _epoch_seconds(df: pd.DataFrame, layout: Layout, checks: RowChecks, report: ReadReport) -> np.ndarray:
    """POSIX seconds of every row; numeric epochs in milliseconds are recognised by size."""
    name = layout.time
    series = df[name]
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        finite = np.isfinite(values)
        if finite.any() and np.max(np.abs(values[finite])) >= MILLISECOND_EPOCH_THRESHOLD:
            df[name] = values / 1000.0
            report.warn(f"column {name} holds epoch milliseconds (values >= 1e11); read as milliseconds")
    return timestamps_to_seconds(df, name, checks, _UNIX_ZERO, report)


def _squawks(df: pd.DataFrame, checks: RowChecks, report: ReadReport) -> pd.Series:
    """Squawks as 4 octal digits; leading zeros lost to a number type are restored, others nulled."""
    if "squawk" not in df.columns:
        return pd.Series(pd.array([None] * len(df), dtype=STRING_DTYPE))
    series = df["squawk"]
    if pd.api.types.is_float_dtype(series.dtype) or pd.api.types.is_integer_dtype(series.dtype):
        values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        whole = np.isfinite(values) & (values == np.round(values))
        text = np.where(whole, np.char.mod("%d", np.where(whole, values, 0).astype(np.int64)), None)
        series = pd.Series(text, index=df.index, dtype=object)
    df["squawk"] = series
    text = as_string(df, "squawk", checks, required=False).str.strip()
    short = text.str.fullmatch(r"[0-7]{1,3}").fillna(False).to_numpy(dtype=bool)
    if short.any():
        report.warn(f"column squawk: {int(short.sum())} code(s) of fewer than 4 digits padded with leading zeros")
        text = text.str.zfill(4)
    valid = text.str.fullmatch(MODE3A_PATTERN).fillna(False).to_numpy(dtype=bool)
    invalid = text.notna().to_numpy() & ~valid
    if invalid.any():
        report.warn(f"column squawk: {int(invalid.sum())} value(s) are not 4 octal digits; read as no code")
        text = text.where(valid)
    return text


def _optional_float(df: pd.DataFrame, name: str, checks: RowChecks, factor: float) -> np.ndarray:
    if name not in df.columns:
        return np.full(len(df), np.nan)
    return as_float(df, name, checks, required=False) * factor


def _convert(df: pd.DataFrame, source: TableSource, layout: Layout, altitude: str, report: ReadReport) -> pd.DataFrame:
    needed = [layout.time, "icao24", layout.lat, layout.lon]
    missing = [name for name in needed if name not in df.columns]
    if layout.baro not in df.columns and layout.geo not in df.columns:
        missing.append(f"{layout.baro} or {layout.geo}")
    if missing:
        raise source.error(
            f"missing required column(s) of the {layout.name} state-vector layout: {', '.join(missing)} "
            f"(needed: {_required_text(layout)}; found: {', '.join(map(str, df.columns))})"
        )
    if len(df) == 0:
        raise source.error("has no rows (no state vectors)")
    _check_not_empty(df, source, needed)
    altitude_name, altitude_kind = _altitude_column(df, source, layout, altitude)

    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    time = _epoch_seconds(df, layout, checks, report)
    icao24 = as_string(df, "icao24", checks, required=True).str.strip().str.lower()
    flag_pattern(checks, icao24, "icao24", ICAO24_PATTERN, "a 24-bit hex address (6 hex digits)")
    lat = as_float(df, layout.lat, checks, required=False)
    flag_values(checks, np.abs(lat) > 90.0, lat, layout.lat, "is outside [-90, 90]")
    lon = as_float(df, layout.lon, checks, required=False)
    flag_values(checks, np.abs(lon) > 180.0, lon, layout.lon, "is outside [-180, 180]")
    baro = _optional_float(df, layout.baro, checks, layout.altitude_to_m)
    geo = _optional_float(df, layout.geo, checks, layout.altitude_to_m)
    speed = _optional_float(df, layout.speed, checks, layout.speed_to_mps)
    flag_values(checks, speed < 0.0, speed, layout.speed, "is negative")
    course = _optional_float(df, layout.course, checks, 1.0)
    climb = _optional_float(df, layout.climb, checks, layout.climb_to_mps)
    callsign = (
        as_string(df, "callsign", checks, required=False).str.strip().replace("", None)
        if "callsign" in df.columns else pd.Series(pd.array([None] * len(df), dtype=STRING_DTYPE))
    )
    squawk = _squawks(df, checks, report)
    if "onground" in df.columns:
        as_bool(df, "onground", checks, default=False, report=report)
        onground = df["onground"].to_numpy(dtype=bool)
    else:
        onground = np.zeros(len(df), dtype=bool)
    checks.finish(df, lenient=False, report=report)

    out = pd.DataFrame(
        {
            "time": time,
            "icao24": icao24.to_numpy(),
            "callsign": callsign.astype(STRING_DTYPE).to_numpy(),
            "squawk": squawk.astype(STRING_DTYPE).to_numpy(),
            "onground": onground,
            "lat": lat,
            "lon": lon,
            "alt_m": geo if altitude_kind == "geometric" else baro,
            "baro_alt_m": baro,
            "geo_alt_m": geo,
            "groundspeed_mps": speed,
            "track_deg": np.remainder(course, 360.0),
            "vertical_rate_mps": climb,
        }
    )
    for name in ("icao24", "callsign", "squawk"):
        out[name] = out[name].astype(STRING_DTYPE)
    out.attrs.update({"file": source.display, "layout": layout.name, "altitude": altitude_kind,
                      "altitude_column": altitude_name})
    return out


def read_state_vectors(path: str | Path, *, altitude: str = "auto") -> pd.DataFrame:
    """Read recorded state vectors (traffic or OpenSky-database layout) in SI units.

    ``altitude`` chooses the height used as ``alt_m``: ``geometric`` (GNSS,
    ``geoaltitude``), ``barometric`` (``altitude`` / ``baroaltitude``, used as a height
    without pressure correction) or ``auto`` (geometric when the file has any, else
    barometric).  Returns a DataFrame with :data:`STATE_COLUMNS`; ``df.attrs`` holds
    ``layout``, ``altitude`` (the kind used) and ``altitude_column``.  Conversion
    warnings (squawks padded, epoch milliseconds) go through :mod:`warnings` as
    :class:`~skytrack.io.errors.InputWarning`.
    """
    path = Path(path)
    report = ReadReport(file=str(path))
    df, source = _load(path)
    layout = detect_layout(df.columns, source)
    states = _convert(df, source, layout, altitude, report)
    emit_warnings(report, lenient=False)
    return states

"""Vectorised row validation shared by the table readers and writers.

A :class:`RowChecks` collects problems as boolean masks over the rows of a table (one
numpy/pandas operation per check, never a Python loop over rows).  Messages are built
only for the first offending rows.  :meth:`RowChecks.finish` then raises the earliest
problem as :class:`InputError` (strict mode) or drops every flagged row and counts it in
the :class:`ReadReport` (lenient mode).

The ``as_*`` helpers coerce one column to the dtype policy of :mod:`skytrack.io.schema`
and flag cells that cannot be converted (text in a numeric column, a fractional value in
an integer column, an unparseable timestamp, ...).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from skytrack.io.errors import MAX_EXAMPLES, InputError, InputWarning, ReadReport
from skytrack.io.schema import IFF_VALUES, STRING_DTYPE, TableSchema
from skytrack.io.tables import TableSource

Describe = Callable[[int], str]

MODE3A_PATTERN = r"[0-7]{4}"
ICAO24_PATTERN = r"[0-9a-f]{6}"


def fmt_value(value: object) -> str:
    """A cell value as shown in messages: numbers as Python prints them, text quoted."""
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return str(int(value))
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return "null"
    return repr(str(value))


@dataclass
class _Problem:
    reason: str
    column: str | None
    rows: np.ndarray
    describe: Describe


class RowChecks:
    """Collects located row problems of one table."""

    def __init__(self, source: TableSource, n_rows: int) -> None:
        self.source = source
        self.n_rows = n_rows
        #: the epoch :func:`timestamps_to_seconds` chose when none was known (chunked reads reuse it)
        self.inferred_epoch: pd.Timestamp | None = None
        self._problems: list[_Problem] = []

    def flag(self, mask_or_rows: np.ndarray, *, reason: str, column: str | None, describe: Describe) -> None:
        """Record rows (a boolean mask over all rows, or row positions) that have a problem."""
        arr = np.asarray(mask_or_rows)
        rows = np.flatnonzero(arr) if arr.dtype == bool else np.unique(arr.astype(np.int64))
        if rows.size:
            self._problems.append(_Problem(reason, column, rows, describe))

    def bad_rows(self) -> np.ndarray:
        mask = np.zeros(self.n_rows, dtype=bool)
        for problem in self._problems:
            mask[problem.rows] = True
        return mask

    def finish(self, df: pd.DataFrame, *, lenient: bool, report: ReadReport | None) -> pd.DataFrame:
        """Raise the earliest problem (strict) or drop and count the bad rows (lenient)."""
        if not self._problems:
            if report is not None:
                report.rows_kept = len(df)
            return df
        bad = self.bad_rows()
        if not lenient or report is None:
            first = min(self._problems, key=lambda p: int(p.rows[0]))
            row = int(first.rows[0])
            raise self.source.error(first.describe(row), row=row, column=first.column, more=int(bad.sum()) - 1)
        for problem in self._problems:
            shown = problem.rows[:MAX_EXAMPLES]
            issues = self.source.issues(shown, problem.column, [problem.describe(int(r)) for r in shown])
            report.add_skipped(problem.reason, int(problem.rows.size), issues)
        kept = df.loc[~bad].reset_index(drop=True)
        report.rows_kept = len(kept)
        return kept


def emit_warnings(report: ReadReport, lenient: bool) -> None:
    """Strict mode returns no report: its warnings go through :mod:`warnings`."""
    if not lenient:
        for message in report.warnings:
            warnings.warn(f"{report.file}: {message}", InputWarning, stacklevel=3)


# ---------------------------------------------------------------------------------
# column presence and order
# ---------------------------------------------------------------------------------


Needed = str | tuple[str | tuple[str, ...], ...]


def require_columns(df: pd.DataFrame, source: TableSource, needed: Sequence[Needed], table: str) -> None:
    """Raise one error listing every missing required column and what was found.

    An entry of ``needed`` is a column name or a tuple of alternatives; an alternative is
    a name or a tuple of names that must all be present (``(("x", "y", "z"), ("lat", "lon",
    "alt_m"))``).
    """
    present = set(map(str, df.columns))
    missing = []
    for entry in needed:
        options = (entry,) if isinstance(entry, str) else entry
        groups = [(o,) if isinstance(o, str) else tuple(o) for o in options]
        if not any(set(group) <= present for group in groups):
            missing.append(" or ".join("/".join(group) for group in groups))
    if missing:
        found = ", ".join(map(str, df.columns)) or "no columns"
        hints = _unit_hints(missing, present)
        raise source.error(f"missing required {table} column(s): {', '.join(missing)} (found: {found}){hints}")


#: unit suffixes of FORMATS.md column names and their meaning
_UNITS = {"m": "metres", "km": "kilometres", "nm": "nautical miles", "ft": "feet", "deg": "degrees",
          "rad": "radians", "mrad": "milliradians", "s": "seconds", "ms": "milliseconds", "mps": "m/s",
          "kt": "knots", "fpm": "feet per minute"}


def _unit_hints(missing: Sequence[str], present: set[str]) -> str:
    """Name columns that are the wanted quantity in another unit (``range_km`` for ``range_m``)."""
    hints = []
    for wanted in (name for entry in missing for name in entry.replace(" or ", "/").split("/")):
        stem, _, unit = wanted.rpartition("_")
        if not stem or unit not in _UNITS:
            continue
        for other in sorted(present):
            other_stem, _, other_unit = other.rpartition("_")
            if other_stem == stem and other_unit != unit and other_unit in _UNITS:
                hints.append(f"{other} is in {_UNITS[other_unit]}, FORMATS.md wants {wanted} in {_UNITS[unit]}")
    return "; " + "; ".join(hints) if hints else ""


def order_columns(df: pd.DataFrame, schema: TableSchema) -> pd.DataFrame:
    """Known columns in FORMATS.md order, then the extra columns in their original order."""
    known = [c for c in schema.names if c in df.columns]
    extra = [c for c in df.columns if c not in schema.names]
    return df[known + extra]


# ---------------------------------------------------------------------------------
# coercion of one column
# ---------------------------------------------------------------------------------


def _is_text(series: pd.Series) -> bool:
    return (
        pd.api.types.is_string_dtype(series.dtype)
        or series.dtype == object
        or isinstance(series.dtype, pd.CategoricalDtype)
    )


def numeric_values(df: pd.DataFrame, name: str, checks: RowChecks) -> np.ndarray:
    """Column ``name`` as float64 (NaN = missing); text that is not a number is flagged."""
    series = df[name]
    dtype = series.dtype
    if pd.api.types.is_bool_dtype(dtype) or pd.api.types.is_datetime64_any_dtype(dtype):
        raise checks.source.error(f"has type {dtype}, expected numbers", column=name)
    if dtype == np.float64:
        return series.to_numpy()
    if pd.api.types.is_numeric_dtype(dtype):
        return series.to_numpy(dtype=np.float64, na_value=np.nan)
    if not _is_text(series):
        raise checks.source.error(f"has type {dtype}, expected numbers", column=name)
    text = series.astype(object) if isinstance(dtype, pd.CategoricalDtype) else series
    values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    not_number = series.notna().to_numpy() & np.isnan(values)
    if not_number.any():
        raw = series.to_numpy()
        checks.flag(
            not_number,
            reason=f"{name} not a number",
            column=name,
            describe=lambda r: f"value {fmt_value(raw[r])} is not a number",
        )
    return values


def as_float(
    df: pd.DataFrame,
    name: str,
    checks: RowChecks,
    *,
    required: bool,
    finite: bool = True,
) -> np.ndarray:
    """Coerce a float column in place; flag missing (if required) and infinite values."""
    values = numeric_values(df, name, checks)
    missing = np.isnan(values)
    if required and missing.any():
        # text that failed conversion is already flagged as "not a number"
        raw_missing = df[name].isna().to_numpy() if not pd.api.types.is_numeric_dtype(df[name].dtype) else missing
        checks.flag(missing & raw_missing, reason=f"{name} missing", column=name, describe=lambda r: "missing value")
    if finite:
        infinite = np.isinf(values)
        if infinite.any():
            checks.flag(
                infinite,
                reason=f"{name} not finite",
                column=name,
                describe=lambda r: f"value {fmt_value(values[r])} is not finite",
            )
    if df[name].dtype != np.float64:
        df[name] = values
    return values


def as_int(df: pd.DataFrame, name: str, checks: RowChecks, *, nullable: bool) -> None:
    """Coerce an integer column in place (int64, or Int64 when nullable)."""
    series = df[name]
    if pd.api.types.is_integer_dtype(series.dtype) and not series.isna().any():
        df[name] = series.astype(pd.Int64Dtype() if nullable else np.int64)
        return
    values = numeric_values(df, name, checks)
    missing = np.isnan(values)
    if not nullable:
        raw_missing = series.isna().to_numpy()
        checks.flag(missing & raw_missing, reason=f"{name} missing", column=name, describe=lambda r: "missing value")
    fractional = ~missing & ((values != np.round(values)) | np.isinf(values))
    checks.flag(
        fractional,
        reason=f"{name} not an integer",
        column=name,
        describe=lambda r: f"value {fmt_value(values[r])} is not an integer",
    )
    clean = np.where(missing | fractional, 0.0, values).astype(np.int64)
    if nullable:
        df[name] = pd.arrays.IntegerArray(clean, missing.copy())
    else:
        df[name] = clean


def as_string(df: pd.DataFrame, name: str, checks: RowChecks, *, required: bool) -> pd.Series:
    """Coerce a text column in place; a required one may not be null or empty."""
    series = df[name]
    if pd.api.types.is_float_dtype(series.dtype):
        # whole numbers written by a tool as floats (e.g. ids with nulls): no ".0"
        values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        finite = np.isfinite(values)
        if np.all(values[finite] == np.round(values[finite])):
            series = pd.Series(pd.arrays.IntegerArray(np.where(finite, values, 0).astype(np.int64), ~finite))
    if isinstance(series.dtype, pd.CategoricalDtype):
        series = series.astype(object)
    text = series.astype(STRING_DTYPE) if series.dtype != STRING_DTYPE else series
    text.index = df.index
    if required:
        empty = (text.isna() | (text == "")).to_numpy(dtype=bool)
        checks.flag(empty, reason=f"{name} missing", column=name, describe=lambda r: "missing value")
    df[name] = text
    return text


def as_bool(df: pd.DataFrame, name: str, checks: RowChecks, *, default: bool, report: ReadReport | None) -> None:
    """Coerce a boolean column in place; nulls take ``default`` (counted as a warning)."""
    series = df[name]
    missing = series.isna().to_numpy()
    if pd.api.types.is_bool_dtype(series.dtype) and not missing.any():
        df[name] = series.to_numpy(dtype=bool)
        return
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        result = values == 1.0
        invalid = ~missing & ~np.isin(values, (0.0, 1.0))
    elif pd.api.types.is_bool_dtype(series.dtype):
        result = series.fillna(False).to_numpy(dtype=bool)
        invalid = np.zeros(len(series), dtype=bool)
    else:
        lowered = series.astype(STRING_DTYPE).str.strip().str.lower()
        result = lowered.isin(["true", "1", "yes", "t", "y"]).to_numpy(dtype=bool)
        invalid = ~missing & ~(result | lowered.isin(["false", "0", "no", "f", "n"]).to_numpy(dtype=bool))
    raw = series.to_numpy()
    checks.flag(
        invalid,
        reason=f"{name} not a boolean",
        column=name,
        describe=lambda r: f"value {fmt_value(raw[r])} is not true/false",
    )
    if missing.any():
        result = np.where(missing, default, result)
        if report is not None:
            report.warn(f"column {name}: {int(missing.sum())} null value(s) set to {default}")
    df[name] = result.astype(bool)


def flag_values(checks: RowChecks, bad: np.ndarray, values: np.ndarray, name: str, rule: str) -> None:
    """Flag rows where ``bad`` and the value is finite (non-finite ones are flagged apart).

    ``rule`` completes "value 361.2 ..." (e.g. "is outside [0, 360)").
    """
    bad = np.asarray(bad, dtype=bool) & np.isfinite(values)
    if np.any(bad):
        checks.flag(
            bad,
            reason=f"{name} {rule.removeprefix('is ')}",
            column=name,
            describe=lambda r: f"value {fmt_value(values[r])} {rule}",
        )


def flag_pattern(checks: RowChecks, text: pd.Series, name: str, pattern: str, expected: str) -> None:
    """Flag non-null text that does not match ``pattern`` entirely."""
    ok = text.str.fullmatch(pattern).fillna(True).to_numpy(dtype=bool) | text.isna().to_numpy()
    if not ok.all():
        raw = text.to_numpy()
        checks.flag(
            ~ok,
            reason=f"{name} not {expected}",
            column=name,
            describe=lambda r: f"value {fmt_value(raw[r])} is not {expected}",
        )


def flag_not_in(checks: RowChecks, text: pd.Series, name: str, allowed: Sequence[str]) -> None:
    """Flag non-null text outside ``allowed``."""
    ok = text.isin(list(allowed)).to_numpy(dtype=bool) | text.isna().to_numpy()
    if not ok.all():
        raw = text.to_numpy()
        choices = ", ".join(allowed)
        checks.flag(
            ~ok,
            reason=f"{name} not one of {choices}",
            column=name,
            describe=lambda r: f"value {fmt_value(raw[r])} is not one of {choices}",
        )


def normalise_code(df: pd.DataFrame, name: str, width: int, report: ReadReport | None) -> None:
    """Integer-typed octal codes (Mode 3/A, squawk) lost their leading zeros: pad them."""
    series = df[name]
    if not pd.api.types.is_numeric_dtype(series.dtype) or pd.api.types.is_bool_dtype(series.dtype):
        return
    values = series.to_numpy(dtype=np.float64, na_value=np.nan)
    whole = np.isfinite(values) & (values == np.round(values)) & (values >= 0)
    padded = pd.Series(np.where(whole, values, 0).astype(np.int64)).astype(str).str.zfill(width).to_numpy(dtype=object)
    # other numbers stay visible as text, so that the code check names them
    other = series.astype(str).to_numpy(dtype=object)
    text = np.where(whole, padded, np.where(np.isnan(values), None, other))
    df[name] = pd.Series(text, index=df.index, dtype=object).astype(STRING_DTYPE)
    if report is not None:
        report.warn(f"column {name} holds numbers; read as {width}-digit text with leading zeros")


# ---------------------------------------------------------------------------------
# time
# ---------------------------------------------------------------------------------


def parse_epoch(epoch_utc: object, source_name: str = "epoch_utc") -> pd.Timestamp:
    """An epoch as a UTC :class:`pandas.Timestamp` (naive values are taken as UTC)."""
    try:
        stamp = pd.Timestamp(epoch_utc)
    except (ValueError, TypeError):
        raise InputError(f"{source_name} {epoch_utc!r} is not a timestamp") from None
    if pd.isna(stamp):
        raise InputError(f"{source_name} {epoch_utc!r} is not a timestamp")
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def timestamps_to_seconds(
    df: pd.DataFrame,
    name: str,
    checks: RowChecks,
    epoch: pd.Timestamp | None,
    report: ReadReport,
) -> np.ndarray:
    """Seconds since ``epoch`` of a timestamp column (datetimes, ISO text or POSIX seconds).

    Without an epoch, time counts from the earliest timestamp; the report says so.
    """
    series = df[name]
    raw = series.to_numpy()
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        stamps = series.dt.tz_localize("UTC") if series.dt.tz is None else series.dt.tz_convert("UTC")
    elif pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        posix = series.to_numpy(dtype=np.float64, na_value=np.nan)
        stamps = None
    elif _is_text(series):
        stamps = pd.to_datetime(series.astype(object), utc=True, errors="coerce", format="ISO8601")
        unparsed = series.notna().to_numpy() & stamps.isna().to_numpy()
        checks.flag(
            unparsed,
            reason=f"{name} not a timestamp",
            column=name,
            describe=lambda r: f"value {fmt_value(raw[r])} is not an ISO 8601 timestamp",
        )
    else:
        raise checks.source.error(f"has type {series.dtype}, expected timestamps", column=name)

    unix_zero = pd.Timestamp("1970-01-01", tz="UTC")
    if stamps is not None:
        # differences of datetimes are exact integers: no float rounding of POSIX seconds
        offsets = (stamps - unix_zero).to_numpy()
        posix = np.asarray(offsets / np.timedelta64(1, "s"), dtype=np.float64)
    missing = np.isnan(posix) & series.isna().to_numpy()
    checks.flag(missing, reason=f"{name} missing", column=name, describe=lambda r: "missing value")
    infinite = np.isinf(posix)
    checks.flag(
        infinite,
        reason=f"{name} not finite",
        column=name,
        describe=lambda r: f"value {fmt_value(raw[r])} is not finite",
    )

    finite = np.isfinite(posix)
    if epoch is None:
        if not finite.any():
            return posix
        first_row = int(np.flatnonzero(finite)[np.argmin(posix[finite])])
        epoch = unix_zero + (
            pd.Timedelta(offsets[first_row]) if stamps is not None else pd.Timedelta(seconds=posix[first_row])
        )
        report.warn(
            f"no epoch_utc known (sensors.json has none): time counts from the earliest {name} {epoch.isoformat()}"
        )
        checks.inferred_epoch = epoch
    if stamps is None:
        return posix - (epoch - unix_zero) / pd.Timedelta(seconds=1)
    seconds = (offsets - (epoch - unix_zero).to_timedelta64()) / np.timedelta64(1, "s")
    return np.asarray(seconds, dtype=np.float64)


def time_column(
    df: pd.DataFrame,
    checks: RowChecks,
    epoch: pd.Timestamp | None,
    report: ReadReport,
) -> np.ndarray:
    """Fill ``time`` (float s since the scenario epoch) from ``time`` or ``timestamp``.

    A ``timestamp`` column is kept as an extra column when ``time`` is computed from it;
    a ``time`` column holding datetimes is converted in place like a timestamp.
    """
    if "time" in df.columns:
        if pd.api.types.is_datetime64_any_dtype(df["time"].dtype):
            seconds = timestamps_to_seconds(df, "time", checks, epoch, report)
            df["time"] = seconds
            return seconds
        return as_float(df, "time", checks, required=True)
    seconds = timestamps_to_seconds(df, "timestamp", checks, epoch, report)
    df.insert(0, "time", seconds)
    return seconds


def flag_time_backwards(
    checks: RowChecks,
    time: np.ndarray,
    groups: np.ndarray,
    group_names: Sequence[str],
    *,
    strict_increase: bool,
    group_label: str,
) -> None:
    """Flag rows whose time is earlier than an earlier row of the same group.

    ``groups`` are integer codes (-1 = row excluded).  Rows already flagged by other
    checks are excluded too, so in lenient mode the kept rows are ordered in each group.
    A row is "backwards" when its time is below the running maximum of the earlier rows
    of its group (or equal to it when ``strict_increase``); the first such row is also
    the first row whose time is below the previous row of its group.
    """
    eligible = (groups >= 0) & ~checks.bad_rows() & np.isfinite(time)
    positions = np.flatnonzero(eligible)
    if positions.size < 2:
        return
    t = pd.Series(time[positions])
    codes = groups[positions]
    running = t.groupby(codes, sort=False).cummax()
    previous = running.groupby(codes, sort=False).shift(1).to_numpy(dtype=np.float64, na_value=np.nan)
    values = t.to_numpy()
    bad = (values <= previous) if strict_increase else (values < previous)
    if not bad.any():
        return
    bad_rows = positions[bad]
    previous_of = dict(
        zip(bad_rows[: 2 * MAX_EXAMPLES].tolist(), previous[bad][: 2 * MAX_EXAMPLES].tolist(), strict=True)
    )
    relation = "is not after" if strict_increase else "is earlier than"

    def describe(row: int) -> str:
        group = group_names[int(groups[row])]
        return (
            f"time {fmt_value(time[row])} {relation} time {fmt_value(previous_of[row])} "
            f"of an earlier row of {group_label} {group}"
        )

    order = "does not increase" if strict_increase else "goes backwards"
    checks.flag(bad_rows, reason=f"time {order} within a {group_label.split()[0]}", column="time", describe=describe)


def check_identity_columns(
    df: pd.DataFrame, checks: RowChecks, report: ReadReport | None, *, required: Sequence[str] = ()
) -> None:
    """mode3a (4 octal digits), icao24/mode_s (6 hex digits, lower-cased), iff, callsign."""
    if "mode3a" in df.columns:
        normalise_code(df, "mode3a", 4, report)
        code = as_string(df, "mode3a", checks, required="mode3a" in required)
        flag_pattern(checks, code, "mode3a", MODE3A_PATTERN, "4 octal digits")
    for name in ("mode_s", "icao24"):
        if name in df.columns:
            text = as_string(df, name, checks, required=name in required).str.lower()
            df[name] = text
            flag_pattern(checks, text, name, ICAO24_PATTERN, "a 24-bit hex address (6 hex digits)")
    if "iff" in df.columns:
        flag_not_in(checks, as_string(df, "iff", checks, required="iff" in required), "iff", IFF_VALUES)
    if "callsign" in df.columns:
        as_string(df, "callsign", checks, required="callsign" in required)

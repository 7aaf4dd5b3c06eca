"""Identity events beside a tracks file (docs/formats.md "identity events"): path, writer, reader.

One row per change of a track's ``icao24``, ``callsign``, ``mode3a`` or ``iff``:
``time, track_id, field, old, new, source, identity_p`` (the rows of
:class:`skytrack.tracker.identity.IdentityEvents`; issue 8, spec 003 R14's identity history).
The file sits next to the tracks: ``tracks.parquet`` -> ``tracks.identity.parquet``,
``tracks.csv`` -> ``tracks.identity.csv`` (:func:`identity_events_path`).

Checks (both directions): ``time`` finite, ``track_id`` an integer, ``field`` one of
:data:`~skytrack.core.tracks.IDENTITY_EVENT_FIELDS`; ``old``/``new`` null or a value of their
field (``mode3a`` 4 octal digits, ``icao24`` 6 hex digits, lower-cased, ``iff``
friend/foe/undetermined, ``callsign`` any text); ``source`` one of
:data:`~skytrack.core.tracks.IDENTITY_SOURCES` or null; ``identity_p`` in [0, 1] or null.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, overload

import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from skytrack.core.tracks import IDENTITY_EVENT_FIELDS, IDENTITY_SOURCES
from skytrack.io.checks import (
    ICAO24_PATTERN,
    MODE3A_PATTERN,
    RowChecks,
    as_float,
    as_int,
    as_string,
    emit_warnings,
    flag_not_in,
    flag_pattern,
    flag_values,
    order_columns,
    require_columns,
)
from skytrack.io.errors import InputError, ReadReport
from skytrack.io.schema import IDENTITY_EVENT_SCHEMA, IFF_VALUES, TEXT_COLUMNS
from skytrack.io.tables import CSV_SUFFIXES, PARQUET_SUFFIXES, TableSource, load_table, table_format, write_table
from skytrack.io.tracks import add_missing_columns

#: text columns of the events file (read as text from CSV: "0123" keeps its zero)
EVENT_TEXT_COLUMNS = TEXT_COLUMNS | {"field", "old", "new", "source"}
#: how the events file is stored (the tracker's tables have these types)
EVENT_ARROW_SCHEMA = pa.schema([
    ("time", pa.float64()), ("track_id", pa.int64()), ("field", pa.string()), ("old", pa.string()),
    ("new", pa.string()), ("source", pa.string()), ("identity_p", pa.float64()),
])


def identity_events_path(tracks_path: str | Path) -> Path:
    """The identity-events file of a tracks file: ``NAME.identity`` + the tracks file's extension."""
    from skytrack.io.asterix.cat062 import beside_asterix, is_asterix_path  # the asterix package loads numba

    path = Path(tracks_path)
    if is_asterix_path(path):
        return beside_asterix(path, "identity")
    table_format(path)  # an unsupported extension is an error here too
    name = path.name
    suffix = next(s for s in sorted(CSV_SUFFIXES + PARQUET_SUFFIXES, key=len, reverse=True)
                  if name.lower().endswith(s))
    return path.with_name(name[: len(name) - len(suffix)] + ".identity" + name[len(name) - len(suffix):])


def _validate_events(df: pd.DataFrame, source: TableSource, lenient: bool, report: ReadReport) -> pd.DataFrame:
    require_columns(df, source, ["time", "track_id", "field"], "identity events")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    as_float(df, "time", checks, required=True)
    as_int(df, "track_id", checks, nullable=False)
    field = as_string(df, "field", checks, required=True)
    flag_not_in(checks, field, "field", IDENTITY_EVENT_FIELDS)
    for name in ("old", "new"):
        if name not in df.columns:
            continue
        text = as_string(df, name, checks, required=False)
        text = text.where(field != "icao24", text.str.lower())
        df[name] = text
        flag_pattern(checks, text.where(field == "mode3a"), name, MODE3A_PATTERN, "4 octal digits (a mode3a value)")
        flag_pattern(checks, text.where(field == "icao24"), name, ICAO24_PATTERN,
                     "a 24-bit hex address (an icao24 value)")
        flag_not_in(checks, text.where(field == "iff"), name, IFF_VALUES)
    if "source" in df.columns:
        flag_not_in(checks, as_string(df, "source", checks, required=False), "source", IDENTITY_SOURCES)
    if "identity_p" in df.columns:
        values = as_float(df, "identity_p", checks, required=False)
        flag_values(checks, (values < 0) | (values > 1), values, "identity_p", "is outside [0, 1]")
    df = checks.finish(df, lenient=lenient, report=report)
    return order_columns(df, IDENTITY_EVENT_SCHEMA)


@overload
def read_identity_events(path: str | Path, *, lenient: Literal[False] = ...) -> pd.DataFrame: ...
@overload
def read_identity_events(path: str | Path, *, lenient: Literal[True] = ...) -> tuple[pd.DataFrame, ReadReport]: ...


def read_identity_events(path, *, lenient=False):
    """Read and validate an identity-events table; ``(events, report)`` with ``lenient=True``."""
    report = ReadReport(file=str(path))
    df, source = load_table(path, text_columns=EVENT_TEXT_COLUMNS, lenient=lenient, report=report)
    events = _validate_events(df, source, lenient, report)
    emit_warnings(report, lenient)
    return (events, report) if lenient else events


def write_identity_events(df: pd.DataFrame, path: str | Path) -> Path:
    """Write identity events (validated) with every column of the layout, in its order."""
    source = TableSource.for_frame(f"identity events to write to {path}")
    report = ReadReport(file=source.display)
    events = _validate_events(df.reset_index(drop=True), source, False, report)
    emit_warnings(report, False)
    return write_table(add_missing_columns(events, IDENTITY_EVENT_SCHEMA), path)


class IdentityEventWriter:
    """Append the tracker's identity-event tables (:meth:`skytrack.tracker.Tracker.drain_identity_events`,
    valid by construction) to a Parquet (one row group per chunk) or CSV file.  Nothing is
    created until a chunk comes or :meth:`close` is told to leave an empty file."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.format = table_format(self.path)
        self._writer = None
        self._stream = None
        self.rows = 0

    def _open(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.format == "parquet":
            self._writer = pq.ParquetWriter(str(self.path), EVENT_ARROW_SCHEMA, write_page_checksum=True)
            return
        self._stream = (pa.CompressedOutputStream(str(self.path), "gzip") if self.path.name.lower().endswith(".gz")
                        else pa.OSFile(str(self.path), "wb"))
        self._writer = pcsv.CSVWriter(self._stream, EVENT_ARROW_SCHEMA)

    def write(self, table: pa.Table | None) -> None:
        """Append ``table`` (columns of :data:`EVENT_ARROW_SCHEMA`); ``None`` writes nothing."""
        if table is None or table.num_rows == 0:
            return
        if self._writer is None:
            self._open()
        try:
            self._writer.write_table(table.select(EVENT_ARROW_SCHEMA.names).cast(EVENT_ARROW_SCHEMA))
        except (pa.ArrowException, KeyError) as exc:
            raise InputError(f"cannot append identity events ({exc})", file=str(self.path)) from None
        self.rows += table.num_rows

    def close(self, create: bool = True) -> None:
        """Finish the file; with ``create`` a writer that got no row leaves a valid empty file."""
        if self._writer is None and create:
            self._open()
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._stream is not None:
            self._stream.close()
            self._stream = None

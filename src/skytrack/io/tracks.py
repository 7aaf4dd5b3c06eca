"""Tracker output (FORMATS.md "tracks"): writer that enforces the layout, and reader.

:func:`write_tracks` writes every :data:`~skytrack.io.schema.TRACK_COLUMNS` column in
FORMATS.md order with its dtype (nulls when the tracker does not know a value, e.g. ``z``
in 2-D tracking), then the extra columns (e.g. ``cov_i_j`` from ``--full-covariance``) in
their order.  With an ``origin``, absent ``lat``/``lon``/``alt_m`` are computed from
``x``/``y``/``z`` where those are known.

Checks (both directions): ``time`` finite, ``track_id`` an integer, ``x``/``y`` finite;
``z``, velocities, variances, lat/lon/alt_m finite or null; variances >= 0; lat/lon in
range; ``status`` confirmed/coasting or null; ``n_updates``/``n_misses`` non-negative
integers or null; identity columns as in plots (``mode3a`` 4 octal digits, ``icao24``
6 hex digits, ``iff`` friend/foe/undetermined); ``identity_source`` one of mode_s, adsb, iff,
radar or null; ``identity_p`` in [0, 1] or null.  ``model_probs`` is JSON text, not parsed.
The identity events beside a tracks file are in :mod:`skytrack.io.identity_events`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Literal, overload

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from skytrack.core.tracks import IDENTITY_SOURCES
from skytrack.geo.sensors import Origin
from skytrack.io.checks import (
    RowChecks,
    as_float,
    as_int,
    as_string,
    check_identity_columns,
    emit_warnings,
    flag_not_in,
    flag_values,
    order_columns,
    require_columns,
)
from skytrack.io.errors import InputError, ReadReport
from skytrack.io.frames import geodetic_from_enu
from skytrack.io.schema import TRACK_SCHEMA, TRACK_STATUS_VALUES, TableSchema
from skytrack.io.tables import (
    TableSource,
    arrow_to_frame,
    load_table,
    table_format,
    write_table,
)

_COVARIANCE = re.compile(r"cov_\d+_\d+")
_VARIANCES = ("var_x", "var_y", "var_z", "var_vx", "var_vy", "var_vz")


def _validate_tracks(df: pd.DataFrame, source: TableSource, lenient: bool, report: ReadReport) -> pd.DataFrame:
    require_columns(df, source, ["time", "track_id", "x", "y"], "tracks")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    as_float(df, "time", checks, required=True)
    as_int(df, "track_id", checks, nullable=False)
    for name in ("x", "y"):
        as_float(df, name, checks, required=True)
    for name in ("z", "vx", "vy", "vz", "alt_m"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
    for name in _VARIANCES:
        if name in df.columns:
            values = as_float(df, name, checks, required=False)
            flag_values(checks, values < 0, values, name, "is negative")
    for name, limit in (("lat", 90.0), ("lon", 180.0)):
        if name in df.columns:
            values = as_float(df, name, checks, required=False)
            flag_values(checks, np.abs(values) > limit, values, name, f"is outside [-{limit:g}, {limit:g}]")
    if "status" in df.columns:
        flag_not_in(checks, as_string(df, "status", checks, required=False), "status", TRACK_STATUS_VALUES)
    for name in ("n_updates", "n_misses"):
        if name in df.columns:
            as_int(df, name, checks, nullable=True)
            values = df[name].to_numpy(dtype=np.float64, na_value=np.nan)
            flag_values(checks, values < 0, values, name, "is negative")
    check_identity_columns(df, checks, report)
    check_identity_confidence(df, checks)
    for name in df.columns:
        if _COVARIANCE.fullmatch(str(name)):  # CSV would infer whole numbers as int64
            as_float(df, name, checks, required=False)
    if "model_probs" in df.columns:
        as_string(df, "model_probs", checks, required=False)
    df = checks.finish(df, lenient=lenient, report=report)
    return order_columns(df, TRACK_SCHEMA)


def check_identity_confidence(df: pd.DataFrame, checks: RowChecks) -> None:
    """``identity_source`` one of :data:`~skytrack.core.tracks.IDENTITY_SOURCES`, ``identity_p``
    in [0, 1] (each null allowed)."""
    if "identity_source" in df.columns:
        flag_not_in(checks, as_string(df, "identity_source", checks, required=False), "identity_source",
                    IDENTITY_SOURCES)
    if "identity_p" in df.columns:
        values = as_float(df, "identity_p", checks, required=False)
        flag_values(checks, (values < 0) | (values > 1), values, "identity_p", "is outside [0, 1]")


def add_missing_columns(df: pd.DataFrame, schema: TableSchema) -> pd.DataFrame:
    """All columns of ``schema``: the absent ones as nulls of the schema dtype."""
    n = len(df)
    for column in schema.columns:
        if column.name in df.columns:
            continue
        if column.kind == "float":
            df[column.name] = np.full(n, np.nan)
        elif column.kind == "int":
            df[column.name] = pd.array([pd.NA] * n, dtype=pd.Int64Dtype())
        elif column.kind == "string":
            df[column.name] = pd.Series([None] * n, index=df.index, dtype=object).astype(column.dtype)
        else:
            raise ValueError(f"no null value for bool column {column.name}")
    return order_columns(df, schema)


@overload
def read_tracks(path: str | Path, *, lenient: Literal[False] = ...) -> pd.DataFrame: ...
@overload
def read_tracks(path: str | Path, *, lenient: Literal[True] = ...) -> tuple[pd.DataFrame, ReadReport]: ...


def read_tracks(path, *, lenient=False):
    """Read and validate a tracks table; ``(tracks, report)`` with ``lenient=True``.

    Absent optional columns stay absent (files written by :func:`write_tracks` have all).
    """
    report = ReadReport(file=str(path))
    from skytrack.io.asterix.cat062 import is_asterix_path

    if is_asterix_path(Path(path)):
        df, source = _cat062_tracks(Path(path)), TableSource.for_frame(f"{path} (CAT062)")
    else:
        df, source = load_table(path, lenient=lenient, report=report)
    tracks = _validate_tracks(df, source, lenient, report)
    emit_warnings(report, lenient)
    return (tracks, report) if lenient else tracks


def _cat062_tracks(path: Path) -> pd.DataFrame:
    """CAT062 system tracks written by ``skytrack track -o tracks.ast`` as a tracks table: times count
    from the epoch of the run's sidecar metadata (from UTC midnight without one); ``z`` stays empty
    (the file carries no system origin)."""
    from skytrack.io.asterix.cat062 import time_of_day_at_epoch
    from skytrack.io.asterix.cat062_read import decode_cat062

    epoch = (read_tracks_metadata(path) or {}).get("epoch_utc")
    frame = decode_cat062(path.read_bytes(), time_of_day_at_epoch_s=time_of_day_at_epoch(epoch))
    return frame.drop(columns=["sac", "sic", "service_id", "time_of_day_s", "track_begin"])


def _tracks_to_write(df: pd.DataFrame, path: str | Path) -> pd.DataFrame:
    """Validate tracks about to be written (strict), in FORMATS.md column order."""
    source = TableSource.for_frame(f"tracks to write to {path}")
    report = ReadReport(file=source.display)
    tracks = _validate_tracks(df.reset_index(drop=True), source, False, report)
    emit_warnings(report, False)
    return tracks


def write_tracks(df: pd.DataFrame, path: str | Path, *, origin: Origin | None = None) -> Path:
    """Write tracks in the FORMATS.md layout: all TRACK_COLUMNS in order, then extras."""
    tracks = _tracks_to_write(df, path)
    if origin is not None and not {"lat", "lon", "alt_m"} & set(tracks.columns):
        z = tracks["z"].to_numpy() if "z" in tracks.columns else np.full(len(tracks), np.nan)
        known = np.isfinite(z)
        geo = np.full((len(tracks), 3), np.nan)
        if known.any():
            geo[known] = geodetic_from_enu(
                tracks["x"].to_numpy()[known], tracks["y"].to_numpy()[known], z[known], origin
            )
        for i, name in enumerate(("lat", "lon", "alt_m")):
            tracks[name] = geo[:, i]
    return write_table(add_missing_columns(tracks, TRACK_SCHEMA), path)


#: columns whose min/max the streamed tracks file records per row group (time windows, track ids)
_STATISTICS_COLUMNS = ("time", "track_id")
_ARROW_KINDS = {"float": pa.float64(), "int": pa.int64(), "string": pa.string(), "bool": pa.bool_()}


def _is_dictionary_text(arrow_type: pa.DataType) -> bool:
    return pa.types.is_dictionary(arrow_type) and pa.types.is_string(arrow_type.value_type)


def _with_missing_arrow_columns(table: pa.Table, schema: TableSchema) -> pa.Table:
    """:func:`add_missing_columns` for an Arrow table: absent columns as nulls of their kind,
    the schema's columns first in its order, then the extra columns in theirs."""
    names = table.column_names
    known = [c.name for c in schema.columns]
    columns = [table[c.name] if c.name in names else pa.nulls(len(table), _ARROW_KINDS[c.kind]) for c in schema.columns]
    extra = [name for name in names if name not in known]
    return pa.Table.from_arrays(columns + [table[name] for name in extra], names=known + extra)


class TrackWriter:
    """Write a tracks table chunk by chunk (bounded memory on long recordings).

    Every chunk is validated and laid out exactly as :func:`write_tracks` does; the
    Arrow schema is fixed from the FORMATS.md column kinds (extra columns take the
    first chunk's types), so chunks whose identity columns happen to be all-null
    still append.  Parquet files are written one row group per chunk; CSV files are
    appended.  A ``.ast`` file is written as ASTERIX CAT062 system tracks
    (:class:`~skytrack.io.asterix.cat062.Cat062Writer`, issue 11 item 2), with the system
    SAC/SIC and the epoch's time of day from ``sensors`` (a ``SensorSet``), and the run
    metadata in the sidecar ``NAME.ast.meta.json``.  Use as a context manager.
    """

    def __init__(self, path: str | Path, *, sensors=None):
        from skytrack.io.asterix.cat062 import Cat062Writer, is_asterix_path  # the asterix package loads numba

        self.path = Path(path)
        self.format = "asterix" if is_asterix_path(self.path) else table_format(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._schema: pa.Schema | None = None
        self._writer = None
        self._stream = None
        self.rows = 0
        self._cat062 = Cat062Writer(self.path, sensors) if self.format == "asterix" else None
        self.run_metadata: dict | None = None
        """what the run knew of its input (epoch, time span), stored with the file on closing
        (:func:`read_tracks_metadata`)"""

    def _schema_for(self, table: pa.Table) -> pa.Schema:
        fields = []
        for field in table.schema:
            kind = TRACK_SCHEMA[field.name].kind if field.name in TRACK_SCHEMA.names else None
            arrow_type = _ARROW_KINDS[kind] if kind else field.type
            if kind == "string" and self.format == "parquet" and _is_dictionary_text(field.type):
                arrow_type = field.type  # Parquet stores the dictionary as it is (no hashing)
            fields.append(pa.field(field.name, arrow_type))
        return pa.schema(fields)

    def write(self, chunk: pd.DataFrame | pa.Table | None, *, checked: bool = False) -> None:
        """Append ``chunk``; ``checked=True`` skips the validation for tables that are valid by
        construction (the tracker's own output, in the docs/formats.md column order).

        A pyarrow Table (:meth:`~skytrack.tracker.Tracker.drain_arrow`) is written as it is when
        ``checked``, else validated like a DataFrame; ``None`` writes nothing."""
        if chunk is None or len(chunk) == 0:
            return
        if self._cat062 is not None:
            frame = arrow_to_frame(chunk) if isinstance(chunk, pa.Table) else chunk
            self._cat062.write(frame if checked else _tracks_to_write(frame, self.path))
            self.rows += len(frame)
            return
        if isinstance(chunk, pa.Table) and checked:
            table = _with_missing_arrow_columns(chunk, TRACK_SCHEMA)
        else:
            if isinstance(chunk, pa.Table):  # validated as a DataFrame, like any other input
                chunk = arrow_to_frame(chunk)
            tracks = add_missing_columns(chunk if checked else _tracks_to_write(chunk, self.path), TRACK_SCHEMA)
            table = pa.Table.from_pandas(tracks, preserve_index=False)
        if self._schema is None:
            self._schema = self._schema_for(table)
            if self.format == "parquet":
                # dictionary-encode only the text columns: trying it on every float column
                # costs more than the whole compression and gains nothing; min/max statistics
                # only where a reader selects row groups by them (they cost a sixth of the write)
                text = [f.name for f in self._schema if pa.types.is_string(f.type) or _is_dictionary_text(f.type)]
                # dictionary columns are plain text in Parquet; without the Arrow schema in the
                # file, readers read them as the plain text they are (not as categories)
                self._writer = pq.ParquetWriter(str(self.path), self._schema, use_dictionary=text,
                                                write_statistics=list(_STATISTICS_COLUMNS), write_page_checksum=True,
                                                store_schema=not any(_is_dictionary_text(f.type) for f in self._schema))
            else:
                self._stream = (
                    pa.CompressedOutputStream(str(self.path), "gzip")
                    if self.path.name.lower().endswith(".gz")
                    else pa.OSFile(str(self.path), "wb")
                )
                self._writer = pcsv.CSVWriter(self._stream, self._schema)
        try:
            self._writer.write_table(table.select(self._schema.names).cast(self._schema))
        except (pa.ArrowException, KeyError) as exc:
            raise InputError(f"cannot append tracks ({exc})", file=str(self.path)) from None
        self.rows += len(table)

    def close(self) -> None:
        if self._cat062 is not None:
            self._cat062.close()  # no row: an empty file, a valid ASTERIX recording of no record
            self._write_sidecar()
            return
        if self._writer is None:
            # nothing was written: still leave a valid, empty tracks file
            write_tracks(add_missing_columns(pd.DataFrame({c: [] for c in TRACK_SCHEMA.required}), TRACK_SCHEMA), self.path)
            self._write_sidecar()
            return
        if self.run_metadata is not None and self.format == "parquet":
            self._writer.add_key_value_metadata({METADATA_KEY: json.dumps(self.run_metadata, allow_nan=False)})
        self._writer.close()
        if self._stream is not None:
            self._stream.close()
        if self.format != "parquet":
            self._write_sidecar()
        self._writer = None

    def _write_sidecar(self) -> None:
        if self.run_metadata is not None:
            sidecar_path(self.path).write_text(json.dumps(self.run_metadata, indent=2, allow_nan=False) + "\n")

    def __enter__(self) -> TrackWriter:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


#: key of the run metadata in a tracks Parquet file's key-value metadata
METADATA_KEY = "skytrack.run"


def sidecar_path(path: str | Path) -> Path:
    """Where the run metadata of a CSV or ASTERIX tracks file lives: ``tracks.csv`` -> ``tracks.csv.meta.json``."""
    path = Path(path)
    return path.with_name(path.name + ".meta.json")


def read_tracks_metadata(path: str | Path) -> dict | None:
    """The run metadata a :class:`TrackWriter` stored with a tracks file (epoch, the input's
    time span), or ``None`` for files written otherwise."""
    from skytrack.io.asterix.cat062 import is_asterix_path

    path = Path(path)
    try:
        if not is_asterix_path(path) and table_format(path) == "parquet":
            stored = (pq.read_metadata(path).metadata or {}).get(METADATA_KEY.encode())
            return None if stored is None else json.loads(stored)
        sidecar = sidecar_path(path)
        return json.loads(sidecar.read_text()) if sidecar.exists() else None
    except (OSError, ValueError, pa.ArrowException):
        return None  # a damaged or foreign file: the evaluation goes without it

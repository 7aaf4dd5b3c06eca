"""Generic table files: Parquet or CSV chosen by extension, with located errors.

``.parquet`` / ``.pq`` are read and written with pyarrow; ``.csv`` and ``.csv.gz`` with
pyarrow's multi-threaded CSV reader and writer.  In CSV files the identity columns of
:data:`skytrack.io.schema.TEXT_COLUMNS` are always read as text; other columns are
inferred (numbers, timestamps, booleans) and the table readers coerce them.

CSV row/line numbering: row ``r`` is the 0-based data row (blank lines and malformed
lines are not data rows); its line is the 1-based physical line where the row starts,
found by re-scanning the file only when an error message needs it.
"""

from __future__ import annotations

import csv
import gzip
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from skytrack.io.errors import InputError, ReadReport
from skytrack.io.schema import STRING_DTYPE, TEXT_COLUMNS

PARQUET_SUFFIXES = (".parquet", ".pq")
CSV_SUFFIXES = (".csv", ".csv.gz")

#: cell texts read as null in CSV files (an empty quoted string ``""`` stays ``""``)
CSV_NULL_TOKENS = ["", "NA", "N/A", "NaN", "nan", "null", "NULL", "None"]

_SCAN_CHUNK = 1 << 24


def table_format(path: str | Path) -> str:
    """``"parquet"`` or ``"csv"`` from the file name; :class:`InputError` otherwise."""
    name = Path(path).name.lower()
    if name.endswith(PARQUET_SUFFIXES):
        return "parquet"
    if name.endswith(CSV_SUFFIXES):
        return "csv"
    raise InputError(
        "unsupported file extension; use .parquet, .pq, .csv or .csv.gz",
        file=str(path),
    )


def _open_text(path: Path) -> io.TextIOBase:
    if path.name.lower().endswith(".gz"):
        return gzip.open(path, "rt", encoding="utf-8-sig", newline="")
    return open(path, encoding="utf-8-sig", newline="")  # pyarrow skips a BOM too


def _open_binary(path: Path):
    if path.name.lower().endswith(".gz"):
        return gzip.open(path, "rb")
    return open(path, "rb")


@dataclass
class TableSource:
    """Where the rows of a DataFrame came from, to locate problems in messages."""

    display: str
    path: Path | None = None
    is_csv: bool = False
    n_fields: int = 0
    n_invalid_lines: int = 0
    row_offset: int = 0  # rows of the file before this DataFrame's first row (chunked reading)
    _simple_layout: bool | None = field(default=None, repr=False)
    _scanned_lines: list[int] = field(default_factory=list, repr=False)
    _invalid_lines: list[tuple[int, int]] = field(default_factory=list, repr=False)

    @classmethod
    def for_frame(cls, description: str) -> TableSource:
        """A DataFrame built in memory (e.g. about to be written): rows only, no lines."""
        return cls(display=description)

    def error(self, message: str, *, row: int | None = None, column: str | None = None, more: int = 0) -> InputError:
        line = self.lines([row])[0] if row is not None else None
        row = None if row is None else row + self.row_offset
        return InputError(message, file=self.display, row=row, line=line, column=column, more=more)

    def issues(self, rows: Sequence[int], column: str | None, messages: Sequence[str]) -> list[InputError]:
        lines = self.lines(rows)
        return [
            InputError(m, file=self.display, row=int(r) + self.row_offset, line=ln, column=column)
            for r, ln, m in zip(rows, lines, messages, strict=True)
        ]

    # -- CSV line numbers -------------------------------------------------------------
    def lines(self, rows: Sequence[int | None]) -> list[int | None]:
        """1-based file lines of 0-based data rows (``None`` for non-CSV sources)."""
        if not self.is_csv or self.path is None:
            return [None] * len(rows)
        wanted = [r for r in rows if r is not None]
        if not wanted:
            return [None] * len(rows)
        if self._is_simple_layout():
            return [None if r is None else int(r) + 2 for r in rows]
        self._scan(max_row=max(wanted))
        return [None if r is None else self._scanned_lines[r] for r in rows]

    def invalid_lines(self, limit: int) -> list[tuple[int, int]]:
        """(line, field count) of the first ``limit`` lines with a wrong number of fields."""
        if self.n_invalid_lines and len(self._invalid_lines) < min(limit, self.n_invalid_lines):
            self._scan(max_row=None, invalid_limit=limit)
        return self._invalid_lines[:limit]

    def _is_simple_layout(self) -> bool:
        """True when data row r is on line r + 2: no quotes, blank or malformed lines."""
        if self._simple_layout is None:
            simple = self.n_invalid_lines == 0
            previous = b""
            with _open_binary(self.path) as stream:
                first = True
                while simple:
                    chunk = stream.read(_SCAN_CHUNK)
                    if not chunk:
                        break
                    if first and chunk[:1] in (b"\n", b"\r"):
                        simple = False
                    first = False
                    window = previous + chunk
                    if b'"' in chunk or b"\n\n" in window or b"\n\r\n" in window or b"\r\r" in window:
                        simple = False
                    previous = chunk[-2:]
            self._simple_layout = simple
        return self._simple_layout

    def _records(self) -> Iterator[tuple[int, list[str]]]:
        """(start line, fields) of every CSV record, blank lines included as []."""
        with _open_text(self.path) as stream:
            reader = csv.reader(stream)
            last_line = 0
            for record in reader:
                yield last_line + 1, record
                last_line = reader.line_num

    def _scan(self, max_row: int | None, invalid_limit: int = 0) -> None:
        if max_row is not None and len(self._scanned_lines) > max_row:
            return
        self._scanned_lines.clear()
        self._invalid_lines.clear()
        header_seen = False
        for start, record in self._records():
            if not record:
                continue
            if not header_seen:
                header_seen = True
                continue
            if len(record) != self.n_fields:
                if len(self._invalid_lines) < max(invalid_limit, 10):
                    self._invalid_lines.append((start, len(record)))
                continue
            self._scanned_lines.append(start)
            done_rows = max_row is None or len(self._scanned_lines) > max_row
            done_invalid = len(self._invalid_lines) >= min(invalid_limit, self.n_invalid_lines)
            if done_rows and done_invalid:
                return


# ---------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------


def _string_mapper(arrow_type: pa.DataType):
    if isinstance(STRING_DTYPE, pd.api.extensions.ExtensionDtype) and (
        pa.types.is_string(arrow_type) or pa.types.is_large_string(arrow_type)
    ):
        return STRING_DTYPE
    return None


def _check_exists(path: Path) -> None:
    if not path.exists():
        raise InputError("file not found", file=str(path))


def _parquet_error(path: Path, exc: Exception) -> InputError:
    reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return InputError(f"not a readable Parquet file ({reason})", file=str(path))


def _read_parquet(path: Path) -> pd.DataFrame:
    try:
        table = pq.read_table(path)
        return table.to_pandas(types_mapper=_string_mapper)
    except (pa.ArrowException, OSError) as exc:
        raise _parquet_error(path, exc) from None


def iter_parquet(path: str | Path, chunk_rows: int) -> Iterator[tuple[pd.DataFrame, TableSource]]:
    """Read a Parquet file in chunks of at most ``chunk_rows`` rows (bounded memory).

    Each chunk comes with a :class:`TableSource` whose ``row_offset`` makes error messages
    name rows of the whole file.
    """
    path = Path(path)
    _check_exists(path)
    offset = 0
    try:
        parquet = pq.ParquetFile(path)
        for batch in parquet.iter_batches(batch_size=chunk_rows):
            frame = batch.to_pandas(types_mapper=_string_mapper)
            source = TableSource(display=str(path), path=path, row_offset=offset)
            _check_unique_columns(frame, source)
            yield frame, source
            offset += len(frame)
    except (pa.ArrowException, OSError) as exc:
        raise _parquet_error(path, exc) from None


def count_rows(path: str | Path) -> int | None:
    """Rows of a Parquet file from its metadata (None for other formats)."""
    path = Path(path)
    if table_format(path) != "parquet":
        return None
    _check_exists(path)
    try:
        return pq.ParquetFile(path).metadata.num_rows
    except (pa.ArrowException, OSError) as exc:
        raise _parquet_error(path, exc) from None


def _csv_header(path: Path) -> list[str]:
    try:
        with _open_text(path) as stream:
            for record in csv.reader(stream):
                if record:
                    return record
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read the CSV header ({exc})", file=str(path)) from None
    raise InputError("empty CSV file (no header line)", file=str(path))


def _read_csv(path: Path, text_columns: frozenset[str], source: TableSource) -> pd.DataFrame:
    header = _csv_header(path)
    source.n_fields = len(header)

    def count_invalid(_row: pcsv.InvalidRow) -> str:
        source.n_invalid_lines += 1
        return "skip"

    convert = pcsv.ConvertOptions(
        column_types={name: pa.string() for name in header if name in text_columns},
        null_values=CSV_NULL_TOKENS,
        strings_can_be_null=True,
        quoted_strings_can_be_null=False,
    )
    parse = pcsv.ParseOptions(invalid_row_handler=count_invalid)
    try:
        table = pcsv.read_csv(path, parse_options=parse, convert_options=convert)
    except (pa.ArrowException, OSError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot read as CSV ({reason})", file=str(path)) from None
    return table.to_pandas(types_mapper=_string_mapper)


def _check_unique_columns(df: pd.DataFrame, source: TableSource) -> None:
    duplicated = sorted({str(c) for c in df.columns[df.columns.duplicated()]})
    if duplicated:
        raise source.error(f"duplicate column name(s): {', '.join(duplicated)}")


def load_table(
    path: str | Path,
    *,
    text_columns: frozenset[str] = TEXT_COLUMNS,
    lenient: bool = False,
    report: ReadReport | None = None,
) -> tuple[pd.DataFrame, TableSource]:
    """Read a table file and describe where its rows come from.

    Malformed CSV lines (wrong number of fields) raise :class:`InputError` in strict mode;
    in lenient mode they are skipped and counted in ``report``.
    """
    path = Path(path)
    fmt = table_format(path)
    _check_exists(path)
    source = TableSource(display=str(path), path=path, is_csv=fmt == "csv")
    df = _read_parquet(path) if fmt == "parquet" else _read_csv(path, text_columns, source)
    _check_unique_columns(df, source)
    if source.n_invalid_lines:
        bad = source.invalid_lines(limit=3)
        issues = [
            InputError(
                f"expected {source.n_fields} fields (as in the header), found {n}",
                file=source.display,
                line=line,
            )
            for line, n in bad
        ]
        if not lenient or report is None:
            first = issues[0]
            first.more = source.n_invalid_lines - 1
            raise first
        report.add_skipped("wrong number of fields", source.n_invalid_lines, issues)
    if report is not None:
        report.rows_read += len(df) + source.n_invalid_lines
    return df, source


def read_table(path: str | Path, *, text_columns: frozenset[str] = TEXT_COLUMNS) -> pd.DataFrame:
    """Read any table file (.parquet/.pq/.csv/.csv.gz) without schema checks.

    Raises :class:`InputError` naming the file for an unsupported extension, a missing
    file, an unreadable or corrupted file, duplicate column names or, in CSV, a line with
    the wrong number of fields.
    """
    return load_table(path, text_columns=text_columns)[0]


# ---------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------


def _plain_arrow_table(df: pd.DataFrame, path: Path, for_csv: bool) -> pa.Table:
    try:
        table = pa.Table.from_pandas(df, preserve_index=False)
    except (pa.ArrowException, TypeError, ValueError) as exc:
        raise InputError(f"cannot convert the table for writing ({exc})", file=str(path)) from None
    if for_csv:  # the CSV writer takes plain types only
        columns = []
        for column in table.columns:
            if pa.types.is_dictionary(column.type):
                column = column.cast(column.type.value_type)
            columns.append(column)
        table = pa.table(columns, names=table.column_names)
    return table


def write_table(df: pd.DataFrame, path: str | Path) -> Path:
    """Write ``df`` as Parquet or CSV (by extension), creating parent directories."""
    path = Path(path)
    fmt = table_format(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = _plain_arrow_table(df, path, for_csv=fmt == "csv")
    try:
        if fmt == "parquet":
            pq.write_table(table, path)
        elif path.name.lower().endswith(".gz"):
            with pa.CompressedOutputStream(str(path), "gzip") as stream:
                pcsv.write_csv(table, stream)
        else:
            pcsv.write_csv(table, path)
    except (pa.ArrowException, OSError) as exc:
        raise InputError(f"cannot write ({exc})", file=str(path)) from None
    return path


def row_positions(mask: np.ndarray) -> np.ndarray:
    """0-based positions of the True entries of a boolean mask."""
    return np.flatnonzero(np.asarray(mask, dtype=bool))

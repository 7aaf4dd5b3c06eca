"""Generic table files: Parquet or CSV chosen by extension, with located errors.

``.parquet`` / ``.pq`` are read and written with pyarrow; ``.csv`` and ``.csv.gz`` with
pyarrow's multi-threaded CSV reader and writer.  In CSV files the identity columns of
:data:`skytrack.io.schema.TEXT_COLUMNS` are always read as text; other columns are
inferred (numbers, timestamps, booleans) and the table readers coerce them.

CSV row/line numbering: row ``r`` is the 0-based data row (blank lines and malformed
lines are not data rows); its line is the 1-based physical line where the row starts,
found by scanning the file only when an error message needs it (one resumable scan per
file, shared by the chunks of a streamed read).

Streaming: :func:`iter_parquet` and :func:`iter_csv` hand a file out in chunks of at most
``chunk_rows`` rows, so memory is bounded by the chunk size; :func:`iter_parquet_tables`
and :func:`iter_csv_tables` hand out the same chunks as Arrow tables (for readers that
check and convert the arrays without a DataFrame).  The CSV stream reads with
``pyarrow.csv.open_csv`` and infers the column types per chunk the way
``pyarrow.csv.read_csv`` infers them for a whole file (:mod:`skytrack.io.csv_types`),
so a chunk reads like a small file would.
"""

from __future__ import annotations

import csv
import gzip
import zlib
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from skytrack.io.csv_text import open_text, undecodable_error, undecodable_lines_silenced
from skytrack.io.csv_types import typed_csv_chunk
from skytrack.io.errors import InputError, ReadReport
from skytrack.io.schema import STRING_DTYPE, TEXT_COLUMNS

PARQUET_SUFFIXES = (".parquet", ".pq")
CSV_SUFFIXES = (".csv", ".csv.gz")

#: cell texts read as null in CSV files (an empty quoted string ``""`` stays ``""``)
CSV_NULL_TOKENS = ["", "NA", "N/A", "NaN", "nan", "null", "NULL", "None"]

_SCAN_CHUNK = 1 << 24
#: malformed CSV lines whose place a scan records (reports show the first few)
_INVALID_LINES_KEPT = 10


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


#: raised on a damaged .gz stream (BadGzipFile is an OSError) and on a damaged Parquet file (non-UTF-8 names)
_GZIP_ERRORS = (OSError, EOFError, zlib.error)
_PARQUET_ERRORS = (pa.ArrowException, OSError, UnicodeDecodeError)


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
    #: text columns a reader handed out dictionary-encoded although the file holds plain text
    dictionary_text: tuple[str, ...] = ()
    _simple_layout: bool | None = field(default=None, repr=False)
    _scanned_lines: list[int] = field(default_factory=list, repr=False)
    _invalid_lines: list[tuple[int, int]] = field(default_factory=list, repr=False)
    _invalid_overflow: bool = field(default=False, repr=False)
    _scan_state: list | None = field(default=None, repr=False)

    @classmethod
    def for_frame(cls, description: str) -> TableSource:
        """A DataFrame built in memory (e.g. about to be written): rows only, no lines."""
        return cls(display=description)

    def error(self, message: str, *, row: int | None = None, column: str | None = None, more: int = 0) -> InputError:
        """An error at ``row`` of this DataFrame (numbered in the whole file in the message)."""
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
        """1-based file lines of 0-based data rows of this DataFrame (``None`` for non-CSV sources).

        Rows are counted from the DataFrame's first row, which is row ``row_offset`` of the file.
        """
        if not self.is_csv or self.path is None:
            return [None] * len(rows)
        rows = [None if r is None else int(r) + self.row_offset for r in rows]
        wanted = [r for r in rows if r is not None]
        if not wanted:
            return [None] * len(rows)
        if self._is_simple_layout():
            return [None if r is None else r + 2 for r in rows]
        self._scan(max_row=max(wanted))
        return [None if r is None else self._scanned_lines[r] for r in rows]

    def invalid_lines(self, limit: int) -> list[tuple[int, int]]:
        """(line, field count) of the first ``limit`` lines with a wrong number of fields."""
        if self.n_invalid_lines and len(self._invalid_lines) < min(limit, self.n_invalid_lines):
            self._scan(max_row=None, invalid_limit=limit)
        return self._invalid_lines[:limit]

    def _is_simple_layout(self) -> bool:
        """True when data row r is on line r + 2: no quotes, blank or malformed lines.

        ``_simple_layout`` caches the byte scan (quotes, blank lines); malformed lines are
        counted while the file is read, so a streamed read re-checks their count each time.
        """
        if self.n_invalid_lines:
            return False
        if self._simple_layout is None:
            simple = True
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
        with open_text(self.path) as stream:
            reader = csv.reader(stream)
            last_line = 0
            for record in reader:
                yield last_line + 1, record
                last_line = reader.line_num

    def _scan(self, max_row: int | None, invalid_limit: int = 0) -> None:
        """Scan on, resuming where the last scan stopped, until row ``max_row`` (``None``: no
        row wanted) and the first ``invalid_limit`` malformed lines are located."""
        keep_invalid = max(invalid_limit, _INVALID_LINES_KEPT)
        if self._invalid_overflow and invalid_limit > len(self._invalid_lines):
            self._scan_state = None  # the wanted malformed lines were passed unrecorded: start over
        if self._scan_state is None:
            self._scanned_lines.clear()
            self._invalid_lines.clear()
            self._invalid_overflow = False
            self._scan_state = [self._records(), False]  # [record iterator, header seen]
        records, header_seen = self._scan_state

        def done() -> bool:
            done_rows = max_row is None or len(self._scanned_lines) > max_row
            done_invalid = len(self._invalid_lines) >= min(invalid_limit, self.n_invalid_lines)
            return done_rows and done_invalid

        if done():
            return
        for start, record in records:
            if not record:
                continue
            if not header_seen:
                header_seen = self._scan_state[1] = True
                continue
            if len(record) != self.n_fields:
                if len(self._invalid_lines) < keep_invalid:
                    self._invalid_lines.append((start, len(record)))
                else:
                    self._invalid_overflow = True
                continue
            self._scanned_lines.append(start)
            if done():
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


def _reason(exc: Exception) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _parquet_error(path: Path, exc: Exception) -> InputError:
    if "checksum" in str(exc).lower():
        # a page of a file written with checksums (skytrack writes them) no longer matches its CRC
        return InputError(f"the Parquet file is damaged: {_reason(exc)}", file=str(path))
    return InputError(f"not a readable Parquet file ({_reason(exc)})", file=str(path))


def arrow_to_frame(table: pa.Table | pa.RecordBatch, source: TableSource | None = None) -> pd.DataFrame:
    """An Arrow table as a DataFrame, text as :data:`~skytrack.io.schema.STRING_DTYPE`.

    Columns a reader handed out dictionary-encoded (``source.dictionary_text``) become plain
    text again first: the DataFrame is the one a plain read gives.
    """
    if source is not None and source.dictionary_text:
        names = table.schema.names
        columns = [
            column.cast(column.type.value_type)
            if name in source.dictionary_text and pa.types.is_dictionary(column.type) else column
            for name, column in zip(names, table.columns)
        ]
        table = pa.Table.from_arrays(columns, names=names)
    # the "pandas" metadata of a file only rebuilds an index, which no table of docs/formats.md
    # has; damaged, it raised JSONDecodeError, KeyError or TypeError from inside pyarrow
    return table.replace_schema_metadata(None).to_pandas(types_mapper=_string_mapper)


def _read_parquet(path: Path) -> pd.DataFrame:
    try:
        return arrow_to_frame(pq.read_table(path, page_checksum_verification=True))
    except _PARQUET_ERRORS as exc:
        raise _parquet_error(path, exc) from None


def iter_parquet_tables(
    path: str | Path, chunk_rows: int, *, text_as_dictionary: Sequence[str] = ()
) -> Iterator[tuple[pa.RecordBatch, TableSource]]:
    """Read a Parquet file in Arrow record batches of at most ``chunk_rows`` rows (bounded memory).

    Each chunk comes with a :class:`TableSource` whose ``row_offset`` makes error messages
    name rows of the whole file.  Duplicate column names raise :class:`InputError`.  The
    text columns named in ``text_as_dictionary`` are read dictionary-encoded, as Parquet
    stores them (no string is built); their names are in ``source.dictionary_text``.
    """
    path = Path(path)
    _check_exists(path)
    offset = 0
    try:
        stored = pq.read_schema(path)
        unique = len(set(stored.names)) == len(stored.names)  # else the first chunk raises, as always
        text = tuple(f.name for f in stored if unique and f.name in text_as_dictionary
                     and (pa.types.is_string(f.type) or pa.types.is_large_string(f.type)))
        parquet = pq.ParquetFile(path, read_dictionary=list(text) or None, page_checksum_verification=True)
        for batch in parquet.iter_batches(batch_size=chunk_rows):
            source = TableSource(display=str(path), path=path, row_offset=offset, dictionary_text=text)
            _check_unique_columns(batch.schema.names, source)
            batch.validate(full=True)  # a damaged page without checksum may hold text that is not UTF-8
            yield batch, source
            offset += batch.num_rows
        if offset != parquet.metadata.num_rows:  # damaged row-group metadata: rows would vanish silently
            raise InputError(f"the Parquet file is damaged: {offset} of {parquet.metadata.num_rows} rows read", file=str(path))
    except _PARQUET_ERRORS as exc:
        raise _parquet_error(path, exc) from None


def iter_parquet(path: str | Path, chunk_rows: int) -> Iterator[tuple[pd.DataFrame, TableSource]]:
    """:func:`iter_parquet_tables` in DataFrames."""
    for batch, source in iter_parquet_tables(path, chunk_rows):
        yield chunk_to_frame(batch, source), source


def chunk_to_frame(table: pa.Table | pa.RecordBatch, source: TableSource) -> pd.DataFrame:
    """:func:`arrow_to_frame` of a chunk of a streamed file; a failure is reported as the
    streams report a file they cannot read."""
    try:
        return arrow_to_frame(table, source)
    except (pa.ArrowException, OSError) as exc:
        if source.is_csv:
            raise InputError(f"cannot read as CSV ({_reason(exc)})", file=source.display) from None
        raise _parquet_error(source.path, exc) from None


def count_rows(path: str | Path) -> int | None:
    """Rows of a Parquet file from its metadata (None for other formats, ASTERIX recordings too)."""
    path = Path(path)
    if path.name.lower().endswith((".ast", ".asterix", ".pcap")) or table_format(path) != "parquet":
        return None
    _check_exists(path)
    try:
        return pq.ParquetFile(path).metadata.num_rows
    except _PARQUET_ERRORS as exc:
        raise _parquet_error(path, exc) from None


def _csv_header(path: Path) -> list[str]:
    try:
        with open_text(path) as stream:
            for record in csv.reader(stream):
                if record and any("\ufffd" in name for name in record):  # open_text's stand-in for non-UTF-8
                    raise InputError("the header is not UTF-8 text", file=str(path), line=1)
                if record:
                    return record
    except (*_GZIP_ERRORS, UnicodeDecodeError, csv.Error) as exc:
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
        raise InputError(f"cannot read as CSV ({_reason(exc)})", file=str(path)) from None
    return arrow_to_frame(table)


# -- streamed CSV ---------------------------------------------------------------------

#: the block size of the streaming CSV reader stays within these bounds (bytes): a block
#: must hold at least one whole line, and a few MiB read fastest (chunks gather blocks)
_MIN_BLOCK_BYTES = 1 << 20
_MAX_BLOCK_BYTES = 4 << 20
def _csv_block_bytes(path: Path, chunk_rows: int) -> int:
    """A reader block of about ``chunk_rows`` lines, from the line length at the top of the file."""
    try:
        with _open_binary(path) as stream:
            sample = stream.read(1 << 16)
    except _GZIP_ERRORS as exc:
        raise InputError(f"cannot read as CSV ({_reason(exc)})", file=str(path)) from None
    line_bytes = max(len(sample) / max(sample.count(b"\n"), 1), 1.0)
    return int(min(max(chunk_rows * line_bytes, _MIN_BLOCK_BYTES), _MAX_BLOCK_BYTES))


def iter_csv(
    path: str | Path,
    chunk_rows: int,
    *,
    text_columns: frozenset[str] = TEXT_COLUMNS,
    lenient: bool = False,
    report: ReadReport | None = None,
    block_bytes: int | None = None,
) -> Iterator[tuple[pd.DataFrame, TableSource]]:
    """:func:`iter_csv_tables` in DataFrames."""
    for table, source in iter_csv_tables(path, chunk_rows, text_columns=text_columns, lenient=lenient,
                                         report=report, block_bytes=block_bytes):
        yield chunk_to_frame(table, source), source


def iter_csv_tables(
    path: str | Path,
    chunk_rows: int,
    *,
    text_columns: frozenset[str] = TEXT_COLUMNS,
    lenient: bool = False,
    report: ReadReport | None = None,
    block_bytes: int | None = None,
) -> Iterator[tuple[pa.Table, TableSource]]:
    """Stream a CSV file (.csv/.csv.gz) in Arrow tables of ``chunk_rows`` rows (the last may be shorter).

    Memory is bounded by a chunk plus one reader block (``block_bytes``, by default about
    ``chunk_rows`` lines).  Every chunk comes with the same :class:`TableSource`, whose
    ``row_offset`` is set to the chunk's first row, so error messages name rows and lines
    of the whole file; validate a chunk before asking for the next one.  Column types are
    inferred per chunk as :func:`pyarrow.csv.read_csv` infers them for a whole file.

    Malformed lines (wrong number of fields) raise :class:`InputError` in strict mode
    (with the count of the whole file); in lenient mode they are skipped and counted in
    ``report`` once the file is read (in ``skipped`` and ``rows_read``; the caller adds
    the data rows it reads to ``rows_read``, as for Parquet).  A file with a header and
    no data rows gives one empty chunk, so its columns can still be checked.
    """
    path = Path(path)
    if chunk_rows < 1:
        raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
    _check_exists(path)
    header = _csv_header(path)
    source = TableSource(display=str(path), path=path, is_csv=True, n_fields=len(header))

    def count_invalid(_row: pcsv.InvalidRow) -> str:
        source.n_invalid_lines += 1
        return "skip"

    # every column is read as text and typed per chunk: the stream can never meet a value
    # that the types guessed from its first block cannot hold
    convert = pcsv.ConvertOptions(
        column_types={name: pa.string() for name in header},
        null_values=CSV_NULL_TOKENS,
        strings_can_be_null=True,
        quoted_strings_can_be_null=False,
    )
    # quoted values may hold line breaks; the reader's blocks must not cut them (a whole
    # read of a small file never cuts, a streamed one does)
    parse = pcsv.ParseOptions(invalid_row_handler=count_invalid, newlines_in_values=True)
    read = pcsv.ReadOptions(block_size=block_bytes or _csv_block_bytes(path, chunk_rows))
    strict = not lenient or report is None

    def malformed_error() -> InputError:
        line, n = source.invalid_lines(limit=1)[0]
        return InputError(
            f"expected {source.n_fields} fields (as in the header), found {n}", file=source.display, line=line,
            more=source.n_invalid_lines - 1,
        )

    def chunk(table: pa.Table, offset: int) -> tuple[pa.Table, TableSource]:
        typed = typed_csv_chunk(table, text_columns)
        source.row_offset = offset
        _check_unique_columns(typed.column_names, source)
        return typed, source

    offset = 0
    pending: list[pa.RecordBatch] = []
    pending_rows = 0
    reader = None
    undecodable: list[BaseException] = []  # what pyarrow could not raise (csv_text.py)
    try:
        with undecodable_lines_silenced(undecodable):
            reader = pcsv.open_csv(path, read_options=read, parse_options=parse, convert_options=convert)
        schema = reader.schema
        while True:
            try:
                with undecodable_lines_silenced(undecodable):
                    batch = reader.read_next_batch()
            except StopIteration:
                break
            if strict and source.n_invalid_lines:
                for _ in reader:  # count the malformed lines of the whole file for the message
                    pass
                raise malformed_error()
            if batch.num_rows:
                pending.append(batch)
                pending_rows += batch.num_rows
            while pending_rows >= chunk_rows:
                table = pa.Table.from_batches(pending, schema=schema)
                yield chunk(table.slice(0, chunk_rows), offset)
                offset += chunk_rows
                rest = table.slice(chunk_rows)
                pending, pending_rows = rest.to_batches(), rest.num_rows
    except (pa.ArrowException, OSError) as exc:
        raise undecodable_error(path, undecodable) or InputError(f"cannot read as CSV ({_reason(exc)})",
                                                                   file=str(path)) from None
    finally:
        if reader is not None:
            reader.close()
    if strict and source.n_invalid_lines:
        raise malformed_error()
    if pending_rows or offset == 0:
        table = pa.Table.from_batches(pending, schema=schema) if pending else schema.empty_table()
        yield chunk(table, offset)
    if source.n_invalid_lines and report is not None:
        issues = [
            InputError(f"expected {source.n_fields} fields (as in the header), found {n}", file=source.display, line=line)
            for line, n in source.invalid_lines(limit=3)
        ]
        report.add_skipped("wrong number of fields", source.n_invalid_lines, issues)
        # a whole-file read lists them first: they are found before any row is checked
        reason = "wrong number of fields"
        report.skipped = {reason: report.skipped[reason], **{k: v for k, v in report.skipped.items() if k != reason}}
        report.rows_read += source.n_invalid_lines


def _check_unique_columns(names: Sequence[object], source: TableSource) -> None:
    counts = Counter(str(name) for name in names)
    duplicated = sorted(name for name, count in counts.items() if count > 1)
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
    _check_unique_columns(list(df.columns), source)
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
            pq.write_table(table, path, write_page_checksum=True)  # readers can tell corruption
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

"""Column types of a streamed CSV chunk, inferred as ``pyarrow.csv.read_csv`` infers them.

:func:`skytrack.io.tables.iter_csv_tables` reads every column as text (so that no later
block can meet a value the types guessed from the first block cannot hold) and types
each chunk with :func:`typed_csv_chunk`: a chunk then reads like a small file would.
"""

from __future__ import annotations

import pyarrow as pa
import pyarrow.compute as pc

_TRUE_VALUES = pa.array(["1", "True", "TRUE", "true"])
_BOOL_VALUES = pa.array(["1", "True", "TRUE", "true", "0", "False", "FALSE", "false"])
#: the types pyarrow's CSV reader tries, in its order (time32 has no cast from text)
_INFERRED_TYPES = (
    pa.int64(), pa.bool_(), pa.date32(), pa.timestamp("s"), pa.timestamp("ns"),
    pa.timestamp("s", "UTC"), pa.timestamp("ns", "UTC"), pa.float64(),
)


def infer_csv_column(column: pa.ChunkedArray) -> pa.ChunkedArray | pa.Array:
    """Type a text column as ``pyarrow.csv.read_csv`` would have inferred it.

    Nulls were already recognised by the reader (``CSV_NULL_TOKENS``).  The first type of
    :data:`_INFERRED_TYPES` that every non-null value converts to wins, else text stays;
    numbers may be surrounded by spaces or tabs, as the CSV reader allows.
    """
    if column.null_count == len(column):
        return pa.nulls(len(column))
    trimmed = None
    head = column.slice(0, 16 * _INFER_HEAD_ROWS).drop_null().slice(0, _INFER_HEAD_ROWS)
    if len(head) == 0:
        head = column.drop_null().slice(0, _INFER_HEAD_ROWS)
    trimmed_head = None
    for target in _INFERRED_TYPES:
        if pa.types.is_boolean(target):
            if _all_bool(head) and _all_bool(column):
                is_true = pc.is_in(column, value_set=_TRUE_VALUES)
                return pc.if_else(pc.is_valid(column), is_true, pa.scalar(None, pa.bool_()))
            continue
        values, first = column, head
        if pa.types.is_integer(target) or pa.types.is_floating(target):
            trimmed_head = trimmed_head if trimmed_head is not None else pc.utf8_trim(head, characters=" \t")
            first = trimmed_head
            if _casts(first, target):
                trimmed = trimmed if trimmed is not None else pc.utf8_trim(column, characters=" \t")
                values = trimmed
        # a failing cast reads its whole input before it fails: try a few values first
        if _casts(first, target) and (converted := _cast_or_none(values, target)) is not None:
            return converted
    return column


#: non-null values of a column tried first when its type is inferred
_INFER_HEAD_ROWS = 16


def _cast_or_none(values, target: pa.DataType):
    try:
        return pc.cast(values, target)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return None


def _all_bool(values) -> bool:
    return bool(pc.all(pc.is_in(values, value_set=_BOOL_VALUES), skip_nulls=True).as_py())


def _casts(values, target: pa.DataType) -> bool:
    return _cast_or_none(values, target) is not None


def typed_csv_chunk(table: pa.Table, text_columns: frozenset[str]) -> pa.Table:
    """``table`` (all text) with every column but ``text_columns`` typed by :func:`infer_csv_column`."""
    columns = [
        column if name in text_columns else infer_csv_column(column)
        for name, column in zip(table.column_names, table.columns)
    ]
    return pa.Table.from_arrays(columns, names=table.column_names)

"""Input checks of the tables that :func:`skytrack.analysis.evaluate.evaluate` reads.

Required columns, non-null and finite values, with messages that name the table, the row
(its index label) and the column.  No metrics here.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import pandas as pd


def _py(value: Any) -> Any:
    """Numpy scalars as plain Python values, so messages read ``row 3``, not ``row np.int64(3)``."""
    return value.item() if isinstance(value, np.generic) else value


def _require_columns(frame: pd.DataFrame, table: str, columns: Sequence[str]) -> None:
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"{table} table: missing required column(s) {', '.join(missing)}")


def _require_finite(frame: pd.DataFrame, table: str, columns: Sequence[str], mask: np.ndarray | None = None) -> None:
    for column in columns:
        values = frame[column].to_numpy(dtype=float, na_value=np.nan)
        bad = ~np.isfinite(values)
        if mask is not None:
            bad &= mask
        if np.any(bad):
            row = _py(frame.index[int(np.flatnonzero(bad)[0])])
            raise ValueError(f"{table} table, row {row!r}, column {column!r}: value is null or not finite")


def _require_not_null(frame: pd.DataFrame, table: str, column: str) -> None:
    nulls = frame[column].isna().to_numpy()
    if np.any(nulls):
        row = _py(frame.index[int(np.flatnonzero(nulls)[0])])
        raise ValueError(f"{table} table, row {row!r}, column {column!r}: value is null")

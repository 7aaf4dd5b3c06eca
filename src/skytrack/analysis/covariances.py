"""Track covariances as the evaluation reads them from a tracks table (FORMATS.md ``tracks``).

``_covariances`` builds P over the evaluated state (e.g. x, y, vx, vy) from ``cov_<a>_<b>``
columns by name, from skytrack's indexed ``cov_i_j`` columns over the filter state (its
per-axis layout found and checked against ``var_*`` by ``_indexed_state_layout``), or
from the ``var_*`` diagonal, and says which.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

_INDEXED_COVARIANCE = re.compile(r"cov_(\d+)_(\d+)")


def _float_column(frame: pd.DataFrame, column: str) -> np.ndarray:
    return frame[column].to_numpy(dtype=float, na_value=np.nan)


def _indexed_state_layout(frame: pd.DataFrame, names: list[str], tracking_dim: int) -> tuple[dict[str, str], str] | None:
    """Map ``names`` pairs to ``cov_i_j`` columns written over the filter state.

    skytrack's tracker writes ``cov_i_j`` (i <= j) over its state vector, laid out per axis in
    blocks of ``order`` derivatives (``[x, vx, (ax,) y, vy, (ay,) z, vz, (az)]``, spec 000 R1).
    The number of axes and the order are found from the largest index and checked against
    the ``var_*`` columns, which must equal the matching ``cov_k_k``.
    """
    indexed: dict[tuple[int, int], str] = {}
    for column in frame.columns:
        match = _INDEXED_COVARIANCE.fullmatch(str(column))
        if match:
            i, j = int(match.group(1)), int(match.group(2))
            indexed.setdefault((i, j), column)
            indexed.setdefault((j, i), column)
    if not indexed:
        return None
    n_state = 1 + max(i for i, _ in indexed)
    for ndim in dict.fromkeys((tracking_dim, 3, 2)):
        order = n_state // ndim
        if n_state % ndim or order < 2:
            continue
        index = {f"{prefix}{axis}": k * order + derivative
                 for k, axis in enumerate("xyz"[:ndim]) for prefix, derivative in (("", 0), ("v", 1))}
        if not all(name in index for name in names):
            continue
        checked = [n for n in index if f"var_{n}" in frame.columns and (index[n], index[n]) in indexed]
        agree = all(
            np.allclose(_float_column(frame, indexed[(index[n], index[n])]), _float_column(frame, f"var_{n}"),
                        rtol=1e-9, atol=0.0, equal_nan=True)
            for n in checked
        )
        if agree:
            columns = {f"{a}|{b}": indexed[(index[a], index[b])] for a in names for b in names if (index[a], index[b]) in indexed}
            how = "checked against var_*" if checked else "assumed: no var_* columns to check it"
            return columns, f"cov_i_j over a state of {ndim} axes x {order} derivatives, {how}"
    return None


def _covariances(frame: pd.DataFrame, names: list[str], tracking_dim: int) -> tuple[np.ndarray | None, str]:
    """Covariance ``[rows, n, n]`` over ``names`` (e.g. x, y, vx, vy).

    Full when every pair has a column: ``cov_<a>_<b>`` by name (either order), or skytrack's
    indexed ``cov_i_j`` (:func:`_indexed_state_layout`); otherwise the ``var_*`` diagonal.
    """
    n = len(names)
    layout = _indexed_state_layout(frame, names, tracking_dim)
    indexed, layout_note = layout if layout else ({}, "")

    def column(a: str, b: str) -> str | None:
        for candidate in (f"cov_{a}_{b}", f"cov_{b}_{a}"):
            if candidate in frame.columns:
                return candidate
        if a == b and f"var_{a}" in frame.columns:
            return f"var_{a}"
        return indexed.get(f"{a}|{b}")

    diagonal = [column(a, a) for a in names]
    if any(c is None for c in diagonal):
        return None, "unavailable (no var_* columns for " + ", ".join(a for a, c in zip(names, diagonal) if c is None) + ")"
    off = {(i, j): column(names[i], names[j]) for i in range(n) for j in range(i + 1, n)}
    P = np.zeros((len(frame), n, n))
    for i, c in enumerate(diagonal):
        P[:, i, i] = _float_column(frame, c)
    if all(c is not None for c in off.values()):
        for (i, j), c in off.items():
            P[:, i, j] = P[:, j, i] = _float_column(frame, c)
        used_indexed = any(c in indexed.values() for c in off.values())
        return P, f"full ({layout_note})" if used_indexed else "full"
    has_cov_columns = any(str(c).startswith("cov_") for c in frame.columns)
    return P, "diagonal (cov_* columns present but incomplete or not matched to var_*)" if has_cov_columns else "diagonal"

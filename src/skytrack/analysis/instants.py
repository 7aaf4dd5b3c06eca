"""The output instants of an evaluation: inferred from the track times, and rows mapped onto them.

:func:`infer_output_times` fills the empty instants of a regular grid of track times (and
extends it back to the tracker's start); ``_steps_for_times`` maps each table row to its
instant within a tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from skytrack.analysis.checks import _py

#: a grid is filled only if it adds at most this many instants per present instant
_MAX_FILL_RATIO = 10


def _steps_for_times(times_of_rows: np.ndarray, grid: np.ndarray, tolerance: float, frame: pd.DataFrame, table: str) -> np.ndarray:
    """Index into ``grid`` of each row time; every time must be on the grid (within tolerance)."""
    if grid.size == 0:
        if times_of_rows.size:
            raise ValueError(f"{table} table has rows but there are no output instants")
        return np.zeros(0, np.int64)
    right = np.clip(np.searchsorted(grid, times_of_rows), 0, grid.size - 1)
    left = np.clip(right - 1, 0, grid.size - 1)
    nearest = np.where(np.abs(grid[left] - times_of_rows) <= np.abs(grid[right] - times_of_rows), left, right)
    off = np.abs(grid[nearest] - times_of_rows) > tolerance
    if np.any(off):
        k = int(np.flatnonzero(off)[0])
        raise ValueError(
            f"{table} table, row {_py(frame.index[k])!r}, column 'time': {_py(times_of_rows[k])!r} is not one of the "
            f"output instants (nearest {_py(grid[nearest[k]])!r}, tolerance {tolerance} s)"
        )
    return nearest.astype(np.int64)


def infer_output_times(track_times, tolerance_s: float = 1e-3, start_time_s: float | None = None) -> tuple[np.ndarray, str]:
    """Output instants from the track times.

    Instants where no track existed do not appear in ``tracks``: when the track times lie on a
    regular grid, its missing instants are filled in, and with ``start_time_s`` (when the
    tracker started) the grid is also extended back to that time.
    """
    unique = np.unique(np.asarray(track_times, dtype=float))
    if unique.size < 3:
        return unique, "unique track times"
    steps = np.diff(unique)
    dt = float(steps.min())
    ratio = steps / dt
    regular = dt > tolerance_s and np.all(np.abs(ratio - np.round(ratio)) * dt <= tolerance_s)
    if not regular:
        return unique, "unique track times (not on a regular grid)"
    n_before = 0
    if start_time_s is not None and start_time_s < unique[0] - tolerance_s:
        n_before = int(math.floor((unique[0] - start_time_s + tolerance_s) / dt))
    n_grid = int(round((unique[-1] - unique[0]) / dt)) + 1 + n_before
    if n_grid > _MAX_FILL_RATIO * unique.size:
        return unique, "unique track times (too sparse to fill a grid)"
    if n_grid == unique.size:
        return unique, "unique track times"
    grid = unique[0] + dt * (np.arange(n_grid) - n_before)
    grid[np.round((unique - unique[0]) / dt).astype(np.int64) + n_before] = unique  # keep exact track times
    before = f", {n_before} of them before the first track (start {start_time_s:g} s)" if n_before else ""
    return grid, f"unique track times with {n_grid - unique.size} empty instant(s) of the {dt:g} s grid filled in{before}"

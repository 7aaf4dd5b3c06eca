"""Track rows associated to truth objects, instant by instant and then along each track.

:func:`associate_rows` is the gated least-squares assignment of
:func:`skytrack.analysis.evaluate.evaluate` (:func:`~skytrack.analysis.metrics.cutoff_matching`,
order 2) at every track time; :func:`smooth_along_tracks` then gives each row the object most of
its track's neighbouring rows follow.  Used by the identification report
(:mod:`skytrack.analysis.identification`) and the track-pair scoring
(:mod:`skytrack.analysis.track_pairs`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skytrack.analysis.metrics import cutoff_matching
from skytrack.analysis.truth import _interpolate_truth


def associate_rows(rows: pd.DataFrame, prepared, axes: list[str], cutoff: float, tolerance: float):
    """The truth object (code, -1 = none) of every row by :func:`metrics.cutoff_matching` per track
    time, with what the duplicate check needs: ``(row_target, row_step, row_position, truth_target,
    truth_step, truth_position)`` (truth of every object that exists at each track time)."""
    grid, step = np.unique(rows["time"].to_numpy(dtype=float), return_inverse=True)
    step = step.astype(np.int64).ravel()
    t_target, t_step, t_pos, _ = _interpolate_truth(prepared, grid, axes, tolerance)
    position = rows[axes].to_numpy(dtype=float)
    match = cutoff_matching(t_step, t_pos, step, position, cutoff, 2.0)
    row_target = np.full(len(rows), -1, np.int64)
    row_target[match.estimate_index] = t_target[match.truth_index]
    return row_target, step, position, t_target, t_step, t_pos



#: rows on either side of a row whose associations decide its object (:func:`smooth_along_tracks`)
SMOOTHING_ROWS = 3


def smooth_along_tracks(row_target: np.ndarray, track_id: np.ndarray, time: np.ndarray,
                        half_width: int = SMOOTHING_ROWS) -> np.ndarray:
    """Each row's object as the one most of its track's rows within ±``half_width`` instants are
    associated to (ties: the row's own; rows without any: none).  A per-instant assignment swaps
    two tracks for one instant at a close crossing, and drops a coasting row that lags outside
    the gate in a turn; neither is the track following another object."""
    order = np.lexsort((time, track_id))
    ordered_target, ordered_track = row_target[order], track_id[order]
    n = len(order)
    offsets = np.arange(-half_width, half_width + 1)
    neighbour = np.arange(n)[:, None] + offsets[None, :]
    inside = (neighbour >= 0) & (neighbour < n)
    neighbour = np.clip(neighbour, 0, max(n - 1, 0))
    same_track = inside & (ordered_track[neighbour] == ordered_track[:, None]) if n else inside
    candidates = np.where(same_track, ordered_target[neighbour], -1)
    votes = ((candidates[:, :, None] == candidates[:, None, :]) & (candidates[:, None, :] >= 0)).sum(axis=2)
    votes = votes + (candidates == ordered_target[:, None]) * 0.5  # ties go to the row's own object
    votes = np.where(candidates >= 0, votes, -1)
    best = candidates[np.arange(n), np.argmax(votes, axis=1)] if n else candidates[:, 0]
    smoothed = np.empty_like(row_target)
    smoothed[order] = best
    return smoothed


def existing_objects(row_step: np.ndarray, row_target: np.ndarray, t_step: np.ndarray,
                     t_target: np.ndarray) -> np.ndarray:
    """``row_target`` where that object exists at the row's instant (the truth of :func:`associate_rows`
    has it at that step), else -1: smoothing must not carry a track onto an object that has ended."""
    base = int(max(row_target.max(initial=-1), t_target.max(initial=-1))) + 2
    present = np.isin(row_step * base + row_target, t_step.astype(np.int64) * base + t_target)
    return np.where((row_target >= 0) & present, row_target, -1)


def last_followed(row_target: np.ndarray, track_id: np.ndarray, time: np.ndarray) -> np.ndarray:
    """The object each row's track was last associated to, at this row or before it (-1: none yet)."""
    order = np.lexsort((time, track_id))
    ordered, track = row_target[order], track_id[order]
    position = np.where(ordered >= 0, np.arange(len(order)), -1)
    start = np.r_[True, track[1:] != track[:-1]] if len(order) else np.zeros(0, dtype=bool)
    # the latest associated position so far, restarted at each track's first row
    group_start = np.maximum.accumulate(np.where(start, np.arange(len(order)), 0))
    latest = np.maximum.accumulate(np.where(position >= group_start, position, -1))
    latest = np.where(latest >= group_start, latest, -1)
    result = np.empty_like(row_target)
    result[order] = np.where(latest >= 0, ordered[np.maximum(latest, 0)], -1)
    return result

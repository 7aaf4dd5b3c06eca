"""Truth on the output instants of an evaluation, its visible intervals and the coverage check.

* ``_prepare_truth`` sorts the truth table (FORMATS.md ``truth``) by (target, segment, time)
  and checks it; ``_interpolate_truth`` gives every object's position (and velocity) at the
  output instants by linear interpolation within a segment, with its visibility (both
  bracketing rows visible); ``_first_visible_time`` is when an object becomes visible.
* :func:`truth_visible_runs` lists each object's continuous visible intervals.
* :func:`coverage_check` is the demo acceptance criterion: every object visible for
  ``min_visible_s`` seconds continuously gets a confirmed track while it is visible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.analysis.checks import _py, _require_columns, _require_finite, _require_not_null

DEFAULT_COVERAGE_S = 120.0


@dataclass
class _Truth:
    """Truth table sorted by (target, segment, time) with codes."""

    frame: pd.DataFrame
    target_code: np.ndarray
    target_ids: np.ndarray
    segment_code: np.ndarray  # 0.. over (target, segment) in sorted order
    time: np.ndarray
    visible: np.ndarray


def _prepare_truth(truth: pd.DataFrame, position_columns: list[str], velocity_columns: list[str]) -> tuple[_Truth, list[str]]:
    notes: list[str] = []
    _require_columns(truth, "truth", ["time", "target_id", *position_columns])
    _require_not_null(truth, "truth", "target_id")
    _require_finite(truth, "truth", ["time", *position_columns])
    codes, uniques = pd.factorize(truth["target_id"].astype(str), sort=True)
    segment = truth["segment"].to_numpy() if "segment" in truth.columns else np.zeros(len(truth), np.int64)
    if "segment" in truth.columns:
        _require_not_null(truth, "truth", "segment")
    if "visible" in truth.columns:
        _require_not_null(truth, "truth", "visible")
        visible = truth["visible"].to_numpy(dtype=bool)
    else:
        visible = np.ones(len(truth), dtype=bool)
        notes.append("truth has no 'visible' column: every truth object counts as visible")
    time = truth["time"].to_numpy(dtype=float)
    order = np.lexsort((time, segment, codes))
    frame = truth.iloc[order]
    codes, segment, time, visible = codes[order], segment[order], time[order], visible[order]
    new_segment = np.r_[True, (codes[1:] != codes[:-1]) | (segment[1:] != segment[:-1])]
    duplicate = ~new_segment[1:] & (time[1:] == time[:-1])
    if np.any(duplicate):
        k = int(np.flatnonzero(duplicate)[0]) + 1
        raise ValueError(
            f"truth table, row {_py(frame.index[k])!r}: target {_py(uniques[codes[k]])!r} segment {_py(segment[k])} "
            f"has two rows at time {_py(time[k])!r}"
        )
    for column in velocity_columns:
        if column not in truth.columns:
            raise ValueError(f"truth table: missing column {column!r} needed for velocity errors")
    _require_finite(frame, "truth", velocity_columns)
    return _Truth(frame, codes, np.asarray(uniques, dtype=object), np.cumsum(new_segment) - 1, time, visible), notes


def _interpolate_truth(truth: _Truth, grid: np.ndarray, columns: list[str], tolerance: float):
    """Truth at the output instants: (target code, step, values[:, columns], visible), sorted by (target, step)."""
    n_rows = truth.time.size
    seg = truth.segment_code
    n_seg = int(seg[-1]) + 1 if n_rows else 0
    first = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]]) if n_rows else np.zeros(0, np.int64)
    last = np.r_[first[1:], n_rows] - 1 if n_rows else np.zeros(0, np.int64)
    lo = np.searchsorted(grid, truth.time[first] - tolerance, side="left")
    hi = np.searchsorted(grid, truth.time[last] + tolerance, side="right")
    counts = np.maximum(hi - lo, 0)
    total = int(counts.sum())
    q_seg = np.repeat(np.arange(n_seg), counts)
    q_step = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(lo, counts)
    q_time = grid[q_step]
    # merge rows and queries sorted by (segment, time, row-before-query): the latest row at or
    # before each query is its left bracket
    merged_seg = np.r_[seg, q_seg]
    merged_time = np.r_[truth.time, q_time]
    kind = np.r_[np.zeros(n_rows, np.int8), np.ones(total, np.int8)]
    order = np.lexsort((kind, merged_time, merged_seg))
    marker = np.r_[np.arange(n_rows), np.full(total, -1)][order]
    latest = np.maximum.accumulate(marker) if marker.size else marker
    left = np.empty(total, np.int64)
    left[order[kind[order] == 1] - n_rows] = latest[kind[order] == 1]
    seg_first, seg_last = first[q_seg], last[q_seg]
    left = np.clip(left, seg_first, np.maximum(seg_first, seg_last - 1))
    right = np.minimum(left + 1, seg_last)
    span = truth.time[right] - truth.time[left]
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = np.where(span > 0, (q_time - truth.time[left]) / span, 0.0)
    weight = np.clip(weight, 0.0, 1.0)
    values_all = truth.frame[columns].to_numpy(dtype=float)
    values = values_all[left] + weight[:, None] * (values_all[right] - values_all[left])
    vis = truth.visible
    visible = np.where(weight <= 0.0, vis[left], np.where(weight >= 1.0, vis[right], vis[left] & vis[right]))
    target = truth.target_code[first[q_seg]]
    # segments touching at one instant: keep the first (lowest segment, queries are in segment order)
    key = target.astype(np.int64) * max(grid.size, 1) + q_step
    _, keep = np.unique(key, return_index=True)
    return target[keep], q_step[keep], values[keep], visible[keep]


def truth_visible_runs(truth: pd.DataFrame, window: tuple[float, float] | None = None, tolerance_s: float = 1e-3) -> pd.DataFrame:
    """Continuous visible intervals of every truth object: consecutive visible rows of a segment,
    joined across segments that touch in time.

    Columns ``target_id, segment`` (the first segment of the interval), ``start, end,
    duration_s``; with ``window = (t0, t1)`` the intervals are clipped to it and those outside
    it dropped.
    """
    prepared, _ = _prepare_truth(truth, ["x"], [])
    seg = prepared.segment_code
    vis = prepared.visible
    if seg.size == 0:
        return pd.DataFrame({"target_id": [], "segment": [], "start": [], "end": [], "duration_s": []})
    start_run = vis & np.r_[True, (~vis[:-1]) | (seg[1:] != seg[:-1])]
    run_id = np.cumsum(start_run) - 1
    rows = np.flatnonzero(vis)
    rid = run_id[rows]
    starts = prepared.time[rows[np.r_[True, rid[1:] != rid[:-1]]]] if rows.size else np.zeros(0)
    ends = prepared.time[rows[np.r_[rid[1:] != rid[:-1], True]]] if rows.size else np.zeros(0)
    first_rows = rows[np.r_[True, rid[1:] != rid[:-1]]] if rows.size else np.zeros(0, np.int64)
    segment_col = prepared.frame["segment"].to_numpy() if "segment" in prepared.frame.columns else np.zeros(len(prepared.frame), np.int64)
    runs = pd.DataFrame(
        {
            "target_id": prepared.target_ids[prepared.target_code[first_rows]].astype(str),
            "segment": segment_col[first_rows].astype(np.int64),
            "start": starts,
            "end": ends,
        }
    )
    # segments of one object that touch in time (next starts where the previous ends) are one
    # continuous visible interval; runs are already in (target, segment, time) order
    code = prepared.target_code[first_rows]
    touching = np.r_[False, (code[1:] == code[:-1]) & (starts[1:] <= ends[:-1] + tolerance_s)]
    if np.any(touching):
        group = np.cumsum(~touching) - 1
        runs = runs.groupby(group).agg(target_id=("target_id", "first"), segment=("segment", "first"),
                                       start=("start", "min"), end=("end", "max")).reset_index(drop=True)
    if window is not None:
        runs["start"] = runs["start"].clip(lower=window[0])
        runs["end"] = runs["end"].clip(upper=window[1])
        runs = runs[runs["end"] >= runs["start"]].reset_index(drop=True)
    runs["duration_s"] = runs["end"] - runs["start"]
    return runs


def _first_visible_time(prepared, grid, n_targets, tolerance, window_start) -> np.ndarray:
    """When each object becomes visible inside the window [window_start, last instant]: its
    first visible truth row there, or ``window_start`` when it is already visible then."""
    first = np.full(n_targets, np.inf)
    if grid.size == 0:
        return first
    rows = prepared.visible & (prepared.time >= window_start - tolerance) & (prepared.time <= grid[-1] + tolerance)
    np.minimum.at(first, prepared.target_code[rows], prepared.time[rows])
    target, _, _, visible = _interpolate_truth(prepared, np.array([window_start]), ["x"], tolerance)
    at_start = target[visible]
    first[at_start] = np.minimum(first[at_start], window_start)
    return np.where(np.isfinite(first), first, np.nan)


def coverage_check(
    truth: pd.DataFrame,
    assignments: pd.DataFrame,
    min_visible_s: float = DEFAULT_COVERAGE_S,
    window: tuple[float, float] | None = None,
    tolerance_s: float = 1e-3,
) -> pd.DataFrame:
    """Truth objects continuously visible for at least ``min_visible_s`` and whether each got a track.

    ``assignments`` is :attr:`Evaluation.assignments` (columns ``time, target_id, track_id``);
    ``window`` clips the visible intervals (use the evaluated time span so that intervals the
    tracker never saw do not count).  Columns: ``target_id, segment, start, end, duration_s,
    tracked, first_track_time, time_to_track_s, track_id``.
    """
    runs = truth_visible_runs(truth, window, tolerance_s)
    runs = runs[runs["duration_s"] >= min_visible_s - tolerance_s].sort_values("start").reset_index(drop=True)
    first = assignments[["time", "target_id", "track_id"]].sort_values("time")
    first = first.assign(target_id=first["target_id"].astype(str), first_track_time=first["time"].astype(float))
    runs = runs.assign(target_id=runs["target_id"].astype(str), start=runs["start"].astype(float))
    if len(runs):
        merged = pd.merge_asof(
            runs,
            first[["first_track_time", "target_id", "track_id"]],
            left_on="start",
            right_on="first_track_time",
            by="target_id",
            direction="forward",
            tolerance=None,
        )
    else:
        merged = runs.assign(first_track_time=np.zeros(0), track_id=np.zeros(0))
    within = merged["first_track_time"].to_numpy(dtype=float, na_value=np.nan) <= merged["end"].to_numpy(dtype=float) + tolerance_s
    merged["tracked"] = within
    merged.loc[~within, ["first_track_time", "track_id"]] = np.nan
    merged["time_to_track_s"] = merged["first_track_time"] - merged["start"]
    merged["track_id"] = merged["track_id"].astype("Int64")
    return merged[["target_id", "segment", "start", "end", "duration_s", "tracked", "first_track_time", "time_to_track_s", "track_id"]]

"""Evaluation of a tracker's output (FORMATS.md ``tracks``) against truth (FORMATS.md ``truth``).

What :func:`evaluate` does, at every output instant ``t_k``:

1. **Truth at the instant.**  Between two rows of a segment the truth is their linear
   interpolation (FORMATS.md); an object exists at ``t_k`` when one of its segments spans
   ``t_k``.  It is *visible* at ``t_k`` when the row at ``t_k`` is visible or, between rows,
   when both bracketing rows are (the conservative reading of a per-row flag).  Where two
   segments touch at one instant the lower-numbered segment is used.
2. **Association.**  Confirmed tracks (status ``confirmed`` or ``coasting``) are assigned
   to visible truth objects by the gated least-squares assignment: maximise
   ``sum (g^2 - d^2)`` over pairs closer than the gate ``g`` (:func:`metrics.cutoff_matching`
   with order 2, i.e. ``linear_sum_assignment`` per connected cluster).
3. **Statistics** from the assigned pairs: position / velocity RMSE (overall, per object,
   per instant), NEES of the position+velocity state with the full covariance when the
   tracks carry it (``cov_<a>_<b>`` by name, e.g. ``cov_x_vy``, or the tracker's
   ``cov_i_j`` over its per-axis state vector, checked against ``var_*``), else the
   ``var_*`` diagonal (``Evaluation.nees['covariance']`` says which); per truth object:
   continuity (fraction of its visible instants with an assigned track), track breaks (at
   consecutive visible instants, an assigned track followed by no track or a different
   track), swaps received (a track that was assigned to another object earlier), number
   of distinct tracks, time from becoming visible to the first assigned track; per track:
   assigned fraction, number of truth changes (swaps), false flag (assigned fraction
   below ``false_track_min_assigned_fraction``); OSPA and GOSPA (metrics module) between
   the visible truth set and the confirmed track set.

The output instants are the track times (a regular grid's empty instants filled in, and
extended back to ``start_time_s`` when given) or ``output_times``.  Tracks without ``z``
(2-D tracking) are evaluated horizontally: x/y positions and vx/vy
velocities only.  :attr:`Evaluation.dimension` says which.

:func:`coverage_check` is the demo acceptance criterion: every truth object that stays
visible for ``min_visible_s`` seconds continuously (inside the evaluated time window)
gets a confirmed track while it is visible.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import pandas as pd

from skytrack.analysis.metrics import cutoff_matching, nees, nees_band, rmse, set_metrics_stacked

__all__ = [
    "Evaluation",
    "evaluate",
    "coverage_check",
    "truth_visible_runs",
    "infer_output_times",
    "CONFIRMED_STATUSES",
]

CONFIRMED_STATUSES = ("confirmed", "coasting")
DEFAULT_CUTOFF_M = 2000.0
DEFAULT_ORDER = 2.0
DEFAULT_GATE_M = 2000.0
DEFAULT_COVERAGE_S = 120.0
#: a grid is filled only if it adds at most this many instants per present instant
_MAX_FILL_RATIO = 10

UNITS_NOTE = (
    "distances in m, velocities in m/s, times in s since the scenario epoch, durations in s; "
    "NEES dimensionless; continuity and fractions in [0, 1]; gospa_localisation is the sum of "
    "d^p over assigned pairs (m^p), gospa_missed / gospa_false are counts, and "
    "GOSPA^p = gospa_localisation + cutoff^p / 2 * (gospa_missed + gospa_false)"
)


# ----------------------------------------------------------------------------- input checks


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


# ----------------------------------------------------------------------------- truth


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


# ----------------------------------------------------------------------------- tracks


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


# ----------------------------------------------------------------------------- result


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(float(value)) else None
    if value is None or value is pd.NA or value is pd.NaT:
        return None
    return value if isinstance(value, str) else str(value)


def _records(frame: pd.DataFrame) -> list[dict[str, Any]]:
    return [_jsonable(r) for r in frame.to_dict(orient="records")]


@dataclass
class Evaluation:
    """Result of :func:`evaluate`.

    * ``series``: one row per output instant (``time, n_truth_visible, n_tracks, n_assigned,
      position_rmse_m, ospa_m, gospa_m, gospa_localisation, gospa_missed, gospa_false``);
    * ``per_target``: one row per truth object visible at some output instant;
    * ``per_track``: one row per confirmed track;
    * ``assignments``: one row per assigned (instant, truth, track) pair with its errors;
    * ``coverage``: the :func:`coverage_check` table for ``parameters['coverage_min_visible_s']``;
    * ``summary``: the scalar results (see :meth:`to_dict`).
    """

    parameters: dict[str, Any]
    dimension: str
    times: np.ndarray
    output_times_source: str
    series: pd.DataFrame
    per_target: pd.DataFrame
    per_track: pd.DataFrame
    assignments: pd.DataFrame
    coverage: pd.DataFrame
    summary: dict[str, Any]
    nees: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def false_track_ids(self) -> list[int]:
        return self.per_track.loc[self.per_track["is_false"], "track_id"].astype(int).tolist()

    def to_dict(self, per_target: bool = True) -> dict[str, Any]:
        """JSON-serialisable summary (NaN becomes null); ``per_target`` adds the per-object table."""
        cov = self.coverage
        untracked = cov.loc[~cov["tracked"], ["target_id", "segment", "start", "end", "duration_s"]]
        out: dict[str, Any] = {
            "units": UNITS_NOTE,
            "dimension": self.dimension,
            "notes": list(self.notes),
            "parameters": dict(self.parameters),
            "output_times_source": self.output_times_source,
            **self.summary,
            "nees": dict(self.nees),
            "false_tracks": {
                "count": self.summary["n_false_tracks"],
                "fraction_of_tracks": self.summary["false_track_fraction"],
                "fraction_of_track_time": self.summary["false_track_time_fraction"],
                "track_ids": self.false_track_ids,
            },
            "coverage": {
                "min_visible_s": self.parameters["coverage_min_visible_s"],
                "n_objects": int(len(cov)),
                "n_tracked": int(cov["tracked"].sum()),
                "all_tracked": bool(cov["tracked"].all()),
                "untracked": _records(untracked),
            },
        }
        if per_target:
            out["per_target"] = _records(self.per_target)
        return _jsonable(out)

    def summary_rows(self) -> list[tuple[str, str, str]]:
        """(metric, value, unit) string rows for a table (e.g. ``rich.table.Table.add_row``)."""
        s = self.summary

        def num(value, fmt="{:.1f}"):
            return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else fmt.format(value)

        cov = self.coverage
        p = self.parameters
        rows = [
            ("evaluation", self.dimension, ""),
            ("output instants", f"{s['n_output_times']} ({num(s['time_start_s'])} .. {num(s['time_end_s'])})", "s"),
            ("truth objects (visible)", str(s["n_truth_objects"]), ""),
            ("confirmed tracks", str(s["n_tracks"]), ""),
            ("position RMSE", num(s["position_rmse_m"]), "m"),
        ]
        if s["position_rmse_vertical_m"] is not None and math.isfinite(s["position_rmse_vertical_m"]):
            rows.append(("  horizontal / vertical", f"{num(s['position_rmse_horizontal_m'])} / {num(s['position_rmse_vertical_m'])}", "m"))
        rows += [
            ("velocity RMSE", num(s["velocity_rmse_mps"]), "m/s"),
            (
                f"NEES mean ({self.nees['state']}, {self.nees['covariance'].split(' ')[0]} covariance)",
                f"{num(self.nees['mean'], '{:.2f}')} (expected {self.nees['expected']}, 95% band "
                f"{num(self.nees['band_95'][0], '{:.2f}')}..{num(self.nees['band_95'][1], '{:.2f}')})",
                "",
            ),
            ("continuity (mean over objects)", num(s["continuity_mean"], "{:.3f}"), ""),
            ("track breaks", str(s["track_breaks"]), ""),
            ("track swaps", f"{s['track_swaps']} ({s['n_swapped_tracks']} tracks)", ""),
            ("tracks per truth object", num(s["tracks_per_truth_mean"], "{:.2f}"), ""),
            ("time to first track (mean / max)", f"{num(s['time_to_first_track_mean_s'])} / {num(s['time_to_first_track_max_s'])}", "s"),
            ("objects never tracked", str(s["n_truth_never_tracked"]), ""),
            (
                "false tracks",
                f"{s['n_false_tracks']} ({num(100 * s['false_track_fraction'] if s['n_tracks'] else float('nan'))}% of tracks, "
                f"{num(100 * s['false_track_time_fraction'] if s['n_tracks'] else float('nan'))}% of track time)",
                "",
            ),
            (f"OSPA mean (c={p['cutoff_m']:g} m, p={p['order']:g})", num(s["ospa_mean_m"]), "m"),
            (f"GOSPA mean (c={p['cutoff_m']:g} m, p={p['order']:g})", num(s["gospa_mean_m"]), "m"),
            (
                f"coverage: objects visible >= {p['coverage_min_visible_s']:g} s tracked",
                f"{int(cov['tracked'].sum())} / {len(cov)}",
                "",
            ),
        ]
        return rows


# ----------------------------------------------------------------------------- coverage


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


# ----------------------------------------------------------------------------- evaluate


def _dimension(tracks: pd.DataFrame, horizontal: bool | None) -> tuple[int, str]:
    has_z = "z" in tracks.columns
    null_z = int(tracks["z"].isna().sum()) if has_z else len(tracks)
    if horizontal is None:
        if not has_z or (len(tracks) and null_z == len(tracks)):
            return 2, "horizontal (tracks have no z: 2-D tracking)"
        if null_z:
            return 2, f"horizontal (z is null in {null_z} of {len(tracks)} track rows)"
        return 3, "3-D"
    if horizontal:
        return 2, "horizontal (requested)"
    if null_z:
        raise ValueError(f"tracks table, column 'z': null in {null_z} of {len(tracks)} rows; 3-D evaluation needs z")
    return 3, "3-D"


def evaluate(
    tracks: pd.DataFrame,
    truth: pd.DataFrame,
    cutoff_m: float = DEFAULT_CUTOFF_M,
    order: float = DEFAULT_ORDER,
    association_gate_m: float = DEFAULT_GATE_M,
    *,
    output_times: Sequence[float] | np.ndarray | None = None,
    start_time_s: float | None = None,
    horizontal: bool | None = None,
    false_track_min_assigned_fraction: float = 0.5,
    coverage_min_visible_s: float = DEFAULT_COVERAGE_S,
    confirmed_statuses: Sequence[str] = CONFIRMED_STATUSES,
    time_tolerance_s: float = 1e-3,
) -> Evaluation:
    """Evaluate ``tracks`` against ``truth`` (both FORMATS.md tables); see the module docstring.

    ``cutoff_m`` and ``order`` are OSPA/GOSPA's ``c`` and ``p``; ``association_gate_m`` is the
    largest track-to-truth distance of an assignment.  ``output_times`` are the instants to
    evaluate (default: :func:`infer_output_times` of the track times; give them explicitly
    when the tracker had instants without any track at the start or end of the run).
    ``start_time_s`` is when the tracker started (e.g. the first plot time): truth visible
    before it counts as becoming visible then, and an inferred regular grid is extended back
    to it; default: the first output instant.
    ``horizontal`` forces (True) or forbids (False) horizontal evaluation; None decides from
    the tracks' ``z``.
    """
    notes: list[str] = []
    _require_columns(tracks, "tracks", ["time", "track_id", "x", "y"])
    _require_not_null(tracks, "tracks", "track_id")
    _require_finite(tracks, "tracks", ["time"])
    if not 0.0 <= false_track_min_assigned_fraction <= 1.0:
        raise ValueError("false_track_min_assigned_fraction must be in [0, 1]")
    if not (np.isfinite(association_gate_m) and association_gate_m > 0):
        raise ValueError(f"association_gate_m must be a finite positive distance, got {association_gate_m!r}")

    if "status" in tracks.columns:
        confirmed = tracks["status"].isin(list(confirmed_statuses)).to_numpy()
        if not confirmed.all():
            other = tracks.loc[~confirmed, "status"].astype(str).value_counts()
            notes.append(
                f"{int((~confirmed).sum())} track rows ignored (status not in {list(confirmed_statuses)}: "
                + ", ".join(f"{k}={v}" for k, v in other.items())
                + ")"
            )
        tracks = tracks[confirmed]
    dim, dimension = _dimension(tracks, horizontal)
    axes = ["x", "y", "z"][:dim]
    vel_axes = ["vx", "vy", "vz"][:dim]
    _require_finite(tracks, "tracks", axes)
    has_velocity = all(c in tracks.columns for c in vel_axes) and all(c in truth.columns for c in vel_axes)
    if not has_velocity:
        notes.append(f"no velocity errors: {', '.join(vel_axes)} missing in tracks or truth")

    if output_times is None:
        grid, source = infer_output_times(tracks["time"].to_numpy(dtype=float), time_tolerance_s, start_time_s)
        if grid.size == 0:
            raise ValueError("tracks table has no confirmed rows: give output_times to evaluate an empty output")
    else:
        grid = np.unique(np.asarray(output_times, dtype=float))
        source = "given"
    n_steps = grid.size
    window_start = float(grid[0]) if start_time_s is None or n_steps == 0 else min(float(start_time_s), float(grid[0]))

    # ---- tracks on the grid
    track_step = _steps_for_times(tracks["time"].to_numpy(dtype=float), grid, time_tolerance_s, tracks, "tracks")
    track_code, track_ids = pd.factorize(tracks["track_id"], sort=True)
    track_ids = np.asarray(track_ids).astype(np.int64)
    dup = pd.Series(track_code * n_steps + track_step).duplicated().to_numpy()
    if np.any(dup):
        k = int(np.flatnonzero(dup)[0])
        raise ValueError(
            f"tracks table, row {_py(tracks.index[k])!r}: track {_py(track_ids[track_code[k]])} appears twice "
            f"at time {_py(grid[track_step[k]])!r}"
        )
    track_pos = tracks[axes].to_numpy(dtype=float)
    track_vel = tracks[vel_axes].to_numpy(dtype=float, na_value=np.nan) if has_velocity else np.full((len(tracks), dim), np.nan)

    # ---- truth on the grid
    prepared, truth_notes = _prepare_truth(truth, axes, vel_axes if has_velocity else [])
    notes += truth_notes
    columns = axes + (vel_axes if has_velocity else [])
    t_target, t_step, t_values, t_visible = _interpolate_truth(prepared, grid, columns, time_tolerance_s)
    vis = np.flatnonzero(t_visible)
    vt_target, vt_step = t_target[vis], t_step[vis]
    vt_pos = t_values[vis, :dim]
    vt_vel = t_values[vis, dim:] if has_velocity else np.full((vis.size, dim), np.nan)

    # ---- association and set metrics
    match = cutoff_matching(vt_step, vt_pos, track_step, track_pos, association_gate_m, 2.0)
    # the association is the cutoff matching with c = gate, p = 2: reuse it when OSPA/GOSPA use the same
    same = float(cutoff_m) == float(association_gate_m) and float(order) == 2.0
    sets = set_metrics_stacked(vt_step, vt_pos, track_step, track_pos, n_steps, cutoff_m, order, match if same else None)

    assigned_track = np.full(vis.size, -1, np.int64)
    assigned_track[match.truth_index] = track_code[match.estimate_index]
    ti, ei = match.truth_index, match.estimate_index
    pos_err = track_pos[ei] - vt_pos[ti]
    vel_err = track_vel[ei] - vt_vel[ti]
    pos_sq = np.einsum("ij,ij->i", pos_err, pos_err)
    vel_sq = np.einsum("ij,ij->i", vel_err, vel_err)
    vel_ok = np.isfinite(vel_sq)

    assignments = pd.DataFrame(
        {
            "time": grid[vt_step[ti]],
            "target_id": prepared.target_ids[vt_target[ti]].astype(str),
            "track_id": track_ids[track_code[ei]],
            "distance_m": match.distance,
            "velocity_error_mps": np.sqrt(vel_sq),
        }
    )
    for a, column in enumerate(axes):
        assignments[f"error_{column}"] = pos_err[:, a]

    tracking_dim = 3 if "z" in tracks.columns and len(tracks) and tracks["z"].notna().all() else 2
    nees_info = _nees_summary(tracks.iloc[ei], pos_err, vel_err, axes, vel_axes, has_velocity, tracking_dim)
    assignments["nees"] = nees_info.pop("_values")

    per_target = _per_target(prepared, grid, vt_target, vt_step, assigned_track, track_ids, ti, ei, track_code,
                             pos_sq, vel_sq, vel_ok, time_tolerance_s, window_start)
    per_track = _per_track(track_code, track_ids, track_step, grid, ei, vt_target[ti], prepared.target_ids,
                           false_track_min_assigned_fraction)

    # ---- series
    step_of_match = vt_step[ti]
    n_assigned = np.bincount(step_of_match, minlength=n_steps)
    with np.errstate(invalid="ignore", divide="ignore"):
        step_rmse = np.sqrt(np.bincount(step_of_match, weights=pos_sq, minlength=n_steps) / n_assigned)
    series = pd.DataFrame(
        {
            "time": grid,
            "n_truth_visible": sets.n_truth,
            "n_tracks": sets.n_estimates,
            "n_assigned": n_assigned,
            "position_rmse_m": step_rmse,
            "ospa_m": sets.ospa,
            "gospa_m": sets.gospa,
            "gospa_localisation": sets.gospa_localisation,
            "gospa_missed": sets.gospa_missed,
            "gospa_false": sets.gospa_false,
        }
    )

    coverage = coverage_check(truth, assignments, coverage_min_visible_s, (window_start, float(grid[-1])) if n_steps else None,
                              time_tolerance_s)
    parameters = {
        "cutoff_m": float(cutoff_m),
        "order": float(order),
        "association_gate_m": float(association_gate_m),
        "false_track_min_assigned_fraction": float(false_track_min_assigned_fraction),
        "coverage_min_visible_s": float(coverage_min_visible_s),
        "confirmed_statuses": list(confirmed_statuses),
        "time_tolerance_s": float(time_tolerance_s),
        "start_time_s": window_start if n_steps else None,
    }
    summary = _summary(grid, per_target, per_track, sets, pos_sq, pos_err, vel_sq, vel_ok, dim, len(tracks))
    return Evaluation(parameters, dimension, grid, source, series, per_target, per_track, assignments, coverage,
                      summary, nees_info, notes)


def _nees_summary(rows: pd.DataFrame, pos_err, vel_err, axes, vel_axes, has_velocity, tracking_dim) -> dict[str, Any]:
    """Mean NEES of the position+velocity state (and of position alone) over assigned pairs."""
    names = axes + (vel_axes if has_velocity else [])
    errors = np.hstack([pos_err, vel_err]) if has_velocity else pos_err
    P, kind = _covariances(rows, names, tracking_dim)
    state = "position+velocity" if has_velocity else "position"
    info: dict[str, Any] = {"state": state, "dimension": len(names), "covariance": kind, "expected": float(len(names))}
    if P is None:
        return {**info, "mean": None, "band_95": [None, None], "n_samples": 0, "n_skipped": int(len(rows)),
                "position_mean": None, "position_dimension": len(axes), "position_band_95": [None, None],
                "_values": np.full(len(rows), np.nan)}
    values, valid = nees(errors, P)
    pos_values, pos_valid = nees(pos_err, P[:, : len(axes), : len(axes)])
    n, n_pos = int(valid.sum()), int(pos_valid.sum())
    info.update(
        mean=float(values[valid].mean()) if n else None,
        band_95=list(nees_band(n, len(names))),
        n_samples=n,
        n_skipped=int(len(rows) - n),
        position_mean=float(pos_values[pos_valid].mean()) if n_pos else None,
        position_dimension=len(axes),
        position_band_95=list(nees_band(n_pos, len(axes))),
        band_note="band assumes independent samples; errors of one track are correlated in time, so it is optimistic",
        _values=values,
    )
    return info


def _per_target(prepared, grid, vt_target, vt_step, assigned_track, track_ids, ti, ei, track_code,
                pos_sq, vel_sq, vel_ok, tolerance, window_start) -> pd.DataFrame:
    n_targets = prepared.target_ids.size
    visible_count = np.bincount(vt_target, minlength=n_targets)
    covered = np.bincount(vt_target, weights=assigned_track >= 0, minlength=n_targets)
    # breaks: at consecutive instants both visible, an assigned track followed by none or another
    same = (vt_target[1:] == vt_target[:-1]) & (vt_step[1:] == vt_step[:-1] + 1)
    is_break = same & (assigned_track[:-1] >= 0) & (assigned_track[1:] != assigned_track[:-1])
    breaks = np.bincount(vt_target[:-1][is_break], minlength=n_targets) if vt_target.size > 1 else np.zeros(n_targets, np.int64)
    # swaps received: the assigned track's previous assigned object was a different one
    tgt_of_match = vt_target[ti]
    code_of_match = track_code[ei]
    step_of_match = vt_step[ti]
    order = np.lexsort((step_of_match, code_of_match))
    c_sorted, t_sorted = code_of_match[order], tgt_of_match[order]
    swap = (c_sorted[1:] == c_sorted[:-1]) & (t_sorted[1:] != t_sorted[:-1])
    swaps = np.bincount(t_sorted[1:][swap], minlength=n_targets) if swap.size else np.zeros(n_targets, np.int64)
    pairs = np.unique(tgt_of_match.astype(np.int64) * (track_ids.size + 1) + code_of_match)
    n_tracks = np.bincount(pairs // (track_ids.size + 1), minlength=n_targets)
    first_step = np.full(n_targets, np.iinfo(np.int64).max)
    np.minimum.at(first_step, tgt_of_match, step_of_match)
    tracked = first_step < np.iinfo(np.int64).max
    first_track_time = np.where(tracked, grid[np.minimum(first_step, grid.size - 1)], np.nan)
    first_visible = _first_visible_time(prepared, grid, n_targets, tolerance, window_start)
    n_assigned = np.bincount(tgt_of_match, minlength=n_targets)
    with np.errstate(invalid="ignore", divide="ignore"):
        pos_rmse = np.sqrt(np.bincount(tgt_of_match, weights=pos_sq, minlength=n_targets) / n_assigned)
        n_vel = np.bincount(tgt_of_match[vel_ok], minlength=n_targets)
        vel_rmse = np.sqrt(np.bincount(tgt_of_match[vel_ok], weights=vel_sq[vel_ok], minlength=n_targets) / n_vel)
        continuity = covered / visible_count
    frame = pd.DataFrame(
        {
            "target_id": prepared.target_ids.astype(str),
            "n_visible_instants": visible_count,
            "n_covered_instants": covered.astype(np.int64),
            "continuity": continuity,
            "track_breaks": breaks,
            "track_swaps": swaps,
            "n_tracks": n_tracks,
            "first_visible_time": first_visible,
            "first_track_time": first_track_time,
            "time_to_first_track_s": first_track_time - first_visible,
            "position_rmse_m": pos_rmse,
            "velocity_rmse_mps": vel_rmse,
        }
    )
    return frame[visible_count > 0].reset_index(drop=True)


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


def _per_track(track_code, track_ids, track_step, grid, ei, match_target, target_ids, min_fraction) -> pd.DataFrame:
    n = track_ids.size
    n_rows = np.bincount(track_code, minlength=n)
    matched_code = track_code[ei]
    n_assigned = np.bincount(matched_code, minlength=n)
    first = np.full(n, np.inf)
    last = np.full(n, -np.inf)
    np.minimum.at(first, track_code, grid[track_step])
    np.maximum.at(last, track_code, grid[track_step])
    order = np.lexsort((track_step[ei], matched_code))
    c_sorted, t_sorted = matched_code[order], match_target[order]
    change = (c_sorted[1:] == c_sorted[:-1]) & (t_sorted[1:] != t_sorted[:-1])
    swaps = np.bincount(c_sorted[1:][change], minlength=n) if change.size else np.zeros(n, np.int64)
    pair_counts = pd.DataFrame({"track": matched_code, "target": match_target}).value_counts().reset_index(name="count")
    pair_counts = pair_counts.sort_values(["track", "count", "target"], ascending=[True, False, True])
    n_truths = pair_counts.groupby("track").size().reindex(range(n), fill_value=0).to_numpy()
    main = pair_counts.drop_duplicates("track").set_index("track")["target"].reindex(range(n))
    has_main = main.notna().to_numpy()
    main_id = np.full(n, None, dtype=object)
    main_id[has_main] = target_ids[main[has_main].to_numpy(dtype=np.int64)].astype(str)
    fraction = n_assigned / np.maximum(n_rows, 1)
    return pd.DataFrame(
        {
            "track_id": track_ids,
            "n_instants": n_rows,
            "n_assigned": n_assigned,
            "assigned_fraction": fraction,
            "n_truths": n_truths,
            "swaps": swaps,
            "main_target_id": main_id,
            "first_time": first,
            "last_time": last,
            "is_false": fraction < min_fraction,
        }
    )


def _summary(grid, per_target, per_track, sets, pos_sq, pos_err, vel_sq, vel_ok, dim, n_track_rows) -> dict[str, Any]:
    def nan_stat(values, fn):
        values = np.asarray(values, dtype=float)
        values = values[np.isfinite(values)]
        return float(fn(values)) if values.size else float("nan")

    horizontal_sq = np.einsum("ij,ij->i", pos_err[:, :2], pos_err[:, :2])
    ttf = per_target["time_to_first_track_s"].to_numpy(dtype=float)
    track_time = per_track["n_instants"].to_numpy()
    total_time = max(int(track_time.sum()), 1)
    n_tracks = len(per_track)
    visible_total = int(per_target["n_visible_instants"].sum())
    return {
        "n_output_times": int(grid.size),
        "time_start_s": float(grid[0]) if grid.size else float("nan"),
        "time_end_s": float(grid[-1]) if grid.size else float("nan"),
        "n_truth_objects": int(len(per_target)),
        "n_tracks": int(n_tracks),
        "n_track_rows": int(n_track_rows),
        "n_truth_visible_instants": visible_total,
        "n_assigned": int(pos_sq.size),
        "position_rmse_m": rmse(np.sqrt(pos_sq)),
        "position_rmse_horizontal_m": rmse(np.sqrt(horizontal_sq)),
        "position_rmse_vertical_m": rmse(pos_err[:, 2]) if dim == 3 else None,
        "velocity_rmse_mps": rmse(np.sqrt(vel_sq[vel_ok])),
        "n_velocity_samples": int(vel_ok.sum()),
        "continuity_mean": nan_stat(per_target["continuity"], np.mean),
        "continuity_overall": float(per_target["n_covered_instants"].sum() / visible_total) if visible_total else float("nan"),
        "track_breaks": int(per_target["track_breaks"].sum()),
        "track_swaps": int(per_track["swaps"].sum()),
        "n_swapped_tracks": int((per_track["swaps"] > 0).sum()),
        "tracks_per_truth_mean": nan_stat(per_target["n_tracks"], np.mean),
        "n_truth_never_tracked": int((per_target["n_tracks"] == 0).sum()),
        "time_to_first_track_mean_s": nan_stat(ttf, np.mean),
        "time_to_first_track_median_s": nan_stat(ttf, np.median),
        "time_to_first_track_max_s": nan_stat(ttf, np.max),
        "n_false_tracks": int(per_track["is_false"].sum()),
        "false_track_fraction": float(per_track["is_false"].mean()) if n_tracks else 0.0,
        "false_track_time_fraction": float(track_time[per_track["is_false"].to_numpy()].sum() / total_time),
        "unassigned_track_time_fraction": float(1.0 - per_track["n_assigned"].sum() / total_time) if n_tracks else 0.0,
        "ospa_mean_m": sets.ospa_mean,
        "gospa_mean_m": sets.gospa_mean,
        "gospa_localisation_mean": nan_stat(sets.gospa_localisation, np.mean),
        "gospa_missed_mean": nan_stat(sets.gospa_missed, np.mean),
        "gospa_false_mean": nan_stat(sets.gospa_false, np.mean),
    }

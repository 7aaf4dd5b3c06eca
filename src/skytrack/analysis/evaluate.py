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
4. **Manoeuvre segments** (optional ``manoeuvre_segments``: ``(target_id, start, end)``
   time intervals of truth objects, e.g. the segments of a manoeuvre rule such as spec 004
   R19's, found by the caller): the assigned pairs whose truth instant lies in a segment of
   its own object (ends included, :func:`metrics.in_intervals`) give the position and
   velocity RMSE in manoeuvres, with the numbers of segments and samples behind them.

The output instants are the track times (a regular grid's empty instants filled in,
extended back to ``start_time_s`` when given, and cut at the truth's last time: after it the
truth does not say what flew, a note says how many were left out) or ``output_times``.  Tracks without ``z``
(2-D tracking) are evaluated horizontally: x/y positions and vx/vy
velocities only.  :attr:`Evaluation.dimension` says which.

:func:`coverage_check` is the demo acceptance criterion: every truth object that stays
visible for ``min_visible_s`` seconds continuously (inside the evaluated time window)
gets a confirmed track while it is visible.

Code layout: this module holds :func:`evaluate` and its per-object / per-track statistics;
the input checks are in :mod:`~skytrack.analysis.checks`, the output instants in
:mod:`~skytrack.analysis.instants`, truth on the instants, visible runs and
:func:`coverage_check` in :mod:`~skytrack.analysis.truth`, the track covariances in
:mod:`~skytrack.analysis.covariances` and the :class:`Evaluation` result in
:mod:`~skytrack.analysis.evaluation`.  Their public names are importable from here.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import pandas as pd

from skytrack.analysis.checks import _py, _require_columns, _require_finite, _require_not_null
from skytrack.analysis.covariances import _covariances
from skytrack.analysis.evaluation import UNITS_NOTE, Evaluation  # noqa: F401 - UNITS_NOTE re-exported
from skytrack.analysis.instants import _steps_for_times, infer_output_times
from skytrack.analysis.metrics import (
    MANOEUVRE_ACCELERATION_MPS2,
    MANOEUVRE_AFTERMATH_S,
    cutoff_matching,
    in_intervals,
    manoeuvring,
    nees,
    nees_band,
    rmse,
    set_metrics_stacked,
)
from skytrack.analysis.truth import (
    DEFAULT_COVERAGE_S,
    _first_visible_time,
    _interpolate_truth,
    _prepare_truth,
    coverage_check,
    truth_visible_runs,
)

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


def _within_truth_span(grid: np.ndarray, tracks: pd.DataFrame, truth: pd.DataFrame, tolerance_s: float,
                       notes: list[str]) -> tuple[np.ndarray, pd.DataFrame]:
    """The inferred instants (and track rows) up to the truth's last time: after it the truth does
    not say what flew, so tracks there are not false (a last plot on a scan boundary makes the
    tracker report one scan past the end of a simulation)."""
    truth_times = truth["time"].to_numpy(dtype=float) if "time" in truth.columns and len(truth) else np.empty(0)
    if truth_times.size == 0 or not np.isfinite(truth_times).any():
        return grid, tracks
    end = float(np.nanmax(truth_times)) + tolerance_s
    after = grid > end
    if not after.any() or after.all():
        return grid, tracks
    notes.append(f"{int(after.sum())} output instant(s) after the truth's last time ({end - tolerance_s:g} s) "
                 "left out: the truth does not cover them")
    return grid[~after], tracks[tracks["time"].to_numpy(dtype=float) <= end]


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
    manoeuvre_segments: pd.DataFrame | Sequence[tuple[Any, float, float]] | None = None,
) -> Evaluation:
    """Evaluate ``tracks`` against ``truth`` (both FORMATS.md tables); see the module docstring.

    ``cutoff_m`` and ``order`` are OSPA/GOSPA's ``c`` and ``p``; ``association_gate_m`` is the
    largest track-to-truth distance of an assignment.  ``output_times`` are the instants to
    evaluate (default: :func:`infer_output_times` of the track times up to the truth's last
    time; give them explicitly when the tracker had instants without any track at the start or
    end of the run).
    ``start_time_s`` is when the tracker started (e.g. the first plot time): truth visible
    before it counts as becoming visible then, and an inferred regular grid is extended back
    to it; default: the first output instant.
    ``horizontal`` forces (True) or forbids (False) horizontal evaluation; None decides from
    the tracks' ``z``.
    ``manoeuvre_segments`` (a table with ``target_id, start, end`` or ``(target_id, start,
    end)`` tuples, times in s) adds ``position_rmse_manoeuvre_m``,
    ``velocity_rmse_manoeuvre_mps`` and their counts to the summary and ``in_manoeuvre`` to
    the assignments (module docstring, step 4).
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
        grid, tracks = _within_truth_span(grid, tracks, truth, time_tolerance_s, notes)
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
    if has_velocity:
        turning = manoeuvring(vt_target, grid[vt_step], vt_vel)[ti]
        nees_info.update(_nees_split(assignments["nees"].to_numpy(dtype=float), turning))

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
    if manoeuvre_segments is not None:
        in_manoeuvre, manoeuvre_figures, manoeuvre_notes = _manoeuvre_errors(
            manoeuvre_segments, prepared.target_ids, vt_target, grid[vt_step], ti, pos_sq, vel_sq, vel_ok,
            time_tolerance_s)
        assignments["in_manoeuvre"] = in_manoeuvre
        summary.update(manoeuvre_figures)
        notes += manoeuvre_notes
    return Evaluation(parameters, dimension, grid, source, series, per_target, per_track, assignments, coverage,
                      summary, nees_info, notes)


def _segment_table(segments) -> pd.DataFrame:
    """``manoeuvre_segments`` as a ``target_id`` (str), ``start``, ``end`` table, checked."""
    if isinstance(segments, pd.DataFrame):
        _require_columns(segments, "manoeuvre segments", ["target_id", "start", "end"])
        frame = segments[["target_id", "start", "end"]].reset_index(drop=True)
    else:
        rows = [tuple(row) for row in segments]
        if any(len(row) != 3 for row in rows):
            raise ValueError("manoeuvre segments: each segment is (target_id, start, end)")
        frame = pd.DataFrame(rows, columns=["target_id", "start", "end"])
    _require_not_null(frame, "manoeuvre segments", "target_id")
    _require_finite(frame, "manoeuvre segments", ["start", "end"])
    start, end = frame["start"].to_numpy(dtype=float), frame["end"].to_numpy(dtype=float)
    if np.any(end < start):
        k = int(np.flatnonzero(end < start)[0])
        raise ValueError(f"manoeuvre segments table, row {k}: end {end[k]!r} is before start {start[k]!r}")
    return pd.DataFrame({"target_id": frame["target_id"].astype(str), "start": start, "end": end})


def _manoeuvre_errors(segments, target_ids, vt_target, vt_time, ti, pos_sq, vel_sq, vel_ok,
                      tolerance) -> tuple[np.ndarray, dict[str, Any], list[str]]:
    """Which assigned pairs lie in a manoeuvre segment of their truth object, and the RMSE over them."""
    table = _segment_table(segments)
    code = pd.Index(np.asarray(target_ids).astype(str)).get_indexer(table["target_id"])
    known = code >= 0
    notes = []
    if not known.all():
        notes.append(f"{int((~known).sum())} of {len(table)} manoeuvre segments name objects that are not in the truth")
    inside, count = in_intervals(vt_target, vt_time, code[known], table["start"].to_numpy()[known],
                                 table["end"].to_numpy()[known], tolerance)
    in_pair = inside[ti]
    vel_in = in_pair & vel_ok
    figures = {
        "n_manoeuvre_segments": int(known.sum()),
        "n_manoeuvre_segments_visible": int((count > 0).sum()),
        "n_manoeuvre_truth_instants": int(inside.sum()),
        "n_manoeuvre_assigned": int(in_pair.sum()),
        "n_manoeuvre_velocity_samples": int(vel_in.sum()),
        "position_rmse_manoeuvre_m": rmse(np.sqrt(pos_sq[in_pair])),
        "velocity_rmse_manoeuvre_mps": rmse(np.sqrt(vel_sq[vel_in])),
    }
    return in_pair, figures, notes


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


def _nees_split(values: np.ndarray, turning: np.ndarray) -> dict[str, Any]:
    """Mean NEES on straight flight and in or after manoeuvres (:func:`manoeuvring`)."""
    valid = np.isfinite(values)
    quiet, turn = valid & ~turning, valid & turning
    return {
        "quiet_mean": float(values[quiet].mean()) if quiet.any() else None, "quiet_n": int(quiet.sum()),
        "manoeuvre_mean": float(values[turn].mean()) if turn.any() else None, "manoeuvre_n": int(turn.sum()),
        "manoeuvre_rule": f"truth acceleration above {MANOEUVRE_ACCELERATION_MPS2:g} m/s^2 within the last "
                          f"{MANOEUVRE_AFTERMATH_S:g} s",
    }


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

"""Association metrics for crossing scenarios, spec 003 R19 (used by study E4, ``fuzzy-crossing``).

Input: one flat row per plot over any number of Monte Carlo runs (``run`` index), with the
scan index, the plot's true object (-1 = false plot) and the id of the track the tracker put
it in after its decision (a plot that started a new track carries that new track's id).
Everything is computed for all runs at once with numpy / pandas group operations; there is
no Python loop over plots, tracks or runs.

Definitions (R19):

* *owner* of a track — the true object of its first plot (in processing order: scans in
  increasing order, and within a scan the input order);
* a plot of object ``o`` is *correctly associated* iff it went to an existing track owned by
  ``o``, or it started a new track while no live track was owned by ``o``.  A track is live
  from its first plot until it is deleted after ``max_misses`` consecutive scans without a
  plot (R15); it is therefore live at scan ``k`` iff its last plot is at a scan
  ``>= k - max_misses`` (a deleted track receives no further plots);
* **CAR** — correct plots / all target plots (false plots are not counted);
* windows around the closest-approach scan ``k_c``: pre = ``k_c-10 .. k_c-6``, post =
  ``k_c+5 .. k_c+9``; ``T_pre(o)``, ``T_post(o)`` = the track with most of ``o``'s plots in
  the window, ties to the lower track id;
* per object-run: **kept** if ``T_post(o) = T_pre(o)``; **swapped** if ``T_post(o) =
  T_pre(o')`` for another object ``o'`` of the run; otherwise **broken** (an empty window
  included);
* rates with binomial standard errors ``sqrt(p (1 - p) / n)`` (``n`` = target plots for CAR,
  object-runs for the outcome rates).  Plots of one run are not independent, so CAR also
  gets ``car_se_runs``, the standard error of the per-run CAR over the runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

#: scan offsets from k_c of the pre- and post-crossing windows (inclusive)
PRE_WINDOW = (-10, -6)
POST_WINDOW = (5, 9)
OUTCOMES = ("kept", "swapped", "broken")
FALSE_PLOT = -1


def binomial_se(successes, trials):
    """Binomial standard error ``sqrt(p (1 - p) / n)`` of the rate ``p = successes / trials`` (NaN if n = 0)."""
    successes = np.asarray(successes, dtype=float)
    trials = np.asarray(trials, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = successes / trials
        value = np.sqrt(p * (1.0 - p) / trials)
    return float(value) if np.ndim(value) == 0 else value


@dataclass
class AssociationMetrics:
    """R19 results.

    * ``plots`` — one row per plot in processing order: ``run, scan, truth, track, owner,
      starts_track, correct`` (``correct`` is False for false plots, which CAR ignores);
    * ``objects`` — one row per (run, object): ``run, object, t_pre, t_post`` (-1 when the
      window holds no plot of the object) and ``outcome`` in :data:`OUTCOMES`;
    * ``summary`` — ``runs, target_plots, car, car_se, car_se_runs, object_runs`` and for each
      outcome its count, rate and ``<outcome>_se`` (the swap rate is ``swapped``).
    """

    plots: pd.DataFrame
    objects: pd.DataFrame
    summary: dict


def _int_array(name: str, values, size: int | None = None) -> np.ndarray:
    array = np.asarray(values)
    if array.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {array.shape}")
    if size is not None and len(array) != size:
        raise ValueError(f"{name} has {len(array)} entries, expected {size} (one per plot)")
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(array)) or np.any(array != np.round(array)):
            raise ValueError(f"{name} must hold integers (no NaN)")
    elif array.dtype.kind not in "iub":
        raise ValueError(f"{name} must hold integers, got dtype {array.dtype}")
    return array.astype(np.int64)


def association_metrics(run, scan, truth, track, k_c, *, max_misses: int = 3,
                        pre_window: tuple[int, int] = PRE_WINDOW,
                        post_window: tuple[int, int] = POST_WINDOW) -> AssociationMetrics:
    """R19 metrics of all runs at once.

    ``run``, ``scan``, ``truth``, ``track``: one entry per plot; within a run and scan the
    input order is the tracker's processing order.  ``k_c``: the closest-approach scan, one
    value or one per plot (e.g. from a per-run table).  Track ids must be >= 0 and unique
    within a run (they may repeat across runs)."""
    run = _int_array("run", run)
    n = len(run)
    scan = _int_array("scan", scan, n)
    truth = _int_array("truth", truth, n)
    track = _int_array("track", track, n)
    k_c = np.full(n, int(k_c), dtype=np.int64) if np.ndim(k_c) == 0 else _int_array("k_c", k_c, n)
    if np.any(track < 0):
        raise ValueError("track ids must be >= 0 (every plot is in a track after the decision)")
    if np.any(truth < FALSE_PLOT):
        raise ValueError("truth must be an object index >= 0 or -1 for a false plot")
    if int(max_misses) < 1:
        raise ValueError(f"max_misses must be >= 1, got {max_misses!r}")

    order = np.lexsort((scan, run))  # stable: the input order is kept within a scan
    run, scan, truth, track, k_c = run[order], scan[order], truth[order], track[order], k_c[order]
    position = np.arange(n)

    # tracks: first plot (owner) and last scan, by unique (run, track)
    _, first_plot, track_code = np.unique(np.column_stack([run, track]), axis=0, return_index=True,
                                          return_inverse=True)
    track_code = track_code.reshape(-1)
    last_scan = np.full(len(first_plot), np.iinfo(np.int64).min)
    np.maximum.at(last_scan, track_code, scan)
    track_owner = truth[first_plot]
    owner = track_owner[track_code]
    starts = first_plot[track_code] == position
    target = truth != FALSE_PLOT

    # a start is correct iff no other live track of the run is owned by the plot's object
    starts_target = pd.DataFrame({"position": position[starts & target], "run": run[starts & target],
                                  "owner": truth[starts & target], "scan": scan[starts & target]})
    tracks = pd.DataFrame({"run": run[first_plot], "owner": track_owner, "first_position": first_plot,
                           "last_scan": last_scan})
    pairs = starts_target.merge(tracks, on=["run", "owner"], how="inner")
    live = (pairs["first_position"] < pairs["position"]) & (pairs["last_scan"] >= pairs["scan"] - int(max_misses))
    blocked = np.zeros(n, dtype=bool)
    blocked[pairs.loc[live, "position"].to_numpy()] = True
    correct = target & np.where(starts, ~blocked, owner == truth)

    plots = pd.DataFrame({"run": run, "scan": scan, "truth": truth, "track": track, "owner": owner,
                          "starts_track": starts, "correct": correct})
    objects = _window_outcomes(plots, k_c, pre_window, post_window)
    return AssociationMetrics(plots, objects, _summary(plots, objects))


def _window_outcomes(plots: pd.DataFrame, k_c: np.ndarray, pre_window, post_window) -> pd.DataFrame:
    """``T_pre``, ``T_post`` and the outcome of every (run, object) with at least one plot."""
    offset = plots["scan"].to_numpy() - k_c
    window = np.full(len(plots), -1)
    window[(offset >= pre_window[0]) & (offset <= pre_window[1])] = 0
    window[(offset >= post_window[0]) & (offset <= post_window[1])] = 1
    target = plots["truth"].to_numpy() != FALSE_PLOT
    in_window = plots.loc[target & (window >= 0), ["run", "truth", "track"]].assign(window=window[target & (window >= 0)])
    counts = in_window.groupby(["run", "truth", "window", "track"], sort=False).size().rename("count").reset_index()
    # most plots first, then the lower track id: the first row of each group is T_window(o)
    best = (counts.sort_values(["run", "truth", "window", "count", "track"], ascending=[True, True, True, False, True])
            .drop_duplicates(["run", "truth", "window"]))
    chosen = best.pivot(index=["run", "truth"], columns="window", values="track")

    objects = plots.loc[target, ["run", "truth"]].drop_duplicates().sort_values(["run", "truth"])
    objects = objects.rename(columns={"truth": "object"}).reset_index(drop=True)
    key = pd.MultiIndex.from_frame(objects.rename(columns={"object": "truth"}))
    for column, name in ((0, "t_pre"), (1, "t_post")):
        values = chosen[column].reindex(key) if column in chosen.columns else pd.Series(np.nan, index=key)
        objects[name] = values.fillna(-1).to_numpy().astype(np.int64)

    has_pre, has_post = objects["t_pre"] >= 0, objects["t_post"] >= 0
    kept = has_pre & has_post & (objects["t_post"] == objects["t_pre"])
    # swapped: T_post(o) is T_pre(o') of another object o' of the same run
    others = objects[["run", "object", "t_post"]].merge(objects[["run", "object", "t_pre"]], on="run",
                                                        suffixes=("", "_other"))
    hit = ((others["object"] != others["object_other"]) & (others["t_post"] >= 0)
           & (others["t_post"] == others["t_pre"]))
    swapped_keys = others.loc[hit, ["run", "object"]].drop_duplicates()
    swapped = pd.MultiIndex.from_frame(objects[["run", "object"]]).isin(pd.MultiIndex.from_frame(swapped_keys))
    objects["outcome"] = np.where(kept, "kept", np.where(swapped & ~kept, "swapped", "broken"))
    return objects


def _summary(plots: pd.DataFrame, objects: pd.DataFrame) -> dict:
    target = plots["truth"].to_numpy() != FALSE_PLOT
    correct = plots["correct"].to_numpy()
    n_target = int(target.sum())
    n_correct = int(correct.sum())
    runs = plots["run"].to_numpy()
    run_ids, run_code = np.unique(runs, return_inverse=True)
    per_run_target = np.bincount(run_code, weights=target, minlength=len(run_ids))
    per_run_correct = np.bincount(run_code, weights=correct, minlength=len(run_ids))
    has_targets = per_run_target > 0
    per_run_car = per_run_correct[has_targets] / per_run_target[has_targets]
    runs_with_targets = len(per_run_car)
    car_se_runs = float(np.std(per_run_car, ddof=1) / np.sqrt(runs_with_targets)) if runs_with_targets > 1 else float("nan")
    summary = {
        "runs": int(len(run_ids)),
        "target_plots": n_target,
        "car": n_correct / n_target if n_target else float("nan"),
        "car_se": binomial_se(n_correct, n_target),
        "car_se_runs": car_se_runs,
        "object_runs": int(len(objects)),
    }
    for outcome in OUTCOMES:
        count = int((objects["outcome"] == outcome).sum())
        summary[f"{outcome}_count"] = count
        summary[outcome] = count / len(objects) if len(objects) else float("nan")
        summary[f"{outcome}_se"] = binomial_se(count, len(objects))
    return summary

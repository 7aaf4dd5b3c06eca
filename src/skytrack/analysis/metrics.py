"""Set distances and error statistics for comparing estimates with truth (pure numpy/scipy).

Set distances, for a truth set ``X`` (``m`` points) and an estimate set ``Y`` (``n`` points),
base distance ``d`` = Euclidean, cutoff ``c > 0`` and order ``p >= 1``:

* **OSPA** (Schuhmacher, Vo & Vo 2008, eq. 3), with ``d_c = min(c, d)`` and, w.l.o.g.,
  ``m <= n``::

      OSPA = ( (1/n) * ( min_pi sum_{i=1..m} d_c(x_i, y_pi(i))^p + c^p (n - m) ) )^(1/p)

  (0 when both sets are empty; ``c`` when exactly one is).
* **GOSPA** with ``alpha = 2`` (Rahmathullah, Garcia-Fernandez & Svensson 2017, eq. 2)::

      GOSPA^p = min_gamma sum_{(i,j) in gamma} d(x_i, y_j)^p + c^p/2 (m + n - 2 |gamma|)

  over assignments ``gamma`` whose pairs have ``d < c``.  Decomposed as
  ``GOSPA^p = localisation + c^p/2 (missed + false)`` with ``localisation`` the sum of
  ``d^p`` over assigned pairs, ``missed`` the unassigned truths and ``false`` the
  unassigned estimates (the identity holds exactly by construction).

Both minimisations have the same optimum: writing the assigned pairs as a matching of
pairs with ``d < c``, ``OSPA^p * n = c^p n - W`` and ``GOSPA^p = c^p (m + n) / 2 - W`` with
``W = sum_matched (c^p - d^p)``.  So one maximum-weight matching on the *sparse* graph of
pairs closer than ``c`` gives both (:func:`cutoff_matching`).  The graph is found with a
k-d tree and split into connected components; a component with a single truth or a single
estimate takes its largest-gain edge, the others are solved with
``scipy.optimize.linear_sum_assignment``.  Many time steps are handled in one call by
giving every point a step index (the k-d tree gets the step as an extra coordinate spaced
more than ``c`` apart, so pairs never cross steps).

Error statistics: Euclidean errors, RMSE, normalised estimation error squared
``NEES = e^T P^-1 e`` and its two-sided chi-square band for the mean of ``N`` samples of
dimension ``n``: ``[chi2_{N n}^-1(a/2) / N, chi2_{N n}^-1(1 - a/2) / N]`` (spec 004 R20, TV19).

Truth samples in time intervals of their own object (:func:`in_intervals`: the manoeuvre
segments of an evaluation) and in or after a manoeuvre by an acceleration threshold
(:func:`manoeuvring`: the NEES split).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import sparse
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.stats import chi2

__all__ = [
    "Matching",
    "GospaResult",
    "SetMetricSeries",
    "cutoff_matching",
    "ospa",
    "gospa",
    "set_metrics_stacked",
    "set_metrics_over_time",
    "euclidean_errors",
    "rmse",
    "nees",
    "nees_band",
]


@dataclass(frozen=True)
class Matching:
    """Matched pairs: ``truth_index[k]`` is matched to ``estimate_index[k]`` at ``distance[k]``."""

    truth_index: np.ndarray
    estimate_index: np.ndarray
    distance: np.ndarray

    def __len__(self) -> int:
        return int(self.truth_index.size)


@dataclass(frozen=True)
class GospaResult:
    """GOSPA (alpha = 2) at one time step and its decomposition.

    ``distance ** order == localisation + cutoff ** order / 2 * (missed + false)``.
    ``localisation`` is in m^p; ``missed``/``false`` are counts; ``assignment`` rows are
    (truth index, estimate index) of the assigned pairs.
    """

    distance: float
    localisation: float
    missed: int
    false: int
    assignment: np.ndarray
    cutoff: float
    order: float


@dataclass(frozen=True)
class SetMetricSeries:
    """OSPA and GOSPA over ``n_steps`` time steps (arrays indexed by step).

    ``gospa ** order == gospa_localisation + cutoff ** order / 2 * (gospa_missed + gospa_false)``
    per step.  ``matching`` holds the optimal pairs (indices into the stacked point arrays).
    """

    cutoff: float
    order: float
    n_truth: np.ndarray
    n_estimates: np.ndarray
    n_assigned: np.ndarray
    ospa: np.ndarray
    gospa: np.ndarray
    gospa_localisation: np.ndarray
    gospa_missed: np.ndarray
    gospa_false: np.ndarray
    matching: Matching

    @property
    def ospa_mean(self) -> float:
        return float(np.mean(self.ospa)) if self.ospa.size else float("nan")

    @property
    def gospa_mean(self) -> float:
        return float(np.mean(self.gospa)) if self.gospa.size else float("nan")


def _check_cutoff_order(cutoff: float, order: float) -> tuple[float, float]:
    cutoff = float(cutoff)
    order = float(order)
    if not (np.isfinite(cutoff) and cutoff > 0.0):
        raise ValueError(f"cutoff must be a finite positive distance, got {cutoff!r}")
    if not (np.isfinite(order) and order >= 1.0):
        raise ValueError(f"order p must be finite and >= 1, got {order!r}")
    return cutoff, order


def _as_points(points, name: str, dim: int | None = None) -> np.ndarray:
    arr = np.asarray(points, dtype=float)
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, dim if dim is not None else 0)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array [points, dimensions], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.argwhere(~np.isfinite(arr))[0, 0])
        raise ValueError(f"{name} has a non-finite coordinate at point {bad}")
    return arr


def _as_steps(steps, n_points: int, name: str) -> np.ndarray:
    arr = np.asarray(steps)
    if arr.shape != (n_points,):
        raise ValueError(f"{name} must have one step index per point ({n_points}), got shape {arr.shape}")
    if n_points and (not np.issubdtype(arr.dtype, np.integer) or arr.min() < 0):
        raise ValueError(f"{name} must hold non-negative integer step indices")
    return arr.astype(np.int64, copy=False)


def _candidate_pairs(truth_step, truth_points, estimate_step, estimate_points, cutoff):
    """All (truth, estimate) pairs of the same step closer than ``cutoff``: (i, j, d)."""
    # the step becomes one more coordinate, spaced 3c apart: pairs of different steps are
    # then farther than c and never returned, and same-step pairs keep their distance
    spacing = 3.0 * cutoff
    aug_truth = np.column_stack([truth_points, truth_step * spacing])
    aug_estimate = np.column_stack([estimate_points, estimate_step * spacing])
    pairs = cKDTree(aug_truth).sparse_distance_matrix(cKDTree(aug_estimate), cutoff, output_type="ndarray")
    i = pairs["i"].astype(np.int64)
    j = pairs["j"].astype(np.int64)
    # recompute from the original coordinates so the step column cannot perturb d
    d = np.linalg.norm(truth_points[i] - estimate_points[j], axis=1)
    keep = (d < cutoff) & (truth_step[i] == estimate_step[j])
    return i[keep], j[keep], d[keep]


def _local_ranks(group: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rank of each value among the distinct values of its group (groups ``0..G-1``) and the
    number of distinct values per group."""
    order = np.lexsort((values, group))
    g, v = group[order], values[order]
    new_group = np.r_[True, g[1:] != g[:-1]]
    new_value = new_group | np.r_[True, v[1:] != v[:-1]]
    distinct = np.cumsum(new_value) - 1
    rank_sorted = distinct - distinct[new_group][g]
    ranks = np.empty_like(rank_sorted)
    ranks[order] = rank_sorted
    n_distinct = np.bincount(g, weights=new_value).astype(np.int64)
    return ranks, n_distinct


def cutoff_matching(truth_step, truth_points, estimate_step, estimate_points, cutoff: float, order: float = 2.0) -> Matching:
    """Optimal matching of truths to estimates per step, using only pairs closer than ``cutoff``.

    Maximises ``sum (c^p - d^p)`` over matched pairs, which is the assignment that
    minimises both OSPA and GOSPA (module docstring) and, with ``order = 2``, the
    gated least-squares assignment used for track-to-truth association.
    ``*_step`` are integer step indices, ``*_points`` arrays ``[count, dim]``.
    """
    cutoff, order = _check_cutoff_order(cutoff, order)
    truth_points = _as_points(truth_points, "truth_points")
    estimate_points = _as_points(estimate_points, "estimate_points", truth_points.shape[1])
    truth_step = _as_steps(truth_step, truth_points.shape[0], "truth_step")
    estimate_step = _as_steps(estimate_step, estimate_points.shape[0], "estimate_step")
    empty = Matching(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    n_truth, n_est = truth_points.shape[0], estimate_points.shape[0]
    if n_truth == 0 or n_est == 0:
        return empty
    if truth_points.shape[1] != estimate_points.shape[1]:
        raise ValueError(
            f"truth points have {truth_points.shape[1]} coordinates but estimates have {estimate_points.shape[1]}"
        )
    i, j, d = _candidate_pairs(truth_step, truth_points, estimate_step, estimate_points, cutoff)
    if i.size == 0:
        return empty
    gain = cutoff**order - d**order
    graph = sparse.coo_matrix((np.ones(i.size), (i, n_truth + j)), shape=(n_truth + n_est, n_truth + n_est))
    _, label = connected_components(graph, directed=False)
    # renumber the components that have edges 0..G-1, then sort the edges by component
    component = np.unique(label[i], return_inverse=True)[1].ravel()
    order_edges = np.argsort(component, kind="stable")
    i, j, gain, component = i[order_edges], j[order_edges], gain[order_edges], component[order_edges]
    local_i, n_rows = _local_ranks(component, i)
    local_j, n_cols = _local_ranks(component, j)
    # a component with one truth or one estimate (a star, including a single edge) is solved
    # by its largest-gain edge; the others go to linear_sum_assignment one by one
    star = (n_rows == 1) | (n_cols == 1)
    star_edges = np.flatnonzero(star[component])
    best = star_edges[np.lexsort((-gain[star_edges], component[star_edges]))]
    first_of_component = np.ones(best.size, dtype=bool)
    first_of_component[1:] = component[best][1:] != component[best][:-1]
    matched_i = [i[best[first_of_component]]]
    matched_j = [j[best[first_of_component]]]
    bounds = np.r_[0, np.cumsum(np.bincount(component))]
    for comp in np.flatnonzero(~star):
        edges = slice(bounds[comp], bounds[comp + 1])
        cost = np.zeros((n_rows[comp], n_cols[comp]))
        cost[local_i[edges], local_j[edges]] = -gain[edges]
        r, c = linear_sum_assignment(cost)
        real = cost[r, c] < 0.0  # zero cost = no edge: left unassigned
        rows = np.empty(n_rows[comp], np.int64)
        cols = np.empty(n_cols[comp], np.int64)
        rows[local_i[edges]] = i[edges]
        cols[local_j[edges]] = j[edges]
        matched_i.append(rows[r[real]])
        matched_j.append(cols[c[real]])
    mi = np.concatenate(matched_i)
    mj = np.concatenate(matched_j)
    sort = np.lexsort((mi, truth_step[mi]))
    mi, mj = mi[sort], mj[sort]
    return Matching(mi, mj, np.linalg.norm(truth_points[mi] - estimate_points[mj], axis=1))


def set_metrics_stacked(
    truth_step,
    truth_points,
    estimate_step,
    estimate_points,
    n_steps: int,
    cutoff: float,
    order: float = 1.0,
    matching: Matching | None = None,
) -> SetMetricSeries:
    """OSPA and GOSPA for every step ``0 .. n_steps-1`` of stacked point arrays (see module doc).

    ``matching`` may pass the result of :func:`cutoff_matching` with the same arguments,
    cutoff and order, to avoid solving it twice.
    """
    cutoff, order = _check_cutoff_order(cutoff, order)
    truth_points = _as_points(truth_points, "truth_points")
    estimate_points = _as_points(estimate_points, "estimate_points", truth_points.shape[1])
    truth_step = _as_steps(truth_step, truth_points.shape[0], "truth_step")
    estimate_step = _as_steps(estimate_step, estimate_points.shape[0], "estimate_step")
    if truth_step.size and truth_step.max() >= n_steps or estimate_step.size and estimate_step.max() >= n_steps:
        raise ValueError(f"step indices must be < n_steps = {n_steps}")
    if matching is None:
        matching = cutoff_matching(truth_step, truth_points, estimate_step, estimate_points, cutoff, order)
    n_truth = np.bincount(truth_step, minlength=n_steps)
    n_est = np.bincount(estimate_step, minlength=n_steps)
    match_step = truth_step[matching.truth_index]
    n_assigned = np.bincount(match_step, minlength=n_steps)
    localisation = np.bincount(match_step, weights=matching.distance**order, minlength=n_steps)
    missed = n_truth - n_assigned
    false = n_est - n_assigned
    cp = cutoff**order
    larger = np.maximum(n_truth, n_est)
    with np.errstate(invalid="ignore", divide="ignore"):
        ospa_p = (localisation + cp * (larger - n_assigned)) / larger
    ospa_values = np.where(larger > 0, ospa_p, 0.0) ** (1.0 / order)
    gospa_values = (localisation + 0.5 * cp * (missed + false)) ** (1.0 / order)
    return SetMetricSeries(
        cutoff=cutoff,
        order=order,
        n_truth=n_truth,
        n_estimates=n_est,
        n_assigned=n_assigned,
        ospa=ospa_values,
        gospa=gospa_values,
        gospa_localisation=localisation,
        gospa_missed=missed,
        gospa_false=false,
        matching=matching,
    )


def _stack(sets: Sequence, name: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """Step index per point and the list of non-empty-or-empty 2-D arrays."""
    arrays = []
    for k, points in enumerate(sets):
        arr = np.asarray(points, dtype=float)
        if arr.size == 0:
            arr = np.zeros((0, arr.shape[-1] if arr.ndim == 2 else 0))
        arrays.append(_as_points(arr, f"{name}[{k}]"))
    steps = np.repeat(np.arange(len(arrays), dtype=np.int64), [a.shape[0] for a in arrays])
    return steps, arrays


def set_metrics_over_time(truth_sets: Sequence, estimate_sets: Sequence, cutoff: float, order: float = 1.0) -> SetMetricSeries:
    """OSPA and GOSPA per time step for lists of point sets (each ``[count, dim]``)."""
    if len(truth_sets) != len(estimate_sets):
        raise ValueError(f"{len(truth_sets)} truth sets but {len(estimate_sets)} estimate sets")
    t_step, t_arrays = _stack(truth_sets, "truth_sets")
    e_step, e_arrays = _stack(estimate_sets, "estimate_sets")
    dims = {a.shape[1] for a in t_arrays + e_arrays if a.shape[0]}
    if len(dims) > 1:
        raise ValueError(f"all point sets must have the same number of coordinates, got {sorted(dims)}")
    dim = dims.pop() if dims else 1
    t_points = np.concatenate([a.reshape(-1, dim) for a in t_arrays]) if t_arrays else np.zeros((0, dim))
    e_points = np.concatenate([a.reshape(-1, dim) for a in e_arrays]) if e_arrays else np.zeros((0, dim))
    return set_metrics_stacked(t_step, t_points, e_step, e_points, len(truth_sets), cutoff, order)


def ospa(truth, estimates, cutoff: float, order: float = 1.0) -> float:
    """OSPA distance (Schuhmacher 2008) between two point sets ``[count, dim]``."""
    return float(set_metrics_over_time([truth], [estimates], cutoff, order).ospa[0])


def gospa(truth, estimates, cutoff: float, order: float = 1.0) -> GospaResult:
    """GOSPA distance (alpha = 2) between two point sets with its decomposition."""
    series = set_metrics_over_time([truth], [estimates], cutoff, order)
    m = series.matching
    return GospaResult(
        distance=float(series.gospa[0]),
        localisation=float(series.gospa_localisation[0]),
        missed=int(series.gospa_missed[0]),
        false=int(series.gospa_false[0]),
        assignment=np.column_stack([m.truth_index, m.estimate_index]),
        cutoff=series.cutoff,
        order=series.order,
    )


def euclidean_errors(estimates, truth) -> np.ndarray:
    """Per-row Euclidean norm of ``estimates - truth`` (arrays ``[count, dim]``)."""
    diff = np.asarray(estimates, dtype=float) - np.asarray(truth, dtype=float)
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


def rmse(errors) -> float:
    """Root mean square of error norms (NaN for no samples)."""
    e = np.asarray(errors, dtype=float)
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


def nees(errors, covariances) -> tuple[np.ndarray, np.ndarray]:
    """``e^T P^-1 e`` per row for ``errors[N, n]`` and ``covariances[N, n, n]``.

    Returns ``(values, valid)``; rows whose covariance is not finite and positive
    definite get NaN and ``valid = False`` (the caller reports how many).
    """
    e = np.asarray(errors, dtype=float)
    P = np.asarray(covariances, dtype=float)
    values = np.full(e.shape[0], np.nan)
    valid = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(P), axis=(1, 2))
    if np.any(valid):
        Pv = 0.5 * (P[valid] + np.swapaxes(P[valid], -1, -2))
        positive = np.linalg.eigvalsh(Pv)[:, 0] > 0.0
        idx = np.flatnonzero(valid)
        valid[idx[~positive]] = False
        if np.any(positive):
            L = np.linalg.cholesky(Pv[positive])
            w = np.linalg.solve(L, e[idx[positive]][..., None])[..., 0]
            values[idx[positive]] = np.einsum("...i,...i->...", w, w)
    return values, valid


def nees_band(n_samples: int, dimension: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided band for the mean NEES of ``n_samples`` independent samples of ``dimension``."""
    if n_samples <= 0:
        return float("nan"), float("nan")
    tail = 0.5 * (1.0 - confidence)
    dof = n_samples * dimension
    return float(chi2.ppf(tail, dof) / n_samples), float(chi2.ppf(1.0 - tail, dof) / n_samples)


#: a truth object manoeuvres when its acceleration exceeds this (m/s^2) ...
MANOEUVRE_ACCELERATION_MPS2 = 0.5
#: ... and its filter still recovers for this long afterwards (s)
MANOEUVRE_AFTERMATH_S = 60.0


def manoeuvring(target: np.ndarray, time: np.ndarray, velocity: np.ndarray,
                threshold_mps2: float = MANOEUVRE_ACCELERATION_MPS2,
                aftermath_s: float = MANOEUVRE_AFTERMATH_S) -> np.ndarray:
    """Whether each truth sample (object ``target`` at ``time`` with ``velocity`` [n, d]) is in a
    manoeuvre or within ``aftermath_s`` after one: the acceleration between consecutive samples
    of the object exceeded ``threshold_mps2`` at some time in (t - aftermath_s, t].

    NEES is split on this: a filter may be consistent on straight flight and not through turns.
    """
    count = len(time)
    order = np.lexsort((time, target))
    t, obj, v = time[order], target[order], velocity[order]
    same = np.r_[False, obj[1:] == obj[:-1]]
    dt = np.r_[np.inf, np.diff(t)]
    accel = np.r_[0.0, np.linalg.norm(np.diff(v, axis=0), axis=1)] / dt
    hard = same & (np.nan_to_num(accel) > threshold_mps2)
    # for every sample, the latest hard sample of the same object at or before it
    position = np.arange(count)
    latest = np.maximum.accumulate(np.where(hard, position, -1)) if count else position
    starts = np.flatnonzero(~same)  # where each object's samples begin
    start = starts[np.searchsorted(starts, position, side="right") - 1] if count else position
    recent = (latest >= start) & (t - t[np.maximum(latest, 0)] < aftermath_s)
    result = np.zeros(count, dtype=bool)
    result[order] = recent
    return result


def in_intervals(sample_object: np.ndarray, sample_time: np.ndarray, interval_object: np.ndarray,
                 interval_start: np.ndarray, interval_end: np.ndarray,
                 tolerance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Which samples fall in a closed time interval of their own object, and how many per interval.

    Sample ``k`` (object ``sample_object[k]`` at ``sample_time[k]``) is inside interval ``j``
    when the objects are equal and ``start_j - tolerance <= t_k <= end_j + tolerance``.
    Returns ``(inside[n_samples], count[n_intervals])``: whether each sample lies in at least
    one interval (intervals of one object may overlap; a sample is still counted once in
    ``inside``), and the number of samples in each interval.  Objects are integer codes.
    """
    obj = np.asarray(sample_object, dtype=np.int64)
    t = np.asarray(sample_time, dtype=float)
    order = np.lexsort((t, obj))
    obj_sorted, t_sorted = obj[order], t[order]
    lo = np.empty(len(interval_object), np.int64)
    hi = np.empty(len(interval_object), np.int64)
    for j, (o, start, end) in enumerate(zip(np.asarray(interval_object, np.int64), interval_start, interval_end)):
        first, last = np.searchsorted(obj_sorted, o, "left"), np.searchsorted(obj_sorted, o, "right")
        times = t_sorted[first:last]
        lo[j] = first + np.searchsorted(times, float(start) - tolerance, "left")
        hi[j] = first + np.searchsorted(times, float(end) + tolerance, "right")
    count = np.maximum(hi - lo, 0)
    # +1 where an interval's samples begin, -1 past their end: covered where the running sum is positive
    edges = np.zeros(t.size + 1, np.int64)
    np.add.at(edges, lo[count > 0], 1)
    np.add.at(edges, hi[count > 0], -1)
    inside = np.zeros(t.size, dtype=bool)
    inside[order] = np.cumsum(edges[:-1]) > 0
    return inside, count

"""Global nearest-neighbour assignment over sparse gated pairs.

Gated pairs form a bipartite graph between tracks and plots; its connected components
(``scipy.sparse.csgraph.connected_components``) are independent assignment problems.
Components made of one track and one plot are assigned directly (vectorised, the
common case in sparse air traffic); every larger component is solved with
``scipy.optimize.linear_sum_assignment`` on the cost matrix augmented with a
"leave the track unassigned" option of cost ``miss_cost`` per track (a plot left
unassigned costs nothing: it goes on to start a track or is clutter), so that a track is
only given a plot when that lowers the total cost.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, min_weight_full_bipartite_matching

from skytrack.association.kernels import assign_clusters

#: cost of a forbidden (non-gated) cell inside a cluster; finite so LSA always succeeds
_FORBIDDEN = 1e18


def assign_gnn(
    track_index: np.ndarray,
    plot_index: np.ndarray,
    cost: np.ndarray,
    n_tracks: int,
    n_plots: int,
    miss_cost: float | np.ndarray,
) -> np.ndarray:
    """Choose at most one plot per track and one track per plot, minimising total cost.

    ``track_index``, ``plot_index`` and ``cost`` describe the gated pairs (one entry per
    pair, at most one entry per (track, plot)).  ``miss_cost`` is the cost of leaving a
    track (scalar or ``[n_tracks]``) or a plot unassigned.  Returns the indices (into the
    pair arrays) of the chosen pairs.
    """
    n_pairs = len(track_index)
    if n_pairs == 0:
        return np.zeros(0, dtype=np.intp)
    miss = np.broadcast_to(np.asarray(miss_cost, dtype=float), (n_tracks,))
    # a pair whose track and plot appear in no other pair is a cluster of its own
    lone = (np.bincount(track_index, minlength=n_tracks)[track_index] == 1) & (
        np.bincount(plot_index, minlength=n_plots)[plot_index] == 1
    )
    single = np.flatnonzero(lone)
    # a lone pair is taken when it is cheaper than leaving its track unassigned
    chosen = [single[cost[single] <= miss[track_index[single]]]]
    rest = np.flatnonzero(~lone)
    if len(rest):
        graph = coo_matrix(
            (np.ones(len(rest)), (track_index[rest], n_tracks + plot_index[rest])),
            shape=(n_tracks + n_plots, n_tracks + n_plots),
        )
        _, labels = connected_components(graph, directed=False)
        pair_label = labels[track_index[rest]]
        order = rest[np.argsort(pair_label, kind="stable")]
        sorted_labels = labels[track_index[order]]
        starts = np.flatnonzero(np.r_[True, sorted_labels[1:] != sorted_labels[:-1]])
        ends = np.r_[starts[1:], len(order)]
        for start, end in zip(starts, ends):
            pairs = order[start:end]
            chosen.append(_solve_cluster(pairs, track_index[pairs], plot_index[pairs], cost[pairs], miss))
    return np.sort(np.concatenate(chosen))


def _solve_cluster(pairs, tracks, plots, costs, miss) -> np.ndarray:
    """Optimal assignment of one cluster with explicit non-assignment options."""
    track_ids, t_local = np.unique(tracks, return_inverse=True)
    plot_ids, p_local = np.unique(plots, return_inverse=True)
    nt, npl = len(track_ids), len(plot_ids)
    size = nt + npl
    matrix = np.full((size, size), _FORBIDDEN)
    matrix[t_local, p_local] = costs
    # track i left unassigned: column npl + i; plot j left unassigned: row nt + j
    matrix[np.arange(nt), npl + np.arange(nt)] = miss[track_ids]
    matrix[nt + np.arange(npl), np.arange(npl)] = 0.0
    matrix[nt:, npl:] = 0.0
    rows, cols = linear_sum_assignment(matrix)
    real = (rows < nt) & (cols < npl)
    lookup = np.full((nt, npl), -1, dtype=np.intp)
    lookup[t_local, p_local] = pairs
    picked = lookup[rows[real], cols[real]]
    return picked[picked >= 0]


#: clusters with more tracks plus plots than this are solved on their edges only (sparse)
MAX_DENSE_CLUSTER = 16


class GNNAssigner:
    """Global nearest neighbour over :class:`~skytrack.association.base.PairScores` (``"gnn"``).

    Only pairs inside the gate take part.  ``compiled=True`` solves every cluster in one numba
    call (:func:`~skytrack.association.kernels.assign_clusters`: dense up to
    :data:`MAX_DENSE_CLUSTER` nodes, sparse shortest paths above), so there is no Python loop
    over clusters; ``compiled=False`` is :func:`assign_gnn`, the reference.
    """

    name = "gnn"

    def __init__(self, compiled: bool = True) -> None:
        self.compiled = compiled

    def assign(self, scores, n_tracks: int, n_plots: int) -> np.ndarray:
        inside = np.flatnonzero(scores.inside)
        ti, pj, cost = scores.pairs.track[inside], scores.pairs.plot[inside], scores.cost[inside]
        if len(inside) == 0:
            return inside
        miss = np.broadcast_to(np.asarray(scores.miss_cost, dtype=float), (n_tracks,))
        return inside[self.assign_gated(ti, pj, cost, miss, n_tracks, n_plots)]

    def assign_gated(self, ti: np.ndarray, pj: np.ndarray, cost: np.ndarray, miss: np.ndarray, n_tracks: int,
                     n_plots: int) -> np.ndarray:
        """Indices of the chosen pairs among pairs that are all inside the gate (sorted)."""
        if not self.compiled:
            return np.sort(assign_gnn(ti, pj, cost, n_tracks, n_plots, miss))
        chosen = assign_clusters(ti.astype(np.int64), pj.astype(np.int64), cost.astype(float),
                                 np.ascontiguousarray(miss, dtype=float), n_tracks, n_plots, MAX_DENSE_CLUSTER)
        return np.flatnonzero(chosen)


def sparse_assignment(ti: np.ndarray, pj: np.ndarray, cost: np.ndarray, miss: np.ndarray) -> np.ndarray:
    """Optimal assignment of gated pairs with "unassigned" options, as one scipy sparse matching
    (the reference of the compiled :func:`~skytrack.association.kernels.assign_sparse`).

    Rows are tracks then plot-dummies, columns plots then track-dummies.  Edges: each pair
    (cost), track -> its own dummy (miss cost), plot-dummy -> its plot (0) and, for each
    pair (t, p), plot-dummy p -> track-dummy t (0): enough for a full matching to exist for
    every choice of pairs.  Every edge gets the same positive offset, which changes no
    optimum (all full matchings have the same number of edges) and keeps zero-cost edges
    explicit.  Returns indices of the chosen pairs.
    """
    tracks, t_local = np.unique(ti, return_inverse=True)
    plots, p_local = np.unique(pj, return_inverse=True)
    nt, npl = len(tracks), len(plots)
    size = nt + npl
    offset = 1.0 + float(np.max(np.abs(cost))) + float(np.max(miss[tracks]))
    rows = np.concatenate([t_local, np.arange(nt), nt + np.arange(npl), nt + p_local])
    cols = np.concatenate([p_local, npl + np.arange(nt), np.arange(npl), npl + t_local])
    weights = np.concatenate([cost, miss[tracks], np.zeros(npl), np.zeros(len(ti))]) + offset
    graph = coo_matrix((weights, (rows, cols)), shape=(size, size)).tocsr()
    row_of, col_of = min_weight_full_bipartite_matching(graph)
    matched_col = np.full(size, -1)
    matched_col[row_of] = col_of
    track_rows = np.arange(nt)
    real = matched_col[:nt] < npl
    keys = t_local.astype(np.int64) * npl + p_local
    order = np.argsort(keys)
    wanted = track_rows[real] * npl + matched_col[:nt][real]
    return np.sort(order[np.searchsorted(keys[order], wanted)]).astype(np.intp)

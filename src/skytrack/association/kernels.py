"""Compiled (numba, cached) association kernels, with numpy/scipy references elsewhere.

* :func:`add_if_within` — the radius check of a candidate search
  (:mod:`skytrack.association.grid_kernels` holds the search itself);
* :func:`assign_clusters` — global nearest neighbour: union-find over the gated pairs gives
  the clusters; a lone pair is taken when it costs no more than leaving its track
  unassigned; clusters up to ``max_dense`` tracks plus plots are solved exactly by a
  shortest-augmenting-path assignment on the matrix augmented with "track unassigned"
  (cost ``miss``) and "plot unassigned" (cost 0) options; larger clusters are flagged
  for the sparse solver.  Reference: :func:`skytrack.association.gnn.assign_gnn`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def add_if_within(track_pos, plot_pos, t, j, radius, dim, out_t, out_p, count):
    """Append the pair (t, j) to ``out_t``/``out_p`` (grown when full) if the plot lies within
    ``radius`` of the track; returns the arrays and the new count."""
    d2 = 0.0
    for c in range(dim):
        diff = plot_pos[j, c] - track_pos[t, c]
        d2 += diff * diff
    if d2 <= radius * radius:
        if count == len(out_t):
            out_t = _grow(out_t, 2 * count + 16)
            out_p = _grow(out_p, 2 * count + 16)
        out_t[count] = t
        out_p[count] = j
        count += 1
    return out_t, out_p, count


@njit(cache=True, nogil=True)
def _grow(values, capacity):
    out = np.empty(capacity, values.dtype)
    out[: len(values)] = values
    return out


@njit(cache=True, nogil=True)
def _find(parent, i):
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


@njit(cache=True, nogil=True)
def _assign_dense(C):
    """Optimal assignment of a square cost matrix (shortest augmenting paths with potentials).

    Returns the column of every row.  ``inf`` marks forbidden cells; a finite assignment
    must exist.
    """
    n = C.shape[0]
    u = np.zeros(n + 1)
    v = np.zeros(n + 1)
    p = np.zeros(n + 1, np.int64)
    way = np.zeros(n + 1, np.int64)
    minv = np.empty(n + 1)
    used = np.empty(n + 1, np.bool_)
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv[:] = np.inf
        used[:] = False
        while True:
            used[j0] = True
            i0 = p[j0]
            delta = np.inf
            j1 = 0
            for j in range(1, n + 1):
                if not used[j]:
                    cur = C[i0 - 1, j - 1] - u[i0] - v[j]
                    if cur < minv[j]:
                        minv[j] = cur
                        way[j] = j0
                    if minv[j] < delta:
                        delta = minv[j]
                        j1 = j
            for j in range(n + 1):
                if used[j]:
                    u[p[j]] += delta
                    v[j] -= delta
                else:
                    minv[j] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while True:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
            if j0 == 0:
                break
    col_of_row = np.empty(n, np.int64)
    for j in range(1, n + 1):
        if p[j] != 0:
            col_of_row[p[j] - 1] = j - 1
    return col_of_row


@njit(cache=True, nogil=True)
def assign_clusters(ti, pj, cost, miss, n_tracks, n_plots, max_dense):
    """Chosen-pair mask and big-cluster mask for gated pairs (see the module docstring)."""
    n_pairs = len(ti)
    parent = np.arange(n_tracks + n_plots)
    for k in range(n_pairs):
        a = _find(parent, ti[k])
        b = _find(parent, n_tracks + pj[k])
        if a != b:
            parent[a] = b
    root = np.empty(n_pairs, np.int64)
    for k in range(n_pairs):
        root[k] = _find(parent, ti[k])
    # pairs grouped by cluster root: a counting sort (stable, linear; numba's argsort is slow)
    nodes = n_tracks + n_plots
    start_of = np.zeros(nodes + 1, np.int64)
    for k in range(n_pairs):
        start_of[root[k] + 1] += 1
    for v in range(nodes):
        start_of[v + 1] += start_of[v]
    order = np.empty(n_pairs, np.int64)
    for k in range(n_pairs):
        order[start_of[root[k]]] = k
        start_of[root[k]] += 1
    chosen = np.zeros(n_pairs, np.bool_)
    big = np.zeros(n_pairs, np.bool_)
    track_local = np.full(n_tracks, -1, np.int64)
    plot_local = np.full(n_plots, -1, np.int64)
    start = 0
    while start < n_pairs:
        stop = start + 1
        while stop < n_pairs and root[order[stop]] == root[order[start]]:
            stop += 1
        if stop - start == 1:
            k = order[start]
            if cost[k] <= miss[ti[k]]:
                chosen[k] = True
            start = stop
            continue
        nt = 0
        npl = 0
        for s in range(start, stop):
            k = order[s]
            if track_local[ti[k]] < 0:
                track_local[ti[k]] = nt
                nt += 1
            if plot_local[pj[k]] < 0:
                plot_local[pj[k]] = npl
                npl += 1
        if nt + npl > max_dense:
            for s in range(start, stop):
                big[order[s]] = True
        else:
            size = nt + npl
            C = np.full((size, size), np.inf)
            pair_at = np.full((nt, npl), -1, np.int64)
            for s in range(start, stop):
                k = order[s]
                a = track_local[ti[k]]
                b = plot_local[pj[k]]
                C[a, b] = cost[k]
                pair_at[a, b] = k
                C[a, npl + a] = miss[ti[k]]
            for b in range(npl):
                C[nt + b, b] = 0.0
                for a in range(nt):
                    C[nt + b, npl + a] = 0.0
            cols = _assign_dense(C)
            for a in range(nt):
                b = cols[a]
                if b < npl and pair_at[a, b] >= 0:
                    chosen[pair_at[a, b]] = True
        for s in range(start, stop):
            k = order[s]
            track_local[ti[k]] = -1
            plot_local[pj[k]] = -1
        start = stop
    return chosen, big

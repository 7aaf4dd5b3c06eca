"""Compiled (numba, cached) association kernels, with numpy/scipy references elsewhere.

* :func:`assign_clusters` — global nearest neighbour: union-find over the gated pairs gives
  the clusters; a lone pair is taken when it costs no more than leaving its track
  unassigned; clusters up to ``max_dense`` tracks plus plots are solved exactly by a
  shortest-augmenting-path assignment on the matrix augmented with "track unassigned"
  (cost ``miss``) and "plot unassigned" (cost 0) options; larger clusters by
  :func:`assign_sparse` (successive shortest paths over the cluster's edges only).
  Reference: :func:`skytrack.association.gnn.assign_gnn`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
def _assign_dense(C, n, u, v, p, way, minv, used, col_of_row):
    """Optimal assignment of the square cost matrix ``C[:n, :n]`` (shortest augmenting paths with
    potentials) into ``col_of_row[:n]``.  ``inf`` marks forbidden cells; a finite assignment
    must exist.  ``u, v, p, way, minv, used`` are scratch arrays of at least n + 1 entries of
    the caller: a window solves thousands of small clusters, and allocating per cluster cost
    more than solving them.
    """
    for j in range(n + 1):
        u[j] = 0.0
        v[j] = 0.0
        p[j] = 0
        way[j] = 0
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv[: n + 1] = np.inf
        used[: n + 1] = False
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
    for j in range(1, n + 1):
        if p[j] != 0:
            col_of_row[p[j] - 1] = j - 1


@njit(cache=True, nogil=True)
def assign_clusters(ti, pj, cost, miss, n_tracks, n_plots, max_dense):
    """Chosen-pair mask of gated pairs (see the module docstring)."""
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
    dense = max(min(max_dense, n_tracks + n_plots), 1)
    C = np.empty((dense, dense))
    pair_at = np.empty((dense, dense), np.int64)
    u, v, minv = np.empty(dense + 1), np.empty(dense + 1), np.empty(dense + 1)
    p, way = np.empty(dense + 1, np.int64), np.empty(dense + 1, np.int64)
    used = np.empty(dense + 1, np.bool_)
    cols = np.empty(dense, np.int64)
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
            _solve_sparse_cluster(order[start:stop], ti, pj, cost, miss, track_local, plot_local, nt, npl, chosen)
        else:
            size = nt + npl
            C[:size, :size] = np.inf
            pair_at[:nt, :npl] = -1
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
            _assign_dense(C, size, u, v, p, way, minv, used, cols)
            for a in range(nt):
                b = cols[a]
                if b < npl and pair_at[a, b] >= 0:
                    chosen[pair_at[a, b]] = True
        for s in range(start, stop):
            k = order[s]
            track_local[ti[k]] = -1
            plot_local[pj[k]] = -1
        start = stop
    return chosen


@njit(cache=True, nogil=True)
def _solve_sparse_cluster(pairs, ti, pj, cost, miss, track_local, plot_local, nt, npl, chosen):
    """One large cluster: every track takes one of its gated plots or its own "unassigned"
    column (cost ``miss``), plots at most once, at least total cost; marks ``chosen``.

    ``track_local``/``plot_local`` number the cluster's tracks and plots 0.. (set by the caller)."""
    row_start = np.zeros(nt + 1, np.int64)
    for s in range(len(pairs)):
        row_start[track_local[ti[pairs[s]]] + 1] += 1
    for a in range(nt):
        row_start[a + 1] += row_start[a] + 1  # one more edge per row: its "unassigned" column
    col = np.empty(row_start[nt], np.int64)
    weight = np.empty(row_start[nt])
    edge_pair = np.full(row_start[nt], -1, np.int64)
    fill = row_start[:-1].copy()
    for s in range(len(pairs)):
        k = pairs[s]
        a = track_local[ti[k]]
        col[fill[a]] = plot_local[pj[k]]
        weight[fill[a]] = cost[k]
        edge_pair[fill[a]] = k
        fill[a] += 1
        # the row's last edge: its own "unassigned" column
        col[row_start[a + 1] - 1] = npl + a
        weight[row_start[a + 1] - 1] = miss[ti[k]]
    col_of_row = assign_sparse(row_start, col, weight, nt, npl + nt)
    for a in range(nt):
        for e in range(row_start[a], row_start[a + 1]):
            if col[e] == col_of_row[a] and edge_pair[e] >= 0:
                chosen[edge_pair[e]] = True


@njit(cache=True, nogil=True)
def assign_sparse(row_start, col, weight, n_rows, n_cols):
    """Least-cost assignment of every row to its own column over sparse edges (row r's edges are
    ``row_start[r]:row_start[r + 1]`` of ``col``/``weight``), by successive shortest augmenting
    paths: Dijkstra on reduced costs with column potentials, one row at a time.  An assignment
    of every row must exist (the caller gives each row a private column).  Returns the column
    of every row.  Reference: :func:`skytrack.association.gnn.sparse_assignment` (scipy).

    Rows are added in the order of their cheapest edge: rows with a clear best column settle
    first and the contested ones search among fewer changes (about a fifth faster on the big
    clusters of the crossing benchmark than the order given)."""
    cheapest = np.full(n_rows, np.inf)
    for r in range(n_rows):
        for e in range(row_start[r], row_start[r + 1]):
            cheapest[r] = min(cheapest[r], weight[e])
    row_order = np.argsort(cheapest, kind="mergesort")
    v = np.zeros(n_cols)
    row_of_col = np.full(n_cols, -1, np.int64)
    col_of_row = np.full(n_rows, -1, np.int64)
    matched_weight = np.zeros(n_cols)
    dist = np.full(n_cols, np.inf)
    reached_from = np.empty(n_cols, np.int64)
    reached_weight = np.empty(n_cols)
    done = np.zeros(n_cols, np.bool_)
    touched = np.empty(n_cols, np.int64)
    finished = np.empty(n_cols, np.int64)
    # a binary heap of (distance, column) in two arrays; an edge is pushed at most once per row
    heap_key = np.empty(len(col) + 1)
    heap_col = np.empty(len(col) + 1, np.int64)
    for r in row_order:
        # most rows' nearest column is free: take it, no search (the potentials stay valid)
        best_e = -1
        best = np.inf
        for e in range(row_start[r], row_start[r + 1]):
            d = weight[e] - v[col[e]]
            if d < best:
                best, best_e = d, e
        if best_e >= 0 and row_of_col[col[best_e]] < 0:
            j = col[best_e]
            row_of_col[j] = r
            col_of_row[r] = j
            matched_weight[j] = weight[best_e]
            continue
        n_touched = 0
        n_finished = 0
        heap_size = 0
        # distances are reduced costs shifted by the unknown row potential of r: a constant
        row, base = r, 0.0
        free_col = -1
        free_dist = 0.0
        # the nearest free column seen so far: nothing at or beyond it can be on the shortest path
        bound = np.inf
        while True:
            for e in range(row_start[row], row_start[row + 1]):
                j = col[e]
                if done[j]:
                    continue
                d = base + weight[e] - v[j]
                if d < dist[j] and d < bound:
                    if row_of_col[j] < 0:
                        bound = d
                    if dist[j] == np.inf:
                        touched[n_touched] = j
                        n_touched += 1
                    dist[j] = d
                    reached_from[j] = row
                    reached_weight[j] = weight[e]
                    heap_size = _heap_push(heap_key, heap_col, heap_size, d, j)
            found = False
            while heap_size:
                d, j = heap_key[0], heap_col[0]
                heap_size = _heap_pop(heap_key, heap_col, heap_size)
                if done[j] or d > dist[j]:
                    continue
                done[j] = True
                finished[n_finished] = j
                n_finished += 1
                if row_of_col[j] < 0:
                    free_col, free_dist = j, d
                    found = True
                    break
                # the matched edge into j has reduced cost 0: its row is reached at distance d
                row = row_of_col[j]
                base = d - (matched_weight[j] - v[j])
                break
            else:
                raise ValueError("no assignment of every row exists")
            if found:
                break
        for s in range(n_finished):
            j = finished[s]
            v[j] += dist[j] - free_dist
        j = free_col
        while True:
            i = reached_from[j]
            previous = col_of_row[i]
            row_of_col[j] = i
            col_of_row[i] = j
            matched_weight[j] = reached_weight[j]
            if i == r:
                break
            j = previous
        for s in range(n_touched):
            dist[touched[s]] = np.inf
        for s in range(n_finished):
            done[finished[s]] = False
    return col_of_row


@njit(cache=True, nogil=True, inline="always")
def _heap_push(keys, values, size, key, value):
    """Add (key, value) to the binary min-heap of ``size`` items; returns the new size."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] <= key:
            break
        keys[i] = keys[parent]
        values[i] = values[parent]
        i = parent
    keys[i] = key
    values[i] = value
    return size + 1


@njit(cache=True, nogil=True, inline="always")
def _heap_pop(keys, values, size):
    """Remove the smallest item (read it from index 0 first); returns the new size."""
    size -= 1
    key = keys[size]
    value = values[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] < keys[child]:
            child += 1
        if key <= keys[child]:
            break
        keys[i] = keys[child]
        values[i] = values[child]
        i = child
    if size > 0:
        keys[i] = key
        values[i] = value
    return size

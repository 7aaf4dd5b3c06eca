"""Compiled spatial index of one association stage (numba, cached): plots in spread classes,
each class cut into columns of x and sorted by y inside a column.

Why not one sort over x: a track's search strip ``|x - x_t| <= reach`` crosses the whole
coverage in y, and with clutter dense near the radar (or 1 000 aircraft in a 25 km box) it
held 10 to 50 times more plots than the candidates.  Columns a reach wide, each searched in y,
bound the scanned area to about ``3 reach x 2 reach``.

Why spread classes: a plot's search radius is ``scale (s_t + s_p) + margin_t`` (the k-d tree
reference, :func:`skytrack.association.candidates.candidate_pairs`), so a few very uncertain
plots (near the radar at an assumed height) would widen every search; a track searches each
class with that class's largest spread instead.  Classes are powers of 16 of the spread
(:func:`spread_class`): every class costs each track a look, and finer classes (powers of 4)
measured slower.  Every column is searched in y by bisection: checking short columns whole
measured slower, because a column a reach wide holds the plots of the whole coverage in y.

* :func:`grid_index` — the index of a batch of plots (a stable counting sort by class and column
  of the plots in y order);
* :func:`search_grid` — exactly the pairs (track, plot) within each pair's own radius (the
  tracker's compiled stage); :func:`grid_candidates` gives exactly the pairs of the k-d tree
  reference, whose radii contain the per-pair radius.
"""

from __future__ import annotations

import numpy as np
from numba import njit


#: spread classes: [0, 256 m), [256 m, 4.1 km), ... by factors of 16, the last one open
SPREAD_BASE_M = 16.0
SPREAD_FACTOR = 16.0
SPREAD_CLASSES = 5
#: a class never has more columns than this (its column width grows instead)
MAX_COLUMNS = 4096


@njit(cache=True, nogil=True, inline="always")
def spread_class(sigma):
    """floor(log16(sigma / SPREAD_BASE_M)), clipped to [0, SPREAD_CLASSES - 1] (0 for NaN)."""
    c = 0
    limit = SPREAD_FACTOR * SPREAD_BASE_M
    while sigma >= limit and c < SPREAD_CLASSES - 1:
        c += 1
        limit *= SPREAD_FACTOR
    return c


@njit(cache=True, nogil=True, inline="always")
def _column(value, x0, width, n_cols):
    if not np.isfinite(value):
        return 0
    k = (value - x0) / width
    if k <= 0.0:
        return 0
    if k >= n_cols - 1:
        return n_cols - 1
    return int(k)


@njit(cache=True, nogil=True)
def grid_index(plot_pos, plot_class, width):
    """Index of the plots (``plot_pos[:, 0]`` is x, ``[:, 1]`` is y) by class, then column of x
    (class c's columns are ``width[c]`` wide from its smallest x), then y.

    Returns ``order`` (plot indices in index order), ``ys`` (their y), ``start`` (the plots of
    global column g are ``order[start[g]:start[g + 1]]``), ``col_base`` (class c's columns are
    ``col_base[c]:col_base[c + 1]``), ``x0``, ``x1`` and the width used per class (widened when
    a class would have more than ``MAX_COLUMNS`` columns).
    """
    n_plots = plot_pos.shape[0]
    n_classes = len(width)
    x0 = np.full(n_classes, np.inf)
    x1 = np.full(n_classes, -np.inf)
    for j in range(n_plots):
        c = plot_class[j]
        x = plot_pos[j, 0]
        if np.isfinite(x):
            x0[c] = min(x0[c], x)
            x1[c] = max(x1[c], x)
    used_width = np.empty(n_classes)
    col_base = np.zeros(n_classes + 1, np.int64)
    for c in range(n_classes):
        w = max(width[c], 1.0)
        n_cols = 1
        if x1[c] >= x0[c]:
            n_cols = int((x1[c] - x0[c]) / w) + 1
            if n_cols > MAX_COLUMNS:
                n_cols = MAX_COLUMNS
                w = (x1[c] - x0[c]) / (MAX_COLUMNS - 1)
        else:
            x0[c] = 0.0
        used_width[c] = w
        col_base[c + 1] = col_base[c] + n_cols
    n_total = col_base[n_classes]
    cell = np.empty(n_plots, np.int64)
    start = np.zeros(n_total + 1, np.int64)
    for j in range(n_plots):
        c = plot_class[j]
        g = col_base[c] + _column(plot_pos[j, 0], x0[c], used_width[c], col_base[c + 1] - col_base[c])
        cell[j] = g
        start[g + 1] += 1
    for g in range(n_total):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    by_y = np.argsort(plot_pos[:, 1])
    order = np.empty(n_plots, np.int64)
    ys = np.empty(n_plots)
    for s in range(n_plots):
        j = by_y[s]
        g = cell[j]
        order[fill[g]] = j
        ys[fill[g]] = plot_pos[j, 1]
        fill[g] += 1
    return order, ys, start, col_base, x0, x1, used_width


@njit(cache=True, nogil=True)
def _in_index_order(order, plot_pos, plot_sigma):
    """The plots' coordinates (``[3, n]``) and spreads in index order: the search then reads
    them one after another instead of through ``order``."""
    n_plots = len(order)
    coords = np.empty((3, n_plots))
    sigma = np.empty(n_plots)
    for s in range(n_plots):
        j = order[s]
        for a in range(min(plot_pos.shape[1], 3)):
            coords[a, s] = plot_pos[j, a]
        sigma[s] = plot_sigma[j]
    return coords, sigma


@njit(cache=True, nogil=True)
def search_grid(track_pos, track_sigma, track_margin, plot_pos, plot_sigma, plot_class, scale, ndim):
    """Every pair (track k, plot j) with ``|p_j - t_k| <= scale (s_k + s_j) + margin_k`` (in the
    first ``ndim`` coordinates).  Returns the track and plot indices of the pairs (track by
    track) and the number of plots looked at."""
    n_tracks = track_pos.shape[0]
    n_plots = plot_pos.shape[0]
    n_classes = SPREAD_CLASSES
    class_max = np.zeros(n_classes)
    class_count = np.zeros(n_classes, np.int64)
    for j in range(n_plots):
        c = plot_class[j]
        class_count[c] += 1
        if plot_sigma[j] > class_max[c]:
            class_max[c] = plot_sigma[j]
    # columns about one typical reach wide: a search then looks at two or three columns
    width = np.zeros(n_classes)
    for c in range(n_classes):
        if class_count[c] == 0 or n_tracks == 0:
            width[c] = 1.0
            continue
        total = 0.0
        for k in range(n_tracks):
            total += scale * (track_sigma[k] + class_max[c]) + track_margin[k]
        width[c] = total / n_tracks if np.isfinite(total) else 1.0
    order, ys, start, col_base, x0, x1, used_width = grid_index(plot_pos, plot_class, width)
    coords, sigma = _in_index_order(order, plot_pos, plot_sigma)
    capacity = 2 * (n_tracks + n_plots) + 16
    out_t = np.empty(capacity, np.int64)
    out_p = np.empty(capacity, np.int64)
    count = 0
    looked = 0
    for k in range(n_tracks):
        xk = track_pos[k, 0]
        yk = track_pos[k, 1]
        for c in range(n_classes):
            if class_count[c] == 0:
                continue
            reach = scale * (track_sigma[k] + class_max[c]) + track_margin[k]
            if not (xk + reach >= x0[c] and xk - reach <= x1[c]):
                continue  # also skips a NaN reach or position
            n_cols = col_base[c + 1] - col_base[c]
            first = col_base[c] + _column(xk - reach, x0[c], used_width[c], n_cols)
            last = col_base[c] + _column(xk + reach, x0[c], used_width[c], n_cols)
            y_low, y_high = yk - reach, yk + reach
            for g in range(first, last + 1):
                end = start[g + 1]
                if end == start[g] or ys[start[g]] > y_high or ys[end - 1] < y_low:
                    continue  # the column holds nothing in the y-interval
                hi = _first_above(ys, start[g], end, y_high)
                lo = _first_not_below(ys, start[g], hi, y_low)
                looked += hi - lo
                for s in range(lo, hi):
                    radius = scale * (track_sigma[k] + sigma[s]) + track_margin[k]
                    d2 = 0.0
                    for a in range(ndim):
                        diff = coords[a, s] - track_pos[k, a]
                        d2 += diff * diff
                    if d2 <= radius * radius:
                        if count == len(out_t):
                            out_t = _grow(out_t, 2 * count + 16)
                            out_p = _grow(out_p, 2 * count + 16)
                        out_t[count] = k
                        out_p[count] = order[s]
                        count += 1
    return out_t[:count], out_p[:count], looked


@njit(cache=True, nogil=True)
def _grow(values, capacity):
    out = np.empty(capacity, values.dtype)
    out[: len(values)] = values
    return out


@njit(cache=True, nogil=True, inline="always")
def _first_not_below(values, lo, hi, key):
    """First index in [lo, hi) of sorted ``values`` with ``values[i] >= key`` (hi if none)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if values[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True, inline="always")
def _first_above(values, lo, hi, key):
    """First index in [lo, hi) of sorted ``values`` with ``values[i] > key`` (hi if none)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if values[mid] <= key:
            lo = mid + 1
        else:
            hi = mid
    return lo


def grid_candidates(track_positions, track_sigma, track_margin, plot_positions, plot_sigma, scale,
                    wide_quantile: float = 0.95):
    """Compiled counterpart of :func:`skytrack.association.candidates.candidate_pairs`: the same
    arguments and the same pairs (in another order), with the reference's radii — plots up to
    the ``wide_quantile`` of spread at ``scale (s_t + s_narrow) + margin_t`` (``s_narrow`` the
    largest of their spreads), wider plots at ``scale (s_p + max s_t) + max margin`` — which
    contain the per-pair radius of :func:`search_grid`."""
    track_positions = np.ascontiguousarray(track_positions, dtype=float)
    plot_positions = np.ascontiguousarray(plot_positions, dtype=float)
    n_tracks, n_plots = len(track_positions), len(plot_positions)
    if n_tracks == 0 or n_plots == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    ndim = track_positions.shape[1]
    if ndim < 2:
        raise ValueError(f"the grid search needs at least 2 coordinates, got {ndim}")
    track_sigma = np.asarray(track_sigma, dtype=float)
    track_margin = np.asarray(track_margin, dtype=float)
    plot_sigma = np.asarray(plot_sigma, dtype=float)
    limit = np.quantile(plot_sigma, wide_quantile) if n_plots > 20 else np.inf
    wide = plot_sigma > limit
    narrow = np.flatnonzero(~wide)
    tracks_at, plots_at = [], []
    if len(narrow):
        as_narrowest = np.full(len(narrow), plot_sigma[narrow].max())
        found_t, found_p, _ = search_grid(track_positions, track_sigma, track_margin, plot_positions[narrow],
                                          as_narrowest, np.zeros(len(narrow), np.int64), float(scale), ndim)
        tracks_at.append(found_t)
        plots_at.append(narrow[found_p])
    if wide.any():
        wide_index = np.flatnonzero(wide)
        widest = np.full(n_tracks, track_sigma.max())
        largest_margin = np.full(n_tracks, track_margin.max())
        found_t, found_p, _ = search_grid(track_positions, widest, largest_margin, plot_positions[wide_index],
                                          plot_sigma[wide_index], spread_classes(plot_sigma[wide_index]),
                                          float(scale), ndim)
        tracks_at.append(found_t)
        plots_at.append(wide_index[found_p])
    return np.concatenate(tracks_at).astype(np.intp), np.concatenate(plots_at).astype(np.intp)


@njit(cache=True, nogil=True)
def spread_classes(sigma):
    """:func:`spread_class` of every value."""
    out = np.empty(len(sigma), np.int64)
    for j in range(len(sigma)):
        out[j] = spread_class(sigma[j])
    return out

"""The compiled grid search of one association stage (spread classes, columns of x, sorted y)
returns exactly the pairs within ``scale (s_t + s_p) + margin_t``: the brute-force set."""

from __future__ import annotations

import numpy as np
import pytest

from skytrack.association.grid_kernels import (
    MAX_COLUMNS,
    SPREAD_BASE_M,
    SPREAD_CLASSES,
    SPREAD_FACTOR,
    grid_index,
    search_grid,
    spread_class,
)

SCALE = 3.8


def brute_force(tracks, s_t, margin, plots, s_p, ndim):
    distance = np.linalg.norm(tracks[:, None, :ndim] - plots[None, :, :ndim], axis=-1)
    within = distance <= SCALE * (s_t[:, None] + s_p[None, :]) + margin[:, None]
    return set(zip(*(axis.tolist() for axis in np.nonzero(within))))


def search(tracks, s_t, margin, plots, s_p, ndim):
    classes = np.array([spread_class(s) for s in s_p], dtype=np.int64)
    a, b, looked = search_grid(tracks, s_t, margin, plots, s_p, classes, SCALE, ndim)
    found = list(zip(a.tolist(), b.tolist()))
    assert len(set(found)) == len(found), "a pair found twice"
    return set(found), looked


@pytest.mark.parametrize("ndim", [2, 3])
@pytest.mark.parametrize("seed", range(6))
def test_grid_search_equals_brute_force(ndim, seed):
    """Random scenes with clutter dense near the origin (uniform in range and azimuth), plots of
    every spread class, some not placeable (30 km), tracks with wide and narrow spreads."""
    rng = np.random.default_rng(seed)
    n_tracks, n_plots = int(rng.integers(1, 300)), int(rng.integers(1, 500))
    r, az = rng.uniform(0, 1.5e5, n_plots), rng.uniform(0, 2 * np.pi, n_plots)
    plots = np.column_stack([r * np.sin(az), r * np.cos(az), rng.uniform(0, 1e4, n_plots)])
    s_p = np.exp(rng.uniform(np.log(5.0), np.log(3e4), n_plots))
    tracks = plots[rng.integers(0, n_plots, n_tracks), :ndim] + rng.normal(0, 2e3, (n_tracks, ndim))
    s_t = np.exp(rng.uniform(np.log(10.0), np.log(5e3), n_tracks))
    margin = rng.uniform(0, 300, n_tracks)
    found, looked = search(tracks, s_t, margin, plots, s_p, ndim)
    assert found == brute_force(tracks, s_t, margin, plots, s_p, ndim)
    assert looked >= len(found)


def test_grid_search_looks_at_a_local_neighbourhood_only():
    """Clutter dense near the radar: the search looks at a neighbourhood of each track, not at a
    strip across the coverage (measured: 0.06 of the strip's plots, 1.2 per candidate; on the
    clutter-2000 benchmark scene the strip held about 50 plots per candidate)."""
    rng = np.random.default_rng(7)
    r, az = rng.uniform(0, 1.5e5, 3000), rng.uniform(0, 2 * np.pi, 3000)
    plots = np.column_stack([r * np.sin(az), r * np.cos(az), np.zeros(3000)])
    s_p = np.full(3000, 40.0)
    tracks = plots[:2000, :2] + rng.normal(0, 100, (2000, 2))
    s_t, margin = np.full(2000, 150.0), np.full(2000, 100.0)
    found, looked = search(tracks, s_t, margin, plots, s_p, 2)
    assert found == brute_force(tracks, s_t, margin, plots, s_p, 2)
    strip = (np.abs(tracks[:, None, 0] - plots[None, :, 0]) <= SCALE * (150 + 40) + 100).sum()
    assert looked < 0.1 * strip
    assert looked < 1.5 * len(found)


def test_plots_with_nan_positions_are_never_candidates():
    plots = np.array([[0.0, 0.0, 0.0], [np.nan, 5.0, 0.0], [3.0, np.nan, 0.0], [1e3, 1e3, 0.0]])
    s_p = np.array([10.0, 10.0, np.nan, 10.0])
    tracks = np.array([[1.0, 1.0], [np.nan, 0.0]])
    found, _ = search(tracks, np.array([10.0, 10.0]), np.zeros(2), plots, s_p, 2)
    assert found == {(0, 0)}


def test_no_tracks_or_no_plots():
    empty_tracks, empty_plots = np.zeros((0, 2)), np.zeros((0, 3))
    assert search(empty_tracks, np.zeros(0), np.zeros(0), np.ones((4, 3)), np.ones(4), 2)[0] == set()
    assert search(np.ones((3, 2)), np.ones(3), np.zeros(3), empty_plots, np.zeros(0), 2)[0] == set()


def test_spread_classes_are_powers_of_sixteen():
    assert SPREAD_FACTOR == 16.0
    assert spread_class(0.0) == 0 and spread_class(np.nan) == 0
    assert spread_class(16 * SPREAD_BASE_M - 1e-9) == 0
    assert spread_class(16 * SPREAD_BASE_M) == 1
    assert spread_class(256 * SPREAD_BASE_M) == 2
    assert spread_class(1e12) == SPREAD_CLASSES - 1


def test_index_orders_by_class_then_column_then_y_and_caps_the_columns():
    rng = np.random.default_rng(3)
    plots = rng.uniform(-1e6, 1e6, (2000, 3))
    classes = rng.integers(0, SPREAD_CLASSES, 2000)
    width = np.full(SPREAD_CLASSES, 10.0)  # 2e5 columns asked for: capped
    order, ys, start, col_base, x0, x1, used = grid_index(plots, classes, width)
    assert sorted(order.tolist()) == list(range(2000))
    np.testing.assert_array_equal(ys, plots[order, 1])
    assert np.all(np.diff(col_base) <= MAX_COLUMNS)
    for c in range(SPREAD_CLASSES):
        for g in range(col_base[c], col_base[c + 1]):
            members = order[start[g]:start[g + 1]]
            assert np.all(classes[members] == c)
            assert np.all(np.diff(plots[members, 1]) >= 0)
            column = np.clip(((plots[members, 0] - x0[c]) / used[c]).astype(int), 0, col_base[c + 1] - col_base[c] - 1)
            assert np.all(column == g - col_base[c])

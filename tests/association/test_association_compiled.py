"""Compiled association kernels against their references: the grid candidate search
against the k-d tree search, the compiled GNN (clusters + shortest augmenting path + sparse
shortest paths for large clusters) against ``assign_gnn`` (scipy's dense assignment per cluster)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from skytrack.association import gnn
from skytrack.association.base import PairScores, Pairs
from skytrack.association.candidates import candidate_pairs
from skytrack.association.gnn import GNNAssigner, assign_gnn, sparse_assignment
from skytrack.association.grid_kernels import grid_candidates
from skytrack.association.kernels import assign_clusters, assign_sparse


def _total_cost(chosen, ti, cost, miss, n_tracks):
    unassigned = np.setdiff1d(np.arange(n_tracks), ti[chosen])
    return cost[chosen].sum() + miss[unassigned].sum()


def _random_problem(rng, max_side=40, max_pairs=300):
    n_tracks, n_plots = int(rng.integers(1, max_side)), int(rng.integers(1, max_side))
    flat = rng.choice(n_tracks * n_plots, size=int(min(rng.integers(1, n_tracks * n_plots + 1), max_pairs)),
                      replace=False)
    ti, pj = flat // n_plots, flat % n_plots
    return ti, pj, rng.uniform(0, 20, len(ti)), rng.uniform(5, 20, n_tracks), n_tracks, n_plots


@pytest.mark.parametrize("seed", range(6))
def test_compiled_gnn_equals_the_scipy_reference(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        ti, pj, cost, miss, n_tracks, n_plots = _random_problem(rng)
        reference = np.sort(assign_gnn(ti, pj, cost, n_tracks, n_plots, miss))
        scores = PairScores(Pairs(ti, pj), cost, np.ones(len(ti), bool), miss)
        compiled = GNNAssigner(compiled=True).assign(scores, n_tracks, n_plots)
        np.testing.assert_array_equal(compiled, reference)
        # one track and one plot at most once
        assert len(np.unique(ti[compiled])) == len(compiled) == len(np.unique(pj[compiled]))


@pytest.mark.parametrize("seed", range(3))
def test_sparse_matching_is_optimal_like_the_dense_reference(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(30):
        ti, pj, cost, miss, n_tracks, n_plots = _random_problem(rng)
        reference = assign_gnn(ti, pj, cost, n_tracks, n_plots, miss)
        sparse = sparse_assignment(ti, pj, cost, miss)
        assert _total_cost(sparse, ti, cost, miss, n_tracks) == pytest.approx(
            _total_cost(reference, ti, cost, miss, n_tracks), abs=1e-9)


def test_large_clusters_go_to_the_sparse_solver(monkeypatch):
    """With the dense limit lowered every cluster is 'large': the result stays optimal."""
    monkeypatch.setattr(gnn, "MAX_DENSE_CLUSTER", 2)
    rng = np.random.default_rng(7)
    for _ in range(20):
        ti, pj, cost, miss, n_tracks, n_plots = _random_problem(rng)
        scores = PairScores(Pairs(ti, pj), cost, np.ones(len(ti), bool), miss)
        chosen = GNNAssigner().assign(scores, n_tracks, n_plots)
        reference = assign_gnn(ti, pj, cost, n_tracks, n_plots, miss)
        assert _total_cost(chosen, ti, cost, miss, n_tracks) == pytest.approx(
            _total_cost(reference, ti, cost, miss, n_tracks), abs=1e-9)


def test_pairs_outside_the_gate_are_never_chosen():
    ti, pj = np.array([0, 1]), np.array([0, 1])
    scores = PairScores(Pairs(ti, pj), np.array([1.0, 1.0]), np.array([True, False]), np.array([10.0, 10.0]))
    np.testing.assert_array_equal(GNNAssigner().assign(scores, 2, 2), [0])


@pytest.mark.parametrize("dim", [2, 3])
def test_grid_candidates_hold_every_pair_within_the_bound(dim):
    """Both searches return every pair within scale (s_t + s_p) + margin (the gate bound), and
    the same pairs; plots with a huge spread (not placeable) are found from their own side."""
    rng = np.random.default_rng(dim)
    for _ in range(20):
        tracks = rng.uniform(-5e4, 5e4, (200, dim))
        plots = rng.uniform(-5e4, 5e4, (300, dim))
        s_t, s_p = rng.uniform(50, 500, 200), rng.uniform(50, 300, 300)
        s_p[:4] = 3e4
        margin = rng.uniform(0, 100, 200)
        scale = 3.8
        within = np.linalg.norm(tracks[:, None, :] - plots[None, :, :], axis=-1) <= scale * (
            s_t[:, None] + s_p[None, :]) + margin[:, None]
        expected = set(zip(*np.nonzero(within)))
        results = []
        for search in (candidate_pairs, grid_candidates):
            a, b = search(tracks, s_t, margin, plots, s_p, scale)
            found = set(zip(a.tolist(), b.tolist()))
            assert expected <= found
            assert len(found) == len(a)  # no pair twice
            results.append(found)
        assert results[0] == results[1]  # the same radii: the same pairs


@pytest.mark.parametrize("seed", range(4))
def test_compiled_sparse_assignment_equals_linear_sum_assignment(seed):
    """:func:`assign_sparse` (successive shortest paths on the edges only) against scipy's dense
    ``linear_sum_assignment`` on the same rectangular problem (forbidden cells very costly),
    rows with a private column so that every row can be assigned; ties are unlikely with
    uniform costs, so the columns must be the same, not only the total."""
    rng = np.random.default_rng(200 + seed)
    for _ in range(25):
        n_rows, n_shared = int(rng.integers(1, 60)), int(rng.integers(1, 60))
        dense = np.full((n_rows, n_shared + n_rows), np.inf)
        for r in range(n_rows):
            picked = rng.choice(n_shared, size=int(rng.integers(0, min(n_shared, 6) + 1)), replace=False)
            dense[r, picked] = rng.uniform(0, 20, len(picked))
            dense[r, n_shared + r] = rng.uniform(5, 20)
        rows, cols = np.nonzero(np.isfinite(dense))
        row_start = np.searchsorted(rows, np.arange(n_rows + 1))
        col_of_row = assign_sparse(row_start, cols.astype(np.int64), dense[rows, cols], n_rows, n_shared + n_rows)
        _, expected = linear_sum_assignment(np.where(np.isfinite(dense), dense, 1e12))
        np.testing.assert_array_equal(col_of_row, expected)
        assert len(np.unique(col_of_row)) == n_rows


def test_compiled_gnn_solves_large_clusters_on_their_edges():
    """Every cluster above two nodes through the sparse solver (``max_dense=2``), compiled in one
    call: the same pairs as the scipy reference."""
    rng = np.random.default_rng(11)
    for _ in range(30):
        ti, pj, cost, miss, n_tracks, n_plots = _random_problem(rng, max_side=80, max_pairs=600)
        chosen = np.flatnonzero(assign_clusters(ti.astype(np.int64), pj.astype(np.int64), cost, miss, n_tracks,
                                                n_plots, 2))
        np.testing.assert_array_equal(chosen, np.sort(assign_gnn(ti, pj, cost, n_tracks, n_plots, miss)))

"""Global nearest neighbour over sparse gated pairs (skytrack.association.gnn)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from skytrack.association.gnn import assign_gnn


def total_cost(chosen, tracks, costs, miss, n_tracks):
    """Cost of a solution: chosen pair costs plus the miss cost of every track left out."""
    assigned = np.zeros(n_tracks, bool)
    assigned[tracks[chosen]] = True
    return float(costs[chosen].sum() + miss[~assigned].sum())


def brute_force_optimum(tracks, plots, costs, miss, n_tracks):
    """Enumerate every matching of the gated pairs (each track: no plot or one free gated plot)."""
    by_track = [np.flatnonzero(tracks == t) for t in range(n_tracks)]
    best = np.inf

    def visit(track, used_plots, cost):
        nonlocal best
        if track == n_tracks:
            best = min(best, cost)
            return
        visit(track + 1, used_plots, cost + miss[track])
        for k in by_track[track]:
            if plots[k] not in used_plots:
                visit(track + 1, used_plots | {plots[k]}, cost + costs[k])

    visit(0, frozenset(), 0.0)
    return best


def check_constraints(chosen, tracks, plots, n_pairs):
    assert np.all(np.diff(chosen) > 0), "indices must be sorted and unique"
    assert chosen.size == 0 or (chosen.min() >= 0 and chosen.max() < n_pairs)
    assert len(set(tracks[chosen].tolist())) == len(chosen), "a track got two plots"
    assert len(set(plots[chosen].tolist())) == len(chosen), "a plot went to two tracks"


@st.composite
def sparse_problems(draw, max_tracks=5, max_plots=5):
    n_tracks = draw(st.integers(1, max_tracks))
    n_plots = draw(st.integers(1, max_plots))
    cells = [(t, p) for t in range(n_tracks) for p in range(n_plots)]
    mask = draw(st.lists(st.booleans(), min_size=len(cells), max_size=len(cells)))
    pairs = [c for c, keep in zip(cells, mask) if keep]
    costs = draw(st.lists(st.floats(0.0, 30.0), min_size=len(pairs), max_size=len(pairs)))
    if draw(st.booleans()):
        miss = np.full(n_tracks, draw(st.floats(0.0, 30.0)))
        miss_arg = float(miss[0])
    else:
        miss = np.array(draw(st.lists(st.floats(0.0, 30.0), min_size=n_tracks, max_size=n_tracks)))
        miss_arg = miss
    # shuffle pair order: assign_gnn must not depend on it
    order = draw(st.permutations(range(len(pairs))))
    pairs = [pairs[i] for i in order]
    costs = [costs[i] for i in order]
    tracks = np.array([p[0] for p in pairs], dtype=np.intp)
    plots = np.array([p[1] for p in pairs], dtype=np.intp)
    return tracks, plots, np.array(costs, dtype=float), n_tracks, n_plots, miss, miss_arg


@settings(max_examples=400, deadline=None, derandomize=True)
@given(sparse_problems())
def test_gnn_equals_brute_force_optimum(problem):
    tracks, plots, costs, n_tracks, n_plots, miss, miss_arg = problem
    chosen = assign_gnn(tracks, plots, costs, n_tracks, n_plots, miss_arg)
    check_constraints(chosen, tracks, plots, len(tracks))
    optimum = brute_force_optimum(tracks, plots, costs, miss, n_tracks)
    assert total_cost(chosen, tracks, costs, miss, n_tracks) == pytest.approx(optimum, abs=1e-9)


def full_lsa_optimum(tracks, plots, costs, miss, n_tracks, n_plots):
    """Reference without clustering: one augmented (tracks + plots)^2 matrix, inf = forbidden."""
    size = n_tracks + n_plots
    M = np.full((size, size), np.inf)
    M[tracks, plots] = costs
    M[np.arange(n_tracks), n_plots + np.arange(n_tracks)] = miss
    M[n_tracks + np.arange(n_plots), np.arange(n_plots)] = 0.0
    M[n_tracks:, n_plots:] = 0.0
    rows, cols = linear_sum_assignment(M)
    return float(M[rows, cols].sum())


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(5, 40), st.integers(5, 40), st.floats(0.02, 0.3))
def test_gnn_equals_full_augmented_lsa_on_larger_problems(seed, n_tracks, n_plots, density):
    rng = np.random.default_rng(seed)
    mask = rng.random((n_tracks, n_plots)) < density
    tracks, plots = np.nonzero(mask)
    costs = rng.uniform(0, 20, len(tracks))
    miss = rng.uniform(2, 20, n_tracks)
    chosen = assign_gnn(tracks, plots, costs, n_tracks, n_plots, miss)
    check_constraints(chosen, tracks, plots, len(tracks))
    reference = full_lsa_optimum(tracks, plots, costs, miss, n_tracks, n_plots)
    assert total_cost(chosen, tracks, costs, miss, n_tracks) == pytest.approx(reference, abs=1e-9)


def test_lone_pair_costlier_than_a_miss_is_left_out():
    tracks, plots = np.array([0, 1]), np.array([0, 1])
    chosen = assign_gnn(tracks, plots, np.array([5.0, 12.0]), 2, 2, miss_cost=10.0)
    np.testing.assert_array_equal(chosen, [0])


def test_track_in_a_cluster_is_left_out_when_its_only_pair_is_too_costly():
    """Track 1's only pair (to plot 0, cost 9) costs more than its miss (4); track 0 takes
    plot 0 (cost 3) and track 1 stays unassigned even though plot 1 is free."""
    tracks = np.array([0, 0, 1])
    plots = np.array([0, 1, 0])
    costs = np.array([3.0, 6.0, 9.0])
    chosen = assign_gnn(tracks, plots, costs, 2, 2, miss_cost=np.array([10.0, 4.0]))
    np.testing.assert_array_equal(chosen, [0])


def test_conflict_resolved_by_total_cost():
    """Two tracks both nearest to plot 0: the joint optimum, not the greedy choice."""
    tracks = np.array([0, 0, 1])
    plots = np.array([0, 1, 0])
    costs = np.array([1.0, 2.0, 1.5])  # greedy 0->0 (1) then 1 has nothing: 1 + miss; optimum 0->1, 1->0 = 3.5
    chosen = assign_gnn(tracks, plots, costs, 2, 2, miss_cost=20.0)
    np.testing.assert_array_equal(chosen, [1, 2])


def test_independent_clusters_and_unrelated_indices():
    """Several clusters in one call; track and plot indices not gated anywhere are fine."""
    tracks = np.array([4, 4, 7, 2])
    plots = np.array([9, 3, 3, 0])
    costs = np.array([2.0, 1.0, 0.5, 11.0])
    chosen = assign_gnn(tracks, plots, costs, 10, 12, miss_cost=10.0)
    np.testing.assert_array_equal(chosen, [0, 2])


def test_no_pairs():
    chosen = assign_gnn(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0), 3, 3, 1.0)
    assert chosen.size == 0 and chosen.dtype.kind == "i"

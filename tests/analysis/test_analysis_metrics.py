"""OSPA / GOSPA / NEES helpers of skytrack.analysis.metrics.

Hand-computed cases, a brute-force oracle over all assignments (the definitions), metric
properties with hypothesis (derandomized: same examples every run), the NEES band of
spec 004 TV19.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from skytrack.analysis.metrics import (
    cutoff_matching,
    euclidean_errors,
    gospa,
    in_intervals,
    nees,
    nees_band,
    ospa,
    rmse,
    set_metrics_over_time,
    set_metrics_stacked,
)

# ----------------------------------------------------------------------------- oracles


def ospa_brute(X, Y, c, p):
    """OSPA straight from Schuhmacher (2008) eq. 3: all injections of the smaller set."""
    X, Y = np.asarray(X, float).reshape(-1, 2), np.asarray(Y, float).reshape(-1, 2)
    if len(X) > len(Y):
        X, Y = Y, X
    m, n = len(X), len(Y)
    if n == 0:
        return 0.0
    best = math.inf
    for perm in itertools.permutations(range(n), m):
        s = sum(min(c, float(np.linalg.norm(X[i] - Y[j]))) ** p for i, j in enumerate(perm))
        best = min(best, s)
    return ((best + c**p * (n - m)) / n) ** (1 / p)


def gospa_brute(X, Y, c, p):
    """GOSPA (alpha = 2) from its assignment-set definition: every partial injection gamma
    of X into Y with pairs closer than c.  Returns (distance, loc, missed, false)."""
    X, Y = np.asarray(X, float).reshape(-1, 2), np.asarray(Y, float).reshape(-1, 2)
    m, n = len(X), len(Y)
    best = (math.inf, 0.0, 0, 0)
    choices = [None] + list(range(n))
    for assign in itertools.product(choices, repeat=m):
        used = [j for j in assign if j is not None]
        if len(used) != len(set(used)):
            continue
        d = [float(np.linalg.norm(X[i] - Y[j])) for i, j in enumerate(assign) if j is not None]
        if any(v >= c for v in d):
            continue
        loc = sum(v**p for v in d)
        k = len(d)
        total = loc + c**p / 2 * (m + n - 2 * k)
        if total < best[0]:
            best = (total, loc, m - k, n - k)
    return best[0] ** (1 / p), best[1], best[2], best[3]


def gospa_permutation_form(X, Y, c, p):
    """Rahmathullah et al. (2017) Proposition 1 form: min over injections of min(d, c)^p + c^p/2 |m - n|."""
    X, Y = np.asarray(X, float).reshape(-1, 2), np.asarray(Y, float).reshape(-1, 2)
    if len(X) > len(Y):
        X, Y = Y, X
    m, n = len(X), len(Y)
    best = math.inf
    for perm in itertools.permutations(range(n), m):
        best = min(best, sum(min(c, float(np.linalg.norm(X[i] - Y[j]))) ** p for i, j in enumerate(perm)))
    if n == 0:
        best = 0.0
    return (best + c**p / 2 * (n - m)) ** (1 / p)


# ----------------------------------------------------------------------------- hand-computed cases

TRUTH_2 = np.array([[0.0, 0.0], [10.0, 0.0]])
TRACKS_3 = np.array([[1.0, 0.0], [10.0, 2.0], [50.0, 50.0]])


def test_two_truths_three_tracks_order_1():
    # pairs d = 1 and d = 2, the third track is unassigned (cardinality error c = 5)
    assert ospa(TRUTH_2, TRACKS_3, cutoff=5.0, order=1) == pytest.approx((1 + 2 + 5) / 3, abs=1e-12)
    g = gospa(TRUTH_2, TRACKS_3, cutoff=5.0, order=1)
    assert g.distance == pytest.approx(1 + 2 + 5 / 2, abs=1e-12)
    assert (g.localisation, g.missed, g.false) == (pytest.approx(3.0), 0, 1)
    assert sorted(map(tuple, g.assignment.tolist())) == [(0, 0), (1, 1)]


def test_two_truths_three_tracks_order_2():
    assert ospa(TRUTH_2, TRACKS_3, cutoff=5.0, order=2) == pytest.approx(math.sqrt((1 + 4 + 25) / 3), abs=1e-12)
    g = gospa(TRUTH_2, TRACKS_3, cutoff=5.0, order=2)
    assert g.distance == pytest.approx(math.sqrt(1 + 4 + 25 / 2), abs=1e-12)
    assert g.localisation == pytest.approx(5.0)


def test_optimal_not_greedy_assignment():
    # greedy would pair x2-y1 (0.1) then x1-y2 (4.0); the optimum is 1.9 + 2.0
    X = np.array([[0.0, 0.0], [2.0, 0.0]])
    Y = np.array([[1.9, 0.0], [4.0, 0.0]])
    assert ospa(X, Y, cutoff=10.0, order=1) == pytest.approx(3.9 / 2, abs=1e-12)
    assert gospa(X, Y, cutoff=10.0, order=1).distance == pytest.approx(3.9, abs=1e-12)
    assert gospa(X, Y, cutoff=10.0, order=2).distance == pytest.approx(math.sqrt(1.9**2 + 2.0**2), abs=1e-12)


def test_pair_beyond_cutoff_is_missed_and_false():
    X, Y = [[0.0, 0.0]], [[4.0, 0.0]]
    g = gospa(X, Y, cutoff=5.0, order=2)
    assert (g.distance, g.missed, g.false) == (pytest.approx(4.0), 0, 0)
    g = gospa(X, Y, cutoff=3.0, order=2)
    assert g.distance == pytest.approx(3.0)  # sqrt(9/2 * 2)
    assert (g.localisation, g.missed, g.false) == (0.0, 1, 1)
    assert ospa(X, Y, cutoff=3.0, order=2) == pytest.approx(3.0)


def test_empty_sets():
    assert ospa(np.zeros((0, 2)), np.zeros((0, 2)), 5.0) == 0.0
    assert ospa(TRUTH_2, np.zeros((0, 2)), 5.0) == 5.0
    assert ospa([], TRACKS_3, 5.0, 2) == 5.0
    g = gospa(TRUTH_2, [], 5.0, 2)
    assert (g.distance, g.missed, g.false) == (pytest.approx(math.sqrt(25 / 2 * 2)), 2, 0)
    assert gospa([], [], 5.0).distance == 0.0


def test_bad_arguments():
    with pytest.raises(ValueError, match="cutoff"):
        ospa(TRUTH_2, TRACKS_3, cutoff=0.0)
    with pytest.raises(ValueError, match="order"):
        gospa(TRUTH_2, TRACKS_3, cutoff=1.0, order=0.5)
    with pytest.raises(ValueError, match="non-finite"):
        ospa([[0.0, np.nan]], TRACKS_3, cutoff=1.0)


# ----------------------------------------------------------------------------- properties

# positions to the millimetre: distinct points then differ by far more than the rounding of the
# assignment's costs (which carry an offset of up to c^p); 1e-151 m apart they could tie
coord = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False).map(lambda v: round(v, 3))
point_sets = st.lists(st.tuples(coord, coord), min_size=0, max_size=4).map(lambda pts: np.array(pts, float).reshape(-1, 2))
cutoffs = st.floats(0.5, 15.0)
orders = st.sampled_from([1.0, 2.0, 3.0])


@settings(max_examples=150, deadline=None, derandomize=True)
@given(point_sets, point_sets, cutoffs, orders)
def test_matches_brute_force_definitions(X, Y, c, p):
    assert ospa(X, Y, c, p) == pytest.approx(ospa_brute(X, Y, c, p), rel=1e-9, abs=1e-9)
    g = gospa(X, Y, c, p)
    dist, loc, missed, false = gospa_brute(X, Y, c, p)
    assert g.distance == pytest.approx(dist, rel=1e-9, abs=1e-9)
    assert g.distance == pytest.approx(gospa_permutation_form(X, Y, c, p), rel=1e-9, abs=1e-9)
    # the decomposition identity holds exactly for the returned parts
    assert g.distance**p == pytest.approx(g.localisation + c**p / 2 * (g.missed + g.false), rel=1e-12, abs=1e-12)
    assert g.missed == len(X) - len(g.assignment) and g.false == len(Y) - len(g.assignment)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(point_sets, point_sets, cutoffs, orders)
def test_symmetry_and_bounds(X, Y, c, p):
    assert ospa(X, Y, c, p) == pytest.approx(ospa(Y, X, c, p), rel=1e-12, abs=1e-12)
    g, h = gospa(X, Y, c, p), gospa(Y, X, c, p)
    assert g.distance == pytest.approx(h.distance, rel=1e-12, abs=1e-12)
    assert (g.missed, g.false) == (h.false, h.missed)
    assert 0.0 <= ospa(X, Y, c, p) <= c + 1e-12
    assert g.distance <= (c**p / 2 * (len(X) + len(Y))) ** (1 / p) + 1e-12


@settings(max_examples=150, deadline=None, derandomize=True)
@given(point_sets, point_sets, st.randoms(use_true_random=False), cutoffs, orders)
def test_zero_iff_equal_sets(X, Y, rnd, c, p):
    shuffled = X[rnd.sample(range(len(X)), len(X))] if len(X) else X
    assert ospa(X, shuffled, c, p) == 0.0
    assert gospa(X, shuffled, c, p).distance == 0.0
    same = len(X) == len(Y) and sorted(map(tuple, X.tolist())) == sorted(map(tuple, Y.tolist()))
    assert (ospa(X, Y, c, p) == 0.0) == same
    assert (gospa(X, Y, c, p).distance == 0.0) == same


@settings(max_examples=200, deadline=None, derandomize=True)
@given(point_sets, point_sets, point_sets, cutoffs, orders)
def test_triangle_inequality(X, Y, Z, c, p):
    assert ospa(X, Z, c, p) <= ospa(X, Y, c, p) + ospa(Y, Z, c, p) + 1e-9
    assert gospa(X, Z, c, p).distance <= gospa(X, Y, c, p).distance + gospa(Y, Z, c, p).distance + 1e-9


# ----------------------------------------------------------------------------- sequences


def dense_reference(X, Y, c, p):
    """Per-step OSPA/GOSPA with one dense LSA on min(d, c)^p (the usual implementation)."""
    m, n = len(X), len(Y)
    if m == 0 or n == 0:
        return (c if m + n else 0.0), (c**p / 2 * (m + n)) ** (1 / p)
    cost = np.minimum(np.linalg.norm(X[:, None] - Y[None], axis=2), c) ** p
    r, k = linear_sum_assignment(cost)
    s = cost[r, k].sum()
    return ((s + c**p * abs(n - m)) / max(m, n)) ** (1 / p), (s + c**p / 2 * abs(n - m)) ** (1 / p)


def test_sequence_equals_dense_per_step_with_crowded_clusters():
    rng = np.random.default_rng(7)
    truth_sets, estimate_sets = [], []
    for _ in range(25):
        truth_sets.append(rng.uniform(0, 12, (rng.integers(0, 30), 2)))
        estimate_sets.append(rng.uniform(0, 12, (rng.integers(0, 30), 2)))
    truth_sets[3] = np.zeros((0, 2))
    estimate_sets[4] = np.zeros((0, 2))
    for c, p in [(2.0, 1.0), (3.0, 2.0)]:
        series = set_metrics_over_time(truth_sets, estimate_sets, c, p)
        for k, (X, Y) in enumerate(zip(truth_sets, estimate_sets)):
            o, g = dense_reference(X, Y, c, p)
            assert series.ospa[k] == pytest.approx(o, rel=1e-9, abs=1e-12), k
            assert series.gospa[k] == pytest.approx(g, rel=1e-9, abs=1e-12), k
        identity = series.gospa_localisation + c**p / 2 * (series.gospa_missed + series.gospa_false)
        np.testing.assert_allclose(series.gospa**p, identity, rtol=1e-12)
        assert series.ospa_mean == pytest.approx(np.mean(series.ospa))


def test_points_of_different_steps_never_match():
    # same position, different steps: one missed truth at step 0, one false estimate at step 1
    series = set_metrics_stacked([0], [[5.0, 5.0]], [1], [[5.0, 5.0]], n_steps=2, cutoff=10.0, order=1)
    assert series.gospa_missed.tolist() == [1, 0]
    assert series.gospa_false.tolist() == [0, 1]
    assert series.ospa.tolist() == [10.0, 10.0]
    assert len(series.matching) == 0


def test_cutoff_matching_is_gated_least_squares():
    # p = 2 matching maximises sum(g^2 - d^2): both pairs taken, the cross pairing is worse
    m = cutoff_matching([0, 0], [[0.0, 0.0], [100.0, 0.0]], [0, 0, 0], [[90.0, 0.0], [10.0, 0.0], [500.0, 0.0]], 50.0, 2.0)
    pairs = sorted(zip(m.truth_index.tolist(), m.estimate_index.tolist()))
    assert pairs == [(0, 1), (1, 0)]
    np.testing.assert_allclose(np.sort(m.distance), [10.0, 10.0])


# ----------------------------------------------------------------------------- errors and NEES


def test_errors_and_rmse():
    est = np.array([[3.0, 4.0], [0.0, 0.0]])
    truth = np.zeros((2, 2))
    np.testing.assert_allclose(euclidean_errors(est, truth), [5.0, 0.0])
    assert rmse([5.0, 0.0]) == pytest.approx(math.sqrt(12.5))
    assert math.isnan(rmse([]))


def test_nees_values_and_invalid_rows():
    e = np.array([[1.0, 2.0], [1.0, 0.0], [1.0, 1.0]])
    P = np.array([[[2.0, 1.0], [1.0, 2.0]], [[1.0, 0.0], [0.0, -1.0]], [[np.nan, 0.0], [0.0, 1.0]]])
    values, valid = nees(e, P)
    # [1 2] (1/3)[[2 -1][-1 2]] [1 2]^T = (2 - 4 + 8) / 3
    assert values[0] == pytest.approx(2.0)
    assert valid.tolist() == [True, False, False]
    assert np.isnan(values[1:]).all()


@pytest.mark.parametrize(
    "n, dim, band",
    [(100, 4, (3.464818, 4.573055)), (100, 6, (5.340186, 6.697692)), (200, 6, (5.529449, 6.489491)), (500, 9, (8.631926, 9.375651))],
)
def test_nees_band_spec004_tv19(n, dim, band):
    lo, hi = nees_band(n, dim)
    assert lo == pytest.approx(band[0], abs=2e-6)
    assert hi == pytest.approx(band[1], abs=2e-6)


def test_manoeuvring_marks_the_turn_and_the_minute_after_it():
    """Object 0 flies straight, turns at 10 m/s^2 from t = 100 to 112 s, then flies straight;
    object 1 flies straight: the samples from 100 s to 168 s of object 0 (last hard step at
    112 s, plus less than 60 s) are manoeuvring, nothing else. Input order does not matter."""
    from skytrack.analysis.metrics import manoeuvring

    t = np.r_[np.arange(0, 300, 4.0), np.arange(0, 100, 4.0)]
    obj = np.r_[np.zeros(75, int), np.ones(25, int)]
    v = np.zeros((100, 2))
    v[:, 0] = 200.0
    turn = (obj == 0) & (t >= 100) & (t <= 112)
    v[turn, 1] = (t[turn] - 96) * 10.0
    v[(obj == 0) & (t > 112), 1] = 160.0
    flags = manoeuvring(obj, t, v)
    expected = (obj == 0) & (t >= 100) & (t <= 168)
    np.testing.assert_array_equal(flags, expected)
    shuffle = np.random.default_rng(1).permutation(100)
    np.testing.assert_array_equal(manoeuvring(obj[shuffle], t[shuffle], v[shuffle]), expected[shuffle])
    assert manoeuvring(obj[:0], t[:0], v[:0]).size == 0


def test_in_intervals_by_hand_with_overlap_tolerance_and_shuffled_input():
    """Object 0 at t = 0, 1, 2, 3; object 1 at t = 0, 1.  Intervals: object 0 [0.5, 2] (holds
    t = 1, 2), object 0 [2, 3] (overlaps the first at t = 2: t = 2, 3), object 1 [1.0005, 4]
    (t = 1 only with a tolerance of 1 ms), object 0 [5, 6] (none).  A sample in two intervals
    is inside once; the counts are per interval."""
    obj = np.array([0, 0, 0, 0, 1, 1])
    t = np.array([0.0, 1.0, 2.0, 3.0, 0.0, 1.0])
    intervals = (np.array([0, 0, 1, 0]), np.array([0.5, 2.0, 1.0005, 5.0]), np.array([2.0, 3.0, 4.0, 6.0]))
    inside, count = in_intervals(obj, t, *intervals, tolerance=1e-3)
    np.testing.assert_array_equal(inside, [False, True, True, True, False, True])
    np.testing.assert_array_equal(count, [2, 2, 1, 0])
    inside, count = in_intervals(obj, t, *intervals)
    np.testing.assert_array_equal(inside, [False, True, True, True, False, False])
    np.testing.assert_array_equal(count, [2, 2, 0, 0])
    shuffle = np.array([5, 2, 0, 4, 3, 1])
    inside, count = in_intervals(obj[shuffle], t[shuffle], *intervals, tolerance=1e-3)
    np.testing.assert_array_equal(inside, np.array([False, True, True, True, False, True])[shuffle])
    np.testing.assert_array_equal(count, [2, 2, 1, 0])
    inside, count = in_intervals(obj[:0], t[:0], *intervals)
    assert inside.size == 0 and count.tolist() == [0, 0, 0, 0]

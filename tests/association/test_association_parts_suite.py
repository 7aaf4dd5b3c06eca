"""Conformance suites of the association parts, parametrised over the registries.

Scorers: the gate is the chi-square quantile of the measured components (spec 000 R7), every
pair inside the gate costs no more than leaving its track unassigned, and the diagnostic
columns are the innovation's.  Assigners: a plot and a track are used at most once, only
pairs inside the gate are chosen, and the total cost is the optimum found by enumerating
every matching of small problems.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import chi2

from skytrack.association.base import PairScores, Pairs
from skytrack.association.registry import ASSIGNERS, SCORERS, build_assigner, build_scorer
from skytrack.filters.base import GaussianState, Innovation


def _innovations(rng, count: int, m: int = 2) -> Innovation:
    A = rng.standard_normal((count, m, m)) * rng.uniform(50, 400, (count, 1, 1))
    S = A @ np.swapaxes(A, -1, -2) + np.eye(m) * 100.0
    L = np.linalg.cholesky(S)
    nu = np.einsum("kij,kj->ki", L, rng.standard_normal((count, m)) * rng.uniform(0.2, 6.0, (count, 1)))
    w = np.linalg.solve(L, nu[..., None])[..., 0]
    d2 = np.einsum("ki,ki->k", w, w)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    loglik = -0.5 * (d2 + logdet + m * np.log(2 * np.pi))
    dummy = GaussianState(np.zeros((count, 4)), np.zeros((count, 4, 4)))
    return Innovation(nu, S, L, d2, logdet, loglik, np.full(count, m), np.zeros((count, m, 4)), np.zeros((count, m, m)),
                      dummy)


@pytest.mark.parametrize("name", sorted(SCORERS))
def test_scorer_gate_and_miss_cost(name):
    rng = np.random.default_rng(5)
    innovation = _innovations(rng, 300)
    pairs = Pairs(rng.integers(0, 40, 300), rng.integers(0, 60, 300))
    scorer = build_scorer(name, p_gate=0.99, max_components=3)
    gated = innovation.d2 <= chi2.ppf(0.99, 2)
    if name == "llr":
        # evidence per pair (ln P_D - ln beta_j + SSR) and ln(1 - P_D): inside the gate AND better than a miss
        evidence = rng.uniform(5.0, 25.0, 300)
        scores = scorer.score(innovation, pairs, 40, evidence, np.log(0.1))
        better = innovation.loglik + evidence > np.log(0.1)
        np.testing.assert_array_equal(scores.inside, gated & better)
        assert (gated & ~better).any()
        # the costs of a track's pairs keep their differences: -2 x the differences of the ratios
        inside = np.flatnonzero(scores.inside)
        first, second = inside[0], inside[np.flatnonzero(pairs.track[inside] == pairs.track[inside[0]])[-1]]
        np.testing.assert_allclose(scores.cost[second] - scores.cost[first],
                                   -2 * (scores.columns["gain"][second] - scores.columns["gain"][first]))
    elif name == "ml":
        # spec 003's ml against a new-object density (here ln beta = -14): inside the gate AND likelier than new
        scores = scorer.score(innovation, pairs, 40, None, np.full(300, -14.0))
        better = innovation.loglik > -14.0
        np.testing.assert_array_equal(scores.inside, gated & better)
        assert (gated & ~better).any()
    else:
        # fuzzy and crisp without identity features: exactly the gate (ln mu >= ln mu_new)
        scores = scorer.score(innovation, pairs, 40)
        np.testing.assert_array_equal(scores.inside, gated)
    assert 0 < scores.inside.sum() < 300
    assert np.all(scores.cost[scores.inside] >= -1e-9)
    inside_costs = scores.cost[scores.inside]
    assert np.all(inside_costs <= scores.miss_cost[pairs.track[scores.inside]] + 1e-9)
    np.testing.assert_array_equal(scores.columns["d2"], innovation.d2)
    np.testing.assert_array_equal(scores.columns["loglik"], innovation.loglik)


def _brute_force(ti, pj, cost, miss, n_tracks):
    """Smallest total cost over every set of pairs with each track and plot used at most once."""
    best = miss.sum()
    for size in range(1, min(n_tracks, len(ti)) + 1):
        for chosen in itertools.combinations(range(len(ti)), size):
            chosen = list(chosen)
            if len(set(ti[chosen])) < size or len(set(pj[chosen])) < size:
                continue
            total = cost[chosen].sum() + miss.sum() - miss[ti[chosen]].sum()
            best = min(best, total)
    return best


@pytest.mark.parametrize("name", sorted(ASSIGNERS))
@pytest.mark.parametrize("seed", range(5))
def test_assigner_is_optimal_on_small_problems(name, seed):
    rng = np.random.default_rng(seed)
    assigner = build_assigner(name)
    for _ in range(20):
        n_tracks, n_plots = int(rng.integers(1, 5)), int(rng.integers(1, 5))
        flat = rng.choice(n_tracks * n_plots, size=int(rng.integers(1, n_tracks * n_plots + 1)), replace=False)
        ti, pj = flat // n_plots, flat % n_plots
        cost = rng.uniform(0, 12, len(ti))
        inside = rng.random(len(ti)) < 0.8
        miss = np.full(n_tracks, 9.0)
        scores = PairScores(Pairs(ti, pj), cost, inside, miss)
        chosen = assigner.assign(scores, n_tracks, n_plots)
        assert np.all(inside[chosen])
        assert len(set(ti[chosen])) == len(chosen) == len(set(pj[chosen]))
        total = cost[chosen].sum() + miss.sum() - miss[ti[chosen]].sum()
        keep = np.flatnonzero(inside)
        assert total == pytest.approx(_brute_force(ti[keep], pj[keep], cost[keep], miss, n_tracks), abs=1e-9)

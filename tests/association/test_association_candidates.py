"""Sparse gating (skytrack.association.candidates): the k-d tree search must return every
pair that passes the exact Mahalanobis gate of spec 000 R7."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skytrack.association.candidates import candidate_pairs, max_eigenvalue_sym


def random_spd(rng, count, dim, low, high):
    """SPD matrices with standard deviations log-uniform in [low, high] and random orientation."""
    sigmas = np.exp(rng.uniform(np.log(low), np.log(high), (count, dim)))
    q, _ = np.linalg.qr(rng.normal(size=(count, dim, dim)))
    return q @ (sigmas[..., None] ** 2 * np.swapaxes(q, -1, -2))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 2**32 - 1),
    dim=st.sampled_from([2, 3]),
    n_tracks=st.integers(0, 30),
    n_plots=st.integers(0, 60),
    n_wide=st.integers(0, 4),
    gate=st.floats(1.0, 30.0),
    with_margin=st.booleans(),
)
def test_candidates_are_a_superset_of_the_exact_gate(seed, dim, n_tracks, n_plots, n_wide, gate, with_margin):
    rng = np.random.default_rng(seed)
    n_wide = min(n_wide, n_plots)
    tracks = rng.uniform(-2e4, 2e4, (n_tracks, dim))
    P = random_spd(rng, n_tracks, dim, 20.0, 3000.0)
    R = random_spd(rng, n_plots, dim, 20.0, 800.0)
    if n_wide:  # plots that could not be placed: huge, elongated uncertainty
        R[:n_wide] = random_spd(rng, n_wide, dim, 1e3, 8e4)
    # half the plots near a track (drawn from its gate region), the rest anywhere
    plots = rng.uniform(-2.5e4, 2.5e4, (n_plots, dim))
    if n_tracks:
        near = rng.random(n_plots) < 0.5
        owner = rng.integers(0, n_tracks, n_plots)
        spread = np.linalg.cholesky(P[owner] + R) @ rng.normal(size=(n_plots, dim, 1))
        plots[near] = tracks[owner[near]] + 1.5 * spread[near, :, 0]
    margin = rng.uniform(0, 500, n_tracks) if with_margin else np.zeros(n_tracks)

    ti, pj = candidate_pairs(
        tracks, np.sqrt(max_eigenvalue_sym(P)) if n_tracks else np.zeros(0), margin,
        plots, np.sqrt(max_eigenvalue_sym(R)) if n_plots else np.zeros(0), np.sqrt(gate),
    )
    found = set(zip(ti.tolist(), pj.tolist()))
    assert len(found) == len(ti), "a pair is returned twice"
    if len(ti):
        assert ti.min() >= 0 and ti.max() < n_tracks and pj.min() >= 0 and pj.max() < n_plots

    # brute force: every pair with d^2 = nu^T (P + R)^-1 nu <= g
    if n_tracks and n_plots:
        nu = plots[None, :, :] - tracks[:, None, :]
        S = P[:, None] + R[None, :]
        d2 = np.einsum("tpi,tpi->tp", nu, np.linalg.solve(S, nu[..., None])[..., 0])
        gated = set(zip(*map(lambda a: a.tolist(), np.nonzero(d2 <= gate))))
        missing = gated - found
        assert not missing, f"pairs inside the gate not returned: {sorted(missing)[:5]}"


def test_candidates_with_no_tracks_or_no_plots():
    empty = np.zeros((0, 2))
    ti, pj = candidate_pairs(empty, np.zeros(0), np.zeros(0), np.ones((3, 2)), np.ones(3), 3.0)
    assert ti.size == 0 and pj.size == 0
    ti, pj = candidate_pairs(np.ones((3, 2)), np.ones(3), np.zeros(3), empty, np.zeros(0), 3.0)
    assert ti.size == 0 and pj.size == 0


def test_candidate_radius_is_scale_times_sigma_sum_plus_margin():
    """One track at the origin, sigma 100, margin 50; plots with sigma 10 on the x axis:
    the radius is 3 * (100 + 10) + 50 = 380 m."""
    track = np.zeros((1, 2))
    plots = np.array([[379.0, 0.0], [381.0, 0.0], [-100.0, 200.0], [0.0, -1000.0]])
    ti, pj = candidate_pairs(track, np.array([100.0]), np.array([50.0]), plots, np.full(4, 10.0), 3.0)
    assert sorted(pj.tolist()) == [0, 2]
    assert set(ti.tolist()) == {0}


def test_wide_plots_are_searched_from_their_own_side():
    """With more than 20 plots, a plot above the 95 % quantile of plot sigma does not inflate
    the tracks' radius but still finds the tracks within its own radius."""
    rng = np.random.default_rng(3)
    plots = rng.uniform(5e4, 6e4, (30, 2))  # far from the tracks
    sigma = np.full(30, 10.0)
    plots[0] = (20_000.0, 0.0)
    sigma[0] = 10_000.0  # wide plot 20 km from track 0
    tracks = np.array([[0.0, 0.0], [-40_000.0, 0.0]])
    ti, pj = candidate_pairs(tracks, np.array([50.0, 50.0]), np.zeros(2), plots, sigma, 3.0)
    assert list(zip(ti.tolist(), pj.tolist())) == [(0, 0)]


def test_max_eigenvalue_exact_for_2x2():
    rng = np.random.default_rng(5)
    M = random_spd(rng, 500, 2, 0.1, 1e4)
    np.testing.assert_allclose(max_eigenvalue_sym(M), np.linalg.eigvalsh(M)[:, -1], rtol=1e-12)
    # diagonal and repeated eigenvalues
    np.testing.assert_allclose(max_eigenvalue_sym(np.array([[[4.0, 0.0], [0.0, 9.0]], [[2.0, 0.0], [0.0, 2.0]]])), [9.0, 2.0])


def test_max_eigenvalue_upper_bound_for_3x3():
    rng = np.random.default_rng(6)
    M = random_spd(rng, 500, 3, 0.1, 1e4)
    exact = np.linalg.eigvalsh(M)[:, -1]
    bound = max_eigenvalue_sym(M)
    assert np.all(bound >= exact * (1 - 1e-12))
    # Gershgorin: at most sqrt(3) times the spectral norm for a 3x3 symmetric matrix
    assert np.all(bound <= np.sqrt(3) * exact * (1 + 1e-12))
    # exact for diagonal matrices
    np.testing.assert_allclose(max_eigenvalue_sym(np.diag([1.0, 7.0, 3.0])[None]), [7.0])


@pytest.mark.parametrize("dim", [2, 3])
def test_max_eigenvalue_keeps_leading_shape(dim):
    M = np.broadcast_to(np.eye(dim), (4, 5, dim, dim))
    assert max_eigenvalue_sym(M).shape == (4, 5)

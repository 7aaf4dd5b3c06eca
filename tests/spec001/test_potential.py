"""Spec 001 R9 / TV-1: potential characteristics (skytrack.identify.potential).

P_ПО (27b)/(28b), P_НО (27a)/(28) against the TV-1 tables with the spec's tolerances, A = 0 row
= P_ПО, closed forms against scipy's ncx2 to 1e-12 on A, r in [0, 10] (and the (28b) limit below
A = 1e-6), the (27c) averages, broadcasting, metric inputs giving the normalised results, and
the circular mode's warning (G10)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import integrate, special, stats

from skytrack.identify.potential import (
    CircularScatteringWarning, characteristics, combined_sigma, difference_covariance, normalised_offset,
    p_correct, p_incorrect, p_incorrect_mean,
)

R = np.array([0.5, 1.0, 2.0, 2.5, 3.0, 4.0])
P_CORRECT = {2: [0.1175030974, 0.3934693403, 0.8646647168, 0.9560630664, 0.9888910035, 0.9996645374],
             3: [0.0308595958, 0.1987480431, 0.7385358701, 0.8999391669, 0.9707091135, 0.9988660157]}
P_INCORRECT = {
    2: [[7.347260e-2, 2.671202e-1, 7.309879e-1, 8.791459e-1, 9.562840e-1, 9.971105e-1],
        [1.793063e-2, 8.189230e-2, 3.964990e-1, 6.058961e-1, 7.856379e-1, 9.658652e-1],
        [1.699767e-3, 1.082945e-2, 1.132792e-1, 2.461016e-1, 4.325202e-1, 8.034878e-1],
        [6.217609e-5, 5.899491e-4, 1.472346e-2, 4.849959e-2, 1.258961e-1, 4.497279e-1],
        [8.712740e-7, 1.279102e-5, 8.007296e-4, 4.136749e-3, 1.661633e-2, 1.329502e-1]],
    3: [[1.918261e-2, 1.322986e-1, 6.024560e-1, 8.043153e-1, 9.233611e-1, 9.942195e-1],
        [4.602888e-3, 3.853592e-2, 3.005641e-1, 5.154344e-1, 7.203598e-1, 9.502544e-1],
        [4.251636e-4, 4.766082e-3, 7.799855e-2, 1.911824e-1, 3.670192e-1, 7.606878e-1],
        [1.505667e-5, 2.420210e-4, 9.252391e-3, 3.442780e-2, 9.816257e-2, 4.002644e-1],
        [2.034749e-7, 4.905425e-6, 4.635283e-4, 2.704005e-3, 1.195194e-2, 1.102611e-1]],
}
A_ROWS = np.arange(1.0, 6.0)


@pytest.mark.parametrize("dim", [2, 3])
def test_tv1_p_correct(dim):
    assert np.max(np.abs(p_correct(R, dim) - P_CORRECT[dim])) <= 1e-9


@pytest.mark.parametrize("method", ["closed", "ncx2"])
@pytest.mark.parametrize("dim", [2, 3])
def test_tv1_p_incorrect_tables_relative_1e_6(dim, method):
    table = p_incorrect(A_ROWS[:, None], R[None, :], dim, method)
    assert table.shape == (5, 6)
    np.testing.assert_allclose(table, P_INCORRECT[dim], rtol=1e-6, atol=0)


@pytest.mark.parametrize("method", ["closed", "ncx2"])
@pytest.mark.parametrize("dim", [2, 3])
def test_tv1_zero_offset_row_is_p_correct(dim, method):
    assert np.max(np.abs(p_incorrect(0.0, R, dim, method) - P_CORRECT[dim])) <= 1e-9
    grid = np.linspace(0, 10, 101)
    assert np.max(np.abs(p_incorrect(0.0, grid, dim, method) - p_correct(grid, dim))) <= 1e-14


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_closed_forms_agree_with_ncx2_to_1e_12_on_a_grid(dim):
    grid = np.linspace(0.0, 10.0, 161)
    closed = p_incorrect(grid[:, None], grid[None, :], dim, "closed")
    reference = p_incorrect(grid[:, None], grid[None, :], dim, "ncx2")
    assert np.max(np.abs(closed - reference)) <= 1e-12
    assert np.max(np.abs(p_correct(grid, dim) - stats.chi2.cdf(grid ** 2, dim))) <= 1e-12


def test_offset_sphere_takes_the_maxwell_limit_below_1e_6_and_stays_continuous():
    r = np.linspace(0.0, 10.0, 201)
    for A in (0.0, 1e-9, 5e-7, 9.99e-7, 1e-6, 1.01e-6, 1e-5, 1e-3):
        closed = p_incorrect(A, r, 3, "closed")
        assert np.max(np.abs(closed - p_incorrect(A, r, 3, "ncx2"))) <= 1e-12
        assert np.all(np.isfinite(closed))
    assert np.array_equal(p_incorrect(9.99e-7, r, 3), p_correct(r, 3))


def test_rice_quadrature_matches_the_literal_integral_27a():
    for A, r in ((1.0, 2.0), (3.0, 2.5), (5.0, 0.5), (0.3, 4.0)):
        literal, _ = integrate.quad(lambda t: math.exp(-A * A / 2 - t * t / 2) * special.i0(A * t) * t, 0.0, r,
                                    epsabs=1e-15, epsrel=1e-13)
        assert p_incorrect(A, r, 2) == pytest.approx(literal, rel=1e-12, abs=1e-15)


def test_higher_dims_use_scipy_and_broadcast():
    A = np.array([0.0, 1.0, 2.5])
    r = np.array([[0.5], [2.0], [4.0], [7.0]])
    for dim in (4, 6):
        values = p_incorrect(A, r, dim)
        assert values.shape == (4, 3)
        expected = np.where(A == 0, stats.chi2.cdf(r ** 2, dim), stats.ncx2.cdf(r ** 2, dim, np.maximum(A, 1e-300) ** 2))
        np.testing.assert_allclose(values, expected, rtol=1e-14, atol=1e-15)
    assert isinstance(p_incorrect(2.0, 1.0, 2), float) and isinstance(p_correct(1.0, 3), float)


def test_probabilities_rise_with_r_and_fall_with_A():
    r = np.linspace(0, 8, 81)
    A = np.linspace(0, 8, 17)
    for dim in (2, 3):
        table = p_incorrect(A[None, :], r[:, None], dim)
        assert np.all(np.diff(table, axis=0) >= -1e-15)
        assert np.all(np.diff(table, axis=1) <= 1e-15)
    # E2: 3-D below 2-D at equal r > 0 and A
    assert np.all(p_incorrect(A[None, :], r[1:, None], 3) < p_incorrect(A[None, :], r[1:, None], 2))


@pytest.mark.parametrize("bad", [dict(A=-1.0, r=1.0, dim=2), dict(A=1.0, r=-0.1, dim=3), dict(A=1.0, r=1.0, dim=0),
                                 dict(A=1.0, r=1.0, dim=2.5)])
def test_bad_arguments_raise(bad):
    with pytest.raises(ValueError):
        p_incorrect(**bad)
    with pytest.raises(ValueError):
        p_incorrect(1.0, 1.0, 2, method="series")


# --- (27c) -----------------------------------------------------------------------------------

def test_tv1_averaged_p_incorrect():
    # sigma = 100 m, Delta in [100, 600] m, h = 200 m: A in [1, 6], r = 2 (tolerance 1e-8)
    assert abs(p_incorrect_mean(2.0, 1.0, 6.0, 2) - 0.1737679657) <= 1e-8
    assert abs(p_incorrect_mean(2.0, 1.0, 6.0, 3) - 0.1335843625) <= 1e-8
    # Delta in [0, 1000] m
    assert abs(p_incorrect_mean(2.0, 0.0, 10.0, 2) - 0.1688640327) <= 1e-8
    assert abs(p_incorrect_mean(2.0, 0.0, 10.0, 3) - 0.1360011925) <= 1e-8


def test_averaged_p_incorrect_is_vectorised_and_reduces_to_p_incorrect():
    r = np.array([0.5, 2.0, 3.0])
    means = p_incorrect_mean(r, 1.0, 6.0, 2)
    assert means.shape == (3,)
    for value, rr in zip(means, r):
        single, _ = integrate.quad(lambda a: p_incorrect(a, rr, 2, "ncx2"), 1.0, 6.0, epsabs=1e-14, epsrel=1e-12)
        assert value == pytest.approx(single / 5.0, abs=1e-11)
    assert p_incorrect_mean(r, 2.0, 2.0, 3) == pytest.approx(p_incorrect(2.0, r, 3), abs=0)
    with pytest.raises(ValueError):
        p_incorrect_mean(r, 3.0, 2.0, 2)


# --- metric inputs, exact and circular modes ---------------------------------------------------

def test_metric_inputs_give_the_normalised_results():
    result, mean = characteristics(2, h=[50.0, 200.0, 400.0], delta=[100.0, 300.0], delta_range=(100.0, 600.0),
                                   sigma=100.0)
    np.testing.assert_allclose(result.r, [0.5, 2.0, 4.0])
    np.testing.assert_allclose(result.A, [1.0, 3.0])
    assert result.sigma == 100.0
    assert np.max(np.abs(result.p_correct - np.array(P_CORRECT[2])[[0, 2, 5]])) <= 1e-9
    np.testing.assert_allclose(result.p_incorrect, np.array(P_INCORRECT[2])[[0, 2]][:, [0, 2, 5]].T, rtol=1e-6)
    assert abs(mean[1] - 0.1737679657) <= 1e-8


def test_per_system_sigmas_are_combined():
    np.testing.assert_allclose(combined_sigma([60.0, 30.0], [80.0, 40.0]), [100.0, 50.0])
    S = difference_covariance(sigma_eta=60.0, sigma_xi=80.0, dim=3)
    np.testing.assert_allclose(S, 1e4 * np.eye(3))
    by_system, _ = characteristics(3, h=200.0, delta=400.0, sigma_eta=60.0, sigma_xi=80.0)
    normalised, _ = characteristics(3, r=2.0, A=4.0)
    assert by_system.p_correct == pytest.approx(normalised.p_correct, abs=1e-15)
    assert by_system.p_incorrect == pytest.approx(normalised.p_incorrect, abs=1e-15)
    assert float(by_system.p_incorrect) == pytest.approx(P_INCORRECT[3][3][2], rel=1e-6)  # TV-1 3-D, A = 4, r = 2


def test_exact_mode_uses_lambda_of_the_full_covariance():
    S = np.array([[100.0 ** 2, 1500.0], [1500.0, 30.0 ** 2]])
    delta = np.array([[150.0, 0.0], [0.0, 150.0], [120.0, -40.0]])
    A = normalised_offset(delta, S, vectors=True)
    lam = np.einsum("ij,jk,ik->i", delta, np.linalg.inv(S), delta)
    np.testing.assert_allclose(A ** 2, lam, rtol=1e-13)
    result, _ = characteristics(r=2.0, delta_vectors=delta, covariance=S)
    np.testing.assert_allclose(result.p_incorrect, stats.ncx2.cdf(4.0, 2, lam), rtol=1e-10)
    # per-axis sigmas: lambda = sum Delta_i^2 / sigma_i^2 (G10)
    result, _ = characteristics(r=2.0, delta_vectors=[[150.0, 0.0], [0.0, 150.0]], sigma_eta=[100.0, 30.0],
                                sigma_xi=[0.0, 0.0])
    np.testing.assert_allclose(result.A, [1.5, 5.0])
    with pytest.raises(ValueError, match="no distance threshold"):
        characteristics(h=200.0, A=1.0, sigma_eta=[100.0, 30.0], sigma_xi=[0.0, 0.0])
    with pytest.raises(ValueError, match="direction"):
        characteristics(r=2.0, delta=150.0, sigma_eta=[100.0, 30.0], sigma_xi=[0.0, 0.0])


def test_circular_mode_takes_the_largest_sigma_and_warns():
    with pytest.warns(CircularScatteringWarning, match="G10"):
        result, _ = characteristics(h=200.0, delta=[150.0, 300.0], sigma_eta=[100.0, 30.0], sigma_xi=[0.0, 0.0],
                                    mode="circular")
    assert result.sigma == pytest.approx(100.0)
    assert result.r == pytest.approx(2.0) and result.A == pytest.approx([1.5, 3.0])
    # E4's circular values: 0.8647, 0.576, 0.113
    assert float(result.p_correct) == pytest.approx(0.8646647168, abs=1e-9)
    assert result.p_incorrect == pytest.approx([0.5763207, 0.1132792], abs=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # equal sigmas: no warning
        characteristics(2, h=200.0, delta=150.0, sigma=100.0, mode="circular")


def test_characteristics_rejects_conflicting_inputs():
    with pytest.raises(ValueError):
        characteristics(2, r=1.0, h=100.0, sigma=100.0)
    with pytest.raises(ValueError):
        characteristics(2, h=100.0)  # metres without a sigma
    with pytest.raises(ValueError):
        characteristics(2, r=1.0, A=1.0, delta=100.0, sigma=100.0)
    with pytest.raises(ValueError):
        characteristics(3, r=1.0, sigma_eta=[1.0, 2.0], sigma_xi=[1.0, 2.0])
    with pytest.raises(ValueError):
        characteristics(2, r=1.0, mode="elliptic")

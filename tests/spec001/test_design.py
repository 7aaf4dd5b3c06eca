"""Spec 001 R10 / R5 / TV-1 / TV-5b: Neyman-Pearson threshold design (skytrack.identify.design).

The NP design table (r 1e-7, P_ПО 1e-7), P_ПО at alpha = 0.05 for A = 2..6 (1e-6), the averaged
(27c) designs (r and P_ПО 1e-7, h in metres), the P_ПО design, and the sequential test's threshold
helpers: chi2 / ncx2 quantiles vectorised over dof, and the worst-direction non-centrality of a
position separation on the TV-5 covariances (lambda 1e-5, thresholds 1e-6 relative)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from skytrack.identify.design import (
    ThresholdDesign, noncentrality_from_separation, np_threshold, threshold_for_p_correct, threshold_for_p_incorrect,
)
from skytrack.identify.potential import p_correct, p_incorrect, p_incorrect_mean

NP_TABLE = [  # dim, A, alpha, r, r^2, P_ПО
    (2, 4, 0.05, 2.51428748, 6.321642, 0.95760907),
    (2, 3, 0.01, 0.97396844, 0.948615, 0.37768399),
    (2, 5, 0.001, 2.06325931, 4.257039, 0.88098664),
    (3, 4, 0.05, 2.66475481, 7.100918, 0.93125021),
    (3, 3, 0.01, 1.21185810, 1.468600, 0.31046385),
    (3, 5, 0.001, 2.20792504, 4.874933, 0.81881239),
]


@pytest.mark.parametrize("method", ["closed", "ncx2"])
@pytest.mark.parametrize("dim, A, alpha, r, r2, p", NP_TABLE)
def test_tv1_np_design_table(dim, A, alpha, r, r2, p, method):
    design = threshold_for_p_incorrect(alpha, dim, A=A, method=method)
    assert abs(design.r - r) <= 1e-7
    assert abs(design.l_threshold - r2) <= 5e-7  # the table's six decimals
    assert abs(design.p_correct - p) <= 1e-7
    assert design.p_incorrect == pytest.approx(alpha, rel=1e-10)
    assert design.h is None and design.A == A and design.alpha == alpha


@pytest.mark.parametrize("dim, expected", [(2, [0.275881, 0.717462, 0.957609, 0.997619, 0.999950]),
                                           (3, [0.243213, 0.642414, 0.931250, 0.995155, 0.999877])])
def test_tv1_p_correct_at_alpha_005_for_A_2_to_6(dim, expected):
    got = [threshold_for_p_incorrect(0.05, dim, A=A).p_correct for A in (2, 3, 4, 5, 6)]
    assert np.max(np.abs(np.array(got) - expected)) <= 1e-6


@pytest.mark.parametrize("dim, alpha, r, h, p", [
    (2, 0.05, 1.09009560, 109.0096, 0.44797073), (3, 0.05, 1.37930169, 137.9302, 0.40710663),
    (2, 0.01, 0.49765900, None, 0.11647195), (3, 0.01, 0.78715321, None, 0.10807124)])
def test_tv1_averaged_np_design(dim, alpha, r, h, p):
    design = threshold_for_p_incorrect(alpha, dim, A_range=(1.0, 6.0), sigma=100.0)
    assert abs(design.r - r) <= 1e-7
    assert abs(design.p_correct - p) <= 1e-7
    assert design.h == pytest.approx(100.0 * design.r, rel=1e-15)
    if h is not None:
        assert abs(design.h - h) <= 5e-5  # quoted to 0.1 mm
    assert p_incorrect_mean(design.r, 1.0, 6.0, dim) == pytest.approx(alpha, rel=1e-9)
    assert design.A_range == (1.0, 6.0) and design.sigma == 100.0


def test_design_is_a_small_frozen_dataclass():
    design = threshold_for_p_incorrect(0.05, 2, A=4.0, sigma=50.0)
    assert isinstance(design, ThresholdDesign)
    assert design.h == pytest.approx(50.0 * 2.51428748, abs=5e-6)
    with pytest.raises(dataclasses.FrozenInstanceError):
        design.r = 1.0


def test_threshold_for_p_correct():
    design = threshold_for_p_correct(0.99, 2, sigma=100.0)
    assert design.l_threshold == pytest.approx(9.2103403720, abs=1e-9)  # chi2_2(0.99), TV-2 / TV-6
    assert design.r == pytest.approx(np.sqrt(9.2103403720), abs=1e-9)
    assert design.p_correct == pytest.approx(0.99, abs=1e-14) and design.p_incorrect is None
    assert design.h == pytest.approx(100.0 * design.r)
    # the inverse of the TV-1 P_ПО table
    assert threshold_for_p_correct(0.8646647168, 2).r == pytest.approx(2.0, abs=1e-8)
    assert threshold_for_p_correct(0.7385358701, 3).r == pytest.approx(2.0, abs=1e-8)


@pytest.mark.parametrize("kwargs", [dict(alpha=0.0, dim=2, A=1.0), dict(alpha=1.0, dim=2, A=1.0),
                                    dict(alpha=0.05, dim=2), dict(alpha=0.05, dim=2, A=1.0, A_range=(1, 2)),
                                    dict(alpha=0.05, dim=2, A_range=(3, 1)), dict(alpha=0.05, dim=2, A=1.0, sigma=0)])
def test_bad_designs_raise(kwargs):
    with pytest.raises(ValueError):
        threshold_for_p_incorrect(**kwargs)


def test_high_alpha_and_large_offset_designs_bracket_the_root():
    for dim, A, alpha in ((2, 12.0, 0.5), (4, 0.0, 0.999), (3, 20.0, 1e-6)):
        design = threshold_for_p_incorrect(alpha, dim, A=A)
        assert p_incorrect(A, design.r, dim) == pytest.approx(alpha, rel=1e-9)
        assert design.p_correct == pytest.approx(p_correct(design.r, dim), abs=0)


# --- R5 helpers for the sequential test --------------------------------------------------------

def test_np_threshold_quantiles_vectorised_over_dof():
    h = np_threshold(np.array([0, 1, 2, 4]), p_correct=0.99)
    assert np.isnan(h[0])  # dof 0: no decision
    np.testing.assert_allclose(h[1:], [6.6348966010, 9.2103403720, 13.2767041360], rtol=1e-10)
    assert np_threshold(4, p_correct=0.99) == pytest.approx(13.276704, abs=1e-6)  # TV-5b
    # TV-5b: NP h for P_НО = 0.01 and P_ПО at that h
    lam = np.array([8.609522, 34.438087, 77.485696, 137.752348, 68.876174, 9.947382, 2.486846])
    h_np = np_threshold(4, p_incorrect=0.01, noncentrality=lam)
    np.testing.assert_allclose(h_np, [1.891399, 14.881644, 44.515110, 91.242414, 38.219947, 2.328567, 0.545655],
                               rtol=1e-6)
    np.testing.assert_allclose(stats.chi2.cdf(h_np[[0, 1, 5, 6]], 4), [0.244275, 0.995047, 0.324427, 0.031093],
                               atol=1e-6)
    # R5: the same numbers are R9's potential characteristics with dim = dof and A = sqrt(lambda)
    p_bad = p_incorrect(np.sqrt(lam[:5]), np.sqrt(13.276704135987622), 4)
    np.testing.assert_allclose(p_bad, [0.5968379, 5.402285e-3, 3.029126e-8, 4.743487e-17, 4.271266e-7], rtol=1e-6)
    both = np_threshold(np.array([[2], [4]]), p_incorrect=0.01, noncentrality=np.array([0.0, 34.438087]))
    assert both.shape == (2, 2)
    assert both[0, 0] == pytest.approx(stats.chi2.ppf(0.01, 2), rel=1e-12)
    assert both[1, 1] == pytest.approx(14.881644, rel=1e-6)


@pytest.mark.parametrize("kwargs", [dict(dof=2), dict(dof=2, p_correct=0.9, p_incorrect=0.1, noncentrality=1.0),
                                    dict(dof=2, p_incorrect=0.1), dict(dof=2, p_correct=0.9, noncentrality=1.0),
                                    dict(dof=2, p_incorrect=0.1, noncentrality=-1.0), dict(dof=2, p_correct=1.0)])
def test_np_threshold_rejects_bad_modes(kwargs):
    with pytest.raises(ValueError):
        np_threshold(**kwargs)


def _tv5_sum_of_covariances() -> np.ndarray:
    """P_eta + P_xi at t = 9.3 of TV-5a, state [x, y, vx, vy] (closed form sigma^2 [[1/N + tau^2/S_tt, ...]])."""
    def per_axis(sigma2, tau):
        return sigma2 * np.array([[0.1 + tau ** 2 / 82.5, tau / 82.5], [tau / 82.5, 1.0 / 82.5]])

    radar, adsb = per_axis(50.0 ** 2, 4.8), per_axis(20.0 ** 2, 4.5)
    np.testing.assert_allclose(radar, [[948.181818, 145.454545], [145.454545, 30.303030]], atol=1e-6)
    np.testing.assert_allclose(adsb, [[138.181818, 21.818182], [21.818182, 4.848485]], atol=1e-6)
    total = np.zeros((4, 4))
    for axis in (0, 1):
        total[np.ix_([axis, axis + 2], [axis, axis + 2])] = radar + adsb
    return total


def test_noncentrality_from_separation_on_tv5():
    P_sum = _tv5_sum_of_covariances()
    lam = noncentrality_from_separation(np.array([50.0, 100.0, 150.0, 200.0, 100.0 * np.sqrt(2.0)]), P_sum)
    np.testing.assert_allclose(lam, [8.609522, 34.438087, 77.485696, 137.752348, 68.876174], atol=1e-5)
    # it is delta^T (P_eta + P_xi)^-1 delta with equal velocities, minimised over the direction
    directions = np.linspace(0.0, np.pi, 181)
    delta = np.stack([100 * np.cos(directions), 100 * np.sin(directions), 0 * directions, 0 * directions], axis=1)
    forms = np.einsum("ij,jk,ik->i", delta, np.linalg.inv(P_sum), delta)
    assert noncentrality_from_separation(100.0, P_sum) == pytest.approx(forms.min(), rel=1e-12)


def test_noncentrality_from_separation_takes_the_worst_direction_and_batches():
    P_sum = np.diag([400.0, 100.0, 4.0, 4.0])
    assert noncentrality_from_separation(10.0, P_sum) == pytest.approx(100.0 / 400.0)
    batch = np.stack([P_sum, 4.0 * P_sum])
    np.testing.assert_allclose(noncentrality_from_separation(10.0, batch), [0.25, 0.0625])
    # a position-only state (TV-6): all components are positions
    assert noncentrality_from_separation(20.0, np.diag([2900.0, 2900.0])) == pytest.approx(400.0 / 2900.0)
    with pytest.raises(ValueError):
        noncentrality_from_separation(1.0, np.eye(2), position_index=(0, 2))

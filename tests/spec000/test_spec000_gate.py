"""Spec 000 R7 and TV12: chi-square gates, gate volume, the 1-D gate interval and its growth with misses."""

import math

import numpy as np
import pytest
from scipy.special import gamma as gamma_fn

from skytrack.association.gate import (
    gate_half_width,
    gate_interval_1d,
    gate_test,
    gate_threshold,
    gate_volume,
)
from skytrack.filters import SingerFilter1D
from skytrack.models import SingerAxisModel

GAMMA_N = np.array([[2500.0, 150.0, 2.0], [150.0, 40.0, 0.8], [2.0, 0.8, 0.6]])
M_N = np.array([1000.0, 200.0, 0.5])
TV10_S = np.array([
    [5000.0, 0.0, 0.0, 100.0],
    [0.0, 7.8538919452e-6, 0.0, -1.7715299832e-4],
    [0.0, 0.0, 2.8384184596e-5, 3.6225267639e-6],
    [100.0, -1.7715299832e-4, 3.6225267639e-6, 101.03139673],
])


def test_tv12_thresholds():
    expected_99 = [6.6348966010212145, 9.21034037197618, 11.344866730144373, 13.276704135987622]
    for m, value in enumerate(expected_99, start=1):
        assert gate_threshold(m) == pytest.approx(value, rel=1e-14)
        assert gate_threshold(m, 0.99) == pytest.approx(value, rel=1e-14)
    assert gate_threshold(1, 0.95) == pytest.approx(3.841458820694124, rel=1e-14)
    assert gate_threshold(2, 0.95) == pytest.approx(5.991464547107979, rel=1e-14)
    np.testing.assert_allclose(gate_threshold(np.array([1, 2, 3, 4])), expected_99, rtol=1e-14)


@pytest.mark.parametrize("p", [0.0, 1.0, 1.5, -0.1, math.nan, "high"])
def test_gate_threshold_rejects_bad_probability(p):
    with pytest.raises(ValueError, match="p_gate"):
        gate_threshold(2, p)


@pytest.mark.parametrize("m", [0, -1, 1.5])
def test_gate_threshold_rejects_bad_dimension(m):
    with pytest.raises(ValueError, match="dimension"):
        gate_threshold(m)


def test_tv4_gate_interval_and_distance():
    f = SingerFilter1D(SingerAxisModel(60.0, 1.0, "paper"), 50.0, m0=M_N, P0=GAMMA_N)
    em, eg = f.extrapolate(10.0)
    g = gate_threshold(1)
    low, high = gate_interval_1d(em[0], eg[0, 0], 50.0, g)
    assert (low + high) / 2 == pytest.approx(3025.0, rel=1e-14)
    assert (high - low) / 2 == pytest.approx(310.1709217751, rel=1e-12)
    out = f.step(3050.0, True, 10.0)
    d2, inside = gate_test(out.nu, out.S, g)
    assert d2 == pytest.approx(0.04310344827586207, rel=1e-12) and bool(inside)
    assert low <= 3050.0 <= high


def test_tv5_gate_distance_two_components():
    f = SingerFilter1D(SingerAxisModel(60.0, 1.0, "paper"), 50.0, "posvel", 5.0, m0=M_N, P0=GAMMA_N)
    out = f.step([3050.0, 215.0], True, 10.0)
    d2, inside = gate_test(out.nu, out.S, gate_threshold(2))
    assert d2 == pytest.approx(0.9800122134535889, rel=1e-12) and bool(inside)


def test_r7_gate_grows_with_consecutive_misses():
    """From TV4's gamma_n, sigma = 50, P_G = 0.99, after k = 0..3 consecutive misses."""
    expected_var = [12000.0, 54325.47131824, 182401.0291412, 479077.2519626]
    expected_half = [310.1709217751, 614.0286039761, 1107.609682954, 1787.516509623]
    f = SingerFilter1D(SingerAxisModel(60.0, 1.0, "paper"), 50.0, m0=M_N, P0=GAMMA_N)
    widths = []
    for k in range(4):
        em, eg = f.extrapolate(10.0)  # extrapolate to the next report's timestamp
        assert eg[0, 0] == pytest.approx(expected_var[k], rel=1e-10)
        half = gate_half_width(eg[0, 0], 50.0)
        assert half == pytest.approx(expected_half[k], rel=1e-10)
        # m = 1: the gate "volume" is the interval length
        assert gate_volume(np.array([[eg[0, 0] + 2500.0]]), gate_threshold(1)) == pytest.approx(2 * half, rel=1e-13)
        widths.append(half)
        f.step(None, False, 10.0)  # the report is missed
    assert np.all(np.diff(widths) > 0)


def test_tv10_gate_volume():
    g4 = gate_threshold(4)
    assert gate_volume(TV10_S, g4) == pytest.approx(9.1388945882, rel=1e-9)
    assert gate_volume(np.diag([5000.0, 7.8538919452e-6]), gate_threshold(2)) == pytest.approx(5.7339383056, rel=1e-9)
    # the constant pi^{m/2}/Gamma(m/2+1) against its definition, m = 1..6
    for m in range(1, 7):
        S = np.eye(m) * 4.0
        expected = math.pi ** (m / 2) / gamma_fn(m / 2 + 1) * 3.0 ** (m / 2) * 2.0**m
        assert gate_volume(S, 3.0) == pytest.approx(expected, rel=1e-13)


def test_gate_volume_is_batched():
    rng = np.random.default_rng(7)
    A = rng.standard_normal((5, 4, 3, 3))
    S = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(3)
    g = np.linspace(1.0, 9.0, 4)
    V = gate_volume(S, g)
    assert V.shape == (5, 4)
    for i in range(5):
        for j in range(4):
            expected = 4 / 3 * math.pi * g[j] ** 1.5 * math.sqrt(np.linalg.det(S[i, j]))
            assert V[i, j] == pytest.approx(expected, rel=1e-12)


def test_gate_volume_validation():
    with pytest.raises(ValueError, match="positive definite"):
        gate_volume(np.array([[1.0, 2.0], [2.0, 1.0]]), 9.0)
    with pytest.raises(ValueError):
        gate_volume(np.eye(2), 0.0)
    with pytest.raises(ValueError):
        gate_volume(np.ones(3), 1.0)
    with pytest.raises(ValueError):
        gate_volume(np.array([[math.nan]]), 1.0)
    with pytest.raises(ValueError):
        gate_test(np.array([math.nan]), np.eye(1), 1.0)
    with pytest.raises(ValueError):
        gate_half_width(-1.0, 50.0)
    with pytest.raises(ValueError):
        gate_half_width(1.0, 0.0)


def test_gate_probability_is_met_statistically():
    """Innovations drawn from N(0, S) fall inside the P_G = 0.99 gate with frequency 0.99 (4 SE)."""
    rng = np.random.default_rng(12)
    n = 40000
    L = np.linalg.cholesky(TV10_S)
    nu = rng.standard_normal((n, 4)) @ L.T
    _, inside = gate_test(nu, np.broadcast_to(TV10_S, (n, 4, 4)), gate_threshold(4))
    se = math.sqrt(0.99 * 0.01 / n)
    assert abs(inside.mean() - 0.99) <= 4 * se


def test_r7_gate_at_the_reports_own_timestamp_1d():
    """Gating a report 7.5 s ahead uses the extrapolation over 7.5 s and leaves the track unchanged."""
    f = SingerFilter1D(SingerAxisModel(60.0, 1.0, "exact"), 50.0, m0=M_N, P0=GAMMA_N)
    nu, S, d2 = f.predicted_innovation(2700.0, 7.5)
    np.testing.assert_array_equal(f.m, M_N)
    em, eg = f.extrapolate(7.5)
    assert nu[0] == pytest.approx(2700.0 - em[0], rel=1e-14)
    assert S[0, 0] == pytest.approx(eg[0, 0] + 2500.0, rel=1e-14)
    out = f.step(2700.0, True, 7.5)
    assert d2 == pytest.approx(out.d2, rel=1e-13)
    np.testing.assert_allclose(S, out.S, rtol=1e-14)
    with pytest.raises(ValueError):
        f.predicted_innovation(float("nan"), 1.0)


def test_r7_gate_at_the_reports_own_timestamp_3d():
    from skytrack.filters import SingerTracker3D

    models = [SingerAxisModel(60.0, 1.0, "exact")] * 3
    trk = SingerTracker3D(models, sigmas=dict(r=50.0, az=0.003, el=0.005))
    x0 = np.array([30000, -150, 0.5, 40000, 100, -0.2, 9000, 2, 0], dtype=float)
    trk.set_state(x0, np.eye(9) * 100.0)
    report = dict(r=50700.0, az=0.641, el=0.178)
    ahead = trk.innovation(report, dt=4.0)
    np.testing.assert_array_equal(trk.x, x0)  # not changed
    trk.predict(4.0)
    now = trk.innovation(report)
    np.testing.assert_allclose(ahead.nu, now.nu, rtol=1e-13)
    np.testing.assert_allclose(ahead.S, now.S, rtol=1e-13)
    assert ahead.d2 == pytest.approx(now.d2, rel=1e-12)
    _, inside = gate_test(ahead.nu, ahead.S, gate_threshold(len(ahead.components)))
    assert bool(inside) == (ahead.d2 <= gate_threshold(3))

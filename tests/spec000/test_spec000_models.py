"""Spec 000 R1, R2: Singer axis model, both discretisations (TV1, TV2, TV3) and validation."""

import math

import mpmath
import numpy as np
import pytest

from oracles import exact_FQ, paper_FQ
from skytrack.models import MotionModel, SingerAxisModel, singer

DT, TAU, SIGMA_A = 10.0, 60.0, 1.0


def rel_err(actual, expected):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    return np.max(np.abs(actual - expected) / np.abs(expected))


def test_tv1_paper_discretisation():
    m = SingerAxisModel(TAU, SIGMA_A, "paper")
    F_expected = np.array([[1, 10, 50], [0, 1, 10], [0, 0, 0.8464817248906141]])
    np.testing.assert_allclose(m.F(DT), F_expected, rtol=1e-15, atol=0)
    np.testing.assert_allclose(m.Q(DT), np.diag([0, 0, 0.28346868942621073]), rtol=1e-14, atol=0)
    # the paper's shorthand: rho, E1, E2 (common parameters of §5)
    rho = m.F(DT)[2, 2]
    assert rho == pytest.approx(0.8464817248906141, rel=1e-15)
    assert rho - 1 == pytest.approx(-0.15351827510938587, rel=1e-14)
    assert math.sqrt(m.Q(DT)[2, 2] / DT) == pytest.approx(0.16836528425605166, rel=1e-14)  # sigma_a E2


TV2_CASES = [
    # (dt, tau, sigma_a, {(i, j) 1-based: value} of F, {(i, j): value} of Q)
    (10.0, 60.0, 1.0,
     {(1, 3): 47.33420960621, (2, 3): 9.211096506563, (3, 3): 0.8464817248906},
     {(1, 1): 152.111908785715, (1, 2): 37.342123317411, (1, 3): 4.709212065622, (2, 2): 9.824120359201,
      (2, 3): 1.414071647554, (3, 3): 0.283468689426}),
    (1.0, 1000.0, 2.0,
     {(1, 3): 0.4998333749916682, (2, 3): 0.9995001666250085, (3, 3): 0.999000499833375},
     {(1, 1): 3.9977785712064e-4, (1, 2): 9.9933361102225e-4, (1, 3): 1.33200073304454e-3,
      (2, 2): 2.66466759966677e-3, (2, 3): 3.99600233233368e-3, (3, 3): 7.99200533066774e-3}),
    (10.0, 1e7, 1.0,
     {(1, 3): 49.9999833333375, (2, 3): 9.99999500000167, (3, 3): 0.9999990000005},
     {(1, 1): 9.999994444446e-4, (1, 2): 2.499998333334e-4, (1, 3): 3.333330000002e-5,
      (2, 2): 6.666661666669e-5, (2, 3): 9.999990000006e-6, (3, 3): 1.999998000001e-6}),
    (10.0, 0.1, 1.0,
     {(1, 3): 0.99, (2, 3): 0.1, (3, 3): 3.72007597602086e-44},
     {(1, 1): 64.68676666667, (1, 2): 9.801, (1, 3): 0.01, (2, 2): 1.97, (2, 3): 0.1, (3, 3): 1.0}),
]


@pytest.mark.parametrize("dt,tau,sigma_a,F_ref,Q_ref", TV2_CASES)
def test_tv2_exact_discretisation(dt, tau, sigma_a, F_ref, Q_ref):
    m = SingerAxisModel(tau, sigma_a, "exact")
    F, Q = m.F(dt), m.Q(dt)
    for (i, j), value in F_ref.items():
        # the printed values have 13-16 significant digits; 1e-10 relative is the spec tolerance
        assert F[i - 1, j - 1] == pytest.approx(value, rel=1e-10), (i, j)
    for (i, j), value in Q_ref.items():
        assert Q[i - 1, j - 1] == pytest.approx(value, rel=1e-10), (i, j)
        assert Q[j - 1, i - 1] == Q[i - 1, j - 1]
    np.testing.assert_array_equal(F[:, :2], [[1, dt], [0, 1], [0, 0]])


def test_tv2_naive_closed_form_fails_at_small_alpha_dt():
    """The naive double-precision closed form gives Q11 = 3.4694e-4 at alpha dt = 1e-3 (must fail TV2)."""
    a, T, s = 1e-3, 1.0, 2.0
    u = a * T
    e1, e2 = math.exp(-u), math.exp(-2 * u)
    naive = 2 * a * s**2 * (1 - e2 + 2 * u + (2 / 3) * u**3 - 2 * u**2 - 4 * u * e1) / (2 * a**5)
    assert naive == pytest.approx(3.4694e-4, rel=1e-3)
    assert abs(naive / 3.9977785712064e-4 - 1) > 0.1
    assert SingerAxisModel(1000.0, 2.0, "exact").Q(1.0)[0, 0] == pytest.approx(3.9977785712064e-4, rel=1e-10)


def _reference_80_digits(tau, sigma_a, T):
    """(X1)-(X2) in 80-digit arithmetic."""
    mpmath.mp.dps = 80
    a = 1 / mpmath.mpf(tau)
    T = mpmath.mpf(T)
    u = a * T
    e1, e2 = mpmath.exp(-u), mpmath.exp(-2 * u)
    F = [[1, T, (u - 1 + e1) / a**2], [0, 1, (1 - e1) / a], [0, 0, e1]]
    q = {
        (0, 0): (1 - e2 + 2 * u + mpmath.mpf(2) / 3 * u**3 - 2 * u**2 - 4 * u * e1) / (2 * a**5),
        (0, 1): (e2 + 1 - 2 * e1 + 2 * u * e1 - 2 * u + u**2) / (2 * a**4),
        (0, 2): (1 - e2 - 2 * u * e1) / (2 * a**3),
        (1, 1): (4 * e1 - 3 - e2 + 2 * u) / (2 * a**3),
        (1, 2): (e2 + 1 - 2 * e1) / (2 * a**2),
        (2, 2): (1 - e2) / (2 * a),
    }
    scale = 2 * a * mpmath.mpf(sigma_a) ** 2
    Q = [[None] * 3 for _ in range(3)]
    for (i, j), v in q.items():
        Q[i][j] = Q[j][i] = scale * v
    return F, Q


def test_r2_exact_relative_error_below_1e10_over_whole_range():
    """R2/TV2: element-wise relative error <= 1e-10 for alpha dt in [1e-6, 1e4] (80-digit reference).

    Entries below the smallest normal double (e^{-alpha dt} for alpha dt > 708) cannot be
    represented; there the model must return (sub)normal values within 1e-300 of zero.
    """
    worst = 0.0
    grid = np.concatenate([np.logspace(-6, 4, 61), [0.999999, 1.0, 1.000001]])
    for k, u in enumerate(grid):
        dt = (0.5, 10.0, 1000.0)[k % 3]
        tau = dt / u
        sigma_a = 1.7
        model = SingerAxisModel(tau, sigma_a, "exact")
        F, Q = model.F(dt), model.Q(dt)
        F_ref, Q_ref = _reference_80_digits(tau, sigma_a, dt)
        for M, M_ref in ((F, F_ref), (Q, Q_ref)):
            for i in range(3):
                for j in range(3):
                    ref = M_ref[i][j]
                    if abs(ref) < 1e-300:
                        assert abs(M[i, j]) < 1e-300
                        continue
                    err = float(abs((mpmath.mpf(float(M[i, j])) - ref) / ref))
                    worst = max(worst, err)
                    assert err <= 1e-10, (u, i, j, float(ref), M[i, j])
    assert worst < 1e-10


def test_r2_batch_matches_scalar_and_van_loan():
    model = SingerAxisModel(60.0, 1.3, "exact")
    steps = np.array([0.5, 3.0, 10.0, 45.0])
    F_b, Q_b = model.F_batch(steps), model.Q_batch(steps)
    for k, dt in enumerate(steps):
        np.testing.assert_allclose(F_b[k], model.F(dt), rtol=1e-15)
        np.testing.assert_allclose(Q_b[k], model.Q(dt), rtol=1e-15)
        F_v, Q_v = exact_FQ(dt, 60.0, 1.3)  # independent Van Loan (alpha dt <= 0.75 here)
        np.testing.assert_allclose(F_b[k], F_v, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(Q_b[k], Q_v, rtol=1e-11, atol=0)
    F_p, Q_p = SingerAxisModel(60.0, 1.3, "paper").F(10.0), SingerAxisModel(60.0, 1.3, "paper").Q(10.0)
    F_o, Q_o = paper_FQ(10.0, 60.0, 1.3)
    np.testing.assert_allclose(F_p, F_o, rtol=1e-15)
    np.testing.assert_allclose(Q_p, Q_o, rtol=1e-14)


def test_r2_both_discretisations_share_q33():
    for tau, dt in ((60.0, 10.0), (5.0, 7.0), (1e4, 0.1)):
        p = SingerAxisModel(tau, 2.0, "paper").Q(dt)[2, 2]
        e = SingerAxisModel(tau, 2.0, "exact").Q(dt)[2, 2]
        expected = 4.0 * (1 - math.exp(-2 * dt / tau))
        assert p == pytest.approx(expected, rel=1e-14)
        assert e == pytest.approx(expected, rel=1e-14)


def test_r2_continuous_psd_is_2_sigma_a2_over_tau():
    """For small dt, Q33 ~ q dt with PSD q = 2 sigma_a^2 / tau."""
    model = SingerAxisModel(60.0, 3.0, "exact")
    dt = 1e-4
    assert model.Q(dt)[2, 2] / dt == pytest.approx(2 * 9.0 / 60.0, rel=1e-5)


@pytest.mark.parametrize("kwargs", [
    dict(tau=0.0, sigma_a=1.0), dict(tau=-5.0, sigma_a=1.0), dict(tau=math.inf, sigma_a=1.0),
    dict(tau=60.0, sigma_a=-1.0), dict(tau=60.0, sigma_a=math.nan), dict(tau=60.0, sigma_a=1.0, discretization="euler"),
])
def test_r2_parameter_validation(kwargs):
    with pytest.raises(ValueError):
        SingerAxisModel(**kwargs)


@pytest.mark.parametrize("dt", [0.0, -1.0, math.nan, math.inf])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r2_dt_validation(dt, disc):
    model = SingerAxisModel(60.0, 1.0, disc)
    with pytest.raises(ValueError):
        model.F(dt)
    with pytest.raises(ValueError):
        model.Q(dt)


def test_r1_three_d_model_is_block_diagonal_with_per_axis_parameters():
    axes = [SingerAxisModel(60.0, 1.0, "exact"), SingerAxisModel(20.0, 3.0, "exact"), SingerAxisModel(100.0, 0.2, "exact")]
    model = MotionModel(axes)
    F, Q = model.F(10.0), model.Q(10.0)
    assert F.shape == Q.shape == (9, 9)
    for a, ax in enumerate(axes):
        block = slice(3 * a, 3 * a + 3)
        np.testing.assert_array_equal(F[block, block], ax.F(10.0))
        np.testing.assert_array_equal(Q[block, block], ax.Q(10.0))
    off = np.ones((9, 9), bool)
    for a in range(3):
        off[3 * a:3 * a + 3, 3 * a:3 * a + 3] = False
    assert np.all(F[off] == 0) and np.all(Q[off] == 0)
    np.testing.assert_array_equal(model.position_index, [0, 3, 6])
    np.testing.assert_array_equal(singer(3, 60.0, 1.0).F(10.0), MotionModel([axes[0]] * 3).F(10.0))

"""Spec 003 R5, R6: one EKF cycle of the airborne radar (TV4) and one-plot initiation (TV5)."""

import math

import numpy as np
import pytest

from skytrack.core import linalg
from skytrack.filters.airborne_ekf import cv_transition, ekf_update, initiate_from_plot, predict
from skytrack.models.airborne import airborne_measurement, airborne_noise

EKF_RTOL = 1e-7
CLOSED_RTOL = 1e-9

X0 = np.array([[21000.0, 38000.0, 6000.0, -200.0, 100.0, 5.0]])
OWN_P0 = np.array([1000.0, -2000.0, 8000.0])
OWN_V = np.array([50.0, 240.0, 0.0])
OWN_P1 = np.array([1100.0, -1520.0, 8000.0])
P0 = np.diag([100.0**2] * 3 + [20.0**2] * 3)[None]
SIGMA_ANGLE = math.radians(0.3)
R = airborne_noise(30.0, SIGMA_ANGLE, SIGMA_ANGLE, 2.0)
PLOT_OFFSET = np.array([45.0, 0.004, -0.003, 1.5])


@pytest.fixture(scope="module")
def cycle():
    x_pred, P_pred = predict(X0, P0, 2.0, 1.0)
    h_pred, _ = airborne_measurement(x_pred, OWN_P1, OWN_V)
    z = h_pred + PLOT_OFFSET
    return x_pred, P_pred, h_pred, z, ekf_update(x_pred, P_pred, z, OWN_P1, OWN_V, R)


# ---------------------------------------------------------------- R5 / TV4


def test_cv_transition_matches_r5():
    T, q = 2.0, 25.0
    F, Q = cv_transition(T, q)
    eye = np.eye(3)
    np.testing.assert_array_equal(F, np.block([[eye, T * eye], [0 * eye, eye]]))
    np.testing.assert_allclose(Q, q * np.block([[T**3 / 3 * eye, T**2 / 2 * eye], [T**2 / 2 * eye, T * eye]]),
                               rtol=1e-15, atol=0)
    F_batch, Q_batch = cv_transition(np.array([2.0, 0.5]), q)
    assert F_batch.shape == Q_batch.shape == (2, 6, 6)
    np.testing.assert_array_equal(F_batch[0], F)
    np.testing.assert_allclose(Q_batch[1], cv_transition(0.5, q)[1], rtol=1e-15)


def test_tv4_prediction(cycle):
    x_pred, P_pred, *_ = cycle
    np.testing.assert_allclose(x_pred[0], [20600.0, 38200.0, 6010.0, -200.0, 100.0, 5.0], rtol=EKF_RTOL)
    np.testing.assert_allclose(np.diag(P_pred[0]), [11602.6666667] * 3 + [402.0] * 3, rtol=EKF_RTOL)
    assert P_pred[0, 0, 3] == pytest.approx(802.0, rel=EKF_RTOL)
    assert P_pred[0, 3, 0] == P_pred[0, 0, 3]


def test_tv4_predicted_measurement(cycle):
    _, _, h_pred, _, _ = cycle
    np.testing.assert_allclose(h_pred[0], [44293.2105407, 0.456370599795, -0.0449430072566, -235.831854871],
                               rtol=EKF_RTOL)


def test_tv4_innovation_and_covariance(cycle):
    *_, result = cycle
    np.testing.assert_allclose(result.nu[0], PLOT_OFFSET, rtol=1e-9)
    S = result.S[0]
    np.testing.assert_allclose(np.diag(S), [12502.6666667, 3.33415590819e-5, 3.33295973837e-5, 406.156771085],
                               rtol=EKF_RTOL)
    assert S[0, 3] == pytest.approx(802.0, rel=EKF_RTOL)
    assert S[1, 3] == pytest.approx(-9.63288432864e-4, rel=EKF_RTOL)
    assert S[2, 3] == pytest.approx(-3.31249576993e-5, rel=EKF_RTOL)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert abs(S[i, j]) < 1e-12
    np.testing.assert_array_equal(S, S.T)


def test_tv4_scores_from_s(cycle):
    *_, result = cycle
    S, nu = result.S, result.nu
    log_det = linalg.logdet_chol(linalg.cholesky(S))
    assert result.d2[0] == pytest.approx(0.916453412223, rel=EKF_RTOL)
    assert log_det[0] == pytest.approx(-5.312847412007, rel=EKF_RTOL)
    assert linalg.gaussian_loglik(result.d2, log_det, 4)[0] == pytest.approx(-1.477557132927, rel=EKF_RTOL)
    assert -0.5 * result.d2[0] == pytest.approx(-0.458226706112, rel=EKF_RTOL)
    # the paper's literal product form (diagonal flag): diag(S) only
    variances = np.diagonal(S, axis1=-2, axis2=-1)
    d2_diag = np.sum(nu**2 / variances, axis=-1)
    log_det_diag = np.sum(np.log(variances), axis=-1)
    assert d2_diag[0] == pytest.approx(0.917417023231, rel=EKF_RTOL)
    assert log_det_diag[0] == pytest.approx(-5.177334209423, rel=EKF_RTOL)
    assert linalg.gaussian_loglik(d2_diag, log_det_diag, 4)[0] == pytest.approx(-1.545795539723, rel=EKF_RTOL)


def test_tv4_update(cycle):
    *_, result = cycle
    np.testing.assert_allclose(
        result.x[0], [20646.1787033, 38222.3933905, 5984.58297165, -197.356070063, 100.431569106, 3.29905093137],
        rtol=EKF_RTOL)
    P = result.P[0]
    np.testing.assert_allclose(
        np.diag(P), [7853.11819804, 2527.30702745, 9526.26122885, 318.813289674, 78.1888124403, 391.372644099],
        rtol=EKF_RTOL)
    assert P[0, 3] == pytest.approx(545.434237839, rel=EKF_RTOL)
    assert P[1, 4] == pytest.approx(115.838644627, rel=EKF_RTOL)
    np.testing.assert_array_equal(P, P.T)
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_joseph_equals_information_form(cycle):
    x_pred, P_pred, _, z, result = cycle
    _, H = airborne_measurement(x_pred, OWN_P1, OWN_V)
    information = np.linalg.inv(P_pred[0]) + H[0].T @ np.linalg.solve(R, H[0])
    np.testing.assert_allclose(result.P[0], np.linalg.inv(information), rtol=1e-7, atol=1e-9)
    standard = ekf_update(x_pred, P_pred, z, OWN_P1, OWN_V, R, form="standard")
    np.testing.assert_allclose(standard.P, result.P, rtol=1e-8)


def test_update_wraps_azimuth_across_north(cycle):
    x_pred, P_pred, _, z, result = cycle
    shifted = z.copy()
    shifted[0, 1] += 2.0 * math.pi  # the same plot with its azimuth one turn on
    again = ekf_update(x_pred, P_pred, shifted, OWN_P1, OWN_V, R)
    np.testing.assert_allclose(again.nu, result.nu, rtol=1e-9)
    np.testing.assert_allclose(again.x, result.x, rtol=1e-12)


def test_update_is_batched_and_three_component_plots_work(cycle):
    x_pred, P_pred, _, z, result = cycle
    xs, Ps, zs = np.repeat(x_pred, 3, 0), np.repeat(P_pred, 3, 0), np.repeat(z, 3, 0)
    batch = ekf_update(xs, Ps, zs, np.tile(OWN_P1, (3, 1)), np.tile(OWN_V, (3, 1)), R)
    np.testing.assert_array_equal(batch.x, np.repeat(result.x, 3, 0))
    no_vr = ekf_update(x_pred, P_pred, z[:, :3], OWN_P1, None, R[:3, :3])
    assert no_vr.S.shape == (1, 3, 3)
    np.testing.assert_allclose(no_vr.S[0], result.S[0, :3, :3], rtol=1e-12)


def test_update_rejects_overhead_pair(cycle):
    x_pred, P_pred, _, z, _ = cycle
    overhead = x_pred.copy()
    overhead[0, :3] = OWN_P1 + [0.0, 0.0, -2000.0]
    with pytest.raises(ValueError, match=r"pair rows \[0\]"):
        ekf_update(overhead, P_pred, z, OWN_P1, OWN_V, R)


# ---------------------------------------------------------------- R6 / TV5


@pytest.fixture(scope="module")
def started():
    plot, _ = airborne_measurement(X0, OWN_P0, OWN_V)
    x, P = initiate_from_plot(plot, OWN_P0, OWN_V, R, sigma_v0=300.0)
    return plot, x[0], P[0]


def test_tv5_state(started):
    plot, x, _ = started
    u = (x[:3] - OWN_P0) / plot[0, 0]
    np.testing.assert_allclose(u, [0.4467670516, 0.8935341032, -0.0446767052], rtol=1e-9)
    np.testing.assert_allclose(x[:3], [21000.0, 38000.0, 6000.0], rtol=0, atol=1e-6)
    # v = (u . v_target) u = -10000 / D^2 * Delta exactly (D^2 = 2.004e9); the spec lists 9-10 digits
    np.testing.assert_allclose(x[3:], -1e4 / 2.004e9 * np.array([20000.0, 40000.0, -2000.0]), rtol=1e-12)
    np.testing.assert_allclose(x[3:], [-0.0998003992, -0.199600798, 0.00998003992], rtol=3e-9)
    h, _ = airborne_measurement(x[None], OWN_P0, OWN_V)
    np.testing.assert_allclose(h - plot, 0.0, atol=1e-9)


def test_tv5_covariance(started):
    _, _, P = started
    P_pp = [[44066.4816221, -21529.3078791, 1078.6586394], [-21529.3078791, 11772.5198035, 2157.3172788],
            [1078.6586394, 2157.3172788, 54832.9319688]]
    P_vv = [[72036.7265469, -35926.5469062, 1796.3273453], [-35926.5469062, 18146.9061876, 3592.6546906],
            [1796.3273453, 3592.6546906, 89820.3672655]]
    np.testing.assert_allclose(P[:3, :3], P_pp, rtol=1e-9)
    np.testing.assert_allclose(P[3:, 3:], P_vv, rtol=1e-9)
    np.testing.assert_array_equal(P[:3, 3:], 0.0)
    np.testing.assert_array_equal(P[3:, :3], 0.0)


def test_initiation_without_range_rate_and_on_noisy_plots(started):
    plot, x_vr, P_vr = started
    x, P = initiate_from_plot(plot[:, :3], OWN_P0, None, R[:3, :3], sigma_v0=150.0)
    np.testing.assert_array_equal(x[0, :3], x_vr[:3])
    np.testing.assert_array_equal(x[0, 3:], 0.0)
    np.testing.assert_allclose(P[0, :3, :3], P_vr[:3, :3], rtol=1e-15)
    np.testing.assert_array_equal(P[0, 3:, 3:], 150.0**2 * np.eye(3))
    # any plot is reproduced exactly by h of its started state (batched, per-plot own-ship)
    rng = np.random.default_rng(11)
    plots = np.column_stack([rng.uniform(5e3, 9e4, 6), rng.uniform(0, 2 * math.pi, 6),
                             rng.uniform(-0.3, 0.3, 6), rng.uniform(-600, 200, 6)])
    own_p = rng.uniform(-1e4, 1e4, (6, 3))
    own_v = rng.uniform(-250, 250, (6, 3))
    xs, Ps = initiate_from_plot(plots, own_p, own_v, R)
    h, _ = airborne_measurement(xs, own_p, own_v)
    np.testing.assert_allclose(h, plots, rtol=1e-9)
    assert np.all(np.linalg.eigvalsh(Ps) > 0)
    with pytest.raises(ValueError, match="sigma_v0"):
        initiate_from_plot(plot, OWN_P0, OWN_V, R, sigma_v0=0.0)

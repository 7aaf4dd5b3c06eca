"""Spec 002 R11-R13 adaptive augmented filter: TV4 (gain 6), TV10 (A5.1 weighting), TV11 (a) one step and
floor, TV11 (b) one-step unbiasedness (Monte Carlo), TV3's A5.2 identity, A4 skip-and-count, R13 preset."""

import numpy as np
import pytest

from skytrack.analysis.identifiability import check_identifiability
from skytrack.filters.adaptive_augmented import (
    AdaptiveAugmentedFilter,
    AdaptiveSettings,
    LinearMeasurement,
    estimator_gain,
    filter_gain,
    literal_settings,
    project_covariance,
)
from skytrack.filters.identifiability_step import NOT_IDENTIFIABLE, step_verdicts
from skytrack.models.augmented import linear_model

RTOL = 1e-9
#: half a unit in the last place of numbers the spec prints with 10 decimals ("printed decimals are rounded")
PRINTED_ATOL = 5e-11
PAPER_H = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1.0, 0]])
PAPER_COMPONENTS = ("x1", "x2", "x3", "x4", "a1", "a2")


def tv3_F(f16=3.0):
    return np.array([[1, 0.5, 0, 0, 2, f16], [0, 1, 0.1, 0, 0.5, 0.7], [0, 0, 1, 0.1, 0.2, 0],
                     [0, 0, 0, 1, 0, 0.4], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]], dtype=float)


def paper_model(f16=3.0, V_w=np.diag([0.04, 0.09])):
    return linear_model("tv3", tv3_F(f16), PAPER_COMPONENTS, ("-",) * 6, ("a1", "a2"), V_w)


# ---------------------------------------------------------------- TV4: gain (6)

TV4_D_VX = np.array([[2, 1, 0, 0, 0.5, 0.1], [1, 3, 0.2, 0, 0, 0], [0, 0.2, 1, 0.1, 0, 0],
                     [0, 0, 0.1, 1, 0, 0.05], [0.5, 0, 0, 0, 0.5, 0.02], [0.1, 0, 0, 0.05, 0.02, 0.04]])


@pytest.mark.parametrize("inverse", ["cholesky", "explicit"])
def test_tv4_gain_cases_a_to_c(inverse):
    gain, _ = filter_gain(np.array([[[4.0]]]), np.array([[[1.0]]]), np.array([[[1.0]]]), inverse)
    np.testing.assert_allclose(gain[0], [[0.8]], rtol=1e-15)
    gain, _ = filter_gain(np.diag([3.0, 7])[None], np.eye(2)[None], np.diag([3.0, 7])[None], inverse)
    np.testing.assert_allclose(gain[0], 0.5 * np.eye(2), rtol=1e-15)
    gain, _ = filter_gain(np.diag([4, 1, 1, 1, 0.25, 0.01])[None], PAPER_H[None], np.diag([1, 0.25])[None], inverse)
    expected = np.zeros((6, 2))
    expected[0, 0], expected[4, 1] = 0.8, 0.5
    np.testing.assert_allclose(gain[0], expected, rtol=1e-15, atol=1e-15)


def test_tv4_gain_case_d_three_forms_agree():
    V_eta = np.diag([1, 0.25])
    expected = [[0.625, 0.25], [0.375, -0.25], [0, 0], [0, 0], [0.0625, 0.625], [0.0325, 0.005]]
    chol, _ = filter_gain(TV4_D_VX[None], PAPER_H[None], V_eta[None], "cholesky")
    explicit, _ = filter_gain(TV4_D_VX[None], PAPER_H[None], V_eta[None], "explicit")
    posterior = np.linalg.inv(np.linalg.inv(TV4_D_VX) + PAPER_H.T @ np.linalg.inv(V_eta) @ PAPER_H)
    information = posterior @ PAPER_H.T @ np.linalg.inv(V_eta)
    np.testing.assert_allclose(chol[0], expected, atol=1e-15)
    np.testing.assert_allclose(explicit[0], expected, atol=1e-15)
    np.testing.assert_allclose(information, expected, atol=1e-14)  # two extra inversions of 6 x 6


@pytest.mark.parametrize("inverse", ["cholesky", "explicit"])
def test_tv4_gain_case_e_tends_to_inverse_of_h(inverse):
    h = np.array([[1.0, 2.0], [0.0, 1.0]])
    gain, _ = filter_gain(np.array([[[2, 0.3], [0.3, 1]]]), h[None], 1e-9 * np.eye(2)[None], inverse)
    assert np.max(np.abs(gain[0] - [[1, -2], [0, 1]])) < 1e-8


# ---------------------------------------------------------------- TV10: A5.1 weighting

def test_tv10_weighting_matrices():
    S = np.array([[[0.5, 0], [0, 0.5], [1, 0]]])
    C = np.diag([2500.0, 2500, 1])[None]
    L, LCL = estimator_gain(S, C, "none")
    np.testing.assert_allclose(L[0], [[0.4, 0, 0.8], [0, 2, 0]], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(LCL[0], np.diag([400.64, 10000]), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(L[0] @ S[0], np.eye(2), atol=1e-14)
    L, LCL = estimator_gain(S, C, "innovation")
    np.testing.assert_allclose(L[0], [[1.99980002e-4, 0, 0.999900009999], [0, 2, 0]], rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(LCL[0], np.diag([0.999900009999, 10000]), rtol=1e-11, atol=1e-9)
    np.testing.assert_allclose(LCL[0], np.linalg.inv(S[0].T @ np.linalg.inv(C[0]) @ S[0]), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(L[0] @ S[0], np.eye(2), atol=1e-14)


# ---------------------------------------------------------------- TV11 (a): one deterministic step

TV11_MODEL = linear_model("tv11", [[1, 1, 0.5], [0, 1, 1], [0, 0, 1]], ("p", "v", "a"), ("m", "m/s", "m/s^2"),
                          ("a",), [[0.01]])
TV11_MEASUREMENT = LinearMeasurement([[1, 0, 0], [0, 1, 0]])
TV11_NOISE = np.diag([100, 0.25])

TV11_EXPECTED = {
    "none": dict(L=(0.4, 0.8), w=8.4, LCL=26.17, Q=44.39, V=8.103636363636,
                 x=(104.7808132038, 104.4224489642, 2.8928649188),
                 P=(20.4983561462, 0.2448319756, 2.8046035575),
                 gain=[[0.2049835615, 0.5157801036], [0.0012894503, 0.9793279025], [-0.0098800031, 0.6692055459]]),
    "innovation": dict(L=(-0.0148735746, 1.0074367873), w=4.3549826475, LCL=4.4721120476, Q=14.4937618124,
                       V=2.6679566932, x=(105.1729335772, 104.3560499143, 1.7797658855),
                       P=(20.3644352537, 0.2409919577, 1.7254651959), gain=None),
}


def tv11_step(weighting, y=(112, 104.5), **settings):
    opts = dict(sigma_min=[0.01], weighting=weighting, forgetting=0.9)
    opts.update(settings)
    filt = AdaptiveAugmentedFilter(TV11_MODEL, TV11_MEASUREMENT, AdaptiveSettings(**opts))
    state = filt.initial_state([0, 100, 0], np.diag([25, 4, 0.25]), V_w0=[[0.04]], count0=5)
    return filt, state, filt.step(state, [y], 1.0, TV11_NOISE)


@pytest.mark.parametrize("weighting", ["none", "innovation"])
def test_tv11a_one_step(weighting):
    expected = TV11_EXPECTED[weighting]
    _, state, out = tv11_step(weighting)
    np.testing.assert_allclose(out.innovation[0], [12, 4.5], rtol=RTOL)
    F = np.array([[1, 1, 0.5], [0, 1, 1], [0, 0, 1]])
    C = TV11_MEASUREMENT.matrix @ F @ np.diag([25, 4, 0.25]) @ F.T @ TV11_MEASUREMENT.matrix.T + TV11_NOISE
    np.testing.assert_allclose(C, [[129.0625, 4.125], [4.125, 4.5]], rtol=RTOL)
    np.testing.assert_allclose(out.estimator_cov[0], C, rtol=RTOL)
    np.testing.assert_allclose(out.sensitivity[0], [[0.5], [1.0]], rtol=RTOL)
    np.testing.assert_allclose(state.count, [5.5], rtol=RTOL)
    np.testing.assert_allclose(out.L[0, 0], expected["L"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.w_hat[0, 0], expected["w"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.w_hat[0, 0] ** 2 - out.Q[0, 0, 0], expected["LCL"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.Q[0, 0, 0], expected["Q"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.V_bar[0, 0, 0], expected["V"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.V_w[0, 0, 0], expected["V"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(out.x[0], expected["x"], rtol=RTOL, atol=PRINTED_ATOL)
    np.testing.assert_allclose(np.diagonal(out.P[0]), expected["P"], rtol=RTOL, atol=PRINTED_ATOL)
    if expected["gain"] is not None:
        np.testing.assert_allclose(out.gain[0], expected["gain"], rtol=RTOL, atol=PRINTED_ATOL)
    nis = out.innovation[0] @ np.linalg.solve(out.innovation_cov[0], out.innovation[0])
    np.testing.assert_allclose(out.nis[0], nis, rtol=1e-12)


@pytest.mark.parametrize("weighting", ["none", "innovation"])
def test_tv11a_floor(weighting):
    _, _, out = tv11_step(weighting, y=(103, 101.2), forgetting=0.0, n0=0.0)
    assert out.Q[0, 0, 0] < 0
    np.testing.assert_allclose(out.V_w[0, 0, 0], 1e-4, rtol=1e-12)
    np.testing.assert_allclose(out.V_bar[0, 0, 0], out.Q[0, 0, 0], rtol=1e-12)  # memory stays raw


def test_tv11a_timing_next_uses_previous_estimate():
    _, _, same = tv11_step("none")
    _, _, nxt = tv11_step("none", timing="next")
    np.testing.assert_allclose(nxt.V_w[0, 0, 0], 0.04, rtol=1e-12)
    np.testing.assert_allclose(nxt.V_bar, same.V_bar, rtol=1e-12)
    assert not np.allclose(nxt.x, same.x)


def test_r13_literal_preset():
    settings = literal_settings([0.01])
    assert (settings.weighting, settings.forgetting, settings.n0) == ("none", 0.0, 0.0)
    assert (settings.gain_inverse, settings.timing, settings.dependent_noise, settings.joseph) == \
        ("explicit", "same", False, True)
    filt = AdaptiveAugmentedFilter(TV11_MODEL, TV11_MEASUREMENT, settings)
    state = filt.initial_state([0, 100, 0], np.diag([25, 4, 0.25]), V_w0=[[0.04]])
    out = filt.step(state, [[112, 104.5]], 1.0, TV11_NOISE)
    np.testing.assert_allclose(out.V_w[0, 0, 0], 44.39, rtol=RTOL)  # λ = 0, n_0 = 0: V̄ = Q (literal eq. 7)
    cholesky, _ = filter_gain(out.prior_cov, TV11_MEASUREMENT.matrix[None], TV11_NOISE[None], "cholesky")
    np.testing.assert_allclose(out.gain, cholesky, rtol=1e-12)


def test_projection_floor_and_ceiling_in_parameter_scale():
    V = np.array([[[4.0, 0.0], [0.0, -1.0]]])
    out = project_covariance(V, np.array([0.1, 0.2]), np.array([1.0, 1.0]))
    np.testing.assert_allclose(out[0], np.diag([1.0, 0.04]), rtol=1e-12, atol=1e-15)


# ---------------------------------------------------------------- TV3: A5.2 identity; A4 skip

TV3_X = np.array([1, 2, 3, 4, 0.5, -0.2])
TV3_W = np.array([0.01, -0.02])


@pytest.mark.parametrize("weighting", ["none", "innovation"])
def test_tv3_noise_free_w_hat_is_the_disturbance(weighting):
    model = paper_model()
    filt = AdaptiveAugmentedFilter(model, LinearMeasurement(PAPER_H), AdaptiveSettings(sigma_min=[1e-3, 1e-3],
                                                                                       weighting=weighting))
    x_true = tv3_F() @ TV3_X + tv3_F() @ model.h_a.T @ TV3_W
    np.testing.assert_allclose(x_true, [2.36, 2.401, 3.502, 3.912, 0.51, -0.22], rtol=1e-14)
    y = PAPER_H @ x_true
    state = filt.initial_state(TV3_X, 0.01 * np.eye(6))
    out = filt.step(state, y[None], 1.0, np.diag([0.01, 0.0025]))
    np.testing.assert_allclose(out.w_hat[0], TV3_W, atol=1e-14)
    # chi-hat of eq. (12) on y-tilde of eq. (10), minus h_a x(k-1), is the same number
    L = out.L[0]
    F = tv3_F()
    y_tilde = y - PAPER_H @ F @ (np.eye(6) - model.h_a.T @ model.h_a) @ TV3_X
    np.testing.assert_allclose(L @ y_tilde, [0.51, -0.22], atol=1e-14)
    np.testing.assert_allclose(L @ np.array([0.3, -0.1]), [-0.1, 0.1666666666666667], rtol=1e-12)


def test_a4_not_identifiable_step_is_skipped_and_counted():
    model = paper_model(f16=0.0)
    filt = AdaptiveAugmentedFilter(model, LinearMeasurement(PAPER_H), AdaptiveSettings(sigma_min=[1e-3, 1e-3]))
    state = filt.initial_state(np.stack([TV3_X, TV3_X]), 0.01 * np.eye(6))
    V_before = state.V_bar.copy()
    for step in (1, 2):
        out = filt.step(state, np.array([[2.4, 0.5], [2.3, 0.52]]), 1.0, np.eye(2))
        np.testing.assert_array_equal(out.skipped, [step, step])
    assert np.all(out.verdict == NOT_IDENTIFIABLE) and np.all(out.zero_influence[:, 1])
    assert np.all(np.isnan(out.Q)) and np.all(np.isnan(out.w_hat))
    np.testing.assert_array_equal(state.V_bar, V_before)
    np.testing.assert_allclose(out.V_w, V_before, rtol=1e-12)  # prior V_w0 is above the floor


def test_step_verdicts_agree_with_analysis_checker():
    rng = np.random.default_rng(3)
    H = np.broadcast_to(PAPER_H, (5, 2, 6))
    F = np.stack([tv3_F(f16) for f16 in (3.0, -1.0, 0.0, 1e-3, 6.123233995736766e-17)])
    F[:, 0, 4] += rng.normal(size=5)
    G = F[:, :, 4:]
    V_eta = np.diag([0.5, 2.0])
    code, kappa, zero = step_verdicts(H, G, np.broadcast_to(V_eta, (5, 2, 2)))
    record = check_identifiability(H=H, G=G, noise_cov=V_eta)
    np.testing.assert_array_equal(code, record.verdict_code)
    np.testing.assert_allclose(kappa, record.kappa, rtol=1e-12)
    np.testing.assert_array_equal(zero, record.zero_influence)
    np.testing.assert_array_equal(code[[2, 4]], [NOT_IDENTIFIABLE, NOT_IDENTIFIABLE])


# ---------------------------------------------------------------- TV11 (b): unbiasedness of A5.3

def test_tv11b_one_step_unbiased_monte_carlo():
    """Mean of Q over N draws = V_w within 4 standard errors (the spec's 2e6 draws scaled to N = 2e5;
    the standard errors are estimated from the draws, ≈ 1.6e-4 and 3.2e-4)."""
    N = 200_000
    rng = np.random.default_rng(2002)
    V_w = np.diag([0.04, 0.09])
    V_eta = np.diag([0.01, 0.0025])
    model = paper_model(V_w=V_w)
    F = tv3_F()
    x_prev = TV3_X + 0.1 * rng.standard_normal((N, 6))
    w = rng.multivariate_normal(np.zeros(2), V_w, size=N)
    eta = rng.multivariate_normal(np.zeros(2), V_eta, size=N)
    x_true = (x_prev + w @ model.h_a) @ F.T
    y = x_true @ PAPER_H.T + eta
    filt = AdaptiveAugmentedFilter(model, LinearMeasurement(PAPER_H), AdaptiveSettings(sigma_min=[1e-3, 1e-3]))
    state = filt.initial_state(np.broadcast_to(TV3_X, (N, 6)), 0.01 * np.eye(6))
    out = filt.step(state, y, 1.0, V_eta)
    np.testing.assert_allclose(out.estimator_cov[0], [[0.1525, 0.02], [0.02, 0.0125]], rtol=1e-12)
    LCL = np.einsum("pm,mn,qn->pq", out.L[0], out.estimator_cov[0], out.L[0])
    np.testing.assert_allclose(LCL, [[0.0125, -0.0016667], [-0.0016667, 0.0136111]], rtol=1e-4)
    second_moment = np.einsum("kp,kq->pq", out.w_hat, out.w_hat) / N
    np.testing.assert_allclose(second_moment, [[0.0525, -0.0016667], [-0.0016667, 0.1036111]], atol=2e-3)
    mean_Q = out.Q.mean(axis=0)
    standard_error = out.Q.std(axis=0) / np.sqrt(N)
    assert np.all(np.abs(mean_Q - V_w) <= 4 * standard_error), (mean_Q, standard_error)


# ---------------------------------------------------------------- A5.4 options, A2 wrapping, A8 short form, bank

def test_window_memory_is_the_mean_of_the_last_Q():
    filt = AdaptiveAugmentedFilter(TV11_MODEL, TV11_MEASUREMENT, AdaptiveSettings(sigma_min=[0.01], window=2))
    state = filt.initial_state([0, 100, 0], np.diag([25, 4, 0.25]), V_w0=[[0.04]])
    Qs = []
    for y in ([112, 104.5], [205, 104.0], [310, 106.0]):
        out = filt.step(state, [y], 1.0, TV11_NOISE)
        Qs.append(out.Q[0, 0, 0])
        np.testing.assert_allclose(out.V_bar[0, 0, 0], np.mean(Qs[-2:]), rtol=1e-12)


def test_rate_option_scales_memory_by_the_interval():
    filt = AdaptiveAugmentedFilter(TV11_MODEL, TV11_MEASUREMENT, AdaptiveSettings(
        sigma_min=[0.01], forgetting=0.0, n0=0.0, rate=True))
    state = filt.initial_state([0, 100, 0], np.diag([25, 4, 0.25]), V_w0=[[0.04]])
    T = 2.0
    out = filt.step(state, [[112, 104.5]], T, TV11_NOISE)
    np.testing.assert_allclose(out.V_bar[0, 0, 0], out.Q[0, 0, 0] / T, rtol=1e-12)
    np.testing.assert_allclose(out.V_w[0, 0, 0], out.Q[0, 0, 0], rtol=1e-12)


def test_short_form_differs_from_joseph_only_for_a_suboptimal_gain():
    _, _, joseph = tv11_step("none")
    _, _, short = tv11_step("none", joseph=False)
    np.testing.assert_allclose(short.P, joseph.P, rtol=1e-9, atol=1e-12)  # optimal gain: the forms agree
    np.testing.assert_allclose(short.x, joseph.x, rtol=1e-14)


def test_angle_innovation_is_wrapped():
    model = linear_model("angle", [[1.0, 1.0], [0.0, 1.0]], ("az", "rate"), ("rad", "rad/s"), ("rate",), [[1e-4]])
    measurement = LinearMeasurement([[1.0, 0.0]], angular=[True])
    filt = AdaptiveAugmentedFilter(model, measurement, AdaptiveSettings(sigma_min=[1e-3]))
    state = filt.initial_state([[np.pi - 0.05, 0.0]], np.diag([1e-4, 1e-4]))
    out = filt.step(state, [[-np.pi + 0.05]], 1.0, [[1e-4]])
    np.testing.assert_allclose(out.innovation[0], [0.1], rtol=1e-9)


def test_bank_equals_tracks_one_by_one_and_is_reproducible():
    from skytrack.models.augmented import ct_omega
    from skytrack.models.augmented_measurements import measurement_for

    model = ct_omega(sigma_omega=1e-3, q_accel=1.0)
    measurement = measurement_for(model, ("pos", "rdot"))
    settings = AdaptiveSettings(sigma_min=[1e-5], sigma_max=[np.radians(2.0)], forgetting=0.8)
    rng = np.random.default_rng(7)
    x0 = np.array([[30_000.0, 0.0, 0.0, 200.0, 0.01], [20_000.0, 5_000.0, -150.0, 50.0, -0.02]])
    P0 = np.diag([2500.0, 2500.0, 100.0, 100.0, 1e-4])
    V_eta = np.diag([50.0**2, 50.0**2, 1.0])
    ys = np.stack([measurement.h(model.phi(x0, float(k))) for k in range(1, 6)]) + rng.normal(size=(5, 2, 3))
    bank = AdaptiveAugmentedFilter(model, measurement, settings)
    together = bank.run(bank.initial_state(x0, P0), ys, 1.0, V_eta)
    again = bank.run(bank.initial_state(x0, P0), ys, 1.0, V_eta)
    for name in together:
        np.testing.assert_array_equal(together[name], again[name])
    for track in range(2):
        alone = bank.run(bank.initial_state(x0[track], P0), ys[:, track:track + 1], 1.0, V_eta)
        np.testing.assert_allclose(alone["x"][:, 0], together["x"][:, track], rtol=1e-12)
        np.testing.assert_allclose(alone["V_w"][:, 0], together["V_w"][:, track], rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(together["P"]) > 0)
    assert together["verdict"].shape == (5, 2) and together["skipped"].shape == (5, 2)

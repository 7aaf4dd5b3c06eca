"""Spec 004 constant-gain filters: gain rules and analysis (§3.3 C, R4) and the batched Cartesian
α–β / α–β–γ filter (R4, R20), test vectors TV5–TV9 and the VD detector threshold of TV14.

Tolerances are the spec's (relative unless marked); Monte Carlo runs are seeded per run with
``SeedSequence(seed).spawn(runs)[r]``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg as sla
from scipy import stats

from skytrack.core import linalg
from skytrack.filters import alpha_beta_gains as G
from skytrack.filters.alpha_beta import AlphaBetaFilter
from skytrack.filters.base import ListRecorder
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.registry import build_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import MotionModel, constant_acceleration, constant_velocity
from skytrack.models.polynomial import PolynomialAxis, dwna, dwpa, polynomial


def rel(actual, expected) -> float:
    """Largest elementwise relative difference; zero entries of ``expected`` are scaled by its largest entry."""
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    assert actual.shape == expected.shape
    scale = np.where(expected != 0, np.abs(expected), np.max(np.abs(expected)))
    return float(np.max(np.abs(actual - expected) / scale))


def gens(seed, runs):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)]


def riccati_gain(F, Q, R, steps=5000):
    """Steady-state KF gain by iterating the Riccati recursion from P⁻ = Q until it stops changing."""
    P = Q.copy()
    for _ in range(steps):
        S = P[0, 0] + R
        K = P[:, 0] / S
        new = F @ (P - np.outer(K, P[0])) @ F.T + Q
        if np.max(np.abs(new - P)) <= 1e-16 * np.max(np.abs(P)):
            break
        P = new
    return P[:, 0] / (P[0, 0] + R)


def cycle(filt, model, state, z, R, dt):
    pred = filt.predict(state, np.full(len(state), dt))
    inn = filt.innovate(pred, z, model, {"R": R})
    return pred, inn, filt.update(pred, z, inn)[0]


# ---------------------------------------------------------------------------- TV5
TV5 = [(0.5, 0.2, 0.428571428571, 0.714285714286, 5.714285714286),
       (0.5, 1 / 6, 0.411764705882, 0.647058823529, 3.921568627451),
       (0.75, 0.5, 0.666666666667, 1.666666666667, 33.333333333333)]


@pytest.mark.parametrize("alpha,beta,filtered,predicted,velocity", TV5)
def test_tv5_noise_only_variance_ratios_closed_form_and_lyapunov(alpha, beta, filtered, predicted, velocity):
    ratios = G.variance_ratios(alpha, beta, 0.1)
    assert rel([ratios.filtered_position, ratios.predicted_position, ratios.velocity], [filtered, predicted, velocity]) <= 1e-9
    P, P_pred = G.steady_state_covariance(alpha, beta, None, 0.1, R=1.0)
    assert rel([P[0, 0], P_pred[0, 0], P[1, 1]], [filtered, predicted, velocity]) <= 1e-9
    # the Lyapunov solution satisfies its equation: P = A P A^T + K K^T
    A = G.error_transition(alpha, beta, None, 0.1)
    K = G.gain_vector(alpha, beta, None, 0.1)
    assert np.max(np.abs(A @ P @ A.T + np.outer(K, K) - P)) <= 1e-12 * np.max(np.abs(P))


# ---------------------------------------------------------------------------- TV6
TV6_AB = [((0.5, 0.2), 0.707106781187, True), ((1.0, 1.9), 0.9, True), ((1.0, 2.0), 1.0, False),
          ((1.0, 2.1), 1.1, False), ((0.5, 2.9), 0.707106781187, True), ((0.5, 3.1), 1.174165738677, False),
          ((1.5, 1.2), 1.138986691903, False)]
TV6_ABG = [((0.5, 0.2, 0.05), 0.826265750920, True), ((0.5, 0.2, 0.26), 0.996705772700, True),
           ((0.5, 0.2, 0.28), 1.006395328655, False), ((1.0, 1.0, 2.1), 0.724568837309, True)]


@pytest.mark.parametrize("gains,radius,stable", TV6_AB + TV6_ABG)
def test_tv6_spectral_radius_and_region(gains, radius, stable):
    assert abs(G.spectral_radius(*gains) - radius) <= 1e-9
    assert G.is_stable(*gains) is stable
    # radius independent of T in the beta/T, gamma/(2T^2) units
    args = (tuple(gains) + (None,))[:3]
    for T in (0.1, 4.0):
        assert abs(np.max(np.abs(np.linalg.eigvals(G.error_transition(*args, period=T)))) - radius) <= 1e-9
    if not stable:
        with pytest.raises(ValueError, match="unstable"):
            G.check_stable(*gains)


def test_tv6_characteristic_polynomials():
    a, b, g = 0.5, 0.2, 0.05
    assert np.allclose(np.poly(G.error_transition(a, b)), [1, a + b - 2, 1 - a], rtol=0, atol=1e-14)
    assert np.allclose(np.poly(G.error_transition(a, b, g)), [1, a + b + g / 4 - 3, 3 - 2 * a - b + g / 4, a - 1],
                       rtol=0, atol=1e-14)


@pytest.mark.parametrize("order", [2, 3])
def test_tv6_region_agrees_with_spectral_radius_on_random_gains(order):
    """2·10⁵ uniform samples over α ∈ [−0.5, 2.5], β ∈ [−0.5, 4.5], γ ∈ [−0.5, 8]: 0 mismatches."""
    rng = np.random.default_rng(np.random.SeedSequence(6).spawn(2)[order - 2])
    count = 200_000
    alpha, beta = rng.uniform(-0.5, 2.5, count), rng.uniform(-0.5, 4.5, count)
    gamma = rng.uniform(-0.5, 8.0, count) if order == 3 else None
    region = G.is_stable(alpha, beta, gamma)
    radius = G.spectral_radius(alpha, beta, gamma)
    assert int(np.sum(region != (radius < 1.0))) == 0
    assert 0.01 < region.mean() < 0.5  # both sides are well represented


# ---------------------------------------------------------------------------- TV7, TV8
TV7 = [(0.1, 0.36, 0.08), (0.5, 0.628373457205, 0.304805898399), (1.0, 0.75, 0.5),
       (2.0, 0.854101966250, 0.763932022500)]
TV8 = [(0.01, 0.350066775836, 0.075129003725, 0.016123687223), (0.1, 0.604758751248, 0.275753887886, 0.125736430481),
       (0.5, 0.795373662666, 0.599826965403, 0.452356427316), (1.0, 0.864317940854, 0.797962290433, 0.736700913930)]


@pytest.mark.parametrize("T", [0.1, 1.0, 4.0])
@pytest.mark.parametrize("lam,alpha,beta", TV7)
def test_tv7_kalata_dwna_closed_form_dare_riccati(lam, alpha, beta, T):
    a, b = G.kalata_alpha_beta(lam)
    assert rel([a, b], [alpha, beta]) <= 1e-10
    r = np.sqrt(lam * lam + 8 * lam)  # the spec's printed closed form
    assert rel([a, b], [-(lam * lam + 8 * lam - (lam + 4) * r) / 8, (lam * lam + 4 * lam - lam * r) / 4]) <= 1e-12
    assert abs(b - (2 * (2 - a) - 4 * np.sqrt(1 - a))) <= 1e-12 and abs(lam**2 - b * b / (1 - a)) <= 1e-12 * lam**2
    sigma_v = 7.0
    sigma_w = lam * sigma_v / T**2
    steady = G.kalata_steady_state(2, T, sigma_w, sigma_v)
    assert rel(steady.gains(T), [a, b]) <= 1e-10
    F, Q = G.polynomial_transition(2, T), G.kalata_noise(2, T, sigma_w)
    assert rel(riccati_gain(F, Q, sigma_v**2) * [1, T], [a, b]) <= 1e-10


@pytest.mark.parametrize("T", [0.1, 1.0, 4.0])
@pytest.mark.parametrize("lam,alpha,beta,gamma", TV8)
def test_tv8_kalata_dwpa_root_finder_dare_riccati(lam, alpha, beta, gamma, T):
    a, b, g = G.kalata_alpha_beta_gamma(lam)
    assert rel([a, b, g], [alpha, beta, gamma]) <= 1e-9
    # the defining relations hold at the root (brentq tol 1e-14)
    assert abs(b - (2 * (2 - a) - 4 * np.sqrt(1 - a))) <= 1e-13
    assert abs(g - b * b / a) <= 1e-13 and abs(lam * lam - g * g / (4 * (1 - a))) <= 1e-12 * lam * lam
    sigma_v = 3.0
    sigma_w = lam * sigma_v / T**2
    assert rel(G.kalata_steady_state(3, T, sigma_w, sigma_v).gains(T), [a, b, g]) <= 1e-9
    F, Q = G.polynomial_transition(3, T), G.kalata_noise(3, T, sigma_w)
    assert rel(riccati_gain(F, Q, sigma_v**2) * [1, T, 2 * T * T], [a, b, g]) <= 1e-9


def test_kalata_vectorised_and_monotone():
    lam = np.geomspace(1e-4, 1e3, 30)
    a2, b2 = G.kalata_alpha_beta(lam)
    a3, b3, g3 = G.kalata_alpha_beta_gamma(lam)
    for values in (a2, b2, a3, b3, g3):
        assert np.all(np.diff(values) > 0)
    assert np.all(G.is_stable(a2, b2)) and np.all(G.is_stable(a3, b3, g3))
    # the inverse relations go through 1 - alpha (~4e-6 at lambda = 1000): relative error ~ eps / (1 - alpha)
    assert rel(G.equivalent_tracking_index(a2, b2), lam) <= 1e-10
    assert rel(G.kalata_beta_from_alpha(a2), b2) <= 1e-10


# ---------------------------------------------------------------------------- TV9, start-up
def test_tv9_benedict_bordner_and_startup_gains():
    assert abs(G.benedict_bordner_beta(0.5) - 1 / 6) <= 1e-15
    alpha, beta = G.startup_gains(np.arange(1, 6))
    assert np.allclose(alpha, [1, 1, 5 / 6, 0.7, 0.6], rtol=0, atol=1e-15)
    assert np.allclose(beta, [3, 1, 1 / 2, 0.3, 0.2], rtol=0, atol=1e-15)
    # switch at the first k with alpha_k <= alpha: alpha = 0.5 -> k = 7 (alpha_6 = 11/21, alpha_7 = 13/28)
    assert G.startup_length(0.5) == 7 and G.startup_length(0.6) == 5 and G.startup_length(1.0) == 1


def least_squares(times, z, degree):
    """Polynomial least-squares fit evaluated at the last time: position, velocity(, acceleration)."""
    c = np.polyfit(times - times[-1], z, degree)[::-1]
    return np.array([c[0], c[1]] if degree == 1 else [c[0], c[1], 2 * c[2]])


@pytest.mark.parametrize("order", [2, 3])
def test_tv9_startup_estimate_is_the_least_squares_fit_for_any_prior(order):
    """α–β: line through all k >= 2 measurements; α–β–γ: parabola through all k >= 3 (position, slope, curvature)."""
    T, steps = 0.7, 14
    motion = polynomial(1, order, "continuous", 1.0)
    gains_ = {"gain_rule": "benedict-bordner", "alpha": 0.2} if order == 2 else {"gain_rule": "critically-damped", "theta": 0.85}
    filt = build_filter("alpha-beta", motion, period=T, startup=True, **gains_)
    assert filt._startup_length[0] > steps  # every measurement below uses start-up gains
    model = ConvertedPositionModel(1, order)
    rng = np.random.default_rng(9)
    times = T * np.arange(1, steps + 1)
    z = 50.0 + 12.0 * times - 0.8 * times**2 + rng.normal(0.0, 3.0, steps)
    priors = np.array([[5.0, -3.0, 2.0][:order], [-400.0, 90.0, -7.0][:order]])
    state = filt.initiate(priors, np.broadcast_to(np.eye(order) * 1e4, (2, order, order)).copy())
    R = np.full((2, 1, 1), 9.0)
    for k in range(1, steps + 1):
        _, _, state = cycle(filt, model, state, np.full((2, 1), z[k - 1]), R, T)
        if k >= order:
            expected = least_squares(times[:k], z[:k], order - 1)
            for row in range(2):
                assert rel(state.x[row], expected) <= 1e-9, (k, row)


def test_tv9_startup_exact_on_noise_free_cv_and_switches_to_steady_gains():
    T = 1.0
    filt = build_filter("alpha-beta", constant_velocity(2, 1.0), gain_rule="benedict-bordner", alpha=0.5,
                        period=T, startup=True)
    filt.recorder = ListRecorder()
    model = ConvertedPositionModel(2, 2)
    truth = lambda t: np.array([[100.0 + 30.0 * t, 30.0, -50.0 - 12.0 * t, -12.0]])  # noqa: E731
    state = filt.initiate(np.array([[0.0, 0.0, 0.0, 0.0]]), np.eye(4)[None] * 1e6)
    for k in range(1, 10):
        _, _, state = cycle(filt, model, state, truth(k)[:, [0, 2]], np.eye(2)[None] * 25.0, T)
        if k >= 2:
            assert np.max(np.abs(state.x - truth(k))) <= 1e-9 * 400
    recorded = [values["gain"][0] for _, values in filt.recorder.channel("gain")]
    start = [np.array(G.startup_gains(k)) for k in range(1, 7)]
    for k in range(1, 7):  # k = 1..6 start-up, from k = 7 the steady Benedict-Bordner gains
        assert np.allclose(recorded[k - 1][[0, 1], 0], start[k - 1] * [1, 1 / T], rtol=1e-15)
    for k in (7, 8, 9):
        assert np.allclose(recorded[k - 1][[0, 1], 0], [0.5, 1 / 6 / T], rtol=1e-15)
        assert np.allclose(recorded[k - 1][[2, 3], 1], [0.5, 1 / 6 / T], rtol=1e-15)
        assert recorded[k - 1][0, 1] == 0.0 and recorded[k - 1][2, 0] == 0.0


def test_startup_covariance_is_the_error_covariance_of_the_gains_used():
    """During start-up P is the Joseph covariance of the start-up gains: after two measurements with
    no process noise it is the two-point least-squares covariance σ²[[1, 1/T], [1/T, 2/T²]] whatever P₀."""
    T, var = 2.0, 16.0
    filt = AlphaBetaFilter(polynomial(1, 2, "continuous", 0.0), 0.4, G.benedict_bordner_beta(0.4), period=T,
                           startup=True)
    model = ConvertedPositionModel(1, 2)
    state = filt.initiate(np.zeros((2, 2)), np.array([np.diag([1e2, 1e1]), np.diag([1e8, 1e6])]))
    for _ in range(2):
        _, _, state = cycle(filt, model, state, np.zeros((2, 1)), np.full((2, 1, 1), var), T)
    expected = var * np.array([[1, 1 / T], [1 / T, 2 / T**2]])
    assert rel(state.P, np.broadcast_to(expected, (2, 2, 2))) <= 1e-9
    assert not state.steady.any()


# ---------------------------------------------------------------------------- critically damped, lags
@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("theta", [0.0, 0.3, 0.8])
def test_critically_damped_gains_put_every_pole_at_theta(order, theta):
    gains_ = G.critically_damped_gains(theta, order)
    A = G.error_transition(*gains_) if order == 3 else G.error_transition(*gains_, None)
    assert np.allclose(np.poly(A), np.poly(np.full(order, theta)), rtol=0, atol=1e-13)


TV4 = [(0.5, 0.2, 0.1, 30.0, 1.5, 0.75, 6.0), (0.5, 0.2, 1.0, 30.0, 150.0, 75.0, 60.0),
       (0.3, 9 / 140, 0.1, 50.0, 7.777777777778, 5.444444444444, 20.833333333333)]


@pytest.mark.parametrize("alpha,beta,T,A,predicted,filtered,velocity", TV4)
def test_tv4_lag_closed_forms_and_cartesian_filter(alpha, beta, T, A, predicted, filtered, velocity):
    lags = G.steady_state_lags(alpha, beta, T, A)
    assert rel([lags.predicted_position, lags.filtered_position, lags.velocity], [predicted, filtered, velocity]) <= 1e-9
    # the 2-D Cartesian filter on a constant acceleration (A on x, -A/2 on y), exact start
    filt = build_filter("alpha-beta", constant_velocity(2, 1.0), gain_rule="fixed", alpha=alpha, beta=beta, period=T)
    model = ConvertedPositionModel(2, 2)
    acc = np.array([A, -A / 2])
    state = filt.initiate(np.array([[1000.0, -600.0, 500.0, 40.0]]), np.eye(4)[None])
    for k in range(1, 401):
        t = k * T
        pos = np.array([1000.0 - 600 * t, 500.0 + 40 * t]) + acc * t * t / 2
        pred, _, state = cycle(filt, model, state, pos[None], np.eye(2)[None], T)
    vel = np.array([-600.0, 40.0]) + acc * t
    scale = acc / A
    assert rel(pos - pred.x[0, [0, 2]], predicted * scale) <= 1e-9
    assert rel(pos - state.x[0, [0, 2]], filtered * scale) <= 1e-9
    assert rel(vel - state.x[0, [1, 3]], velocity * scale) <= 1e-9


# ---------------------------------------------------------------------------- the Cartesian filter
def test_cartesian_filter_is_the_per_axis_recursion_with_per_axis_gains():
    """3-D α–β–γ, Kalata gains with a different tracking index per axis, against a plain loop of
    x⁻ = F x, x = x⁻ + K_i (z_i − x⁻_0) per axis."""
    T = 0.5
    filt = build_filter("alpha-beta", constant_acceleration(3, 2.0), gain_rule="kalata",
                        tracking_index=[0.05, 0.4, 2.0], period=T)
    K = np.array([G.gain_vector(*G.kalata_alpha_beta_gamma(lam), period=T) for lam in (0.05, 0.4, 2.0)])
    assert np.allclose(filt.gains, K, rtol=1e-15)
    F = G.polynomial_transition(3, T)
    model = ConvertedPositionModel(3, 3)
    rng = np.random.default_rng(21)
    x0 = rng.normal(0.0, 100.0, (4, 9))
    state = filt.initiate(x0, np.broadcast_to(np.eye(9), (4, 9, 9)).copy())
    ref = x0.reshape(4, 3, 3).copy()
    for _ in range(25):
        z = rng.normal(0.0, 500.0, (4, 3))
        _, _, state = cycle(filt, model, state, z, np.broadcast_to(np.eye(3) * 100.0, (4, 3, 3)).copy(), T)
        ref = np.einsum("ij,raj->rai", F, ref)
        ref = ref + K[None] * (z - ref[:, :, 0])[:, :, None]
    assert np.max(np.abs(state.x - ref.reshape(4, 9))) <= 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("order", [2, 3])
def test_steady_state_covariance_of_kalata_gains_is_the_dare_solution(order):
    """R4/R20: with Kalata gains on the DWNA/DWPA model (σ_w, σ_v, T), the covariance after an update
    is the KF's steady filtered P, after a predict by T the predicted P⁻, and S = P⁻₁₁ + σ_v²."""
    T, sigma_w, sigma_v = 0.5, 3.0, 20.0
    motion = (dwna if order == 2 else dwpa)(2, sigma_w)
    filt = build_filter("alpha-beta", motion, tracking_index=G.tracking_index(sigma_w, sigma_v, T), period=T)
    steady = G.kalata_steady_state(order, T, sigma_w, sigma_v)
    model = ConvertedPositionModel(2, order)
    R = np.broadcast_to(np.eye(2) * sigma_v**2, (3, 2, 2)).copy()
    state = filt.initiate(np.zeros((3, 2 * order)), np.broadcast_to(np.eye(2 * order) * 1e4, (3, 2 * order, 2 * order)).copy())
    _, _, state = cycle(filt, model, state, np.ones((3, 2)), R, T)
    assert state.steady.all()
    blockdiag = lambda B: sla.block_diag(B, B)  # noqa: E731
    assert rel(state.estimate().P, np.broadcast_to(blockdiag(steady.filtered), state.P.shape)) <= 1e-9
    pred = filt.predict(state, np.full(3, T))
    assert rel(pred.estimate().P, np.broadcast_to(blockdiag(steady.predicted), state.P.shape)) <= 1e-9
    inn = filt.innovate(pred, np.ones((3, 2)), model, {"R": R})
    assert rel(np.diagonal(inn.S, axis1=1, axis2=2), np.full((3, 2), steady.innovation_variance)) <= 1e-9
    assert np.max(np.abs(inn.S[:, 0, 1])) <= 1e-9 * steady.innovation_variance


def test_steady_state_covariance_with_correlated_r_and_per_axis_gains_solves_the_full_lyapunov_equation():
    T = 1.5
    motion = MotionModel([PolynomialAxis(2, "piecewise_constant", 2.0), PolynomialAxis(2, "piecewise_constant", 5.0)])
    filt = build_filter("alpha-beta", motion, gain_rule="benedict-bordner", alpha=[0.3, 0.7], period=T)
    R = np.array([[[400.0, 300.0], [300.0, 900.0]]])
    state = filt.initiate(np.zeros((1, 4)), np.eye(4)[None] * 1e3)
    model = ConvertedPositionModel(2, 2)
    pred, _, state = cycle(filt, model, state, np.array([[3.0, -4.0]]), R, T)
    # the full 4x4 equation P = A P A^T + (I-KH) Q (I-KH)^T + K R K^T
    K = np.zeros((4, 2))
    K[[0, 1], 0] = filt.gains[0]
    K[[2, 3], 1] = filt.gains[1]
    H = np.zeros((2, 4))
    H[[0, 1], [0, 2]] = 1.0
    F, Q = motion.F(T), motion.Q(T)
    I_KH = np.eye(4) - K @ H
    P = sla.solve_discrete_lyapunov(I_KH @ F, I_KH @ Q @ I_KH.T + K @ R[0] @ K.T)
    assert rel(state.P[0], P) <= 1e-9
    # predict by T: the precomputed steady P⁻; by another step: F P F^T + Q of that step
    assert rel(filt.predict(state, np.array([T])).P[0], F @ P @ F.T + Q) <= 1e-9
    half = filt.predict(state, np.array([T / 2]))
    assert rel(half.P[0], motion.F(T / 2) @ P @ motion.F(T / 2).T + motion.Q(T / 2)) <= 1e-9
    assert np.linalg.eigvalsh(state.P[0]).min() > 0


@pytest.mark.parametrize("order", [2, 3])
def test_nees_and_nis_with_the_steady_state_covariance_are_consistent(order):
    """Truth from the motion model at T = period, constant R, non-Kalata gains (Benedict–Bordner /
    critically damped): after the transient, mean NEES over 400 runs × 50 scans and mean NIS lie in the
    two-sided 99 % chi-square interval of one scan's average (conservative for the time average)."""
    runs, steps, T = 400, 120, 1.0
    if order == 2:
        motion, options = dwna(2, 2.0), {"gain_rule": "benedict-bordner", "alpha": 0.5}
    else:
        motion, options = constant_acceleration(2, 0.5), {"gain_rule": "critically-damped", "theta": 0.6}
    filt = build_filter("alpha-beta", motion, period=T, **options)
    n, model = motion.dim, ConvertedPositionModel(2, order)
    R = np.diag([30.0**2, 50.0**2])
    F, Q = motion.F(T), motion.Q(T)
    w, U = np.linalg.eigh(Q)
    Qs = U * np.sqrt(np.clip(w, 0, None))
    noise_w, noise_v = [], []
    for g in gens(404, runs):
        noise_w.append(g.standard_normal((steps, n)))
        noise_v.append(g.standard_normal((steps, 2)))
    noise_w, noise_v = np.array(noise_w), np.array(noise_v)
    truth = np.zeros((runs, n))
    truth[:, motion.velocity_index] = [200.0, -100.0]
    state = filt.initiate(truth.copy(), np.broadcast_to(np.eye(n), (runs, n, n)).copy())
    Rs = np.broadcast_to(R, (runs, 2, 2)).copy()
    nees, nis = [], []
    for k in range(steps):
        truth = truth @ F.T + noise_w[:, k] @ Qs.T
        z = truth[:, motion.position_index] + noise_v[:, k] * np.sqrt(np.diag(R))
        _, inn, state = cycle(filt, model, state, z, Rs, T)
        if k >= steps - 50:
            e = truth - state.x
            nees.append(np.mean(np.einsum("ki,ki->k", e, np.linalg.solve(state.P, e[..., None])[..., 0])))
            nis.append(np.mean(inn.d2))
    for value, dim in ((np.mean(nees), n), (np.mean(nis), 2)):
        lo, hi = stats.chi2.ppf([0.005, 0.995], runs * dim) / runs
        assert lo <= value <= hi, (value, lo, hi)


def test_zero_dt_keeps_the_steady_state_and_backwards_prediction_inverts():
    filt = build_filter("alpha-beta", constant_velocity(2, 1.0), period=2.0)
    model = ConvertedPositionModel(2, 2)
    state = filt.initiate(np.array([[0.0, 10.0, 0.0, 5.0]]), np.eye(4)[None] * 100)
    _, _, state = cycle(filt, model, state, np.array([[1.0, 2.0]]), np.eye(2)[None] * 9, 2.0)
    same = filt.predict(state, np.zeros(1))
    assert same.steady.all() and np.array_equal(same.x, state.x) and rel(same.P, state.P) <= 1e-15
    there_and_back = filt.predict(filt.predict(state, np.array([3.0])), np.array([-3.0]))
    assert np.max(np.abs(there_and_back.x - state.x)) <= 1e-12 * 100


def test_recorder_gain_channel_and_inactive_recorder_changes_nothing():
    filt = build_filter("alpha-beta", constant_velocity(3, 1.0), gain_rule="fixed", alpha=0.6, beta=0.3, period=0.5)
    model = ConvertedPositionModel(3, 2)
    state = filt.initiate(np.zeros((5, 6)), np.broadcast_to(np.eye(6), (5, 6, 6)).copy())
    pred = filt.predict(state, np.full(5, 0.5))
    z = np.arange(15.0).reshape(5, 3)
    inn = filt.innovate(pred, z, model, {"R": np.broadcast_to(np.eye(3), (5, 3, 3)).copy()})
    plain = filt.update(pred, z, inn)[0]
    filt.recorder = ListRecorder()
    recorded = filt.update(pred, z, inn)[0]
    assert np.array_equal(plain.x, recorded.x) and np.array_equal(plain.P, recorded.P)
    (rows, values), = filt.recorder.channel("gain")
    assert np.array_equal(rows, np.arange(5)) and values["gain"].shape == (5, 6, 3)
    expected = np.zeros((6, 3))
    for axis in range(3):
        expected[2 * axis: 2 * axis + 2, axis] = [0.6, 0.3 / 0.5]
    assert np.array_equal(values["gain"], np.broadcast_to(expected, (5, 6, 3)))


def test_multiply_adds_of_a_steady_cycle_are_fewer_than_the_kalman_filter():
    """R22 counting: a steady α–β–γ cycle (predict by T, innovate, update) costs fewer multiply-adds
    than the Kalman filter's reference path on the same 3-D model, and is counted (non-zero)."""
    motion = constant_acceleration(3, 1.0)
    model = ConvertedPositionModel(3, 3)
    counts = {}
    for name, filt in (("alpha-beta", build_filter("alpha-beta", motion, period=1.0)),
                       ("kalman", KalmanFilter(motion, compiled=False))):
        state = filt.initiate(np.zeros((4, 9)), np.broadcast_to(np.eye(9) * 100, (4, 9, 9)).copy())
        R = np.broadcast_to(np.eye(3) * 25, (4, 3, 3)).copy()
        _, _, state = cycle(filt, model, state, np.ones((4, 3)), R, 1.0)
        with linalg.counting() as ops:
            cycle(filt, model, state, np.ones((4, 3)), R, 1.0)
        counts[name] = ops.madds
    assert 0 < counts["alpha-beta"] < counts["kalman"] / 5, counts


# ---------------------------------------------------------------------------- bad configuration
BAD = [
    (dict(gain_rule="fixed", alpha=1.0, beta=2.5), "unstable"),
    (dict(gain_rule="fixed", alpha=0.5, beta=0.2, gamma=0.3), "gamma"),
    (dict(gain_rule="benedict-bordner", alpha=1.2), "alpha must be in"),
    (dict(gain_rule="benedict-bordner", alpha=0.5, beta=0.1), "does not take"),
    (dict(gain_rule="fixed", alpha=0.5), "needs"),
    (dict(gain_rule="simplex"), "gain_rule"),
    (dict(gain_rule="kalata", tracking_index=-1.0), "tracking_index"),
    (dict(gain_rule="critically-damped", theta=1.0), "theta"),
    (dict(gain_rule="benedict-bordner", alpha=[0.5, 0.5, 0.5]), "per axis"),
    (dict(period=0.0), "period"),
    (dict(gain_rule="fixed", alpha=1.5, beta=0.4, startup=True), "startup"),
]


@pytest.mark.parametrize("options,message", BAD)
def test_bad_configuration_is_a_value_error_naming_the_option(options, message):
    with pytest.raises(ValueError, match=message):
        build_filter("alpha-beta", constant_velocity(2, 1.0), **options)


def test_bad_motion_and_measurement_models():
    with pytest.raises(ValueError, match="order"):
        build_filter("alpha-beta", polynomial(2, 1, "continuous", 1.0))
    with pytest.raises(ValueError, match="benedict-bordner"):
        build_filter("alpha-beta", constant_acceleration(2, 1.0), gain_rule="benedict-bordner", alpha=0.5)
    filt = build_filter("alpha-beta", constant_velocity(2, 1.0))
    state = filt.initiate(np.zeros((1, 4)), np.eye(4)[None])
    doppler = ConvertedPositionModel(2, 2, range_rate_sigma=1.0)
    context = {"R": np.eye(2)[None], "has_range_rate": np.array([False]), "sensor_position": np.zeros((1, 3)),
               "rotation": np.eye(3)[None], "sensor_velocity": np.zeros((1, 3))}
    with pytest.raises(ValueError, match="position"):
        filt.innovate(state, np.zeros((1, 3)), doppler, context)


# ---------------------------------------------------------------------------- VD detector (TV14)
@pytest.mark.parametrize("n_z,rho,p_fa,d,threshold,decimals", [
    (1, 0.8, 0.01, 9, 12.036663519, 9), (2, 0.8, 0.01, 18, 19.336280964, 9), (3, 0.8, 0.01, 27, 26.090523403, 9),
    (2, 0.9, 0.001, 38, 37.212046, 6)])
def test_tv14_detector_threshold(n_z, rho, p_fa, d, threshold, decimals):
    """Values as printed (to their last decimal); c = 1/(1+ρ) = 0.526315789 for ρ = 0.9."""
    c, dof = G.detector_scale_dof(n_z, rho)
    assert abs(c - 1 / (1 + rho)) <= 1e-15 and abs(dof - d) <= 1e-12
    assert abs(G.detector_threshold(n_z, rho, p_fa) - threshold) <= 0.5 * 10.0**-decimals
    assert G.detector_window(0.8) == 5 and G.detector_window(0.9) == 10


@pytest.mark.parametrize("n_z", [1, 2, 3])
def test_tv14_stationary_exceedance_under_white_innovations(n_z):
    """u_k = 0.8 u_{k−1} + ε_k, ε ~ χ²_{n_z}: exceedance of the P_fa = 0.01 threshold in [0.010, 0.016]
    over 2·10⁶ stationary samples (4000 runs × 500 scans after 50 scans of burn-in, ρ⁵⁰ ≈ 1.4e−5)."""
    runs, burn, steps = 4000, 50, 500
    eps = np.array([np.sum(g.standard_normal((burn + steps, n_z)) ** 2, axis=1) for g in gens(1400 + n_z, runs)])
    threshold = G.detector_threshold(n_z, 0.8, 0.01)
    u = np.zeros(runs)
    above = 0
    for k in range(burn + steps):
        u = 0.8 * u + eps[:, k]
        if k >= burn:
            above += int(np.sum(u > threshold))
    assert 0.010 <= above / (runs * steps) <= 0.016


def test_detector_bad_configuration():
    for args, message in (((1, 1.0, 0.01), "rho"), ((0, 0.8, 0.01), "n_z"), ((1, 0.8, 0.0), "p_fa")):
        with pytest.raises(ValueError, match=message):
            G.detector_threshold(*args)

"""Spec 004 R1 motion models: polynomial orders 1-4 with three noise variants, Van Loan and
known-input discretisation, Singer (reused from spec 000) against them, coordinated turn CT(omega)
in the order-2 and order-3 layouts, m = 3 embedding (TV12 and the identities of §3.3 B)."""

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm
from scipy.stats import chi2

from skytrack.filters.kalman import KalmanFilter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.discretize import (
    coordinated_turn_generator,
    input_response,
    polynomial_generator,
    singer_generator,
    singer_input,
    van_loan,
)
from skytrack.models.embedding import EmbeddedAxis, embed
from skytrack.models.motion import (
    ConstantAccelerationAxis,
    ConstantVelocityAxis,
    MotionModel,
    SingerAxisModel,
    constant_velocity,
    singer,
)
from skytrack.models.polynomial import NOISE_VARIANTS, PolynomialAxis, dwna, dwpa, polynomial
from skytrack.models.turn import SMALL_TURN, CoordinatedTurn, coordinated_turn, turn_coefficients

STEPS = np.array([1e-4, 0.05, 0.37, 1.0, 4.0, 12.5, 60.0])


def close(actual, expected, rel, floor=0.0) -> bool:
    """Elementwise |a - e| <= rel * |e| + floor (same shapes)."""
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    return actual.shape == expected.shape and bool(np.all(np.abs(actual - expected) <= rel * np.abs(expected) + floor))


def assert_printed(actual, printed: list[str]):
    """Agreement with numbers printed in the spec to their last printed digit (half a unit)."""
    for value, text in zip(np.ravel(actual), printed):
        mantissa = text.lower().split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(text.lower().split("e")[1]) if "e" in text.lower() else 0
        assert abs(value - float(text)) <= 0.5 * 10.0 ** (exponent - decimals) * (1 + 1e-9), (value, text)


def singer_closed_form_q(tau, sigma, T):
    """Singer (1970) closed form of §3.3 B, written out independently of the library."""
    k, q = 1.0 / tau, 2.0 * sigma**2 / tau
    E1, E2 = math.exp(-k * T), math.exp(-2 * k * T)
    q11 = q / (2 * k**5) * (1 - E2 + 2 * k * T + 2 * k**3 * T**3 / 3 - 2 * k**2 * T**2 - 4 * k * T * E1)
    q12 = q / (2 * k**4) * (E2 + 1 - 2 * E1 + 2 * k * T * E1 - 2 * k * T + k**2 * T**2)
    q13 = q / (2 * k**3) * (1 - E2 - 2 * k * T * E1)
    q22 = q / (2 * k**3) * (4 * E1 - 3 - E2 + 2 * k * T)
    q23 = q / (2 * k**2) * (E2 + 1 - 2 * E1)
    q33 = q / (2 * k) * (1 - E2)
    return np.array([[q11, q12, q13], [q12, q22, q23], [q13, q23, q33]])


# ---------------------------------------------------------------------------- TV12 Singer
TV12_SINGER_F = [["1", "1", "0.491769800286"], ["0", "1", "0.975411509986"], ["0", "0", "0.951229424501"]]
TV12_SINGER_Q = [["4.377201258003", "10.882689141282", "14.270225028849"],
                 ["10.882689141282", "28.900788082727", "42.814242621568"],
                 ["14.270225028849", "42.814242621568", "85.646323767636"]]


def test_tv12_singer_van_loan_matches_spec_quadrature_and_spec000_model():
    """tau = 20, sigma_m = 30, T = 1: Van Loan = TV12 numbers, = adaptive quadrature of
    int e^{At} L q L^T e^{A^T t} dt (rel 1e-12), = spec 000's SingerAxisModel (rel 1e-12),
    = the Singer closed form (rel 1e-8)."""
    A, L, qc = singer_generator(20.0, 30.0)
    assert qc == pytest.approx(2 * 30.0**2 / 20.0, rel=1e-15)
    F, Q = van_loan(A, L, qc, 1.0)
    expected_F = np.array(TV12_SINGER_F, dtype=float)
    expected_Q = np.array(TV12_SINGER_Q, dtype=float)
    assert_printed(F, sum(TV12_SINGER_F, []))
    assert_printed(Q, sum(TV12_SINGER_Q, []))
    assert close(Q, expected_Q, 1e-12)
    assert close(F, expected_F, 1e-12)

    integrand = lambda s: expm(A * s) @ L @ L.T @ expm(A.T * s) * qc  # noqa: E731
    Q_quad, _ = quad_vec(integrand, 0.0, 1.0, epsrel=1e-14, epsabs=0.0)
    assert close(Q, Q_quad, 1e-12)

    model = SingerAxisModel(20.0, 30.0, "exact")
    assert close(model.F(1.0), F, 1e-12, floor=1e-15)
    assert close(model.Q(1.0), Q, 1e-12)
    assert close(singer_closed_form_q(20.0, 30.0, 1.0), Q, 1e-8)


@pytest.mark.parametrize("tau, T, diagonal", [
    (5.0, 5.0, ["33645.160543664", "7564.105832609", "778.198245088"]),
    (60.0, 0.1, ["1.498611937e-05", "9.987509716e-03", "2.995005551"]),
])
def test_tv12_singer_q_diagonal(tau, T, diagonal):
    """TV12 Singer Q diagonals (sigma_m = 30) by Van Loan and by spec 000's model, rel 1e-9."""
    expected = np.array([float(v) for v in diagonal])
    _, Q = van_loan(*singer_generator(tau, 30.0), T)
    assert close(np.diag(Q), expected, 1e-9)
    assert close(np.diag(SingerAxisModel(tau, 30.0).Q(T)), expected, 1e-9)


@pytest.mark.parametrize("tau, T, printed", [
    (10.0, 1.0, ["0.162581964", "0.4837418036", "0.9516258196"]),
    (30.0, 0.1, ["1.665279e-04", "4.9944491e-03", "0.0998335184"]),
])
def test_tv12_singer_input_response(tau, T, printed):
    """Singer input B (§3.3 B): library (series / closed form) = augmented expm rel 1e-9 and the
    TV12 numbers to their printed digits; the literal closed form agrees where it is accurate."""
    A, _, _ = singer_generator(tau, 1.0)
    F, B_expm = input_response(A, np.array([0.0, 0.0, 1.0]), T)
    B = singer_input(tau, T)
    assert close(B, B_expm, 1e-9)
    assert_printed(B, printed)
    np.testing.assert_allclose(F, SingerAxisModel(tau, 1.0).F(T), rtol=1e-12, atol=1e-15)
    k, E1 = 1 / tau, math.exp(-T / tau)
    literal = [T**2 / (2 * k) - T / k**2 + (1 - E1) / k**3, T / k - (1 - E1) / k**2, (1 - E1) / k]
    assert close(literal, B_expm, 1e-8)


def test_singer_input_series_and_closed_form_meet_and_batch():
    """Both branches of singer_input equal expm on each side of kT = 1 and for large kT
    (rel 1e-12), at T -> 0 B -> [T^3/6, T^2/2, T], and an array of steps gives the stack."""
    tau = 2.0
    steps = np.array([1e-6, 0.3, 2.0 * (1 - 1e-12), 2.0 * (1 + 1e-12), 7.0, 40.0])
    A, _, _ = singer_generator(tau, 1.0)
    B = singer_input(tau, steps)
    assert B.shape == (len(steps), 3)
    _, B_expm = input_response(A, np.array([0.0, 0.0, 1.0]), steps)
    assert close(B, B_expm, 1e-12)
    assert close(B[0], [1e-18 / 6, 1e-12 / 2, 1e-6], 1e-6)


# ---------------------------------------------------------------------------- Van Loan generic
def test_van_loan_batch_and_input_response_forms():
    """A stack of steps equals step-by-step calls; a vector b gives B[n], a matrix b gives B[n, p]."""
    A, L, qc = singer_generator(7.0, 3.0)
    F, Q = van_loan(A, L, qc, STEPS)
    assert F.shape == Q.shape == (len(STEPS), 3, 3)
    for k, T in enumerate(STEPS):
        F1, Q1 = van_loan(A, L, qc, T)
        np.testing.assert_allclose(F[k], F1, rtol=1e-13, atol=0)
        np.testing.assert_allclose(Q[k], Q1, rtol=1e-13, atol=0)
    b = np.array([[0.0, 1.0], [0.0, 0.0], [1.0, 0.5]])
    _, B2 = input_response(A, b, 1.5)
    _, B_first = input_response(A, b[:, 0], 1.5)
    assert B2.shape == (3, 2) and B_first.shape == (3,)
    np.testing.assert_allclose(B2[:, 0], B_first, rtol=1e-13)
    with pytest.raises(ValueError, match="qc must be"):
        van_loan(A, L, np.eye(2), 1.0)


# ---------------------------------------------------------------------------- polynomial
@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_tv12_polynomial_continuous_equals_van_loan(m):
    """TV12: `continuous` Q formula = Van Loan of the integrator chain, q = 2.5, T = 0.7 (1e-12);
    F = expm(A T) likewise; also over a range of steps."""
    A, L = polynomial_generator(m)
    axis = PolynomialAxis(m, "continuous", 2.5)
    F_vl, Q_vl = van_loan(A, L, 2.5, 0.7)
    assert close(axis.Q(0.7), Q_vl, 1e-12)
    assert close(axis.F(0.7), F_vl, 1e-12, floor=1e-300)
    # over a range of steps: expm (scaling and squaring) is accurate only relative to |Q| (~2e-12 at T = 60)
    F_vl, Q_vl = van_loan(A, L, 2.5, STEPS)
    for Fk, Qk, F_ref, Q_ref in zip(axis.F_batch(STEPS), axis.Q_batch(STEPS), F_vl, Q_vl):
        assert np.max(np.abs(Qk - Q_ref)) <= 1e-11 * np.max(np.abs(Q_ref))
        assert np.max(np.abs(Fk - F_ref)) <= 1e-12 * np.max(np.abs(F_ref))


def test_polynomial_continuous_equals_existing_cv_ca():
    """m = 2 / 3 `continuous` are spec 000's ConstantVelocityAxis / ConstantAccelerationAxis."""
    for m, cls in ((2, ConstantVelocityAxis), (3, ConstantAccelerationAxis)):
        np.testing.assert_allclose(PolynomialAxis(m, "continuous", 1.7).Q_batch(STEPS), cls(1.7).Q_batch(STEPS),
                                   rtol=1e-14)
        np.testing.assert_array_equal(PolynomialAxis(m, "continuous", 1.7).F_batch(STEPS), cls(1.7).F_batch(STEPS))


@pytest.mark.parametrize("T", [0.25, 1.0, 3.0])
def test_dwna_dwpa_gain_vectors(T):
    """DWNA (m = 2 piecewise_constant) g = [T^2/2, T]; DWPA (m = 3 wiener_increment) g = [T^2/2, T, 1];
    Q = sigma_w^2 g g^T; general g_i = T^{m-i}/(m-i)! and T^{m-1-i}/(m-1-i)!."""
    sigma = 1.3
    dwna_axis = PolynomialAxis(2, "piecewise_constant", sigma)
    dwpa_axis = PolynomialAxis(3, "wiener_increment", sigma)
    np.testing.assert_allclose(dwna_axis.noise_gain(T), [T**2 / 2, T], rtol=1e-15)
    np.testing.assert_allclose(dwpa_axis.noise_gain(T), [T**2 / 2, T, 1.0], rtol=1e-15)
    g = np.array([T**2 / 2, T])
    np.testing.assert_allclose(dwna_axis.Q(T), sigma**2 * np.outer(g, g), rtol=1e-15)
    g = np.array([T**2 / 2, T, 1.0])
    np.testing.assert_allclose(dwpa_axis.Q(T), sigma**2 * np.outer(g, g), rtol=1e-15)
    np.testing.assert_allclose(PolynomialAxis(4, "piecewise_constant", 1).noise_gain(T),
                               [T**4 / 24, T**3 / 6, T**2 / 2, T], rtol=1e-15)
    np.testing.assert_allclose(PolynomialAxis(4, "wiener_increment", 1).noise_gain(T),
                               [T**3 / 6, T**2 / 2, T, 1.0], rtol=1e-15)
    np.testing.assert_allclose(PolynomialAxis(1, "piecewise_constant", 2).Q(T), [[4 * T**2]], rtol=1e-15)
    np.testing.assert_allclose(PolynomialAxis(1, "wiener_increment", 2).Q(T), [[4.0]], rtol=1e-15)
    assert dwna(3, sigma).axes[0] == dwna_axis and dwpa(2, sigma).axes[0] == dwpa_axis


def test_wiener_increment_has_no_increment_over_zero_step():
    """Q(0) = 0 for every variant (a zero-length step carries no Wiener increment)."""
    for m in (1, 2, 3, 4):
        for noise in NOISE_VARIANTS:
            np.testing.assert_array_equal(PolynomialAxis(m, noise, 2.0).Q_batch(np.array([0.0, 0.0])), 0.0)


@pytest.mark.parametrize("noise", NOISE_VARIANTS)
@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_isotropic_model_is_kronecker_product(m, noise):
    """polynomial(3, m, ...) F and Q = I_3 (x) (per-axis F, Q) in the axis-major layout (R1)."""
    axis = PolynomialAxis(m, noise, 0.8)
    model = polynomial(3, m, noise, 0.8)
    assert (model.ndim, model.order, model.dim) == (3, m, 3 * m) and model.identical_axes
    for T in (0.4, 2.0):
        np.testing.assert_array_equal(model.F(T), np.kron(np.eye(3), axis.F(T)))
        np.testing.assert_array_equal(model.Q(T), np.kron(np.eye(3), axis.Q(T)))
    np.testing.assert_array_equal(model.position_index, np.arange(3) * m)


# ---------------------------------------------------------------------------- coordinated turn
def test_tv12_coordinated_turn_coefficients_and_expm():
    """omega = 0.1, T = 1: s/w, (1-c)/w, c, s as printed; F = expm(A_CT T) to 1e-14 (order 2,
    horizontal block; z is CV)."""
    s_over, one_minus_c_over, c, s = turn_coefficients(0.1, 1.0)
    assert_printed([s_over, one_minus_c_over, c, s],
                   ["0.998334166468", "0.049958347220", "0.995004165278", "0.099833416647"])
    for ndim in (2, 3):
        F = CoordinatedTurn(0.1, 1.0, ndim=ndim).F(1.0)
        assert np.max(np.abs(F[:4, :4] - expm(coordinated_turn_generator(0.1)))) <= 1e-14
    F3 = CoordinatedTurn(0.1, 1.0, ndim=3).F(1.0)
    np.testing.assert_array_equal(F3[4:, 4:], [[1.0, 1.0], [0.0, 1.0]])
    assert not F3[:4, 4:].any() and not F3[4:, :4].any()


@pytest.mark.parametrize("omega", [-0.3, 0.02, 0.7])
def test_coordinated_turn_equals_expm_over_steps(omega):
    """F_batch equals expm of the generator for many steps and either turn direction (1e-13 rel to |F|)."""
    F = CoordinatedTurn(omega, 1.0, ndim=2).F_batch(STEPS)
    for k, T in enumerate(STEPS):
        F_ref = expm(coordinated_turn_generator(omega) * T)
        assert np.max(np.abs(F[k] - F_ref)) <= 1e-13 * max(1.0, np.max(np.abs(F_ref)))


def test_coordinated_turn_small_angle_series_is_continuous():
    """On either side of |wT| = 1e-6 the series and the trigonometric form agree (rel 1e-12);
    omega = 0 is constant velocity with DWNA noise."""
    T = 2.0
    below, above = (SMALL_TURN * (1 - 1e-9)) / T, (SMALL_TURN * (1 + 1e-9)) / T
    lo = np.array(turn_coefficients(below, T), dtype=float)
    hi = np.array(turn_coefficients(above, T), dtype=float)
    assert close(lo, hi, 1e-8)  # the coefficients themselves move by the 2e-9 relative change of omega
    # the series side against the trigonometric values at that omega ((1-c) as 2 sin^2, no cancellation)
    w = below
    assert close(lo[:2], [math.sin(w * T) / w, 2 * math.sin(w * T / 2) ** 2 / w], 1e-12)
    ct0 = CoordinatedTurn(0.0, 1.5, ndim=3)
    np.testing.assert_array_equal(ct0.F_batch(STEPS), dwna(3, 1.5).F_batch(STEPS))
    np.testing.assert_allclose(ct0.Q_batch(STEPS), dwna(3, 1.5).Q_batch(STEPS), rtol=1e-15)
    np.testing.assert_allclose(CoordinatedTurn(1e-12, 1.5, ndim=2).F(3.0), constant_velocity(2, 1.0).F(3.0),
                               rtol=0, atol=1e-11)


def test_coordinated_turn_noise_is_dwna_per_axis():
    """Q = blockdiag(sigma_w^2 g g^T, sigma_w^2 g g^T, sigma_v^2 g g^T), g = [T^2/2, T]."""
    T = 1.7
    g = np.array([T**2 / 2, T])
    block = np.outer(g, g)
    Q = CoordinatedTurn(0.2, 2.0, ndim=3, sigma_w_vertical=0.5).Q(T)
    expected = np.zeros((6, 6))
    expected[:2, :2] = expected[2:4, 2:4] = 4.0 * block
    expected[4:, 4:] = 0.25 * block
    np.testing.assert_allclose(Q, expected, rtol=1e-15)
    np.testing.assert_allclose(CoordinatedTurn(0.2, 2.0, ndim=3).scaled(9.0).Q(T),
                               9.0 * CoordinatedTurn(0.2, 2.0, ndim=3).Q(T), rtol=1e-14)


# ---------------------------------------------------------------------------- embedding
def test_embedded_cv_matches_spec_form():
    """CV in m = 3: F_cv = [[1, T, 0], [0, 1, 0], [0, 0, 0]], g = [T^2/2, T, 0] per axis (9 states)."""
    T, sigma = 1.5, 2.0
    model = embed(dwna(3, sigma))
    assert (model.dim, model.order, model.ndim) == (9, 3, 3)
    np.testing.assert_array_equal(model.F(T), np.kron(np.eye(3), [[1, T, 0], [0, 1, 0], [0, 0, 0]]))
    g = np.array([T**2 / 2, T, 0.0])
    np.testing.assert_allclose(model.Q(T), np.kron(np.eye(3), sigma**2 * np.outer(g, g)), rtol=1e-15)
    np.testing.assert_array_equal(model.position_index, [0, 3, 6])
    # continuous-noise CV embeds the same way
    cv = embed(constant_velocity(2, 1.0))
    assert isinstance(cv.axes[0], EmbeddedAxis) and cv.dim == 6
    np.testing.assert_array_equal(cv.Q(T)[:2, :2], ConstantVelocityAxis(1.0).Q(T))
    assert not cv.Q(T)[2].any() and not cv.F(T)[2].any()


def test_embed_keeps_order_three_models_and_rejects_higher_order():
    s = singer(3, 20.0, 30.0)
    assert embed(s) is s
    ca = dwpa(3, 1.0)
    assert embed(ca) is ca
    with pytest.raises(ValueError, match="cannot embed an order-4"):
        embed(polynomial(3, 4, "continuous", 1.0))
    with pytest.raises(ValueError, match="MotionModel or CoordinatedTurn"):
        embed(ConstantVelocityAxis(1.0))
    assert embed(CoordinatedTurn(0.1, 1.0)).order == 3


def test_embedded_coordinated_turn_zero_acceleration():
    """order 3, ct_acceleration="zero": position/velocity blocks are those of order 2, acceleration
    rows and columns of F and Q are zero."""
    T = 1.3
    ct2 = CoordinatedTurn(0.15, 1.2, ndim=3)
    ct3 = embed(ct2)
    keep = [0, 1, 3, 4, 6, 7]
    acc = [2, 5, 8]
    F3, Q3 = ct3.F(T), ct3.Q(T)
    assert F3.shape == Q3.shape == (9, 9)
    np.testing.assert_array_equal(F3[np.ix_(keep, keep)], ct2.F(T))
    np.testing.assert_array_equal(Q3[np.ix_(keep, keep)], ct2.Q(T))
    assert not F3[acc].any() and not F3[:, acc].any() and not Q3[acc].any() and not Q3[:, acc].any()


def test_embedded_coordinated_turn_centripetal():
    """ct_acceleration="centripetal": F3 = J F2 S, Q3 = J Q2 J^T with a = Omega v, Omega = w [[0,-1],[1,0]];
    the predicted acceleration of a state on a turn is the centripetal one."""
    T, w = 0.8, 0.25
    ct2 = CoordinatedTurn(w, 1.2, ndim=3)
    ct3 = CoordinatedTurn(w, 1.2, ndim=3, order=3, ct_acceleration="centripetal")
    keep = [0, 1, 3, 4, 6, 7]
    J = np.zeros((9, 6))
    J[keep, range(6)] = 1.0
    J[2, 3] = -w  # a_x = -w v_y
    J[5, 1] = w   # a_y = w v_x
    S = np.zeros((6, 9))
    S[range(6), keep] = 1.0
    np.testing.assert_allclose(ct3.F(T), J @ ct2.F(T) @ S, rtol=1e-15, atol=0)
    np.testing.assert_allclose(ct3.Q(T), J @ ct2.Q(T) @ J.T, rtol=1e-15, atol=0)
    speed = 200.0
    x = np.array([[0.0, speed, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])  # heading east, turning left
    x_next = ct3.f(x, T)[0]
    v_next = x_next[[1, 4]]
    np.testing.assert_allclose(x_next[[2, 5]], w * np.array([-v_next[1], v_next[0]]), rtol=1e-15)
    assert math.hypot(*x_next[[2, 5]]) == pytest.approx(w * speed, rel=1e-14)


# ---------------------------------------------------------------------------- common properties
def all_models():
    models = {f"poly{m}-{noise}": MotionModel([PolynomialAxis(m, noise, 1.7)] * 3)
              for m in (1, 2, 3, 4) for noise in NOISE_VARIANTS}
    models["ct2"] = CoordinatedTurn(0.3, 2.0, ndim=2)
    models["ct3"] = CoordinatedTurn(-0.1, 2.0, ndim=3, sigma_w_vertical=0.7)
    models["ct3-embedded-zero"] = CoordinatedTurn(0.1, 2.0, ndim=3, order=3)
    models["ct3-embedded-centripetal"] = CoordinatedTurn(0.1, 2.0, ndim=3, order=3, ct_acceleration="centripetal")
    models["cv-embedded"] = embed(dwna(3, 1.0))
    return models


@pytest.mark.parametrize("name", list(all_models()))
def test_q_symmetric_psd_and_f_at_zero(name):
    """Q symmetric and positive semi-definite (eigenvalues >= -1e-12 |Q|) for every step;
    F(0) = I for non-embedded models and diag(1, 1, 0) per axis for embedded ones; Q(0) = 0."""
    model = all_models()[name]
    Q = model.Q_batch(STEPS)
    assert Q.shape == (len(STEPS), model.dim, model.dim)
    np.testing.assert_array_equal(Q, np.swapaxes(Q, -1, -2))
    for Qk in Q:
        assert np.linalg.eigvalsh(Qk).min() >= -1e-12 * np.abs(Qk).max()
    F0 = model.F_batch(np.zeros(1))[0]
    embedded = "embedded" in name
    expected = np.kron(np.eye(model.ndim), np.diag([1.0, 1.0, 0.0])) if embedded else np.eye(model.dim)
    if name.endswith("centripetal"):  # a' = Omega v: a_x' = -w v_y, a_y' = w v_x
        expected[2, 4], expected[5, 1] = -model.omega, model.omega
    np.testing.assert_array_equal(F0, expected)
    np.testing.assert_array_equal(model.Q_batch(np.zeros(1)), 0.0)
    for k, T in enumerate(STEPS):
        np.testing.assert_array_equal(model.F(T), model.F_batch(STEPS)[k])


# ---------------------------------------------------------------------------- filters over the models
@pytest.mark.parametrize("compiled", [True, False])
def test_kalman_filter_predicts_with_coordinated_turn(compiled):
    """KalmanFilter over CT: x' = F x, P' = F P F^T + Q per row; a negative step extrapolates
    backwards with F^-1 (forward then backward returns to the start)."""
    model = CoordinatedTurn(0.12, 1.5, ndim=3)
    kf = KalmanFilter(model, compiled=compiled)
    rng = np.random.default_rng(7)
    x = rng.normal(size=(3, 6)) * 100.0
    A = rng.normal(size=(3, 6, 6))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(6)
    dt = np.array([1.0, 4.5, 0.3])
    pred = kf.predict(kf.initiate(x, P), dt)
    for r in range(3):
        F, Q = model.F(dt[r]), model.Q(dt[r])
        np.testing.assert_allclose(pred.x[r], F @ x[r], rtol=1e-13, atol=1e-10)
        np.testing.assert_allclose(pred.P[r], F @ P[r] @ F.T + Q, rtol=1e-12, atol=1e-10)
    back = KalmanFilter(model, compiled=compiled).predict(kf.initiate(pred.x, pred.P), -dt)
    np.testing.assert_allclose(back.x, x, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("model,base", [(embed(dwna(3, 1.0)), dwna(3, 1.0)),
                                        (CoordinatedTurn(0.1, 1.0, ndim=3, order=3), CoordinatedTurn(0.1, 1.0, ndim=3))],
                         ids=["cv-embedded", "ct-embedded"])
def test_embedded_models_extrapolate_backwards_with_zero_acceleration(model, base):
    """The m = 3 embedding has a singular F; KalmanFilter's backward prediction (dt < 0) uses the
    Moore-Penrose inverse, which runs the order-2 model back and keeps the acceleration at zero:
    position and velocity equal the order-2 model's backward prediction to 1e-12."""
    rng = np.random.default_rng(4)
    x3 = rng.normal(0.0, 100.0, (2, 9))
    back = KalmanFilter(model).predict(KalmanFilter(model).initiate(x3, np.tile(np.eye(9), (2, 1, 1))),
                                       np.array([-1.0, -3.0]))
    keep = np.array([0, 1, 3, 4, 6, 7])
    x2 = x3[:, keep]
    expected = KalmanFilter(base).predict(KalmanFilter(base).initiate(x2, np.tile(np.eye(6), (2, 1, 1))),
                                          np.array([-1.0, -3.0]))
    np.testing.assert_allclose(back.x[:, keep], expected.x, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(back.x[:, [2, 5, 8]], 0.0, atol=1e-9)


def test_kalman_filter_on_coordinated_turn_is_consistent():
    """Matched-model NEES: 200 Monte Carlo runs of a CT(0.05) target with DWNA noise, positions
    measured (sigma 20 m); the run-average NEES after 25 scans lies in the two-sided 99.9 %
    chi-square interval of 200 x 6 degrees of freedom."""
    runs, scans, T = 200, 25, 2.0
    model = CoordinatedTurn(0.05, 3.0, ndim=3)
    F, Q = model.F(T), model.Q(T)
    R = np.eye(3) * 20.0**2
    P0 = np.diag([100.0, 25.0, 100.0, 25.0, 100.0, 4.0])
    x_true = np.empty((runs, 6))
    z = np.empty((scans, runs, 3))
    truths = np.empty((scans, runs, 6))
    g = np.array([T**2 / 2, T])
    for r, seq in enumerate(np.random.SeedSequence(2004).spawn(runs)):
        rng = np.random.default_rng(seq)
        x = np.array([0.0, 150.0, 0.0, 50.0, 3000.0, 0.0]) + rng.normal(size=6) * np.sqrt(np.diag(P0))
        x_true[r] = x
        for k in range(scans):
            sig = np.array([3.0, 3.0, 3.0])
            w = np.concatenate([g * sig[a] * rng.normal() for a in range(3)])
            x = F @ x + w
            truths[k, r] = x
            z[k, r] = x[[0, 2, 4]] + rng.normal(size=3) * 20.0
    np.testing.assert_allclose(Q, np.kron(np.eye(3), 9.0 * np.outer(g, g)), rtol=1e-15)
    kf = KalmanFilter(model)
    meas = ConvertedPositionModel(3, 2)
    state = kf.initiate(np.tile([0.0, 150.0, 0.0, 50.0, 3000.0, 0.0], (runs, 1)), np.tile(P0, (runs, 1, 1)))
    Rb = np.broadcast_to(R, (runs, 3, 3)).copy()
    for k in range(scans):
        pred = kf.predict(state, np.full(runs, T))
        state, _ = kf.update(pred, z[k], kf.innovate(pred, z[k], meas, {"R": Rb}))
    err = truths[-1] - state.x
    nees = np.einsum("ri,rij,rj->r", err, np.linalg.inv(state.P), err)
    low, high = chi2.ppf([0.0005, 0.9995], runs * 6) / runs
    assert low <= nees.mean() <= high


# ---------------------------------------------------------------------------- configuration errors
def test_bad_configuration_is_a_named_value_error():
    with pytest.raises(ValueError, match="polynomial order"):
        PolynomialAxis(5, "continuous", 1.0)
    with pytest.raises(ValueError, match="polynomial order"):
        PolynomialAxis(0, "continuous", 1.0)
    with pytest.raises(ValueError, match="polynomial noise"):
        PolynomialAxis(2, "dwna", 1.0)
    with pytest.raises(ValueError, match="polynomial intensity"):
        PolynomialAxis(2, "continuous", -1.0)
    with pytest.raises(ValueError, match="noise_gain"):
        PolynomialAxis(2, "continuous", 1.0).noise_gain(1.0)
    with pytest.raises(ValueError, match="ndim"):
        coordinated_turn(1, 0.1, 1.0)
    with pytest.raises(ValueError, match="order"):
        CoordinatedTurn(0.1, 1.0, order=4)
    with pytest.raises(ValueError, match="ct_acceleration"):
        CoordinatedTurn(0.1, 1.0, order=3, ct_acceleration="tangential")
    with pytest.raises(ValueError, match="sigma_w"):
        CoordinatedTurn(0.1, -1.0)
    with pytest.raises(ValueError, match="omega"):
        CoordinatedTurn(float("nan"), 1.0)
    with pytest.raises(ValueError, match="time step"):
        CoordinatedTurn(0.1, 1.0).F_batch(np.array([-1.0]))
    with pytest.raises(ValueError, match="factor"):
        CoordinatedTurn(0.1, 1.0).scaled(0.0)
    with pytest.raises(ValueError, match="tau"):
        singer_input(0.0, 1.0)


@pytest.mark.parametrize("omega", [0.3, 0.1, -0.05, 0.01, 1e-3, 1e-4, 0.0])
@pytest.mark.parametrize("T", [0.1, 1.0, 4.0, 12.0, 30.0])
def test_coordinated_turn_continuous_noise_equals_van_loan(omega, T):
    """noise="continuous": white acceleration of PSD sigma_w^2 on the turning velocity (and on vz),
    discretised in closed form (series below |wT| = 0.1) = Van Loan of the CT generator, 1e-12."""
    q = 0.49
    model = CoordinatedTurn(omega, math.sqrt(q), ndim=3, noise="continuous")
    A = np.zeros((6, 6))
    A[0, 1] = A[2, 3] = A[4, 5] = 1.0
    A[1, 3], A[3, 1] = -omega, omega
    L = np.zeros((6, 3))
    L[1, 0] = L[3, 1] = L[5, 2] = 1.0
    F, Q = van_loan(A, L, np.eye(3) * q, T)
    np.testing.assert_allclose(model.Q(T), Q, rtol=0, atol=1e-12 * np.abs(Q).max())
    np.testing.assert_allclose(model.F(T), F, rtol=0, atol=1e-12 * np.abs(F).max())

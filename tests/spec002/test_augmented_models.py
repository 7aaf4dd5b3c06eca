"""Spec 002 R1-R4: augmented-state models (ct-omega TV7, ca-accel) and the unwhitened S rows of TV8."""

import math

import numpy as np
import pytest

from skytrack.models.augmented import AugmentedModel, ca_accel, ct_omega, linear_model, rk4_substeps
from skytrack.models.augmented_measurements import (
    augment_for_biases,
    measurement_for,
    one_step_sensitivity,
)

TV7_STATE = np.array([1000.0, 2000.0, 150.0, -100.0, 0.05])
RTOL = 1e-9

TV7_CASES = {
    # T: (phi, G)
    1.0: ((1152.43698702210, 1903.79088027374, 154.810455986313, -92.3781506488949, 0.05),
          (47.4693792842055, 76.6193815472104, 92.3781506488949, 154.810455986313, 1.0)),
    4.0: ((1635.87483670270, 1662.46160488615, 166.876919755692, -68.2062581648650, 0.05),
          (632.656846401382, 1294.26724908775, 272.825032659460, 667.507679022769, 1.0)),
}


# ---------------------------------------------------------------- TV7: ct-omega (R2)


@pytest.mark.parametrize("T", sorted(TV7_CASES))
def test_tv7_ct_phi_and_G(T):
    phi, G = TV7_CASES[T]
    model = ct_omega()
    np.testing.assert_allclose(model.phi(TV7_STATE, T), phi, rtol=RTOL)
    np.testing.assert_allclose(model.G(TV7_STATE, T)[:, 0], G, rtol=RTOL)


def test_tv7_ct_F_velocity_block():
    expected = [[0.999583385414, -0.0249947921007], [0.0249947921007, 0.999583385414],
                [0.998750260395, -0.0499791692707], [0.0499791692707, 0.998750260395]]
    F = ct_omega().F(TV7_STATE, 1.0)
    np.testing.assert_allclose(F[0:4, 2:4], expected, rtol=1e-11)  # printed to 12 digits
    np.testing.assert_array_equal(F[:, :2], np.eye(5)[:, :2])
    np.testing.assert_array_equal(F[4], [0, 0, 0, 0, 1])  # the parameter is a random walk


def test_tv7_series_branch_small_turn():
    x = TV7_STATE.copy()
    x[4] = 1e-5
    model = ct_omega()
    np.testing.assert_allclose(model.phi(x, 1.0),
                               (1150.00049999750, 1900.00075000167, 150.000999992500, -99.9984999950000, 1e-5),
                               rtol=RTOL)
    np.testing.assert_allclose(model.G(x, 1.0)[:, 0],
                               (49.9994999987500, 75.0003333314583, 99.9984999950000, 150.000999992500, 1.0),
                               rtol=RTOL)


def test_ct_series_and_closed_form_meet_at_the_switch():
    # just below and above |wT| = 1e-3 the two branches agree to rounding
    model = ct_omega()
    below, above = TV7_STATE.copy(), TV7_STATE.copy()
    below[4], above[4] = 0.999999e-3, 1.000001e-3
    F_below, F_above = model.F(below, 1.0), model.F(above, 1.0)
    np.testing.assert_allclose(F_below, F_above, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(model.phi(below, 1.0)[:4], model.phi(above, 1.0)[:4], rtol=1e-8)


@pytest.mark.parametrize("T", [1.0, 4.0])
def test_tv7_drift_route_rk4_and_finite_difference_F(T):
    exact, drift = ct_omega(), ct_omega(route="drift")
    assert rk4_substeps(T) == round(T / 0.1)
    assert np.max(np.abs(drift.phi(TV7_STATE, T) - exact.phi(TV7_STATE, T))) < 1e-6
    analytic = exact.F(TV7_STATE, T)
    assert np.max(np.abs(drift.F(TV7_STATE, T) - analytic)) < 1e-5
    assert np.max(np.abs(exact.finite_difference_F(TV7_STATE, T) - analytic)) < 1e-5


def test_ct_batched_rows_equal_single_rows():
    model = ct_omega()
    states = np.array([TV7_STATE, [0.0, 0.0, 200.0, 0.0, -0.03], [5.0, -3.0, 0.0, 100.0, 1e-6]])
    steps = np.array([1.0, 4.0, 2.5])
    phi, F = model.phi(states, steps), model.F(states, steps)
    for k in range(3):
        np.testing.assert_array_equal(phi[k], model.phi(states[k], steps[k]))
        np.testing.assert_array_equal(F[k], model.F(states[k], steps[k]))
    drift = ct_omega(route="drift")
    np.testing.assert_allclose(drift.phi(states, steps), phi, atol=1e-6)


def test_ct_turns_left_for_positive_omega():
    # heading east with omega > 0 turns north (counter-clockwise seen from above): a quarter
    # turn of radius v/omega ends at (R, R) heading north
    x = np.array([0.0, 0.0, 100.0, 0.0, math.pi / 20])
    radius = 100.0 / (math.pi / 20)
    after = ct_omega().phi(x, 10.0)
    np.testing.assert_allclose(after[:4], [radius, radius, 0.0, 100.0], atol=1e-9)


# ---------------------------------------------------------------- R1 structure, R3 ca-accel


def test_structure_h_a_units_and_G_is_F_h_a_transpose():
    model = ct_omega(sigma_omega=2e-4)
    assert model.units == ("m", "m", "m/s", "m/s", "rad/s")
    np.testing.assert_array_equal(model.h_a, [[0, 0, 0, 0, 1]])
    np.testing.assert_array_equal(model.h_a @ model.h_a.T, np.eye(1))
    np.testing.assert_allclose(model.V_w, [[4e-8]], rtol=1e-15)
    F = model.F(TV7_STATE, 4.0)
    np.testing.assert_array_equal(model.G(TV7_STATE, 4.0), F @ model.h_a.T)
    np.testing.assert_array_equal(model.Q_dep(1.0), np.zeros((5, 5)))


def test_ca_accel_linear_G():
    model = ca_accel()
    T = 3.0
    x = np.array([1.0, 2.0, 3.0, 4.0, 0.5, -0.2])
    G = model.G(x, T)
    np.testing.assert_array_equal(G, np.vstack([T * T / 2 * np.eye(2), T * np.eye(2), np.eye(2)]))
    np.testing.assert_allclose(model.phi(x, T), model.F(x, T) @ x, rtol=1e-15)
    np.testing.assert_allclose(model.phi(x, T), [1 + 9 + 0.5 * 4.5, 2 + 12 - 0.2 * 4.5, 4.5, 3.4, 0.5, -0.2])
    assert model.parameters == ("ax", "ay") and model.unit_of("ax") == "m/s^2"


def test_white_acceleration_dependent_noise():
    model = ct_omega(q_accel=2.0)
    Q = model.Q_dep(np.array([1.0, 2.0]))
    np.testing.assert_allclose(Q[1][np.ix_([0, 2], [0, 2])], 2.0 * np.array([[8 / 3, 2.0], [2.0, 2.0]]))
    np.testing.assert_array_equal(Q[:, 4], 0.0)


def test_generic_drift_model_by_rk4_matches_closed_form():
    # x' = -a x with a a parameter: classical RK4 multiplies x by R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24,
    # z = -a h, per sub-step; T = 2 s gives 20 sub-steps of h = 0.1 s
    model = AugmentedModel(name="decay", components=("x", "a"), units=("m", "1/s"), parameters=("a",),
                           V_w=[[1e-4]], drift=lambda s: np.stack([-s[:, 1] * s[:, 0], 0 * s[:, 1]], axis=1))
    x = np.array([3.0, 0.7])
    z = -0.7 * 0.1
    amplification = (1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) ** 20
    np.testing.assert_allclose(model.phi(x, 2.0), [3.0 * amplification, 0.7], rtol=1e-13)
    # and the RK4 solution is within its 4th-order error of the exact exp(-aT) x
    assert abs(model.phi(x, 2.0)[0] - 3.0 * math.exp(-1.4)) < 1e-6
    # F by central differences: d phi / da of the exact solution is -T x exp(-aT)
    np.testing.assert_allclose(model.G(x, 2.0)[:, 0], [-2.0 * 3.0 * math.exp(-1.4), 1.0], rtol=1e-5)


def test_tv3_linear_model_propagates_the_disturbance_through_G():
    # eq. (3)-(4): x(k) = F x(k-1) + G w(k-1) = phi(x(k-1) + h_a^T w(k-1))
    F = [[1, 0.5, 0, 0, 2, 3], [0, 1, 0.1, 0, 0.5, 0.7], [0, 0, 1, 0.1, 0.2, 0], [0, 0, 0, 1, 0, 0.4],
         [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]
    model = linear_model("paper-example", F, [f"x{i}" for i in range(1, 7)], ["-"] * 6, ("x5", "x6"),
                         np.eye(2))
    x_prev, w = np.array([1.0, 2.0, 3.0, 4.0, 0.5, -0.2]), np.array([0.01, -0.02])
    expected = [2.36, 2.401, 3.502, 3.912, 0.51, -0.22]
    np.testing.assert_allclose(model.phi(x_prev, 1.0) + model.G(x_prev, 1.0) @ w, expected, rtol=1e-12)
    np.testing.assert_allclose(model.phi(x_prev + model.h_a.T @ w, 1.0), expected, rtol=1e-12)
    np.testing.assert_array_equal(model.G(x_prev, 1.0), np.array(F)[:, 4:])


def test_appended_bias_keeps_dependent_noise_and_random_walk():
    model = augment_for_biases(ct_omega(q_accel=1.0), measurement_for(ct_omega(), "rdot").with_bias("rdot"))
    Q = model.Q_dep(2.0)
    np.testing.assert_allclose(Q[:5, :5], ct_omega(q_accel=1.0).Q_dep(2.0), rtol=1e-15)
    np.testing.assert_array_equal(Q[5], 0.0)
    x = np.append(TV7_STATE, 0.3)
    F = model.F(x, 4.0)
    np.testing.assert_array_equal(F[5], [0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(F[:5, :5], ct_omega().F(TV7_STATE, 4.0))
    np.testing.assert_allclose(model.V_w, np.diag([1e-8, 1e-6]), rtol=1e-15)


# ---------------------------------------------------------------- TV8: S = H F h_a^T (R4)

P0 = (30_000.0, 0.0)
GEOMETRY = {"radial": (-200.0, 0.0), "tangential": (0.0, 200.0)}


def _ct_state(geometry):
    return np.array([*P0, *GEOMETRY[geometry], 0.0])


def _ca_state(geometry):
    return np.array([*P0, *GEOMETRY[geometry], 0.0, 0.0])


def test_tv8_omega_rows():
    model = ct_omega()
    meas = measurement_for(model, ("pos", "rdot"))
    assert meas.units == ("m", "m", "m/s")
    S_rad = one_step_sensitivity(model, meas, _ct_state("radial"), 1.0)
    np.testing.assert_allclose(S_rad[:, 0], [0.0, -100.0, 0.0], rtol=1e-12, atol=1e-12)
    S_tan = one_step_sensitivity(model, meas, _ct_state("tangential"), 1.0)
    np.testing.assert_allclose(S_tan[:, 0], [-100.0, 0.0, -199.99111155553362], rtol=1e-12, atol=1e-12)


def test_tv8_acceleration_rows():
    model = ca_accel()
    meas = measurement_for(model, ("pos", "rdot"))
    S_rad = one_step_sensitivity(model, meas, _ca_state("radial"), 1.0)
    np.testing.assert_allclose(S_rad, [[0.5, 0.0], [0.0, 0.5], [1.0, 0.0]], rtol=1e-12, atol=1e-12)
    S_tan = one_step_sensitivity(model, meas, _ca_state("tangential"), 1.0)
    np.testing.assert_allclose(S_tan[:2], [[0.5, 0.0], [0.0, 0.5]], rtol=1e-12)
    np.testing.assert_allclose(S_tan[2], [0.9999555577776681, 0.009999629646912757], rtol=1e-12)
    # batched over a leading axis of states: both geometries in one call
    both = one_step_sensitivity(model, meas, np.stack([_ca_state("radial"), _ca_state("tangential")]), 1.0)
    np.testing.assert_array_equal(both, np.stack([S_rad, S_tan]))


@pytest.mark.parametrize("geometry", sorted(GEOMETRY))
def test_tv8_bias_columns(geometry):
    base = ca_accel()
    meas = measurement_for(base, ("pos", "rdot")).with_bias("x").with_bias("rdot")
    model = augment_for_biases(base, meas)
    assert model.parameters == ("ax", "ay", "b_x", "b_rdot")
    assert model.units[-2:] == ("m", "m/s") and meas.bias_units == ("m", "m/s")
    x = np.concatenate([_ca_state(geometry), [0.0, 0.0]])
    S = one_step_sensitivity(model, meas, x, 1.0)
    np.testing.assert_array_equal(S[:, 2], [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(S[:, 3], [0.0, 0.0, 1.0])
    unbiased = one_step_sensitivity(base, measurement_for(base, ("pos", "rdot")), _ca_state(geometry), 1.0)
    np.testing.assert_array_equal(S[:, :2], unbiased)


def test_bias_shifts_the_channel_and_omega_model_takes_a_rdot_bias():
    base = ct_omega()
    meas = measurement_for(base, "rdot").with_bias("rdot")
    model = augment_for_biases(base, meas, variances=[1e-6])
    x = np.append(_ct_state("tangential"), 2.5)
    plain = measurement_for(base, "rdot").h(x[:5])
    np.testing.assert_allclose(meas.h(x), plain + 2.5, rtol=1e-15)
    S = one_step_sensitivity(model, meas, x, 1.0)
    np.testing.assert_allclose(S, [[-199.99111155553362, 1.0]], rtol=1e-12)


def test_polar_channels_and_jacobians_by_finite_differences():
    model = ct_omega()
    meas = measurement_for(model, ("polar", "rdot"), sensor=(100.0, -50.0))
    assert meas.units == ("m", "rad", "m/s") and list(meas.angular) == [False, True, False]
    x = np.array([-3000.0, 4000.0, 120.0, 35.0, 0.01])
    h, H = meas.evaluate(x)
    dx, dy = -3100.0, 4050.0
    np.testing.assert_allclose(h[:2], [math.hypot(dx, dy), math.atan2(dx, dy) % (2 * math.pi)], rtol=1e-14)
    numeric = np.zeros_like(H)
    for i in range(5):
        step = 1e-4 * max(1.0, abs(x[i]))
        e = np.eye(5)[i] * step
        numeric[:, i] = (meas.h(x + e) - meas.h(x - e)) / (2 * step)
    np.testing.assert_allclose(H, numeric, rtol=1e-7, atol=1e-12)

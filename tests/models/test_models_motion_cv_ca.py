"""Constant-velocity and constant-acceleration axis models and their assembly
(skytrack.models.motion; the Singer parts are tested under tests/spec000)."""

import numpy as np
import pytest
from scipy.linalg import expm

from skytrack.models.motion import (
    ConstantAccelerationAxis,
    ConstantVelocityAxis,
    MotionModel,
    block_diag_batch,
    constant_acceleration,
    constant_velocity,
)

STEPS = [1e-3, 0.37, 1.0, 4.0, 12.5, 60.0]


def van_loan(order: int, q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F = e^{A dt} and Q = int_0^dt e^{As} G q G^T e^{A^T s} ds for the chain of integrators
    driven by white noise of PSD q on the last state (Van Loan 1978)."""
    A = np.diag(np.ones(order - 1), 1)
    G = np.zeros((order, 1))
    G[-1, 0] = 1.0
    M = np.zeros((2 * order, 2 * order))
    M[:order, :order] = -A
    M[:order, order:] = G @ G.T * q
    M[order:, order:] = A.T
    E = expm(M * dt)
    F = E[order:, order:].T
    return F, F @ E[:order, order:]


@pytest.mark.parametrize("cls, order", [(ConstantVelocityAxis, 2), (ConstantAccelerationAxis, 3)])
@pytest.mark.parametrize("dt", STEPS)
def test_closed_forms_match_van_loan(cls, order, dt):
    q = 3.7
    model = cls(q)
    F_ref, Q_ref = van_loan(order, q, dt)
    np.testing.assert_allclose(model.F(dt), F_ref, rtol=1e-12, atol=1e-12 * np.abs(F_ref).max())
    np.testing.assert_allclose(model.Q(dt), Q_ref, rtol=1e-10, atol=1e-12 * np.abs(Q_ref).max())
    np.testing.assert_array_equal(model.Q(dt), model.Q(dt).T)


def test_cv_known_values():
    F = ConstantVelocityAxis(2.0).F(4.0)
    Q = ConstantVelocityAxis(2.0).Q(4.0)
    np.testing.assert_array_equal(F, [[1.0, 4.0], [0.0, 1.0]])
    np.testing.assert_allclose(Q, [[2.0 * 64 / 3, 2.0 * 8], [2.0 * 8, 2.0 * 4]], rtol=1e-15)


def test_ca_known_values():
    F = ConstantAccelerationAxis(1.0).F(2.0)
    Q = ConstantAccelerationAxis(1.0).Q(2.0)
    np.testing.assert_array_equal(F, [[1.0, 2.0, 2.0], [0.0, 1.0, 2.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(Q, [[32 / 20, 16 / 8, 8 / 6], [16 / 8, 8 / 3, 2.0], [8 / 6, 2.0, 2.0]], rtol=1e-15)


@pytest.mark.parametrize("cls", [ConstantVelocityAxis, ConstantAccelerationAxis])
@pytest.mark.parametrize("dt", STEPS)
def test_step_aggregation_is_exact(cls, dt):
    """Two steps of dt equal one step of 2 dt: F(2t) = F(t)^2, Q(2t) = F(t) Q(t) F(t)^T + Q(t)."""
    model = cls(0.8)
    F, Q = model.F(dt), model.Q(dt)
    np.testing.assert_allclose(model.F(2 * dt), F @ F, rtol=1e-14)
    np.testing.assert_allclose(model.Q(2 * dt), F @ Q @ F.T + Q, rtol=1e-12)


@pytest.mark.parametrize("cls", [ConstantVelocityAxis, ConstantAccelerationAxis])
def test_batched_equals_per_element(cls):
    model = cls(1.3)
    steps = np.array([0.0, 0.5, 4.0, 4.0, 17.25])
    F_batch, Q_batch = model.F_batch(steps), model.Q_batch(steps)
    assert F_batch.shape == (5, model.order, model.order)
    np.testing.assert_array_equal(F_batch[0], np.eye(model.order))
    np.testing.assert_array_equal(Q_batch[0], np.zeros((model.order, model.order)))
    for k, dt in enumerate(steps[1:], start=1):
        np.testing.assert_array_equal(F_batch[k], model.F(dt))
        np.testing.assert_array_equal(Q_batch[k], model.Q(dt))
    # any leading shape
    grid = steps[1:].reshape(2, 2)
    np.testing.assert_array_equal(model.F_batch(grid).reshape(4, model.order, model.order), F_batch[1:])


@pytest.mark.parametrize("cls", [ConstantVelocityAxis, ConstantAccelerationAxis])
@pytest.mark.parametrize("q", [-1.0, np.nan, np.inf])
def test_invalid_psd_raises(cls, q):
    with pytest.raises(ValueError, match="q must be finite and >= 0"):
        cls(q)


@pytest.mark.parametrize("cls", [ConstantVelocityAxis, ConstantAccelerationAxis])
def test_invalid_steps_raise(cls):
    model = cls(1.0)
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="time step"):
            model.F(bad)
        with pytest.raises(ValueError, match="time step"):
            model.Q(bad)
    with pytest.raises(ValueError, match="time step must be >= 0"):
        model.F_batch(np.array([1.0, -0.5]))
    with pytest.raises(ValueError, match="finite"):
        model.Q_batch(np.array([1.0, np.nan]))


def test_zero_psd_is_allowed_and_gives_zero_noise():
    np.testing.assert_array_equal(ConstantVelocityAxis(0.0).Q(5.0), np.zeros((2, 2)))


def test_motion_model_assembles_per_axis_blocks():
    model = constant_velocity(3, 2.0)
    assert (model.ndim, model.order, model.dim) == (3, 2, 6)
    np.testing.assert_array_equal(model.position_index, [0, 2, 4])
    np.testing.assert_array_equal(model.velocity_index, [1, 3, 5])
    axis = ConstantVelocityAxis(2.0)
    F, Q = model.F(3.0), model.Q(3.0)
    for k in range(3):
        block = slice(2 * k, 2 * k + 2)
        np.testing.assert_array_equal(F[block, block], axis.F(3.0))
        np.testing.assert_array_equal(Q[block, block], axis.Q(3.0))
    off_diagonal = np.ones((6, 6), bool)
    for k in range(3):
        off_diagonal[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = False
    assert not F[off_diagonal].any() and not Q[off_diagonal].any()
    # batched assembly equals per-step assembly
    steps = np.array([1.0, 4.0])
    np.testing.assert_array_equal(model.F_batch(steps)[1], model.F(4.0))
    np.testing.assert_array_equal(model.Q_batch(steps)[0], model.Q(1.0))


def test_motion_model_with_different_axes():
    model = MotionModel([ConstantAccelerationAxis(1.0), ConstantAccelerationAxis(5.0)])
    Q = model.Q(2.0)
    np.testing.assert_array_equal(Q[:3, :3], ConstantAccelerationAxis(1.0).Q(2.0))
    np.testing.assert_array_equal(Q[3:, 3:], ConstantAccelerationAxis(5.0).Q(2.0))
    np.testing.assert_array_equal(model.position_index, [0, 3])
    np.testing.assert_array_equal(constant_acceleration(2, 1.0).velocity_index, [1, 4])


def test_motion_model_validation():
    with pytest.raises(ValueError, match="at least one axis"):
        MotionModel([])
    with pytest.raises(ValueError, match="same order"):
        MotionModel([ConstantVelocityAxis(1.0), ConstantAccelerationAxis(1.0)])


def test_embed_position():
    model = constant_acceleration(2, 1.0)
    x = model.embed_position(np.array([[10.0, 20.0], [-1.0, 2.0]]))
    np.testing.assert_array_equal(x, [[10.0, 0, 0, 20.0, 0, 0], [-1.0, 0, 0, 2.0, 0, 0]])


def test_block_diag_batch():
    a = np.arange(8.0).reshape(2, 2, 2)
    b = np.arange(18.0).reshape(2, 3, 3)
    out = block_diag_batch([a, b])
    assert out.shape == (2, 5, 5)
    np.testing.assert_array_equal(out[1, :2, :2], a[1])
    np.testing.assert_array_equal(out[1, 2:, 2:], b[1])
    assert not out[:, :2, 2:].any() and not out[:, 2:, :2].any()

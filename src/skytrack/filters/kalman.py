"""Kalman filter (and EKF through the measurement model's Jacobian) on the batched protocol.

* predict — spec 000 Theorem 2 / (5): ``x' = F x``, ``P' = F P F^T + s Q`` with the
  transition model's ``F(|dt|)``, ``Q(|dt|)`` and a per-row process-noise factor ``s``
  (``context["q_scale"]``, used by the manoeuvre switch).  A negative ``dt`` (sectors of
  merged sensors overlap) extrapolates backwards with the Moore-Penrose inverse of
  ``F(|dt|)``: the inverse for every nonsingular transition, and for the singular m = 3
  embedding of CV and CT (spec 004, zero acceleration rows) the embedded model run back
  with the acceleration kept at zero.
* innovate — ``nu = z - h(x)`` (the measurement model forms it), ``S = H P H^T + R``,
  Cholesky factor, ``d^2 = nu^T S^-1 nu`` (spec 000 R7), ``ln det S`` and the Gaussian
  log-likelihood.
* update — gain ``K = P H^T S^-1`` from the innovation's Cholesky factor (no
  recomputation), ``x + K nu``, covariance in Joseph form
  ``(I - K H) P (I - K H)^T + K R K^T`` (default) or the literal ``P - K S K^T`` of
  spec 000 (4); both symmetrised.

With ``compiled=True`` (default) the steps run the numba kernels of
:mod:`skytrack.filters.kernels`; ``compiled=False`` is the numpy reference they are tested
against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.core import linalg
from skytrack.filters import kernels
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.models.motion import ConstantVelocityAxis, MotionModel

UPDATE_FORMS = ("joseph", "standard")


@dataclass(eq=False)
class KalmanFilter(BatchFilter):
    """Linear Kalman filter over a :class:`~skytrack.models.motion.MotionModel` (EKF for nonlinear h)."""

    transition: MotionModel
    form: str = "joseph"
    compiled: bool = True

    kind = "kalman"
    capabilities = Capabilities()
    state_type = GaussianState

    def __post_init__(self) -> None:
        if self.form not in UPDATE_FORMS:
            raise ValueError(f"update form must be one of {UPDATE_FORMS}, got {self.form!r}")

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def initiate(self, x: np.ndarray, P: np.ndarray) -> GaussianState:
        return GaussianState(np.array(x, dtype=float), np.array(P, dtype=float))

    # -------------------------------------------------------------------- predict
    def predict(self, state: GaussianState, dt, context: dict | None = None) -> GaussianState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        scale = _row_scale(context, len(state))
        return self.predict_arrays(state.x, state.P, dt, scale)

    def predict_arrays(self, x: np.ndarray, P: np.ndarray, dt: np.ndarray, scale: np.ndarray) -> GaussianState:
        model = self.transition
        if self.compiled and model.identical_axes and type(model.axes[0]) is ConstantVelocityAxis:
            x_new, P_new = kernels.predict_cv(x, P, np.asarray(dt, dtype=float), float(model.axes[0].q),
                                              np.asarray(scale, dtype=float))
            if linalg.is_counting():
                linalg.count("predict_cv", len(x) * (model.ndim * 4 + 2 * model.ndim**2 * 8))
            return GaussianState(x_new, P_new)
        step = np.abs(dt)
        backwards = dt < 0
        if self.compiled and model.identical_axes:
            Fa = model.axes[0].F_batch(step)
            Qa = model.axes[0].Q_batch(step)
            if backwards.any():
                Fa[backwards] = np.linalg.pinv(Fa[backwards])
            x_new, P_new = kernels.predict_blocks(x, P, Fa, Qa, scale)
            if linalg.is_counting():
                o, axes = Fa.shape[-1], model.ndim
                linalg.count("predict_blocks", len(x) * (axes * o * o + 2 * axes * axes * o**3))
            return GaussianState(x_new, P_new)
        F = model.F_batch(step)
        Q = model.Q_batch(step) * scale[:, None, None]
        if backwards.any():
            F[backwards] = np.linalg.pinv(F[backwards])
        return GaussianState(linalg.matvec(F, x), linalg.sandwich(F, P, Q))

    # -------------------------------------------------------------------- innovate
    def innovate(self, state: GaussianState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        return innovate_gaussian(state, z, model, context, self.compiled)

    # -------------------------------------------------------------------- update
    def update(self, state: GaussianState, z: np.ndarray, innovation: Innovation) -> tuple[GaussianState, UpdateStats]:
        predicted = innovation.predicted
        x, P = predicted.x, predicted.P
        H, R, nu, L = innovation.H, innovation.R, innovation.nu, innovation.chol
        if self.compiled and self.form == "joseph" and not self.recorder.active:
            x_new, P_new = kernels.update_dense(x, P, np.ascontiguousarray(H), R, nu, L)
            if linalg.is_counting():
                rows, m, n = H.shape
                linalg.count("update_dense", rows * (2 * n * n * m + 2 * n * m * m + n * m + n**3 + n * n * (n + m)))
        else:
            PHt = linalg.matmul(P, np.swapaxes(H, -1, -2))
            K = np.swapaxes(linalg.cho_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)
            x_new = x + linalg.matvec(K, nu)
            if self.form == "joseph":
                A = np.eye(x.shape[-1]) - linalg.matmul(K, H)
                P_new = linalg.sandwich(A, P, linalg.sandwich(K, R))
            else:
                P_new = linalg.symmetrize(P - linalg.matmul(linalg.matmul(K, innovation.S), np.swapaxes(K, -1, -2)))
            self.recorder.record("gain", np.arange(len(x)), gain=K)
        return GaussianState(x_new, P_new), UpdateStats(innovation.d2 / innovation.m)


def innovate_gaussian(state: GaussianState, z: np.ndarray, model, context: dict | None = None,
                      compiled: bool = True) -> Innovation:
    """Innovation of ``z`` against Gaussian estimates ``state`` through measurement ``model``
    (the Kalman filter's innovate; mixtures and banks use it for their moment-matched estimate)."""
    H, R, nu, m = measurement_terms(state.x, z, model, context)
    if compiled:
        S, L, d2, logdet, ok = kernels.innovate_dense(state.P, np.ascontiguousarray(H), R, nu)
        if not ok.all():
            raise ValueError("innovation covariance is not positive definite")
        if linalg.is_counting():
            rows, mm, n = H.shape
            linalg.count("innovate_dense", rows * (mm * n * n + mm * mm * n + linalg.cholesky_cost(mm) + mm * mm + mm))
    else:
        S = linalg.sandwich(H, state.P, R)
        L = linalg.cholesky(S)
        d2 = linalg.mahalanobis_chol(nu, L)
        logdet = linalg.logdet_chol(L)
    loglik = linalg.gaussian_loglik(d2, logdet, m)
    return Innovation(nu, S, L, d2, logdet, loglik, m, H, R, state)


def _row_scale(context: dict | None, rows: int) -> np.ndarray:
    if context is None or context.get("q_scale") is None:
        return np.ones(rows)
    return np.broadcast_to(np.asarray(context["q_scale"], dtype=float), (rows,)).copy()

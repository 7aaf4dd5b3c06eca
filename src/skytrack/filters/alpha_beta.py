"""Batched Cartesian α–β and α–β–γ filters with constant per-axis gains (spec 004 §3.3 C, R4, R20).

Per axis i the gain is ``K_i = [α_i, β_i/T(, γ_i/(2T²))]`` with T the design ``period``; the
motion model's order selects α–β (order 2) or α–β–γ (order 3), and its per-axis ``F`` is the
transition (the polynomial F for the CV/CA/polynomial models, for which this is exactly the
filter of §3.3 C).  Steps:

* predict: ``x⁻ = F(dt) x`` per axis (a negative ``dt`` extrapolates backwards with ``F(|dt|)⁻¹``);
* update: ``x = x⁻ + K ν`` with ``ν`` the position innovation of each axis — constant gains,
  nothing depends on R or on a covariance;
* optional start-up (``startup=True``): the k-th update of a row uses the growing-memory
  least-squares gains of :func:`~skytrack.filters.alpha_beta_gains.startup_gains` until the first
  k whose α_k is <= the axis's α (exact least-squares line / parabola through all measurements).

The filter has no covariance of its own (``has_covariance=False``, ``gain_depends_on_r=False``),
but R20 gates with, and computes NEES from, the steady-state covariance of R4, so the state
carries the covariance ``estimate()`` reports:

* after a steady-gain update with measurement covariance R (rows ``[ndim, ndim]``, axes may be
  correlated): the steady-state filtered error covariance of these gains, ``P = Σ_ij R_ij M_ij +
  blockdiag(P_Q,i)`` — the Lyapunov equation ``P = A P Aᵀ + (I−KH) Q (I−KH)ᵀ + K R Kᵀ`` (A, K
  block-diagonal per axis, Q of the motion model at T) is linear in R and Q, so its solution is
  pre-computed per axis pair (``M_ij = A_i M_ij A_jᵀ + K_i K_jᵀ``) and only combined per row;
* predict by ``dt = T`` from that state: the steady-state predicted covariance (same form, so the
  innovation covariance is R20's steady-state S); any other step, or a state that is not at the
  steady state: ``F P Fᵀ + Q(dt)``;
* during start-up the steady state does not apply (the first gains are 1 and 3): the covariance
  is then the exact error covariance of the gains used, Joseph form
  ``(I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`` (this also covers the rows' initial P).

Gain history goes to the recorder channel ``"gain"`` (``gain[N, n, ndim]``) when it is active.
Registered kind: ``"alpha-beta"`` (options: ``gain_rule``, its parameter, ``period``,
``startup``; see :func:`_alpha_beta`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg as sla

from skytrack.core import linalg
from skytrack.filters import alpha_beta_gains as gains
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.registry import register_filter
from skytrack.models.motion import MotionModel, block_diag_batch

#: relative tolerance within which a step equals the design period (steady-state prediction)
PERIOD_MATCH_RTOL = 1e-9


@dataclass
class AlphaBetaState(GaussianState):
    """``x[N, n]``; ``P[N, n, n]`` the covariance ``estimate()`` reports (module docstring);
    ``R[N, ndim, ndim]`` the measurement covariance of the last update; ``steady[N]`` whether
    ``P`` is the steady-state filtered covariance for that R; ``updates[N]`` updates so far."""

    R: np.ndarray
    steady: np.ndarray
    updates: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, self.P)

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """New estimate for ``rows``: its P is propagated until the next update (start-up count kept)."""
        self.x[rows] = x
        self.P[rows] = P
        self.steady[rows] = False


@dataclass(eq=False)
class AlphaBetaFilter(BatchFilter):
    """Constant-gain α–β (order-2 motion) or α–β–γ (order-3 motion) filter, gains per axis.

    ``alpha``, ``beta`` (and ``gamma`` for order 3) are scalars or one value per axis, in the
    dimensionless units of §3.3 C; ``period`` is the design step T of the velocity and
    acceleration gains and of the steady-state covariance.  ``compiled`` is accepted for the
    registry and ignored (the steps are a few elementwise operations).
    """

    transition: MotionModel
    alpha: float | np.ndarray
    beta: float | np.ndarray
    gamma: float | np.ndarray | None = None
    period: float = 1.0
    startup: bool = False
    compiled: bool = True

    kind = "alpha-beta"
    capabilities = Capabilities(has_covariance=False, gain_depends_on_r=False)
    state_type = AlphaBetaState

    def __post_init__(self) -> None:
        motion = self.transition
        order, ndim = motion.order, motion.ndim
        if order not in (2, 3):
            raise ValueError(f"alpha-beta: the motion model must have order 2 (alpha-beta) or 3 "
                             f"(alpha-beta-gamma) states per axis, got {order}")
        if (self.gamma is None) != (order == 2):
            raise ValueError("alpha-beta: gamma must be given for an order-3 motion (alpha-beta-gamma) "
                             "and only then")
        T = self.period = float(self.period)
        if not (np.isfinite(T) and T > 0):
            raise ValueError(f"alpha-beta: period must be finite and > 0, got {self.period}")

        def per_axis(value, name):
            arr = np.asarray(value, dtype=float)
            if arr.ndim > 1 or (arr.ndim == 1 and len(arr) != ndim):
                raise ValueError(f"alpha-beta: {name} must be a scalar or one value per axis ({ndim}), got {value}")
            return np.broadcast_to(arr, (ndim,)).copy()

        self._alpha = per_axis(self.alpha, "alpha")
        self._beta = per_axis(self.beta, "beta")
        self._gamma = None if self.gamma is None else per_axis(self.gamma, "gamma")
        gains.check_stable(self._alpha, self._beta, self._gamma, option="alpha-beta gains")
        self._K = gains.gain_vector(self._alpha, self._beta, self._gamma, T)  # [ndim, m]
        self._scale = gains.gain_vector(1.0, 1.0, None if order == 2 else 1.0, T)  # unit gains -> K units
        F_axes = [ax.F_batch(np.array([T]))[0] for ax in motion.axes]
        Q_axes = [ax.Q_batch(np.array([T]))[0] for ax in motion.axes]
        I_KH = [np.eye(order) - np.outer(self._K[i], np.eye(order)[0]) for i in range(ndim)]
        A = [I_KH[i] @ F_axes[i] for i in range(ndim)]
        radius = [float(np.max(np.abs(np.linalg.eigvals(a)))) for a in A]
        if max(radius) >= 1.0:
            raise ValueError(f"alpha-beta gains: (I - K H) F(period) of the motion model has spectral radius "
                             f"{max(radius):.6g} >= 1 (unstable with this motion model and period {T})")
        # steady state, linear in R and Q (module docstring)
        M = np.zeros((ndim, ndim, order, order))
        for i in range(ndim):
            for j in range(i, ndim):
                M[i, j] = _stein(A[i], A[j], np.outer(self._K[i], self._K[j]))
                M[j, i] = M[i, j].T
        PQ = [sla.solve_discrete_lyapunov(A[i], I_KH[i] @ Q_axes[i] @ I_KH[i].T) for i in range(ndim)]
        PQ = [0.5 * (p + p.T) for p in PQ]
        self._M_filtered = M
        self._M_predicted = np.einsum("iab,ijbc,jdc->ijad", np.array(F_axes), M, np.array(F_axes))
        self._PQ_filtered = block_diag_batch([p[None] for p in PQ])[0]
        self._PQ_predicted = block_diag_batch([(F_axes[i] @ PQ[i] @ F_axes[i].T + Q_axes[i])[None]
                                               for i in range(ndim)])[0]
        self._PQ_predicted = 0.5 * (self._PQ_predicted + self._PQ_predicted.T)
        if self.startup and np.any(self._alpha > 1.0):
            raise ValueError(f"alpha-beta: startup needs a steady alpha <= 1 on every axis, got {self._alpha}")
        # first update index served by the steady gains, per axis (1: no start-up)
        self._startup_length = np.array([gains.startup_length(a, order) if self.startup else 1 for a in self._alpha])
        self._pos = motion.position_index
        self._selector = np.zeros((ndim, motion.dim))
        self._selector[np.arange(ndim), self._pos] = 1.0

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    @property
    def gains(self) -> np.ndarray:
        """Steady gains ``K[ndim, m] = [α, β/T(, γ/(2T²))]`` per axis."""
        return self._K.copy()

    def steady_state(self, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Steady-state filtered and predicted covariances ``[N, n, n]`` for measurement covariances
        ``R[N, ndim, ndim]`` (the motion model's Q at ``period`` as the process noise)."""
        R = np.asarray(R, dtype=float)
        return self._combine(R, self._M_filtered, self._PQ_filtered), self._combine(R, self._M_predicted, self._PQ_predicted)

    def _combine(self, R: np.ndarray, M: np.ndarray, PQ: np.ndarray) -> np.ndarray:
        rows, n = len(R), self.transition.dim
        P = np.einsum("kij,ijab->kiajb", R, M).reshape(rows, n, n) + PQ
        if linalg.is_counting():
            linalg.count("alpha_beta_steady_covariance", rows * n * n)
        return P

    def initiate(self, x: np.ndarray, P: np.ndarray) -> AlphaBetaState:
        x = np.array(x, dtype=float)
        rows, ndim = len(x), self.transition.ndim
        return AlphaBetaState(x, np.array(P, dtype=float), np.zeros((rows, ndim, ndim)), np.zeros(rows, dtype=bool),
                              np.zeros(rows, dtype=np.int64))

    # -------------------------------------------------------------------- predict
    def _axis_transitions(self, step: np.ndarray, backwards: np.ndarray) -> np.ndarray:
        """Per-axis ``F[N, ndim, m, m]`` for the steps (inverted for the backward rows)."""
        model = self.transition
        if model.identical_axes:
            F = np.repeat(model.axes[0].F_batch(step)[:, None], model.ndim, axis=1)
        else:
            F = np.stack([ax.F_batch(step) for ax in model.axes], axis=1)
        if backwards.any():
            F[backwards] = linalg.inv(F[backwards])
        return F

    def predict(self, state: AlphaBetaState, dt, context: dict | None = None) -> AlphaBetaState:
        rows = len(state)
        dt = np.broadcast_to(self.transition_dt(dt), (rows,))
        step, backwards = np.abs(dt), dt < 0
        model = self.transition
        F = self._axis_transitions(step, backwards)
        x = linalg.matvec(F, state.x.reshape(rows, model.ndim, model.order)).reshape(rows, model.dim)
        P = np.empty_like(state.P)
        at_period = state.steady & (np.abs(dt - self.period) <= PERIOD_MATCH_RTOL * self.period)
        if at_period.any():
            P[at_period] = self._combine(state.R[at_period], self._M_predicted, self._PQ_predicted)
        other = ~at_period
        if other.any():
            F_full = block_diag_batch([F[other, i] for i in range(model.ndim)])
            P[other] = linalg.sandwich(F_full, state.P[other], model.Q_batch(step[other]))
        return AlphaBetaState(x, P, state.R.copy(), state.steady & (dt == 0), state.updates.copy())

    # -------------------------------------------------------------------- innovate
    def innovate(self, state: AlphaBetaState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        H, R, nu, m = measurement_terms(state.x, z, model, context)
        if H.shape[1:] != self._selector.shape or not np.array_equal(H, np.broadcast_to(self._selector, H.shape)):
            raise ValueError("alpha-beta filters take the position of every axis as the measurement "
                             "(H must select the positions; no range rate or partial measurements)")
        if not np.all(np.isfinite(nu)):
            raise ValueError("non-finite measurement or innovation")
        pos = self._pos
        S = state.P[:, pos[:, None], pos[None, :]] + R
        if linalg.is_counting():
            linalg.count("alpha_beta_innovation_covariance", len(S) * S.shape[-1] ** 2)
        L = linalg.cholesky(S)
        d2 = linalg.mahalanobis_chol(nu, L)
        logdet = linalg.logdet_chol(L)
        return Innovation(nu, linalg.symmetrize(S), L, d2, logdet, linalg.gaussian_loglik(d2, logdet, m), m, H, R, state)

    # -------------------------------------------------------------------- update
    def row_gains(self, updates: np.ndarray) -> np.ndarray:
        """Gains ``[N, ndim, m]`` of the next update of rows that have had ``updates`` updates."""
        rows, ndim = len(updates), self.transition.ndim
        K = np.broadcast_to(self._K, (rows,) + self._K.shape).copy()
        if self.startup:
            k = updates + 1
            early = k[:, None] < self._startup_length[None, :]  # [N, ndim]
            if early.any():
                start = np.stack(np.broadcast_arrays(*gains.startup_gains(np.maximum(k, 1), self.transition.order)),
                                 axis=-1) * self._scale  # [N, m]
                K = np.where(early[..., None], np.repeat(start[:, None, :], ndim, axis=1), K)
        return K

    def update(self, state: AlphaBetaState, z: np.ndarray, innovation: Innovation) -> tuple[AlphaBetaState, UpdateStats]:
        pred = innovation.predicted
        rows, model = len(pred), self.transition
        n, ndim, order = model.dim, model.ndim, model.order
        K = self.row_gains(pred.updates)
        x = pred.x + (K * innovation.nu[:, :, None]).reshape(rows, n)
        if linalg.is_counting():
            linalg.count("alpha_beta_update", rows * n)
        transient = pred.updates + 1 < self._startup_length.max()
        P = np.empty_like(pred.P)
        steady = ~transient
        if steady.any():
            P[steady] = self._combine(innovation.R[steady], self._M_filtered, self._PQ_filtered)
        if transient.any() or self.recorder.active:
            K_full = np.zeros((rows, n, ndim))
            K_full[:, np.arange(ndim)[:, None] * order + np.arange(order)[None, :], np.arange(ndim)[:, None]] = K
            if transient.any():
                Kt = K_full[transient]
                A = np.eye(n) - linalg.matmul(Kt, np.broadcast_to(self._selector, (len(Kt),) + self._selector.shape))
                P[transient] = linalg.sandwich(A, pred.P[transient], linalg.sandwich(Kt, innovation.R[transient]))
            self.recorder.record("gain", np.arange(rows), gain=K_full)
        new = AlphaBetaState(x, P, np.array(innovation.R, dtype=float), steady, pred.updates + 1)
        return new, UpdateStats(innovation.d2 / innovation.m)


def _stein(A1: np.ndarray, A2: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``X = A1 X A2ᵀ + C``: the discrete Lyapunov equation when ``A1 = A2``, else its Kronecker form."""
    if np.array_equal(A1, A2):
        return sla.solve_discrete_lyapunov(A1, C)
    m = len(A1)
    # row-major vec: vec(A1 X A2^T) = (A1 kron A2) vec(X)
    return np.linalg.solve(np.eye(m * m) - np.kron(A1, A2), C.reshape(-1)).reshape(m, m)


@register_filter("alpha-beta")
def _alpha_beta(motion: MotionModel, compiled: bool = True, gain_rule: str = "kalata", alpha=None, beta=None,
                gamma=None, tracking_index=None, theta=None, period: float = 1.0,
                startup: bool = False) -> AlphaBetaFilter:
    """α–β for order-2 motions, α–β–γ for order-3 motions; gains by ``gain_rule`` (one of
    ``fixed``, ``benedict-bordner``, ``kalata``, ``critically-damped``) from its parameter(s),
    scalars or one per axis.  Default: Kalata with ``tracking_index = 1`` (α–β: α = 0.75, β = 0.5)."""
    if motion.order not in (2, 3):
        raise ValueError(f"alpha-beta: the motion model must have order 2 or 3, got {motion.order}")
    if gain_rule == "kalata" and all(v is None for v in (alpha, beta, gamma, tracking_index, theta)):
        tracking_index = 1.0
    a, b, g = gains.design_gains(gain_rule, motion.order, alpha=alpha, beta=beta, gamma=gamma,
                                 tracking_index=tracking_index, theta=theta)
    return AlphaBetaFilter(motion, a, b, g, period=period, startup=startup, compiled=compiled)

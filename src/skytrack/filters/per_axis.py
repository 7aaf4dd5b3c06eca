"""Kalman filter with separate processing per coordinate axis (spec 004 §3.3 D, R6), and the
axis-block pieces it shares with the transformed-gain filter (§3.3 G, :mod:`.transformed_gain`).

Per-axis processing (the paper's item 3): the covariance is kept block-diagonal, one ``m x m``
block per Cartesian axis (:class:`AxisBlockState`, ``P_axes[N, ndim, m, m]``; cross-axis
covariances are never formed).  Prediction runs per block with the axis model's ``F``, ``Q``;
the update uses only the diagonal of ``R`` (the converted-measurement cross-covariances are
dropped), so each axis is a scalar-measurement Kalman filter (§3.3 A) with the Joseph form
``P_i = (I - k_i h^T) P_i^- (I - k_i h^T)^T + r_i k_i k_i^T``, ``k_i = P_i^- h / s_i``,
``s_i = h^T P_i^- h + r_i``.  The filter's innovation covariance is ``diag(s_i)``: ``d^2``,
``ln det S`` and the log-likelihood are those of the per-axis filter.  It equals the coupled
filter when R is diagonal and P0, Q are block-diagonal (TV18 a); ``initiate`` keeps only the
diagonal blocks of the given P0.

``per_axis=False`` gives the coupled Kalman filter of §3.3 A (the composed
:class:`~skytrack.filters.kalman.KalmanFilter`, Gaussian states), so studies switch between the
two with one flag.

The measurement must measure each axis by one row of ``H`` that touches only that axis (the
positions of :class:`~skytrack.models.converted.ConvertedPositionModel`); other models raise
ValueError.  Axis models may differ between axes.  ``context["q_scale"]`` multiplies Q per row
as in the Kalman filter.  The gain used (``K[N, n, ndim]``, block-structured) goes to the
recorder channel ``"gain"``.  There is no compiled kernel: ``compiled`` only reaches the coupled
filter of ``per_axis=False``.  Every product goes through :mod:`skytrack.core.linalg`, so
``linalg.counting()`` measures the saving over the coupled filter (R22, study E8).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.core import linalg
from skytrack.filters.base import (
    ArrayState,
    BatchFilter,
    Capabilities,
    GaussianState,
    Innovation,
    measurement_terms,
    Recorder,
    UpdateStats,
)
from skytrack.filters.kalman import KalmanFilter
from skytrack.models.motion import MotionModel


# ---------------------------------------------------------------------------- shared pieces
class RecorderSharing:
    """Mixin of filters composed over an inner ``self.kalman``: both report to one recorder."""

    @property
    def recorder(self) -> Recorder:
        return self.__dict__.get("_recorder", BatchFilter.recorder)

    @recorder.setter
    def recorder(self, value: Recorder) -> None:
        self.__dict__["_recorder"] = value
        self.kalman.recorder = value


def row_scale(context: dict | None, rows: int) -> np.ndarray:
    """Per-row process-noise factor ``context["q_scale"]`` (1 when absent)."""
    if context is None or context.get("q_scale") is None:
        return np.ones(rows)
    return np.broadcast_to(np.asarray(context["q_scale"], dtype=float), (rows,)).copy()


def axis_blocks(P: np.ndarray, ndim: int) -> np.ndarray:
    """The diagonal ``m x m`` blocks ``[N, ndim, m, m]`` of axis-major covariances ``P[N, n, n]``."""
    rows, n = P.shape[0], P.shape[-1]
    m = n // ndim
    blocks = P.reshape(rows, ndim, m, ndim, m)
    return np.ascontiguousarray(blocks[:, np.arange(ndim), :, np.arange(ndim), :].transpose(1, 0, 2, 3))


def block_diagonal(blocks: np.ndarray) -> np.ndarray:
    """Axis-major block-diagonal matrices ``[N, n, n]`` from blocks ``[N, ndim, m, m]``."""
    rows, ndim, m, _ = blocks.shape
    out = np.zeros((rows, ndim, m, ndim, m))
    out[:, np.arange(ndim), :, np.arange(ndim), :] = blocks.transpose(1, 0, 2, 3)
    return out.reshape(rows, ndim * m, ndim * m)


def axis_transitions(motion: MotionModel, dt: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis ``F`` and ``scale * Q`` for steps ``dt[N]``: ``[N, 1, m, m]`` when all axes share one
    model (broadcast over the axes), else ``[N, ndim, m, m]``.  A negative step extrapolates back with
    ``F(|dt|)^-1`` (as the Kalman filter) and still adds ``Q(|dt|)``."""
    step = np.abs(dt)
    axes = motion.axes[:1] if motion.identical_axes else motion.axes
    F = np.stack([ax.F_batch(step) for ax in axes], axis=1)
    Q = np.stack([ax.Q_batch(step) for ax in axes], axis=1) * scale[:, None, None, None]
    backwards = dt < 0
    if backwards.any():
        F[backwards] = linalg.inv(F[backwards])
    return F, Q


def predict_axis_blocks(x: np.ndarray, P_axes: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x_i' = F_i x_i``, ``P_i' = F_i P_i F_i^T + Q_i`` per axis block."""
    rows, ndim, m, _ = P_axes.shape
    x_new = linalg.matvec(F, x.reshape(rows, ndim, m)).reshape(rows, ndim * m)
    return x_new, linalg.sandwich(F, P_axes, Q)


def measurement_axes(H: np.ndarray, ndim: int, order: int, who: str) -> np.ndarray:
    """The per-axis measurement vectors ``h[N, ndim, m]`` of an ``H[N, ndim, n]`` whose row i touches
    only axis i; ValueError naming the filter ``who`` otherwise."""
    rows, mz, n = H.shape
    if mz != ndim or n != ndim * order:
        raise ValueError(f"{who}: the measurement must have one component per axis ({ndim}), got {mz}")
    blocks = H.reshape(rows, ndim, ndim, order)
    diagonal = np.arange(ndim)
    h = blocks[:, diagonal, diagonal, :]
    off = blocks.copy()
    off[:, diagonal, diagonal, :] = 0.0
    if np.any(off != 0.0):
        raise ValueError(f"{who}: each measurement component must depend on its own axis only")
    return h


def scalar_innovation_variances(P_axes: np.ndarray, h: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``P_i h`` and ``s_i = h^T P_i h + r_i`` per block (``[N, A, m]``, ``[N, A]``)."""
    Ph = linalg.matvec(P_axes, h)
    s = linalg.matvec(h[..., None, :], Ph)[..., 0] + r
    if not np.all(s > 0.0):
        raise ValueError("innovation covariance is not positive definite")
    return Ph, s


def scalar_joseph_update(P_axes: np.ndarray, h: np.ndarray, Ph: np.ndarray, s: np.ndarray, r: np.ndarray,
                         innovations: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scalar-measurement update of every block: gains ``k_i = P_i h / s_i``, increments
    ``k_i zeta_i`` (``[N, A, m]``) and the Joseph form (valid for any gain, §3.3 A)."""
    rows, A, m, _ = P_axes.shape
    k = Ph / s[..., None]
    if linalg.is_counting():
        linalg.count("scalar_gain", rows * A * m * 2)  # the 1x1 solve for m right-hand sides; k zeta
    increments = k * innovations[..., None]
    I_kh = np.eye(m) - linalg.matmul(k[..., :, None], h[..., None, :])
    rkk = linalg.matmul(k[..., :, None], k[..., None, :]) * r[..., None, None]
    return k, increments, linalg.sandwich(I_kh, P_axes, rkk)


def diagonal_innovation(nu: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``S = diag(s)``, its Cholesky factor, ``d^2 = sum nu_i^2 / s_i`` and ``ln det S``."""
    rows, A = s.shape
    S = np.zeros((rows, A, A))
    L = np.zeros((rows, A, A))
    diagonal = np.arange(A)
    S[:, diagonal, diagonal] = s
    L[:, diagonal, diagonal] = np.sqrt(s)
    d2 = np.sum(nu * nu / s, axis=-1)
    if linalg.is_counting():
        linalg.count("diagonal_d2", rows * 2 * A)
    return S, L, d2, np.sum(np.log(s), axis=-1)


def block_gain(k: np.ndarray) -> np.ndarray:
    """The gain matrix ``K[N, n, ndim]`` of per-axis gains ``k[N, ndim, m]`` (axis i's block in column i)."""
    rows, ndim, m = k.shape
    out = np.zeros((rows, ndim, m, ndim))
    diagonal = np.arange(ndim)
    out[:, diagonal, :, diagonal] = k.transpose(1, 0, 2)
    return out.reshape(rows, ndim * m, ndim)


@dataclass
class AxisBlockState(ArrayState):
    """Estimate ``x[N, n]`` (axis-major) with one covariance block per axis ``P_axes[N, ndim, m, m]``."""

    x: np.ndarray
    P_axes: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, block_diagonal(self.P_axes))

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the estimate of ``rows``; only the diagonal blocks of ``P`` are kept."""
        self.x[rows] = x
        self.P_axes[rows] = axis_blocks(np.asarray(P, dtype=float), self.P_axes.shape[1])


# ---------------------------------------------------------------------------- the filter
@dataclass(eq=False)
class PerAxisKalmanFilter(RecorderSharing, BatchFilter):
    """Kalman filter with a block-diagonal covariance and per-axis scalar updates (``per_axis=True``),
    or the coupled Kalman filter (``per_axis=False``)."""

    transition: MotionModel
    per_axis: bool = True
    compiled: bool = True
    kalman: KalmanFilter = field(init=False, repr=False)

    kind = "kalman-per-axis"
    capabilities = Capabilities()

    def __post_init__(self) -> None:
        if not isinstance(self.per_axis, (bool, np.bool_)):
            raise ValueError(f"per-axis KF: per_axis must be True or False, got {self.per_axis!r}")
        self.kalman = KalmanFilter(self.transition, compiled=self.compiled)
        self.state_type = AxisBlockState if self.per_axis else GaussianState

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def initiate(self, x: np.ndarray, P: np.ndarray):
        if not self.per_axis:
            return self.kalman.initiate(x, P)
        return AxisBlockState(np.array(x, dtype=float), axis_blocks(np.asarray(P, dtype=float), self.transition.ndim))

    def predict(self, state, dt, context: dict | None = None):
        if not self.per_axis:
            return self.kalman.predict(state, dt, context)
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        F, Q = axis_transitions(self.transition, dt, row_scale(context, len(state)))
        return AxisBlockState(*predict_axis_blocks(state.x, state.P_axes, F, Q))

    def innovate(self, state, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        if not self.per_axis:
            return self.kalman.innovate(state, z, model, context)
        H, R, nu, m = measurement_terms(state.x, z, model, context)
        h = measurement_axes(H, self.transition.ndim, self.transition.order, "per-axis KF")
        r = np.diagonal(R, axis1=-2, axis2=-1).copy()
        Ph, s = scalar_innovation_variances(state.P_axes, h, r)
        S, L, d2, logdet = diagonal_innovation(nu, s)
        loglik = linalg.gaussian_loglik(d2, logdet, m)
        return Innovation(nu, S, L, d2, logdet, loglik, m, H, R, state,
                          {"axis_h": h, "axis_r": r, "axis_Ph": Ph, "axis_s": s})

    def update(self, state, z: np.ndarray, innovation: Innovation):
        if not self.per_axis:
            return self.kalman.update(state, z, innovation)
        predicted: AxisBlockState = innovation.predicted
        extra = innovation.extra
        rows, ndim, m, _ = predicted.P_axes.shape
        k, increments, P_axes = scalar_joseph_update(predicted.P_axes, extra["axis_h"], extra["axis_Ph"],
                                                     extra["axis_s"], extra["axis_r"], innovation.nu)
        x = predicted.x + increments.reshape(rows, ndim * m)
        if self.recorder.active:
            self.recorder.record("gain", np.arange(rows), gain=block_gain(k))
        return AxisBlockState(x, P_axes), UpdateStats(innovation.d2 / innovation.m)


# Imported here, after the shared pieces: importing the registry imports every filter module, and the
# siblings that use the pieces above (transformed gain, pseudo-noise, piecewise gain) must
# find them defined even when this module is the one being imported first.
from skytrack.filters.registry import register_filter  # noqa: E402


@register_filter("kalman-per-axis")
def _per_axis(motion: MotionModel, compiled: bool = True, per_axis: bool = True) -> PerAxisKalmanFilter:
    """Per-axis KF (§3.3 D); ``per_axis=False`` is the coupled KF."""
    return PerAxisKalmanFilter(motion, per_axis=per_axis, compiled=compiled)

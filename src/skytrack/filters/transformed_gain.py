"""Transformed-gain filter (spec 004 §3.3 G, R9): skytrack's definition of the paper's "generalised
KF with a transformed weight matrix" (item 4b; the paper gives only the name).

The gain is computed per axis of the sensor's line-of-sight (LOS) frame, where the converted
measurement error is nearly uncorrelated, and transformed to ENU.  The LOS frame at the predicted
position ``p^-`` relative to the sensor: ``u_r = p/|p|``, ``u_a = (z x u_r)/|z x u_r|``,
``u_e = u_r x u_a``, ``C = [u_r, u_a, u_e]`` (2-D: ``C = [u_r, u_a]``, ``u_a`` = ``u_r`` turned by
+90 degrees).  The state keeps the ENU estimate ``x`` and one ``m x m`` covariance block per LOS
axis, ``P_axes[N, ndim, m, m]``, with the frame ``C[N, ndim, ndim]`` they refer to
(:class:`LosBlockState`).  Per scan:

* predict: ``x^- = F x``, ``C_k`` at ``p^-``, ``D = C_k^T C_{k-1}``, ``P_i <- sum_j D_ij^2 P_j`` (block
  rotation, cross-blocks dropped), then each block ``F P_i F^T + Q`` with the one axis model;
* innovate: ``zeta = C_k^T (z - H x^-)``, ``r_i = (C_k^T R C_k)_ii``, ``s_i = h^T P_i h + r_i``; the
  filter's innovation covariance is ``C_k diag(s) C_k^T`` (``d^2 = sum zeta_i^2 / s_i``);
* update: ``k_i = P_i h / s_i``, ``x = x^- + (C_k (x) I_m) blockdiag(k_i) zeta`` — i.e.
  ``K_ENU = (C_k (x) I_m) blockdiag(k_i) C_k^T`` — and the scalar Joseph form per block.

The block rotation and the per-axis prediction commute only for an isotropic model (the same F, Q
on every axis): other models raise ValueError, as does a measurement other than one position-like
component per axis with the same ``h`` on every axis.  Approximations (the price of the saving,
measured in study E8): ``C^T R C`` off-diagonals and the cross-blocks that the rotation would
create are dropped, so the covariance is not the exact one when R is not diagonal in the LOS frame
or the frame turns.  With the LOS frame equal to the ENU axes it is the per-axis filter (TV18 b).

Sensor position: ``context["sensor_position"]`` (``[ndim]`` or ``[N, ndim]``, ENU metres) in
``predict`` when given, else the filter's ``sensor_position`` (default: the ENU origin, spec §3.3
G); ``initiate`` uses the filter's.  A row predicted by 0 s keeps its frame (a zero step changes
nothing).  At the sensor itself the frame is the ENU axes; straight above it ``u_a`` is north.
The gain ``K_ENU[N, n, ndim]`` goes to the recorder channel ``"gain"``; ``compiled`` is accepted and
ignored (no kernel).  Products go through :mod:`skytrack.core.linalg`; the frame construction is
counted as ``los_frame`` (R22: model rebuilding such as frame rotations is part of the cost).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.per_axis import (
    AxisBlockState,
    axis_transitions,
    measurement_axes,
    row_scale,
    scalar_innovation_variances,
    scalar_joseph_update,
)
from skytrack.filters.registry import register_filter
from skytrack.models.motion import MotionModel

#: multiply-adds of one LOS frame (norms, normalisations, cross products), by dimension
FRAME_COST = {2: 6, 3: 18}


def los_frame(p: np.ndarray, sensor: np.ndarray) -> np.ndarray:
    """LOS frames ``C[N, d, d]`` (columns u_r, u_a[, u_e] in ENU) of positions ``p[N, d]`` seen from ``sensor``."""
    rows, d = p.shape
    rel = p - sensor
    rng = np.sqrt(np.sum(rel * rel, axis=-1))
    at_sensor = rng == 0.0
    u_r = np.where(at_sensor[:, None], np.eye(d)[0], rel / np.where(at_sensor, 1.0, rng)[:, None])
    C = np.empty((rows, d, d))
    C[:, :, 0] = u_r
    if d == 2:
        C[:, 0, 1], C[:, 1, 1] = -u_r[:, 1], u_r[:, 0]
    else:
        horizontal = np.hypot(u_r[:, 0], u_r[:, 1])
        overhead = horizontal < 1e-12
        safe = np.where(overhead, 1.0, horizontal)
        u_a = np.stack([np.where(overhead, 0.0, -u_r[:, 1] / safe), np.where(overhead, 1.0, u_r[:, 0] / safe),
                        np.zeros(rows)], axis=-1)
        C[:, :, 1] = u_a
        C[:, :, 2] = np.cross(u_r, u_a)
    if linalg.is_counting():
        linalg.count("los_frame", rows * FRAME_COST[d])
    return C


@dataclass
class LosBlockState(AxisBlockState):
    """ENU estimate ``x[N, n]``, covariance blocks per LOS axis ``P_axes[N, d, m, m]`` and their frame ``C[N, d, d]``."""

    C: np.ndarray

    def estimate(self) -> GaussianState:
        """ENU covariance ``(C (x) I_m) blockdiag(P_i) (C (x) I_m)^T``."""
        rows, d, m, _ = self.P_axes.shape
        P = np.einsum("kai,kbi,kijl->kajbl", self.C, self.C, self.P_axes).reshape(rows, d * m, d * m)
        return GaussianState(self.x, linalg.symmetrize(P))

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the estimate of ``rows``; the covariance is taken into their current frame (cross-blocks dropped)."""
        self.x[rows] = x
        self.P_axes[rows] = frame_blocks(np.asarray(P, dtype=float), self.C[rows])


def frame_blocks(P: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Diagonal blocks ``[N, d, m, m]`` of ENU covariances ``P[N, n, n]`` expressed in frames ``C``."""
    rows, d = C.shape[:2]
    m = P.shape[-1] // d
    return np.einsum("kai,kbi,kajbl->kijl", C, C, P.reshape(rows, d, m, d, m))


@dataclass(eq=False)
class TransformedGainFilter(BatchFilter):
    """Kalman filter with scalar gains in the sensor's LOS frame, transformed to ENU (§3.3 G)."""

    transition: MotionModel
    sensor_position: tuple[float, ...] | None = None
    compiled: bool = True

    kind = "kalman-transformed-gain"
    capabilities = Capabilities()
    state_type = LosBlockState

    def __post_init__(self) -> None:
        ndim = self.transition.ndim
        if ndim not in (2, 3):
            raise ValueError(f"transformed gain: needs a 2-D or 3-D motion model, got {ndim} axes")
        if not self.transition.identical_axes:
            raise ValueError("transformed gain: needs an isotropic motion model (the same F and Q on every axis), "
                             f"got {self.transition!r}")
        sensor = np.zeros(ndim) if self.sensor_position is None else np.asarray(self.sensor_position, dtype=float)
        if sensor.shape != (ndim,) or not np.all(np.isfinite(sensor)):
            raise ValueError(f"transformed gain: sensor_position must be {ndim} finite numbers, got {self.sensor_position!r}")
        self.sensor_position = tuple(float(v) for v in sensor)

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def _sensor(self, context: dict | None, rows: int) -> np.ndarray:
        ndim = self.transition.ndim
        value = self.sensor_position if context is None or context.get("sensor_position") is None \
            else context["sensor_position"]
        return np.broadcast_to(np.asarray(value, dtype=float), (rows, ndim))

    def initiate(self, x: np.ndarray, P: np.ndarray) -> LosBlockState:
        x = np.array(x, dtype=float)
        C = los_frame(x[:, self.transition.position_index], self._sensor(None, len(x)))
        return LosBlockState(x, frame_blocks(np.asarray(P, dtype=float), C), C)

    def predict(self, state: LosBlockState, dt, context: dict | None = None) -> LosBlockState:
        rows = len(state)
        dt = np.broadcast_to(self.transition_dt(dt), (rows,))
        F, Q = axis_transitions(self.transition, dt, row_scale(context, rows))
        x = linalg.matvec(F, state.x.reshape(rows, self.transition.ndim, -1)).reshape(rows, -1)
        C = los_frame(x[:, self.transition.position_index], self._sensor(context, rows))
        C = np.where((dt == 0.0)[:, None, None], state.C, C)
        D = linalg.matmul(np.swapaxes(C, -1, -2), state.C)
        rotated = np.einsum("kij,kjab->kiab", D * D, state.P_axes)
        if linalg.is_counting():
            d, m = D.shape[-1], state.P_axes.shape[-1]
            linalg.count("block_rotation", rows * (d * d + d * d * m * m))
        return LosBlockState(x, linalg.sandwich(F, rotated, Q), C)

    def innovate(self, state: LosBlockState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        H, R, nu, m = measurement_terms(state.x, z, model, context)
        h = measurement_axes(H, self.transition.ndim, self.transition.order, "transformed gain")
        if np.any(h != h[:, :1]):
            raise ValueError("transformed gain: the measurement must be the same function of every axis")
        C = state.C
        Ct = np.swapaxes(C, -1, -2)
        zeta = linalg.matvec(Ct, nu)
        r = np.einsum("kai,kai->ki", C, linalg.matmul(R, C))
        Ph, s = scalar_innovation_variances(state.P_axes, h, r)
        S = linalg.symmetrize(linalg.matmul(C * s[:, None, :], Ct))
        L = linalg.cholesky(S)
        d2 = np.sum(zeta * zeta / s, axis=-1)
        logdet = np.sum(np.log(s), axis=-1)
        if linalg.is_counting():
            d = C.shape[-1]
            linalg.count("los_innovation", len(s) * (d * d + 2 * d))  # diag(C^T R C), C diag(s), d^2
        loglik = linalg.gaussian_loglik(d2, logdet, m)
        return Innovation(nu, S, L, d2, logdet, loglik, m, H, R, state,
                          {"axis_h": h, "axis_r": r, "axis_Ph": Ph, "axis_s": s, "los_zeta": zeta})

    def update(self, state: LosBlockState, z: np.ndarray, innovation: Innovation) -> tuple[LosBlockState, UpdateStats]:
        predicted: LosBlockState = innovation.predicted
        extra = innovation.extra
        rows, d, m, _ = predicted.P_axes.shape
        k, increments, P_axes = scalar_joseph_update(predicted.P_axes, extra["axis_h"], extra["axis_Ph"],
                                                     extra["axis_s"], extra["axis_r"], extra["los_zeta"])
        C = predicted.C
        x = predicted.x + linalg.matmul(C, increments).reshape(rows, d * m)
        if self.recorder.active:
            gain = np.einsum("kai,kij,kbi->kajb", C, k, C).reshape(rows, d * m, d)
            self.recorder.record("gain", np.arange(rows), gain=gain)
        return LosBlockState(x, P_axes, C), UpdateStats(innovation.d2 / innovation.m)


@register_filter("kalman-transformed-gain")
def _transformed_gain(motion: MotionModel, compiled: bool = True, sensor_position=None) -> TransformedGainFilter:
    """Transformed-gain filter (§3.3 G); isotropic motion models only."""
    return TransformedGainFilter(motion, sensor_position=sensor_position, compiled=compiled)

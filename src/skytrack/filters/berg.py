"""Berg-type target-frame acceleration model and its two filters: spec 004 §3.3 M, R15 (study E5, R22).

State: axis-major, three states per ENU axis, ``x = [x, vx, ax, y, vy, ay, z, vz, az]``.  The
target frame ``C = [t, n, b]`` (columns in ENU) comes from the velocity estimate: ``t = v/|v|``,
``n = (z x t)/|z x t|`` (horizontal, to the left), ``b = t x n``; when ``|z x t| < 1e-6`` (vertical
flight) the previous ``n`` is kept (made orthogonal to the new ``t``), and a zero velocity keeps
the previous frame (:func:`target_frame`).  Each frame axis is a Singer channel (tangential,
normal, binormal: ``(tau, sigma)`` each; F and Q from :class:`~skytrack.models.motion.SingerAxisModel`
with the exact discretisation, the known-input response B from
:func:`skytrack.models.discretize.singer_input`).  A coordinated turn's mean jerk
``omega = (v x a)/|v|^2``, ``j = omega x a`` enters as the known input ``j_f = C^T j`` (flag
``mean_jerk``, :func:`mean_jerk`).

* ``berg_full`` (:class:`BergFullFilter`): a 9x9 Kalman filter (§3.3 A, Joseph form) with
  ``F = (C kron I3) blockdiag(F_t, F_n, F_b) (C kron I3)^T``, Q likewise and input
  ``(C kron I3) blockdiag(B_t, B_n, B_b) j_f``.
* ``berg_frame`` (:class:`BergFrameFilter`, the paper's "modified" model): the covariance is three
  3x3 blocks, one per frame axis.  Per channel ``xi_i = F_i xi_i + B_i j_f,i``,
  ``P_i = F_i P_i F_i^T + Q_i``; the position measurement is taken to the frame, ``zeta = C^T z``,
  with ``r_i = (C^T R C)_ii`` (off-diagonal terms dropped), and each channel takes a scalar
  update.  When the frame changes, ``D = C_k^T C_{k-1}`` and ``P_i <- sum_j D_ij^2 P_j`` (flag
  ``block_rotation``; without it the blocks keep their numbers in the new frame).

Frames.  ``berg_full`` keeps the frame of its current velocity estimate (evaluated at
``initiate`` and at the end of every predict and update), so its predict of scan k is built in
``C_k`` from ``v_{k-1}``.  ``berg_frame`` follows §3.3 M's order: its predict evaluates ``C_k``
from the state's velocity (``v_{k-1}`` after an update, the predicted one when a track coasts),
rotates the blocks from the stored ``C_{k-1}`` into it, predicts the channels, and the update of
scan k uses the same ``C_k``.  Both filters therefore use the same frames.  Because the rotation
drops the cross blocks, a zero-length prediction of ``berg_frame`` right after an update is not
the identity (``Capabilities(zero_dt_identity=False)``, as for a mixing step).

Registered kinds ``"berg-full"`` and ``"berg-frame"`` (options ``tangential``, ``normal``,
``binormal`` as ``(tau, sigma)``, ``mean_jerk``, and ``block_rotation`` for the frame filter)
accept only 3-axis motions with 3 states per axis.  A channel not given takes the Singer
parameters of the motion's axis with the same index when that axis is Singer, else the spec §6
default (:data:`SPEC_CHANNELS`: (60 s, 3), (15 s, 40), (30 s, 10) m/s^2).

Every product goes through :mod:`skytrack.core.linalg`; the frame and mean-jerk arithmetic
(cross products, norms) is counted in the R22 model as its multiplications.  Recorder channels:
``"gain"`` (the gain of each update: 9x3 for the full filter, one 3-vector per channel for the
frame filter) and ``"mean_jerk"`` (``j_f`` per predicted row).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.core import linalg
from skytrack.filters.base import ArrayState, BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.registry import register_filter
from skytrack.models.discretize import singer_input
from skytrack.models.motion import MotionModel, SingerAxisModel

#: spec 004 §6 defaults: (tau s, sigma m/s^2) of the tangential, normal and binormal channels
SPEC_CHANNELS = ((60.0, 3.0), (15.0, 40.0), (30.0, 10.0))
CHANNEL_NAMES = ("tangential", "normal", "binormal")
#: |z x t| below which the previous normal is kept (§3.3 M)
VERTICAL_LIMIT = 1e-6
#: speeds (m/s) at or below which the velocity has no direction: the previous frame is kept
MIN_SPEED = 1e-9
#: multiplications counted per row for one frame evaluation and one mean-jerk evaluation
_FRAME_MADDS = 28
_JERK_MADDS = 18
_VELOCITY = np.array([1, 4, 7])
_ACCELERATION = np.array([2, 5, 8])
_POSITION = np.array([0, 3, 6])


# ---------------------------------------------------------------------------- frame and jerk
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    norm = np.sqrt(np.sum(v * v, axis=-1))
    safe = np.where(norm > 0.0, norm, 1.0)
    return v / safe[..., None], norm


def target_frame(v: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
    """Frames ``C[K, 3, 3]`` (columns t, n, b in ENU) of velocities ``v[K, 3]`` (§3.3 M).

    ``previous[K, 3, 3]`` (default: the ENU axes) supplies the normal when ``|z x t| < 1e-6``
    (kept, minus its component along the new ``t``; its binormal if the normal is parallel to
    ``t``) and the whole frame when ``|v| <= 1e-9`` m/s.
    """
    v = np.asarray(v, dtype=float)
    rows = len(v)
    if previous is None:
        previous = np.broadcast_to(np.eye(3), (rows, 3, 3))
    t, speed = _unit(v)
    moving = speed > MIN_SPEED
    t = np.where(moving[:, None], t, previous[:, :, 0])
    horizontal = np.stack([-t[:, 1], t[:, 0], np.zeros(rows)], axis=-1)  # z x t
    n_new, h_norm = _unit(horizontal)
    kept = previous[:, :, 1] - np.sum(previous[:, :, 1] * t, axis=-1, keepdims=True) * t
    kept_b = previous[:, :, 2] - np.sum(previous[:, :, 2] * t, axis=-1, keepdims=True) * t
    kept, kept_norm = _unit(kept)
    kept = np.where((kept_norm > VERTICAL_LIMIT)[:, None], kept, _unit(kept_b)[0])
    n = np.where((h_norm >= VERTICAL_LIMIT)[:, None], n_new, kept)
    C = np.stack([t, n, _cross(t, n)], axis=-1)
    C = np.where(moving[:, None, None], C, previous)
    if linalg.is_counting():
        linalg.count("berg_frame_axes", rows * _FRAME_MADDS)
    return C


def mean_jerk(v: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinated-turn rate ``omega = (v x a)/|v|^2`` and mean jerk ``j = omega x a`` (ENU, ``[K, 3]``).

    Both are zero for a velocity of at most 1e-9 m/s.
    """
    v, a = np.asarray(v, dtype=float), np.asarray(a, dtype=float)
    speed2 = np.sum(v * v, axis=-1)
    moving = speed2 > MIN_SPEED**2
    omega = _cross(v, a) / np.where(moving, speed2, 1.0)[:, None]
    omega = np.where(moving[:, None], omega, 0.0)
    if linalg.is_counting():
        linalg.count("berg_mean_jerk", len(v) * _JERK_MADDS)
    return omega, _cross(omega, a)


# ---------------------------------------------------------------------------- channels
def _check_channel(name: str, value) -> tuple[float, float]:
    try:
        tau, sigma = (float(item) for item in value)
    except (TypeError, ValueError):
        raise ValueError(f"berg: {name} must be a pair (tau s, sigma m/s^2), got {value!r}") from None
    if not (math.isfinite(tau) and tau > 0):
        raise ValueError(f"berg: {name} tau must be finite and > 0, got {tau}")
    if not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"berg: {name} sigma must be finite and >= 0, got {sigma}")
    return tau, sigma


def resolve_channels(motion: MotionModel, tangential=None, normal=None, binormal=None) -> tuple[tuple[float, float], ...]:
    """The ``(tau, sigma)`` of the three channels; ValueError unless ``motion`` has 3 axes of order 3.

    A channel left as None takes the Singer parameters of the motion's axis with the same index
    when that axis is a :class:`SingerAxisModel` (so an isotropic Singer motion gives the Singer
    filter, the model the conformance suite simulates), otherwise the spec §6 default
    (:data:`SPEC_CHANNELS`).
    """
    if motion.ndim != 3 or motion.order != 3:
        raise ValueError("berg: needs a 3-axis motion with 3 states per axis (position, velocity, acceleration), "
                         f"got ndim={motion.ndim}, order={motion.order}")
    out = []
    for index, (name, value) in enumerate(zip(CHANNEL_NAMES, (tangential, normal, binormal))):
        if value is None:
            axis = motion.axes[index]
            value = (axis.tau, axis.sigma_a) if isinstance(axis, SingerAxisModel) else SPEC_CHANNELS[index]
        out.append(_check_channel(name, value))
    return tuple(out)


def _channel_models(channels) -> tuple[SingerAxisModel, ...]:
    return tuple(SingerAxisModel(tau, sigma, "exact") for tau, sigma in channels)


def _channel_matrices(models, taus, dt: np.ndarray):
    """Per-channel ``F[K, 3, 3, 3]``, ``Q[K, 3, 3, 3]`` and input response ``B[K, 3, 3]`` (channel first).

    A negative step runs backwards: ``x = F^-1 (x' - B j)``, so ``F <- F^-1``, ``B <- -F^-1 B``
    with the process noise of ``|dt|``.
    """
    step = np.abs(dt)
    F = np.stack([m.F_batch(step) for m in models], axis=1)
    Q = np.stack([m.Q_batch(step) for m in models], axis=1)
    B = np.stack([singer_input(tau, step) for tau in taus], axis=1)
    back = dt < 0
    if back.any():
        F[back] = linalg.inv(F[back])
        B[back] = -linalg.matvec(F[back], B[back])
    return F, Q, B


def _pair_weights(C: np.ndarray) -> np.ndarray:
    """``M[K, 9, 3]`` with ``M[(a, b), c] = C_ac C_bc``: maps frame blocks to ENU blocks."""
    M = (C[:, :, None, :] * C[:, None, :, :]).reshape(len(C), 9, 3)
    if linalg.is_counting():
        linalg.count("berg_pair_weights", M.size)
    return M


def frame_to_enu(C: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """``(C kron I3) blockdiag(blocks) (C kron I3)^T`` for ``blocks[K, 3, 3, 3]`` -> ``[K, 9, 9]``."""
    rows = len(C)
    flat = linalg.matmul(_pair_weights(C), blocks.reshape(rows, 3, 9))  # [(a, b), (i, j)]
    return flat.reshape(rows, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(rows, 9, 9)


def enu_to_frame_blocks(C: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Diagonal blocks ``[K, 3, 3, 3]`` of ``(C^T kron I3) P (C kron I3)`` (the cross blocks are dropped)."""
    rows = len(C)
    pairs = P.reshape(rows, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(rows, 9, 9)  # [(a, b), (i, j)]
    blocks = linalg.matmul(np.swapaxes(_pair_weights(C), -1, -2), pairs).reshape(rows, 3, 3, 3)
    return linalg.symmetrize(blocks)


# ---------------------------------------------------------------------------- states
@dataclass
class BergFullState(ArrayState):
    """``x[N, 9]``, ``P[N, 9, 9]`` (ENU) and the target frame ``frame[N, 3, 3]`` of ``x``'s velocity."""

    x: np.ndarray
    P: np.ndarray
    frame: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, self.P)

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the estimate of ``rows``; their frame follows the new velocity."""
        self.x[rows] = x
        self.P[rows] = P
        self.frame[rows] = target_frame(x[:, _VELOCITY], self.frame[rows])


@dataclass
class BergFrameState(ArrayState):
    """``x[N, 9]`` (ENU), covariance blocks ``blocks[N, 3, 3, 3]`` per frame axis, ``frame[N, 3, 3]``."""

    x: np.ndarray
    blocks: np.ndarray
    frame: np.ndarray

    def estimate(self) -> GaussianState:
        """ENU estimate: ``P = (C kron I3) blockdiag(blocks) (C kron I3)^T``."""
        return GaussianState(self.x, linalg.symmetrize(frame_to_enu(self.frame, self.blocks)))

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the estimate of ``rows``; their frame follows the new velocity."""
        self.x[rows] = x
        self.frame[rows] = target_frame(x[:, _VELOCITY], self.frame[rows])
        self.blocks[rows] = enu_to_frame_blocks(self.frame[rows], P)


# ---------------------------------------------------------------------------- filters
@dataclass(eq=False)
class _BergFilter(BatchFilter):
    """Channel parameters and the parts both Berg-type filters share."""

    channels: tuple = SPEC_CHANNELS
    mean_jerk: bool = True

    def __post_init__(self) -> None:
        if len(self.channels) != 3:
            raise ValueError(f"berg: channels needs three (tau, sigma) pairs, got {self.channels!r}")
        self.channels = tuple(_check_channel(name, value) for name, value in zip(CHANNEL_NAMES, self.channels))
        if not isinstance(self.mean_jerk, (bool, np.bool_)):
            raise ValueError(f"berg: mean_jerk must be True or False, got {self.mean_jerk!r}")
        self._models = _channel_models(self.channels)
        self._taus = tuple(tau for tau, _ in self.channels)

    @property
    def state_dim(self) -> int:
        return 9

    def _model(self, x, C, dt):
        """Channel ``F``, ``Q``, ``B`` for the row steps and the frame input ``j_f = C^T j`` of states ``x``."""
        dt = np.broadcast_to(self.transition_dt(dt), (len(x),))
        F, Q, B = _channel_matrices(self._models, self._taus, dt)
        if self.mean_jerk:
            _, jerk = mean_jerk(x[:, _VELOCITY], x[:, _ACCELERATION])
            j_f = linalg.matvec(np.swapaxes(C, -1, -2), jerk)
        else:
            j_f = np.zeros((len(x), 3))
        if self.recorder.active:
            self.recorder.record("mean_jerk", np.arange(len(x)), j_f=j_f)
        return F, Q, B, j_f

    @staticmethod
    def _measure(state, z, model, context):
        return measurement_terms(state.x, z, model, context)


@dataclass(eq=False)
class BergFullFilter(_BergFilter):
    """``berg_full``: 9x9 Kalman filter with the frame-rotated Singer channels (§3.3 M)."""

    kind = "berg-full"
    capabilities = Capabilities()
    state_type = BergFullState

    def initiate(self, x: np.ndarray, P: np.ndarray) -> BergFullState:
        x = np.array(x, dtype=float)
        return BergFullState(x, np.array(P, dtype=float), target_frame(x[:, _VELOCITY]))

    def predict(self, state: BergFullState, dt, context: dict | None = None) -> BergFullState:
        rows, C = len(state), state.frame
        F, Q, B, j_f = self._model(state.x, C, dt)
        M = _pair_weights(C)
        # (C kron I3) blockdiag(F_c) (C kron I3)^T entry (a i, b j) = sum_c C_ac C_bc F_c,ij
        F_full = linalg.matmul(M, F.reshape(rows, 3, 9)).reshape(rows, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(rows, 9, 9)
        Q_full = linalg.matmul(M, Q.reshape(rows, 3, 9)).reshape(rows, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(rows, 9, 9)
        u = linalg.matmul(C, B * j_f[:, :, None]).reshape(rows, 9)
        x = linalg.matvec(F_full, state.x) + u
        P = linalg.sandwich(F_full, state.P, linalg.symmetrize(Q_full))
        return BergFullState(x, P, target_frame(x[:, _VELOCITY], C))

    def innovate(self, state: BergFullState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        H, R, nu, m = self._measure(state, z, model, context)
        S = linalg.sandwich(H, state.P, R)
        L = linalg.cholesky(S)
        d2 = linalg.mahalanobis_chol(nu, L)
        logdet = linalg.logdet_chol(L)
        return Innovation(nu, S, L, d2, logdet, linalg.gaussian_loglik(d2, logdet, m), m, H, R, state)

    def update(self, state: BergFullState, z: np.ndarray, innovation: Innovation) -> tuple[BergFullState, UpdateStats]:
        predicted = innovation.predicted
        H, R, L = innovation.H, innovation.R, innovation.chol
        PHt = linalg.matmul(predicted.P, np.swapaxes(H, -1, -2))
        K = np.swapaxes(linalg.cho_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)
        x = predicted.x + linalg.matvec(K, innovation.nu)
        A = np.eye(9) - linalg.matmul(K, H)
        P = linalg.sandwich(A, predicted.P, linalg.sandwich(K, R))
        if self.recorder.active:
            self.recorder.record("gain", np.arange(len(x)), gain=K)
        frame = target_frame(x[:, _VELOCITY], predicted.frame)
        return BergFullState(x, P, frame), UpdateStats(innovation.d2 / innovation.m)


@dataclass(eq=False)
class BergFrameFilter(_BergFilter):
    """``berg_frame``: three 3x3 covariance blocks in the target frame, scalar updates (§3.3 M)."""

    block_rotation: bool = True

    kind = "berg-frame"
    # predict re-expresses the blocks in the frame of the current velocity (dropping the cross
    # blocks), which a zero-length prediction right after an update does too
    capabilities = Capabilities(zero_dt_identity=False)
    state_type = BergFrameState

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.block_rotation, (bool, np.bool_)):
            raise ValueError(f"berg: block_rotation must be True or False, got {self.block_rotation!r}")

    def initiate(self, x: np.ndarray, P: np.ndarray) -> BergFrameState:
        x = np.array(x, dtype=float)
        C = target_frame(x[:, _VELOCITY])
        return BergFrameState(x, enu_to_frame_blocks(C, np.asarray(P, dtype=float)), C)

    def predict(self, state: BergFrameState, dt, context: dict | None = None) -> BergFrameState:
        rows, previous = len(state), state.frame
        C = target_frame(state.x[:, _VELOCITY], previous)
        blocks = state.blocks
        if self.block_rotation:
            D = linalg.matmul(np.swapaxes(C, -1, -2), previous)
            weights = D * D
            if linalg.is_counting():
                linalg.count("berg_block_rotation", weights.size)
            blocks = linalg.matmul(weights, blocks.reshape(rows, 3, 9)).reshape(rows, 3, 3, 3)
        F, Q, B, j_f = self._model(state.x, C, dt)
        xi = linalg.matmul(np.swapaxes(C, -1, -2), state.x.reshape(rows, 3, 3))  # Xi = C^T X
        xi = linalg.matvec(F, xi) + B * j_f[:, :, None]
        blocks = linalg.sandwich(F, blocks, Q)
        x = linalg.matmul(C, xi).reshape(rows, 9)
        return BergFrameState(x, blocks, C)

    def innovate(self, state: BergFrameState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        H, R, nu, m = self._measure(state, z, model, context)
        if H.shape[1] != 3 or not np.array_equal(H, np.broadcast_to(_position_selector(), H.shape)):
            raise ValueError("berg-frame: the measurements must be the three ENU positions (no range rate)")
        C = state.frame
        nu_f = linalg.matvec(np.swapaxes(C, -1, -2), nu)
        r = np.sum(C * linalg.matmul(R, C), axis=1)  # (C^T R C)_ii
        s = state.blocks[:, :, 0, 0] + r
        d2 = np.sum(nu_f * nu_f / s, axis=-1)
        logdet = np.sum(np.log(s), axis=-1)
        # ENU form of the channel-diagonal innovation covariance, for gating and the protocol
        S = linalg.matmul(C * s[:, None, :], np.swapaxes(C, -1, -2))
        if linalg.is_counting():
            linalg.count("berg_frame_innovation", len(C) * 21)  # r (9), d2 (6), C diag(s) (9) less 3 shared
        L = linalg.cholesky(linalg.symmetrize(S))
        extra = {"nu_f": nu_f, "r": r, "s": s}
        return Innovation(nu, S, L, d2, logdet, linalg.gaussian_loglik(d2, logdet, m), m, H, R, state, extra)

    def update(self, state: BergFrameState, z: np.ndarray, innovation: Innovation) -> tuple[BergFrameState, UpdateStats]:
        predicted = innovation.predicted
        rows, C = len(predicted), predicted.frame
        nu_f, r, s = innovation.extra["nu_f"], innovation.extra["r"], innovation.extra["s"]
        xi = linalg.matmul(np.swapaxes(C, -1, -2), predicted.x.reshape(rows, 3, 3))
        K = predicted.blocks[:, :, :, 0] / s[:, :, None]  # per channel: P_i e_0 / s_i
        xi = xi + K * nu_f[:, :, None]
        A = np.broadcast_to(np.eye(3), (rows, 3, 3, 3)).copy()
        A[..., :, 0] -= K
        KK = r[:, :, None, None] * K[..., :, None] * K[..., None, :]
        if linalg.is_counting():
            linalg.count("berg_frame_scalar_update", rows * 3 * (3 + 3 + 9))  # K, K nu, r K K^T
        blocks = linalg.sandwich(A, predicted.blocks, KK)  # Joseph form per channel
        x = linalg.matmul(C, xi).reshape(rows, 9)
        if self.recorder.active:
            self.recorder.record("gain", np.arange(rows), gain=K)
        return BergFrameState(x, blocks, C.copy()), UpdateStats(innovation.d2 / innovation.m)


def _position_selector() -> np.ndarray:
    H = np.zeros((3, 9))
    H[np.arange(3), _POSITION] = 1.0
    return H


def _check_flag(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"berg: {name} must be True or False, got {value!r}")
    return bool(value)


@register_filter("berg-full")
def _berg_full(motion: MotionModel, compiled: bool = True, tangential=None, normal=None, binormal=None,
               mean_jerk: bool = True) -> BergFullFilter:
    """``berg_full`` on a 3-axis order-3 ``motion`` (``compiled`` is accepted: numpy only)."""
    channels = resolve_channels(motion, tangential, normal, binormal)
    return BergFullFilter(channels, _check_flag("mean_jerk", mean_jerk))


@register_filter("berg-frame")
def _berg_frame(motion: MotionModel, compiled: bool = True, tangential=None, normal=None, binormal=None,
                mean_jerk: bool = True, block_rotation: bool = True) -> BergFrameFilter:
    """``berg_frame`` on a 3-axis order-3 ``motion`` (``compiled`` is accepted: numpy only)."""
    channels = resolve_channels(motion, tangential, normal, binormal)
    return BergFrameFilter(channels, _check_flag("mean_jerk", mean_jerk), _check_flag("block_rotation", block_rotation))

"""Interacting multiple model (IMM) filter over Kalman mode filters (spec 004 §3.3 O, R17).

State: a Gaussian mixture per row, ``x[N, M, n]``, ``P[N, M, n, n]``, mode probabilities
``mu[N, M]`` (:class:`~skytrack.filters.base.MixtureState`).  The modes share one state
space (spec 004 embeds every model in m = 3 states per axis; the tracker's constant-velocity
and coordinated-turn modes share m = 2).

The mode sequence is a Markov chain with ``pi_ij = P(mode j at k | mode i at k-1)``:

* :class:`TransitionMatrix` — a fixed matrix, used for every step whatever its length (the
  discrete-time IMM of a constant scan period); rows must sum to 1;
* :class:`SojournTransition` — from mean sojourn times ``tau_j``: ``pi_jj = max(0, 1 - T/tau_j)``,
  off-diagonal ``(1 - pi_jj) / (M - 1)`` with ``T`` the row's step, so a tracker's uneven
  revisit intervals get the matching switching probability and a zero step mixes nothing.

One cycle (Blom and Bar-Shalom), split over the protocol's steps:

1. ``predict``: ``c_j = sum_i pi_ij mu_i``, ``mu_{i|j} = pi_ij mu_i / c_j``,
   ``x0_j = sum_i mu_{i|j} x_i``, ``P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)^T)``,
   then mode-matched prediction of every ``(x0_j, P0_j)``; the predicted weights are ``c``;
2. ``innovate``: per-mode innovation and likelihood ``L_j = N(nu_j; 0, S_j)``; gating uses
   the innovation of the moment-matched prediction (weights ``c``, spread of means included:
   spec 004 R20), and the row's log-likelihood is ``ln sum_j c_j L_j``;
3. ``update``: mode-matched updates and ``mu_j = L_j c_j / sum_i L_i c_i`` (log-sum-exp);
4. output: the moment-matched estimate ``MixtureState.estimate()``.

Mode probabilities after each update go to the recorder channel ``"mode_probabilities"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, MixtureState, UpdateStats
from skytrack.filters.imm_kernels import imm_predict, mode_table
from skytrack.filters.kalman import KalmanFilter

#: tolerance of the row-sum check of a user transition matrix
ROW_SUM_TOLERANCE = 1e-9


@dataclass(frozen=True)
class TransitionMatrix:
    """A fixed Markov matrix ``Pi[M, M]`` used for every step (rows sum to 1, entries >= 0)."""

    matrix: np.ndarray

    def __post_init__(self) -> None:
        Pi = np.array(self.matrix, dtype=float)
        if Pi.ndim != 2 or Pi.shape[0] != Pi.shape[1]:
            raise ValueError(f"transition_matrix must be square, got shape {Pi.shape}")
        if not np.all(np.isfinite(Pi)) or Pi.min() < 0.0:
            raise ValueError("transition_matrix entries must be finite and >= 0")
        sums = Pi.sum(axis=1)
        bad = np.flatnonzero(np.abs(sums - 1.0) > ROW_SUM_TOLERANCE)
        if bad.size:
            raise ValueError(f"transition_matrix is not stochastic: row {bad[0]} sums to {sums[bad[0]]:.12g}, not 1")
        object.__setattr__(self, "matrix", Pi)

    @property
    def modes(self) -> int:
        return len(self.matrix)

    #: a fixed matrix mixes even over a zero step
    mixes_at_zero_step = True

    def __call__(self, dt: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.matrix, (len(dt),) + self.matrix.shape)


@dataclass(frozen=True)
class SojournTransition:
    """``pi_jj = max(0, 1 - |T| / tau_j)``, off-diagonal ``(1 - pi_jj) / (M - 1)`` per row (spec 004 §3.3 O)."""

    sojourn_s: tuple[float, ...]

    def __post_init__(self) -> None:
        tau = np.array(self.sojourn_s, dtype=float)
        if tau.ndim != 1 or len(tau) < 2:
            raise ValueError(f"sojourn_s needs one mean sojourn time per mode (at least two), got {self.sojourn_s}")
        if not np.all(np.isfinite(tau)) or tau.min() <= 0.0:
            raise ValueError(f"sojourn_s must be finite and > 0 s, got {self.sojourn_s}")
        object.__setattr__(self, "sojourn_s", tuple(float(t) for t in tau))

    @property
    def modes(self) -> int:
        return len(self.sojourn_s)

    mixes_at_zero_step = False

    def __call__(self, dt: np.ndarray) -> np.ndarray:
        tau = np.array(self.sojourn_s)
        M = len(tau)
        stay = np.maximum(0.0, 1.0 - np.abs(np.asarray(dt, dtype=float))[:, None] / tau[None, :])  # [K, M]
        Pi = np.repeat(((1.0 - stay) / (M - 1))[:, :, None], M, axis=2)
        idx = np.arange(M)
        Pi[:, idx, idx] = stay
        return Pi


def sojourn_matrix(sojourn_s, dt: float) -> np.ndarray:
    """``Pi`` for one step ``dt`` from mean sojourn times (spec 004 TV19)."""
    return SojournTransition(tuple(sojourn_s))(np.array([float(dt)]))[0]


@dataclass(eq=False)
class IMMFilter(BatchFilter):
    """IMM over ``modes`` (Kalman filters on one state space) with a Markov ``transition``."""

    modes: list[KalmanFilter]
    transition: TransitionMatrix | SojournTransition
    initial_probabilities: np.ndarray | None = None
    names: tuple[str, ...] | None = None
    manoeuvre_mode: int | None = None
    compiled: bool = True
    capabilities: Capabilities = field(init=False)
    _modes: np.ndarray | None = field(init=False, repr=False)

    kind = "imm"
    state_type = MixtureState

    def __post_init__(self) -> None:
        count = len(self.modes)
        if count < 2:
            raise ValueError("an IMM needs at least two modes")
        if len({m.state_dim for m in self.modes}) != 1:
            raise ValueError(f"all IMM modes must share one state space, got dimensions {[m.state_dim for m in self.modes]}")
        if self.transition.modes != count:
            raise ValueError(f"the transition is for {self.transition.modes} modes, the IMM has {count}")
        if self.initial_probabilities is None:
            self.initial_probabilities = np.full(count, 1.0 / count)
        self.initial_probabilities = np.asarray(self.initial_probabilities, dtype=float)
        if self.initial_probabilities.shape != (count,) or self.initial_probabilities.min() < 0 \
                or not np.isclose(self.initial_probabilities.sum(), 1.0):
            raise ValueError(f"initial_probabilities must be {count} probabilities summing to 1")
        if self.names is None:
            self.names = tuple(f"mode{j}" for j in range(count))
        if len(self.names) != count:
            raise ValueError(f"names needs one name per mode ({count}), got {self.names}")
        if self.manoeuvre_mode is not None and not 0 <= self.manoeuvre_mode < count:
            raise ValueError(f"manoeuvre_mode must be a mode index in 0..{count - 1}, got {self.manoeuvre_mode}")
        # the compiled predict covers the tracker's continuous-noise CV and CT modes (imm_kernels)
        self._modes = mode_table([m.transition for m in self.modes]) if self.compiled else None
        # a fixed matrix mixes over a zero step, so a zero-step prediction is not the identity
        self.capabilities = Capabilities(zero_dt_identity=not self.transition.mixes_at_zero_step,
                                         multiple_model=True)

    @property
    def state_dim(self) -> int:
        return self.modes[0].state_dim

    @property
    def supports_manoeuvre_gate(self) -> bool:
        """A tracker may re-gate quiet tracks with the manoeuvre mode alone (``context["manoeuvre"]``)."""
        return self.manoeuvre_mode is not None

    def in_manoeuvre(self, state: MixtureState) -> np.ndarray:
        """Rows whose manoeuvre mode is the most probable (they need no manoeuvre gate)."""
        if self.manoeuvre_mode is None:
            return np.zeros(len(state), bool)
        return np.argmax(state.mu, axis=1) == self.manoeuvre_mode

    @property
    def n_modes(self) -> int:
        return len(self.modes)

    def transition_matrix(self, dt) -> np.ndarray:
        """``Pi`` per row for steps ``dt``, ``[K, M, M]`` (rows i -> columns j)."""
        return self.transition(np.atleast_1d(np.asarray(dt, dtype=float)))

    def initiate(self, x: np.ndarray, P: np.ndarray) -> MixtureState:
        count, M = len(x), self.n_modes
        xs = np.repeat(np.asarray(x, dtype=float)[:, None, :], M, axis=1)
        Ps = np.repeat(np.asarray(P, dtype=float)[:, None, :, :], M, axis=1)
        return MixtureState(xs, Ps, np.tile(self.initial_probabilities, (count, 1)))

    def mix(self, state: MixtureState, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps 1-2: predicted mode probabilities ``c[K, M]`` and mixed ``x0[K, M, n]``, ``P0[K, M, n, n]``."""
        Pi = self.transition_matrix(dt)
        c = np.einsum("kij,ki->kj", Pi, state.mu)
        weights = Pi * state.mu[:, :, None] / np.maximum(c[:, None, :], 1e-300)  # mu_{i|j}
        x0 = np.einsum("kij,kin->kjn", weights, state.x)
        d = state.x[:, :, None, :] - x0[:, None, :, :]  # [K, i, j, n]
        P0 = np.einsum("kij,kijab->kjab", weights, state.P[:, :, None] + d[..., :, None] * d[..., None, :])
        if linalg.is_counting():
            K, M, n = state.x.shape
            linalg.count("imm_mix", K * (M * M + M * M * n + M * M * (n * n + n * n)))
        return c / c.sum(axis=1, keepdims=True), x0, linalg.symmetrize(P0)

    def predict(self, state: MixtureState, dt, context: dict | None = None) -> MixtureState:
        """Mixing over ``Pi(dt)`` and each mode predicted by ``dt``.  ``context["mixing_dt"]`` (per
        row) mixes over another interval: a tracker mixes a track once per scan, over the interval
        to its reference time, and predicts the mixed modes to each candidate plot's own time."""
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        mixing_dt = dt if context is None or context.get("mixing_dt") is None else np.broadcast_to(
            self.transition_dt(context["mixing_dt"]), (len(state),))
        forced = bool(context is not None and context.get("manoeuvre") and self.manoeuvre_mode is not None)
        if self._modes is not None and (context is None or context.get("q_scale") is None):
            return self._predict_compiled(state, np.ascontiguousarray(dt, dtype=float),
                                          np.ascontiguousarray(mixing_dt, dtype=float), forced)
        c, x0, P0 = self.mix(state, mixing_dt)
        xs, Ps = np.empty_like(x0), np.empty_like(P0)
        for j, mode in enumerate(self.modes):
            predicted = mode.predict(GaussianState(x0[:, j], P0[:, j]), dt, context)
            xs[:, j], Ps[:, j] = predicted.x, predicted.P
        if forced:
            # the manoeuvre gate: the prediction of the manoeuvre mode alone; a plot found only this
            # way puts the track in that mode (the counterpart of forcing psi = 1, spec 000 S3)
            c = np.zeros_like(c)
            c[:, self.manoeuvre_mode] = 1.0
        return MixtureState(xs, Ps, c)

    def _predict_compiled(self, state: MixtureState, dt: np.ndarray, mixing_dt: np.ndarray,
                          forced: bool) -> MixtureState:
        transition = self.transition
        if isinstance(transition, SojournTransition):
            sojourn, fixed = np.array(transition.sojourn_s), np.zeros((self.n_modes, self.n_modes))
        else:
            sojourn, fixed = np.zeros(0), transition.matrix
        force = np.full(len(state), forced)
        x, P, c = imm_predict(np.ascontiguousarray(state.x), np.ascontiguousarray(state.P),
                              np.ascontiguousarray(state.mu), dt, mixing_dt, self._modes, sojourn, fixed, force,
                              -1 if self.manoeuvre_mode is None else self.manoeuvre_mode)
        if linalg.is_counting():
            K, M, n = state.x.shape
            linalg.count("imm_predict", K * (M * M + M * M * n + M * M * n * n + M * (n * n + 2 * n**3)))
        return MixtureState(x, P, c)

    def innovate(self, state: MixtureState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        per_mode = [mode.innovate(GaussianState(state.x[:, j], state.P[:, j]), z, model, context)
                    for j, mode in enumerate(self.modes)]
        mode_loglik = np.stack([inn.loglik for inn in per_mode], axis=1)
        combined = self.modes[0].innovate(state.estimate(), z, model, context)
        combined.loglik = logsumexp(mode_loglik, axis=1, b=state.mu)
        combined.predicted = state
        combined.extra["modes"] = per_mode
        combined.extra["mode_loglik"] = mode_loglik
        return combined

    def update(self, state: MixtureState, z: np.ndarray, innovation: Innovation) -> tuple[MixtureState, UpdateStats]:
        predicted: MixtureState = innovation.predicted
        xs, Ps = np.empty_like(predicted.x), np.empty_like(predicted.P)
        for j, mode in enumerate(self.modes):
            inn = innovation.extra["modes"][j]
            updated, _ = mode.update(inn.predicted, z, inn)
            xs[:, j], Ps[:, j] = updated.x, updated.P
        mu = posterior_probabilities(predicted.mu, innovation.extra["mode_loglik"])
        if self.recorder.active:
            self.recorder.record("mode_probabilities", np.arange(len(mu)), mu=mu)
        return MixtureState(xs, linalg.symmetrize(Ps), mu), UpdateStats(innovation.d2 / innovation.m)


def posterior_probabilities(prior: np.ndarray, loglik: np.ndarray) -> np.ndarray:
    """``mu_j = L_j c_j / sum_i L_i c_i`` over the last axis, in the log domain (no underflow)."""
    with np.errstate(divide="ignore"):
        log_mu = np.log(prior) + loglik
    return np.exp(log_mu - logsumexp(log_mu, axis=-1, keepdims=True))

"""Interacting multiple model (IMM) filter over Kalman mode filters (spec 004 family).

State: a Gaussian mixture per row, ``x[N, M, n]``, ``P[N, M, n, n]``, mode probabilities
``mu[N, M]`` (:class:`~skytrack.filters.base.MixtureState`).  The mode sequence is a
continuous-time Markov chain with rate matrix ``Lambda`` (off-diagonal switching rates per
second), so the transition matrix over a step is ``Pi(dt) = expm(Lambda dt)``: a zero step
mixes nothing, and steps of any length are consistent.

One cycle (Blom and Bar-Shalom's IMM):

1. mixing: ``c_j = sum_i Pi_ij mu_i``, ``mu_{i|j} = Pi_ij mu_i / c_j``,
   ``x0_j = sum_i mu_{i|j} x_i``, ``P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)^T)``;
2. mode-matched prediction of every ``(x0_j, P0_j)`` with mode j's filter, ``mu <- c``;
3. innovation per mode, likelihood ``L_j = N(nu_j; 0, S_j)``; gating uses the moment-matched
   estimate's innovation, and the row's log-likelihood is ``ln sum_j mu_j L_j``;
4. mode-matched updates and ``mu_j <- mu_j L_j / sum_k mu_k L_k``;
5. output: the moment-matched estimate ``MixtureState.estimate()``.

Mode probabilities after each update go to the recorder channel ``"mode_probabilities"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, MixtureState, UpdateStats
from skytrack.filters.kalman import KalmanFilter


@dataclass(eq=False)
class IMMFilter(BatchFilter):
    """IMM over ``modes`` (Kalman filters on state spaces of one dimension) with switching ``rates``."""

    modes: list[KalmanFilter]
    rates: np.ndarray
    initial_probabilities: np.ndarray | None = None
    _eig: tuple = field(init=False, repr=False)

    kind = "imm"
    capabilities = Capabilities()
    state_type = MixtureState

    def __post_init__(self) -> None:
        count = len(self.modes)
        if count < 2:
            raise ValueError("an IMM needs at least two modes")
        if len({m.state_dim for m in self.modes}) != 1:
            raise ValueError("all IMM modes must share one state space")
        rates = np.array(self.rates, dtype=float)
        if rates.shape != (count, count) or np.any(rates[~np.eye(count, dtype=bool)] < 0):
            raise ValueError(f"rates must be a {count}x{count} matrix with non-negative off-diagonal rates")
        np.fill_diagonal(rates, 0.0)
        np.fill_diagonal(rates, -rates.sum(axis=1))
        self.rates = rates
        values, vectors = np.linalg.eig(rates)
        self._eig = (values, vectors, np.linalg.inv(vectors))
        if self.initial_probabilities is None:
            self.initial_probabilities = np.full(count, 1.0 / count)
        self.initial_probabilities = np.asarray(self.initial_probabilities, dtype=float)
        if not np.isclose(self.initial_probabilities.sum(), 1.0):
            raise ValueError("initial mode probabilities must sum to 1")

    @property
    def state_dim(self) -> int:
        return self.modes[0].state_dim

    @property
    def n_modes(self) -> int:
        return len(self.modes)

    def transition_matrix(self, dt: np.ndarray) -> np.ndarray:
        """``Pi(dt) = expm(Lambda |dt|)`` per row, ``[K, M, M]`` (rows i -> columns j)."""
        values, vectors, inverse = self._eig
        decay = np.exp(values[None, :] * np.abs(dt)[:, None])
        Pi = np.einsum("ij,kj,jl->kil", vectors, decay, inverse).real
        return np.clip(Pi, 0.0, 1.0)

    def initiate(self, x: np.ndarray, P: np.ndarray) -> MixtureState:
        count, M = len(x), self.n_modes
        xs = np.repeat(np.asarray(x, dtype=float)[:, None, :], M, axis=1)
        Ps = np.repeat(np.asarray(P, dtype=float)[:, None, :, :], M, axis=1)
        return MixtureState(xs, Ps, np.tile(self.initial_probabilities, (count, 1)))

    def predict(self, state: MixtureState, dt, context: dict | None = None) -> MixtureState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        Pi = self.transition_matrix(dt)
        c = np.einsum("kij,ki->kj", Pi, state.mu)
        weights = Pi * state.mu[:, :, None] / np.maximum(c[:, None, :], 1e-300)  # mu_{i|j}
        x0 = np.einsum("kij,kin->kjn", weights, state.x)
        d = state.x[:, :, None, :] - x0[:, None, :, :]  # [K, i, j, n]
        P0 = np.einsum("kij,kijab->kjab", weights, state.P[:, :, None] + d[..., :, None] * d[..., None, :])
        xs, Ps = np.empty_like(x0), np.empty_like(P0)
        for j, mode in enumerate(self.modes):
            predicted = mode.predict(GaussianState(x0[:, j], P0[:, j]), dt, context)
            xs[:, j], Ps[:, j] = predicted.x, predicted.P
        return MixtureState(xs, Ps, c / c.sum(axis=1, keepdims=True))

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
        log_mu = np.log(np.maximum(predicted.mu, 1e-300)) + innovation.extra["mode_loglik"]
        mu = np.exp(log_mu - logsumexp(log_mu, axis=1, keepdims=True))
        self.recorder.record("mode_probabilities", np.arange(len(mu)), mu=mu)
        return MixtureState(xs, linalg.symmetrize(Ps), mu), UpdateStats(innovation.d2 / innovation.m)

"""The manoeuvre indicator psi of spec 000 (S3) as a filter: a Kalman filter whose process
noise is multiplied by ``scale`` while psi = 1.

psi is a function of past innovations only, as Theorem 1 (2a) requires: after each update
the normalised innovation squared per component ``nis = d^2 / m`` is smoothed,
``a <- nis`` at the first update and ``a <- memory a + (1 - memory) nis`` after, and psi is
set when ``a > on`` and cleared when ``a < off`` (hysteresis).  A tracker may also force
psi = 1 for rows predicted with ``context["manoeuvre"] = True`` (the manoeuvre gate: a
quiet track that only finds its plot with the manoeuvre noise switches to it); such an
update sets psi and raises ``a`` to at least ``on``.

Switches are reported on the recorder channel ``"switch"`` (rows, new psi).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats
from skytrack.filters.kalman import KalmanFilter


@dataclass
class ManoeuvreState(GaussianState):
    """Gaussian state plus psi, the smoothed NIS and the number of updates per row."""

    psi: np.ndarray
    nis_avg: np.ndarray
    n_updates: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, self.P)


@dataclass(eq=False)
class ManoeuvreSwitchFilter(BatchFilter):
    """Kalman filter with the psi switch of spec 000 S3 (``scale = 1`` switches it off)."""

    kalman: KalmanFilter
    scale: float = 3000.0
    on: float = 3.0
    off: float = 1.2
    memory: float = 0.5

    kind = "kalman-psi"
    capabilities = Capabilities()
    state_type = ManoeuvreState

    def __post_init__(self) -> None:
        if not (np.isfinite(self.scale) and self.scale >= 1.0):
            raise ValueError(f"manoeuvre scale must be >= 1, got {self.scale}")
        if not 0.0 < self.off <= self.on:
            raise ValueError("need 0 < off <= on for the manoeuvre switch")
        if not 0.0 <= self.memory < 1.0:
            raise ValueError(f"manoeuvre memory must be in [0, 1), got {self.memory}")

    @property
    def state_dim(self) -> int:
        return self.kalman.state_dim

    @property
    def transition(self):
        return self.kalman.transition

    @property
    def supports_manoeuvre_gate(self) -> bool:
        """A tracker may re-gate quiet tracks with psi forced on; with ``scale = 1`` that changes nothing."""
        return self.scale != 1.0

    def in_manoeuvre(self, state: ManoeuvreState) -> np.ndarray:
        """Rows with psi = 1 (they need no manoeuvre gate)."""
        return state.psi

    def initiate(self, x: np.ndarray, P: np.ndarray) -> ManoeuvreState:
        count = len(x)
        return ManoeuvreState(np.array(x, dtype=float), np.array(P, dtype=float), np.zeros(count, bool),
                              np.zeros(count), np.zeros(count, np.int64))

    def q_scale(self, state: ManoeuvreState, context: dict | None) -> np.ndarray:
        if context is not None and context.get("manoeuvre"):
            return np.full(len(state), self.scale)
        if self.scale == 1.0:
            return np.ones(len(state))
        return np.where(state.psi, self.scale, 1.0)

    def predict(self, state: ManoeuvreState, dt, context: dict | None = None) -> ManoeuvreState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        g = self.kalman.predict_arrays(state.x, state.P, dt, self.q_scale(state, context))
        return ManoeuvreState(g.x, g.P, state.psi, state.nis_avg, state.n_updates)

    def innovate(self, state: ManoeuvreState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        innovation = self.kalman.innovate(state, z, model, context)
        innovation.extra["manoeuvre"] = np.full(len(state), bool(context and context.get("manoeuvre")))
        return innovation

    def update(self, state: ManoeuvreState, z: np.ndarray, innovation: Innovation) -> tuple[ManoeuvreState, UpdateStats]:
        predicted: ManoeuvreState = innovation.predicted
        updated, stats = self.kalman.update(state, z, innovation)
        forced = innovation.extra.get("manoeuvre", np.zeros(len(predicted), bool))
        nis = stats.nis
        first = predicted.n_updates == 0
        smoothed = np.where(first, nis, self.memory * predicted.nis_avg + (1.0 - self.memory) * nis)
        psi = np.where(predicted.psi, smoothed > self.off, smoothed > self.on)
        psi = np.where(forced, True, psi)
        nis_avg = np.where(forced, np.maximum(predicted.nis_avg, self.on), smoothed)
        switched = psi != predicted.psi
        if switched.any():
            self.recorder.record("switch", np.flatnonzero(switched), psi=psi[switched])
        new = ManoeuvreState(updated.x, updated.P, psi, nis_avg, predicted.n_updates + 1)
        return new, stats

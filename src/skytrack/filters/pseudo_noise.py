"""Pseudo-noise Kalman filter (spec 004 §3.3 E, R7): the paper's contrast case to the adaptive
filter — the process noise is a function fixed in advance, not estimated from the data.

``Q_k = q(x̂_{k-1}, k) · Q_unit(dt)``: ``Q_unit`` is the process noise of the given motion model
and ``q`` is either a constant (default 1, i.e. the motion model as configured; with a
sigma_w = 1 model pass ``q = sigma_w**2``, e.g. 400 for spec 004 §6's pseudo-noise KF-CV with
sigma_w = 20 m/s^2) or a vectorised callable ``q(x, k) -> [N]`` of the filtered states ``x[N, n]``
and the scan index ``k[N]`` of the step being predicted (1 for the first prediction after
``initiate``; the state counts updates, so several predictions before one update share k).
The callable must return finite values >= 0 (ValueError otherwise).  ``context["q_scale"]``
multiplies on top, as in the Kalman filter.

Everything else is the composed :class:`~skytrack.filters.kalman.KalmanFilter` (§3.3 A, Joseph
form, compiled kernels when ``compiled=True``); its gains go to the recorder channel ``"gain"``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.per_axis import RecorderSharing, row_scale
from skytrack.filters.registry import register_filter
from skytrack.models.motion import MotionModel


@dataclass
class PseudoNoiseState(GaussianState):
    """Gaussian state plus the number of updates per row (the scan index of the last update)."""

    scans: np.ndarray


@dataclass(eq=False)
class PseudoNoiseKalmanFilter(RecorderSharing, BatchFilter):
    """Kalman filter whose process noise is ``q(x̂, k)`` times the motion model's."""

    transition: MotionModel
    q: float | Callable[[np.ndarray, np.ndarray], np.ndarray] = 1.0
    compiled: bool = True
    kalman: KalmanFilter = field(init=False, repr=False)

    kind = "kalman-pseudo-noise"
    capabilities = Capabilities()
    state_type = PseudoNoiseState

    def __post_init__(self) -> None:
        if not callable(self.q):
            try:
                value = float(self.q)
            except (TypeError, ValueError):
                raise ValueError(f"pseudo-noise KF: q must be a number or a callable q(x, k), got {self.q!r}") from None
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"pseudo-noise KF: q must be finite and >= 0, got {self.q!r}")
            self.q = value
        self.kalman = KalmanFilter(self.transition, compiled=self.compiled)

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def initiate(self, x: np.ndarray, P: np.ndarray) -> PseudoNoiseState:
        return PseudoNoiseState(np.array(x, dtype=float), np.array(P, dtype=float), np.zeros(len(x), np.int64))

    def noise_factor(self, state: PseudoNoiseState) -> np.ndarray:
        """``q(x̂_{k-1}, k)`` per row, checked."""
        if not callable(self.q):
            return np.full(len(state), self.q)
        value = np.broadcast_to(np.asarray(self.q(state.x, state.scans + 1), dtype=float), (len(state),)).copy()
        if not np.all(np.isfinite(value) & (value >= 0.0)):
            raise ValueError("pseudo-noise KF: q(x, k) must return finite values >= 0")
        return value

    def predict(self, state: PseudoNoiseState, dt, context: dict | None = None) -> PseudoNoiseState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        scale = self.noise_factor(state) * row_scale(context, len(state))
        g = self.kalman.predict_arrays(state.x, state.P, dt, scale)
        return PseudoNoiseState(g.x, g.P, state.scans)

    def innovate(self, state: PseudoNoiseState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        return self.kalman.innovate(state, z, model, context)

    def update(self, state: PseudoNoiseState, z: np.ndarray, innovation: Innovation) -> tuple[PseudoNoiseState, UpdateStats]:
        updated, stats = self.kalman.update(state, z, innovation)
        return PseudoNoiseState(updated.x, updated.P, innovation.predicted.scans + 1), stats


@register_filter("kalman-pseudo-noise")
def _pseudo_noise(motion: MotionModel, compiled: bool = True, q=1.0) -> PseudoNoiseKalmanFilter:
    """Pseudo-noise KF (§3.3 E): Q = q(x̂, k) Q_motion, ``q`` a constant or a callable."""
    return PseudoNoiseKalmanFilter(motion, q=q, compiled=compiled)

"""The identification model: a linear-Gaussian motion model in position-first state order.

Spec 001 R1: identification works with any linear-Gaussian motion model of
:mod:`skytrack.models` (F(Δ) invertible, Q(Δ) ⪰ 0).  Those models order the state axis by
axis (``[x, vx, y, vy]``); the identification code, its test vectors and its reports use
the paper's derivative-major order (``[x, y, vx, vy]``, §2 conventions), so that a report
measuring positions (and, for ADS-B with velocity, velocities) measures the *first* m state
components: H = [I_m 0].  :class:`IdentificationModel` does that permutation once.

The process noise is also given factored as Q = G Q_w G^T with Q_w ≻ 0 (an eigenvalue
split), which the information-form time update of R3(a) needs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.models import MotionModel, constant_velocity

#: eigenvalues of Q below this fraction of its largest are treated as zero (Q ⪰ 0 of rank < n)
_Q_RANK_TOLERANCE = 1e-12


@dataclass(frozen=True)
class IdentificationModel:
    """A motion model of :mod:`skytrack.models` with the state in derivative-major order."""

    motion: MotionModel
    order_to_motion: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        motion = self.motion
        # derivative-major position k*ndim + axis  <-  axis-major axis*order + k
        perm = np.array([axis * motion.order + k for k in range(motion.order) for axis in range(motion.ndim)])
        object.__setattr__(self, "order_to_motion", perm)

    @property
    def n(self) -> int:
        """State dimension."""
        return self.motion.dim

    @property
    def ndim(self) -> int:
        """Spatial dimensions (2 or 3)."""
        return self.motion.ndim

    def F(self, dt) -> np.ndarray:
        """Transitions ``[K, n, n]`` for steps ``dt`` ``[K]`` (dt ≥ 0)."""
        p = self.order_to_motion
        return self.motion.F_batch(np.atleast_1d(np.asarray(dt, float)))[:, p[:, None], p]

    def Q(self, dt) -> np.ndarray:
        """Process-noise covariances ``[K, n, n]`` for steps ``dt`` ``[K]``."""
        p = self.order_to_motion
        return self.motion.Q_batch(np.atleast_1d(np.asarray(dt, float)))[:, p[:, None], p]

    def from_motion_order(self, x: np.ndarray) -> np.ndarray:
        """A state (or ``[..., n]`` states) in the motion model's axis-major order, re-ordered."""
        return np.asarray(x)[..., self.order_to_motion]

    def to_motion_order(self, x: np.ndarray) -> np.ndarray:
        """States in this model's order put back in the motion model's axis-major order."""
        out = np.empty_like(np.asarray(x, float))
        out[..., self.order_to_motion] = x
        return out

    def position_matrix(self) -> np.ndarray:
        """H = [I 0] measuring the positions."""
        return np.eye(self.ndim, self.n)

    def position_velocity_matrix(self) -> np.ndarray:
        """H = [I 0] measuring positions and velocities (ADS-B with velocity)."""
        return np.eye(2 * self.ndim, self.n)


def cv_model(ndim: int = 2, q: float = 0.0) -> IdentificationModel:
    """Nearly-constant-velocity identification model, white-noise acceleration PSD ``q`` (m²/s³)."""
    return IdentificationModel(constant_velocity(ndim, q))


def factor_process_noise(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q = G Q_w G^T per row, with Q_w ≻ 0 diagonal; returns ``(G, q_w, has_noise)``.

    ``G`` is ``[K, n, n]`` with the columns of zero eigenvalues set to zero and ``q_w`` the
    eigenvalues (zeros replaced by 1, harmless because their columns of G are zero).  Rows
    whose Q is zero have ``has_noise`` false: their time update is the noise-free one.
    """
    Q = 0.5 * (Q + np.swapaxes(Q, -1, -2))
    eigenvalues, vectors = np.linalg.eigh(Q)
    top = eigenvalues.max(axis=-1, keepdims=True)
    keep = eigenvalues > _Q_RANK_TOLERANCE * np.maximum(top, 0.0)
    keep &= top > 0
    G = vectors * keep[:, None, :]
    q_w = np.where(keep, eigenvalues, 1.0)
    return G, q_w, keep.any(axis=-1)

"""Track initiation from plots left over by association.

* ``"one-point"`` (default): position from the plot with its converted covariance, zero
  velocity with a prior of ``sigma_v`` per axis (and, for a Singer state, acceleration
  variance ``sigma_a^2`` of the model, else 10 m/s^2 squared);
* ``"two-point"``: the same, and after the second plot of a tentative track its state is
  replaced by the two-point difference: position of the second plot, velocity from the
  difference, covariances from both plots' noise (``R2``, ``(R1 + R2) / dt^2``, cross ``R2 / dt``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INIT_METHODS = ("one-point", "two-point")


@dataclass
class InitiationConfig:
    method: str = "one-point"
    sigma_v: float = 150.0

    def __post_init__(self) -> None:
        if self.method not in INIT_METHODS:
            raise ValueError(f"init must be one of {INIT_METHODS}, got {self.method!r}")
        if not (np.isfinite(self.sigma_v) and self.sigma_v > 0):
            raise ValueError(f"init_sigma_v must be finite and > 0, got {self.sigma_v}")


class Initiator:
    """Starting states for new tracks of a state space with ``order`` states per axis."""

    def __init__(self, config: InitiationConfig, dim: int, order: int, acceleration_sigma: float) -> None:
        self.config = config
        self.dim = dim
        self.order = order
        self.n = dim * order
        self.pos = np.arange(dim) * order
        self.vel = self.pos + 1
        self.acceleration_sigma = acceleration_sigma

    def one_point(self, position: np.ndarray, covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States ``x``, ``P`` from plots' positions ``[K, 3]`` and covariances ``[K, 3, 3]``."""
        count, dim = len(position), self.dim
        x = np.zeros((count, self.n))
        x[:, self.pos] = position[:, :dim]
        P = np.zeros((count, self.n, self.n))
        P[:, self.pos[:, None], self.pos] = covariance[:, :dim, :dim]
        P[:, self.vel, self.vel] = self.config.sigma_v**2
        if self.order == 3:
            acc = self.pos + 2
            P[:, acc, acc] = self.acceleration_sigma**2
        return x, P

    def two_point(self, first_position: np.ndarray, first_covariance: np.ndarray, dt: np.ndarray,
                  position: np.ndarray, covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The two-point difference state after a second plot ``dt`` seconds after the first."""
        dim, n = self.dim, self.n
        dt = np.maximum(dt, 1e-3)
        z2, R2 = position[:, :dim], covariance[:, :dim, :dim]
        z1, R1 = first_position, first_covariance
        x = np.zeros((len(dt), n))
        x[:, self.pos] = z2
        x[:, self.vel] = (z2 - z1) / dt[:, None]
        P = np.zeros((len(dt), n, n))
        P[:, self.pos[:, None], self.pos] = R2
        P[:, self.vel[:, None], self.vel] = (R1 + R2) / np.square(dt)[:, None, None]
        cross = R2 / dt[:, None, None]
        P[:, self.pos[:, None], self.vel] = cross
        P[:, self.vel[:, None], self.pos] = np.swapaxes(cross, -1, -2)
        if self.order == 3:
            acc = self.pos + 2
            P[:, acc, acc] = self.acceleration_sigma**2
        return x, P

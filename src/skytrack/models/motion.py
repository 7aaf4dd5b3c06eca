"""Motion models: per-axis constant velocity, constant acceleration and Singer models,
and their assembly into 1-, 2- and 3-D state spaces.

State layout (spec 000, R1): per axis, blocks stacked axis after axis, e.g. for the
3-D Singer model ``[x, vx, ax, y, vy, ay, z, vz, az]`` and for 2-D constant velocity
``[x, vx, y, vy]``.  Every model gives the transition ``F(dt)`` and the process noise
``Q(dt)``; the ``*_batch`` variants take an array of step lengths and return stacked
matrices ``[K, n, n]`` so that a whole bank of tracks is predicted in one call
(DESIGN.md rule 1).

Singer model (spec 000):

* ``discretization="paper"`` is (K6): F_P = [[1, T, T^2/2], [0, 1, T], [0, 0, rho]],
  Q_P = diag(0, 0, sigma_a^2 (1 - rho^2)), rho = exp(-T/tau);
* ``discretization="exact"`` is the exact sampling (X1)-(X2) of
  da/dt = -a/tau + w with stationary variance sigma_a^2 (white-noise PSD 2 sigma_a^2/tau).
  For alpha*T <= 1 the entries are evaluated from their power series in u = alpha*T
  (every coefficient is a rational number, so there is no cancellation); above that the
  closed form (X1)-(X2) is used, which is accurate there (spec 000 section 3.3, TV2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: series order for the small-alpha*T Singer evaluation; (1/26!) < 1e-26
_SERIES_TERMS = 26
#: alpha*T at and below which the power series is used (spec 000, R2)
SINGER_SERIES_LIMIT = 1.0


def _as_steps(dt, allow_zero: bool) -> np.ndarray:
    steps = np.asarray(dt, dtype=float)
    if not np.all(np.isfinite(steps)):
        raise ValueError("time step must be finite")
    if allow_zero:
        if np.any(steps < 0):
            raise ValueError(f"time step must be >= 0, got {steps[steps < 0].min()}")
    elif np.any(steps <= 0):
        raise ValueError(f"time step must be > 0, got {steps.min() if steps.ndim else float(steps)}")
    return steps


class AxisModel:
    """A one-axis motion model: ``order`` states (position, velocity[, acceleration])."""

    order: int = 2

    def F(self, dt: float) -> np.ndarray:
        return self.F_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def Q(self, dt: float) -> np.ndarray:
        return self.Q_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def F_batch(self, dt) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def Q_batch(self, dt) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantVelocityAxis(AxisModel):
    """Nearly constant velocity: continuous white-noise acceleration of PSD ``q`` (m^2/s^3)."""

    q: float

    order = 2

    def __post_init__(self):
        if not (self.q >= 0 and math.isfinite(self.q)):
            raise ValueError(f"process noise PSD q must be finite and >= 0, got {self.q}")

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        F = np.zeros(t.shape + (2, 2))
        F[..., 0, 0] = F[..., 1, 1] = 1.0
        F[..., 0, 1] = t
        return F

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        Q = np.empty(t.shape + (2, 2))
        Q[..., 0, 0] = self.q * t**3 / 3.0
        Q[..., 0, 1] = Q[..., 1, 0] = self.q * t**2 / 2.0
        Q[..., 1, 1] = self.q * t
        return Q


@dataclass(frozen=True)
class ConstantAccelerationAxis(AxisModel):
    """Nearly constant acceleration: continuous white-noise jerk of PSD ``q`` (m^2/s^5)."""

    q: float

    order = 3

    def __post_init__(self):
        if not (self.q >= 0 and math.isfinite(self.q)):
            raise ValueError(f"process noise PSD q must be finite and >= 0, got {self.q}")

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        F = np.zeros(t.shape + (3, 3))
        F[..., 0, 0] = F[..., 1, 1] = F[..., 2, 2] = 1.0
        F[..., 0, 1] = F[..., 1, 2] = t
        F[..., 0, 2] = t * t / 2.0
        return F

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        q = self.q
        Q = np.empty(t.shape + (3, 3))
        Q[..., 0, 0] = q * t**5 / 20.0
        Q[..., 0, 1] = Q[..., 1, 0] = q * t**4 / 8.0
        Q[..., 0, 2] = Q[..., 2, 0] = q * t**3 / 6.0
        Q[..., 1, 1] = q * t**3 / 3.0
        Q[..., 1, 2] = Q[..., 2, 1] = q * t**2 / 2.0
        Q[..., 2, 2] = q * t
        return Q


@lru_cache(maxsize=1)
def _singer_series_coefficients() -> tuple[np.ndarray, np.ndarray]:
    """Power-series coefficients in (-u) of the exact Singer F and Q entries.

    With f(s) = e^{A s} e_3 = (f1, f2, f3), f_i(s) = sum_k (-alpha)^{k-d_i} s^k / k!,
    d = (2, 1, 0), the exact process noise is
    Q_ij = 2 sigma_a^2 T^{d_i + d_j} u sum_p (-u)^p c_ijp,
    c_ijp = sum_{k+l=p} 1 / ((k+d_i)! (l+d_j)! (p + d_i + d_j + 1)),
    and F_{i3} = T^{d_i} sum_k (-u)^k / (k + d_i)!.
    Returned: ``f_coef[i, k]`` and ``q_coef[i, j, p]``.
    """
    depth = (2, 1, 0)
    n = _SERIES_TERMS
    fact = [math.factorial(k) for k in range(2 * n + 4)]
    f_coef = np.array([[1.0 / fact[k + d] for k in range(n)] for d in depth])
    q_coef = np.zeros((3, 3, n))
    for i, di in enumerate(depth):
        for j, dj in enumerate(depth):
            for p in range(n):
                q_coef[i, j, p] = sum(
                    1.0 / (fact[k + di] * fact[p - k + dj] * (p + di + dj + 1)) for k in range(p + 1)
                )
    return f_coef, q_coef


def _horner(coefficients: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate sum_p coefficients[p] x^p for an array x."""
    result = np.zeros_like(x)
    for c in coefficients[::-1]:
        result = result * x + c
    return result


@dataclass(frozen=True)
class SingerAxisModel(AxisModel):
    """Singer model of one axis (spec 000, R2): acceleration is a first-order Markov process.

    ``tau`` is the mean manoeuvre time (s), ``sigma_a`` the stationary acceleration
    standard deviation (m/s^2), ``discretization`` is ``"paper"`` (K6) or ``"exact"`` (X1-X2).
    """

    tau: float
    sigma_a: float
    discretization: str = "exact"

    order = 3

    def __post_init__(self):
        if not (math.isfinite(self.tau) and self.tau > 0):
            raise ValueError(f"Singer tau must be finite and > 0, got {self.tau}")
        if not (math.isfinite(self.sigma_a) and self.sigma_a >= 0):
            raise ValueError(f"Singer sigma_a must be finite and >= 0, got {self.sigma_a}")
        if self.discretization not in ("paper", "exact"):
            raise ValueError(f"discretization must be 'paper' or 'exact', got {self.discretization!r}")

    @property
    def alpha(self) -> float:
        return 1.0 / self.tau

    def rho(self, dt) -> np.ndarray:
        """One-step acceleration correlation rho = exp(-dt/tau)."""
        return np.exp(-np.asarray(dt, dtype=float) / self.tau)

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        F = np.zeros(t.shape + (3, 3))
        F[..., 0, 0] = F[..., 1, 1] = 1.0
        F[..., 0, 1] = t
        F[..., 2, 2] = np.exp(-t / self.tau)
        if self.discretization == "paper":
            F[..., 0, 2] = t * t / 2.0
            F[..., 1, 2] = t
            return F
        a = self.alpha
        u = a * t
        small = u <= SINGER_SERIES_LIMIT
        f_coef, _ = _singer_series_coefficients()
        neg_u = -u
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            series13 = t * t * _horner(f_coef[0], neg_u)
            series23 = t * _horner(f_coef[1], neg_u)
            closed13 = (u - 1.0 + np.exp(-u)) / (a * a)
            closed23 = -np.expm1(-u) / a
        F[..., 0, 2] = np.where(small, series13, closed13)
        F[..., 1, 2] = np.where(small, series23, closed23)
        return F

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        var = self.sigma_a**2
        if self.discretization == "paper":
            Q = np.zeros(t.shape + (3, 3))
            Q[..., 2, 2] = var * -np.expm1(-2.0 * t / self.tau)
            return Q
        a = self.alpha
        u = a * t
        small = u <= SINGER_SERIES_LIMIT
        _, q_coef = _singer_series_coefficients()
        depth = (2, 1, 0)
        Q = np.empty(t.shape + (3, 3))
        neg_u = -u
        e1 = np.exp(-u)
        e2 = np.exp(-2.0 * u)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            closed = {
                (0, 0): (1 - e2 + 2 * u + (2.0 / 3.0) * u**3 - 2 * u**2 - 4 * u * e1) / (2 * a**5),
                (0, 1): (e2 + 1 - 2 * e1 + 2 * u * e1 - 2 * u + u**2) / (2 * a**4),
                (0, 2): (1 - e2 - 2 * u * e1) / (2 * a**3),
                (1, 1): (4 * e1 - 3 - e2 + 2 * u) / (2 * a**3),
                (1, 2): (e2 + 1 - 2 * e1) / (2 * a**2),
                (2, 2): -np.expm1(-2.0 * u) / (2 * a),
            }
            for (i, j), closed_ij in closed.items():
                series = 2.0 * var * t ** (depth[i] + depth[j]) * u * _horner(q_coef[i, j], neg_u)
                value = np.where(small, series, 2.0 * a * var * closed_ij)
                Q[..., i, j] = value
                Q[..., j, i] = value
        return Q


@dataclass(frozen=True)
class ScaledAxis(AxisModel):
    """An axis model whose process noise is multiplied by ``factor`` (same transition)."""

    base: AxisModel
    factor: float

    def __post_init__(self):
        if not (math.isfinite(self.factor) and self.factor > 0):
            raise ValueError(f"process-noise factor must be finite and > 0, got {self.factor}")

    @property
    def order(self) -> int:  # type: ignore[override]
        return self.base.order

    def F_batch(self, dt) -> np.ndarray:
        return self.base.F_batch(dt)

    def Q_batch(self, dt) -> np.ndarray:
        return self.base.Q_batch(dt) * self.factor


def block_diag_batch(blocks: list[np.ndarray]) -> np.ndarray:
    """Block-diagonal assembly of stacked matrices: blocks ``[K, n_i, n_i]`` -> ``[K, n, n]``."""
    lead = blocks[0].shape[:-2]
    size = sum(b.shape[-1] for b in blocks)
    out = np.zeros(lead + (size, size))
    start = 0
    for b in blocks:
        n = b.shape[-1]
        out[..., start : start + n, start : start + n] = b
        start += n
    return out


class MotionModel:
    """Independent axis models stacked per axis (spec 000, R1; Q block-diagonal)."""

    def __init__(self, axes: list[AxisModel]):
        if not axes:
            raise ValueError("a motion model needs at least one axis")
        self.axes = list(axes)
        self.order = axes[0].order
        if any(ax.order != self.order for ax in axes):
            raise ValueError("all axes of a motion model must have the same order")
        self.ndim = len(axes)
        self.dim = self.order * self.ndim
        self._identical = all(ax == axes[0] for ax in axes)

    @property
    def identical_axes(self) -> bool:
        """Every axis has the same model (F and Q are one block repeated)."""
        return self._identical

    @property
    def is_linear(self) -> bool:
        return True

    def f(self, x: np.ndarray, dt) -> np.ndarray:
        """Deterministic transition ``F(dt) x`` of states ``[K, n]`` (transition-model protocol)."""
        return np.einsum("kij,kj->ki", self.F_batch(np.broadcast_to(dt, (len(x),))), x)

    @property
    def position_index(self) -> np.ndarray:
        return np.arange(self.ndim) * self.order

    @property
    def velocity_index(self) -> np.ndarray:
        return np.arange(self.ndim) * self.order + 1

    def _batch(self, method: str, dt) -> np.ndarray:
        if self._identical:
            block = getattr(self.axes[0], method)(dt)
            return block_diag_batch([block] * self.ndim)
        return block_diag_batch([getattr(ax, method)(dt) for ax in self.axes])

    def F_batch(self, dt) -> np.ndarray:
        return self._batch("F_batch", dt)

    def Q_batch(self, dt) -> np.ndarray:
        return self._batch("Q_batch", dt)

    def F(self, dt: float) -> np.ndarray:
        return self.F_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def Q(self, dt: float) -> np.ndarray:
        return self.Q_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def scaled(self, factor: float) -> "MotionModel":
        """The same model with every axis's process noise multiplied by ``factor``."""
        return MotionModel([ScaledAxis(ax, factor) for ax in self.axes])

    def embed_position(self, positions: np.ndarray) -> np.ndarray:
        """State vectors ``[K, dim]`` with the given positions ``[K, ndim]`` and zero derivatives."""
        x = np.zeros(positions.shape[:-1] + (self.dim,))
        x[..., self.position_index] = positions
        return x

    def __repr__(self) -> str:
        return f"MotionModel({self.axes!r})"


def constant_velocity(ndim: int, q: float) -> MotionModel:
    """Nearly-constant-velocity model in ``ndim`` dimensions with acceleration PSD ``q``."""
    return MotionModel([ConstantVelocityAxis(q)] * ndim)


def constant_acceleration(ndim: int, q: float) -> MotionModel:
    """Nearly-constant-acceleration model in ``ndim`` dimensions with jerk PSD ``q``."""
    return MotionModel([ConstantAccelerationAxis(q)] * ndim)


def singer(ndim: int, tau: float, sigma_a: float, discretization: str = "exact") -> MotionModel:
    """Singer model in ``ndim`` dimensions, same (tau, sigma_a) on every axis."""
    return MotionModel([SingerAxisModel(tau, sigma_a, discretization)] * ndim)

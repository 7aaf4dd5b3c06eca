"""Polynomial motion models of order m = 1..4 with three process-noise variants (spec 004 §3.3 B, R1).

One axis holds m states (position, velocity, ...; the motion is a polynomial of degree m-1):
``F_ij = T^{j-i} / (j-i)!`` for j >= i, else 0.  Noise variants (``noise=``):

* ``"continuous"`` — white m-th derivative of power spectral density ``q = intensity``:
  ``Q_ij = q T^{2m-1-i-j} / ((2m-1-i-j) (m-1-i)! (m-1-j)!)`` (the Van Loan integral of the
  chain of integrators; m = 2 and 3 equal :class:`~skytrack.models.motion.ConstantVelocityAxis`
  and :class:`~skytrack.models.motion.ConstantAccelerationAxis`).
* ``"piecewise_constant"`` — the m-th derivative is constant over each interval with standard
  deviation ``sigma_w = intensity``: ``Q = sigma_w^2 g g^T``, ``g_i = T^{m-i}/(m-i)!``.
  m = 2 is DWNA (``g = [T^2/2, T]``).
* ``"wiener_increment"`` — the (m-1)-th derivative receives a white increment of standard
  deviation ``sigma_w = intensity`` each interval: ``g_i = T^{m-1-i}/(m-1-i)!``.  m = 3 is DWPA
  (``g = [T^2/2, T, 1]``).  The increment happens once per elapsed interval, so a step of length
  zero carries none: ``Q(0) = 0`` (the literal formula would give ``sigma_w^2 e_m e_m^T``), which
  keeps a zero-length prediction the identity.

``intensity`` is therefore a PSD (``continuous``) or a standard deviation (the two discrete
variants), as the spec's symbols q and sigma_w.

Isotropic 1-, 2- and 3-D models are ``MotionModel([axis] * ndim)``: MotionModel stacks the axes
block-diagonally in the axis-major layout of spec 004 §2, which is the Kronecker product
``I_ndim (x) F_axis`` (and likewise for Q) required by R1.  :func:`polynomial`, :func:`dwna` and
:func:`dwpa` build them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.models.motion import AxisModel, MotionModel, _as_steps

NOISE_VARIANTS = ("continuous", "piecewise_constant", "wiener_increment")
MAX_ORDER = 4


@dataclass(frozen=True)
class PolynomialAxis(AxisModel):
    """Polynomial model of one axis: ``order`` = m states, process noise variant ``noise``.

    ``intensity`` is the PSD q for ``noise="continuous"`` and the standard deviation sigma_w for
    ``"piecewise_constant"`` / ``"wiener_increment"`` (spec 004 §3.3 B).
    """

    order: int
    noise: str = "continuous"
    intensity: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.order, (int, np.integer)) and 1 <= self.order <= MAX_ORDER):
            raise ValueError(f"polynomial order must be an integer in 1..{MAX_ORDER}, got {self.order!r}")
        if self.noise not in NOISE_VARIANTS:
            raise ValueError(f"polynomial noise must be one of {NOISE_VARIANTS}, got {self.noise!r}")
        if not (math.isfinite(self.intensity) and self.intensity >= 0):
            raise ValueError(f"polynomial intensity must be finite and >= 0, got {self.intensity}")

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        m = self.order
        F = np.zeros(t.shape + (m, m))
        for i in range(m):
            for j in range(i, m):
                F[..., i, j] = t ** (j - i) / math.factorial(j - i)
        return F

    def noise_gain(self, dt) -> np.ndarray:
        """The vector ``g[..., m]`` of the discrete variants (``Q = sigma_w^2 g g^T``)."""
        if self.noise == "continuous":
            raise ValueError("noise_gain: the 'continuous' variant has no noise gain vector")
        t = _as_steps(dt, allow_zero=True)
        m = self.order
        top = m if self.noise == "piecewise_constant" else m - 1
        g = np.stack([t ** (top - i) / math.factorial(top - i) for i in range(m)], axis=-1)
        if self.noise == "wiener_increment":
            g = np.where((t > 0)[..., None], g, 0.0)
        return g

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        m = self.order
        if self.noise == "continuous":
            q = self.intensity
            Q = np.empty(t.shape + (m, m))
            for i in range(m):
                for j in range(m):
                    p = 2 * m - 1 - i - j
                    Q[..., i, j] = q * t**p / (p * math.factorial(m - 1 - i) * math.factorial(m - 1 - j))
            return Q
        # sigma_w g first, so that Q is exactly symmetric
        g = self.intensity * self.noise_gain(t)
        return g[..., :, None] * g[..., None, :]


def polynomial(ndim: int, order: int, noise: str = "continuous", intensity: float = 0.0) -> MotionModel:
    """Isotropic ``ndim``-D polynomial model: the same :class:`PolynomialAxis` on every axis."""
    if ndim not in (1, 2, 3):
        raise ValueError(f"polynomial: ndim must be 1, 2 or 3, got {ndim!r}")
    return MotionModel([PolynomialAxis(order, noise, intensity)] * ndim)


def dwna(ndim: int, sigma_w: float) -> MotionModel:
    """Discrete white-noise acceleration (order 2, ``piecewise_constant``, g = [T^2/2, T])."""
    return polynomial(ndim, 2, "piecewise_constant", sigma_w)


def dwpa(ndim: int, sigma_w: float) -> MotionModel:
    """Discrete Wiener-process acceleration (order 3, ``wiener_increment``, g = [T^2/2, T, 1])."""
    return polynomial(ndim, 3, "wiener_increment", sigma_w)

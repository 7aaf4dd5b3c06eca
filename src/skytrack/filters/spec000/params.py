"""Per-step Singer coefficients and the filter history a coefficient policy sees (spec 000, R10).

What lives here:

* :class:`SingerParams` — the coefficients (sigma_a, tau) of one Singer axis for one step;
  the model's own values are the default.  Their meaning is the kinematic model (K2)-(K3):
  sigma_a the stationary acceleration st. dev., tau the mean manoeuvre time, rho = exp(-dt/tau).
* :class:`SingerHistory` — what a filter has seen and done, scan by scan.  It is the only
  argument of a non-anticipative ``coefficient_policy`` (R10), so coefficients may depend on
  the whole observed past xi^n, as Glonti's extension (2a) of Theorem 1 allows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from skytrack.models.motion import SingerAxisModel


@dataclass(frozen=True)
class SingerParams:
    """Per-step Singer coefficients (R10): acceleration st. dev. ``sigma_a`` (m/s^2), ``tau`` (s)."""

    sigma_a: float
    tau: float

    def __post_init__(self):
        if not (math.isfinite(self.sigma_a) and self.sigma_a >= 0):
            raise ValueError(f"SingerParams.sigma_a must be finite and >= 0, got {self.sigma_a}")
        if not (math.isfinite(self.tau) and self.tau > 0):
            raise ValueError(f"SingerParams.tau must be finite and > 0, got {self.tau}")

    @classmethod
    def of(cls, model: SingerAxisModel) -> "SingerParams":
        return cls(sigma_a=float(model.sigma_a), tau=float(model.tau))


@dataclass
class SingerHistory:
    """What a filter has seen and done, scan by scan (R10): the argument of a coefficient policy.

    Entry k describes step k+1: its ``dt``, the parameters used (per axis in 3-D), the
    detection flag, the measurement (None on a miss), the updated mean and d^2 (NaN on a miss).
    """

    dt: list[float] = field(default_factory=list)
    params: list = field(default_factory=list)
    detected: list[bool] = field(default_factory=list)
    measurements: list = field(default_factory=list)
    means: list[np.ndarray] = field(default_factory=list)
    d2: list[float] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.dt)

    def append(self, dt, params, detected, measurement, mean, d2) -> None:
        self.dt.append(float(dt))
        self.params.append(params)
        self.detected.append(bool(detected))
        self.measurements.append(measurement)
        self.means.append(mean)
        self.d2.append(float(d2))

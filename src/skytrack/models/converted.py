"""Measurement model of the tracker: converted plot positions, optionally with Doppler range rate.

Implements the measurement protocol every filter's ``innovate`` uses:

* ``evaluate(x, context) -> (h[K, m], H[K, m, n])`` — predicted measurement and Jacobian;
* ``noise(context) -> R[K, m, m]``;
* ``residual(z, h, context) -> nu[K, m]`` — the one place where innovations are formed
  (angles wrapped, absent components padded with zero);
* ``measured(context) -> m[K]`` — components actually measured per row.

The position part is linear, ``h = x[pos]`` with the converted-plot covariance of
:func:`skytrack.models.conversion.convert_plots` per row (``context["R"]``).  When
``range_rate_sigma`` is given, rows whose plot carries a range rate (``context["has_range_rate"]``)
add the nonlinear Doppler component ``rdot = (p . v) / |p|`` relative to the sensor (spec 000
R9); other rows pad it with a zero row of ``H``, zero innovation and unit variance, which
leaves ``d^2`` and the gain exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.models.measurement import PolarMeasurementModel


@dataclass(frozen=True)
class ConvertedPositionModel:
    """Positions of the first ``ndim`` axes of an ``order``-per-axis state, plus optional range rate."""

    ndim: int
    order: int
    range_rate_sigma: float | None = None

    @property
    def dim(self) -> int:
        return self.ndim + (1 if self.range_rate_sigma is not None else 0)

    @property
    def position_index(self) -> np.ndarray:
        return np.arange(self.ndim) * self.order

    @property
    def linear(self) -> bool:
        return self.range_rate_sigma is None

    def evaluate(self, x: np.ndarray, context: dict) -> tuple[np.ndarray, np.ndarray]:
        count, n = x.shape
        pos = self.position_index
        h = np.zeros((count, self.dim))
        H = np.zeros((count, self.dim, n))
        h[:, : self.ndim] = x[:, pos]
        H[:, np.arange(self.ndim), pos] = 1.0
        if self.range_rate_sigma is not None:
            has = context["has_range_rate"]
            if has.any():
                polar = PolarMeasurementModel(("rdot",), (self.range_rate_sigma,), self.order)
                value, J = polar.evaluate(x, sensor_position=context["sensor_position"],
                                          rotation=context["rotation"], sensor_velocity=context["sensor_velocity"])
                h[has, -1] = value[has, 0]
                H[has, -1, :] = J[has, 0, :]
        return h, H

    def noise(self, context: dict) -> np.ndarray:
        R = context["R"]
        if self.range_rate_sigma is None:
            return R
        count = len(R)
        full = np.zeros((count, self.dim, self.dim))
        full[:, : self.ndim, : self.ndim] = R
        full[:, -1, -1] = np.where(context["has_range_rate"], self.range_rate_sigma**2, 1.0)
        return full

    def residual(self, z: np.ndarray, h: np.ndarray, context: dict) -> np.ndarray:
        nu = z - h
        if self.range_rate_sigma is not None:
            nu[~context["has_range_rate"], -1] = 0.0
        return nu

    def measured(self, context: dict) -> np.ndarray:
        count = len(context["R"])
        m = np.full(count, self.ndim)
        if self.range_rate_sigma is not None:
            m = m + context["has_range_rate"].astype(int)
        return m

"""Measurement models, vectorised over a batch of K (state, sensor) pairs.

Each model gives the predicted measurement ``h(x)`` ``[K, m]``, its Jacobian with
respect to the state ``[K, m, n]`` and the noise covariance ``R`` ``[m, m]``.

* :class:`PolarMeasurementModel` — radar polar components in the sensor's local frame
  (spec 000, R8): range ``r = |p|``, azimuth ``az = atan2(x, y) mod 2 pi`` (clockwise from
  north), elevation ``el = atan2(z, sqrt(x^2 + y^2))``, range rate
  ``rdot = (p . v) / r`` (positive opening), and the linear altitude ``z_alt = z``.
  ``p`` and ``v`` are the target's position and velocity relative to the sensor, rotated
  into the sensor frame: ``p = A (x_pos - p_s)``, ``v = A (x_vel - v_s)``.  A moving sensor
  passes per-pair ``p_s`` and ``v_s``.  The angle components are flagged in ``angular`` so
  that innovations are wrapped to (-pi, pi].
* :class:`CartesianPositionModel` — linear position measurement (ADS-B, converted plots).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.geo.polar import azimuth_of

POLAR_COMPONENTS = ("r", "az", "el", "rdot", "z_alt")


def state_indices(ndim: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity indices of the per-axis state layout."""
    base = np.arange(ndim) * order
    return base, base + 1


@dataclass(frozen=True)
class PolarMeasurementModel:
    """Radar measurement made of any subset of ``r, az, el, rdot, z_alt`` (in that order).

    ``sigmas`` maps each component to its standard deviation (m, rad, rad, m/s, m).
    The state is 3-D with ``order`` states per axis (2 for CV, 3 for CA/Singer).
    """

    components: tuple[str, ...]
    sigmas: tuple[float, ...]
    order: int = 3

    def __post_init__(self):
        unknown = [c for c in self.components if c not in POLAR_COMPONENTS]
        if unknown:
            raise ValueError(f"unknown polar components {unknown}; known: {POLAR_COMPONENTS}")
        if len(self.sigmas) != len(self.components):
            raise ValueError("one sigma per component is needed")
        if any(not (s > 0 and np.isfinite(s)) for s in self.sigmas):
            raise ValueError(f"measurement sigmas must be finite and > 0, got {self.sigmas}")
        if list(self.components) != sorted(self.components, key=POLAR_COMPONENTS.index):
            raise ValueError(f"components must be in the order {POLAR_COMPONENTS}")

    @property
    def dim(self) -> int:
        return len(self.components)

    @property
    def R(self) -> np.ndarray:
        return np.diag(np.square(self.sigmas))

    @property
    def angular(self) -> np.ndarray:
        return np.array([c in ("az", "el") for c in self.components])

    def evaluate(self, states, sensor_position=None, rotation=None, sensor_velocity=None, jacobian=True):
        """Return ``h [K, m]`` and, with ``jacobian``, ``H [K, m, n]`` for states ``[K, n]``."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        k, n = states.shape
        pos_idx, vel_idx = state_indices(3, self.order)
        rot = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
        p_s = np.zeros(3) if sensor_position is None else np.asarray(sensor_position, dtype=float)
        rel = (states[:, pos_idx] - p_s) @ rot.T
        x, y, z = rel[:, 0], rel[:, 1], rel[:, 2]
        ground2 = x * x + y * y
        ground = np.sqrt(ground2)
        r2 = ground2 + z * z
        r = np.sqrt(r2)
        needs_velocity = "rdot" in self.components
        if needs_velocity:
            v_s = np.zeros(3) if sensor_velocity is None else np.asarray(sensor_velocity, dtype=float)
            relv = (states[:, vel_idx] - v_s) @ rot.T
            radial = np.einsum("ki,ki->k", rel, relv)
        h = np.empty((k, self.dim))
        if jacobian:
            d_local_pos = np.zeros((k, self.dim, 3))
            d_local_vel = np.zeros((k, self.dim, 3))
        for row, comp in enumerate(self.components):
            if comp == "r":
                h[:, row] = r
                if jacobian:
                    d_local_pos[:, row] = rel / r[:, None]
            elif comp == "az":
                h[:, row] = azimuth_of(x, y)
                if jacobian:
                    d_local_pos[:, row, 0] = y / ground2
                    d_local_pos[:, row, 1] = -x / ground2
            elif comp == "el":
                h[:, row] = np.arctan2(z, ground)
                if jacobian:
                    scale = z / (r2 * ground)
                    d_local_pos[:, row, 0] = -x * scale
                    d_local_pos[:, row, 1] = -y * scale
                    d_local_pos[:, row, 2] = ground / r2
            elif comp == "rdot":
                h[:, row] = radial / r
                if jacobian:
                    d_local_pos[:, row] = relv / r[:, None] - (radial / (r2 * r))[:, None] * rel
                    d_local_vel[:, row] = rel / r[:, None]
            else:  # z_alt: the target's common-frame z, linear
                h[:, row] = states[:, pos_idx[2]]
        if not jacobian:
            return h
        H = np.zeros((k, self.dim, n))
        H[:, :, pos_idx] = d_local_pos @ rot
        if needs_velocity:
            H[:, :, vel_idx] = d_local_vel @ rot
        if "z_alt" in self.components:
            row = self.components.index("z_alt")
            H[:, row, :] = 0.0
            H[:, row, pos_idx[2]] = 1.0
        return h, H


@dataclass(frozen=True)
class CartesianPositionModel:
    """Linear position measurement of the first ``ndim`` axes: ``h(x) = H x``.

    ``sigma_m`` is the per-axis standard deviation (e.g. an ADS-B report's ``sigma_m``);
    ``R`` is only defined when it is given.
    """

    ndim: int
    order: int
    state_ndim: int | None = None
    sigma_m: float | None = None

    def __post_init__(self):
        if self.sigma_m is not None and not (np.isfinite(self.sigma_m) and self.sigma_m > 0):
            raise ValueError(f"sigma_m must be finite and > 0, got {self.sigma_m}")

    @property
    def dim(self) -> int:
        return self.ndim

    @property
    def R(self) -> np.ndarray:
        if self.sigma_m is None:
            raise ValueError("CartesianPositionModel has no sigma_m: R is unknown")
        return np.eye(self.ndim) * self.sigma_m**2

    @property
    def angular(self) -> np.ndarray:
        return np.zeros(self.ndim, dtype=bool)

    def matrix(self) -> np.ndarray:
        n_axes = self.state_ndim or self.ndim
        H = np.zeros((self.ndim, n_axes * self.order))
        H[np.arange(self.ndim), np.arange(self.ndim) * self.order] = 1.0
        return H

    def evaluate(self, states, jacobian=True, **_unused):
        states = np.atleast_2d(np.asarray(states, dtype=float))
        H = self.matrix()
        h = states @ H.T
        if not jacobian:
            return h
        return h, np.broadcast_to(H, (states.shape[0],) + H.shape)

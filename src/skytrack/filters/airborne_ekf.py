"""EKF cycle and one-plot initiation for spec 003's airborne radar (R5, R6), batched over rows.

State ``x = [e, n, u, v_e, v_n, v_u]`` (ENU, spec layout of :mod:`skytrack.models.airborne`);
covariances ``P [K, 6, 6]``; measurements ``z [K, m]`` = (D, az, el[, V_r]), m = 4 or 3.

* :func:`cv_transition` / :func:`predict` — R5 motion model, constant velocity with white
  acceleration of spectral density ``q`` (m^2/s^3):
  ``F = [[I, T I], [0, I]]``, ``Q = q [[T^3/3 I, T^2/2 I], [T^2/2 I, T I]]``; the per-axis
  blocks are :class:`skytrack.models.motion.ConstantVelocityAxis`'s, arranged for the
  spec layout, and the step is :func:`skytrack.filters.ekf.predict`.
* :func:`ekf_update` — R5 update: ``h`` and ``H`` at ``x^-`` with the plot's own-ship state,
  ``nu = z - h(x^-)`` with the azimuth wrapped to (-pi, pi] (R4), ``S = H P^- H^T + R``,
  ``K = P^- H^T S^-1``, ``x^+ = x^- + K nu`` and the Joseph-form ``P^+``
  (:func:`skytrack.filters.ekf.update`, which also returns ``nu``, ``S``, ``K`` and ``d^2`` so
  that the association layer can reuse them).
* :func:`initiate_from_plot` — R6 one-plot initiation:
  ``u = (cos el sin az, cos el cos az, sin el)``, ``p = p_o + D u``,
  ``v = (V_r + u . v_o) u`` (so ``h(x)`` reproduces the plot exactly),
  ``P_pp = J R_3 J^T`` with ``J = d p / d(D, az, el)``,
  ``P_vv = sigma_v0^2 (I - u u^T) + sigma_V^2 u u^T``, ``P_pv = 0``; without range rate
  ``v = 0`` and ``P_vv = sigma_v0^2 I``.
"""

from __future__ import annotations

import numpy as np

from skytrack.core import linalg
from skytrack.filters import ekf
from skytrack.geo.polar import polar_to_cartesian
from skytrack.models.airborne import airborne_measurement, wrap_residual
from skytrack.models.motion import ConstantVelocityAxis

#: default velocity standard deviation of a one-plot track across the line of sight (m/s, R6)
DEFAULT_SIGMA_V0 = 300.0


def cv_transition(dt, q: float) -> tuple[np.ndarray, np.ndarray]:
    """``F`` and ``Q`` of R5 in the spec layout: ``[6, 6]`` for a scalar ``dt``, ``[K, 6, 6]`` for ``dt [K]``."""
    axis = ConstantVelocityAxis(q)
    blocks_F, blocks_Q = axis.F_batch(dt), axis.Q_batch(dt)
    eye3 = np.eye(3)
    # the (position, velocity) block entry a, b multiplies the 3x3 identity: Kronecker product
    F = np.einsum("...ab,ij->...aibj", blocks_F, eye3).reshape(blocks_F.shape[:-2] + (6, 6))
    Q = np.einsum("...ab,ij->...aibj", blocks_Q, eye3).reshape(blocks_Q.shape[:-2] + (6, 6))
    return F, Q


def predict(x: np.ndarray, P: np.ndarray, dt, q: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity prediction of ``x [K, 6]``, ``P [K, 6, 6]`` over ``dt`` (scalar or ``[K]``) (R5)."""
    F, Q = cv_transition(dt, q)
    return ekf.predict(np.asarray(x, dtype=float), np.asarray(P, dtype=float), F, Q)


def ekf_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, own_p, own_v, R: np.ndarray,
               form: str = "joseph") -> ekf.UpdateResult:
    """EKF update of predicted ``x [K, 6]``, ``P [K, 6, 6]`` with plots ``z [K, m]`` (R5).

    ``own_p``, ``own_v`` ``[K, 3]`` (or ``[3]``) are the own-ship state at the plots' time; ``R`` is
    ``[m, m]`` or ``[K, m, m]``.  Returns :class:`skytrack.filters.ekf.UpdateResult` with
    ``x``, ``P`` (Joseph form), the wrapped innovation ``nu``, ``S``, the gain ``K`` and ``d2``.
    Raises ``ValueError`` for a pair with the object overhead of the own-ship (R3).
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    z = np.atleast_2d(np.asarray(z, dtype=float))
    h, H = airborne_measurement(x, own_p, own_v, with_range_rate=_has_range_rate(z))
    nu = wrap_residual(z - h)
    return ekf.update(x, np.asarray(P, dtype=float), nu, H, np.asarray(R, dtype=float), form=form)


def _has_range_rate(z: np.ndarray) -> bool:
    if z.shape[-1] not in (3, 4):
        raise ValueError(f"airborne plots have 4 (D, az, el, V_r) or 3 components, got {z.shape[-1]}")
    return z.shape[-1] == 4


def initiate_from_plot(z, own_p, own_v, R, sigma_v0: float = DEFAULT_SIGMA_V0) -> tuple[np.ndarray, np.ndarray]:
    """One-plot track start (R6): state ``[K, 6]`` and covariance ``[K, 6, 6]`` from plots ``z [K, m]``.

    ``R`` (``[m, m]`` or ``[K, m, m]``) gives ``R_3`` (its first three rows and columns) and
    ``sigma_V^2``; ``own_v`` is only used with range rate (m = 4).
    """
    if not (np.isfinite(sigma_v0) and sigma_v0 > 0):
        raise ValueError(f"sigma_v0 must be finite and > 0, got {sigma_v0}")
    z = np.atleast_2d(np.asarray(z, dtype=float))
    with_range_rate = _has_range_rate(z)
    count = z.shape[0]
    R = np.broadcast_to(np.asarray(R, dtype=float), (count,) + (z.shape[-1],) * 2)
    own_p = np.broadcast_to(np.asarray(own_p, dtype=float), (count, 3))
    distance, az, el = z[:, 0], z[:, 1], z[:, 2]
    u = np.stack(polar_to_cartesian(np.ones(count), az, el), axis=-1)
    sin_az, cos_az, sin_el, cos_el = np.sin(az), np.cos(az), np.sin(el), np.cos(el)
    zero = np.zeros(count)
    d_az = distance[:, None] * np.stack([cos_el * cos_az, -cos_el * sin_az, zero], axis=-1)
    d_el = distance[:, None] * np.stack([-sin_el * sin_az, -sin_el * cos_az, cos_el], axis=-1)
    J = np.stack([u, d_az, d_el], axis=-1)  # columns d p / d(D, az, el)

    x = np.zeros((count, 6))
    x[:, :3] = own_p + distance[:, None] * u
    P = np.zeros((count, 6, 6))
    P[:, :3, :3] = linalg.sandwich(J, R[:, :3, :3])
    eye3 = np.eye(3)
    if with_range_rate:
        own_v = np.broadcast_to(np.asarray(own_v, dtype=float), (count, 3))
        speed_along_los = z[:, 3] + np.einsum("ki,ki->k", u, own_v)
        x[:, 3:] = speed_along_los[:, None] * u
        uu = u[:, :, None] * u[:, None, :]
        P[:, 3:, 3:] = sigma_v0**2 * (eye3 - uu) + R[:, 3, 3, None, None] * uu
    else:
        P[:, 3:, 3:] = sigma_v0**2 * eye3
    return x, P

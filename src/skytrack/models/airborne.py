"""Airborne radar measurement model of spec 003 (§2.3, R3, R4), vectorised over pairs.

State in ENU, in the spec's layout ``x = [e, n, u, v_e, v_n, v_u]`` (position block, then
velocity block; the per-axis layout of :mod:`skytrack.models.motion` is
``[e, v_e, n, v_n, u, v_u]``, see :data:`SPEC_TO_PER_AXIS`).  The radar sits on the
own-ship at ``p_o`` moving with ``v_o``; with ``Delta = (e, n, u) - p_o``,
``Delta_v = (v_e, v_n, v_u) - v_o``, ``rho = sqrt(De^2 + Dn^2)`` and ``D = |Delta|``:

    D   = |Delta|                       (range, m)
    az  = atan2(De, Dn) mod 2 pi        (azimuth clockwise from north, in [0, 2 pi))
    el  = atan2(Du, rho)                (elevation)
    V_r = Delta . Delta_v / D           (range rate dD/dt, positive opening)

The values and the analytic Jacobian come from
:class:`skytrack.models.measurement.PolarMeasurementModel` (the same formulas for a moving
sensor with per-pair position and velocity); this module only maps the state layout and adds
what spec 003 asks on top:

* R3: the 3-row variant without ``V_r``; pairs with ``rho < 1e-6 D`` (object overhead or
  underneath the own-ship, azimuth undefined) raise ``ValueError`` naming their rows, and
  :func:`degenerate_pairs` gives the same test as a mask so that the tracker can exclude
  and count such pairs without exceptions;
* R4: :func:`wrap_residual` wraps the azimuth residual to (-pi, pi] (elevation is not
  wrapped: it never leaves [-pi/2, pi/2]);
* :func:`airborne_noise`: ``R = diag(sigma_D^2, sigma_az^2, sigma_el^2[, sigma_V^2])``.
"""

from __future__ import annotations

import numpy as np

from skytrack.geo.polar import wrap_angle
from skytrack.models.measurement import PolarMeasurementModel

#: measurement components, in row order (the 3-row variant drops the last)
AIRBORNE_COMPONENTS = ("range_m", "az", "el", "vr")
#: column of the azimuth in a measurement or residual vector
AZIMUTH_COLUMN = 1
#: a pair whose horizontal distance is below this fraction of its range has no usable azimuth (R3)
OVERHEAD_RATIO = 1e-6
#: spec-layout state ``[e, n, u, v_e, v_n, v_u]`` -> per-axis layout ``[e, v_e, n, v_n, u, v_u]``
SPEC_TO_PER_AXIS = np.array([0, 3, 1, 4, 2, 5])
#: per-axis column -> spec-layout column (the inverse permutation)
PER_AXIS_TO_SPEC = np.argsort(SPEC_TO_PER_AXIS)

# The polar model's sigmas only build its R, which is not used here (airborne_noise builds R).
_POLAR_MODELS = {
    True: PolarMeasurementModel(("r", "az", "el", "rdot"), (1.0, 1.0, 1.0, 1.0), order=2),
    False: PolarMeasurementModel(("r", "az", "el"), (1.0, 1.0, 1.0), order=2),
}
#: how many offending rows an error message lists
_ROWS_SHOWN = 10


def _pairs(x, own_p) -> tuple[np.ndarray, np.ndarray]:
    states = np.atleast_2d(np.asarray(x, dtype=float))
    if states.shape[-1] != 6:
        raise ValueError(f"airborne states must be [K, 6] (e, n, u, v_e, v_n, v_u), got shape {states.shape}")
    own_p = np.broadcast_to(np.asarray(own_p, dtype=float), (states.shape[0], 3))
    return states, own_p


def degenerate_pairs(x, own_p) -> np.ndarray:
    """Boolean mask ``[K]`` of (state, own-ship) pairs with ``rho < 1e-6 D`` or ``D = 0`` (R3).

    Azimuth and the elevation's Jacobian are undefined there; the tracker excludes these
    pairs from association and counts them.
    """
    states, own_p = _pairs(x, own_p)
    delta = states[:, :3] - own_p
    rho = np.hypot(delta[:, 0], delta[:, 1])
    distance = np.sqrt(rho * rho + delta[:, 2] ** 2)
    return (rho < OVERHEAD_RATIO * distance) | (distance == 0.0)


def airborne_measurement(x, own_p, own_v=None, with_range_rate: bool = True, jacobian: bool = True):
    """Predicted measurement ``h [K, m]`` and Jacobian ``H [K, m, 6]`` of spec 003 §2.3.

    ``x [K, 6]`` in the spec layout; ``own_p``, ``own_v`` ``[K, 3]`` (or ``[3]``, shared) are
    the own-ship's position and velocity at the plot time.  ``m`` is 4 (D, az, el, V_r) or 3
    without range rate (``own_v`` is then not needed).  Azimuth is in [0, 2 pi).  With
    ``jacobian=False`` only ``h`` is returned.  Raises ``ValueError`` naming the pair rows
    with ``rho < 1e-6 D`` (see :func:`degenerate_pairs`).
    """
    states, own_p = _pairs(x, own_p)
    bad = degenerate_pairs(states, own_p)
    if bad.any():
        rows = np.flatnonzero(bad)
        shown = ", ".join(str(r) for r in rows[:_ROWS_SHOWN]) + (", ..." if len(rows) > _ROWS_SHOWN else "")
        raise ValueError(
            f"airborne measurement undefined for pair rows [{shown}] ({len(rows)} pairs): horizontal distance "
            f"rho < {OVERHEAD_RATIO:g} * range (object overhead or underneath the own-ship)"
        )
    if with_range_rate:
        if own_v is None:
            raise ValueError("own_v is required for the range-rate component")
        own_v = np.broadcast_to(np.asarray(own_v, dtype=float), own_p.shape)
    result = _POLAR_MODELS[bool(with_range_rate)].evaluate(
        states[:, SPEC_TO_PER_AXIS], sensor_position=own_p, sensor_velocity=own_v, jacobian=jacobian
    )
    if not jacobian:
        return result
    h, H_per_axis = result
    return h, H_per_axis[:, :, PER_AXIS_TO_SPEC]


def wrap_residual(nu) -> np.ndarray:
    """A copy of residuals ``nu [..., m]`` with the azimuth (column 1) wrapped to (-pi, pi] (R4)."""
    wrapped = np.array(nu, dtype=float, copy=True)
    wrapped[..., AZIMUTH_COLUMN] = wrap_angle(wrapped[..., AZIMUTH_COLUMN])
    return wrapped


def airborne_noise(sigma_range, sigma_az, sigma_el, sigma_vr=None, with_range_rate: bool = True) -> np.ndarray:
    """Measurement noise ``R = diag(sigma_D^2, sigma_az^2, sigma_el^2[, sigma_V^2])`` (§2.1).

    Scalars give ``[m, m]``; arrays (one value per plot, broadcast together) give ``[..., m, m]``.
    Units m, rad, rad, m/s; every sigma must be finite and > 0.
    """
    sigmas = [sigma_range, sigma_az, sigma_el]
    if with_range_rate:
        if sigma_vr is None:
            raise ValueError("sigma_vr is required when with_range_rate is True")
        sigmas.append(sigma_vr)
    stacked = np.stack(np.broadcast_arrays(*[np.asarray(s, dtype=float) for s in sigmas]), axis=-1)
    if not np.all(np.isfinite(stacked) & (stacked > 0)):
        raise ValueError(f"measurement sigmas must be finite and > 0, got {stacked.tolist()}")
    return stacked[..., :, None] ** 2 * np.eye(stacked.shape[-1])

"""Steady state of the 1-D Singer filter without misses (spec 000, R12, TV8; the paper's A1).

What lives here: :class:`SteadyState` and :func:`steady_state`, the P_D = 1 limits (P-, P+)
of the filter.  P- solves the filter-form discrete algebraic Riccati equation
P- = F P- F^T - F P- H^T (H P- H^T + R)^-1 H P- F^T + Q, with F, Q from (K6) or (X1)-(X2)
and H, R from (M2)/(M3); P+ is one update (4) of P-.  With P_D = 1 the filter is the
Kalman filter (S2), and its steady state is the start gamma(0) of the accuracy study (A1, §6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from skytrack.filters.spec000.kernels import _axis_FQ, _measurement_noise_bl, _predict_bl, _update_cov_bl
from skytrack.filters.spec000.validation import _check_dt, _check_form, _check_measurement, _check_sigma
from skytrack.models.motion import SingerAxisModel


@dataclass(frozen=True)
class SteadyState:
    """P_D = 1 limits (R12): predicted ``P_pred`` (P-) and filtered ``P_filt`` (P+); unpacks as (P-, P+)."""

    P_pred: np.ndarray
    P_filt: np.ndarray

    def __iter__(self):
        return iter((self.P_pred, self.P_filt))


def steady_state(
    model: SingerAxisModel,
    measurement: str = "pos",
    *,
    sigma: float,
    dt: float,
    sigma_v: float | None = None,
    update_form: str = "joseph",
) -> SteadyState:
    """Steady-state (P-, P+) of the 1-D filter without misses (R12, TV8), from the DARE.

    ``scipy.linalg.solve_discrete_are`` solves P- = F P- F^T - F P- H^T (H P- H^T + R)^-1
    H P- F^T + Q (the filter-form DARE is the control DARE with a = F^T, b = H^T); a few
    Riccati iterations with the filter's own update then remove the solver's last-digit
    residual, so that the recursion started from P+ stays at P+ (E3).
    """
    idx = _check_measurement(measurement)
    _check_form(update_form)
    dt = _check_dt(dt)
    sigma_arr = _check_sigma("sigma", sigma)
    if sigma_arr.size != 1:
        raise ValueError("steady_state takes one scalar sigma")
    if len(idx) == 2:
        _check_sigma("sigma_v", sigma_v)
    F, Q = _axis_FQ(model, None, dt)
    H = np.eye(3)[list(idx)]
    R = np.diag([float(sigma_arr[0]) ** 2] + ([float(sigma_v) ** 2] if len(idx) == 2 else []))
    P_pred = solve_discrete_are(F.T, H.T, Q, R)
    P_pred = 0.5 * (P_pred + P_pred.T)
    R_bl = _measurement_noise_bl(idx, sigma_arr, sigma_v)
    P = P_pred[..., None]
    for _ in range(100):
        P_filt = _update_cov_bl(P, idx, R_bl, update_form)[-1]
        _, P_next = _predict_bl(None, P_filt, F, Q)
        change = np.max(np.abs(P_next - P)) / np.max(np.abs(P))
        P = P_next
        if change <= 4e-16:
            break
    P_filt = _update_cov_bl(P, idx, R_bl, update_form)[-1]
    if not (np.all(np.isfinite(P)) and np.all(np.linalg.eigvalsh(P[..., 0]) > 0)):
        raise ValueError("steady-state covariance is not positive definite; check the model parameters")
    return SteadyState(P[..., 0], P_filt[..., 0])

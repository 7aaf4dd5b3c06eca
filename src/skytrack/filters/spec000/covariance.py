"""Covariance recursion along realised detection patterns (spec 000, §6 protocol, the paper's A1-A3).

What lives here: :func:`covariance_recursion` and its result :class:`CovarianceAverages`.
For n = 1..N, B tracks at once: e-gamma(n) = F gamma(n-1) F^T + Q (Theorem 2 (5)); gamma(n)
is the update (4) of e-gamma(n) if scan n is detected and e-gamma(n) itself on a miss (S1, R4).
The time averages of diag(gamma) and diag(e-gamma) give FS11 and FES11 of (A3).  This is the
covariance half of the filter only: it needs no trajectory simulation, which lets the study
vectorise its runs dimension (R15).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from skytrack.filters.spec000.kernels import _axis_FQ, _measurement_noise_bl, _predict_bl, _update_cov_bl
from skytrack.filters.spec000.validation import (
    _check_covariance,
    _check_dt,
    _check_form,
    _check_measurement,
    _check_sigma,
)
from skytrack.models.motion import SingerAxisModel


@dataclass(frozen=True)
class CovarianceAverages:
    """Time averages over scans 1..N of diag(gamma(n)) (``filtered``) and diag(e-gamma(n)) (``predicted``), [B, 3].

    ``final`` is gamma(N) [B, 3, 3].  With ``record=True`` the full sequences gamma(n),
    e-gamma(n), n = 1..N, are kept as ``filtered_history`` / ``predicted_history`` [N, B, 3, 3].
    """

    filtered: np.ndarray
    predicted: np.ndarray
    final: np.ndarray
    filtered_history: np.ndarray | None = None
    predicted_history: np.ndarray | None = None


def covariance_recursion(
    model: SingerAxisModel,
    measurement: str,
    *,
    sigma,
    dt: float,
    P0: np.ndarray,
    detection: Callable[[int], np.ndarray] | np.ndarray,
    n_scans: int,
    sigma_v: float | None = None,
    update_form: str = "joseph",
    record: bool = False,
) -> CovarianceAverages:
    """Covariance half of the filter along realised detection patterns, B tracks at once (§6, A1-A3).

    For n = 1..N: e-gamma(n) = F gamma(n-1) F^T + Q; gamma(n) = update(e-gamma(n)) if the
    scan is detected, else e-gamma(n).  ``sigma`` is a scalar or one value per track [B];
    ``P0`` is [3, 3] or [B, 3, 3]; ``detection`` is a bool array [N, B] or a callable
    ``n -> bool[B]`` for n = 1..N (so that the flags of a large study need not be stored).
    """
    idx = _check_measurement(measurement)
    form = _check_form(update_form)
    dt = _check_dt(dt)
    sigma_arr = _check_sigma("sigma", sigma)
    if len(idx) == 2:
        _check_sigma("sigma_v", sigma_v)
    if int(n_scans) != n_scans or n_scans < 1:
        raise ValueError(f"n_scans must be a positive integer, got {n_scans!r}")
    P0 = np.asarray(P0, dtype=float)
    if P0.shape[-2:] != (3, 3):
        raise ValueError(f"P0 must be [3, 3] or [B, 3, 3], got shape {P0.shape}")
    _check_covariance("P0", P0)
    if callable(detection):
        flags_at = detection
    else:
        flags = np.asarray(detection, dtype=bool)
        if flags.ndim != 2 or flags.shape[0] != n_scans:
            raise ValueError(f"detection must be [n_scans={n_scans}, B], got shape {flags.shape}")
        flags_at = lambda n: flags[n - 1]  # noqa: E731 - scans are counted from 1
    first = np.atleast_1d(np.asarray(flags_at(1), dtype=bool))
    batch = max(first.size, sigma_arr.size, 1 if P0.ndim == 2 else P0.shape[0])
    for name, size in (("detection flags", first.size), ("sigma", sigma_arr.size), ("P0", 1 if P0.ndim == 2 else P0.shape[0])):
        if size not in (1, batch):
            raise ValueError(f"{name} has {size} tracks, others have {batch}")
    P = np.broadcast_to(P0, (batch, 3, 3)).transpose(1, 2, 0).copy()
    R = _measurement_noise_bl(idx, sigma_arr, sigma_v)
    F, Q = _axis_FQ(model, None, dt)
    sum_filt = np.zeros((3, batch))
    sum_pred = np.zeros((3, batch))
    hist_filt = np.empty((int(n_scans), batch, 3, 3)) if record else None
    hist_pred = np.empty((int(n_scans), batch, 3, 3)) if record else None
    diag = np.arange(3)
    for n in range(1, int(n_scans) + 1):
        detected = first if n == 1 else np.asarray(flags_at(n), dtype=bool)
        _, P_pred = _predict_bl(None, P, F, Q)
        sum_pred += P_pred[diag, diag]
        if np.any(detected):
            P_upd = _update_cov_bl(P_pred, idx, R, form)[-1]
            P = np.where(detected, P_upd, P_pred)
        else:
            P = P_pred
        sum_filt += P[diag, diag]
        if record:
            hist_pred[n - 1] = P_pred.transpose(2, 0, 1)
            hist_filt[n - 1] = P.transpose(2, 0, 1)
    return CovarianceAverages(
        filtered=(sum_filt / n_scans).T, predicted=(sum_pred / n_scans).T, final=P.transpose(2, 0, 1).copy(),
        filtered_history=hist_filt, predicted_history=hist_pred,
    )

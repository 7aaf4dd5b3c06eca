"""Batch-last covariance kernels of the 1-D Singer filters (spec 000, Theorem 2 (5), Theorem 1 (3)-(4)).

What lives here (all private to :mod:`skytrack.filters.spec000`):

* ``_singer_FQ`` / ``_axis_FQ`` — F(dt), Q(dt) of one Singer axis, from (K6) (``"paper"``)
  or (X1)-(X2) (``"exact"``), cached because steps repeat scan after scan.
* ``_predict_bl`` — Theorem 2 (5): em = F m, eP = F P F^T + Q.
* ``_update_cov_bl`` — the covariance half of Theorem 1 (4) in Kalman form (§3.1 "Check",
  (F9)-(F10) for the paper model): S = H eP H^T + R, K = eP H^T S^-1, and P+ in the Joseph
  or the standard form, followed by P <- (P + P^T)/2.
* ``_cholesky_small``, ``_inverse_from_cholesky``, ``_mahalanobis_from_cholesky`` — the 1x1 /
  2x2 Cholesky factor of S and d^2 = nu^T S^-1 nu by forward substitution (R7).
* ``_measurement_noise_bl`` — R = diag(sigma^2) (M2) or diag(sigma^2, sigma_v^2) (M3).

Layout: m[3, N], P[3, 3, N] (batch-last), F, Q [3, 3] shared, R [k, k, N] or [k, k, 1];
numpy's element-wise arithmetic over a trailing batch axis is an order of magnitude faster
than stacked 3x3 matmul (see the package docstring).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from skytrack.filters.spec000.params import SingerParams
from skytrack.models.motion import SingerAxisModel


@lru_cache(maxsize=4096)
def _singer_FQ(tau: float, sigma_a: float, discretization: str, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F(dt), Q(dt) of one Singer axis, cached (steps repeat scan after scan); read-only arrays."""
    model = SingerAxisModel(tau, sigma_a, discretization)
    F, Q = model.F(dt), model.Q(dt)
    F.setflags(write=False)
    Q.setflags(write=False)
    return F, Q


def _axis_FQ(model: SingerAxisModel, params: SingerParams | None, dt: float):
    p = SingerParams.of(model) if params is None else params
    return _singer_FQ(float(p.tau), float(p.sigma_a), model.discretization, dt)


# --------------------------------------------------------------------------- batch-last kernels
# m[3, N], P[3, 3, N]; F, Q [3, 3] shared; R [k, k, N] or [k, k, 1].


def _sym_bl(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.swapaxes(0, 1))


def _predict_bl(m: np.ndarray | None, P: np.ndarray, F: np.ndarray, Q: np.ndarray):
    """Theorem 2 (5): (F m, F P F^T + Q), symmetrised."""
    FP = np.einsum("ij,jk...->ik...", F, P)
    P_pred = np.einsum("ik...,jk->ij...", FP, F) + Q[..., None]
    m_pred = None if m is None else F @ m
    return m_pred, _sym_bl(P_pred)


def _cholesky_small(S: np.ndarray) -> tuple[np.ndarray, ...]:
    """Element-wise Cholesky of 1x1 / 2x2 matrices ``S[k, k, N]``: returns (L11,) or (L11, L21, L22)."""
    s11 = S[0, 0]
    if not np.all(s11 > 0):  # also catches NaN
        raise ValueError("innovation covariance S is not positive definite")
    L11 = np.sqrt(s11)
    if S.shape[0] == 1:
        return (L11,)
    L21 = S[1, 0] / L11
    schur = S[1, 1] - L21 * L21
    if not np.all(schur > 0):
        raise ValueError("innovation covariance S is not positive definite")
    return (L11, L21, np.sqrt(schur))


def _inverse_from_cholesky(L: tuple[np.ndarray, ...]) -> np.ndarray:
    """S^-1 from the factors of :func:`_cholesky_small` (S = L L^T)."""
    if len(L) == 1:
        return (1.0 / (L[0] * L[0]))[None, None]
    L11, L21, L22 = L
    # L^-1 = [[a, 0], [c, d]] with a = 1/L11, c = -L21/(L11 L22), d = 1/L22; S^-1 = L^-T L^-1
    a = 1.0 / L11
    d = 1.0 / L22
    c = -L21 * a * d
    cd = c * d
    return np.array([[a * a + c * c, cd], [cd, d * d]])


def _update_cov_bl(P_pred: np.ndarray, idx: tuple[int, ...], R: np.ndarray, form: str):
    """Kalman covariance update for H selecting the leading state rows ``idx`` (R diagonal, [k, k, N or 1]).

    Returns (S, chol(S) factors, K, P+).  The Joseph form (I - K H) eP (I - K H)^T + K R K^T
    is evaluated as B = eP - K (H eP), then B - (B H^T) K^T + K R K^T: the same product,
    using the rank-k structure of K H instead of full 3x3 products.
    """
    rows = slice(idx[0], idx[-1] + 1)  # MEASUREMENT_INDEX entries are contiguous
    PHt = P_pred[:, rows]  # [3, k, N]
    S = PHt[rows] + R
    S = 0.5 * (S + S.swapaxes(0, 1))
    L = _cholesky_small(S)
    K = np.einsum("ian,abn->ibn", PHt, _inverse_from_cholesky(L))  # [3, k, N]
    if form == "joseph":
        B = P_pred - np.einsum("ian,jan->ijn", K, PHt)
        KR = K * np.einsum("aan->an", R)[None]
        P_new = B - np.einsum("ian,jan->ijn", B[:, rows], K) + np.einsum("ian,jan->ijn", KR, K)
    else:
        P_new = P_pred - np.einsum("ian,abn,jbn->ijn", K, S, K)
    return S, L, K, _sym_bl(P_new)


def _mahalanobis_from_cholesky(nu: np.ndarray, L: tuple[np.ndarray, ...]) -> np.ndarray:
    """d^2 = nu^T S^-1 nu by forward substitution with the Cholesky factor of S (R7); nu [k, N]."""
    w1 = nu[0] / L[0]
    if len(L) == 1:
        return w1 * w1
    w2 = (nu[1] - L[1] * w1) / L[2]
    return w1 * w1 + w2 * w2


def _measurement_noise_bl(idx: tuple[int, ...], sigma: np.ndarray, sigma_v: float | None) -> np.ndarray:
    """R[k, k, N or 1] of the 1-D variants: diag(sigma^2) or diag(sigma^2, sigma_v^2)."""
    sig = np.atleast_1d(np.asarray(sigma, dtype=float))
    R = np.zeros((len(idx), len(idx), sig.size))
    R[0, 0] = sig * sig
    if len(idx) == 2:
        R[1, 1] = float(sigma_v) ** 2
    return R

"""Batched (extended) Kalman filter steps over a bank of N tracks stored as arrays.

DESIGN.md rule 1: states ``x[N, n]``, covariances ``P[N, n, n]``; every function here
is vectorised over the leading axis (no Python loop over tracks).

* :func:`predict` — Theorem 2 of spec 000 / (5): ``x' = F x``, ``P' = F P F^T + Q``.
* :func:`update` — measurement update with innovation ``nu = z - h(x)`` (angles wrapped),
  ``S = H P H^T + R``, gain ``K = P H^T S^-1``; covariance in Joseph form
  ``(I - K H) P (I - K H)^T + K R K^T`` (default) or the literal form ``P - K S K^T`` of
  spec 000 (4); both symmetrised.  A boolean ``mask`` leaves the masked-out rows
  untouched (missed detection = no update, spec 000 R4).
* :func:`mahalanobis` — squared distances ``d^2 = nu^T S^-1 nu`` through a Cholesky
  factorisation (spec 000 R7).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.geo.polar import wrap_angle

UPDATE_FORMS = ("joseph", "standard")


def symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predict states ``x[N, n]`` and covariances ``P[N, n, n]`` with ``F, Q`` ``[N, n, n]`` (or shared)."""
    x_pred = np.einsum("...ij,...j->...i", F, x)
    P_pred = F @ P @ np.swapaxes(F, -1, -2) + Q
    return x_pred, symmetrize(P_pred)


def innovation(z: np.ndarray, h: np.ndarray, angular: np.ndarray | None = None) -> np.ndarray:
    """``z - h`` with the angular components (boolean mask over the last axis) wrapped to (-pi, pi]."""
    nu = np.asarray(z, dtype=float) - h
    if angular is not None and np.any(angular):
        nu = nu.copy()
        nu[..., angular] = wrap_angle(nu[..., angular])
    return nu


def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    return symmetrize(H @ P @ np.swapaxes(H, -1, -2) + R)


def mahalanobis(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distances ``nu^T S^-1 nu`` for ``nu[K, m]``, ``S[K, m, m]``."""
    L = np.linalg.cholesky(S)
    w = np.linalg.solve(L, nu[..., None])[..., 0]
    return np.einsum("...i,...i->...", w, w)


@dataclass
class UpdateResult:
    """Outputs of :func:`update`: new state and covariance plus the innovation statistics."""

    x: np.ndarray
    P: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    K: np.ndarray
    d2: np.ndarray


def update(
    x: np.ndarray,
    P: np.ndarray,
    nu: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    mask: np.ndarray | None = None,
    form: str = "joseph",
) -> UpdateResult:
    """Kalman measurement update of a batch; rows where ``mask`` is False are not updated."""
    if form not in UPDATE_FORMS:
        raise ValueError(f"update form must be one of {UPDATE_FORMS}, got {form!r}")
    if not (np.all(np.isfinite(nu[mask] if mask is not None else nu))):
        raise ValueError("non-finite measurement or innovation in Kalman update")
    S = innovation_covariance(P, H, R)
    Ht = np.swapaxes(H, -1, -2)
    PHt = P @ Ht
    # K^T = S^-1 (P H^T)^T, S symmetric
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)
    d2 = np.einsum("...i,...i->...", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    x_new = x + np.einsum("...ij,...j->...i", K, nu)
    if form == "joseph":
        n = x.shape[-1]
        A = np.eye(n) - K @ H
        P_new = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    else:
        P_new = P - K @ S @ np.swapaxes(K, -1, -2)
    P_new = symmetrize(P_new)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        x_new = np.where(mask[..., None], x_new, x)
        P_new = np.where(mask[..., None, None], P_new, P)
    return UpdateResult(x_new, P_new, nu, S, K, d2)

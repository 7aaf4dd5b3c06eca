"""Stateless batched (extended) Kalman filter steps, used by the spec 000 filters and the gate.

The filter families of the tracker implement the batched protocol (:mod:`skytrack.filters.kalman`);
these functions are the same steps on bare arrays.  Every product and solve goes through the
one linear-algebra layer, :mod:`skytrack.core.linalg` (so ``counting()`` sees them too).

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

from skytrack.core import linalg
from skytrack.geo.polar import wrap_angle

UPDATE_FORMS = ("joseph", "standard")


symmetrize = linalg.symmetrize


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predict states ``x[N, n]`` and covariances ``P[N, n, n]`` with ``F, Q`` ``[N, n, n]`` (or shared)."""
    return linalg.matvec(F, x), linalg.sandwich(F, P, Q)


def innovation(z: np.ndarray, h: np.ndarray, angular: np.ndarray | None = None) -> np.ndarray:
    """``z - h`` with the angular components (boolean mask over the last axis) wrapped to (-pi, pi]."""
    nu = np.asarray(z, dtype=float) - h
    if angular is not None and np.any(angular):
        nu = nu.copy()
        nu[..., angular] = wrap_angle(nu[..., angular])
    return nu


def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    return linalg.sandwich(H, P, R)


def mahalanobis(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distances ``nu^T S^-1 nu`` for ``nu[K, m]``, ``S[K, m, m]``
    (ValueError when an ``S`` is not positive definite)."""
    return linalg.mahalanobis_chol(nu, linalg.cholesky(S))


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
    L = linalg.cholesky(S)
    PHt = linalg.matmul(P, np.swapaxes(H, -1, -2))
    # K^T = S^-1 (P H^T)^T, S symmetric
    K = np.swapaxes(linalg.cho_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)
    d2 = linalg.mahalanobis_chol(nu, L)
    x_new = x + linalg.matvec(K, nu)
    if form == "joseph":
        A = np.eye(x.shape[-1]) - linalg.matmul(K, H)
        P_new = linalg.sandwich(A, P, linalg.sandwich(K, R))
    else:
        P_new = linalg.symmetrize(P - linalg.matmul(linalg.matmul(K, S), np.swapaxes(K, -1, -2)))
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        x_new = np.where(mask[..., None], x_new, x)
        P_new = np.where(mask[..., None, None], P_new, P)
    return UpdateResult(x_new, P_new, nu, S, K, d2)

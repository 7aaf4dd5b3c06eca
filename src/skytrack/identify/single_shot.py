"""The single-shot test and the fusion of two estimates: spec 001 (20b)–(25), R7, R8 and R14.

* :func:`single_shot` — one estimate from each channel (the paper's interrogator З against
  the radar ПОТ): the statistic l = d^T (R_η + R_ξ)^{-1} d of (25), the fused estimate (24)
  in both of its forms with C^{-1}, the log-likelihoods 𝓛_0 = 0 and 𝓛_1 of (22)–(23) with
  the identity 𝓛_0 − 𝓛_1 = l/2, the p-value χ²_dim.sf(l) and a decision with R5's modes.
  ``half_statistic=True`` is the paper's literal threshold on l/2 (gap G8): a threshold
  designed for l must then be halved, which is easy to get wrong.
* :func:`fuse_information` — literal (24) on two estimates (R14 ``fusion="information"``):
  it assumes independent errors, so for tracks with process noise it is overconfident
  (the common process noise correlates them); the pair's joint filter is the exact fusion.
* :func:`track_states_test` — literal (25) on track states (R8): exact for Q = 0 with
  full-rank filters, approximate for Q > 0 (it ignores the cross-correlation of common
  process noise).

Every function is batched over a leading axis of pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from skytrack.identify.sequential import DIFFERENT, SAME


@dataclass(frozen=True)
class SingleShotResult:
    """R7's outputs, per pair."""

    statistic: np.ndarray
    """l of (25) (or l/2 with ``half_statistic``)"""
    fused_from_eta: np.ndarray
    """X̂_З + C^{-1} C_ξ (X̂_ПОТ − X̂_З), the first form of (24)"""
    fused_from_xi: np.ndarray
    """X̂_ПОТ + C^{-1} C_η (X̂_З − X̂_ПОТ), the second form of (24)"""
    fused_covariance: np.ndarray
    """C^{-1} = (C_η + C_ξ)^{-1}"""
    loglik_different: np.ndarray
    """𝓛_0 at the conditional estimates (22): 0, since they equal the data"""
    loglik_same: np.ndarray
    """𝓛_1 at the fused estimate (23): −l/2"""
    p_value: np.ndarray
    """χ²_dim.sf(l)"""
    threshold: np.ndarray
    decision: np.ndarray


def fuse_information(x_eta, P_eta, x_xi, P_xi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(24): the fused estimate in both forms and C^{-1}, for ``[K, n]`` states and ``[K, n, n]`` covariances."""
    x_eta, x_xi = np.atleast_2d(np.asarray(x_eta, float)), np.atleast_2d(np.asarray(x_xi, float))
    C_eta, C_xi = np.linalg.inv(np.asarray(P_eta, float)), np.linalg.inv(np.asarray(P_xi, float))
    C_inv = np.linalg.inv(C_eta + C_xi)
    C_inv = 0.5 * (C_inv + np.swapaxes(C_inv, -1, -2))
    from_eta = x_eta + np.einsum("...ij,...jk,...k->...i", C_inv, C_xi, x_xi - x_eta)
    from_xi = x_xi + np.einsum("...ij,...jk,...k->...i", C_inv, C_eta, x_eta - x_xi)
    return from_eta, from_xi, C_inv


def track_states_test(x_eta, P_eta, x_xi, P_xi) -> np.ndarray:
    """(25) on two track states at one time: (x̂_η − x̂_ξ)^T (P_η + P_ξ)^{-1} (x̂_η − x̂_ξ) (R8).

    Approximate for Q > 0: two tracks of one object share its process noise, which this ignores.
    """
    d = np.atleast_2d(np.asarray(x_eta, float) - np.asarray(x_xi, float))
    S = np.asarray(P_eta, float) + np.asarray(P_xi, float)
    return np.einsum("...i,...i->...", d, np.linalg.solve(S, d[..., None])[..., 0])


def single_shot(eta, R_eta, xi, R_xi, threshold=None, half_statistic: bool = False) -> SingleShotResult:
    """R7: the single-shot identification of estimates ``eta`` and ``xi`` (any dimension).

    ``threshold``: a :class:`~skytrack.identify.threshold.Threshold`, a number (literal h),
    or ``None`` for P(correct) = 0.99.  With ``half_statistic`` the statistic and the
    threshold are the paper's l/2 and h of (21) (gap G8).
    """
    from skytrack.identify.threshold import Threshold

    eta, xi = np.atleast_2d(np.asarray(eta, float)), np.atleast_2d(np.asarray(xi, float))
    R_eta = np.broadcast_to(np.asarray(R_eta, float), eta.shape + eta.shape[-1:])
    R_xi = np.broadcast_to(np.asarray(R_xi, float), xi.shape + xi.shape[-1:])
    for name, R in (("R_eta", R_eta), ("R_xi", R_xi)):
        if not np.all(np.isfinite(R)) or np.any(np.linalg.eigvalsh(R).min(axis=-1) <= 0):
            raise ValueError(f"{name} is not a finite positive-definite covariance")
    if not (np.all(np.isfinite(eta)) and np.all(np.isfinite(xi))):
        raise ValueError("eta and xi must be finite")
    dim = eta.shape[-1]
    l_stat = track_states_test(xi, R_xi, eta, R_eta)
    from_eta, from_xi, C_inv = fuse_information(eta, R_eta, xi, R_xi)
    C_eta, C_xi = np.linalg.inv(R_eta), np.linalg.inv(R_xi)
    r_eta, r_xi = eta - from_eta, xi - from_eta
    loglik_same = -0.5 * (np.einsum("ki,kij,kj->k", r_eta, C_eta, r_eta) + np.einsum("ki,kij,kj->k", r_xi, C_xi, r_xi))
    rule = Threshold(p_correct=0.99) if threshold is None else (
        threshold if isinstance(threshold, Threshold) else Threshold(h=float(threshold)))
    h = rule.value(np.full(len(l_stat), dim), covariance_sum=R_eta + R_xi)
    statistic = l_stat
    if half_statistic:
        statistic, h = 0.5 * l_stat, (h if rule.h is not None else 0.5 * h)
    decision = np.where(statistic > h, DIFFERENT, SAME).astype(object)
    return SingleShotResult(statistic, from_eta, from_xi, C_inv, np.zeros(len(l_stat)), loglik_same,
                            stats.chi2.sf(l_stat, dim), h, decision)

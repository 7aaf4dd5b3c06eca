"""Neyman-Pearson threshold design (spec 001 R10, the threshold modes of R5; gaps G7, G9).

Potential characteristics (:mod:`skytrack.identify.potential`, (26)-(28b)):

* :func:`threshold_for_p_incorrect` — the paper's NP criterion (26a): the normalised distance
  threshold r with P_НО(A, r) = alpha at a given offset A, or with the (27c) average
  P̄_НО(r) = alpha over an offset range; both are increasing in r, solved by brentq;
* :func:`threshold_for_p_correct` — r with P_ПО(r) = P (``r^2 = chi2_dim.ppf(P)``).

Both return a :class:`ThresholdDesign`: r, the threshold on the statistic l (27) ``r^2``, h = r sigma
in metres when sigma is given (G9: sigma is the per-axis sd of the estimate difference), P_ПО(r)
and the P_НО (or P̄_НО) reached.

Thresholds of the sequential and single-shot tests (R5, G7; (20a), (25)), vectorised over arrays
of degrees of freedom:

* :func:`np_threshold` — ``h = chi2.ppf(P, dof)`` (``p_correct=P``) or ``h = ncx2.ppf(alpha, dof, lambda)``
  (``p_incorrect=alpha`` with a design non-centrality ``lambda``); NaN where dof < 1 (no decision);
* :func:`noncentrality_from_separation` — R5's third mode: the worst-direction non-centrality of a
  minimum position separation Delta with equal velocities, ``Delta^2 lambda_min([(P_eta + P_xi)^-1]_pos)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from skytrack.identify.potential import Method, p_correct, p_incorrect, p_incorrect_mean

#: brentq tolerances on r (the spec's design values are given to 1e-8)
R_XTOL = 1e-13
R_RTOL = 4 * np.finfo(float).eps
#: bracket growth: the upper end doubles at most this many times
MAX_BRACKET_DOUBLINGS = 60
#: the spec 001 state order [x, y, vx, vy]: position components
DEFAULT_POSITION_INDEX = (0, 1)


@dataclass(frozen=True)
class ThresholdDesign:
    """A designed threshold: ``r`` (normalised distance), ``l_threshold = r^2`` (on l, (27)), ``h = r sigma``
    in metres (None without sigma), ``p_correct`` = P_ПО(r), ``p_incorrect`` = the P_НО (or the
    averaged P̄_НО) reached at r (None for a P_ПО design), and the design inputs."""

    dim: int
    r: float
    l_threshold: float
    h: float | None
    p_correct: float
    p_incorrect: float | None
    alpha: float | None = None
    A: float | None = None
    A_range: tuple[float, float] | None = None
    sigma: float | None = None


def _check_probability(name: str, value: float) -> float:
    value = float(value)
    if not 0.0 < value < 1.0:
        raise ValueError(f"{name} must lie in (0, 1), got {value!r}")
    return value


def _check_sigma(sigma) -> float | None:
    if sigma is None:
        return None
    sigma = float(sigma)
    if not sigma > 0.0 or not math.isfinite(sigma):
        raise ValueError(f"sigma must be > 0, got {sigma!r}")
    return sigma


def threshold_for_p_incorrect(alpha: float, dim: int, A: float | None = None,
                              A_range: tuple[float, float] | None = None, sigma: float | None = None,
                              method: Method = "closed") -> ThresholdDesign:
    """NP design (R10): r with P_НО(A, r) = alpha, or P̄_НО(r) = alpha (27c) over ``A_range = (A_min, A_max)``.

    Offsets are normalised (Delta / sigma); with ``sigma`` the design also reports h = r sigma in metres.
    """
    alpha = _check_probability("alpha", alpha)
    sigma = _check_sigma(sigma)
    if (A is None) == (A_range is None):
        raise ValueError("give exactly one of A and A_range")
    if A is not None:
        A = float(A)
        if not A >= 0.0 or not math.isfinite(A):
            raise ValueError(f"A must be >= 0, got {A!r}")
        largest = A

        def reached(r: float) -> float:
            return float(p_incorrect(A, r, dim, method))
    else:
        low, high = (float(a) for a in A_range)
        if not 0.0 <= low <= high or not math.isfinite(high):
            raise ValueError(f"A_range must satisfy 0 <= A_min <= A_max < inf, got {A_range!r}")
        A_range = (low, high)
        largest = high

        def reached(r: float) -> float:
            return float(p_incorrect_mean(r, low, high, dim, method))

    upper = largest + 8.0 + math.sqrt(dim)
    for _ in range(MAX_BRACKET_DOUBLINGS):
        if reached(upper) > alpha:
            break
        upper *= 2.0
    else:
        raise ValueError(f"P_НО does not reach alpha = {alpha} for r up to {upper:g}")
    # P_НО(0) = 0 < alpha: the root lies in (0, upper)
    r = optimize.brentq(lambda x: reached(x) - alpha, 0.0, upper, xtol=R_XTOL, rtol=R_RTOL, maxiter=500)
    return ThresholdDesign(dim=int(dim), r=r, l_threshold=r * r, h=None if sigma is None else r * sigma,
                           p_correct=float(p_correct(r, dim)), p_incorrect=reached(r), alpha=alpha, A=A,
                           A_range=A_range, sigma=sigma)


def threshold_for_p_correct(P: float, dim: int, sigma: float | None = None) -> ThresholdDesign:
    """r with P_ПО(r) = P: ``r = sqrt(chi2_dim.ppf(P))`` (R10)."""
    P = _check_probability("P", P)
    sigma = _check_sigma(sigma)
    l_threshold = float(stats.chi2.ppf(P, dim))
    r = math.sqrt(l_threshold)
    return ThresholdDesign(dim=int(dim), r=r, l_threshold=l_threshold, h=None if sigma is None else r * sigma,
                           p_correct=float(p_correct(r, dim)), p_incorrect=None, sigma=sigma)


def np_threshold(dof, p_correct: float | None = None, p_incorrect: float | None = None, noncentrality=None):
    """Threshold h on a chi-square statistic (Lambda of (20a), l of (25)) with ``dof`` degrees of freedom (R5).

    ``p_correct=P``: ``h = chi2.ppf(P, dof)``, so that P(statistic <= h | same) = P.
    ``p_incorrect=alpha`` with ``noncentrality=lambda``: ``h = ncx2.ppf(alpha, dof, lambda)``, so that
    P(statistic <= h | different, lambda) = alpha (the paper's NP criterion).
    ``dof`` and ``noncentrality`` broadcast; NaN where dof < 1 (no decision is possible there).
    """
    if (p_correct is None) == (p_incorrect is None):
        raise ValueError("give exactly one of p_correct and p_incorrect")
    dof = np.asarray(dof, dtype=float)
    valid = dof >= 1
    safe_dof = np.where(valid, dof, 1.0)
    if p_correct is not None:
        if noncentrality is not None:
            raise ValueError("noncentrality goes with p_incorrect, not with p_correct")
        h = stats.chi2.ppf(_check_probability("p_correct", p_correct), safe_dof)
    else:
        alpha = _check_probability("p_incorrect", p_incorrect)
        if noncentrality is None:
            raise ValueError("p_incorrect needs the design noncentrality (lambda = delta^T (P_eta + P_xi)^-1 delta)")
        lam = np.asarray(noncentrality, dtype=float)
        if np.any(lam < 0) or np.any(np.isnan(lam)):
            raise ValueError(f"noncentrality must be >= 0, got {noncentrality!r}")
        safe_dof, lam = np.broadcast_arrays(safe_dof, lam)
        valid = np.broadcast_to(valid, safe_dof.shape)
        # nc = 0 is kept away from ncx2: older scipy versions return NaN for it
        h = np.where(lam > 0, stats.ncx2.ppf(alpha, safe_dof, np.where(lam > 0, lam, 1.0)),
                     stats.chi2.ppf(alpha, safe_dof))
    h = np.where(valid, h, np.nan)
    return float(h) if np.ndim(h) == 0 else h


def noncentrality_from_separation(delta_pos_m, P_sum, position_index=DEFAULT_POSITION_INDEX):
    """Design non-centrality of a minimum position separation (R5, third mode).

    ``P_sum`` = P_eta + P_xi, the full state covariances (..., n, n) at one common time; its inverse's
    position block (rows/columns ``position_index``; default x, y of spec 001's [x, y, vx, vy]) is the
    information about a position difference with equal velocities.  The worst direction gives
    ``lambda = Delta^2 lambda_min([(P_eta + P_xi)^-1]_pos)``.  ``delta_pos_m`` broadcasts against the batch.
    """
    P_sum = np.asarray(P_sum, dtype=float)
    if P_sum.ndim < 2 or P_sum.shape[-1] != P_sum.shape[-2]:
        raise ValueError(f"P_sum must be (..., n, n), got shape {P_sum.shape}")
    index = np.asarray(position_index, dtype=int)
    if index.ndim != 1 or index.size == 0 or index.min() < 0 or index.max() >= P_sum.shape[-1]:
        raise ValueError(f"position_index {position_index!r} does not fit a state of dimension {P_sum.shape[-1]}")
    information = np.linalg.inv(P_sum)
    block = information[..., index[:, None], index[None, :]]
    smallest = np.linalg.eigvalsh(0.5 * (block + np.swapaxes(block, -1, -2)))[..., 0]
    delta = np.asarray(delta_pos_m, dtype=float)
    lam = np.square(delta) * smallest
    return float(lam) if np.ndim(lam) == 0 else lam

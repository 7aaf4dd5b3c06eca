"""Gates (expectation regions) from the one-scan extrapolation of spec 000 (R7, G8).

The paper motivates the expectation region by Theorem 2 but never sizes it (gap G8);
skytrack uses the chi-square gate of the extrapolated innovation:

* ``gate_threshold(m, p_gate)`` — g = chi2_m^-1(P_G), the P_G-quantile of a chi-square
  law with m degrees of freedom (m = number of measured components of the report; TV12);
* ``gate_test(nu, S, g)`` — d^2 = nu^T S^-1 nu by a Cholesky solve, inside iff d^2 <= g;
* ``gate_volume(S, g)`` — V = pi^(m/2) / Gamma(m/2 + 1) * g^(m/2) * sqrt(det S), the
  volume of the ellipsoid {nu : nu^T S^-1 nu <= g} (TV10), batched over ``S[..., m, m]``;
* ``gate_interval_1d`` / ``gate_half_width`` — the 1-D interval em_1 +- sqrt(g (e-gamma_11
  + sigma^2)) of the paper's position-only filter (R7, TV4 and the gate-growth numbers).

S comes from the extrapolation to the report's own timestamp, S = J e-gamma J^T + R
(``SingerFilter1D.extrapolate`` / ``SingerTracker3D.innovation``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln

from skytrack.core.chi2 import chi2_quantile
from skytrack.filters.ekf import mahalanobis

DEFAULT_GATE_PROBABILITY = 0.99


def _check_probability(p_gate) -> float:
    try:
        p = float(p_gate)
    except (TypeError, ValueError):
        raise ValueError(f"gate probability p_gate must be a number in (0, 1), got {p_gate!r}") from None
    if not (0.0 < p < 1.0):
        raise ValueError(f"gate probability p_gate must lie in (0, 1), got {p_gate!r}")
    return p


def _check_dimension(m) -> np.ndarray:
    dims = np.asarray(m)
    if dims.dtype.kind not in "iu" and not (dims.dtype.kind == "f" and np.all(dims == np.round(dims))):
        raise ValueError(f"gate dimension m must be a positive integer, got {m!r}")
    if np.any(dims < 1):
        raise ValueError(f"gate dimension m must be >= 1, got {m!r}")
    return dims.astype(int)


def gate_threshold(m, p_gate: float = DEFAULT_GATE_PROBABILITY):
    """chi-square gate g = chi2_m^-1(p_gate) for m measured components (R7, TV12).

    ``m`` may be an integer or an integer array (one report per entry); returns a float or
    an array of the same shape.
    """
    dims = _check_dimension(m)
    return chi2_quantile(_check_probability(p_gate), dims)


def _check_threshold(g) -> np.ndarray:
    g = np.asarray(g, dtype=float)
    if not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise ValueError(f"gate threshold g must be finite and > 0, got {g!r}")
    return g


def unit_ball_volume(m) -> np.ndarray:
    """pi^(m/2) / Gamma(m/2 + 1): the volume of the unit ball in m dimensions."""
    dims = _check_dimension(m)
    return np.exp(0.5 * dims * math.log(math.pi) - gammaln(0.5 * dims + 1.0))


def gate_volume(S, g):
    """Volume of the gate {nu : nu^T S^-1 nu <= g} (R7): c_m g^(m/2) sqrt(det S).

    ``S`` is ``[..., m, m]`` (symmetric positive definite), ``g`` a scalar or an array that
    broadcasts against the leading dimensions.  The determinant is taken from the Cholesky
    factor so that a non-positive-definite S is reported, not silently rooted.
    """
    S = np.asarray(S, dtype=float)
    if S.ndim < 2 or S.shape[-1] != S.shape[-2]:
        raise ValueError(f"S must be [..., m, m], got shape {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ValueError("S contains non-finite values")
    m = S.shape[-1]
    g = _check_threshold(g)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise ValueError("innovation covariance S is not positive definite") from None
    sqrt_det = np.prod(np.diagonal(L, axis1=-2, axis2=-1), axis=-1)
    volume = unit_ball_volume(m) * g ** (0.5 * m) * sqrt_det
    return float(volume) if np.ndim(volume) == 0 else volume


def gate_test(nu, S, g) -> tuple[np.ndarray, np.ndarray]:
    """Squared distances d^2 = nu^T S^-1 nu (Cholesky solve) and the gate decision d^2 <= g.

    ``nu[..., m]``, ``S[..., m, m]``; angle components of nu must already be wrapped
    (``skytrack.filters.ekf.innovation`` does that).
    """
    nu = np.asarray(nu, dtype=float)
    S = np.asarray(S, dtype=float)
    if not (np.all(np.isfinite(nu)) and np.all(np.isfinite(S))):
        raise ValueError("non-finite innovation or innovation covariance in gate test")
    g = _check_threshold(g)
    d2 = mahalanobis(nu, S)
    return d2, d2 <= g


def gate_half_width(predicted_variance, sigma, g=None, p_gate: float = DEFAULT_GATE_PROBABILITY):
    """Half-width sqrt(g (e-gamma_11 + sigma^2)) of the 1-D position gate (R7).

    ``g`` defaults to the chi-square 1-dof threshold at ``p_gate``.
    """
    var = np.asarray(predicted_variance, dtype=float)
    sig = np.asarray(sigma, dtype=float)
    if not (np.all(np.isfinite(var)) and np.all(var >= 0)):
        raise ValueError(f"predicted position variance must be finite and >= 0, got {predicted_variance!r}")
    if not (np.all(np.isfinite(sig)) and np.all(sig > 0)):
        raise ValueError(f"measurement sigma must be finite and > 0, got {sigma!r}")
    g = gate_threshold(1, p_gate) if g is None else _check_threshold(g)
    width = np.sqrt(g * (var + sig * sig))
    return float(width) if np.ndim(width) == 0 else width


def gate_interval_1d(predicted_position, predicted_variance, sigma, g=None, p_gate: float = DEFAULT_GATE_PROBABILITY):
    """The 1-D expectation region em_1 +- sqrt(g (e-gamma_11 + sigma^2)) as (low, high) (R7, TV4)."""
    centre = np.asarray(predicted_position, dtype=float)
    if not np.all(np.isfinite(centre)):
        raise ValueError(f"predicted position must be finite, got {predicted_position!r}")
    half = gate_half_width(predicted_variance, sigma, g, p_gate)
    low, high = centre - half, centre + half
    if np.ndim(low) == 0:
        return float(low), float(high)
    return low, high

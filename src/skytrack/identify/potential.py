"""Potential characteristics of identification (spec 001 R9; equations (26)-(28b), gaps G9, G10).

Two estimates of the same 1, 2, 3, ... coordinates are compared by their difference.  Under
"same object" (own object С in both) the normalised squared distance is chi-square with ``dim``
degrees of freedom; under "different objects" (the radar estimate belongs to a foreign object Ч
at separation Delta) it is non-central chi-square with non-centrality ``A^2``, ``A = Delta / sigma``.
With a threshold ``r = h / sigma`` on the normalised distance (``r^2`` on the statistic l):

* :func:`p_correct` — P_ПО(r) = chi2_dim.cdf(r^2): Rayleigh (27b) in 2-D, Maxwell (28b) in 3-D;
* :func:`p_incorrect` — P_НО(A, r) = ncx2_dim.cdf(r^2; A^2): Rice (27a, evaluated by quadrature)
  in 2-D, the offset sphere (28) in 3-D, ``method="ncx2"`` through scipy for any dim;
* :func:`p_incorrect_mean` — (27c), P_НО averaged over a separation uniform on [A_min, A_max],
  by adaptive quadrature (vectorised over r).

Every function broadcasts arrays of ``r`` and ``A`` (e.g. ``A[None, :]`` against ``r[:, None]``).
For ``dim`` other than 1, 2, 3 there is no closed form; both methods then use scipy.

Metric inputs (R9): :func:`difference_covariance` builds the covariance S of the estimate
difference from one sigma, per-axis sigmas, per-axis sigmas of each system (combined as
``sigma_i^2 = sigma_i_eta^2 + sigma_i_xi^2``, :func:`combined_sigma`) or a full matrix, and
:func:`characteristics` turns a metric threshold ``h`` and separations ``delta`` into ``(r, A)``
and the probabilities in one of two modes:

* ``mode="exact"`` (default) — the normalised statistic (27), ``l = delta^T S^-1 delta``; it needs no
  circular scattering (G10): l ~ chi2_dim under "same", ncx2_dim(lambda = delta^T S^-1 delta) under
  "different", so A = sqrt(lambda).  A distance threshold ``h`` in metres is only meaningful when
  S is isotropic; otherwise give ``r`` (the threshold on l is r^2).
* ``mode="circular"`` (literal paper) — the Euclidean distance thresholded at h with the circular
  laws and ``sigma := max sigma_i`` (the largest principal sd of S).  Known weakness (G10): for
  elliptical scattering this bounds P_ПО from below only; P_НО is bounded neither way (study E4).
  A :class:`CircularScatteringWarning` is emitted when the sigma_i differ.

sigma is the per-axis standard deviation of the *difference* of the two estimates, not a "radial
RMS" (G9).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import integrate, special, stats

Method = Literal["closed", "ncx2"]
Mode = Literal["exact", "circular"]

#: dims with a closed form of P_НО (1-D: two normal tails; 2-D: (27a); 3-D: (28))
CLOSED_FORM_DIMS = (1, 2, 3)
#: below this offset (28) is replaced by its A -> 0 limit (28b) (R9); the error is O(A^2)
SMALL_OFFSET = 1e-6
#: half-width (in units of sigma) of the window of the Rice integrand kept by the quadrature of
#: (27a); beyond it the integrand is below exp(-72) of its peak
RICE_WINDOW = 12.0
RICE_PANELS = 8
RICE_NODES = 16
#: elements per block of the vectorised quadrature (about 8 MB per temporary array)
RICE_BLOCK = 8192
_LEGENDRE_X, _LEGENDRE_W = np.polynomial.legendre.leggauss(RICE_NODES)
#: (27c) quadrature tolerances
MEAN_EPSABS = 1e-13
MEAN_EPSREL = 1e-11


class CircularScatteringWarning(UserWarning):
    """``mode="circular"`` applied to elliptical scattering: sigma := max sigma_i (spec 001 G10)."""


def _check_dim(dim) -> int:
    if int(dim) != dim or dim < 1:
        raise ValueError(f"dim must be an integer >= 1, got {dim!r}")
    return int(dim)


def _nonnegative(name: str, value) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if np.any(array < 0):
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return array


def _as_result(array: np.ndarray):
    return float(array) if np.ndim(array) == 0 else array


# --------------------------------------------------------------------------- P_ПО


def p_correct(r, dim: int):
    """P_ПО(r) = chi2_dim.cdf(r^2), probability that the own object's estimates fall within r.

    2-D: Rayleigh (27b) ``1 - exp(-r^2 / 2)``; 3-D: Maxwell (28b) ``2 Phi(r) - 1 - 2 r p_0(r)``;
    1-D: ``2 Phi(r) - 1``; other dims: scipy's chi2.
    """
    dim = _check_dim(dim)
    r = _nonnegative("r", r)
    if dim == 1:
        value = special.erf(r / math.sqrt(2.0))
    elif dim == 2:
        value = -np.expm1(-0.5 * r * r)
    elif dim == 3:
        value = special.erf(r / math.sqrt(2.0)) - 2.0 * r * _normal_pdf(r)
    else:
        value = stats.chi2.cdf(r * r, dim)
    return _as_result(np.asarray(value, dtype=float))


def _normal_pdf(x):
    return np.exp(-0.5 * np.square(x)) / math.sqrt(2.0 * math.pi)


# --------------------------------------------------------------------------- P_НО


def p_incorrect(A, r, dim: int, method: Method = "closed"):
    """P_НО(A, r) = ncx2_dim.cdf(r^2; A^2): a foreign object at normalised offset A within r.

    ``method="closed"``: (27a) by composite Gauss-Legendre quadrature of the Rice integrand in
    2-D, (28) (with expm1; its (28b) limit for A < 1e-6) in 3-D, ``Phi(r - A) - Phi(-r - A)`` in 1-D.
    ``method="ncx2"``: scipy.stats.ncx2 (chi2 where A = 0).  Dims without a closed form use scipy
    under both methods.  A = 0 gives P_ПО.  A and r broadcast.
    """
    dim = _check_dim(dim)
    A = _nonnegative("A", A)
    r = _nonnegative("r", r)
    A, r = np.broadcast_arrays(A, r)
    if method not in ("closed", "ncx2"):
        raise ValueError(f"method must be 'closed' or 'ncx2', got {method!r}")
    if method == "ncx2" or dim not in CLOSED_FORM_DIMS:
        value = _p_incorrect_ncx2(A, r, dim)
    elif dim == 1:
        value = special.ndtr(r - A) - special.ndtr(-r - A)
    elif dim == 2:
        value = _rice_integral(A, r)
    else:
        value = _offset_sphere(A, r)
    return _as_result(np.asarray(value, dtype=float))


def _p_incorrect_ncx2(A: np.ndarray, r: np.ndarray, dim: int) -> np.ndarray:
    central = stats.chi2.cdf(r * r, dim)
    offset = A > 0
    if not np.any(offset):
        return np.asarray(central, dtype=float)
    # nc = 0 is kept away from ncx2: older scipy versions return NaN for it
    noncentral = stats.ncx2.cdf(r * r, dim, np.where(offset, A * A, 1.0))
    return np.where(offset, noncentral, central)


def _rice_integral(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(27a): exp(-A^2/2) int_0^r exp(-t^2/2) I_0(A t) t dt.

    The integrand is written ``t exp(-(t - A)^2 / 2) i0e(A t)`` (no overflow of I_0) and integrated
    over the part of [0, r] within RICE_WINDOW of its peak (near min(r, A)), on RICE_PANELS panels
    of RICE_NODES-point Gauss-Legendre: the same nodes for every element, so a block of elements is
    one numpy expression (blocks of RICE_BLOCK bound the memory).
    """
    shape = A.shape
    A = A.reshape(-1)
    r = r.reshape(-1)
    total = np.empty(A.size)
    for start in range(0, A.size, RICE_BLOCK):
        block = slice(start, start + RICE_BLOCK)
        total[block] = _rice_block(A[block], r[block])
    return np.minimum(total, 1.0).reshape(shape)


def _rice_block(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    low = np.maximum(0.0, np.minimum(A, r) - RICE_WINDOW)
    high = np.minimum(r, A + RICE_WINDOW)
    width = np.maximum(high - low, 0.0) / RICE_PANELS
    panel_start = low[:, None] + width[:, None] * np.arange(RICE_PANELS)[None, :]
    t = panel_start[:, :, None] + 0.5 * width[:, None, None] * (_LEGENDRE_X + 1.0)[None, None, :]
    a = A[:, None, None]
    integrand = t * np.exp(-0.5 * np.square(t - a)) * special.i0e(a * t)
    return 0.5 * width * np.einsum("ijk,k->i", integrand, _LEGENDRE_W)


def _offset_sphere(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(28): Phi(r + A) + Phi(r - A) - 1 - (p_0(r - A) / A) (1 - exp(-2 A r)); (28b) for A < SMALL_OFFSET."""
    small = A < SMALL_OFFSET
    safe_A = np.where(small, 1.0, A)
    # Phi(r+A) + Phi(r-A) - 1 = Phi(r-A) - Phi(-r-A): two lower tails, no 1 - 1 cancellation when A > r
    shell = special.ndtr(r - safe_A) - special.ndtr(-r - safe_A)
    value = shell + _normal_pdf(r - safe_A) / safe_A * np.expm1(-2.0 * safe_A * r)
    maxwell = special.erf(r / math.sqrt(2.0)) - 2.0 * r * _normal_pdf(r)
    return np.clip(np.where(small, maxwell, value), 0.0, 1.0)


# --------------------------------------------------------------------------- (27c)


def p_incorrect_mean(r, A_min: float, A_max: float, dim: int, method: Method = "closed"):
    """(27c): P_НО averaged over an offset uniform on [A_min, A_max] (Delta / sigma), for each r.

    Adaptive Gauss-Kronrod quadrature (scipy.integrate.quad_vec), the whole array of r at once.
    A_min = A_max gives P_НО(A_min, r).
    """
    dim = _check_dim(dim)
    A_min, A_max = float(A_min), float(A_max)
    if not 0.0 <= A_min <= A_max or not math.isfinite(A_max):
        raise ValueError(f"need 0 <= A_min <= A_max < inf, got A_min={A_min!r}, A_max={A_max!r}")
    r = _nonnegative("r", r)
    if A_max == A_min:
        return p_incorrect(A_min, r, dim, method)
    flat = r.reshape(-1)
    integral, _ = integrate.quad_vec(lambda a: np.asarray(p_incorrect(a, flat, dim, method)), A_min, A_max,
                                     epsabs=MEAN_EPSABS, epsrel=MEAN_EPSREL, norm="max")
    return _as_result(np.clip(np.asarray(integral) / (A_max - A_min), 0.0, 1.0).reshape(r.shape))


# --------------------------------------------------------------------------- metric inputs


def combined_sigma(sigma_eta, sigma_xi) -> np.ndarray:
    """Per-axis sd of the estimate difference: ``sqrt(sigma_i_eta^2 + sigma_i_xi^2)`` ((27))."""
    sigma_eta = _nonnegative("sigma_eta", sigma_eta)
    sigma_xi = _nonnegative("sigma_xi", sigma_xi)
    return np.sqrt(np.square(sigma_eta) + np.square(sigma_xi))


def difference_covariance(dim: int | None = None, *, sigma=None, sigma_axes=None, sigma_eta=None, sigma_xi=None,
                          covariance=None) -> np.ndarray:
    """Covariance S (dim x dim) of the difference of the two estimates, from exactly one of:

    ``sigma`` (one sd for every axis, needs ``dim``), ``sigma_axes`` (per-axis sd), ``sigma_eta`` and
    ``sigma_xi`` (per-axis or scalar sd of each system, combined by :func:`combined_sigma`) or
    ``covariance`` (a full symmetric positive definite matrix).
    """
    given = [name for name, value in (("sigma", sigma), ("sigma_axes", sigma_axes), ("covariance", covariance),
                                      ("sigma_eta/sigma_xi", sigma_eta if sigma_eta is not None else sigma_xi))
             if value is not None]
    if len(given) != 1:
        raise ValueError(f"give exactly one of sigma, sigma_axes, sigma_eta and sigma_xi, covariance; got {given or 'none'}")
    if covariance is not None:
        S = np.array(covariance, dtype=float)
        if S.ndim != 2 or S.shape[0] != S.shape[1] or not np.allclose(S, S.T, rtol=1e-12, atol=0.0):
            raise ValueError(f"covariance must be a symmetric square matrix, got shape {S.shape}")
        if np.linalg.eigvalsh(S)[0] <= 0.0:
            raise ValueError("covariance must be positive definite")
    else:
        if sigma is not None:
            axes = _nonnegative("sigma", sigma)
        elif sigma_axes is not None:
            axes = _nonnegative("sigma_axes", sigma_axes)
        else:
            if sigma_eta is None or sigma_xi is None:
                raise ValueError("sigma_eta and sigma_xi go together")
            axes = combined_sigma(sigma_eta, sigma_xi)
        axes = np.atleast_1d(axes)
        if axes.ndim != 1:
            raise ValueError("per-axis sigmas must be one value per axis")
        if axes.size == 1 and dim is not None:
            axes = np.full(_check_dim(dim), axes[0])
        if axes.size == 1 and dim is None:
            raise ValueError("a single sigma needs dim")
        if np.any(axes <= 0):
            raise ValueError("sigmas must be > 0")
        S = np.diag(np.square(axes))
    if dim is not None and S.shape[0] != _check_dim(dim):
        raise ValueError(f"dim = {dim} but the scattering has {S.shape[0]} axes")
    return S


def principal_sigmas(S: np.ndarray) -> np.ndarray:
    """Principal standard deviations of S, ascending (sqrt of its eigenvalues)."""
    return np.sqrt(np.linalg.eigvalsh(np.asarray(S, dtype=float)))


def is_circular(S: np.ndarray, rtol: float = 1e-12) -> bool:
    """True when S = sigma^2 I (circular / spherical scattering)."""
    S = np.asarray(S, dtype=float)
    return bool(np.allclose(S, S[0, 0] * np.eye(S.shape[0]), rtol=rtol, atol=0.0))


@dataclass(frozen=True)
class Characteristics:
    """Normalised threshold and offsets, and the probabilities, of :func:`characteristics`.

    ``r`` has the shape of the given thresholds, ``A`` of the given separations; ``p_incorrect``
    is ``r.shape + A.shape`` (None without separations).  ``sigma`` is the sd used to normalise
    metric inputs (None in exact mode with anisotropic S).
    """

    dim: int
    mode: str
    r: np.ndarray
    A: np.ndarray | None
    p_correct: np.ndarray
    p_incorrect: np.ndarray | None
    sigma: float | None


def normalised_offset(delta, S: np.ndarray, mode: Mode = "exact", vectors: bool = False) -> np.ndarray:
    """A for separations in metres: distances (any shape), or with ``vectors=True`` vectors (..., dim).

    exact: ``A = sqrt(delta^T S^-1 delta)``; a bare distance needs isotropic S.  circular: ``A = |delta| / sigma_max``.
    """
    S = np.asarray(S, dtype=float)
    delta = np.asarray(delta, dtype=float)
    if vectors and (delta.ndim == 0 or delta.shape[-1] != S.shape[0]):
        raise ValueError(f"separation vectors need {S.shape[0]} components, got shape {delta.shape}")
    if mode == "circular":
        distance = np.linalg.norm(delta, axis=-1) if vectors else np.abs(delta)
        return distance / principal_sigmas(S)[-1]
    _check_mode(mode)
    if vectors:
        return np.sqrt(np.einsum("...i,ij,...j->...", delta, np.linalg.inv(S), delta))
    if not is_circular(S):
        raise ValueError("with unequal sigma_i the exact offset depends on the direction: give separation vectors "
                         "(one component per axis) or use mode='circular'")
    return np.abs(delta) / math.sqrt(S[0, 0])


def normalised_threshold(h, S: np.ndarray, mode: Mode = "exact") -> np.ndarray:
    """r for a distance threshold h in metres: ``h / sigma`` (exact: isotropic S only; circular: sigma_max)."""
    S = np.asarray(S, dtype=float)
    h = _nonnegative("h", h)
    if mode == "circular":
        return h / principal_sigmas(S)[-1]
    _check_mode(mode)
    if not is_circular(S):
        raise ValueError("the exact statistic (27) with unequal sigma_i has no distance threshold in metres: "
                         "give r (the threshold on l is r^2) or use mode='circular'")
    return h / math.sqrt(S[0, 0])


def _check_mode(mode: str) -> None:
    if mode not in ("exact", "circular"):
        raise ValueError(f"mode must be 'exact' or 'circular', got {mode!r}")


def characteristics(dim: int | None = None, *, r=None, h=None, A=None, delta=None, delta_vectors=None, A_range=None,
                    delta_range=None, sigma=None, sigma_axes=None, sigma_eta=None, sigma_xi=None, covariance=None,
                    mode: Mode = "exact", method: Method = "closed") -> tuple[Characteristics, np.ndarray | None]:
    """P_ПО and P_НО from normalised or metric inputs (R9).

    Threshold: ``r`` (normalised) or ``h`` (metres, with a scattering).  Offsets: ``A`` (normalised),
    ``delta`` (distances in metres) or ``delta_vectors`` (separation vectors (..., dim) in metres).  ``A_range`` / ``delta_range``
    add the (27c) average.  Scattering: ``sigma``, ``sigma_axes``, ``sigma_eta`` + ``sigma_xi`` or
    ``covariance`` (see :func:`difference_covariance`).  Returns the :class:`Characteristics` and
    P̄_НО over the range (shape of r) or None.  In circular mode with unequal sigma_i a
    :class:`CircularScatteringWarning` is emitted.
    """
    _check_mode(mode)
    scattering_given = any(v is not None for v in (sigma, sigma_axes, sigma_eta, sigma_xi, covariance))
    S = None
    if scattering_given:
        S = difference_covariance(dim, sigma=sigma, sigma_axes=sigma_axes, sigma_eta=sigma_eta, sigma_xi=sigma_xi,
                                  covariance=covariance)
        dim = S.shape[0]
    if dim is None:
        raise ValueError("dim is needed when no per-axis scattering is given")
    dim = _check_dim(dim)
    if S is not None and mode == "circular" and not is_circular(S):
        sig = principal_sigmas(S)
        warnings.warn(f"circular mode with unequal sigma_i ({', '.join(f'{s:g}' for s in sig)}): sigma := {sig[-1]:g}; "
                      "this bounds P_ПО from below only, P_НО is bounded neither way (spec 001 G10)",
                      CircularScatteringWarning, stacklevel=2)
    metric = h is not None or delta is not None or delta_vectors is not None or delta_range is not None
    if metric and S is None:
        raise ValueError("metric inputs (h, delta, delta_vectors, delta_range) need a scattering: sigma, sigma_axes, "
                         "sigma_eta and sigma_xi, or covariance")
    if (r is None) == (h is None):
        raise ValueError("give exactly one of r and h")
    if sum(v is not None for v in (A, delta, delta_vectors)) > 1:
        raise ValueError("give at most one of A, delta and delta_vectors")
    if A_range is not None and delta_range is not None:
        raise ValueError("give at most one of A_range and delta_range")
    r_values = _nonnegative("r", r) if r is not None else normalised_threshold(h, S, mode)
    offsets = None
    if A is not None:
        offsets = _nonnegative("A", A)
    elif delta is not None:
        offsets = normalised_offset(delta, S, mode)
    elif delta_vectors is not None:
        offsets = normalised_offset(delta_vectors, S, mode, vectors=True)
    if delta_range is not None:
        low, high = normalised_offset(np.asarray(delta_range, dtype=float), S, mode)
        A_range = (float(low), float(high))
    sigma_used = None
    if S is not None and (mode == "circular" or is_circular(S)):
        sigma_used = float(principal_sigmas(S)[-1])
    p_ok = np.asarray(p_correct(r_values, dim), dtype=float)
    p_bad = None
    if offsets is not None:
        p_bad = np.asarray(p_incorrect(offsets[(None,) * r_values.ndim], r_values[(...,) + (None,) * offsets.ndim],
                                       dim, method), dtype=float)
    mean = None
    if A_range is not None:
        mean = np.asarray(p_incorrect_mean(r_values, A_range[0], A_range[1], dim, method), dtype=float)
    result = Characteristics(dim=dim, mode=mode, r=r_values, A=offsets, p_correct=p_ok, p_incorrect=p_bad,
                             sigma=sigma_used)
    return result, mean

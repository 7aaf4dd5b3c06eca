"""Discretisation of linear continuous-time motion models (spec 004 §3.3 B, R1).

* :func:`van_loan` — Van Loan (1978) for ``dx/dt = A x + L w`` with white ``w`` of power
  spectral density ``qc``: ``M = [[-A, L qc L^T], [0, A^T]] T``, ``E = expm(M)``,
  ``F = E22^T``, ``Q = F E12`` (``Q = int_0^T e^{As} L qc L^T e^{A^T s} ds``).
* :func:`input_response` — response to a known input held constant over the step:
  ``expm([[A, b], [0, 0]] T) = [[F, B], [0, 1]]``, ``B = int_0^T e^{As} b ds``.
* :func:`singer_input` — the closed form of that response for Singer's acceleration channel
  (``da/dt = -a/tau + j``, input on the acceleration derivative), used by the Berg-type model
  (§3.3 M): ``B = [T^2/(2k) - T/k^2 + (1-E1)/k^3, T/k - (1-E1)/k^2, (1-E1)/k]``, ``k = 1/tau``,
  ``E1 = e^{-kT}``.  The closed form cancels catastrophically as ``kT -> 0`` (the first entry
  loses ~``eps/(kT)^3``), so for ``kT <= 1`` the entries are evaluated from their power series
  ``B_i = T^{3-i} sum_k (-kT)^k / (k + 3 - i)!`` (i = 0, 1, 2), which has no cancellation.
* Generators of the models of §3.3 B (:func:`polynomial_generator`, :func:`singer_generator`,
  :func:`coordinated_turn_generator`), so that any closed form can be checked against
  :func:`van_loan` (TV12).

Every function accepts a scalar step or an array of steps ``T[K]``; arrays give stacked
results ``[K, n, n]`` / ``[K, n]`` (scipy's ``expm`` works on stacks).  These routines are for
building and checking models, not for the per-scan hot path: the model classes use closed
forms.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

#: kT at and below which :func:`singer_input` uses its power series
SINGER_INPUT_SERIES_LIMIT = 1.0
#: terms of that series; 1/26! < 1e-26, far below double precision for kT <= 1
_SERIES_TERMS = 26


def _steps(T) -> np.ndarray:
    t = np.asarray(T, dtype=float)
    if not np.all(np.isfinite(t)):
        raise ValueError("van loan: time step T must be finite")
    return t


def van_loan(A, L, qc, T) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation ``(F, Q)`` of ``dx/dt = A x + L w``, ``E[w w^T] = qc delta``.

    ``A`` is ``[n, n]``, ``L`` is ``[n, p]`` (a vector is taken as one column), ``qc`` is
    ``[p, p]`` or a scalar PSD.  ``T`` is a scalar (results ``[n, n]``) or an array of steps
    (results stacked ``T.shape + (n, n)``).  Negative ``T`` is allowed (``F = e^{AT}``).
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"van loan: A must be square, got shape {A.shape}")
    L = np.asarray(L, dtype=float).reshape(n, -1)
    qc = np.atleast_2d(np.asarray(qc, dtype=float))
    if qc.shape != (L.shape[1], L.shape[1]):
        raise ValueError(f"van loan: qc must be {L.shape[1]}x{L.shape[1]}, got {qc.shape}")
    t = _steps(T)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = L @ qc @ L.T
    M[n:, n:] = A.T
    E = expm(M * t[..., None, None])
    F = np.swapaxes(E[..., n:, n:], -1, -2)
    Q = F @ E[..., :n, n:]
    # Q is symmetric in exact arithmetic; remove the rounding asymmetry of the product
    Q = 0.5 * (Q + np.swapaxes(Q, -1, -2))
    return F, Q


def input_response(A, b, T) -> tuple[np.ndarray, np.ndarray]:
    """``(F, B)`` with ``F = e^{AT}``, ``B = int_0^T e^{As} b ds`` from ``expm([[A, b], [0, 0]] T)``.

    ``b`` is ``[n]`` (one input; ``B`` is then ``[n]``) or ``[n, p]`` (``B`` is ``[n, p]``).
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"input response: A must be square, got shape {A.shape}")
    b_arr = np.asarray(b, dtype=float)
    vector = b_arr.ndim == 1
    b2 = b_arr.reshape(n, -1)
    p = b2.shape[1]
    t = _steps(T)
    M = np.zeros((n + p, n + p))
    M[:n, :n] = A
    M[:n, n:] = b2
    E = expm(M * t[..., None, None])
    F = E[..., :n, :n]
    B = E[..., :n, n:]
    return F, (B[..., 0] if vector else B)


def polynomial_generator(order: int) -> tuple[np.ndarray, np.ndarray]:
    """``(A, L)`` of the chain of ``order`` integrators driven on its last state (§3.3 B)."""
    if not (isinstance(order, (int, np.integer)) and order >= 1):
        raise ValueError(f"polynomial order must be an integer >= 1, got {order!r}")
    A = np.diag(np.ones(order - 1), 1)
    L = np.zeros((order, 1))
    L[-1, 0] = 1.0
    return A, L


def singer_generator(tau: float, sigma_m: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(A, L, qc)`` of Singer's model ``da/dt = -a/tau + w``, ``qc = 2 sigma_m^2 / tau`` (§3.3 B)."""
    if not (math.isfinite(tau) and tau > 0):
        raise ValueError(f"singer: tau must be finite and > 0, got {tau}")
    if not (math.isfinite(sigma_m) and sigma_m >= 0):
        raise ValueError(f"singer: sigma_m must be finite and >= 0, got {sigma_m}")
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / tau]])
    L = np.array([[0.0], [0.0], [1.0]])
    return A, L, 2.0 * sigma_m**2 / tau


def coordinated_turn_generator(omega: float) -> np.ndarray:
    """Generator ``A`` of CT(omega) on ``[x, vx, y, vy]``: ``dvx/dt = -omega vy``, ``dvy/dt = omega vx``."""
    if not math.isfinite(omega):
        raise ValueError(f"coordinated turn: omega must be finite, got {omega}")
    A = np.zeros((4, 4))
    A[0, 1] = A[2, 3] = 1.0
    A[1, 3] = -omega
    A[3, 1] = omega
    return A


def singer_input(tau: float, T) -> np.ndarray:
    """Singer channel response ``B[..., 3]`` to a unit input held on ``da/dt`` over ``T`` (§3.3 B).

    Power series for ``T/tau <= 1`` (no cancellation), the closed form of §3.3 B above.
    """
    if not (math.isfinite(tau) and tau > 0):
        raise ValueError(f"singer input: tau must be finite and > 0, got {tau}")
    t = _steps(T)
    if np.any(t < 0):
        raise ValueError("singer input: T must be >= 0")
    k = 1.0 / tau
    u = k * t
    small = u <= SINGER_INPUT_SERIES_LIMIT
    series = []
    for depth in (3, 2, 1):
        coefficients = [1.0 / math.factorial(j + depth) for j in range(_SERIES_TERMS)]
        acc = np.zeros_like(u)
        for c in coefficients[::-1]:
            acc = acc * (-u) + c
        series.append(t**depth * acc)
    one_minus_e1 = -np.expm1(-u)
    closed = (
        t * t / (2.0 * k) - t / k**2 + one_minus_e1 / k**3,
        t / k - one_minus_e1 / k**2,
        one_minus_e1 / k,
    )
    return np.stack([np.where(small, s, c) for s, c in zip(series, closed)], axis=-1)

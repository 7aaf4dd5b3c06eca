"""Gain design and steady-state analysis of constant-gain α–β and α–β–γ filters (spec 004 §3.3 C, R4),
and the fading-memory NIS detector threshold of the VD filter (§3.3 J) that R3's manoeuvre gains use.

Conventions (spec 004 §2, §3.3 C): per axis the gain is ``K = [α, β/T]`` (α–β, order 2) or
``K = [α, β/T, γ/(2T²)]`` (α–β–γ, order 3), ``F`` the polynomial transition of that order
(``F_ij = T^{j−i}/(j−i)!``), ``H = [1, 0(, 0)]``.  Every function takes scalars or arrays
(broadcast elementwise) unless it says otherwise.

Gain rules: fixed; Benedict–Bordner ``β = α²/(2−α)``; Kalata from the tracking index
``λ = σ_w T²/σ_v`` — DWNA α–β in closed form, DWPA α–β–γ by a bracketed root finder
(``scipy.optimize.brentq``, tol 1e−14); critically damped (fading memory θ); growing-memory
least-squares start-up gains.

Analysis: noise-only variance ratios, steady-state lags under a constant acceleration, the
stability region and the spectral radius of the error matrix ``(I − K H) F``, the steady-state
error covariance of given gains (discrete Lyapunov equation
``P = A P Aᵀ + (I−KH) Q (I−KH)ᵀ + K R Kᵀ``, ``A = (I−KH)F``, ``P⁻ = F P Fᵀ + Q``) and of the
Kalata gains (discrete algebraic Riccati equation of the matching Kalman filter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg as sla
from scipy import optimize

from skytrack.core.chi2 import chi2_quantile
from skytrack.models.polynomial import PolynomialAxis

GAIN_RULES = ("fixed", "benedict-bordner", "kalata", "critically-damped")
KALATA_ROOT_TOL = 1e-14


def _out(value: np.ndarray):
    """A Python scalar (bool or float) for 0-d results, the array otherwise."""
    value = np.asarray(value)
    if value.ndim:
        return value
    return bool(value) if value.dtype == bool else float(value)


def _check_order(order: int) -> int:
    if order not in (2, 3):
        raise ValueError(f"alpha-beta order must be 2 (alpha-beta) or 3 (alpha-beta-gamma), got {order!r}")
    return int(order)


def _check_period(period: float) -> float:
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"alpha-beta period T must be finite and > 0, got {period}")
    return float(period)


# ---------------------------------------------------------------------------- matrices
def polynomial_transition(order: int, period: float) -> np.ndarray:
    """The polynomial ``F`` (order × order) of one axis for the step ``period``."""
    return PolynomialAxis(_check_order(order)).F_batch(np.array([_check_period(period)]))[0]


def gain_vector(alpha, beta, gamma=None, period: float = 1.0) -> np.ndarray:
    """``K[..., m] = [α, β/T(, γ/(2T²))]`` (m = 3 when ``gamma`` is given)."""
    T = _check_period(period)
    parts = [np.asarray(alpha, float), np.asarray(beta, float) / T]
    if gamma is not None:
        parts.append(np.asarray(gamma, float) / (2.0 * T * T))
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def error_transition(alpha, beta, gamma=None, period: float = 1.0) -> np.ndarray:
    """The filtered-error matrix ``(I − K H) F`` of shape ``[..., m, m]``."""
    K = gain_vector(alpha, beta, gamma, period)
    m = K.shape[-1]
    F = polynomial_transition(m, period)
    # (I - K H) F = F - K (H F), and H F is the first row of F
    return F - K[..., :, None] * F[0]


def spectral_radius(alpha, beta, gamma=None):
    """Largest eigenvalue modulus of ``(I − K H) F`` (independent of T in these gain units)."""
    return _out(np.max(np.abs(np.linalg.eigvals(error_transition(alpha, beta, gamma, 1.0))), axis=-1))


def is_stable(alpha, beta, gamma=None):
    """The stability region of §3.3 C: ``0 < α < 2``, ``0 < β < 4 − 2α`` (and ``0 < γ < 4αβ/(2 − α)``)."""
    a, b = np.asarray(alpha, float), np.asarray(beta, float)
    inside = (a > 0) & (a < 2) & (b > 0) & (b < 4 - 2 * a)
    if gamma is not None:
        g = np.asarray(gamma, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = inside & (g > 0) & (g < 4 * a * b / (2 - a))
    return _out(inside)


def check_stable(alpha, beta, gamma=None, option: str = "gains") -> None:
    """ValueError naming ``option`` unless every (α, β[, γ]) lies inside the stability region."""
    for name, value in (("alpha", alpha), ("beta", beta), ("gamma", gamma)):
        if value is not None and not np.all(np.isfinite(np.asarray(value, float))):
            raise ValueError(f"{option}: {name} must be finite, got {value}")
    if not np.all(is_stable(alpha, beta, gamma)):
        label = "(alpha, beta)" if gamma is None else "(alpha, beta, gamma)"
        values = (alpha, beta) if gamma is None else (alpha, beta, gamma)
        bound = "0 < alpha < 2, 0 < beta < 4 - 2 alpha" + ("" if gamma is None else ", 0 < gamma < 4 alpha beta / (2 - alpha)")
        raise ValueError(f"{option}: unstable {label} = {values}; the stable region is {bound} "
                         f"(spectral radius of (I - K H) F = {np.max(spectral_radius(alpha, beta, gamma)):.6g})")


# ---------------------------------------------------------------------------- gain rules
def _check_open_unit(value, option: str) -> np.ndarray:
    v = np.asarray(value, float)
    if not np.all((v > 0) & (v < 1)):
        raise ValueError(f"{option} must be in (0, 1), got {value}")
    return v


def benedict_bordner_beta(alpha):
    """Benedict–Bordner: ``β = α²/(2 − α)`` for α in (0, 1)."""
    a = _check_open_unit(alpha, "benedict-bordner: alpha")
    return _out(a * a / (2.0 - a))


def kalata_alpha_beta(tracking_index):
    """Kalata DWNA α–β from ``λ > 0``: the steady-state Kalman gain of the DWNA model.

    With ``t = 1 − √(1 − α)`` the relations ``β = 2 t²`` and ``λ² = β²/(1 − α)`` give
    ``2t² = λ(1 − t)``, i.e. ``t = 2λ/(λ + √(λ² + 8λ))`` (the spec's closed form, written without
    the cancellation of ``−(λ² + 8λ − (λ+4) r)/8`` at large λ); ``α = t(2 − t)``.
    """
    lam = _check_tracking_index(tracking_index)
    t = 2.0 * lam / (lam + np.sqrt(lam * lam + 8.0 * lam))
    return _out(t * (2.0 - t)), _out(2.0 * t * t)


def kalata_beta_from_alpha(alpha):
    """β on the Kalata DWNA curve: ``β = 2(2 − α) − 4√(1 − α) = 2(1 − √(1 − α))²``."""
    a = _check_open_unit(alpha, "kalata: alpha")
    return _out(2.0 * (a / (1.0 + np.sqrt(1.0 - a))) ** 2)


def equivalent_tracking_index(alpha, beta):
    """``λ = β/√(1 − α)``: the tracking index of (α, β) (exact for Kalata gains; R3's nominal λ)."""
    a = _check_open_unit(alpha, "tracking index: alpha")
    return _out(np.asarray(beta, float) / np.sqrt(1.0 - a))


def _check_tracking_index(tracking_index) -> np.ndarray:
    lam = np.asarray(tracking_index, float)
    if not np.all(np.isfinite(lam) & (lam > 0)):
        raise ValueError(f"kalata: tracking_index must be finite and > 0, got {tracking_index}")
    return lam


def kalata_alpha_beta_gamma(tracking_index):
    """Kalata DWPA α–β–γ from ``λ > 0``: ``β = 2(2 − α) − 4√(1 − α)``, ``γ = β²/α``,
    ``λ² = γ²/(4(1 − α))`` solved for α in (0, 1).

    With ``t = 1 − √(1 − α)``: ``α = t(2 − t)``, ``β = 2t²``, ``γ = 4t³/(2 − t)`` and
    ``λ = γ/(2√(1 − α)) = 2t³/((1 − t)(2 − t))``, increasing from 0 to ∞ on t in (0, 1); its root
    ``2t³ − λ(1 − t)(2 − t) = 0`` is bracketed by [0, 1] (value −2λ at 0, +2 at 1) and found by
    ``brentq`` with ``xtol = rtol = 1e−14`` (no cancellation in α, β, γ from t).
    """
    lam = _check_tracking_index(tracking_index)
    flat = lam.reshape(-1)
    t = np.empty_like(flat)
    for i, value in enumerate(flat):
        t[i] = optimize.brentq(lambda s, v=value: 2.0 * s**3 - v * (1.0 - s) * (2.0 - s), 0.0, 1.0,
                               xtol=KALATA_ROOT_TOL, rtol=KALATA_ROOT_TOL)
    t = t.reshape(lam.shape)
    return _out(t * (2.0 - t)), _out(2.0 * t * t), _out(4.0 * t**3 / (2.0 - t))


def critically_damped_gains(theta, order: int = 2):
    """Fading-memory (critically damped) gains: every eigenvalue of ``(I − K H) F`` equals θ in [0, 1).

    α–β: ``α = 1 − θ²``, ``β = (1 − θ)²`` (§3.3 C).  α–β–γ (same pole placement, γ/(2T²)
    convention): ``α = 1 − θ³``, ``β = 1.5 (1 − θ)²(1 + θ)``, ``γ = 2 (1 − θ)³``.
    Returns ``(α, β)`` or ``(α, β, γ)``.
    """
    th = np.asarray(theta, float)
    if not np.all((th >= 0) & (th < 1)):
        raise ValueError(f"critically-damped: theta must be in [0, 1), got {theta}")
    if _check_order(order) == 2:
        return _out(1.0 - th * th), _out((1.0 - th) ** 2)
    return _out(1.0 - th**3), _out(1.5 * (1.0 - th) ** 2 * (1.0 + th)), _out(2.0 * (1.0 - th) ** 3)


def startup_gains(k, order: int = 2):
    """Growing-memory least-squares gains for the k-th measurement (k = 1, 2, …).

    α–β (§3.3 C): ``α_k = 2(2k−1)/(k(k+1))``, ``β_k = 6/(k(k+1))``; the estimate after k ≥ 2
    measurements is the least-squares line through all of them.  α–β–γ (the quadratic analogue,
    γ/(2T²) convention): ``α_k = 3(3k²−3k+2)/D``, ``β_k = 18(2k−1)/D``, ``γ_k = 120/D``,
    ``D = k(k+1)(k+2)``; exact quadratic least squares from k ≥ 3.
    """
    kk = np.asarray(k, float)
    if not np.all((kk >= 1) & (kk == np.floor(kk))):
        raise ValueError(f"start-up gains: k must be an integer >= 1, got {k}")
    if _check_order(order) == 2:
        d = kk * (kk + 1.0)
        return _out(2.0 * (2.0 * kk - 1.0) / d), _out(6.0 / d)
    d = kk * (kk + 1.0) * (kk + 2.0)
    return (_out(3.0 * (3.0 * kk * kk - 3.0 * kk + 2.0) / d), _out(18.0 * (2.0 * kk - 1.0) / d),
            _out(120.0 / d))


def startup_length(alpha: float, order: int = 2) -> int:
    """The first k whose start-up α_k is <= the steady α: start-up gains serve k = 1 … k_s − 1."""
    a = float(alpha)
    if not (0 < a <= 1):
        raise ValueError(f"start-up gains: the steady alpha must be in (0, 1], got {alpha}")
    low, high = 0, 1  # alpha_k is non-increasing in k: double, then bisect
    while startup_gains(high, order)[0] > a:
        low, high = high, high * 2
    while high - low > 1:
        mid = (low + high) // 2
        if startup_gains(mid, order)[0] > a:
            low = mid
        else:
            high = mid
    return high


def tracking_index(sigma_w, sigma_v, period: float):
    """Kalata's tracking index ``λ = σ_w T²/σ_v``."""
    T = _check_period(period)
    sw, sv = np.asarray(sigma_w, float), np.asarray(sigma_v, float)
    if not np.all(sv > 0) or not np.all(sw >= 0):
        raise ValueError(f"tracking index: need sigma_v > 0 and sigma_w >= 0, got {sigma_v}, {sigma_w}")
    return _out(sw * T * T / sv)


def design_gains(rule: str, order: int, *, alpha=None, beta=None, gamma=None, tracking_index=None,
                 theta=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(α, β, γ or None) by ``rule`` (one of :data:`GAIN_RULES`), checked for stability.

    Parameters may be scalars or per-axis arrays: ``fixed`` takes alpha, beta (and gamma for
    order 3); ``benedict-bordner`` alpha (order 2 only); ``kalata`` tracking_index (DWNA for
    order 2, DWPA for order 3); ``critically-damped`` theta.  Parameters a rule does not use are
    an error, so a misspelt configuration does not pass silently.
    """
    order = _check_order(order)
    given = {"alpha": alpha, "beta": beta, "gamma": gamma, "tracking_index": tracking_index, "theta": theta}
    uses = {"fixed": ("alpha", "beta", "gamma") if order == 3 else ("alpha", "beta"),
            "benedict-bordner": ("alpha",), "kalata": ("tracking_index",), "critically-damped": ("theta",)}
    if rule not in uses:
        raise ValueError(f"gain_rule must be one of {GAIN_RULES}, got {rule!r}")
    extra = sorted(k for k, v in given.items() if v is not None and k not in uses[rule])
    missing = [k for k in uses[rule] if given[k] is None]
    if extra:
        raise ValueError(f"gain_rule {rule!r} (order {order}) does not take {extra}; it takes {list(uses[rule])}")
    if missing:
        raise ValueError(f"gain_rule {rule!r} (order {order}) needs {missing}")
    if rule == "fixed":
        a, b = np.asarray(alpha, float), np.asarray(beta, float)
        g = np.asarray(gamma, float) if order == 3 else None
    elif rule == "benedict-bordner":
        if order == 3:
            raise ValueError("gain_rule 'benedict-bordner' is an alpha-beta rule (order 2); "
                             "use 'kalata' or 'critically-damped' for alpha-beta-gamma")
        a = np.asarray(alpha, float)
        b, g = np.asarray(benedict_bordner_beta(a)), None
    elif rule == "kalata":
        if order == 2:
            a, b = map(np.asarray, kalata_alpha_beta(tracking_index))
            g = None
        else:
            a, b, g = map(np.asarray, kalata_alpha_beta_gamma(tracking_index))
    else:
        gains = critically_damped_gains(theta, order)
        a, b = np.asarray(gains[0]), np.asarray(gains[1])
        g = np.asarray(gains[2]) if order == 3 else None
    check_stable(a, b, g, option=f"gain_rule {rule!r}")
    return a, b, g


# ---------------------------------------------------------------------------- analysis
@dataclass(frozen=True)
class VarianceRatios:
    """Steady-state error variances of an α–β filter per unit measurement variance σ_v²."""

    filtered_position: float | np.ndarray
    predicted_position: float | np.ndarray
    velocity: float | np.ndarray  # 1/s²


def variance_ratios(alpha, beta, period: float = 1.0) -> VarianceRatios:
    """Noise-only steady state of α–β (§3.3 C): filtered position ``(2α² + 2β − 3αβ)/(α(4 − 2α − β))``,
    predicted position ``(2α² + αβ + 2β)/(α(4 − 2α − β))``, velocity ``2β²/(T² α(4 − 2α − β))``."""
    check_stable(alpha, beta, option="variance_ratios")
    T = _check_period(period)
    a, b = np.asarray(alpha, float), np.asarray(beta, float)
    den = a * (4.0 - 2.0 * a - b)
    return VarianceRatios(_out((2 * a * a + 2 * b - 3 * a * b) / den), _out((2 * a * a + a * b + 2 * b) / den),
                          _out(2 * b * b / (T * T * den)))


@dataclass(frozen=True)
class Lags:
    """Steady-state errors (truth − estimate) of α–β under a constant acceleration."""

    predicted_position: float | np.ndarray
    filtered_position: float | np.ndarray
    velocity: float | np.ndarray


def steady_state_lags(alpha, beta, period: float, acceleration) -> Lags:
    """Lags for constant acceleration A: predicted ``A T²/β``, filtered ``(1 − α) A T²/β``,
    velocity ``A T (2α − β)/(2β)``."""
    check_stable(alpha, beta, option="steady_state_lags")
    T = _check_period(period)
    a, b, A = np.asarray(alpha, float), np.asarray(beta, float), np.asarray(acceleration, float)
    return Lags(_out(A * T * T / b), _out((1.0 - a) * A * T * T / b), _out(A * T * (2.0 * a - b) / (2.0 * b)))


def steady_state_covariance(alpha: float, beta: float, gamma: float | None = None, period: float = 1.0,
                            R: float = 1.0, Q: np.ndarray | None = None,
                            F: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Filtered and predicted steady-state error covariances of one axis with constant gains.

    Solves ``P = A P Aᵀ + (I−KH) Q (I−KH)ᵀ + K R Kᵀ``, ``A = (I−KH)F``, by
    ``scipy.linalg.solve_discrete_lyapunov``; ``P⁻ = F P Fᵀ + Q``.  ``F`` defaults to the
    polynomial transition, ``Q`` to zero (noise only: ``P/R`` are the variance ratios).
    """
    check_stable(alpha, beta, gamma, option="steady_state_covariance")
    K = gain_vector(float(alpha), float(beta), None if gamma is None else float(gamma), period)
    m = len(K)
    F = polynomial_transition(m, period) if F is None else np.asarray(F, float)
    Q = np.zeros((m, m)) if Q is None else np.asarray(Q, float)
    I_KH = np.eye(m)
    I_KH[:, 0] -= K
    A = I_KH @ F
    if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        raise ValueError("steady_state_covariance: the gains are unstable with this F")
    P = sla.solve_discrete_lyapunov(A, I_KH @ Q @ I_KH.T + float(R) * np.outer(K, K))
    P = 0.5 * (P + P.T)
    return P, F @ P @ F.T + Q


def kalata_noise(order: int, period: float, sigma_w: float) -> np.ndarray:
    """The process noise of Kalata's designs: DWNA (order 2) or DWPA (order 3), from the R1 models."""
    variant = "piecewise_constant" if _check_order(order) == 2 else "wiener_increment"
    return PolynomialAxis(order, variant, float(sigma_w)).Q_batch(np.array([_check_period(period)]))[0]


@dataclass(frozen=True)
class KalmanSteadyState:
    """Steady state of the Kalman filter whose gain the Kalata rule reproduces."""

    gain: np.ndarray  # K = [alpha, beta/T(, gamma/(2T^2))]
    filtered: np.ndarray
    predicted: np.ndarray
    innovation_variance: float

    def gains(self, period: float) -> tuple[float, ...]:
        """(α, β[, γ]) in the spec's dimensionless units."""
        scale = [1.0, period, 2.0 * period * period][: len(self.gain)]
        return tuple(float(k * s) for k, s in zip(self.gain, scale))


def kalata_steady_state(order: int, period: float, sigma_w: float, sigma_v: float) -> KalmanSteadyState:
    """DARE solution (``scipy.linalg.solve_discrete_are``) of the KF with the polynomial F, DWNA/DWPA
    Q of ``sigma_w`` and ``R = σ_v²``: predicted P⁻, ``K = P⁻Hᵀ/S``, filtered ``(I − K H) P⁻``."""
    F = polynomial_transition(order, period)
    Q = kalata_noise(order, period, sigma_w)
    R = float(sigma_v) ** 2
    if not R > 0:
        raise ValueError(f"kalata_steady_state: sigma_v must be > 0, got {sigma_v}")
    H = np.zeros((1, order))
    H[0, 0] = 1.0
    P_pred = sla.solve_discrete_are(F.T, H.T, Q, np.array([[R]]))
    P_pred = 0.5 * (P_pred + P_pred.T)
    S = P_pred[0, 0] + R
    K = P_pred[:, 0] / S
    P = P_pred - np.outer(K, P_pred[0])
    return KalmanSteadyState(K, 0.5 * (P + P.T), P_pred, float(S))


# ---------------------------------------------------------------------------- VD detector
def detector_scale_dof(n_z: int, rho: float) -> tuple[float, float]:
    """Moment-matched ``u ~ c χ²_d`` of the fading NIS sum ``u_k = ρ u_{k−1} + ε_k`` (§3.3 J):
    ``c = 1/(1 + ρ)``, ``d = n_z (1 + ρ)/(1 − ρ)``."""
    if not 0 <= rho < 1:
        raise ValueError(f"detector: rho must be in [0, 1), got {rho}")
    if n_z < 1:
        raise ValueError(f"detector: n_z must be >= 1, got {n_z}")
    return 1.0 / (1.0 + rho), n_z * (1.0 + rho) / (1.0 - rho)


def detector_threshold(n_z: int, rho: float, p_fa: float) -> float:
    """Manoeuvre threshold ``c · χ²_d⁻¹(1 − P_fa)`` on ``u_k``."""
    if not 0 < p_fa < 1:
        raise ValueError(f"detector: p_fa must be in (0, 1), got {p_fa}")
    c, d = detector_scale_dof(n_z, rho)
    return float(c * chi2_quantile(1.0 - p_fa, d))


def detector_window(rho: float) -> int:
    """The VD window ``s = round(1/(1 − ρ))`` (ρ = 0.8 → 5)."""
    if not 0 <= rho < 1:
        raise ValueError(f"detector: rho must be in [0, 1), got {rho}")
    return int(round(1.0 / (1.0 - rho)))

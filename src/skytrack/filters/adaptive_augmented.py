"""Adaptive augmented-state filter of spec 002 (R11 steps A1-A8, R12 estimator A5.1-A5.5, R13 literal preset, R15).

The paper's adaptive filter inverts two matrices: the gain (6) and the a-posteriori estimate (7) of
the disturbance covariance V_w, whose ξ(k) is undefined (gap G1).  skytrack's estimator (R12):

* A5.1 L_k = (S_kᵀWS_k)⁻¹S_kᵀW, S_k = H_kG_k, W = I (``weighting="none"``, literal eq. 12) or
  W = C_k⁻¹ (``"innovation"``, default, gap G12);
* A5.2 ŵ = L_kν_k (for linear models: χ̂ of eq. 12 minus h_a x̂(k−1|k−1), TV3);
* A5.3 Q_k = ŵŵᵀ − L_kC_kL_kᵀ, unbiased for V_w when the filter is consistent (TV11 b);
* A5.4 fading memory n_j = λn_{j−1} + 1, V̄_j = V̄_{j−1} + (Q_k − V̄_{j−1})/n_j, or the mean of the last
  N_w Q's; ``rate=True`` averages Q_k/T_k and scales by T_k (irregular sampling);
* A5.5 output V̂_w = Π(V̄): symmetrised, eigenvalues of D⁻¹V̄D⁻¹ floored at 1 (D = diag σ_min) and
  optionally capped with D' = diag σ_max; the memory V̄ itself stays raw.

The estimator runs only when the R5 verdict on S_k (with V_η) is not ``not_identifiable`` (A4);
otherwise V̂_w is kept and the step is counted.  Gain (6) by a Cholesky solve or, literally, by an
explicit inverse; covariance update in Joseph form, the short form (I − ΓH)V_x only by flag (E5).
Dependent-state noise Q_dep is the model's (gap G11); the literal preset (R13) drops it.

Everything is batched over a bank of N tracks (x ``[N, n]``, P ``[N, n, n]``); one step is one call of
:meth:`AdaptiveAugmentedFilter.step`.  Angles (channels the measurement declares ``angular``) are
wrapped to (−π, π] in the innovation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from skytrack.filters.identifiability_step import NOT_IDENTIFIABLE, step_verdicts
from skytrack.models.augmented import AugmentedModel

Weighting = Literal["none", "innovation"]
Timing = Literal["same", "next"]
GainInverse = Literal["cholesky", "explicit"]


@dataclass(frozen=True)
class AdaptiveSettings:
    """Options of R11/R12; the defaults are R12's generic ones.

    ``sigma_min`` (p-vector, > 0, per step, parameter units) is required by the floor of A5.5;
    ``sigma_max`` is the optional ceiling.  ``forgetting`` is λ, ``n0`` the initial memory count;
    ``window`` (int) replaces fading memory by the mean of the last ``window`` Q's.
    """

    sigma_min: np.ndarray
    sigma_max: np.ndarray | None = None
    weighting: Weighting = "innovation"
    forgetting: float = 0.95
    n0: float = 1.0
    window: int | None = None
    rate: bool = False
    timing: Timing = "same"
    gain_inverse: GainInverse = "cholesky"
    joseph: bool = True
    dependent_noise: bool = True

    def __post_init__(self):
        sigma_min = np.atleast_1d(np.asarray(self.sigma_min, float))
        if np.any(sigma_min <= 0):
            raise ValueError("sigma_min must be positive (A5.5 floor)")
        object.__setattr__(self, "sigma_min", sigma_min)
        if self.sigma_max is not None:
            sigma_max = np.atleast_1d(np.asarray(self.sigma_max, float))
            if sigma_max.shape != sigma_min.shape or np.any(sigma_max < sigma_min):
                raise ValueError("sigma_max must be a p-vector at least sigma_min")
            object.__setattr__(self, "sigma_max", sigma_max)
        if self.weighting not in ("none", "innovation"):
            raise ValueError(f"weighting must be 'none' or 'innovation', not {self.weighting!r}")
        if self.timing not in ("same", "next"):
            raise ValueError(f"timing must be 'same' or 'next', not {self.timing!r}")
        if self.gain_inverse not in ("cholesky", "explicit"):
            raise ValueError(f"gain_inverse must be 'cholesky' or 'explicit', not {self.gain_inverse!r}")
        if not 0.0 <= self.forgetting <= 1.0:
            raise ValueError("forgetting factor λ must lie in [0, 1]")
        if self.window is not None and self.window < 1:
            raise ValueError("window must be a positive number of steps")


def literal_settings(sigma_min, sigma_max=None, **overrides) -> AdaptiveSettings:
    """R13 preset: weighting none, λ = 0, n_0 = 0, Q_dep = 0, explicit gain inverse, timing same.

    The floor Π and the Joseph form are kept (without the floor P can become indefinite).
    """
    settings = AdaptiveSettings(sigma_min=sigma_min, sigma_max=sigma_max, weighting="none", forgetting=0.0,
                                n0=0.0, dependent_noise=False, gain_inverse="explicit", timing="same")
    return replace(settings, **overrides) if overrides else settings


@dataclass
class AdaptiveBankState:
    """Filter state of a bank of N tracks: estimates and the V_w estimator's memory."""

    x: np.ndarray  # [N, n]
    P: np.ndarray  # [N, n, n]
    V_bar: np.ndarray  # [N, p, p] raw memory (rate units when rate=True)
    count: np.ndarray  # [N] fading-memory count n_j
    skipped: np.ndarray  # [N] int, steps whose A5 was skipped (A4)
    history: np.ndarray | None = None  # [N, N_w, p, p] last Q's (window memory)
    filled: np.ndarray | None = None  # [N] int, Q's in the window
    cursor: np.ndarray | None = None  # [N] int, next slot of the window


@dataclass
class AdaptiveStepOutput:
    """R15 per-step outputs for the bank (N leading axis)."""

    x: np.ndarray
    P: np.ndarray
    innovation: np.ndarray
    innovation_cov: np.ndarray  # H V_x(k|k−1) Hᵀ + V_η, the gain's and the NIS's
    estimator_cov: np.ndarray  # C_k = H A_k Hᵀ + V_η of A3, the estimator's (without G V̂_w Gᵀ)
    sensitivity: np.ndarray  # S_k = H_k G_k
    nis: np.ndarray
    V_w: np.ndarray  # V̂_w used in the prediction covariance (A6)
    V_w_estimate: np.ndarray  # V̂_w(k−1) = Π(V̄) after this step
    V_bar: np.ndarray
    w_hat: np.ndarray  # NaN on skipped tracks
    Q: np.ndarray  # NaN on skipped tracks
    L: np.ndarray  # NaN on skipped tracks
    gain: np.ndarray
    verdict: np.ndarray
    kappa: np.ndarray
    zero_influence: np.ndarray
    adapted: np.ndarray
    skipped: np.ndarray
    prior_cov: np.ndarray = field(repr=False, default=None)  # V_x(k|k−1)


def wrap_angles(values: np.ndarray) -> np.ndarray:
    """Wrap to (−π, π]."""
    return np.pi - np.mod(np.pi - values, 2.0 * np.pi)


def project_covariance(V: np.ndarray, sigma_min: np.ndarray, sigma_max: np.ndarray | None = None) -> np.ndarray:
    """A5.5 Π: symmetrise, floor the eigenvalues of D⁻¹VD⁻¹ at 1 (D = diag σ_min), optional ceiling."""
    V = 0.5 * (V + np.swapaxes(V, -1, -2))
    V = _clamp_scaled(V, np.asarray(sigma_min, float), np.maximum)
    if sigma_max is not None:
        V = _clamp_scaled(V, np.asarray(sigma_max, float), np.minimum)
    return V


def _clamp_scaled(V: np.ndarray, scale: np.ndarray, clamp) -> np.ndarray:
    scaled = V / np.multiply.outer(scale, scale)
    eigenvalues, U = np.linalg.eigh(scaled)
    scaled = (U * clamp(eigenvalues, 1.0)[..., None, :]) @ np.swapaxes(U, -1, -2)
    return scaled * np.multiply.outer(scale, scale)


def estimator_gain(S: np.ndarray, C: np.ndarray, weighting: Weighting):
    """A5.1: L = (SᵀWS)⁻¹SᵀW and L C Lᵀ for W = I ('none') or W = C⁻¹ ('innovation'), batched.

    Tracks with a singular SᵀWS get NaN (the filter never uses them: A4 skips them first).
    """
    St = np.swapaxes(S, -1, -2)
    weighted_T = St if weighting == "none" else np.swapaxes(np.linalg.solve(C, S), -1, -2)
    normal = weighted_T @ S
    singular = np.linalg.matrix_rank(normal) < normal.shape[-1]
    safe = np.where(singular[:, None, None], np.eye(normal.shape[-1]), normal)
    L = np.linalg.solve(safe, weighted_T)
    L = np.where(singular[:, None, None], np.nan, L)
    return L, L @ C @ np.swapaxes(L, -1, -2)


def filter_gain(Vx: np.ndarray, H: np.ndarray, noise_cov: np.ndarray, inverse: GainInverse = "cholesky"):
    """Gain (6) Γ = V_x Hᵀ (H V_x Hᵀ + V_η)⁻¹ and the innovation covariance, batched (A7).

    ``"cholesky"`` solves with the Cholesky factor (fails loudly if the sum is not positive
    definite); ``"explicit"`` forms the inverse, as the paper writes it (R13).
    """
    Ht = np.swapaxes(H, -1, -2)
    innovation_cov = H @ Vx @ Ht + noise_cov
    cross = Vx @ Ht
    if inverse == "explicit":
        return cross @ np.linalg.inv(innovation_cov), innovation_cov
    chol = np.linalg.cholesky(innovation_cov)
    half = np.linalg.solve(chol, np.swapaxes(cross, -1, -2))
    gain = np.swapaxes(np.linalg.solve(np.swapaxes(chol, -1, -2), half), -1, -2)
    return gain, innovation_cov


class AdaptiveAugmentedFilter:
    """R11 adaptive augmented filter over a bank of tracks.

    ``model`` is an :class:`~skytrack.models.augmented.AugmentedModel`; ``measurement`` anything with
    ``evaluate(states [N, n]) -> (h [N, m], H [N, m, n])`` and, optionally, ``angular`` (m bools).
    """

    def __init__(self, model: AugmentedModel, measurement, settings: AdaptiveSettings):
        self.model = model
        self.measurement = measurement
        self.settings = settings
        p = model.n_parameters
        if settings.sigma_min.shape != (p,):
            raise ValueError(f"sigma_min needs {p} entries, one per parameter {model.parameters}")
        angular = getattr(measurement, "angular", None)
        self.angular = None if angular is None or not np.any(angular) else np.asarray(angular, bool)

    # ---------------------------------------------------------------- state
    def initial_state(self, x0, P0, V_w0=None, count0: float | None = None) -> AdaptiveBankState:
        """Bank state from x0 ``[N, n]`` (or ``[n]``), P0, the prior V_w0 (default: the model's V_w)."""
        x = np.atleast_2d(np.asarray(x0, float)).copy()
        N, n = x.shape
        P = np.broadcast_to(np.asarray(P0, float), (N, n, n)).copy()
        p = self.model.n_parameters
        V0 = self.model.V_w if V_w0 is None else np.asarray(V_w0, float).reshape(p, p)
        n0 = self.settings.n0 if count0 is None else count0
        state = AdaptiveBankState(x=x, P=P, V_bar=np.broadcast_to(V0, (N, p, p)).copy(),
                                  count=np.full(N, float(n0)), skipped=np.zeros(N, dtype=int))
        if self.settings.window is not None:
            state.history = np.zeros((N, self.settings.window, p, p))
            state.filled = np.zeros(N, dtype=int)
            state.cursor = np.zeros(N, dtype=int)
        return state

    # ---------------------------------------------------------------- one step
    def step(self, state: AdaptiveBankState, y, T, noise_cov) -> AdaptiveStepOutput:
        """One step A1-A8 for every track; ``state`` is updated in place and the R15 record returned.

        ``y`` ``[N, m]``, ``T`` scalar or ``[N]``, ``noise_cov`` V_η ``[m, m]`` or ``[N, m, m]``.
        """
        s = self.settings
        model = self.model
        x, P = state.x, state.P
        N, n = x.shape
        T = np.broadcast_to(np.asarray(T, float), (N,))
        y = np.atleast_2d(np.asarray(y, float))
        m = y.shape[1]
        V_eta = np.broadcast_to(np.asarray(noise_cov, float), (N, m, m))

        # A1 prediction
        F = model.F(x, T)
        G = model.G(x, T, F=F)
        x_pred = model.phi(x, T)
        # A2 innovation at the predicted state
        h_pred, H = self.measurement.evaluate(x_pred)
        nu = y - h_pred
        if self.angular is not None:
            nu[:, self.angular] = wrap_angles(nu[:, self.angular])
        # A3
        A = F @ P @ np.swapaxes(F, -1, -2)
        if s.dependent_noise:
            A = A + model.Q_dep(T)
        Ht = np.swapaxes(H, -1, -2)
        C = H @ A @ Ht + V_eta
        S = H @ G
        # A4 per-step identifiability (R5)
        verdict, kappa, zero = step_verdicts(H, G, V_eta)
        adapted = verdict != NOT_IDENTIFIABLE

        scale = T[:, None, None] if s.rate else np.ones((N, 1, 1))
        V_before = project_covariance(scale * state.V_bar, s.sigma_min, s.sigma_max)

        # A5 estimator on the identifiable tracks
        p = model.n_parameters
        w_hat = np.full((N, p), np.nan)
        Q = np.full((N, p, p), np.nan)
        L_out = np.full((N, p, m), np.nan)
        if adapted.any():
            idx = np.flatnonzero(adapted)
            L, LCL = estimator_gain(S[idx], C[idx], s.weighting)
            w = np.einsum("kpm,km->kp", L, nu[idx])
            Q_k = np.einsum("kp,kq->kpq", w, w) - LCL
            w_hat[idx], Q[idx], L_out[idx] = w, Q_k, L
            self._remember(state, idx, Q_k / scale[idx])
        state.skipped = state.skipped + (~adapted)
        V_after = project_covariance(scale * state.V_bar, s.sigma_min, s.sigma_max)

        # A6 prior covariance with the chosen V̂_w
        V_used = V_after if s.timing == "same" else V_before
        Vx = A + G @ V_used @ np.swapaxes(G, -1, -2)
        Vx = 0.5 * (Vx + np.swapaxes(Vx, -1, -2))
        # A7 gain (6)
        gain, innovation_cov = filter_gain(Vx, H, V_eta, s.gain_inverse)
        white = np.linalg.solve(np.linalg.cholesky(innovation_cov), nu[..., None])[..., 0]
        nis = np.einsum("ki,ki->k", white, white)
        # A8 update
        x_new = x_pred + np.einsum("kij,kj->ki", gain, nu)
        I_KH = np.eye(n) - gain @ H
        if s.joseph:
            P_new = I_KH @ Vx @ np.swapaxes(I_KH, -1, -2) + gain @ V_eta @ np.swapaxes(gain, -1, -2)
            P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
        else:
            P_new = I_KH @ Vx
        state.x, state.P = x_new, P_new
        return AdaptiveStepOutput(
            x=x_new, P=P_new, innovation=nu, innovation_cov=innovation_cov, estimator_cov=C,
            sensitivity=S, nis=nis, V_w=V_used,
            V_w_estimate=V_after, V_bar=state.V_bar.copy(), w_hat=w_hat, Q=Q, L=L_out, gain=gain,
            verdict=verdict, kappa=kappa, zero_influence=zero, adapted=adapted, skipped=state.skipped.copy(),
            prior_cov=Vx,
        )

    def _remember(self, state: AdaptiveBankState, idx: np.ndarray, Q: np.ndarray) -> None:
        """A5.4: fold the new Q's of tracks ``idx`` into the memory."""
        s = self.settings
        if s.window is None:
            count = s.forgetting * state.count[idx] + 1.0
            state.count[idx] = count
            state.V_bar[idx] = state.V_bar[idx] + (Q - state.V_bar[idx]) / count[:, None, None]
            return
        slot = state.cursor[idx]
        state.history[idx, slot] = Q
        state.cursor[idx] = (slot + 1) % s.window
        state.filled[idx] = np.minimum(state.filled[idx] + 1, s.window)
        state.V_bar[idx] = state.history[idx].sum(axis=1) / state.filled[idx][:, None, None]

    # ---------------------------------------------------------------- runs
    def run(self, state: AdaptiveBankState, measurements, T, noise_cov) -> dict[str, np.ndarray]:
        """Steps over measurements ``[K, N, m]``; returns R15's outputs stacked as ``[K, N, ...]``.

        ``T`` scalar or ``[K]`` / ``[K, N]``; ``noise_cov`` ``[m, m]``, ``[K, m, m]`` or ``[K, N, m, m]``.
        """
        measurements = np.asarray(measurements, float)
        K = len(measurements)
        T = np.asarray(T, float)
        noise_cov = np.asarray(noise_cov, float)
        per_step_cov = noise_cov.ndim >= 3
        names = ("x", "P", "innovation", "innovation_cov", "nis", "V_w", "w_hat", "Q", "verdict", "kappa",
                 "skipped")
        out: dict[str, list] = {name: [] for name in names}
        for k in range(K):
            record = self.step(state, measurements[k], T if T.ndim == 0 else T[k],
                               noise_cov[k] if per_step_cov else noise_cov)
            for name in names:
                out[name].append(getattr(record, name))
        return {name: np.stack(values) for name, values in out.items()}


class LinearMeasurement:
    """A fixed observation matrix h (m × n): h(x) = h x, H = h (eq. 5)."""

    def __init__(self, matrix, angular=None):
        self.matrix = np.atleast_2d(np.asarray(matrix, float))
        self.angular = None if angular is None else np.asarray(angular, bool)

    def evaluate(self, states):
        x = np.atleast_2d(np.asarray(states, float))
        H = np.broadcast_to(self.matrix, (len(x), *self.matrix.shape)).copy()
        return x @ self.matrix.T, H

"""The tracker's adaptive augmented filters of spec 002 R14: ``ct-omega-adaptive`` and ``ca-accel-adaptive``.

Registered batched filters (:class:`~skytrack.filters.base.BatchFilter`) that estimate an aircraft's
unknown turn rate (R2) or constant acceleration (R3) as random-walk parameters appended to the
tracker's constant-velocity state, with the disturbance covariance V_w estimated on line by R12
(steps A1-A8 of R11; :mod:`skytrack.filters.adaptive_augmented` is the same algorithm for a bank
of spec 002's own state order).

State layout (one row per track; the tracker's per-axis CV layout first, so that every tracker
part reading positions and velocities by ``axis * 2`` works unchanged)::

    [x, vx, y, vy(, z, vz) | parameters (p) | V̄ (p*p, row-major) | n_j | skipped | psi | NIS]

``ct-omega``: p = 1 (omega, rad/s, counter-clockwise > 0) turns the horizontal axes (R2's phi and
analytic F); z is constant velocity.  ``ca-accel``: p = ndim accelerations (R3).
The estimator's memory (the raw fading mean V̄, its count n_j, the count of steps whose
adaptation was skipped, and the manoeuvre switch with its smoothed NIS) rides in the state row
as components with zero covariance: every bank operation (take, put, the compiled compaction)
carries it, the transition keeps it, and a
measurement cannot change it through the gain (its rows of P are zero).  ``estimate()`` is the
CV part (what gating and output read); :meth:`AdaptiveTrackingFilter.parameters` gives the
parameters and V̂_w.

The protocol's steps split R11 as follows (``timing="same"``):

* ``predict``: A1 (x̂(k|k−1) = phi, F at x̂(k−1|k−1), G = F h_aᵀ), A3's A_k = F P Fᵀ + Q_dep(|T|) and
  V_x = A_k + G V̂_w Gᵀ with V̂_w = Π(V̄) from the memory (what the gate and the score use);
* ``innovate``: the Kalman innovation of that prediction (positions, optionally range rate);
* ``update``: A2-A8 on the chosen pairs: C_k = H A_k Hᵀ + V_η, S_k = H G, A4's verdict (R5),
  the innovation-weighted estimator (A5.1-A5.3), fading memory (A5.4), Π (A5.5), the prior
  covariance with the new V̂_w (A6), the gain by Cholesky (A7) and the Joseph update (A8).

Presets (R14): ``ct-omega-adaptive`` V_w0 = (1e-4 rad/s)², σ_min = 1e-5 rad/s, σ_max = 2°/s per step,
λ = 0.8, Q_dep white acceleration q_a = 1 m²/s³ per axis; ``ca-accel-adaptive`` V_w0 = (0.1 m/s²)²,
σ_min = 1e-3 m/s², σ_max = 5 m/s² per step, λ = 0.8, Q_dep = 0.

skytrack's additions for real radars (each a preset option; docs/methods/adaptive-identification.md
gives the measurements behind them):

* the manoeuvre switch psi of spec 000 S3 on Q_dep (PSD ``manoeuvre_q`` while the smoothed NIS is
  high, and the tracker's manoeuvre gate), as the default ``kalman-psi`` filter has it;
* a precision gate: a step adapts only when its one-step precision (L_kC_kL_kᵀ)_ii is at most
  (``precision_fraction`` σ_max)²; an imprecise step folds the prior V_w0 into the memory in place
  of its Q_k (its noise, clipped by Π, would otherwise raise V̂_w with nothing to bring it back);
* the parameters' prior at a track's start (the spec is silent): ω ~ N(0, (0.2°/s)²),
  a ~ N(0, (3 m/s²)²).

This module is the numpy reference; the tracker's compiled stage
(:mod:`skytrack.tracker.adaptive_stage_kernel`, on :mod:`skytrack.filters.adaptive_tracking_kernels`)
is tested equal to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.filters.adaptive_augmented import estimator_gain, project_covariance
from skytrack.filters.adaptive_tracking_kernels import predict_rows, settings_vector
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.identifiability_step import NOT_IDENTIFIABLE, step_verdicts
from skytrack.filters.registry import register_filter
from skytrack.core import linalg
from skytrack.models.augmented import ct_coefficients
from skytrack.models.motion import MotionModel

#: model codes shared with the compiled kernels
CT_OMEGA, CA_ACCEL = 0, 1
MODEL_CODES = {"ct-omega": CT_OMEGA, "ca-accel": CA_ACCEL}


@dataclass(frozen=True)
class AdaptivePreset:
    """The settings of one tracker preset (R14); variances per step in parameter units squared."""

    model: str
    V_w0: float  # prior V_w (each parameter), variance per step
    sigma_min: float
    sigma_max: float
    forgetting: float
    n0: float
    q_a: float  # Q_dep white-acceleration PSD per axis (m^2/s^3)
    prior_sigma: float  # a new track's parameter standard deviation
    manoeuvre_q: float = 1500.0  # Q_dep's PSD while psi = 1 (q_a: no switch)
    precision_fraction: float = 0.25  # adapt only where the one-step precision is <= this x sigma_max
    manoeuvre_on: float = 3.0
    manoeuvre_off: float = 1.2
    manoeuvre_memory: float = 0.5

    def __post_init__(self):
        if self.model not in MODEL_CODES:
            raise ValueError(f"adaptive preset: model must be one of {sorted(MODEL_CODES)}, got {self.model!r}")
        for name in ("V_w0", "sigma_min", "sigma_max", "prior_sigma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"adaptive preset: {name} must be finite and > 0, got {value}")
        if self.sigma_max < self.sigma_min:
            raise ValueError("adaptive preset: sigma_max must be at least sigma_min")
        if not 0.0 <= self.forgetting <= 1.0:
            raise ValueError(f"adaptive preset: forgetting factor must lie in [0, 1], got {self.forgetting}")
        if not (math.isfinite(self.q_a) and self.q_a >= 0):
            raise ValueError(f"adaptive preset: q_a must be finite and >= 0, got {self.q_a}")
        if not (math.isfinite(self.n0) and self.n0 >= 0):
            raise ValueError(f"adaptive preset: n0 must be finite and >= 0, got {self.n0}")
        if not (math.isfinite(self.manoeuvre_q) and self.manoeuvre_q >= self.q_a):
            raise ValueError(f"adaptive preset: manoeuvre_q must be finite and >= q_a, got {self.manoeuvre_q}")
        if not 0.0 < self.manoeuvre_off <= self.manoeuvre_on:
            raise ValueError("adaptive preset: need 0 < manoeuvre_off <= manoeuvre_on")
        if not self.precision_fraction > 0:
            raise ValueError("adaptive preset: precision_fraction must be > 0 (inf: no gate), "
                             f"got {self.precision_fraction}")
        if not 0.0 <= self.manoeuvre_memory < 1.0:
            raise ValueError(f"adaptive preset: manoeuvre_memory must be in [0, 1), got {self.manoeuvre_memory}")


PRESETS = {
    "ct-omega-adaptive": AdaptivePreset("ct-omega", V_w0=1e-4**2, sigma_min=1e-5, sigma_max=math.radians(2.0),
                                        forgetting=0.8, n0=1.0, q_a=1.0, prior_sigma=math.radians(0.2)),
    "ca-accel-adaptive": AdaptivePreset("ca-accel", V_w0=0.1**2, sigma_min=1e-3, sigma_max=5.0,
                                        forgetting=0.8, n0=1.0, q_a=0.0, prior_sigma=3.0),
}


#: row width 2 ndim + p + p^2 + 4 -> CV components 2 ndim, for every layout of the presets
#: (ndim 1-3; p = 1 for ct-omega, p = ndim for ca-accel): the widths are all different
MOTION_DIM_OF_WIDTH = {2 * ndim + p + p * p + 4: 2 * ndim for ndim in (1, 2, 3) for p in {1, ndim}}


@dataclass
class AdaptiveTrackState(GaussianState):
    """Rows ``[motion | parameters | memory]`` (module docstring); ``estimate()`` is the motion part."""

    def estimate(self) -> GaussianState:
        n = MOTION_DIM_OF_WIDTH[self.x.shape[1]]
        return GaussianState(self.x[:, :n], self.P[:, :n, :n])

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """The motion part of ``rows`` becomes ``(x, P)``; parameters and memory keep their values
        (:meth:`AdaptiveTrackingFilter.restart` resets them)."""
        n = x.shape[1]
        self.x[rows, :n] = x
        self.P[rows, :n, :] = 0.0
        self.P[rows, :, :n] = 0.0
        self.P[rows, :n, :n] = P


@dataclass
class AdaptivePrediction(AdaptiveTrackState):
    """A prediction: the state with V_x in P, plus A_k (P without G V̂_w Gᵀ) and G for the update."""

    A: np.ndarray = None
    G: np.ndarray = None


class AdaptiveTrackingFilter(BatchFilter):
    """R14 presets on the tracker's CV layout (order 2), numpy reference of the compiled stage."""

    state_type = AdaptiveTrackState
    capabilities = Capabilities(zero_dt_identity=False)

    def __init__(self, motion: MotionModel, preset: AdaptivePreset, kind: str, compiled: bool = True) -> None:
        if motion.order != 2:
            raise ValueError(f"{kind} needs the constant-velocity layout (order 2, --model cv), "
                             f"got a model of order {motion.order}")
        self.kind = kind
        self.motion = motion
        self.preset = preset
        self.compiled = bool(compiled)
        self.ndim = motion.ndim
        self.code = MODEL_CODES[preset.model]
        if self.code == CT_OMEGA and self.ndim < 2:
            raise ValueError(f"{kind} turns the horizontal plane: it needs 2 or 3 axes")
        self.n_motion = 2 * self.ndim
        self.p = 1 if self.code == CT_OMEGA else self.ndim
        self.n_aug = self.n_motion + self.p
        self.n_total = self.n_aug + self.p * self.p + 4
        self.parameter_names = ("omega",) if self.code == CT_OMEGA else tuple(f"a{axis}" for axis in "xyz"[: self.ndim])
        self.sigma_min = np.full(self.p, preset.sigma_min)
        self.sigma_max = np.full(self.p, preset.sigma_max)
        self.settings = settings_vector(self.code, preset)
        # ca-accel's accelerations are random walks: no CV-layout motion model simulates the truth it is consistent on
        self.capabilities = Capabilities(zero_dt_identity=False, matched_consistent=self.code == CT_OMEGA)

    @property
    def state_dim(self) -> int:
        return self.n_motion

    # ---------------------------------------------------------------- layout
    @property
    def memory_slice(self) -> slice:
        return slice(self.n_aug, self.n_aug + self.p * self.p)

    @property
    def count_index(self) -> int:
        return self.n_aug + self.p * self.p

    @property
    def skipped_index(self) -> int:
        return self.count_index + 1

    @property
    def psi_index(self) -> int:
        return self.count_index + 2

    @property
    def nis_index(self) -> int:
        return self.count_index + 3

    @property
    def supports_manoeuvre_gate(self) -> bool:
        """A quiet track that finds no plot may retry with the manoeuvre noise (as ``kalman-psi``)."""
        return self.preset.manoeuvre_q > self.preset.q_a

    def in_manoeuvre(self, state: AdaptiveTrackState) -> np.ndarray:
        return state.x[:, self.psi_index] > 0.5

    def initiate(self, x: np.ndarray, P: np.ndarray) -> AdaptiveTrackState:
        """Rows from CV-layout ``x[N, 2 ndim]``, ``P``; parameters and memory at their priors."""
        x = np.asarray(x, float)
        count = len(x)
        if x.shape[1] != self.n_motion:
            raise ValueError(f"{self.kind}: initiate expects {self.n_motion} CV components, got {x.shape[1]}")
        state = AdaptiveTrackState(np.zeros((count, self.n_total)), np.zeros((count, self.n_total, self.n_total)))
        state.x[:, : self.n_motion] = x
        state.P[:, : self.n_motion, : self.n_motion] = P
        self.restart(state, np.arange(count))
        return state

    def restart(self, state: AdaptiveTrackState, rows) -> None:
        """Parameters, their covariance and the estimator's memory of ``rows`` back to the prior."""
        a = slice(self.n_motion, self.n_aug)
        state.x[rows, a] = 0.0
        state.P[rows, a, :] = 0.0
        state.P[rows, :, a] = 0.0
        for i in range(self.n_motion, self.n_aug):
            state.P[rows, i, i] = self.preset.prior_sigma**2
        state.x[rows, self.memory_slice] = (self.preset.V_w0 * np.eye(self.p)).reshape(-1)
        state.x[rows, self.count_index] = self.preset.n0
        state.x[rows, self.skipped_index] = 0.0
        state.x[rows, self.psi_index] = 0.0
        state.x[rows, self.nis_index] = 1.0

    def parameters(self, state: AdaptiveTrackState) -> tuple[np.ndarray, np.ndarray]:
        """Parameter estimates ``[N, p]`` and the current V̂_w = Π(V̄) ``[N, p, p]``."""
        return state.x[:, self.n_motion:self.n_aug].copy(), self._projected(state.x)

    def _memory(self, x: np.ndarray) -> np.ndarray:
        return x[:, self.memory_slice].reshape(-1, self.p, self.p)

    def _projected(self, x: np.ndarray) -> np.ndarray:
        return project_covariance(self._memory(x), self.sigma_min, self.sigma_max)

    # ---------------------------------------------------------------- A1, A3, A6 (prior V̂_w)
    def transition(self, x_aug: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(phi(x, T), F)`` of the augmented part ``[K, n_aug]``: R2 on the horizontal axes (z CV)
        or R3 on every axis."""
        count = len(x_aug)
        n, nm = self.n_aug, self.n_motion
        F = np.broadcast_to(np.eye(n), (count, n, n)).copy()
        if self.code == CT_OMEGA:
            vx, vy, w = x_aug[:, 1], x_aug[:, 3], x_aug[:, nm]
            s, c, ds, dc, sin, cos = ct_coefficients(w, T)
            F[:, 0, 1], F[:, 0, 3], F[:, 0, nm] = s, -c, ds * vx - dc * vy
            F[:, 2, 1], F[:, 2, 3], F[:, 2, nm] = c, s, dc * vx + ds * vy
            F[:, 1, 1], F[:, 1, 3], F[:, 1, nm] = cos, -sin, -T * (sin * vx + cos * vy)
            F[:, 3, 1], F[:, 3, 3], F[:, 3, nm] = sin, cos, T * (cos * vx - sin * vy)
            if self.ndim == 3:
                F[:, 4, 5] = T
            x_new = x_aug.copy()
            x_new[:, 0] = x_aug[:, 0] + s * vx - c * vy
            x_new[:, 2] = x_aug[:, 2] + c * vx + s * vy
            x_new[:, 1] = cos * vx - sin * vy
            x_new[:, 3] = sin * vx + cos * vy
            if self.ndim == 3:
                x_new[:, 4] = x_aug[:, 4] + T * x_aug[:, 5]
            return x_new, F
        for axis in range(self.ndim):
            F[:, 2 * axis, 2 * axis + 1] = T
            F[:, 2 * axis, nm + axis] = T * T / 2.0
            F[:, 2 * axis + 1, nm + axis] = T
        return np.einsum("kij,kj->ki", F, x_aug), F

    def dependent_noise(self, T: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Q_dep(|T|): white acceleration of PSD ``q`` (per row) on every axis."""
        t = np.abs(T)
        Q = np.zeros((len(t), self.n_aug, self.n_aug))
        for axis in range(self.ndim):
            p, v = 2 * axis, 2 * axis + 1
            Q[:, p, p] = q * t**3 / 3.0
            Q[:, p, v] = Q[:, v, p] = q * t * t / 2.0
            Q[:, v, v] = q * t
        return Q

    def predict(self, state: AdaptiveTrackState, dt, context: dict | None = None) -> AdaptivePrediction:
        T = np.broadcast_to(self.transition_dt(dt), (len(state),)).astype(float)
        n = self.n_aug
        forced = bool(context and context.get("manoeuvre"))
        switched = np.full(len(state), True) if forced else state.x[:, self.psi_index] > 0.5
        if self.compiled:
            return self._predict_compiled(state, T, switched, forced)
        x_pred, F = self.transition(state.x[:, :n], T)
        q = np.where(switched, self.preset.manoeuvre_q, self.preset.q_a)
        A = linalg.symmetrize(F @ state.P[:, :n, :n] @ np.swapaxes(F, -1, -2) + self.dependent_noise(T, q))
        G = F[:, :, self.n_motion:n]
        Vx = linalg.symmetrize(A + G @ self._projected(state.x) @ np.swapaxes(G, -1, -2))
        x = state.x.copy()
        x[:, :n] = x_pred
        P = np.zeros_like(state.P)
        P[:, :n, :n] = Vx
        if forced:
            x[:, self.psi_index] = 2.0  # the manoeuvre gate's prediction (psi forced on by the update)
        return AdaptivePrediction(x, P, A, G)

    def _predict_compiled(self, state: AdaptiveTrackState, T, switched, forced: bool) -> AdaptivePrediction:
        """:meth:`predict` by the compiled row kernel
        (:func:`~skytrack.filters.adaptive_tracking_kernels.predict_rows`)."""
        count, n = len(state), self.n_aug
        x = np.empty_like(state.x)
        P = np.zeros_like(state.P)
        A = np.empty((count, n, n))
        G = np.empty((count, n, self.p))
        P_aug = np.empty((count, n, n))
        predict_rows(self.code, np.ascontiguousarray(state.x), np.ascontiguousarray(state.P), np.ascontiguousarray(T),
                     switched, self.ndim, self.p, self.settings, x, P_aug, A, G)
        P[:, :n, :n] = P_aug
        if forced:
            x[:, self.psi_index] = 2.0
        return AdaptivePrediction(x, P, A, G)

    # ---------------------------------------------------------------- innovation (gate, score)
    def innovate(self, state: AdaptivePrediction, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        n = self.n_aug
        H_motion, R, nu, m = measurement_terms(state.x[:, : self.n_motion], z, model, context)
        H = np.zeros((len(nu), H_motion.shape[1], n))
        H[:, :, : self.n_motion] = H_motion
        S = linalg.sandwich(H, state.P[:, :n, :n], R)
        L = linalg.cholesky(S)
        d2 = linalg.mahalanobis_chol(nu, L)
        logdet = linalg.logdet_chol(L)
        return Innovation(nu, S, L, d2, logdet, linalg.gaussian_loglik(d2, logdet, m), m, H, R, state)

    # ---------------------------------------------------------------- A2-A8
    def update(self, state: AdaptivePrediction, z: np.ndarray, innovation: Innovation):
        predicted = innovation.predicted
        n, p = self.n_aug, self.p
        H, R, nu = innovation.H, innovation.R, innovation.nu
        A, G = predicted.A, predicted.G
        Ht = np.swapaxes(H, -1, -2)
        C = H @ A @ Ht + R
        S = H @ G
        verdict, _, _ = step_verdicts(H, G, R)
        adapted = verdict != NOT_IDENTIFIABLE
        x = predicted.x.copy()
        memory = self._memory(x).copy()
        count = x[:, self.count_index].copy()
        if adapted.any():
            rows = np.flatnonzero(adapted)
            L_est, LCL = estimator_gain(S[rows], C[rows], "innovation")
            if math.isfinite(self.preset.precision_fraction):
                limit = (self.preset.precision_fraction * self.preset.sigma_max) ** 2
                precise = np.all(np.einsum("kpp->kp", LCL) <= limit, axis=1)
                adapted[rows[~precise]] = False
                # an imprecise step cannot tell V_w: it folds in the prior V_w0 in place of its Q_k, so
                # that a memory raised by a few noisy steps returns to the prior instead of staying there
                vague = rows[~precise]
                count[vague] = self.preset.forgetting * count[vague] + 1.0
                memory[vague] += (self.preset.V_w0 * np.eye(p) - memory[vague]) / count[vague, None, None]
                rows, L_est, LCL = rows[precise], L_est[precise], LCL[precise]
            w = np.einsum("kpm,km->kp", L_est, nu[rows])
            Q = np.einsum("kp,kq->kpq", w, w) - LCL
            count[rows] = self.preset.forgetting * count[rows] + 1.0
            memory[rows] = memory[rows] + (Q - memory[rows]) / count[rows, None, None]
        x[:, self.memory_slice] = memory.reshape(len(x), p * p)
        x[:, self.count_index] = count
        x[:, self.skipped_index] += ~adapted
        self._switch(x, innovation.d2 / innovation.m)
        V_w = project_covariance(memory, self.sigma_min, self.sigma_max)
        Vx = linalg.symmetrize(A + G @ V_w @ np.swapaxes(G, -1, -2))
        innovation_cov = linalg.sandwich(H, Vx, R)
        chol = linalg.cholesky(innovation_cov)
        gain = np.swapaxes(linalg.cho_solve(chol, H @ Vx), -1, -2)
        x[:, :n] = x[:, :n] + linalg.matvec(gain, nu)
        I_KH = np.eye(n) - gain @ H
        P = np.zeros_like(predicted.P)
        P[:, :n, :n] = linalg.sandwich(I_KH, Vx, linalg.sandwich(gain, R))
        if self.recorder.active:
            self.recorder.record("adaptation", np.arange(len(x)), adapted=adapted, V_w=V_w,
                                 parameters=x[:, self.n_motion:n].copy(), psi=x[:, self.psi_index].copy())
        return AdaptiveTrackState(x, P), UpdateStats(innovation.d2 / innovation.m, {"adapted": adapted})

    def _switch(self, x: np.ndarray, nis: np.ndarray) -> None:
        """Spec 000 S3's psi on Q_dep from the gate's NIS per component (:mod:`skytrack.filters.maneuver`);
        a forced prediction (psi slot 2) sets psi and lifts the smoothed NIS to at least ``on``."""
        preset = self.preset
        forced = x[:, self.psi_index] > 1.5
        smoothed = preset.manoeuvre_memory * x[:, self.nis_index] + (1.0 - preset.manoeuvre_memory) * nis
        psi = np.where(x[:, self.psi_index] > 0.5, smoothed > preset.manoeuvre_off, smoothed > preset.manoeuvre_on)
        x[:, self.psi_index] = np.where(forced | psi, 1.0, 0.0)
        x[:, self.nis_index] = np.where(forced, np.maximum(smoothed, preset.manoeuvre_on), smoothed)


def _preset_factory(kind: str):
    def factory(motion: MotionModel, compiled: bool = True, **overrides) -> AdaptiveTrackingFilter:
        base = PRESETS[kind]
        unknown = sorted(set(overrides) - set(AdaptivePreset.__dataclass_fields__) - {"model"})
        if unknown or "model" in overrides:
            raise ValueError(f"{kind}: unknown option(s) {unknown or ['model']}; "
                             f"options: {sorted(set(AdaptivePreset.__dataclass_fields__) - {'model'})}")
        preset = AdaptivePreset(**{**base.__dict__, **{k: float(v) for k, v in overrides.items()}})
        return AdaptiveTrackingFilter(motion, preset, kind, compiled=compiled)
    factory.__name__ = kind.replace("-", "_")
    return factory


for _kind in PRESETS:
    register_filter(_kind)(_preset_factory(_kind))

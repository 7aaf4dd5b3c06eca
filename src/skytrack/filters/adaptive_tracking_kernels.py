"""Compiled per-row steps of the tracker's adaptive augmented filters (spec 002 R2, R3, R11 A1-A8, R12, R14).

The numba counterparts of :class:`skytrack.filters.adaptive_tracking.AdaptiveTrackingFilter`'s
numpy steps, for one track row in the layout documented there (``[x, vx, y, vy(, z, vz) |
parameters | V̄ | n_j | skipped | psi | smoothed NIS]``), used by the tracker's compiled stage
(:mod:`skytrack.tracker.adaptive_stage_kernel`):

* :func:`predict_row`: phi and F of R2 (``code`` 0, turn rate; z constant velocity) or R3 (``code`` 1,
  accelerations), A_k = F P Fᵀ + Q_dep(|T|), G = F h_aᵀ and V_x = A_k + G V̂_w Gᵀ;
* :func:`project_row`: A5.5's Π for a scalar floor and ceiling (the presets give every parameter the
  same σ_min, σ_max), clip for p = 1, eigenvalue clamp otherwise;
* :func:`adapt_row`: A4 (R5's zero-influence test and κ on S_k = H G whitened by V_η) and A5.1-A5.4
  with the innovation weighting (W = C⁻¹), the precision gate (an imprecise step folds in the prior
  V_w0) and the fading memory, in place.

The settings travel as one float vector (:func:`settings_vector`, indices ``S_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from skytrack.filters.identifiability_step import TAU_REL, TAU_ZERO
from skytrack.filters.kernels import _cholesky_row

S_CODE, S_QA, S_MQ, S_SMIN, S_SMAX, S_FORGET, S_PRECISION, S_ON, S_OFF, S_MEMORY, S_VW0, S_N0, S_PRIOR = range(13)
SETTINGS_SIZE = 13
#: |omega T| below which the R2 series is used (models.augmented.CT_SERIES_BELOW)
CT_SERIES = 1e-3


def settings_vector(code: int, preset) -> np.ndarray:
    """The kernels' settings from an :class:`~skytrack.filters.adaptive_tracking.AdaptivePreset`."""
    vector = np.zeros(SETTINGS_SIZE)
    vector[S_CODE] = code
    vector[S_QA] = preset.q_a
    vector[S_MQ] = preset.manoeuvre_q
    vector[S_SMIN] = preset.sigma_min
    vector[S_SMAX] = preset.sigma_max
    vector[S_FORGET] = preset.forgetting
    limit = preset.precision_fraction * preset.sigma_max
    vector[S_PRECISION] = limit * limit if math.isfinite(limit) else np.inf
    vector[S_ON] = preset.manoeuvre_on
    vector[S_OFF] = preset.manoeuvre_off
    vector[S_MEMORY] = preset.manoeuvre_memory
    vector[S_VW0] = preset.V_w0
    vector[S_N0] = preset.n0
    vector[S_PRIOR] = preset.prior_sigma
    return vector


@njit(cache=True, nogil=True, error_model="numpy")
def project_row(memory, p, sigma_min, sigma_max, out):
    """Π of A5.5 for D = σ I: eigenvalues of V̄/σ_min² floored at 1, of the result/σ_max² capped at 1."""
    if p == 1:
        out[0, 0] = min(max(memory[0, 0], sigma_min * sigma_min), sigma_max * sigma_max)
        return
    sym = 0.5 * (memory + memory.T)
    values, vectors = np.linalg.eigh(sym)
    low, high = sigma_min * sigma_min, sigma_max * sigma_max
    for i in range(p):
        values[i] = min(max(values[i], low), high)
    for i in range(p):
        for j in range(p):
            acc = 0.0
            for l in range(p):
                acc += vectors[i, l] * values[l] * vectors[j, l]
            out[i, j] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def _ct_coefficients(w, T):
    """``(s, c, s', c', sin wT, cos wT)`` of R2 (series for |wT| < 1e-3)."""
    wt = w * T
    sn, cs = np.sin(wt), np.cos(wt)
    if abs(wt) < CT_SERIES:
        s = T * (1.0 - wt * wt / 6.0 + wt**4 / 120.0)
        c = T * (wt / 2.0 - wt**3 / 24.0)
        ds = -w * T**3 / 3.0 + w**3 * T**5 / 30.0
        dc = T * T / 2.0 - w * w * T**4 / 8.0
    else:
        s = sn / w
        c = (1.0 - cs) / w
        ds = (wt * cs - sn) / (w * w)
        dc = (wt * sn - 1.0 + cs) / (w * w)
    return s, c, ds, dc, sn, cs


@njit(cache=True, nogil=True, error_model="numpy")
def predict_row(code, x, P, T, ndim, p, q, vw, x_out, F, A, G, Vx, FP, position_only):
    """A1, A3, A6 for one row: ``x_out`` (every slot; memory copied), F, A_k, G and V_x (n_aug blocks);
    ``FP`` is scratch.  With ``position_only`` only the position rows and columns of A and V_x are
    formed (all a gate needs)."""
    nm = 2 * ndim
    n = nm + p
    for i in range(n):
        for j in range(n):
            F[i, j] = 0.0
        F[i, i] = 1.0
    for i in range(len(x)):
        x_out[i] = x[i]
    if code == 0:
        vx, vy, w = x[1], x[3], x[nm]
        s, c, ds, dc, sn, cs = _ct_coefficients(w, T)
        F[0, 1], F[0, 3], F[0, nm] = s, -c, ds * vx - dc * vy
        F[2, 1], F[2, 3], F[2, nm] = c, s, dc * vx + ds * vy
        F[1, 1], F[1, 3], F[1, nm] = cs, -sn, -T * (sn * vx + cs * vy)
        F[3, 1], F[3, 3], F[3, nm] = sn, cs, T * (cs * vx - sn * vy)
        x_out[0] = x[0] + s * vx - c * vy
        x_out[2] = x[2] + c * vx + s * vy
        x_out[1] = cs * vx - sn * vy
        x_out[3] = sn * vx + cs * vy
        if ndim == 3:
            F[4, 5] = T
            x_out[4] = x[4] + T * x[5]
    else:
        for a in range(ndim):
            F[2 * a, 2 * a + 1] = T
            F[2 * a, nm + a] = 0.5 * T * T
            F[2 * a + 1, nm + a] = T
        for a in range(ndim):
            x_out[2 * a] = x[2 * a] + T * x[2 * a + 1] + 0.5 * T * T * x[nm + a]
            x_out[2 * a + 1] = x[2 * a + 1] + T * x[nm + a]
    for i in range(n):
        for j in range(p):
            G[i, j] = F[i, nm + j]
    # A = F P F^T + Q_dep(|T|) and V_x, on every row or (position_only) on the position rows only
    stride, count = (2, ndim) if position_only else (1, n)
    for r in range(count):
        i = stride * r
        for j in range(n):
            acc = 0.0
            for l in range(n):
                acc += F[i, l] * P[l, j]
            FP[i, j] = acc
    for r in range(count):
        i = stride * r
        for c in range(r, count):
            j = stride * c
            acc = 0.0
            for l in range(n):
                acc += FP[i, l] * F[j, l]
            A[i, j] = acc
            A[j, i] = acc
    t = abs(T)
    for a in range(ndim):
        A[2 * a, 2 * a] += q * t**3 / 3.0
        if not position_only:
            A[2 * a, 2 * a + 1] += q * t * t / 2.0
            A[2 * a + 1, 2 * a] += q * t * t / 2.0
            A[2 * a + 1, 2 * a + 1] += q * t
    prior_covariance(A, G, vw, stride, count, p, Vx)


@njit(cache=True, nogil=True, error_model="numpy")
def predict_rows(code, x, P, T, switched, ndim, p, settings, x_out, P_out, A_out, G_out):
    """:meth:`AdaptiveTrackingFilter.predict` for a batch: every row with its own V̂_w and Q_dep PSD
    (the manoeuvre PSD where ``switched``), into the output arrays (P_out's memory rows stay zero)."""
    n = 2 * ndim + p
    FP = np.empty((n, n))
    F = np.empty((n, n))
    Vx = np.empty((n, n))
    memory = np.empty((p, p))
    vw = np.empty((p, p))
    for k in range(len(x)):
        for i in range(p):
            for j in range(p):
                memory[i, j] = x[k, n + i * p + j]
        project_row(memory, p, settings[S_SMIN], settings[S_SMAX], vw)
        q = settings[S_MQ] if switched[k] else settings[S_QA]
        predict_row(code, x[k], P[k], T[k], ndim, p, q, vw, x_out[k], F, A_out[k], G_out[k], Vx, FP, False)
        for i in range(n):
            for j in range(n):
                P_out[k, i, j] = Vx[i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def prior_covariance(A, G, vw, stride, count, p, Vx):
    """A6: V_x = A + G V̂_w Gᵀ (symmetric by construction) on rows and columns ``0, stride, ..``
    (``count`` of them)."""
    for r in range(count):
        i = stride * r
        for c in range(r, count):
            j = stride * c
            acc = A[i, j]
            for a in range(p):
                for b in range(p):
                    acc += G[i, a] * vw[a, b] * G[j, b]
            Vx[i, j] = acc
            Vx[j, i] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def _forward(L, b, m, out):
    for a in range(m):
        acc = b[a]
        for l in range(a):
            acc -= L[a, l] * out[l]
        out[a] = acc / L[a, a]


@njit(cache=True, nogil=True, error_model="numpy")
def adapt_row(nu, A, G, R, m, ndim, p, settings, memory, state_row, count_index, skipped_index):
    """A4 and A5.1-A5.4 for a position measurement (H selects positions): returns True when the
    memory ``memory`` (p x p, written back to ``state_row``) took this step's Q_k."""
    nm = 2 * ndim
    # S = H G, C = H A H^T + R
    S = np.empty((m, p))
    C = np.empty((m, m))
    for a in range(m):
        for j in range(p):
            S[a, j] = G[2 * a, j]
        for b in range(m):
            C[a, b] = A[2 * a, 2 * b] + R[a, b]
    # A4: R5 on S whitened by V_eta = R
    Lr = np.zeros((m, m))
    if not _cholesky_row(R, Lr):
        return False
    if m == 2:
        half_trace = 0.5 * (R[0, 0] + R[1, 1])
        off = 0.5 * (R[0, 1] + R[1, 0])
        lam_min = half_trace - np.sqrt((0.5 * (R[0, 0] - R[1, 1])) ** 2 + off * off)
    else:
        lam_min = np.linalg.eigvalsh(0.5 * (R + R.T))[0]
    if lam_min <= 0.0:
        return False
    white_norm = 1.0 / np.sqrt(lam_min)  # ||V_eta^-1/2 H||_2 with H selecting positions
    column = np.empty(m)
    out = np.empty(m)
    white = np.empty((m, p))
    for j in range(p):
        for a in range(m):
            column[a] = S[a, j]
        _forward(Lr, column, m, out)
        norm_s = 0.0
        for a in range(m):
            white[a, j] = out[a]
            norm_s += out[a] * out[a]
        norm_s = np.sqrt(norm_s)
        norm_g = 0.0
        for i in range(nm + p):
            norm_g += G[i, j] * G[i, j]
        bound = white_norm * np.sqrt(norm_g)
        rho = norm_s / bound if bound > 0.0 else 0.0
        if rho <= TAU_ZERO:
            return False
        for a in range(m):
            white[a, j] /= norm_s
    if p > 1:
        sigma = np.linalg.svd(white)[1]
        if len(sigma) < p or sigma[0] <= 0.0 or sigma[p - 1] / sigma[0] <= TAU_REL:
            return False
    # A5.1-A5.3 with W = C^-1: Y = Lc^-1 S, u = Lc^-1 nu, N = Y^T Y, w = N^-1 Y^T u, L C L^T = N^-1
    Lc = np.zeros((m, m))
    if not _cholesky_row(C, Lc):
        return False
    Y = np.empty((m, p))
    u = np.empty(m)
    for j in range(p):
        for a in range(m):
            column[a] = S[a, j]
        _forward(Lc, column, m, out)
        for a in range(m):
            Y[a, j] = out[a]
    _forward(Lc, nu, m, u)
    N = np.empty((p, p))
    for i in range(p):
        for j in range(p):
            acc = 0.0
            for a in range(m):
                acc += Y[a, i] * Y[a, j]
            N[i, j] = acc
    if p == 1:
        if N[0, 0] <= 0.0:
            return False
        N_inv = np.empty((1, 1))
        N_inv[0, 0] = 1.0 / N[0, 0]
    else:
        N_inv = np.linalg.inv(N)
    count = settings[S_FORGET] * state_row[count_index] + 1.0
    for i in range(p):
        if N_inv[i, i] > settings[S_PRECISION]:
            # imprecise: the prior V_w0 takes the place of this step's Q_k (adaptive_tracking.update)
            state_row[count_index] = count
            for a in range(p):
                for b in range(p):
                    prior = settings[S_VW0] if a == b else 0.0
                    memory[a, b] += (prior - memory[a, b]) / count
                    state_row[nm + p + a * p + b] = memory[a, b]
            return False
    Ytu = np.empty(p)
    for i in range(p):
        acc = 0.0
        for a in range(m):
            acc += Y[a, i] * u[a]
        Ytu[i] = acc
    w = np.empty(p)
    for i in range(p):
        acc = 0.0
        for j in range(p):
            acc += N_inv[i, j] * Ytu[j]
        w[i] = acc
    # A5.4 fading memory
    state_row[count_index] = count
    for i in range(p):
        for j in range(p):
            q_ij = w[i] * w[j] - N_inv[i, j]
            memory[i, j] += (q_ij - memory[i, j]) / count
            state_row[nm + p + i * p + j] = memory[i, j]
    return True

"""Compiled (numba, cached) steps of the IMM for the tracker's mode models (spec 004 §3.3 O).

The tracker's model sets (:mod:`skytrack.filters.model_sets` with ``noise="continuous"``) hold
constant-velocity and coordinated-turn modes on the layout ``[x, vx, y, vy(, z, vz)]``, both
with continuous white-noise acceleration.  Each mode is described by four numbers
(:func:`mode_table`): ``omega`` (rad/s; 0 is CV), the horizontal PSD ``q``, the vertical PSD
``q_z`` and a kind code, so one compiled loop runs every mode of every row:

* the per-mode prediction ``F x0``, ``F P0 F^T + Q(|dt|)`` on the transition's block structure:
  CV ``[[1, dt], [0, 1]]`` with ``q [[T^3/3, T^2/2], [T^2/2, T]]`` per axis
  (:func:`_predict_cv_mode`); CT(omega) the turn of :mod:`skytrack.models.turn` (exact
  continuous-noise Q, series below ``|wT| < 0.1``) and CV on z (:func:`_predict_ct_mode`).  A
  negative ``dt`` gives ``F(-|dt|)``, the inverse of ``F(|dt|)`` for both kinds (the reference
  :class:`~skytrack.filters.kalman.KalmanFilter` takes the pseudo-inverse, equal to it).
* :func:`imm_predict` — mixing with ``Pi(dt)`` (sojourn times or a fixed matrix, as
  :mod:`skytrack.filters.imm`) then ``x' = F x0``, ``P' = F P0 F^T + Q`` per mode, and the
  predicted probabilities ``c``; a row with ``force`` takes ``c`` one-hot on the manoeuvre mode;
* :func:`imm_predict_matched` — the same, moment-matched, for the rows of an output instant.

They are tested equal to the numpy reference (``IMMFilter(..., compiled=False)``) by the
conformance suite and ``tests/filters/test_spec004_multiple_model.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from skytrack.models.motion import ConstantVelocityAxis, MotionModel, ScaledAxis
from skytrack.models.turn import SMALL_TURN, SMALL_TURN_Q, CoordinatedTurn

KIND_CV = 0
KIND_CT = 1


def mode_table(models) -> np.ndarray | None:
    """``[M, 4]`` rows ``(kind, omega, q, q_z)`` of the modes, or None when a mode is not a
    continuous-noise CV or CT model on ``[x, vx, y, vy(, z, vz)]`` (then the numpy path runs)."""
    rows = []
    ndims = set()
    for model in models:
        row = _mode_row(model)
        if row is None:
            return None
        rows.append(row)
        ndims.add(model.ndim)
    if len(ndims) != 1 or ndims.pop() not in (2, 3):
        return None
    return np.array(rows, dtype=float)


def _mode_row(model):
    if isinstance(model, CoordinatedTurn):
        if model.order != 2 or model.noise != "continuous":
            return None
        vertical = model.sigma_w if model.sigma_w_vertical is None else model.sigma_w_vertical
        return (KIND_CT, model.omega, model.sigma_w**2, vertical**2)
    if isinstance(model, MotionModel) and model.order == 2 and model.identical_axes:
        factor, axis = 1.0, model.axes[0]
        while isinstance(axis, ScaledAxis):
            factor *= axis.factor
            axis = axis.base
        if type(axis) is ConstantVelocityAxis:
            return (KIND_CV, 0.0, axis.q * factor, axis.q * factor)
    return None


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def turn_terms(omega, dt):
    """What CT(omega) over ``dt`` needs, from one sine and one cosine of the half angle:
    ``(sin(wT)/w, (1 - cos wT)/w, cos wT, sin wT)`` of the transition (series below
    ``|wT| < SMALL_TURN``) and ``a = (wT - sin wT)/w^3``, ``b = (1 - cos wT)/w^2`` of its
    continuous-noise Q over ``T = |dt|`` (series below ``|wT| < SMALL_TURN_Q``):
    ``Q_xx = Q_yy = 2 q a``, ``Q_x,vx = Q_y,vy = q b``, ``Q_x,vy = -Q_vx,y = q w a``
    (:mod:`skytrack.models.turn`)."""
    wt = omega * dt
    half_sin = math.sin(0.5 * wt)
    half_cos = math.cos(0.5 * wt)
    sin_wt = 2.0 * half_sin * half_cos
    cos_wt = 1.0 - 2.0 * half_sin * half_sin
    if abs(wt) < SMALL_TURN:
        s_over = dt
        one_minus_c_over = omega * dt * dt / 2.0
    else:
        s_over = sin_wt / omega
        one_minus_c_over = 2.0 * half_sin * half_sin / omega
    step = abs(dt)
    x2 = wt * wt
    if abs(wt) < SMALL_TURN_Q:
        a_ = step**3 * (1 / 6 - x2 * (1 / 120 - x2 * (1 / 5040 - x2 / 362880)))
        b_ = step * step * (1 / 2 - x2 * (1 / 24 - x2 * (1 / 720 - x2 / 40320)))
    else:
        # (|w|T - sin(|w|T)) / |w|^3 with sin(|wT|) = sign(wT) sin(wT)
        a_ = (abs(wt) - (sin_wt if wt >= 0.0 else -sin_wt)) / abs(omega) ** 3
        b_ = 2.0 * half_sin * half_sin / (omega * omega)
    return s_over, one_minus_c_over, cos_wt, sin_wt, a_, b_


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _turn_apply(v, out, s_over, omc_over, c, s, dt, ndim):
    """``out = F v`` for the CT transition (horizontal turn, CV on z): 13 products, no zeros visited."""
    out[0] = v[0] + s_over * v[1] - omc_over * v[3]
    out[1] = c * v[1] - s * v[3]
    out[2] = omc_over * v[1] + v[2] + s_over * v[3]
    out[3] = s * v[1] + c * v[3]
    if ndim == 3:
        out[4] = v[4] + dt * v[5]
        out[5] = v[5]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _predict_ct_mode(x0, P0, dt, omega, q, q_z, ndim, x_out, P_out, G, column, result):
    """``F x0``, ``F P0 F^T + Q`` of a CT(omega) mode with the transition's block structure
    (``G = P0 F^T`` row by row, then ``F G`` column by column; ``G``, ``column``, ``result`` scratch)."""
    n = 2 * ndim
    s_over, omc_over, c, s, a_, b_ = turn_terms(omega, dt)
    _turn_apply(x0, x_out, s_over, omc_over, c, s, dt, ndim)
    for b in range(n):
        _turn_apply(P0[b], G[b], s_over, omc_over, c, s, dt, ndim)
    for a in range(n):
        for l in range(n):
            column[l] = G[l, a]
        _turn_apply(column, result, s_over, omc_over, c, s, dt, ndim)
        for b in range(a, n):
            P_out[b, a] = result[b]
    for a in range(n):
        for b in range(a + 1, n):
            P_out[a, b] = P_out[b, a]
    step = abs(dt)
    P_out[0, 0] += 2.0 * q * a_
    P_out[2, 2] += 2.0 * q * a_
    P_out[1, 1] += q * step
    P_out[3, 3] += q * step
    P_out[0, 1] += q * b_
    P_out[1, 0] += q * b_
    P_out[2, 3] += q * b_
    P_out[3, 2] += q * b_
    P_out[0, 3] += q * omega * a_
    P_out[3, 0] += q * omega * a_
    P_out[1, 2] -= q * omega * a_
    P_out[2, 1] -= q * omega * a_
    if ndim == 3:
        P_out[4, 4] += q_z * step * step * step / 3.0
        P_out[4, 5] += q_z * step * step / 2.0
        P_out[5, 4] += q_z * step * step / 2.0
        P_out[5, 5] += q_z * step


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def transition_row(dt, sojourn, fixed, Pi):
    """``Pi(dt)`` into ``Pi`` (M x M): sojourn times (``pi_jj = max(0, 1 - |dt|/tau_j)``, the rest
    even), or the fixed matrix when ``sojourn`` is empty."""
    M = Pi.shape[0]
    if len(sojourn) == 0:
        for i in range(M):
            for j in range(M):
                Pi[i, j] = fixed[i, j]
        return
    for i in range(M):
        stay = max(0.0, 1.0 - abs(dt) / sojourn[i])
        for j in range(M):
            Pi[i, j] = stay if i == j else (1.0 - stay) / (M - 1)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _predict_cv_mode(x0, P0, dt, q, q_z, ndim, x_out, P_out):
    """``F x0``, ``F P0 F^T + Q`` of a CV mode block by block (F = [[1, dt], [0, 1]] per axis)."""
    step = abs(dt)
    for a in range(ndim):
        i = 2 * a
        x_out[i] = x0[i] + dt * x0[i + 1]
        x_out[i + 1] = x0[i + 1]
    for a in range(ndim):
        for b in range(a, ndim):
            i = 2 * a
            j = 2 * b
            r00 = P0[i, j] + dt * P0[i + 1, j]
            r01 = P0[i, j + 1] + dt * P0[i + 1, j + 1]
            r10 = P0[i + 1, j]
            r11 = P0[i + 1, j + 1]
            P_out[i, j] = r00 + r01 * dt
            P_out[i, j + 1] = r01
            P_out[i + 1, j] = r10 + r11 * dt
            P_out[i + 1, j + 1] = r11
            if a == b:
                qa = q_z if a == 2 else q
                P_out[i, j] += qa * step * step * step / 3.0
                P_out[i, j + 1] += qa * step * step / 2.0
                P_out[i + 1, j] += qa * step * step / 2.0
                P_out[i + 1, j + 1] += qa * step
                # the diagonal block's two off-diagonal entries are equal up to rounding
                P_out[i + 1, j] = P_out[i, j + 1] = 0.5 * (P_out[i, j + 1] + P_out[i + 1, j])
            else:
                for u in range(2):
                    for v in range(2):
                        P_out[j + v, i + u] = P_out[i + u, j + v]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def predict_mode_position(mode, x0, P0, dt, ndim, x_out, P_pos, G):
    """``F x0`` and the position block ``P_pos[ndim, ndim]`` of ``F P0 F^T + Q`` of one mode, with
    the arithmetic of :func:`predict_mode` (the gate and the search need no more; ``G`` scratch)."""
    n = 2 * ndim
    step = abs(dt)
    if mode[0] == KIND_CV:
        for a in range(ndim):
            i = 2 * a
            x_out[i] = x0[i] + dt * x0[i + 1]
            x_out[i + 1] = x0[i + 1]
            for b in range(a, ndim):
                j = 2 * b
                r00 = P0[i, j] + dt * P0[i + 1, j]
                r01 = P0[i, j + 1] + dt * P0[i + 1, j + 1]
                P_pos[a, b] = r00 + r01 * dt
                if a == b:
                    qa = mode[3] if a == 2 else mode[2]
                    P_pos[a, b] += qa * step * step * step / 3.0
                P_pos[b, a] = P_pos[a, b]
        return
    omega, q = mode[1], mode[2]
    s_over, omc_over, c, s, a_, _ = turn_terms(omega, dt)
    _turn_apply(x0, x_out, s_over, omc_over, c, s, dt, ndim)
    # G[l, a] = (P0 F^T)[l, 2a] (the position rows of F, as _turn_apply writes them), then
    # P_pos[b, a] = (F G)[2b, a] for b >= a: the arithmetic of _predict_ct_mode
    for l in range(n):
        v = P0[l]
        G[l, 0] = v[0] + s_over * v[1] - omc_over * v[3]
        G[l, 1] = omc_over * v[1] + v[2] + s_over * v[3]
        if ndim == 3:
            G[l, 2] = v[4] + dt * v[5]
    for a in range(ndim):
        P_pos[0, a] = P_pos[a, 0] = G[0, a] + s_over * G[1, a] - omc_over * G[3, a]
    P_pos[1, 1] = omc_over * G[1, 1] + G[2, 1] + s_over * G[3, 1]
    if ndim == 3:
        P_pos[1, 2] = P_pos[2, 1] = omc_over * G[1, 2] + G[2, 2] + s_over * G[3, 2]
        P_pos[2, 2] = G[4, 2] + dt * G[5, 2]
    P_pos[0, 0] += 2.0 * q * a_
    P_pos[1, 1] += 2.0 * q * a_
    if ndim == 3:
        P_pos[2, 2] += mode[3] * step * step * step / 3.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def predict_mode(mode, x0, P0, dt, ndim, x_out, P_out, G, column, result):
    """``F x0``, ``F P0 F^T + Q(|dt|)`` of one mode (a row of :func:`mode_table`); ``G``,
    ``column``, ``result`` scratch."""
    if mode[0] == KIND_CV:
        _predict_cv_mode(x0, P0, dt, mode[2], mode[3], ndim, x_out, P_out)
    else:
        _predict_ct_mode(x0, P0, dt, mode[1], mode[2], mode[3], ndim, x_out, P_out, G, column, result)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def mix_scratch(M, n):
    """The scratch arrays of :func:`mix_row` and :func:`mix_predict_row`, allocated once per call of a kernel."""
    return (np.empty((M, M)), np.empty((M, M)), np.empty((n, n)), np.empty(n), np.empty(n), np.empty((M, n, n)),
            np.empty(n), np.empty((M, n)), np.empty((M, n, n)))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def mix_row(x, P, mu, dt, sojourn, fixed, forced_mode, x0, P0, c_out, scratch):
    """Mixing of one row: ``x[M, n]``, ``P[M, n, n]``, ``mu[M]`` over ``Pi(dt)`` into the mixed
    ``x0[M, n]``, ``P0[M, n, n]`` and the predicted probabilities ``c_out`` (one-hot on
    ``forced_mode`` when it is >= 0); ``scratch`` is :func:`mix_scratch`'s."""
    Pi, weight, _, _, _, S, e, _, _ = scratch
    M, n = x.shape
    transition_row(dt, sojourn, fixed, Pi)
    total = 0.0
    for j in range(M):
        acc = 0.0
        for i in range(M):
            acc += Pi[i, j] * mu[i]
        c_out[j] = acc
        total += acc
    for j in range(M):
        for i in range(M):
            weight[i, j] = Pi[i, j] * mu[i] / max(c_out[j], 1e-300)
    for j in range(M):
        c_out[j] /= total
    # P0_j = sum_i w_ij (P_i + d_i d_i^T) - e_j e_j^T with d_i, e_j taken from mode 0's mean (the
    # same algebra as sum_i w_ij (P_i + (x_i - x0_j)(...)^T), a third of the products, and no
    # cancellation: the offsets between modes are small where the positions are large)
    for i in range(1, M):  # S_0 = P_0: mode 0's offset is zero
        for a in range(n):
            d = x[i, a] - x[0, a]
            for b in range(a, n):
                S[i, a, b] = P[i, a, b] + d * (x[i, b] - x[0, b])
    for j in range(M):
        for a in range(n):
            acc = 0.0
            for i in range(M):
                acc += weight[i, j] * (x[i, a] - x[0, a])
            e[a] = acc
            x0[j, a] = x[0, a] + acc
        if M == 3:
            # the tracker's three-mode sets: the sum over modes written out (same terms, same order)
            w0, w1, w2 = weight[0, j], weight[1, j], weight[2, j]
            for a in range(n):
                for b in range(a, n):
                    value = w0 * P[0, a, b] + w1 * S[1, a, b] + w2 * S[2, a, b] - e[a] * e[b]
                    P0[j, a, b] = value
                    P0[j, b, a] = value
            continue
        for a in range(n):
            for b in range(a, n):
                acc = weight[0, j] * P[0, a, b]
                for i in range(1, M):
                    acc += weight[i, j] * S[i, a, b]
                P0[j, a, b] = acc - e[a] * e[b]
                P0[j, b, a] = P0[j, a, b]
    if forced_mode >= 0:
        for j in range(M):
            c_out[j] = 1.0 if j == forced_mode else 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def mix_predict_row(x, P, mu, dt, mixing_dt, modes, sojourn, fixed, forced_mode, x_out, P_out, c_out, scratch):
    """One row of :func:`imm_predict`: :func:`mix_row` over ``Pi(mixing_dt)``, then every mode
    predicted by ``dt`` (:func:`predict_mode`) into ``x_out``, ``P_out``."""
    _, _, G, column, result, _, _, x0, P0 = scratch
    M, n = x.shape
    mix_row(x, P, mu, mixing_dt, sojourn, fixed, forced_mode, x0, P0, c_out, scratch)
    for j in range(M):
        predict_mode(modes[j], x0[j], P0[j], dt, n // 2, x_out[j], P_out[j], G, column, result)


@njit(cache=True, nogil=True, error_model="numpy")
def imm_predict(x, P, mu, dt, mixing_dt, modes, sojourn, fixed, force, forced_mode):
    """Mixing over ``Pi(mixing_dt[K])`` and mode-matched prediction by ``dt[K]`` of rows
    ``x[K, M, n]``, ``P[K, M, n, n]``, ``mu[K, M]``; returns the predicted ``x``, ``P`` and ``c`` (one-hot on ``forced_mode`` where
    ``force``)."""
    K, M, n = x.shape
    x_out = np.empty_like(x)
    P_out = np.empty_like(P)
    c_out = np.empty_like(mu)
    scratch = mix_scratch(M, n)
    for k in range(K):
        mix_predict_row(x[k], P[k], mu[k], dt[k], mixing_dt[k], modes, sojourn, fixed, forced_mode if force[k] else -1,
                        x_out[k], P_out[k], c_out[k], scratch)
    return x_out, P_out, c_out


@njit(cache=True, nogil=True, error_model="numpy")
def moment_match_rows(x, P, mu):
    """``x = sum_j mu_j x_j``, ``P = sum_j mu_j (P_j + d_j d_j^T)`` per row of ``x[K, M, n]``,
    ``P[K, M, n, n]``, ``mu[K, M]`` (symmetrised): the compiled :meth:`MixtureState.estimate`."""
    K, M, n = x.shape
    x_out = np.empty((K, n))
    P_out = np.empty((K, n, n))
    for k in range(K):
        for a in range(n):
            acc = 0.0
            for j in range(M):
                acc += mu[k, j] * x[k, j, a]
            x_out[k, a] = acc
        for a in range(n):
            for b in range(a, n):
                acc = 0.0
                for j in range(M):
                    acc += mu[k, j] * (P[k, j, a, b] + (x[k, j, a] - x_out[k, a]) * (x[k, j, b] - x_out[k, b]))
                P_out[k, a, b] = acc
                P_out[k, b, a] = acc
    return x_out, P_out


@njit(cache=True, nogil=True, error_model="numpy")
def imm_predict_matched(x, P, mu, rows, dt, modes, sojourn, fixed):
    """Rows ``rows`` of ``x[N, M, n]``, ``P[N, M, n, n]``, ``mu[N, M]`` mixed and predicted by
    ``dt[K]`` (:func:`imm_predict`), then moment-matched (:func:`moment_match_rows`): returns the
    Gaussian ``x[K, n]``, ``P[K, n, n]`` and the predicted probabilities ``c[K, M]``, without the
    per-mode arrays (an output instant's or a snapshot's picture)."""
    _, M, n = x.shape
    K = len(rows)
    x_out = np.empty((K, n))
    P_out = np.empty((K, n, n))
    c_out = np.empty((K, M))
    xp = np.empty((M, n))
    Pp = np.empty((M, n, n))
    scratch = mix_scratch(M, n)
    for r in range(K):
        k = rows[r]
        mix_predict_row(x[k], P[k], mu[k], dt[r], dt[r], modes, sojourn, fixed, -1, xp, Pp, c_out[r], scratch)
        for a in range(n):
            acc = 0.0
            for j in range(M):
                acc += c_out[r, j] * xp[j, a]
            x_out[r, a] = acc
        for a in range(n):
            for b in range(a, n):
                acc = 0.0
                for j in range(M):
                    acc += c_out[r, j] * (Pp[j, a, b] + (xp[j, a] - x_out[r, a]) * (xp[j, b] - x_out[r, b]))
                P_out[r, a, b] = acc
                P_out[r, b, a] = acc
    return x_out, P_out, c_out

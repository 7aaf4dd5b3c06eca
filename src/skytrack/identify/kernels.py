"""Compiled report loop of the many-to-many identifier (spec 001 R13 step 3, R17).

:func:`process_reports` takes a batch of reports in merge order (time, system 1 first at
equal times) and, for each report of track k, runs the Kalman recursion of R2/R3 on k's
own filter and on the joint filter of every live pair (k, ·), adding
q_joint − q_own to the pair's Λ and applying the drop rule of R13 step 5.  The arrays are
those of :class:`~skytrack.identify.kalman.FilterBank` (tracks) and of the identifier's pair
bank, changed in place.  The model is the nearly-constant-velocity one with white-noise
acceleration PSD q (position-first state order, :mod:`skytrack.identify.model`), and a
report measures the first m state components (positions, then velocities).

The numpy reference of every step is :class:`~skytrack.identify.kalman.FilterBank`; the
tests run both on the same reports.  One call per batch: no Python per report or pair.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.identify.kalman import RANK_TOLERANCE

#: outliers left out in a row before the next one is taken as the track's motion
MAX_CONSECUTIVE_GATED = 2


@njit(cache=True)
def cv_transition(ndim, dt, q, F, Q):
    """F(dt) and Q(dt) of the CV model in position-first order (F, Q written in place)."""
    n = 2 * ndim
    for i in range(n):
        for j in range(n):
            F[i, j] = 0.0
            Q[i, j] = 0.0
    for a in range(ndim):
        F[a, a] = 1.0
        F[ndim + a, ndim + a] = 1.0
        F[a, ndim + a] = dt
        Q[a, a] = q * dt ** 3 / 3.0
        Q[a, ndim + a] = q * dt ** 2 / 2.0
        Q[ndim + a, a] = q * dt ** 2 / 2.0
        Q[ndim + a, ndim + a] = q * dt


@njit(cache=True)
def _predict_cv(x, P, ndim, dt, q, work):
    """CV prediction in place without allocation: F = I + dt E, E moving velocity into position."""
    n = 2 * ndim
    for a in range(ndim):
        x[a] += dt * x[ndim + a]
    for i in range(n):
        for j in range(n):
            work[i, j] = P[i, j]
    for a in range(ndim):  # F P: position rows take dt times their velocity rows
        for j in range(n):
            work[a, j] += dt * P[ndim + a, j]
    for i in range(n):  # (F P) F^T: position columns take dt times their velocity columns
        for a in range(ndim):
            work[i, a] += dt * work[i, ndim + a]
    q3, q2, q1 = q * dt ** 3 / 3.0, q * dt ** 2 / 2.0, q * dt
    for a in range(ndim):
        work[a, a] += q3
        work[a, ndim + a] += q2
        work[ndim + a, a] += q2
        work[ndim + a, ndim + a] += q1
    for i in range(n):
        for j in range(i, n):
            value = 0.5 * (work[i, j] + work[j, i])
            P[i, j] = value
            P[j, i] = value


@njit(cache=True)
def _innovation_cholesky(P, V, m, chol):
    """Lower Cholesky factor of S = H P H^T + V for H = [I_m 0], written into ``chol``."""
    for i in range(m):
        for j in range(i + 1):
            total = P[i, j] + V[i, j]
            for k in range(j):
                total -= chol[i, k] * chol[j, k]
            if i == j:
                chol[i, i] = np.sqrt(total)
            else:
                chol[i, j] = total / chol[j, j]


@njit(cache=True)
def _update_covariance(x, P, z, V, m, work):
    """Joseph update with H = [I_m 0] without allocation; returns (ν^T S^{-1} ν, ln det S).

    ``work`` is ``[5, max(n, 3), n]`` scratch: Cholesky factor of S, S^{-1}, the gain, (I − K H) P, vectors.
    """
    n = x.shape[0]
    chol, s_inv, gain, product = work[0], work[1], work[2], work[3]
    solve, nu, correction = work[4, 0], work[4, 1], work[4, 2]
    _innovation_cholesky(P, V, m, chol)
    for col in range(m):  # S^{-1} column by column: forward then back substitution
        for i in range(m):
            total = 1.0 if i == col else 0.0
            for k in range(i):
                total -= chol[i, k] * solve[k]
            solve[i] = total / chol[i, i]
        for i in range(m - 1, -1, -1):
            total = solve[i]
            for k in range(i + 1, m):
                total -= chol[k, i] * s_inv[k, col]
            s_inv[i, col] = total / chol[i, i]
    for i in range(m):
        nu[i] = z[i] - x[i]
    quadratic = 0.0
    logdet = 0.0
    for i in range(m):
        logdet += 2.0 * np.log(chol[i, i])
        for j in range(m):
            quadratic += nu[i] * s_inv[i, j] * nu[j]
    for i in range(n):  # K = P H^T S^{-1}, and K ν
        step = 0.0
        for j in range(m):
            total = 0.0
            for k in range(m):
                total += P[i, k] * s_inv[k, j]
            gain[i, j] = total
            step += total * nu[j]
        correction[i] = step
    for i in range(n):
        x[i] += correction[i]
    for i in range(n):  # (I − K H) P
        for j in range(n):
            total = P[i, j]
            for k in range(m):
                total -= gain[i, k] * P[k, j]
            product[i, j] = total
    for i in range(n):  # (I − K H) P (I − K H)^T + K V K^T, symmetric: upper triangle then mirror
        for j in range(i, n):
            total = product[i, j]
            for k in range(m):
                total -= product[i, k] * gain[j, k]
            for k in range(m):
                for l in range(m):
                    total += gain[i, k] * V[k, l] * gain[j, l]
            P[i, j] = total
    for i in range(n):
        for j in range(i):
            P[i, j] = P[j, i]
    return quadratic, logdet


@njit(cache=True)
def _predict_information(Y, y, c0, F, Q, q):
    """R3(a) time update; for the CV model with q > 0, Q is full rank (G = I, Q_w = Q)."""
    F_inv = np.linalg.inv(F)
    M = F_inv.T @ Y @ F_inv
    M = 0.5 * (M + M.T)
    u = F_inv.T @ y
    if q > 0.0:
        A = M + np.linalg.inv(Q)
        A_inv = np.linalg.inv(A)
        MA = M @ A_inv
        Y_new = M - MA @ M
        y[:] = u - MA @ u
        c0[0] -= u @ (A_inv @ u)
        Y[:, :] = 0.5 * (Y_new + Y_new.T)
    else:
        Y[:, :] = M
        y[:] = u


@njit(cache=True)
def _information_minimum(Y, y, c0):
    """(J = c₀ − y^T Y⁻ y, rank) with R3's scale-invariant rank test."""
    n = Y.shape[0]
    scale = np.empty(n)
    for i in range(n):
        scale[i] = 1.0 / np.sqrt(Y[i, i]) if Y[i, i] > 0 else 1.0
    scaled = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            scaled[i, j] = 0.5 * (Y[i, j] + Y[j, i]) * scale[i] * scale[j]
    w, vectors = np.linalg.eigh(scaled)
    ys = y * scale
    projected = vectors.T @ ys
    quadratic = 0.0
    rank = 0
    for i in range(n):
        if w[i] > RANK_TOLERANCE:
            rank += 1
            quadratic += projected[i] ** 2 / w[i]
    return c0 - quadratic, rank


@njit(cache=True)
def _normalised_innovation(x, P, z, V, m, chol, solve):
    """ν^T S^{-1} ν of a report against a covariance-form filter (nothing changes)."""
    _innovation_cholesky(P, V, m, chol)
    quadratic = 0.0
    for i in range(m):
        total = z[i] - x[i]
        for k in range(i):
            total -= chol[i, k] * solve[k]
        solve[i] = total / chol[i, i]
        quadratic += solve[i] ** 2
    return quadratic


@njit(cache=True)
def _update_track(k, t, z, V, m, ndim, q, tr_t, tr_full, tr_Y, tr_y, tr_c0, tr_x, tr_P, tr_J, tr_L, tr_m, tr_rank,
                  F, Q, work, report_gate, tr_gated):
    """Predict and update track k; returns the increment of its J, or NaN when the report is an
    outlier of the track's own filter (normalised innovation above ``report_gate`` > 0): it is
    then left out, for the track and its pairs."""
    n = 2 * ndim
    if np.isfinite(tr_t[k]):
        dt = t - tr_t[k]
        if dt > 0.0:
            if tr_full[k]:
                _predict_cv(tr_x[k], tr_P[k], ndim, dt, q, work[0])
            else:
                cv_transition(ndim, dt, q, F, Q)
                _predict_information(tr_Y[k], tr_y[k], tr_c0[k:k + 1], F, Q, q)
    tr_t[k] = t
    if tr_full[k] and report_gate > 0.0:
        # a lone outlier is left out; a run of them is the track's real motion and is taken
        if _normalised_innovation(tr_x[k], tr_P[k], z, V, m, work[0], work[4, 0]) > report_gate \
                and tr_gated[k] < MAX_CONSECUTIVE_GATED:
            tr_gated[k] += 1
            return np.nan
        tr_gated[k] = 0
    tr_m[k] += m
    if tr_full[k]:
        quadratic, logdet = _update_covariance(tr_x[k], tr_P[k], z, V, m, work)
        tr_J[k] += quadratic
        tr_L[k] += logdet
        return quadratic
    V_inv = np.linalg.inv(np.ascontiguousarray(V[:m, :m]))
    for i in range(m):
        for j in range(m):
            tr_Y[k, i, j] += V_inv[i, j]
    for i in range(m):
        acc = 0.0
        for j in range(m):
            acc += V_inv[i, j] * z[j]
        tr_y[k, i] += acc
        tr_c0[k] += z[i] * acc
    J_new, rank = _information_minimum(tr_Y[k], tr_y[k], tr_c0[k])
    old = tr_J[k]
    tr_rank[k] = rank
    if rank == n:
        P = np.linalg.inv(tr_Y[k])
        tr_P[k] = 0.5 * (P + P.T)
        tr_x[k] = tr_P[k] @ tr_y[k]
        J_new = tr_c0[k] - tr_y[k] @ tr_x[k]
        tr_full[k] = True
    tr_J[k] = J_new
    return J_new - old


@njit(cache=True)
def process_reports(report_track, report_time, report_z, report_m, report_V, ndim, q,
                    tr_t, tr_full, tr_Y, tr_y, tr_c0, tr_x, tr_P, tr_J, tr_L, tr_m, tr_rank,
                    adj_ptr, adj_pair,
                    pr_alive, pr_t, pr_x, pr_P, pr_lam, pr_updates, pr_exceed, pr_dropped_at,
                    drop_gate, drop_count, report_gate, tr_gated):
    """Process reports in the given (merge) order; tracks and pairs change in place.

    ``adj_ptr``/``adj_pair`` list, per track row, the pair rows it belongs to (CSR).  A pair
    whose Λ exceeds ``drop_gate`` on ``drop_count`` consecutive updates dies, with its
    time in ``pr_dropped_at``.  A report whose normalised innovation in its track's own filter
    exceeds ``report_gate`` (when > 0) is left out, unless it is the third in a row
    (``tr_gated`` counts them per track).  Returns the number of pair updates done and
    of reports left out.
    """
    n = 2 * ndim
    F = np.empty((n, n))
    Q = np.empty((n, n))
    work = np.zeros((5, max(n, 3), n))
    pair_updates = 0
    gated = 0
    for r in range(len(report_track)):
        k = report_track[r]
        t = report_time[r]
        m = report_m[r]
        z = report_z[r]
        V = report_V[r]
        own = _update_track(k, t, z, V, m, ndim, q, tr_t, tr_full, tr_Y, tr_y, tr_c0, tr_x, tr_P, tr_J, tr_L, tr_m,
                            tr_rank, F, Q, work, report_gate, tr_gated)
        if np.isnan(own):
            gated += 1
            continue
        for a in range(adj_ptr[k], adj_ptr[k + 1]):
            p = adj_pair[a]
            if not pr_alive[p]:
                continue
            dt = t - pr_t[p]
            if dt > 0.0:
                _predict_cv(pr_x[p], pr_P[p], ndim, dt, q, work[0])
                pr_t[p] = t
            joint, _ = _update_covariance(pr_x[p], pr_P[p], z, V, m, work)
            pr_lam[p] += joint - own
            pr_updates[p] += 1
            pair_updates += 1
            if pr_lam[p] > drop_gate:
                pr_exceed[p] += 1
                if pr_exceed[p] >= drop_count:
                    pr_alive[p] = False
                    pr_dropped_at[p] = t
            else:
                pr_exceed[p] = 0
    return pair_updates, gated

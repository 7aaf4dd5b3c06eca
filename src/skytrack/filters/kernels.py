"""Compiled (numba, cached) kernels of the Kalman family, row by row over a batch.

Each kernel has a numpy reference in :mod:`skytrack.filters.kalman` and is tested equal to
it.  They exist because at tens of rows per call numpy's per-call overhead dominates: one
compiled loop over rows replaces a dozen stacked-matrix calls.

* :func:`predict_blocks` — ``x' = F x``, ``P' = F P F^T + s Q`` for a state made of identical
  per-axis blocks (spec 000 R1 layout): ``F``, ``Q`` are given as one ``[K, o, o]`` block per row,
  so ``P'`` is computed block by block.
* :func:`innovate_dense` — ``S = H P H^T + R``, its Cholesky factor, ``d^2``, ``ln det S``.
* :func:`update_dense` — gain ``K = P H^T S^-1`` through the Cholesky factor, ``x + K nu`` and the
  Joseph form ``(I - K H) P (I - K H)^T + K R K^T``, symmetrised.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def predict_blocks(x, P, Fa, Qa, scale):
    rows, n = x.shape
    o = Fa.shape[1]
    axes = n // o
    x_out = np.empty_like(x)
    P_out = np.empty_like(P)
    tmp = np.empty((o, o))
    for k in range(rows):
        for a in range(axes):
            base = a * o
            for i in range(o):
                acc = 0.0
                for j in range(o):
                    acc += Fa[k, i, j] * x[k, base + j]
                x_out[k, base + i] = acc
        for a in range(axes):
            for b in range(axes):
                ra, rb = a * o, b * o
                # tmp = Fa P_ab
                for i in range(o):
                    for j in range(o):
                        acc = 0.0
                        for l in range(o):
                            acc += Fa[k, i, l] * P[k, ra + l, rb + j]
                        tmp[i, j] = acc
                # P'_ab = tmp Fa^T (+ Q on the diagonal blocks)
                for i in range(o):
                    for j in range(o):
                        acc = 0.0
                        for l in range(o):
                            acc += tmp[i, l] * Fa[k, j, l]
                        if a == b:
                            acc += scale[k] * Qa[k, i, j]
                        P_out[k, ra + i, rb + j] = acc
        for i in range(n):
            for j in range(i + 1, n):
                mean = 0.5 * (P_out[k, i, j] + P_out[k, j, i])
                P_out[k, i, j] = mean
                P_out[k, j, i] = mean
    return x_out, P_out


@njit(cache=True, nogil=True)
def _cholesky_row(S, L):
    m = S.shape[0]
    for i in range(m):
        for j in range(i + 1):
            acc = S[i, j]
            for l in range(j):
                acc -= L[i, l] * L[j, l]
            if i == j:
                if acc <= 0.0:
                    return False
                L[i, i] = np.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
        for j in range(i + 1, m):
            L[i, j] = 0.0
    return True


@njit(cache=True, nogil=True)
def innovate_dense(P, H, R, nu):
    rows, m, n = H.shape
    S = np.empty((rows, m, m))
    L = np.zeros((rows, m, m))
    d2 = np.empty(rows)
    logdet = np.empty(rows)
    ok = np.ones(rows, dtype=np.bool_)
    HP = np.empty((m, n))
    w = np.empty(m)
    for k in range(rows):
        for i in range(m):
            for j in range(n):
                acc = 0.0
                for l in range(n):
                    acc += H[k, i, l] * P[k, l, j]
                HP[i, j] = acc
        for i in range(m):
            for j in range(m):
                acc = R[k, i, j]
                for l in range(n):
                    acc += HP[i, l] * H[k, j, l]
                S[k, i, j] = acc
        for i in range(m):
            for j in range(i + 1, m):
                mean = 0.5 * (S[k, i, j] + S[k, j, i])
                S[k, i, j] = mean
                S[k, j, i] = mean
        if not _cholesky_row(S[k], L[k]):
            ok[k] = False
            d2[k] = np.nan
            logdet[k] = np.nan
            continue
        total = 0.0
        ld = 0.0
        for i in range(m):
            acc = nu[k, i]
            for l in range(i):
                acc -= L[k, i, l] * w[l]
            w[i] = acc / L[k, i, i]
            total += w[i] * w[i]
            ld += np.log(L[k, i, i])
        d2[k] = total
        logdet[k] = 2.0 * ld
    return S, L, d2, logdet, ok


@njit(cache=True, nogil=True)
def update_dense(x, P, H, R, nu, L):
    rows, m, n = H.shape
    x_out = np.empty_like(x)
    P_out = np.empty_like(P)
    PHt = np.empty((n, m))
    K = np.empty((n, m))
    A = np.empty((n, n))
    AP = np.empty((n, n))
    KR = np.empty((n, m))
    y = np.empty(m)
    for k in range(rows):
        for i in range(n):
            for j in range(m):
                acc = 0.0
                for l in range(n):
                    acc += P[k, i, l] * H[k, j, l]
                PHt[i, j] = acc
        # K = PHt S^-1: solve S K^T = PHt^T row by row through L L^T
        for i in range(n):
            for a in range(m):
                acc = PHt[i, a]
                for l in range(a):
                    acc -= L[k, a, l] * y[l]
                y[a] = acc / L[k, a, a]
            for a in range(m - 1, -1, -1):
                acc = y[a]
                for l in range(a + 1, m):
                    acc -= L[k, l, a] * K[i, l]
                K[i, a] = acc / L[k, a, a]
        for i in range(n):
            acc = x[k, i]
            for j in range(m):
                acc += K[i, j] * nu[k, j]
            x_out[k, i] = acc
        for i in range(n):
            for j in range(n):
                acc = 1.0 if i == j else 0.0
                for l in range(m):
                    acc -= K[i, l] * H[k, l, j]
                A[i, j] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for l in range(n):
                    acc += A[i, l] * P[k, l, j]
                AP[i, j] = acc
        for i in range(n):
            for j in range(m):
                acc = 0.0
                for l in range(m):
                    acc += K[i, l] * R[k, l, j]
                KR[i, j] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for l in range(n):
                    acc += AP[i, l] * A[j, l]
                for l in range(m):
                    acc += KR[i, l] * K[j, l]
                P_out[k, i, j] = acc
        for i in range(n):
            for j in range(i + 1, n):
                mean = 0.5 * (P_out[k, i, j] + P_out[k, j, i])
                P_out[k, i, j] = mean
                P_out[k, j, i] = mean
    return x_out, P_out


@njit(cache=True, nogil=True)
def predict_cv(x, P, dt, q, scale):
    """``predict_blocks`` for the constant-velocity axis model, with ``F`` and ``Q`` formed inline:
    ``F = [[1, dt], [0, 1]]`` per axis (``F(|dt|)^-1`` for a negative step) and
    ``Q = s q [[|dt|^3/3, |dt|^2/2], [|dt|^2/2, |dt|]]``."""
    rows, n = x.shape
    axes = n // 2
    x_out = np.empty_like(x)
    P_out = np.empty_like(P)
    for k in range(rows):
        f = dt[k]
        step = abs(f)
        s = scale[k]
        q00 = q * step * step * step / 3.0 * s
        q01 = q * step * step / 2.0 * s
        q11 = q * step * s
        for a in range(axes):
            i = 2 * a
            x_out[k, i] = x[k, i] + f * x[k, i + 1]
            x_out[k, i + 1] = x[k, i + 1]
        for a in range(axes):
            for b in range(axes):
                i = 2 * a
                j = 2 * b
                m00 = P[k, i, j]
                m01 = P[k, i, j + 1]
                m10 = P[k, i + 1, j]
                m11 = P[k, i + 1, j + 1]
                r00 = m00 + f * m10
                r01 = m01 + f * m11
                P_out[k, i, j] = r00 + r01 * f
                P_out[k, i, j + 1] = r01
                P_out[k, i + 1, j] = m10 + m11 * f
                P_out[k, i + 1, j + 1] = m11
                if a == b:
                    P_out[k, i, j] += q00
                    P_out[k, i, j + 1] += q01
                    P_out[k, i + 1, j] += q01
                    P_out[k, i + 1, j + 1] += q11
        for i in range(n):
            for j in range(i + 1, n):
                mean = 0.5 * (P_out[k, i, j] + P_out[k, j, i])
                P_out[k, i, j] = mean
                P_out[k, j, i] = mean
    return x_out, P_out

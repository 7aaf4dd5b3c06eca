"""Reference oracles of spec 000 R11, written from the spec's equations only (no skytrack imports).

(a) ``thm1_step``  — Theorem 1, equations (3)-(4), literally (Liptser-Shiryaev / Glonti form);
(b) ``thm2``       — Theorem 2, equation (5);
(c) ``explicit_1d_pos`` / ``explicit_1d_posvel`` — the printed scalar filter (F1)-(F6) with the
    definitions (F7) (Gamma_H1..Gamma_H5, Gamma_D, Gamma_DV, Gamma_S, Gamma_SV) and the derived
    covariances (F8)-(F10).

Helpers build the coefficients of form (2) for any (F, Q, H, R) and detection flag, as in
§3.4 "General form": a0 = 0, a1 = (F - E)/dt, b1 = L/sqrt(dt) (L L^T = Q), b2 = 0,
A0 = -xi_n/dt, A1 = phi H F/dt, B1 = phi H b1, B2 = R^(1/2)/sqrt(dt), each observation block
extended by the fictitious p row of (M6)/(M7).  F and Q come from (K6) directly or, for
the exact Singer model, from Van Loan's matrix exponential (scipy) — independent of the
production series / closed form.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm, sqrtm


# --------------------------------------------------------------------------- (a), (b)


def thm1_step(m, gamma, a0, a1, b1, b2, A0, A1, B1, B2, dt, dxi, symmetrize=True):
    """One step of (3)-(4). Returns (m(n+1), gamma(n+1), gain) where
    gain = [(E + a1 dt) gamma A1^* + (b o B)] [(B o B) + A1 gamma A1^* dt]^-1.

    (4) maps symmetric matrices to symmetric matrices, but evaluated literally in floating
    point its antisymmetric rounding part is amplified at every detected scan (measured:
    x1.7 per scan for posvel at sigma_v = 4 m/s, reaching 1e-3 relative after 60 scans).
    ``symmetrize`` (default) therefore returns (gamma + gamma^T)/2, which leaves the exact
    recursion unchanged; ``symmetrize=False`` gives the raw literal value.
    """
    m = np.asarray(m, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    E = np.eye(m.size)
    bb = b1 @ b1.T + b2 @ b2.T
    bB = b1 @ B1.T + b2 @ B2.T
    BB = B1 @ B1.T + B2 @ B2.T
    G = (E + a1 * dt) @ gamma @ A1.T + bB
    D = BB + A1 @ gamma @ A1.T * dt
    gain = np.linalg.solve(D.T, G.T).T  # G D^-1
    dm = (a0 + a1 @ m) * dt + gain @ (dxi - (A0 + A1 @ m) * dt)
    dgamma = dt * (bb + a1 @ gamma @ a1.T * dt + a1 @ gamma + gamma @ a1.T - gain @ G.T)
    new_gamma = gamma + dgamma
    if symmetrize:
        new_gamma = 0.5 * (new_gamma + new_gamma.T)
    return m + dm, new_gamma, gain


def thm2(m, gamma, a0, a1, b1, b2, dt):
    """Theorem 2, (5): e-m(n+1) = m + (a0 + a1 m) dt, e-gamma(n+1) = gamma + dt [(b o b) + a1 g a1^* dt + a1 g + g a1^*]."""
    m = np.asarray(m, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    bb = b1 @ b1.T + b2 @ b2.T
    em = m + (a0 + a1 @ m) * dt
    egamma = gamma + dt * (bb + a1 @ gamma @ a1.T * dt + a1 @ gamma + gamma @ a1.T)
    return em, egamma


# --------------------------------------------------------------------------- models


def paper_FQ(dt, tau, sigma_a):
    """(K6): F_P = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, rho]], Q_P = diag(0, 0, sigma_a^2 (1 - rho^2))."""
    rho = math.exp(-dt / tau)
    F = np.array([[1.0, dt, dt * dt / 2.0], [0.0, 1.0, dt], [0.0, 0.0, rho]])
    Q = np.diag([0.0, 0.0, sigma_a**2 * (1.0 - rho * rho)])
    return F, Q


def exact_FQ(dt, tau, sigma_a):
    """Exact Singer sampling by Van Loan: d(x, v, a) = A (x, v, a) dt + G dw, PSD q = 2 sigma_a^2 / tau."""
    alpha = 1.0 / tau
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -alpha]])
    Qc = np.diag([0.0, 0.0, 2.0 * sigma_a**2 * alpha])
    M = np.zeros((6, 6))
    M[:3, :3] = -A
    M[:3, 3:] = Qc
    M[3:, 3:] = A.T
    E = expm(M * dt)
    F = E[3:, 3:].T
    Q = F @ E[:3, 3:]
    return F, 0.5 * (Q + Q.T)


def noise_factor(Q):
    """L with L L^T = Q; exact for the diagonal (rank-one) paper Q, Cholesky otherwise."""
    Q = np.asarray(Q, dtype=float)
    if np.count_nonzero(Q - np.diag(np.diag(Q))) == 0:
        return np.diag(np.sqrt(np.diag(Q)))
    return np.linalg.cholesky(Q)


def theorem1_coefficients(F, Q, H, R, phi, dt, xi_n):
    """Coefficients of (2) for one step with the p row appended (M6/M7 and §3.4 general form).

    ``xi_n`` is the observed vector at scan n: the measured components followed by p_n.
    Returns (a0, a1, b1, b2, A0, A1, B1, B2).
    """
    k = F.shape[0]
    mz = H.shape[0]
    l = mz + 1
    a0 = np.zeros(k)
    a1 = (F - np.eye(k)) / dt
    b1 = noise_factor(Q) / math.sqrt(dt)
    b2 = np.zeros((k, l))
    A0 = -np.asarray(xi_n, dtype=float) / dt
    A1 = np.zeros((l, k))
    A1[:mz] = phi * H @ F / dt
    B1 = np.zeros((l, k))
    B1[:mz] = phi * H @ b1
    B2 = np.zeros((l, l))
    B2[:mz, :mz] = np.real(sqrtm(R)) / math.sqrt(dt)
    B2[mz, mz] = 1.0 / math.sqrt(dt)
    return a0, a1, b1, b2, A0, A1, B1, B2


def thm1_run(m0, gamma0, steps, dt, H, R):
    """Drive (3)-(4) over ``steps``: a list of dicts with F, Q, phi, xi_n, xi_next.

    Returns the lists of m(n), gamma(n) for n = 1..N and the gains.
    """
    m, gamma = np.asarray(m0, dtype=float), np.asarray(gamma0, dtype=float)
    ms, gammas, gains = [], [], []
    for step in steps:
        a0, a1, b1, b2, A0, A1, B1, B2 = theorem1_coefficients(step["F"], step["Q"], H, R, step["phi"], dt, step["xi_n"])
        dxi = np.asarray(step["xi_next"], dtype=float) - np.asarray(step["xi_n"], dtype=float)
        m, gamma, gain = thm1_step(m, gamma, a0, a1, b1, b2, A0, A1, B1, B2, dt, dxi)
        ms.append(m)
        gammas.append(gamma)
        gains.append(gain)
    return ms, gammas, gains


# --------------------------------------------------------------------------- (c)


def _gamma_h(gamma, dt, rho):
    g = gamma
    h1 = g[0, 0] / dt + 2 * g[0, 1] + dt * (g[0, 2] + g[1, 1]) + dt**2 * g[1, 2] + 0.25 * dt**3 * g[2, 2]
    h2 = g[0, 1] / dt + g[1, 1] + g[0, 2] + 1.5 * dt * g[1, 2] + 0.5 * dt**2 * g[2, 2]
    h3 = rho * (g[0, 2] / dt + g[1, 2] + 0.5 * dt * g[2, 2])
    h4 = g[1, 1] / dt + 2 * g[1, 2] + dt * g[2, 2]
    h5 = rho * (g[1, 2] / dt + g[2, 2])
    return h1, h2, h3, h4, h5


def _egamma_f8(gamma, dt, rho, sigma_a, h):
    h1, h2, h3, h4, h5 = h
    eg = dt * np.array([[h1, h2, h3], [h2, h4, h5], [h3, h5, rho * rho * gamma[2, 2] / dt]])
    eg[2, 2] += sigma_a**2 * (1 - rho * rho)
    return eg


def explicit_1d_pos(m, gamma, z_next, phi, dt, tau, sigma_a, sigma):
    """(F1)-(F3), (F7)-(F9). Returns (m(n+1), gamma(n+1), dict of the Gamma quantities)."""
    rho = math.exp(-dt / tau)
    E1 = rho - 1.0
    m1, m2, m3 = m
    h = _gamma_h(gamma, dt, rho)
    h1, h2, h3, h4, h5 = h
    GD = phi / (sigma**2 / dt + h1)
    GS = (z_next - m1 - m2 * dt - m3 * dt**2 / 2) if phi else 0.0
    new_m = np.array([
        m1 + m2 * dt + m3 * dt**2 / 2 + GD * h1 * GS,
        m2 + m3 * dt + GD * h2 * GS,
        m3 * (E1 + 1) + GD * h3 * GS,
    ])
    eg = _egamma_f8(gamma, dt, rho, sigma_a, h)
    hv = np.array([h1, h2, h3])
    new_gamma = eg - dt * GD * np.outer(hv, hv)
    return new_m, new_gamma, {"GH": h, "GD": GD, "GS": GS, "egamma": eg}


def explicit_1d_posvel(m, gamma, z_next, V_next, phi, dt, tau, sigma_a, sigma, sigma_v):
    """(F4)-(F6), (F7), (F8), (F10). Returns (m(n+1), gamma(n+1), dict of the Gamma quantities)."""
    rho = math.exp(-dt / tau)
    E1 = rho - 1.0
    m1, m2, m3 = m
    h = _gamma_h(gamma, dt, rho)
    h1, h2, h3, h4, h5 = h
    s2, v2 = sigma**2 / dt, sigma_v**2 / dt
    GDV = phi / ((s2 + h1) * (v2 + h4) - h2**2)
    GS = (z_next - m1 - m2 * dt - m3 * dt**2 / 2) if phi else 0.0
    GSV = (V_next - m2 - m3 * dt) if phi else 0.0
    new_m = np.array([
        m1 + m2 * dt + 0.5 * m3 * dt**2 + ((h1 * (v2 + h4) - h2**2) * GS + h2 * s2 * GSV) * GDV,
        m2 + m3 * dt + (h2 * v2 * GS + (h4 * (s2 + h1) - h2**2) * GSV) * GDV,
        m3 * (E1 + 1) + ((h3 * (v2 + h4) - h2 * h5) * GS + (h5 * (s2 + h1) - h3 * h2) * GSV) * GDV,
    ])
    eg = _egamma_f8(gamma, dt, rho, sigma_a, h)
    G = np.array([[h1, h2], [h2, h4], [h3, h5]])
    adj = np.array([[v2 + h4, -h2], [-h2, s2 + h1]])
    new_gamma = eg - dt * GDV * G @ adj @ G.T
    return new_m, new_gamma, {"GH": h, "GDV": GDV, "GS": GS, "GSV": GSV, "egamma": eg}

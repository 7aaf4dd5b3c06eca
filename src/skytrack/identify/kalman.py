"""Batched Kalman filters of spec 001 with exact diffuse initialisation (R2, R3).

Every filter of the identification — a pair's joint "same object" filter (14), a system's
own filter (17)/(20) — is a row of a :class:`FilterBank`: the leading axis is pairs,
tracks or Monte Carlo trials alike (DESIGN rule 1).  Each row accumulates

* ``J`` — the sum of the normalised innovation quadratic forms ν^T S^{-1} ν (R2), or, in
  the information phase of a diffuse start, the generalised least-squares residual;
* ``L`` — the sum of ln det S over the innovations (gap G1: the log-determinants the paper
  drops);
* ``m`` — the measurement dimensions seen, and ``rank`` — the information rank r ≤ n.

Initialisation (gap G3, R3):

* ``diffuse`` — exact diffuse start.  Until the information matrix is full rank the row
  keeps the cost c(x) = x^T Y x − 2 y^T x + c₀ (information form); J = c₀ − y^T Y⁺ y is the
  minimum over the initial state of the GLS cost of the row's reports, process noise
  integrated out by the time update of R3(a) with Q = G Q_w G^T.  At full rank it turns to
  the covariance form (P = Y^{-1}, x̂ = P y) and continues with innovations (12)–(14).
* ``prior`` — a proper Gaussian N(x₀, P₀) at t₀; every report contributes an innovation.

The covariance-form update is Joseph's.  Rank is tested scale-invariantly on
D^{-½} Y D^{-½}, D = diag(Y) (zero entries replaced by 1).  This module is the numpy
reference; :mod:`skytrack.identify.kernels` is the compiled version the many-to-many
identifier runs, tested against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.identify.model import IdentificationModel, factor_process_noise

#: an eigenvalue of the scaled information matrix below this counts as zero (rank test, R3)
RANK_TOLERANCE = 1e-9


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def information_rank(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scale-invariant rank of information matrices ``[K, n, n]`` and a generalised inverse of each.

    With Y_s = D^{-½} Y D^{-½}, the returned inverse D^{-½} Y_s⁺ D^{-½} satisfies Y Y⁻ Y = Y,
    so y^T Y⁻ y is the GLS minimum whenever y lies in the range of Y (it always does here).
    """
    d = np.diagonal(Y, axis1=-2, axis2=-1)
    scale = 1.0 / np.sqrt(np.where(d > 0, d, 1.0))
    scaled = _sym(Y * scale[:, :, None] * scale[:, None, :])
    eigenvalues, vectors = np.linalg.eigh(scaled)
    keep = eigenvalues > RANK_TOLERANCE
    inverse_eigen = np.where(keep, 1.0 / np.where(keep, eigenvalues, 1.0), 0.0)
    pseudo = np.einsum("kij,kj,klj->kil", vectors, inverse_eigen, vectors)
    return keep.sum(axis=-1), pseudo * scale[:, :, None] * scale[:, None, :]


@dataclass
class StepResult:
    """What one update did to each of its rows."""

    quadratic: np.ndarray
    """increment of J (ν^T S^{-1} ν, or the GLS residual's growth in the information phase)"""
    logdet: np.ndarray
    """ln det S of the innovation (0 where the row was still in the information phase)"""
    innovated: np.ndarray
    """the row was in the covariance form before the report (its increment is an innovation term)"""


class FilterBank:
    """K Kalman filters of one identification model, in information or covariance form per row."""

    def __init__(self, model: IdentificationModel, size: int, *, init: str = "diffuse",
                 x0=None, P0=None, t0: float | None = None):
        n = model.n
        self.model = model
        self.Y = np.zeros((size, n, n))
        self.y = np.zeros((size, n))
        self.c0 = np.zeros(size)
        self.x = np.zeros((size, n))
        self.P = np.zeros((size, n, n))
        self.J = np.zeros(size)
        self.L = np.zeros(size)
        self.m = np.zeros(size, dtype=np.int64)
        self.rank = np.zeros(size, dtype=np.int64)
        self.full = np.zeros(size, dtype=bool)
        self.t = np.full(size, np.nan)
        if init == "prior":
            if x0 is None or P0 is None or t0 is None:
                raise ValueError("init='prior' needs x0, P0 and t0")
            self.x[:] = np.asarray(x0, float)
            self.P[:] = np.asarray(P0, float)
            if np.linalg.eigvalsh(np.asarray(P0, float)).min() <= 0:
                raise ValueError("the prior covariance P0 must be positive definite")
            self.t[:] = float(t0)
            self.full[:] = True
            self.rank[:] = n
        elif init != "diffuse":
            raise ValueError(f"init must be 'diffuse' or 'prior', got {init!r}")

    def __len__(self) -> int:
        return len(self.J)

    #: the per-row arrays, in the order :mod:`skytrack.identify.kernels` takes them
    FIELDS = ("t", "full", "Y", "y", "c0", "x", "P", "J", "L", "m", "rank")

    def grow(self, size: int) -> None:
        """Make room for ``size`` rows; new rows are empty diffuse filters."""
        old = len(self)
        if size <= old:
            return
        for name in self.FIELDS:
            array = getattr(self, name)
            fill = np.nan if name == "t" else 0
            grown = np.full((size,) + array.shape[1:], fill, dtype=array.dtype)
            grown[:old] = array
            setattr(self, name, grown)

    def reset(self, rows: np.ndarray) -> None:
        """Make ``rows`` empty diffuse filters again (rows reused for new tracks or pairs)."""
        for name in self.FIELDS:
            getattr(self, name)[rows] = np.nan if name == "t" else 0

    # ------------------------------------------------------------------ time update
    def predict(self, rows: np.ndarray, t: np.ndarray) -> None:
        """Bring ``rows`` to times ``t`` (a row without any report yet only takes the time)."""
        rows = np.asarray(rows, dtype=np.intp)
        t = np.broadcast_to(np.asarray(t, float), rows.shape)
        dt = t - self.t[rows]
        started = np.isfinite(dt)
        if np.any(dt[started] < 0):
            bad = rows[started][np.argmin(dt[started])]
            raise ValueError(f"time goes backwards for filter row {bad}: report at t={t[rows == bad][0]:.6g} s "
                             f"after one at t={self.t[bad]:.6g} s")
        moving = started & (dt > 0)
        self.t[rows[~started]] = t[~started]
        if not moving.any():
            return
        rows, dt = rows[moving], dt[moving]
        self.t[rows] = t[moving]
        F, Q = self.model.F(dt), self.model.Q(dt)
        full = self.full[rows]
        if full.any():
            r, Fr = rows[full], F[full]
            self.x[r] = np.einsum("kij,kj->ki", Fr, self.x[r])
            self.P[r] = _sym(Fr @ self.P[r] @ np.swapaxes(Fr, -1, -2) + Q[full])
        if (~full).any():
            self._predict_information(rows[~full], F[~full], Q[~full])

    def _predict_information(self, rows: np.ndarray, F: np.ndarray, Q: np.ndarray) -> None:
        """R3(a): M = F^{-T} Y F^{-1}, u = F^{-T} y, then integrate the process noise out."""
        F_inv = np.linalg.inv(F)
        F_inv_T = np.swapaxes(F_inv, -1, -2)
        M = _sym(F_inv_T @ self.Y[rows] @ F_inv)
        u = np.einsum("kij,kj->ki", F_inv_T, self.y[rows])
        G, q_w, noisy = factor_process_noise(Q)
        A = np.swapaxes(G, -1, -2) @ M @ G + np.eye(G.shape[-1]) / q_w[:, None, :] * np.eye(G.shape[-1])
        MG = M @ G
        A_inv = np.linalg.inv(A)
        Gt_u = np.einsum("kji,kj->ki", G, u)
        Y_new = _sym(M - MG @ A_inv @ np.swapaxes(MG, -1, -2))
        y_new = u - np.einsum("kij,kj->ki", MG @ A_inv, Gt_u)
        c_drop = np.einsum("ki,kij,kj->k", Gt_u, A_inv, Gt_u)
        noisy = noisy[:, None, None]
        self.Y[rows] = np.where(noisy, Y_new, M)
        self.y[rows] = np.where(noisy[:, :, 0], y_new, u)
        self.c0[rows] -= np.where(noisy[:, 0, 0], c_drop, 0.0)

    # ------------------------------------------------------------------ measurement update
    def update(self, rows: np.ndarray, z: np.ndarray, V: np.ndarray, H: np.ndarray) -> StepResult:
        """Update ``rows`` (already at the report time) with reports ``z`` ``[K, m]``, ``V`` and ``H``."""
        rows = np.asarray(rows, dtype=np.intp)
        k = len(rows)
        z = np.asarray(z, float).reshape(k, -1)
        m = z.shape[1]
        V = np.broadcast_to(np.asarray(V, float), (k, m, m))
        H = np.broadcast_to(np.asarray(H, float), (k, m, self.model.n))
        quadratic, logdet = np.zeros(k), np.zeros(k)
        full = self.full[rows].copy()
        if full.any():
            quadratic[full], logdet[full] = self._update_covariance(rows[full], z[full], V[full], H[full])
        if (~full).any():
            quadratic[~full] = self._update_information(rows[~full], z[~full], V[~full], H[~full])
        self.m[rows] += m
        return StepResult(quadratic, logdet, full)

    def _update_covariance(self, rows, z, V, H) -> tuple[np.ndarray, np.ndarray]:
        x, P = self.x[rows], self.P[rows]
        Ht = np.swapaxes(H, -1, -2)
        nu = z - np.einsum("kij,kj->ki", H, x)
        S = _sym(H @ P @ Ht + V)
        chol = np.linalg.cholesky(S)
        S_inv = np.linalg.inv(S)
        gain = P @ Ht @ S_inv
        I_KH = np.eye(self.model.n) - gain @ H
        self.x[rows] = x + np.einsum("kij,kj->ki", gain, nu)
        self.P[rows] = _sym(I_KH @ P @ np.swapaxes(I_KH, -1, -2) + gain @ V @ np.swapaxes(gain, -1, -2))
        quadratic = np.einsum("ki,kij,kj->k", nu, S_inv, nu)
        logdet = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
        self.J[rows] += quadratic
        self.L[rows] += logdet
        return quadratic, logdet

    def _update_information(self, rows, z, V, H) -> np.ndarray:
        V_inv = np.linalg.inv(V)
        Ht_Vinv = np.swapaxes(H, -1, -2) @ V_inv
        self.Y[rows] = _sym(self.Y[rows] + Ht_Vinv @ H)
        self.y[rows] += np.einsum("kij,kj->ki", Ht_Vinv, z)
        self.c0[rows] += np.einsum("ki,kij,kj->k", z, V_inv, z)
        rank, Y_pinv = information_rank(self.Y[rows])
        y = self.y[rows]
        J_new = self.c0[rows] - np.einsum("ki,kij,kj->k", y, Y_pinv, y)
        quadratic = J_new - self.J[rows]
        self.J[rows] = J_new
        self.rank[rows] = rank
        done = rank == self.model.n
        if done.any():
            r = rows[done]
            P = _sym(np.linalg.inv(self.Y[r]))
            self.P[r] = P
            self.x[r] = np.einsum("kij,kj->ki", P, self.y[r])
            self.J[r] = self.c0[r] - np.einsum("ki,ki->k", self.y[r], self.x[r])
            quadratic[done] = self.J[r] - (J_new[done] - quadratic[done])
            self.full[r] = True
        return quadratic

    def normalised_innovation(self, rows: np.ndarray, z: np.ndarray, V: np.ndarray, H: np.ndarray) -> np.ndarray:
        """ν^T S^{-1} ν of reports against covariance-form ``rows`` at the report time (no change)."""
        x, P = self.x[rows], self.P[rows]
        H = np.broadcast_to(H, (len(rows),) + np.shape(H)[-2:])
        nu = z - np.einsum("kij,kj->ki", H, x)
        S = H @ P @ np.swapaxes(H, -1, -2) + V
        return np.einsum("ki,ki->k", nu, np.linalg.solve(S, nu[..., None])[..., 0])

    # ------------------------------------------------------------------ views
    def estimate_at(self, rows: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States and covariances of full-rank ``rows`` predicted to ``t`` (the bank is not changed)."""
        rows = np.asarray(rows, dtype=np.intp)
        if not np.all(self.full[rows]):
            raise ValueError("estimate_at needs rows in the covariance form (information rank n)")
        dt = np.broadcast_to(np.asarray(t, float), rows.shape) - self.t[rows]
        F = self.model.F(np.abs(dt))
        backwards = dt < 0
        if backwards.any():
            F[backwards] = np.linalg.inv(F[backwards])
        Q = self.model.Q(np.abs(dt))
        Q[backwards] = 0.0  # retrodiction without process noise: only used for a common time in checks
        x = np.einsum("kij,kj->ki", F, self.x[rows])
        P = _sym(F @ self.P[rows] @ np.swapaxes(F, -1, -2) + Q)
        return x, P

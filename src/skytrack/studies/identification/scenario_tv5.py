"""The TV-5 Monte Carlo scenario of spec 001 (R16) and the batch quadratic forms of studies E5-E9.

TV-5 (spec 001 §5): 2-D constant velocity, the radar reports at t = 0, 1, ..., 9 s with σ = 50 m
per axis, ADS-B at t = 0.3, 1.3, ..., 9.3 s with σ = 20 m; object 1 starts at [0, 0, 100, −50]
(state order [x, y, vx, vy]).  :data:`TV3_GEOMETRY` is the 4 + 4 report geometry of TV-3 (E8).

The statistic Λ of (20a) is a difference of three accumulated quadratic forms (14b), (17), (20).
After an exact diffuse start (R3a) each J is the generalised least-squares residual of its
filter's reports with the initial state profiled out and the process noise integrated out:

    J = z^T M z,   M = C^{-1} − C^{-1} X (X^T C^{-1} X)^{-1} X^T C^{-1},

where X maps the state at a reference epoch t_ref (≤ every report) to the positions and C is the
covariance of the reports given that state: the integrated white-noise acceleration of the CV
model, Cov(p(s), p(t)) = q s²(3t − s)/6 (s ≤ t, measured from t_ref), plus the report noise (gap G5).
Process noise before a filter's first report only moves its positions along the columns of X,
so the value does not depend on t_ref.  With A = M_joint − M_η − M_ξ (the separate filters'
matrices embedded in the merged stream) Λ = z^T A z for every report stream: the Monte Carlo of
E5/E6 is one matrix product over all trials, as the spec's own computation.  The reports of one
time have isotropic covariance σ² I and the model is axis by axis, so each matrix acts per axis.

* Under θ = 1 with Q = 0, Λ ~ χ²(4) (gap G7); under θ = 0, Λ ~ ncχ²(4, λ) with the closed form
  λ = δ^T (P_η + P_ξ)^{-1} δ (R5, R8), also equal to μ^T A μ for the offset μ of the ξ reports.
* With Q > 0, Λ = e^T A e with e ~ N(0, C_joint): a weighted sum of χ²_1 with the eigenvalues of
  L^T A L (C_joint = L L^T); :func:`imhof_cdf` is its exact distribution (TV-5c).
* :func:`recursive_forms` runs the library's recursive filters
  (:class:`~skytrack.identify.sequential.SequentialPairTest`, R2-R4) batched over trials (rows);
  the studies check the batch forms against it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import integrate, stats

from skytrack.identify.model import cv_model
from skytrack.identify.sequential import PairForms, SequentialPairTest, merge_order

OBJECT_1 = np.array([0.0, 0.0, 100.0, -50.0])
NDIM = 2
#: h = χ²_4(0.99) and the joint-only statistic's χ²_36(0.99) (TV-5b column headers)
H_99 = float(stats.chi2.ppf(0.99, 4))
JOINT_H_99 = float(stats.chi2.ppf(0.99, 36))
DOF, JOINT_DOF = 4, 36


@dataclass(frozen=True)
class Geometry:
    """Report times and per-axis noise of the two systems (η = system 1, ξ = system 2)."""

    times_eta: tuple[float, ...]
    sigma_eta: float
    times_xi: tuple[float, ...]
    sigma_xi: float

    def merged(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, systems (1/2) and σ of the merged stream in merge order (system 1 first at ties)."""
        time = np.r_[self.times_eta, self.times_xi].astype(float)
        system = np.r_[np.ones(len(self.times_eta), int), np.full(len(self.times_xi), 2)]
        order = merge_order(time, system)
        sigma = np.where(system == 1, self.sigma_eta, self.sigma_xi)
        return time[order], system[order], sigma[order].astype(float)

    @property
    def reports(self) -> int:
        return len(self.times_eta) + len(self.times_xi)


TV5_GEOMETRY = Geometry(tuple(np.arange(10.0)), 50.0, tuple(np.arange(10.0) + 0.3), 20.0)
TV3_GEOMETRY = Geometry((0.0, 1.0, 2.0, 3.0), 50.0, (0.3, 1.3, 2.3, 3.3), 20.0)

#: TV-5b offsets of object 0 from object 1 (state difference at t = 0)
OFFSETS: dict[str, tuple[float, float, float, float]] = {
    "+50 m in x": (50.0, 0.0, 0.0, 0.0),
    "+100 m in x": (100.0, 0.0, 0.0, 0.0),
    "+150 m in x": (150.0, 0.0, 0.0, 0.0),
    "+200 m in x": (200.0, 0.0, 0.0, 0.0),
    "+100 m in x and y": (100.0, 100.0, 0.0, 0.0),
    "+10 m/s in vx": (0.0, 0.0, 10.0, 0.0),
    "+5 m/s in vx": (0.0, 0.0, 5.0, 0.0),
}
#: TV-5b: λ, P_НО at h = χ²_4(0.99), NP h for P_НО = 0.01, P_ПО at that h, joint-only P_НО at
#: χ²_36(0.99), joint-only P_ПО at P_НО = 0.01 (None: "≈1")
TV5B = {
    "+50 m in x": (8.609522, 0.5968379, 1.891399, 0.244275, 0.9053968, 0.064522),
    "+100 m in x": (34.438087, 5.402285e-3, 14.881644, 0.995047, 0.2125455, 0.730442),
    "+150 m in x": (77.485696, 3.029126e-8, 44.515110, None, 5.214158e-4, 0.999682),
    "+200 m in x": (137.752348, 4.743487e-17, 91.242414, None, 1.615252e-9, None),
    "+100 m in x and y": (68.876174, 4.271266e-7, 38.219947, None, 2.266531e-3, 0.998199),
    "+10 m/s in vx": (9.947382, 0.5166102, 2.328567, 0.324427, 0.8806419, 0.081262),
    "+5 m/s in vx": (2.486846, 0.9261686, 0.545655, 0.031093, 0.9772352, 0.018397),
}
TV5B_COLUMNS = ("lambda", "p_incorrect", "np_h", "p_correct_at_np_h", "joint_p_incorrect", "joint_p_correct")
#: TV-5a: separate covariances per axis at t = 9.3 s, [[pos, pos-vel], [pos-vel, vel]]
TV5A = {"radar": ((948.181818, 145.454545), (145.454545, 30.303030)),
        "adsb": ((138.181818, 21.818182), (21.818182, 4.848485))}
TV5A_TIME = 9.3
#: TV-5c: q -> (E Λ, var Λ, P(Λ ≤ χ²_4(0.99)))
TV5C = {0.0: (4.0, 8.0, 0.990000), 1.0: (4.0, 8.002865, 0.989997), 25.0: (4.0, 8.732738, 0.989284),
        100.0: (4.0, 11.181199, 0.986303), 400.0: (4.0, 15.678443, 0.979164)}


# --------------------------------------------------------------------------- quadratic forms


def integrated_noise_covariance(times_a, times_b, q: float, t_ref: float) -> np.ndarray:
    """Cov(p(s), p(t)) of the CV model's position noise accumulated since ``t_ref``: q s²(3t − s)/6, s ≤ t."""
    s = np.asarray(times_a, float)[:, None] - t_ref
    t = np.asarray(times_b, float)[None, :] - t_ref
    low, high = np.minimum(s, t), np.maximum(s, t)
    return q * low ** 2 * (3.0 * high - low) / 6.0


def residual_matrix(times, sigma, q: float, t_ref: float) -> np.ndarray:
    """M of one filter (per axis): its diffuse-start J is z^T M z for its reports ``z`` at ``times``."""
    times = np.asarray(times, float)
    C = integrated_noise_covariance(times, times, q, t_ref) + np.diag(np.broadcast_to(sigma, times.shape) ** 2)
    X = np.column_stack([np.ones_like(times), times - t_ref])
    C_inv = np.linalg.inv(C)
    CX = C_inv @ X
    M = C_inv - CX @ np.linalg.solve(X.T @ CX, CX.T)
    return 0.5 * (M + M.T)


@dataclass(frozen=True)
class QuadraticForms:
    """Per-axis matrices over the merged reports: J_joint = Σ_axes z_a^T joint z_a, and so on."""

    joint: np.ndarray
    eta: np.ndarray
    xi: np.ndarray

    @property
    def statistic(self) -> np.ndarray:
        """A of Λ = z^T A z (20a)."""
        return self.joint - self.eta - self.xi


def quadratic_forms(geometry: Geometry, q: float = 0.0) -> QuadraticForms:
    """The matrices of J_joint, J_η, J_ξ for ``geometry`` with the filters' process noise ``q``."""
    time, system, sigma = geometry.merged()
    t_ref = float(time.min())
    joint = residual_matrix(time, sigma, q, t_ref)
    separate = []
    for s in (1, 2):
        mine = np.flatnonzero(system == s)
        full = np.zeros_like(joint)
        full[np.ix_(mine, mine)] = residual_matrix(time[mine], sigma[mine], q, t_ref)
        separate.append(full)
    return QuadraticForms(joint, *separate)


def evaluate_forms(z: np.ndarray, forms: QuadraticForms) -> dict[str, np.ndarray]:
    """J_joint, J_η, J_ξ and Λ of reports ``z`` ``[N, R, 2]`` (merged order), one value per trial."""
    def quadratic(M):
        return np.einsum("nra,rs,nsa->n", z, M, z, optimize=True)

    joint, eta, xi = quadratic(forms.joint), quadratic(forms.eta), quadratic(forms.xi)
    return {"J_joint": joint, "J_eta": eta, "J_xi": xi, "statistic": joint - eta - xi}


def offset_noncentrality(geometry: Geometry, offset) -> float:
    """λ as μ^T A μ: μ the positions of the offset δ (at t = 0) on the ξ reports (θ = 0, Q = 0)."""
    time, system, _ = geometry.merged()
    delta = np.asarray(offset, float)
    mu = (delta[None, :NDIM] + delta[None, NDIM:] * time[:, None]) * (system == 2)[:, None]
    A = quadratic_forms(geometry).statistic
    return float(np.einsum("ra,rs,sa->", mu, A, mu))


# --------------------------------------------------------------------------- reports


def object_positions(states: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Positions ``[N, R, 2]`` at ``times`` of constant-velocity objects with states ``[N, 4]`` at t = 0."""
    return states[:, None, :NDIM] + states[:, None, NDIM:] * np.asarray(times)[None, :, None]


def noisy_truth(rng: np.random.Generator, trials: int, times: np.ndarray, q: float, start=OBJECT_1) -> np.ndarray:
    """Positions ``[N, R, 2]`` of objects following the CV model with white-noise acceleration ``q``
    (exact discrete steps Q(Δ) between the report times; the truth starts at ``start`` at t = 0)."""
    model = cv_model(NDIM, q)
    states = np.broadcast_to(np.asarray(start, float), (trials, 2 * NDIM)).copy()
    positions = np.empty((trials, len(times), NDIM))
    previous = 0.0
    for k, t in enumerate(times):  # a loop over the report times, every trial at once
        dt = float(t - previous)
        if dt > 0:
            F, Q = model.F(np.array([dt]))[0], model.Q(np.array([dt]))[0]
            states = states @ F.T
            if q > 0:
                states += rng.multivariate_normal(np.zeros(2 * NDIM), Q, size=trials, method="cholesky")
        positions[:, k] = states[:, :NDIM]
        previous = t
    return positions


def draw_reports(rng: np.random.Generator, trials: int, geometry: Geometry = TV5_GEOMETRY, offset=None,
                 q: float = 0.0) -> np.ndarray:
    """Reports ``[N, R, 2]`` in merged order: η of object 1, ξ of object 1 (``offset`` None, θ = 1) or of
    object 0 = object 1 + ``offset`` (state difference at t = 0, both at constant velocity; θ = 0)."""
    time, system, sigma = geometry.merged()
    if q > 0:
        if offset is not None:
            raise ValueError("offsets (theta = 0) are simulated without process noise")
        truth = noisy_truth(rng, trials, time, q)
    else:
        truth = object_positions(OBJECT_1[None, :], time)
    if offset is not None:
        delta = np.asarray(offset, float)
        truth = truth + ((delta[None, :NDIM] + delta[None, NDIM:] * time[:, None]) * (system == 2)[:, None])[None]
    noise = rng.standard_normal((trials, len(time), NDIM)) * sigma[None, :, None]
    return np.broadcast_to(truth, noise.shape) + noise


def recursive_forms(z: np.ndarray, geometry: Geometry, q: float = 0.0, statistic: str = "four-forms",
                    **prior) -> tuple[PairForms, SequentialPairTest]:
    """The library's recursive filters (R2-R4) on reports ``z`` ``[N, R, 2]``, one pair row per trial."""
    time, system, sigma = geometry.merged()
    test = SequentialPairTest(cv_model(NDIM, q), len(z), statistic=statistic, **prior)
    for k in range(len(time)):  # one call per report, all trials at once
        test.add(int(system[k]), time[k], z[:, k], sigma[k] ** 2 * np.eye(NDIM))
    return test.forms(), test


# --------------------------------------------------------------------------- closed forms


def separate_covariances(geometry: Geometry = TV5_GEOMETRY, t: float = TV5A_TIME) -> tuple[np.ndarray, np.ndarray]:
    """P_η and P_ξ ``[4, 4]`` of the separate filters (Q = 0) at the common time ``t``."""
    z = object_positions(OBJECT_1[None, :], geometry.merged()[0])
    _, test = recursive_forms(z, geometry)
    rows = np.array([0])
    return test.eta.estimate_at(rows, t)[1][0], test.xi.estimate_at(rows, t)[1][0]


def closed_form_covariance(times, sigma: float, t: float) -> np.ndarray:
    """TV-5a per axis: σ² [[1/N + τ²/S_tt, τ/S_tt], [τ/S_tt, 1/S_tt]], τ = t − mean(times)."""
    times = np.asarray(times, float)
    s_tt = float(np.sum((times - times.mean()) ** 2))
    tau = t - times.mean()
    return sigma ** 2 * np.array([[1.0 / len(times) + tau ** 2 / s_tt, tau / s_tt], [tau / s_tt, 1.0 / s_tt]])


def closed_form_noncentrality(offset, geometry: Geometry = TV5_GEOMETRY, t: float = TV5A_TIME) -> float:
    """λ = δ^T (P_η + P_ξ)^{-1} δ with δ the state difference at ``t`` (R5, TV-5b)."""
    P_eta, P_xi = separate_covariances(geometry, t)
    delta = np.asarray(offset, float).copy()
    delta[:NDIM] += delta[NDIM:] * t
    return float(delta @ np.linalg.solve(P_eta + P_xi, delta))


def tv5b_row(lam: float) -> dict[str, float]:
    """The TV-5b columns for non-centrality ``lam`` (scipy's χ² and ncχ²)."""
    np_h = float(stats.ncx2.ppf(0.01, DOF, lam))
    joint_np_h = float(stats.ncx2.ppf(0.01, JOINT_DOF, lam))
    return {"lambda": lam, "p_incorrect": float(stats.ncx2.cdf(H_99, DOF, lam)), "np_h": np_h,
            "p_correct_at_np_h": float(stats.chi2.cdf(np_h, DOF)),
            "joint_p_incorrect": float(stats.ncx2.cdf(JOINT_H_99, JOINT_DOF, lam)),
            "joint_p_correct": float(stats.chi2.cdf(joint_np_h, JOINT_DOF))}


def table_tolerance(expected: float, relative: float = 1e-6) -> float:
    """A table value's tolerance: ``relative`` × |value|, or half a unit of its last printed digit when the
    table gives fewer digits than that (e.g. 0.064522 in TV-5b: ±5e-7)."""
    mantissa, _, exponent = repr(float(expected)).partition("e")
    decimals = len(mantissa.partition(".")[2].rstrip("0") or "")
    unit = 10.0 ** (-decimals + (int(exponent) if exponent else 0))
    return max(relative * abs(expected), 0.5 * unit)


# --------------------------------------------------------------------------- exact distribution, Q > 0


def statistic_eigenvalues(geometry: Geometry, q: float) -> np.ndarray:
    """Weights of Λ = Σ w_i χ²_1 under θ = 1 when truth and filters share ``q`` (both axes, TV-5c)."""
    time, _, sigma = geometry.merged()
    t_ref = float(time.min())
    C = integrated_noise_covariance(time, time, q, t_ref) + np.diag(sigma ** 2)
    L = np.linalg.cholesky(C)
    w = np.linalg.eigvalsh(L.T @ quadratic_forms(geometry, q).statistic @ L)
    w = w[np.abs(w) > 1e-10 * np.abs(w).max()]
    return np.repeat(w, NDIM)


def imhof_cdf(x: float, weights: np.ndarray, split: float = 20.0) -> float:
    """P(Σ w_i χ²_1 ≤ x) by Imhof's inversion (weights of either sign).

    1/2 − (1/π) ∫_0^∞ sin θ(u) / (u ρ(u)) du with θ(u) = ½ Σ arctan(w_i u) − ½ x u and
    ρ(u) = Π (1 + w_i² u²)^{1/4}.  Below ``split`` plain quadrature; above it the oscillating
    factor of frequency x/2 is taken out (sin(a − ½xu) = sin a cos ½xu − cos a sin ½xu) and the
    Fourier integrals to infinity use QUADPACK's QAWF.  Agrees with χ²_k to ~1e-11.
    """
    w = np.asarray(weights, float)

    def rho(u: float) -> float:
        return float(np.exp(0.25 * np.sum(np.log1p((w * u) ** 2))))

    def phase(u: float) -> float:
        return 0.5 * float(np.sum(np.arctan(w * u)))

    def head(u: float) -> float:
        return np.sin(phase(u) - 0.5 * x * u) / (u * rho(u)) if u > 0 else 0.5 * (float(np.sum(w)) - x)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        edges = np.linspace(0.0, split, 41)
        total = sum(integrate.quad(head, a, b, limit=200, epsabs=1e-15, epsrel=1e-13)[0]
                    for a, b in zip(edges[:-1], edges[1:]))
        total += integrate.quad(lambda u: np.sin(phase(u)) / (u * rho(u)), split, np.inf, weight="cos",
                                wvar=0.5 * x, limlst=100)[0]
        total -= integrate.quad(lambda u: np.cos(phase(u)) / (u * rho(u)), split, np.inf, weight="sin",
                                wvar=0.5 * x, limlst=100)[0]
    return float(0.5 - total / np.pi)


def exact_moments(weights: np.ndarray) -> tuple[float, float]:
    """Mean Σ w_i and variance 2 Σ w_i² of Σ w_i χ²_1."""
    w = np.asarray(weights, float)
    return float(w.sum()), float(2.0 * np.sum(w ** 2))

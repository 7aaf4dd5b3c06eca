"""Ellipsoidal set-membership (bounded-noise) filter: spec 004 §3.3 I, R11 (containment and the
consistency gate of R20).

Model: ``x_{k+1} = F x_k + w_k`` with ``w_k`` in ``E(0, Q_b)``, ``z_k = H x_k + v_k`` with ``v_k``
in ``E(0, R_b)``, ``E(c, P) = {x: (x - c)^T P^-1 (x - c) <= 1}``.  The estimate is an ellipsoid
``E(x, P)`` guaranteed to contain the state when the bounds hold; ``P`` is a shape matrix, not a
covariance (``Capabilities(has_covariance=False, estimate="set")``).

* predict — outer bound of the Minkowski sum ``F E(x, P) + E(0, Q_b)``:
  ``P^- = (1 + 1/p) A + (1 + p) Q_b`` with ``A = F P F^T``; ``p = sqrt(tr A / tr Q_b)`` minimises
  the trace (closed form), ``criterion="det"`` minimises ``ln det P^-`` by a bounded search in
  ``ln p`` (:func:`minkowski_sum_bound`).
* innovate — ``d^2 = max_eta delta(eta)``: the measurement is consistent with the bounds
  (the two sets intersect) iff ``d^2 < 1`` (R20's gate); ``S = W(eta)`` at the maximising
  ``eta`` so that ``d^2 = nu^T S^-1 nu``.
* update — ``W = H P^- H^T / (1 - eta) + R_b / eta``, ``K = P^- H^T W^-1 / (1 - eta)``,
  ``delta = nu^T W^-1 nu``, ``x = x^- + K nu``, ``P = (1 - delta) / (1 - eta) (I - K H) P^-``
  with ``eta`` minimising ``tr P`` (default) or ``ln det P`` on (0, 1) (tolerance 1e-10).  When
  ``d^2 >= 1`` the bounds are violated: the row's counter goes up, and ``P^-`` is inflated by the
  smallest factor in [1, 1e6] (bisection) that makes ``max_eta delta < 1``.

Every scalar search is per row and vectorised over rows with a fixed number of iterations
(golden section, bisection), so a row's result never depends on the other rows of its batch.
The searches run in coordinates where ``R_b = I`` and ``H P^- H^T`` is diagonal (eigenvalues
``lambda_i``): there ``tr P`` and ``ln det P`` cost O(m) per trial ``eta``.

Helpers: :func:`box_process_bound` (the default ``Q_b``: per-axis acceleration ``|a_i(t)| <=
a_max`` varying within the interval), :func:`constant_input_process_bound` (acceleration
constant over each interval), :func:`two_point_initial_set`, :func:`set_update` (the gain form
for a given ``eta``).  Recorder channels: ``"set_update"`` (eta, delta, inflation, violation per
updated row) and ``"bound_violation"`` (the violating rows, their ``d^2`` and inflation factor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.core import linalg
from skytrack.filters.base import ArrayState, BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.registry import register_filter
from skytrack.models.motion import MotionModel

G0 = 9.80665
CRITERIA = ("trace", "det")
PROCESS_BOUNDS = ("box", "constant")
#: bounded-search tolerance on eta (§3.3 I)
ETA_TOLERANCE = 1e-10
#: largest inflation factor of P^- tried after a bound violation (§3.3 I)
INFLATION_LIMIT = 1e6
#: relative precision of the inflation factor found by bisection
INFLATION_TOLERANCE = 1e-9
#: half-width of the search interval of ln p around the trace-optimal p (criterion "det"), and its tolerance
LOG_P_HALF_WIDTH = 30.0
LOG_P_TOLERANCE = 1e-10
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
#: multiply-adds counted per trial point of a scalar search, per measured component
_SEARCH_MADDS_PER_COMPONENT = 3


def _eigh_madds(n: int, vectors: bool) -> int:
    """Multiply-adds counted for a symmetric eigen-decomposition (R22 has no entry for it).

    Golub & Van Loan: about 9 n^3 flops with eigenvectors, 4 n^3 / 3 for eigenvalues only; a
    multiply-add is two flops.  Rounded up to whole multiply-adds.
    """
    return math.ceil((4.5 if vectors else 2.0 / 3.0) * n**3)


# ---------------------------------------------------------------------------- bounds and helpers
def _steps(dt) -> np.ndarray:
    t = np.atleast_1d(np.asarray(dt, dtype=float))
    if not np.all(np.isfinite(t)) or np.any(t < 0):
        raise ValueError("process bound: time steps must be finite and >= 0")
    return t


def _check_bound_args(a_max: float, ndim: int, order: int) -> None:
    if not (math.isfinite(a_max) and a_max >= 0):
        raise ValueError(f"set-membership: a_max must be finite and >= 0, got {a_max}")
    if not (isinstance(ndim, (int, np.integer)) and ndim >= 1):
        raise ValueError(f"set-membership: ndim must be an integer >= 1, got {ndim!r}")
    if not (isinstance(order, (int, np.integer)) and order >= 1):
        raise ValueError(f"set-membership: order must be an integer >= 1, got {order!r}")


def _input_response(t: np.ndarray, order: int) -> np.ndarray:
    """``g_i = T^(order-i) / (order-i)!``: response of state i to a unit constant input on derivative ``order``."""
    return np.stack([t ** (order - i) / math.factorial(order - i) for i in range(order)], axis=-1)


def box_process_bound(dt, a_max: float, ndim: int, order: int = 2) -> np.ndarray:
    """Default ``Q_b[K, n, n]``: the ellipsoid ``E(0, d diag(h_i^2))`` around the box of increments.

    With the ``order``-th derivative (acceleration for order 2) bounded by ``|a_i(t)| <= a_max``
    on every axis and free to vary within the interval, the increment of state component i of an
    axis lies in ``|.| <= h_i = a_max T^(order-i) / (order-i)!`` (for order 2: ``a_max T^2 / 2`` and
    ``a_max T``).  A box with half-widths ``h_1 .. h_d`` lies in ``E(0, d diag(h^2))``; here
    ``d = n = ndim * order`` (every state component is involved).
    """
    _check_bound_args(a_max, ndim, order)
    t = _steps(dt)
    h = a_max * np.tile(_input_response(t, order), (1, ndim))
    n = ndim * order
    Q = np.zeros((len(t), n, n))
    Q[:, np.arange(n), np.arange(n)] = n * h * h
    return Q


def constant_input_process_bound(dt, a_max: float, ndim: int, order: int = 2) -> np.ndarray:
    """``Q_b[K, n, n] = a_max^2 (I_ndim kron g g^T)``: acceleration constant over each interval.

    The increment is ``G a`` with ``G = I kron g``; for ``|a| <= a_max`` (Euclidean norm of the
    acceleration vector) the set of increments is exactly ``E(0, a_max^2 G G^T)``; one axis gives
    §3.3 I's ``a_max^2 g g^T``.  The matrix is singular (rank ``ndim``).
    """
    _check_bound_args(a_max, ndim, order)
    t = _steps(dt)
    g = _input_response(t, order)
    block = a_max**2 * g[:, :, None] * g[:, None, :]
    n = ndim * order
    Q = np.zeros((len(t), n, n))
    for axis in range(ndim):
        s = slice(axis * order, (axis + 1) * order)
        Q[:, s, s] = block
    return Q


def _golden_minimise(objective, lo: np.ndarray, hi: np.ndarray, width: float, tol: float, madds_per_call: float):
    """Per-row golden-section search of ``objective(points[K]) -> values[K]`` on ``[lo, hi]``.

    The iteration count follows from the common initial ``width`` and ``tol`` only, so every row
    does the same work whatever the batch holds.  Returns the best point and its value.
    """
    iterations = max(1, math.ceil(math.log(tol / width) / math.log(_GOLDEN)))
    lo, hi = lo.astype(float), hi.astype(float)
    c = hi - _GOLDEN * (hi - lo)
    d = lo + _GOLDEN * (hi - lo)
    fc, fd = objective(c), objective(d)
    for _ in range(iterations):
        left = fc < fd
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        new = np.where(left, hi - _GOLDEN * (hi - lo), lo + _GOLDEN * (hi - lo))
        f_new = objective(new)
        c, d, fc, fd = (np.where(left, new, d), np.where(left, c, new),
                        np.where(left, f_new, fd), np.where(left, fc, f_new))
    if linalg.is_counting():
        linalg.count("set_search", len(lo) * (iterations + 2) * madds_per_call)
    best = fc <= fd
    return np.where(best, c, d), np.where(best, fc, fd)


def minkowski_sum_bound(A: np.ndarray, B: np.ndarray, criterion: str = "trace") -> np.ndarray:
    """Outer ellipsoid ``(1 + 1/p) A + (1 + p) B`` of ``E(0, A) + E(0, B)`` (shapes ``[K, n, n]``).

    ``criterion="trace"``: ``p = sqrt(tr A / tr B)`` (minimum trace).  ``"det"``: ``p`` minimises
    ``ln det``, found by golden section on ``ln p`` in ``ln p_trace +- 30`` after simultaneous
    diagonalisation (``A + B = L L^T``, ``alpha`` the eigenvalues of ``L^-1 A L^-T``:
    ``ln det = ln det(A + B) + sum ln((1 + 1/p) alpha_i + (1 + p)(1 - alpha_i))``), so either
    matrix may be singular as long as ``A + B`` is not.  Rows with ``tr B = 0`` give ``A`` exactly
    (the limit ``p -> inf``), rows with ``tr A = 0`` give ``B``.
    """
    if criterion not in CRITERIA:
        raise ValueError(f"set-membership: criterion must be one of {CRITERIA}, got {criterion!r}")
    trA = np.einsum("kii->k", A)
    trB = np.einsum("kii->k", B)
    out = A.copy()
    only_b = (trA <= 0.0) & (trB > 0.0)
    out[only_b] = B[only_b]
    both = (trA > 0.0) & (trB > 0.0)
    if not both.any():
        return out
    a, b = A[both], B[both]
    log_p_trace = 0.5 * np.log(trA[both] / trB[both])
    if criterion == "trace":
        p = np.exp(log_p_trace)
    else:
        n = A.shape[-1]
        Li = linalg.inv(linalg.cholesky(a + b))
        alpha = np.clip(np.linalg.eigvalsh(linalg.sandwich(Li, a)), 0.0, 1.0)
        if linalg.is_counting():
            linalg.count("eigvalsh", len(a) * _eigh_madds(n, vectors=False))

        def log_det(s):
            return np.sum(np.log((1.0 + np.exp(-s))[:, None] * alpha + (1.0 + np.exp(s))[:, None] * (1.0 - alpha)), axis=-1)

        s, _ = _golden_minimise(log_det, log_p_trace - LOG_P_HALF_WIDTH, log_p_trace + LOG_P_HALF_WIDTH,
                                2.0 * LOG_P_HALF_WIDTH, LOG_P_TOLERANCE, _SEARCH_MADDS_PER_COMPONENT * n)
        p = np.exp(s)
    out[both] = linalg.symmetrize((1.0 + 1.0 / p)[:, None, None] * a + (1.0 + p)[:, None, None] * b)
    return out


def two_point_initial_set(z0, z1, dt, R_b, R_b0=None, criterion: str = "trace") -> tuple[np.ndarray, np.ndarray]:
    """Centre ``x[K, 2 ndim]`` and shape ``P`` of the set after two-point initialisation (§3.3 I).

    ``x = [z1, (z1 - z0) / T]`` per axis (axis-major, order 2).  Its error is ``M1 v1 + M0 v0``
    with ``v1`` in ``E(0, R_b)`` (the error of ``z1``) and ``v0`` in ``E(0, R_b0)`` (default
    ``R_b``), ``M1 = I kron [1, 1/T]^T``, ``M0 = I kron [0, -1/T]^T``; ``P`` is the Minkowski-sum bound
    of ``A = M1 R_b M1^T`` and ``B = M0 R_b0 M0^T``.
    """
    z0, z1 = np.atleast_2d(np.asarray(z0, dtype=float)), np.atleast_2d(np.asarray(z1, dtype=float))
    rows, ndim = z1.shape
    T = np.broadcast_to(np.asarray(dt, dtype=float), (rows,))
    if not np.all(np.isfinite(T)) or np.any(T <= 0):
        raise ValueError("two-point initial set: dt must be finite and > 0")
    R1 = np.broadcast_to(np.asarray(R_b, dtype=float), (rows, ndim, ndim))
    R0 = R1 if R_b0 is None else np.broadcast_to(np.asarray(R_b0, dtype=float), (rows, ndim, ndim))
    n = 2 * ndim
    x = np.empty((rows, n))
    x[:, 0::2] = z1
    x[:, 1::2] = (z1 - z0) / T[:, None]
    M1 = np.zeros((rows, n, ndim))
    M0 = np.zeros((rows, n, ndim))
    axes = np.arange(ndim)
    M1[:, 2 * axes, axes] = 1.0
    M1[:, 2 * axes + 1, axes] = (1.0 / T)[:, None]
    M0[:, 2 * axes + 1, axes] = (-1.0 / T)[:, None]
    return x, minkowski_sum_bound(linalg.sandwich(M1, R1), linalg.sandwich(M0, R0), criterion)


def _gain_form(x, P, HP, S0, R_b, nu, eta):
    """Update of §3.3 I for per-row ``eta``: returns ``(x, P, delta)``; ``HP = H P``, ``S0 = H P H^T``."""
    one_minus = 1.0 - eta
    W = S0 / one_minus[:, None, None] + R_b / eta[:, None, None]
    L = linalg.cholesky(W)
    gain_t = linalg.cho_solve(L, HP) / one_minus[:, None, None]  # K^T = W^-1 H P / (1 - eta)
    K = np.swapaxes(gain_t, -1, -2)
    delta = linalg.mahalanobis_chol(nu, L)
    x_new = x + linalg.matvec(K, nu)
    P_new = linalg.symmetrize(((1.0 - delta) / one_minus)[:, None, None] * (P - linalg.matmul(K, HP)))
    return x_new, P_new, delta, K


def set_update(x, P, H, R_b, nu, eta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gain form of the set update for a given ``eta`` per row (§3.3 I): ``(x, P, delta)``.

    ``x[K, n]``, ``P[K, n, n]`` predicted; ``H[K, m, n]``; ``R_b[K, m, m]``; ``nu = z - H x``.
    """
    eta = np.broadcast_to(np.asarray(eta, dtype=float), (len(x),))
    if np.any((eta <= 0.0) | (eta >= 1.0)):
        raise ValueError("set update: eta must lie in (0, 1)")
    HP = linalg.matmul(H, P)
    S0 = linalg.symmetrize(linalg.matmul(HP, np.swapaxes(H, -1, -2)))
    x_new, P_new, delta, _ = _gain_form(x, P, HP, S0, R_b, nu, eta)
    return x_new, P_new, delta


# ---------------------------------------------------------------------------- scalar searches
# In whitened coordinates (R_b = I, H P^- H^T = diag(lam)) with u = (1 - eta) / eta:
#   delta(eta) = (1 - eta) sum nu_i^2 / (lam_i + u),
#   tr P(eta)  = (1 - delta) / (1 - eta) (tr P^- - sum m_i / (lam_i + u)),  m_i = |(T H P^-)_i|^2,
#   ln det P(eta) = n ln(1 - delta) - n ln(1 - eta) + sum ln(u / (lam_i + u)) + ln det P^-.
def _delta(eta, lam, nu2):
    u = (1.0 - eta) / eta
    return (1.0 - eta) * np.sum(nu2 / (lam + u[:, None]), axis=-1)


def _max_delta(lam, nu2):
    """``max_eta delta(eta)`` per row and the maximising ``eta``."""
    rows, m = lam.shape
    eta, value = _golden_minimise(lambda e: -_delta(e, lam, nu2), np.zeros(rows), np.ones(rows), 1.0,
                                  ETA_TOLERANCE, _SEARCH_MADDS_PER_COMPONENT * m)
    return -value, eta


def _best_eta(criterion, lam, nu2, mw, trace0, n):
    rows, m = lam.shape

    def objective(eta):
        u = (1.0 - eta) / eta
        c = lam + u[:, None]
        delta = (1.0 - eta) * np.sum(nu2 / c, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            if criterion == "trace":
                return (1.0 - delta) / (1.0 - eta) * (trace0 - np.sum(mw / c, axis=-1))
            return n * np.log(1.0 - delta) - n * np.log(1.0 - eta) + np.sum(np.log(u[:, None] / c), axis=-1)

    eta, _ = _golden_minimise(objective, np.zeros(rows), np.ones(rows), 1.0, ETA_TOLERANCE,
                              _SEARCH_MADDS_PER_COMPONENT * m)
    return eta


def _inflation(lam, nu2):
    """Smallest factor ``s`` in [1, 1e6] (bisection on ``ln s``) with ``max_eta delta < 1`` for ``s P^-``.

    ``max delta`` decreases with ``s`` (every term ``eta (1 - eta) / (1 - eta + eta s lam)`` does).
    Returns ``s`` and whether the limit was enough.
    """
    top = math.log(INFLATION_LIMIT)
    recovered = _max_delta(lam * INFLATION_LIMIT, nu2)[0] < 1.0
    lo, hi = np.zeros(len(lam)), np.full(len(lam), top)
    for _ in range(math.ceil(math.log2(top / INFLATION_TOLERANCE))):
        mid = 0.5 * (lo + hi)
        ok = _max_delta(lam * np.exp(mid)[:, None], nu2)[0] < 1.0
        hi = np.where(ok, mid, hi)
        lo = np.where(ok, lo, mid)
    return np.exp(hi), recovered


# ---------------------------------------------------------------------------- the filter
@dataclass
class SetMembershipState(ArrayState):
    """Ellipsoids ``E(x[N, n], P[N, n, n])`` and the number of bound violations of each row."""

    x: np.ndarray
    P: np.ndarray
    violations: np.ndarray

    def estimate(self) -> GaussianState:
        """Centre and shape matrix (not a covariance)."""
        return GaussianState(self.x, self.P)

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the set of ``rows`` (e.g. by :func:`two_point_initial_set`); counters are kept."""
        self.x[rows] = x
        self.P[rows] = P


@dataclass(eq=False)
class SetMembershipFilter(BatchFilter):
    """Ellipsoidal set-membership filter (§3.3 I) over a constant-velocity motion's transition.

    ``a_max`` (m/s^2) bounds the acceleration: with ``process_bound="box"`` (default,
    :func:`box_process_bound`) each axis's ``|a_i(t)|``, free to vary within the interval; with
    ``"constant"`` (:func:`constant_input_process_bound`) the norm ``|a|`` of an acceleration held
    constant over each interval (tighter, but not guaranteed for a turn, whose acceleration rotates);
    ``R_b = r_bound_scale * R`` with ``R`` the measurement model's noise (9: the 3-sigma bound of a
    Gaussian error, spec §6); ``criterion`` is ``"trace"`` or ``"det"`` for both steps.
    """

    transition: MotionModel
    a_max: float = 7.0 * G0
    process_bound: str = "box"
    r_bound_scale: float = 9.0
    criterion: str = "trace"

    kind = "set-membership"
    capabilities = Capabilities(has_covariance=False, estimate="set")
    state_type = SetMembershipState

    def __post_init__(self) -> None:
        if self.transition.order != 2:
            raise ValueError("set-membership: the acceleration bounds need a constant-velocity motion "
                             f"(order 2 per axis), got order {self.transition.order}")
        _check_bound_args(self.a_max, self.transition.ndim, 2)
        if self.process_bound not in PROCESS_BOUNDS:
            raise ValueError(f"set-membership: process_bound must be one of {PROCESS_BOUNDS}, got {self.process_bound!r}")
        if not (math.isfinite(self.r_bound_scale) and self.r_bound_scale > 0):
            raise ValueError(f"set-membership: r_bound_scale must be finite and > 0, got {self.r_bound_scale}")
        if self.criterion not in CRITERIA:
            raise ValueError(f"set-membership: criterion must be one of {CRITERIA}, got {self.criterion!r}")

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def initiate(self, x: np.ndarray, P: np.ndarray) -> SetMembershipState:
        x = np.array(x, dtype=float)
        return SetMembershipState(x, np.array(P, dtype=float), np.zeros(len(x), dtype=np.int64))

    def process_bound_matrix(self, dt) -> np.ndarray:
        """``Q_b[K, n, n]`` for steps ``|dt|``."""
        bound = box_process_bound if self.process_bound == "box" else constant_input_process_bound
        return bound(np.abs(np.asarray(dt, dtype=float)), self.a_max, self.transition.ndim, 2)

    # -------------------------------------------------------------------- predict
    def predict(self, state: SetMembershipState, dt, context: dict | None = None) -> SetMembershipState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        F = self.transition.F_batch(np.abs(dt))
        Qb = self.process_bound_matrix(dt)
        backwards = dt < 0
        if backwards.any():
            # x_k = F^-1 (x_{k+1} - w): the set of x_k is F^-1 E(x, P) + F^-1 E(0, Q_b)
            F[backwards] = linalg.inv(F[backwards])
            Qb[backwards] = linalg.sandwich(F[backwards], Qb[backwards])
        A = linalg.sandwich(F, state.P)
        P_pred = minkowski_sum_bound(A, Qb, self.criterion)
        return SetMembershipState(linalg.matvec(F, state.x), P_pred, state.violations.copy())

    # -------------------------------------------------------------------- innovate
    def innovate(self, state: SetMembershipState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        context = context or {}
        if not getattr(model, "linear", True):
            raise ValueError("set-membership: the measurement model must be linear (no range rate)")
        H, R, nu, m = measurement_terms(state.x, z, model, context)
        R_b = self.r_bound_scale * R
        HP = linalg.matmul(H, state.P)
        S0 = linalg.symmetrize(linalg.matmul(HP, np.swapaxes(H, -1, -2)))
        # whitening T with T R_b T^T = I and T S0 T^T = diag(lam)
        Li = linalg.inv(linalg.cholesky(R_b))
        lam, U = np.linalg.eigh(linalg.sandwich(Li, S0))
        dim = H.shape[-2]
        if linalg.is_counting():
            linalg.count("eigh", len(H) * _eigh_madds(dim, vectors=True))
        T = linalg.matmul(np.swapaxes(U, -1, -2), Li)
        lam = np.clip(lam, 0.0, None)
        nu_w = linalg.matvec(T, nu)
        Y = linalg.matmul(T, HP)
        mw = np.sum(Y * Y, axis=-1)
        if linalg.is_counting():
            linalg.count("set_whitened_norms", Y.size)
        _, eta = _max_delta(lam, nu_w * nu_w)
        S = S0 / (1.0 - eta)[:, None, None] + R_b / eta[:, None, None]
        L = linalg.cholesky(S)
        d2 = linalg.mahalanobis_chol(nu, L)
        logdet = linalg.logdet_chol(L)
        # a set filter has no likelihood: this is the formal Gaussian value of (d2, S)
        loglik = linalg.gaussian_loglik(d2, logdet, m)
        extra = {"HP": HP, "S0": S0, "lam": lam, "nu_w": nu_w, "mw": mw}
        return Innovation(nu, S, L, d2, logdet, loglik, m, H, R_b, state, extra)

    # -------------------------------------------------------------------- update
    def update(self, state: SetMembershipState, z: np.ndarray, innovation: Innovation
               ) -> tuple[SetMembershipState, UpdateStats]:
        predicted = innovation.predicted
        extra = innovation.extra
        rows = len(predicted)
        lam, nu2, mw = extra["lam"], extra["nu_w"] ** 2, extra["mw"]
        violated = innovation.d2 >= 1.0
        scale = np.ones(rows)
        recovered = np.ones(rows, dtype=bool)
        if violated.any():
            scale[violated], recovered[violated] = _inflation(lam[violated], nu2[violated])
        P = predicted.P * scale[:, None, None]
        HP = extra["HP"] * scale[:, None, None]
        S0 = extra["S0"] * scale[:, None, None]
        lam = lam * scale[:, None]
        mw = mw * (scale * scale)[:, None]
        trace0 = np.einsum("kii->k", P)
        eta = _best_eta(self.criterion, lam, nu2, mw, trace0, predicted.x.shape[-1])
        x_new, P_new, delta, K = _gain_form(predicted.x, P, HP, S0, innovation.R, innovation.nu, eta)
        stuck = ~recovered
        if stuck.any():
            # even 1e6 P^- does not reach the measurement: keep the inflated prediction
            x_new[stuck] = predicted.x[stuck]
            P_new[stuck] = P[stuck]
        violations = predicted.violations + violated.astype(np.int64)
        if self.recorder.active:
            all_rows = np.arange(rows)
            self.recorder.record("set_update", all_rows, eta=eta, delta=delta, inflation=scale, violation=violated)
            if violated.any():
                self.recorder.record("bound_violation", all_rows[violated], d2=innovation.d2[violated],
                                     inflation=scale[violated], recovered=recovered[violated])
        stats = UpdateStats(innovation.d2 / innovation.m,
                            {"eta": eta, "delta": delta, "violation": violated, "inflation": scale})
        return SetMembershipState(x_new, P_new, violations), stats


@register_filter("set-membership")
def _set_membership(motion: MotionModel, compiled: bool = True, a_max: float = 7.0 * G0, process_bound: str = "box",
                    r_bound_scale: float = 9.0, criterion: str = "trace") -> SetMembershipFilter:
    """Set-membership filter on a constant-velocity ``motion`` (``compiled`` is accepted: numpy only)."""
    return SetMembershipFilter(motion, a_max=a_max, process_bound=process_bound, r_bound_scale=r_bound_scale,
                               criterion=criterion)

"""Variable-dimension (VD) filter of spec 004 §3.3 J (Bar-Shalom & Birmiwal 1982), requirement R12.

State layout: m = 3 states per axis, axis-major (``[x, vx, ax, y, vy, ay, z, vz, az]`` for 3 axes;
1 and 2 axes work the same).  Two models, both embedded in m = 3 (§3.3 B):

* quiescent: CV with DWNA noise ``sigma_cv`` (``F_cv = [[1, T, 0], [0, 1, 0], [0, 0, 0]]``,
  ``g = [T^2/2, T, 0]``);
* manoeuvre: CA with DWPA noise ``sigma_ca`` (``g = [T^2/2, T, 1]``).

Detector (CV mode): fading NIS ``u_k = rho u_{k-1} + eps_k``; a manoeuvre is declared when
``u_k > c chi2_d^-1(1 - P_fa)``, ``c = 1/(1+rho)``, ``d = n_z (1+rho)/(1-rho)``
(:func:`~skytrack.filters.alpha_beta_gains.detector_threshold`, shared with R3's manoeuvre
gains).  On detection at scan k the acceleration is assumed to have started at ``k-s-1``
(window ``s = round(1/(1-rho))``): the CV estimate at ``k-s-1`` and the measurement ``z(k-s)`` give ``[p', v', a] = calM [z, p, v]`` per axis and
``P' = calM blockdiag(R, P_pv) calM^T`` (:func:`onset_reinitialisation`), then ``z(k-s+1..k)`` are
re-filtered with CA.  Each row keeps the last ``s + 1`` estimates, measurements, their R and
time steps in fixed-size per-row buffers (slot 0 newest).  While fewer than ``s + 1`` scans
exist, the window is what there is (``w = min(s, k - 1)``), so a detection is never deferred;
a window whose onset measurement was reached by a zero step (two-point acceleration undefined)
is shortened to the longest one that was not.
CA mode returns to CV when the acceleration is insignificant,
``sum_{last s scans} a^T P_aa^-1 a <= chi2_{n_a s}^-1(0.95)`` (:func:`return_threshold`).  The
spec does not say when the test starts.  By default (``count_refiltered=False``) it starts once
s scans have been filtered in CA mode after the detection, so its window never holds the
re-filtered scans: their acceleration rests on the two-point re-initialisation (variance at
least 4R/T^4), so they look insignificant, and counting them (``count_refiltered=True``: the test
starts on the scan after the detection) sends the filter back to CV one scan after most
detections in a 5 g turn and re-detects a few scans later.  On a return ``u`` is reset to 0
and the acceleration is dropped by the next prediction, whose ``F_cv`` has a zero acceleration
column, which gives exactly the spec's CV prediction from the estimate with the acceleration
zeroed.  The estimate of the return scan itself keeps the CA numbers, so that a measurement
without information (huge R) never changes the estimate.

Acceleration in CV mode.  The embedded CV model leaves the acceleration entries at zero with
zero covariance, which would make the reported covariance singular.  skytrack reports, in CV
mode, the acceleration the DWNA model assumes for the coming interval: zero mean, variance
``sigma_cv^2`` per axis, uncorrelated with position and velocity.  It is the quiescent Q's
acceleration diagonal; F_cv's zero acceleration column keeps it
out of every position/velocity number, which are exactly those of the spec's CV filter.

Matched motion (``matched_motion``, the conformance suite's truth model): the motion under which
the quiescent filter is exactly consistent, :class:`QuiescentAccelerationAxis` with
``sigma = sigma_cv`` on every axis -- DWNA position and velocity whose acceleration entry is the
acceleration of the coming interval, a fresh N(0, sigma_cv^2) sample at every scan.  VD's CV-mode
estimate (acceleration 0, variance sigma_cv^2, uncorrelated) is then the exact conditional
distribution of the truth (false alarms aside).

Measurements: positions only (``H`` selects the positions; e.g.
:class:`~skytrack.models.converted.ConvertedPositionModel` without range rate), since the
re-initialisation reads ``z`` as a position.  A backward step (``dt < 0``) uses ``F(dt)`` and
``Q(|dt|)``.  Diagnostics: recorder channel ``"switch"`` (rows, ``mode`` 1 = manoeuvre /
0 = quiescent, ``scan`` = the row's number of updates, ``refiltered`` = scans re-filtered at the
detection, 0 on a return)
and, when a recorder is active, ``"detector"`` (rows, ``fading_nis``, ``mode``) every update.
All matrix products go through :mod:`skytrack.core.linalg` (R2, R22).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from skytrack.core.chi2 import chi2_quantile
from skytrack.core import linalg
from skytrack.filters.alpha_beta_gains import detector_threshold, detector_window
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.models.embedding import EmbeddedAxis
from skytrack.models.motion import AxisModel, MotionModel, _as_steps, block_diag_batch
from skytrack.models.polynomial import PolynomialAxis

__all__ = ["detector_threshold", "detector_window", "return_threshold", "onset_reinitialisation",
           "QuiescentAccelerationAxis", "VariableDimensionFilter", "VariableDimensionState"]


#: states per axis of the spec 004 manoeuvre filters (position, velocity, acceleration)
ORDER = 3
#: probability of the acceleration-significance test that ends a manoeuvre (§3.3 J)
RETURN_PROBABILITY = 0.95


# ---------------------------------------------------------------------------- thresholds
def return_threshold(n_a: int, window: int) -> float:
    """``chi2_{n_a s}^-1(0.95)``: below it the summed acceleration significance ends a manoeuvre."""
    return float(chi2_quantile(RETURN_PROBABILITY, n_a * window))


# ---------------------------------------------------------------------------- models
def embedded_axis_models(dt: np.ndarray, sigma_cv: float, sigma_ca: float) -> dict[str, np.ndarray]:
    """Per-axis m = 3 matrices ``[K, 3, 3]`` of the quiescent and manoeuvre models and the input gain.

    ``F_cv``, ``Q_cv``: CV/DWNA embedded (spec models, :mod:`skytrack.models.embedding`; zero
    acceleration rows); ``F_ca``, ``Q_ca``: DWPA; ``G``: ``[T^2/2, T, 0]`` (DWNA gain, the input
    gain of §3.3 K).
    A negative step uses ``F(dt)`` (the polynomial ``F(-T) = F(T)^-1``) and ``Q(|dt|)``.
    This is the one place where the models are built.
    """
    dt = np.asarray(dt, dtype=float)
    step = np.abs(dt)
    cv = EmbeddedAxis(PolynomialAxis(2, "piecewise_constant", sigma_cv), ORDER)
    ca = PolynomialAxis(3, "wiener_increment", sigma_ca)
    # odd powers of T change sign backwards: F(-T) = D F(T) D, g(-T) = D g(T), D = diag(1, -1, 1)
    sign = np.where(dt < 0, -1.0, 1.0)[..., None]
    D = np.concatenate([np.ones_like(sign), sign, np.ones_like(sign)], axis=-1)
    pattern = D[..., :, None] * D[..., None, :]
    G = np.zeros(step.shape + (ORDER,))
    G[..., :2] = PolynomialAxis(2, "piecewise_constant", 1.0).noise_gain(step)
    return {"F_cv": cv.F_batch(step) * pattern, "Q_cv": cv.Q_batch(step), "F_ca": ca.F_batch(step) * pattern,
            "Q_ca": ca.Q_batch(step), "G": G * D}


@dataclass(frozen=True)
class QuiescentAccelerationAxis(AxisModel):
    """One axis of the quiescent (DWNA) model of §3.3 J-L in the m = 3 layout, with the acceleration
    entry meaning the acceleration of the coming interval: the matched truth model of the manoeuvre
    detectors (their ``matched_motion``).

    ``x_{k+1} = [p + T v + T^2/2 a_k, v + T a_k, a_{k+1}]`` with ``a_{k+1} ~ N(0, sigma^2)`` fresh at
    every step: ``F = [[1, T, T^2/2], [0, 1, T], [0, 0, 0]]``, ``Q = diag(0, 0, sigma^2)``.  Position
    and velocity follow DWNA with ``sigma_w = sigma`` exactly (``g a_k`` with ``g = [T^2/2, T]``), and
    the acceleration at scan k is independent of everything before it, which is what the
    filters report in quiet flight (mean 0 or ``u_app``, variance ``sigma^2``, uncorrelated with
    position and velocity).  A zero step is no interval: ``F(0) = I``, ``Q(0) = 0``.  Steps must be
    >= 0 (a truth model, not a filter's prediction).
    """

    sigma: float = 1.0
    order = ORDER

    def __post_init__(self):
        if not (np.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"quiescent acceleration axis: sigma must be finite and >= 0, got {self.sigma}")

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        F = PolynomialAxis(ORDER).F_batch(t)
        F[..., 2, 2] = np.where(t > 0, 0.0, 1.0)
        return F

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        Q = np.zeros(t.shape + (ORDER, ORDER))
        Q[..., 2, 2] = np.where(t > 0, self.sigma**2, 0.0)
        return Q


def stack_axes(block: np.ndarray, ndim: int) -> np.ndarray:
    """The per-axis block ``[K, 3, 3]`` repeated on ``ndim`` axes, axis-major ``[K, 3 ndim, 3 ndim]``."""
    return block_diag_batch([block] * ndim)


def check_order3(motion: MotionModel, kind: str) -> int:
    """``motion.ndim`` if the motion has 3 states per axis, else ValueError naming the family."""
    if motion.order != ORDER:
        raise ValueError(f"{kind}: needs a motion with 3 states per axis (position, velocity, acceleration; "
                         f"spec 004 m = 3 embedding), got order {motion.order}")
    return motion.ndim


# ---------------------------------------------------------------------------- shared KF steps
def innovate_linear(state: GaussianState, z: np.ndarray, model, context: dict | None, kind: str) -> Innovation:
    """Innovation of a position-only linear measurement (the measurement model forms ``nu``, H, R)."""
    H, R, nu, _ = measurement_terms(state.x, z, model, context)
    ndim = state.x.shape[1] // ORDER
    if H.shape[1] != ndim or not np.array_equal(H, np.broadcast_to(position_selector(ndim), H.shape)):
        raise ValueError(f"{kind}: the measurement must be the {ndim} positions (H selecting them), "
                         f"got H of shape {H.shape[1:]}")
    S = linalg.sandwich(H, state.P, R)
    L = linalg.cholesky(S)
    d2 = linalg.mahalanobis_chol(nu, L)
    logdet = linalg.logdet_chol(L)
    m = np.full(len(nu), H.shape[1])
    return Innovation(nu, S, L, d2, logdet, linalg.gaussian_loglik(d2, logdet, m), m, H, R, state)


def kalman_update(x, P, H, R, nu, L, frozen=None):
    """Gain ``K = P H^T S^-1`` (from the Cholesky factor ``L`` of S) and the Joseph-form update:
    ``(x, P, K, I - K H)``.  ``frozen``: state indices whose gain rows are zero (Schmidt's consider
    update: those entries keep their value and covariance, their uncertainty still counts in S
    and in the cross-covariances; the Joseph form is exact for any gain)."""
    PHt = linalg.matmul(P, np.swapaxes(H, -1, -2))
    K = np.swapaxes(linalg.cho_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)
    if frozen is not None:
        K[:, frozen, :] = 0.0
    x_new = x + linalg.matvec(K, nu)
    A = np.eye(x.shape[-1]) - linalg.matmul(K, H)
    return x_new, linalg.sandwich(A, P, linalg.sandwich(K, R)), K, A


def position_selector(ndim: int) -> np.ndarray:
    H = np.zeros((ndim, ORDER * ndim))
    H[np.arange(ndim), np.arange(ndim) * ORDER] = 1.0
    return H


def acceleration_index(ndim: int) -> np.ndarray:
    return np.arange(ndim) * ORDER + 2


def position_velocity_index(ndim: int) -> np.ndarray:
    return np.sort(np.concatenate([np.arange(ndim) * ORDER, np.arange(ndim) * ORDER + 1]))


# ---------------------------------------------------------------------------- re-initialisation
def onset_reinitialisation(z, R, x, P, dt):
    """Manoeuvre-onset re-initialisation of §3.3 J (TV14), batched: ``(x'[K, 3n], P'[K, 3n, 3n])``.

    ``x``, ``P``: the CV estimate at ``k-s-1`` in the m = 3 layout (only position and velocity
    are used); ``z[K, n]``, ``R[K, n, n]``: the measurement of ``k-s``; ``dt[K]`` the step between
    them.  Per axis ``a = (2/T^2)(z - p - T v)``, ``v' = v + T a``, ``p' = z``, i.e.
    ``calM = [[1, 0, 0], [2/T, -2/T, -1], [2/T^2, -2/T^2, -2/T]]`` on ``[z, p, v]``, and
    ``P' = calM blockdiag(R, P_pv) calM^T`` (z independent of the old estimate).
    """
    z, R, x, P = (np.asarray(a, dtype=float) for a in (z, R, x, P))
    T = np.asarray(dt, dtype=float)
    count, ndim = z.shape
    pv = position_velocity_index(ndim)
    # inputs [z_1..z_n, p_1, v_1, ..., p_n, v_n]; outputs axis-major [p', v', a'] per axis
    M = np.zeros((count, ORDER * ndim, 3 * ndim))
    for axis in range(ndim):
        row, zc, pc, vc = ORDER * axis, axis, ndim + 2 * axis, ndim + 2 * axis + 1
        M[:, row, zc] = 1.0
        M[:, row + 1, zc], M[:, row + 1, pc], M[:, row + 1, vc] = 2.0 / T, -2.0 / T, -1.0
        M[:, row + 2, zc], M[:, row + 2, pc], M[:, row + 2, vc] = 2.0 / T**2, -2.0 / T**2, -2.0 / T
    inputs = np.concatenate([z, x[:, pv]], axis=1)
    cov = np.zeros((count, 3 * ndim, 3 * ndim))
    cov[:, :ndim, :ndim] = R
    cov[:, ndim:, ndim:] = P[:, pv[:, None], pv[None, :]]
    return linalg.matvec(M, inputs), linalg.sandwich(M, cov)


def acceleration_significance(x: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``eps_a = a^T P_aa^-1 a`` of the acceleration components (§3.3 J)."""
    acc = acceleration_index(x.shape[1] // ORDER)
    L = linalg.cholesky(P[:, acc[:, None], acc[None, :]])
    return linalg.mahalanobis_chol(x[:, acc], L)


# ---------------------------------------------------------------------------- state
@dataclass
class VariableDimensionState(GaussianState):
    """VD rows: estimate, mode, detector, scan count and the per-row buffers of the last scans.

    ``history_*[N, s+1, ...]``: slot j holds scan ``k-1-j`` after ``k-1`` updates (slot 0 newest):
    the estimate (``x``, ``P``), its measurement (``z``, ``R``) and the time step that led to it
    (``dt``; the initial estimate is scan 0, without measurement).  ``significance[N, s]``: the
    acceleration significance of the last s scans in CA mode (slot 0 newest), of which the first
    ``ca_scans`` (at most s) hold values.
    """

    manoeuvre: np.ndarray
    fading_nis: np.ndarray
    scan: np.ndarray
    pending_dt: np.ndarray
    history_x: np.ndarray
    history_P: np.ndarray
    history_z: np.ndarray
    history_R: np.ndarray
    history_dt: np.ndarray
    significance: np.ndarray
    ca_scans: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, self.P)


def _push(buffer: np.ndarray, newest: np.ndarray) -> np.ndarray:
    """The buffer shifted by one slot with ``newest`` in slot 0 (the oldest slot drops out)."""
    return np.concatenate([newest[:, None], buffer[:, :-1]], axis=1)


# ---------------------------------------------------------------------------- filter
@dataclass(eq=False)
class VariableDimensionFilter(BatchFilter):
    """VD filter (§3.3 J, R12): CV/DWNA quiescent, CA/DWPA manoeuvre model, fading-NIS detector."""

    ndim: int
    sigma_cv: float = 1.0
    sigma_ca: float = 8.0
    rho: float = 0.8
    p_fa: float = 0.01
    window: int | None = None
    count_refiltered: bool = False

    kind = "variable-dimension"
    capabilities = Capabilities()
    state_type = VariableDimensionState

    def __post_init__(self) -> None:
        if self.ndim not in (1, 2, 3):
            raise ValueError(f"variable-dimension: ndim must be 1, 2 or 3, got {self.ndim!r}")
        for name in ("sigma_cv", "sigma_ca"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"variable-dimension: {name} must be finite and > 0, got {value}")
        self.threshold = detector_threshold(self.ndim, self.rho, self.p_fa)
        if self.window is None:
            self.window = detector_window(self.rho)
        if not (isinstance(self.window, (int, np.integer)) and self.window >= 1):
            raise ValueError(f"variable-dimension: window s must be an integer >= 1, got {self.window!r}")
        self.window = int(self.window)
        self.return_level = return_threshold(self.ndim, self.window)

    @property
    def state_dim(self) -> int:
        return ORDER * self.ndim

    @property
    def matched_motion(self) -> MotionModel:
        """The truth model of quiet flight on which this filter is consistent (module docstring)."""
        return MotionModel([QuiescentAccelerationAxis(self.sigma_cv)] * self.ndim)

    # -------------------------------------------------------------------- initiate
    def initiate(self, x: np.ndarray, P: np.ndarray) -> VariableDimensionState:
        """Rows in CV mode at scan 0 with the given estimate (the first CV prediction drops its acceleration)."""
        x, P = np.array(x, dtype=float), np.array(P, dtype=float)
        count, n, s = len(x), self.state_dim, self.window
        history_x = np.zeros((count, s + 1, n))
        history_P = np.zeros((count, s + 1, n, n))
        history_x[:, 0], history_P[:, 0] = x, P
        return VariableDimensionState(
            x, P, np.zeros(count, bool), np.zeros(count), np.zeros(count, np.int64), np.zeros(count),
            history_x, history_P, np.zeros((count, s + 1, self.ndim)), np.zeros((count, s + 1, self.ndim, self.ndim)),
            np.zeros((count, s + 1)), np.zeros((count, s)), np.zeros(count, np.int64))

    # -------------------------------------------------------------------- predict
    def _transition(self, dt: np.ndarray, manoeuvre: np.ndarray):
        models = embedded_axis_models(dt, self.sigma_cv, self.sigma_ca)
        pick = manoeuvre[:, None, None]
        F = np.where(pick, models["F_ca"], models["F_cv"])
        Q_cv = models["Q_cv"]
        Q_cv[..., 2, 2] += self.sigma_cv**2  # the quiescent acceleration (module docstring)
        Q = np.where(pick, models["Q_ca"], Q_cv)
        return stack_axes(F, self.ndim), stack_axes(Q, self.ndim)

    def _predict_arrays(self, x, P, dt, manoeuvre):
        F, Q = self._transition(dt, manoeuvre)
        return linalg.matvec(F, x), linalg.sandwich(F, P, Q)

    def predict(self, state: VariableDimensionState, dt, context: dict | None = None) -> VariableDimensionState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),)).astype(float)
        x, P = self._predict_arrays(state.x, state.P, dt, state.manoeuvre)
        # a zero step is no scan interval: it keeps a CA estimate whose row has just returned to CV
        # (F_cv(0) = diag(1, 1, 0) would drop its acceleration before any time has passed)
        still = dt == 0.0
        x = np.where(still[:, None], state.x, x)
        P = np.where(still[:, None, None], state.P, P)
        return dataclasses.replace(state, x=x, P=P, pending_dt=state.pending_dt + dt)

    # -------------------------------------------------------------------- innovate / update
    def innovate(self, state: VariableDimensionState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        return innovate_linear(state, z, model, context, self.kind)

    def update(self, state: VariableDimensionState, z: np.ndarray,
               innovation: Innovation) -> tuple[VariableDimensionState, UpdateStats]:
        pred: VariableDimensionState = innovation.predicted
        z = np.asarray(z, dtype=float)
        x, P, _, _ = kalman_update(pred.x, pred.P, innovation.H, innovation.R, innovation.nu, innovation.chol)
        rows = len(x)
        scan = pred.scan + 1
        manoeuvre = pred.manoeuvre.copy()
        quiet = ~pred.manoeuvre
        fading = np.where(quiet, self.rho * pred.fading_nis + innovation.d2, pred.fading_nis)
        significance, ca_scans = pred.significance, pred.ca_scans

        # CA rows: acceleration significance of this scan, and the return test
        if pred.manoeuvre.any():
            ca = np.flatnonzero(pred.manoeuvre)
            significance, ca_scans = significance.copy(), ca_scans.copy()
            significance[ca] = _push(significance[ca], acceleration_significance(x[ca], P[ca]))
            ca_scans[ca] = np.minimum(ca_scans[ca] + 1, self.window)
            full = ca_scans[ca] >= self.window
            back = ca[full & (significance[ca].sum(axis=1) <= self.return_level)]
            if len(back):
                manoeuvre[back] = False
                fading[back] = 0.0
                significance[back] = 0.0
                ca_scans[back] = 0
                self.recorder.record("switch", back, mode=np.zeros(len(back), np.int64), scan=scan[back],
                                     refiltered=np.zeros(len(back), np.int64))

        # CV rows over the threshold: re-initialise at the assumed onset and re-filter with CA
        window = self._windows(pred)
        detect = np.flatnonzero(quiet & (fading > self.threshold) & (window >= 0))
        if len(detect):
            x, P, significance, ca_scans = x.copy(), P.copy(), significance.copy(), ca_scans.copy()
            x[detect], P[detect], significance[detect], refiltered = self._refilter(
                pred.take(detect), z[detect], innovation.R[detect], window[detect])
            ca_scans[detect] = refiltered if self.count_refiltered else 0
            manoeuvre[detect] = True
            self.recorder.record("switch", detect, mode=np.ones(len(detect), np.int64), scan=scan[detect],
                                 refiltered=refiltered)
        if self.recorder.active:
            self.recorder.record("detector", np.arange(rows), fading_nis=fading, mode=manoeuvre.astype(np.int64))

        new = VariableDimensionState(
            x, P, manoeuvre, fading, scan, np.zeros(rows),
            _push(pred.history_x, x), _push(pred.history_P, P), _push(pred.history_z, z),
            _push(pred.history_R, innovation.R), _push(pred.history_dt, pred.pending_dt), significance, ca_scans)
        return new, UpdateStats(innovation.d2 / innovation.m)

    def _windows(self, pred: VariableDimensionState) -> np.ndarray:
        """Re-filtering window w per row: ``min(s, k-1)``, shortened to the longest one whose onset
        measurement was reached by a nonzero step (the two-point acceleration divides by it); -1
        when there is none.  Ages as in :meth:`_refilter`."""
        steps = np.concatenate([pred.pending_dt[:, None], pred.history_dt[:, : self.window]], axis=1)
        ages = np.arange(self.window + 1)
        usable = (ages[None, :] <= np.minimum(pred.scan, self.window)[:, None]) & (steps != 0.0)
        return np.where(usable.any(axis=1), self.window - np.argmax(usable[:, ::-1], axis=1), -1)

    def _refilter(self, pred: VariableDimensionState, z: np.ndarray, R: np.ndarray, w: np.ndarray):
        """Re-initialisation and CA re-filtering of the detecting rows (masked over their windows w).

        Index by age a (scans before the current one): the measurement, R and step of age a are
        the current ones for a = 0 and history slot a-1 otherwise; the estimate of age a is
        history slot a-1.  Re-initialise from the estimate of age w+1 and the measurement of age w,
        then filter ages w-1 .. 0.
        """
        s, count = self.window, len(pred)
        rows = np.arange(count)
        meas_z = np.concatenate([z[:, None], pred.history_z[:, :s]], axis=1)
        meas_R = np.concatenate([R[:, None], pred.history_R[:, :s]], axis=1)
        meas_dt = np.concatenate([pred.pending_dt[:, None], pred.history_dt[:, :s]], axis=1)
        x, P = onset_reinitialisation(meas_z[rows, w], meas_R[rows, w], pred.history_x[rows, w],
                                      pred.history_P[rows, w], meas_dt[rows, w])
        H = np.broadcast_to(position_selector(self.ndim), (count, self.ndim, self.state_dim))
        significance = np.zeros((count, s))
        always = np.ones(count, bool)
        for age in range(s - 1, -1, -1):
            active = age < w
            if not active.any():
                continue
            xp, Pp = self._predict_arrays(x, P, meas_dt[:, age], always)
            nu = meas_z[:, age] - linalg.matvec(H, xp)
            L = linalg.cholesky(linalg.sandwich(H, Pp, meas_R[:, age]))
            xu, Pu, _, _ = kalman_update(xp, Pp, H, meas_R[:, age], nu, L)
            x = np.where(active[:, None], xu, x)
            P = np.where(active[:, None, None], Pu, P)
            if self.count_refiltered:
                significance[active, age] = acceleration_significance(x[active], P[active])
        return x, P, significance, w.astype(np.int64)


# Imported here, after the shared pieces: importing the registry imports every filter module, and the
# sibling modules of spec 004 §3.3 J-L import these pieces whichever module loads first.
from skytrack.filters.registry import register_filter  # noqa: E402


@register_filter("variable-dimension")
def _variable_dimension(motion: MotionModel, compiled: bool = True, sigma_cv: float = 1.0, sigma_ca: float = 8.0,
                        rho: float = 0.8, p_fa: float = 0.01, window: int | None = None,
                        count_refiltered: bool = False) -> VariableDimensionFilter:
    """VD filter on the axes of an order-3 ``motion`` (only its number of axes is used; the quiescent
    and manoeuvre models are the spec's CV/DWNA and CA/DWPA).  ``compiled`` is accepted and ignored:
    the family has no compiled kernel."""
    return VariableDimensionFilter(check_order3(motion, "variable-dimension"), sigma_cv, sigma_ca, rho, p_fa, window,
                                   count_refiltered)

"""Piecewise-constant gain Kalman filter (spec 004 §3.3 H, R10; the paper's item 5).

The optimal gain ``K = P^- H^T (H P^- H^T + R)^-1`` is recomputed at the scans k with
``(k - 1) mod N = 0`` (k = 1 is a row's first update, counted per row) and held for the next
N - 1 scans.  N = 1 is the Kalman filter (TV10, TV18 d).  Two covariance modes:

* ``"joseph"`` (default): the exact covariance of the suboptimal filter, Joseph form
  ``(I - K H) P^- (I - K H)^T + K R K^T`` every scan, so only the gain computation is saved on
  hold scans (:class:`PiecewiseGainState`).
* ``"offline"``: covariances and gains come from a schedule precomputed once for a constant step
  T, noise R, process-noise factor and measurement matrix H (:class:`OfflineGainState`); the
  online cost is the state update ``x^- = F x``, ``x = x^- + K nu`` plus ``d^2`` from the scheduled
  Cholesky factor of S.  A schedule starts at a row's predicted covariance ``P^-`` and held gain,
  runs the recursion above until a recomputed gain differs from the previous recomputed one by
  less than 1e-9 (relative to its largest entry) and repeats its last N scans thereafter (at most
  ``horizon`` scans are computed; a schedule cut there repeats its last N scans too).  It is
  rebuilt from the row's current ``P^-`` when the step, ``R`` or the process-noise factor
  (``context["q_scale"]``) changes by more than 1 % (``R`` in Frobenius norm) or ``H`` changes;
  the first scan of a row predicts its covariance online.  Schedules are cached in the filter by
  their exact inputs (rows with the same inputs, e.g. Monte Carlo runs, share one; the cache only
  memoises a deterministic function of the state).  Steps must not add up to a negative time and the
  measurement model must be linear (ValueError otherwise).

The gain used goes to the recorder channel ``"gain"`` (``K[N, n, m]``).  Predict and innovate of the
joseph mode are those of the composed :class:`~skytrack.filters.kalman.KalmanFilter` (compiled when
``compiled=True``); the measurement must have one component per axis (the converted positions).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats, measurement_terms
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.per_axis import RecorderSharing, axis_transitions, row_scale
from skytrack.filters.registry import register_filter
from skytrack.models.motion import MotionModel

COVARIANCE_MODES = ("joseph", "offline")
#: relative change of T, R or the process-noise factor that makes the offline schedule stale (spec: 1 %)
SCHEDULE_TOLERANCE = 0.01
#: relative change of the recomputed gain below which the schedule is periodic (spec: 1e-9)
GAIN_CONVERGENCE = 1e-9
SCHEDULE_FIELDS = ("P_pred", "S", "chol", "logdet", "K", "P_post")
#: ``sched_T`` of a row without a valid schedule (steps are >= 0; a schedule may have T = 0)
NO_SCHEDULE = -1.0


@dataclass
class PiecewiseGainState(GaussianState):
    """Gaussian state, the held gain ``K[N, n, m]`` and the number of updates per row."""

    K: np.ndarray
    scans: np.ndarray


@dataclass
class OfflineGainState(PiecewiseGainState):
    """Plus the time since the last update, the last prediction's process-noise factor, and the
    origin of the row's schedule: predicted covariance, held gain, scan index, T, R, factor, H."""

    elapsed: np.ndarray
    scale: np.ndarray
    sched_P: np.ndarray
    sched_K: np.ndarray
    sched_k0: np.ndarray
    sched_T: np.ndarray
    sched_R: np.ndarray
    sched_scale: np.ndarray
    sched_H: np.ndarray


def _relative_change(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    axes = tuple(range(1, new.ndim))
    diff = np.sqrt(np.sum((new - old) ** 2, axis=axes)) if axes else np.abs(new - old)
    size = np.sqrt(np.sum(old**2, axis=axes)) if axes else np.abs(old)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(diff == 0.0, 0.0, diff / size)


@dataclass(eq=False)
class PiecewiseGainFilter(RecorderSharing, BatchFilter):
    """Kalman filter whose gain is recomputed every ``N`` scans and held in between (§3.3 H)."""

    transition: MotionModel
    N: int = 5
    covariance: str = "joseph"
    compiled: bool = True
    horizon: int = 5000
    cache_size: int = 64
    kalman: KalmanFilter = field(init=False, repr=False)
    _schedules: OrderedDict = field(init=False, repr=False)

    kind = "kalman-piecewise-gain"
    state_type = PiecewiseGainState

    def __post_init__(self) -> None:
        if not (isinstance(self.N, (int, np.integer)) and self.N >= 1):
            raise ValueError(f"piecewise gain: N must be an integer >= 1, got {self.N!r}")
        if self.covariance not in COVARIANCE_MODES:
            raise ValueError(f"piecewise gain: covariance must be one of {COVARIANCE_MODES}, got {self.covariance!r}")
        if not (isinstance(self.horizon, (int, np.integer)) and self.horizon >= max(2 * self.N, 2)):
            raise ValueError(f"piecewise gain: horizon must be an integer >= 2 N, got {self.horizon!r}")
        self.N = int(self.N)
        self.kalman = KalmanFilter(self.transition, compiled=self.compiled)
        self._schedules = OrderedDict()
        # on hold scans the gain does not see the scan's R
        self.capabilities = Capabilities(gain_depends_on_r=self.N == 1)
        self.state_type = OfflineGainState if self.covariance == "offline" else PiecewiseGainState

    @property
    def state_dim(self) -> int:
        return self.transition.dim

    def initiate(self, x: np.ndarray, P: np.ndarray) -> PiecewiseGainState:
        x, P = np.array(x, dtype=float), np.array(P, dtype=float)
        rows, n = x.shape
        mz = self.transition.ndim
        K = np.zeros((rows, n, mz))
        scans = np.zeros(rows, np.int64)
        if self.covariance == "joseph":
            return PiecewiseGainState(x, P, K, scans)
        none = np.full(rows, NO_SCHEDULE)
        return OfflineGainState(x, P, K, scans, np.zeros(rows), np.ones(rows), P.copy(), K.copy(), scans.copy(),
                                none, np.zeros((rows, mz, mz)), np.ones(rows), np.zeros((rows, mz, n)))

    # -------------------------------------------------------------------- predict
    def predict(self, state: PiecewiseGainState, dt, context: dict | None = None) -> PiecewiseGainState:
        rows = len(state)
        dt = np.broadcast_to(self.transition_dt(dt), (rows,))
        scale = row_scale(context, rows)
        if self.covariance == "joseph":
            g = self.kalman.predict_arrays(state.x, state.P, dt, scale)
            return PiecewiseGainState(g.x, g.P, state.K, state.scans)
        return self._predict_offline(state, dt, scale)

    def _predict_offline(self, state: OfflineGainState, dt: np.ndarray, scale: np.ndarray) -> OfflineGainState:
        rows, ndim = len(state), self.transition.ndim
        elapsed = state.elapsed + dt
        if np.any(elapsed < 0.0):
            raise ValueError("piecewise gain (offline covariance): steps since the last update must not add up to a negative time")
        F, _ = axis_transitions(self.transition, dt, scale)
        x = linalg.matvec(F, state.x.reshape(rows, ndim, -1)).reshape(rows, -1)
        moved = dt != 0.0
        scale = np.where(moved, scale, state.scale)
        on_schedule = moved & (state.sched_T != NO_SCHEDULE) \
            & (np.abs(elapsed - state.sched_T) <= SCHEDULE_TOLERANCE * state.sched_T) \
            & (np.abs(scale - state.sched_scale) <= SCHEDULE_TOLERANCE * state.sched_scale)
        online = moved & ~on_schedule
        P = state.P.copy()
        sched_T = state.sched_T.copy()
        if online.any():
            P[online] = self.kalman.predict_arrays(state.x[online], state.P[online], dt[online], scale[online]).P
            sched_T[online] = NO_SCHEDULE  # the next innovation starts a schedule from here
        if on_schedule.any():
            P[on_schedule] = self._lookup(state, on_schedule, state.scans[on_schedule] + 1)["P_pred"]
        new = state.copy()
        new.x, new.P, new.elapsed, new.scale, new.sched_T = x, P, elapsed, scale, sched_T
        return new

    # -------------------------------------------------------------------- innovate
    def innovate(self, state: PiecewiseGainState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        if self.covariance == "joseph":
            innovation = self.kalman.innovate(state, z, model, context)
            self._check_dimension(innovation.H)
            return innovation
        if not getattr(model, "linear", True):
            raise ValueError("piecewise gain (offline covariance): the measurement model must be linear")
        H, R, nu, m = measurement_terms(state.x, z, model, context)
        self._check_dimension(H)
        stale = (state.sched_T == NO_SCHEDULE) | (_relative_change(R, state.sched_R) > SCHEDULE_TOLERANCE) \
            | np.any(H != state.sched_H, axis=(1, 2))
        predicted = state
        if stale.any():
            predicted = state.copy()
            predicted.sched_P[stale] = state.P[stale]
            predicted.sched_K[stale] = state.K[stale]
            predicted.sched_k0[stale] = state.scans[stale] + 1
            predicted.sched_T[stale] = state.elapsed[stale]
            predicted.sched_R[stale] = R[stale]
            predicted.sched_scale[stale] = state.scale[stale]
            predicted.sched_H[stale] = H[stale]
        entries = self._lookup(predicted, np.ones(len(state), bool), state.scans + 1)
        d2 = linalg.mahalanobis_chol(nu, entries["chol"])
        loglik = linalg.gaussian_loglik(d2, entries["logdet"], m)
        return Innovation(nu, entries["S"], entries["chol"], d2, entries["logdet"], loglik, m, H, R, predicted,
                          {"pcg_K": entries["K"], "pcg_P": entries["P_post"]})

    def _check_dimension(self, H: np.ndarray) -> None:
        if H.shape[1] != self.transition.ndim:
            raise ValueError(f"piecewise gain: the measurement must have one component per axis "
                             f"({self.transition.ndim}), got {H.shape[1]}")

    # -------------------------------------------------------------------- update
    def update(self, state: PiecewiseGainState, z: np.ndarray, innovation: Innovation) -> tuple[PiecewiseGainState, UpdateStats]:
        predicted = innovation.predicted
        x, P, H, R, nu = predicted.x, predicted.P, innovation.H, innovation.R, innovation.nu
        scans = predicted.scans + 1
        if self.covariance == "offline":
            K = innovation.extra["pcg_K"]
            new = predicted.copy()
            new.x, new.P, new.K, new.scans = x + linalg.matvec(K, nu), innovation.extra["pcg_P"].copy(), K.copy(), scans
            new.elapsed = np.zeros(len(x))
        else:
            recompute = (scans - 1) % self.N == 0
            K = predicted.K.copy()
            if recompute.any():
                PHt = linalg.matmul(P[recompute], np.swapaxes(H[recompute], -1, -2))
                chol = innovation.chol[recompute]
                K[recompute] = np.swapaxes(linalg.cho_solve(chol, np.swapaxes(PHt, -1, -2)), -1, -2)
            A = np.eye(x.shape[-1]) - linalg.matmul(K, H)
            P_new = linalg.sandwich(A, P, linalg.sandwich(K, R))
            new = PiecewiseGainState(x + linalg.matvec(K, nu), P_new, K, scans)
        self.recorder.record("gain", np.arange(len(x)), gain=K)
        return new, UpdateStats(innovation.d2 / innovation.m)

    # -------------------------------------------------------------------- offline schedules
    def _lookup(self, state: OfflineGainState, rows: np.ndarray, k: np.ndarray) -> dict[str, np.ndarray]:
        """Schedule entries at scans ``k`` for the selected ``rows`` (built and cached when missing)."""
        count = int(np.sum(rows))
        P0, K0, k0 = state.sched_P[rows], state.sched_K[rows], state.sched_k0[rows]
        T, R, scale, H = state.sched_T[rows], state.sched_R[rows], state.sched_scale[rows], state.sched_H[rows]
        phase = (k0 - 1) % self.N
        keys = np.concatenate([P0.reshape(count, -1), K0.reshape(count, -1), phase[:, None].astype(float),
                               T[:, None], R.reshape(count, -1), scale[:, None], H.reshape(count, -1)], axis=1)
        unique, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        names = [u.tobytes() for u in unique]
        missing = [g for g, name in enumerate(names) if name not in self._schedules]
        if missing:
            at = first[missing]
            built = self._build(P0[at], K0[at], phase[at], T[at], R[at], scale[at], H[at])
            for g, schedule in zip(missing, built):
                self._schedules[names[g]] = schedule
        out = {}
        j = k - k0
        for g, name in enumerate(names):
            schedule = self._schedules[name]
            self._schedules.move_to_end(name)
            members = inverse == g
            length = len(schedule["K"])
            jj = j[members]
            jj = np.where(jj < length, jj, length - self.N + (jj - length) % self.N)
            for key in SCHEDULE_FIELDS:
                if key not in out:
                    out[key] = np.empty((count,) + schedule[key].shape[1:])
                out[key][members] = schedule[key][jj]
        while len(self._schedules) > self.cache_size:
            self._schedules.popitem(last=False)
        return out

    def _build(self, P_pred, K_held, phase, T, R, scale, H) -> list[dict[str, np.ndarray]]:
        """The recursion of §3.3 H for G schedule origins at once (phase = (k0 - 1) mod N)."""
        G, n = P_pred.shape[:2]
        F = self.transition.F_batch(T)
        Q = self.transition.Q_batch(T) * scale[:, None, None]
        Ht = np.swapaxes(H, -1, -2)
        entries = {key: [] for key in SCHEDULE_FIELDS}
        length = np.full(G, self.horizon)
        last_gain = np.full_like(K_held, np.nan)
        done = np.zeros(G, bool)
        for j in range(self.horizon):
            S = linalg.sandwich(H, P_pred, R)
            chol = linalg.cholesky(S)
            recompute = (phase + j) % self.N == 0
            K = K_held.copy()
            if recompute.any():
                PHt = linalg.matmul(P_pred[recompute], Ht[recompute])
                K[recompute] = np.swapaxes(linalg.cho_solve(chol[recompute], np.swapaxes(PHt, -1, -2)), -1, -2)
                change = np.max(np.abs(K - last_gain), axis=(1, 2)) / np.max(np.abs(K), axis=(1, 2))
                settled = recompute & ~done & (change < GAIN_CONVERGENCE)
                length[settled] = j  # scan j repeats scan j - N from here on
                done |= settled
                last_gain[recompute] = K[recompute]
            A = np.eye(n) - linalg.matmul(K, H)
            P_post = linalg.sandwich(A, P_pred, linalg.sandwich(K, R))
            for key, value in zip(SCHEDULE_FIELDS, (P_pred, S, chol, linalg.logdet_chol(chol), K, P_post)):
                entries[key].append(value)
            if done.all():
                break
            K_held = K
            P_pred = linalg.sandwich(F, P_post, Q)
        stacked = {key: np.stack(values, axis=1) for key, values in entries.items()}
        return [{key: value[g, : length[g]].copy() for key, value in stacked.items()} for g in range(G)]


@register_filter("kalman-piecewise-gain")
def _piecewise_gain(motion: MotionModel, compiled: bool = True, N: int = 5, covariance: str = "joseph",
                    horizon: int = 5000) -> PiecewiseGainFilter:
    """Piecewise-constant gain (§3.3 H): gain recomputed every ``N`` scans; ``covariance`` "joseph" or "offline"."""
    return PiecewiseGainFilter(motion, N=N, covariance=covariance, compiled=compiled, horizon=horizon)

"""Monte Carlo runner of the studies: any protocol filter over the runs of one case (spec 004 R20-R22).

Runs are the batch dimension (row r = run r).  Protocol of one case (§6 common defaults):

1. two-point initialisation from the measurements of scans 0 and 1, per run:
   ``p = z1``, ``v = (z1 - z0)/T``, ``P_pp = R1``, ``P_pv = R1/T``, ``P_vv = (R0 + R1)/T^2``
   (3x3 blocks, cross-axis terms of the converted R kept); order-3 states add a zero
   acceleration with variance ``init_accel_sigma^2`` ((20 m/s^2)^2 by default);
2. from scan 2 on: predict by T, then the output filter's predicted estimate
   (``predicted.estimate()``: the moment-matched mixture for banks and IMM, the steady-state
   covariance for constant-gain filters) gives ``S = H P^- H^T + R`` and the true-measurement
   NIS ``eps = nu^T S^-1 nu`` used for gating and track loss (R20); set estimates use the
   consistency test ``max_eta delta(eta) < 1`` of §3.3 I instead;
3. ``gating="off"`` (default): every measurement is used, a run is lost when eps exceeds
   ``chi2_{3}^-1(gate_probability)`` on ``loss_scans`` consecutive scans; ``gating="on"``: a
   measurement outside the gate is not used (the filter coasts on its prediction) and a run is
   lost after ``loss_scans`` consecutive unused measurements;
4. per scan and run: position and velocity errors, NEES on position+velocity, eps, gate and use
   flags, containment of the truth in E(x, P) for set estimates; diagnostics recorded by the
   filter (gains, switch times, ...) when ``record`` is set.

Cost per update (R22): multiply-adds of predict + innovate + update counted by
``skytrack.core.linalg.counting()`` and wall time, both divided by the number of runs; the
runner's own bookkeeping (NIS, NEES, gating) stays outside the counted blocks.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from skytrack.analysis.metrics import nees
from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, ListRecorder
from skytrack.models.converted import ConvertedPositionModel
from skytrack.studies.maneuver.measurements import MeasurementSet
from skytrack.studies.maneuver.scenarios import Case

GATINGS = ("off", "on")
GATE_PROBABILITY = 0.9999
LOSS_SCANS = 3
INIT_ACCEL_SIGMA = 20.0
FIRST_SCAN = 2
NDIM = 3
#: containment tolerance of the set estimate's quadratic form (E9: <= 1 + 1e-9)
CONTAINMENT_TOLERANCE = 1e-9
#: eta grid of the set-membership consistency test (logit-spaced, then golden-section refined)
_ETA = 1.0 / (1.0 + np.exp(-np.linspace(-12.0, 12.0, 241)))
_GOLDEN_STEPS = 60


@dataclass(frozen=True)
class RunOptions:
    """Options of :func:`run_filter` (module docstring)."""

    gating: str = "off"
    gate_probability: float = GATE_PROBABILITY
    loss_scans: int = LOSS_SCANS
    init_accel_sigma: float = INIT_ACCEL_SIGMA
    record: bool = False
    count_cost: bool = True

    def __post_init__(self) -> None:
        if self.gating not in GATINGS:
            raise ValueError(f"gating must be one of {GATINGS}, got {self.gating!r}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        if int(self.loss_scans) != self.loss_scans or self.loss_scans < 1:
            raise ValueError(f"loss_scans must be an integer >= 1, got {self.loss_scans}")
        if not (math.isfinite(self.init_accel_sigma) and self.init_accel_sigma > 0):
            raise ValueError(f"init_accel_sigma must be > 0, got {self.init_accel_sigma}")

    @property
    def gate(self) -> float:
        return float(chi2.ppf(self.gate_probability, NDIM))


@dataclass
class FilterRun:
    """Per-scan results of one filter on one case; arrays ``[K, runs]`` (NaN / False before scan 2)."""

    label: str
    kind: str
    case: str
    gating: str
    order: int
    estimate: str  # "gaussian" | "set"
    time: np.ndarray
    position_error: np.ndarray  # [K, runs, 3] estimate - truth
    velocity_error: np.ndarray  # [K, runs, 3]
    nees: np.ndarray  # position+velocity NEES
    nis: np.ndarray  # eps of the true measurement against the predicted output estimate
    consistency: np.ndarray  # max_eta delta of set estimates (NaN otherwise)
    in_gate: np.ndarray
    used: np.ndarray
    contained: np.ndarray  # 1/0 for set estimates, NaN otherwise
    lost: np.ndarray  # [runs]
    loss_scan: np.ndarray  # [runs], -1 when not lost
    madds: np.ndarray  # [K] multiply-adds per track per update (NaN where not counted)
    wall_us: np.ndarray  # [K] wall microseconds per track per update
    diagnostics: list = field(default_factory=list)  # per scan: [(channel, global rows, values)]

    @property
    def runs(self) -> int:
        return self.nis.shape[1]

    @property
    def first_scan(self) -> int:
        return FIRST_SCAN

    @property
    def madds_per_update(self) -> float:
        finite = self.madds[np.isfinite(self.madds)]
        return float(finite.mean()) if finite.size else math.nan

    @property
    def us_per_update(self) -> float:
        finite = self.wall_us[np.isfinite(self.wall_us)]
        return float(np.median(finite)) if finite.size else math.nan

    def history(self, channel: str, key: str) -> np.ndarray:
        """``[K, runs, ...]`` of a recorded value (NaN where a scan did not record it for a run)."""
        sample = next((values[key] for scan in self.diagnostics for ch, _, values in scan if ch == channel and key in values), None)
        if sample is None:
            raise ValueError(f"filter {self.label!r} recorded no {channel!r}/{key!r} (run with record=True)")
        out = np.full((len(self.time), self.runs) + sample.shape[1:], np.nan)
        for k, scan in enumerate(self.diagnostics):
            for ch, rows, values in scan:
                if ch == channel and key in values:
                    out[k, rows] = values[key]
        return out


def two_point_initiation(z0, z1, R0, R1, dt: float, order: int, accel_sigma: float = INIT_ACCEL_SIGMA):
    """Two-point start ``(x[runs, 3 order], P[runs, 3 order, 3 order])`` in the axis-major layout (module docstring)."""
    if order not in (2, 3):
        raise ValueError(f"two-point initialisation supports 2 or 3 states per axis, got {order}")
    runs = len(z0)
    n = NDIM * order
    pos = np.arange(NDIM) * order
    vel = pos + 1
    x = np.zeros((runs, n))
    x[:, pos] = z1
    x[:, vel] = (z1 - z0) / dt
    P = np.zeros((runs, n, n))
    P[:, pos[:, None], pos[None, :]] = R1
    P[:, pos[:, None], vel[None, :]] = R1 / dt
    P[:, vel[:, None], pos[None, :]] = R1 / dt
    P[:, vel[:, None], vel[None, :]] = (R0 + R1) / dt**2
    if order == 3:
        acc = pos + 2
        P[:, acc, acc] = accel_sigma**2
    return x, P


def truth_state(case: Case, order: int) -> np.ndarray:
    """Truth ``[K, 3 order]`` in the axis-major layout (derivatives above acceleration are 0)."""
    parts = (case.truth.position, case.truth.velocity, case.truth.acceleration)
    x = np.zeros((case.scans, NDIM * order))
    for j in range(min(order, 3)):
        x[:, np.arange(NDIM) * order + j] = parts[j]
    return x


def set_consistency(nu: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``max_eta nu^T (A/(1-eta) + B/eta)^-1 nu`` per row (§3.3 I; ``A = H P^- H^T`` of the shape matrix,
    ``B = R_b``).  Whitening by B's Cholesky factor and the eigenvectors of the whitened A make
    ``delta(eta) = sum_i w_i / (lam_i/(1-eta) + 1/eta)``; its maximum is bracketed on a logit grid of
    eta and refined by golden-section search."""
    C = np.linalg.cholesky(B)
    w = np.linalg.solve(C, nu[..., None])[..., 0]
    Ci = np.linalg.inv(C)
    lam, U = np.linalg.eigh(Ci @ A @ np.swapaxes(Ci, -1, -2))
    lam = np.maximum(lam, 0.0)
    proj = np.einsum("rji,rj->ri", U, w) ** 2

    def delta(eta):  # eta [rows, G] -> [rows, G]
        e = eta[..., None]
        return np.sum(proj[:, None, :] / (lam[:, None, :] / (1.0 - e) + 1.0 / e), axis=-1)

    coarse = delta(np.broadcast_to(_ETA, (len(nu), len(_ETA))))
    best = np.argmax(coarse, axis=1)
    lo = _ETA[np.maximum(best - 1, 0)].copy()
    hi = _ETA[np.minimum(best + 1, len(_ETA) - 1)].copy()
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(_GOLDEN_STEPS):
        a = hi - ratio * (hi - lo)
        b = lo + ratio * (hi - lo)
        values = delta(np.stack([a, b], axis=1))
        left = values[:, 0] >= values[:, 1]
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
    refined = delta(((lo + hi) / 2.0)[:, None])[:, 0]
    return np.maximum(coarse.max(axis=1), refined)


def _loss(flag: np.ndarray, loss_scans: int) -> tuple[np.ndarray, np.ndarray]:
    """Per run: lost (``flag`` true on ``loss_scans`` consecutive scans) and the scan completing the run."""
    scans, runs = flag.shape
    count = np.zeros(runs, dtype=np.int64)
    loss_scan = np.full(runs, -1, dtype=np.int64)
    for k in range(scans):
        count = np.where(flag[k], count + 1, 0)
        newly = (count >= loss_scans) & (loss_scan < 0)
        loss_scan[newly] = k
    return loss_scan >= 0, loss_scan


def run_filter(filt: BatchFilter, case: Case, meas: MeasurementSet, *, label: str, options: RunOptions = RunOptions(),
               r_scale: float = 1.0, progress=None) -> FilterRun:
    """Run ``filt`` over every run of ``case`` (module docstring); ``progress(scans_done)`` after each scan."""
    scans, runs = meas.scans, meas.runs
    if scans != case.scans:
        raise ValueError(f"measurements have {scans} scans, case {case.label!r} has {case.scans}")
    if scans <= FIRST_SCAN:
        raise ValueError(f"case {case.label!r} needs more than {FIRST_SCAN} scans")
    order = filt.state_dim // NDIM
    if order * NDIM != filt.state_dim:
        raise ValueError(f"filter {label!r}: state dimension {filt.state_dim} is not 3 axes x states per axis")
    is_set = filt.capabilities.estimate == "set"
    recorder = ListRecorder() if options.record else None
    if recorder is not None:
        filt.recorder = recorder
    model = ConvertedPositionModel(NDIM, order)
    pos = np.arange(NDIM) * order
    pv = np.concatenate([pos, pos + 1])
    pv = np.sort(pv)
    truth = truth_state(case, order)
    gate = options.gate
    z, R = meas.z, meas.R * r_scale

    def empty(fill=np.nan, dtype=float, tail=()):
        return np.full((scans, runs) + tail, fill, dtype=dtype)

    pos_err, vel_err = empty(tail=(NDIM,)), empty(tail=(NDIM,))
    nees_pv, nis, consistency, contained = empty(), empty(), empty(), empty()
    in_gate, used = empty(False, bool), empty(False, bool)
    madds, wall = np.full(scans, np.nan), np.full(scans, np.nan)
    diagnostics: list = [[] for _ in range(scans)]

    x0, P0 = two_point_initiation(z[0], z[1], R[0], R[1], case.truth.time[1] - case.truth.time[0], order,
                                  options.init_accel_sigma)
    state = filt.initiate(x0, P0)
    all_rows = np.arange(runs)
    for k in range(FIRST_SCAN, scans):
        dt = np.full(runs, case.truth.time[k] - case.truth.time[k - 1])
        ops_count = 0.0
        started = time.perf_counter()
        if options.count_cost:
            with linalg.counting() as ops:
                predicted = filt.predict(state, dt)
            ops_count += ops.madds
        else:
            predicted = filt.predict(state, dt)
        elapsed = time.perf_counter() - started

        est = predicted.estimate()
        nu = z[k] - est.x[:, pos]
        A = est.P[:, pos[:, None], pos[None, :]]
        if is_set:
            consistency[k] = set_consistency(nu, A, R[k])
            in_gate[k] = consistency[k] < 1.0
        else:
            S = A + R[k]
            with np.errstate(invalid="ignore"):
                nis[k] = np.einsum("ri,ri->r", nu, np.linalg.solve(S, nu[..., None])[..., 0])
            in_gate[k] = nis[k] <= gate
        rows = all_rows if options.gating == "off" else np.flatnonzero(in_gate[k])
        used[k, rows] = True
        if rows.size:
            subset = predicted if rows.size == runs else predicted.take(rows)
            context = {"R": R[k, rows]}
            events_before = len(recorder.events) if recorder is not None else 0
            started = time.perf_counter()
            if options.count_cost:
                with linalg.counting() as ops:
                    innovation = filt.innovate(subset, z[k, rows], model, context)
                    updated, _ = filt.update(subset, z[k, rows], innovation)
                ops_count += ops.madds
            else:
                innovation = filt.innovate(subset, z[k, rows], model, context)
                updated, _ = filt.update(subset, z[k, rows], innovation)
            elapsed += time.perf_counter() - started
            if rows.size == runs:
                state = updated
            else:
                predicted.put(rows, updated)
                state = predicted
            if recorder is not None:
                diagnostics[k] = [(ch, rows[np.asarray(r)], v) for ch, r, v in recorder.events[events_before:]]
        else:
            state = predicted
        if rows.size == runs:
            if options.count_cost:
                madds[k] = ops_count / runs
            wall[k] = elapsed / runs * 1e6

        out = state.estimate()
        err = out.x - truth[k]
        pos_err[k] = err[:, pos]
        vel_err[k] = err[:, pos + 1]
        if is_set:
            values, valid = nees(err, out.P)
            contained[k] = np.where(valid, values <= 1.0 + CONTAINMENT_TOLERANCE, np.nan)
        else:
            nees_pv[k], _ = nees(err[:, pv], out.P[:, pv[:, None], pv[None, :]])
        if progress is not None:
            progress(k)
    lost, loss_scan = _loss(~in_gate[FIRST_SCAN:] if options.gating == "off" else ~used[FIRST_SCAN:], options.loss_scans)
    loss_scan = np.where(lost, loss_scan + FIRST_SCAN, -1)
    return FilterRun(label, getattr(filt, "kind", type(filt).__name__), case.label, options.gating, order,
                     "set" if is_set else "gaussian", case.truth.time, pos_err, vel_err, nees_pv, nis, consistency,
                     in_gate, used, contained, lost, loss_scan, madds, wall, diagnostics)

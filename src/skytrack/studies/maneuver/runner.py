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
   consistency test of §3.3 I instead, ``d^2 = max_eta delta(eta) < 1`` as the filter's own
   ``innovate`` computes it with its bound ``R_b`` (their initial set is the two-point bounding
   ellipsoid, ``initiation="two-point-set"``);
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

import contextlib
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
INITIATIONS = ("two-point", "two-point-set")


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
    consistency: np.ndarray  # d^2 = max_eta delta of set estimates (NaN otherwise)
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


def quadratic_form(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``e^T P^-1 e`` per row through a batched Cholesky factor; when some P is not positive definite,
    :func:`skytrack.analysis.metrics.nees` takes over (NaN for those rows)."""
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return nees(e, P)[0]
    w = np.linalg.solve(L, e[..., None])[..., 0]
    return np.einsum("ri,ri->r", w, w)


class _Cost:
    """Multiply-adds (``linalg.counting``) and wall seconds of the filter steps of one scan."""

    def __init__(self, count: bool) -> None:
        self.count = count
        self.madds = 0.0
        self.seconds = 0.0

    @contextlib.contextmanager
    def measure(self):
        started = time.perf_counter()
        if self.count:
            with linalg.counting() as ops:
                yield
            self.madds += ops.madds
        else:
            yield
        self.seconds += time.perf_counter() - started


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
               r_scale: float = 1.0, initiation: str = "two-point", progress=None) -> FilterRun:
    """Run ``filt`` over every run of ``case`` (module docstring); ``progress(scan)`` after each scan.

    ``initiation``: ``two-point`` (Gaussian, module docstring) or ``two-point-set`` (the bounding
    ellipsoid of :func:`skytrack.filters.set_membership.two_point_initial_set` with the filter's
    ``R_b = r_bound_scale R``); ``r_scale`` multiplies the measurement covariance handed to the filter.
    """
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

    dt0 = case.truth.time[1] - case.truth.time[0]
    if initiation == "two-point-set":
        from skytrack.filters.set_membership import two_point_initial_set

        scale = float(getattr(filt, "r_bound_scale", 1.0))
        x0, P0 = two_point_initial_set(z[0], z[1], dt0, scale * R[1], scale * R[0])
    elif initiation == "two-point":
        x0, P0 = two_point_initiation(z[0], z[1], R[0], R[1], dt0, order, options.init_accel_sigma)
    else:
        raise ValueError(f"initiation must be one of {INITIATIONS}, got {initiation!r}")
    state = filt.initiate(x0, P0)
    all_rows = np.arange(runs)
    for k in range(FIRST_SCAN, scans):
        dt = np.full(runs, case.truth.time[k] - case.truth.time[k - 1])
        cost = _Cost(options.count_cost)
        with cost.measure():
            predicted = filt.predict(state, dt)
        est = predicted.estimate()
        innovation = None
        events_before = len(recorder.events) if recorder is not None else 0
        if is_set or options.gating == "off":
            with cost.measure():
                innovation = filt.innovate(predicted, z[k], model, {"R": R[k]})
        if is_set:
            consistency[k] = innovation.d2
            in_gate[k] = innovation.d2 < 1.0
        else:
            nu = z[k] - est.x[:, pos]
            S = est.P[:, pos[:, None], pos[None, :]] + R[k]
            with np.errstate(invalid="ignore"):
                nis[k] = np.einsum("ri,ri->r", nu, np.linalg.solve(S, nu[..., None])[..., 0])
            in_gate[k] = nis[k] <= gate
        rows = all_rows if options.gating == "off" else np.flatnonzero(in_gate[k])
        used[k, rows] = True
        if rows.size == runs:
            with cost.measure():
                if innovation is None:
                    innovation = filt.innovate(predicted, z[k], model, {"R": R[k]})
                state, _ = filt.update(predicted, z[k], innovation)
            if options.count_cost:
                madds[k] = cost.madds / runs
            wall[k] = cost.seconds / runs * 1e6
        elif rows.size:
            subset = predicted.take(rows)
            events_before = len(recorder.events) if recorder is not None else 0
            innovation = filt.innovate(subset, z[k, rows], model, {"R": R[k, rows]})
            updated, _ = filt.update(subset, z[k, rows], innovation)
            predicted.put(rows, updated)
            state = predicted
        else:
            state = predicted
        if recorder is not None and rows.size:
            diagnostics[k] = [(ch, rows[np.asarray(r)], v) for ch, r, v in recorder.events[events_before:]]

        out = state.estimate()
        err = out.x - truth[k]
        pos_err[k] = err[:, pos]
        vel_err[k] = err[:, pos + 1]
        if is_set:
            values = quadratic_form(err, out.P)
            contained[k] = np.where(np.isfinite(values), values <= 1.0 + CONTAINMENT_TOLERANCE, np.nan)
        else:
            nees_pv[k] = quadratic_form(err[:, pv], out.P[:, pv[:, None], pv[None, :]])
        if progress is not None:
            progress(k)
    lost, loss_scan = _loss(~in_gate[FIRST_SCAN:] if options.gating == "off" else ~used[FIRST_SCAN:], options.loss_scans)
    loss_scan = np.where(lost, loss_scan + FIRST_SCAN, -1)
    return FilterRun(label, getattr(filt, "kind", type(filt).__name__), case.label, options.gating, order,
                     "set" if is_set else "gaussian", case.truth.time, pos_err, vel_err, nees_pv, nis, consistency,
                     in_gate, used, contained, lost, loss_scan, madds, wall, diagnostics)

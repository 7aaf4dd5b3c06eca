"""Adaptive Q/R + input estimation, spec 004 §3.3 L (the paper's combined algorithm), requirement R14.

Composition of two families, no new filter equations:

* the quiescent filter is the ``structured`` adaptive Kalman filter of §3.3 F
  (:class:`~skytrack.filters.adaptive.AdaptiveKalmanFilter`, R8) on the IE quiescent model
  (:class:`~skytrack.filters.input_estimation.AppliedInputAxis`: CV/DWNA on position and velocity,
  the applied input carried in the acceleration entries, ``Q_unit`` the sigma_w = 1 DWNA model,
  ``Q = q^ Q_unit``); its prediction is completed with ``G u_app``;
* the onset bank, detection and correction are those of §3.3 K
  (:class:`~skytrack.filters.input_estimation.InputEstimationFilter`), run with the gain, S and R^
  the adaptive filter used on the scan.

Adaptation is suspended for N_w scans after every IE correction and on scans failing the adaptive
filter's NIS gate (default); ``adapt_always=True`` turns both off (the adaptive filter adapts on
every scan after its warm-up).  The suspension goes through the adaptive filter's own NIS gate: a
suspended scan is handed to it with ``d2 = inf``, so it updates with its current R^, q^ and does not
adapt (its ``"adaptive"`` recorder channel then shows ``nis = inf`` for those rows).

The acceleration block of the covariance follows input estimation's convention with the current
``q^`` as the DWNA variance: ``U + q^ I`` (U = 0 until the first correction, then ``L_s``).
``propagate_input`` (default True) is input estimation's option: the error of ``u_app`` is a
consider parameter, propagated into position and velocity with its cross-covariance; the
adaptive filter's standard update is then turned into the consider (Schmidt) update by keeping
the acceleration entries and their covariance block of the prediction (for an optimal gain the two
updates differ only there), and the bank runs with the consider gain.  The adaptive filter's
Frobenius projection does not see the acceleration entries (``Q_unit`` is zero there).
``matched_motion`` is input estimation's with ``sigma = sqrt(q0)``.  On it the NEES depends on the
adaptive filter's rule (:mod:`~skytrack.filters.adaptive`), because q̂ is also the reported
acceleration variance: with the default ``information`` weighting 9.42 for 9 states in the
conformance suite (band 8.42-9.60; 9.09 without adaptation, 9.32 on average over 10 seeds, 9.10
over scans 101-200 of a long run); with the spec's fading weights q̂ wanders over orders of
magnitude and the NEES is 87.5 (68.0 with the literal rule) (``benchmarks/adaptive_nees.py``).

Options: those of §3.3 K (``window`` N_w, ``p_fa``, ``bonferroni``, ``threshold``, ``input_axes``,
``record_bank``, ``propagate_input``)
and of the structured adaptive filter (``b``, ``warmup``, ``gate_probability``, ``r_lo``, ``r_hi``,
``q_lo``, ``q_hi``, ``q0``, ``r0_scale``, ``fixed_weight``, ``weighting``, ``r_prior_sd``, ``q_prior_sd``,
``prior_scans``, ``gate_correction``).  Recorder channels: the IE channels
(``"detection"``, ``"likelihood"``, ``"bank"``) and the adaptive filter's (``"adaptive"``, ``"gain"``).  Like the
adaptive filter, the gain follows R^ rather than the model's R after a row's first update
(``gain_depends_on_r`` is False).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from skytrack.core import linalg
from skytrack.filters import adaptive as adaptive_family
from skytrack.filters import input_estimation as ie_family
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, Recorder, UpdateStats
from skytrack.filters.variable_dimension import (
    ORDER,
    QuiescentAccelerationAxis,
    acceleration_index,
    check_order3,
    position_selector,
)
from skytrack.models.motion import MotionModel

#: options of the structured adaptive filter that this family passes on
ADAPTIVE_OPTIONS = ("b", "warmup", "gate_probability", "r_lo", "r_hi", "q_lo", "q_hi", "q0", "r0_scale",
                    "fixed_weight", "weighting", "r_prior_sd", "q_prior_sd", "prior_scans", "gate_correction")


@dataclass
class AdaptiveInputEstimationState(GaussianState):
    """The fields of the structured adaptive state (:class:`~skytrack.filters.adaptive.StructuredAdaptiveState`:
    R^, R_nom, Q_acc, ``scans`` = updates so far, adaptations, q^) plus the IE bank (``bias``,
    ``information``, ``score``, ``live`` as in :class:`~skytrack.filters.input_estimation.InputEstimationState`)
    and ``suspended[N]``, the scans of adaptation suspension left after a correction.

    The adaptive fields are declared here rather than inherited, so that this module imports its two
    sibling families lazily (importing the filter registry imports every filter module, in any order).
    """

    R_hat: np.ndarray
    R_nom: np.ndarray
    Q_acc: np.ndarray
    scans: np.ndarray
    adaptations: np.ndarray
    q_hat: np.ndarray
    r_information: np.ndarray
    q_information: np.ndarray
    bias: np.ndarray
    information: np.ndarray
    score: np.ndarray
    live: np.ndarray
    suspended: np.ndarray

    def adaptive_part(self):
        """The structured adaptive filter's state over the same arrays (no copies)."""
        base = adaptive_family.StructuredAdaptiveState
        return base(**{f.name: getattr(self, f.name) for f in dataclasses.fields(base)})

    def with_adaptive(self, part, **bank) -> "AdaptiveInputEstimationState":
        """This state with the adaptive fields of ``part`` and the given bank fields replaced."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        fields.update({f.name: getattr(part, f.name) for f in dataclasses.fields(part)})
        fields.update(bank)
        return AdaptiveInputEstimationState(**fields)


@dataclass(eq=False)
class AdaptiveInputEstimationFilter(BatchFilter):
    """Structured adaptive KF (§3.3 F) as the quiescent filter of input estimation (§3.3 K): §3.3 L, R14."""

    ndim: int
    window: int = 20
    p_fa: float = 0.01
    bonferroni: bool = True
    threshold: float | None = None
    input_axes: int | None = None
    adapt_always: bool = False
    adaptive_options: dict = field(default_factory=dict)
    record_bank: bool = False
    compiled: bool = True
    propagate_input: bool = True

    kind = "adaptive-input-estimation"
    capabilities = Capabilities(gain_depends_on_r=False)
    state_type = AdaptiveInputEstimationState

    def __post_init__(self) -> None:
        unknown = sorted(set(self.adaptive_options) - set(ADAPTIVE_OPTIONS))
        if unknown:
            raise ValueError(f"adaptive input estimation: unknown options {unknown}; the adaptive filter's are "
                             f"{', '.join(ADAPTIVE_OPTIONS)} (the variant is always 'structured')")
        self.ie = ie_family.InputEstimationFilter(self.ndim, 1.0, self.window, self.p_fa, self.bonferroni, self.threshold,
                                                  self.input_axes, self.record_bank, self.propagate_input)
        self.threshold = self.ie.threshold
        self.adaptive = adaptive_family.AdaptiveKalmanFilter(
            MotionModel([ie_family.AppliedInputAxis(1.0)] * self.ndim), variant="structured",
                                             gate=not self.adapt_always, compiled=self.compiled,
                                             **self.adaptive_options)

    @property
    def recorder(self) -> Recorder:
        return self.__dict__.get("_recorder", BatchFilter.recorder)

    @recorder.setter
    def recorder(self, value: Recorder) -> None:
        self.__dict__["_recorder"] = value
        if "ie" in self.__dict__:
            self.ie.recorder = value
            self.adaptive.recorder = value

    @property
    def state_dim(self) -> int:
        return ORDER * self.ndim

    @property
    def matched_motion(self) -> MotionModel:
        """Quiet flight with the adaptive filter's starting noise: DWNA of variance ``q0`` (q^ has
        nothing to learn), acceleration entry the coming interval's
        (:class:`~skytrack.filters.variable_dimension.QuiescentAccelerationAxis`)."""
        return MotionModel([QuiescentAccelerationAxis(float(np.sqrt(self.adaptive.q0)))] * self.ndim)

    # -------------------------------------------------------------------- steps
    def initiate(self, x: np.ndarray, P: np.ndarray) -> AdaptiveInputEstimationState:
        """As input estimation: ``u_app`` = the initial acceleration, its cross-covariance dropped."""
        q0 = self.adaptive.q0
        base = self.adaptive.initiate(np.array(x, dtype=float), ie_family.known_input_covariance(P, self.ndim, q0))
        count = len(base)
        return AdaptiveInputEstimationState(**base.to_arrays(), **dict(zip(
            ("bias", "information", "score", "live"), self.ie.empty_bank(count))), suspended=np.zeros(count, np.int64))

    def predict(self, state: AdaptiveInputEstimationState, dt, context: dict | None = None) -> AdaptiveInputEstimationState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),)).astype(float)
        part = self.adaptive.predict(state.adaptive_part(), dt, context)  # F_cov x, F_cov P F_cov^T + q^ Q_unit
        F_mean, F_cov, _, G_u = self.ie.transition(dt)
        applied = state.x[:, acceleration_index(self.ndim)[: self.ie.n_u]]
        part.x = part.x + linalg.matvec(G_u, applied)
        if self.propagate_input:
            part.P = part.P + self._input_error_propagation(state, F_mean, F_cov)
        return state.with_adaptive(part, bias=self.ie.bank_predict(state.bias, state.live, F_cov, G_u))

    def _input_error_propagation(self, state: AdaptiveInputEstimationState, F_mean, F_cov) -> np.ndarray:
        """``F_mean X F_mean^T - F_cov X F_cov^T`` with ``X = P - q^ E`` (the covariance of the errors of
        position, velocity and ``u_app``): what the consider prediction adds to the adaptive filter's.
        Zero, and not computed, for rows whose ``u_app`` has no error covariance (before their first
        correction)."""
        acc = acceleration_index(self.ndim)
        internal = state.P.copy()
        internal[:, acc, acc] -= state.q_hat[:, None]
        extra = np.zeros_like(internal)
        rows = np.flatnonzero(np.any(internal[:, :, acc] != 0.0, axis=(1, 2)))
        if len(rows):
            X = internal[rows]
            extra[rows] = linalg.sandwich(F_mean[rows], X) - linalg.sandwich(F_cov[rows], X)
        return extra

    def innovate(self, state: AdaptiveInputEstimationState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        innovation = self.adaptive.innovate(state.adaptive_part(), z, model, context)
        innovation.predicted = state
        H = innovation.H
        if not np.array_equal(H, np.broadcast_to(position_selector(self.ndim), H.shape)):
            raise ValueError(f"{self.kind}: the measurement must be the {self.ndim} positions (H selecting them)")
        return innovation

    def update(self, state: AdaptiveInputEstimationState, z: np.ndarray,
               innovation: Innovation) -> tuple[AdaptiveInputEstimationState, UpdateStats]:
        pred: AdaptiveInputEstimationState = innovation.predicted
        handed = innovation
        suspended = pred.suspended > 0
        if not self.adapt_always and suspended.any():
            handed = dataclasses.replace(innovation, d2=np.where(suspended, np.inf, innovation.d2))
        handed = dataclasses.replace(handed, predicted=pred.adaptive_part())
        new, _ = self.adaptive.update(handed.predicted, z, handed)
        acc = acceleration_index(self.ndim)
        # the gain the adaptive filter used: S = H P^- H^T + R^ of this scan
        H = innovation.H
        S = innovation.S - innovation.R + new.R_hat
        L = linalg.cholesky(S)
        PHt = linalg.matmul(pred.P, np.swapaxes(H, -1, -2))
        K = np.swapaxes(linalg.cho_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)
        if self.propagate_input:
            # consider update: u_app keeps its value and error covariance (module docstring)
            K[:, acc, :] = 0.0
            new.x = new.x.copy()
            new.x[:, acc] = pred.x[:, acc]
            new.P = new.P.copy()
            new.P[:, acc[:, None], acc[None, :]] = pred.P[:, acc[:, None], acc[None, :]]
        A = np.eye(self.state_dim) - linalg.matmul(K, H)
        used = dataclasses.replace(innovation, S=S, chol=L, R=new.R_hat)
        bank = self.ie.bank_update(pred.bias, pred.information, pred.score, pred.live, A, used)
        # the acceleration block is U + q^ I (input_estimation's docstring with sigma_w^2 = q^)
        P = new.P.copy()
        P[:, acc, acc] += (new.q_hat - pred.q_hat)[:, None]
        x, P, bank, detect = self.ie.detect_and_correct(new.x, P, bank, new.scans, new.q_hat)
        new.x, new.P = x, P
        suspended = np.where(detect, self.window, np.maximum(pred.suspended - 1, 0))
        return pred.with_adaptive(new, **dict(zip(("bias", "information", "score", "live"), bank)),
                                  suspended=suspended), UpdateStats(innovation.d2 / innovation.m)


from skytrack.filters.registry import register_filter  # noqa: E402  (after the pieces, as the siblings)


@register_filter("adaptive-input-estimation")
def _adaptive_input_estimation(motion: MotionModel, compiled: bool = True, window: int = 20, p_fa: float = 0.01,
                               bonferroni: bool = True, threshold: float | None = None, input_axes: int | None = None,
                               adapt_always: bool = False, record_bank: bool = False, propagate_input: bool = True,
                               **adaptive_options) -> AdaptiveInputEstimationFilter:
    """§3.3 L on the axes of an order-3 ``motion`` (only its number of axes is used)."""
    return AdaptiveInputEstimationFilter(check_order3(motion, "adaptive-input-estimation"), window, p_fa, bonferroni,
                                         threshold, input_axes, adapt_always, adaptive_options, record_bank, compiled,
                                         propagate_input)

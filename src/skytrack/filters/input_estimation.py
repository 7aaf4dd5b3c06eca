"""Input estimation with an onset-time bank, spec 004 §3.3 K (Chan, Hu & Plant 1979; onset
hypotheses as Bogler 1987), requirement R13.

Quiescent filter: CV with DWNA noise ``sigma_w`` in the m = 3 layout,
``x_{k+1} = F x_k + G u_k + w_k`` with ``G = I (x) [T^2/2, T, 0]^T`` and the unknown acceleration
u (``n_u`` = the number of axes, or the leading ``input_axes`` of them, e.g. 2 for a horizontal
study).  The applied input ``u_app`` is kept in the acceleration entries of the state and used
in prediction, ``x^- = F_cv x + G u_app`` (which is the CA transition of the mean), and is changed
only by corrections.  The acceleration block of P says what the model believes of the
acceleration over the coming interval: ``u_app`` plus the DWNA acceleration, covariance
``U + sigma_w^2 I``, where U is the covariance of the error of ``u_app``: 0 until the first
correction (IE starts from a known input, the initial estimate's acceleration; its covariance and
cross-covariance are dropped at ``initiate``), ``L_s`` of the last correction after it.

Propagation of the applied input's error (``propagate_input``).  After a correction ``u_app`` is
wrong by an error of covariance L, and that error keeps driving position and velocity through
``G`` at every prediction while ``u_app`` stays fixed.  The spec's filter (``propagate_input=False``,
the literal §3.3 K) propagates P with ``F_cv`` only and drops the correction's cross-covariance, so
it never accounts for that error: on its own quiescent model (conformance suite, 200 runs x 50
scans) the false alarms of the default P_fa = 0.01 leave it overconfident, 9-state NEES 10.22
(9.03 with detection off), rows after a false alarm reaching NEES ~300 on the next scan.  By
default (``propagate_input=True``) ``u_app`` is a *consider* parameter (Schmidt): the covariance of
``[position, velocity, u_app]`` is propagated with the transition of the mean (``F_cv`` plus ``G`` in
the acceleration column, applied to P with the DWNA acceleration variance taken out of the
acceleration block and put back after), the gain rows of the acceleration entries are zero (``u_app``
is still changed only by corrections), and a correction sets the cross-covariance of the corrected
state and ``u_app`` to ``M L`` (error ``e0 + M (du - u)`` of the state, ``du - u`` of the input, with
e0 orthogonal to the innovations that form du).  Until a row's first correction the two forms are
identical.  On the same runs the NEES is 9.09 (what remains above 9.03 is selection: a false
alarm's du is picked for its size, so it is larger than L says).

Matched motion (``matched_motion``, the conformance suite's truth model): the quiescent model in
this layout, :class:`~skytrack.filters.variable_dimension.QuiescentAccelerationAxis` with
``sigma = sigma_w`` (DWNA whose acceleration entry is the coming interval's, fresh every scan).

Onset bank (per row, arrays ``[rows, N_w, ...]``): hypothesis s says an extra constant input
started on the transition ``k-s -> k-s+1``.  One hypothesis is created after every update
(slot 0, bias ``M = 0``) and the oldest dropped, so at the update of scan k slot j holds
``s = j + 1``.  Per hypothesis, ``B_j = F M_{j-1} + G`` (predict), ``Psi_j = H B_j``,
``M_j = (I - K_j H) B_j``, ``J += Psi^T S^-1 Psi``, ``g += Psi^T S^-1 nu`` (update); then
``du_s = J^-1 g``, ``L_s = J^-1``, ``l_s = g^T J^-1 g``, ML onset ``s^ = argmax l_s``; detection
when ``l_s^ > chi2_{n_u}^-1(1 - P_fa/N_w)`` (``bonferroni=False``: ``1 - P_fa``; ``threshold``
overrides, ``inf`` disables detection).  On detection ``x <- x + M du``, ``P <- P + M L M^T``,
``u_app <- u_app + du`` (with ``propagate_input`` the cross-covariance ``M L``), and the bank is
cleared; the end of a manoeuvre is detected the same way.  The bank's recursions hold for the
gain actually used (the consider gain included), since they describe the filter's linear
response to an input.

No detection while the bank holds fewer than ``min(2, N_w)`` hypotheses.  ``N_w`` is in
[1, 50] (default 20); ``N_w = 1`` (E4) is a one-scan window: the only hypothesis is s = 1, whose
``l_1`` is the NIS of the last innovation when ``n_u = n_z``, and a detection corrects from that
innovation alone.

Costs (R22): every product goes through :mod:`skytrack.core.linalg`; predict and update process
all N_w slots (dead ones masked), so the multiply-adds per update are affine in N_w (E4).  With
detection disabled and no active recorder, ``du`` and ``l`` are not computed.

Diagnostics: recorder channel ``"detection"`` (rows, ``scan`` = the row's number of updates,
``onset`` = s^, ``delta_u``, ``ell``); when a recorder is active, ``"likelihood"`` every update
(rows, ``onset`` = s^, ``ell`` = l_s^; ``onset`` 0 and ``ell`` -inf when no hypothesis is usable)
and, with ``record_bank=True``, ``"bank"`` every update (rows, ``ell[K, N_w]`` with ``-inf`` for
empty slots, ``delta_u[K, N_w, n_u]``, ``input_cov[K, N_w, n_u, n_u]`` = L_s,
``bias[K, N_w, n, n_u]`` = M_s; slot j is s = j + 1; large: N_w (1 + n_u)(1 + n_u + n) numbers
per row and scan).  Measurements: positions only (as VD).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.core.chi2 import chi2_quantile
from skytrack.core import linalg
from skytrack.filters.base import BatchFilter, Capabilities, GaussianState, Innovation, UpdateStats
from skytrack.filters.variable_dimension import (
    ORDER,
    QuiescentAccelerationAxis,
    acceleration_index,
    check_order3,
    embedded_axis_models,
    innovate_linear,
    kalman_update,
    stack_axes,
)
from skytrack.models.motion import AxisModel, MotionModel

MAX_WINDOW = 50


def detection_threshold(n_u: int, p_fa: float, window: int, bonferroni: bool = True) -> float:
    """``chi2_{n_u}^-1(1 - P_fa/N_w)`` (Bonferroni over the N_w onset hypotheses) or ``chi2_{n_u}^-1(1 - P_fa)``."""
    if not 0.0 < p_fa < 1.0:
        raise ValueError(f"input estimation: p_fa must be in (0, 1), got {p_fa}")
    return float(chi2_quantile(1.0 - (p_fa / window if bonferroni else p_fa), n_u))


@dataclass
class InputEstimationState(GaussianState):
    """IE rows: the quiescent estimate (acceleration entries = ``u_app``) and the onset bank.

    ``bias[N, N_w, n, n_u]``: M of each hypothesis after an update, B after a prediction;
    ``information[N, N_w, n_u, n_u]`` = J; ``score[N, N_w, n_u]`` = g; ``live[N, N_w]``; slot 0 newest.
    """

    bias: np.ndarray
    information: np.ndarray
    score: np.ndarray
    live: np.ndarray
    scan: np.ndarray

    def estimate(self) -> GaussianState:
        return GaussianState(self.x, self.P)


def known_input_covariance(P: np.ndarray, ndim: int, variance) -> np.ndarray:
    """A copy of ``P`` in IE's form: no position/velocity-acceleration cross-covariance (the applied
    input is known to the position/velocity filter) and the acceleration block ``variance I``
    (the quiescent acceleration variance; ``variance`` scalar or per row)."""
    P = np.array(P, dtype=float)
    acc = acceleration_index(ndim)
    P[:, acc, :] = 0.0
    P[:, :, acc] = 0.0
    P[:, acc, acc] = np.asarray(variance, dtype=float).reshape(-1, 1)
    return P


@dataclass(frozen=True)
class AppliedInputAxis(AxisModel):
    """One axis of the IE quiescent model as a motion model: F = F_cv on position/velocity with the
    applied input carried unchanged (identity on the acceleration entry), Q = DWNA with sigma_w.
    Its F is the covariance transition; the mean adds ``G u_app`` (:meth:`InputEstimationFilter.transition`)."""

    sigma_w: float = 1.0
    order = ORDER

    def F_batch(self, dt) -> np.ndarray:
        F = embedded_axis_models(np.asarray(dt, dtype=float), self.sigma_w, 1.0)["F_cv"]
        F[..., 2, 2] = 1.0
        return F

    def Q_batch(self, dt) -> np.ndarray:
        return embedded_axis_models(np.asarray(dt, dtype=float), self.sigma_w, 1.0)["Q_cv"]


def _push(buffer: np.ndarray, newest) -> np.ndarray:
    """``buffer`` shifted by one slot along axis 1 with ``newest`` in slot 0 (the oldest drops out)."""
    head = np.broadcast_to(newest, buffer[:, :1].shape)
    return np.concatenate([head, buffer[:, :-1]], axis=1)


@dataclass(eq=False)
class InputEstimationFilter(BatchFilter):
    """Input-estimation filter with an onset-time bank (§3.3 K, R13) on ``ndim`` axes."""

    ndim: int
    sigma_w: float = 1.0
    window: int = 20
    p_fa: float = 0.01
    bonferroni: bool = True
    threshold: float | None = None
    input_axes: int | None = None
    record_bank: bool = False
    propagate_input: bool = True

    kind = "input-estimation"
    capabilities = Capabilities()
    state_type = InputEstimationState

    def __post_init__(self) -> None:
        if self.ndim not in (1, 2, 3):
            raise ValueError(f"input estimation: ndim must be 1, 2 or 3, got {self.ndim!r}")
        if not (np.isfinite(self.sigma_w) and self.sigma_w > 0):
            raise ValueError(f"input estimation: sigma_w must be finite and > 0, got {self.sigma_w}")
        if not (isinstance(self.window, (int, np.integer)) and 1 <= self.window <= MAX_WINDOW):
            raise ValueError(f"input estimation: window N_w must be an integer in [1, {MAX_WINDOW}], got {self.window!r}")
        self.window = int(self.window)
        if self.input_axes is None:
            self.input_axes = self.ndim
        if not (isinstance(self.input_axes, (int, np.integer)) and 1 <= self.input_axes <= self.ndim):
            raise ValueError(f"input estimation: input_axes must be in 1..{self.ndim}, got {self.input_axes!r}")
        if self.threshold is None:
            self.threshold = detection_threshold(self.input_axes, self.p_fa, self.window, self.bonferroni)
        elif not self.threshold > 0:
            raise ValueError(f"input estimation: threshold must be > 0 (inf disables detection), got {self.threshold}")
        self.threshold = float(self.threshold)

    @property
    def state_dim(self) -> int:
        return ORDER * self.ndim

    @property
    def n_u(self) -> int:
        return int(self.input_axes)

    @property
    def matched_motion(self) -> MotionModel:
        """Quiet flight as this filter models it: DWNA with ``sigma_w`` whose acceleration entry is the
        coming interval's, :class:`~skytrack.filters.variable_dimension.QuiescentAccelerationAxis`."""
        return MotionModel([QuiescentAccelerationAxis(self.sigma_w)] * self.ndim)

    @property
    def min_hypotheses(self) -> int:
        return min(2, self.window)

    # -------------------------------------------------------------------- initiate
    def initiate(self, x: np.ndarray, P: np.ndarray) -> InputEstimationState:
        """The given estimate with ``u_app`` = its acceleration (known, as in §3.3 K: no cross-covariance,
        acceleration covariance ``sigma_w^2 I``).  Empty bank but for the hypothesis of an onset on
        the coming transition."""
        x, P = np.array(x, dtype=float), known_input_covariance(P, self.ndim, self.sigma_w**2)
        return InputEstimationState(x, P, *self.empty_bank(len(x)), np.zeros(len(x), np.int64))

    def empty_bank(self, count: int):
        """``(bias, information, score, live)`` holding only the hypothesis of an onset on the coming transition."""
        n, w, nu = self.state_dim, self.window, self.n_u
        live = np.zeros((count, w), bool)
        live[:, 0] = True
        return np.zeros((count, w, n, nu)), np.zeros((count, w, nu, nu)), np.zeros((count, w, nu)), live

    # -------------------------------------------------------------------- predict
    def transition(self, dt: np.ndarray):
        """``(F_mean, F_cov, Q, G_u)``: the mean transition ``F_cv x + G u_app`` as one matrix, the
        covariance transition (F_cv on position/velocity, identity on the applied input), the
        DWNA Q and the input matrix ``[K, n, n_u]``."""
        models = embedded_axis_models(dt, self.sigma_w, 1.0)
        F_cov = models["F_cv"]
        F_cov[..., 2, 2] = 1.0
        F_mean = F_cov.copy()
        F_mean[..., :, 2] += models["G"]
        G_u = np.zeros(dt.shape + (self.state_dim, self.n_u))
        for axis in range(self.n_u):
            G_u[:, ORDER * axis: ORDER * axis + ORDER, axis] = models["G"]
        return (stack_axes(F_mean, self.ndim), stack_axes(F_cov, self.ndim), stack_axes(models["Q_cv"], self.ndim),
                G_u)

    def predict(self, state: InputEstimationState, dt, context: dict | None = None) -> InputEstimationState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),)).astype(float)
        F_mean, F_cov, Q, G_u = self.transition(dt)
        x = linalg.matvec(F_mean, state.x)
        if self.propagate_input:
            P = self.propagate_input_error(state.P, F_mean, Q, self.sigma_w**2)
        else:
            P = linalg.sandwich(F_cov, state.P, Q)
        return InputEstimationState(x, P, self.bank_predict(state.bias, state.live, F_cov, G_u), state.information,
                                    state.score, state.live, state.scan)

    def propagate_input_error(self, P: np.ndarray, F_mean: np.ndarray, Q: np.ndarray, variance) -> np.ndarray:
        """``F_mean (P - v E) F_mean^T + Q + v E``: the consider prediction of the covariance (module
        docstring), E the acceleration entries, v the DWNA acceleration variance (scalar or per row),
        which is the coming interval's and not an error of ``u_app``, so it is not propagated."""
        acc = acceleration_index(self.ndim)
        v = np.broadcast_to(np.asarray(variance, dtype=float), (len(P),))[:, None]
        internal = P.copy()
        internal[:, acc, acc] -= v
        predicted = linalg.sandwich(F_mean, internal, Q)
        predicted[:, acc, acc] += v
        return predicted

    # -------------------------------------------------------------------- innovate / update
    def innovate(self, state: InputEstimationState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        return innovate_linear(state, z, model, context, self.kind)

    def update(self, state: InputEstimationState, z: np.ndarray,
               innovation: Innovation) -> tuple[InputEstimationState, UpdateStats]:
        pred: InputEstimationState = innovation.predicted
        x, P, _, A = kalman_update(pred.x, pred.P, innovation.H, innovation.R, innovation.nu, innovation.chol,
                                   frozen=acceleration_index(self.ndim) if self.propagate_input else None)
        scan = pred.scan + 1
        bank = self.bank_update(pred.bias, pred.information, pred.score, pred.live, A, innovation)
        x, P, bank, _ = self.detect_and_correct(x, P, bank, scan, self.sigma_w**2)
        return InputEstimationState(x, P, *bank, scan), UpdateStats(innovation.d2 / innovation.m)

    # -------------------------------------------------------------------- the bank (shared with §3.3 L)
    def bank_predict(self, bias: np.ndarray, live: np.ndarray, F_cov: np.ndarray, G_u: np.ndarray) -> np.ndarray:
        """``B = F M + G`` for every slot (dead slots stay zero)."""
        B = linalg.matmul(F_cov[:, None], bias) + G_u[:, None]
        return np.where(live[:, :, None, None], B, 0.0)

    def bank_update(self, B, information, score, live, A, innovation: Innovation):
        """``(M, J, g, live)`` after the scan: ``M = (I - K H) B``, ``Psi = H B``, ``J += Psi^T S^-1 Psi``,
        ``g += Psi^T S^-1 nu``, with ``A = I - K H`` and S (its Cholesky factor) of the gain used.
        Every slot is processed (dead ones masked), so the cost is affine in N_w."""
        H, L, nu = innovation.H, innovation.chol, innovation.nu
        bias = linalg.matmul(A[:, None], B)
        Psi = linalg.matmul(H[:, None], B)
        weighted = linalg.cho_solve(L[:, None], Psi)  # S^-1 Psi
        information = information + linalg.matmul(np.swapaxes(Psi, -1, -2), weighted)
        score = score + linalg.matvec(np.swapaxes(weighted, -1, -2), nu[:, None])
        mask = live[:, :, None]
        return (np.where(mask[..., None], bias, 0.0), np.where(mask[..., None], information, 0.0),
                np.where(mask, score, 0.0), live)

    def detect_and_correct(self, x, P, bank, scan, quiescent_variance):
        """Detection over the updated bank, correction of the detecting rows (their acceleration block
        becomes ``L_s + quiescent_variance I``; scalar or per row), bank reset, and the new hypothesis
        of this scan: ``(x, P, (bias, information, score, live) for the next scan, detect)``."""
        bias, information, score, live = bank
        rows = len(x)
        detect = np.zeros(rows, bool)
        if np.isfinite(self.threshold) or self.recorder.active:
            delta_u, ell, input_cov = self._hypotheses(information, score, live)
            onset = np.argmax(ell, axis=1)
            best = ell[np.arange(rows), onset]
            detect = (live.sum(axis=1) >= self.min_hypotheses) & (best > self.threshold)
            if self.recorder.active:
                usable = np.isfinite(best)
                self.recorder.record("likelihood", np.arange(rows), onset=np.where(usable, onset + 1, 0), ell=best)
                if self.record_bank:
                    self.recorder.record("bank", np.arange(rows), ell=ell, delta_u=delta_u, input_cov=input_cov,
                                         bias=bias)
        if detect.any():
            hit = np.flatnonzero(detect)
            s_hat = onset[hit]
            M = bias[hit, s_hat]
            du = delta_u[hit, s_hat]
            cov = input_cov[hit, s_hat]
            x, P = x.copy(), P.copy()
            x[hit] += linalg.matvec(M, du)
            acc = acceleration_index(self.ndim)[: self.n_u]
            x[hit[:, None], acc[None, :]] += du
            P[hit] += linalg.sandwich(M, cov)
            variance = np.broadcast_to(np.asarray(quiescent_variance, dtype=float), (rows,))[hit]
            if self.propagate_input:
                # cross-covariance of the corrected state and u_app: M L (M is zero in the acceleration rows)
                cross = linalg.matmul(M, cov)
                P[hit[:, None, None], np.arange(self.state_dim)[None, :, None], acc[None, None, :]] = cross
                P[hit[:, None, None], acc[None, :, None], np.arange(self.state_dim)[None, None, :]] = \
                    np.swapaxes(cross, -1, -2)
            P[hit[:, None, None], acc[None, :, None], acc[None, None, :]] = cov + variance[:, None, None] * np.eye(self.n_u)
            live = live.copy()
            live[hit] = False
            self.recorder.record("detection", hit, scan=scan[hit], onset=s_hat + 1, delta_u=du, ell=best[hit])
        # one new hypothesis (onset on the coming transition) per scan; the oldest drops out
        keep = live[:, :, None]
        bank = (_push(np.where(keep[..., None], bias, 0.0), 0.0), _push(np.where(keep[..., None], information, 0.0), 0.0),
                _push(np.where(keep, score, 0.0), 0.0), _push(live, True))
        return x, P, bank, detect

    def _hypotheses(self, information, score, live):
        """``(du[K, N_w, n_u], l[K, N_w], L[K, N_w, n_u, n_u])``; ``l = -inf`` where a slot is empty or
        its J is not yet positive definite (a hypothesis after a zero step has no information)."""
        nu = self.n_u
        usable = live & np.all(np.diagonal(information, axis1=-2, axis2=-1) > 0.0, axis=-1)
        J = np.where(usable[:, :, None, None], information, np.eye(nu))
        chol = linalg.cholesky(J)
        delta_u = linalg.cho_solve(chol, score)
        input_cov = linalg.cho_solve(chol, np.broadcast_to(np.eye(nu), J.shape))
        ell = linalg.matvec(score[..., None, :], delta_u)[..., 0]
        return delta_u, np.where(usable, ell, -np.inf), input_cov


# Imported here, after the shared pieces: importing the registry imports every filter module, and the
# sibling modules of spec 004 §3.3 J-L import these pieces whichever module loads first.
from skytrack.filters.registry import register_filter  # noqa: E402


@register_filter("input-estimation")
def _input_estimation(motion: MotionModel, compiled: bool = True, sigma_w: float = 1.0, window: int = 20,
                      p_fa: float = 0.01, bonferroni: bool = True, threshold: float | None = None,
                      input_axes: int | None = None, record_bank: bool = False,
                      propagate_input: bool = True) -> InputEstimationFilter:
    """IE filter on the axes of an order-3 ``motion`` (only its number of axes is used).  ``compiled``
    is accepted and ignored: the family has no compiled kernel.  ``propagate_input=False`` is the
    literal §3.3 K (the applied input treated as exactly known between corrections)."""
    return InputEstimationFilter(check_order3(motion, "input-estimation"), sigma_w, window, p_fa, bonferroni,
                                 threshold, input_axes, record_bank, propagate_input)

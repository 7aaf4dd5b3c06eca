"""The paper's α–β range / closing-speed tracker (spec 004 §3.1, equations (1)–(4); R3), batched over runs.

One scan, for every run (arrays ``[runs]``), with T explicit and ``s = +1`` for
``velocity_convention="range_rate"`` (the printed signs; V = dД/dt) or ``s = −1`` for
``"closing_speed"`` (V = −dД/dt):

(1) ``Д_э(k+1) = Д_о(k) + s T V(k)``; (4) ``ΔД(k+1) = Д_и(k+1) − Д_э(k+1)``;
(2) ``Д_о(k+1) = Д_э(k+1) + α ΔД(k+1)``; (3) ``V(k+1) = V(k) + s (β/T) ΔД(k+1)``.

Both conventions give the same ranges (TV3).  Options (R3):

* ``initialisation``: ``"given"`` (Д_0, V_0 from the acquisition mode, the literal method),
  ``"two_point"`` (Д_0 = Д_и(0), V_0 = s (Д_и(1) − Д_и(0))/T: the first two measurements form the
  estimate at scan 1), ``"startup_ls"`` (growing-memory least-squares gains α_k, β_k of §3.3 C
  from any prior until the first k with α_k <= α: the estimate is the least-squares line
  through all measurements so far);
* range gate (``gating=True``): a scan whose ``|ΔД| > g √S`` is a miss (Д_о = Д_э, V unchanged);
  after ``max_misses`` (L_miss) consecutive misses a run is ``lost``: it coasts and takes no more
  measurements (break-lock);
* ``maneuver_gains``: the fading NIS detector of §3.3 J on ``ε = ΔД²/S`` (n_z = 1,
  ``u_k = ρ u_{k−1} + ε_k``, threshold ``c χ²_d⁻¹(1 − P_fa)``) switches a run to (α_m, β_m) at a
  detection (for that scan already, gate included) until u_k has stayed below the threshold for
  s = round(1/(1 − ρ)) scans; ``"kalata"`` (or True) means the Kalata gains of 10× the nominal
  λ = β/√(1 − α).  The detector sees every residual, also one that then falls outside the gate,
  and starts after the start-up gains.

The gate and detector variance S is R3's ``S₀ = σ_v² (1 + predicted-position variance ratio)``
whenever the run has been at the steady state of its gains — always, for fixed gains started
from given values (the literal method).  Where the gains change it is the innovation variance of
the gains actually used: each run carries the noise-only error covariance of its estimate
(Joseph form ``P = (I − K H) F P Fᵀ (I − K H)ᵀ + σ_v² K Kᵀ`` over the scans it used, started at
the steady state for ``given``, at the two-point covariance for ``two_point``, and exact
least-squares for ``startup_ls``, whose first two scans have no gate), and ``S = H F P Fᵀ Hᵀ + σ_v²``.
A miss leaves P as it is, as the literal fixed gate does.  Without this, a run returning from
manoeuvre gains (velocity error variance ~30× the nominal one at the defaults) would meet the
narrow nominal gate and be lost by the very option meant to keep it.

The gains used go to the recorder channel ``"gain"`` (``alpha``, ``beta`` per run) when it is active.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.filters import alpha_beta_gains as gains
from skytrack.filters.base import ArrayState, Recorder

VELOCITY_CONVENTIONS = ("range_rate", "closing_speed")
INITIALISATIONS = ("given", "two_point", "startup_ls")
#: R3's default: maneuver gains are the Kalata gains of this multiple of the nominal tracking index
MANEUVER_INDEX_FACTOR = 10.0


@dataclass
class RangeTrackState(ArrayState):
    """Per run: filtered range Д_о, velocity V (in the tracker's convention), measurements used,
    consecutive misses, lost flag, detector sum u, manoeuvre-gain flag, scans below threshold, and
    the noise-only error covariance of (range, range rate) ``p11, p12, p22`` that sets the gate."""

    range: np.ndarray
    velocity: np.ndarray
    updates: np.ndarray
    misses: np.ndarray
    lost: np.ndarray
    detector: np.ndarray
    maneuver: np.ndarray
    quiet: np.ndarray
    p11: np.ndarray
    p12: np.ndarray
    p22: np.ndarray


@dataclass
class ScanResult:
    """One scan per run: predicted range Д_э, residual ΔД, its variance S (gate and detector; inf
    during the first two start-up scans), whether the measurement was used."""

    predicted: np.ndarray
    residual: np.ndarray
    variance: np.ndarray
    used: np.ndarray


@dataclass
class RangeTrackResult:
    """Histories ``[runs, scans]``, one column per measurement column given to :meth:`RangeAlphaBeta.run`.

    Columns consumed by a two-point initialisation have no prediction or residual (NaN); the first
    column's velocity is NaN there.
    """

    predicted: np.ndarray
    residual: np.ndarray
    variance: np.ndarray
    range: np.ndarray
    velocity: np.ndarray
    used: np.ndarray
    lost: np.ndarray
    maneuver: np.ndarray
    detector: np.ndarray

    @property
    def lost_scan(self) -> np.ndarray:
        """Column at which each run was declared lost, −1 if never."""
        return np.where(self.lost.any(axis=1), np.argmax(self.lost, axis=1), -1)


@dataclass(eq=False)
class RangeAlphaBeta:
    """The α–β range tracker of (1)–(4) with fixed gains (α, β) and period T (module docstring).

    ``sigma_v`` (m) is needed by the gate and the detector; without it variances are reported in
    units of σ_v² (σ_v = 1).
    """

    alpha: float
    beta: float
    period: float
    velocity_convention: str = "range_rate"
    initialisation: str = "given"
    sigma_v: float | None = None
    gating: bool = False
    gate: float = 3.0
    max_misses: int = 3
    maneuver_gains: tuple[float, float] | str | bool | None = None
    detector_rho: float = 0.8
    detector_p_fa: float = 0.01
    recorder: Recorder = field(default_factory=Recorder)

    def __post_init__(self) -> None:
        if self.velocity_convention not in VELOCITY_CONVENTIONS:
            raise ValueError(f"velocity_convention must be one of {VELOCITY_CONVENTIONS}, got {self.velocity_convention!r}")
        if self.initialisation not in INITIALISATIONS:
            raise ValueError(f"initialisation must be one of {INITIALISATIONS}, got {self.initialisation!r}")
        if not (np.isfinite(self.period) and self.period > 0):
            raise ValueError(f"period T must be finite and > 0, got {self.period}")
        gains.check_stable(self.alpha, self.beta, option="RangeAlphaBeta gains")
        self.sign = 1.0 if self.velocity_convention == "range_rate" else -1.0
        self.startup_length = 1
        if self.initialisation == "startup_ls":
            self.startup_length = gains.startup_length(self.alpha, 2)  # checks alpha in (0, 1]
        if self.maneuver_gains is True or self.maneuver_gains == "kalata":
            nominal = gains.equivalent_tracking_index(self.alpha, self.beta)
            self.maneuver_pair = gains.kalata_alpha_beta(MANEUVER_INDEX_FACTOR * nominal)
        elif self.maneuver_gains is None or self.maneuver_gains is False:
            self.maneuver_pair = None
        elif isinstance(self.maneuver_gains, str):
            raise ValueError(f"maneuver_gains must be None, 'kalata' or a pair (alpha_m, beta_m), got {self.maneuver_gains!r}")
        else:
            pair = tuple(float(v) for v in self.maneuver_gains)
            if len(pair) != 2:
                raise ValueError(f"maneuver_gains must be a pair (alpha_m, beta_m), got {self.maneuver_gains!r}")
            gains.check_stable(*pair, option="maneuver_gains")
            self.maneuver_pair = pair
        needs_sigma = self.gating or self.maneuver_pair is not None
        if needs_sigma and not (self.sigma_v is not None and np.isfinite(self.sigma_v) and self.sigma_v > 0):
            raise ValueError(f"sigma_v (> 0) is needed for the range gate and the manoeuvre detector, got {self.sigma_v}")
        if not (np.isfinite(self.gate) and self.gate > 0):
            raise ValueError(f"gate g must be finite and > 0, got {self.gate}")
        if int(self.max_misses) != self.max_misses or self.max_misses < 1:
            raise ValueError(f"max_misses (L_miss) must be an integer >= 1, got {self.max_misses}")
        if self.maneuver_pair is not None:
            self.threshold = gains.detector_threshold(1, self.detector_rho, self.detector_p_fa)
            self.window = gains.detector_window(self.detector_rho)

    # -------------------------------------------------------------------- analysis
    def gate_variance(self, alpha: float | None = None, beta: float | None = None) -> float:
        """``S₀ = σ_v² (1 + (2α² + αβ + 2β)/(α(4 − 2α − β)))`` of the nominal (or the given) gains."""
        a = self.alpha if alpha is None else alpha
        b = self.beta if beta is None else beta
        return self._sigma2 * (1.0 + gains.variance_ratios(a, b).predicted_position)

    @property
    def _sigma2(self) -> float:
        return float(self.sigma_v) ** 2 if self.sigma_v is not None else 1.0

    # -------------------------------------------------------------------- state
    def start(self, range0, velocity0) -> RangeTrackState:
        """State from Д_0, V_0 (``given``; for ``startup_ls`` any prior one period before the first scan)."""
        rng, vel = np.broadcast_arrays(np.array(range0, dtype=float), np.array(velocity0, dtype=float))
        rng, vel = np.atleast_1d(rng).copy(), np.atleast_1d(vel).copy()
        runs = len(rng)
        zeros_i = np.zeros(runs, dtype=np.int64)
        if self.initialisation == "startup_ls":  # any prior: exact least squares from the second scan
            cov = np.zeros(3)
        else:
            P = gains.steady_state_covariance(self.alpha, self.beta, None, self.period, self._sigma2)[0]
            cov = np.array([P[0, 0], P[0, 1], P[1, 1]])
        return RangeTrackState(rng, vel, zeros_i.copy(), zeros_i.copy(), np.zeros(runs, dtype=bool), np.zeros(runs),
                               np.zeros(runs, dtype=bool), zeros_i.copy(), *(np.full(runs, c) for c in cov))

    def start_two_point(self, z0, z1) -> RangeTrackState:
        """The two-point acquisition: estimate at scan 1 is ``Д_и(1)`` and ``s (Д_и(1) − Д_и(0))/T``."""
        z0, z1 = np.atleast_1d(np.asarray(z0, dtype=float)), np.atleast_1d(np.asarray(z1, dtype=float))
        state = self.start(z1, self.sign * (z1 - z0) / self.period)
        state.updates[:] = 2
        T, var = self.period, self._sigma2
        state.p11[:], state.p12[:], state.p22[:] = var, var / T, 2.0 * var / (T * T)
        return state

    # -------------------------------------------------------------------- one scan
    def step(self, state: RangeTrackState, z) -> tuple[RangeTrackState, ScanResult]:
        """Process one measurement per run (pure: returns a new state)."""
        T, sign = self.period, self.sign
        z = np.broadcast_to(np.asarray(z, dtype=float), state.range.shape)
        predicted = state.range + sign * T * state.velocity
        residual = z - predicted
        k = state.updates + 1
        in_startup = k < self.startup_length
        alpha = np.full(len(z), float(self.alpha))
        beta = np.full(len(z), float(self.beta))
        if in_startup.any():
            a_k, b_k = gains.startup_gains(k, 2)
            alpha, beta = np.where(in_startup, a_k, alpha), np.where(in_startup, b_k, beta)
        # noise-only predicted covariance of (range, range rate) and the innovation variance
        m11 = state.p11 + 2.0 * T * state.p12 + T * T * state.p22
        m12 = state.p12 + T * state.p22
        S = np.where(in_startup & (state.updates < 2), np.inf, m11 + self._sigma2)
        u, maneuver, quiet = state.detector.copy(), state.maneuver.copy(), state.quiet.copy()
        if self.maneuver_pair is not None:
            watching = ~in_startup & ~state.lost
            u = np.where(watching, self.detector_rho * u + residual**2 / S, u)
            detected = watching & (u > self.threshold)
            quiet = np.where(detected | ~maneuver, 0, quiet + watching)
            maneuver = (maneuver | detected) & (quiet < self.window)
            quiet = np.where(maneuver, quiet, 0)
            alpha = np.where(maneuver, self.maneuver_pair[0], alpha)
            beta = np.where(maneuver, self.maneuver_pair[1], beta)
        used = ~state.lost
        if self.gating:
            used &= np.abs(residual) <= self.gate * np.sqrt(S)
        new_range = np.where(used, predicted + alpha * residual, predicted)
        new_velocity = np.where(used, state.velocity + sign * (beta / T) * residual, state.velocity)
        k1, k2, var = alpha, beta / T, self._sigma2
        p11 = np.where(used, (1.0 - k1) ** 2 * m11 + k1 * k1 * var, state.p11)
        p12 = np.where(used, (1.0 - k1) * (m12 - k2 * m11) + k1 * k2 * var, state.p12)
        p22 = np.where(used, k2 * k2 * (m11 + var) - 2.0 * k2 * m12 + state.p22, state.p22)
        misses = np.where(used, 0, state.misses + 1)
        lost = state.lost | (self.gating & (misses >= self.max_misses))
        if self.recorder.active:
            self.recorder.record("gain", np.arange(len(z)), alpha=alpha, beta=beta)
        new = RangeTrackState(new_range, new_velocity, state.updates + used, misses, lost, u, maneuver, quiet,
                              p11, p12, p22)
        return new, ScanResult(predicted, residual, S, used)

    # -------------------------------------------------------------------- whole runs
    def run(self, measurements, range0=None, velocity0=None) -> RangeTrackResult:
        """Track ``measurements[runs, scans]`` (one row per run).

        ``given``: column j is Д_и(j+1) and (range0, velocity0) the estimate at scan 0.
        ``two_point``: columns 0 and 1 initialise (the estimate at column 1), later columns are filtered.
        ``startup_ls``: every column is filtered from the prior (range0, velocity0), by default the
        first measurement and zero velocity one period before it (any prior gives the same
        estimates from the second measurement on).
        """
        z = np.atleast_2d(np.asarray(measurements, dtype=float))
        runs, scans = z.shape
        out = {name: np.full((runs, scans), np.nan) for name in ("predicted", "residual", "variance", "range", "velocity",
                                                                 "detector")}
        flags = {name: np.zeros((runs, scans), dtype=bool) for name in ("used", "lost", "maneuver")}
        first = 0
        if self.initialisation == "given":
            if range0 is None or velocity0 is None:
                raise ValueError("initialisation 'given' needs range0 and velocity0 (from the acquisition mode)")
            state = self.start(np.broadcast_to(range0, (runs,)), np.broadcast_to(velocity0, (runs,)))
        elif self.initialisation == "two_point":
            if scans < 2:
                raise ValueError("initialisation 'two_point' needs at least two measurement columns")
            state = self.start_two_point(z[:, 0], z[:, 1])
            out["range"][:, 0], out["range"][:, 1], out["velocity"][:, 1] = z[:, 0], z[:, 1], state.velocity
            out["detector"][:, :2] = 0.0
            flags["used"][:, :2] = True
            first = 2
        else:
            prior = z[:, 0] if range0 is None else np.broadcast_to(range0, (runs,))
            state = self.start(prior, np.broadcast_to(0.0 if velocity0 is None else velocity0, (runs,)))
        for j in range(first, scans):
            state, scan = self.step(state, z[:, j])
            out["predicted"][:, j], out["residual"][:, j], out["variance"][:, j] = scan.predicted, scan.residual, scan.variance
            out["range"][:, j], out["velocity"][:, j], out["detector"][:, j] = state.range, state.velocity, state.detector
            flags["used"][:, j], flags["lost"][:, j], flags["maneuver"][:, j] = scan.used, state.lost, state.maneuver
        return RangeTrackResult(out["predicted"], out["residual"], out["variance"], out["range"], out["velocity"], flags["used"],
                                flags["lost"], flags["maneuver"], out["detector"])

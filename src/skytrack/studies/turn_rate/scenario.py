"""Scenario, configurations and prototype numbers of spec 002 §6 E3/E4 (``skytrack study turn-rate-adaptive``).

* truth: coordinated turn (R2) with a piecewise-constant turn rate ω(t) = 0 on [0, 60) s, +3°/s on
  [60, 92), 0 on [92, 152), −1.5°/s on [152, 212), 0 on [212, 272]; sensor at the origin,
  p(0) = (0, 30 km), v(0) = (200, 0) m/s; the step t_k → t_{k+1} uses ω(t_k).  The truth state
  x(k) = φ(x(k−1) with ω := ω(t_{k−1})) therefore carries, as its ω component, the turn rate of
  the interval ending at t_k — the quantity the filter's ω̂(k|k) estimates (eqs. 3-4: the parameter
  receives its disturbance at t_{k−1} and the whole state propagates it);
* measurements every T: (x, y) with σ = 20 m, optionally range rate ṙ with σ = 0.5 m/s (R4);
* the five metric windows (two turns, three straight legs);
* the filter configurations of E3 (fixed V_w, adaptive λ, literal R13 with the R14 preset's Q_dep,
  floor and ceiling) on top of the ``ct-omega-adaptive`` preset (R14);
* the prototype ω-RMSE table of E3 and the divergence fractions of E4, with the spec's tolerances
  (factor 1.5 on RMSE, ±15 percentage points on divergence fractions).

Angles inside are in rad; the tables of the spec are in °/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.models.augmented import ct_omega_transition

DEG = math.pi / 180.0

#: sensor position (m), truth start p(0) (m) and v(0) (m/s)
SENSOR = (0.0, 0.0)
START_POSITION = (0.0, 30_000.0)
START_VELOCITY = (200.0, 0.0)
#: end of the scenario, s (the last sample is t = 272 s)
DURATION = 272.0
#: (start s, end s, turn rate rad/s) of the piecewise-constant ω(t)
TURN_SCHEDULE = ((0.0, 60.0, 0.0), (60.0, 92.0, 3.0 * DEG), (92.0, 152.0, 0.0),
                 (152.0, 212.0, -1.5 * DEG), (212.0, math.inf, 0.0))
#: metric windows [start, end) s and their names, in the spec's order
WINDOWS = ((20.0, 60.0), (60.0, 92.0), (100.0, 152.0), (152.0, 212.0), (220.0, 272.0))
WINDOW_NAMES = ("straight 1", "turn 1", "straight 2", "turn 2", "straight 3")
STRAIGHT_WINDOWS = (0, 2, 4)
TURN_WINDOWS = (1, 3)

SIGMA_POSITION = 20.0  # m
SIGMA_RANGE_RATE = 0.5  # m/s
SIGMA_INITIAL_VELOCITY = 10.0  # m/s, per axis, on top of the true v(0)
#: P(0|0) of E3: diag(400 m², 400 m², 100 (m/s)², 100 (m/s)², (2°/s)²)
INITIAL_COVARIANCE = np.diag([400.0, 400.0, 100.0, 100.0, (2.0 * DEG) ** 2])
#: run diverged when its position error exceeds this at any sample (m)
DIVERGENCE_DISTANCE = 1000.0

#: R14 ``ct-omega-adaptive``
PRESET_Q_ACCEL = 1.0  # m²/s³
PRESET_V_W0 = 1e-4**2  # (rad/s)²
PRESET_SIGMA_MIN = 1e-5  # rad/s per step
PRESET_SIGMA_MAX = 2.0 * DEG  # rad/s per step
PRESET_FORGETTING = 0.8

MEASUREMENT_SETS = {"pos": ("pos",), "pos+rdot": ("pos", "rdot")}
MEASUREMENT_LABELS = {"pos": "pos", "pos+rdot": "pos+ṙ"}

#: spec's tolerances for the comparison with the prototype
RMSE_FACTOR = 1.5
DIVERGENCE_POINTS = 15.0


@dataclass(frozen=True)
class Configuration:
    """One filter configuration of E3: ``kind`` fixed / adaptive / literal with its σ_w or λ."""

    key: str
    label: str
    kind: str
    sigma_w_deg: float | None = None
    forgetting: float | None = None


CONFIGURATIONS = (
    Configuration("fixed-0.1", "fixed 0.1", "fixed", sigma_w_deg=0.1),
    Configuration("fixed-0.5", "fixed 0.5", "fixed", sigma_w_deg=0.5),
    Configuration("adaptive-0.8", "adaptive 0.8", "adaptive", forgetting=0.8),
    Configuration("adaptive-0.95", "adaptive 0.95", "adaptive", forgetting=0.95),
    Configuration("literal", "literal", "literal"),
)
CONFIGURATION_KEYS = tuple(c.key for c in CONFIGURATIONS)
FIXED_KEYS = ("fixed-0.1", "fixed-0.5")

# Prototype ω-RMSE (°/s), 100 runs, q_a = 1 m²/s³: (T, measurement set) -> configuration -> five windows.
PROTOTYPE_OMEGA_RMSE = {
    (1.0, "pos"): {"fixed-0.1": (.108, 1.27, .282, .470, .165), "fixed-0.5": (.426, .993, .438, .533, .420),
                   "adaptive-0.8": (.704, 1.31, .817, .908, .752), "adaptive-0.95": (.523, 1.68, .832, 1.07, .853),
                   "literal": (.831, 1.17, .851, .888, .804)},
    (1.0, "pos+rdot"): {"fixed-0.1": (.038, .640, .129, .387, .046), "fixed-0.5": (.128, .275, .172, .265, .138),
                        "adaptive-0.8": (.007, .201, .059, .330, .018),
                        "adaptive-0.95": (.030, .246, .518, .495, .211),
                        "literal": (.119, .492, .234, .399, .136)},
    (4.0, "pos"): {"fixed-0.1": (.072, 1.42, .509, .523, .256), "fixed-0.5": (.238, .928, .276, .418, .258),
                   "adaptive-0.8": (.253, 1.27, .582, .736, .536), "adaptive-0.95": (.188, 1.87, .631, .579, .527),
                   "literal": (.598, .933, .725, .753, .680)},
    (4.0, "pos+rdot"): {"fixed-0.1": (.021, .822, .300, .467, .085), "fixed-0.5": (.046, .206, .096, .216, .055),
                        "adaptive-0.8": (.009, .179, .080, .218, .036),
                        "adaptive-0.95": (.009, .178, .096, .219, .041),
                        "literal": (.028, .226, .093, .355, .050)},
}
# Prototype divergence fractions (%) of E4 (q_a = 0, 100 runs); with q_a = 1 they are 0 everywhere.
PROTOTYPE_DIVERGENCE_NO_QDEP = {
    (1.0, "pos"): {"fixed-0.1": 0, "fixed-0.5": 0, "adaptive-0.8": 0, "adaptive-0.95": 0, "literal": 0},
    (1.0, "pos+rdot"): {"fixed-0.1": 0, "fixed-0.5": 6, "adaptive-0.8": 24, "adaptive-0.95": 17, "literal": 71},
    (4.0, "pos"): {"fixed-0.1": 100, "fixed-0.5": 0, "adaptive-0.8": 36, "adaptive-0.95": 78, "literal": 32},
    (4.0, "pos+rdot"): {"fixed-0.1": 0, "fixed-0.5": 20, "adaptive-0.8": 73, "adaptive-0.95": 72, "literal": 96},
}
#: spec's range of position RMSE (m) over every q_a = 1 configuration and window
POSITION_RMSE_RANGE = (9.7, 54.0)


def prototype_divergence(T: float, measurement: str, key: str, q_accel: float) -> float | None:
    """The prototype's divergence fraction in %, or None when the spec gives none for this setting."""
    if q_accel == PRESET_Q_ACCEL:
        return 0.0
    if q_accel == 0.0:
        table = PROTOTYPE_DIVERGENCE_NO_QDEP.get((float(T), measurement))
        return None if table is None else float(table[key])
    return None


def prototype_omega_rmse(T: float, measurement: str, key: str, q_accel: float):
    """The five prototype ω-RMSE values (°/s) or None (no prototype for other T or q_a)."""
    if q_accel != PRESET_Q_ACCEL:
        return None
    table = PROTOTYPE_OMEGA_RMSE.get((float(T), measurement))
    return None if table is None else table.get(key)


def sample_times(T: float) -> np.ndarray:
    """t_k = kT for k = 0 … ⌊272/T⌋ (s)."""
    count = int(math.floor(DURATION / T + 1e-9)) + 1
    return np.arange(count) * float(T)


def turn_rate(t) -> np.ndarray:
    """ω(t) of the schedule (rad/s), vectorised over times."""
    t = np.asarray(t, float)
    out = np.zeros_like(t)
    for start, end, omega in TURN_SCHEDULE:
        out = np.where((t >= start) & (t < end), omega, out)
    return out


#: which sample's ω drives the truth step t_k → t_{k+1}: "start" = ω(t_k) (spec 002 E3's text),
#: "end" = ω(t_{k+1}) (turns one sample earlier; reproduces the prototype's numbers, see the report)
TRUTH_RATE_CHOICES = ("start", "end")


def simulate_truth(T: float, rate_at: str = "start") -> tuple[np.ndarray, np.ndarray]:
    """Times ``[K]`` and the truth states ``[K, 5]`` = (x, y, vx, vy, ω) in spec 002 order.

    ``rate_at="start"``: the step t_k → t_{k+1} uses ω(t_k) (E3), so row k holds ω of the interval
    ending at t_k (row 0: ω(0)).  ``"end"``: the step uses ω(t_{k+1}) and row k holds ω(t_k).
    """
    if rate_at not in TRUTH_RATE_CHOICES:
        raise ValueError(f"rate_at must be one of {TRUTH_RATE_CHOICES}, got {rate_at!r}")
    times = sample_times(T)
    states = np.empty((len(times), 5))
    states[0] = (*START_POSITION, *START_VELOCITY, turn_rate(0.0))
    rates = turn_rate(times)
    shift = 0 if rate_at == "start" else 1
    for k in range(1, len(times)):
        previous = states[k - 1].copy()
        previous[4] = rates[k - 1 + shift]
        states[k] = ct_omega_transition(previous[None], np.array([float(T)]))[0]
    return times, states


def range_rate(states: np.ndarray) -> np.ndarray:
    """ṙ of states ``[..., ≥4]`` from the sensor at the origin (m/s)."""
    rel = states[..., :2] - np.asarray(SENSOR)
    return np.einsum("...i,...i->...", rel, states[..., 2:4]) / np.hypot(rel[..., 0], rel[..., 1])


def measurement_noise(measurement: str) -> np.ndarray:
    """V_η for a measurement set: diag(σ_pos², σ_pos²[, σ_ṙ²])."""
    sigmas = [SIGMA_POSITION, SIGMA_POSITION] + ([SIGMA_RANGE_RATE] if measurement == "pos+rdot" else [])
    return np.diag(np.square(sigmas))


def simulate_measurements(truth: np.ndarray, measurement: str, runs: int, rng: np.random.Generator):
    """Measurements ``[K, runs, m]`` of the truth and the initial velocities ``[runs, 2]`` (true v(0) + N(0, 10²)).

    The position channels and v(0) are drawn first, so with the same generator state a run's (x, y) and
    initial velocity are the same with and without ṙ.
    """
    K = len(truth)
    position = truth[:, None, :2] + SIGMA_POSITION * rng.standard_normal((K, runs, 2))
    velocity0 = truth[0, 2:4] + SIGMA_INITIAL_VELOCITY * rng.standard_normal((runs, 2))
    if measurement == "pos":
        return position, velocity0
    rdot = range_rate(truth)[:, None] + SIGMA_RANGE_RATE * rng.standard_normal((K, runs))
    return np.concatenate([position, rdot[..., None]], axis=2), velocity0


def window_masks(times: np.ndarray) -> np.ndarray:
    """``[5, K]`` booleans: sample k lies in window w."""
    return np.stack([(times >= start) & (times < end) for start, end in WINDOWS])


def setup_seed(seed: int, T: float) -> list[int]:
    """Entropy of one sampling period: the same draws for every configuration and both measurement sets
    (common random numbers: the configurations are compared on the same data)."""
    return [int(seed), int(round(T * 1000))]

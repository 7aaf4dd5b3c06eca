"""Batched Monte Carlo runs of spec 002 §6 E3/E4: the adaptive augmented filter and spec 004's IMM.

* :func:`build_filter_for` — the ``ct-omega-adaptive`` preset of R14 (R2 model, white-acceleration
  Q_dep with PSD q_a, V_w0 = (10⁻⁴ rad/s)², σ_min = 10⁻⁵ rad/s, σ_max = 2°/s per step) turned into one
  E3 configuration: *fixed* σ_w (σ_min = σ_max = σ_w, so Π of A5.5 pins V̂_w = σ_w² whatever the
  estimator says: adaptation off), *adaptive* λ (R12 defaults otherwise: innovation weighting,
  n_0 = 1, timing same), *literal* (R13: weighting none, λ = 0, n_0 = 0, explicit inverse, but with
  the preset's Q_dep, floor and ceiling);
* :func:`run_configuration` — every run of one configuration as the rows of one
  :class:`~skytrack.filters.adaptive_augmented.AdaptiveAugmentedFilter` (R11), initialised as E3 says:
  x̂ = (y_x(0), y_y(0), true v(0) + N(0, (10 m/s)²), 0), P = diag(400, 400, 100, 100, (2°/s)²);
* :func:`run_imm` — spec 004's IMM (``build_filter("imm", …, model_set="cv-ct")``, state per axis
  [x, vx, y, vy]) on the same position measurements, batched over runs; its turn-rate estimate is
  the mode-probability mix Σ μ_j ω_j.

A run whose position error exceeds 1 km at some sample is *diverged* (E3): it is counted, excluded
from the metrics, and its filter row is reset to a harmless state so that one exploding row cannot
stop the batch (Cholesky of a non-positive-definite matrix, overflow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.filters.adaptive_augmented import AdaptiveAugmentedFilter, AdaptiveSettings, literal_settings
from skytrack.models.augmented import ct_omega
from skytrack.models.augmented_measurements import measurement_for
from skytrack.studies.turn_rate import scenario as sc

#: IMM (spec 004 R17/R18) for the comparison: cv-ct set with CT modes at ±3°/s (the truth's largest
#: turn rate; the spec 004 default n0 g0 / V0 would give 14°/s at 200 m/s), DWNA σ = 1 m/s², sojourn 20/10/10 s
IMM_TURN_RATE_DEG = 3.0
IMM_OPTIONS = {"model_set": "cv-ct", "turn_rate_deg_s": IMM_TURN_RATE_DEG}


@dataclass
class RunSet:
    """Per-sample results of one configuration on one setup (``[K, N]`` arrays, N = runs).

    ``omega_hat`` in rad/s, ``position_error`` in m (Euclidean), ``sigma_w`` = √V̂_w in rad/s
    (NaN for the IMM), ``diverged`` ``[N]``.
    """

    key: str
    times: np.ndarray
    omega_true: np.ndarray  # [K]
    omega_hat: np.ndarray
    position_error: np.ndarray
    sigma_w: np.ndarray
    diverged: np.ndarray
    skipped: np.ndarray  # [N] steps whose A5 was skipped (A4)


def build_filter_for(config: sc.Configuration, measurement: str, q_accel: float = sc.PRESET_Q_ACCEL):
    """The E3 configuration's filter on top of the ``ct-omega-adaptive`` preset (R14)."""
    model = ct_omega(sigma_omega=math.sqrt(sc.PRESET_V_W0), q_accel=q_accel)
    channels = measurement_for(model, sc.MEASUREMENT_SETS[measurement], sensor=sc.SENSOR)
    floor, ceiling = np.array([sc.PRESET_SIGMA_MIN]), np.array([sc.PRESET_SIGMA_MAX])
    if config.kind == "fixed":
        sigma = np.array([config.sigma_w_deg * sc.DEG])
        settings = AdaptiveSettings(sigma_min=sigma, sigma_max=sigma, forgetting=sc.PRESET_FORGETTING)
    elif config.kind == "adaptive":
        settings = AdaptiveSettings(sigma_min=floor, sigma_max=ceiling, forgetting=config.forgetting)
    elif config.kind == "literal":
        settings = literal_settings(floor, ceiling, dependent_noise=True)
    else:
        raise ValueError(f"unknown configuration kind {config.kind!r}")
    return AdaptiveAugmentedFilter(model, channels, settings)


def initial_estimates(measurements: np.ndarray, velocity0: np.ndarray) -> np.ndarray:
    """x̂(0|0) = (y_x(0), y_y(0), v̂(0), 0) per run ``[N, 5]``."""
    runs = measurements.shape[1]
    return np.c_[measurements[0, :, :2], velocity0, np.zeros(runs)]


def run_configuration(config: sc.Configuration, T: float, measurement: str, times: np.ndarray,
                      truth: np.ndarray, measurements: np.ndarray, velocity0: np.ndarray,
                      q_accel: float = sc.PRESET_Q_ACCEL) -> RunSet:
    """All runs of one configuration as the rows of one adaptive filter; ``measurements`` ``[K, N, m]``."""
    filt = build_filter_for(config, measurement, q_accel)
    K, N, _ = measurements.shape
    x0 = initial_estimates(measurements, velocity0)
    state = filt.initial_state(x0, sc.INITIAL_COVARIANCE, V_w0=[[sc.PRESET_V_W0]])
    reset = filt.initial_state(np.tile(truth[0], (N, 1)), sc.INITIAL_COVARIANCE, V_w0=[[sc.PRESET_V_W0]])
    noise_cov = sc.measurement_noise(measurement)
    omega_hat, error, sigma_w = np.full((K, N), np.nan), np.full((K, N), np.nan), np.full((K, N), np.nan)
    omega_hat[0] = x0[:, 4]
    error[0] = np.hypot(*(x0[:, :2] - truth[0, :2]).T)
    sigma_w[0] = math.sqrt(sc.PRESET_V_W0)
    diverged = error[0] > sc.DIVERGENCE_DISTANCE
    for k in range(1, K):
        with np.errstate(all="ignore"):
            record = filt.step(state, measurements[k], T, noise_cov)
        omega_hat[k] = record.x[:, 4]
        error[k] = np.hypot(*(record.x[:, :2] - truth[k, :2]).T)
        sigma_w[k] = np.sqrt(record.V_w[:, 0, 0])
        bad = ~np.isfinite(error[k]) | (error[k] > sc.DIVERGENCE_DISTANCE) | ~np.all(np.isfinite(state.P), (1, 2))
        diverged |= bad
        if bad.any():
            _reset_rows(state, reset, bad, truth[k])
    return RunSet(config.key, times, truth[:, 4], omega_hat, error, sigma_w, diverged, state.skipped.copy())


def _reset_rows(state, reset, rows: np.ndarray, truth_k: np.ndarray) -> None:
    """Put diverged rows on the truth with the initial covariance and memory (they are excluded anyway)."""
    state.x[rows] = truth_k
    state.P[rows] = reset.P[rows]
    state.V_bar[rows] = reset.V_bar[rows]
    state.count[rows] = reset.count[rows]


def run_imm(T: float, times: np.ndarray, truth: np.ndarray, measurements: np.ndarray,
            velocity0: np.ndarray) -> RunSet:
    """Spec 004's IMM (cv-ct) on the position channels, batched over runs; ω̂ = Σ μ_j ω_j."""
    from skytrack.filters.registry import build_filter
    from skytrack.models.converted import ConvertedPositionModel
    from skytrack.models.motion import constant_velocity

    filt = build_filter("imm", constant_velocity(2, 1.0), **IMM_OPTIONS)
    mode_rates = np.array([0.0, IMM_TURN_RATE_DEG * sc.DEG, -IMM_TURN_RATE_DEG * sc.DEG])
    K, N, _ = measurements.shape
    z = measurements[:, :, :2]
    R = np.broadcast_to(sc.measurement_noise("pos"), (N, 2, 2)).copy()
    model = ConvertedPositionModel(2, 2)
    # per-axis layout [x, vx, y, vy] (spec 004) from spec 002's [x, y, vx, vy]
    x0 = np.c_[z[0, :, 0], velocity0[:, 0], z[0, :, 1], velocity0[:, 1]]
    P0 = np.diag([sc.INITIAL_COVARIANCE[0, 0], sc.INITIAL_COVARIANCE[2, 2],
                  sc.INITIAL_COVARIANCE[1, 1], sc.INITIAL_COVARIANCE[3, 3]])
    state = filt.initiate(x0, np.broadcast_to(P0, (N, 4, 4)).copy())
    omega_hat, error = np.full((K, N), np.nan), np.full((K, N), np.nan)
    omega_hat[0] = state.mu @ mode_rates
    error[0] = np.hypot(x0[:, 0] - truth[0, 0], x0[:, 2] - truth[0, 1])
    diverged = error[0] > sc.DIVERGENCE_DISTANCE
    dt = np.full(N, float(T))
    for k in range(1, K):
        predicted = filt.predict(state, dt)
        innovation = filt.innovate(predicted, z[k], model, {"R": R})
        state, _ = filt.update(predicted, z[k], innovation)
        estimate = state.estimate().x
        omega_hat[k] = state.mu @ mode_rates
        error[k] = np.hypot(estimate[:, 0] - truth[k, 0], estimate[:, 2] - truth[k, 1])
        diverged |= ~np.isfinite(error[k]) | (error[k] > sc.DIVERGENCE_DISTANCE)
    return RunSet("imm", times, truth[:, 4], omega_hat, error, np.full((K, N), np.nan), diverged,
                  np.zeros(N, dtype=int))


def simulate_setup(T: float, measurement: str, runs: int, seed: int, truth_rate: str = "start"):
    """Truth, measurements ``[K, runs, m]`` and initial velocities of one setup (common random numbers)."""
    times, truth = sc.simulate_truth(T, truth_rate)
    rng = np.random.default_rng(sc.setup_seed(seed, T))
    measurements, velocity0 = sc.simulate_measurements(truth, measurement, runs, rng)
    return times, truth, measurements, velocity0

"""Monte Carlo measurements of the studies (spec 004 §6 common defaults, R21).

Runs are the batch dimension.  Run r draws its noise from its own generator
``numpy.random.default_rng(SeedSequence(seed).spawn(runs)[r])`` (R21), so a run's
measurements depend neither on the number of runs nor on the batching; every filter of a
study sees the same measurements (common random numbers).

Measurement modes:

* ``polar`` (default) — the 3-D radar of the case measures range, azimuth and elevation of the
  truth with independent Gaussian errors (sigma_r, sigma_az, sigma_el); each plot is converted
  to Cartesian with the linearised covariance ``J diag(sigma^2) J^T`` of
  :func:`skytrack.models.conversion.convert_plots`, evaluated at the measured plot (so R
  varies from run to run: spec 004 §3.5 item 8);
* ``cartesian`` — ``z = p + v`` with ``v ~ N(0, sigma^2 I)``: a fixed R, identical across runs
  (E2, E9 b);
* ``cartesian_uniform`` — ``v`` uniform in the ball of radius sigma, i.e. in ``E(0, sigma^2 I)``
  (E9 a, bounded noise); ``R`` is then that bound ``sigma^2 I`` (the noise covariance is
  ``sigma^2 I / 5``);
* ``polar_doppler`` — the ``polar`` plots (the same draws, so the positions equal those of
  ``polar`` for the same seed) plus the radial velocity ``rdot = (p - p_s) . v / |p - p_s|`` of the
  truth relative to the static radar with a Gaussian error of ``range_rate_sigma`` (default
  :data:`DEFAULT_RANGE_RATE_SIGMA`), drawn from each run's generator after its position noise
  (E10 (1)); ``MeasurementSet.range_rate[K, runs]`` and ``range_rate_sigma`` hold them (None in
  the other modes).  Filters measure range rate through
  ``skytrack.models.converted.ConvertedPositionModel(3, order, range_rate_sigma=...)``.

Arrays are scan-major: ``z[K, runs, 3]``, ``R[K, runs, 3, 3]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.geo.polar import cartesian_to_polar
from skytrack.geo.sensors import Sensor
from skytrack.models.conversion import convert_plots
from skytrack.studies.maneuver.scenarios import Case, SensorSpec

MODES = ("polar", "cartesian", "cartesian_uniform", "polar_doppler")
#: range-rate error st. dev. of the ``polar_doppler`` mode (m/s): a pulse-Doppler radar's order of magnitude
DEFAULT_RANGE_RATE_SIGMA = 1.0


@dataclass(frozen=True)
class MeasurementSet:
    """Measurements of one case: ``z[K, runs, 3]`` (ENU m) and ``R[K, runs, 3, 3]``; with ``polar_doppler``
    also the measured range rate ``range_rate[K, runs]`` (m/s) and its error st. dev."""

    z: np.ndarray
    R: np.ndarray
    mode: str
    seed: int
    range_rate: np.ndarray | None = None
    range_rate_sigma: float | None = None

    @property
    def runs(self) -> int:
        return self.z.shape[1]

    @property
    def scans(self) -> int:
        return self.z.shape[0]


def run_generators(seed: int, runs: int) -> list[np.random.Generator]:
    """Generator of run r: ``default_rng(SeedSequence(seed).spawn(runs)[r])`` (R21)."""
    if int(runs) != runs or runs < 1:
        raise ValueError(f"--runs must be a positive integer, got {runs}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"--seed must be a non-negative integer, got {seed}")
    return [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(int(runs))]


def standard_noise(seed: int, runs: int, scans: int) -> np.ndarray:
    """Standard normal draws ``[K, runs, 3]``; run r's column comes from run r's generator only."""
    noise = np.empty((scans, runs, 3))
    for r, rng in enumerate(run_generators(seed, runs)):
        noise[:, r, :] = rng.standard_normal((scans, 3))
    return noise


def radar_noise_with_range_rate(seed: int, runs: int, scans: int) -> tuple[np.ndarray, np.ndarray]:
    """Standard normal draws ``[K, runs, 3]`` (equal to :func:`standard_noise`) and, drawn after them from
    the same run generator, ``[K, runs]`` for the range rate."""
    noise = np.empty((scans, runs, 3))
    extra = np.empty((scans, runs))
    for r, rng in enumerate(run_generators(seed, runs)):
        noise[:, r, :] = rng.standard_normal((scans, 3))
        extra[:, r] = rng.standard_normal(scans)
    return noise, extra


def true_range_rate(position: np.ndarray, velocity: np.ndarray, sensor_position) -> np.ndarray:
    """``rdot = (p - p_s) . v / |p - p_s|`` of truth ``[K, 3]`` relative to a static sensor (positive opening)."""
    rel = np.asarray(position, dtype=float) - np.asarray(sensor_position, dtype=float)
    return np.einsum("ki,ki->k", rel, np.asarray(velocity, dtype=float)) / np.linalg.norm(rel, axis=-1)


def uniform_ball_noise(seed: int, runs: int, scans: int) -> np.ndarray:
    """Points uniform in the unit ball ``[K, runs, 3]``; run r's from run r's generator only
    (direction from 3 normals, radius ``u^(1/3)``)."""
    noise = np.empty((scans, runs, 3))
    for r, rng in enumerate(run_generators(seed, runs)):
        direction = rng.standard_normal((scans, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        noise[:, r, :] = direction * rng.random(scans)[:, None] ** (1.0 / 3.0)
    return noise


def radar_sensor(spec: SensorSpec) -> Sensor:
    """The :class:`~skytrack.geo.sensors.Sensor` (3-D radar, north = +y) of a study sensor."""
    sensor = Sensor(name="study-radar", type="radar-3d", sigma_range_m=spec.sigma_range_m,
                    sigma_azimuth_deg=math.degrees(spec.sigma_azimuth_rad),
                    sigma_elevation_deg=math.degrees(spec.sigma_elevation_rad))
    sensor.position = np.asarray(spec.position, dtype=float)
    return sensor


def polar_measurements(position: np.ndarray, sensor: SensorSpec, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Converted plots ``z[K, runs, 3]`` and covariances for truth ``position[K, 3]`` and ``noise[K, runs, 3]``."""
    scans, runs, _ = noise.shape
    rel = np.asarray(position, dtype=float) - np.asarray(sensor.position, dtype=float)
    r, az, el = cartesian_to_polar(rel[:, 0], rel[:, 1], rel[:, 2])
    sig = np.array([sensor.sigma_range_m, sensor.sigma_azimuth_rad, sensor.sigma_elevation_rad])
    measured = np.stack([r, az, el], axis=-1)[:, None, :] + noise * sig
    flat = measured.reshape(-1, 3)
    nan = np.full(len(flat), np.nan)
    plots = convert_plots(radar_sensor(sensor), flat[:, 0], flat[:, 1], flat[:, 2], nan, nan, np.full((len(flat), 6), np.nan))
    return plots.position.reshape(scans, runs, 3), plots.covariance.reshape(scans, runs, 3, 3)


def simulate_measurements(case: Case, runs: int, seed: int, mode: str = "polar",
                          cartesian_sigma_m: float | None = None,
                          range_rate_sigma: float = DEFAULT_RANGE_RATE_SIGMA) -> MeasurementSet:
    """Measurements of ``case`` for ``runs`` Monte Carlo runs (module docstring); ``range_rate_sigma``
    (m/s) is used by ``polar_doppler`` only."""
    if mode not in MODES:
        raise ValueError(f"measurement mode must be one of {MODES}, got {mode!r}")
    if mode == "polar":
        z, R = polar_measurements(case.truth.position, case.sensor, standard_noise(seed, runs, case.scans))
    elif mode == "polar_doppler":
        if not (math.isfinite(range_rate_sigma) and range_rate_sigma > 0):
            raise ValueError(f"polar_doppler measurements need range_rate_sigma > 0, got {range_rate_sigma}")
        noise, extra = radar_noise_with_range_rate(seed, runs, case.scans)
        z, R = polar_measurements(case.truth.position, case.sensor, noise)
        rdot = true_range_rate(case.truth.position, case.truth.velocity, case.sensor.position)
        return MeasurementSet(z, R, mode, int(seed), rdot[:, None] + range_rate_sigma * extra, float(range_rate_sigma))
    else:
        if cartesian_sigma_m is None or not (math.isfinite(cartesian_sigma_m) and cartesian_sigma_m > 0):
            raise ValueError(f"cartesian measurements need sigma > 0, got {cartesian_sigma_m}")
        noise = standard_noise(seed, runs, case.scans) if mode == "cartesian" else uniform_ball_noise(seed, runs, case.scans)
        z = case.truth.position[:, None, :] + cartesian_sigma_m * noise
        R = np.broadcast_to(cartesian_sigma_m**2 * np.eye(3), (case.scans, runs, 3, 3)).copy()
    return MeasurementSet(z, R, mode, int(seed))

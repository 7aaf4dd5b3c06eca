"""Truth and measurement simulator of spec 000's 1-D Singer model with missed detections (R14).

Many independent runs are simulated at once (arrays ``[runs, ...]``; the only loop is over
scans):

* truth: theta_0 ~ N(m0, P0), theta_{n+1} = F theta_n + w_n, w_n ~ N(0, Q), with (F, Q)
  of the chosen discretisation — ``"paper"`` (K6) or ``"exact"`` (X1)-(X2).  The
  paper's Q is singular (rank 1), so the noise is drawn through a symmetric square root
  (eigen-decomposition), not a Cholesky factor;
* detections: Bernoulli(P_D) per scan, independent between scans (M4), from
  ``rng.random() < P_D`` (the paper's uniform generator, A2);
* measurements: z_n = x_n + sigma e (M2), and V_n = v_n + sigma_v e' for ``posvel`` (M3);
  NaN where the scan is missed, so a missed value cannot be used by accident.

Scan 0 is the initial report (always present); scans 1..N follow.  Same generator state
=> identical output.  ``rng`` is one generator for the whole batch, or one generator per
run: then run r draws only from ``rng[r]``, so its trajectory does not depend on the other
runs of the batch (Monte Carlo studies seed run r with ``SeedSequence(seed).spawn(runs)[r]``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skytrack.models.motion import SingerAxisModel

MEASUREMENT_INDEX = {"pos": (0,), "posvel": (0, 1)}


@dataclass(frozen=True)
class SingerScenario1D:
    """Simulated runs: ``truth[runs, N+1, 3]``, ``measurements[runs, N+1, k]``, ``detected[runs, N+1]``."""

    truth: np.ndarray
    measurements: np.ndarray
    detected: np.ndarray
    dt: float
    measurement: str

    @property
    def runs(self) -> int:
        return self.truth.shape[0]

    @property
    def n_scans(self) -> int:
        return self.truth.shape[1] - 1


def _symmetric_sqrt(C: np.ndarray, name: str) -> np.ndarray:
    """L with L L^T = C for a PSD C (possibly singular)."""
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    if w[0] < -1e-9 * max(abs(w[-1]), 1e-300):
        raise ValueError(f"{name} is not positive semi-definite (smallest eigenvalue {w[0]:.3g})")
    return V * np.sqrt(np.clip(w, 0.0, None))


def simulate_singer_1d(
    model: SingerAxisModel,
    *,
    dt: float,
    n_scans: int,
    runs: int,
    sigma: float,
    p_detection: float,
    rng: np.random.Generator | Sequence[np.random.Generator],
    measurement: str = "pos",
    sigma_v: float | None = None,
    m0=None,
    P0=None,
) -> SingerScenario1D:
    """Simulate ``runs`` independent tracks of ``n_scans`` scans (R14).

    ``m0``/``P0`` give the law of the initial state (default: zero mean, position and velocity
    st. dev. 0 and the stationary acceleration variance sigma_a^2), so that a filter started
    from (m0, P0) has the correct prior.  ``rng``: one generator for all runs, or a sequence
    of ``runs`` generators, one per run (run r's noise and detections come from ``rng[r]`` only).
    """
    if not isinstance(model, SingerAxisModel):
        raise TypeError(f"model must be a SingerAxisModel, got {type(model).__name__}")
    per_run = not isinstance(rng, np.random.Generator)
    if per_run and not (
        isinstance(rng, Sequence) and len(rng) > 0 and all(isinstance(g, np.random.Generator) for g in rng)
    ):
        raise TypeError(
            "rng must be a numpy.random.Generator or a sequence of them, one per run "
            "(simulations take an explicit generator)"
        )
    if measurement not in MEASUREMENT_INDEX:
        raise ValueError(f"measurement must be one of {tuple(MEASUREMENT_INDEX)}, got {measurement!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    if int(n_scans) != n_scans or n_scans < 1:
        raise ValueError(f"n_scans must be a positive integer, got {n_scans!r}")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be a positive integer, got {runs!r}")
    if per_run and len(rng) != runs:
        raise ValueError(f"rng has {len(rng)} generators for {runs} runs; give one per run")
    if not (np.isfinite(sigma) and sigma > 0):
        raise ValueError(f"sigma must be finite and > 0, got {sigma!r}")
    if not (0.0 <= p_detection <= 1.0):
        raise ValueError(f"p_detection must lie in [0, 1], got {p_detection!r}")
    idx = list(MEASUREMENT_INDEX[measurement])
    if len(idx) == 2 and not (sigma_v is not None and np.isfinite(sigma_v) and sigma_v > 0):
        raise ValueError(f"measurement='posvel' needs a finite sigma_v > 0, got {sigma_v!r}")
    n_scans, runs = int(n_scans), int(runs)
    m0 = np.zeros(3) if m0 is None else np.asarray(m0, dtype=float).reshape(3)
    P0 = np.diag([0.0, 0.0, model.sigma_a**2]) if P0 is None else np.asarray(P0, dtype=float).reshape(3, 3)
    if not (np.all(np.isfinite(m0)) and np.all(np.isfinite(P0))):
        raise ValueError("m0 and P0 must be finite")
    F, Q = model.F(dt), model.Q(dt)
    L0 = _symmetric_sqrt(P0, "P0")
    LQ = _symmetric_sqrt(Q, "Q")

    # scan-major storage (one contiguous [runs, 3] slab per scan); returned as [runs, scan, ...] views.
    # The standard normals of the truth are drawn into ``truth`` first and transformed in place.
    k = len(idx)
    truth = np.empty((n_scans + 1, runs, 3))
    noise = np.empty((n_scans + 1, runs, k))
    uniforms = np.empty((n_scans + 1, runs))
    if per_run:
        for r, g in enumerate(rng):
            truth[0, r] = g.standard_normal(3)
            truth[1:, r] = g.standard_normal((n_scans, 3))
            noise[:, r] = g.standard_normal((n_scans + 1, k))
            uniforms[:, r] = g.random(n_scans + 1)
    else:  # one stream, in this order: initial states, process noise scan by scan, measurement noise, detections
        truth[0] = rng.standard_normal((runs, 3))
        truth[1:] = rng.standard_normal((n_scans, runs, 3))
        noise[:] = rng.standard_normal((n_scans + 1, runs, k))
        uniforms[:] = rng.random((n_scans + 1, runs))
    truth[0] = m0 + truth[0] @ L0.T
    for n in range(n_scans):
        truth[n + 1] = truth[n] @ F.T + truth[n + 1] @ LQ.T
    noise_sd = np.array([sigma, sigma_v][:k], dtype=float)
    measurements = truth[:, :, idx] + noise * noise_sd
    detected = uniforms < p_detection
    detected[0] = True
    measurements[~detected] = np.nan
    truth, measurements, detected = truth.transpose(1, 0, 2), measurements.transpose(1, 0, 2), detected.T
    return SingerScenario1D(truth=truth, measurements=measurements, detected=detected, dt=float(dt), measurement=measurement)

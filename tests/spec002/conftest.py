"""Shared pieces of the spec 002 tests: the long-run simulation of TV11 (c)/(d)."""

import numpy as np
import pytest

from skytrack.filters.adaptive_augmented import AdaptiveAugmentedFilter, AdaptiveSettings, LinearMeasurement
from skytrack.models.augmented import linear_model

F_1D = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
SIGMA_MEAS = np.array([10.0, 0.5])


def run_bank(n_tracks, n_measurements, sigma_w, seed, **settings):
    """Truth x(k) = F(x(k−1) + h_aᵀw(k−1)) (eqs. 3-4), y = (p, v) + η; returns the filter's final state and
    V̂_w per step ``[K−1, N]``.  ``sigma_w(k)`` is the std of w(k−1)."""
    rng = np.random.default_rng(seed)
    model = linear_model("ca-1d", F_1D, ("p", "v", "a"), ("m", "m/s", "m/s^2"), ("a",), [[0.01]])
    options = dict(sigma_min=[1e-4], forgetting=1.0, n0=1.0)
    options.update(settings)
    filt = AdaptiveAugmentedFilter(model, LinearMeasurement([[1, 0, 0], [0, 1, 0]]), AdaptiveSettings(**options))
    truth = np.tile([0.0, 100.0, 0.0], (n_tracks, 1))
    y0 = truth[:, :2] + SIGMA_MEAS * rng.standard_normal((n_tracks, 2))
    state = filt.initial_state(np.c_[y0, np.zeros(n_tracks)], np.diag([100, 0.25, 1]), V_w0=[[0.01]])
    noise_cov = np.diag(SIGMA_MEAS**2)
    estimates = np.empty((n_measurements - 1, n_tracks))
    for k in range(1, n_measurements):
        truth[:, 2] += sigma_w(k) * rng.standard_normal(n_tracks)
        truth = truth @ F_1D.T
        y = truth[:, :2] + SIGMA_MEAS * rng.standard_normal((n_tracks, 2))
        estimates[k - 1] = filt.step(state, y, 1.0, noise_cov).V_w[:, 0, 0]
    return state, estimates


@pytest.fixture
def tv11_bank():
    """:func:`run_bank`: TV11's 1-D constant-acceleration scene run as a bank of seeds."""
    return run_bank

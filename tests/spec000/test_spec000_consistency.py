"""Spec 000 R14 / TV13 and E5: Monte Carlo consistency of the filter with missed detections."""

import dataclasses

import numpy as np
import pytest

from skytrack.models import SingerAxisModel
from skytrack.sim.singer_truth import simulate_singer_1d
from skytrack.studies.singer_missed import StudyConfig, filter_consistency, monte_carlo_consistency

SIGMA, SIGMA_V, PD, DT = 100.0, 5.0, 0.8, 10.0


@pytest.mark.parametrize("variant", ["pos", "posvel"])
@pytest.mark.parametrize("disc", ["paper", "exact"])
def test_r14_tv13_mse_over_mean_variance(variant, disc):
    """20 000 runs x 200 scans, statistics after scan 50: MSE / mean gamma_ii in [0.98, 1.02]."""
    model = SingerAxisModel(60.0, 1.0, disc)
    P0 = np.diag([SIGMA**2, 30.0**2, 1.0])
    m0 = np.array([0.0, 200.0, 0.0])
    seed = {"paper": 140, "exact": 141}[disc] + {"pos": 0, "posvel": 10}[variant]
    scenario = simulate_singer_1d(model, dt=DT, n_scans=200, runs=20000, sigma=SIGMA, p_detection=PD,
                                  rng=np.random.default_rng(seed), measurement=variant, sigma_v=SIGMA_V, m0=m0, P0=P0)
    # the detections are Bernoulli(P_D)
    rate = scenario.detected[:, 1:].mean()
    assert abs(rate - PD) <= 4 * np.sqrt(PD * (1 - PD) / scenario.detected[:, 1:].size)
    stats = filter_consistency(model, variant, sigma=SIGMA, sigma_v=SIGMA_V if variant == "posvel" else None, dt=DT,
                               truth=scenario.truth, measurements=scenario.measurements, detected=scenario.detected,
                               m0=m0, P0=P0, burn_in=50)
    assert stats.samples == 20000 * 150
    for key, ratio in stats.ratios.items():
        assert 0.98 <= ratio <= 1.02, (key, ratio)


def test_r14_simulator_statistics_and_determinism():
    model = SingerAxisModel(60.0, 1.0, "exact")
    kwargs = dict(dt=DT, n_scans=300, runs=4000, sigma=SIGMA, p_detection=0.6, measurement="posvel", sigma_v=SIGMA_V)
    a = simulate_singer_1d(model, rng=np.random.default_rng(3), **kwargs)
    b = simulate_singer_1d(model, rng=np.random.default_rng(3), **kwargs)
    np.testing.assert_array_equal(a.truth, b.truth)
    np.testing.assert_array_equal(a.detected, b.detected)
    assert a.truth.shape == (4000, 301, 3) and a.measurements.shape == (4000, 301, 2)
    assert a.detected[:, 0].all() and np.isnan(a.measurements[~a.detected]).all()
    # the acceleration is stationary with variance sigma_a^2 (default start) and correlation rho per scan
    acc = a.truth[:, 100:, 2]
    assert acc.var() == pytest.approx(1.0, rel=0.03)
    rho = np.mean(acc[:, 1:] * acc[:, :-1]) / np.mean(acc * acc)
    assert rho == pytest.approx(np.exp(-DT / 60.0), abs=0.01)
    # measurement errors have the configured spread
    err = (a.measurements[..., 0] - a.truth[..., 0])[a.detected]
    assert err.std() == pytest.approx(SIGMA, rel=0.01)
    assert abs(a.detected[:, 1:].mean() - 0.6) < 4 * np.sqrt(0.24 / a.detected[:, 1:].size)
    # the process noise of the truth follows Q of the chosen discretisation
    paper = simulate_singer_1d(SingerAxisModel(60.0, 1.0, "paper"), rng=np.random.default_rng(4), **kwargs)
    F = SingerAxisModel(60.0, 1.0, "paper").F(DT)
    w = paper.truth[:, 1:] - paper.truth[:, :-1] @ F.T
    assert np.abs(w[..., :2]).max() < 1e-6  # "paper": no noise on x and v (rank-one Q_P)
    F_e, Q_e = model.F(DT), model.Q(DT)
    w_e = (a.truth[:, 1:] - a.truth[:, :-1] @ F_e.T).reshape(-1, 3)
    np.testing.assert_allclose(np.cov(w_e.T), Q_e, rtol=0.03, atol=0.03 * np.abs(Q_e).max())


def test_r14_simulator_validation():
    model = SingerAxisModel(60.0, 1.0, "paper")
    good = dict(dt=DT, n_scans=10, runs=3, sigma=SIGMA, p_detection=0.5, rng=np.random.default_rng(0))
    for bad in (dict(dt=0.0), dict(n_scans=0), dict(runs=0), dict(sigma=-1.0), dict(p_detection=1.5),
                dict(measurement="vel"), dict(measurement="posvel"), dict(P0=-np.eye(3))):
        with pytest.raises(ValueError):
            simulate_singer_1d(model, **{**good, **bad})
    with pytest.raises(TypeError):
        simulate_singer_1d(model, **{**good, "rng": 0})


def test_r14_simulator_with_one_generator_per_run_does_not_depend_on_the_batch():
    model = SingerAxisModel(60.0, 1.0, "exact")
    kwargs = dict(dt=DT, n_scans=40, sigma=SIGMA, p_detection=0.6, measurement="posvel", sigma_v=SIGMA_V)
    seeds = np.random.SeedSequence(11).spawn(6)
    batch = simulate_singer_1d(model, runs=6, rng=[np.random.default_rng(s) for s in seeds], **kwargs)
    for r in (0, 4):
        alone = simulate_singer_1d(model, runs=1, rng=[np.random.default_rng(seeds[r])], **kwargs)
        # same random numbers; the batched matrix products may round differently in the last bit
        np.testing.assert_allclose(batch.truth[r], alone.truth[0], rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(batch.detected[r], alone.detected[0])
        np.testing.assert_allclose(batch.measurements[r], alone.measurements[0], rtol=1e-12, atol=1e-9)
    with pytest.raises(ValueError):
        simulate_singer_1d(model, runs=5, rng=[np.random.default_rng(s) for s in seeds], **kwargs)
    with pytest.raises(TypeError):
        simulate_singer_1d(model, runs=2, rng=[0, 1], **kwargs)


def test_e5_runs_are_seeded_per_run_from_the_spawned_seed_sequence():
    """Run r of every cell gets a generator seeded with SeedSequence(seed).spawn(mc_runs)[r]."""
    config = StudyConfig(sigmas=(100.0,), pds=(0.9,), variants=("pos",), fig1_sigma=100.0, fig2_pds=(0.9,), scans=20, seed=5)
    seen = []

    def recording(model, *, rng, runs, **kwargs):
        seen.append([g.random() for g in rng])
        return simulate_singer_1d(model, rng=rng, runs=runs, **kwargs)

    monte_carlo_consistency(config, recording, mc_runs=4)
    expected = [np.random.default_rng(s).random() for s in np.random.SeedSequence(5).spawn(4)]
    assert seen == [expected]


def test_e5_monte_carlo_ratios_within_three_percent():
    """E5 at the spec's --mc-runs 2000: the ratios lie within 1 +- 0.03 for P_D >= 0.7.

    (With 400 runs the sigma = 100 m, P_D = 0.7 cell is at the edge of the band: its ratio
    deviates by more than 0.03 for about one seed in three.)
    """
    config = StudyConfig(sigmas=(100.0, 1000.0), pds=(0.7, 0.9), fig1_sigma=100.0, fig2_pds=(0.9,), scans=300, seed=2)
    calls = []
    table = monte_carlo_consistency(config, simulate_singer_1d, mc_runs=2000, on_cell_done=lambda: calls.append(1))
    assert len(table) == len(calls) == 2 * 2 * 2
    for column in ("ratio_filtered", "ratio_extrapolated"):
        assert ((table[column] - 1).abs() <= 0.03).all(), table[["variant", "sigma_m", "pd", column]]


def test_e5_monte_carlo_is_deterministic_for_a_seed():
    config = StudyConfig(sigmas=(100.0,), pds=(0.7, 0.9), fig1_sigma=100.0, fig2_pds=(0.9,), scans=100, seed=2)
    table = monte_carlo_consistency(config, simulate_singer_1d, mc_runs=50)
    again = monte_carlo_consistency(config, simulate_singer_1d, mc_runs=50)
    np.testing.assert_array_equal(table.ratio_filtered.to_numpy(), again.ratio_filtered.to_numpy())
    other = monte_carlo_consistency(dataclasses.replace(config, seed=3), simulate_singer_1d, mc_runs=50)
    assert not np.array_equal(table.ratio_filtered.to_numpy(), other.ratio_filtered.to_numpy())

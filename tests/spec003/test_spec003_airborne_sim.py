"""Spec 003 R17 (and the stream rules of R18): airborne scenario generator and the E4 scenario.

Statistical checks use 4 standard errors: a sample standard deviation of n Gaussian values
has SE sigma / sqrt(2 n); a fraction has SE sqrt(p (1 - p) / n).
"""

import math

import numpy as np
import pytest

from skytrack.geo.polar import wrap_angle
from skytrack.sim.airborne import (
    AirborneRadar,
    AirborneScenario,
    AirborneTarget,
    ConstantVelocityLegs,
    UniformClutter,
    crossing_scenario,
    simulate_airborne,
    spawn_streams,
)

RUNS = 200


def runs(scenario, count=RUNS, first_seed=0):
    truth = scenario.truth()
    return [simulate_airborne(scenario, seed, truth) for seed in range(first_seed, first_seed + count)]


def residuals(run):
    """Plot minus noise-free measurement of its true object (azimuth wrapped)."""
    nu = run.measurements - run.true.h[run.scan, run.truth]
    nu[:, 1] = wrap_angle(nu[:, 1])
    return nu


# ---------------------------------------------------------------- geometry


def test_crossing_scenario_geometry():
    scenario = crossing_scenario()
    truth = scenario.truth()
    assert scenario.n_scans == 61 and scenario.scan_period_s == 2.0 and scenario.crossing_scan == 30
    np.testing.assert_array_equal(truth.t, np.arange(61) * 2.0)
    np.testing.assert_array_equal(truth.own_p[0], [0.0, 0.0, 8000.0])
    np.testing.assert_allclose(truth.own_p[30], [0.0, 15000.0, 8000.0], rtol=1e-15)
    np.testing.assert_array_equal(truth.own_v, np.tile([0.0, 250.0, 0.0], (61, 1)))
    # both targets at C at t = 60 s, 250 m/s, turned by +-5 deg from due south
    np.testing.assert_allclose(truth.states[30, :, :3], [[0.0, 55000.0, 6000.0]] * 2, rtol=0, atol=1e-9)
    speeds = np.linalg.norm(truth.states[..., 3:], axis=-1)
    np.testing.assert_allclose(speeds, 250.0, rtol=1e-14)
    beta = math.radians(5.0)
    np.testing.assert_allclose(truth.states[0, 0, 3:], 250.0 * np.array([math.sin(beta), -math.cos(beta), 0]))
    np.testing.assert_allclose(truth.states[0, 1, 3:], 250.0 * np.array([-math.sin(beta), -math.cos(beta), 0]))
    # closing on the own-ship throughout, at 480-500 m/s
    assert np.all(truth.h[..., 3] < -480.0)
    # the targets are due north of the own-ship at the crossing
    np.testing.assert_allclose(truth.h[30, :, 1], 0.0, atol=1e-15)


def test_crossing_scenario_offsets_and_parallel_case():
    truth = crossing_scenario(beta_deg=0.0, d_e=20000.0, dh=300.0).truth()
    offset = truth.states[:, 1, :3] - truth.states[:, 0, :3]
    np.testing.assert_allclose(offset, np.tile([20000.0, 0.0, 300.0], (61, 1)), rtol=1e-12, atol=1e-9)


def test_constant_velocity_legs_are_continuous():
    legs = ConstantVelocityLegs((0.0, 0.0, 1000.0), (0.0, 10.0, 25.0),
                                ((100.0, 0.0, 0.0), (0.0, -50.0, 5.0), (10.0, 10.0, 0.0)))
    p, v = legs.state(np.array([-1.0, 0.0, 10.0, 20.0, 25.0, 30.0]))
    np.testing.assert_allclose(p, [[-100, 0, 1000], [0, 0, 1000], [1000, 0, 1000], [1000, -500, 1050],
                                   [1000, -750, 1075], [1050, -700, 1075]], rtol=1e-15)
    np.testing.assert_array_equal(v[[0, 2, 5]], [[100, 0, 0], [0, -50, 5], [10, 10, 0]])
    with pytest.raises(ValueError, match="increasing"):
        ConstantVelocityLegs((0, 0, 0), (5.0, 5.0), ((1, 0, 0), (0, 1, 0)))


# ---------------------------------------------------------------- plots


def test_plot_fields_identity_and_azimuth_range():
    run = simulate_airborne(crossing_scenario(), seed=1)
    assert len(run) == 122  # P_D = 1, perfect resolution, no clutter
    assert np.all(np.diff(run.scan) >= 0)
    np.testing.assert_array_equal(run.t, run.scan * 2.0)
    np.testing.assert_array_equal(run.own_p, run.true.own_p[run.scan])
    np.testing.assert_array_equal(run.own_v, run.true.own_v[run.scan])
    assert np.all((run.az >= 0.0) & (run.az < 2 * math.pi))
    # around the crossing the true azimuth is 0, so noisy plots fall on both sides of north
    near_crossing = np.abs(run.scan - 30) <= 2
    assert np.any(run.az[near_crossing] > math.pi) and np.any(run.az[near_crossing] < math.pi)
    np.testing.assert_array_equal(run.target_status, [0, 1])  # IFF_VALUES: friend, foe
    np.testing.assert_array_equal(run.target_code, [int("1234", 8), int("5670", 8)])
    np.testing.assert_array_equal(run.noise, AirborneRadar().noise)
    assert run.measurements.shape == (122, 4)


def test_measurement_noise_statistics():
    all_nu = np.concatenate([residuals(run) for run in runs(crossing_scenario())])
    n = len(all_nu)
    assert n == RUNS * 122
    sigmas = np.array([30.0, math.radians(0.3), math.radians(0.3), 2.0])
    np.testing.assert_allclose(all_nu.std(axis=0), sigmas, rtol=4.0 / math.sqrt(2 * n))
    assert np.all(np.abs(all_nu.mean(axis=0)) < 4.0 * sigmas / math.sqrt(n))
    correlation = np.corrcoef(all_nu.T)[np.triu_indices(4, 1)]
    assert np.all(np.abs(correlation) < 4.0 / math.sqrt(n))


def test_detection_fraction_matches_p_d_per_target():
    base = crossing_scenario()
    targets = (AirborneTarget(base.targets[0].motion, 0.7, "friend", "1234"),
               AirborneTarget(base.targets[1].motion, 0.4, "foe", None))
    scenario = AirborneScenario(base.own_ship, targets, n_scans=61)
    all_runs = runs(scenario)
    truth = np.concatenate([run.truth for run in all_runs])
    slots = RUNS * 61
    for j, p_d in enumerate((0.7, 0.4)):
        fraction = np.mean(truth == j) * len(truth) / slots
        assert abs(fraction - p_d) < 4.0 * math.sqrt(p_d * (1 - p_d) / slots)
    assert all_runs[0].target_code[1] == -1
    # at most one plot per target and scan (perfect resolution)
    for run in all_runs[:20]:
        pairs = run.scan * 2 + run.truth
        assert len(np.unique(pairs)) == len(pairs)


def test_detection_does_not_move_the_noise_of_remaining_plots():
    full = simulate_airborne(crossing_scenario(), seed=7)
    thinned = simulate_airborne(crossing_scenario(p_detection=0.5), seed=7)
    assert 0 < len(thinned) < len(full)
    key_full = {(s, o): z for s, o, z in zip(full.scan, full.truth, full.measurements.tolist())}
    for s, o, z in zip(thinned.scan, thinned.truth, thinned.measurements.tolist()):
        assert key_full[(s, o)] == z


def test_same_seed_same_output_and_streams_are_spawned():
    scenario = crossing_scenario(clutter=UniformClutter(per_scan=2.0))
    seed = np.random.SeedSequence(123)
    a, b = simulate_airborne(scenario, seed), simulate_airborne(scenario, seed)
    for name in ("scan", "t", "range_m", "az", "el", "vr", "own_p", "own_v", "truth"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.iff_rng.random() == b.iff_rng.random()
    c = simulate_airborne(scenario, 124)
    assert len(c) != len(a) or not np.array_equal(c.range_m, a.range_m)
    # the IFF stream is the fourth child of the run seed
    expected = np.random.default_rng(np.random.SeedSequence(5).spawn(5)[3]).random(3)
    np.testing.assert_array_equal(simulate_airborne(scenario, 5).iff_rng.random(3), expected)
    assert spawn_streams(5)._fields == ("noise", "detection", "order", "iff", "clutter")


def test_plot_order_is_a_seeded_permutation_within_each_scan():
    all_runs = runs(crossing_scenario(), count=100)
    a_first = 0
    for run in all_runs:
        per_scan = run.truth.reshape(61, 2)
        np.testing.assert_array_equal(np.sort(per_scan, axis=1), np.tile([0, 1], (61, 1)))
        a_first += int(np.sum(per_scan[:, 0] == 0))
    n = 100 * 61
    assert abs(a_first / n - 0.5) < 4.0 * math.sqrt(0.25 / n)


def test_clutter_is_off_by_default_and_independent_of_target_plots():
    plain = simulate_airborne(crossing_scenario(), seed=3)
    assert np.all(plain.truth >= 0)
    box = UniformClutter(per_scan=3.0, range_m=(5000.0, 80000.0), el_rad=(-0.1, 0.05), vr_mps=(-100.0, 50.0))
    cluttered_runs = runs(crossing_scenario(clutter=box), count=50, first_seed=3)
    false_counts = [int(np.sum(run.truth == -1)) for run in cluttered_runs]
    assert abs(np.mean(false_counts) / 61 - 3.0) < 4.0 * math.sqrt(3.0 / (50 * 61))
    run = cluttered_runs[0]
    false = run.truth == -1
    assert np.all((run.range_m[false] >= 5000.0) & (run.range_m[false] <= 80000.0))
    assert np.all((run.el[false] >= -0.1) & (run.el[false] <= 0.05))
    assert np.all((run.vr[false] >= -100.0) & (run.vr[false] <= 50.0))
    assert np.all((run.az[false] >= 0.0) & (run.az[false] < 2 * math.pi))
    targets = ~false
    order_plain = np.lexsort((plain.truth, plain.scan))
    order_cluttered = np.lexsort((run.truth[targets], run.scan[targets]))
    np.testing.assert_array_equal(run.measurements[targets][order_cluttered], plain.measurements[order_plain])


def test_without_range_rate():
    radar = AirborneRadar(with_range_rate=False)
    run = simulate_airborne(crossing_scenario(radar=radar, clutter=UniformClutter(per_scan=1.0)), seed=2)
    assert run.measurements.shape == (len(run), 3)
    assert np.all(np.isnan(run.vr))
    assert run.noise.shape == (3, 3)
    assert run.true.h.shape == (61, 2, 3)


@pytest.mark.parametrize("kwargs, message", [
    ({"iff_status": "undetermined"}, "true status"),
    ({"code": "1238"}, "octal"),
    ({"code": "123"}, "octal"),
    ({"p_detection": 1.5}, "p_detection"),
])
def test_target_validation(kwargs, message):
    motion = ConstantVelocityLegs.straight((0, 1000, 0), (0, 0, 0))
    with pytest.raises(ValueError, match=message):
        AirborneTarget(motion, **kwargs)

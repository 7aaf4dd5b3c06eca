"""Spec 004 Kalman-family variants (R5-R7, R9, R10, R22): per-axis KF (§3.3 D), pseudo-noise KF
(§3.3 E), transformed-gain filter (§3.3 G), piecewise-constant gain (§3.3 H) and the KF gain history.

Test vectors TV10 (1e-8; N = 1 against the KF with P = (I - K H) P^- to 1e-12 rel), TV18 (a)-(d)
(1e-12), the multiply-add comparisons that study E8 asserts, and bad configuration.  The adaptive
filter (§3.3 F) is in ``test_spec004_kalman_variants_adaptive.py``.  "rel" means
``max|a - b| <= rtol * max|b|`` over the compared array.  Monte Carlo runs draw from
``np.random.default_rng(np.random.SeedSequence(seed).spawn(runs)[r])``.
"""

from __future__ import annotations

import numpy as np
import pytest

from skytrack.core import linalg
from skytrack.filters.base import ListRecorder
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.per_axis import PerAxisKalmanFilter
from skytrack.filters.piecewise_gain import PiecewiseGainFilter
from skytrack.filters.pseudo_noise import PseudoNoiseKalmanFilter
from skytrack.filters.registry import FILTERS, build_filter, register_filter
from skytrack.filters.transformed_gain import TransformedGainFilter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import MotionModel, SingerAxisModel, constant_velocity, singer
from skytrack.models.polynomial import dwna


def gens(seed, runs):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)]


def rel_error(actual, expected) -> float:
    """Largest |actual - expected| over the largest |expected| (inf when the shapes differ)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    if actual.shape != expected.shape:
        return np.inf
    return float(np.max(np.abs(actual - expected)) / max(np.max(np.abs(expected)), 1e-300))


def cycle(filt, state, dt, z, R, model, context=None):
    pred = filt.predict(state, dt, context)
    inn = filt.innovate(pred, z, model, {"R": R, **(context or {})})
    return filt.update(pred, z, inn)[0]


def random_run(filters, motion, rows, steps, seed, full_r=False, block_p0=True, dt=1.0):
    """Run every filter on the same simulated measurements; returns the final states."""
    ndim, n = motion.ndim, motion.dim
    model = ConvertedPositionModel(ndim, motion.order)
    rngs = gens(seed, rows)
    sigma = np.array([g.uniform(20.0, 90.0, ndim) for g in rngs])
    R = np.zeros((rows, ndim, ndim))
    R[:, np.arange(ndim), np.arange(ndim)] = sigma**2
    if full_r:
        R = R + 0.6 * sigma[:, :, None] * sigma[:, None, :] * (1 - np.eye(ndim))
    x0 = np.array([g.normal(0.0, 1e4, n) for g in rngs])
    axis_sd = np.tile([100.0, 30.0, 3.0][: motion.order], ndim)
    P0 = np.broadcast_to(np.diag(axis_sd**2), (rows, n, n)).copy()
    if not block_p0:
        P0 = P0 + 0.3 * np.outer(axis_sd, axis_sd) * (1 - np.eye(n))
    states = [f.initiate(x0, P0) for f in filters]
    for k in range(steps):
        z = np.array([g.normal(0.0, 1e4, ndim) for g in rngs]) * 0.01 + x0[:, motion.position_index] + 50.0 * k
        states = [cycle(f, s, np.full(rows, dt), z, R, model) for f, s in zip(filters, states)]
    return states


# ---------------------------------------------------------------------------- TV10, TV18 d: piecewise gain
TV10_Z = [12, 18, 33, 41, 49, 62, 68, 81]
TV10 = {
    1: {1: ([0.5560488346, 0.1132075472], [11.1120976693, 10.2264150943], [55.6048834628, 11.3207547170, 23.1132075472]),
        2: ([0.5039918745, 0.1732752914], [19.6559294578, 9.6479333224], [50.3991874495, 17.3275291391, 18.0600150564]),
        4: ([0.4977347158, 0.1550688505], [41.2424394494, 10.2253374894], [49.7734715793, 15.5068850536, 8.9393868304]),
        8: ([0.4007190192, 0.0904818559], [80.1575708382, 9.9227994275], [40.0719019199, 9.0481855936, 4.3185020612])},
    3: {2: ([0.5560488346, 0.1132075472], [19.4821366320, 9.8484702532], [50.9455347690, 16.6971071751, 18.7874494895]),
        3: ([0.5560488346, 0.1132075472], [31.3709686505, 10.2638732473], [51.2939153529, 17.0746827347, 14.2464744490]),
        4: ([0.4998493428, 0.1591537268], [41.3175165924, 10.1628357934], [49.9849342797, 15.9153726784, 10.1820186926]),
        7: ([0.4350403241, 0.1075146749], [69.7451756053, 9.7528969709], [43.5040324094, 10.7514674919, 5.1902797418]),
        8: ([0.4350403241, 0.1075146749], [80.1514715694, 9.9143762097], [41.4113209248, 9.6871777357, 4.6250903398])},
}


def tv10_run(filt):
    """TV10: 1-D CV, T = 1, DWNA sigma_w = 1, R = 100, x0 = [0, 10], P0 = diag(100, 25)."""
    filt.recorder = ListRecorder()
    model = ConvertedPositionModel(1, 2)
    state = filt.initiate(np.array([[0.0, 10.0]]), np.diag([100.0, 25.0])[None])
    out = {}
    for k, value in enumerate(TV10_Z, start=1):
        z = np.array([[float(value)]])
        state = cycle(filt, state, np.ones(1), z, np.array([[[100.0]]]), model)
        out[k] = (filt.recorder.events[-1][2]["gain"][0, :, 0], state.x[0], state.P[0][np.triu_indices(2)])
    return out


@pytest.mark.parametrize("covariance", ["joseph", "offline"])
@pytest.mark.parametrize("N", [1, 3])
def test_tv10_piecewise_gain_table(N, covariance):
    """Gains recomputed at k = 1 (N = 1: every scan; N = 3: k = 1, 4, 7) and held; both covariance modes."""
    out = tv10_run(PiecewiseGainFilter(dwna(1, 1.0), N=N, covariance=covariance))
    for k, (K, x, P) in TV10[N].items():
        np.testing.assert_allclose(out[k][0], K, rtol=0, atol=1e-8, err_msg=f"K at k={k}")
        np.testing.assert_allclose(out[k][1], x, rtol=0, atol=1e-8, err_msg=f"x at k={k}")
        np.testing.assert_allclose(out[k][2], P, rtol=0, atol=1e-8, err_msg=f"P at k={k}")


def test_tv10_n1_equals_kf_with_short_form_covariance():
    """N = 1 equals the KF whose covariance update is P = (I - K H) P^- (1e-12 rel), written out here."""
    out = tv10_run(PiecewiseGainFilter(dwna(1, 1.0), N=1))
    F, Q, H = np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([[0.25, 0.5], [0.5, 1.0]]), np.array([[1.0, 0.0]])
    x, P = np.array([0.0, 10.0]), np.diag([100.0, 25.0])
    for k, z in enumerate(TV10_Z, start=1):
        x, P = F @ x, F @ P @ F.T + Q
        K = P @ H.T / (H @ P @ H.T + 100.0)
        x, P = x + K[:, 0] * (z - x[0]), (np.eye(2) - K @ H) @ P
        assert rel_error(out[k][0], K[:, 0]) <= 1e-12, f"K {k}"
        assert rel_error(out[k][1], x) <= 1e-12, f"x {k}"
        assert rel_error(out[k][2], P[np.triu_indices(2)]) <= 1e-12, f"P {k}"


@pytest.mark.parametrize("compiled", [True, False])
def test_tv18d_piecewise_gain_n1_equals_kalman_filter(compiled):
    """TV18 d on a 3-D Singer model, rows with different R and full R, P0: PCG(N = 1) = KF to 1e-12 rel."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    run = [KalmanFilter(motion, compiled=compiled), PiecewiseGainFilter(motion, N=1, compiled=compiled)]
    a, b = random_run(run, motion, rows=5, steps=30, seed=41, full_r=True, block_p0=False)
    assert rel_error(b.x, a.x) <= 1e-12, "x"
    assert rel_error(b.P, a.P) <= 1e-12, "P"


def test_piecewise_offline_schedule_is_shared_repeats_and_matches_joseph():
    """Monte Carlo rows with one T, R, P0 share one cached schedule; over 300 scans (past the schedule's
    convergence, after which it repeats) the offline covariance and estimate equal the joseph mode's to
    1e-7 rel; the offline update costs fewer multiply-adds than the joseph one."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    joseph, offline = PiecewiseGainFilter(motion, N=4), PiecewiseGainFilter(motion, N=4, covariance="offline")
    model = ConvertedPositionModel(3, 3)
    rows = 6
    R = np.broadcast_to(np.diag([50.0, 70.0, 40.0]) ** 2, (rows, 3, 3)).copy()
    x0 = np.zeros((rows, 9))
    P0 = np.broadcast_to(np.diag(np.tile([100.0, 30.0, 10.0], 3) ** 2), (rows, 9, 9)).copy()
    sj, so = joseph.initiate(x0, P0), offline.initiate(x0, P0)
    noise = np.array([g.normal(0.0, 50.0, (300, 3)) for g in gens(7, rows)])
    for k in range(300):
        z = np.array([1000.0 + 200.0 * k, -50.0 * k, 3.0 * k]) + noise[:, k]
        sj, so = cycle(joseph, sj, np.ones(rows), z, R, model), cycle(offline, so, np.ones(rows), z, R, model)
    assert len(offline._schedules) == 1
    schedule = next(iter(offline._schedules.values()))
    assert 8 <= len(schedule["K"]) < 300  # converged and repeating, not cut at the horizon
    assert rel_error(so.P, sj.P) <= 1e-7, "P"
    assert rel_error(so.x, sj.x) <= 1e-7, "x"
    costs = []
    for filt, state in ((joseph, sj), (offline, so)):
        with linalg.counting() as ops:
            cycle(filt, state, np.ones(rows), z, R, model)
        costs.append(ops.madds / rows)
    assert costs[1] < costs[0]


def test_piecewise_offline_schedule_recomputed_on_one_percent_change():
    """R changed by 0.5 % keeps the schedule (the result is the unchanged-R run's); by 5 % it is rebuilt
    from the current P^- (the result is the joseph mode's with the new R, 1e-9 rel).  Same for T."""
    motion = constant_velocity(2, 1.0)
    model = ConvertedPositionModel(2, 2)
    R = np.broadcast_to(np.eye(2) * 2500.0, (1, 2, 2))
    P0 = np.diag([1e4, 900.0, 1e4, 900.0])[None]

    def run(covariance, factor, step):
        filt = PiecewiseGainFilter(motion, N=3, covariance=covariance)
        state = filt.initiate(np.zeros((1, 4)), P0)
        for k in range(40):
            changed = k >= 20
            dt = np.full(1, step if changed else 2.0)
            state = cycle(filt, state, dt, np.array([[40.0 * k, 5.0 * k]]), R * (factor if changed else 1.0), model)
        return state, filt

    base, _ = run("offline", 1.0, 2.0)
    small, filt = run("offline", 1.005, 2.0)
    assert len(filt._schedules) == 1
    assert np.array_equal(small.P, base.P)
    for factor, step in ((1.05, 2.0), (1.0, 2.1)):
        changed, filt = run("offline", factor, step)
        assert len(filt._schedules) == 2
        exact, _ = run("joseph", factor, step)
        assert rel_error(changed.P, exact.P) <= 1e-9, f"P {factor} {step}"
        assert rel_error(changed.x, exact.x) <= 1e-9, f"x {factor} {step}"


def test_piecewise_offline_mode_passes_the_conformance_properties():
    """The registered kind's conformance run uses the default (joseph) mode; the offline mode, under a
    temporary kind, satisfies the same properties: zero-step identity, batch = rows, same seed same
    output, and the matched-model NEES band of the conformance suite (cv2: chi2 99 % band of 200 x 4)."""
    import test_filter_conformance as conformance  # tests/filters is on sys.path (pytest's rootdir import)

    kind = "test-pcg-offline"
    register_filter(kind)(lambda motion, compiled=True: PiecewiseGainFilter(motion, N=3, covariance="offline",
                                                                            compiled=compiled))
    try:
        assert conformance.check_zero_dt_identity(kind, "singer3", True) <= 1e-12
        assert conformance.check_batch_equals_rows(kind, "cv2", False) <= 1e-12
        first, second = conformance.check_same_seed_same_output(kind, "singer3", True)
        assert np.array_equal(first, second)
        value, n = conformance.check_nees(kind, "cv2", True)
        assert 3.504 <= value <= 4.534 and n == 4
    finally:
        FILTERS.pop(kind, None)


def test_piecewise_hold_scans_skip_the_gain_computation():
    """Joseph mode: a hold scan costs fewer multiply-adds than a recompute scan (it saves the gain)."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    filt = PiecewiseGainFilter(motion, N=2)
    model = ConvertedPositionModel(3, 3)
    R = np.broadcast_to(np.eye(3) * 2500.0, (4, 3, 3))
    state = filt.initiate(np.zeros((4, 9)), np.broadcast_to(np.eye(9) * 100.0, (4, 9, 9)).copy())
    costs = []
    for _ in range(2):  # k = 1 recomputes, k = 2 holds
        with linalg.counting() as ops:
            state = cycle(filt, state, np.ones(4), np.zeros((4, 3)), R, model)
        costs.append(ops.madds)
    assert costs[1] < costs[0]


# ---------------------------------------------------------------------------- TV18 c: gain history (R5)
@pytest.mark.parametrize("compiled", [True, False])
def test_tv18c_kf_gain_history_does_not_depend_on_measurements(compiled):
    """R5's gain history is the KalmanFilter's recorder channel "gain" (K[N, n, m] per update).  Two
    different measurement sequences with the same T, R give identical histories (1e-12)."""
    histories = []
    for seed in (1, 2):
        filt = KalmanFilter(singer(3, tau=10.0, sigma_a=30.0), compiled=compiled)
        filt.recorder = ListRecorder()
        model = ConvertedPositionModel(3, 3)
        state = filt.initiate(np.zeros((3, 9)), np.broadcast_to(np.eye(9) * 400.0, (3, 9, 9)).copy())
        rng = np.random.default_rng(seed)
        R = np.broadcast_to(np.diag([30.0, 50.0, 70.0]) ** 2, (3, 3, 3))
        for _ in range(25):
            state = cycle(filt, state, np.ones(3), rng.normal(0.0, 1e3, (3, 3)), R, model)
        histories.append(np.stack([values["gain"] for _, values in filt.recorder.channel("gain")]))
    assert histories[0].shape == (25, 3, 9, 3)
    assert rel_error(histories[1], histories[0]) <= 1e-12, "gain history"
    assert np.max(np.abs(histories[0][-1] - histories[0][0])) > 1e-3  # the gain does evolve


# ---------------------------------------------------------------------------- TV18 a: per-axis KF
@pytest.mark.parametrize("compiled", [True, False])
def test_tv18a_per_axis_equals_coupled_for_block_diagonal_r_q_p0(compiled):
    """Axes with different Singer models, diagonal R per row, block-diagonal P0 and Q: 1e-12 rel."""
    motion = MotionModel([SingerAxisModel(10.0, 30.0), SingerAxisModel(20.0, 10.0), SingerAxisModel(5.0, 3.0)])
    filters = [KalmanFilter(motion, compiled=compiled), PerAxisKalmanFilter(motion, compiled=compiled)]
    coupled, per_axis = random_run(filters, motion, rows=4, steps=30, seed=3)
    assert rel_error(per_axis.estimate().x, coupled.x) <= 1e-12, "x"
    assert rel_error(per_axis.estimate().P, coupled.P) <= 1e-12, "P"


def test_per_axis_drops_r_cross_covariances_and_flag_gives_coupled_kf():
    """With a full R the per-axis filter equals itself run on diag(R) exactly (it uses only the diagonal)
    and differs from the coupled filter; ``per_axis=False`` is the coupled KF exactly."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    full = random_run([PerAxisKalmanFilter(motion), KalmanFilter(motion, compiled=False),
                       PerAxisKalmanFilter(motion, per_axis=False, compiled=False)],
                      motion, rows=3, steps=10, seed=5, full_r=True)
    diagonal = random_run([PerAxisKalmanFilter(motion)], motion, rows=3, steps=10, seed=5)
    assert np.array_equal(full[0].x, diagonal[0].x) and np.array_equal(full[0].P_axes, diagonal[0].P_axes)
    assert np.max(np.abs(full[0].x - full[1].x)) > 1e-3
    assert np.array_equal(full[2].x, full[1].x) and np.array_equal(full[2].P, full[1].P)


def test_per_axis_rejects_a_measurement_mixing_axes():
    filt = PerAxisKalmanFilter(constant_velocity(2, 1.0))

    class Mixed(ConvertedPositionModel):
        def evaluate(self, x, context):
            h, H = super().evaluate(x, context)
            H[:, 0, 2] = 0.5
            return h, H

    state = filt.initiate(np.zeros((1, 4)), np.eye(4)[None])
    with pytest.raises(ValueError, match="its own axis"):
        filt.innovate(state, np.zeros((1, 2)), Mixed(2, 2), {"R": np.eye(2)[None]})


# ---------------------------------------------------------------------------- TV18 b: transformed gain
def radial_run(filt, steps=25, compiled_kf=None):
    """Target on the x axis moving radially (sensor at the origin): the LOS frame is the ENU axes."""
    model = ConvertedPositionModel(3, filt.transition.order)
    n = filt.transition.dim
    x0 = np.zeros((2, n))
    x0[:, 0], x0[:, 1] = [2e4, 3e4], [-250.0, 180.0]
    P0 = np.broadcast_to(np.diag(np.tile([200.0, 40.0, 5.0][: filt.transition.order], 3) ** 2), (2, n, n)).copy()
    R = np.array([np.diag([25.0, 400.0, 300.0]) ** 2, np.diag([10.0, 900.0, 800.0]) ** 2])
    R[:, 1, 2] = R[:, 2, 1] = 1e4  # off-diagonal in the cross-range plane: both filters drop it
    state = filt.initiate(x0, P0)
    rng = np.random.default_rng(11)
    for k in range(steps):
        z = np.zeros((2, 3))
        z[:, 0] = x0[:, 0] + x0[:, 1] * (k + 1) + rng.normal(0.0, 30.0, 2)
        state = cycle(filt, state, np.ones(2), z, R, model)
    return state


@pytest.mark.parametrize("motion", [constant_velocity(3, 2.0), singer(3, tau=10.0, sigma_a=30.0)], ids=["cv", "singer"])
def test_tv18b_transformed_gain_equals_per_axis_when_los_is_enu(motion):
    tg, pa = radial_run(TransformedGainFilter(motion)), radial_run(PerAxisKalmanFilter(motion))
    assert np.array_equal(tg.C, np.broadcast_to(np.eye(3), (2, 3, 3)))
    assert rel_error(tg.x, pa.x) <= 1e-12, "x"
    assert rel_error(tg.P_axes, pa.P_axes) <= 1e-12, "P blocks"
    assert rel_error(tg.estimate().P, pa.estimate().P) <= 1e-12, "P"


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_transformed_gain_is_equivariant_under_rotations_about_the_vertical():
    """Rotating target, measurements, R and P0 about the sensor's vertical rotates the estimate and
    covariance the same way (the LOS frames turn along): 1e-9 rel.  The ENU gain recorded explains the
    update: x - x^- = K_ENU nu (1e-9 rel)."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    model = ConvertedPositionModel(3, 3)
    rows, steps = 3, 20
    rngs = gens(21, rows)
    x0 = np.array([np.repeat(g.uniform(-4e4, 4e4, 3), 3) * np.tile([1.0, 0.0, 0.0], 3)
                   + np.tile([0.0, 1.0, 0.0], 3) * np.repeat(g.normal(0.0, 200.0, 3), 3) for g in rngs])
    R = np.array([np.diag(g.uniform(20.0, 200.0, 3) ** 2) for g in rngs])
    P0 = np.broadcast_to(np.diag(np.tile([300.0, 50.0, 5.0], 3) ** 2), (rows, 9, 9)).copy()
    paths = np.array([g.normal(0.0, 80.0, (steps, 3)) for g in rngs]) + np.cumsum(np.full((steps, 3), 150.0), axis=0)
    Rot = rotation_z(0.7)
    Big = np.kron(Rot, np.eye(3))
    results = []
    for rotate in (False, True):
        filt = TransformedGainFilter(motion)
        filt.recorder = ListRecorder()
        state = filt.initiate(x0 @ Big.T if rotate else x0, Big @ P0 @ Big.T if rotate else P0)
        for k in range(steps):
            z = x0[:, motion.position_index] + paths[:, k]
            Rk = Rot @ R @ Rot.T if rotate else R
            pred = filt.predict(state, np.ones(rows))
            state = filt.update(pred, z @ Rot.T if rotate else z, filt.innovate(pred, z @ Rot.T if rotate else z, model, {"R": Rk}))[0]
            K = filt.recorder.events[-1][2]["gain"]
            nu = (z @ Rot.T if rotate else z) - pred.x[:, motion.position_index]
            assert rel_error(state.x - pred.x, np.einsum("kij,kj->ki", K, nu)) <= 1e-9, "K_ENU nu"
        results.append(state.estimate())
    assert rel_error(results[1].x, results[0].x @ Big.T) <= 1e-9, "x"
    assert rel_error(results[1].P, Big @ results[0].P @ Big.T) <= 1e-9, "P"


def test_transformed_gain_sensor_position_from_context_or_parameter():
    """A sensor away from the origin, given in the context or as the parameter, equals the same
    geometry shifted so that the sensor is at the origin (1e-9 rel).  ``initiate`` uses the parameter
    only; P0 is the same on every axis, so its LOS blocks do not depend on the initial frame."""
    motion = constant_velocity(3, 1.0)
    model = ConvertedPositionModel(3, 2)
    sensor = np.array([5e3, -8e3, 300.0])
    shift = np.kron(sensor, [1.0, 0.0])
    x0 = np.array([[3e4, -200.0, 1e4, 50.0, 5e3, 0.0]])
    P0 = np.diag([200.0, 40.0] * 3)[None] ** 2
    R = np.diag([40.0, 900.0, 700.0])[None] ** 2
    zs = [np.array([[3e4 - 200.0 * k, 1e4 + 50.0 * k, 5e3 + 10.0 * (-1) ** k]]) for k in range(1, 15)]
    runs = []
    for filt, offset, context in ((TransformedGainFilter(motion), shift, {"sensor_position": sensor}),
                                  (TransformedGainFilter(motion, sensor_position=tuple(sensor)), shift, None),
                                  (TransformedGainFilter(motion), np.zeros(6), None)):
        state = filt.initiate(x0 + offset, P0)
        for z in zs:
            state = cycle(filt, state, np.ones(1), z + offset[::2], R, model, context)
        runs.append(state)
    for state in runs[:2]:
        assert rel_error(state.x - shift, runs[2].x) <= 1e-9, "x"
        assert rel_error(state.P_axes, runs[2].P_axes) <= 1e-9, "P"


def test_transformed_gain_rejects_non_isotropic_models_and_bad_sensor():
    mixed = MotionModel([SingerAxisModel(10.0, 30.0), SingerAxisModel(20.0, 30.0), SingerAxisModel(10.0, 30.0)])
    with pytest.raises(ValueError, match="isotropic"):
        TransformedGainFilter(mixed)
    with pytest.raises(ValueError, match="isotropic"):
        build_filter("kalman-transformed-gain", mixed)
    with pytest.raises(ValueError, match="2-D or 3-D"):
        TransformedGainFilter(constant_velocity(1, 1.0))
    with pytest.raises(ValueError, match="sensor_position"):
        TransformedGainFilter(constant_velocity(3, 1.0), sensor_position=(0.0, 1.0))


# ---------------------------------------------------------------------------- pseudo-noise KF (R7)
def test_pseudo_noise_constant_q_is_the_kf_on_the_scaled_model():
    motion = singer(3, tau=10.0, sigma_a=1.0)
    a, b = random_run([PseudoNoiseKalmanFilter(motion, q=400.0), KalmanFilter(motion.scaled(400.0))],
                      motion, rows=3, steps=20, seed=8)
    assert rel_error(a.x, b.x) <= 1e-12, "x"
    assert rel_error(a.P, b.P) <= 1e-12, "P"


def test_pseudo_noise_callable_sees_filtered_state_and_scan_index():
    """Q_k = q(x_{k-1}, k) Q_unit: the callable gets the filtered states and k = 1, 2, ... per row, and the
    prediction adds exactly q Q_unit (1e-12 rel)."""
    motion = constant_velocity(2, 1.0)
    calls = []

    def q(x, k):
        calls.append((x.copy(), k.copy()))
        return 1.0 + np.abs(x[:, 1]) / 100.0 + k

    filt = PseudoNoiseKalmanFilter(motion, q=q)
    model = ConvertedPositionModel(2, 2)
    state = filt.initiate(np.array([[0.0, 100.0, 0.0, 0.0], [0.0, -300.0, 0.0, 5.0]]),
                          np.broadcast_to(np.eye(4) * 100.0, (2, 4, 4)).copy())
    R = np.broadcast_to(np.eye(2) * 400.0, (2, 2, 2))
    for step in range(1, 4):
        pred = filt.predict(state, np.full(2, 2.0))
        x_seen, k_seen = calls[-1]
        assert np.array_equal(x_seen, state.x) and np.array_equal(k_seen, [step, step])
        F, Qu = motion.F(2.0), motion.Q(2.0)
        expected = F @ state.P @ F.T + q(state.x, k_seen)[:, None, None] * Qu
        assert rel_error(pred.P, expected) <= 1e-12, f"P^- {step}"
        state = filt.update(pred, np.zeros((2, 2)), filt.innovate(pred, np.zeros((2, 2)), model, {"R": R}))[0]


def test_pseudo_noise_bad_q():
    motion = constant_velocity(2, 1.0)
    with pytest.raises(ValueError, match="q must be finite"):
        build_filter("kalman-pseudo-noise", motion, q=-1.0)
    filt = PseudoNoiseKalmanFilter(motion, q=lambda x, k: np.full(len(x), np.nan))
    with pytest.raises(ValueError, match="q\\(x, k\\)"):
        filt.predict(filt.initiate(np.zeros((1, 4)), np.eye(4)[None]), np.ones(1))


# ---------------------------------------------------------------------------- R22 / E8: multiply-adds
def madds_per_update(filt, motion, rows=4, warm=12):
    """Multiply-adds per row of one predict + innovate + update of a Singer 3-D filter after ``warm`` scans."""
    model = ConvertedPositionModel(3, 3)
    R = np.broadcast_to(np.diag([40.0, 300.0, 250.0]) ** 2, (rows, 3, 3)).copy()
    x = np.zeros((rows, 9))
    x[:, 0], x[:, 3], x[:, 1] = 4e4, 1e4, -250.0
    state = filt.initiate(x, np.broadcast_to(np.diag(np.tile([200.0, 40.0, 10.0], 3) ** 2), (rows, 9, 9)).copy())
    for k in range(warm + 1):
        z = np.stack([np.full(rows, 4e4 - 250.0 * (k + 1)), np.full(rows, 1e4), np.zeros(rows)], axis=1)
        if k == warm:
            with linalg.counting() as ops:
                state = cycle(filt, state, np.ones(rows), z, R, model)
        else:
            state = cycle(filt, state, np.ones(rows), z, R, model)
    return ops.madds / rows


def test_e8_cost_per_update_of_reduced_cost_filters_is_below_the_coupled_kf():
    """Study E8's asserts on a Singer 3-D model: MAC(per-axis), MAC(transformed), MAC(PCG offline) <
    MAC(coupled KF) (the cheaper of its compiled and numpy paths)."""
    motion = singer(3, tau=10.0, sigma_a=30.0)
    coupled = min(madds_per_update(KalmanFilter(motion, compiled=flag), motion) for flag in (True, False))
    costs = {
        "per-axis": madds_per_update(PerAxisKalmanFilter(motion), motion),
        "transformed": madds_per_update(TransformedGainFilter(motion), motion),
        "pcg-offline": madds_per_update(PiecewiseGainFilter(motion, N=5, covariance="offline"), motion),
    }
    for name, cost in costs.items():
        assert 0 < cost < coupled, (name, cost, coupled)
    assert costs["pcg-offline"] < costs["per-axis"] < costs["transformed"]


# ---------------------------------------------------------------------------- bad configuration
@pytest.mark.parametrize("kind,options,match", [
    ("kalman-piecewise-gain", {"N": 0}, "N must be"),
    ("kalman-piecewise-gain", {"N": 2.5}, "N must be"),
    ("kalman-piecewise-gain", {"covariance": "exact"}, "covariance must be"),
    ("kalman-per-axis", {"per_axis": "yes"}, "per_axis"),
    ("kalman-pseudo-noise", {"q": "large"}, "q must be"),
    ("kalman-transformed-gain", {"unknown": 1}, "unknown"),
])
def test_bad_configuration_names_the_option(kind, options, match):
    with pytest.raises(ValueError, match=match):
        build_filter(kind, singer(3, tau=10.0, sigma_a=30.0), **options)

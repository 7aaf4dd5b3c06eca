"""The tracker presets of spec 002 R14 (``ct-omega-adaptive``, ``ca-accel-adaptive``): the filter on the
tracker's CV layout against spec 002's own adaptive filter, its compiled kernels against the numpy
reference, and the tracker's compiled stage against the composed parts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.filters.adaptive_augmented import AdaptiveAugmentedFilter, AdaptiveSettings, LinearMeasurement
from skytrack.filters.adaptive_tracking import PRESETS
from skytrack.filters.registry import build_filter
from skytrack.models.augmented import ct_omega
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_velocity, singer
from skytrack.sim import load_scenario, simulate
from skytrack.tracker.config import FilterConfig, TrackerConfig
from skytrack.tracker.tracker import Tracker

#: tracker layout [x, vx, y, vy] <- spec 002 order [x, y, vx, vy]
TO_TRACKER = np.array([0, 2, 1, 3])


def ct_track(rows: int, steps: int, T: float, seed: int, omega: float = math.radians(2.0)):
    """Noisy positions of coordinated turns at 200 m/s (one row per run)."""
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.zeros(rows), np.full(rows, 30e3), np.full(rows, 200.0), np.zeros(rows)])
    positions = []
    for _ in range(steps):
        wt = omega * T
        vx, vy = x[:, 2], x[:, 3]
        x = np.column_stack([x[:, 0] + (math.sin(wt) * vx - (1 - math.cos(wt)) * vy) / omega,
                             x[:, 1] + ((1 - math.cos(wt)) * vx + math.sin(wt) * vy) / omega,
                             math.cos(wt) * vx - math.sin(wt) * vy, math.sin(wt) * vx + math.cos(wt) * vy])
        positions.append(x[:, :2] + rng.normal(0.0, 20.0, (rows, 2)))
    return np.array(positions)


def run_preset(filt, z, T, x0, P0):
    """The preset's predict / innovate / update over steps ``z[K, N, 2]`` (R = 400 m^2 I)."""
    model = ConvertedPositionModel(2, 2)
    rows = z.shape[1]
    state = filt.initiate(x0, P0)
    R = np.broadcast_to(400.0 * np.eye(2), (rows, 2, 2)).copy()
    for k in range(len(z)):
        predicted = filt.predict(state, np.full(rows, T))
        innovation = filt.innovate(predicted, z[k], model, {"R": R})
        state, _ = filt.update(predicted, z[k], innovation)
    return state


def test_preset_equals_spec002_filter_with_the_same_settings():
    """Without the manoeuvre switch and the precision gate, ct-omega-adaptive on the tracker's
    layout is R11-R14's filter (skytrack.filters.adaptive_augmented with the preset's settings and
    Q_dep) step for step: states to 1e-6 m and the turn rate to 1e-9 rad/s."""
    T, steps, rows = 4.0, 25, 6
    z = ct_track(rows, steps, T, seed=3)
    preset = PRESETS["ct-omega-adaptive"]
    filt = build_filter("ct-omega-adaptive", constant_velocity(2, 1.0), compiled=False,
                        manoeuvre_q=preset.q_a, precision_fraction=math.inf)
    x0 = np.column_stack([z[0, :, 0], np.full(rows, 200.0), z[0, :, 1], np.zeros(rows)])
    P0 = np.broadcast_to(np.diag([400.0, 100.0, 400.0, 100.0]), (rows, 4, 4)).copy()
    state = run_preset(filt, z[1:], T, x0, P0)

    reference = AdaptiveAugmentedFilter(
        ct_omega(sigma_omega=math.sqrt(preset.V_w0), q_accel=preset.q_a), LinearMeasurement(np.eye(2, 5)),
        AdaptiveSettings(sigma_min=[preset.sigma_min], sigma_max=[preset.sigma_max], forgetting=preset.forgetting,
                         n0=preset.n0))
    x_ref0 = np.column_stack([x0[:, TO_TRACKER], np.zeros(rows)])
    P_ref0 = np.zeros((rows, 5, 5))
    P_ref0[:, :4, :4] = P0[:, TO_TRACKER][:, :, TO_TRACKER]
    P_ref0[:, 4, 4] = preset.prior_sigma**2
    bank = reference.initial_state(x_ref0, P_ref0, V_w0=[[preset.V_w0]])
    reference.run(bank, z[1:], T, 400.0 * np.eye(2))
    np.testing.assert_allclose(state.x[:, :4], bank.x[:, TO_TRACKER], rtol=0, atol=1e-6)
    np.testing.assert_allclose(state.x[:, 4], bank.x[:, 4], rtol=0, atol=1e-9)
    np.testing.assert_allclose(state.x[:, 5], bank.V_bar[:, 0, 0], rtol=1e-9, atol=1e-15)


def test_turn_rate_is_learnt_on_a_turn():
    """On a 2 deg/s turn seen every 1 s at 30 km (sigma 20 m), the preset's omega converges: mean over 40
    runs within 0.15 deg/s of the truth after 120 s (its standard error is about 0.02 deg/s)."""
    T, steps, rows = 1.0, 120, 40
    z = ct_track(rows, steps, T, seed=5)
    filt = build_filter("ct-omega-adaptive", constant_velocity(2, 1.0))
    x0 = np.column_stack([z[0, :, 0], np.full(rows, 200.0), z[0, :, 1], np.zeros(rows)])
    P0 = np.broadcast_to(np.diag([400.0, 100.0, 400.0, 100.0]), (rows, 4, 4)).copy()
    state = run_preset(filt, z[1:], T, x0, P0)
    omega, _ = filt.parameters(state)
    assert abs(math.degrees(omega.mean()) - 2.0) < 0.15


@pytest.mark.parametrize("kind", sorted(PRESETS))
@pytest.mark.parametrize("ndim", [2, 3])
def test_compiled_prediction_equals_numpy(kind, ndim):
    """The compiled row kernel (filters/adaptive_tracking_kernels.predict_rows) against the numpy
    prediction, with random memories, parameters, psi flags and steps (forward and backward): 1e-9 relative."""
    rng = np.random.default_rng(11)
    fast = build_filter(kind, constant_velocity(ndim, 1.0), compiled=True)
    slow = build_filter(kind, constant_velocity(ndim, 1.0), compiled=False)
    rows = 50
    x = np.zeros((rows, fast.n_motion))
    x[:, ::2] = rng.uniform(-5e4, 5e4, (rows, ndim))
    x[:, 1::2] = rng.normal(0.0, 150.0, (rows, ndim))
    state = fast.initiate(x, np.broadcast_to(np.eye(fast.n_motion) * 100.0, (rows, fast.n_motion, fast.n_motion)))
    state.x[:, fast.n_motion:fast.n_aug] = rng.normal(0.0, 0.02, (rows, fast.p))
    state.x[:, fast.memory_slice] = (np.eye(fast.p) * 10.0 ** rng.uniform(-12, 0, (rows, 1, 1))).reshape(rows, -1)
    state.x[:, fast.psi_index] = rng.integers(0, 2, rows)
    dt = rng.uniform(-5.0, 12.0, rows)
    for context in (None, {"manoeuvre": True}):
        a, b = fast.predict(state, dt, context), slow.predict(state, dt, context)
        for name in ("x", "P", "A", "G"):
            got, want = getattr(a, name), getattr(b, name)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max(), err_msg=name)


@pytest.fixture(scope="module")
def crossing():
    return simulate(load_scenario("crossing"))


@pytest.mark.parametrize("kind", sorted(PRESETS))
def test_compiled_stage_equals_the_composed_reference(crossing, kind):
    """The tracker's compiled stage (tracker/adaptive_stage_kernel.py) against the composed parts with
    the numpy filter: the same rows, states to 1e-6 m and m/s, the same bank (parameters and memory
    to 1e-6 relative), the same manoeuvre-gate hits; two-point starts run on both paths."""
    outputs = {}
    for compiled in (True, False):
        config = TrackerConfig()
        config.filter = FilterConfig(kind=kind, options={"compiled": compiled})
        config.initiation.method = "two-point"
        tracker = Tracker(crossing.sensors, config)
        outputs[compiled] = (tracker.run(crossing.plots), tracker)
    (fast, fast_tracker), (reference, reference_tracker) = outputs[True], outputs[False]
    assert fast_tracker.scan.fused_adaptive is not None and reference_tracker.scan.fused_adaptive is None
    assert len(fast) == len(reference) > 100
    np.testing.assert_array_equal(fast["track_id"], reference["track_id"])
    for column in ("x", "y", "vx", "vy"):
        np.testing.assert_allclose(fast[column], reference[column], rtol=0, atol=1e-6, err_msg=column)
    np.testing.assert_allclose(fast_tracker.bank.state.x, reference_tracker.bank.state.x, rtol=1e-6, atol=1e-9)
    assert fast_tracker.stats["manoeuvre_gate_hits"] == reference_tracker.stats["manoeuvre_gate_hits"]


def test_preset_options_are_checked():
    motion = constant_velocity(2, 1.0)
    with pytest.raises(ValueError, match="unknown option"):
        build_filter("ct-omega-adaptive", motion, sigma=1.0)
    with pytest.raises(ValueError, match="sigma_max"):
        build_filter("ct-omega-adaptive", motion, sigma_max=1e-6)
    with pytest.raises(ValueError, match="order 2"):
        build_filter("ca-accel-adaptive", singer(2, tau=20.0, sigma_a=3.0))


def test_imprecise_steps_fold_the_prior_into_the_memory():
    """Steps whose one-step precision is above the gate (R = (5 km)^2 I) adapt nothing: the memory
    V̄ raised to (1 deg/s)^2 returns to the prior V_w0 by the fading-memory recursion
    V̄_j = V̄_{j-1} + (V_w0 - V̄_{j-1}) / n_j, n_j = lambda n_{j-1} + 1 (to 1e-12 relative), and every
    such step counts as skipped."""
    rows, steps, T = 3, 6, 4.0
    filt = build_filter("ct-omega-adaptive", constant_velocity(2, 1.0), compiled=False)
    preset = filt.preset
    x0 = np.tile([0.0, 200.0, 30e3, 0.0], (rows, 1))
    state = filt.initiate(x0, np.broadcast_to(np.diag([400.0, 100.0, 400.0, 100.0]), (rows, 4, 4)).copy())
    raised = math.radians(1.0) ** 2
    state.x[:, filt.memory_slice] = raised
    model = ConvertedPositionModel(2, 2)
    R = np.broadcast_to(25e6 * np.eye(2), (rows, 2, 2)).copy()
    expected, count = raised, preset.n0
    for k in range(steps):
        predicted = filt.predict(state, np.full(rows, T))
        z = predicted.estimate().x[:, [0, 2]] + 100.0
        state, stats = filt.update(predicted, z, filt.innovate(predicted, z, model, {"R": R}))
        count = preset.forgetting * count + 1.0
        expected += (preset.V_w0 - expected) / count
        assert not stats.extra["adapted"].any()
        np.testing.assert_allclose(state.x[:, filt.memory_slice][:, 0], expected, rtol=1e-12)
    np.testing.assert_array_equal(state.x[:, filt.skipped_index], steps)

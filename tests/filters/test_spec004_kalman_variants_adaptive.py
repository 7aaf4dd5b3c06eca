"""Spec 004 adaptive Kalman filter (§3.3 F, R8; kind "kalman-adaptive"): TV16 (structured one step
with d forced to 0.5, and the d_k sequence for b = 0.97; 1e-9), warm-up, NIS gate, limits, the
one-step formulas of the sage_husa_full and covariance_matching variants, several predictions
before one update, the R-hat / q-hat histories of study E6 and its R-hat assertion, bad
configuration.  "rel" means ``max|a - b| <= rtol * max|b|``.  Monte Carlo runs draw from
``np.random.default_rng(np.random.SeedSequence(seed).spawn(runs)[r])``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from skytrack.core import linalg
from skytrack.filters.adaptive import AdaptiveKalmanFilter, StructuredAdaptiveState, fading_weight
from skytrack.filters.base import ListRecorder
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.registry import build_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_velocity
from skytrack.models.polynomial import dwna


def gens(seed, runs):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)]


def assert_rel(actual, expected, rtol, what=""):
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape, what
    err = np.max(np.abs(actual - expected)) / max(np.max(np.abs(expected)), 1e-300)
    assert err <= rtol, f"{what}: relative difference {err:.3e} > {rtol:.0e}"


def step(filt, state, z, R, dt=1.0, model=None):
    model = model or ConvertedPositionModel(R.shape[-1], filt.transition.order)
    pred = filt.predict(state, np.full(len(state), dt))
    inn = filt.innovate(pred, z, model, {"R": R})
    return pred, inn, filt.update(pred, z, inn)[0]


def cv_rows(filt, rows, ndim=3, seed=0):
    rng = np.random.default_rng(seed)
    x = np.zeros((rows, 2 * ndim))
    x[:, 0::2] = rng.uniform(-1e4, 1e4, (rows, ndim))
    x[:, 1::2] = rng.normal(0.0, 100.0, (rows, ndim))
    return filt.initiate(x, np.broadcast_to(np.diag(np.tile([100.0, 30.0], ndim) ** 2), (rows, 2 * ndim, 2 * ndim)).copy())


# ---------------------------------------------------------------------------- TV16
def test_tv16_structured_one_step_with_d_forced_to_half():
    filt = AdaptiveKalmanFilter(dwna(1, 1.0), fixed_weight=0.5)
    filt.recorder = ListRecorder()
    state = StructuredAdaptiveState(np.array([[100.0, 10.0]]), np.array([[[300.0, 40.0], [40.0, 20.0]]]),
                                    np.array([[[400.0]]]), np.array([[[400.0]]]), np.zeros((1, 2, 2)),
                                    np.array([10]), np.array([3]), np.array([4.0]))
    z = np.array([[135.0]])
    pred, inn, new = step(filt, state, z, np.array([[[1.0]]]))  # the model's R is not used after the first update
    np.testing.assert_allclose(pred.x[0], [110.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(pred.P[0], [[401.0, 62.0], [62.0, 24.0]], atol=1e-9)
    np.testing.assert_allclose(inn.nu[0], [25.0], atol=1e-9)
    np.testing.assert_allclose(new.R_hat[0], [[312.0]], atol=1e-9)
    gain = filt.recorder.channel("gain")[-1][1]["gain"][0, :, 0]
    np.testing.assert_allclose(gain, [0.5624123422, 0.0869565217], atol=1e-9)
    np.testing.assert_allclose(new.x[0], [124.0603085554, 12.1739130435], atol=1e-9)
    np.testing.assert_allclose(new.P[0], [[175.4726507714, 27.1304347826], [27.1304347826, 18.6086956522]], atol=1e-9)
    projection = (new.q_hat[0] - 0.5 * 4.0) / 0.5
    np.testing.assert_allclose(projection, -3.633825036538, atol=1e-9)
    np.testing.assert_allclose(new.q_hat[0], 0.183087481731, atol=1e-9)
    event = filt.recorder.channel("adaptive")[-1][1]
    assert event["adapted"][0] and event["weight"][0] == 0.5 and event["q_hat"][0] == new.q_hat[0]
    assert new.adaptations[0] == 4 and new.scans[0] == 11
    # S = H P^- H^T + r-hat' = 401 + 312: the update used the new R-hat
    np.testing.assert_allclose(gain[0], 401.0 / 713.0, atol=1e-12)


def test_tv16_fading_weights_for_b_097():
    np.testing.assert_allclose(fading_weight(0.97, np.arange(5)),
                               [1.0, 0.507614213198, 0.343536363324, 0.261535480034, 0.212365363625], atol=1e-9)
    assert abs(fading_weight(0.97, 10_000) - 0.03) < 1e-12
    # the filter applies them on successive adaptation scans (warm-up 0, gate off)
    filt = AdaptiveKalmanFilter(constant_velocity(2, 1.0), warmup=0, gate=False)
    filt.recorder = ListRecorder()
    state = cv_rows(filt, 2, ndim=2)
    rng = np.random.default_rng(3)
    R = np.broadcast_to(np.eye(2) * 900.0, (2, 2, 2))
    for _ in range(5):
        state = step(filt, state, state.x[:, 0::2] + rng.normal(0.0, 30.0, (2, 2)), R)[2]
    weights = np.array([values["weight"] for _, values in filt.recorder.channel("adaptive")])
    np.testing.assert_allclose(weights, np.repeat(fading_weight(0.97, np.arange(5))[:, None], 2, axis=1), atol=1e-15)


# ---------------------------------------------------------------------------- defaults, configuration
def test_defaults_are_spec_004_section_6():
    filt = build_filter("kalman-adaptive", constant_velocity(3, 1.0))
    assert (filt.variant, filt.b, filt.warmup, filt.gate, filt.gate_probability) == ("structured", 0.97, 10, True, 0.99)
    assert (filt.r_lo, filt.r_hi, filt.q_lo, filt.q_hi, filt.window) == (0.1, 10.0, 0.01, 2500.0, 20)
    assert build_filter("kalman-adaptive", constant_velocity(3, 1.0), variant="sage_husa_full").gate is False
    assert not filt.capabilities.gain_depends_on_r


@pytest.mark.parametrize("options,match", [
    ({"b": 0.0}, "b must be"), ({"b": 1.0}, "b must be"), ({"b": 1.3}, "b must be"),
    ({"variant": "sage_husa"}, "variant must be"), ({"r_lo": 2.0, "r_hi": 1.0}, "r_lo"),
    ({"q_lo": 0.0}, "q_lo"), ({"warmup": -1}, "warmup"), ({"window": 0}, "window"),
    ({"fixed_weight": 0.0}, "fixed_weight"), ({"gate_probability": 1.0}, "gate_probability"),
    ({"q0": -1.0}, "q0"), ({"r_hat0": 4.0}, "r_hat0"),
])
def test_bad_configuration_names_the_option(options, match):
    with pytest.raises(ValueError, match=match):
        build_filter("kalman-adaptive", constant_velocity(3, 1.0), **options)


# ---------------------------------------------------------------------------- warm-up, R-hat vs the model's R
def test_warmup_is_the_kalman_filter_with_r0_and_q0_and_ignores_later_model_r():
    """During the warm-up (10 updates) the filter is the KF with Q = q0 Q_unit and R = r0_scale diag(R of
    the first update) (1e-12 rel), whatever R the model reports later; the 11th update adapts."""
    motion = constant_velocity(3, 1.0)
    filt = AdaptiveKalmanFilter(motion, r0_scale=4.0, q0=25.0)
    kf = KalmanFilter(motion.scaled(25.0), compiled=False)
    rows = 3
    rngs = gens(5, rows)
    R_first = np.array([np.diag(g.uniform(30.0, 80.0, 3) ** 2) + 100.0 for g in rngs])  # full: only the diagonal counts
    R_kf = 4.0 * np.array([np.diag(np.diag(r)) for r in R_first])
    state, ref = cv_rows(filt, rows), cv_rows(kf, rows)
    noise = np.array([g.normal(0.0, 50.0, (11, 3)) for g in rngs])
    for k in range(11):
        z = state.x[:, 0::2] + noise[:, k]
        R_model = R_first if k == 0 else R_first * (k + 1.0)
        pred, inn, state = step(filt, state, z, R_model)
        if k < 10:
            ref = step(kf, ref, z, R_kf)[2]
            assert_rel(state.x, ref.x, 1e-12, f"x {k}")
            assert_rel(state.P, ref.P, 1e-12, f"P {k}")
            assert_rel(state.R_hat, R_kf, 1e-15, "R-hat")
            assert np.all(state.adaptations == 0) and np.all(state.q_hat == 25.0)
    assert_rel(state.R_nom, R_kf, 1e-15, "R_nom")
    assert np.all(state.adaptations == 1)
    assert not np.allclose(state.R_hat, R_kf)


def plot_with_nis(filt, pred, R, nis):
    """Measurements whose NIS against the filter's current S is exactly ``nis`` (per row)."""
    model = ConvertedPositionModel(3, 2)
    h = pred.x[:, 0::2]
    L = filt.innovate(pred, h, model, {"R": R}).chol
    return h + np.einsum("kij,kj->ki", L, np.full((len(h), 3), 1.0 / np.sqrt(3.0)) * np.sqrt(nis)[:, None])


@pytest.mark.parametrize("gate", [True, False])
def test_nis_gate_keeps_manoeuvre_innovations_out_of_the_estimates(gate):
    """At an adaptation scan, a row with NIS above chi2_3^-1(0.99) = 11.34 does not adapt (R-hat, q-hat and
    k' unchanged) when the gate is on; a row with NIS 2 adapts; with the gate off both adapt."""
    motion = constant_velocity(3, 1.0)
    filt = AdaptiveKalmanFilter(motion, warmup=3, gate=gate)
    R = np.broadcast_to(np.eye(3) * 2500.0, (2, 3, 3))
    state = cv_rows(filt, 2)
    for _ in range(3):
        state = step(filt, state, state.x[:, 0::2], R)[2]
    pred = filt.predict(state, np.ones(2))
    threshold = stats.chi2.ppf(0.99, 3)
    z = plot_with_nis(filt, pred, R, np.array([2.0, 1.5 * threshold]))
    new = filt.update(pred, z, filt.innovate(pred, z, ConvertedPositionModel(3, 2), {"R": R}))[0]
    adapted = new.adaptations - state.adaptations
    assert adapted[0] == 1
    if gate:
        assert adapted[1] == 0
        assert np.array_equal(new.R_hat[1], state.R_hat[1]) and new.q_hat[1] == state.q_hat[1]
    else:
        assert adapted[1] == 1 and not np.array_equal(new.R_hat[1], state.R_hat[1])


def test_limits_clip_r_and_q():
    """First adaptation (d = 1), gate off: a huge innovation puts r-hat at r_hi R_nom and q-hat at q_hi; a
    zero innovation puts r-hat at r_lo R_nom and q-hat at q_lo."""
    filt = AdaptiveKalmanFilter(constant_velocity(3, 1.0), warmup=1, gate=False, r_lo=0.2, r_hi=5.0, q_lo=0.05, q_hi=300.0)
    R = np.broadcast_to(np.diag([900.0, 1600.0, 2500.0]), (2, 3, 3))
    state = step(filt, cv_rows(filt, 2), np.zeros((2, 3)), R)[2]
    state.x[:, 0::2] = 0.0
    pred = filt.predict(state, np.ones(2))
    z = np.array([[1e5, -1e5, 1e5], list(pred.x[1, 0::2])])
    new = filt.update(pred, z, filt.innovate(pred, z, ConvertedPositionModel(3, 2), {"R": R}))[0]
    assert_rel(new.R_hat[0], 5.0 * R[0], 1e-15, "r_hi")
    assert_rel(new.R_hat[1], 0.2 * R[1], 1e-15, "r_lo")
    assert new.q_hat[0] == 300.0 and new.q_hat[1] == 0.05


# ---------------------------------------------------------------------------- the two other variants
def eig_floor(M, floor):
    w, U = np.linalg.eigh(0.5 * (M + M.T))
    return (U * np.maximum(w, floor)) @ U.T


def test_sage_husa_full_one_step_and_psd_projection():
    """One adaptation scan against the formulas of §3.3 F.1 written out with numpy (1e-9 rel), then 40
    scans of wild innovations keep R-hat's eigenvalues >= r_floor min diag R_nom and Q-hat PSD."""
    motion = constant_velocity(3, 1.0)
    filt = AdaptiveKalmanFilter(motion, variant="sage_husa_full", warmup=2)
    R = np.broadcast_to(np.diag([900.0, 1600.0, 2500.0]), (2, 3, 3))
    rng = np.random.default_rng(4)
    state = cv_rows(filt, 2)
    for _ in range(4):
        state = step(filt, state, state.x[:, 0::2] + rng.normal(0.0, 40.0, (2, 3)), R)[2]
    z = state.x[:, 0::2] + rng.normal(0.0, 40.0, (2, 3))
    pred, inn, new = step(filt, state, z, R)
    d = fading_weight(0.97, state.adaptations[0])
    H = np.kron(np.eye(3), [[1.0, 0.0]])
    F, floor = motion.F(1.0), 1e-3 * 900.0
    for r in range(2):
        nu, Pm = inn.nu[r], pred.P[r]
        R_hat = eig_floor((1 - d) * state.R_hat[r] + d * (np.outer(nu, nu) - H @ Pm @ H.T), floor)
        S = H @ Pm @ H.T + R_hat
        K = Pm @ H.T @ np.linalg.inv(S)
        A = np.eye(6) - K @ H
        P_k = A @ Pm @ A.T + K @ R_hat @ K.T
        M_Q = K @ np.outer(nu, nu) @ K.T + P_k - F @ state.P[r] @ F.T
        Q_hat = eig_floor((1 - d) * state.Q_hat[r] + d * M_Q, 0.0)
        assert_rel(new.R_hat[r], R_hat, 1e-9, "R-hat")
        assert_rel(new.x[r], pred.x[r] + K @ nu, 1e-9, "x")
        assert_rel(new.P[r], P_k, 1e-9, "P")
        assert_rel(new.Q_hat[r], Q_hat, 1e-9, "Q-hat")
    for _ in range(40):
        new = step(filt, new, new.x[:, 0::2] + rng.standard_cauchy((2, 3)) * 30.0, R)[2]
        assert np.linalg.eigvalsh(new.R_hat).min() >= floor * (1 - 1e-9)
        assert np.linalg.eigvalsh(new.Q_hat).min() >= -1e-9 * np.abs(new.Q_hat).max()


def test_covariance_matching_window_and_one_step():
    """Nothing is estimated until the window holds M = 4 innovations of adaptation scans (warm-up 2, so
    update 6 is the first estimate); then C = mean nu nu^T over the window, R-hat = PSD(C - H P^- H^T)
    floored, the update with R-hat, Q-hat = K C K^T (1e-9 rel, numpy written out)."""
    motion = constant_velocity(3, 1.0)
    filt = AdaptiveKalmanFilter(motion, variant="covariance_matching", warmup=2, window=4, gate=False)
    R = np.broadcast_to(np.diag([900.0, 1600.0, 2500.0]), (2, 3, 3))
    rng = np.random.default_rng(9)
    state = cv_rows(filt, 2)
    innovations = []
    for k in range(6):
        pred, inn, new = step(filt, state, state.x[:, 0::2] + rng.normal(0.0, 60.0, (2, 3)), R)
        if k >= 2:
            innovations.append(inn.nu)
        if k < 5:
            assert np.all(new.adaptations == 0) and np.array_equal(new.R_hat, R)
            state = new
    assert np.all(new.adaptations == 1) and np.all(new.stored == 4)
    H = np.kron(np.eye(3), [[1.0, 0.0]])
    window = np.array(innovations)
    for r in range(2):
        C = np.einsum("wi,wj->ij", window[:, r], window[:, r]) / 4.0
        Pm = pred.P[r]
        R_hat = eig_floor(C - H @ Pm @ H.T, 1e-3 * 900.0)
        K = Pm @ H.T @ np.linalg.inv(H @ Pm @ H.T + R_hat)
        assert_rel(new.R_hat[r], R_hat, 1e-9, "R-hat")
        assert_rel(new.x[r], pred.x[r] + K @ inn.nu[r], 1e-9, "x")
        assert_rel(new.Q_hat[r], K @ C @ K.T, 1e-9, "Q-hat")


# ---------------------------------------------------------------------------- several predictions, histories
def test_two_predictions_before_an_update_equal_one():
    """Structured variant: predicting by 0.4 s then 0.6 s and updating equals one 1 s prediction and the
    same update (F P_{k-1} F^T = P^- - Q_acc with the noise of both steps), 1e-9 rel."""
    filt = AdaptiveKalmanFilter(constant_velocity(3, 2.0), warmup=0, gate=False, q_hi=1e9)
    R = np.broadcast_to(np.diag([900.0, 1600.0, 2500.0]), (3, 3, 3))
    state = step(filt, cv_rows(filt, 3), np.zeros((3, 3)), R)[2]
    z = state.x[:, 0::2] + 80.0
    once = filt.predict(state, np.ones(3))
    twice = filt.predict(filt.predict(state, np.full(3, 0.4)), np.full(3, 0.6))
    model = ConvertedPositionModel(3, 2)
    a = filt.update(once, z, filt.innovate(once, z, model, {"R": R}))[0]
    b = filt.update(twice, z, filt.innovate(twice, z, model, {"R": R}))[0]
    for name in ("x", "P", "R_hat", "q_hat"):
        assert_rel(getattr(b, name), getattr(a, name), 1e-9, name)
    assert not np.allclose(a.q_hat, state.q_hat)


def test_e6_r_hat_recovers_from_four_times_r_and_histories_are_recorded():
    """Study E6 set-up on a straight CV flight: R-hat_0 = 4 R_true, q-hat_0 = 25, 100 runs, 60 scans.  The
    recorder holds the R-hat and q-hat histories (60 x runs); after the warm-up the mean over runs of
    R-hat_ii / R_true,ii lies in E6's [0.6, 1.4] at scan 60; it is exactly 4 during the warm-up."""
    runs, steps = 100, 60
    motion = constant_velocity(3, 1.0)
    filt = AdaptiveKalmanFilter(motion, r0_scale=4.0, q0=25.0)
    filt.recorder = ListRecorder()
    rngs = gens(2024, runs)
    R = np.broadcast_to(np.diag([50.0, 60.0, 40.0]) ** 2, (runs, 3, 3)).copy()
    F, Qs = motion.F(1.0), np.linalg.cholesky(motion.Q(1.0))
    truth = np.tile([-1e4, 250.0, 4e4, 0.0, 6e3, 0.0], (runs, 1))
    P0 = np.diag([100.0, 30.0] * 3) ** 2
    state = filt.initiate(truth + np.array([g.standard_normal(6) for g in rngs]) * np.sqrt(np.diag(P0)),
                          np.broadcast_to(P0, (runs, 6, 6)).copy())
    w = np.array([g.standard_normal((steps, 6)) for g in rngs])
    v = np.array([g.standard_normal((steps, 3)) for g in rngs]) * [50.0, 60.0, 40.0]
    for k in range(steps):
        truth = truth @ F.T + w[:, k] @ Qs.T
        state = step(filt, state, truth[:, 0::2] + v[:, k], R)[2]
    events = filt.recorder.channel("adaptive")
    R_hist = np.stack([values["R_hat"] for _, values in events])
    q_hist = np.stack([values["q_hat"] for _, values in events])
    assert R_hist.shape == (steps, runs, 3, 3) and q_hist.shape == (steps, runs)
    ratio = np.diagonal(R_hist, axis1=-2, axis2=-1) / np.diag(R[0])
    assert np.all(ratio[:10] == 4.0) and np.all(q_hist[:10] == 25.0)
    assert np.all((ratio[-1].mean(axis=0) >= 0.6) & (ratio[-1].mean(axis=0) <= 1.4)), ratio[-1].mean(axis=0)


def test_adaptation_cost_is_counted():
    """The counting layer sees the adaptation: an adaptation scan costs more multiply-adds than a
    warm-up scan of the same filter (study E6 reports MACs relative to the KF)."""
    filt = AdaptiveKalmanFilter(constant_velocity(3, 1.0), variant="sage_husa_full", warmup=1, compiled=False)
    R = np.broadcast_to(np.eye(3) * 2500.0, (2, 3, 3))
    state = cv_rows(filt, 2)
    costs = []
    for _ in range(2):
        with linalg.counting() as ops:
            state = step(filt, state, state.x[:, 0::2] + 10.0, R)[2]
        costs.append(ops.madds)
    assert state.adaptations.tolist() == [1, 1]
    assert costs[1] > costs[0] > 0

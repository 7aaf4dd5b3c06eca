"""Spec 004 R3: the paper's α–β range / closing-speed tracker (1)–(4), test vectors TV1–TV5 and TV9,
initialisations, range gate and loss, manoeuvre gains with the VD detector.

Monte Carlo runs are seeded per run with ``SeedSequence(seed).spawn(runs)[r]``.
"""

from __future__ import annotations

import numpy as np
import pytest

from skytrack.filters import alpha_beta_gains as G
from skytrack.filters.base import ListRecorder
from skytrack.filters.range_tracker import RangeAlphaBeta

G0 = 9.80665


def noise(seed, runs, scans, sigma):
    return np.array([g.standard_normal(scans) for g in
                     (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs))]) * sigma


def cv_range(scans, T=0.1, start=30000.0, rate=-600.0):
    """Noise-free Д(k) = start + rate k T, k = 1..scans, as one run."""
    return (start + rate * T * np.arange(1, scans + 1))[None, :]


def accelerating(n, T=0.1, scans=300, onset=10.0, duration=5.0):
    """E1's range: 30 km, −600 m/s, range acceleration n g₀ from ``onset`` for ``duration`` s (exact)."""
    t = T * np.arange(1, scans + 1)
    A = n * G0
    during = np.clip(t - onset, 0.0, duration)
    after = np.clip(t - onset - duration, 0.0, None)
    return 30000.0 - 600.0 * t + A * during**2 / 2 + A * duration * after


# ---------------------------------------------------------------------------- TV1-TV3
def test_tv1_exact_on_a_noise_free_cv_target():
    z = cv_range(100)
    result = RangeAlphaBeta(0.5, 0.2, 0.1).run(z, 30000.0, -600.0)
    assert np.max(np.abs(result.residual)) <= 1e-6
    assert np.max(np.abs(result.range - z)) <= 1e-6
    assert np.max(np.abs(result.velocity + 600.0)) <= 1e-6


TV2 = {1: (-1, -16, 29941, -584), 2: (-1.3, -10.8, 29881.3, -589.2), 3: (-1.19, -6.04, 29821.19, -593.96),
       5: (-0.5711, -0.1676, None, None), 10: (0.088274927, 0.650905932, 29399.911725073, -600.650905932),
       20: (-0.00340812854206, -0.00559900114193, None, None)}


def test_tv2_error_decay_from_a_velocity_error():
    T, alpha, beta = 0.1, 0.5, 0.2
    z = cv_range(100)
    result = RangeAlphaBeta(alpha, beta, T).run(z, 30000.0, -580.0)
    e_range, e_velocity = z[0] - result.range[0], -600.0 - result.velocity[0]
    for k, (er, ev, rng, vel) in TV2.items():
        assert abs(e_range[k - 1] - er) <= 1e-8 and abs(e_velocity[k - 1] - ev) <= 1e-8, k
        if rng is not None:
            assert abs(result.range[0, k - 1] - rng) <= 1e-8 and abs(result.velocity[0, k - 1] - vel) <= 1e-8
    # e_k = M^k [0, -20] for every k
    M = np.array([[1 - alpha, (1 - alpha) * T], [-beta / T, 1 - beta]])
    expected = np.array([np.linalg.matrix_power(M, k) @ [0.0, -20.0] for k in range(1, 101)])
    assert np.max(np.abs(np.stack([e_range, e_velocity], axis=1) - expected)) <= 1e-8
    eig = np.linalg.eigvals(M)
    assert np.allclose(sorted(eig.imag), [-0.278388218142, 0.278388218142], rtol=0, atol=1e-9)
    assert np.allclose(eig.real, 0.65, rtol=0, atol=1e-12) and np.allclose(np.abs(eig), 2**-0.5, rtol=0, atol=1e-12)


def test_tv3_closing_speed_convention_gives_the_same_ranges():
    z = cv_range(100)
    rate = RangeAlphaBeta(0.5, 0.2, 0.1).run(z, 30000.0, -580.0)
    closing = RangeAlphaBeta(0.5, 0.2, 0.1, velocity_convention="closing_speed").run(z, 30000.0, 580.0)
    assert np.max(np.abs(closing.range - rate.range)) <= 1e-9
    assert np.max(np.abs(closing.velocity + rate.velocity)) <= 1e-9
    assert np.max(np.abs(closing.predicted - rate.predicted)) <= 1e-9


# ---------------------------------------------------------------------------- TV4, TV5
TV4 = [(0.5, 0.2, 0.1, 30.0, 1.5, 0.75, 6.0), (0.5, 0.2, 1.0, 30.0, 150.0, 75.0, 60.0),
       (0.3, 9 / 140, 0.1, 50.0, 7.777777777778, 5.444444444444, 20.833333333333)]


@pytest.mark.parametrize("alpha,beta,T,A,predicted,filtered,velocity", TV4)
def test_tv4_steady_state_lags_under_constant_range_acceleration(alpha, beta, T, A, predicted, filtered, velocity):
    t = T * np.arange(1, 401)
    truth = 30000.0 - 600.0 * t + A * t * t / 2
    result = RangeAlphaBeta(alpha, beta, T).run(truth[None], 30000.0, -600.0)
    lag = np.array([truth[-1] - result.predicted[0, -1], truth[-1] - result.range[0, -1],
                    -600.0 + A * t[-1] - result.velocity[0, -1]])
    assert np.max(np.abs(lag / [predicted, filtered, velocity] - 1.0)) <= 1e-9


def test_tv5_noise_only_variances_match_the_closed_form():
    """E1's assert: 1000 runs, σ_v = 10 m, T = 0.1 s, Benedict–Bordner α = 0.5, exact start, gate off:
    the error variances over scans 100–299 are within 5 % of σ_v² × the §3.3 C ratios."""
    T, sigma, alpha = 0.1, 10.0, 0.5
    beta = G.benedict_bordner_beta(alpha)
    truth = cv_range(300, T)
    result = RangeAlphaBeta(alpha, beta, T).run(truth + noise(5, 1000, 300, sigma), 30000.0, -600.0)
    window = slice(100, 300)
    measured = [np.mean(np.var(truth - result.range, axis=0)[window]),
                np.mean(np.var(truth - result.predicted, axis=0)[window]),
                np.mean(np.var(-600.0 - result.velocity, axis=0)[window])]
    ratios = G.variance_ratios(alpha, beta, T)
    expected = sigma**2 * np.array([ratios.filtered_position, ratios.predicted_position, ratios.velocity])
    assert np.max(np.abs(np.array(measured) / expected - 1.0)) <= 0.05, (measured, expected)


# ---------------------------------------------------------------------------- initialisation
def test_two_point_initialisation():
    T = 0.5
    z = 20000.0 + np.array([[0.0, -210.0, -390.0, -605.0, -800.0, -1010.0]])
    for convention, sign in (("range_rate", 1.0), ("closing_speed", -1.0)):
        tracker = RangeAlphaBeta(0.6, 0.25, T, velocity_convention=convention, initialisation="two_point")
        result = tracker.run(z)
        assert result.range[0, 0] == z[0, 0] and result.range[0, 1] == z[0, 1]
        assert np.isnan(result.velocity[0, 0]) and result.velocity[0, 1] == sign * -210.0 / T
        assert np.isnan(result.predicted[0, :2]).all()
        given = RangeAlphaBeta(0.6, 0.25, T, velocity_convention=convention).run(z[:, 2:], z[0, 1], sign * -420.0)
        assert np.array_equal(result.range[:, 2:], given.range) and np.array_equal(result.velocity[:, 2:], given.velocity)


def test_tv9_startup_ls_is_the_least_squares_line_for_any_prior():
    T, alpha = 0.2, 0.15
    tracker = RangeAlphaBeta(alpha, G.benedict_bordner_beta(alpha), T, initialisation="startup_ls")
    scans = 20
    assert tracker.startup_length > scans
    z = accelerating(0, T, scans)[None] + noise(11, 1, scans, 15.0)
    results = [tracker.run(z), tracker.run(z, 1.0e5, 3000.0)]
    times = T * np.arange(1, scans + 1)
    for k in range(2, scans + 1):
        slope, intercept = np.polyfit(times[:k] - times[k - 1], z[0, :k], 1)
        for result in results:
            assert abs(result.range[0, k - 1] / intercept - 1) <= 1e-9
            assert abs(result.velocity[0, k - 1] / slope - 1) <= 1e-9


def test_startup_gains_switch_to_the_nominal_gains_and_gate_with_the_least_squares_variance():
    T, alpha, beta, sigma = 0.1, 0.5, 0.2, 10.0
    tracker = RangeAlphaBeta(alpha, beta, T, initialisation="startup_ls", sigma_v=sigma, gating=True)
    tracker.recorder = ListRecorder()
    assert tracker.startup_length == 7
    result = tracker.run(cv_range(30, T))
    gains_used = np.array([[values["alpha"][0], values["beta"][0]] for _, values in tracker.recorder.channel("gain")])
    start = np.stack(G.startup_gains(np.arange(1, 7)), axis=1)
    assert np.allclose(gains_used[:6], start, rtol=1e-15) and np.all(gains_used[6:] == [alpha, beta])
    assert np.isinf(result.variance[0, :2]).all() and result.used.all()
    j = np.arange(2, 7)
    assert np.allclose(result.variance[0, 2:7], sigma**2 * (1 + 2 * (2 * j + 1) / (j * (j - 1))), rtol=1e-12)
    # from the 7th scan the variance converges to S0 of the nominal gains
    assert abs(result.variance[0, -1] / tracker.gate_variance() - 1) <= 1e-3


# ---------------------------------------------------------------------------- gate and loss
def test_gate_variance_is_s0_throughout_for_fixed_gains_from_given_values():
    tracker = RangeAlphaBeta(0.4, G.benedict_bordner_beta(0.4), 0.1, sigma_v=10.0, gating=True)
    s0 = 100.0 * (1 + G.variance_ratios(0.4, G.benedict_bordner_beta(0.4)).predicted_position)
    assert abs(tracker.gate_variance() - s0) <= 1e-12 * s0
    result = tracker.run(cv_range(200) + noise(3, 4, 200, 10.0), 30000.0, -600.0)
    assert np.max(np.abs(result.variance / s0 - 1)) <= 1e-12


def test_a_gated_out_measurement_is_a_miss_and_l_miss_misses_lose_the_track():
    T = 0.1
    z = cv_range(60, T).copy()
    z[0, 10] += 100.0
    z[0, [30, 31, 32]] += 100.0
    tracker = RangeAlphaBeta(0.5, 0.2, T, sigma_v=1.0, gating=True)
    result = tracker.run(z, 30000.0, -600.0)
    assert not result.used[0, 10] and result.used[0, 11:30].all() and result.used[0, :10].all()
    assert result.range[0, 10] == result.predicted[0, 10] and result.velocity[0, 10] == result.velocity[0, 9]
    assert np.max(np.abs(result.range[0, 11:30] - z[0, 11:30])) <= 1e-6  # an exact track is not disturbed
    assert not result.lost[0, :32].any() and result.lost[0, 32:].all() and result.lost_scan[0] == 32
    # a miss does not widen the gate (R3's fixed S0): the variance stays S0 before, at and after it
    assert np.allclose(result.variance[0, :33], tracker.gate_variance(), rtol=1e-12)
    assert not result.used[0, 30:].any()  # a lost run takes no more measurements: it coasts
    assert np.all(result.velocity[0, 32:] == result.velocity[0, 29])
    assert np.allclose(np.diff(result.range[0, 32:]), T * result.velocity[0, 29], rtol=1e-9)
    # gate off: everything used, nothing lost; L_miss = 1: lost at the first miss
    assert RangeAlphaBeta(0.5, 0.2, T).run(z, 30000.0, -600.0).used.all()
    assert RangeAlphaBeta(0.5, 0.2, T, sigma_v=1.0, gating=True, max_misses=1).run(z, 30000.0, -600.0).lost_scan[0] == 10


def test_runs_are_independent_rows():
    T = 0.1
    z = accelerating(6, T)[None] + noise(8, 5, 300, 10.0)
    tracker = RangeAlphaBeta(0.2, G.benedict_bordner_beta(0.2), T, sigma_v=10.0, gating=True, maneuver_gains="kalata")
    batch = tracker.run(z, 30000.0, -600.0)
    for r in range(5):
        alone = tracker.run(z[[r]], 30000.0, -600.0)
        for name in ("predicted", "residual", "variance", "range", "velocity", "used", "lost", "maneuver", "detector"):
            expected = getattr(batch, name)[r]
            assert np.array_equal(getattr(alone, name)[0], expected, equal_nan=expected.dtype.kind == "f"), (r, name)


# ---------------------------------------------------------------------------- manoeuvre gains
def test_default_maneuver_gains_are_kalata_at_ten_times_the_nominal_index():
    alpha, beta = 0.4, G.benedict_bordner_beta(0.4)
    tracker = RangeAlphaBeta(alpha, beta, 0.1, sigma_v=10.0, maneuver_gains="kalata")
    assert np.allclose(tracker.maneuver_pair, G.kalata_alpha_beta(10 * beta / np.sqrt(1 - alpha)), rtol=1e-14)
    assert tracker.threshold == G.detector_threshold(1, 0.8, 0.01) and tracker.window == 5
    assert RangeAlphaBeta(alpha, beta, 0.1, sigma_v=10.0, maneuver_gains=(0.9, 0.7)).maneuver_pair == (0.9, 0.7)


def test_maneuver_flag_follows_the_detector_rule():
    """On at u_k > threshold (that scan), off once u_k has stayed below it for s = 5 scans; the
    detector sum is u_k = 0.8 u_{k−1} + ΔД²/S; the gains used are the manoeuvre pair while on; S is
    σ_v² + the predicted range variance of the noise-only Joseph recursion over the gains used (a
    miss leaves the covariance unchanged), starting at the nominal steady state."""
    T = 0.1
    tracker = RangeAlphaBeta(0.3, G.benedict_bordner_beta(0.3), T, sigma_v=10.0, gating=True, maneuver_gains="kalata")
    tracker.recorder = ListRecorder()
    z = accelerating(5, T)[None] + noise(12, 20, 300, 10.0)
    result = tracker.run(z, 30000.0, -600.0)
    used_alpha = np.array([values["alpha"] for _, values in tracker.recorder.channel("gain")]).T
    used_beta = np.array([values["beta"] for _, values in tracker.recorder.channel("gain")]).T
    assert result.maneuver.any() and not result.maneuver.all()
    F = np.array([[1.0, T], [0.0, 1.0]])
    for r in range(20):
        u_prev, on, quiet = 0.0, False, 0
        P = G.steady_state_covariance(0.3, G.benedict_bordner_beta(0.3), None, T, 100.0)[0]
        for k in range(300):
            if result.lost[r, k - 1] if k else False:
                break
            P_pred = F @ P @ F.T
            assert abs(result.variance[r, k] / (P_pred[0, 0] + 100.0) - 1) <= 1e-9
            if result.used[r, k]:
                K = np.array([used_alpha[r, k], used_beta[r, k] / T])
                A = np.eye(2) - np.outer(K, [1.0, 0.0])
                P = A @ P_pred @ A.T + 100.0 * np.outer(K, K)
            u = 0.8 * u_prev + result.residual[r, k] ** 2 / result.variance[r, k]
            assert abs(u - result.detector[r, k]) <= 1e-9 * max(u, 1.0)
            if u > tracker.threshold:
                on, quiet = True, 0
            elif on:
                quiet += 1
                on = quiet < tracker.window
            assert result.maneuver[r, k] == on, (r, k)
            assert used_alpha[r, k] == (tracker.maneuver_pair[0] if on else 0.3)
            u_prev = u


def test_maneuver_gains_keep_a_low_gain_tracker_through_a_hard_manoeuvre():
    """E1 scenario at α = 0.2 (Benedict–Bordner), 6 g for 5 s, gate 3, L_miss 3, 200 runs: the fixed gains
    lose nearly every run through lag; the manoeuvre gains keep most of them."""
    T, alpha = 0.1, 0.2
    z = accelerating(6, T)[None] + noise(2024, 200, 300, 10.0)
    common = dict(alpha=alpha, beta=G.benedict_bordner_beta(alpha), period=T, sigma_v=10.0, gating=True)
    fixed = RangeAlphaBeta(**common).run(z, 30000.0, -600.0)
    switched = RangeAlphaBeta(**common, maneuver_gains="kalata").run(z, 30000.0, -600.0)
    assert fixed.lost[:, -1].mean() >= 0.8
    assert switched.lost[:, -1].mean() <= 0.4
    assert not fixed.lost[:, :99].any()  # nothing is lost before the onset at t = 10 s


# ---------------------------------------------------------------------------- configuration
BAD = [
    (dict(velocity_convention="closing"), "velocity_convention"),
    (dict(initialisation="lock-on"), "initialisation"),
    (dict(alpha=1.0, beta=2.5), "unstable"),
    (dict(alpha=1.5, beta=0.2, initialisation="startup_ls"), "alpha"),
    (dict(gating=True), "sigma_v"),
    (dict(maneuver_gains="kalata"), "sigma_v"),
    (dict(sigma_v=1.0, maneuver_gains="big"), "maneuver_gains"),
    (dict(sigma_v=1.0, maneuver_gains=(1.0, 2.5)), "maneuver_gains"),
    (dict(sigma_v=1.0, gating=True, max_misses=0), "max_misses"),
    (dict(sigma_v=1.0, gating=True, gate=-1.0), "gate"),
    (dict(period=0.0), "period"),
    (dict(sigma_v=1.0, maneuver_gains="kalata", detector_rho=1.0), "rho"),
]


@pytest.mark.parametrize("options,message", BAD)
def test_bad_configuration_is_a_value_error_naming_the_option(options, message):
    arguments = {"alpha": 0.5, "beta": 0.2, "period": 0.1, **options}
    with pytest.raises(ValueError, match=message):
        RangeAlphaBeta(**arguments)


def test_given_initialisation_needs_the_initial_values():
    with pytest.raises(ValueError, match="range0"):
        RangeAlphaBeta(0.5, 0.2, 0.1).run(cv_range(5))
    with pytest.raises(ValueError, match="two"):
        RangeAlphaBeta(0.5, 0.2, 0.1, initialisation="two_point").run(cv_range(1))

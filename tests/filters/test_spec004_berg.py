"""Spec 004 §3.3 M / R15: the Berg-type target-frame model, ``berg_full`` and ``berg_frame`` (TV17, E5).

Tolerances: TV17's printed digits (frame 1e-9, jerk 1e-8 absolute), its identity 1e-9 relative
(largest entry of the compared array sets the scale), model identities 1e-9 relative.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.core import linalg
from skytrack.filters.base import ListRecorder
from skytrack.filters.berg import (
    SPEC_CHANNELS,
    BergFrameFilter,
    BergFullFilter,
    enu_to_frame_blocks,
    frame_to_enu,
    mean_jerk,
    target_frame,
)
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.registry import build_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_acceleration, constant_velocity, singer

G0 = 9.80665
MODEL = ConvertedPositionModel(3, 3)
VEL, ACC, POS = [1, 4, 7], [2, 5, 8], [0, 3, 6]


def rel_err(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ---------------------------------------------------------------------------- TV17 frame and mean jerk
def test_tv17_frame():
    C = target_frame(np.array([[200.0, -120.0, 15.0]]))[0]
    assert np.max(np.abs(C[:, 0] - [0.855725100, -0.513435060, 0.064179383])) <= 1e-9
    assert np.max(np.abs(C[:, 1] - [0.514495755, 0.857492926, 0.0])) <= 1e-9
    assert np.max(np.abs(C[:, 2] - [-0.055033366, 0.033020020, 0.997938378])) <= 1e-9
    assert np.max(np.abs(C.T @ C - np.eye(3))) <= 1e-15 and abs(np.linalg.det(C) - 1.0) <= 1e-15


def test_tv17_mean_jerk():
    omega, jerk = mean_jerk(np.array([[250.0, 0.0, 0.0]]), np.array([[0.0, 5 * G0, 0.0]]))
    assert np.max(np.abs(omega[0] - [0.0, 0.0, 0.196133])) <= 1e-9
    assert np.max(np.abs(jerk[0] - [-9.617038422, 0.0, 0.0])) <= 1e-8
    v, a = np.array([[200.0, 150.0, 0.0]]), 3 * G0 * np.array([[-0.6, 0.8, 0.0]])
    omega, jerk = mean_jerk(v, a)
    assert np.max(np.abs(omega[0] - [0.0, 0.0, 0.117679800])) <= 1e-9
    assert np.max(np.abs(jerk[0] - [-2.769707066, -2.077280299, 0.0])) <= 1e-8
    j_f = target_frame(v)[0].T @ jerk[0]
    assert np.max(np.abs(j_f - [-3.462133832, 0.0, 0.0])) <= 1e-8
    assert abs(j_f[0] + np.sum(a * a) / np.linalg.norm(v)) <= 1e-12  # -a_n^2 / |v|


def test_vertical_and_zero_velocity_keep_the_previous_axes():
    previous = target_frame(np.array([[200.0, -120.0, 15.0], [0.0, 80.0, 0.0]]))
    C = target_frame(np.array([[0.0, 0.0, 150.0], [0.0, 0.0, 0.0]]), previous)
    # vertical: t = z, the previous (horizontal) normal is kept, b = t x n
    assert np.array_equal(C[0, :, 0], [0.0, 0.0, 1.0])
    assert np.max(np.abs(C[0, :, 1] - previous[0, :, 1])) <= 1e-15
    assert np.max(np.abs(C[0].T @ C[0] - np.eye(3))) <= 1e-15 and np.linalg.det(C[0]) > 0
    # zero velocity: the whole previous frame
    assert np.array_equal(C[1], previous[1])
    # just above the vertical limit the new normal is used, below it the previous one
    tilt = np.array([[2e-6, 0.0, 1.0], [5e-7, 0.0, 1.0]])
    C = target_frame(tilt, previous[[1, 1]])
    assert np.max(np.abs(C[0, :, 1] - [0.0, 1.0, 0.0])) <= 1e-12  # z x t for t ~ east-tilted: north
    assert np.max(np.abs(C[1, :, 1] - previous[1, :, 1])) <= 1e-6


def test_frame_blocks_round_trip_and_rotation_rule():
    rng = np.random.default_rng(3)
    C_old = target_frame(rng.normal(0, 200, (5, 3)))
    C_new = target_frame(rng.normal(0, 200, (5, 3)))
    M = rng.standard_normal((5, 3, 3, 3))
    blocks = M @ np.swapaxes(M, -1, -2) + np.eye(3)
    assert rel_err(enu_to_frame_blocks(C_old, frame_to_enu(C_old, blocks)), blocks) <= 1e-13
    # P_i <- sum_j D_ij^2 P_j is the diagonal-block part of the exact re-expression in the new frame
    D = np.swapaxes(C_new, -1, -2) @ C_old
    rotated = np.einsum("kij,kjab->kiab", D * D, blocks)
    assert rel_err(rotated, enu_to_frame_blocks(C_new, frame_to_enu(C_old, blocks))) <= 1e-12


# ---------------------------------------------------------------------------- TV17 identity
def straight_flight(scans=30):
    v = np.array([200.0, -120.0, 15.0])
    p0 = np.array([1000.0, 2000.0, 5000.0])
    x0 = np.zeros(9)
    x0[POS], x0[VEL] = p0, v
    C = target_frame(v[None])
    blocks = np.array([np.diag([2500.0, 500.0, 100.0]), np.diag([2500.0, 400.0, 900.0]), np.diag([2500.0, 300.0, 400.0])])
    P0 = frame_to_enu(C, blocks[None])
    z = [p0 + v * k for k in range(1, scans + 1)]
    return x0[None], P0, z


def run(filt, x0, P0, z, R):
    state = filt.initiate(x0, P0)
    for zk in z:
        state = filt.predict(state, np.ones(1))
        state, _ = filt.update(state, zk[None], filt.innovate(state, zk[None], MODEL, {"R": R}))
    return state


def test_tv17_full_equals_frame_on_straight_flight():
    x0, P0, z = straight_flight()
    R = (50.0**2 * np.eye(3))[None]
    full = run(BergFullFilter(SPEC_CHANNELS), x0, P0, z, R).estimate()
    frame = run(BergFrameFilter(SPEC_CHANNELS), x0, P0, z, R).estimate()
    assert rel_err(frame.x, full.x) <= 1e-9
    assert rel_err(frame.P, full.P) <= 1e-9
    # and the run is not trivial: the covariance moved far from P0 and the estimate follows the target
    assert rel_err(full.P, P0) > 0.5
    assert np.max(np.abs(full.x[0, POS] - z[-1])) <= 1e-6


def test_berg_full_with_isotropic_channels_is_the_singer_kalman_filter():
    """F and Q of equal channels are rotation invariant; without mean jerk berg_full is the Singer KF."""
    rng = np.random.default_rng(4)
    rows = 6
    motion = singer(3, 20.0, 3.0)
    berg = build_filter("berg-full", motion, mean_jerk=False)
    kf = KalmanFilter(motion, compiled=False)
    x = rng.normal(0, 100, (rows, 9))
    x[:, VEL] += rng.normal(0, 200, (rows, 3))
    A = rng.standard_normal((rows, 9, 9))
    P = A @ np.swapaxes(A, -1, -2) + 50 * np.eye(9)
    sb, sk = berg.initiate(x, P), kf.initiate(x, P)
    for _ in range(10):
        dt = rng.uniform(0.5, 5.0, rows)
        sb, sk = berg.predict(sb, dt), kf.predict(sk, dt)
        z = sk.x[:, POS] + rng.normal(0, 60, (rows, 3))
        R = np.broadcast_to(np.diag([900.0, 2500.0, 4900.0]), (rows, 3, 3)).copy()
        sb, _ = berg.update(sb, z, berg.innovate(sb, z, MODEL, {"R": R}))
        sk, _ = kf.update(sk, z, kf.innovate(sk, z, MODEL, {"R": R}))
    assert rel_err(sb.x, sk.x) <= 1e-9
    assert rel_err(sb.P, sk.P) <= 1e-9


# ---------------------------------------------------------------------------- E5: cost
def test_e5_frame_filter_costs_at_most_two_thirds_of_the_full_filter():
    """MAC(berg_frame) <= MAC(berg_full) / 1.5 per predict + innovate + update (R22 model, spec §6 E5)."""
    rng = np.random.default_rng(5)
    rows = 8
    x = rng.normal(0, 100, (rows, 9))
    x[:, VEL] += rng.normal(0, 200, (rows, 3))
    x[:, ACC] = rng.normal(0, 20, (rows, 3))
    P = np.broadcast_to(np.diag(np.tile([2500.0, 400.0, 100.0], 3)), (rows, 9, 9)).copy()
    R = np.broadcast_to(np.diag([900.0, 2500.0, 4900.0]), (rows, 3, 3)).copy()
    motion = constant_acceleration(3, 1.0)
    costs = {}
    for kind in ("berg-full", "berg-frame"):
        filt = build_filter(kind, motion)
        state = filt.initiate(x, P)
        with linalg.counting() as ops:
            pred = filt.predict(state, np.ones(rows))
            z = pred.x[:, POS] + 30.0
            filt.update(pred, z, filt.innovate(pred, z, MODEL, {"R": R}))
        costs[kind] = ops.madds / rows
        # the frame and mean-jerk arithmetic is counted, the rebuilt model's products too
        assert ops.by_name["berg_frame_axes"] > 0 and ops.by_name["berg_mean_jerk"] > 0
    assert costs["berg-frame"] <= costs["berg-full"] / 1.5, costs
    assert costs["berg-frame"] > 0


# ---------------------------------------------------------------------------- behaviour of the flags
def coordinated_turn(n_g=5.0, speed=250.0, T=1.0, scans=20):
    omega = n_g * G0 / speed
    k = np.arange(scans + 1) * T
    pos = np.stack([speed / omega * np.sin(omega * k), speed / omega * (1 - np.cos(omega * k)), np.full_like(k, 6000.0)], 1)
    vel = np.stack([speed * np.cos(omega * k), speed * np.sin(omega * k), np.zeros_like(k)], 1)
    acc = np.stack([-speed * omega * np.sin(omega * k), speed * omega * np.cos(omega * k), np.zeros_like(k)], 1)
    return pos, vel, acc


def test_mean_jerk_input_improves_the_prediction_of_a_turn():
    pos, vel, acc = coordinated_turn()
    x = np.zeros((1, 9))
    x[0, POS], x[0, VEL], x[0, ACC] = pos[0], vel[0], acc[0]
    P = np.diag(np.tile([100.0, 10.0, 1.0], 3))[None]
    errors = {}
    for jerk in (True, False):
        filt = BergFullFilter(SPEC_CHANNELS, mean_jerk=jerk)
        filt.recorder = ListRecorder()
        pred = filt.predict(filt.initiate(x, P), np.full(1, 2.0))
        truth = coordinated_turn(T=2.0, scans=1)
        errors[jerk] = np.linalg.norm(pred.x[0, POS] - truth[0][1])
        j_f = filt.recorder.channel("mean_jerk")[0][1]["j_f"][0]
        assert (abs(j_f[0] + (5 * G0) ** 2 / 250.0) <= 1e-9) if jerk else np.array_equal(j_f, np.zeros(3))
    assert errors[True] < 0.3 * errors[False]  # 3.0 m vs 13.1 m; the rest is the decay e^(-T/tau_n)


def test_block_rotation_and_mean_jerk_flags_change_the_frame_filter_in_a_turn():
    pos, vel, acc = coordinated_turn(scans=15)
    rng = np.random.default_rng(6)
    x = np.zeros((1, 9))
    x[0, POS], x[0, VEL] = pos[0], vel[0]
    P = np.diag(np.tile([2500.0, 400.0, 400.0], 3))[None]
    R = (50.0**2 * np.eye(3))[None]
    z = pos[1:] + rng.normal(0, 50.0, (15, 3))
    results = {}
    for flags in ((True, True), (False, True), (True, False)):
        filt = BergFrameFilter(SPEC_CHANNELS, mean_jerk=flags[0], block_rotation=flags[1])
        results[flags] = run(filt, x, P, z, R).estimate()
    for other in ((False, True), (True, False)):
        assert rel_err(results[other].x, results[(True, True)].x) > 1e-6
        assert rel_err(results[other].P, results[(True, True)].P) > 1e-6


# ---------------------------------------------------------------------------- configuration
def test_channel_defaults_and_bad_configuration():
    assert build_filter("berg-frame", constant_acceleration(3, 1.0)).channels == SPEC_CHANNELS
    assert build_filter("berg-full", singer(3, 20.0, 3.0)).channels == ((20.0, 3.0),) * 3
    filt = build_filter("berg-frame", singer(3, 20.0, 3.0), tangential=(60, 3), normal=(15, 40), binormal=(30, 10),
                        block_rotation=False, mean_jerk=False)
    assert filt.channels == SPEC_CHANNELS and not filt.block_rotation and not filt.mean_jerk
    for kind in ("berg-full", "berg-frame"):
        with pytest.raises(ValueError, match="order"):
            build_filter(kind, constant_velocity(3, 1.0))
        with pytest.raises(ValueError, match="ndim=2"):
            build_filter(kind, constant_acceleration(2, 1.0))
        with pytest.raises(ValueError, match="tangential"):
            build_filter(kind, singer(3, 20.0, 3.0), tangential=(-1.0, 3.0))
        with pytest.raises(ValueError, match="binormal"):
            build_filter(kind, singer(3, 20.0, 3.0), binormal=(30.0,))
        with pytest.raises(ValueError, match="mean_jerk"):
            build_filter(kind, singer(3, 20.0, 3.0), mean_jerk="yes")
    with pytest.raises(ValueError, match="block_rotation"):
        build_filter("berg-frame", singer(3, 20.0, 3.0), block_rotation=1)
    doppler = ConvertedPositionModel(3, 3, range_rate_sigma=1.0)
    filt = build_filter("berg-frame", singer(3, 20.0, 3.0))
    state = filt.initiate(np.ones((1, 9)), np.eye(9)[None])
    context = {"R": np.eye(3)[None], "has_range_rate": np.array([False])}
    with pytest.raises(ValueError, match="ENU positions"):
        filt.innovate(state, np.zeros((1, 4)), doppler, context)
    assert math.isclose(SPEC_CHANNELS[1][1], 40.0)

"""Spec 004 §3.3 I / R11: the ellipsoidal set-membership filter (TV13, containment, E9's assert).

Tolerances: TV13's own (eta 1e-6 absolute, P 1e-6 relative; the predict numbers to 1e-10
relative), gain form = information form to 1e-12 relative, containment as quadratic forms
``<= 1 + 1e-9``.  Monte Carlo run r draws from ``default_rng(SeedSequence(seed).spawn(runs)[r])``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.core import linalg
from skytrack.filters.base import ListRecorder
from skytrack.filters.registry import build_filter
from skytrack.filters.set_membership import (
    G0,
    SetMembershipFilter,
    box_process_bound,
    constant_input_process_bound,
    minkowski_sum_bound,
    set_update,
    two_point_initial_set,
)
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_velocity, singer

F_TV = np.array([[1.0, 1.0], [0.0, 1.0]])
H_TV = np.array([[[1.0, 0.0]]])


def quadratic_form(points, centre, P):
    """``(p - c)^T P^-1 (p - c)`` for points ``[K, n]`` and one ellipsoid."""
    d = points - centre
    return np.einsum("ki,ki->k", d, np.linalg.solve(P, d.T).T)


def rel_err(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b))))


def tv13_filter(criterion="trace"):
    # one CV axis, a_max^2 = 1/2: the box bound 2 diag((a T^2/2)^2, (a T)^2) is TV13's Q_b = diag(0.25, 1) at T = 1
    return SetMembershipFilter(constant_velocity(1, 1.0), a_max=math.sqrt(0.5), r_bound_scale=1.0, criterion=criterion)


def tv13_update(criterion):
    filt = tv13_filter(criterion)
    filt.recorder = ListRecorder()
    state = filt.initiate(np.zeros((1, 2)), np.diag([4.0, 1.0])[None])
    z = np.array([[1.5]])
    innovation = filt.innovate(state, z, ConvertedPositionModel(1, 2), {"R": np.ones((1, 1, 1))})
    new, stats = filt.update(state, z, innovation)
    return new, stats, innovation


# ---------------------------------------------------------------------------- TV13 predict
def test_tv13_predict_trace_criterion():
    filt = tv13_filter()
    assert np.allclose(filt.process_bound_matrix(np.ones(1))[0], np.diag([0.25, 1.0]), rtol=0, atol=1e-15)
    pred = filt.predict(filt.initiate(np.zeros((1, 2)), np.diag([4.0, 1.0])[None]), np.ones(1))
    expected = np.array([[8.079899880443, 1.456435464588], [1.456435464588, 4.647325694608]])
    assert rel_err(pred.P[0], expected) <= 1e-10
    assert abs(np.trace(pred.P[0]) - 12.727225575052) <= 1e-9
    assert np.array_equal(pred.x, np.zeros((1, 2)))
    # p = sqrt(tr A / tr Q_b) = 2.190890230021 and the trace is larger at 0.9 p and 1.1 p
    A = F_TV @ np.diag([4.0, 1.0]) @ F_TV.T
    Qb = np.diag([0.25, 1.0])
    p = math.sqrt(np.trace(A) / np.trace(Qb))
    assert abs(p - 2.190890230021) <= 1e-11
    assert rel_err(pred.P[0], (1 + 1 / p) * A + (1 + p) * Qb) <= 1e-13
    for factor in (0.9, 1.1):
        q = factor * p
        assert np.trace((1 + 1 / q) * A + (1 + q) * Qb) > np.trace(pred.P[0])


def test_det_criterion_predict_minimises_log_det_also_for_singular_bound():
    rng = np.random.default_rng(11)
    M = rng.standard_normal((3, 4, 4))
    A = M @ np.swapaxes(M, -1, -2) + 0.1 * np.eye(4)
    B = np.stack([np.diag([0.25, 1.0, 0.5, 2.0]),
                  constant_input_process_bound(2.0, 3.0, 2)[0],  # singular (rank 2)
                  np.diag([1e-4, 1e-2, 1e-4, 1e-2])])
    P = minkowski_sum_bound(A, B, "det")
    grid = np.exp(np.linspace(-12.0, 12.0, 20001))
    for r in range(3):
        got = np.linalg.slogdet(P[r])[1]
        on_grid = [np.linalg.slogdet((1 + 1 / p) * A[r] + (1 + p) * B[r])[1] for p in grid]
        assert got <= min(on_grid) + 1e-9
        # and P is of the family (1 + 1/p) A + (1 + p) B: tr P = tr A + tr B + tr A / p + p tr B gives p
        a, b, c = np.trace(B[r]), np.trace(A[r]) + np.trace(B[r]) - np.trace(P[r]), np.trace(A[r])
        roots = np.roots([a, b, c]).real
        assert min(rel_err((1 + 1 / q) * A[r] + (1 + q) * B[r], P[r]) for q in roots if q > 0) <= 1e-9


def test_zero_bound_gives_the_propagated_set_exactly():
    A = np.diag([4.0, 1.0])[None]
    for criterion in ("trace", "det"):
        assert np.array_equal(minkowski_sum_bound(A, np.zeros((1, 2, 2)), criterion), A)


# ---------------------------------------------------------------------------- TV13 update
@pytest.mark.parametrize("criterion,eta,delta,x0,P_diag", [
    ("trace", 0.362803473917, 0.249064311953, 1.042333834782, (1.438291401394, 1.178499344093)),
    ("det", 1.0 / 3.0, 0.25, 1.0, (1.5, 1.125)),
])
def test_tv13_update(criterion, eta, delta, x0, P_diag):
    new, stats, innovation = tv13_update(criterion)
    assert abs(stats.extra["eta"][0] - eta) <= 1e-6
    assert abs(stats.extra["delta"][0] - delta) <= 1e-6
    assert abs(new.x[0, 0] - x0) <= 1e-6 and abs(new.x[0, 1]) <= 1e-12
    assert rel_err(new.P[0], np.diag(P_diag)) <= 1e-6
    assert not stats.extra["violation"][0] and new.violations[0] == 0
    # the consistency statistic d^2 = max_eta delta(eta) (here 0.25 at eta = 1/3) and S = W(eta)
    etas = np.linspace(1e-4, 1 - 1e-4, 99999)
    deltas = 2.25 * etas * (1 - etas) / (1 + 3 * etas)
    assert abs(innovation.d2[0] - deltas.max()) <= 1e-9
    assert abs(innovation.d2[0] - innovation.nu[0, 0] ** 2 / innovation.S[0, 0, 0]) <= 1e-12


def test_tv13_fixed_eta():
    x, P, delta = set_update(np.zeros((1, 2)), np.diag([4.0, 1.0])[None], H_TV, np.ones((1, 1, 1)),
                             np.array([[1.5]]), 0.5)
    assert rel_err(x[0], [1.2, 0.0]) <= 1e-12
    assert rel_err(P[0], np.diag([1.24, 1.55])) <= 1e-12
    assert abs(delta[0] - 0.225) <= 1e-12


def information_form(x, P, H, R, z, eta):
    """§3.3 I's information form: A_eta = (1-eta) P^-1 + eta H^T R^-1 H, centre, P = (1 - delta) A_eta^-1."""
    Pi, Ri = np.linalg.inv(P), np.linalg.inv(R)
    A_eta = (1 - eta) * Pi + eta * H.T @ Ri @ H
    centre = np.linalg.solve(A_eta, (1 - eta) * Pi @ x + eta * H.T @ Ri @ z)
    nu = z - H @ x
    W = H @ P @ H.T / (1 - eta) + R / eta
    delta = nu @ np.linalg.solve(W, nu)
    return centre, (1 - delta) * np.linalg.inv(A_eta)


def test_gain_form_equals_information_form():
    rng = np.random.default_rng(5)
    cases = 0
    for n, m in ((2, 1), (4, 2), (6, 3)):
        for eta in (0.05, 0.3, 0.5, 0.9):
            M = rng.standard_normal((n, n))
            P = M @ M.T + np.eye(n)
            N = rng.standard_normal((m, m))
            R = N @ N.T + 0.5 * np.eye(m)
            H = np.zeros((m, n))
            H[np.arange(m), np.arange(m) * (n // m)] = 1.0
            x = rng.standard_normal(n)
            z = H @ x + 0.3 * rng.standard_normal(m)
            gx, gP, _ = set_update(x[None], P[None], H[None], R[None], (z - H @ x)[None], eta)
            ix, iP = information_form(x, P, H, R, z, eta)
            assert rel_err(gx[0], ix) <= 1e-12
            assert rel_err(gP[0], iP) <= 1e-12
            cases += 1
    assert cases == 12


@pytest.mark.parametrize("criterion", ["trace", "det", "fixed"])
def test_tv13_containment_of_the_intersection(criterion):
    """Every sampled point of E(x^-, P^-) with |z - x_1| <= 1 (boundary included) lies in E(x, P)."""
    if criterion == "fixed":
        x, P, _ = set_update(np.zeros((1, 2)), np.diag([4.0, 1.0])[None], H_TV, np.ones((1, 1, 1)), np.array([[1.5]]), 0.5)
        x, P = x[0], P[0]
    else:
        new, _, _ = tv13_update(criterion)
        x, P = new.x[0], new.P[0]
    rng = np.random.default_rng(13)
    angle = rng.uniform(0, 2 * np.pi, 200000)
    radius = np.sqrt(rng.uniform(0, 1, 200000))
    radius[:50000] = 1.0  # on the boundary of E(x^-, P^-)
    points = np.stack([2.0 * radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    # points on the measurement strip's edge x_1 = 0.5 inside E(x^-, P^-) (the other edge, 2.5, is outside it)
    edge = np.stack([np.full(10000, 0.5), rng.uniform(-1, 1, 10000) * math.sqrt(1 - 0.5**2 / 4)], axis=1)
    points = np.concatenate([points, edge])
    inside = np.abs(1.5 - points[:, 0]) <= 1.0
    assert inside.sum() > 80000
    assert quadratic_form(points[inside], x, P).max() <= 1.0 + 1e-12


# ---------------------------------------------------------------------------- violations
def test_bound_violation_is_counted_and_p_inflated_by_the_smallest_factor():
    filt = tv13_filter()
    filt.recorder = ListRecorder()
    state = filt.initiate(np.zeros((2, 2)), np.broadcast_to(np.diag([4.0, 1.0]), (2, 2, 2)).copy())
    z = np.array([[1.5], [10.0]])  # |nu| = 10 > 2 + 1: the second row's sets do not intersect
    model = ConvertedPositionModel(1, 2)
    R = np.ones((2, 1, 1))
    innovation = filt.innovate(state, z, model, {"R": R})
    assert innovation.d2[0] < 1.0 <= innovation.d2[1]
    new, stats = filt.update(state, z, innovation)
    assert list(new.violations) == [0, 1]
    assert list(stats.extra["violation"]) == [False, True]
    s = stats.extra["inflation"][1]
    # 1-D: the intersection is empty iff |nu| > sqrt(s P_11) + sqrt(R): s* = ((10 - 1) / 2)^2
    assert abs(s - 20.25) <= 20.25 * 1e-8 and s >= 20.25
    assert stats.extra["delta"][1] < 1.0
    events = filt.recorder.channel("bound_violation")
    assert len(events) == 1 and list(events[0][0]) == [1]
    # the counter is carried by predict and a consistent scan does not add to it
    pred = filt.predict(new, np.ones(2))
    assert list(pred.violations) == [0, 1]
    z_next = pred.x[:, :1]
    again, _ = filt.update(pred, z_next, filt.innovate(pred, z_next, model, {"R": R}))
    assert list(again.violations) == [0, 1]


def test_consistency_statistic_is_the_maximum_of_delta_over_eta():
    rng = np.random.default_rng(21)
    rows, n, m = 4, 6, 3
    M = rng.standard_normal((rows, n, n))
    P = M @ np.swapaxes(M, -1, -2) + np.eye(n)
    N = rng.standard_normal((rows, m, m))
    R = N @ np.swapaxes(N, -1, -2) + 0.5 * np.eye(m)
    filt = SetMembershipFilter(constant_velocity(3, 1.0), r_bound_scale=1.0)
    state = filt.initiate(rng.standard_normal((rows, n)), P)
    model = ConvertedPositionModel(3, 2)
    z = state.x[:, model.position_index] + 2.0 * rng.standard_normal((rows, m))
    innovation = filt.innovate(state, z, model, {"R": R})
    H = np.broadcast_to(innovation.H[0], (rows, m, n))
    grid = [set_update(state.x, P, H, R, innovation.nu, eta)[2] for eta in np.linspace(1e-3, 1 - 1e-3, 2999)]
    best = np.max(grid, axis=0)
    assert np.all(innovation.d2 >= best - 1e-12) and np.all(innovation.d2 <= best * (1 + 1e-5))
    assert rel_err(innovation.d2, linalg.mahalanobis_chol(innovation.nu, np.linalg.cholesky(innovation.S))) <= 1e-12


# ---------------------------------------------------------------------------- helpers
def test_box_bound_contains_every_bounded_acceleration_increment():
    """Increments of per-axis accelerations |a_i(t)| <= a_max (piecewise constant on 40 sub-steps,
    random and bang-bang) lie in E(0, Q_b); the all-a_max profile reaches a corner of the box, on the boundary."""
    T, a_max, ndim, sub = 1.7, 7 * G0, 3, 40
    Qb = box_process_bound(T, a_max, ndim)[0]
    assert rel_err(np.diag(Qb), 6 * np.tile([(a_max * T**2 / 2) ** 2, (a_max * T) ** 2], ndim)) <= 1e-15
    rng = np.random.default_rng(3)
    tau = T / sub
    start = np.arange(sub) * tau
    weights_p = tau * (T - start - tau / 2)  # int over a sub-step of (T - s) ds
    profiles = np.concatenate([rng.uniform(-1, 1, (4000, ndim, sub)),
                               rng.choice([-1.0, 1.0], (4000, ndim, sub)),
                               np.sign(rng.standard_normal((2000, ndim, 1))) * np.ones((1, 1, sub))]) * a_max
    dp = profiles @ weights_p
    dv = profiles.sum(axis=-1) * tau
    w = np.stack([dp, dv], axis=-1).reshape(len(profiles), 2 * ndim)
    q = quadratic_form(w, np.zeros(2 * ndim), Qb)
    assert q.max() <= 1.0 + 1e-12
    assert q.max() >= 1.0 - 1e-12  # the constant +-a_max profiles hit the corners


def test_constant_input_bound():
    Qb = constant_input_process_bound(np.array([2.0]), 3.0, 3)[0]
    block = 9.0 * np.outer([2.0, 2.0], [2.0, 2.0])  # g = [T^2/2, T] = [2, 2]
    assert np.array_equal(Qb, np.kron(np.eye(3), block))
    assert np.linalg.matrix_rank(Qb) == 3


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_two_point_initial_set_contains_the_truth(criterion):
    rng = np.random.default_rng(8)
    rows, T = 3000, 2.0
    L = np.linalg.cholesky(np.array([[1e4, 3e3, 0.0], [3e3, 2e4, 1e3], [0.0, 1e3, 5e3]]))
    R_b = np.broadcast_to(L @ L.T, (rows, 3, 3))
    u = rng.standard_normal((2, rows, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    u[:, 1000:] *= rng.uniform(0, 1, (2, rows - 1000, 1)) ** (1 / 3)  # first 1000: on the boundary
    v0, v1 = u[0] @ L.T, u[1] @ L.T
    p0 = rng.uniform(-5e4, 5e4, (rows, 3))
    vel = rng.normal(0, 200, (rows, 3))
    p1 = p0 + vel * T
    x, P = two_point_initial_set(p0 + v0, p1 + v1, T, R_b, criterion=criterion)
    assert rel_err(x[:, 0::2], p1 + v1) <= 1e-15
    assert rel_err(x[:, 1::2], (p1 + v1 - p0 - v0) / T) <= 1e-12
    truth = np.empty((rows, 6))
    truth[:, 0::2], truth[:, 1::2] = p1, vel
    d = truth - x
    q = np.einsum("ki,ki->k", d, np.linalg.solve(P, d[..., None])[..., 0])
    assert q.max() <= 1.0 + 1e-9


# ---------------------------------------------------------------------------- E9's assert
def turn_truth(times, t_turn_start, n_g, speed=250.0, p0=(-10000.0, 40000.0, 6000.0)):
    """Straight east, a left coordinated turn of n g through 180 deg from ``t_turn_start``, then straight west."""
    omega = n_g * G0 / speed
    t_end = t_turn_start + math.pi / omega
    pos = np.empty((len(times), 3))
    vel = np.empty((len(times), 3))
    p1 = np.array(p0) + np.array([speed * t_turn_start, 0.0, 0.0])
    centre = p1 + np.array([0.0, speed / omega, 0.0])
    for k, t in enumerate(times):
        if t <= t_turn_start:
            pos[k] = np.array(p0) + np.array([speed * t, 0.0, 0.0])
            vel[k] = (speed, 0.0, 0.0)
        elif t <= t_end:
            a = omega * (t - t_turn_start)
            pos[k] = centre + speed / omega * np.array([math.sin(a), -math.cos(a), 0.0])
            vel[k] = speed * np.array([math.cos(a), math.sin(a), 0.0])
        else:
            pos[k] = centre + np.array([0.0, speed / omega, 0.0]) + np.array([-speed * (t - t_end), 0.0, 0.0])
            vel[k] = (-speed, 0.0, 0.0)
    return pos, vel


def run_e9(criterion, n_g, a_max, runs=40, seed=9, T=1.0):
    """E9 case (a): CV set-membership filter with the box bound of ``a_max``, R_b = (100 m)^2 I, errors
    uniform inside E(0, R_b), two-point initial set at scans 0, 1; returns the largest quadratic form of
    the truth in E(x, P) over runs and scans, the violation counters and the number of scans."""
    times = np.arange(0.0, 40.0 + math.pi * 250.0 / (n_g * G0) + 20.0, T)
    pos, vel = turn_truth(times, 40.0, n_g)
    R_b = np.broadcast_to(1e4 * np.eye(3), (runs, 3, 3)).copy()
    errors = []
    for seq in np.random.SeedSequence(seed).spawn(runs):
        g = np.random.default_rng(seq)
        direction = g.standard_normal((len(times), 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        errors.append(100.0 * direction * g.uniform(0, 1, (len(times), 1)) ** (1 / 3))
    z = pos[None] + np.array(errors)
    filt = build_filter("set-membership", constant_velocity(3, 1.0), a_max=a_max, r_bound_scale=1.0, criterion=criterion)
    model = ConvertedPositionModel(3, 2)
    x, P = two_point_initial_set(z[:, 0], z[:, 1], T, R_b)
    state = filt.initiate(x, P)
    worst, scans = 0.0, 0
    for k in range(2, len(times)):
        state = filt.predict(state, np.full(runs, T))
        innovation = filt.innovate(state, z[:, k], model, {"R": R_b})
        state, _ = filt.update(state, z[:, k], innovation)
        truth = np.empty((runs, 6))
        truth[:, 0::2], truth[:, 1::2] = pos[k], vel[k]
        d = truth - state.x
        q = np.einsum("ki,ki->k", d, np.linalg.solve(state.P, d[..., None])[..., 0])
        worst = max(worst, float(q.max()))
        scans += 1
    assert scans == len(times) - 2
    return worst, state.violations, scans


@pytest.mark.parametrize("criterion,n_g", [("trace", 5), ("trace", 7), ("det", 7)])
def test_e9_truth_always_inside_with_bounded_errors_and_accelerations(criterion, n_g):
    """Turns of n <= 7 g under the a_max = 7 g0 bound: truth inside E(x, P) on every scan of every run
    (quadratic form <= 1 + 1e-9) and no bound violation (spec 004 §6 E9's assert)."""
    worst, violations, scans = run_e9(criterion, n_g, 7 * G0)
    assert scans >= 70
    assert worst <= 1.0 + 1e-9
    assert np.all(violations == 0)


def test_e9_bound_below_the_manoeuvre_is_violated():
    """The same 7 g turn with a bound of 1 g0: violations are counted and containment is lost (the
    containment check above can fail)."""
    worst, violations, _ = run_e9("trace", 7, 1 * G0)
    assert np.mean(violations > 0) > 0.5
    assert worst > 1.0


# ---------------------------------------------------------------------------- configuration
def test_registered_kind_and_bad_configuration():
    filt = build_filter("set-membership", constant_velocity(2, 1.0), criterion="det", process_bound="constant")
    assert isinstance(filt, SetMembershipFilter) and filt.capabilities.estimate == "set"
    assert not filt.capabilities.has_covariance
    for options, name in (({"criterion": "volume"}, "criterion"), ({"process_bound": "ball"}, "process_bound"),
                          ({"a_max": -1.0}, "a_max"), ({"r_bound_scale": 0.0}, "r_bound_scale")):
        with pytest.raises(ValueError, match=name):
            build_filter("set-membership", constant_velocity(3, 1.0), **options)
    with pytest.raises(ValueError, match="order 2"):
        build_filter("set-membership", singer(3, 20.0, 3.0))
    with pytest.raises(ValueError, match="eta"):
        set_update(np.zeros((1, 2)), np.eye(2)[None], H_TV, np.ones((1, 1, 1)), np.ones((1, 1)), 1.0)

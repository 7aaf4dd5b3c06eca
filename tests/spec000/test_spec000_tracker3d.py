"""Spec 000 R8, R9, R10 (3-D), R13 (3-D) and TV10, TV11: the 3-D polar-radar Singer EKF."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from skytrack.association.gate import gate_threshold, gate_volume
from skytrack.filters import SingerFilter1D, SingerParams, SingerTracker3D, innovation_covariance
from skytrack.geo import Origin, Sensor, SensorSet, polar_to_cartesian
from skytrack.models import PolarMeasurementModel, SingerAxisModel

DEG = math.pi / 180
TV10_STATE = np.array([30000, -150, 0.5, 40000, 100, -0.2, 9000, 2, 0], dtype=float)
TV10_BLOCK = np.array([[2500.0, 100.0, 1.0], [100.0, 100.0, 2.0], [1.0, 2.0, 1.0]])
TV10_SIGMAS = dict(r=50.0, az=0.15 * DEG, el=0.3 * DEG, rdot=1.0)
TV10_REPORT = dict(r=50900.0, az=0.6450, el=0.1790, rdot=-12.0)


def block_diag3(block):
    P = np.zeros((9, 9))
    for a in range(3):
        P[3 * a:3 * a + 3, 3 * a:3 * a + 3] = block
    return P


def models(disc="exact", params=((60.0, 1.0), (60.0, 1.0), (60.0, 1.0))):
    return [SingerAxisModel(tau, sa, disc) for tau, sa in params]


def tv10_tracker(form="joseph"):
    trk = SingerTracker3D(models(), sigmas=TV10_SIGMAS, use_range_rate=True, update_form=form)
    trk.set_state(TV10_STATE, block_diag3(TV10_BLOCK))
    return trk


def test_tv10_measurement_function_and_jacobian():
    inn = tv10_tracker().innovation(TV10_REPORT)
    assert inn.components == ("r", "az", "el", "rdot")
    np.testing.assert_allclose(inn.h, [50803.543184, 0.64350110879, 0.17809293823, -9.4875272431], rtol=1e-10)
    H = inn.H
    np.testing.assert_allclose(H[0, [0, 3, 6]], [0.59050999438, 0.78734665918, 0.17715299832], rtol=1e-10)
    np.testing.assert_allclose(H[1, [0, 3]], [1.6e-5, -1.2e-5], rtol=1e-10)
    np.testing.assert_allclose(H[2, [0, 3, 6]], [-2.0922123208e-6, -2.7896164277e-6, 1.9372336304e-5], rtol=1e-9)
    np.testing.assert_allclose(H[3, [0, 1, 3, 4, 6, 7]], [-2.8422726309e-3, 0.59050999438, 2.1154031027e-3, 0.78734665918,
                                                        7.2450535279e-5, 0.17715299832], rtol=1e-9)
    nonzero = {0: [0, 3, 6], 1: [0, 3], 2: [0, 3, 6], 3: [0, 1, 3, 4, 6, 7]}
    for row, cols in nonzero.items():
        mask = np.ones(9, bool)
        mask[cols] = False
        assert np.all(H[row, mask] == 0)


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_tv10_innovation_gate_and_update(form):
    trk = tv10_tracker(form)
    inn = trk.innovation(TV10_REPORT)
    np.testing.assert_allclose(inn.nu, [96.456816478, 1.4988912067e-3, 9.0706176880e-4, -2.5124727569], rtol=1e-9)
    S = inn.S
    expected = {(0, 0): 5000, (1, 1): 7.8538919452e-6, (2, 2): 2.8384184596e-5, (3, 3): 101.03139673, (0, 3): 100,
                (1, 3): -1.7715299832e-4, (2, 3): 3.6225267639e-6}
    for (i, j), value in expected.items():
        assert S[i, j] == pytest.approx(value, rel=1e-9)
        assert S[j, i] == S[i, j]
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert abs(S[i, j]) <= 1e-12 * math.sqrt(S[i, i] * S[j, j])
    assert inn.d2 == pytest.approx(2.372034389568844, rel=1e-9)
    assert gate_threshold(4) == pytest.approx(13.276704135987622, rel=1e-14)
    assert gate_volume(S, gate_threshold(4)) == pytest.approx(9.1388945882, rel=1e-9)
    trk.update(TV10_REPORT)
    state = [30034.907941, -151.12702595, 0.46244491140, 40030.066558, 97.838204187, -0.25666439700, 9009.6894321,
             1.6305742027, -0.011579706719]
    diag = [1853.9449962, 65.446201299, 0.98615125591, 1589.2677280, 38.164852574, 0.97525744875, 2377.3114501,
            96.758918872, 0.99873757562]
    np.testing.assert_allclose(trk.x, state, rtol=1e-8)
    np.testing.assert_allclose(np.diag(trk.P), diag, rtol=1e-8)
    np.testing.assert_array_equal(trk.P, trk.P.T)


def test_tv10_information_form_cross_check():
    trk = tv10_tracker()
    inn = trk.innovation(TV10_REPORT)
    P0 = block_diag3(TV10_BLOCK)
    P_info = np.linalg.inv(np.linalg.inv(P0) + inn.H.T @ np.linalg.inv(inn.R) @ inn.H)
    trk.update(TV10_REPORT)
    assert np.max(np.abs(trk.P - P_info)) <= 1e-8 * np.max(np.abs(P_info))


def test_tv10_position_only_gate():
    pm = PolarMeasurementModel(("r", "az"), (50.0, 0.15 * DEG))
    _, H = pm.evaluate(TV10_STATE[None])
    S = innovation_covariance(block_diag3(TV10_BLOCK)[None], H, pm.R)[0]
    np.testing.assert_allclose(np.diag(S), [5000, 7.8538919452e-6], rtol=1e-9)
    assert abs(S[0, 1]) <= 1e-12 * math.sqrt(S[0, 0] * S[1, 1])
    assert gate_volume(S, gate_threshold(2)) == pytest.approx(5.7339383056, rel=1e-9)


def test_tv11_azimuth_wrap():
    trk = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.15 * DEG, z_alt=100.0))
    trk.set_state([-10, 0, 0, 10000, 0, 0, 0, 0, 0], np.eye(9))
    inn = trk.innovation(dict(r=10000.0, az=0.1 * DEG, z_alt=0.0))
    assert inn.h[1] == pytest.approx(6.2821853075, rel=1e-10)
    assert math.degrees(inn.h[1]) == pytest.approx(359.9427042, rel=1e-9)
    assert math.degrees(inn.nu[1]) == pytest.approx(0.1572957604, rel=1e-9)


# --------------------------------------------------------------------------- R8 Jacobians


def rotated_sensor():
    sensors = SensorSet(
        origin=Origin(lat=48.0, lon=11.0, alt_m=500.0),
        sensors=[Sensor(name="psr", type="radar-3d", x=2500.0, y=-4000.0, z=35.0, north_offset_deg=7.5,
                        sigma_range_m=60.0, sigma_azimuth_deg=0.2, sigma_elevation_deg=0.35, sigma_range_rate_mps=1.5)],
    )
    return sensors["psr"]


SUBSETS = [
    ("r", "az", "el", "rdot"),
    ("r", "az", "el"),
    ("r", "az", "z_alt"),
    ("r", "az", "rdot", "z_alt"),
    ("az", "el"),
    ("r", "rdot", "x", "y", "z"),
    ("x", "y", "z"),
    ("z_alt", "x", "y", "z"),
]


@pytest.mark.parametrize("components", SUBSETS)
@pytest.mark.parametrize("with_sensor", [False, True])
def test_r8_analytic_jacobians_match_central_differences(components, with_sensor):
    rng = np.random.default_rng(SUBSETS.index(components))
    sensor = rotated_sensor() if with_sensor else None
    sigmas = dict(z_alt=30.0, x=20.0, y=20.0, z=20.0, **({} if with_sensor else dict(r=50.0, az=0.01, el=0.01, rdot=1.0)))
    trk = SingerTracker3D(models(), sensor, sigmas=sigmas, use_range_rate=True)
    report = {c: 0.0 for c in components}
    if "r" in report:
        report["r"] = 1e4
    for _ in range(5):
        x = np.array([rng.uniform(-6e4, 6e4), rng.uniform(-300, 300), rng.uniform(-3, 3),
                      rng.uniform(-6e4, 6e4), rng.uniform(-300, 300), rng.uniform(-3, 3),
                      rng.uniform(500, 1.2e4), rng.uniform(-20, 20), rng.uniform(-1, 1)])
        trk.set_state(x, np.eye(9))
        inn = trk.innovation(report)
        H = inn.H
        H_fd = np.zeros_like(H)
        for j in range(9):
            step = 1e-3 * max(1.0, abs(x[j])) * 1e-2
            xp, xm = x.copy(), x.copy()
            xp[j] += step
            xm[j] -= step
            trk.set_state(xp, np.eye(9))
            hp = trk.innovation(report).h
            trk.set_state(xm, np.eye(9))
            hm = trk.innovation(report).h
            diff = hp - hm
            diff[inn.angular] = (diff[inn.angular] + math.pi) % (2 * math.pi) - math.pi
            H_fd[:, j] = diff / (2 * step)
        scale = np.maximum(np.abs(H_fd), 1e-6 * np.max(np.abs(H_fd), axis=1, keepdims=True))
        assert np.all(np.abs(H - H_fd) <= 1e-6 * scale), (components, np.max(np.abs(H - H_fd) / scale))


# --------------------------------------------------------------------------- R8 decoupling


@pytest.mark.parametrize("form", ["joseph", "standard"])
def test_r8_cartesian_tracker_equals_three_1d_filters(form):
    params = ((60.0, 1.0), (20.0, 3.0), (120.0, 0.3))
    sig = (40.0, 55.0, 70.0)
    trk = SingerTracker3D(models("exact", params), sigmas=dict(x=sig[0], y=sig[1], z=sig[2]), update_form=form)
    rng = np.random.default_rng(8)
    blocks = []
    for a in range(3):
        A = rng.standard_normal((3, 3)) * np.array([50.0, 5.0, 0.5])[:, None]
        blocks.append(A @ A.T + np.diag([100.0, 1.0, 0.01]))
    x0 = np.array([1000.0, 150.0, 0.0, -2000.0, 80.0, 0.1, 9000.0, 0.0, 0.0])
    P0 = np.zeros((9, 9))
    for a in range(3):
        P0[3 * a:3 * a + 3, 3 * a:3 * a + 3] = blocks[a]
    trk.set_state(x0, P0)
    filters = [SingerFilter1D(SingerAxisModel(tau, sa, "exact"), sig[a], update_form=form, m0=x0[3 * a:3 * a + 3], P0=blocks[a])
               for a, (tau, sa) in enumerate(params)]
    for n in range(80):
        dt = float(rng.choice([4.0, 5.0, 10.0]))
        detected = bool(rng.random() < 0.75)
        z = x0[[0, 3, 6]] + np.array([150.0, 80.0, 0.0]) * 5 * n + rng.normal(0, 60.0, 3)
        trk.step(dict(x=z[0], y=z[1], z=z[2]) if detected else None, dt)
        for a in range(3):
            filters[a].step(z[a], detected, dt)
    for a in range(3):
        block = slice(3 * a, 3 * a + 3)
        assert np.max(np.abs(trk.x[block] - filters[a].m)) <= 1e-9 * np.max(np.abs(filters[a].m))
        assert np.max(np.abs(trk.P[block, block] - filters[a].P)) <= 1e-9 * np.max(np.abs(filters[a].P))
    off = np.ones((9, 9), bool)
    for a in range(3):
        off[3 * a:3 * a + 3, 3 * a:3 * a + 3] = False
    assert np.max(np.abs(trk.P[off])) <= 1e-9 * np.max(np.abs(trk.P))


# --------------------------------------------------------------------------- R8/R9 component handling


def test_r8_altitude_is_required_or_injected():
    base = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002, z_alt=100.0))
    base.set_state(TV10_STATE, block_diag3(TV10_BLOCK))
    with pytest.raises(ValueError, match="assumed_altitude"):
        base.innovation(dict(r=50800.0, az=0.644))
    injected = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002), assumed_altitude=(8800.0, 400.0))
    injected.set_state(TV10_STATE, block_diag3(TV10_BLOCK))
    inn = injected.innovation(dict(r=50800.0, az=0.644))
    assert inn.components == ("r", "az", "z_alt")
    assert inn.z[2] == 8800.0 and inn.R[2, 2] == 400.0**2
    explicit = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002, z_alt=400.0))
    explicit.set_state(TV10_STATE, block_diag3(TV10_BLOCK))
    injected.update(dict(r=50800.0, az=0.644))
    explicit.update(dict(r=50800.0, az=0.644, z_alt=8800.0))
    np.testing.assert_array_equal(injected.x, explicit.x)
    np.testing.assert_array_equal(injected.P, explicit.P)
    # elevation or a Cartesian position make the altitude unnecessary
    assert base.innovation(dict(r=50800.0, az=0.644, z_alt=9100.0)).components == ("r", "az", "z_alt")


def test_r8_refuses_updates_close_to_the_radar():
    trk = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002, el=0.004))
    trk.set_state([0.3, 0, 0, 0.4, 0, 0, 0.2, 0, 0], np.eye(9))
    with pytest.raises(ValueError, match="refused"):
        trk.update(dict(r=0.6, az=0.6, el=0.3))
    trk.set_state([0.3, 0, 0, 0.4, 0, 0, 5000.0, 0, 0], np.eye(9))  # overhead: horizontal range 0.5 m
    with pytest.raises(ValueError, match="refused"):
        trk.update(dict(r=5000.0, az=0.6, el=1.5))
    trk.set_state(TV10_STATE, np.eye(9))
    with pytest.raises(ValueError, match="refused"):
        trk.update(dict(r=0.5, az=0.6, el=0.2))


@pytest.mark.parametrize("bad", [dict(r=math.nan, az=0.6, el=0.2), dict(r=5e4, az=math.inf, el=0.2),
                                 dict(r=5e4, az=0.6, el=0.2, range=3.0), dict(x=1.0, y=2.0)])
def test_r16_bad_reports_are_rejected(bad):
    trk = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002, el=0.004, x=10.0, y=10.0, z=10.0))
    trk.set_state(TV10_STATE, np.eye(9))
    with pytest.raises(ValueError):
        trk.update(bad)


def test_r8_missing_sigma_is_an_error():
    trk = SingerTracker3D(models(), sigmas=dict(r=50.0, az=0.002))
    trk.set_state(TV10_STATE, np.eye(9))
    with pytest.raises(ValueError, match="'el'"):
        trk.update(dict(r=5e4, az=0.6, el=0.2))


def test_r9_range_rate_variants_and_gate_dimension():
    report = dict(TV10_REPORT)
    pos_only = SingerTracker3D(models(), sigmas=TV10_SIGMAS, use_range_rate=False)
    pos_only.set_state(TV10_STATE, block_diag3(TV10_BLOCK))
    inn = pos_only.innovation(report)
    assert inn.components == ("r", "az", "el") and inn.S.shape == (3, 3)
    with_rdot = tv10_tracker()
    assert with_rdot.innovation(report).S.shape == (4, 4)
    no_rdot = {k: v for k, v in report.items() if k != "rdot"}
    inn2 = with_rdot.innovation(no_rdot)
    assert inn2.components == ("r", "az", "el")
    np.testing.assert_array_equal(inn2.S, inn.S)
    assert gate_threshold(len(inn2.components)) == pytest.approx(11.344866730144373, rel=1e-14)


def test_r8_sensor_sigmas_and_frame():
    sensor = rotated_sensor()
    trk = SingerTracker3D(models(), sensor, use_range_rate=True)
    assert trk.sigmas["r"] == 60.0 and trk.sigmas["az"] == pytest.approx(0.2 * DEG)
    assert trk.sigmas["el"] == pytest.approx(0.35 * DEG) and trk.sigmas["rdot"] == 1.5
    target = np.array([20000.0, 30000.0, 7000.0])
    trk.set_state([target[0], 0, 0, target[1], 0, 0, target[2], 0, 0], np.eye(9))
    local = sensor.to_local(target)
    inn = trk.innovation(dict(r=1e4, az=0.0, el=0.0))
    assert inn.h[0] == pytest.approx(np.linalg.norm(local), rel=1e-14)
    assert inn.h[1] == pytest.approx(math.atan2(local[0], local[1]) % (2 * math.pi), rel=1e-14)
    assert inn.h[2] == pytest.approx(math.atan2(local[2], math.hypot(local[0], local[1])), rel=1e-14)


# --------------------------------------------------------------------------- R13, R10 in 3-D


def _numeric_jacobian(fun, params, steps):
    J = np.zeros((3, len(params)))
    for j in range(len(params)):
        p, m = np.array(params, float), np.array(params, float)
        p[j] += steps[j]
        m[j] -= steps[j]
        J[:, j] = (np.asarray(fun(p)) - np.asarray(fun(m))) / (2 * steps[j])
    return J


@pytest.mark.parametrize("with_sensor", [False, True])
def test_r13_single_plot_initialisation_polar(with_sensor):
    sensor = rotated_sensor() if with_sensor else None
    sig = dict(r=60.0, az=0.2 * DEG, el=0.35 * DEG)
    trk = SingerTracker3D(models("exact", ((60.0, 1.0), (60.0, 2.0), (60.0, 0.5))), sensor, sigmas=sig)
    plot = dict(r=42000.0, az=1.1, el=0.12)
    trk.initialize_from_report(plot, sigma_v0=150.0)
    rot = np.eye(3) if sensor is None else sensor.rotation
    pos0 = np.zeros(3) if sensor is None else sensor.position

    def to_common(p):
        return np.array(polar_to_cartesian(*p)) @ rot + pos0

    np.testing.assert_allclose(trk.x[[0, 3, 6]], to_common([42000.0, 1.1, 0.12]), rtol=1e-14, atol=1e-9)
    J = _numeric_jacobian(to_common, [42000.0, 1.1, 0.12], [1e-2, 1e-7, 1e-7])
    expected = J @ np.diag([sig["r"] ** 2, sig["az"] ** 2, sig["el"] ** 2]) @ J.T
    pos = np.array([0, 3, 6])
    np.testing.assert_allclose(trk.P[np.ix_(pos, pos)], expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    np.testing.assert_array_equal(trk.x[pos + 1], 0.0)
    np.testing.assert_array_equal(trk.x[pos + 2], 0.0)
    np.testing.assert_array_equal(np.diag(trk.P)[pos + 1], 150.0**2)
    np.testing.assert_array_equal(np.diag(trk.P)[pos + 2], [1.0, 4.0, 0.25])


def test_r13_single_plot_initialisation_with_altitude():
    sig = dict(r=60.0, az=0.2 * DEG, z_alt=80.0)
    trk = SingerTracker3D(models(), sigmas=sig)
    trk.initialize_from_report(dict(r=42000.0, az=1.1, z_alt=6000.0), sigma_v0=100.0)

    def to_enu(p):
        r, az, z = p
        el = math.asin(z / r)
        return np.array(polar_to_cartesian(r, az, el))

    np.testing.assert_allclose(trk.x[[0, 3, 6]], to_enu([42000.0, 1.1, 6000.0]), rtol=1e-13)
    assert trk.x[6] == pytest.approx(6000.0, rel=1e-13)
    J = _numeric_jacobian(to_enu, [42000.0, 1.1, 6000.0], [1e-2, 1e-7, 1e-2])
    expected = J @ np.diag([60.0**2, (0.2 * DEG) ** 2, 80.0**2]) @ J.T
    pos = np.array([0, 3, 6])
    np.testing.assert_allclose(trk.P[np.ix_(pos, pos)], expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    with pytest.raises(ValueError):
        SingerTracker3D(models(), sigmas=dict(r=60.0, az=0.003)).initialize_from_report(dict(r=4e4, az=1.0), sigma_v0=100.0)


def test_r10_per_axis_parameters_in_3d():
    trk = SingerTracker3D(models("exact"), sigmas=dict(x=10.0, y=10.0, z=10.0))
    trk.set_state(np.zeros(9), np.eye(9) * 100.0)
    p = (SingerParams(2.0, 20.0), SingerParams(1.0, 60.0), SingerParams(0.1, 300.0))
    F, Q = trk.transition(7.0, p)
    for a, params in enumerate(p):
        ax = SingerAxisModel(params.tau, params.sigma_a, "exact")
        block = slice(3 * a, 3 * a + 3)
        np.testing.assert_array_equal(F[block, block], ax.F(7.0))
        np.testing.assert_array_equal(Q[block, block], ax.Q(7.0))
    trk.step(dict(x=1.0, y=2.0, z=3.0), 7.0, params=p)
    trk.step(None, 7.0, params=SingerParams(3.0, 10.0))
    trk.step(None, 7.0)
    assert trk.history.params[0] == p
    assert trk.history.params[1] == (SingerParams(3.0, 10.0),) * 3
    assert trk.history.params[2] == (SingerParams(1.0, 60.0),) * 3
    assert trk.history.detected == [True, False, False]
    calls = []
    policy_trk = SingerTracker3D(models("exact"), sigmas=dict(x=10.0, y=10.0, z=10.0),
                                 coefficient_policy=lambda h: calls.append(len(h)) or SingerParams(2.0, 30.0))
    policy_trk.set_state(np.zeros(9), np.eye(9))
    for _ in range(3):
        policy_trk.step(None, 5.0)
    assert calls == [0, 1, 2]
    assert policy_trk.history.params[-1] == (SingerParams(2.0, 30.0),) * 3


def test_tracker_validation():
    with pytest.raises(ValueError):
        SingerTracker3D(models()[:2])
    with pytest.raises(ValueError):
        SingerTracker3D(models(), sigmas=dict(r=-1.0))
    with pytest.raises(ValueError):
        SingerTracker3D(models(), sigmas=dict(range=1.0))
    with pytest.raises(ValueError):
        SingerTracker3D(models(), assumed_altitude=(math.nan, 10.0))
    trk = SingerTracker3D(models(), sigmas=dict(x=1.0, y=1.0, z=1.0))
    with pytest.raises(ValueError, match="not initialised"):
        trk.step(None, 1.0)
    trk.set_state(np.zeros(9), np.eye(9))
    with pytest.raises(ValueError, match="dt"):
        trk.step(None, -1.0)
    with pytest.raises(ValueError):
        trk.set_state(np.full(9, math.nan), np.eye(9))
    stand_in = SimpleNamespace(position=np.zeros(3), rotation=np.eye(3))
    assert SingerTracker3D(models(), stand_in, sigmas=dict(r=1.0)).sigmas == {"r": 1.0}

"""Radar polar and Cartesian measurement models (skytrack.models.measurement)."""

import numpy as np
import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.models.measurement import (
    POLAR_COMPONENTS,
    CartesianPositionModel,
    PolarMeasurementModel,
    state_indices,
)

# ----------------------------------------------------------------------------- spec 000, TV10

TV10_STATE = np.array([30000.0, -150.0, 0.5, 40000.0, 100.0, -0.2, 9000.0, 2.0, 0.0])
TV10_SIGMAS = (50.0, np.radians(0.15), np.radians(0.3), 1.0)
# values are printed with 11 significant digits in the spec
RTOL = 5e-10


@pytest.fixture
def tv10():
    model = PolarMeasurementModel(("r", "az", "el", "rdot"), TV10_SIGMAS, order=3)
    h, H = model.evaluate(TV10_STATE)
    return model, h[0], H[0]


def test_tv10_predicted_measurement(tv10):
    _, h, _ = tv10
    np.testing.assert_allclose(h, [50803.543184, 0.64350110879, 0.17809293823, -9.4875272431], rtol=RTOL)


def test_tv10_jacobian_nonzero_entries(tv10):
    _, _, H = tv10
    x, vx, ax, y, vy, ay, z, vz, az = range(9)
    expected = np.zeros((4, 9))
    expected[0, [x, y, z]] = (0.59050999438, 0.78734665918, 0.17715299832)
    expected[1, [x, y]] = (1.6e-5, -1.2e-5)
    expected[2, [x, y, z]] = (-2.0922123208e-6, -2.7896164277e-6, 1.9372336304e-5)
    expected[3, [x, vx, y, vy, z, vz]] = (
        -2.8422726309e-3, 0.59050999438, 2.1154031027e-3, 0.78734665918, 7.2450535279e-5, 0.17715299832,
    )
    np.testing.assert_allclose(H, expected, rtol=RTOL, atol=0)


def test_tv10_innovation_covariance_and_distance(tv10):
    """S = H P H^T + R and d^2 with the spec's P (per-axis [[2500,100,1],[100,100,2],[1,2,1]])."""
    model, h, H = tv10
    block = np.array([[2500.0, 100.0, 1.0], [100.0, 100.0, 2.0], [1.0, 2.0, 1.0]])
    P = np.kron(np.eye(3), block)
    S = H @ P @ H.T + model.R
    for (i, j), value in {
        (0, 0): 5000.0, (1, 1): 7.8538919452e-6, (2, 2): 2.8384184596e-5, (3, 3): 101.03139673,
        (0, 3): 100.0, (1, 3): -1.7715299832e-4, (2, 3): 3.6225267639e-6,
    }.items():
        assert S[i, j] == pytest.approx(value, rel=RTOL)
    nu = np.array([50900.0, 0.6450, 0.1790, -12.0]) - h
    np.testing.assert_allclose(nu, [96.456816478, 1.4988912067e-3, 9.0706176880e-4, -2.5124727569], rtol=1e-9)
    assert nu @ np.linalg.solve(S, nu) == pytest.approx(2.372034389568844, rel=1e-9)


def test_tv11_azimuth_just_west_of_north():
    model = PolarMeasurementModel(("az",), (0.001,), order=2)
    h = model.evaluate(np.array([-10.0, 0.0, 10000.0, 0.0, 0.0, 0.0]), jacobian=False)
    assert h[0, 0] == pytest.approx(6.2821853075, rel=1e-10)


def test_predicted_azimuth_is_below_two_pi():
    model = PolarMeasurementModel(("az",), (0.001,), order=2)
    states = np.array([[-1e-12, 0.0, 1e4, 0.0, 0.0, 0.0], [-1e-13, 0.0, 5e4, 0.0, 0.0, 0.0]])
    h = model.evaluate(states, jacobian=False)
    assert np.all((h >= 0.0) & (h < 2 * np.pi))


# ----------------------------------------------------------------------------- finite differences


@pytest.fixture(scope="module")
def tilted_sensor():
    """A sensor 60 km from the origin: its frame is shifted and rotated (tilted and turned)."""
    sensor = Sensor("s", lat=49.2, lon=3.1, alt_m=120.0, sigma_range_m=1.0, sigma_azimuth_deg=0.1)
    SensorSet(Origin(48.86, 2.50, 0.0), [sensor])
    return sensor


def numeric_jacobian(model, states, step, **kwargs):
    n = states.shape[1]
    J = np.zeros((len(states), model.dim, n))
    for j in range(n):
        plus, minus = states.copy(), states.copy()
        plus[:, j] += step[j]
        minus[:, j] -= step[j]
        diff = model.evaluate(plus, jacobian=False, **kwargs) - model.evaluate(minus, jacobian=False, **kwargs)
        angular = model.angular
        diff[:, angular] = np.angle(np.exp(1j * diff[:, angular]))  # azimuth may wrap inside the step
        J[:, :, j] = diff / (2 * step[j])
    return J


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("moving", [False, True])
def test_polar_jacobian_matches_central_differences(tilted_sensor, order, moving):
    rng = np.random.default_rng(100 + order + 10 * moving)
    k = 64
    pos_idx, vel_idx = state_indices(3, order)
    states = np.zeros((k, 3 * order))
    states[:, pos_idx] = tilted_sensor.position + rng.uniform([-1.5e5, -1.5e5, 1e3], [1.5e5, 1.5e5, 1.2e4], (k, 3))
    states[:, vel_idx] = rng.uniform(-300, 300, (k, 3))
    if order == 3:
        states[:, pos_idx + 2] = rng.uniform(-20, 20, (k, 3))
    kwargs = dict(sensor_position=tilted_sensor.position, rotation=tilted_sensor.rotation)
    if moving:
        # an airborne sensor: its own position and velocity per pair
        kwargs["sensor_position"] = tilted_sensor.position + rng.uniform(-5e3, 5e3, (k, 3))
        kwargs["sensor_velocity"] = rng.uniform([100.0, -200.0, -5.0], [250.0, 200.0, 5.0], (k, 3))
    model = PolarMeasurementModel(POLAR_COMPONENTS, (40.0, 1e-3, 2e-3, 1.0, 30.0), order=order)
    h, H = model.evaluate(states, **kwargs)
    assert h.shape == (k, 5) and H.shape == (k, 5, 3 * order)
    step = np.ones(3 * order)  # 1 m, 1 m/s, 1 m/s^2: truncation (1 / 1e4 m)^2, rounding 1e-16 * 6 / 1
    J = numeric_jacobian(model, states, step, **kwargs)
    scale = np.linalg.norm(J, axis=2, keepdims=True)
    np.testing.assert_allclose(H / scale, J / scale, rtol=0, atol=1e-6)
    # the acceleration columns never enter
    if order == 3:
        assert not H[:, :, pos_idx + 2].any()


def test_polar_measurement_in_the_sensor_frame(tilted_sensor):
    """h is the polar form of the target relative to the sensor, in the sensor's own frame."""
    rng = np.random.default_rng(7)
    states = np.zeros((20, 6))
    states[:, [0, 2, 4]] = tilted_sensor.position + rng.uniform([-1e5, -1e5, 1e3], [1e5, 1e5, 1e4], (20, 3))
    states[:, [1, 3, 5]] = rng.uniform(-250, 250, (20, 3))
    v_s = np.array([100.0, 20.0, -1.0])
    model = PolarMeasurementModel(("r", "az", "el", "rdot", "z_alt"), (1.0, 1.0, 1.0, 1.0, 1.0), order=2)
    h = model.evaluate(states, sensor_position=tilted_sensor.position, rotation=tilted_sensor.rotation,
                       sensor_velocity=v_s, jacobian=False)
    local = tilted_sensor.to_local(states[:, [0, 2, 4]])
    rel_v = (states[:, [1, 3, 5]] - v_s) @ tilted_sensor.rotation.T
    r = np.linalg.norm(local, axis=1)
    np.testing.assert_allclose(h[:, 0], r, rtol=1e-14)
    np.testing.assert_allclose(h[:, 1], np.remainder(np.arctan2(local[:, 0], local[:, 1]), 2 * np.pi), rtol=1e-13)
    np.testing.assert_allclose(h[:, 2], np.arcsin(local[:, 2] / r), rtol=1e-12)
    np.testing.assert_allclose(h[:, 3], np.sum(local * rel_v, axis=1) / r, rtol=1e-12)
    np.testing.assert_array_equal(h[:, 4], states[:, 4])  # z_alt: the common-frame z


def test_moving_sensor_per_pair_positions():
    """Per-pair sensor positions and velocities: each row uses its own sensor state."""
    model = PolarMeasurementModel(("r", "rdot"), (1.0, 1.0), order=2)
    states = np.array([[1000.0, 10.0, 0.0, 0.0, 0.0, 0.0], [1000.0, 10.0, 0.0, 0.0, 0.0, 0.0]])
    p_s = np.array([[0.0, 0.0, 0.0], [400.0, 0.0, 0.0]])
    v_s = np.array([[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]])
    h = model.evaluate(states, sensor_position=p_s, sensor_velocity=v_s, jacobian=False)
    np.testing.assert_allclose(h, [[1000.0, 10.0], [600.0, -20.0]])


def test_polar_model_properties():
    model = PolarMeasurementModel(("r", "az", "rdot"), (40.0, 1e-3, 2.0), order=2)
    assert model.dim == 3
    np.testing.assert_allclose(model.R, np.diag([1600.0, 1e-6, 4.0]))
    np.testing.assert_array_equal(model.angular, [False, True, False])


@pytest.mark.parametrize(
    "components, sigmas, message",
    [
        (("az", "r"), (1.0, 1.0), "order"),
        (("r", "rdot", "el"), (1.0, 1.0, 1.0), "order"),
        (("r", "range"), (1.0, 1.0), "unknown polar components"),
        (("r", "az"), (1.0,), "one sigma per component"),
        (("r", "az"), (1.0, 0.0), "finite and > 0"),
        (("r", "az"), (1.0, np.nan), "finite and > 0"),
        (("r",), (np.inf,), "finite and > 0"),
    ],
)
def test_polar_model_validation(components, sigmas, message):
    with pytest.raises(ValueError, match=message):
        PolarMeasurementModel(components, sigmas)


def test_cartesian_position_model():
    model = CartesianPositionModel(ndim=2, order=3, state_ndim=3)
    H = model.matrix()
    expected = np.zeros((2, 9))
    expected[0, 0] = expected[1, 3] = 1.0
    np.testing.assert_array_equal(H, expected)
    states = np.arange(18.0).reshape(2, 9)
    h, J = model.evaluate(states)
    np.testing.assert_array_equal(h, states[:, [0, 3]])
    assert J.shape == (2, 2, 9)
    np.testing.assert_array_equal(J[1], expected)
    assert model.dim == 2 and not model.angular.any()
    # default: as many state axes as measured axes
    full = CartesianPositionModel(ndim=3, order=2)
    np.testing.assert_array_equal(full.evaluate(np.arange(6.0), jacobian=False), [[0.0, 2.0, 4.0]])


def test_cartesian_position_noise():
    model = CartesianPositionModel(ndim=3, order=2, sigma_m=30.0)
    np.testing.assert_array_equal(model.R, np.eye(3) * 900.0)
    with pytest.raises(ValueError, match="sigma_m"):
        CartesianPositionModel(ndim=2, order=2).R
    with pytest.raises(ValueError, match="sigma_m must be finite and > 0"):
        CartesianPositionModel(ndim=2, order=2, sigma_m=-1.0)

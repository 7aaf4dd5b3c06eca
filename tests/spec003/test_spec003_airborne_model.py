"""Spec 003 R1, R3, R4: paper frame, airborne measurement model h(x), Jacobian, wrapping (TV3)."""

import math

import numpy as np
import pytest

from skytrack.geo.paper_frame import enu_to_paper_xyz, paper_xyz_to_enu
from skytrack.models.airborne import (
    airborne_measurement,
    airborne_noise,
    degenerate_pairs,
    wrap_residual,
)

# TV3 inputs (ENU)
OWN_P = np.array([1000.0, -2000.0, 8000.0])
OWN_V = np.array([50.0, 240.0, 0.0])
TARGET = np.array([21000.0, 38000.0, 6000.0, -200.0, 100.0, 5.0])

H_TV3 = np.array([
    [4.4676705161e-01, 8.9353410322e-01, -4.4676705161e-02, 0, 0, 0],
    [2.0000000000e-05, -1.0000000000e-05, 0, 0, 0, 0],
    [4.4632095359e-07, 8.9264190719e-07, 2.2316047680e-05, 0, 0, 0],
    [-3.2192196733e-03, 1.6033675824e-03, -1.2484508428e-04, 4.4676705161e-01, 8.9353410322e-01, -4.4676705161e-02],
])


def assert_rel(actual, expected, rtol, atol_near_zero=1e-12):
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol_near_zero)


# ---------------------------------------------------------------- R1: frames


def test_tv3_paper_frame_maps_to_enu():
    target_paper = np.array([38000.0, 21000.0, 6000.0, 100.0, -200.0, 5.0])  # X, Y, Z, Vx, Vy, Vz
    own_paper = np.array([-2000.0, 1000.0, 8000.0])
    np.testing.assert_array_equal(paper_xyz_to_enu(target_paper), TARGET)
    np.testing.assert_array_equal(paper_xyz_to_enu(own_paper), OWN_P)
    np.testing.assert_array_equal(enu_to_paper_xyz(TARGET), target_paper)
    # batches [..., 3] / [..., 6] and the round trip
    batch = np.arange(24.0).reshape(2, 2, 6)
    np.testing.assert_array_equal(enu_to_paper_xyz(paper_xyz_to_enu(batch)), batch)
    np.testing.assert_array_equal(paper_xyz_to_enu(batch[..., 3:])[..., 0], batch[..., 4])


def test_paper_frame_is_a_reflection_with_the_same_azimuth():
    swap = paper_xyz_to_enu(np.eye(3))
    assert np.linalg.det(swap) == pytest.approx(-1.0, abs=1e-15)
    target_paper, own_paper = enu_to_paper_xyz(TARGET[:3]), enu_to_paper_xyz(OWN_P)
    dX, dY = target_paper[:2] - own_paper[:2]
    az_paper = math.atan2(dY, dX)  # atan2(Y - Y_o, X - X_o)
    az_enu = math.atan2(TARGET[0] - OWN_P[0], TARGET[1] - OWN_P[1])  # atan2(e - e_o, n - n_o)
    assert az_paper == az_enu


@pytest.mark.parametrize("shape", [(2,), (4,), (5, 7)])
def test_paper_frame_rejects_other_shapes(shape):
    with pytest.raises(ValueError, match=r"\[\.\.\., 3\] or \[\.\.\., 6\]"):
        paper_xyz_to_enu(np.zeros(shape))


# ---------------------------------------------------------------- R3: h and H


def test_tv3_measurement_values():
    h, _ = airborne_measurement(TARGET[None], OWN_P, OWN_V)
    D, az, el, vr = h[0]
    assert D == pytest.approx(math.sqrt(2.004e9), rel=1e-9)
    assert D == pytest.approx(44766.05857119, rel=1e-9)
    assert az == pytest.approx(0.46364760900, rel=1e-9)
    assert math.degrees(az) == pytest.approx(26.565051177, rel=1e-9)
    assert az == pytest.approx(math.atan(0.5), rel=1e-12)  # De = 20 km, Dn = 40 km
    assert el == pytest.approx(-0.044691581036, rel=1e-9)
    assert math.degrees(el) == pytest.approx(-2.560638973, rel=1e-9)
    assert vr == pytest.approx(-237.00992088, rel=1e-9)


def test_tv3_jacobian_matches_listed_values():
    _, H = airborne_measurement(TARGET[None], OWN_P, OWN_V)
    assert H.shape == (1, 4, 6)
    assert_rel(H[0], H_TV3, rtol=1e-9)


def central_difference(state, own_p, own_v, with_range_rate=True):
    steps = np.array([1.0, 1.0, 1.0, 1e-2, 1e-2, 1e-2])
    columns = []
    for j, step in enumerate(steps):
        plus, minus = state.copy(), state.copy()
        plus[j] += step
        minus[j] -= step
        h_plus = airborne_measurement(plus[None], own_p, own_v, with_range_rate, jacobian=False)[0]
        h_minus = airborne_measurement(minus[None], own_p, own_v, with_range_rate, jacobian=False)[0]
        columns.append((h_plus - h_minus) / (2 * step))
    return np.stack(columns, axis=-1)


@pytest.mark.parametrize("state, own_p, own_v", [
    (TARGET, OWN_P, OWN_V),
    (np.array([-5000.0, -30000.0, 12000.0, 150.0, 220.0, -10.0]), np.array([3000.0, 2000.0, 9000.0]),
     np.array([-180.0, 90.0, 3.0])),
    (np.array([-40000.0, 200.0, 500.0, 0.0, -250.0, 0.0]), np.zeros(3), np.array([0.0, 250.0, 0.0])),
])
def test_jacobian_equals_central_difference(state, own_p, own_v):
    _, H = airborne_measurement(state[None], own_p, own_v)
    fd = central_difference(state, own_p, own_v)
    row_scale = np.abs(H[0]).max(axis=1, keepdims=True)
    # entries that vanish analytically are compared against their row's largest entry
    np.testing.assert_allclose(fd / row_scale, H[0] / row_scale, rtol=1e-6, atol=1e-6)


def test_batch_equals_rows_and_three_row_variant_drops_range_rate():
    rng = np.random.default_rng(3)
    states = np.column_stack([rng.uniform(-5e4, 5e4, (5, 2)), rng.uniform(1e3, 1e4, 5), rng.uniform(-300, 300, (5, 3))])
    own_p = np.column_stack([rng.uniform(-1e4, 1e4, (5, 2)), np.full(5, 8000.0)])
    own_v = rng.uniform(-250, 250, (5, 3))
    h, H = airborne_measurement(states, own_p, own_v)
    for k in range(5):
        h_k, H_k = airborne_measurement(states[k:k + 1], own_p[k], own_v[k])
        np.testing.assert_array_equal(h_k[0], h[k])
        np.testing.assert_array_equal(H_k[0], H[k])
    h3, H3 = airborne_measurement(states, own_p, None, with_range_rate=False)
    np.testing.assert_array_equal(h3, h[:, :3])
    np.testing.assert_array_equal(H3, H[:, :3])


def test_overhead_pair_raises_naming_rows_and_mask_matches():
    states = np.tile(TARGET, (4, 1))
    states[0, :3] = OWN_P + [0.0, 0.0, 5000.0]  # straight above
    states[2, :3] = OWN_P + [0.4e-6 * 5000.0, 0.0, -5000.0]  # rho = 0.4e-6 D: below
    states[3, :3] = OWN_P + [2e-6 * 5000.0, 0.0, 5000.0]  # rho = 2e-6 D: usable
    mask = degenerate_pairs(states, OWN_P)
    np.testing.assert_array_equal(mask, [True, False, True, False])
    with pytest.raises(ValueError, match=r"pair rows \[0, 2\]"):
        airborne_measurement(states, OWN_P, OWN_V)
    h, _ = airborne_measurement(states[~mask], OWN_P, OWN_V)
    assert np.all(np.isfinite(h))
    # the object at the own-ship itself (D = 0) is degenerate too
    assert degenerate_pairs(np.concatenate([OWN_P, np.zeros(3)])[None], OWN_P)[0]


# ---------------------------------------------------------------- R4: wrapping


def test_tv3_wrap_case():
    predicted, measured = math.radians(359.8), math.radians(0.1)
    nu = wrap_residual(np.array([[0.0, measured - predicted, 0.0, 0.0]]))
    assert nu[0, 1] == pytest.approx(5.235987755983e-3, rel=1e-9)
    assert math.degrees(nu[0, 1]) == pytest.approx(0.3, rel=1e-9)
    # the 3-component residual wraps the same column; elevation is not wrapped
    nu3 = wrap_residual(np.array([predicted - measured, predicted - measured, 4.0]))
    assert nu3[0] == predicted - measured and nu3[2] == 4.0
    assert nu3[1] == pytest.approx(-5.235987755983e-3, rel=1e-9)
    # the interval is (-pi, pi]
    assert wrap_residual(np.array([0.0, -math.pi, 0.0]))[1] == math.pi


def test_predicted_azimuth_in_zero_two_pi():
    # targets just west of north and exactly north of the own-ship
    west = np.array([OWN_P[0] - 1e-9, OWN_P[1] + 40000.0, 7000.0, 0, 0, 0])
    north = np.array([OWN_P[0], OWN_P[1] + 40000.0, 7000.0, 0, 0, 0])
    at_359_8 = np.concatenate([OWN_P + 40000.0 * np.array([math.sin(math.radians(359.8)),
                                                           math.cos(math.radians(359.8)), 0.0]), np.zeros(3)])
    h, _ = airborne_measurement(np.stack([west, north, at_359_8]), OWN_P, OWN_V)
    assert np.all((h[:, 1] >= 0.0) & (h[:, 1] < 2.0 * math.pi))
    assert h[1, 1] == 0.0
    assert h[2, 1] == pytest.approx(math.radians(359.8), rel=1e-12)


# ---------------------------------------------------------------- noise


def test_airborne_noise():
    sigma_az = math.radians(0.3)
    R = airborne_noise(30.0, sigma_az, sigma_az, 2.0)
    np.testing.assert_array_equal(R, np.diag([900.0, sigma_az**2, sigma_az**2, 4.0]))
    np.testing.assert_array_equal(airborne_noise(30.0, sigma_az, sigma_az, with_range_rate=False), R[:3, :3])
    per_plot = airborne_noise(np.array([30.0, 60.0]), sigma_az, sigma_az, 2.0)
    assert per_plot.shape == (2, 4, 4)
    assert per_plot[1, 0, 0] == 3600.0 and per_plot[1, 3, 3] == 4.0
    with pytest.raises(ValueError, match="finite and > 0"):
        airborne_noise(0.0, sigma_az, sigma_az, 2.0)
    with pytest.raises(ValueError, match="sigma_vr"):
        airborne_noise(30.0, sigma_az, sigma_az)

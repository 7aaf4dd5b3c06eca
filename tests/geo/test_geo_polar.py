"""Radar polar coordinates, angle wrapping and the 2-D sphere projection (skytrack.geo.polar)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skytrack.geo.polar import (
    EARTH_RADIUS_M,
    cartesian_to_polar,
    polar_to_cartesian,
    slant_to_local,
    wrap_angle,
)

finite_coord = st.floats(-5e5, 5e5, allow_nan=False, allow_infinity=False)


def test_cartesian_polar_round_trip():
    rng = np.random.default_rng(3)
    p = rng.uniform([-3e5, -3e5, -2e4], [3e5, 3e5, 2e4], size=(5000, 3))
    r, az, el = cartesian_to_polar(*p.T)
    np.testing.assert_allclose(np.column_stack(polar_to_cartesian(r, az, el)), p, rtol=0, atol=1e-8)
    r2, az2, el2 = cartesian_to_polar(*polar_to_cartesian(r, az, el))
    np.testing.assert_allclose(r2, r, rtol=1e-14)
    np.testing.assert_allclose(wrap_angle(az2 - az), 0.0, atol=1e-12)
    np.testing.assert_allclose(el2, el, atol=1e-12)


def test_polar_known_values():
    # north-east at 45 deg, 30 deg elevation
    r, az, el = cartesian_to_polar(1000.0, 1000.0, np.sqrt(2e6) * np.tan(np.radians(30.0)))
    assert az == pytest.approx(np.pi / 4, abs=1e-15)
    assert el == pytest.approx(np.pi / 6, abs=1e-15)
    assert r == pytest.approx(np.sqrt(2e6) / np.cos(np.pi / 6), rel=1e-15)
    # due west is 270 deg clockwise from north
    assert cartesian_to_polar(-5.0, 0.0, 0.0)[1] == pytest.approx(1.5 * np.pi, abs=1e-15)
    np.testing.assert_allclose(polar_to_cartesian(10.0, np.pi / 2, 0.0), (10.0, 0.0, 0.0), atol=1e-14)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(finite_coord, finite_coord)
def test_azimuth_in_zero_two_pi_and_points_at_the_target(x, y):
    """az is in [0, 2 pi] (the open upper end is tested separately below) and
    points at the target: (r sin az, r cos az) = (x, y)."""
    r, az, _ = cartesian_to_polar(x, y, 0.0)
    assert 0.0 <= az <= 2.0 * np.pi
    back = polar_to_cartesian(r, az, 0.0)
    assert abs(back[0] - x) <= 1e-9 * max(1.0, r) and abs(back[1] - y) <= 1e-9 * max(1.0, r)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.floats(1e-300, 1e5), st.floats(-1e5, 1e5, allow_nan=False))
def test_azimuth_west_half_plane_is_above_pi(minus_x, y):
    """Targets west of the sensor (x < 0) have az in (pi, 2 pi) -- or 2 pi exactly through the
    rounding bug below; never negative."""
    az = cartesian_to_polar(-minus_x, y, 0.0)[1]
    assert np.pi <= az <= 2.0 * np.pi


def test_azimuth_just_west_of_north_is_below_two_pi():
    """A target a hair west of north: atan2 gives -1e-16, and remainder(-1e-16, 2 pi) rounds
    to exactly 2 pi, outside the documented [0, 2 pi)."""
    x = np.array([-1e-12, -1e-13, -5e-324])
    az = cartesian_to_polar(x, np.full(3, 1e4), np.zeros(3))[1]
    assert np.all(az < 2.0 * np.pi)
    assert np.all(az >= 0.0)


@pytest.mark.parametrize(
    "angle, expected",
    [
        (np.pi, np.pi),
        (-np.pi, np.pi),
        (3 * np.pi, np.pi),
        (-3 * np.pi, np.pi),
        (0.0, 0.0),
        (2 * np.pi, 0.0),
        (np.pi / 2 + 2 * np.pi, np.pi / 2),
        (-np.pi / 2 - 4 * np.pi, -np.pi / 2),
        (np.nextafter(np.pi, 0.0), np.nextafter(np.pi, 0.0)),
        (np.nextafter(-np.pi, 0.0), np.nextafter(-np.pi, 0.0)),
    ],
)
def test_wrap_angle_known_values(angle, expected):
    assert float(wrap_angle(angle)) == pytest.approx(expected, abs=4 * np.spacing(4 * np.pi))


@settings(max_examples=500, deadline=None, derandomize=True)
@given(st.floats(-1e4, 1e4, allow_nan=False))
def test_wrap_angle_range_and_congruence(angle):
    w = float(wrap_angle(angle))
    assert -np.pi < w <= np.pi
    # same direction: the difference is a multiple of 2 pi (to rounding of |angle|)
    k = (angle - w) / (2 * np.pi)
    assert abs(k - round(k)) < 1e-12 * max(1.0, abs(angle))


def test_wrap_angle_is_vectorised():
    a = np.array([[-np.pi, np.pi], [7.0, -7.0]])
    w = wrap_angle(a)
    assert w.shape == a.shape
    np.testing.assert_allclose(w, [[np.pi, np.pi], [7.0 - 2 * np.pi, -7.0 + 2 * np.pi]], atol=1e-15)


def test_range_rate_sign_and_value():
    # target at (3000, 4000, 0): r = 5000; radial unit vector (0.6, 0.8, 0)
    p = (3000.0, 4000.0, 0.0)
    assert cartesian_to_polar(*p, 30.0, 40.0, 0.0)[3] == pytest.approx(50.0, rel=1e-15)  # receding
    assert cartesian_to_polar(*p, -30.0, -40.0, 0.0)[3] == pytest.approx(-50.0, rel=1e-15)  # closing
    assert cartesian_to_polar(*p, -40.0, 30.0, 7.0)[3] == pytest.approx(0.0, abs=1e-12)  # tangential
    # general value: (p . v) / |p|
    rng = np.random.default_rng(4)
    pos = rng.uniform(-1e5, 1e5, size=(100, 3))
    vel = rng.uniform(-300, 300, size=(100, 3))
    rdot = cartesian_to_polar(*pos.T, *vel.T)[3]
    np.testing.assert_allclose(rdot, np.sum(pos * vel, axis=1) / np.linalg.norm(pos, axis=1), rtol=1e-12)


# ----------------------------------------------------------------------------- slant_to_local


def sphere_point(phi, az, h, sensor_alt, R=EARTH_RADIUS_M):
    """Sensor-local ENU of a target at Earth-central angle phi, azimuth az and height h, and
    its slant range from the FORMATS formula r^2 = (a - b)^2 + 4 a b sin^2(phi / 2)."""
    a, b = R + sensor_alt, R + h
    ground = b * np.sin(phi)
    local = np.stack([ground * np.sin(az), ground * np.cos(az), b * np.cos(phi) - a], axis=-1)
    r = np.sqrt((a - b) ** 2 + 4 * a * b * np.sin(phi / 2) ** 2)
    return local, r


def test_sphere_formula_is_the_chord_length():
    """The FORMATS formula equals the straight-line distance of the constructed point."""
    rng = np.random.default_rng(8)
    phi = rng.uniform(1e-5, 0.06, 500)
    local, r = sphere_point(phi, rng.uniform(0, 2 * np.pi, 500), rng.uniform(0, 15e3, 500), rng.uniform(0, 2e3, 500))
    np.testing.assert_allclose(np.linalg.norm(local, axis=1), r, rtol=1e-12)


def test_slant_to_local_inverts_the_sphere_formula():
    rng = np.random.default_rng(9)
    n = 2000
    phi = rng.uniform(1e-5, 0.06, n)  # up to ~380 km ground distance
    az = rng.uniform(0, 2 * np.pi, n)
    h = rng.uniform(0, 15e3, n)
    sensor_alt = rng.uniform(0, 2e3, n)
    local, r = sphere_point(phi, az, h, sensor_alt)
    x, y, z, consistent = slant_to_local(r, az, h, sensor_alt)
    assert consistent.all()
    np.testing.assert_allclose(np.column_stack([x, y, z]), local, rtol=0, atol=1e-6)


def test_slant_to_local_custom_radius():
    local, r = sphere_point(0.01, 1.0, 9000.0, 100.0, R=6_378_137.0)
    x, y, z, ok = slant_to_local(r, 1.0, 9000.0, 100.0, earth_radius_m=6_378_137.0)
    np.testing.assert_allclose([x, y, z], local, atol=1e-6)


def test_slant_to_local_jacobian_matches_central_differences():
    rng = np.random.default_rng(10)
    n = 200
    r = rng.uniform(15e3, 300e3, n)
    az = rng.uniform(0, 2 * np.pi, n)
    h = rng.uniform(500, 12e3, n)
    sensor_alt = rng.uniform(0, 1e3, n)
    *_, J = slant_to_local(r, az, h, sensor_alt, jacobian=True)
    steps = (1.0, 1e-6, 1.0)  # m, rad, m: truncation ~ (step/scale)^2, rounding ~ 1e-16 scale/step
    for col, (arg, step) in enumerate(zip((r, az, h), steps)):
        args_plus = [r, az, h]
        args_minus = [r, az, h]
        args_plus[col] = arg + step
        args_minus[col] = arg - step
        plus = np.column_stack(slant_to_local(*args_plus, sensor_alt)[:3])
        minus = np.column_stack(slant_to_local(*args_minus, sensor_alt)[:3])
        numeric = (plus - minus) / (2 * step)
        scale = np.linalg.norm(numeric, axis=1, keepdims=True)
        np.testing.assert_allclose(J[:, :, col] / scale, numeric / scale, rtol=0, atol=1e-6)


def test_slant_to_local_flags_a_range_shorter_than_the_height_difference():
    # 6000 m above a radar at 0 m, slant range 1000 m: impossible geometry
    x, y, z, consistent = slant_to_local(np.array([1000.0, 6000.0, 6000.1]), np.zeros(3), 6000.0, 0.0)
    np.testing.assert_array_equal(consistent, [False, True, True])
    # the impossible plot is put straight above the radar, at the given height
    assert x[0] == 0.0 and y[0] == 0.0
    assert z[0] == pytest.approx(6000.0, abs=1e-6)
    # and a target below the radar
    *_, consistent_below = slant_to_local(500.0, 0.0, 0.0, 2000.0)
    assert not consistent_below

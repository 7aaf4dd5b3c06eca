"""WGS84 geodetic <-> local ENU conversions and the ECEF -> ENU rotation (skytrack.geo.wgs84)."""

import numpy as np
import pymap3d
import pytest

from skytrack.geo.wgs84 import (
    enu_rotation,
    enu_to_geodetic,
    enu_to_geodetic_closed_form,
    geodetic_to_ecef_point,
    geodetic_to_enu,
)

N_POINTS = 2000


@pytest.fixture
def origins():
    rng = np.random.default_rng(20240601)
    return rng.uniform(-85, 85, N_POINTS), rng.uniform(-180, 180, N_POINTS), rng.uniform(-100, 3000, N_POINTS)


def test_enu_geodetic_enu_round_trip_is_micrometre_exact(origins):
    rng = np.random.default_rng(1)
    lat0, lon0, alt0 = origins
    enu = rng.uniform([-4e5, -4e5, -2e4], [4e5, 4e5, 2e4], size=(N_POINTS, 3))
    lat, lon, alt = enu_to_geodetic(*enu.T, lat0, lon0, alt0)
    back = np.column_stack(geodetic_to_enu(lat, lon, alt, lat0, lon0, alt0))
    assert np.max(np.abs(back - enu)) < 1e-6


def test_geodetic_enu_geodetic_round_trip_is_micrometre_exact(origins):
    rng = np.random.default_rng(2)
    lat0, lon0, alt0 = origins
    lat = rng.uniform(-89.9, 89.9, N_POINTS)
    lon = rng.uniform(-180, 180, N_POINTS)
    alt = rng.uniform(-400, 20_000, N_POINTS)
    e, n, u = geodetic_to_enu(lat, lon, alt, lat0, lon0, alt0)
    lat2, lon2, alt2 = enu_to_geodetic(e, n, u, lat0, lon0, alt0)
    # compare as ECEF points: a metric distance, free of the longitude singularity at the poles
    a = np.array(pymap3d.geodetic2ecef(lat, lon, alt))
    b = np.array(pymap3d.geodetic2ecef(lat2, lon2, alt2))
    assert np.max(np.linalg.norm(a - b, axis=0)) < 1e-6


def test_geodetic_to_enu_of_the_origin_is_zero_and_up_is_height():
    e, n, u = geodetic_to_enu(48.86, 2.5, 1234.5, 48.86, 2.5, 1000.0)
    np.testing.assert_allclose([e, n, u], [0.0, 0.0, 234.5], atol=1e-8)


@pytest.mark.parametrize("lat, lon", [(0.0, 0.0), (48.86, 2.5), (-33.9, 151.2), (89.0, -179.0), (-70.0, 100.0)])
def test_enu_rotation_is_a_proper_rotation(lat, lon):
    R = enu_rotation(lat, lon)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("lat, lon", [(0.0, 0.0), (48.86, 2.5), (-33.9, 151.2), (89.0, -179.0), (-70.0, 100.0)])
def test_enu_rotation_agrees_with_pymap3d_for_a_vector(lat, lon):
    rng = np.random.default_rng(7)
    ecef_vectors = rng.normal(size=(3, 20)) * 1000.0
    expected = np.array(pymap3d.ecef2enuv(*ecef_vectors, lat, lon))
    np.testing.assert_allclose(enu_rotation(lat, lon) @ ecef_vectors, expected, atol=1e-9)


def test_enu_rotation_up_row_is_the_ellipsoid_normal():
    # the geodetic normal at (lat, lon) is (cos lat cos lon, cos lat sin lon, sin lat)
    lat, lon = 48.86, 2.5
    phi, lam = np.radians(lat), np.radians(lon)
    normal = [np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)]
    np.testing.assert_allclose(enu_rotation(lat, lon)[2], normal, atol=1e-15)


# ------------------------------------------------------------- closed form (the output path)
ORIGINS = [(48.86, 2.5, 100.0), (0.0, 0.0, 0.0), (-33.9, 151.2, 20.0), (89.9, -179.99, 3000.0),
           (-89.5, 45.0, -100.0), (52.0, 179.95, 12.0), (10.0, -179.95, 0.0)]


@pytest.mark.parametrize("lat0, lon0, alt0", ORIGINS)
def test_closed_form_enu_to_geodetic_agrees_with_pymap3d(lat0, lon0, alt0):
    rng = np.random.default_rng(11)
    enu = rng.uniform([-4e5, -4e5, -2e4], [4e5, 4e5, 2e4], size=(N_POINTS, 3))  # air surveillance
    want = enu_to_geodetic(*enu.T, lat0, lon0, alt0)
    got = enu_to_geodetic_closed_form(*enu.T, lat0, lon0, alt0)
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-9)
    lon_difference = (got[1] - want[1] + 180.0) % 360.0 - 180.0  # across the date line
    np.testing.assert_allclose(lon_difference, 0.0, rtol=0, atol=1e-9)
    assert np.all((got[1] >= -180.0) & (got[1] <= 180.0))
    np.testing.assert_allclose(got[2], want[2], rtol=0, atol=1e-4)


@pytest.mark.parametrize("lat0, lon0, alt0", ORIGINS)
def test_closed_form_enu_to_geodetic_is_exact_far_out(lat0, lon0, alt0):
    # thousands of km up pymap3d's one-step closed form drifts by metres; this one stays exact
    rng = np.random.default_rng(12)
    enu = rng.uniform([-3e6, -3e6, -5e4], [3e6, 3e6, 5e6], size=(N_POINTS, 3))
    ecef = np.array(pymap3d.enu2ecef(*enu.T, lat0, lon0, alt0))
    lat, lon, alt = enu_to_geodetic_closed_form(*enu.T, lat0, lon0, alt0)
    back = np.array(pymap3d.geodetic2ecef(lat, lon, alt))
    assert np.max(np.linalg.norm(back - ecef, axis=0)) < 1e-6


def test_closed_form_enu_to_geodetic_keeps_nan_shape_and_input():
    x = np.array([[1000.0, np.nan], [0.0, -5000.0]])
    y = np.array([[np.nan, 200.0], [0.0, 7000.0]])
    z = np.array([[10.0, 10.0], [np.nan, 8000.0]])
    before = x.copy()
    lat, lon, alt = enu_to_geodetic_closed_form(x, y, z, 48.86, 2.5, 100.0)
    assert lat.shape == lon.shape == alt.shape == (2, 2)
    np.testing.assert_array_equal(x, before)
    for got in (lat, lon, alt):
        np.testing.assert_array_equal(np.isnan(got), [[True, True], [True, False]])
    want = enu_to_geodetic(-5000.0, 7000.0, 8000.0, 48.86, 2.5, 100.0)
    np.testing.assert_allclose([lat[1, 1], lon[1, 1], alt[1, 1]], want, rtol=0, atol=1e-9)
    scalar = enu_to_geodetic_closed_form(0.0, 0.0, 0.0, 48.86, 2.5, 100.0)
    np.testing.assert_allclose(scalar, (48.86, 2.5, 100.0), rtol=0, atol=1e-9)
    empty = enu_to_geodetic_closed_form([], [], [], 48.86, 2.5, 100.0)
    assert all(len(a) == 0 for a in empty)


@pytest.mark.parametrize("lat, lon, alt", ORIGINS)
def test_geodetic_to_ecef_point_agrees_with_pymap3d(lat, lon, alt):
    np.testing.assert_allclose(geodetic_to_ecef_point(lat, lon, alt), pymap3d.geodetic2ecef(lat, lon, alt),
                               rtol=0, atol=1e-8)

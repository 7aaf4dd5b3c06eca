"""Sensor frames of sensors.json (skytrack.geo.sensors): positions, rotations, checks."""

import math

import numpy as np
import pymap3d
import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet

ORIGIN = Origin(48.86, 2.50, 35.0)


def radar(name="r", **kwargs):
    values = dict(sigma_range_m=40.0, sigma_azimuth_deg=0.07, scan_period_s=4.0)
    values.update(kwargs)
    return Sensor(name, **values)


def test_sensor_position_from_lat_lon_matches_pymap3d():
    sensors = SensorSet(ORIGIN, [radar("a", lat=49.3, lon=3.1, alt_m=150.0), radar("b", lat=48.0, lon=1.7)])
    for sensor, alt in zip(sensors.sensors, (150.0, 0.0)):
        expected = pymap3d.geodetic2enu(sensor.lat, sensor.lon, alt, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
        np.testing.assert_allclose(sensor.position, expected, atol=1e-6)
        # x/y/z are filled from the geodetic position
        np.testing.assert_allclose([sensor.x, sensor.y, sensor.z], expected, atol=1e-6)


def test_to_local_equals_the_sensors_own_enu_frame():
    """A geodetic sensor's local frame is exactly its own WGS84 ENU frame."""
    sensor = radar("a", lat=49.3, lon=3.1, alt_m=150.0)
    SensorSet(ORIGIN, [sensor])
    rng = np.random.default_rng(11)
    common = rng.uniform([-2e5, -2e5, 0.0], [2e5, 2e5, 12e3], size=(500, 3))
    lat, lon, alt = pymap3d.enu2geodetic(*common.T, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    expected = np.column_stack(pymap3d.geodetic2enu(lat, lon, alt, sensor.lat, sensor.lon, sensor.alt_m))
    np.testing.assert_allclose(sensor.to_local(common), expected, atol=1e-6)


@pytest.mark.parametrize("kwargs", [dict(lat=49.3, lon=3.1, alt_m=150.0), dict(x=12e3, y=-40e3, z=80.0, north_offset_deg=-0.4)])
def test_to_local_and_to_common_are_inverse(kwargs):
    sensor = radar("a", **kwargs)
    SensorSet(ORIGIN, [sensor])
    rng = np.random.default_rng(12)
    points = rng.uniform(-3e5, 3e5, size=(300, 3))
    np.testing.assert_allclose(sensor.to_common(sensor.to_local(points)), points, atol=1e-8)
    np.testing.assert_allclose(sensor.to_local(sensor.to_common(points)), points, atol=1e-8)
    # a per-point position (moving platform) overrides the fixed one
    platform = rng.uniform(-1e4, 1e4, size=(300, 3))
    np.testing.assert_allclose(sensor.to_local(points, platform), (points - platform) @ sensor.rotation.T, atol=1e-8)
    np.testing.assert_allclose(sensor.to_common(sensor.to_local(points, platform), platform), points, atol=1e-8)


def test_north_offset_of_a_sensor_east_of_the_origin_is_the_meridian_convergence():
    """Sensor 1 deg of longitude east, same latitude: its north points west of the frame's north
    by gamma = atan2(sin(lat) sin(dlon), sin^2(lat) cos(dlon) + cos^2(lat)) ~= dlon sin(lat).

    north_offset_deg is clockwise from +y, so the value is negative (counter-clockwise)."""
    dlon = 1.0
    sensor = radar("east", lat=ORIGIN.lat, lon=ORIGIN.lon + dlon, alt_m=0.0)
    SensorSet(ORIGIN, [sensor])
    phi, dl = math.radians(ORIGIN.lat), math.radians(dlon)
    exact = -math.degrees(math.atan2(math.sin(phi) * math.sin(dl), math.sin(phi) ** 2 * math.cos(dl) + math.cos(phi) ** 2))
    assert sensor.north_offset_deg == pytest.approx(exact, rel=1e-12)
    assert sensor.north_offset_deg == pytest.approx(-dlon * math.sin(phi), rel=1e-4)
    # the sensor's north, seen from the common frame, has that azimuth
    north_in_common = sensor.rotation[1]
    assert math.degrees(math.atan2(north_in_common[0], north_in_common[1])) == pytest.approx(exact, rel=1e-12)


def test_horizontal_frame_from_x_y_and_north_offset_matches_the_geodetic_one():
    """Giving x/y and the north offset of a geodetic sensor yields the same azimuths for points
    in the sensor's horizontal plane, up to the second-order effect of the tilt eps = d / R
    between the two tangent planes (which a rotation about z cannot represent): |err| < eps^2 / 2."""
    geodetic = radar("g", lat=49.1, lon=3.3, alt_m=0.0)
    SensorSet(ORIGIN, [geodetic])
    planar = radar("p", x=geodetic.x, y=geodetic.y, z=geodetic.z, north_offset_deg=geodetic.north_offset_deg)
    SensorSet(ORIGIN, [planar])
    np.testing.assert_allclose(planar.position, geodetic.position, atol=1e-9)
    rng = np.random.default_rng(5)
    az = rng.uniform(0, 2 * np.pi, 200)
    ground = rng.uniform(2e4, 1e5, 200)
    local = np.column_stack([ground * np.sin(az), ground * np.cos(az), np.zeros(200)])
    seen = planar.to_local(geodetic.to_common(local))
    err = np.angle(np.exp(1j * (np.arctan2(seen[:, 0], seen[:, 1]) - az)))
    eps = np.linalg.norm(geodetic.position) / 6.371e6
    assert np.max(np.abs(err)) < eps**2 / 2


def test_inconsistent_x_y_and_lat_lon_raise_naming_the_sensor():
    good = radar("ok", lat=49.3, lon=3.1, alt_m=0.0)
    SensorSet(ORIGIN, [good])
    bad = radar("bad", lat=49.3, lon=3.1, alt_m=0.0, x=good.x + 5.0, y=good.y, z=good.z)
    with pytest.raises(ValueError, match="'bad'.*disagree"):
        SensorSet(ORIGIN, [bad])
    # within the 1 m tolerance it is accepted
    fine = radar("fine", lat=49.3, lon=3.1, alt_m=0.0, x=good.x + 0.5, y=good.y, z=good.z)
    SensorSet(ORIGIN, [fine])
    np.testing.assert_allclose(fine.position, good.position)


def test_duplicate_sensor_names_raise():
    with pytest.raises(ValueError, match="unique.*radar1"):
        SensorSet(ORIGIN, [radar("radar1", x=0.0, y=0.0), radar("radar2", x=1.0, y=0.0), radar("radar1", x=2.0, y=0.0)])


def test_unknown_sensor_key_error_names_it_and_the_known_ones():
    sensors = SensorSet(ORIGIN, [radar("radar1", x=0.0, y=0.0), radar("radar2", x=1.0, y=0.0)])
    with pytest.raises(KeyError, match="'radarX'.*radar1, radar2"):
        sensors["radarX"]
    assert "radar2" in sensors and "radarX" not in sensors
    assert sensors["radar2"] is sensors.sensors[1]


def test_sensor_without_position_raises():
    with pytest.raises(ValueError, match="'lost'.*position is unknown"):
        SensorSet(ORIGIN, [radar("lost")])


def test_planar_sensor_rotation_turns_by_the_north_offset():
    """north_offset_deg = +30: the sensor's north is 30 deg clockwise of +y, so a point
    at common azimuth 30 deg is at the sensor's azimuth 0."""
    sensor = radar("p", x=0.0, y=0.0, north_offset_deg=30.0)
    SensorSet(ORIGIN, [sensor])
    az = math.radians(30.0)
    local = sensor.to_local(np.array([[1000 * math.sin(az), 1000 * math.cos(az), 0.0]]))
    np.testing.assert_allclose(local, [[0.0, 1000.0, 0.0]], atol=1e-9)


def test_geodetic_radar_without_alt_m_stands_on_the_ellipsoid():
    """docs/formats.md: alt_m defaults to 0; before, alt_m stayed None and every 2-D plot of
    such a radar was placed at NaN (no tracks at all)."""
    sensors = SensorSet(Origin(48.0, 2.0, 0.0), [Sensor("r", type="radar-2d", lat=48.1, lon=2.1)])
    radar = sensors.sensors[0]
    assert radar.alt_m == 0.0
    e, n, u = pymap3d.geodetic2enu(48.1, 2.1, 0.0, 48.0, 2.0, 0.0)
    np.testing.assert_allclose(radar.position, [e, n, u], atol=1e-6)

"""Geometry: WGS84 geodetic <-> ECEF <-> local ENU, radar polar coordinates, sensor frames.

Conventions (DESIGN.md): SI units, right-handed local East-North-Up frame around a
reference origin, azimuth clockwise from north in radians inside the library.
"""

from skytrack.geo.polar import (
    azimuth_of,
    cartesian_to_polar,
    polar_to_cartesian,
    slant_to_local,
    wrap_angle,
    EARTH_RADIUS_M,
)
from skytrack.geo.sensors import Origin, Sensor, SensorSet, SENSOR_TYPES
from skytrack.geo.wgs84 import enu_to_geodetic, geodetic_to_enu, enu_rotation

__all__ = [
    "azimuth_of",
    "cartesian_to_polar",
    "polar_to_cartesian",
    "slant_to_local",
    "wrap_angle",
    "EARTH_RADIUS_M",
    "Origin",
    "Sensor",
    "SensorSet",
    "SENSOR_TYPES",
    "enu_to_geodetic",
    "geodetic_to_enu",
    "enu_rotation",
]

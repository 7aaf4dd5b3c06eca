"""Sensor descriptions (the ``sensors.json`` model of FORMATS.md) and their frames.

A :class:`SensorSet` holds the common ENU origin and the sensors.  Each
:class:`Sensor` knows its position ``position`` in the common frame and the rotation
``rotation`` that takes common-frame vectors to its own local ENU frame (its own
north and up).  When the sensor's geodetic position is known the rotation is the
exact WGS84 one, ``R_enu(sensor) @ R_enu(origin).T``; otherwise it is the rotation about
``z`` by ``north_offset_deg`` (clockwise from +y), as FORMATS.md describes.

This module is below ``io`` in the package order: the JSON reading lives in
``skytrack.io.sensors``, which builds these objects.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from skytrack.geo.wgs84 import enu_rotation, geodetic_to_enu

SENSOR_TYPES = ("radar-2d", "radar-3d", "radar-airborne", "adsb")

#: tolerance for the consistency check between given x/y/z and lat/lon/alt_m
_POSITION_TOLERANCE_M = 1.0


@dataclass(frozen=True)
class Origin:
    """Geodetic origin of the common ENU frame."""

    lat: float
    lon: float
    alt_m: float = 0.0


@dataclass
class Sensor:
    """One sensor of ``sensors.json``; angles in degrees as in the file, SI otherwise."""

    name: str
    type: str = "radar-2d"
    lat: float | None = None
    lon: float | None = None
    alt_m: float | None = None
    x: float | None = None
    y: float | None = None
    z: float | None = None
    north_offset_deg: float | None = None
    scan_period_s: float | None = None
    scan_phase_s: float | None = 0.0
    sigma_range_m: float | None = None
    sigma_azimuth_deg: float | None = None
    sigma_elevation_deg: float | None = None
    sigma_range_rate_mps: float | None = None
    max_range_m: float | None = None
    min_elevation_deg: float | None = None
    p_detection: float | None = None
    clutter_per_scan: float | None = None
    #: ASTERIX System Area Code and System Identification Code (I048/010, I021/010), 0-255 each
    sac: int | None = None
    sic: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    # filled by SensorSet.resolve()
    position: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3), repr=False)

    @property
    def is_radar(self) -> bool:
        return self.type.startswith("radar")

    @property
    def is_3d(self) -> bool:
        """Measures elevation: a ``radar-3d``, or a ``radar-airborne`` with ``sigma_elevation_deg``
        (its plots are then placed in 3-D from range, azimuth and elevation, not on the sphere model)."""
        return self.type == "radar-3d" or (self.type == "radar-airborne" and self.sigma_elevation_deg is not None)

    @property
    def is_moving(self) -> bool:
        return self.type == "radar-airborne"

    @property
    def sigma_azimuth_rad(self) -> float:
        return math.radians(self.sigma_azimuth_deg)

    @property
    def sigma_elevation_rad(self) -> float | None:
        return None if self.sigma_elevation_deg is None else math.radians(self.sigma_elevation_deg)

    def to_local(self, points: np.ndarray, position: np.ndarray | None = None) -> np.ndarray:
        """Common-frame points ``[..., 3]`` to this sensor's local ENU frame."""
        origin = self.position if position is None else position
        return (np.asarray(points) - origin) @ self.rotation.T

    def to_common(self, local: np.ndarray, position: np.ndarray | None = None) -> np.ndarray:
        """Sensor-local points ``[..., 3]`` to the common ENU frame."""
        origin = self.position if position is None else position
        return np.asarray(local) @ self.rotation + origin

    def to_dict(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in ("extra", "position", "rotation")}
        for key in ("sac", "sic"):  # written only when given: files without ASTERIX stay as they were
            if out[key] is None:
                del out[key]
        out.update(self.extra)
        return out


def _horizontal_rotation(north_offset_deg: float) -> np.ndarray:
    """Rotation common -> sensor frame for a sensor whose north is ``north_offset_deg`` clockwise of +y."""
    off = math.radians(north_offset_deg)
    c, s = math.cos(off), math.sin(off)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class SensorSet:
    """The content of ``sensors.json``: origin, epoch and sensors, with resolved frames."""

    origin: Origin
    sensors: list[Sensor]
    epoch_utc: str | None = None
    format_version: str = "1"
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        names = [s.name for s in self.sensors]
        duplicated = sorted({n for n in names if names.count(n) > 1})
        if duplicated:
            raise ValueError(f"sensor names must be unique; repeated: {', '.join(duplicated)}")
        pairs = [(s.sac, s.sic) for s in self.sensors if s.sac is not None or s.sic is not None]
        repeated = sorted({p for p in pairs if pairs.count(p) > 1})
        if repeated:
            raise ValueError(f"ASTERIX sac/sic must be unique; repeated: {', '.join(f'{a}/{b}' for a, b in repeated)}")
        for sensor in self.sensors:
            self._resolve(sensor)

    def __getitem__(self, name: str) -> Sensor:
        for sensor in self.sensors:
            if sensor.name == name:
                return sensor
        known = ", ".join(s.name for s in self.sensors) or "none"
        raise KeyError(f"unknown sensor {name!r} (sensors.json has: {known})")

    def __contains__(self, name: str) -> bool:
        return any(s.name == name for s in self.sensors)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.sensors]

    def by_sac_sic(self) -> dict[tuple[int, int], str]:
        """Sensor name by its ASTERIX (SAC, SIC), for the sensors that have them."""
        return {(s.sac, s.sic): s.name for s in self.sensors if s.sac is not None and s.sic is not None}

    def _resolve(self, sensor: Sensor) -> None:
        """Fill ``position`` and ``rotation`` of a sensor from its geodetic or ENU position."""
        o = self.origin
        has_geodetic = sensor.lat is not None and sensor.lon is not None
        has_enu = sensor.x is not None and sensor.y is not None
        if has_geodetic:
            alt = 0.0 if sensor.alt_m is None else sensor.alt_m
            e, n, u = geodetic_to_enu(sensor.lat, sensor.lon, alt, o.lat, o.lon, o.alt_m)
            position = np.array([float(e), float(n), float(u)])
            if has_enu:
                given = np.array([sensor.x, sensor.y, 0.0 if sensor.z is None else sensor.z])
                if np.max(np.abs(given - position)) > _POSITION_TOLERANCE_M:
                    raise ValueError(
                        f"sensor {sensor.name!r}: x/y/z {given.tolist()} disagree with lat/lon/alt_m, "
                        f"which give {np.round(position, 2).tolist()} in the origin's ENU frame"
                    )
            rotation = enu_rotation(sensor.lat, sensor.lon) @ enu_rotation(o.lat, o.lon).T
            if sensor.north_offset_deg is None:
                sensor.north_offset_deg = math.degrees(math.atan2(rotation[1, 0], rotation[1, 1]))
        elif has_enu:
            position = np.array([sensor.x, sensor.y, 0.0 if sensor.z is None else sensor.z], dtype=float)
            rotation = _horizontal_rotation(sensor.north_offset_deg or 0.0)
        elif sensor.is_moving or sensor.type == "adsb":
            position = np.zeros(3)
            rotation = _horizontal_rotation(sensor.north_offset_deg or 0.0)
        else:
            raise ValueError(f"sensor {sensor.name!r} has neither lat/lon nor x/y: its position is unknown")
        if sensor.x is None:
            sensor.x, sensor.y, sensor.z = (float(v) for v in position)
        if sensor.alt_m is None:
            # a geodetic position without alt_m is on the ellipsoid (docs/formats.md default)
            sensor.alt_m = 0.0 if has_geodetic else float(position[2]) + o.alt_m
        sensor.position = position
        sensor.rotation = rotation

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"format_version": self.format_version}
        if self.epoch_utc is not None:
            out["epoch_utc"] = self.epoch_utc
        out["origin"] = dataclasses.asdict(self.origin)
        out["sensors"] = [s.to_dict() for s in self.sensors]
        out.update(self.extra)
        return out

"""Parsers of the scenario sections: sensors (with their IFF interrogator, an airborne
radar's carrier, and ``secondary_only`` for an interrogator without primary radar: spec 001's
system З, issue 9), targets with their legs (and their ADS-B settings, read by
:func:`skytrack.sim.adsb.parse_adsb_aircraft`), and random traffic.

Each parser reads one section of a scenario document through :class:`~skytrack.sim._validate.Fields`
(errors name the document and the key path) into the dataclasses of :mod:`skytrack.sim.spec`;
:func:`skytrack.sim.scenario.load_scenario` assembles them into a
:class:`~skytrack.sim.scenario.Scenario`.  The keys are documented in :mod:`skytrack.sim.scenario`.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.geo.wgs84 import enu_to_geodetic, geodetic_to_enu
from skytrack.sim._validate import Fields, ScenarioError, describe, join_path
from skytrack.sim.adsb import ADSB_AIRCRAFT_KEYS, parse_adsb_aircraft
from skytrack.sim.earth import place_at_height, sensor_relative_positions
from skytrack.sim.spec import (
    LEG_TYPES,
    SCENARIO_TYPES,
    TARGET_IFF_STATUSES,
    AccelerateLeg,
    ClimbLeg,
    ClutterPatch,
    IffSpec,
    LandLeg,
    Leg,
    ManeuverSpec,
    RadarSimParams,
    RegionSpec,
    SingerLeg,
    StraightLeg,
    TargetSpec,
    TrafficSpec,
    TurnLeg,
    Waypoint,
    WaypointsLeg,
)

_MODE3A = re.compile(r"[0-7]{4}")
_ICAO24 = re.compile(r"[0-9a-f]{6}")
_CALLSIGN = re.compile(r"[A-Z0-9]{1,8}")

_POSITION_KEYS = ("name", "type", "lat", "lon", "alt_m", "x", "y", "z")
_SENSOR_VALUE_KEYS = (
    "north_offset_deg", "scan_period_s", "scan_phase_s", "sigma_range_m", "sigma_azimuth_deg",
    "sigma_elevation_deg", "sigma_range_rate_mps", "max_range_m", "min_elevation_deg",
    "p_detection", "clutter_per_scan",
)
_SENSOR_SIM_KEYS = ("p_mode3a", "p_mode_c", "clutter_elevation_deg", "clutter_range_rate_mps",
                    "clutter_distribution", "clutter_patches", "clutter_p_mode3a", "clutter_p_mode_c", "iff",
                    "secondary_only")
#: per-sensor only (no sensor_defaults): the flight of a radar-airborne sensor's carrier
_CARRIER_KEY = "carrier"
_IFF_KEYS = ("p_reply", "p_flip", "p_code", "false_reply_p", "interrogate")
_CARRIER_KEYS = ("x", "y", "lat", "lon", "range_m", "azimuth_deg", "sensor", "alt_m", "speed_mps", "heading_deg", "legs")
_PATCH_KEYS = ("range_m", "azimuth_deg", "per_scan")
_TARGET_KEYS = (
    "id", "start_time_s", "x", "y", "lat", "lon", "range_m", "azimuth_deg", "sensor", "alt_m",
    "speed_mps", "heading_deg", "transponder", "mode3a", "icao24", "iff", "iff_p_reply", "legs",
    "callsign", "adsb",
)
_LEG_KEYS = {
    "straight": ("type", "duration_s"),
    "turn": ("type", "g", "direction", "duration_s", "turn_deg"),
    "climb": ("type", "rate_mps", "duration_s", "to_alt_m"),
    "accelerate": ("type", "to_speed_mps", "rate_mps2"),
    "singer": ("type", "tau_s", "sigma_a_mps2", "duration_s", "speed_range_mps"),
    "waypoints": ("type", "points", "max_g"),
    "land": ("type", "rate_mps", "field_alt_m"),
}
_WAYPOINT_KEYS = ("x", "y", "lat", "lon", "range_m", "azimuth_deg", "sensor", "alt_m")
_TRAFFIC_KEYS = (
    "count", "id_prefix", "region", "alt_m", "speed_mps", "heading_deg", "start_time_s",
    "transponder_fraction", "mode_s_fraction", "mode3a_allocation", "mode3a_range",
    "maneuver_fraction", "maneuvers", "landing_fraction", "landing_rate_mps", "departure_fraction",
    "departure_alt_m",
)
_MANEUVER_KEYS = (
    "count", "straight_s", "weights", "turn_g", "turn_deg", "climb_rate_mps", "singer_tau_s",
    "singer_sigma_a_mps2", "singer_duration_s", "accelerate_rate_mps2",
)


@dataclass
class _Context:
    origin: Origin
    sensors: SensorSet
    duration_s: float
    source: str


# -- sensors -------------------------------------------------------------------------------


def _parse_sensors(top: Fields, origin: Origin, duration_s: float) -> tuple[SensorSet, dict[str, RadarSimParams]]:
    defaults = top.sub("sensor_defaults", _SENSOR_VALUE_KEYS + _SENSOR_SIM_KEYS + ("type",), None)
    items = top.items("sensors")
    if not items:
        raise top.error("sensors", "at least one sensor is needed")
    sensors: list[Sensor] = []
    params: dict[str, RadarSimParams] = {}
    carriers: dict[str, Fields] = {}
    for path, item in items:
        if isinstance(item, dict) and defaults is not None:
            item = {**defaults.data, **item}
        fields = Fields(item, path, top.source, _POSITION_KEYS + _SENSOR_VALUE_KEYS + _SENSOR_SIM_KEYS + (_CARRIER_KEY,))
        sensor, sim = _parse_sensor(fields, origin)
        if sensor.name in params:
            raise fields.error("name", f"sensor name {sensor.name!r} is used twice")
        sensors.append(sensor)
        params[sensor.name] = sim
        if sensor.is_moving:
            carriers[sensor.name] = fields
    try:
        sensor_set = SensorSet(origin=origin, sensors=sensors)
    except ValueError as exc:  # pragma: no cover - positions are made consistent above
        raise ScenarioError(f"{top.source}: sensors: {exc}") from None
    # carriers may be placed relative to a ground sensor, so they are read once all sensors are known
    ctx = _Context(origin, sensor_set, duration_s, top.source)
    for name, fields in carriers.items():
        params[name] = dataclasses.replace(params[name], carrier=_parse_carrier(fields, name, ctx))
    return sensor_set, params


def _parse_sensor(f: Fields, origin: Origin) -> tuple[Sensor, RadarSimParams]:
    name = f.string("name")
    if not name:
        raise f.error("name", "must not be empty")
    kind = f.string("type", "radar-2d", choices=SCENARIO_TYPES)
    airborne = kind == "radar-airborne"
    if airborne:
        lat = lon = alt = x = y = z = None
        for key in ("lat", "lon", "alt_m", "x", "y", "z", "clutter_patches"):
            if f.has(key):
                raise f.error(key, "is not allowed for type radar-airborne (the radar flies with its carrier: give carrier)")
        if not f.has(_CARRIER_KEY):
            raise f.error(_CARRIER_KEY, "is required for type radar-airborne: the carrier's start and legs, as a target's")
    else:
        if f.has(_CARRIER_KEY):
            raise f.error(_CARRIER_KEY, "is only allowed for type radar-airborne")
        lat, lon, alt, x, y, z = _sensor_position(f, origin)
    north = f.number("north_offset_deg", None)
    if north is not None and not airborne:
        derived = SensorSet(origin, [Sensor(name=name, lat=lat, lon=lon, alt_m=alt)]).sensors[0].north_offset_deg
        if abs((north - derived + 180.0) % 360.0 - 180.0) > 1e-3:
            raise f.error(
                "north_offset_deg",
                f"is derived from the sensor position ({derived:.6f}); leave it out or give that value, got {north}",
            )
    if kind == "radar-3d":
        sigma_el = f.number("sigma_elevation_deg", ge=0.0)
    elif airborne:
        sigma_el = f.number("sigma_elevation_deg", None, ge=0.0)
    elif f.has("sigma_elevation_deg"):
        raise f.error("sigma_elevation_deg", "is only allowed for type radar-3d or radar-airborne")
    else:
        sigma_el = None
    # an airborne radar looks down as well as up
    min_el = f.number("min_elevation_deg", -90.0 if airborne else 0.0, ge=-90.0, lt=90.0)
    secondary_only = f.boolean("secondary_only", False)
    if secondary_only and airborne:
        raise f.error("secondary_only", "is only available for ground sensors (radar-2d, radar-3d), not radar-airborne")
    if secondary_only and f.has("sigma_range_rate_mps"):
        raise f.error("sigma_range_rate_mps", "is not allowed with secondary_only: an interrogator measures no range rate")
    sensor = Sensor(
        name=name,
        type=kind,
        lat=lat,
        lon=lon,
        alt_m=alt,
        x=x,
        y=y,
        z=z,
        north_offset_deg=north,
        scan_period_s=f.number("scan_period_s", gt=0.0),
        scan_phase_s=f.number("scan_phase_s", 0.0),
        sigma_range_m=f.number("sigma_range_m", ge=0.0),
        sigma_azimuth_deg=f.number("sigma_azimuth_deg", ge=0.0),
        sigma_elevation_deg=sigma_el,
        sigma_range_rate_mps=f.number("sigma_range_rate_mps", None, ge=0.0),
        max_range_m=f.number("max_range_m", gt=0.0),
        min_elevation_deg=min_el,
        p_detection=f.number("p_detection", 1.0, ge=0.0, le=1.0),
        clutter_per_scan=f.number("clutter_per_scan", 0.0, ge=0.0),
    )
    sim = RadarSimParams(
        p_mode3a=f.number("p_mode3a", 1.0, ge=0.0, le=1.0),
        p_mode_c=f.number("p_mode_c", 1.0, ge=0.0, le=1.0),
        clutter_elevation_deg=f.interval("clutter_elevation_deg", _clutter_elevation_default(min_el, airborne), ge=-90.0, le=90.0),
        clutter_range_rate_mps=f.interval("clutter_range_rate_mps", (-300.0, 300.0)),
        clutter_distribution=f.string("clutter_distribution", "range", choices=("range", "area")),
        clutter_patches=_parse_patches(f, sensor.max_range_m),
        # a false reply (fruit) of an interrogator carries a code and a height, a primary false plot none
        clutter_p_mode3a=f.number("clutter_p_mode3a", 1.0 if secondary_only else 0.0, ge=0.0, le=1.0),
        clutter_p_mode_c=f.number("clutter_p_mode_c", 1.0 if secondary_only else 0.0, ge=0.0, le=1.0),
        iff=_parse_iff(f.sub("iff", _IFF_KEYS, None)),
        secondary_only=secondary_only,
    )
    return sensor, sim


def _clutter_elevation_default(min_el: float, airborne: bool) -> tuple[float, float]:
    """False plots from the lowest elevation up 10 deg; an airborne radar's within +-10 deg of its horizontal."""
    if airborne:
        return (max(min_el, -10.0), max(min_el, 10.0))
    return (min_el, min(min_el + 10.0, 90.0))


def _parse_iff(f: Fields | None) -> IffSpec | None:
    """The IFF interrogator of a radar; ``interrogate`` is always, never or [[start, end], ...] (s)."""
    if f is None:
        return None
    policy = f.raw("interrogate", "always")
    if isinstance(policy, str):
        if policy == "track":
            raise f.error("interrogate", "track (interrogate until the status is determined) needs the tracker's "
                                         "tracks, which the simulator does not have; give always, never or time windows")
        policy = f.string("interrogate", "always", choices=("always", "never"))
    else:
        windows = []
        for path, window in f.items("interrogate"):
            if not isinstance(window, list) or len(window) != 2:
                raise f.error_at(path, f"must be a [start, end] pair of seconds, got {describe(window)}")
            start, end = (f.check_number(join_path(path, i), value, ge=0.0) for i, value in enumerate(window))
            if end < start:
                raise f.error_at(path, f"start must be <= end, got [{start:g}, {end:g}]")
            windows.append((start, end))
        if not windows:
            raise f.error("interrogate", "give at least one [start, end] window, or never")
        policy = tuple(windows)
    return IffSpec(
        p_reply=f.number("p_reply", 0.9, ge=0.0, le=1.0),
        p_flip=f.number("p_flip", 0.0, ge=0.0, le=1.0),
        p_code=f.number("p_code", 0.0, ge=0.0, le=1.0),
        false_reply_p=f.number("false_reply_p", 0.0, ge=0.0, le=1.0),
        interrogate=policy,
    )


def _parse_carrier(sensor_fields: Fields, name: str, ctx: _Context) -> TargetSpec:
    """The carrier of an airborne radar: a target's start and legs, flown from t = 0."""
    raw = sensor_fields.raw(_CARRIER_KEY)
    carrier = Fields(raw, join_path(sensor_fields.path, _CARRIER_KEY), sensor_fields.source, _CARRIER_KEYS)
    spec = _parse_target(Fields({**carrier.data, "id": name}, carrier.path, carrier.source, _CARRIER_KEYS + ("id",)), ctx)
    if spec.legs and isinstance(spec.legs[-1], LandLeg):
        raise carrier.error(f"legs[{len(spec.legs) - 1}]", "a carrier does not land (its radar would stop measuring)")
    return spec


def _parse_patches(f: Fields, max_range_m: float) -> tuple[ClutterPatch, ...]:
    patches = []
    for path, item in f.items("clutter_patches", None):
        pf = Fields(item, path, f.source, _PATCH_KEYS)
        low, high = pf.interval("range_m", ge=0.0)
        if high <= low:
            raise pf.error("range_m", f"must be [low, high] with low < high, got [{low:g}, {high:g}]")
        if high > max_range_m:
            raise pf.error("range_m", f"must lie within the instrumented range [0, {max_range_m:g}] (max_range_m), got [{low:g}, {high:g}]")
        azimuth = pf.raw("azimuth_deg")
        if not isinstance(azimuth, list) or len(azimuth) != 2:
            raise pf.error("azimuth_deg", f"must be a [from, to] pair of degrees, got {describe(azimuth)}")
        az_path = join_path(pf.path, "azimuth_deg")
        first, last = (pf.check_number(join_path(az_path, i), value, ge=0.0, le=360.0) for i, value in enumerate(azimuth))
        patch = ClutterPatch((low, high), (first, last), pf.number("per_scan", ge=0.0))
        if patch.width_deg == 0.0:
            raise pf.error("azimuth_deg", f"is an empty sector [{first:g}, {last:g}]; give [0, 360] for all azimuths")
        patches.append(patch)
    return tuple(patches)


def _sensor_position(f: Fields, origin: Origin) -> tuple[float, float, float, float, float, float]:
    """Geodetic and ENU position of a sensor, both filled so that the frames are exact WGS84."""
    geodetic = f.has("lat") or f.has("lon")
    enu = f.has("x") or f.has("y") or f.has("z")
    if geodetic and enu:
        raise f.error_at(f.path, "give the position either as lat/lon or as x/y[/z], not both")
    if geodetic:
        lat = f.number("lat", ge=-90.0, le=90.0)
        lon = f.number("lon", ge=-180.0, le=360.0)
        alt = f.number("alt_m", 0.0)
        e, n, u = geodetic_to_enu(lat, lon, alt, origin.lat, origin.lon, origin.alt_m)
        return lat, lon, alt, float(e), float(n), float(u)
    if not enu:
        raise f.error_at(f.path, "sensor position missing: give lat/lon or x/y")
    x, y = f.number("x"), f.number("y")
    if f.has("z"):
        z = f.number("z")
        lat, lon, alt = (float(v) for v in enu_to_geodetic(x, y, z, origin.lat, origin.lon, origin.alt_m))
        if f.has("alt_m") and abs(f.number("alt_m") - alt) > 1.0:
            raise f.error("alt_m", f"disagrees with z, which gives a height of {alt:.2f} m above the ellipsoid")
        return lat, lon, alt, x, y, z
    alt = f.number("alt_m", 0.0)
    z, lat, lon, _ = place_at_height(np.array([x]), np.array([y]), alt, origin)
    return float(lat[0]), float(lon[0]), alt, x, y, float(z[0])


# -- targets -------------------------------------------------------------------------------


def _horizontal_position(f: Fields, ctx: _Context, alt_m: float) -> tuple[float, float]:
    """Common-frame (x, y) of a position given as x/y, lat/lon or range/azimuth from a sensor."""
    groups = {"x/y": ("x", "y"), "lat/lon": ("lat", "lon"), "range_m/azimuth_deg/sensor": ("range_m", "azimuth_deg", "sensor")}
    present = [g for g, keys in groups.items() if any(f.has(k) for k in keys)]
    if len(present) != 1:
        what = "none" if not present else " and ".join(present)
        raise f.error_at(f.path, f"give the position as exactly one of x/y, lat/lon or range_m/azimuth_deg/sensor (got {what})")
    kind = present[0]
    if kind == "x/y":
        return f.number("x"), f.number("y")
    if kind == "lat/lon":
        e, n, _ = geodetic_to_enu(f.number("lat", ge=-90.0, le=90.0), f.number("lon", ge=-180.0, le=360.0), alt_m, *_origin_tuple(ctx.origin))
        return float(e), float(n)
    name = _ground_sensor(f, ctx)
    x, y = sensor_relative_positions(ctx.sensors[name], ctx.origin, f.number("range_m", ge=0.0), f.number("azimuth_deg"), alt_m)
    return float(x[0]), float(y[0])


def _ground_sensor(f: Fields, ctx: _Context) -> str:
    """The ``sensor`` key naming a known sensor that stands still (positions are relative to it)."""
    name = f.string("sensor")
    if name not in ctx.sensors:
        raise f.error("sensor", f"unknown sensor {name!r}; sensors: {', '.join(ctx.sensors.names)}")
    if ctx.sensors[name].is_moving:
        raise f.error("sensor", f"{name!r} is airborne: place positions relative to a ground sensor or as x/y, lat/lon")
    return name


def _origin_tuple(origin: Origin) -> tuple[float, float, float]:
    return origin.lat, origin.lon, origin.alt_m


def _parse_target(f: Fields, ctx: _Context) -> TargetSpec:
    raw_id = f.raw("id")
    if isinstance(raw_id, bool) or not isinstance(raw_id, (str, int)) or str(raw_id) == "":
        raise f.error("id", f"must be a non-empty text, got {describe(raw_id)}")
    alt = f.number("alt_m")
    x, y = _horizontal_position(f, ctx, alt)
    mode3a = _mode3a(f, "mode3a")
    icao24 = f.string("icao24", None)
    if icao24 is not None:
        icao24 = icao24.lower()
        if not _ICAO24.fullmatch(icao24):
            raise f.error("icao24", f"must be 6 hexadecimal digits such as 'a1b2c3', got {icao24!r}")
    transponder = f.boolean("transponder", mode3a is not None or icao24 is not None)
    if not transponder and (mode3a is not None or icao24 is not None):
        raise f.error("transponder", "is false but mode3a/icao24 is given")
    iff = f.string("iff", None, choices=TARGET_IFF_STATUSES)
    iff_p_reply = f.number("iff_p_reply", None, ge=0.0, le=1.0)
    if iff_p_reply is not None and iff is None:
        raise f.error("iff_p_reply", "needs iff (the target's true status, friend or foe)")
    legs = _parse_legs(f, ctx, alt)
    callsign = f.string("callsign", None)
    if callsign is not None and not _CALLSIGN.fullmatch(callsign.strip().upper()):
        raise f.error("callsign", f"must be 1-8 letters or digits such as 'AFR123', got {callsign!r}")
    adsb = f.sub("adsb", ADSB_AIRCRAFT_KEYS, None)
    return TargetSpec(
        id=str(raw_id),
        x=x,
        y=y,
        alt_m=alt,
        speed_mps=f.number("speed_mps", gt=0.0),
        heading_deg=f.number("heading_deg"),
        start_time_s=f.number("start_time_s", 0.0, ge=0.0, lt=ctx.duration_s),
        legs=legs,
        transponder=transponder,
        mode3a=mode3a,
        icao24=icao24,
        iff=iff,
        iff_p_reply=iff_p_reply,
        callsign=None if callsign is None else callsign.strip().upper(),
        adsb=None if adsb is None else parse_adsb_aircraft(adsb),
    )


def _mode3a(f: Fields, key: str) -> str | None:
    value = f.raw(key, None)
    if value is None:
        return None
    if not isinstance(value, str):
        raise f.error(key, f"must be a quoted string of 4 octal digits such as \"0100\" (YAML reads unquoted 0100 as the number 64), got {describe(value)}")
    if not _MODE3A.fullmatch(value):
        raise f.error(key, f"must be 4 octal digits (0-7), got {value!r}")
    return value


def _parse_legs(f: Fields, ctx: _Context, alt: float) -> tuple[Leg, ...]:
    """The legs of a target; a land leg must come last and start above its field."""
    items = f.items("legs", None)
    legs: list[Leg] = []
    height = alt
    for index, (path, item) in enumerate(items):
        leg = _parse_leg(path, item, f.source, ctx, alt)
        if isinstance(leg, LandLeg):
            if index != len(items) - 1:
                raise f.error_at(path, "a land leg ends the flight (the truth ends at touchdown), so it must be the last leg")
            if leg.field_alt_m >= height:
                raise f.error_at(
                    join_path(path, "field_alt_m"),
                    f"must be below the height at the start of the leg ({height:g} m), got {leg.field_alt_m:g}",
                )
        height = _height_after(leg, height)
        legs.append(leg)
    return tuple(legs)


def _height_after(leg: Leg, height: float) -> float:
    """Height at the end of a leg that starts at ``height`` (as the trajectories fly it)."""
    if isinstance(leg, ClimbLeg):
        return leg.to_alt_m if leg.to_alt_m is not None else height + leg.rate_mps * leg.duration_s
    if isinstance(leg, WaypointsLeg):
        for point in leg.points:
            height = height if point.alt_m is None else point.alt_m
        return height
    if isinstance(leg, LandLeg):
        return leg.field_alt_m
    return height


def _parse_leg(path: str, item: Any, source: str, ctx: _Context, alt: float) -> Leg:
    if not isinstance(item, dict) or "type" not in item:
        raise ScenarioError(f"{source}: {path}: must be a mapping with a 'type' key ({', '.join(LEG_TYPES)}), got {describe(item)}")
    kind = item["type"]
    if kind not in LEG_TYPES:
        raise ScenarioError(f"{source}: {join_path(path, 'type')}: must be one of {', '.join(LEG_TYPES)}, got {describe(kind)}")
    f = Fields(item, path, source, _LEG_KEYS[kind])
    if kind == "straight":
        return StraightLeg(f.number("duration_s", gt=0.0))
    if kind == "turn":
        duration, angle = f.number("duration_s", None, gt=0.0), f.number("turn_deg", None, gt=0.0)
        if (duration is None) == (angle is None):
            raise f.error_at(path, "a turn needs exactly one of duration_s or turn_deg")
        return TurnLeg(f.number("g", gt=0.0), f.string("direction", choices=("left", "right")), duration, angle)
    if kind == "climb":
        duration, to_alt = f.number("duration_s", None, gt=0.0), f.number("to_alt_m", None)
        if (duration is None) == (to_alt is None):
            raise f.error_at(path, "a climb needs exactly one of duration_s or to_alt_m")
        rate = f.number("rate_mps", gt=0.0) if to_alt is not None else f.number("rate_mps")
        if rate == 0.0:
            raise f.error("rate_mps", "must not be 0 (use a straight leg)")
        return ClimbLeg(rate, duration, to_alt)
    if kind == "accelerate":
        return AccelerateLeg(f.number("to_speed_mps", gt=0.0), f.number("rate_mps2", gt=0.0))
    if kind == "land":
        return LandLeg(f.number("rate_mps", gt=0.0), f.number("field_alt_m", 0.0))
    if kind == "singer":
        return SingerLeg(
            f.number("tau_s", gt=0.0),
            f.number("sigma_a_mps2", ge=0.0),
            f.number("duration_s", gt=0.0),
            f.interval("speed_range_mps", None, gt=0.0),
        )
    points = []
    for point_path, point in f.items("points"):
        pf = Fields(point, point_path, source, _WAYPOINT_KEYS)
        point_alt = pf.number("alt_m", None)
        px, py = _horizontal_position(pf, ctx, alt if point_alt is None else point_alt)
        points.append(Waypoint(px, py, point_alt))
    if not points:
        raise f.error("points", "at least one waypoint is needed")
    return WaypointsLeg(tuple(points), f.number("max_g", gt=0.0))


# -- traffic -------------------------------------------------------------------------------


def _parse_traffic(f: Fields, ctx: _Context) -> TrafficSpec:
    region = _parse_region(f.sub("region", ("type", "sensor", "min_range_m", "max_range_m", "x_m", "y_m")), ctx)
    codes = f.raw("mode3a_range", ["0001", "7777"])
    if not isinstance(codes, list) or len(codes) != 2:
        raise f.error("mode3a_range", f"must be a [first, last] pair of quoted octal codes, got {describe(codes)}")
    pair = Fields({"first": codes[0], "last": codes[1]}, join_path(f.path, "mode3a_range"), f.source, ("first", "last"))
    first, last = _mode3a(pair, "first"), _mode3a(pair, "last")
    if int(last, 8) < int(first, 8):
        raise f.error("mode3a_range", f"first must be <= last, got [{first!r}, {last!r}]")
    duration = ctx.duration_s
    alt = f.interval("alt_m")
    landing = f.number("landing_fraction", 0.0, ge=0.0, le=1.0)
    departure = f.number("departure_fraction", 0.0, ge=0.0, le=1.0)
    if landing + departure > 1.0:
        raise f.error("departure_fraction", f"landing_fraction + departure_fraction must be <= 1 (an aircraft lands, departs or neither), got {landing:g} + {departure:g}")
    if landing > 0.0 and alt[0] <= 0.0:
        raise f.error("alt_m", f"must be > 0 when landing_fraction > 0 (landing aircraft touch down at 0 m), got [{alt[0]:g}, {alt[1]:g}]")
    departure_alt = f.interval("departure_alt_m", (200.0, 600.0), ge=0.0)
    if departure > 0.0 and departure_alt[1] > alt[0]:
        raise f.error(
            "departure_alt_m",
            f"must lie below alt_m (departing aircraft climb from it to a height in alt_m), got [{departure_alt[0]:g}, {departure_alt[1]:g}] with alt_m [{alt[0]:g}, {alt[1]:g}]",
        )
    return TrafficSpec(
        count=f.integer("count", ge=0),
        region=region,
        alt_m=alt,
        speed_mps=f.interval("speed_mps", gt=0.0),
        heading_deg=f.interval("heading_deg", (0.0, 360.0)),
        start_time_s=f.interval("start_time_s", (0.0, 0.0), ge=0.0, le=duration),
        id_prefix=f.string("id_prefix", "T"),
        transponder_fraction=f.number("transponder_fraction", 1.0, ge=0.0, le=1.0),
        mode_s_fraction=f.number("mode_s_fraction", 0.0, ge=0.0, le=1.0),
        mode3a_allocation=f.string("mode3a_allocation", "unique", choices=("unique", "random")),
        mode3a_range=(first, last),
        maneuver_fraction=f.number("maneuver_fraction", 0.0, ge=0.0, le=1.0),
        maneuvers=_parse_maneuvers(f.sub("maneuvers", _MANEUVER_KEYS, None)),
        landing_fraction=landing,
        landing_rate_mps=f.interval("landing_rate_mps", (5.0, 10.0), gt=0.0),
        departure_fraction=departure,
        departure_alt_m=departure_alt,
    )


def _parse_region(f: Fields, ctx: _Context) -> RegionSpec:
    kind = f.string("type", choices=("annulus", "rectangle"))
    if kind == "annulus":
        for key in ("x_m", "y_m"):
            if f.has(key):
                raise f.error(key, "is only allowed for type rectangle")
        name = _ground_sensor(f, ctx)
        low = f.number("min_range_m", 0.0, ge=0.0)
        high = f.number("max_range_m", gt=low)
        return RegionSpec("annulus", sensor=name, min_range_m=low, max_range_m=high)
    for key in ("sensor", "min_range_m", "max_range_m"):
        if f.has(key):
            raise f.error(key, "is only allowed for type annulus")
    return RegionSpec("rectangle", x_m=f.interval("x_m"), y_m=f.interval("y_m"))


def _parse_maneuvers(f: Fields | None) -> ManeuverSpec:
    if f is None:
        return ManeuverSpec()
    base = ManeuverSpec()
    count = f.raw("count", list(base.count))
    count_pair = f.interval("count", base.count, ge=0.0)
    if any(not float(c).is_integer() for c in count_pair):
        raise f.error("count", f"must be whole numbers, got {describe(count)}")
    weights = dict(base.weights)
    wf = f.sub("weights", tuple(weights), None)
    if wf is not None:
        weights = {k: wf.number(k, 0.0, ge=0.0) for k in weights}
        if sum(weights.values()) <= 0.0:
            raise f.error("weights", "at least one weight must be > 0")
    return ManeuverSpec(
        count=(int(count_pair[0]), int(count_pair[1])),
        straight_s=f.interval("straight_s", base.straight_s, ge=0.0),
        weights=tuple(weights.items()),
        turn_g=f.interval("turn_g", base.turn_g, gt=0.0),
        turn_deg=f.interval("turn_deg", base.turn_deg, gt=0.0),
        climb_rate_mps=f.interval("climb_rate_mps", base.climb_rate_mps, gt=0.0),
        singer_tau_s=f.interval("singer_tau_s", base.singer_tau_s, gt=0.0),
        singer_sigma_a_mps2=f.interval("singer_sigma_a_mps2", base.singer_sigma_a_mps2, ge=0.0),
        singer_duration_s=f.interval("singer_duration_s", base.singer_duration_s, gt=0.0),
        accelerate_rate_mps2=f.interval("accelerate_rate_mps2", base.accelerate_rate_mps2, gt=0.0),
    )

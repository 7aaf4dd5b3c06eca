"""Scenario files of the simulator: YAML (or an equivalent dict) -> validated :class:`Scenario`.

Errors name the document and the key path, e.g.
``scenario.yaml: targets[3].legs[1].g: must be > 0, got -2``; unknown keys are rejected
with the list of the keys allowed at that place; duplicated YAML keys are an error.
Numbers may be written ``250e3`` (plain YAML would read that as a string).

Conventions: SI units, degrees only in keys ending in ``_deg``; the common frame is the
ENU frame at ``origin`` (x east, y north); headings and azimuths are clockwise from
north; ``alt_m`` is the height above the WGS84 ellipsoid; times are seconds since
``epoch_utc``.

Key reference
=============

Top level
---------
``name``               text, default: file name without extension
``description``        free text
``origin``             ``{lat, lon, alt_m}`` of the common ENU frame (alt_m default 0)
``epoch_utc``          ISO-8601 UTC time of t = 0 (optional, written to sensors.json)
``duration_s``         simulated time span [0, duration_s]; > 0, required
``seed``               integer >= 0 (default 0).  Trajectories, including random traffic and
                       Singer legs, depend on the seed only; sensor randomness (detection,
                       noise, clutter, SSR) comes from the Generator given to ``simulate``
                       (default: one derived from the same seed)
``truth_sample_s``     truth sampling step, default 1.0
``sensor_defaults``    mapping of sensor keys applied to every sensor that does not set them
``sensors``            list of sensors (at least one)
``targets``            list of scripted targets (optional)
``traffic``            random traffic generator (optional)

Sensors (``sensors[i]``) -- the key names of ``sensors.json`` (FORMATS.md)
----------------------------------------------------------------------
``name``                  unique text, required
``type``                  ``radar-2d`` (default) or ``radar-3d``
``lat``, ``lon``          geodetic position, or
``x``, ``y`` [, ``z``]    position in the common ENU frame (m).  Without ``z`` the sensor is at
                          height ``alt_m`` above the ellipsoid; with ``z`` its height follows
                          from z (and ``alt_m``, if given, must agree within 1 m)
``alt_m``                 antenna height above the ellipsoid, default 0
``north_offset_deg``      derived from the position (the sensor's own north); if given it must
                          agree with the derived value within 0.001 deg
``scan_period_s``         antenna revolution period, > 0, required
``scan_phase_s``          time at which the beam points north (default 0); the beam points
                          north at scan_phase_s + k scan_period_s and turns clockwise
``sigma_range_m``         range noise standard deviation >= 0, required
``sigma_azimuth_deg``     azimuth noise standard deviation >= 0, required
``sigma_elevation_deg``   elevation noise, required for radar-3d, not allowed for radar-2d
``sigma_range_rate_mps``  range-rate noise; absent/null = the radar measures no range rate
``max_range_m``           instrumented range, > 0, required
``min_elevation_deg``     lowest elevation seen, default 0 (in [-90, 90))
``p_detection``           detection probability per beam crossing in coverage, default 1
``clutter_per_scan``      Poisson mean of false plots per scan, default 0
Simulation-only keys (not written to sensors.json):
``p_mode3a``              probability that a plot of a transponder target carries Mode 3/A (default 1)
``p_mode_c``              same for Mode C (default 1)
``clutter_elevation_deg`` [low, high] elevation of false plots of a radar-3d
                          (default [min_elevation_deg, min_elevation_deg + 10])
``clutter_range_rate_mps`` [low, high] range rate of false plots (default [-300, 300])

Coverage: slant range <= max_range_m, elevation in the sensor's frame >= min_elevation_deg,
and ground distance within the 4/3-Earth radar horizon of sensor and target heights.

Targets (``targets[i]``)
------------------------
``id``             unique text (an integer is turned into text), required
``start_time_s``   time the target appears, in [0, duration_s), default 0
position, one of:  ``x``, ``y`` (common ENU, m) | ``lat``, ``lon`` |
                   ``range_m``, ``azimuth_deg``, ``sensor``: ground range and azimuth in the
                   named sensor's own frame
``alt_m``          height above the ellipsoid, required
``speed_mps``      horizontal speed > 0, required
``heading_deg``    clockwise from the common frame's north, required
``transponder``    true/false; default true when ``mode3a`` or ``icao24`` is given
``mode3a``         Mode 3/A code, a *quoted* string of 4 octal digits ("0100")
``icao24``         Mode S address, 6 hex digits (reported as ``mode_s``); needs a transponder
``legs``           list of manoeuvres flown one after the other; after the last leg the
                   target flies straight and level until ``duration_s`` or until it has
                   left the coverage of every sensor for good (outside every max range
                   and opening from every sensor)

Legs (``targets[i].legs[j]``), selected by ``type``:
``straight``    ``duration_s`` > 0
``turn``        coordinated turn: ``g`` (lateral acceleration in g, > 0), ``direction``
                ``left`` | ``right``, and exactly one of ``duration_s`` or ``turn_deg`` (> 0).
                Exact circular arc of radius v^2 / (g * 9.80665 m/s^2)
``climb``       ``rate_mps`` (vertical rate, negative = descent) with ``duration_s``, or
                ``rate_mps`` > 0 with ``to_alt_m`` (climbs or descends at that rate)
``accelerate``  ``to_speed_mps`` > 0 reached at ``rate_mps2`` > 0 along the current heading
``singer``      random manoeuvre: ``tau_s`` (manoeuvre time constant), ``sigma_a_mps2``
                (acceleration standard deviation), ``duration_s``; each horizontal axis
                follows the exact Singer model (spec 000, X1-X2) sampled every second,
                cubic-Hermite between samples; the speed is kept within
                ``speed_range_mps`` [low, high] (default [0.7 v, 1.3 v] at the leg start)
``waypoints``   ``points``: list of positions (same position keys as a target, optional
                ``alt_m``, reached linearly along the way), ``max_g`` > 0: each point is
                reached by a coordinated turn at max_g followed by a straight line through
                the point, at constant speed.  A point given by range/azimuth is placed at
                its alt_m or the target's initial altitude

Traffic (``traffic``) -- random aircraft, all drawn from ``seed``
------------------------------------------------------------------
``count``                 number of aircraft (>= 0), required
``id_prefix``             default ``T`` (ids T0000, T0001, ...)
``region``                ``{type: annulus, sensor, min_range_m, max_range_m}`` (uniform in area
                          around the sensor, in its frame) or ``{type: rectangle, x_m: [lo, hi],
                          y_m: [lo, hi]}`` (common frame)
``alt_m``                 [low, high] initial height, required
``speed_mps``             [low, high], required
``heading_deg``           [low, high], default [0, 360]
``start_time_s``          [low, high], default [0, 0]
``transponder_fraction``  default 1
``mode_s_fraction``       fraction of transponder aircraft with a Mode S address, default 0
``mode3a_allocation``     ``unique`` (distinct codes while the range lasts, then reused; default)
                          or ``random`` (independent draws, duplicates possible)
``mode3a_range``          [first, last] quoted octal codes, default ["0001", "7777"]; the special
                          codes 7000, 7500, 7600 and 7700 are never allocated
``maneuver_fraction``     fraction of aircraft flying random manoeuvres, default 0
``maneuvers``             how they manoeuvre:
    ``count`` [low, high] manoeuvres per aircraft (default [1, 3]), each preceded by a
    straight leg of ``straight_s`` [low, high] s (default [20, 120]); the kind is drawn with
    ``weights`` {turn, climb, singer, accelerate} (default 2, 1, 1, 0); parameters uniform in
    ``turn_g`` (default [1, 3]), ``turn_deg`` ([30, 180]), ``climb_rate_mps`` ([5, 20]; climbs
    to a height uniform in ``alt_m``), ``singer_tau_s`` ([10, 60]), ``singer_sigma_a_mps2``
    ([2, 10]), ``singer_duration_s`` ([30, 120]), ``accelerate_rate_mps2`` ([0.5, 2]; to a
    speed uniform in ``speed_mps``)
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Union

import numpy as np

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.geo.wgs84 import enu_to_geodetic, geodetic_to_enu
from skytrack.sim._validate import Fields, ScenarioError, describe, join_path, load_yaml
from skytrack.sim.earth import place_at_height

GRAVITY_MPS2 = 9.80665
SCENARIO_TYPES = ("radar-2d", "radar-3d")
LEG_TYPES = ("straight", "turn", "climb", "accelerate", "singer", "waypoints")
RESERVED_MODE3A = ("7000", "7500", "7600", "7700")
_MODE3A = re.compile(r"[0-7]{4}")
_ICAO24 = re.compile(r"[0-9a-f]{6}")

# ---------------------------------------------------------------------------------------
# Scenario objects
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StraightLeg:
    duration_s: float


@dataclass(frozen=True)
class TurnLeg:
    g: float
    direction: str
    duration_s: float | None = None
    turn_deg: float | None = None


@dataclass(frozen=True)
class ClimbLeg:
    rate_mps: float
    duration_s: float | None = None
    to_alt_m: float | None = None


@dataclass(frozen=True)
class AccelerateLeg:
    to_speed_mps: float
    rate_mps2: float


@dataclass(frozen=True)
class SingerLeg:
    tau_s: float
    sigma_a_mps2: float
    duration_s: float
    speed_range_mps: tuple[float, float] | None = None


@dataclass(frozen=True)
class Waypoint:
    x: float
    y: float
    alt_m: float | None = None


@dataclass(frozen=True)
class WaypointsLeg:
    points: tuple[Waypoint, ...]
    max_g: float


Leg = Union[StraightLeg, TurnLeg, ClimbLeg, AccelerateLeg, SingerLeg, WaypointsLeg]


@dataclass(frozen=True)
class TargetSpec:
    """Initial state (common ENU frame) and manoeuvres of one simulated aircraft."""

    id: str
    x: float
    y: float
    alt_m: float
    speed_mps: float
    heading_deg: float
    start_time_s: float = 0.0
    legs: tuple[Leg, ...] = ()
    transponder: bool = False
    mode3a: str | None = None
    icao24: str | None = None


@dataclass(frozen=True)
class RadarSimParams:
    """Simulation-only parameters of one radar (not part of sensors.json)."""

    p_mode3a: float = 1.0
    p_mode_c: float = 1.0
    clutter_elevation_deg: tuple[float, float] = (0.0, 10.0)
    clutter_range_rate_mps: tuple[float, float] = (-300.0, 300.0)


@dataclass(frozen=True)
class RegionSpec:
    type: str
    sensor: str | None = None
    min_range_m: float = 0.0
    max_range_m: float = 0.0
    x_m: tuple[float, float] = (0.0, 0.0)
    y_m: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class ManeuverSpec:
    count: tuple[int, int] = (1, 3)
    straight_s: tuple[float, float] = (20.0, 120.0)
    weights: tuple[tuple[str, float], ...] = (("turn", 2.0), ("climb", 1.0), ("singer", 1.0), ("accelerate", 0.0))
    turn_g: tuple[float, float] = (1.0, 3.0)
    turn_deg: tuple[float, float] = (30.0, 180.0)
    climb_rate_mps: tuple[float, float] = (5.0, 20.0)
    singer_tau_s: tuple[float, float] = (10.0, 60.0)
    singer_sigma_a_mps2: tuple[float, float] = (2.0, 10.0)
    singer_duration_s: tuple[float, float] = (30.0, 120.0)
    accelerate_rate_mps2: tuple[float, float] = (0.5, 2.0)


@dataclass(frozen=True)
class TrafficSpec:
    count: int
    region: RegionSpec
    alt_m: tuple[float, float]
    speed_mps: tuple[float, float]
    heading_deg: tuple[float, float] = (0.0, 360.0)
    start_time_s: tuple[float, float] = (0.0, 0.0)
    id_prefix: str = "T"
    transponder_fraction: float = 1.0
    mode_s_fraction: float = 0.0
    mode3a_allocation: str = "unique"
    mode3a_range: tuple[str, str] = ("0001", "7777")
    maneuver_fraction: float = 0.0
    maneuvers: ManeuverSpec = field(default_factory=ManeuverSpec)


@dataclass(frozen=True)
class Scenario:
    """A validated scenario: sensors (as :class:`SensorSet`), scripted targets and traffic."""

    name: str
    source: str
    origin: Origin
    duration_s: float
    seed: int
    truth_sample_s: float
    sensors: SensorSet
    radar_params: dict[str, RadarSimParams]
    targets: tuple[TargetSpec, ...] = ()
    traffic: TrafficSpec | None = None
    epoch_utc: str | None = None
    description: str = ""

    def all_targets(self) -> list[TargetSpec]:
        """Scripted targets followed by the traffic drawn from the seed (ids checked unique)."""
        from skytrack.sim.traffic import generate_traffic

        targets = list(self.targets)
        if self.traffic is not None and self.traffic.count > 0:
            targets += generate_traffic(self)
        seen: set[str] = set()
        for target in targets:
            if target.id in seen:
                raise ScenarioError(f"{self.source}: target id {target.id!r} is used twice (scripted targets and traffic ids must differ)")
            seen.add(target.id)
        return targets


def scale_traffic(scenario: Scenario, count: int) -> Scenario:
    """The same scenario with ``count`` random aircraft (used by the throughput benchmark)."""
    if scenario.traffic is None:
        raise ScenarioError(f"{scenario.source}: traffic: the scenario has no traffic section to scale")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ValueError(f"traffic count must be an integer >= 0, got {count!r}")
    return dataclasses.replace(scenario, traffic=dataclasses.replace(scenario.traffic, count=int(count)))


# ---------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------

_TOP_KEYS = (
    "name", "description", "origin", "epoch_utc", "duration_s", "seed", "truth_sample_s",
    "sensor_defaults", "sensors", "targets", "traffic",
)
_POSITION_KEYS = ("name", "type", "lat", "lon", "alt_m", "x", "y", "z")
_SENSOR_VALUE_KEYS = (
    "north_offset_deg", "scan_period_s", "scan_phase_s", "sigma_range_m", "sigma_azimuth_deg",
    "sigma_elevation_deg", "sigma_range_rate_mps", "max_range_m", "min_elevation_deg",
    "p_detection", "clutter_per_scan",
)
_SENSOR_SIM_KEYS = ("p_mode3a", "p_mode_c", "clutter_elevation_deg", "clutter_range_rate_mps")
_TARGET_KEYS = (
    "id", "start_time_s", "x", "y", "lat", "lon", "range_m", "azimuth_deg", "sensor", "alt_m",
    "speed_mps", "heading_deg", "transponder", "mode3a", "icao24", "legs",
)
_LEG_KEYS = {
    "straight": ("type", "duration_s"),
    "turn": ("type", "g", "direction", "duration_s", "turn_deg"),
    "climb": ("type", "rate_mps", "duration_s", "to_alt_m"),
    "accelerate": ("type", "to_speed_mps", "rate_mps2"),
    "singer": ("type", "tau_s", "sigma_a_mps2", "duration_s", "speed_range_mps"),
    "waypoints": ("type", "points", "max_g"),
}
_WAYPOINT_KEYS = ("x", "y", "lat", "lon", "range_m", "azimuth_deg", "sensor", "alt_m")
_TRAFFIC_KEYS = (
    "count", "id_prefix", "region", "alt_m", "speed_mps", "heading_deg", "start_time_s",
    "transponder_fraction", "mode_s_fraction", "mode3a_allocation", "mode3a_range",
    "maneuver_fraction", "maneuvers",
)
_MANEUVER_KEYS = (
    "count", "straight_s", "weights", "turn_g", "turn_deg", "climb_rate_mps", "singer_tau_s",
    "singer_sigma_a_mps2", "singer_duration_s", "accelerate_rate_mps2",
)

#: directory of the example scenarios shipped with the package
SCENARIO_DIR = resources.files("skytrack") / "scenarios"


def bundled_scenarios() -> list[str]:
    """Names of the example scenarios shipped with skytrack (``demo``, ``two_radars``, ...)."""
    return sorted(p.name[: -len(".yaml")] for p in SCENARIO_DIR.iterdir() if p.name.endswith(".yaml"))


def bundled_scenario_path(name: str) -> Path:
    """Path of a shipped example scenario by name (``demo`` -> .../scenarios/demo.yaml)."""
    path = SCENARIO_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ScenarioError(f"no bundled scenario named {name!r}; available: {', '.join(bundled_scenarios())}")
    return Path(str(path))


def load_scenario(source: str | Path | dict) -> Scenario:
    """Read and validate a scenario from a YAML file, a bundled scenario name or a dict."""
    if isinstance(source, dict):
        return _parse(source, "scenario", default_name="scenario")
    path = Path(source)
    if not path.exists() and path.suffix == "" and len(path.parts) == 1:
        path = bundled_scenario_path(str(source))
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{source}: cannot read scenario file: {exc.strerror or exc}") from None
    data = load_yaml(text, str(source))
    return _parse(data, str(source), default_name=path.stem)


def _parse(data: Any, source: str, default_name: str) -> Scenario:
    top = Fields(data, "", source, _TOP_KEYS)
    origin_fields = top.sub("origin", ("lat", "lon", "alt_m"))
    origin = Origin(
        lat=origin_fields.number("lat", ge=-90.0, le=90.0),
        lon=origin_fields.number("lon", ge=-180.0, le=360.0),
        alt_m=origin_fields.number("alt_m", 0.0),
    )
    duration = top.number("duration_s", gt=0.0)
    epoch = top.timestamp("epoch_utc", None)
    sensors, radar_params = _parse_sensors(top, origin)
    sensors.epoch_utc = epoch
    context = _Context(origin, sensors, duration, source)
    targets = tuple(_parse_target(Fields(item, path, source, _TARGET_KEYS), context) for path, item in top.items("targets", None))
    traffic_fields = top.sub("traffic", _TRAFFIC_KEYS, None)
    traffic = None if traffic_fields is None else _parse_traffic(traffic_fields, context)
    return Scenario(
        name=top.string("name", default_name),
        source=source,
        origin=origin,
        duration_s=duration,
        seed=top.integer("seed", 0, ge=0),
        truth_sample_s=top.number("truth_sample_s", 1.0, gt=0.0),
        sensors=sensors,
        radar_params=radar_params,
        targets=targets,
        traffic=traffic,
        epoch_utc=epoch,
        description=top.string("description", ""),
    )


@dataclass
class _Context:
    origin: Origin
    sensors: SensorSet
    duration_s: float
    source: str


# -- sensors -------------------------------------------------------------------------------


def _parse_sensors(top: Fields, origin: Origin) -> tuple[SensorSet, dict[str, RadarSimParams]]:
    defaults = top.sub("sensor_defaults", _SENSOR_VALUE_KEYS + _SENSOR_SIM_KEYS + ("type",), None)
    items = top.items("sensors")
    if not items:
        raise top.error("sensors", "at least one sensor is needed")
    sensors: list[Sensor] = []
    params: dict[str, RadarSimParams] = {}
    for path, item in items:
        if isinstance(item, dict) and defaults is not None:
            item = {**defaults.data, **item}
        fields = Fields(item, path, top.source, _POSITION_KEYS + _SENSOR_VALUE_KEYS + _SENSOR_SIM_KEYS)
        sensor, sim = _parse_sensor(fields, origin)
        if sensor.name in params:
            raise fields.error("name", f"sensor name {sensor.name!r} is used twice")
        sensors.append(sensor)
        params[sensor.name] = sim
    try:
        sensor_set = SensorSet(origin=origin, sensors=sensors)
    except ValueError as exc:  # pragma: no cover - positions are made consistent above
        raise ScenarioError(f"{top.source}: sensors: {exc}") from None
    return sensor_set, params


def _parse_sensor(f: Fields, origin: Origin) -> tuple[Sensor, RadarSimParams]:
    name = f.string("name")
    if not name:
        raise f.error("name", "must not be empty")
    kind = f.string("type", "radar-2d", choices=SCENARIO_TYPES)
    lat, lon, alt, x, y, z = _sensor_position(f, origin)
    north = f.number("north_offset_deg", None)
    if north is not None:
        derived = SensorSet(origin, [Sensor(name=name, lat=lat, lon=lon, alt_m=alt)]).sensors[0].north_offset_deg
        if abs((north - derived + 180.0) % 360.0 - 180.0) > 1e-3:
            raise f.error(
                "north_offset_deg",
                f"is derived from the sensor position ({derived:.6f}); leave it out or give that value, got {north}",
            )
    if kind == "radar-3d":
        sigma_el = f.number("sigma_elevation_deg", ge=0.0)
    elif f.has("sigma_elevation_deg"):
        raise f.error("sigma_elevation_deg", "is only allowed for type radar-3d")
    else:
        sigma_el = None
    min_el = f.number("min_elevation_deg", 0.0, ge=-90.0, lt=90.0)
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
        clutter_elevation_deg=f.interval("clutter_elevation_deg", (min_el, min(min_el + 10.0, 90.0)), ge=-90.0, le=90.0),
        clutter_range_rate_mps=f.interval("clutter_range_rate_mps", (-300.0, 300.0)),
    )
    return sensor, sim


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
    name = f.string("sensor")
    if name not in ctx.sensors:
        raise f.error("sensor", f"unknown sensor {name!r}; sensors: {', '.join(ctx.sensors.names)}")
    x, y = sensor_relative_positions(ctx.sensors[name], ctx.origin, f.number("range_m", ge=0.0), f.number("azimuth_deg"), alt_m)
    return float(x[0]), float(y[0])


def _origin_tuple(origin: Origin) -> tuple[float, float, float]:
    return origin.lat, origin.lon, origin.alt_m


def sensor_relative_positions(sensor: Sensor, origin: Origin, ground_range_m, azimuth_deg, alt_m) -> tuple[np.ndarray, np.ndarray]:
    """Common-frame (x, y) of points at ground range / azimuth in a sensor's own frame and height ``alt_m``."""
    ground = np.atleast_1d(np.asarray(ground_range_m, dtype=float))
    az = np.radians(np.atleast_1d(np.asarray(azimuth_deg, dtype=float)))
    alt = np.broadcast_to(np.asarray(alt_m, dtype=float), ground.shape)
    sensor_origin = Origin(sensor.lat, sensor.lon, sensor.alt_m)
    _, lat, lon, _ = place_at_height(ground * np.sin(az), ground * np.cos(az), alt, sensor_origin)
    x, y, _ = geodetic_to_enu(lat, lon, alt, *_origin_tuple(origin))
    return np.asarray(x), np.asarray(y)


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
    legs = tuple(_parse_leg(path, item, f.source, ctx, alt) for path, item in f.items("legs", None))
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
    return TrafficSpec(
        count=f.integer("count", ge=0),
        region=region,
        alt_m=f.interval("alt_m"),
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
    )


def _parse_region(f: Fields, ctx: _Context) -> RegionSpec:
    kind = f.string("type", choices=("annulus", "rectangle"))
    if kind == "annulus":
        for key in ("x_m", "y_m"):
            if f.has(key):
                raise f.error(key, "is only allowed for type rectangle")
        name = f.string("sensor")
        if name not in ctx.sensors:
            raise f.error("sensor", f"unknown sensor {name!r}; sensors: {', '.join(ctx.sensors.names)}")
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


__all__ = [
    "AccelerateLeg",
    "ClimbLeg",
    "GRAVITY_MPS2",
    "Leg",
    "ManeuverSpec",
    "RadarSimParams",
    "RegionSpec",
    "Scenario",
    "ScenarioError",
    "SingerLeg",
    "StraightLeg",
    "TargetSpec",
    "TrafficSpec",
    "TurnLeg",
    "Waypoint",
    "WaypointsLeg",
    "bundled_scenario_path",
    "bundled_scenarios",
    "load_scenario",
    "scale_traffic",
    "sensor_relative_positions",
]

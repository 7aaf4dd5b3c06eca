"""Scenarios of the manoeuvring-target studies (spec 004 §6, R19): named, from YAML, or recorded.

A scenario yields one or more :class:`Case` objects: a truth trajectory sampled at the scan
times ``k T``, its manoeuvres (onset, end), and the radar that measures it.

Named scripted scenarios (common defaults of §6: radar at the ENU origin, T = 1 s,
sigma_r = 25 m, sigma_az = sigma_el = 1.5 mrad, start (-10 000, 40 000, 6 000) m at
(250, 0, 0) m/s):

* ``default`` — straight 40 s, left coordinated turn of n g0 through 180 deg, straight 30 s;
  one case per n (parameter ``n``, default 3, 5, 7);
* ``weave`` — straight 40 s, then 4 alternating +-4 g turns of 90 deg separated by 10 s
  straight, straight 30 s;
* ``vertical`` — straight 40 s, 3 g pull-up for 10 s, 1 g longitudinal acceleration for 10 s,
  straight 30 s;
* ``fighter`` — the default legs with T = 0.1 s, sigma_r = 10 m, sigma_angle = 2 mrad, the start
  moved along its line of sight to 20 km from the radar, n in 3, 5, 7, 9.

A scenario file (YAML) holds one scripted trajectory::

    name: my-turn                      # optional (default: the file's stem)
    dt_s: 1.0                          # optional, default 1
    sensor: {sigma_range_m: 25, sigma_azimuth_mrad: 1.5, sigma_elevation_mrad: 1.5}
    start: {position_m: [-10000, 40000, 6000], velocity_mps: [250, 0, 0]}
    legs:
      - {type: straight, duration_s: 40}
      - {type: turn, g: 5, direction: left, turn_deg: 180}     # or duration_s
      - {type: pull_up, g: 3, duration_s: 10}                  # direction up|down
      - {type: accelerate, g: 1, duration_s: 10}               # along the velocity
      - {type: straight, duration_s: 30}

Recorded trajectories come from :mod:`skytrack.studies.maneuver.recorded` (``--truth FILE``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from skytrack.studies.maneuver.trajectory import Kinematics, Leg, accelerate, fly, pull_up, straight, turn

DEFAULT_START_POSITION = (-10_000.0, 40_000.0, 6_000.0)
DEFAULT_START_VELOCITY = (250.0, 0.0, 0.0)
DEFAULT_TURN_G = (3.0, 5.0, 7.0)
FIGHTER_TURN_G = (3.0, 5.0, 7.0, 9.0)
FIGHTER_RANGE_M = 20_000.0
NAMED_SCENARIOS = ("default", "weave", "vertical", "fighter")


@dataclass(frozen=True)
class SensorSpec:
    """A 3-D radar: position (ENU m), range and angle noise (m, rad)."""

    sigma_range_m: float = 25.0
    sigma_azimuth_rad: float = 1.5e-3
    sigma_elevation_rad: float = 1.5e-3
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("sigma_range_m", "sigma_azimuth_rad", "sigma_elevation_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"sensor {name} must be > 0, got {value}")

    @classmethod
    def from_dict(cls, values: dict, base: "SensorSpec | None" = None) -> "SensorSpec":
        """Config keys ``sigma_range_m``, ``sigma_azimuth_mrad``, ``sigma_elevation_mrad``, ``sigma_angle_mrad``, ``position_m``."""
        base = base or cls()
        known = {"sigma_range_m", "sigma_azimuth_mrad", "sigma_elevation_mrad", "sigma_angle_mrad", "position_m"}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"sensor: unknown key(s) {unknown}; known: {sorted(known)}")
        angle = values.get("sigma_angle_mrad")
        az = values.get("sigma_azimuth_mrad", angle)
        el = values.get("sigma_elevation_mrad", angle)
        return cls(
            sigma_range_m=float(values.get("sigma_range_m", base.sigma_range_m)),
            sigma_azimuth_rad=base.sigma_azimuth_rad if az is None else float(az) * 1e-3,
            sigma_elevation_rad=base.sigma_elevation_rad if el is None else float(el) * 1e-3,
            position=tuple(float(v) for v in values.get("position_m", base.position)),
        )


@dataclass(frozen=True)
class Case:
    """One truth trajectory to run the filters on: scans ``0..K-1`` at ``truth.time = k dt``."""

    scenario: str
    label: str
    dt: float
    truth: Kinematics
    maneuvers: list[tuple[float, float]]
    sensor: SensorSpec = field(default_factory=SensorSpec)
    params: dict = field(default_factory=dict)

    @property
    def scans(self) -> int:
        return len(self.truth)


def _scan_times(duration_s: float, dt: float) -> np.ndarray:
    count = int(math.floor(duration_s / dt + 1e-9)) + 1
    return np.arange(count) * dt


def scripted_case(scenario: str, label: str, start_position, start_velocity, legs, dt: float,
                  sensor: SensorSpec, params: dict | None = None) -> Case:
    """Fly ``legs`` and sample the truth at ``k dt`` (see :func:`skytrack.studies.maneuver.trajectory.fly`)."""
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"scenario dt must be > 0, got {dt}")
    path = fly(start_position, start_velocity, legs)
    truth = path.evaluate(_scan_times(path.duration_s, dt))
    return Case(scenario, label, float(dt), truth, path.maneuvers(), sensor, dict(params or {}))


def default_legs(n: float) -> list[Leg]:
    return [straight(40.0), turn(n, 180.0, "left"), straight(30.0)]


def weave_legs(n: float = 4.0) -> list[Leg]:
    legs = [straight(40.0)]
    for i, direction in enumerate(("left", "right", "left", "right")):
        legs.append(turn(n, 90.0, direction))
        legs.append(straight(10.0 if i < 3 else 30.0))
    return legs


def vertical_legs() -> list[Leg]:
    return [straight(40.0), pull_up(3.0, duration_s=10.0), accelerate(1.0, 10.0), straight(30.0)]


def named_cases(name: str, *, dt: float | None = None, sensor: SensorSpec | None = None,
                turn_g: tuple[float, ...] | None = None) -> list[Case]:
    """The cases of a named scenario (module docstring); ``dt``, ``sensor`` and ``turn_g`` override its defaults."""
    if name not in NAMED_SCENARIOS:
        raise ValueError(f"--scenario: unknown scenario {name!r}; named scenarios: {', '.join(NAMED_SCENARIOS)} (or a YAML file)")
    if name == "fighter":
        sensor = sensor or SensorSpec(sigma_range_m=10.0, sigma_azimuth_rad=2e-3, sigma_elevation_rad=2e-3)
        dt = 0.1 if dt is None else dt
        start = np.array(DEFAULT_START_POSITION) * FIGHTER_RANGE_M / np.linalg.norm(DEFAULT_START_POSITION)
        return [scripted_case(name, f"fighter n={g:g}", start, DEFAULT_START_VELOCITY, default_legs(g), dt, sensor, {"n": g})
                for g in (turn_g or FIGHTER_TURN_G)]
    sensor = sensor or SensorSpec()
    dt = 1.0 if dt is None else dt
    if name == "default":
        return [scripted_case(name, f"default n={g:g}", DEFAULT_START_POSITION, DEFAULT_START_VELOCITY, default_legs(g), dt,
                              sensor, {"n": g}) for g in (turn_g or DEFAULT_TURN_G)]
    if name == "weave":
        return [scripted_case(name, "weave", DEFAULT_START_POSITION, DEFAULT_START_VELOCITY, weave_legs(), dt, sensor, {"n": 4.0})]
    return [scripted_case(name, "vertical", DEFAULT_START_POSITION, DEFAULT_START_VELOCITY, vertical_legs(), dt, sensor, {"n": 3.0})]


_LEG_KEYS = {"type", "duration_s", "g", "turn_deg", "direction"}
_FILE_KEYS = {"name", "dt_s", "sensor", "start", "legs"}


def parse_scenario(values: dict, default_name: str, *, dt: float | None = None, sensor: SensorSpec | None = None) -> Case:
    """A :class:`Case` from the YAML mapping of a scenario file (module docstring)."""
    if not isinstance(values, dict):
        raise ValueError("scenario file: expected a mapping at the top level")
    unknown = sorted(set(values) - _FILE_KEYS)
    if unknown:
        raise ValueError(f"scenario file: unknown key(s) {unknown}; known: {sorted(_FILE_KEYS)}")
    start = values.get("start") or {}
    if not isinstance(start, dict) or set(start) - {"position_m", "velocity_mps"}:
        raise ValueError("scenario file: start takes position_m and velocity_mps")
    position = start.get("position_m", DEFAULT_START_POSITION)
    velocity = start.get("velocity_mps", DEFAULT_START_VELOCITY)
    if len(position) != 3 or len(velocity) != 3:
        raise ValueError("scenario file: start position_m and velocity_mps need 3 values (ENU)")
    items = values.get("legs")
    if not isinstance(items, list) or not items:
        raise ValueError("scenario file: legs must be a non-empty list")
    legs = []
    for index, item in enumerate(items):
        if not isinstance(item, dict) or "type" not in item:
            raise ValueError(f"scenario file: legs[{index}] must be a mapping with a type")
        bad = sorted(set(item) - _LEG_KEYS)
        if bad:
            raise ValueError(f"scenario file: legs[{index}] has unknown key(s) {bad}; known: {sorted(_LEG_KEYS)}")
        try:
            legs.append(Leg(**item))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"scenario file: legs[{index}]: {exc}") from None
    name = str(values.get("name", default_name))
    base_sensor = sensor or SensorSpec()
    if "sensor" in values:
        base_sensor = SensorSpec.from_dict(values["sensor"] or {}, base_sensor)
    step = float(values.get("dt_s", 1.0)) if dt is None else dt
    return scripted_case(name, name, position, velocity, legs, step, base_sensor)


def load_scenario_file(path: str | Path, *, dt: float | None = None, sensor: SensorSpec | None = None) -> Case:
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--scenario: {path} is neither a named scenario ({', '.join(NAMED_SCENARIOS)}) nor a file")
    with open(path, encoding="utf-8") as handle:
        values = yaml.safe_load(handle)
    try:
        return parse_scenario(values, path.stem, dt=dt, sensor=sensor)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def recorded_cases(path: str | Path, *, dt: float = 1.0, sensor: SensorSpec | None = None, **options) -> list[Case]:
    """One case per recorded (target, segment) of a truth file (``options``: those of
    :func:`skytrack.studies.maneuver.recorded.load_recorded`)."""
    from skytrack.studies.maneuver.recorded import load_recorded

    sensor = sensor or SensorSpec()
    return [Case("recorded", item.label, float(dt), item.truth, item.maneuvers, sensor, {"start_time": item.start_time})
            for item in load_recorded(path, dt, **options)]


def with_sensor(cases: list[Case], sensor: SensorSpec) -> list[Case]:
    return [replace(case, sensor=sensor) for case in cases]

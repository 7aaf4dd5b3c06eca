"""``sensors.json`` (FORMATS.md): reader and writer of :class:`skytrack.geo.SensorSet`.

Validation: ``format_version`` is version 1 (written ``"1"``, ``1``, ``"1.0"`` or any
``1.x``, as other tools write it); ``epoch_utc``, when given, is a timestamp;
``origin`` has ``lat`` in [-90, 90], ``lon`` in [-180, 180] and a finite ``alt_m``; each
sensor has a unique non-empty ``name`` and a ``type`` in ``SENSOR_TYPES``; numbers are
numbers (not text, not booleans) and finite, within plausibility limits far beyond any
surveillance sensor (``_RULES``: e.g. ``0 < sigma_range_m <= 1e5``, ``0.001 <= scan_period_s <=
3600``, ``0 <= p_detection <= 1``); radars have
``sigma_range_m`` and ``sigma_azimuth_deg``, a ``radar-3d`` also ``sigma_elevation_deg``,
ground radars (they rotate) ``scan_period_s``;
a sensor's position is known (lat/lon or x/y, except airborne radars and ADS-B) and,
when both are given, consistent.  ASTERIX identities ``sac`` and ``sic`` (optional, issue
11): integers in [0, 255], given together, no two sensors with the same pair.

Top-level defaults: a top-level key named like a :class:`~skytrack.geo.Sensor` field
(e.g. ``"scan_period_s": 4.0``) is the default of every sensor that does not give a
value; a per-sensor ``null`` counts as "not given".  Unknown per-sensor keys go to
``Sensor.extra``, unknown top-level keys to ``SensorSet.extra``; both are written back.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from skytrack.geo.sensors import SENSOR_TYPES, Origin, Sensor, SensorSet
from skytrack.io.checks import parse_epoch
from skytrack.io.errors import InputError

FORMAT_VERSION = "1"

#: Sensor fields that a file may set (and that may have top-level defaults)
SENSOR_KEYS = tuple(f.name for f in dataclasses.fields(Sensor) if f.name not in ("extra", "position", "rotation"))
#: ASTERIX SAC/SIC (issue 11): integers 0-255, given together, a pair used by one sensor only
_INTEGER_KEYS = ("sac", "sic")
_NUMERIC_KEYS = tuple(k for k in SENSOR_KEYS if k not in ("name", "type", *_INTEGER_KEYS))
_TOP_LEVEL_KEYS = ("format_version", "epoch_utc", "origin", "sensors")

# key -> (predicate, rule text)
_RULES: dict[str, tuple[Any, str]] = {
    "lat": (lambda v: -90 <= v <= 90, "must be in [-90, 90]"),
    "lon": (lambda v: -180 <= v <= 180, "must be in [-180, 180]"),
    # upper limits: far beyond any surveillance sensor, below what breaks the arithmetic
    # (a sigma of 1e300 overflowed the covariance, a scan period of 1e-320 s the output clock)
    "scan_period_s": (lambda v: 1e-3 <= v <= 3600, "must be in [0.001, 3600]"),
    "sigma_range_m": (lambda v: 0 < v <= 1e5, "must be in (0, 1e+05]"),
    "sigma_azimuth_deg": (lambda v: 0 < v <= 45, "must be in (0, 45]"),
    "sigma_elevation_deg": (lambda v: 0 < v <= 45, "must be in (0, 45]"),
    "sigma_range_rate_mps": (lambda v: 0 < v <= 1e4, "must be in (0, 1e+04]"),
    "max_range_m": (lambda v: 0 < v <= 1e7, "must be in (0, 1e+07]"),
    "alt_m": (lambda v: -1e4 <= v <= 1e6, "must be in [-1e+04, 1e+06]"),
    "clutter_per_scan": (lambda v: 0 <= v <= 1e7, "must be in [0, 1e+07]"),
    "min_elevation_deg": (lambda v: -90 <= v <= 90, "must be in [-90, 90]"),
    "p_detection": (lambda v: 0 <= v <= 1, "must be in [0, 1]"),
}


class _Where:
    """Builds errors located in one part of the file."""

    def __init__(self, file: str, where: str | None = None) -> None:
        self.file = file
        self.where = where

    def error(self, message: str, key: str | None = None) -> InputError:
        return InputError(message, file=self.file, where=self.where, key=key)


def _show(value: Any) -> str:
    if isinstance(value, float) and math.isfinite(value) and abs(value) < 1e15 and value == int(value):
        return str(int(value))
    if isinstance(value, float):
        return f"{value:g}"
    return json.dumps(value) if isinstance(value, str) else repr(value)


def is_version_one(version: Any) -> bool:
    """Whether a ``format_version`` value means version 1: ``"1"``, ``1``, ``1.0``, ``"1.0"``
    or ``"1.x"`` with x digits (not a boolean)."""
    if isinstance(version, bool):
        return False
    if isinstance(version, int):
        return version == 1
    if isinstance(version, float):
        return 1.0 <= version < 2.0
    if isinstance(version, str):
        major, dot, minor = version.strip().partition(".")
        return major == "1" and (not dot or minor.isdigit())
    return False


def _number(value: Any, key: str, where: _Where) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise where.error(f"{key} must be a number, got {_show(value)}", key)
    try:
        number = float(value)
    except OverflowError:
        digits = int(value.bit_length() * math.log10(2)) + 1
        raise where.error(f"{key} is out of range (an integer of about {digits} digits)", key) from None
    if not math.isfinite(number):
        raise where.error(f"{key} must be finite, got {_show(value)}", key)
    rule = _RULES.get(key)
    if rule is not None and not rule[0](number):
        raise where.error(f"{key} {rule[1]}, got {_show(value)}", key)
    return number


def _origin(data: dict, where: _Where) -> Origin:
    if "origin" not in data or data["origin"] is None:
        raise where.error("origin is missing (it gives the lat/lon/alt_m of the ENU frame)", "origin")
    raw = data["origin"]
    at = _Where(where.file, "origin")
    if not isinstance(raw, dict):
        raise at.error(f"must be an object with lat, lon, alt_m, got {_show(raw)}", "origin")
    for key in ("lat", "lon"):
        if raw.get(key) is None:
            raise at.error(f"{key} is missing", key)
    alt = raw.get("alt_m")
    return Origin(
        lat=_number(raw["lat"], "lat", at),
        lon=_number(raw["lon"], "lon", at),
        alt_m=0.0 if alt is None else _number(alt, "alt_m", at),
    )


def _sensor(raw: Any, index: int, defaults: dict[str, Any], file: str) -> Sensor:
    name = raw.get("name") if isinstance(raw, dict) else None
    label = f"sensors[{index}]" + (f" ({name!r})" if isinstance(name, str) and name else "")
    where = _Where(file, label)
    if not isinstance(raw, dict):
        raise where.error(f"must be an object, got {_show(raw)}")
    if not isinstance(name, str) or not name.strip():
        raise where.error(f"name must be a non-empty string, got {_show(name)}", "name")
    merged = {k: v for k, v in defaults.items()}
    merged.update({k: v for k, v in raw.items() if v is not None or k not in defaults})
    sensor_type = merged.get("type", "radar-2d")
    if sensor_type is None:
        sensor_type = "radar-2d"
    if sensor_type not in SENSOR_TYPES:
        raise where.error(f"type must be one of {', '.join(SENSOR_TYPES)}, got {_show(sensor_type)}", "type")
    values: dict[str, Any] = {"name": name, "type": sensor_type}
    for key in _NUMERIC_KEYS:
        if merged.get(key) is not None:
            values[key] = _number(merged[key], key, where)
        elif key in merged:
            values[key] = None
    for key in _INTEGER_KEYS:
        value = merged.get(key)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int):
            raise where.error(f"{key} must be an integer in [0, 255] (ASTERIX), got {_show(value)}", key)
        if not 0 <= value <= 255:
            raise where.error(f"{key} must be in [0, 255] (an ASTERIX octet), got {_show(value)}", key)
        values[key] = value
    if ("sac" in values) != ("sic" in values):
        missing = "sic" if "sac" in values else "sac"
        raise where.error(f"{missing} is missing: an ASTERIX source is named by sac and sic together", missing)
    needed = []
    if sensor_type.startswith("radar"):
        needed = ["sigma_range_m", "sigma_azimuth_deg"] + (["sigma_elevation_deg"] if sensor_type == "radar-3d" else [])
    for key in needed:
        if values.get(key) is None:
            raise where.error(f"{key} is required for a {sensor_type} sensor", key)
    if sensor_type in ("radar-2d", "radar-3d") and values.get("scan_period_s") is None:
        raise where.error(f"scan_period_s is required for a {sensor_type} sensor (the antenna's revolution "
                          "period, per sensor or at the top level)", "scan_period_s")
    has_geodetic = values.get("lat") is not None and values.get("lon") is not None
    has_enu = values.get("x") is not None and values.get("y") is not None
    if not (has_geodetic or has_enu or sensor_type in ("radar-airborne", "adsb")):
        raise where.error("position unknown: give lat and lon, or x and y", "lat")
    extra = {k: v for k, v in raw.items() if k not in SENSOR_KEYS}
    return Sensor(**values, extra=extra)


def sensor_set_from_dict(data: Any, file: str = "sensors.json") -> SensorSet:
    """Validate the parsed JSON of a ``sensors.json`` file and build the SensorSet."""
    top = _Where(file)
    if not isinstance(data, dict):
        raise top.error("the top level must be a JSON object")
    version = data.get("format_version")
    if version is None:
        raise top.error(f'format_version is missing (expected "{FORMAT_VERSION}")', "format_version")
    if not is_version_one(version):
        raise top.error(f'format_version must be version 1 ("1", 1, "1.0" or "1.x"), got {_show(version)}',
                        "format_version")
    version = FORMAT_VERSION
    epoch = data.get("epoch_utc")
    if epoch is not None:
        if not isinstance(epoch, str):
            raise top.error(f"epoch_utc must be an ISO 8601 UTC text, got {_show(epoch)}", "epoch_utc")
        try:
            parse_epoch(epoch)
        except InputError as exc:
            raise top.error(exc.message, "epoch_utc") from None
    origin = _origin(data, top)
    raw_sensors = data.get("sensors")
    if not isinstance(raw_sensors, list):
        raise top.error(f"sensors must be a list, got {_show(raw_sensors)}", "sensors")
    defaults = {k: v for k, v in data.items() if k in SENSOR_KEYS and k != "name" and v is not None}
    sensors = [_sensor(raw, i, defaults, file) for i, raw in enumerate(raw_sensors)]
    seen: dict[str, int] = {}
    seen_pairs: dict[tuple[int, int], int] = {}
    for i, sensor in enumerate(sensors):
        if sensor.name in seen:
            raise _Where(file, f"sensors[{i}] ({sensor.name!r})").error(
                f"name repeats sensors[{seen[sensor.name]}]", "name"
            )
        seen[sensor.name] = i
        if sensor.sac is not None:
            pair = (sensor.sac, sensor.sic)
            if pair in seen_pairs:
                raise _Where(file, f"sensors[{i}] ({sensor.name!r})").error(
                    f"sac/sic {pair[0]}/{pair[1]} repeats sensors[{seen_pairs[pair]}]: each ASTERIX source needs "
                    "its own pair", "sic")
            seen_pairs[pair] = i
        try:  # resolves the frame of this sensor alone, to name it in the error
            SensorSet(origin, [dataclasses.replace(sensor, extra=dict(sensor.extra))])
        except ValueError as exc:
            raise _Where(file, f"sensors[{i}] ({sensor.name!r})").error(str(exc)) from None
    extra = {k: v for k, v in data.items() if k not in _TOP_LEVEL_KEYS and k not in SENSOR_KEYS}
    return SensorSet(origin=origin, sensors=sensors, epoch_utc=epoch, format_version=version, extra=extra)


def read_sensors(path: str | Path) -> SensorSet:
    """Read and validate ``sensors.json``; :class:`InputError` names the file, sensor and key."""
    path = Path(path)
    file = str(path)
    if not path.exists():
        raise InputError("file not found", file=file)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read ({exc})", file=file) from None
    try:
        data = json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg} at character {exc.colno})", file=file, line=exc.lineno) from None
    except RecursionError:
        raise InputError("not valid sensors JSON (nested too deeply)", file=file) from None
    except ValueError as exc:  # NaN/Infinity, or an integer literal beyond Python's digit limit
        raise InputError(f"not valid sensors JSON ({exc})", file=file) from None
    return sensor_set_from_dict(data, file)


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number that sensors.json may hold")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_sensors(sensor_set: SensorSet, path: str | Path) -> Path:
    """Write ``sensors.json`` (validated as on reading), creating parent directories."""
    path = Path(path)
    data = sensor_set.to_dict()
    try:
        text = json.dumps(data, indent=2, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise InputError(f"cannot encode as JSON ({exc})", file=f"sensors to write to {path}") from None
    sensor_set_from_dict(json.loads(text), f"sensors to write to {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text + "\n", encoding="utf-8")
    return path

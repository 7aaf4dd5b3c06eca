"""Plot chunks straight from Arrow arrays to a :class:`~skytrack.core.plots.PlotBatch`.

The fast path of :func:`skytrack.io.iter_plot_batches`: a chunk from the Parquet or CSV
stream is checked with whole-column numpy operations for every rule of
:func:`skytrack.io.plots._validate_plots` (module docstring of :mod:`skytrack.io.plots`)
and, when every row passes, converted to a batch without a DataFrame.  This module only
answers "is every row good?": on the first failed check, or a column type it does not
handle (timestamps, numbers in an identity column, ...), :func:`plot_batch_from_arrow`
returns ``None`` and the caller runs the detailed pandas validation, which locates,
describes and counts the problems.  So messages, lenient counts and warnings are always
those of the detailed path, and a good chunk gives the batch that path would give
(tests/io/test_io_plot_arrays.py compares the two on good and bad input).

Text columns are handled through their dictionary (Parquet stores them so, the CSV
stream encodes them once): each distinct value is checked and parsed once.

:class:`PlotStream` is what the checks of one chunk hand on to the next (both paths).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from skytrack.core.plots import FT_TO_M, IFF_VALUES, PLATFORM_COLUMNS, PlotBatch
from skytrack.geo.sensors import SensorSet

#: identity codes as the detailed checks accept them (mode_s is lower-cased there first)
_MODE3A = re.compile(r"[0-7]{4}")
_ICAO24_EITHER_CASE = re.compile(r"[0-9a-fA-F]{6}")
_IFF_CODES = {value: k for k, value in enumerate(IFF_VALUES)}
_REQUIRED = ("time", "sensor", "range_m", "azimuth_deg")


#: Mode C altitudes outside this range are refused: the code spans -1 000 to 126 700 ft
MODE_C_RANGE_FT = (-1500.0, 130_000.0)

@dataclass
class PlotStream:
    """What the checks of one chunk pass on to the next, so that a file read in chunks is
    checked like a whole file: the epoch inferred from the first chunk with timestamps,
    the latest time of every sensor (time order across chunks), and the value ranges
    behind the unit warnings (given once, for the whole file)."""

    epoch: object = None
    last_time: dict[str, float] = field(default_factory=dict)
    rows: int = 0
    largest_range: float = -math.inf
    largest_azimuth: float = -math.inf

    def add_units(self, range_m: np.ndarray, azimuth: np.ndarray) -> None:
        self.rows += len(range_m)
        self.largest_range = max(self.largest_range, float(np.nanmax(np.asarray(range_m, dtype=float), initial=-np.inf)))
        self.largest_azimuth = max(self.largest_azimuth, float(np.nanmax(np.asarray(azimuth, dtype=float), initial=-np.inf)))

    def add_latest(self, sensors, latest) -> None:
        """Raise the latest time of each sensor in ``sensors`` to the matching ``latest``."""
        for sensor, time in zip(sensors, latest, strict=True):
            self.last_time[str(sensor)] = max(float(time), self.last_time.get(str(sensor), -math.inf))


def plot_batch_from_arrow(table: pa.Table | pa.RecordBatch, sensors: SensorSet, stream: PlotStream) -> PlotBatch | None:
    """The batch of a chunk whose every row is good, else ``None`` (nothing is changed then).

    ``batch.row`` counts from 0 (the caller shifts it).  On success ``stream`` takes the
    chunk's latest times and value ranges, as the detailed path's would.
    """
    count = table.num_rows
    names = set(table.schema.names)
    if count == 0 or not names.issuperset(_REQUIRED):
        return None
    time = _numbers(table, "time")
    if time is None or not np.isfinite(time).all():
        return None
    sensor = _sensor_index(table, sensors)
    if sensor is None or not _in_time_order(time, sensor, sensors.names, stream.last_time):
        return None
    range_m, azimuth = _numbers(table, "range_m"), _numbers(table, "azimuth_deg")
    if range_m is None or azimuth is None or not _all_good_numbers(range_m, azimuth):
        return None
    optional = {name: _optional_numbers(table, name, count) for name in ("elevation_deg", "range_rate_mps", "mode_c_ft")}
    if any(values is None or np.isinf(values).any() for values in optional.values()):
        return None
    elevation, mode_c = optional["elevation_deg"], optional["mode_c_ft"]
    if ((elevation < -90) | (elevation > 90)).any():  # NaN compares False: absent is fine
        return None
    if ((mode_c < MODE_C_RANGE_FT[0]) | (mode_c > MODE_C_RANGE_FT[1])).any():
        return None
    if not _scan_ok(table) or not _extra_text_ok(table):
        return None
    mode3a = _codes(table, "mode3a", _mode3a, np.int32)
    mode_s = _codes(table, "mode_s", _icao24, np.int32)
    if "icao24" in names and _codes(table, "icao24", _icao24, np.int32) is None:  # checked like mode_s
        return None
    iff = _codes(table, "iff", _IFF_CODES.get, np.int8)
    if names.intersection(PLATFORM_COLUMNS):
        platform = [_optional_numbers(table, name, count) for name in PLATFORM_COLUMNS]
        if any(values is None for values in platform):
            return None
        platform = np.column_stack(platform)
    else:
        platform = np.full((count, 6), np.nan)
    if mode3a is None or mode_s is None or iff is None:
        return None
    airborne = np.array([s.is_moving for s in sensors.sensors], dtype=bool)
    if airborne.any() and (airborne[sensor] & ~np.isfinite(platform[:, :3]).all(axis=1)).any():
        return None  # an airborne radar's plot without its carrier's position: the detailed path says where

    stream.add_units(range_m, azimuth)
    present, latest = _latest_per_sensor(time, sensor)
    stream.add_latest([sensors.names[k] for k in present], latest)
    # as PlotBatch.from_frame converts a validated table (the same numpy operations)
    return PlotBatch(
        time=time, sensor=sensor, range_m=range_m * 1.0, azimuth=np.radians(azimuth),
        elevation=np.radians(elevation), range_rate=optional["range_rate_mps"] * 1.0,
        mode_c_m=optional["mode_c_ft"] * FT_TO_M, mode3a=mode3a, mode_s=mode_s, iff=iff,
        platform=platform, row=np.arange(count, dtype=np.int64),
    )


# the same codes come back chunk after chunk (the dictionaries of Parquet row groups):
# each distinct text is parsed once per run
@functools.lru_cache(maxsize=1 << 16)
def _mode3a(text: str) -> int | None:
    return int(text, 8) if _MODE3A.fullmatch(text) else None


@functools.lru_cache(maxsize=1 << 16)
def _icao24(text: str) -> int | None:
    return int(text, 16) if _ICAO24_EITHER_CASE.fullmatch(text) else None


def _is_number_type(kind: pa.DataType) -> bool:
    return pa.types.is_integer(kind) or pa.types.is_floating(kind)


def _numbers(table, name: str) -> np.ndarray | None:
    """A numeric column as a fresh float64 array (NaN where null); ``None`` for other types."""
    column = table.column(name)
    if not _is_number_type(column.type):
        return None
    values = column.to_numpy() if isinstance(column, pa.ChunkedArray) else column.to_numpy(zero_copy_only=False)
    return np.array(values, dtype=np.float64)  # a copy: the batch owns writable arrays


def _optional_numbers(table, name: str, count: int) -> np.ndarray | None:
    """An optional numeric column: all NaN when absent or all null."""
    if name not in table.schema.names or pa.types.is_null(table.schema.field(name).type):
        return np.full(count, np.nan)
    return _numbers(table, name)


def _all_good_numbers(range_m: np.ndarray, azimuth: np.ndarray) -> bool:
    """Ranges finite and >= 0, azimuths finite in [0, 360) (NaN fails every comparison)."""
    return bool((range_m >= 0).all() and np.isfinite(range_m).all() and ((azimuth >= 0) & (azimuth < 360)).all())


def _scan_ok(table) -> bool:
    """``scan``: integers (nulls allowed), or floats that are whole numbers or NaN."""
    if "scan" not in table.schema.names:
        return True
    kind = table.schema.field("scan").type
    if pa.types.is_integer(kind) or pa.types.is_null(kind):
        return True
    if not pa.types.is_floating(kind):
        return False
    values = _numbers(table, "scan")
    known = values[~np.isnan(values)]
    return bool(np.isfinite(known).all() and (known == np.round(known)).all())


def _extra_text_ok(table) -> bool:
    """``truth_id`` and ``callsign`` are only made text by the detailed path: text, numbers or
    nulls convert (other types are left to it)."""
    for name in ("truth_id", "callsign"):
        if name in table.schema.names:
            kind = table.schema.field(name).type
            kind = kind.value_type if pa.types.is_dictionary(kind) else kind
            if not (_is_text(kind) or _is_number_type(kind) or pa.types.is_null(kind)):
                return False
    return True


def _is_text(kind: pa.DataType) -> bool:
    return pa.types.is_string(kind) or pa.types.is_large_string(kind)


def _dictionary(table, name: str) -> tuple[np.ndarray, list[str]] | None:
    """Indices (-1 = null) and distinct values of a text column; ``None`` if it is not text."""
    column = table.column(name)
    if isinstance(column, pa.ChunkedArray):
        column = column.combine_chunks()
    if pa.types.is_dictionary(column.type):
        if not _is_text(column.type.value_type):
            return None
        encoded = column
    elif _is_text(column.type):
        encoded = column.dictionary_encode()
    else:
        return None
    indices = encoded.indices
    if indices.null_count:
        indices = indices.fill_null(-1)
    return indices.to_numpy(), encoded.dictionary.to_pylist()


def _used(indices: np.ndarray, size: int) -> np.ndarray:
    """Which of ``size`` dictionary entries the rows use (a chunk may use part of a row group's)."""
    used = np.zeros(size + 1, dtype=bool)  # the last entry stands for null (index -1)
    used[indices] = True
    return used[:size]


def _codes(table, name: str, parse, dtype) -> np.ndarray | None:
    """Integer codes of an optional identity column (-1 = absent); ``None`` if a value used
    by a row does not parse (``parse`` returns ``None``) or the column is not text."""
    count = table.num_rows
    if name not in table.schema.names or pa.types.is_null(table.schema.field(name).type):
        return np.full(count, -1, dtype=dtype)
    found = _dictionary(table, name)
    if found is None:
        return None
    indices, values = found
    parsed = [None if value is None else parse(value) for value in values]
    if None in parsed and any(code is None and used for code, used in zip(parsed, _used(indices, len(values)),
                                                                              strict=True)):
        return None
    lookup = np.array([-1 if code is None else code for code in parsed] + [-1], dtype=dtype)
    return lookup[indices]  # index -1 takes the last entry: absent


def _sensor_index(table, sensors: SensorSet) -> np.ndarray | None:
    """Sensor set indices of the rows; ``None`` when a sensor is null, empty or unknown."""
    found = _dictionary(table, "sensor")
    if found is None:
        return None
    indices, values = found
    if (indices < 0).any():
        return None
    position = {name: k for k, name in enumerate(sensors.names)}
    known = [value != "" and value in position for value in values]
    if not all(known) and any(use and not ok for ok, use in zip(known, _used(indices, len(values)), strict=True)):
        return None
    lookup = np.array([position.get(value, -1) for value in values], dtype=np.int16)
    return lookup[indices]


def _in_time_order(time: np.ndarray, sensor: np.ndarray, names: list[str], last_time: dict[str, float]) -> bool:
    """No time earlier than an earlier time of its sensor, in this chunk or the earlier ones."""
    carry = np.array([last_time.get(name, -np.inf) for name in names])
    if len(time) and (sensor == sensor[0]).all():
        return bool(time[0] >= carry[sensor[0]] and (time[1:] >= time[:-1]).all())
    order = np.argsort(sensor, kind="stable")
    by_sensor, times = sensor[order], time[order]
    same = by_sensor[1:] == by_sensor[:-1]
    firsts = np.flatnonzero(np.concatenate([[True], ~same]))
    return bool(((times[1:] >= times[:-1]) | ~same).all() and (times[firsts] >= carry[by_sensor[firsts]]).all())


def _latest_per_sensor(time: np.ndarray, sensor: np.ndarray) -> tuple[list[int], list[float]]:
    """The sensors present in a chunk and the latest time of each."""
    if (sensor == sensor[0]).all():
        return [int(sensor[0])], [float(time.max())]
    present = np.flatnonzero(np.bincount(sensor))
    return [int(k) for k in present], [float(time[sensor == k].max()) for k in present]

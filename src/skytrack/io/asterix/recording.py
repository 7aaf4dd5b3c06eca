"""A simulated ASTERIX recording (issue 11 item 2: ``skytrack simulate ... --format asterix``).

- CAT048 plots (I048/010, 140, 020, 040, 070, 090, 220) and CAT034 north markers
  (I034/010, 000, 030) assembled with numpy over all records (:func:`plot_record_bytes`,
  :func:`service_record_bytes`), byte for byte the records of the libasterix encoder
  ``skytrack.io.asterix.encode`` (tested);
- CAT021 ADS-B reports assembled with numpy (``skytrack.io.asterix.cat021.cat021_record_bytes``),
  byte for byte the records of the libasterix encoder ``cat021.encode_cat021`` (tested);
- one north marker per antenna revolution of every rotating radar: at
  ``scan_phase_s + k * scan_period_s`` within the simulated time span (:func:`north_markers`);
- all records in time order (CAT034 before CAT048 before CAT021 at equal times), each run of
  one category in data blocks of at most 128 records (:func:`encode_recording`);
- SAC/SIC: a radar's ``sac``/``sic`` from sensors.json, else assigned in sensor order
  (SAC 0, SIC 1, 2, ... skipping pairs in use) and written back to sensors.json
  (:func:`with_sac_sic`); the ADS-B ground station's pair is the top-level
  ``"adsb_station": {"sac", "sic"}`` (default SAC 0, SIC 101).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Mapping

import numpy as np
import pandas as pd

from skytrack.io.asterix import units as u
from skytrack.io.asterix.bytes_assembly import (
    assemble_records,
    big_endian,
    blocks_from_records,
    codes_of_texts,
    distinct_texts,
    finite_column,
    icao24_code,
    mode3a_code,
    time_of_day_raw,
)

DEFAULT_ADSB_STATION = (0, 101)
MAX_RECORDS_PER_BLOCK = 128
#: plot-time span of a data block when blocks are cut like a radar's sectors (1/32 of a 4 s scan)
SECTOR_BLOCK_S = 0.125


def _sensor_pair(sensor) -> tuple[int, int] | None:
    sac = getattr(sensor, "sac", None) if hasattr(sensor, "sac") else sensor.extra.get("sac")
    sic = getattr(sensor, "sic", None) if hasattr(sensor, "sic") else sensor.extra.get("sic")
    return None if sac is None or sic is None else (int(sac), int(sic))


def with_sac_sic(sensor_set, *, adsb: bool = False):
    """The sensor set with a (SAC, SIC) for every sensor (see the module docstring) and, with
    ``adsb``, the ADS-B station's pair at the top level; and the map sensor name -> (SAC, SIC)."""
    from skytrack.geo.sensors import Sensor, SensorSet

    has_fields = "sac" in {f.name for f in dataclasses.fields(Sensor)}
    taken = {pair for pair in map(_sensor_pair, sensor_set.sensors) if pair is not None}
    extra = dict(sensor_set.extra)
    if adsb:
        extra.setdefault("adsb_station", {"sac": DEFAULT_ADSB_STATION[0], "sic": DEFAULT_ADSB_STATION[1]})
        taken.add(adsb_station(sensor_set.__class__(sensor_set.origin, [], extra=extra)))
    next_sic, sensors, pairs = 1, [], {}
    for sensor in sensor_set.sensors:
        pair = _sensor_pair(sensor)
        if pair is None:
            while (0, next_sic) in taken:
                next_sic += 1
            pair = (0, next_sic)
            taken.add(pair)
            sensor = (dataclasses.replace(sensor, sac=pair[0], sic=pair[1]) if has_fields
                      else dataclasses.replace(sensor, extra={**sensor.extra, "sac": pair[0], "sic": pair[1]}))
        sensors.append(sensor)
        pairs[sensor.name] = pair
    return SensorSet(sensor_set.origin, sensors, sensor_set.epoch_utc, sensor_set.format_version, extra), pairs


def adsb_station(sensor_set) -> tuple[int, int]:
    station = sensor_set.extra.get("adsb_station") or {}
    return int(station.get("sac", DEFAULT_ADSB_STATION[0])), int(station.get("sic", DEFAULT_ADSB_STATION[1]))


def north_markers(sensor_set, start_s: float, end_s: float) -> pd.DataFrame:
    """One north marker per revolution of every radar with a scan period and phase, in [start_s, end_s]."""
    times, names = [], []
    for sensor in sensor_set.sensors:
        period, phase = sensor.scan_period_s, sensor.scan_phase_s
        if sensor.type == "adsb" or period is None or phase is None:
            continue
        first, last = np.ceil((start_s - phase) / period), np.floor((end_s - phase) / period)
        k = np.arange(first, last + 1)
        times.append(phase + k * period)
        names.extend([sensor.name] * k.size)
    time = np.concatenate(times) if times else np.empty(0)
    return pd.DataFrame({"time": time, "sensor": pd.Series(names, dtype=object), "message": "north_marker"})


def _sac_sic_raw(sensors: np.ndarray, sac_sic: Mapping[str, tuple[int, int]], what: str) -> np.ndarray:
    names, index = np.unique(sensors.astype(str), return_inverse=True)
    missing = sorted(set(names) - set(sac_sic))
    if missing:
        raise ValueError(f"{what}: no SAC/SIC for sensor(s) {', '.join(missing)}")
    pairs = np.array([sac_sic[name][0] * 256 + sac_sic[name][1] for name in names], np.int64)
    return pairs[index] if pairs.size else np.zeros(0, np.int64)


def _in_range(raw: np.ndarray, present: np.ndarray, low: int, high: int, column: str) -> None:
    bad = present & ((raw < low) | (raw > high))
    if bad.any():
        raise ValueError(f"plots: row {int(np.flatnonzero(bad)[0])}, column {column}: value outside what the item "
                         "can hold")


def plot_record_bytes(plots: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *,
                      ssr_only_sensors: Collection[str] = (), time_of_day_at_epoch_s: float = 0.0
                      ) -> tuple[np.ndarray, np.ndarray]:
    """CAT048 records of ``plots`` (the items and rules of ``encode.plot_records``) assembled with numpy."""
    n = len(plots)
    time = finite_column(plots, "time", "plots")
    rho = np.rint(finite_column(plots, "range_m", "plots") / u.RHO_LSB_M).astype(np.int64)
    _in_range(rho, np.ones(n, bool), 0, 65535, "range_m")
    theta = np.mod(np.rint(finite_column(plots, "azimuth_deg", "plots") / u.THETA_LSB_DEG).astype(np.int64), 65536)
    distinct, index = distinct_texts(plots, "mode3a")
    has_3a, code3a = index >= 0, codes_of_texts(distinct, index, mode3a_code, "mode3a", "plots")
    distinct, index = distinct_texts(plots, "mode_s")
    has_s, address = index >= 0, codes_of_texts(distinct, index, icao24_code, "mode_s", "plots")
    mode_c = plots["mode_c_ft"].to_numpy(float) if "mode_c_ft" in plots.columns else np.full(n, np.nan)
    has_c = ~np.isnan(mode_c)
    quarter_fl = np.where(has_c, np.rint(np.nan_to_num(mode_c) / u.FLIGHT_LEVEL_LSB_FT), 0).astype(np.int64)
    _in_range(quarter_fl, has_c, -(1 << 13), (1 << 13) - 1, "mode_c_ft")
    primary = ~np.isin(plots["sensor"].astype(str).to_numpy(), list(ssr_only_sensors))
    has_ssr = has_3a | has_c | has_s
    typ = np.where(has_s, np.where(primary, u.TYP_MODE_S_ROLL_CALL_PSR, u.TYP_MODE_S_ROLL_CALL),
                   np.where(has_ssr, np.where(primary, u.TYP_SSR_PSR, u.TYP_SSR), u.TYP_PSR))
    typ = np.where(~primary & ~has_ssr, u.TYP_NO_DETECTION, typ)
    always = np.ones(n, bool)
    columns = [
        (0, always, [(always, big_endian(_sac_sic_raw(plots["sensor"].to_numpy(), sac_sic, "plots"), 2))]),
        (1, always, [(always, big_endian(time_of_day_raw(time, time_of_day_at_epoch_s), 3))]),
        (2, always, [(always, big_endian(typ << 5, 1))]),
        (3, always, [(always, big_endian((rho << 16) | theta, 4))]),
        (4, has_3a, [(always, big_endian(code3a, 2))]),
        (5, has_c, [(always, big_endian(quarter_fl & 0x3FFF, 2))]),
        (7, has_s, [(always, big_endian(address, 3))]),
    ]
    return assemble_records(n, columns)


def service_record_bytes(service: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *,
                         time_of_day_at_epoch_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """CAT034 north-marker records (I034/010, 000, 030) assembled with numpy."""
    n = len(service)
    if (service["message"].astype(str).to_numpy() != "north_marker").any():
        raise ValueError("service messages: only north markers are assembled here (encode.service_records writes "
                         "sector crossings)")
    time = finite_column(service, "time", "service messages")
    always = np.ones(n, bool)
    columns = [
        (0, always, [(always, big_endian(_sac_sic_raw(service["sensor"].to_numpy(), sac_sic, "service messages"), 2))]),
        (1, always, [(always, big_endian(np.full(n, u.NORTH_MARKER), 1))]),
        (2, always, [(always, big_endian(time_of_day_raw(time, time_of_day_at_epoch_s), 3))]),
    ]
    return assemble_records(n, columns)


def encode_recording(plots: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *,
                     service: pd.DataFrame | None = None, adsb: pd.DataFrame | None = None,
                     adsb_sac_sic: tuple[int, int] = DEFAULT_ADSB_STATION, origin=None,
                     time_of_day_at_epoch_s: float = 0.0, max_records_per_block: int = MAX_RECORDS_PER_BLOCK,
                     ssr_only_sensors: Collection[str] = (), block_span_s: float | None = None,
                     progress: Callable[[float], None] | None = None) -> bytes:
    """CAT034 north markers, CAT048 plots and CAT021 ADS-B reports as one time-ordered byte string
    (with plots alone: byte for byte ``encode.encode_asterix``'s output, at about 5 x 10^5 plots/s).

    With ``block_span_s`` a new data block also starts at every multiple of that many seconds, as
    a radar sends each sector's plots as soon as the sector is swept: a block then never holds
    plots further apart than that, which bounds the delay a replay's whole-block datagrams add."""
    if block_span_s is not None and not block_span_s > 0:
        raise ValueError(f"block_span_s must be positive, got {block_span_s}")
    report = progress or (lambda fraction: None)
    parts = []  # (time, category, rank at equal times, record bytes, starts)
    if service is not None and len(service):
        parts.append((service["time"].to_numpy(float), 34, 0,
                      *service_record_bytes(service, sac_sic, time_of_day_at_epoch_s=time_of_day_at_epoch_s)))
    if len(plots):
        parts.append((plots["time"].to_numpy(float), 48, 1,
                      *plot_record_bytes(plots, sac_sic, ssr_only_sensors=ssr_only_sensors,
                                         time_of_day_at_epoch_s=time_of_day_at_epoch_s)))
    report(0.1)
    if adsb is not None and len(adsb):
        from skytrack.io.asterix.cat021 import cat021_record_bytes

        parts.append((adsb["time"].to_numpy(float), 21, 2,
                      *cat021_record_bytes(adsb, adsb_sac_sic, origin=origin,
                                           time_of_day_at_epoch_s=time_of_day_at_epoch_s)))
    if not parts:
        return b""
    time = np.concatenate([p[0] for p in parts])
    category = np.concatenate([np.full(p[0].size, p[1]) for p in parts])
    rank = np.concatenate([np.full(p[0].size, p[2]) for p in parts])
    buffer = np.concatenate([p[3] for p in parts])
    shift = np.cumsum([0] + [p[3].size for p in parts[:-1]])
    starts = np.concatenate([p[4][:-1] + s for p, s in zip(parts, shift)])
    lengths = np.concatenate([np.diff(p[4]) for p in parts])
    order = np.lexsort((np.arange(time.size), rank, time))  # stable: each source keeps its own order
    sorted_lengths = lengths[order]
    sorted_starts = np.concatenate([[0], np.cumsum(sorted_lengths)]).astype(np.int64)
    source = np.repeat(starts[order] - sorted_starts[:-1], sorted_lengths) + np.arange(sorted_starts[-1])
    new_block = None
    if block_span_s is not None:
        slot = np.floor(np.rint(time[order] / u.TIME_LSB_S) * u.TIME_LSB_S / block_span_s)  # on the times written
        new_block = np.concatenate([[True], slot[1:] != slot[:-1]])
    data = blocks_from_records(buffer[source], sorted_starts, max_records_per_block, category[order], new_block)
    report(1.0)
    return data

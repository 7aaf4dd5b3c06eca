"""CAT062 system tracks (edition 1.21) from the tracks table (issue 11 item 2: ``track ... -o tracks.ast``).

Items written, in UAP order (docs/formats.md, "ASTERIX CAT062"):

- I062/010 SDPS SAC/SIC (the system's, :func:`system_sac_sic`), I062/015 service id,
  I062/070 time of track information (1/128 s, time of day), always;
- I062/105 WGS-84 position (180/2^25 deg) when ``lat``/``lon`` are known;
- I062/100 Cartesian position relative to the system reference, the ``sensors.json`` origin
  (``x``/``y``, 0.5 m), always;
- I062/185 Cartesian velocity (``vx``/``vy``, 0.25 m/s) when known;
- I062/060 Mode 3/A (``mode3a``); I062/380 ADR (``icao24``) and ID (``callsign``) when known;
- I062/040 track number (``track_id`` modulo 65 536: the item has 16 bits);
- I062/080 track status, 4 octets: CNF 1 for a row without ``status`` (tentative), CST for
  ``coasting``, TSB on a track's first row, MON for a one-radar system, MRH and SRC
  (3-D radar) when the height is geometric;
- I062/136 measured flight level (1/4 FL) from ``alt_m`` in 2-D tracking (the last Mode C
  height), or I062/130 geometric altitude (6.25 ft) in 3-D tracking (``z`` known);
- I062/220 rate of climb (``vz``, 6.25 ft/min) when known;
- I062/500 APC (sqrt of ``var_x``/``var_y``, 0.5 m), ATV (sqrt of ``var_vx``/``var_vy``,
  0.25 m/s), AGA (sqrt of ``var_z``, 6.25 ft, with I062/130), saturated at the subfields' maxima.

:func:`encode_cat062` assembles the bytes with numpy over all rows (no per-record Python):
every item is a column of bytes scattered into one buffer at offsets computed from the
presence of the items (:mod:`skytrack.io.asterix.bytes_assembly`, shared with CAT048/034/021).  It is tested byte for byte against libasterix's encoder
(:func:`reference_records`).  :func:`decode_cat062` reads any CAT062 edition 1.21 data with
libasterix (the reference decoder) into a tracks-table-like DataFrame.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from skytrack.io.asterix.bytes_assembly import (
    assemble_records,
    big_endian,
    blocks_from_records,
    callsign_code,
    codes_of_texts,
    distinct_texts,
    icao24_code,
    mode3a_code,
)

CATEGORY = 62
FEET_M = 0.3048
TIME_LSB_S = 1.0 / 128.0
LATLON_LSB_DEG = 180.0 / 2**25
XY_LSB_M = 0.5
V_LSB_MPS = 0.25
ALTITUDE_LSB_M = 6.25 * FEET_M
FLIGHT_LEVEL_LSB_M = 25.0 * FEET_M
CLIMB_LSB_MPS = 6.25 * FEET_M / 60.0
SECONDS_PER_DAY = 86400.0
#: the system's SAC/SIC when sensors.json has no top-level "system": {"sac", "sic"}
DEFAULT_SYSTEM_SAC_SIC = (0, 100)
DEFAULT_SERVICE_ID = 1
MAX_RECORDS_PER_BLOCK = 128
_WHAT = "tracks to CAT062"  # the start of every error message about a tracks row

#: (item, FRN index from 0, size in bytes or 0 when variable), in UAP order
_ITEMS = (("010", 0, 2), ("015", 2, 1), ("070", 3, 3), ("105", 4, 8), ("100", 5, 6), ("185", 6, 4), ("060", 8, 2),
          ("380", 10, 0), ("040", 11, 2), ("080", 12, 4), ("136", 16, 2), ("130", 17, 2), ("220", 19, 2),
          ("500", 26, 0))


def _spec():
    import asterix.generated as gen

    return gen.Cat_062_1_21


def system_sac_sic(extra: Mapping | None) -> tuple[int, int]:
    """The system's (SAC, SIC) from sensors.json's top level ``"system": {"sac", "sic"}``
    (``SensorSet.extra``), else :data:`DEFAULT_SYSTEM_SAC_SIC`."""
    system = (extra or {}).get("system")
    if system is None:
        return DEFAULT_SYSTEM_SAC_SIC
    try:
        sac, sic = int(system["sac"]), int(system["sic"])
    except (TypeError, KeyError, ValueError):
        raise ValueError(f'sensors.json: "system" must be {{"sac": int, "sic": int}}, got {system!r}') from None
    if not (0 <= sac <= 255 and 0 <= sic <= 255):
        raise ValueError(f"sensors.json: system SAC/SIC must be in [0, 255], got {(sac, sic)}")
    return sac, sic


def time_of_day_at_epoch(epoch_utc: str | None) -> float:
    """Seconds since UTC midnight of ``epoch_utc`` (0 when the epoch is unknown: time counts from midnight)."""
    if not epoch_utc:
        return 0.0
    stamp = pd.Timestamp(epoch_utc)
    stamp = stamp.tz_convert("UTC") if stamp.tzinfo is not None else stamp
    return float((stamp - stamp.normalize()).total_seconds())


def _floats(tracks: pd.DataFrame, name: str) -> np.ndarray:
    if name not in tracks.columns:
        return np.full(len(tracks), np.nan)
    return pd.to_numeric(tracks[name], errors="coerce").to_numpy(float, na_value=np.nan)



def _quantise(values: np.ndarray, lsb: float, bits: int, signed: bool, present: np.ndarray, column: str) -> np.ndarray:
    raw = np.zeros(values.size, np.int64)
    raw[present] = np.rint(values[present] / lsb).astype(np.int64)
    low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    bad = present & ((raw < low) | (raw > high))
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"tracks to CAT062: row {row}, column {column}: {values[row]!r} is outside what the "
                         f"item can hold ({low * lsb:g} to {high * lsb:g})")
    return raw & ((1 << bits) - 1)


def _saturated(std: np.ndarray, lsb: float, bits: int, present: np.ndarray) -> np.ndarray:
    raw = np.zeros(std.size, np.int64)
    raw[present] = np.minimum(np.rint(std[present] / lsb), (1 << bits) - 1).astype(np.int64)
    return raw






def quantise_tracks(tracks: pd.DataFrame, *, sac_sic: tuple[int, int] = DEFAULT_SYSTEM_SAC_SIC,
                    service_id: int = DEFAULT_SERVICE_ID, time_of_day_at_epoch_s: float = 0.0,
                    monosensor: bool = False, begun: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The raw integer of every field written, and the presence of every optional item, per row.

    ``begun`` marks the rows that begin a track (I062/080 TSB); by default a track's first row
    in ``tracks``."""
    n = len(tracks)
    time = _floats(tracks, "time")
    x, y = _floats(tracks, "x"), _floats(tracks, "y")
    for name, values in (("time", time), ("x", x), ("y", y)):
        if not np.isfinite(values).all():
            raise ValueError(f"tracks to CAT062: row {int(np.flatnonzero(~np.isfinite(values))[0])}, column {name}: "
                             "a finite number is required")
    track_id = tracks["track_id"].to_numpy(np.int64)
    if (track_id < 0).any():
        raise ValueError(f"tracks to CAT062: row {int(np.flatnonzero(track_id < 0)[0])}, column track_id: negative")
    lat, lon = _floats(tracks, "lat"), _floats(tracks, "lon")
    vx, vy, vz, z = _floats(tracks, "vx"), _floats(tracks, "vy"), _floats(tracks, "vz"), _floats(tracks, "z")
    alt = _floats(tracks, "alt_m")
    raw: dict[str, np.ndarray] = {}
    raw["sac"], raw["sic"] = np.full(n, sac_sic[0]), np.full(n, sac_sic[1])
    raw["service_id"] = np.full(n, service_id)
    seconds = np.mod(time + time_of_day_at_epoch_s, SECONDS_PER_DAY)
    raw["time_of_day"] = np.mod(np.rint(seconds / TIME_LSB_S).astype(np.int64), int(SECONDS_PER_DAY / TIME_LSB_S))
    raw["has_105"] = np.isfinite(lat) & np.isfinite(lon)
    raw["lat"] = _quantise(lat, LATLON_LSB_DEG, 32, True, raw["has_105"], "lat")
    raw["lon"] = _quantise(lon, LATLON_LSB_DEG, 32, True, raw["has_105"], "lon")
    everywhere = np.ones(n, bool)
    raw["x"], raw["y"] = (_quantise(v, XY_LSB_M, 24, True, everywhere, c) for v, c in ((x, "x"), (y, "y")))
    raw["has_185"] = np.isfinite(vx) & np.isfinite(vy)
    raw["vx"], raw["vy"] = (_quantise(v, V_LSB_MPS, 16, True, raw["has_185"], c) for v, c in ((vx, "vx"), (vy, "vy")))
    distinct, index = distinct_texts(tracks, "mode3a")
    raw["has_060"], raw["mode3a"] = index >= 0, codes_of_texts(distinct, index, mode3a_code, "mode3a", _WHAT)
    distinct, index = distinct_texts(tracks, "icao24")
    raw["has_adr"], raw["address"] = index >= 0, codes_of_texts(distinct, index, icao24_code, "icao24", _WHAT)
    distinct, index = distinct_texts(tracks, "callsign")
    raw["has_id"], raw["callsign"] = index >= 0, codes_of_texts(distinct, index, callsign_code, "callsign", _WHAT)
    raw["track_number"] = track_id & 0xFFFF
    geometric = np.isfinite(z) & np.isfinite(alt)
    raw["has_130"], raw["has_136"] = geometric, ~np.isfinite(z) & np.isfinite(alt)
    raw["altitude"] = _quantise(alt / FEET_M, 6.25, 16, True, geometric, "alt_m")
    raw["flight_level"] = _quantise(alt / FEET_M / 100.0, 0.25, 16, True, raw["has_136"], "alt_m")
    raw["has_220"] = np.isfinite(vz)
    raw["climb"] = _quantise(vz / FEET_M * 60.0, 6.25, 16, True, raw["has_220"], "vz")
    status = tracks["status"].astype(object).to_numpy() if "status" in tracks.columns else np.full(n, None)
    if begun is None:
        begun = np.zeros(n, bool)
        begun[np.unique(track_id, return_index=True)[1]] = True
    raw["status"] = (
        (int(monosensor) << 31) | (geometric.astype(np.int64) << 29) | (np.where(geometric, 2, 0) << 26)
        | (pd.isna(status).astype(np.int64) << 25) | (1 << 24)
        | (np.asarray(begun, np.int64) << 21) | (1 << 16) | (1 << 8)
        | ((status == "coasting").astype(np.int64) << 7))
    std_x, std_y = np.sqrt(_floats(tracks, "var_x")), np.sqrt(_floats(tracks, "var_y"))
    std_vx, std_vy, std_z = (np.sqrt(_floats(tracks, c)) for c in ("var_vx", "var_vy", "var_z"))
    raw["has_apc"] = np.isfinite(std_x) & np.isfinite(std_y)
    raw["has_atv"] = np.isfinite(std_vx) & np.isfinite(std_vy)
    raw["has_aga"] = np.isfinite(std_z) & geometric
    raw["apc_x"], raw["apc_y"] = (_saturated(s, XY_LSB_M, 16, raw["has_apc"]) for s in (std_x, std_y))
    raw["atv_x"], raw["atv_y"] = (_saturated(s, V_LSB_MPS, 8, raw["has_atv"]) for s in (std_vx, std_vy))
    raw["aga"] = _saturated(std_z / FEET_M, 6.25, 8, raw["has_aga"])
    return raw



def _item_columns(raw: dict[str, np.ndarray]) -> list[tuple[int, np.ndarray, list[np.ndarray]]]:
    """Per item in UAP order: FRN index, presence, and the byte columns (rows, k) of its parts in
    order (a part of a variable item is written only where its own presence holds)."""
    n = raw["x"].size
    always = np.ones(n, bool)
    has_380 = raw["has_adr"] | raw["has_id"]
    has_500 = raw["has_apc"] | raw["has_atv"] | raw["has_aga"]
    primary_380 = (raw["has_adr"].astype(np.int64) << 7) | (raw["has_id"].astype(np.int64) << 6)
    primary_500 = ((raw["has_apc"].astype(np.int64) << 7) | (raw["has_aga"].astype(np.int64) << 4)
                   | (raw["has_atv"].astype(np.int64) << 2))
    parts = {
        "010": [(always, big_endian((raw["sac"] << 8) | raw["sic"], 2))],
        "015": [(always, big_endian(raw["service_id"], 1))],
        "070": [(always, big_endian(raw["time_of_day"], 3))],
        "105": [(always, big_endian((raw["lat"] << 32) | raw["lon"], 8))],
        "100": [(always, big_endian((raw["x"] << 24) | raw["y"], 6))],
        "185": [(always, big_endian((raw["vx"] << 16) | raw["vy"], 4))],
        "060": [(always, big_endian(raw["mode3a"], 2))],
        "380": [(always, big_endian(primary_380, 1)), (raw["has_adr"], big_endian(raw["address"], 3)),
                (raw["has_id"], big_endian(raw["callsign"], 6))],
        "040": [(always, big_endian(raw["track_number"], 2))],
        "080": [(always, big_endian(raw["status"], 4))],
        "136": [(always, big_endian(raw["flight_level"], 2))],
        "130": [(always, big_endian(raw["altitude"], 2))],
        "220": [(always, big_endian(raw["climb"], 2))],
        "500": [(always, big_endian(primary_500, 1)), (raw["has_apc"], big_endian((raw["apc_x"] << 16) | raw["apc_y"], 4)),
                (raw["has_aga"], big_endian(raw["aga"], 1)),
                (raw["has_atv"], big_endian((raw["atv_x"] << 8) | raw["atv_y"], 2))],
    }
    presence = {"105": raw["has_105"], "185": raw["has_185"], "060": raw["has_060"], "380": has_380,
                "136": raw["has_136"], "130": raw["has_130"], "220": raw["has_220"], "500": has_500}
    return [(frn, presence.get(item, always), parts[item]) for item, frn, _ in _ITEMS]



def record_bytes(raw: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """All CAT062 records back to back (uint8) and each record's start offset (one more: the end)."""
    return assemble_records(raw["x"].size, _item_columns(raw))



def encode_cat062(tracks: pd.DataFrame, *, sac_sic: tuple[int, int] = DEFAULT_SYSTEM_SAC_SIC,
                  service_id: int = DEFAULT_SERVICE_ID, time_of_day_at_epoch_s: float = 0.0, monosensor: bool = False,
                  begun: np.ndarray | None = None, max_records_per_block: int = MAX_RECORDS_PER_BLOCK) -> bytes:
    """One CAT062 record per tracks row (in row order), in data blocks; see the module docstring."""
    if max_records_per_block < 1:
        raise ValueError("max_records_per_block must be at least 1")
    raw = quantise_tracks(tracks, sac_sic=sac_sic, service_id=service_id, time_of_day_at_epoch_s=time_of_day_at_epoch_s,
                          monosensor=monosensor, begun=begun)
    return blocks_from_records(*record_bytes(raw), max_records_per_block, CATEGORY)


def reference_records(raw: dict[str, np.ndarray]) -> list:
    """The same records built with libasterix (the reference encoder), one per row of ``raw``."""
    spec = _spec()
    records = []
    for i in range(raw["x"].size):
        s = int(raw["status"][i])
        items: dict = {
            "010": (("SAC", int(raw["sac"][i])), ("SIC", int(raw["sic"][i]))), "015": int(raw["service_id"][i]),
            "070": int(raw["time_of_day"][i]), "100": (("X", int(raw["x"][i])), ("Y", int(raw["y"][i]))),
            "040": int(raw["track_number"][i]),
            # every group of the extended item ends with None, its FX bit (libasterix sets it)
            "080": ((("MON", s >> 31 & 1), ("SPI", 0), ("MRH", s >> 29 & 1), ("SRC", s >> 26 & 7), ("CNF", s >> 25 & 1),
                     None), (0, 0, ("TSB", s >> 21 & 1), 0, 0, 0, 0, None), 0, (("CST", s >> 7 & 1), 0, 0, 0, 0, 0, 0, None)),
        }
        if raw["has_105"][i]:
            items["105"] = (("LAT", int(raw["lat"][i])), ("LON", int(raw["lon"][i])))
        if raw["has_185"][i]:
            items["185"] = (("VX", int(raw["vx"][i])), ("VY", int(raw["vy"][i])))
        if raw["has_060"][i]:
            items["060"] = (0, 0, 0, 0, ("MODE3A", int(raw["mode3a"][i])))
        sub380 = {}
        if raw["has_adr"][i]:
            sub380["ADR"] = int(raw["address"][i])
        if raw["has_id"][i]:
            sub380["ID"] = int(raw["callsign"][i])
        if sub380:
            items["380"] = sub380
        for item, key, flag in (("136", "flight_level", "has_136"), ("130", "altitude", "has_130"),
                                ("220", "climb", "has_220")):
            if raw[flag][i]:
                items[item] = int(raw[key][i])
        sub500: dict = {}
        if raw["has_apc"][i]:
            sub500["APC"] = (("X", int(raw["apc_x"][i])), ("Y", int(raw["apc_y"][i])))
        if raw["has_aga"][i]:
            sub500["AGA"] = int(raw["aga"][i])
        if raw["has_atv"][i]:
            sub500["ATV"] = (("X", int(raw["atv_x"][i])), ("Y", int(raw["atv_y"][i])))
        if sub500:
            items["500"] = sub500
        records.append(spec.cv_record.create(items))
    return records


#: file name endings written as CAT062 by ``skytrack track -o``
ASTERIX_SUFFIXES = (".ast", ".asterix")


def is_asterix_path(path) -> bool:
    return str(path).lower().endswith(ASTERIX_SUFFIXES)


def beside_asterix(path, tag: str):
    """The Parquet file written beside an ASTERIX tracks file: ``tracks.ast`` -> ``tracks.<tag>.parquet``
    (identity events, track reports: tables CAT062 has no record for)."""
    from pathlib import Path

    path = Path(path)
    name = path.name
    suffix = next(s for s in ASTERIX_SUFFIXES if name.lower().endswith(s))
    return path.with_name(f"{name[:len(name) - len(suffix)]}.{tag}.parquet")


class Cat062Writer:
    """Append tracks chunks to a CAT062 file (streamed: memory bounded by one chunk).

    A track's first row over the whole file has I062/080 TSB set.  ``sensors`` (a
    ``SensorSet``) gives the system SAC/SIC (``"system"`` in sensors.json), the time of day
    of the epoch and MON (one radar)."""

    def __init__(self, path, sensors=None, *, service_id: int = DEFAULT_SERVICE_ID,
                 max_records_per_block: int = MAX_RECORDS_PER_BLOCK):
        self.path = path
        radars = [] if sensors is None else [s for s in sensors.sensors if s.type != "adsb"]
        self.settings = {
            "sac_sic": system_sac_sic(None if sensors is None else sensors.extra), "service_id": service_id,
            "time_of_day_at_epoch_s": time_of_day_at_epoch(None if sensors is None else sensors.epoch_utc),
            "monosensor": len(radars) == 1, "max_records_per_block": max_records_per_block,
        }
        self._file = open(path, "wb")  # noqa: SIM115  (open for the writer's life, closed by close())
        self._seen = np.empty(0, np.int64)
        self.rows = 0

    def write(self, tracks: pd.DataFrame) -> None:
        if tracks is None or len(tracks) == 0:
            return
        track_id = tracks["track_id"].to_numpy(np.int64)
        distinct, first_row = np.unique(track_id, return_index=True)
        new = ~np.isin(distinct, self._seen)
        begun = np.zeros(len(tracks), bool)
        begun[first_row[new]] = True
        self._file.write(encode_cat062(tracks, begun=begun, **self.settings))
        self._seen = np.union1d(self._seen, distinct)
        self.rows += len(tracks)

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

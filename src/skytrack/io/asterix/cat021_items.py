"""Vectorised decoding of the CAT021 items skytrack reads (issue 11 item 1; I021/010, 040, 071,
073, 080, 090, 130, 131, 140, 145, 155, 157, 160, 170), with their resolutions.

:func:`decode_cat021_records` decodes, with numpy over all records at once, the CAT021 records
that ``framing.scan_records`` found; :func:`missing_required` names the required item group a
record lacks.  The encoder and the user-facing decoder are in :mod:`.cat021`.
"""

from __future__ import annotations

import numpy as np

from skytrack.geo.sensors import Origin
from skytrack.io.asterix import units as u
from skytrack.io.asterix.framing import ITEMS_READ
from skytrack.io.asterix.problems import CAT021_REQUIRED

FEET_M = 0.3048
HEIGHT_LSB_FT = 6.25
RATE_LSB_FT_PER_MIN = 6.25
LAT_LON_HIGH_LSB_DEG = 180.0 / 2**30
LAT_LON_LSB_DEG = 180.0 / 2**23
GROUND_SPEED_LSB_MPS = u.NAUTICAL_MILE_M / 2**14
TRACK_LSB_DEG = 360.0 / 2**16
ATP_24_BIT_ADDRESS = 1
#: NACp -> 95 % horizontal position bound (m), as in skytrack.io.adsb (DO-260B)
NACP_EPU_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6, 7: 185.2, 8: 92.6,
              9: 30.0, 10: 10.0, 11: 3.0}
EPU95_PER_SIGMA = float(np.sqrt(-2.0 * np.log(0.05)))

#: ICAO 6-bit character set of I021/170 (index = code); "" where no character is defined
_SIX_BIT = ["", *"ABCDEFGHIJKLMNOPQRSTUVWXYZ", *[""] * 5, " ", *[""] * 15, *"0123456789", *[""] * 6]
_CODE_OF_CHAR = {c: i for i, c in enumerate(_SIX_BIT) if c}



def _unsigned(data: np.ndarray, offsets: np.ndarray, n_bytes: int) -> np.ndarray:
    at = np.where(offsets >= 0, offsets, 0).astype(np.int64)
    value = np.zeros(offsets.size, np.int64)
    for k in range(n_bytes):
        value = (value << 8) | data[at + k]
    return np.where(offsets >= 0, value, 0)


def _signed(value: np.ndarray, bits: int) -> np.ndarray:
    value = value & ((1 << bits) - 1)
    return np.where(value >= 1 << (bits - 1), value - (1 << bits), value)


def _callsigns(code: np.ndarray, present: np.ndarray) -> np.ndarray:
    """I021/170 codes as text (trailing spaces removed), formatted once per distinct code."""
    out = np.full(code.size, None, object)
    if not present.any():
        return out
    distinct, index = np.unique(code[present], return_inverse=True)
    table = np.array(["".join(_SIX_BIT[(int(v) >> (42 - 6 * k)) & 63] for k in range(8)).rstrip()
                      for v in distinct], object)
    out[present] = table[index]
    return out


def _item(items: np.ndarray, name: str) -> np.ndarray:
    return items[:, ITEMS_READ[21].index(name)].astype(np.int64)


def decode_cat021_records(data: np.ndarray, items: np.ndarray, origin: Origin | None = None) -> dict[str, np.ndarray]:
    """The ADS-B columns (module docstring) of CAT021 records whose item offsets are ``items``
    (rows of ``framing.scan_records``' table for category 21, all with the required items).
    ``time`` is the time of day here; the caller unwraps it over midnight."""
    sac_sic = _unsigned(data, _item(items, "010"), 2)
    t071, t073 = _item(items, "071"), _item(items, "073")
    time_of_day = _unsigned(data, np.where(t071 >= 0, t071, t073), 3) * u.TIME_LSB_S
    p131, p130 = _item(items, "131"), _item(items, "130")
    high = _unsigned(data, p131, 8)
    low = _unsigned(data, p130, 6)
    lat = np.where(p131 >= 0, _signed(high >> 32, 32) * LAT_LON_HIGH_LSB_DEG, _signed(low >> 24, 24) * LAT_LON_LSB_DEG)
    lon = np.where(p131 >= 0, _signed(high, 32) * LAT_LON_HIGH_LSB_DEG, _signed(low, 24) * LAT_LON_LSB_DEG)
    h140, h145 = _item(items, "140"), _item(items, "145")
    geometric = _signed(_unsigned(data, h140, 2), 16) * HEIGHT_LSB_FT * FEET_M
    level = _signed(_unsigned(data, h145, 2), 16) * 25.0 * FEET_M
    alt = np.where(h140 >= 0, geometric, level)
    address = _unsigned(data, _item(items, "080"), 3)
    ident = _item(items, "170")
    q090 = _item(items, "090")
    quality = _unsigned(data, q090, 2)
    has_nacp = (q090 >= 0) & ((quality >> 8) & 1 == 1)  # the first octet's FX: NACp's octet follows
    nacp = np.where(has_nacp, (quality >> 1) & 0xF, -1)
    g160 = _item(items, "160")
    ground = _unsigned(data, g160, 4)
    speed = np.where(g160 >= 0, ((ground >> 16) & 0x7FFF) * GROUND_SPEED_LSB_MPS, np.nan)
    track = np.where(g160 >= 0, (ground & 0xFFFF) * TRACK_LSB_DEG, np.nan)
    r157, r155 = _item(items, "157"), _item(items, "155")
    rate_raw = _signed(_unsigned(data, np.where(r157 >= 0, r157, r155), 2), 15)
    rate = np.where((r157 >= 0) | (r155 >= 0), rate_raw * RATE_LSB_FT_PER_MIN * FEET_M / 60.0, np.nan)
    columns = {
        "time": time_of_day.copy(),
        "icao24": np.empty(0, object),
        "lat": lat, "lon": lon, "alt_m": alt,
        "nacp": np.where(nacp >= 0, nacp, np.nan),
        "callsign": _callsigns(_unsigned(data, ident, 6), ident >= 0),
        "sac": sac_sic >> 8, "sic": sac_sic & 0xFF, "time_of_day_s": time_of_day,
        "icao24_address": address,
        "ground_speed_mps": speed, "track_deg": track, "vertical_rate_mps": rate,
    }
    if address.size:
        distinct, index = np.unique(address, return_inverse=True)
        columns["icao24"] = np.array([f"{int(v):06x}" for v in distinct], object)[index]
    if origin is not None:
        course = np.radians(track)
        local = np.column_stack([speed * np.sin(course), speed * np.cos(course), np.nan_to_num(rate)])
        from skytrack.io.frames import local_to_origin_velocity

        velocity = local_to_origin_velocity(lat, lon, local, origin).reshape(-1, 3)
        velocity[~np.isfinite(speed)] = np.nan  # no ground vector: no velocity (no rate: level, as read_adsb)
        columns["vx"], columns["vy"], columns["vz"] = velocity[:, 0], velocity[:, 1], velocity[:, 2]
    return columns


def missing_required(items: np.ndarray) -> np.ndarray:
    """Per CAT021 record: index+1 of the first required group it lacks (0: none missing)."""
    first_missing = np.zeros(items.shape[0], np.int64)
    for k, group in enumerate(CAT021_REQUIRED):
        has = np.zeros(items.shape[0], bool)
        for name in group:
            has |= _item(items, name) >= 0
        first_missing = np.where((first_missing == 0) & ~has, k + 1, first_missing)
    return first_missing

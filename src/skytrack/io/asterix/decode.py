"""Vectorised decoding of ASTERIX CAT048 plots and CAT034 service messages (issue 11 item 1-2).

``framing.scan_records`` finds every record and the byte offsets of the items read; the
items are then decoded with numpy byte arithmetic over all records at once:

- I048/010 SAC/SIC, I048/140 time of day (1/128 s), I048/020 TYP (first octet),
  I048/040 RHO (1/256 NM) and THETA (360/2^16 deg), I048/070 Mode 3/A (12 bits, octal),
  I048/090 flight level (14-bit two's complement, 1/4 FL), I048/220 aircraft address;
- I034/000 message type, I034/010 SAC/SIC, I034/030 time of day, I034/020 sector azimuth
  (360/2^8 deg).

The result is in the plots layout of docs/formats.md (``range_m``, ``azimuth_deg``,
``mode3a`` octal text, ``mode_c_ft``, ``mode_s`` hex text; missing values NaN / None)
plus ``sac``, ``sic``, ``time_of_day_s``, ``detection_type`` (I048/020 TYP) and the integer
codes ``mode3a_code`` and ``mode_s_address`` (-1 when the item is absent).
``time`` is the time of day unwrapped over midnight per SAC/SIC (CAT048 and CAT034
together, in input order): a step back of more than 12 h adds a day, a step forward of
more than 12 h takes one away, so ``time`` counts seconds from midnight of the day of that
sensor's first message.  Validity bits (I048/070 V/G/L, I048/090 V/G) are not read.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.io.asterix import units as u
from skytrack.io.asterix.cat021_items import decode_cat021_records, missing_required
from skytrack.io.asterix.framing import ITEMS_READ, scan_records
from skytrack.io.asterix.problems import (
    MISSING_CAT021,
    MISSING_ITEM,
    PROBLEM_KINDS,
    REQUIRED_ITEMS,
    AsterixDecodeError,
    AsterixProblem,
    DecodeProblems,
)


def _unsigned(data: np.ndarray, offsets: np.ndarray, n_bytes: int) -> np.ndarray:
    """Big-endian unsigned integers of ``n_bytes`` at ``offsets`` (0 where the offset is -1)."""
    at = np.where(offsets >= 0, offsets, 0)
    value = np.zeros(offsets.size, np.int64)
    for k in range(n_bytes):
        value = (value << 8) | data[at + k]
    return np.where(offsets >= 0, value, 0)


#: the 4 096 Mode 3/A codes as 4 octal digits, indexed by the code
_OCTAL_CODES = np.array([f"{code:04o}" for code in range(4096)], dtype=object)


def _octal_text(codes: np.ndarray, present: np.ndarray) -> np.ndarray:
    return np.where(present, _OCTAL_CODES[codes], None)


def _text_by_value(values: np.ndarray, present: np.ndarray, text) -> np.ndarray:
    """``text(v)`` for every value, formatted once per distinct value (few aircraft, few sensors)."""
    if values.size == 0:
        return np.empty(0, object)
    distinct, index = np.unique(values, return_inverse=True)
    table = np.array([text(int(v)) for v in distinct], dtype=object)
    return np.where(present, table[index], None)


def unwrap_time_of_day(time_of_day_s: np.ndarray, sensor_key: np.ndarray) -> np.ndarray:
    """Seconds since midnight of each sensor's first message day (see the module docstring)."""
    order = np.argsort(sensor_key, kind="stable")
    key, t = sensor_key[order], time_of_day_s[order]
    step = np.diff(t)
    same = key[1:] == key[:-1]
    days = np.where(same & (step < -u.SECONDS_PER_DAY / 2), 1, 0) - np.where(same & (step > u.SECONDS_PER_DAY / 2), 1, 0)
    total = np.concatenate([[0], np.cumsum(days)])
    first = np.concatenate([[True], ~same])
    group_start = np.maximum.accumulate(np.where(first, np.arange(key.size), 0)) if key.size else key
    days_since_first = total - total[group_start]
    unwrapped = np.empty_like(t)
    unwrapped[order] = t + u.SECONDS_PER_DAY * days_since_first
    return unwrapped


@dataclass
class DecodedAsterix:
    """Plots (CAT048), service messages (CAT034) and ADS-B reports (CAT021, :mod:`.cat021`) as
    column arrays, and the problems met."""

    plots: dict[str, np.ndarray]
    service: dict[str, np.ndarray]
    problems: DecodeProblems
    adsb: dict[str, np.ndarray] = field(default_factory=dict)

    def plots_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.plots)

    def north_marker_times(self) -> dict[tuple[int, int], np.ndarray]:
        """``time`` of the north markers (I034/000 = 1) per (SAC, SIC), in input order."""
        s = self.service
        north = s["message_type"] == u.NORTH_MARKER
        keys = sorted({(int(a), int(b)) for a, b in zip(s["sac"][north], s["sic"][north])})
        return {k: s["time"][north & (s["sac"] == k[0]) & (s["sic"] == k[1])] for k in keys}


def _column(items: np.ndarray, cat: int, item: str) -> np.ndarray:
    return items[:, ITEMS_READ[cat].index(item)]


def decode_asterix(data: bytes | bytearray | memoryview | np.ndarray, *, strict: bool = False,
                   sensor_names: Mapping[tuple[int, int], str] | None = None,
                   origin: Origin | None = None) -> DecodedAsterix:
    """Decode CAT048 plots and CAT034 service messages from ASTERIX bytes.

    Lenient (default): problems are counted in ``problems`` with their byte offsets and
    decoding resumes at the next block; a record without a required item (plots: I048/010,
    140, 040; service messages: I034/010, 000, 030) is skipped and counted.  ``strict=True`` raises :class:`AsterixDecodeError` at the first problem.
    ``sensor_names`` maps (SAC, SIC) to the ``sensor`` column; otherwise it is ``"SAC/SIC"``.
    CAT021 ADS-B reports go to ``adsb`` (their velocities ``vx, vy, vz`` in the ENU frame of
    ``origin`` when it is given); a report without a required item is skipped and counted.
    """
    buf = np.frombuffer(bytes(data), np.uint8) if not isinstance(data, np.ndarray) else data.astype(np.uint8, copy=False)
    records, raw_problems, n_blocks = scan_records(buf)
    problems = [AsterixProblem(PROBLEM_KINDS[int(c)], int(o), int(b), int(d), int(s))
                for c, o, b, d, s in zip(*(raw_problems[k] for k in ("code", "offset", "block", "detail", "skipped")))]
    items = records["items"]
    cat = records["cat"]
    start = records["start"]

    # which records can be used, then one time unwrap over both categories
    is_plot = cat == 48
    is_service = cat == 34
    usable = np.zeros(cat.size, bool)
    for category, items_needed in REQUIRED_ITEMS.items():
        of_category = cat == category
        usable |= of_category
        for item in items_needed:
            missing = of_category & usable & (_column(items, category, item) < 0)
            usable &= ~missing
            for i in np.flatnonzero(missing):  # one problem per skipped record, for its first missing item
                same_block_next = i + 1 < start.size and records["block"][i + 1] == records["block"][i]
                problems.append(AsterixProblem(MISSING_ITEM[category, item], int(start[i]), int(records["block"][i]),
                                               0, int(start[i + 1] - start[i]) if same_block_next else 0))
    is_adsb = cat == 21
    adsb_rows = np.flatnonzero(is_adsb)
    lacking = missing_required(items[adsb_rows])
    for i, group in zip(adsb_rows[lacking > 0], lacking[lacking > 0]):
        same_block_next = i + 1 < start.size and records["block"][i + 1] == records["block"][i]
        problems.append(AsterixProblem(MISSING_CAT021[group - 1], int(start[i]), int(records["block"][i]), 0,
                                       int(start[i + 1] - start[i]) if same_block_next else 0))
    is_adsb[adsb_rows[lacking > 0]] = False
    usable |= is_adsb
    problems.sort(key=lambda p: p.offset)
    if strict and problems:
        raise AsterixDecodeError(problems[0])
    is_plot &= usable
    is_service &= usable

    # the columns of I048/010 and I034/010 (and 140 / 030) are the same: column 0 and 1 / 2
    sac_sic = _unsigned(buf, np.where(is_plot, _column(items, 48, "010"), _column(items, 34, "010")), 2)
    time_offsets = np.where(is_plot, _column(items, 48, "140"), _column(items, 34, "030"))
    adsb = decode_cat021_records(buf, items[is_adsb], origin)
    time_of_day = _unsigned(buf, time_offsets, 3) * u.TIME_LSB_S
    time_of_day[is_adsb] = adsb["time_of_day_s"]
    sac_sic[is_adsb] = (adsb["sac"] << 8) | adsb["sic"]
    time = np.full(cat.size, np.nan)
    # CAT021 unwraps apart from the radars: a ground station may share a radar's SAC/SIC
    time[usable] = unwrap_time_of_day(time_of_day[usable], (sac_sic + (is_adsb.astype(np.int64) << 16))[usable])
    adsb["time"] = time[is_adsb]
    sac, sic = sac_sic >> 8, sac_sic & 0xFF
    names_given = sensor_names or {}
    names = _text_by_value(sac_sic, np.ones(sac_sic.size, bool),
                           lambda v: names_given.get((v >> 8, v & 0xFF), f"{v >> 8}/{v & 0xFF}"))

    p = items[is_plot]
    position = _unsigned(buf, p[:, ITEMS_READ[48].index("040")], 4)
    mode3a_at, level_at = p[:, ITEMS_READ[48].index("070")], p[:, ITEMS_READ[48].index("090")]
    address_at, typ_at = p[:, ITEMS_READ[48].index("220")], p[:, ITEMS_READ[48].index("020")]
    mode3a_code = _unsigned(buf, mode3a_at, 2) & 0x0FFF
    address = _unsigned(buf, address_at, 3)
    level = _unsigned(buf, level_at, 2) & 0x3FFF
    level = np.where(level >= 1 << 13, level - (1 << 14), level)
    plots = {
        "time": time[is_plot],
        "sensor": names[is_plot],
        "range_m": (position >> 16) * u.RHO_LSB_M,
        "azimuth_deg": (position & 0xFFFF) * u.THETA_LSB_DEG,
        "mode3a": _octal_text(mode3a_code, mode3a_at >= 0),
        "mode_c_ft": np.where(level_at >= 0, level * u.FLIGHT_LEVEL_LSB_FT, np.nan),
        "mode_s": _text_by_value(address, address_at >= 0, lambda v: f"{v:06x}"),
        "sac": sac[is_plot],
        "sic": sic[is_plot],
        "time_of_day_s": time_of_day[is_plot],
        "detection_type": np.where(typ_at >= 0, _unsigned(buf, typ_at, 1) >> 5, -1),
        "mode3a_code": np.where(mode3a_at >= 0, mode3a_code, -1),
        "mode_s_address": np.where(address_at >= 0, address, -1),
        "byte_offset": start[is_plot],
    }
    s = items[is_service]
    azimuth_at = s[:, ITEMS_READ[34].index("020")]
    service = {
        "time": time[is_service],
        "sensor": names[is_service],
        "message_type": _unsigned(buf, s[:, ITEMS_READ[34].index("000")], 1),
        "azimuth_deg": np.where(azimuth_at >= 0, _unsigned(buf, azimuth_at, 1) * u.SECTOR_LSB_DEG, np.nan),
        "sac": sac[is_service],
        "sic": sic[is_service],
        "time_of_day_s": time_of_day[is_service],
        "byte_offset": start[is_service],
    }
    report = DecodeProblems(problems=problems, blocks=n_blocks, records=int(cat.size))
    adsb["sensor"] = names[is_adsb]
    adsb["byte_offset"] = start[is_adsb]
    return DecodedAsterix(plots=plots, service=service, problems=report, adsb=adsb)

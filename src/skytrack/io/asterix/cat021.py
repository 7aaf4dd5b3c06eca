"""ASTERIX CAT021 ADS-B reports (issue 11 items 1-2): numpy and libasterix encoders, vectorised decoder.

Edition 2.6.  Items written and read, with their resolutions:

- I021/010 SAC/SIC (the ADS-B ground station);
- I021/040 target report descriptor: written with ATP = 1 (24-bit ICAO address), read: ATP;
- I021/071 time of applicability for position (1/128 s; read, else I021/073 time of
  message reception for position);
- I021/131 high-resolution position (180/2^30 deg; read, else I021/130, 180/2^23 deg);
- I021/140 geometric height (6.25 ft, the ``alt_m`` column; read, else I021/145 flight
  level in 1/4 FL as a pressure altitude, 1 FL = 100 ft);
- I021/080 target address (``icao24``), I021/170 target identification (``callsign``,
  8 characters of the ICAO 6-bit alphabet: A-Z, 0-9, space);
- I021/090 quality indicators: NACp (first extension), written from ``nacp`` or from
  ``sigma_m`` (the best NACp whose 95 % bound holds 2.4477 sigma_m, so reading gives back a
  ``sigma_m`` no smaller than the one written);
- I021/160 ground vector (ground speed 2^-14 NM/s, track angle 360/2^16 deg) and I021/157
  geometric vertical rate (6.25 ft/min; read, else I021/155 barometric rate).

:func:`quantise_adsb` turns an ADS-B table into the raw integers of these fields (the first
row and column a value does not fit in is named).  :func:`cat021_record_bytes` and
:func:`encode_cat021_blocks` assemble the records with numpy over all rows
(``bytes_assembly.assemble_records``; about 5 x 10^5 records/s); :func:`encode_cat021` builds
the same records with libasterix (about 1.4 x 10^3 records/s), the reference they are tested
against byte for byte.

``cat021_items.decode_cat021_records`` decodes the records found by ``framing.scan_records`` with numpy
over all records at once, in the ADS-B layout of docs/formats.md (``time``, ``icao24``,
``lat``, ``lon``, ``alt_m``, ``nacp``, ``callsign``, and with an origin ``vx, vy, vz`` in its
ENU frame), plus ``sac``, ``sic``, ``time_of_day_s`` and the raw ground speed, track and
vertical rate.  A record without I021/010, I021/080, a time (071/073), a position
(130/131) or a height (140/145) is skipped and counted as a problem at its byte offset.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.io.asterix.bytes_assembly import (
    assemble_records,
    big_endian,
    blocks_from_records,
    callsign_code,
    codes_of_texts,
    distinct_texts,
    finite_column,
    time_of_day_raw,
)
from skytrack.io.asterix.cat021_items import (
    ATP_24_BIT_ADDRESS,
    EPU95_PER_SIGMA,
    FEET_M,
    GROUND_SPEED_LSB_MPS,
    HEIGHT_LSB_FT,
    LAT_LON_HIGH_LSB_DEG,
    LAT_LON_LSB_DEG,
    NACP_EPU_M,
    RATE_LSB_FT_PER_MIN,
    TRACK_LSB_DEG,
    decode_cat021_records,
    missing_required,
)
from skytrack.io.asterix.decode import decode_asterix


def _spec():
    import asterix.generated as gen  # libasterix is only needed to encode

    return gen.Cat_021_2_6


_WHAT = "adsb"  # the start of every error message about an ADS-B row


def sigma_to_nacp(sigma_m: np.ndarray) -> np.ndarray:
    """The highest NACp whose 95 % bound is at least ``EPU95_PER_SIGMA * sigma_m`` (0: none)."""
    epu = np.asarray(sigma_m, float) * EPU95_PER_SIGMA
    nacp = np.zeros(epu.shape, np.int64)
    for category, bound in sorted(NACP_EPU_M.items()):
        nacp = np.where(np.isfinite(epu) & (epu <= bound), category, nacp)
    return nacp


def origin_to_local_velocity(lat: np.ndarray, lon: np.ndarray, v_origin: np.ndarray, origin: Origin) -> np.ndarray:
    """Rotate velocities ``[N, 3]`` from the origin's ENU frame to each point's own (the inverse of
    :func:`skytrack.io.frames.local_to_origin_velocity`)."""
    from skytrack.geo.wgs84 import enu_rotation

    ecef = np.asarray(v_origin, float) @ enu_rotation(origin.lat, origin.lon)
    phi, lam = np.radians(lat), np.radians(lon)
    sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
    ex, ey, ez = ecef[:, 0], ecef[:, 1], ecef[:, 2]
    return np.column_stack([-sl * ex + cl * ey, -sp * cl * ex - sp * sl * ey + cp * ez,
                            cp * cl * ex + cp * sl * ey + sp * ez])


def _check(raw: np.ndarray, present: np.ndarray, low: int, high: int, column: str) -> None:
    bad = present & ((raw < low) | (raw > high))
    if bad.any():
        raise ValueError(f"{_WHAT}: row {int(np.flatnonzero(bad)[0])}, column {column}: value outside what the item "
                         "can hold")


def _hex_address(text: str) -> int:
    address = int(text, 16)
    if not 0 <= address < 1 << 24:
        raise ValueError(text)
    return address


def quantise_adsb(adsb: pd.DataFrame, sac_sic: tuple[int, int], *, time_of_day_at_epoch_s: float = 0.0,
                  origin: Origin | None = None) -> dict[str, np.ndarray]:
    """The raw integer of every CAT021 field written, and the presence of every optional item,
    per ADS-B row (the rules of :func:`encode_cat021`); the first row a value does not fit is named."""
    sac, sic = (int(v) for v in sac_sic)
    if not (0 <= sac <= 255 and 0 <= sic <= 255):
        raise ValueError(f"CAT021 SAC/SIC must be two integers in [0, 255], got {(sac, sic)}")
    n = len(adsb)
    everywhere = np.ones(n, bool)
    time = finite_column(adsb, "time", _WHAT)
    lat, lon, alt = (finite_column(adsb, name, _WHAT) for name in ("lat", "lon", "alt_m"))
    raw: dict[str, np.ndarray] = {"sac_sic": np.full(n, sac * 256 + sic, np.int64),
                                  "time_of_day": time_of_day_raw(time, time_of_day_at_epoch_s)}
    # the 32-bit fields would hold +-360 deg: the check keeps latitudes to +-90 deg and longitudes to +-180 deg
    raw["lat"] = np.rint(lat / LAT_LON_HIGH_LSB_DEG).astype(np.int64)
    raw["lon"] = np.rint(lon / LAT_LON_HIGH_LSB_DEG).astype(np.int64)
    _check(raw["lat"], everywhere, -(2**29), 2**29, "lat")
    _check(raw["lon"], everywhere, -(2**30), 2**30, "lon")
    raw["height"] = np.rint(alt / FEET_M / HEIGHT_LSB_FT).astype(np.int64)
    _check(raw["height"], everywhere, -(2**15), 2**15 - 1, "alt_m")
    distinct, index = distinct_texts(adsb, "icao24")
    if (index < 0).any():
        raise ValueError(f"{_WHAT}: row {int(np.flatnonzero(index < 0)[0])}, column icao24: an ICAO 24-bit address "
                         "(hexadecimal) is required")
    raw["address"] = codes_of_texts(distinct, index, _hex_address, "icao24", _WHAT)
    distinct, index = distinct_texts(adsb, "callsign")
    blank = np.array([not text.strip() for text in distinct] + [False], bool)  # index -1: the appended False
    index = np.where(blank[index], -1, index)  # a blank callsign is no I021/170
    raw["has_170"], raw["callsign"] = index >= 0, codes_of_texts(distinct, index, callsign_code, "callsign", _WHAT)
    nacp_values = adsb["nacp"].to_numpy(float) if "nacp" in adsb.columns else np.full(n, np.nan)
    has_nacp = np.isfinite(nacp_values)
    nacp = np.where(has_nacp, nacp_values, 0).astype(np.int64)
    if "sigma_m" in adsb.columns:
        sigma = adsb["sigma_m"].to_numpy(float)
        from_sigma = ~has_nacp & np.isfinite(sigma)
        nacp = np.where(from_sigma, sigma_to_nacp(sigma), nacp)
        has_nacp |= from_sigma
    _check(nacp, has_nacp, 0, 15, "nacp")
    raw["has_090"], raw["nacp"] = has_nacp, nacp
    has_velocity, has_rate = np.zeros(n, bool), np.zeros(n, bool)
    speed, track, rate = np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64)
    if {"vx", "vy"} <= set(adsb.columns):
        v = np.column_stack([adsb[c].to_numpy(float) if c in adsb.columns else np.zeros(n) for c in ("vx", "vy", "vz")])
        has_velocity = np.isfinite(v[:, 0]) & np.isfinite(v[:, 1])
        if has_velocity.any() and origin is None:
            raise ValueError("adsb: vx, vy, vz are in the origin's ENU frame: encode_cat021 needs origin= to write "
                             "them as a ground vector")
    if has_velocity.any():
        local = origin_to_local_velocity(lat, lon, np.nan_to_num(v), origin)
        speed = np.where(has_velocity, np.rint(np.hypot(local[:, 0], local[:, 1]) / GROUND_SPEED_LSB_MPS), 0)
        course = np.rint(np.degrees(np.arctan2(local[:, 0], local[:, 1])) / TRACK_LSB_DEG)
        track = np.mod(np.where(has_velocity, course, 0).astype(np.int64), 2**16)
        has_rate = has_velocity & np.isfinite(v[:, 2])
        rate = np.where(has_rate, np.rint(local[:, 2] / FEET_M * 60.0 / RATE_LSB_FT_PER_MIN), 0).astype(np.int64)
        speed = speed.astype(np.int64)
    # RE (range exceeded): a ground speed or rate beyond the field is written at its maximum with RE set
    raw["has_160"], raw["speed_exceeded"] = has_velocity, has_velocity & (speed > 2**15 - 1)
    raw["speed"], raw["track"] = np.minimum(speed, 2**15 - 1), track
    raw["has_157"], raw["rate_exceeded"] = has_rate, has_rate & (np.abs(rate) > 2**14 - 1)
    raw["rate"] = np.clip(rate, -(2**14), 2**14 - 1)
    return raw


def reference_records(raw: dict[str, np.ndarray]) -> list:
    """libasterix CAT021 records (the reference encoder), one per row of :func:`quantise_adsb`'s ``raw``."""
    spec = _spec()
    records = []
    for i in range(raw["sac_sic"].size):
        items: dict = {
            "010": (("SAC", int(raw["sac_sic"][i]) >> 8), ("SIC", int(raw["sac_sic"][i]) & 0xFF)),
            "040": (ATP_24_BIT_ADDRESS << 4,),
            "071": int(raw["time_of_day"][i]),
            "131": (("LAT", int(raw["lat"][i])), ("LON", int(raw["lon"][i]))),
            "080": int(raw["address"][i]),
            "140": int(raw["height"][i]),
        }
        if raw["has_090"][i]:
            items["090"] = (0, int(raw["nacp"][i]))
        if raw["has_170"][i]:
            items["170"] = int(raw["callsign"][i])
        if raw["has_160"][i]:
            items["160"] = (("RE", int(raw["speed_exceeded"][i])), ("GS", int(raw["speed"][i])),
                            ("TA", int(raw["track"][i])))
        if raw["has_157"][i]:
            items["157"] = (("RE", int(raw["rate_exceeded"][i])), ("GVR", int(raw["rate"][i])))
        records.append(spec.cv_record.create(items))
    return records


def encode_cat021(adsb: pd.DataFrame, sac_sic: tuple[int, int], *, time_of_day_at_epoch_s: float = 0.0,
                  origin: Origin | None = None) -> list:
    """One libasterix CAT021 record per ADS-B report (columns as in docs/formats.md, adsb): the
    reference encoder (about 1.4 x 10^3 records/s); :func:`cat021_record_bytes` writes the same bytes with numpy.

    Needs ``time``, ``icao24``, ``lat``, ``lon``, ``alt_m`` (geometric height); optional
    ``callsign``, ``nacp`` or ``sigma_m``, and ``vx, vy, vz`` (ENU in the origin's frame: they
    are written as I021/160 and 157 when ``origin`` is given; finite velocities without an
    origin are an error, since they cannot be turned to the aircraft's north).  ``time``
    (seconds since the epoch) becomes the time of day ``time_of_day_at_epoch_s + time``
    modulo one day.  Pack the records into blocks with :func:`cat021_blocks`.
    """
    return reference_records(quantise_adsb(adsb, sac_sic, time_of_day_at_epoch_s=time_of_day_at_epoch_s,
                                           origin=origin))


#: FRN index (from 0) of the items written, in UAP order
_FRN = {"010": 0, "040": 1, "071": 4, "131": 6, "080": 10, "140": 15, "090": 16, "157": 24, "160": 25, "170": 28}


def cat021_record_bytes(adsb: pd.DataFrame, sac_sic: tuple[int, int], *, time_of_day_at_epoch_s: float = 0.0,
                        origin: Origin | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The records of :func:`encode_cat021`, assembled with numpy over all rows (byte for byte the
    same, tested): all records back to back (uint8) and each record's start offset (one more: the end)."""
    raw = quantise_adsb(adsb, sac_sic, time_of_day_at_epoch_s=time_of_day_at_epoch_s, origin=origin)
    n = raw["sac_sic"].size
    always = np.ones(n, bool)
    one = np.int64(1)
    # I021/090: the first octet (NUCr, NUCp 0) only announces, by its FX, the extension holding NACp
    quality = (one << 8) | (raw["nacp"] << 1)
    ground = (raw["speed_exceeded"] << 31) | (raw["speed"] << 16) | raw["track"]
    rate = (raw["rate_exceeded"].astype(np.int64) << 15) | (raw["rate"] & 0x7FFF)
    fields = (("010", always, raw["sac_sic"], 2), ("040", always, np.full(n, ATP_24_BIT_ADDRESS << 5), 1),
              ("071", always, raw["time_of_day"], 3), ("131", always, (raw["lat"] << 32) | (raw["lon"] & 0xFFFFFFFF), 8),
              ("080", always, raw["address"], 3), ("140", always, raw["height"], 2),
              ("090", raw["has_090"], quality, 2), ("157", raw["has_157"], rate, 2),
              ("160", raw["has_160"], ground, 4), ("170", raw["has_170"], raw["callsign"], 6))
    return assemble_records(n, [(_FRN[item], present, [(always, big_endian(values, size))])
                                for item, present, values, size in fields])


def encode_cat021_blocks(adsb: pd.DataFrame, sac_sic: tuple[int, int], *, time_of_day_at_epoch_s: float = 0.0,
                         origin: Origin | None = None, max_records_per_block: int = 128) -> bytes:
    """CAT021 data blocks of the ADS-B reports, with numpy: ``cat021_blocks(encode_cat021(...))`` without libasterix."""
    if max_records_per_block < 1:
        raise ValueError("max_records_per_block must be at least 1")
    records, starts = cat021_record_bytes(adsb, sac_sic, time_of_day_at_epoch_s=time_of_day_at_epoch_s, origin=origin)
    return blocks_from_records(records, starts, max_records_per_block, 21)


def cat021_blocks(records: list, max_records_per_block: int = 128) -> bytes:
    """CAT021 records (from :func:`encode_cat021`) as data blocks of at most ``max_records_per_block``."""
    from skytrack.io.asterix.encode import _blocks

    return b"".join(_blocks(_spec(), records, max_records_per_block))


def decode_cat021(data: bytes | bytearray | memoryview | np.ndarray, *, strict: bool = False,
                  origin: Origin | None = None, sensor_names: Mapping[tuple[int, int], str] | None = None):
    """Decode the CAT021 ADS-B reports of ASTERIX bytes (other categories' records are skipped
    by their structure): ``(DataFrame in the ADS-B layout, DecodeProblems)``.  ``time`` is the
    time of day unwrapped over midnight per SAC/SIC, as in :func:`decode_asterix`.  Strict
    mode raises :class:`AsterixDecodeError` at the first problem."""
    decoded = decode_asterix(data, strict=strict, origin=origin, sensor_names=sensor_names)
    return pd.DataFrame(decoded.adsb), decoded.problems


__all__ = ["ATP_24_BIT_ADDRESS", "EPU95_PER_SIGMA", "FEET_M", "GROUND_SPEED_LSB_MPS", "HEIGHT_LSB_FT",
           "LAT_LON_HIGH_LSB_DEG", "LAT_LON_LSB_DEG", "NACP_EPU_M", "RATE_LSB_FT_PER_MIN", "TRACK_LSB_DEG",
           "cat021_blocks", "cat021_record_bytes", "decode_cat021", "decode_cat021_records", "encode_cat021",
           "encode_cat021_blocks", "missing_required", "origin_to_local_velocity", "quantise_adsb", "reference_records",
           "sigma_to_nacp"]

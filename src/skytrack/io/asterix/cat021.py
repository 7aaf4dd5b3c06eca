"""ASTERIX CAT021 ADS-B reports (issue 11 item 1): libasterix encoder, vectorised decoder.

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
from skytrack.io.asterix import units as u
from skytrack.io.asterix.cat021_items import (
    _CODE_OF_CHAR,
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


def sigma_to_nacp(sigma_m: np.ndarray) -> np.ndarray:
    """The highest NACp whose 95 % bound is at least ``EPU95_PER_SIGMA * sigma_m`` (0: none)."""
    epu = np.asarray(sigma_m, float) * EPU95_PER_SIGMA
    nacp = np.zeros(epu.shape, np.int64)
    for category, bound in sorted(NACP_EPU_M.items()):
        nacp = np.where(np.isfinite(epu) & (epu <= bound), category, nacp)
    return nacp


def _callsign_code(text: str, row: int) -> int:
    padded = text.upper().ljust(8)
    if len(padded) > 8 or any(c not in _CODE_OF_CHAR for c in padded):
        raise ValueError(f"adsb: row {row}, column callsign: {text!r} is not up to 8 characters of A-Z, 0-9, space")
    code = 0
    for c in padded:
        code = (code << 6) | _CODE_OF_CHAR[c]
    return code


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


def _finite_column(adsb: pd.DataFrame, name: str) -> np.ndarray:
    values = adsb[name].to_numpy(float)
    if not np.isfinite(values).all():
        raise ValueError(f"adsb: row {int(np.flatnonzero(~np.isfinite(values))[0])}, column {name}: "
                         "a finite number is required")
    return values


def _check(raw: np.ndarray, present: np.ndarray, low: int, high: int, column: str) -> None:
    bad = present & ((raw < low) | (raw > high))
    if bad.any():
        raise ValueError(f"adsb: row {int(np.flatnonzero(bad)[0])}, column {column}: value outside what the item "
                         "can hold")


def encode_cat021(adsb: pd.DataFrame, sac_sic: tuple[int, int], *, time_of_day_at_epoch_s: float = 0.0,
                  origin: Origin | None = None) -> list:
    """One libasterix CAT021 record per ADS-B report (columns as in docs/formats.md, adsb).

    Needs ``time``, ``icao24``, ``lat``, ``lon``, ``alt_m`` (geometric height); optional
    ``callsign``, ``nacp`` or ``sigma_m``, and ``vx, vy, vz`` (ENU in the origin's frame: they
    are written as I021/160 and 157 when ``origin`` is given; finite velocities without an
    origin are an error, since they cannot be turned to the aircraft's north).  ``time``
    (seconds since the epoch) becomes the time of day ``time_of_day_at_epoch_s + time``
    modulo one day.  Pack the records into blocks with :func:`cat021_blocks`.
    """
    spec = _spec()
    sac, sic = (int(v) for v in sac_sic)
    if not (0 <= sac <= 255 and 0 <= sic <= 255):
        raise ValueError(f"CAT021 SAC/SIC must be two integers in [0, 255], got {(sac, sic)}")
    n = len(adsb)
    time = _finite_column(adsb, "time")
    lat, lon, alt = (_finite_column(adsb, name) for name in ("lat", "lon", "alt_m"))
    seconds = np.mod(time + time_of_day_at_epoch_s, u.SECONDS_PER_DAY)
    tod = np.mod(np.rint(seconds / u.TIME_LSB_S).astype(np.int64), int(u.SECONDS_PER_DAY / u.TIME_LSB_S))
    lat_raw = np.rint(lat / LAT_LON_HIGH_LSB_DEG).astype(np.int64)
    lon_raw = np.rint(lon / LAT_LON_HIGH_LSB_DEG).astype(np.int64)
    lon_raw = np.where(lon_raw == 2**31, -(2**31), lon_raw)  # +180 deg is -180 deg
    _check(lat_raw, np.ones(n, bool), -(2**30), 2**30, "lat")
    height = np.rint(alt / FEET_M / HEIGHT_LSB_FT).astype(np.int64)
    _check(height, np.ones(n, bool), -(2**15), 2**15 - 1, "alt_m")
    address = np.array([int(str(v), 16) for v in adsb["icao24"].to_numpy()], np.int64)
    _check(address, np.ones(n, bool), 0, 2**24 - 1, "icao24")
    callsigns = adsb["callsign"].to_numpy(object) if "callsign" in adsb.columns else np.full(n, None)
    if "nacp" in adsb.columns:
        nacp_values = adsb["nacp"].to_numpy(float)
        has_nacp = np.isfinite(nacp_values)
        nacp = np.where(has_nacp, nacp_values, 0).astype(np.int64)
    else:
        has_nacp, nacp = np.zeros(n, bool), np.zeros(n, np.int64)
    if "sigma_m" in adsb.columns:
        sigma = adsb["sigma_m"].to_numpy(float)
        from_sigma = ~has_nacp & np.isfinite(sigma)
        nacp = np.where(from_sigma, sigma_to_nacp(sigma), nacp)
        has_nacp |= from_sigma
    _check(nacp, has_nacp, 0, 15, "nacp")
    has_velocity = np.zeros(n, bool)
    if {"vx", "vy"} <= set(adsb.columns):
        v = np.column_stack([adsb[c].to_numpy(float) if c in adsb.columns else np.zeros(n) for c in ("vx", "vy", "vz")])
        has_velocity = np.isfinite(v[:, 0]) & np.isfinite(v[:, 1])
        if has_velocity.any() and origin is None:
            raise ValueError("adsb: vx, vy, vz are in the origin's ENU frame: encode_cat021 needs origin= to write "
                             "them as a ground vector")
    if has_velocity.any():
        local = origin_to_local_velocity(lat, lon, np.nan_to_num(v), origin)
        speed = np.rint(np.hypot(local[:, 0], local[:, 1]) / GROUND_SPEED_LSB_MPS).astype(np.int64)
        track = np.mod(np.rint(np.degrees(np.arctan2(local[:, 0], local[:, 1])) / TRACK_LSB_DEG).astype(np.int64), 2**16)
        has_rate = has_velocity & np.isfinite(v[:, 2])
        rate = np.rint(local[:, 2] / FEET_M * 60.0 / RATE_LSB_FT_PER_MIN).astype(np.int64)
        speed_out, rate_out = speed > 2**15 - 1, has_rate & (np.abs(rate) > 2**14 - 1)
        speed, rate = np.minimum(speed, 2**15 - 1), np.clip(rate, -(2**14), 2**14 - 1)  # RE: beyond range
    records = []
    for i in range(n):
        items: dict = {
            "010": (("SAC", sac), ("SIC", sic)),
            "040": (ATP_24_BIT_ADDRESS << 4,),
            "071": int(tod[i]),
            "131": (("LAT", int(lat_raw[i])), ("LON", int(lon_raw[i]))),
            "080": int(address[i]),
            "140": int(height[i]),
        }
        if has_nacp[i]:
            items["090"] = (0, int(nacp[i]))
        callsign = callsigns[i]
        if callsign is not None and not pd.isna(callsign) and str(callsign).strip():
            items["170"] = _callsign_code(str(callsign).strip(), i)
        if has_velocity[i]:
            items["160"] = (("RE", int(speed_out[i])), ("GS", int(speed[i])), ("TA", int(track[i])))
            if has_rate[i]:
                items["157"] = (("RE", int(rate_out[i])), ("GVR", int(rate[i])))
        records.append(spec.cv_record.create(items))
    return records


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
           "cat021_blocks", "decode_cat021", "decode_cat021_records", "encode_cat021", "missing_required",
           "origin_to_local_velocity", "sigma_to_nacp"]

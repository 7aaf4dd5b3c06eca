"""Plots and radar service messages to ASTERIX bytes, with libasterix as the encoder (issue 11 item 1-2).

CAT048 (monoradar target reports, edition 1.32) records carry I048/010 (SAC/SIC),
I048/140 (time of day, 1/128 s), I048/020 (target report descriptor, TYP only),
I048/040 (RHO 1/256 NM, THETA 360/2^16 deg), and when the plot has them I048/070
(Mode 3/A), I048/090 (flight level, 1/4 FL) and I048/220 (aircraft address).
CAT034 (service messages, edition 1.29) records carry I034/000 (1 north marker,
2 sector crossing), I034/010, I034/030 (time of day) and for sector crossings I034/020
(sector azimuth 360/2^8 deg).

Values are quantised here (round to the nearest LSB) and handed to libasterix as raw
integers, so the bytes are libasterix's.  Messages are written in time order (service
messages before plots at equal times); each run of one category is one data block, split
so that a block has at most ``max_records_per_block`` records and 65 535 bytes.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

import numpy as np
import pandas as pd

from skytrack.io.asterix import units as u

MAX_BLOCK_BYTES = 65535


def _specs():
    import asterix.generated as gen  # libasterix is only needed to encode

    return gen.Cat_048_1_32, gen.Cat_034_1_29


def _column(frame: pd.DataFrame, name: str) -> np.ndarray | None:
    return frame[name].to_numpy() if name in frame.columns else None


def _present(values: np.ndarray | None, n: int) -> np.ndarray:
    if values is None:
        return np.zeros(n, bool)
    return ~pd.isna(values)


def _time_of_day_raw(time_s: np.ndarray, time_of_day_at_epoch_s: float) -> np.ndarray:
    seconds = np.mod(np.asarray(time_s, float) + time_of_day_at_epoch_s, u.SECONDS_PER_DAY)
    return np.mod(np.rint(seconds / u.TIME_LSB_S).astype(np.int64), int(u.SECONDS_PER_DAY / u.TIME_LSB_S))


def _sac_sic(sensors: np.ndarray, sac_sic: Mapping[str, tuple[int, int]], what: str) -> np.ndarray:
    missing = sorted(set(map(str, sensors)) - set(sac_sic))
    if missing:
        raise ValueError(f"{what}: no SAC/SIC for sensor(s) {', '.join(missing)}")
    for name, (sac, sic) in sac_sic.items():
        if not (0 <= sac <= 255 and 0 <= sic <= 255):
            raise ValueError(f"SAC/SIC of sensor {name} must be two integers in [0, 255], got {(sac, sic)}")
    return np.array([sac_sic[str(s)] for s in sensors], np.int64).reshape(-1, 2)


def _check_range(raw: np.ndarray, present: np.ndarray, low: int, high: int, column: str, what: str) -> None:
    bad = present & ((raw < low) | (raw > high))
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}: row {row}, column {column}: value outside what the item can hold")


def plot_records(plots: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *, ssr_only_sensors: Collection[str] = (),
                 time_of_day_at_epoch_s: float = 0.0) -> list:
    """One libasterix CAT048 record per plot row (columns as in docs/formats.md, plots)."""
    cat048, _ = _specs()
    n = len(plots)
    for name in ("time", "range_m", "azimuth_deg"):
        finite = np.isfinite(plots[name].to_numpy(float))
        if not finite.all():
            raise ValueError(f"plots: row {int(np.flatnonzero(~finite)[0])}, column {name}: a finite number is required")
    ids = _sac_sic(plots["sensor"].to_numpy(), sac_sic, "plots")
    tod = _time_of_day_raw(plots["time"].to_numpy(float), time_of_day_at_epoch_s)
    rho = np.rint(plots["range_m"].to_numpy(float) / u.RHO_LSB_M).astype(np.int64)
    _check_range(rho, np.ones(n, bool), 0, 65535, "range_m", "plots")
    theta = np.mod(np.rint(plots["azimuth_deg"].to_numpy(float) / u.THETA_LSB_DEG).astype(np.int64), 65536)
    mode3a, mode_c, mode_s = (_column(plots, c) for c in ("mode3a", "mode_c_ft", "mode_s"))
    has_3a, has_c, has_s = _present(mode3a, n), _present(mode_c, n), _present(mode_s, n)
    code3a = np.array([int(str(v), 8) if h else 0 for v, h in zip(mode3a, has_3a)], np.int64) if mode3a is not None \
        else np.zeros(n, np.int64)
    _check_range(code3a, has_3a, 0, 0o7777, "mode3a", "plots")
    quarter_fl = np.zeros(n, np.int64)
    if mode_c is not None:
        quarter_fl[has_c] = np.rint(mode_c[has_c].astype(float) / u.FLIGHT_LEVEL_LSB_FT).astype(np.int64)
    _check_range(quarter_fl, has_c, -(1 << 13), (1 << 13) - 1, "mode_c_ft", "plots")
    address = np.array([int(str(v), 16) if h else 0 for v, h in zip(mode_s, has_s)], np.int64) if mode_s is not None \
        else np.zeros(n, np.int64)
    primary = ~np.isin(plots["sensor"].astype(str).to_numpy(), list(ssr_only_sensors))
    has_ssr = has_3a | has_c | has_s
    typ = np.where(has_s, np.where(primary, u.TYP_MODE_S_ROLL_CALL_PSR, u.TYP_MODE_S_ROLL_CALL),
                   np.where(has_ssr, np.where(primary, u.TYP_SSR_PSR, u.TYP_SSR), u.TYP_PSR))
    typ = np.where(~primary & ~has_ssr, u.TYP_NO_DETECTION, typ)
    records = []
    for i in range(n):
        items: dict = {
            "010": (("SAC", int(ids[i, 0])), ("SIC", int(ids[i, 1]))),
            "140": int(tod[i]),
            "020": (int(typ[i]) << 4,),
            "040": (("RHO", int(rho[i])), ("THETA", int(theta[i]))),
        }
        if has_3a[i]:
            items["070"] = (0, 0, 0, 0, ("MODE3A", int(code3a[i])))
        if has_c[i]:
            items["090"] = (0, 0, ("FL", int(quarter_fl[i])))
        if has_s[i]:
            items["220"] = int(address[i])
        records.append(cat048.cv_record.create(items))
    return records


def service_records(service: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *,
                    time_of_day_at_epoch_s: float = 0.0) -> list:
    """One libasterix CAT034 record per row of ``service``: columns ``time``, ``sensor``,
    ``message`` (``north_marker`` or ``sector_crossing``) and ``azimuth_deg`` (sector crossings)."""
    _, cat034 = _specs()
    finite = np.isfinite(service["time"].to_numpy(float))
    if not finite.all():
        raise ValueError(f"service messages: row {int(np.flatnonzero(~finite)[0])}, column time: a finite number is required")
    ids = _sac_sic(service["sensor"].to_numpy(), sac_sic, "service messages")
    tod = _time_of_day_raw(service["time"].to_numpy(float), time_of_day_at_epoch_s)
    kinds = service["message"].astype(str).to_numpy()
    unknown = ~np.isin(kinds, ["north_marker", "sector_crossing"])
    if unknown.any():
        row = int(np.flatnonzero(unknown)[0])
        raise ValueError(f"service messages: row {row}, column message: {kinds[row]!r} is not north_marker "
                         "or sector_crossing")
    azimuth = _column(service, "azimuth_deg")
    records = []
    for i in range(len(service)):
        items: dict = {"000": u.NORTH_MARKER, "010": (("SAC", int(ids[i, 0])), ("SIC", int(ids[i, 1]))),
                       "030": int(tod[i])}
        if kinds[i] == "sector_crossing":
            if azimuth is None or pd.isna(azimuth[i]):
                raise ValueError(f"service messages: row {i}, column azimuth_deg: a sector crossing needs an azimuth")
            items["000"] = u.SECTOR_CROSSING
            items["020"] = int(np.mod(np.rint(float(azimuth[i]) / u.SECTOR_LSB_DEG), 256))
        records.append(cat034.cv_record.create(items))
    return records


def _blocks(spec, records: list, max_records_per_block: int) -> list[bytes]:
    blocks, current, size = [], [], 3
    for record in records:
        record_bytes = len(record.unparse().to_bytes())
        if current and (len(current) >= max_records_per_block or size + record_bytes > MAX_BLOCK_BYTES):
            blocks.append(spec.create(current).unparse().to_bytes())
            current, size = [], 3
        current.append(record)
        size += record_bytes
    if current:
        blocks.append(spec.create(current).unparse().to_bytes())
    return blocks


def encode_asterix(plots: pd.DataFrame | None, sac_sic: Mapping[str, tuple[int, int]], *,
                   service: pd.DataFrame | None = None, ssr_only_sensors: Collection[str] = (),
                   time_of_day_at_epoch_s: float = 0.0, max_records_per_block: int = 128) -> bytes:
    """Encode plots (CAT048) and service messages (CAT034) to one ASTERIX byte string.

    ``sac_sic`` maps each sensor name to its (SAC, SIC).  ``time`` (seconds since the
    scenario epoch) becomes the time of day ``time_of_day_at_epoch_s + time`` modulo one day.
    I048/020 TYP: Mode S roll-call when ``mode_s`` is given, else SSR when ``mode3a`` or
    ``mode_c_ft`` is, combined with PSR unless the sensor is in ``ssr_only_sensors``; a plot
    without SSR data is a single PSR detection (0, no detection, for an SSR-only sensor).
    """
    if max_records_per_block < 1:
        raise ValueError("max_records_per_block must be at least 1")
    cat048, cat034 = _specs()
    entries: list[tuple[float, int, int, object]] = []  # (time, service first, order, record)
    if service is not None and len(service):
        for i, (t, rec) in enumerate(zip(service["time"].to_numpy(float),
                                         service_records(service, sac_sic, time_of_day_at_epoch_s=time_of_day_at_epoch_s))):
            entries.append((t, 0, i, rec))
    if plots is not None and len(plots):
        for i, (t, rec) in enumerate(zip(plots["time"].to_numpy(float),
                                         plot_records(plots, sac_sic, ssr_only_sensors=ssr_only_sensors,
                                                      time_of_day_at_epoch_s=time_of_day_at_epoch_s))):
            entries.append((t, 1, i, rec))
    entries.sort(key=lambda e: (e[0], e[1], e[2]))
    out: list[bytes] = []
    start = 0
    while start < len(entries):
        kind = entries[start][1]
        stop = start
        while stop < len(entries) and entries[stop][1] == kind:
            stop += 1
        spec = cat034 if kind == 0 else cat048
        out.extend(_blocks(spec, [e[3] for e in entries[start:stop]], max_records_per_block))
        start = stop
    return b"".join(out)

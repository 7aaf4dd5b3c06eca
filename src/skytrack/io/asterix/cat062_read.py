"""Reading CAT062 system tracks back (issue 11 item 2): numpy over all records, or libasterix record by record.

:func:`decode_cat062` returns the tracks-like table of the items skytrack writes
(:mod:`skytrack.io.asterix.cat062`): I062/010, 015, 070, 105, 100, 185, 060, 380 ADR/ID,
040, 080 CNF/CST/TSB, 136/130, 220 and 500 APC/ATV/AGA.  The numpy engine finds the
records with the compiled scan of :mod:`skytrack.io.asterix.framing` (the CAT062 edition 1.21
UAP below) and decodes every item over all records at once; it is tested value for value
against the libasterix engine.  ``engine="auto"`` uses numpy and falls back to libasterix
for input the scan cannot walk (I062/510, an I062/295 beyond 28 subitems, a damaged block:
libasterix then names the block).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skytrack.io.asterix import framing as fr  # the compiled record scan
from skytrack.io.asterix.cat062 import CATEGORY, FEET_M, LATLON_LSB_DEG, SECONDS_PER_DAY, TIME_LSB_S, _spec

DECODED_COLUMNS = ["time", "track_id", "x", "y", "z", "vx", "vy", "vz", "var_x", "var_y", "var_z", "var_vx", "var_vy",
                   "lat", "lon", "alt_m", "status", "mode3a", "icao24", "callsign", "sac", "sic", "service_id",
                   "time_of_day_s", "track_begin"]
#: the fields the engines read, before ``time`` and ``z`` are derived
_FIELDS = [c for c in DECODED_COLUMNS if c not in ("time", "z")] + ["geometric"]


def _quantity(item, name: str, unit: str) -> float:
    return item.variation.get_item(name).variation.content.as_quantity(unit)


def _record_values(record) -> dict:
    """The fields skytrack writes, read from one libasterix CAT062 record (NaN / None when absent)."""
    nan = float("nan")
    row: dict = {}
    i010 = record.get_item("010")
    row["sac"], row["sic"] = (i010.variation.get_item(k).as_uint() for k in ("SAC", "SIC"))
    i015 = record.get_item("015")
    row["service_id"] = i015.as_uint() if i015 is not None else -1
    row["time_of_day_s"] = record.get_item("070").variation.content.as_quantity("s")
    i040 = record.get_item("040")
    row["track_id"] = i040.as_uint() if i040 is not None else -1
    i100, i105, i185 = record.get_item("100"), record.get_item("105"), record.get_item("185")
    row["x"], row["y"] = (_quantity(i100, k, "m") for k in ("X", "Y")) if i100 is not None else (nan, nan)
    row["lat"], row["lon"] = (_quantity(i105, k, "°") for k in ("LAT", "LON")) if i105 is not None else (nan, nan)
    row["vx"], row["vy"] = (_quantity(i185, k, "m/s") for k in ("VX", "VY")) if i185 is not None else (nan, nan)
    i130, i136, i220 = record.get_item("130"), record.get_item("136"), record.get_item("220")
    row["alt_m"] = (i130.variation.content.as_quantity("ft") * FEET_M if i130 is not None
                    else i136.variation.content.as_quantity("FL") * 100.0 * FEET_M if i136 is not None else nan)
    row["geometric"] = i130 is not None
    row["vz"] = i220.variation.content.as_quantity("ft/min") * FEET_M / 60.0 if i220 is not None else nan
    i060 = record.get_item("060")
    row["mode3a"] = i060.variation.get_item("MODE3A").variation.content.as_string() if i060 is not None else None
    i380 = record.get_item("380")
    adr = i380.variation.get_item("ADR") if i380 is not None else None
    ident = i380.variation.get_item("ID") if i380 is not None else None
    row["icao24"] = f"{adr.as_uint():06x}" if adr is not None else None
    row["callsign"] = ident.variation.content.as_string().rstrip() if ident is not None else None
    i080 = record.get_item("080")
    status = {}
    for flag in ("CNF", "CST", "TSB"):
        value = i080.variation.get_item(flag) if i080 is not None else None
        status[flag] = value.as_uint() if value is not None else 0
    row["status"] = None if i080 is None or status["CNF"] else "coasting" if status["CST"] else "confirmed"
    row["track_begin"] = bool(status["TSB"])
    i500 = record.get_item("500")
    accuracy = {k: (i500.variation.get_item(k) if i500 is not None else None) for k in ("APC", "ATV", "AGA")}
    apc, atv, aga = accuracy["APC"], accuracy["ATV"], accuracy["AGA"]
    row["var_x"], row["var_y"] = ((_quantity(apc, k, "m") ** 2 for k in ("X", "Y")) if apc is not None else (nan, nan))
    row["var_vx"], row["var_vy"] = ((_quantity(atv, k, "m/s") ** 2 for k in ("X", "Y")) if atv is not None
                                    else (nan, nan))
    row["var_z"] = (aga.variation.content.as_quantity("ft") * FEET_M) ** 2 if aga is not None else nan
    return row


def decode_cat062_libasterix(data: bytes | bytearray | memoryview) -> tuple[pd.DataFrame, list[tuple[int, int]]]:
    """Every CAT062 record's fields through libasterix (about 400-4 000 records/s), and the
    (byte offset, category) of the blocks of other categories; a block libasterix cannot parse
    is an error naming its byte offset."""
    from asterix.base import Bits, RawDatablock

    spec = _spec()
    data = bytes(data)
    rows: list[dict] = []
    skipped: list[tuple[int, int]] = []
    offset, block = 0, 0
    while offset < len(data):
        length = int.from_bytes(data[offset + 1:offset + 3], "big") if offset + 3 <= len(data) else -1
        if length < 3 or offset + length > len(data):
            raise ValueError(f"CAT062 input: byte offset {offset} (block {block}): bad block length {length}")
        if data[offset] != CATEGORY:
            skipped.append((offset, data[offset]))
        else:
            parsed = RawDatablock.parse(Bits.from_bytes(data[offset:offset + length]))
            records = (ValueError("not one data block") if isinstance(parsed, ValueError) or len(parsed) != 1
                       else spec.cv_uap.parse(parsed[0].get_raw_records()))
            if isinstance(records, ValueError):
                raise ValueError(f"CAT062 input: byte offset {offset} (block {block}): libasterix cannot parse "
                                 f"the block ({records})")
            rows.extend(_record_values(record) for record in records)
        offset += length
        block += 1
    return pd.DataFrame(rows, columns=_FIELDS), skipped


#: CAT062 edition 1.21 UAP for the scan: (item, kind, size, compound subitems as (kind, size)); kind 0: not
#: walked by the scan (spare FRNs; I062/510, whose elements end in FX) -> engine "auto" falls back to libasterix
_F, _E, _R, _X, _C = fr.FIXED, fr.EXTENDED, fr.REPETITIVE, fr.EXPLICIT, fr.COMPOUND
_UAP = [
    ("010", _F, 2, None), ("-", 0, 0, None), ("015", _F, 1, None), ("070", _F, 3, None), ("105", _F, 8, None),
    ("100", _F, 6, None), ("185", _F, 4, None), ("210", _F, 2, None), ("060", _F, 2, None), ("245", _F, 7, None),
    ("380", _C, 0, [(_F, 3), (_F, 6), (_F, 2), (_F, 2), (_F, 2), (_F, 2), (_F, 2), (_E, 1), (_R, 15), (_F, 2), (_F, 2),
                    (_F, 7), (_F, 2), (_F, 2), (_F, 2), (_F, 2), (_F, 2), (_F, 2), (_F, 1), (_F, 8), (_F, 1), (_F, 6),
                    (_F, 2), (_F, 1), (_R, 8), (_F, 2), (_F, 2), (_F, 2)]),
    ("040", _F, 2, None), ("080", _E, 1, None),
    ("290", _C, 0, [(_F, 1)] * 4 + [(_F, 2)] + [(_F, 1)] * 5), ("200", _F, 1, None),
    ("295", _C, 0, [(_F, 1)] * 31), ("136", _F, 2, None), ("130", _F, 2, None), ("135", _F, 2, None),
    ("220", _F, 2, None),
    ("390", _C, 0, [(_F, 2), (_F, 7), (_F, 4), (_F, 1), (_F, 4), (_F, 1), (_F, 4), (_F, 4), (_F, 3), (_F, 2), (_F, 2),
                    (_R, 4), (_F, 6), (_F, 1), (_F, 7), (_F, 7), (_F, 2), (_F, 7)]),
    ("270", _E, 1, None), ("300", _F, 1, None),
    ("110", _C, 0, [(_F, 1), (_F, 4), (_F, 6), (_F, 2), (_F, 2), (_F, 1), (_F, 1)]), ("120", _F, 2, None),
    ("510", 0, 0, None), ("500", _C, 0, [(_F, 4), (_F, 2), (_F, 4), (_F, 1), (_F, 1), (_F, 2), (_F, 2), (_F, 1)]),
    ("340", _C, 0, [(_F, 2), (_F, 4), (_F, 2), (_F, 2), (_F, 2), (_F, 1)]),
    ("-", 0, 0, None), ("-", 0, 0, None), ("-", 0, 0, None), ("-", 0, 0, None), ("-", 0, 0, None),
    ("RE", _X, 0, None), ("SP", _X, 0, None),
]
ITEMS_READ = ("010", "015", "070", "105", "100", "185", "060", "380", "040", "080", "136", "130", "220", "500")


def _tables() -> tuple[np.ndarray, ...]:
    width, sub_width = max(fr.MAX_FRN, len(_UAP)), max(fr.MAX_SUB, 32)  # the scan never indexes past these
    category_row = np.full(256, -1, np.int64)
    category_row[CATEGORY] = 0
    kinds, sizes = np.zeros((1, width), np.int64), np.zeros((1, width), np.int64)
    read_column = np.full((1, width), -1, np.int64)
    sub_kinds, sub_sizes = np.zeros((1, width, sub_width), np.int64), np.zeros((1, width, sub_width), np.int64)
    for frn, (item, kind, size, subs) in enumerate(_UAP):
        kinds[0, frn], sizes[0, frn] = kind, size
        if item in ITEMS_READ:
            read_column[0, frn] = ITEMS_READ.index(item)
        for j, (sub_kind, sub_size) in enumerate(subs or []):
            sub_kinds[0, frn, j], sub_sizes[0, frn, j] = sub_kind, sub_size
    return category_row, kinds, sizes, read_column, sub_kinds, sub_sizes


_TABLES = _tables()


def _unsigned(buf: np.ndarray, at: np.ndarray, n_bytes: int) -> np.ndarray:
    """Big-endian unsigned integers of ``n_bytes`` at ``at`` (0 where ``at`` is -1)."""
    safe = np.where(at >= 0, at, 0)
    value = np.zeros(at.size, np.int64)
    for k in range(n_bytes):
        value = (value << 8) | buf[np.minimum(safe + k, buf.size - 1)]
    return np.where(at >= 0, value, 0)


def _signed(value: np.ndarray, bits: int) -> np.ndarray:
    return np.where(value >= 1 << (bits - 1), value - (1 << bits), value)


def _compound(buf: np.ndarray, at: np.ndarray, sizes: list[int]) -> tuple[np.ndarray, list[np.ndarray]]:
    """Offsets of the first ``len(sizes)`` (<= 7, first octet) subitems of compound items at ``at`` (-1: absent)."""
    n_primary = np.where(at >= 0, 1, 0)
    more = at >= 0
    for _ in range(3):  # an FSPEC of up to 4 octets
        more &= (_unsigned(buf, np.where(more, at + n_primary - 1, -1), 1) & 1) == 1
        n_primary += more
    first = _unsigned(buf, at, 1)
    cursor, offsets = at + n_primary, []
    for j, size in enumerate(sizes):
        present = (at >= 0) & ((first >> (7 - j)) & 1 == 1)
        offsets.append(np.where(present, cursor, -1))
        cursor = cursor + np.where(present, size, 0)
    return first, offsets


def _decode_numpy(data) -> tuple[pd.DataFrame, list[tuple[int, int]]] | None:
    """The numpy engine; ``None`` when the scan met anything but blocks of other categories."""
    buf = np.frombuffer(bytes(data), np.uint8)
    n = buf.size
    rec_cat, rec_block, rec_start = (np.empty(n // 2 + 1, np.int64) for _ in range(3))
    rec_items = np.empty((n // 2 + 1, len(ITEMS_READ)), np.int64)
    problems = [np.empty(n // 3 + 2, np.int64) for _ in range(5)]
    count, n_problems, _ = fr.scan(buf, *_TABLES, rec_cat, rec_block, rec_start, rec_items, *problems)
    code, offset, _, category = (p[:n_problems] for p in problems[:4])
    if (code != 2).any():
        return None
    items = rec_items[:count]
    at = {item: items[:, k] for k, item in enumerate(ITEMS_READ)}
    if (at["070"] < 0).any() or (at["010"] < 0).any():
        return None  # a record without its time or source: libasterix says which
    nan = np.nan
    sac_sic = _unsigned(buf, at["010"], 2)
    lat_lon = _unsigned(buf, at["105"], 8)
    xy = _unsigned(buf, at["100"], 6)
    v = _unsigned(buf, at["185"], 4)
    alt130, fl136, climb = (_signed(_unsigned(buf, at[i], 2), 16) for i in ("130", "136", "220"))
    present = {item: at[item] >= 0 for item in ITEMS_READ}
    _, (adr_at, id_at) = _compound(buf, at["380"], [3, 6])
    _, (apc_at, _cov, _apw, aga_at, _aba, atv_at) = _compound(buf, at["500"], [4, 2, 4, 1, 1, 2])
    status = at["080"]
    octet = [_unsigned(buf, status, 1)]
    for _ in range(3):
        previous = octet[-1]
        status = np.where((status >= 0) & (previous & 1 == 1), status + 1, -1)
        octet.append(_unsigned(buf, status, 1))
    cnf, tsb, cst = (octet[0] >> 1) & 1, (octet[1] >> 5) & 1, (octet[3] >> 7) & 1
    apc, atv = _unsigned(buf, apc_at, 4), _unsigned(buf, atv_at, 2)
    from skytrack.io.asterix.decode import _OCTAL_CODES, _text_by_value

    callsign = _unsigned(buf, id_at, 6)
    frame = pd.DataFrame({
        "sac": sac_sic >> 8, "sic": sac_sic & 0xFF,
        "service_id": np.where(present["015"], _unsigned(buf, at["015"], 1), -1),
        "time_of_day_s": _unsigned(buf, at["070"], 3) * TIME_LSB_S,
        "track_id": np.where(present["040"], _unsigned(buf, at["040"], 2), -1),
        "x": np.where(present["100"], _signed(xy >> 24, 24) * 0.5, nan),
        "y": np.where(present["100"], _signed(xy & 0xFFFFFF, 24) * 0.5, nan),
        "lat": np.where(present["105"], _signed(lat_lon >> 32, 32) * LATLON_LSB_DEG, nan),
        "lon": np.where(present["105"], _signed(lat_lon & 0xFFFFFFFF, 32) * LATLON_LSB_DEG, nan),
        "vx": np.where(present["185"], _signed(v >> 16, 16) * 0.25, nan),
        "vy": np.where(present["185"], _signed(v & 0xFFFF, 16) * 0.25, nan),
        "alt_m": np.where(present["130"], alt130 * 6.25 * FEET_M,
                          np.where(present["136"], fl136 * 0.25 * 100.0 * FEET_M, nan)),
        "geometric": present["130"],
        "vz": np.where(present["220"], climb * 6.25 * FEET_M / 60.0, nan),
        "mode3a": np.where(present["060"], _OCTAL_CODES[_unsigned(buf, at["060"], 2) & 0x0FFF], None),
        "icao24": _text_by_value(_unsigned(buf, adr_at, 3), adr_at >= 0, lambda a: f"{a:06x}"),
        "callsign": _text_by_value(callsign, id_at >= 0, _callsign_text),
        "status": np.where(~present["080"] | (cnf == 1), None, np.where(cst == 1, "coasting", "confirmed")),
        "track_begin": tsb == 1,
        "var_x": np.where(apc_at >= 0, ((apc >> 16) * 0.5) ** 2, nan),
        "var_y": np.where(apc_at >= 0, ((apc & 0xFFFF) * 0.5) ** 2, nan),
        "var_z": np.where(aga_at >= 0, (_unsigned(buf, aga_at, 1) * 6.25 * FEET_M) ** 2, nan),
        "var_vx": np.where(atv_at >= 0, ((atv >> 8) * 0.25) ** 2, nan),
        "var_vy": np.where(atv_at >= 0, ((atv & 0xFF) * 0.25) ** 2, nan),
    }, columns=_FIELDS)
    return frame, [(int(o), int(c)) for o, c in zip(offset, category)]


#: the ICAO 6-bit alphabet of I062/380 ID, by code
_ID_ALPHABET = {**{1 + k: chr(65 + k) for k in range(26)}, 32: " ", **{48 + d: str(d) for d in range(10)}}


def _callsign_text(code: int) -> str:
    return "".join(_ID_ALPHABET.get((code >> (42 - 6 * k)) & 0x3F, "?") for k in range(8)).rstrip()


def decode_cat062(data: bytes | bytearray | memoryview, *, time_of_day_at_epoch_s: float = 0.0,
                  origin=None, engine: str = "auto") -> pd.DataFrame:
    """CAT062 records (edition 1.21) as a tracks-like table (columns :data:`DECODED_COLUMNS`).

    ``time`` is the I062/070 time of day unwrapped over midnight (per SAC/SIC) minus
    ``time_of_day_at_epoch_s``, a whole number of days added so that the first record lies
    within 12 h of the epoch; ``track_id`` is the 16-bit I062/040; ``status`` is ``coasting``
    (CST), ``confirmed``, or null for a tentative track (CNF = 1); ``track_begin`` is TSB;
    variances are the squared I062/500 standard deviations; ``z`` is computed from
    ``lat``/``lon``/``alt_m`` (a geometric I062/130 height) when ``origin`` is given.  Blocks
    of other categories are skipped and listed in ``frame.attrs["skipped_blocks"]`` as (byte
    offset, category).  ``engine``: ``numpy``, ``libasterix`` or ``auto`` (see the module docstring).
    """
    if engine not in ("auto", "numpy", "libasterix"):
        raise ValueError(f"engine must be auto, numpy or libasterix, got {engine!r}")
    decoded = None if engine == "libasterix" else _decode_numpy(data)
    if decoded is None and engine == "numpy":
        raise ValueError("CAT062 input: the numpy engine cannot walk these records (I062/510, a damaged block, ...); "
                         "use engine='libasterix' to locate them")
    frame, skipped = decoded if decoded is not None else decode_cat062_libasterix(data)
    from skytrack.io.asterix.decode import unwrap_time_of_day

    time = np.empty(0)
    if len(frame):
        key = frame["sac"].to_numpy(np.int64) * 256 + frame["sic"].to_numpy(np.int64)
        time = unwrap_time_of_day(frame["time_of_day_s"].to_numpy(float), key) - time_of_day_at_epoch_s
        time -= SECONDS_PER_DAY * np.round(time[0] / SECONDS_PER_DAY)
    frame["time"] = time
    z = np.full(len(frame), np.nan)
    geometric = frame["geometric"].to_numpy(bool)
    if origin is not None and geometric.any():
        from skytrack.io.frames import enu_from_geodetic

        enu = enu_from_geodetic(frame["lat"].to_numpy(float)[geometric], frame["lon"].to_numpy(float)[geometric],
                                frame["alt_m"].to_numpy(float)[geometric], origin)
        z[geometric] = enu[:, 2]
    frame["z"] = z
    frame = frame[DECODED_COLUMNS].astype({"track_id": np.int64, "sac": np.int64, "sic": np.int64,
                                           "service_id": np.int64, "track_begin": bool})
    frame.attrs["skipped_blocks"] = skipped
    return frame

"""CAT048 plots to ASTERIX bytes with numpy, for ``skytrack replay`` and the service benchmark (issue 11 item 3).

:func:`skytrack.io.asterix.encode_asterix` builds every record with libasterix (about 3 000 records/s): a
replay of a large plots file, or a benchmark at 50 000 plots/s, needs more.  :func:`encode_plots_cat048`
writes the same items (I048/010, 140, 020 TYP, 040, and I048/070, 090, 220 when the plot has them) with
numpy byte arithmetic over all plots at once, in the same order (time, stable) and the same blocks
(``max_records_per_block`` records each), so its output is byte for byte ``encode_asterix``'s for plots
without service messages (tests/service/test_replay.py checks the equality).

Record layout (CAT048 edition 1.32 UAP): FSPEC (1 octet, 2 with I048/220: FRN 1-7 + FX, FRN 8), then
010 SAC SIC | 140 time of day (1/128 s, 3 octets) | 020 TYP << 5 | 040 RHO (1/256 NM), THETA (360/2^16 deg)
| 070 Mode 3/A (12 bits) | 090 flight level (14-bit two's complement, 1/4 FL) | 220 address (3 octets).
Values are quantised exactly as the libasterix encoder path quantises them (:mod:`skytrack.io.asterix.encode`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

import numpy as np
import pandas as pd

from skytrack.io.asterix import units as u
from skytrack.io.asterix.encode import _check_range, _present, _sac_sic, _time_of_day_raw

#: (item, octets) in record order
_ITEMS = (("fspec1", 1), ("fspec2", 1), ("010", 2), ("140", 3), ("020", 1), ("040", 4), ("070", 2), ("090", 2),
          ("220", 3))


def _codes(values, present: np.ndarray, base: int) -> np.ndarray:
    """Integer codes of a text column, one parse per distinct text."""
    out = np.zeros(len(present), np.int64)
    if values is None or not present.any():
        return out
    texts = np.asarray(values, dtype=object)[present].astype(str)
    distinct, inverse = np.unique(texts, return_inverse=True)
    parsed = np.array([int(text, base) for text in distinct], np.int64)
    out[present] = parsed[inverse.reshape(-1)]
    return out


def _big_endian(value: np.ndarray, octets: int) -> np.ndarray:
    """``[n, octets]`` big-endian bytes of non-negative integers."""
    shifts = 8 * np.arange(octets - 1, -1, -1)
    return ((value[:, None] >> shifts) & 0xFF).astype(np.uint8)


def encode_plots_cat048(plots: pd.DataFrame, sac_sic: Mapping[str, tuple[int, int]], *,
                        ssr_only_sensors: Collection[str] = (), time_of_day_at_epoch_s: float = 0.0,
                        max_records_per_block: int = 128) -> tuple[bytes, np.ndarray, np.ndarray]:
    """Plots (docs/formats.md columns) to CAT048 data blocks; returns ``(data, block_starts, block_times)``:
    the bytes, each block's byte offset, and the latest plot time (seconds since the epoch) in each block."""
    if max_records_per_block < 1:
        raise ValueError("max_records_per_block must be at least 1")
    n = len(plots)
    if n == 0:
        return b"", np.zeros(0, np.int64), np.zeros(0)
    for name in ("time", "range_m", "azimuth_deg"):
        finite = np.isfinite(plots[name].to_numpy(float))
        if not finite.all():
            row = int(np.flatnonzero(~finite)[0])
            raise ValueError(f"plots: row {row}, column {name}: a finite number is required")
    order = np.argsort(plots["time"].to_numpy(float), kind="stable")
    plots = plots.iloc[order]
    times = plots["time"].to_numpy(float)
    ids = _sac_sic(plots["sensor"].to_numpy(), sac_sic, "plots")
    tod = _time_of_day_raw(times, time_of_day_at_epoch_s)
    rho = np.rint(plots["range_m"].to_numpy(float) / u.RHO_LSB_M).astype(np.int64)
    _check_range(rho, np.ones(n, bool), 0, 65535, "range_m", "plots")
    theta = np.mod(np.rint(plots["azimuth_deg"].to_numpy(float) / u.THETA_LSB_DEG).astype(np.int64), 65536)
    columns = {c: (plots[c].to_numpy() if c in plots.columns else None) for c in ("mode3a", "mode_c_ft", "mode_s")}
    has_3a, has_c, has_s = (_present(columns[c], n) for c in ("mode3a", "mode_c_ft", "mode_s"))
    code3a = _codes(columns["mode3a"], has_3a, 8)
    _check_range(code3a, has_3a, 0, 0o7777, "mode3a", "plots")
    quarter_fl = np.zeros(n, np.int64)
    if columns["mode_c_ft"] is not None:
        quarter_fl[has_c] = np.rint(columns["mode_c_ft"][has_c].astype(float) / u.FLIGHT_LEVEL_LSB_FT).astype(np.int64)
    _check_range(quarter_fl, has_c, -(1 << 13), (1 << 13) - 1, "mode_c_ft", "plots")
    address = _codes(columns["mode_s"], has_s, 16)
    primary = ~np.isin(plots["sensor"].astype(str).to_numpy(), list(ssr_only_sensors))
    has_ssr = has_3a | has_c | has_s
    typ = np.where(has_s, np.where(primary, u.TYP_MODE_S_ROLL_CALL_PSR, u.TYP_MODE_S_ROLL_CALL),
                   np.where(has_ssr, np.where(primary, u.TYP_SSR_PSR, u.TYP_SSR), u.TYP_PSR))
    typ = np.where(~primary & ~has_ssr, u.TYP_NO_DETECTION, typ)

    fspec1 = 0xF0 | (has_3a * 0x08) | (has_c * 0x04) | (has_s * 0x01)
    parts = {
        "fspec1": (fspec1[:, None].astype(np.uint8), np.ones(n, bool)),
        "fspec2": (np.full((n, 1), 0x80, np.uint8), has_s),
        "010": (np.column_stack([ids[:, 0], ids[:, 1]]).astype(np.uint8), np.ones(n, bool)),
        "140": (_big_endian(tod, 3), np.ones(n, bool)),
        "020": ((typ << 5)[:, None].astype(np.uint8), np.ones(n, bool)),
        "040": (_big_endian((rho << 16) | theta, 4), np.ones(n, bool)),
        "070": (_big_endian(code3a & 0x0FFF, 2), has_3a),
        "090": (_big_endian(quarter_fl & 0x3FFF, 2), has_c),
        "220": (_big_endian(address, 3), has_s),
    }
    width = sum(octets for _, octets in _ITEMS)
    table = np.zeros((n, width), np.uint8)
    used = np.zeros((n, width), bool)
    column = 0
    for name, octets in _ITEMS:
        values, present = parts[name]
        table[:, column:column + octets] = values
        used[:, column:column + octets] = present[:, None]
        column += octets
    record_bytes = table[used]  # row-major: each record's bytes in item order, records one after the other
    record_length = used.sum(axis=1)

    # blocks of max_records_per_block records: a 3-octet header (CAT, LEN) before each
    block = np.arange(n) // max_records_per_block
    n_blocks = int(block[-1]) + 1
    block_length = 3 + np.bincount(block, weights=record_length, minlength=n_blocks).astype(np.int64)
    block_starts = np.concatenate([[0], np.cumsum(block_length)[:-1]])
    out = np.empty(int(block_length.sum()), np.uint8)
    header_at = block_starts[:, None] + np.arange(3)
    out[header_at] = np.column_stack([np.full(n_blocks, 48), block_length >> 8, block_length & 0xFF]).astype(np.uint8)
    is_record = np.ones(out.size, bool)
    is_record[header_at.reshape(-1)] = False
    out[is_record] = record_bytes
    block_times = np.maximum.reduceat(times, np.arange(0, n, max_records_per_block))
    return out.tobytes(), block_starts.astype(np.int64), block_times

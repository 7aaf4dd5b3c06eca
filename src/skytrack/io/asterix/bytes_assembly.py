"""Record assembly with numpy shared by the ASTERIX encoders (issue 11 item 2; CAT062, CAT048,
CAT034 and CAT021 records written by skytrack).

Every item is a column of bytes (:func:`big_endian`); :func:`assemble_records` scatters the
columns of all rows into one buffer at offsets computed from each item's presence and writes
the FSPECs; :func:`blocks_from_records` cuts the records into data blocks.  Text columns are
turned to codes once per distinct text (:func:`distinct_texts`, :func:`codes_of_texts`,
naming the first row a text cannot be written from): Mode 3/A (I048/070, I062/060), ICAO
24-bit address (I048/220, I062/380 ADR, I021/080), callsign in the ICAO 6-bit set
(I062/380 ID, I021/170).  :func:`time_of_day_raw` is the 1/128 s time of day of
I048/140, I034/030, I062/070 and I021/071.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skytrack.io.asterix import units as u

#: the ICAO 6-bit character set of I062/380 ID and I021/170 (space, A-Z, 0-9) -> code
SIX_BIT_CODE = {" ": 32, **{chr(65 + k): 1 + k for k in range(26)}, **{str(d): 48 + d for d in range(10)}}


def time_of_day_raw(time_s: np.ndarray, time_of_day_at_epoch_s: float) -> np.ndarray:
    """Seconds since the epoch as the time of day in 1/128 s (modulo one day)."""
    seconds = np.mod(np.asarray(time_s, float) + time_of_day_at_epoch_s, u.SECONDS_PER_DAY)
    return np.mod(np.rint(seconds / u.TIME_LSB_S).astype(np.int64), int(u.SECONDS_PER_DAY / u.TIME_LSB_S))


def finite_column(frame: pd.DataFrame, name: str, what: str) -> np.ndarray:
    """A required numeric column; the first row without a finite number is named."""
    values = frame[name].to_numpy(float)
    if not np.isfinite(values).all():
        raise ValueError(f"{what}: row {int(np.flatnonzero(~np.isfinite(values))[0])}, column {name}: "
                         "a finite number is required")
    return values


def distinct_texts(frame: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Distinct texts and each row's index into them (-1: null)."""
    if name not in frame.columns:
        return np.empty(0, object), np.full(len(frame), -1)
    values = frame[name].astype(object).to_numpy()
    present = ~pd.isna(values)
    index = np.full(len(values), -1)
    if not present.any():
        return np.empty(0, object), index
    distinct, inverse = np.unique(values[present].astype(str), return_inverse=True)
    index[present] = inverse
    return distinct, index


def codes_of_texts(distinct: np.ndarray, index: np.ndarray, parse, column: str, what: str) -> np.ndarray:
    """``parse`` of every distinct text (few aircraft), spread to the rows; the first bad row is named."""
    codes = np.zeros(distinct.size, np.int64)
    for k, text in enumerate(distinct):
        try:
            codes[k] = parse(text)
        except ValueError:
            row = int(np.flatnonzero(index == k)[0])
            raise ValueError(f"{what}: row {row}, column {column}: {text!r} cannot be written") from None
    return np.where(index >= 0, codes[np.maximum(index, 0)] if codes.size else 0, 0)


def mode3a_code(text: str) -> int:
    if len(text) != 4 or any(c not in "01234567" for c in text):
        raise ValueError(text)
    return int(text, 8)


def icao24_code(text: str) -> int:
    if len(text) != 6:
        raise ValueError(text)
    return int(text, 16)


def callsign_code(text: str) -> int:
    """Up to 8 characters of the ICAO 6-bit set (I062/380 ID, I021/170) as one 48-bit integer, space-padded."""
    text = text.strip().upper()
    if len(text) > 8 or any(c not in SIX_BIT_CODE for c in text):
        raise ValueError(text)
    code = 0
    for c in text.ljust(8):
        code = (code << 6) | SIX_BIT_CODE[c]
    return code


def big_endian(values: np.ndarray, n_bytes: int) -> np.ndarray:
    """(rows, n_bytes) uint8, most significant byte first."""
    shifts = 8 * np.arange(n_bytes - 1, -1, -1)
    return ((np.asarray(values, np.int64)[:, None] >> shifts) & 0xFF).astype(np.uint8)


def assemble_records(n: int, columns: list[tuple[int, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]]
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Records of any category assembled with numpy: ``columns`` lists, in UAP order, each item's
    FRN index (from 0), presence per row and parts ``(present, bytes (rows, k))``.  Returns all
    records back to back (uint8) and each record's start offset (one more: the end)."""
    n_octets = max(frn for frn, _, _ in columns) // 7 + 1
    top = 7 * n_octets - 1
    fspec_bits = np.zeros(n, np.int64)  # FRN index k at bit top - k (octets of 7 bits)
    for frn, present, _ in columns:
        fspec_bits |= present.astype(np.int64) << (top - frn)
    octets = np.stack([(fspec_bits >> (top - 6 - 7 * k)) & 0x7F for k in range(n_octets)], axis=1)
    fspec_len = np.where(octets.any(axis=1), n_octets - np.argmax(octets[:, ::-1] != 0, axis=1), 1)
    fspec = (octets << 1) | (np.arange(n_octets)[None, :] < fspec_len[:, None] - 1)  # FX on all but the last octet
    lengths = fspec_len.copy()
    for _, present, parts in columns:
        for part_present, data in parts:
            lengths += np.where(present & part_present, data.shape[1], 0)
    starts = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    out = np.zeros(int(starts[-1]), np.uint8)
    for k in range(n_octets):
        used = k < fspec_len
        out[starts[:-1][used] + k] = fspec[used, k]
    cursor = starts[:-1] + fspec_len
    for _, present, parts in columns:
        for part_present, data in parts:
            rows = present & part_present
            at = cursor[rows]
            for b in range(data.shape[1]):
                out[at + b] = data[rows, b]
            cursor = cursor + np.where(rows, data.shape[1], 0)
    return out, starts


def blocks_from_records(records: np.ndarray, starts: np.ndarray, max_records_per_block: int,
                        category: int | np.ndarray, new_block: np.ndarray | None = None) -> bytes:
    """Data blocks (CAT, LEN, records) with numpy: a new block when the category (per record,
    or one for all) changes, where ``new_block`` (per record) says so, or after
    ``max_records_per_block`` records of one run."""
    n = starts.size - 1
    if n == 0:
        return b""
    categories = np.broadcast_to(np.asarray(category, np.int64), (n,))
    new_run = np.concatenate([[True], categories[1:] != categories[:-1]])
    if new_block is not None:
        new_run |= np.asarray(new_block, bool)
    run_start = np.maximum.accumulate(np.where(new_run, np.arange(n), 0))
    first = np.flatnonzero(new_run | ((np.arange(n) - run_start) % max_records_per_block == 0))
    ends = np.append(first[1:], n)
    sizes = 3 + starts[ends] - starts[first]
    if (sizes > 65535).any():
        raise ValueError("ASTERIX: a data block would exceed 65 535 bytes; lower max_records_per_block")
    out = np.empty(int(records.size + 3 * first.size), np.uint8)
    header_at = starts[first] + 3 * np.arange(first.size)
    out[header_at] = categories[first]
    out[header_at + 1] = sizes >> 8
    out[header_at + 2] = sizes & 0xFF
    block_of_byte = np.searchsorted(starts[first], np.arange(records.size), side="right") - 1
    out[np.arange(records.size) + 3 * (block_of_byte + 1)] = records
    return out.tobytes()

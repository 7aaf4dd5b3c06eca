"""ASTERIX framing (issue 11 item 1-2): data blocks, FSPECs and the byte offset of each item.

The one sequential part of decoding: where record k+1 starts depends on the length of
record k, which depends on its FSPEC and on variable-length items.  A compiled scan
(numba) walks all blocks and records once and writes, for every record, its category,
block, start offset and the byte offsets of the items the decoder reads (I048/010, 140,
020, 040, 070, 090, 220; I034/010, 000, 030, 020; I021/010, 040, 071, 073, 130, 131, 140,
145, 080, 170, 090, 160, 157, 155); the items themselves are then decoded
with numpy over all records at once (``decode``).  Items the decoder does not read are
skipped by their structure from the UAP tables below (CAT048 edition 1.32, CAT034 edition
1.29, CAT021 edition 2.6): fixed, extended (FX per octet), repetitive, explicit (SP, RE) and compound items.

Problems (bad block length, unknown category, truncated record, unknown FRN, empty FSPEC)
are written to arrays with their byte offsets; after a bad block length the scan looks for
the next plausible block: one of a known category whose records fill it to the byte,
followed by the end of the input or by another such block.  A block of an unknown category
is skipped by its length when that leads on to the end or to a known block that parses (at
most one more unknown block between); otherwise its header is taken for damage and the scan
resynchronises the same way, so that a misread length never jumps over good blocks.
"""

from __future__ import annotations

import numpy as np
from numba import njit

FIXED, EXTENDED, REPETITIVE, EXPLICIT, COMPOUND = 1, 2, 3, 4, 5

CATEGORIES = (48, 34, 21)
#: column of each read item in the offsets table, per category
ITEMS_READ = {48: ("010", "140", "020", "040", "070", "090", "220"), 34: ("010", "000", "030", "020"),
              21: ("010", "040", "071", "073", "130", "131", "140", "145", "080", "170", "090", "160", "157", "155")}
N_READ = max(len(items) for items in ITEMS_READ.values())

# (item, kind, size, compound subitems as (kind, size) or None), in UAP (FRN) order
_UAP = {
    48: [
        ("010", FIXED, 2, None), ("140", FIXED, 3, None), ("020", EXTENDED, 1, None), ("040", FIXED, 4, None),
        ("070", FIXED, 2, None), ("090", FIXED, 2, None), ("130", COMPOUND, 0, [(FIXED, 1)] * 7),
        ("220", FIXED, 3, None), ("240", FIXED, 6, None), ("250", REPETITIVE, 8, None), ("161", FIXED, 2, None),
        ("042", FIXED, 4, None), ("200", FIXED, 4, None), ("170", EXTENDED, 1, None), ("210", FIXED, 4, None),
        ("030", EXTENDED, 1, None), ("080", FIXED, 2, None), ("100", FIXED, 4, None), ("110", FIXED, 2, None),
        ("120", COMPOUND, 0, [(FIXED, 2), (REPETITIVE, 6)]), ("230", FIXED, 2, None), ("260", FIXED, 7, None),
        ("055", FIXED, 1, None), ("050", FIXED, 2, None), ("065", FIXED, 1, None), ("060", FIXED, 2, None),
        ("SP", EXPLICIT, 0, None), ("RE", EXPLICIT, 0, None),
    ],
    34: [
        ("010", FIXED, 2, None), ("000", FIXED, 1, None), ("030", FIXED, 3, None), ("020", FIXED, 1, None),
        ("041", FIXED, 2, None), ("050", COMPOUND, 0, [(FIXED, 1), (0, 0), (0, 0), (FIXED, 1), (FIXED, 1), (FIXED, 2)]),
        ("060", COMPOUND, 0, [(FIXED, 1), (0, 0), (0, 0), (FIXED, 1), (FIXED, 1), (FIXED, 1)]),
        ("070", REPETITIVE, 2, None), ("100", FIXED, 8, None), ("110", FIXED, 1, None), ("120", FIXED, 8, None),
        ("090", FIXED, 2, None), ("RE", EXPLICIT, 0, None), ("SP", EXPLICIT, 0, None),
    ],
    21: [
        ("010", FIXED, 2, None), ("040", EXTENDED, 1, None), ("161", FIXED, 2, None), ("015", FIXED, 1, None),
        ("071", FIXED, 3, None), ("130", FIXED, 6, None), ("131", FIXED, 8, None), ("072", FIXED, 3, None),
        ("150", FIXED, 2, None), ("151", FIXED, 2, None), ("080", FIXED, 3, None), ("073", FIXED, 3, None),
        ("074", FIXED, 4, None), ("075", FIXED, 3, None), ("076", FIXED, 4, None), ("140", FIXED, 2, None),
        ("090", EXTENDED, 1, None), ("210", FIXED, 1, None), ("070", FIXED, 2, None), ("230", FIXED, 2, None),
        ("145", FIXED, 2, None), ("152", FIXED, 2, None), ("200", FIXED, 1, None), ("155", FIXED, 2, None),
        ("157", FIXED, 2, None), ("160", FIXED, 4, None), ("165", FIXED, 2, None), ("077", FIXED, 3, None),
        ("170", FIXED, 6, None), ("020", FIXED, 1, None),
        ("220", COMPOUND, 0, [(FIXED, 2), (FIXED, 2), (FIXED, 2), (FIXED, 1)]),
        ("146", FIXED, 2, None), ("148", FIXED, 2, None), ("110", COMPOUND, 0, [(EXTENDED, 1), (REPETITIVE, 15)]),
        ("016", FIXED, 1, None), ("008", FIXED, 1, None), ("271", EXTENDED, 1, None), ("132", FIXED, 1, None),
        ("250", REPETITIVE, 8, None), ("260", FIXED, 7, None), ("400", FIXED, 1, None),
        ("295", COMPOUND, 0, [(FIXED, 1)] * 23),
        ("", 0, 0, None), ("", 0, 0, None), ("", 0, 0, None), ("", 0, 0, None), ("", 0, 0, None),  # spare FRN 43-47
        ("RE", EXPLICIT, 0, None), ("SP", EXPLICIT, 0, None),
    ],
}

MAX_FRN = max(len(uap) for uap in _UAP.values())
MAX_SUB = 28  # a compound item's FSPEC of up to 4 octets (I021/295 has 23 subitems)


def _tables() -> tuple[np.ndarray, ...]:
    category_row = np.full(256, -1, np.int64)
    kinds = np.zeros((len(CATEGORIES), MAX_FRN), np.int64)
    sizes = np.zeros((len(CATEGORIES), MAX_FRN), np.int64)
    read_column = np.full((len(CATEGORIES), MAX_FRN), -1, np.int64)
    sub_kinds = np.zeros((len(CATEGORIES), MAX_FRN, MAX_SUB), np.int64)
    sub_sizes = np.zeros((len(CATEGORIES), MAX_FRN, MAX_SUB), np.int64)
    for row, cat in enumerate(CATEGORIES):
        category_row[cat] = row
        for frn, (item, kind, size, subs) in enumerate(_UAP[cat]):
            kinds[row, frn], sizes[row, frn] = kind, size
            if item in ITEMS_READ[cat]:
                read_column[row, frn] = ITEMS_READ[cat].index(item)
            for j, (sub_kind, sub_size) in enumerate(subs or []):
                sub_kinds[row, frn, j], sub_sizes[row, frn, j] = sub_kind, sub_size
    return category_row, kinds, sizes, read_column, sub_kinds, sub_sizes


TABLES = _tables()


@njit(cache=True)
def _simple_size(data, q, end, kind, size):
    """Bytes of a fixed / extended / repetitive / explicit item at ``q``; -1 if it runs past ``end``."""
    if kind == FIXED:
        return size
    if q >= end:
        return -1
    if kind == EXTENDED:
        n = 0
        while True:
            if q + n >= end:
                return -1
            n += 1
            if (data[q + n - 1] & 1) == 0:
                return n
    if kind == REPETITIVE:
        return 1 + np.int64(data[q]) * size
    if kind == EXPLICIT:
        n = np.int64(data[q])
        return n if n >= 1 else -1
    return -1


@njit(cache=True)
def _item_size(data, q, end, kind, size, sub_kinds, sub_sizes):
    if kind != COMPOUND:
        return _simple_size(data, q, end, kind, size)
    # compound: FX-extended presence octets, then the present subitems in order
    n_primary = _simple_size(data, q, end, EXTENDED, 1)
    if n_primary < 0:
        return -1
    pos = q + n_primary
    for octet in range(n_primary):
        bits = data[q + octet]
        for bit in range(7):
            if bits & (0x80 >> bit):
                j = octet * 7 + bit
                if j >= MAX_SUB or sub_kinds[j] == 0:
                    return -2
                n = _simple_size(data, pos, end, sub_kinds[j], sub_sizes[j])
                if n < 0:
                    return -1
                pos += n
    return pos - q


@njit(cache=True)
def _records_fit(data, p, category_row, kinds, sizes, sub_kinds, sub_sizes):
    """Whether the block at ``p`` (a known category, a length that fits the input) holds records
    whose FSPECs and items end exactly at the block's end, with no unknown FRN."""
    n = data.size
    if p + 2 >= n:
        return False
    row = category_row[data[p]]
    end = p + np.int64(data[p + 1]) * 256 + data[p + 2]
    if row < 0 or end < p + 4 or end > n:
        return False
    r = p + 3
    while r < end:
        n_fspec = _simple_size(data, r, end, EXTENDED, 1)
        if n_fspec < 0:
            return False
        q = r + n_fspec
        present = 0
        for octet in range(n_fspec):
            bits = data[r + octet]
            for bit in range(7):
                if bits & (0x80 >> bit):
                    frn = octet * 7 + bit
                    present += 1
                    if frn >= MAX_FRN or kinds[row, frn] == 0:
                        return False
                    size = _item_size(data, q, end, kinds[row, frn], sizes[row, frn], sub_kinds[row, frn],
                                      sub_sizes[row, frn])
                    if size < 0 or q + size > end:
                        return False
                    q += size
        if present == 0:
            return False
        r = q
    return r == end


@njit(cache=True)
def _resync(data, start, category_row, kinds, sizes, sub_kinds, sub_sizes):
    """First offset >= start where a block of a known category starts whose records fill it
    exactly and which is followed by the end of the input or by another such block (or a
    header of an unknown category whose length leads on to one); data.size if none.  Bytes
    inside damaged blocks rarely pass this: two consecutive blocks must parse to the byte."""
    n = data.size
    for p in range(start, n - 2):
        if not _records_fit(data, p, category_row, kinds, sizes, sub_kinds, sub_sizes):
            continue
        nxt = p + np.int64(data[p + 1]) * 256 + data[p + 2]
        if nxt == n or _records_fit(data, nxt, category_row, kinds, sizes, sub_kinds, sub_sizes):
            return p
        if nxt + 2 < n and category_row[data[nxt]] < 0:
            after = nxt + np.int64(data[nxt + 1]) * 256 + data[nxt + 2]
            if after == n or (after > nxt + 2 and _records_fit(data, after, category_row, kinds, sizes, sub_kinds,
                                                               sub_sizes)):
                return p
    return n


@njit(cache=True)
def _unknown_block_fits(data, p, category_row, kinds, sizes, sub_kinds, sub_sizes):
    """Whether the length of an unknown-category header at ``p`` leads to the end of the input or
    to a block of a known category that parses (after at most one more unknown header)."""
    n = data.size
    for _ in range(2):
        if p + 2 >= n:
            return False
        length = np.int64(data[p + 1]) * 256 + data[p + 2]
        if length < 3 or p + length > n:
            return False
        p += length
        if p == n:
            return True
        if category_row[data[p]] >= 0:
            return _records_fit(data, p, category_row, kinds, sizes, sub_kinds, sub_sizes)
    return False


@njit(cache=True)
def scan(data, category_row, kinds, sizes, read_column, sub_kinds, sub_sizes,
         rec_cat, rec_block, rec_start, rec_items, prob_code, prob_offset, prob_block, prob_detail, prob_skipped):
    """Walk the blocks and records of ``data``; fill the record and problem arrays.

    Returns (records, problems, blocks).  A problem inside a block skips the rest of that
    block (the records before it are kept); a bad block length resynchronises (``_resync``).
    """
    n = data.size
    p = 0
    nrec = 0
    nprob = 0
    block = 0
    while p < n:
        length = np.int64(-1) if n - p < 3 else np.int64(data[p + 1]) * 256 + data[p + 2]
        if length < 3 or p + length > n:
            nxt = _resync(data, p + 1, category_row, kinds, sizes, sub_kinds, sub_sizes)
            prob_code[nprob], prob_offset[nprob], prob_block[nprob] = 1, p, block
            prob_detail[nprob], prob_skipped[nprob] = length, nxt - p
            nprob += 1
            p = nxt
            block += 1
            continue
        row = category_row[data[p]]
        end = p + length
        if row < 0:
            # an unknown category is skipped by its length when that length leads on to a known
            # block that parses; otherwise the header is not one
            # (a misread length could jump over 64 kB of good blocks): resynchronise
            if not _unknown_block_fits(data, p, category_row, kinds, sizes, sub_kinds, sub_sizes):
                end = _resync(data, p + 1, category_row, kinds, sizes, sub_kinds, sub_sizes)
            prob_code[nprob], prob_offset[nprob], prob_block[nprob] = 2, p, block
            prob_detail[nprob], prob_skipped[nprob] = data[p], end - p
            nprob += 1
            p = end
            block += 1
            continue
        r = p + 3
        while r < end:
            n_fspec = _simple_size(data, r, end, EXTENDED, 1)
            code = 0
            frn_at_fault = 0
            q = r + n_fspec
            if n_fspec < 0:
                code = 3
            for j in range(rec_items.shape[1]):
                rec_items[nrec, j] = -1
            present = 0
            for octet in range(max(n_fspec, 0)):
                if code != 0:
                    break
                bits = data[r + octet]
                for bit in range(7):
                    if bits & (0x80 >> bit):
                        frn = octet * 7 + bit
                        present += 1
                        if frn >= MAX_FRN or kinds[row, frn] == 0:
                            code = 4
                            frn_at_fault = frn + 1
                            break
                        column = read_column[row, frn]
                        if column >= 0:
                            rec_items[nrec, column] = q
                        size = _item_size(data, q, end, kinds[row, frn], sizes[row, frn],
                                          sub_kinds[row, frn], sub_sizes[row, frn])
                        if size == -2:
                            code = 4
                        elif size < 0 or q + size > end:
                            code = 3
                        if code != 0:
                            frn_at_fault = frn + 1
                            break
                        q += size
            if code == 0 and present == 0:
                code = 5
            if code != 0:
                prob_code[nprob], prob_offset[nprob], prob_block[nprob] = code, r, block
                prob_detail[nprob], prob_skipped[nprob] = frn_at_fault, end - r
                nprob += 1
                break
            rec_cat[nrec] = data[p]
            rec_block[nrec] = block
            rec_start[nrec] = r
            nrec += 1
            r = q
        p = end
        block += 1
    return nrec, nprob, block


def scan_records(data: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], int]:
    """Scan ``data`` (uint8): record arrays (``cat``, ``block``, ``start``, ``items`` with -1 for
    an absent item), problem arrays (``code``, ``offset``, ``block``, ``detail``, ``skipped``) and the
    number of blocks."""
    n = data.size
    max_records = n // 2 + 1  # a record has at least an FSPEC byte and one item byte
    max_problems = n // 3 + 2
    rec_cat = np.empty(max_records, np.int64)
    rec_block = np.empty(max_records, np.int64)
    rec_start = np.empty(max_records, np.int64)
    # item offsets as int32 when they fit: 4 bytes per read item and possible record, not 8
    rec_items = np.empty((max_records, N_READ), np.int32 if n < 2**31 - 1 else np.int64)
    prob = [np.empty(max_problems, np.int64) for _ in range(5)]
    nrec, nprob, nblocks = scan(data, *TABLES, rec_cat, rec_block, rec_start, rec_items, *prob)
    records = {"cat": rec_cat[:nrec], "block": rec_block[:nrec], "start": rec_start[:nrec], "items": rec_items[:nrec]}
    problems = dict(zip(("code", "offset", "block", "detail", "skipped"), (a[:nprob] for a in prob)))
    return records, problems, int(nblocks)

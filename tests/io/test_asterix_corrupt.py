"""ASTERIX decoding of damaged input (skytrack.io.asterix): problems counted with their byte offsets.

Hand-made corruptions (bad block length, truncated record, unknown category, unknown FRN,
empty FSPEC, a plot without I048/040, trailing bytes) are located exactly; lenient decoding
keeps every record outside the damaged block and resumes at the next block, strict decoding
raises an error naming the offset.  A fuzz loop of a few hundred randomly damaged inputs
must never raise in lenient mode and never yields values outside the items' ranges.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import asterix.generated as gen

from skytrack.io.asterix import AsterixDecodeError, decode_asterix, encode_asterix
from skytrack.io.asterix import problems as kinds
from skytrack.io.asterix import units as u

SAC_SIC = {"a": (1, 2), "b": (3, 4)}


@pytest.fixture(scope="module")
def clean() -> bytes:
    rng = np.random.default_rng(7)
    n = 40
    plots = pd.DataFrame({
        "time": np.arange(n) * 0.25, "sensor": rng.choice(["a", "b"], n),
        "range_m": rng.uniform(1e3, 4e5, n), "azimuth_deg": rng.uniform(0, 360, n),
        "mode3a": [f"{c:04o}" if c % 2 else None for c in rng.integers(0, 4096, n)],
        "mode_c_ft": np.where(rng.random(n) < 0.5, rng.uniform(0, 4e4, n), np.nan),
        "mode_s": [f"{c:06x}" if c % 3 else None for c in rng.integers(0, 1 << 24, n)],
    })
    service = pd.DataFrame({"time": [0.0, 4.9, 8.0], "sensor": ["a", "b", "a"],
                            "message": ["north_marker", "sector_crossing", "north_marker"],
                            "azimuth_deg": [np.nan, 90.0, np.nan]})
    return encode_asterix(plots, SAC_SIC, service=service, max_records_per_block=6)


def block_offsets(data: bytes) -> list[int]:
    offsets, p = [], 0
    while p < len(data):
        offsets.append(p)
        p += int.from_bytes(data[p + 1:p + 3], "big")
    return offsets


def record_times(decoded) -> list[float]:
    return list(decoded.plots["time_of_day_s"])


def times_without_block(data: bytes, k: int) -> list[float]:
    """Plot times of ``data`` with block ``k`` cut out (what a lenient decode must still give)."""
    offsets = block_offsets(data) + [len(data)]
    return record_times(decode_asterix(data[:offsets[k]] + data[offsets[k + 1]:], strict=True))


def only_problem(decoded):
    assert decoded.problems.count == 1, decoded.problems.summary()
    return decoded.problems.problems[0]


def test_clean_input_has_no_problem_and_several_blocks(clean):
    decoded = decode_asterix(clean, strict=True)
    assert decoded.problems.count == 0 and decoded.problems.blocks == len(block_offsets(clean)) >= 9
    assert decoded.plots["range_m"].size == 40 and decoded.service["time"].size == 3


def test_unknown_category_skips_that_block_only(clean):
    k = 3
    offset = block_offsets(clean)[k]
    length = int.from_bytes(clean[offset + 1:offset + 3], "big")
    data = bytearray(clean)
    data[offset] = 99
    problem = only_problem(decode_asterix(bytes(data)))
    assert (problem.kind, problem.offset, problem.block, problem.detail, problem.skipped_bytes) == \
        (kinds.UNKNOWN_CATEGORY, offset, k, 99, length)
    assert record_times(decode_asterix(bytes(data))) == times_without_block(clean, k)
    with pytest.raises(AsterixDecodeError, match=f"byte offset {offset} \\(block {k}\\): unknown category"):
        decode_asterix(bytes(data), strict=True)


@pytest.mark.parametrize("bad_length", [0, 2, 65535])
def test_bad_block_length_resumes_at_the_next_block(clean, bad_length):
    k = 4
    offsets = block_offsets(clean)
    data = bytearray(clean)
    data[offsets[k] + 1:offsets[k] + 3] = bad_length.to_bytes(2, "big")
    decoded = decode_asterix(bytes(data))
    problem = only_problem(decoded)
    assert (problem.kind, problem.offset, problem.block, problem.detail) == (kinds.BAD_BLOCK_LENGTH, offsets[k], k,
                                                                             bad_length)
    assert problem.skipped_bytes == offsets[k + 1] - offsets[k]
    assert record_times(decoded) == times_without_block(clean, k)
    with pytest.raises(AsterixDecodeError, match=f"byte offset {offsets[k]} .*bad block length") as error:
        decode_asterix(bytes(data), strict=True)
    assert error.value.problem == problem


def test_trailing_bytes_are_a_bad_block_length_at_the_end(clean):
    problem = only_problem(decode_asterix(clean + b"\x30\x00"))
    assert (problem.kind, problem.offset, problem.skipped_bytes) == (kinds.BAD_BLOCK_LENGTH, len(clean), 2)


def test_truncated_record_keeps_the_records_before_it(clean):
    k = 2
    offsets = block_offsets(clean) + [len(clean)]
    assert clean[offsets[k]] == 48
    block = bytearray(clean[offsets[k]:offsets[k + 1] - 1])  # last record loses its last byte
    block[1:3] = len(block).to_bytes(2, "big")
    data = clean[:offsets[k]] + bytes(block) + clean[offsets[k + 1]:]
    clean_times = record_times(decode_asterix(clean))
    records_in_block = decode_asterix(clean[offsets[k]:offsets[k + 1]], strict=True).problems.records
    decoded = decode_asterix(data)
    problem = only_problem(decoded)
    assert problem.kind == kinds.TRUNCATED_RECORD and problem.block == k and problem.detail >= 1
    # only the last record of the block is lost; the ones before it and all later blocks are kept
    lost_index = offsets_of_records = sum(len(decode_asterix(clean[o:offsets[i + 1]]).plots["time"])
                                          for i, o in enumerate(offsets[:k])) + records_in_block - 1
    assert record_times(decoded) == clean_times[:lost_index] + clean_times[lost_index + 1:]
    # the offset is that of the lost record: the block's bytes from there on are skipped
    assert problem.offset + problem.skipped_bytes == offsets[k + 1] - 1
    assert offsets_of_records == lost_index and data[problem.offset] & 0x80  # its FSPEC starts with I048/010
    with pytest.raises(AsterixDecodeError, match=f"byte offset {problem.offset} .*truncated record"):
        decode_asterix(data, strict=True)


def test_unknown_frn_and_empty_fspec_are_located():
    good = gen.Cat_034_1_29.cv_record.create({"000": 1, "010": (("SAC", 1), ("SIC", 2)), "030": 128})
    good_bytes = good.unparse().to_bytes()
    bad_frn = bytes([0x01, 0x01, 0x80, 0x00])  # FSPEC of three octets: FRN 15 does not exist in CAT034
    block = good_bytes + bad_frn + good_bytes
    data = bytes([34]) + (len(block) + 3).to_bytes(2, "big") + block
    decoded = decode_asterix(data)
    problem = only_problem(decoded)
    assert (problem.kind, problem.offset, problem.detail) == (kinds.UNSUPPORTED_ITEM, 3 + len(good_bytes), 15)
    assert problem.skipped_bytes == len(bad_frn) + len(good_bytes)
    assert list(decoded.service["time_of_day_s"]) == [1.0]
    empty = bytes([34, 0, 4 + len(good_bytes)]) + good_bytes + b"\x00"
    problem = only_problem(decode_asterix(empty))
    assert (problem.kind, problem.offset) == (kinds.EMPTY_RECORD, 3 + len(good_bytes))


def test_plot_without_position_is_counted_and_strict_refuses_it():
    cat048 = gen.Cat_048_1_32
    with_position = cat048.cv_record.create({"010": (("SAC", 1), ("SIC", 2)), "140": 1,
                                             "040": (("RHO", 3), ("THETA", 4))})
    without = cat048.cv_record.create({"010": (("SAC", 1), ("SIC", 2)), "140": 2})
    data = cat048.create([with_position, without, with_position]).unparse().to_bytes()
    decoded = decode_asterix(data)
    problem = only_problem(decoded)
    second = 3 + len(with_position.unparse().to_bytes())
    assert (problem.kind, problem.offset, problem.skipped_bytes) == (kinds.NO_POSITION, second,
                                                                     len(without.unparse().to_bytes()))
    assert list(decoded.plots["range_m"]) == [3 * u.RHO_LSB_M] * 2
    with pytest.raises(AsterixDecodeError, match=f"byte offset {second} .*without I048/040"):
        decode_asterix(data, strict=True)


def test_random_damage_never_raises_in_lenient_mode(clean):
    rng = np.random.default_rng(2026)
    for trial in range(400):
        data = bytearray(clean)
        how = trial % 4
        if how == 0:  # flip a few bytes
            for at in rng.integers(0, len(data), rng.integers(1, 6)):
                data[at] = rng.integers(0, 256)
        elif how == 1:  # cut anywhere
            data = data[:rng.integers(0, len(data))]
        elif how == 2:  # insert junk
            at = int(rng.integers(0, len(data)))
            data[at:at] = rng.integers(0, 256, rng.integers(1, 8)).astype(np.uint8).tobytes()
        else:  # a whole random block after a good prefix
            at = block_offsets(clean)[int(rng.integers(0, 5))]
            data = data[:at] + bytes([48]) + rng.integers(0, 256, 60).astype(np.uint8).tobytes()
        decoded = decode_asterix(bytes(data))
        p = decoded.plots
        assert np.all((p["range_m"] >= 0) & (p["range_m"] < 256 * u.NAUTICAL_MILE_M))
        assert np.all((p["azimuth_deg"] >= 0) & (p["azimuth_deg"] < 360))
        assert np.all((p["time_of_day_s"] >= 0) & (p["time_of_day_s"] < 131072))
        assert all(0 <= q.offset <= len(data) and 0 <= q.skipped_bytes <= len(data) for q in decoded.problems.problems)
        assert decoded.problems.skipped_bytes <= len(data)
        if how == 1 and len(data) not in block_offsets(clean) + [len(clean)]:
            assert decoded.problems.count >= 1  # a cut inside a block is never silent

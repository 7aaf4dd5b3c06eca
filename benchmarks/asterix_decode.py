"""Benchmark (not a test): the vectorised ASTERIX CAT048 decoder against libasterix (issue 11 item 1-2).

Usage: python benchmarks/asterix_decode.py [RECORDS] [RUNS]
Encodes 10^4 random plots with libasterix (blocks of 128 records), repeats the bytes up to
RECORDS (default 10^6) CAT048 records and times ``decode_asterix`` on them (median of RUNS,
default 5, after one warm-up that compiles the scan); then times libasterix parsing and
reading the same items on the 10^4 records (median of 3).  Prints records/second, the
machine and the date.  The issue's target is >= 100 000 records/s on one core.
"""

from __future__ import annotations

import datetime
import platform
import statistics
import sys
import time

import numpy as np
import pandas as pd

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from machine import cpu_model, usable_cores, versions  # noqa: E402

from skytrack.io.asterix import decode_asterix, encode_asterix  # noqa: E402

BASE_RECORDS = 10_000


def random_plots(n: int, rng: np.random.Generator) -> pd.DataFrame:
    return pd.DataFrame({
        "time": np.sort(rng.uniform(0, 3600, n)),
        "sensor": rng.choice(["r1", "r2", "r3"], n),
        "range_m": rng.uniform(0, 450e3, n),
        "azimuth_deg": rng.uniform(0, 360, n),
        "mode3a": np.where(rng.random(n) < 0.8, np.char.zfill(np.char.mod("%o", rng.integers(0, 4096, n)), 4), None),
        "mode_c_ft": np.where(rng.random(n) < 0.7, rng.uniform(0, 45000, n), np.nan),
        "mode_s": np.where(rng.random(n) < 0.5, np.char.zfill(np.char.mod("%x", rng.integers(0, 1 << 24, n)), 6), None),
    })


def libasterix_decode(data: bytes) -> int:
    """Parse with libasterix and read the items decode_asterix reads; returns the records read."""
    import asterix.generated as gen
    from asterix.base import Bits, RawDatablock

    spec = gen.Cat_048_1_32
    count = 0
    for block in RawDatablock.parse(Bits.from_bytes(data)):
        for record in spec.cv_uap.parse(block.get_raw_records()):
            for item in ("010", "140", "020", "040", "070", "090", "220"):
                found = record.get_item(item)
                if found is not None:
                    found.unparse()
            position = record.get_item("040").variation
            position.get_item("RHO").variation.content.as_quantity("NM")
            position.get_item("THETA").variation.content.as_quantity("°")
            count += 1
    return count


def median_time(function, runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    records = int(float(sys.argv[1])) if len(sys.argv) > 1 else 1_000_000
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    print(f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, {cpu_model()}, "
          f"{usable_cores()} usable cores, Python {platform.python_version()}, {versions(('numpy', 'numba'))}")
    rng = np.random.default_rng(11)
    start = time.perf_counter()
    base = encode_asterix(random_plots(BASE_RECORDS, rng), {"r1": (1, 1), "r2": (1, 2), "r3": (1, 3)})
    print(f"libasterix encoded {BASE_RECORDS} records in {time.perf_counter() - start:.1f} s ({len(base)} bytes)")
    data = base * max(1, records // BASE_RECORDS)
    n = decode_asterix(base).plots["range_m"].size  # warm-up (compiles the scan)
    assert n == BASE_RECORDS
    n = decode_asterix(data).plots["range_m"].size
    seconds = median_time(lambda: decode_asterix(data), runs)
    print(f"decode_asterix: {n} records ({len(data) / 1e6:.1f} MB) in {seconds:.3f} s (median of {runs}): "
          f"{n / seconds:,.0f} records/s")
    lib_seconds = median_time(lambda: libasterix_decode(base), 3)
    print(f"libasterix:     {BASE_RECORDS} records in {lib_seconds:.3f} s (median of 3): "
          f"{BASE_RECORDS / lib_seconds:,.0f} records/s; decode_asterix is {seconds and (n / seconds) / (BASE_RECORDS / lib_seconds):.0f} "
          "times faster")


if __name__ == "__main__":
    main()

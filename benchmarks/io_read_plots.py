"""Benchmark (not a test): read, validate and write N plot rows, Parquet and CSV.

Usage: python benchmarks/io_read_plots.py [N] [DIR]
Prints rows/second of each step and the peak memory of the process.
"""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.io import read_plots, write_plots, write_table


def make_plots(n: int, rng: np.random.Generator) -> pd.DataFrame:
    sensors = np.array(["radar1", "radar2", "radar3"])
    return pd.DataFrame(
        {
            "time": np.sort(rng.uniform(0, 36000, n)),
            "sensor": sensors[rng.integers(0, 3, n)],
            "range_m": rng.uniform(0, 250e3, n),
            "azimuth_deg": rng.uniform(0, 360, n),
            "scan": rng.integers(0, 9000, n),
            "mode3a": np.char.zfill(np.char.mod("%o", rng.integers(0, 4096, n)), 4),
            "mode_c_ft": rng.uniform(0, 40000, n),
            "iff": np.where(rng.random(n) < 0.5, "friend", None),
        }
    )


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 5_000_000
    directory = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(tempfile.mkdtemp())
    plots = make_plots(n, np.random.default_rng(1))
    for name in ("plots.parquet", "plots.csv"):
        path = directory / name
        start = time.perf_counter()
        write_table(plots, path)  # raw write, no validation
        raw = time.perf_counter() - start
        start = time.perf_counter()
        back = read_plots(path)
        read = time.perf_counter() - start
        start = time.perf_counter()
        write_plots(back, path)
        write = time.perf_counter() - start
        print(
            f"{name}: {n} rows; raw write {raw:.2f} s; read_plots {read:.2f} s ({n / read:,.0f} rows/s); "
            f"write_plots {write:.2f} s ({n / write:,.0f} rows/s)"
        )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()

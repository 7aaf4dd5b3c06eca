"""Chunked plot reading (skytrack.io.iter_plots): same rows as read_plots, whole-file row numbers."""

import numpy as np
import pandas as pd
import pytest

from skytrack.io import InputError, ReadReport, iter_plots, read_plots, write_plots


def _plots(n: int) -> pd.DataFrame:
    rng = np.random.default_rng(3)
    return pd.DataFrame(
        {
            "time": np.arange(n, dtype=float),
            "sensor": "radar1",
            "range_m": rng.uniform(1e3, 2e5, n),
            "azimuth_deg": rng.uniform(0, 360, n),
        }
    )


@pytest.mark.parametrize("suffix", ["parquet", "csv"])
def test_chunks_concatenate_to_the_whole_table(tmp_path, suffix):
    path = write_plots(_plots(1000), tmp_path / f"plots.{suffix}")
    chunks = list(iter_plots(path, chunk_rows=128))
    assert [len(c) for c in chunks] == [128] * 7 + [104]
    pd.testing.assert_frame_equal(pd.concat(chunks, ignore_index=True), read_plots(path))


def test_errors_name_rows_of_the_whole_file(tmp_path):
    plots = _plots(1000)
    plots.loc[700, "azimuth_deg"] = 400.0
    plots.to_parquet(tmp_path / "plots.parquet")
    with pytest.raises(InputError) as caught:
        for _ in iter_plots(tmp_path / "plots.parquet", chunk_rows=128):
            pass
    assert caught.value.row == 700 and caught.value.column == "azimuth_deg"


def test_lenient_counts_accumulate_over_chunks(tmp_path):
    plots = _plots(1000)
    plots.loc[[5, 300, 999], "range_m"] = -1.0
    plots.to_parquet(tmp_path / "plots.parquet")
    report = ReadReport(file="plots.parquet")
    kept = sum(len(c) for c in iter_plots(tmp_path / "plots.parquet", lenient=True, chunk_rows=128, report=report))
    assert kept == 997
    assert (report.rows_read, report.rows_kept, report.rows_skipped) == (1000, 997, 3)
    [entry] = report.skipped.values()
    assert entry.count == 3 and [e.row for e in entry.examples] == [5, 300, 999]

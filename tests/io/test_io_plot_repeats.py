"""Plot rows that repeat an earlier row exactly are reported (not dropped), within a chunk and
across chunk boundaries, by every plots reader; ordinary files raise no such warning."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.io import iter_plot_batches, iter_plots, read_plots
from skytrack.io.plot_repeats import RepeatedRows
from skytrack.sim import load_scenario, simulate


@pytest.fixture(scope="module")
def crossing():
    return simulate(load_scenario("crossing"))


def _with_repeats(plots: pd.DataFrame, rows: list[int]) -> pd.DataFrame:
    """``plots`` with copies of ``rows`` inserted right after them (time order kept)."""
    parts = [plots, plots.iloc[rows]]
    return pd.concat(parts).sort_values("time", kind="stable").reset_index(drop=True)


@pytest.mark.parametrize("chunk_rows", [100_000, 7])
def test_repeats_are_reported_by_every_reader(crossing, tmp_path, chunk_rows):
    plots = _with_repeats(crossing.plots, [5, 300, 301])
    plots.to_parquet(tmp_path / "plots.parquet", index=False)
    expected = "3 plot rows repeat an earlier row exactly (sensor, time, range, azimuth), first row 6 repeating row 5"
    _, report = read_plots(tmp_path / "plots.parquet", crossing.sensors, lenient=True)
    assert any(w.startswith(expected) for w in report.warnings), report.warnings
    for reader in (iter_plots, iter_plot_batches):
        with pytest.warns(UserWarning, match="3 plot rows repeat an earlier row exactly") as caught:
            chunks = list(reader(tmp_path / "plots.parquet", crossing.sensors, chunk_rows=chunk_rows))
        assert sum(len(c) for c in chunks) == len(plots)  # reported, not dropped
        assert any(str(w.message).endswith(expected + ": a file concatenated twice? They are tracked as detections")
                   for w in caught)


def test_an_ordinary_file_has_no_repeats(crossing, tmp_path):
    crossing.plots.to_parquet(tmp_path / "plots.parquet", index=False)
    _, report = read_plots(tmp_path / "plots.parquet", crossing.sensors, lenient=True)
    assert not any("repeat" in w for w in report.warnings)


def test_repeats_across_a_chunk_boundary_are_counted_once():
    """Rows at a sensor's last time are carried to the next chunk, and a repeat among them is
    not counted twice; plots of another sensor at the same values are not repeats."""
    finder = RepeatedRows()
    finder.add(np.array([0, 0, 0]), np.array([1.0, 2.0, 2.0]), np.array([5.0, 6.0, 6.0]), np.array([0.1, 0.2, 0.2]),
               np.array([0, 1, 2]))
    finder.add(np.array([0, 1, 0]), np.array([2.0, 2.0, 3.0]), np.array([6.0, 6.0, 7.0]), np.array([0.2, 0.2, 0.3]),
               np.array([3, 4, 5]))
    assert finder.count == 2  # row 2 repeats row 1, row 3 repeats row 1 (row 4 is another sensor)
    assert finder.first == (2, 1)

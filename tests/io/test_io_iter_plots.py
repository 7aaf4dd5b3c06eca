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


def test_a_column_in_another_unit_is_named(tmp_path):
    plots = _plots(10).rename(columns={"range_m": "range_km", "azimuth_deg": "azimuth_rad"})
    plots.to_csv(tmp_path / "plots.csv", index=False)
    with pytest.raises(InputError) as caught:
        read_plots(tmp_path / "plots.csv")
    message = str(caught.value)
    assert "range_km is in kilometres, FORMATS.md wants range_m in metres" in message
    assert "azimuth_rad is in radians, FORMATS.md wants azimuth_deg in degrees" in message


def test_values_in_another_unit_give_a_warning(tmp_path):
    plots = _plots(100)
    plots["range_m"] /= 1000.0
    plots["azimuth_deg"] = np.radians(plots["azimuth_deg"])
    plots.to_parquet(tmp_path / "plots.parquet")
    _, report = read_plots(tmp_path / "plots.parquet", lenient=True)
    assert any("kilometres instead of metres" in w for w in report.warnings)
    assert any("radians instead of degrees" in w for w in report.warnings)
    with pytest.warns(UserWarning) as caught:
        read_plots(tmp_path / "plots.parquet")
    messages = [str(w.message) for w in caught]
    assert any("kilometres" in m for m in messages) and any("radians" in m for m in messages)


@pytest.mark.parametrize("suffix", ["parquet", "csv"])
def test_plot_batches_are_the_parsed_plots_in_si_units(tmp_path, suffix):
    """iter_plot_batches parses each validated chunk once: azimuth in radians, Mode C in
    metres, Mode 3/A as its octal value, rows numbered over the whole file."""
    from skytrack.core.plots import PlotBatch
    from skytrack.geo.sensors import Origin, Sensor, SensorSet
    from skytrack.io import iter_plot_batches

    sensors = SensorSet(Origin(48.0, 2.0, 0.0), [Sensor("radar1", type="radar-2d", x=0.0, y=0.0,
                                                        sigma_range_m=40.0, sigma_azimuth_deg=0.07,
                                                        scan_period_s=4.0)])
    plots = _plots(300)
    plots["mode_c_ft"] = 10000.0
    plots["mode3a"] = "7000"
    path = write_plots(plots, tmp_path / f"plots.{suffix}", sensors=sensors)
    batches = list(iter_plot_batches(path, sensors, chunk_rows=128))
    assert [len(b) for b in batches] == [128, 128, 44]
    whole = PlotBatch.concat(batches)
    np.testing.assert_array_equal(whole.row, np.arange(300))
    np.testing.assert_allclose(whole.azimuth, np.radians(plots["azimuth_deg"]), rtol=1e-12)
    np.testing.assert_allclose(whole.mode_c_m, 10000.0 * 0.3048)
    assert (whole.mode3a == 0o7000).all() and (whole.sensor == 0).all()

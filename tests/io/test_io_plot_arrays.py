"""The Arrow fast path of iter_plot_batches (skytrack.io.plot_arrays) against the detailed
pandas validation alone: the same batches, errors, lenient reports and warnings, on good
input and on every kind of bad input; good chunks take the fast path, bad ones never do."""

from __future__ import annotations

import warnings
from dataclasses import fields

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from io_samples import EPOCH, make_plots

import skytrack.io.plots as plots_module
from skytrack.core.plots import PlotBatch
from skytrack.io import InputError, ReadReport, iter_plot_batches
from skytrack.io.plot_arrays import PlotStream, plot_batch_from_arrow

CHUNK_ROWS = 16
ROW = 17  # a radar1 row of the second chunk


def _set(name, value, row=ROW):
    def corrupt(df):
        column = df[name].astype(object if isinstance(value, str) or value is None else float)
        column.iloc[row] = value
        df[name] = column
    return corrupt


def _time_backwards(df):
    df.loc[ROW, "time"] = df.loc[13, "time"] - 0.5  # rows 13 and 17 are radar1 rows of one chunk


def _time_behind_earlier_chunk(df):
    df.loc[16, "time"] = df.loc[14, "time"] - 0.01  # first radar1 row of chunk 2, behind chunk 1


def _one_sensor(df):
    df["sensor"] = "radar1"


def _one_sensor_time_backwards(df):
    _one_sensor(df)
    df.loc[ROW, "time"] = df.loc[ROW - 2, "time"] - 0.5


def _one_sensor_behind_earlier_chunk(df):
    _one_sensor(df)
    df.loc[16, "time"] = df.loc[15, "time"] - 0.01


def _timestamps(df):
    df.insert(0, "timestamp", pd.Timestamp(EPOCH) + pd.to_timedelta(df.pop("time"), unit="s"))


def _mode3a_numbers(df):
    df["mode3a"] = np.arange(len(df)) % 8


def _truth_numbers(df):
    df["truth_id"] = np.arange(len(df), dtype=float)


def _bad_icao24(df):
    df["icao24"] = np.array(["3c6444"] * len(df), dtype=object)
    df.loc[ROW, "icao24"] = "3c64zz"


def _range_text(df):
    df["range_m"] = df["range_m"].map(repr).astype(object)
    df.loc[ROW, "range_m"] = "far"


def _no_azimuth(df):
    del df["azimuth_deg"]


def _extra_and_empty(df):
    df["operator_note"] = "ok"
    df["elevation_deg"] = np.nan


def _integer_times(df):
    df["time"] = np.arange(len(df), dtype=np.int64)


def _upper_case_mode_s(df):
    df["mode_s"] = df["mode_s"].str.upper()


#: name -> change to valid plots; the first ones leave them valid
CHANGES = {
    "valid": lambda df: None,
    "mode_s upper case": _upper_case_mode_s,
    "extra column, elevation all null": _extra_and_empty,
    "integer times": _integer_times,
    "truth_id numbers": _truth_numbers,
    "one sensor": _one_sensor,
    "negative range": _set("range_m", -5.0),
    "azimuth 360": _set("azimuth_deg", 360.0),
    "time missing": _set("time", np.nan),
    "time infinite": _set("time", np.inf),
    "time infinite at the end": _set("time", np.inf, row=39),
    "range missing": _set("range_m", np.nan),
    "sensor null": _set("sensor", None),
    "sensor empty": _set("sensor", ""),
    "sensor unknown": _set("sensor", "radar9"),
    "elevation 91": _set("elevation_deg", 91.0),
    "range rate infinite": _set("range_rate_mps", np.inf),
    "mode C infinite": _set("mode_c_ft", -np.inf),
    "scan fraction": _set("scan", 2.5),
    "mode3a not octal": _set("mode3a", "0128"),
    "mode_s not hex": _set("mode_s", "3c64zz"),
    "iff unknown": _set("iff", "ally"),
    "time backwards": _time_backwards,
    "time behind an earlier chunk": _time_behind_earlier_chunk,
    "one sensor, time backwards": _one_sensor_time_backwards,
    "one sensor, time behind an earlier chunk": _one_sensor_behind_earlier_chunk,
    "timestamps": _timestamps,
    "mode3a numbers": _mode3a_numbers,
    "icao24 not hex": _bad_icao24,
    "range as text": _range_text,
    "azimuth missing": _no_azimuth,
}
#: valid plots the fast path takes, and valid plots it leaves to the detailed path (conversions)
VALID = ("valid", "mode_s upper case", "extra column, elevation all null", "integer times", "truth_id numbers",
         "one sensor")
VALID_DETAILED = ("timestamps", "mode3a numbers")


def _write(df: pd.DataFrame, path):
    if path.suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        pq.write_table(pa.Table.from_pandas(df, preserve_index=False), path)
    return path


def _read(path, sensors, lenient: bool, fast: bool, monkeypatch):
    """What iter_plot_batches gives with the fast path (``fast``) or the detailed path alone:
    batches, report text and warnings, or the error; plus how many chunks went the fast way."""
    taken = []

    def spy(table, sensor_set, stream):
        batch = plot_batch_from_arrow(table, sensor_set, stream) if fast else None
        taken.append(batch is not None)
        return batch

    monkeypatch.setattr(plots_module, "plot_batch_from_arrow", spy)
    report = ReadReport(file=str(path)) if lenient else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            batches = list(iter_plot_batches(path, sensors, lenient, chunk_rows=CHUNK_ROWS, report=report))
        except InputError as exc:
            return ("error", str(exc), exc.row, exc.line, exc.column), taken
    skipped = None if report is None else [
        (reason, rows.count, [str(e) for e in rows.examples]) for reason, rows in report.skipped.items()]
    result = ("read", batches, str(report), skipped, [str(w.message) for w in caught])
    return result, taken


def _same(a, b) -> None:
    assert a[0] == b[0], (a, b)
    if a[0] == "error":
        assert a == b
        return
    assert a[2:] == b[2:]
    assert len(a[1]) == len(b[1])
    for got, want in zip(a[1], b[1], strict=True):
        for f in fields(PlotBatch):
            x, y = getattr(got, f.name), getattr(want, f.name)
            assert x.dtype == y.dtype and x.shape == y.shape, f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)


@pytest.mark.parametrize("lenient", [False, True], ids=["strict", "lenient"])
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
@pytest.mark.parametrize("change", list(CHANGES))
def test_fast_path_reads_as_the_detailed_path(tmp_path, sensor_set, monkeypatch, change, suffix, lenient):
    df = make_plots(40, seed=3)
    CHANGES[change](df)
    path = _write(df, tmp_path / f"plots{suffix}")
    fast, taken = _read(path, sensor_set, lenient, True, monkeypatch)
    detailed, _ = _read(path, sensor_set, lenient, False, monkeypatch)
    _same(fast, detailed)
    if change in VALID:
        assert fast[0] == "read" and sum(len(b) for b in fast[1]) == 40
        assert all(taken) and len(taken) == 3
    else:
        assert not all(taken)  # the chunk with the problem (or conversion) went the detailed way
        if not lenient and change not in VALID_DETAILED:
            assert fast[0] == "error"


def test_a_bad_chunk_leaves_the_stream_as_it_was(sensor_set):
    df = make_plots(40, seed=3)
    good = pa.Table.from_pandas(df, preserve_index=False)
    stream = PlotStream()
    assert plot_batch_from_arrow(good.slice(0, 20), sensor_set, stream) is not None
    before = (dict(stream.last_time), stream.rows, stream.largest_range, stream.largest_azimuth)
    df.loc[30, "range_m"] = -1.0
    bad = pa.Table.from_pandas(df, preserve_index=False).slice(20)
    assert plot_batch_from_arrow(bad, sensor_set, stream) is None
    assert (dict(stream.last_time), stream.rows, stream.largest_range, stream.largest_azimuth) == before


def test_dictionary_entries_no_row_uses_do_not_matter(sensor_set):
    """A Parquet row group's dictionary may hold values of rows outside the chunk."""
    df = make_plots(12, seed=1)
    table = pa.Table.from_pandas(df, preserve_index=False)
    sensor = pa.DictionaryArray.from_arrays(
        pa.array([0 if s == "radar1" else 1 for s in df["sensor"]], pa.int32()), pa.array(["radar1", "radar2", "nope"]))
    mode3a = pa.DictionaryArray.from_arrays(
        pa.array([None if pd.isna(m) else ["0123", "7000", "0001"].index(m) for m in df["mode3a"]], pa.int32()),
        pa.array(["0123", "7000", "0001", "9999"]))
    with_dictionaries = table.set_column(1, "sensor", sensor).set_column(7, "mode3a", mode3a)
    fast = plot_batch_from_arrow(with_dictionaries, sensor_set, PlotStream())
    plain = plot_batch_from_arrow(table, sensor_set, PlotStream())
    assert fast is not None and plain is not None
    for f in fields(PlotBatch):
        np.testing.assert_array_equal(getattr(fast, f.name), getattr(plain, f.name))

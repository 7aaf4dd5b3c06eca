"""Plots: round trips, files written by other tools, and every malformed case."""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from io_samples import EPOCH, make_plots

from skytrack.io import (
    PLOT_COLUMNS,
    STRING_DTYPE,
    InputError,
    InputWarning,
    read_plots,
    write_plots,
)

BAD_ROW = 7  # a radar1 row (row % 3 != 0) in the middle of make_plots(12)


def _texts(series: pd.Series) -> list:
    return [None if pd.isna(v) else v for v in series]


def _expected_dtypes():
    return {
        "time": np.float64,
        "sensor": STRING_DTYPE,
        "range_m": np.float64,
        "azimuth_deg": np.float64,
        "scan": pd.Int64Dtype(),
        "elevation_deg": np.float64,
        "range_rate_mps": np.float64,
        "mode3a": STRING_DTYPE,
        "mode_c_ft": np.float64,
        "mode_s": STRING_DTYPE,
        "iff": STRING_DTYPE,
        "truth_id": STRING_DTYPE,
    }


@pytest.mark.parametrize("name", ["plots.parquet", "plots.pq", "plots.csv", "plots.csv.gz"])
def test_round_trip(tmp_path, sensor_set, name):
    plots = make_plots(24)
    path = write_plots(plots, tmp_path / "out" / name, sensors=sensor_set)
    back = read_plots(path, sensors=sensor_set)
    assert tuple(back.columns) == PLOT_COLUMNS
    for column, dtype in _expected_dtypes().items():
        assert back[column].dtype == dtype, column
    for column in ("time", "range_m", "azimuth_deg", "elevation_deg", "range_rate_mps", "mode_c_ft"):
        np.testing.assert_array_equal(back[column].to_numpy(), plots[column].to_numpy())
    assert back["scan"].tolist() == plots["scan"].tolist()
    for column in ("sensor", "mode3a", "mode_s", "iff"):
        assert _texts(back[column]) == _texts(plots[column]), column
    # FORMATS: "" marks a false plot and must survive, also in CSV
    assert back["truth_id"].tolist() == plots["truth_id"].tolist()


def test_reader_puts_formats_columns_first_and_keeps_extras(tmp_path):
    plots = make_plots()
    plots["note"] = "x"
    plots["snr_db"] = np.arange(len(plots), dtype=float)
    table = pa.Table.from_pandas(
        plots[["snr_db", "azimuth_deg", "note", "sensor", "mode3a", "time", "range_m"]], preserve_index=False
    )
    path = tmp_path / "foreign.parquet"
    pq.write_table(table, path)
    back = read_plots(path)
    assert list(back.columns) == ["time", "sensor", "range_m", "azimuth_deg", "mode3a", "snr_db", "note"]
    assert back["snr_db"].tolist() == list(range(len(plots)))


def test_file_by_another_tool_csv(tmp_path):
    """pandas.to_csv output: different order, extras, leading-zero codes, nulls, upper-case hex."""
    plots = make_plots(12)
    plots["mode_s"] = plots["mode_s"].str.upper()
    plots["operator"] = "lab"
    plots = plots[["operator", "mode3a", "azimuth_deg", "range_m", "sensor", "time", "mode_s", "iff", "mode_c_ft"]]
    path = tmp_path / "other.csv"
    plots.to_csv(path, index=False)
    assert "0123" in path.read_text() and "0001" in path.read_text()
    back = read_plots(path)
    assert list(back.columns) == [
        "time",
        "sensor",
        "range_m",
        "azimuth_deg",
        "mode3a",
        "mode_c_ft",
        "mode_s",
        "iff",
        "operator",
    ]
    assert back["mode3a"].tolist()[:2] == ["0123", "7000"] and back["mode3a"].tolist()[3] == "0001"
    assert back["mode3a"].isna().tolist() == plots["mode3a"].isna().tolist()
    assert back["mode_s"].tolist()[0] == "3c6444"  # normalised to lower-case hex
    assert back["mode_c_ft"].isna().sum() == plots["mode_c_ft"].isna().sum()
    assert back["operator"].dtype == STRING_DTYPE


def test_file_by_another_tool_parquet_integer_codes_and_categories(tmp_path):
    plots = make_plots(8).drop(columns=["mode_s"])
    table = pa.table(
        {
            "sensor": pa.array(plots["sensor"]).dictionary_encode(),
            "time": pa.array(plots["time"]),
            "range_m": pa.array(plots["range_m"], pa.float32()),
            "azimuth_deg": pa.array(plots["azimuth_deg"]),
            "mode3a": pa.array([123, 7000, None, 1, 123, 7000, None, 1], pa.int64()),
            "scan": pa.array([0, 1, None, 3, 4, 5, 6, 7], pa.int32()),
            "truth_id": pa.array([None] * 8, pa.string()),
        }
    )
    path = tmp_path / "other.parquet"
    pq.write_table(table, path)
    back, report = read_plots(path, lenient=True)
    assert back["sensor"].dtype == STRING_DTYPE and back["sensor"].tolist() == plots["sensor"].tolist()
    assert back["range_m"].dtype == np.float64
    assert back["mode3a"].tolist()[:2] == ["0123", "7000"] and pd.isna(back["mode3a"][2])
    assert back["scan"].dtype == pd.Int64Dtype() and back["scan"].isna().tolist() == [False, False, True] + [False] * 5
    assert report.rows_skipped == 0
    assert report.warnings == ["column mode3a holds numbers; read as 4-digit text with leading zeros"]
    with pytest.warns(InputWarning, match="mode3a holds numbers"):
        read_plots(path)


def test_missing_required_columns_lists_missing_and_found(tmp_path):
    path = tmp_path / "p.csv"
    make_plots()[["time", "sensor", "mode3a"]].to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_plots(path, lenient=True)  # a missing column is fatal even when lenient
    assert str(info.value) == (
        f"{path}: missing required plots column(s): range_m, azimuth_deg (found: time, sensor, mode3a)"
    )
    path2 = tmp_path / "q.csv"
    make_plots()[["sensor", "range_m", "azimuth_deg"]].to_csv(path2, index=False)
    with pytest.raises(InputError, match=r"missing required plots column\(s\): time or timestamp"):
        read_plots(path2)


# (column, bad value, reason key in the report, message fragment)
ROW_CASES = [
    ("range_m", "abc", "range_m not a number", "value 'abc' is not a number"),
    ("range_m", "", "range_m missing", "missing value"),
    ("range_m", "inf", "range_m not finite", "value inf is not finite"),
    ("range_m", "-3.5", "range_m negative", "value -3.5 is negative"),
    ("azimuth_deg", "361.2", "azimuth_deg outside [0, 360)", "value 361.2 is outside [0, 360)"),
    ("azimuth_deg", "360", "azimuth_deg outside [0, 360)", "value 360.0 is outside [0, 360)"),
    ("azimuth_deg", "-0.1", "azimuth_deg outside [0, 360)", "value -0.1 is outside [0, 360)"),
    ("azimuth_deg", "-inf", "azimuth_deg not finite", "value -inf is not finite"),
    ("time", "nan", "time missing", "missing value"),
    ("time", "x12", "time not a number", "value 'x12' is not a number"),
    ("elevation_deg", "90.5", "elevation_deg outside [-90, 90]", "value 90.5 is outside [-90, 90]"),
    ("elevation_deg", "inf", "elevation_deg not finite", "value inf is not finite"),
    ("mode_c_ft", "inf", "mode_c_ft not finite", "value inf is not finite"),
    ("mode_c_ft", "FL350", "mode_c_ft not a number", "value 'FL350' is not a number"),
    ("range_rate_mps", "-inf", "range_rate_mps not finite", "value -inf is not finite"),
    ("scan", "1.5", "scan not an integer", "value 1.5 is not an integer"),
    ("mode3a", "0128", "mode3a not 4 octal digits", "value '0128' is not 4 octal digits"),
    ("mode3a", "123", "mode3a not 4 octal digits", "value '123' is not 4 octal digits"),
    ("mode3a", "12345", "mode3a not 4 octal digits", "value '12345' is not 4 octal digits"),
    ("mode_s", "3c64", "mode_s not a 24-bit hex address (6 hex digits)", "value '3c64' is not a 24-bit hex address"),
    ("iff", "ally", "iff not one of friend, foe, undetermined", "value 'ally' is not one of friend, foe, undetermined"),
    ("sensor", "", "sensor missing", "missing value"),
]


def _with_bad_cell(column: str, text: str) -> pd.DataFrame:
    plots = make_plots(12).astype({column: object})
    plots.loc[BAD_ROW, column] = text
    return plots


@pytest.mark.parametrize("column, text, reason, fragment", ROW_CASES)
def test_bad_cell_csv_strict_names_file_line_row_column(tmp_path, column, text, reason, fragment):
    path = tmp_path / "plots.csv"
    _with_bad_cell(column, text).to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_plots(path)
    error = info.value
    assert (error.file, error.row, error.line, error.column) == (str(path), BAD_ROW, BAD_ROW + 2, column)
    assert str(error).startswith(f"{path}, line {BAD_ROW + 2} (row {BAD_ROW}), column {column}: {fragment}")


@pytest.mark.parametrize("column, text, reason, fragment", ROW_CASES)
def test_bad_cell_csv_lenient_skips_and_counts(tmp_path, column, text, reason, fragment):
    path = tmp_path / "plots.csv"
    plots = _with_bad_cell(column, text)
    plots.to_csv(path, index=False)
    back, report = read_plots(path, lenient=True)
    assert len(back) == 11 and report.rows_read == 12 and report.rows_kept == 11
    assert list(report.skipped) == [reason]
    entry = report.skipped[reason]
    assert entry.count == 1
    assert (entry.examples[0].row, entry.examples[0].line, entry.examples[0].column) == (BAD_ROW, BAD_ROW + 2, column)
    assert fragment in entry.examples[0].message
    np.testing.assert_array_equal(back["time"].to_numpy(), np.delete(make_plots(12)["time"].to_numpy(), BAD_ROW))


@pytest.mark.parametrize(
    "column, value, fragment",
    [
        ("range_m", -1.0, "value -1.0 is negative"),
        ("azimuth_deg", 361.2, "value 361.2 is outside [0, 360)"),
        ("azimuth_deg", np.nan, "missing value"),
        ("elevation_deg", -91.0, "value -91.0 is outside [-90, 90]"),
        ("mode_c_ft", np.inf, "value inf is not finite"),
    ],
)
def test_bad_cell_parquet_names_row_and_column(tmp_path, column, value, fragment):
    plots = make_plots(12)
    plots.loc[BAD_ROW, column] = value
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path)
    with pytest.raises(InputError) as info:
        read_plots(path)
    assert str(info.value) == f"{path}, row {BAD_ROW}, column {column}: {fragment}"
    assert info.value.line is None
    _, report = read_plots(path, lenient=True)
    assert report.rows_skipped == 1


def test_unknown_sensor(tmp_path, sensor_set):
    plots = make_plots(12)
    plots.loc[BAD_ROW, "sensor"] = "radar9"
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    read_plots(path)  # without a SensorSet any name is accepted
    with pytest.raises(InputError) as info:
        read_plots(path, sensors=sensor_set)
    assert str(info.value) == (
        f"{path}, line {BAD_ROW + 2} (row {BAD_ROW}), column sensor: unknown sensor 'radar9' "
        "(sensors.json has: radar1, radar2)"
    )
    back, report = read_plots(path, sensors=sensor_set, lenient=True)
    assert report.skipped["unknown sensor"].count == 1 and "radar9" not in set(back["sensor"])


def test_time_backwards_within_a_sensor(tmp_path):
    plots = make_plots(12)
    # rows of different sensors may interleave in time; within radar1 row 7 goes back
    plots.loc[BAD_ROW, "time"] = plots.loc[4, "time"] - 0.5
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_plots(path)
    error = info.value
    assert (error.row, error.line, error.column) == (BAD_ROW, BAD_ROW + 2, "time")
    assert "is earlier than time" in error.message and "of an earlier row of sensor 'radar1'" in error.message
    back, report = read_plots(path, lenient=True)
    assert report.skipped["time goes backwards within a sensor"].count == 1
    for _, group in back.groupby("sensor"):
        assert np.all(np.diff(group["time"].to_numpy()) >= 0)


def test_equal_times_and_interleaved_sensors_are_fine(tmp_path):
    plots = make_plots(12)
    plots["time"] = np.repeat([0.0, 4.0, 4.0, 8.0], 3)
    plots.loc[0, "time"] = 3.0  # radar2 (rows 0, 3, 6, 9): 3, 4, 4, 8 — sorted per sensor only
    assert not plots["time"].is_monotonic_increasing
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path)
    assert len(read_plots(path)) == 12


def test_lenient_drops_later_rows_behind_the_running_maximum(tmp_path):
    plots = make_plots(12).assign(sensor="radar1", elevation_deg=np.nan)
    plots["time"] = [0, 1, 10, 2, 3, 11, 12, 4, 13, 14, 15, 16]
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path)
    back, report = read_plots(path, lenient=True)
    assert report.skipped["time goes backwards within a sensor"].count == 3  # 2, 3, 4
    assert back["time"].tolist() == [0, 1, 10, 11, 12, 13, 14, 15, 16]


def test_strict_reports_the_earliest_problem_and_counts_the_rest(tmp_path):
    plots = make_plots(12).astype({"range_m": object})
    plots.loc[9, "azimuth_deg"] = 400.0
    plots.loc[5, "range_m"] = "far"
    plots.loc[10, "iff"] = "maybe"
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_plots(path)
    assert (info.value.row, info.value.column, info.value.more) == (5, "range_m", 2)
    back, report = read_plots(path, lenient=True)
    assert report.rows_skipped == 3 and len(back) == 9
    assert sorted(report.skipped) == sorted(
        ["range_m not a number", "azimuth_deg outside [0, 360)", "iff not one of friend, foe, undetermined"]
    )


def test_timestamp_column_iso_text_with_epoch(tmp_path, sensor_set):
    plots = make_plots(6).drop(columns=["time"])
    stamps = pd.Timestamp(EPOCH) + pd.to_timedelta([0.0, 1.5, 2.0, 3.25, 4.0, 3600.0], unit="s")
    plots.insert(0, "timestamp", [s.isoformat() for s in stamps])
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    back = read_plots(path, sensors=sensor_set)
    np.testing.assert_allclose(back["time"].to_numpy(), [0.0, 1.5, 2.0, 3.25, 4.0, 3600.0], rtol=0, atol=1e-9)
    assert "timestamp" in back.columns  # kept as an extra column
    shifted = read_plots(path, sensors=sensor_set, epoch_utc="2021-10-07T11:59:00Z")
    np.testing.assert_allclose(shifted["time"].to_numpy() - back["time"].to_numpy(), 60.0, atol=1e-9)


@pytest.mark.parametrize("kind", ["aware", "naive", "posix"])
def test_timestamp_column_parquet_types(tmp_path, sensor_set, kind):
    plots = make_plots(4).drop(columns=["time"])
    stamps = pd.Timestamp(EPOCH) + pd.to_timedelta([10.0, 20.0, 30.0, 40.5], unit="s")
    if kind == "aware":
        plots["timestamp"] = stamps
    elif kind == "naive":
        plots["timestamp"] = stamps.tz_localize(None)
    else:
        plots["timestamp"] = (stamps - pd.Timestamp("1970-01-01", tz="UTC")) / pd.Timedelta(seconds=1)
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path)
    back = read_plots(path, sensors=sensor_set)
    np.testing.assert_allclose(back["time"].to_numpy(), [10.0, 20.0, 30.0, 40.5], atol=1e-6)


def test_bom_and_datetime_time_column(tmp_path, sensor_set):
    bom = tmp_path / "bom.csv"
    bom.write_text("sensor,time,range_m,azimuth_deg\n007,1,2,3\n", encoding="utf-8-sig")
    assert read_plots(bom)["sensor"].tolist() == ["007"]  # text even as the first column
    plots = make_plots(3)
    plots["time"] = pd.Timestamp(EPOCH) + pd.to_timedelta([1.0, 2.0, 3.5], unit="s")
    path = tmp_path / "dt.parquet"
    plots.to_parquet(path)
    np.testing.assert_allclose(read_plots(path, sensors=sensor_set)["time"], [1.0, 2.0, 3.5])


def test_empty_tables(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text("time,sensor,range_m,azimuth_deg,mode3a\n")
    empty = read_plots(path)
    assert len(empty) == 0 and empty["time"].dtype == np.float64 and empty["mode3a"].dtype == STRING_DTYPE


def test_timestamp_without_epoch_counts_from_first_with_warning(tmp_path):
    plots = make_plots(3).drop(columns=["time"])
    plots.insert(0, "timestamp", ["2021-10-07T12:00:05Z", "2021-10-07T12:00:07Z", "2021-10-07T12:00:05.5Z"])
    plots["sensor"] = ["radar1", "radar1", "radar2"]
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    back, report = read_plots(path, lenient=True)
    np.testing.assert_allclose(back["time"].to_numpy(), [0.0, 2.0, 0.5])
    assert report.rows_skipped == 0
    assert report.warnings == [
        "no epoch_utc known (sensors.json has none): time counts from the earliest timestamp 2021-10-07T12:00:05+00:00"
    ]
    with pytest.warns(InputWarning, match="no epoch_utc known"):
        read_plots(path)


def test_unparseable_timestamp(tmp_path, sensor_set):
    plots = make_plots(12).drop(columns=["time"])
    plots.insert(0, "timestamp", [f"2021-10-07T12:00:{s:02d}Z" for s in range(12)])
    plots.loc[BAD_ROW, "timestamp"] = "yesterday"
    path = tmp_path / "plots.csv"
    plots.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_plots(path, sensors=sensor_set)
    assert str(info.value) == (
        f"{path}, line 9 (row 7), column timestamp: value 'yesterday' is not an ISO 8601 timestamp"
    )
    back, report = read_plots(path, sensors=sensor_set, lenient=True)
    assert report.skipped["timestamp not a timestamp"].count == 1 and len(back) == 11


def test_write_plots_validates_and_orders(tmp_path):
    plots = make_plots(6)
    plots["extra"] = 1.0
    plots = plots[list(plots.columns[::-1])]
    path = write_plots(plots, tmp_path / "a" / "b" / "plots.parquet")
    assert pq.read_schema(path).names == list(PLOT_COLUMNS) + ["extra"]
    bad = plots.copy()
    bad.loc[2, "azimuth_deg"] = 720.0
    with pytest.raises(InputError) as info:
        write_plots(bad, tmp_path / "bad.parquet")
    assert str(info.value).startswith(f"plots to write to {tmp_path / 'bad.parquet'}, row 2, column azimuth_deg")
    assert not (tmp_path / "bad.parquet").exists()


def test_validation_is_vectorised_on_a_large_table(tmp_path):
    """200 000 rows with a few bad ones: every count is exact, only examples get messages."""
    n = 200_000
    rng = np.random.default_rng(11)
    plots = pd.DataFrame(
        {
            "time": np.arange(n, dtype=float),
            "sensor": "radar1",
            "range_m": rng.uniform(0, 1e5, n),
            "azimuth_deg": rng.uniform(0, 360, n),
        }
    )
    bad = rng.choice(n, 1000, replace=False)
    plots.loc[bad, "azimuth_deg"] += 360.0
    path = tmp_path / "big.parquet"
    plots.to_parquet(path)
    back, report = read_plots(path, lenient=True)
    assert report.skipped["azimuth_deg outside [0, 360)"].count == 1000
    assert [e.row for e in report.skipped["azimuth_deg outside [0, 360)"].examples] == sorted(bad)[:3]
    assert len(back) == n - 1000


codes = st.integers(0, 8**4 - 1).map(lambda c: format(c, "04o"))
finite = dict(allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(
            st.floats(0, 1e6, **finite),
            st.sampled_from(["radar1", "radar2", 'r 3,"quoted"']),
            st.floats(0, 5e5, **finite),
            st.floats(0, 360, exclude_max=True, **finite),
            st.one_of(st.none(), codes),
            st.one_of(st.none(), st.floats(-1e3, 6e4, **finite)),
        ),
        min_size=1,
        max_size=30,
    ),
    st.sampled_from(["p.csv", "p.parquet", "p.csv.gz"]),
)
def test_property_round_trip_is_exact(rows, name):
    plots = pd.DataFrame(rows, columns=["time", "sensor", "range_m", "azimuth_deg", "mode3a", "mode_c_ft"])
    plots = plots.sort_values("time", kind="stable").reset_index(drop=True)
    plots["mode_c_ft"] = plots["mode_c_ft"].astype(float)
    with tempfile.TemporaryDirectory() as directory:
        back = read_plots(write_plots(plots, Path(directory) / name))
    for column in ("time", "range_m", "azimuth_deg", "mode_c_ft"):
        np.testing.assert_array_equal(back[column].to_numpy(), plots[column].to_numpy())
    assert back["sensor"].tolist() == plots["sensor"].tolist()
    assert _texts(back["mode3a"]) == _texts(plots["mode3a"])


def test_no_warning_for_clean_files(tmp_path, sensor_set):
    path = write_plots(make_plots(), tmp_path / "p.csv")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_plots(path, sensors=sensor_set)
    assert [str(w.message) for w in caught] == []


def test_a_damaged_page_is_reported_as_damage(tmp_path):
    """skytrack writes Parquet page checksums and verifies them on reading: a flipped byte in a
    data page is reported as a damaged file, not as whatever the garbled values break (before:
    'time goes backwards', or silently wrong plots)."""
    import numpy as np
    import pandas as pd

    from skytrack.io import InputError, read_plots, write_plots

    rng = np.random.default_rng(0)
    n = 20_000
    plots = pd.DataFrame({"time": np.sort(rng.uniform(0, 1000, n)), "sensor": "radar1",
                          "range_m": rng.uniform(1e3, 2e5, n), "azimuth_deg": rng.uniform(0, 360, n)})
    path = write_plots(plots, tmp_path / "plots.parquet")
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside the column data, far from the footer
    path.write_bytes(bytes(data))
    with pytest.raises(InputError) as info:
        read_plots(path)
    assert str(info.value).startswith(f"{path}: the Parquet file is damaged: ")
    assert "checksum" in str(info.value)


@pytest.mark.parametrize("metadata", [b"{not json", b'{"index_columns": []}', b'{"columns": 5, "index_columns": []}'])
def test_damaged_pandas_metadata_does_not_matter(tmp_path, metadata):
    """A Parquet file's "pandas" metadata only rebuilds an index: damaged, it raised
    JSONDecodeError, KeyError or TypeError from inside pyarrow; now it is not read at all."""
    from skytrack.io import read_plots

    plots = pd.DataFrame({"time": [0.0, 1.0, 2.0], "sensor": "radar1", "range_m": [1e4, 2e4, 3e4],
                          "azimuth_deg": [10.0, 20.0, 30.0]})
    table = pa.Table.from_pandas(plots, preserve_index=False).replace_schema_metadata({b"pandas": metadata})
    pq.write_table(table, tmp_path / "plots.parquet")
    back = read_plots(tmp_path / "plots.parquet")
    np.testing.assert_array_equal(back["range_m"].to_numpy(), plots["range_m"].to_numpy())


@pytest.mark.parametrize("value", [1e308, -5000.0, 2e5])
def test_mode_c_outside_its_range_is_refused(tmp_path, value):
    """A Mode C of 1e308 ft was tracked silently (it broke the k-d tree of the reference path):
    altitudes outside the Mode C code's range are a located error, by both read paths."""
    from skytrack.geo.sensors import Origin, Sensor, SensorSet
    from skytrack.io import InputError, iter_plot_batches, read_plots

    plots = pd.DataFrame({"time": [0.0, 1.0, 2.0], "sensor": "radar1", "range_m": [1e4, 2e4, 3e4],
                          "azimuth_deg": [10.0, 20.0, 30.0], "mode_c_ft": [10000.0, value, 12000.0]})
    plots.to_parquet(tmp_path / "plots.parquet", index=False)
    with pytest.raises(InputError, match=r"row 1, column mode_c_ft: .* is outside \[-1500, 130000\] ft"):
        read_plots(tmp_path / "plots.parquet")
    sensors = SensorSet(Origin(48.0, 2.0, 0.0), [Sensor("radar1", x=0.0, y=0.0, sigma_range_m=40.0,
                                                        sigma_azimuth_deg=0.07, scan_period_s=4.0)])
    with pytest.raises(InputError, match=r"row 1, column mode_c_ft"):
        list(iter_plot_batches(tmp_path / "plots.parquet", sensors))


@pytest.mark.parametrize("suffix", ["parquet", "csv"])
def test_airborne_plots_need_their_platform_and_platform_values_are_numbers(tmp_path, suffix):
    """Both were plain errors without file, row or column ("could not convert string to float:
    'abc'", "sensor 'air' is airborne: plots need platform_x/y/z columns")."""
    from skytrack.geo.sensors import Origin, Sensor, SensorSet
    from skytrack.io import InputError, iter_plot_batches

    sensors = SensorSet(Origin(48.0, 2.0, 0.0), [
        Sensor("radar1", x=0.0, y=0.0, sigma_range_m=40.0, sigma_azimuth_deg=0.07, scan_period_s=4.0),
        Sensor("air", type="radar-airborne", sigma_range_m=50.0, sigma_azimuth_deg=0.5)])
    plots = pd.DataFrame({"time": [0.0, 1.0, 2.0, 3.0], "sensor": ["radar1", "radar1", "air", "air"],
                          "range_m": [1e4, 2e4, 3e4, 4e4], "azimuth_deg": [10.0, 20.0, 30.0, 40.0]})
    path = tmp_path / f"plots.{suffix}"
    write = (lambda df: df.to_parquet(path, index=False)) if suffix == "parquet" else (
        lambda df: df.to_csv(path, index=False))
    write(plots)
    with pytest.raises(InputError) as info:
        list(iter_plot_batches(path, sensors))
    assert "row 2" in str(info.value) and "column platform_x: sensor 'air' is airborne" in str(info.value)
    with_platform = plots.assign(platform_x=[np.nan, np.nan, 0.0, "abc"], platform_y=0.0, platform_z=9000.0)
    write(with_platform.astype({"platform_x": str}) if suffix == "parquet" else with_platform)
    with pytest.raises(InputError, match=r"row 3.*column platform_x: value 'abc' is not a number"):
        list(iter_plot_batches(path, sensors))

"""Streamed CSV (skytrack.io.iter_plots / tables.iter_csv): chunked reading gives what a whole read gives.

Same plots, the same strict error (row, line, column, message) and the same lenient
report, also when problems sit on chunk boundaries, in later chunks whose column types
differ from the first, behind quoted multi-line fields or malformed lines.  (A streamed
strict read stops at the first bad chunk, so its count of further bad rows covers the
rows read so far; malformed lines are counted in the whole file, as a whole read does.)
The reader blocks are made tiny so that they do not line up with the chunks.
"""

from __future__ import annotations

import gzip

import numpy as np
import pandas as pd
import pytest

import skytrack.io.tables as tables
from io_samples import make_plots
from skytrack.io import InputError, ReadReport, iter_plots, read_plots, write_plots
from skytrack.io.csv_types import infer_csv_column
from skytrack.io.tables import iter_csv

CHUNKS = [1, 7, 128, 5000]


@pytest.fixture(autouse=True)
def tiny_reader_blocks(monkeypatch):
    """Blocks of a few hundred bytes: many per chunk, and cut anywhere inside a chunk."""
    monkeypatch.setattr(tables, "_MIN_BLOCK_BYTES", 300)


def _csv(tmp_path, plots: pd.DataFrame, name: str = "plots.csv"):
    path = tmp_path / name
    plots.to_csv(path, index=False)
    return path


def _whole(path, sensors=None, lenient=False):
    """read_plots, with the warnings of a strict read collected instead of shown."""
    return read_plots(path, sensors, lenient)


def _strict_error(call) -> InputError:
    with pytest.raises(InputError) as caught:
        call()
    return caught.value


def _located(error: InputError) -> tuple:
    return error.file, error.row, error.line, error.column, error.message


def _chunked(path, chunk_rows, sensors=None, lenient=False):
    report = ReadReport(file=str(path))
    chunks = list(iter_plots(path, sensors, lenient, chunk_rows=chunk_rows, report=report))
    return chunks, report


def _report_facts(report: ReadReport) -> dict:
    return {
        "rows": (report.rows_read, report.rows_kept, report.rows_skipped),
        "skipped": {
            reason: (entry.count, [(e.row, e.line, e.column, e.message) for e in entry.examples])
            for reason, entry in report.skipped.items()
        },
        "warnings": list(report.warnings),
    }


def _assert_same_lenient_read(path, chunk_rows, sensors=None):
    whole, whole_report = read_plots(path, sensors, lenient=True)
    chunks, report = _chunked(path, chunk_rows, sensors, lenient=True)
    assert all(0 < len(c) <= chunk_rows for c in chunks)
    pd.testing.assert_frame_equal(pd.concat(chunks, ignore_index=True), whole)
    assert _report_facts(report) == _report_facts(whole_report)
    if "wrong number of fields" in whole_report.skipped:  # malformed lines are listed first, as in a whole read
        assert list(report.skipped)[0] == "wrong number of fields"
    assert str(report).splitlines()[0] == str(whole_report).splitlines()[0]


@pytest.mark.parametrize("chunk_rows", CHUNKS)
def test_chunks_are_the_whole_read(tmp_path, sensor_set, chunk_rows):
    path = _csv(tmp_path, make_plots(1000, seed=4))
    chunks, report = _chunked(path, chunk_rows, sensor_set)
    assert [len(c) for c in chunks] == [chunk_rows] * (1000 // chunk_rows) + ([1000 % chunk_rows] if 1000 % chunk_rows else [])
    pd.testing.assert_frame_equal(pd.concat(chunks, ignore_index=True), read_plots(path, sensor_set))
    assert (report.rows_read, report.rows_kept) == (1000, 1000)


def test_gzip_and_quoted_text_stream_too(tmp_path, sensor_set):
    plots = make_plots(600, seed=5)
    plots["note"] = np.where(np.arange(600) % 50 == 0, "two\nlines, quoted", "x")
    path = tmp_path / "plots.csv.gz"
    with gzip.open(path, "wt", newline="") as stream:
        plots.to_csv(stream, index=False)
    chunks, _ = _chunked(path, 64, sensor_set)
    pd.testing.assert_frame_equal(pd.concat(chunks, ignore_index=True), read_plots(path, sensor_set))


@pytest.mark.parametrize("damage", ["cut", "cut_header", "flipped", "trailing"])
def test_damaged_gzip_stream_is_a_located_error(tmp_path, sensor_set, damage):
    # fuzz suite: EOFError / zlib.error / BadGzipFile from Python's gzip escaped as tracebacks
    packed = bytearray(gzip.compress(make_plots(300, seed=2).to_csv(index=False).encode(), mtime=0))
    if damage == "cut":
        del packed[len(packed) // 2:]
    elif damage == "cut_header":
        del packed[30:]
    elif damage == "flipped":
        packed[len(packed) // 3] ^= 0xFF
    else:
        packed += b"garbage"
    path = tmp_path / "plots.csv.gz"
    path.write_bytes(bytes(packed))
    with pytest.raises(InputError) as info:
        _chunked(path, 64, sensor_set)
    assert str(info.value).startswith(f"{path}: cannot read ") and "\n" not in str(info.value)


@pytest.mark.parametrize("row", [0, 127, 128, 129, 700, 999])
@pytest.mark.parametrize("chunk_rows", [128, 5000])
def test_strict_error_names_the_row_and_line_of_the_whole_file(tmp_path, row, chunk_rows):
    plots = make_plots(1000, seed=6)
    plots.loc[row, "azimuth_deg"] = 400.0
    path = _csv(tmp_path, plots)
    whole = _strict_error(lambda: read_plots(path))
    chunked = _strict_error(lambda: _chunked(path, chunk_rows))
    assert (chunked.row, chunked.line, chunked.column) == (row, row + 2, "azimuth_deg")
    assert str(chunked) == str(whole)  # one bad row: the count agrees too


def test_lines_behind_multi_line_fields_and_malformed_lines(tmp_path):
    """Rows are not on line row + 2 here: the line comes from scanning the file, across chunks."""
    lines = ["time,sensor,range_m,azimuth_deg,note"]
    for k in range(400):
        note = '"two\nlines"' if k % 90 == 5 else "x"
        lines.append(f"{k}.0,radar1,{1000 + k},10,{note}")
    lines.insert(150, "")  # a blank line
    lines[330] = lines[330].replace(",10,", ",400.5,")
    text = "\n".join(lines) + "\n"
    path = tmp_path / "plots.csv"
    path.write_text(text)
    whole = _strict_error(lambda: read_plots(path))
    for chunk_rows in (7, 128):
        chunked = _strict_error(lambda: _chunked(path, chunk_rows))
        assert (chunked.row, chunked.line) == (whole.row, whole.line) and str(chunked) == str(whole)
    # the same with a malformed line early on: lenient reads skip it and agree on every line
    lines.insert(20, "3.5,radar1,1000")
    path.write_text("\n".join(lines) + "\n")
    for chunk_rows in (7, 128):
        _assert_same_lenient_read(path, chunk_rows)


@pytest.mark.parametrize("chunk_rows", [7, 128])
def test_malformed_lines_strict_error_counts_the_whole_file(tmp_path, chunk_rows):
    lines = ["time,sensor,range_m,azimuth_deg"] + [f"{k}.0,radar1,{1000 + k},10" for k in range(500)]
    for at in (300, 420, 480):
        lines[at] += ",surplus"
    path = tmp_path / "plots.csv"
    path.write_text("\n".join(lines) + "\n")
    whole = _strict_error(lambda: read_plots(path))
    chunked = _strict_error(lambda: _chunked(path, chunk_rows))
    assert (chunked.line, chunked.more) == (301, 2)
    assert str(chunked) == str(whole)
    _assert_same_lenient_read(path, chunk_rows)


@pytest.mark.parametrize("chunk_rows", [7, 128, 256])
def test_time_going_backwards_across_a_chunk_boundary(tmp_path, sensor_set, chunk_rows):
    plots = make_plots(1000, seed=7)
    radar1 = np.flatnonzero(plots["sensor"].to_numpy() == "radar1")
    # the first radar1 row of the chunk starting at row 256 goes back before earlier chunks
    first = radar1[radar1 >= 256][0]
    plots.loc[first, "time"] = plots.loc[radar1[radar1 < 256][-3], "time"]
    plots.loc[600, "time"] = 1.0
    path = _csv(tmp_path, plots)
    whole = _strict_error(lambda: read_plots(path, sensor_set))
    chunked = _strict_error(lambda: _chunked(path, chunk_rows, sensor_set))
    assert chunked.row == first and _located(chunked) == _located(whole)
    assert "is earlier than time" in str(chunked)
    _assert_same_lenient_read(path, chunk_rows, sensor_set)


@pytest.mark.parametrize("chunk_rows", [7, 128])
def test_bad_cells_spread_over_chunks_give_the_whole_files_report(tmp_path, sensor_set, chunk_rows):
    plots = make_plots(900, seed=8).astype({"range_m": object, "mode3a": object})
    plots.loc[[3, 200, 640], "range_m"] = "abc"  # text in a number column, in some chunks only
    plots.loc[[130, 131, 890], "azimuth_deg"] = 360.0
    plots.loc[[10, 500], "sensor"] = "radar9"
    plots.loc[[256, 257], "mode3a"] = "9999"
    plots.loc[[400], "range_m"] = "-5"
    plots.loc[777, "range_m"] = np.nan
    path = _csv(tmp_path, plots)
    _assert_same_lenient_read(path, chunk_rows, sensor_set)
    whole = _strict_error(lambda: read_plots(path, sensor_set))
    chunked = _strict_error(lambda: _chunked(path, chunk_rows, sensor_set))
    assert (chunked.row, chunked.line) == (3, 5)
    assert _located(chunked) == _located(whole)


@pytest.mark.parametrize("chunk_rows", [7, 128])
def test_column_types_may_differ_between_chunks(tmp_path, chunk_rows):
    """Integers in the first chunk, decimals and empty cells later: what a whole read gives."""
    lines = ["time,sensor,range_m,azimuth_deg,scan,mode_c_ft,extra"]
    for k in range(300):
        range_text = str(1000 + k) if k < 150 else f"{1000 + k}.25"
        mode_c = "" if k % 97 == 3 else (str(10000 + k) if k < 200 else f"{10000 + k}.5")
        extra = "true" if k < 250 else "maybe"
        lines.append(f"{k},radar1,{range_text},{k % 360},{k // 4},{mode_c},{extra}")
    path = tmp_path / "plots.csv"
    path.write_text("\n".join(lines) + "\n")
    chunks, _ = _chunked(path, chunk_rows)
    whole = read_plots(path)
    together = pd.concat(chunks, ignore_index=True)
    known = [c for c in whole.columns if c != "extra"]
    pd.testing.assert_frame_equal(together[known], whole[known])
    # extra columns are not checked: typed per chunk (here booleans, then text), same values
    assert together["extra"].astype(str).str.lower().tolist() == whole["extra"].astype(str).str.lower().tolist()


def test_timestamps_without_epoch_count_from_the_first_chunk_once(tmp_path):
    start = pd.Timestamp("2024-05-01T12:00:00Z")
    plots = make_plots(400, seed=9).drop(columns=["time"])
    plots.insert(0, "timestamp", [(start + pd.Timedelta(seconds=4 * k)).isoformat() for k in range(400)])
    path = _csv(tmp_path, plots)
    whole, whole_report = read_plots(path, lenient=True)
    chunks, report = _chunked(path, 64, lenient=True)
    pd.testing.assert_frame_equal(pd.concat(chunks, ignore_index=True), whole)
    assert report.warnings == whole_report.warnings and len(report.warnings) == 1
    assert float(chunks[-1]["time"].iloc[-1]) == 4.0 * 399


def test_unit_warning_is_given_once_for_the_whole_file(tmp_path):
    plots = make_plots(300, seed=10)
    plots["range_m"] = plots["range_m"] / 1000.0
    path = _csv(tmp_path, plots)
    _, whole_report = read_plots(path, lenient=True)
    _, report = _chunked(path, 20, lenient=True)  # 20-row chunks: too few rows each for the check
    assert report.warnings == whole_report.warnings
    assert len(report.warnings) == 1 and "kilometres" in report.warnings[0]
    with pytest.warns(UserWarning, match="kilometres") as caught:
        _chunked(path, 20)
    assert len([w for w in caught if "kilometres" in str(w.message)]) == 1


def test_header_only_and_missing_columns(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("time,sensor,range_m,azimuth_deg\n")
    assert _chunked(empty, 10)[0] == []
    wrong = tmp_path / "wrong.csv"
    wrong.write_text("time,sensor,range_km,azimuth_deg\n")
    assert "range_km is in kilometres" in str(_strict_error(lambda: _chunked(wrong, 10)))
    none = tmp_path / "none.csv"
    none.write_text("")
    assert str(_strict_error(lambda: _chunked(none, 10))) == str(_strict_error(lambda: read_plots(none)))


def test_the_csv_is_never_read_whole(tmp_path, monkeypatch):
    path = write_plots(make_plots(500, seed=11), tmp_path / "plots.csv")

    def whole_read(*args, **kwargs):
        raise AssertionError("iter_plots read the whole CSV file")

    monkeypatch.setattr(tables.pcsv, "read_csv", whole_read)
    monkeypatch.setattr("skytrack.io.plots.load_table", whole_read)
    batches = []
    real_open = tables.pcsv.open_csv

    def counting_open(*args, **kwargs):
        reader = real_open(*args, **kwargs)
        batches.append(kwargs["read_options"].block_size)
        return reader

    monkeypatch.setattr(tables.pcsv, "open_csv", counting_open)
    assert sum(len(c) for c in iter_plots(path, chunk_rows=50)) == 500
    assert batches and batches[0] < path.stat().st_size


def test_iter_csv_refuses_an_empty_chunk_size(tmp_path):
    path = write_plots(make_plots(5), tmp_path / "plots.csv")
    with pytest.raises(ValueError, match="chunk_rows"):
        next(iter_csv(path, 0))


@pytest.mark.parametrize("chunk_rows", [7, 128])
def test_parquet_chunks_are_checked_like_the_whole_file_too(tmp_path, sensor_set, chunk_rows):
    plots = make_plots(600, seed=12)
    plots.loc[300, "time"] = 0.5  # behind every earlier chunk
    plots.loc[[5, 450], "azimuth_deg"] = 365.0
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path, index=False)
    whole = _strict_error(lambda: read_plots(path, sensor_set))
    chunked = _strict_error(lambda: _chunked(path, chunk_rows, sensor_set))
    assert _located(chunked) == _located(whole)
    _assert_same_lenient_read(path, chunk_rows, sensor_set)


@pytest.mark.parametrize(
    "cells",
    [
        ["1", "2"], ["1", "2.5"], ["1e3"], ["inf", "1"], [" 1"], ["1 "], ["+1.5"], ["0x10"], [".5"], ["1_000"],
        ["2024-05-01T12:00:00Z"], ["2024-05-01T12:00:00+02:00"], ["2024-05-01 12:00:00.123"], ["2024-05-01T12:00"],
        ["2024-05-01"], ["2024-05-01T12:00:00Z", "2024-05-01T12:00:00"], ["true", "false"], ["True", "0"],
        ["true", ""], ["", ""], ["NaN", "2.0"], ["abc", "1"], ["1e400"], ["00012"], ["9223372036854775808"],
        [" ", " 2"], ['"1"'], ['""', "1"], ["1"] * 40 + ["1.5"], ["1"] * 40 + ["abc"], [""] * 300 + ["2.5"],
        ["2024-05-01T12:00:00"] * 30 + ["2024-05-01T12:00:00.5"],
    ],
)
def test_a_chunk_is_typed_as_pyarrow_types_a_whole_file(cells):
    import io

    import pyarrow as pa
    import pyarrow.csv as pcsv

    def read(column_types):
        data = ("c\n" + "\n".join(cells) + "\n").encode()
        options = pcsv.ConvertOptions(column_types=column_types, null_values=tables.CSV_NULL_TOKENS,
                                      strings_can_be_null=True, quoted_strings_can_be_null=False)
        return pcsv.read_csv(io.BytesIO(data), convert_options=options).column(0)

    inferred = read({})
    ours = infer_csv_column(read({"c": pa.string()}))
    assert ours.type == inferred.type
    assert ours.to_pandas().astype(str).tolist() == inferred.to_pandas().astype(str).tolist()

"""Generic table files: extensions, missing/corrupted files, CSV lines, error texts."""

from __future__ import annotations

import gzip
import pickle

import numpy as np
import pandas as pd
import pytest
from io_samples import make_plots

from skytrack.io import InputError, ReadReport, read_plots, read_table, table_format, write_table
from skytrack.io.errors import SkippedRows
from skytrack.io.tables import TableSource


@pytest.mark.parametrize(
    "name, expected",
    [("a.parquet", "parquet"), ("A.PQ", "parquet"), ("a.csv", "csv"), ("a.CSV.GZ", "csv"), ("dir.x/a.csv", "csv")],
)
def test_format_by_extension(name, expected):
    assert table_format(name) == expected


@pytest.mark.parametrize("name", ["plots.txt", "plots.json", "plots.gz", "plots", "plots.parquet.gz"])
def test_unsupported_extension_names_file(tmp_path, name):
    path = tmp_path / name
    path.write_text("time\n1\n")
    with pytest.raises(InputError) as info:
        read_table(path)
    assert str(path) in str(info.value)
    assert "unsupported file extension" in str(info.value)
    with pytest.raises(InputError, match="unsupported file extension"):
        write_table(pd.DataFrame({"a": [1]}), path)


@pytest.mark.parametrize("name", ["nothing.parquet", "nothing.csv"])
def test_missing_file(tmp_path, name):
    with pytest.raises(InputError) as info:
        read_table(tmp_path / name)
    assert str(info.value) == f"{tmp_path / name}: file not found"
    assert info.value.file == str(tmp_path / name)


def test_corrupted_parquet_names_file_without_traceback(tmp_path):
    good = tmp_path / "good.parquet"
    write_table(make_plots(), good)
    data = good.read_bytes()
    cases = {
        "garbage.parquet": b"this is not parquet at all",
        "truncated.parquet": data[: len(data) // 2],
        "empty.pq": b"",
    }
    for name, content in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(InputError) as info:
            read_table(path)
        text = str(info.value)
        assert text.startswith(f"{path}: not a readable Parquet file (")
        assert "\n" not in text and "Traceback" not in text
        assert info.value.__cause__ is None and info.value.__suppress_context__


@pytest.mark.parametrize("name", ["t.parquet", "t.pq", "t.csv", "t.csv.gz"])
def test_round_trip_keeps_values_and_text(tmp_path, name):
    df = pd.DataFrame(
        {
            "f": [0.1, 1 / 3, -1e-300, np.nan, 123456789.123456789],
            "mode3a": ["0123", None, "", "7000", "0001"],
            "n": [1, 2, 3, 4, 5],
        }
    )
    path = write_table(df, tmp_path / "sub" / "dir" / name)  # parents are created
    back = read_table(path)
    np.testing.assert_array_equal(back["f"].to_numpy(), df["f"].to_numpy())  # exact floats, NaN = NaN
    assert back["mode3a"].tolist()[0] == "0123" and back["mode3a"].tolist()[2] == ""
    assert back["mode3a"].isna().tolist() == [False, True, False, False, False]
    assert back["n"].tolist() == [1, 2, 3, 4, 5]


def test_csv_gz_is_really_compressed(tmp_path):
    path = write_table(make_plots(), tmp_path / "p.csv.gz")
    with gzip.open(path, "rt") as stream:
        assert stream.readline().startswith('"time","sensor"')


def test_duplicate_column_names(tmp_path):
    path = tmp_path / "dup.csv"
    path.write_text("time,sensor,time\n1,r,2\n")
    with pytest.raises(InputError, match=r"dup\.csv: duplicate column name\(s\): time"):
        read_table(path)


def test_empty_csv(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text("")
    with pytest.raises(InputError, match=r"empty\.csv: empty CSV file"):
        read_table(path)


def _ragged_file(tmp_path):
    path = tmp_path / "ragged.csv"
    path.write_text(
        "time,sensor,range_m,azimuth_deg\n"
        "0.0,radar1,1000,10\n"
        "1.0,radar1,1000\n"  # line 3: a field is missing
        "2.0,radar1,1000,10\n"
        "3.0,radar1,1000,10,99\n"  # line 5: one field too many
    )
    return path


def test_wrong_field_count_strict(tmp_path):
    path = _ragged_file(tmp_path)
    with pytest.raises(InputError) as info:
        read_table(path)
    assert info.value.line == 3
    assert str(info.value).startswith(f"{path}, line 3: expected 4 fields (as in the header), found 3")
    assert info.value.more == 1


def test_wrong_field_count_lenient_counts(tmp_path):
    path = _ragged_file(tmp_path)
    plots, report = read_plots(path, lenient=True)
    assert len(plots) == 2
    assert report.rows_read == 4 and report.rows_kept == 2 and report.rows_skipped == 2
    entry = report.skipped["wrong number of fields"]
    assert entry.count == 2
    assert [e.line for e in entry.examples] == [3, 5]


def test_csv_line_numbers_with_blank_lines_and_quoted_newlines(tmp_path):
    path = tmp_path / "lines.csv"
    path.write_text(
        "time,sensor,range_m,azimuth_deg,note\n"  # line 1
        "0.0,radar1,1000,10,plain\n"  # line 2, row 0
        "\n"  # line 3: blank
        '1.0,radar1,1000,10,"two\nlines"\n'  # lines 4-5, row 1
        "2.0,radar1,1000,400.5,x\n"  # line 6, row 2
    )
    with pytest.raises(InputError) as info:
        read_plots(path)
    assert (info.value.row, info.value.line, info.value.column) == (2, 6, "azimuth_deg")
    assert str(info.value) == f"{path}, line 6 (row 2), column azimuth_deg: value 400.5 is outside [0, 360)"


def test_line_numbers_gzip_simple_layout(tmp_path):
    plots = make_plots(40)
    path = write_table(
        plots.drop(columns=["truth_id", "mode3a", "mode_s", "iff", "sensor"]).assign(sensor="radar1"),
        tmp_path / "p.csv.gz",
    )
    source = TableSource(display=str(path), path=path, is_csv=True, n_fields=8)
    # pyarrow quotes text, so this file takes the scanning path; both must agree with r + 2
    assert source.lines([0, 5, 39]) == [2, 7, 41]
    raw = tmp_path / "raw.csv"
    raw.write_text("a,b\n1,2\n3,4\n")
    simple = TableSource(display=str(raw), path=raw, is_csv=True, n_fields=2)
    assert simple.lines([1]) == [3] and simple._simple_layout is True


def test_input_error_text_forms():
    assert (
        str(InputError("value 361.2 is outside [0, 360)", file="plots.csv", row=15, line=17, column="azimuth_deg"))
        == "plots.csv, line 17 (row 15), column azimuth_deg: value 361.2 is outside [0, 360)"
    )
    assert str(InputError("m", file="p.parquet", row=3, column="c")) == "p.parquet, row 3, column c: m"
    assert str(InputError("m", file="p.parquet", column="c")) == "p.parquet, column c: m"
    assert (
        str(InputError("sigma_range_m must be > 0, got -3", file="sensors.json", where="sensors[1] ('radar2')"))
        == "sensors.json: sensors[1] ('radar2'): sigma_range_m must be > 0, got -3"
    )
    assert str(InputError("m", file="f.csv", row=1, line=3, more=2)).endswith(
        "m (and 2 more bad rows; lenient mode skips and counts them)"
    )
    assert isinstance(InputError("m"), ValueError)


def test_input_error_pickles_with_location():
    error = InputError("bad", file="f.csv", row=1, line=3, column="c", more=4)
    back = pickle.loads(pickle.dumps(error))
    assert (back.file, back.row, back.line, back.column, back.more, str(back)) == (
        "f.csv",
        1,
        3,
        "c",
        4,
        str(error),
    )


def test_report_text_lists_reasons_and_examples():
    report = ReadReport(file="p.csv", rows_read=10, rows_kept=7)
    report.add_skipped(
        "azimuth_deg outside [0, 360)",
        3,
        [
            InputError(f"value {v} is outside [0, 360)", file="p.csv", row=r, line=r + 2)
            for r, v in ((1, 400.0), (4, -1.0), (8, 360.0), (9, 999.0))
        ],
    )
    report.warn("something converted")
    text = str(report)
    assert text.splitlines()[0] == "p.csv: 10 rows read, 7 kept, 3 skipped"
    assert "3 × azimuth_deg outside [0, 360) (e.g. line 3 (row 1): value 400.0 is outside [0, 360)" in text
    assert "999.0" not in text  # only the first three examples are kept
    assert text.splitlines()[-1] == "  warning: something converted"
    assert isinstance(report.skipped["azimuth_deg outside [0, 360)"], SkippedRows)
    assert not report.ok


def test_parquet_text_and_names_that_are_not_utf8_are_located_errors(tmp_path):
    """Fuzz suite: a damaged name raised UnicodeDecodeError, damaged text an ArrowException."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from skytrack.io.tables import count_rows, iter_parquet_tables

    good = tmp_path / "good.parquet"
    pq.write_table(pa.table({"sensQr": ["abcQd"] * 3}), good, store_schema=False, use_dictionary=False,
                   compression="none", write_statistics=False)
    for name, marker, damaged in [("name.parquet", b"sensQr", b"sens\xffr"), ("text.parquet", b"abcQd", b"abc\xffd")]:
        path = tmp_path / name
        path.write_bytes(good.read_bytes().replace(marker, damaged))
        with pytest.raises(InputError) as info:
            count_rows(path)
            list(iter_parquet_tables(path, 2))
        assert str(info.value).startswith(f"{path}: not a readable Parquet file (")


def test_a_malformed_csv_line_that_is_not_utf8_is_a_located_error_without_noise(tmp_path, capsys):
    """pyarrow cannot decode such a line for the invalid-row handler and aborts the read: the
    reader names the line and the byte (strict and lenient alike), and nothing is printed."""
    import gzip
    import sys

    from skytrack.io.errors import InputError
    from skytrack.io.tables import iter_csv_tables

    hook = sys.unraisablehook
    text = b"sensor,time,range_m,azimuth_deg\nradar1,1,2,3\nradar1,2,3,4,\xff\xfe5\nradar1,3,4,5\n"
    plain = tmp_path / "bad.csv"
    plain.write_bytes(text)
    packed = tmp_path / "bad.csv.gz"
    packed.write_bytes(gzip.compress(text))
    for path in (plain, packed):
        for lenient in (False, True):
            with pytest.raises(InputError, match=r"line 3: byte 14 \(0xff\) is not UTF-8 text"):
                list(iter_csv_tables(path, 100, lenient=lenient))
    captured = capsys.readouterr()
    assert "Exception ignored" not in captured.err + captured.out
    assert sys.unraisablehook is hook  # the reader's silencing ends with its calls


def test_a_csv_header_that_is_not_utf8_is_a_located_error(tmp_path):
    """Found by the fuzz run of seed 5: pyarrow builds column names from the header's raw bytes
    and fails on them outside the reader; the header check names line 1 instead."""
    from skytrack.io.errors import InputError
    from skytrack.io.tables import iter_csv_tables

    path = tmp_path / "bad_header.csv"
    path.write_bytes(b"sensor,ti\x80me,range_m,azimuth_deg\nradar1,1,2,3\n")
    for lenient in (False, True):
        with pytest.raises(InputError, match="line 1: the header is not UTF-8 text"):
            list(iter_csv_tables(path, 100, lenient=lenient))

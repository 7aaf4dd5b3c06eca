"""Recorded state vectors: the traffic and OpenSky-database layouts, their units, file kinds, errors."""

from __future__ import annotations

import gzip
import json
import warnings

import numpy as np
import pandas as pd
import pytest

from skytrack.io import InputError, InputWarning, read_state_vectors

# 2021-10-07T12:00:00Z and one second later, as POSIX seconds
T0 = 1633608000.0


def traffic_rows() -> pd.DataFrame:
    """Two aircraft in the traffic library's layout with round values in its units."""
    return pd.DataFrame(
        {
            "timestamp": ["2021-10-07T12:00:00Z", "2021-10-07T12:00:01Z", "2021-10-07T12:00:00.5Z"],
            "icao24": ["3C6444", "3c6444", "0101de"],
            "callsign": ["DLH123  ", "DLH123", None],
            "latitude": [48.5, 48.501, 47.25],
            "longitude": [2.25, 2.252, -1.5],
            "altitude": [10000.0, 10025.0, None],
            "geoaltitude": [10500.0, 10525.0, 3000.0],
            "groundspeed": [450.0, 450.0, 300.0],
            "track": [90.0, -90.0, 360.0],
            "vertical_rate": [-1000.0, 1200.0, None],
            "squawk": ["0671", "671", "7000"],
            "onground": [False, False, True],
        }
    )


def opensky_rows() -> pd.DataFrame:
    """The same kind of data in the OpenSky database's layout (SI units, POSIX seconds)."""
    return pd.DataFrame(
        {
            "time": [T0, T0 + 1.0, T0 + 5.0],
            "icao24": ["4ca84d", "4ca84d", "4ca84d"],
            "lat": [49.0, 49.001, 49.002],
            "lon": [2.5, 2.501, 2.502],
            "velocity": [231.5, 230.0, 229.0],
            "heading": [45.0, 46.0, 47.0],
            "vertrate": [5.0, -2.5, 0.0],
            "callsign": ["RYR3YM", "RYR3YM", "RYR3YM"],
            "onground": [False, False, False],
            "squawk": ["1000", "1000", "1000"],
            "baroaltitude": [3000.0, 3005.0, 3010.0],
            "geoaltitude": [3100.0, 3105.0, None],
            "lastposupdate": [T0, T0 + 1.0, T0 + 4.5],
        }
    )


def read(path, **kwargs) -> pd.DataFrame:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        return read_state_vectors(path, **kwargs)


def test_traffic_layout_units_are_converted_exactly(tmp_path):
    path = tmp_path / "traffic.csv"
    traffic_rows().to_csv(path, index=False)
    with pytest.warns(InputWarning, match="fewer than 4 digits padded"):
        states = read_state_vectors(path)
    assert states.attrs["layout"] == "traffic" and states.attrs["altitude"] == "geometric"
    assert states["time"].tolist() == [T0, T0 + 1.0, T0 + 0.5]
    assert states["icao24"].tolist() == ["3c6444", "3c6444", "0101de"]
    # 1 ft = 0.3048 m, 1 kt = 1852/3600 m/s, 1 ft/min = 0.00508 m/s
    np.testing.assert_allclose(states["baro_alt_m"][:2], [3048.0, 3055.62], rtol=0, atol=1e-9)
    assert np.isnan(states["baro_alt_m"][2])
    np.testing.assert_allclose(states["geo_alt_m"], [3200.4, 3208.02, 914.4], rtol=0, atol=1e-9)
    np.testing.assert_allclose(states["alt_m"], states["geo_alt_m"], rtol=0, atol=0)
    np.testing.assert_allclose(states["groundspeed_mps"], [231.5, 231.5, 154.33333333333334], rtol=0, atol=1e-9)
    np.testing.assert_allclose(states["vertical_rate_mps"][:2], [-5.08, 6.096], rtol=0, atol=1e-12)
    assert states["track_deg"].tolist() == [90.0, 270.0, 0.0]
    assert states["squawk"].tolist() == ["0671", "0671", "7000"]
    assert states["callsign"].tolist()[:2] == ["DLH123", "DLH123"] and pd.isna(states["callsign"][2])
    assert states["onground"].tolist() == [False, False, True]


def test_barometric_altitude_on_request(tmp_path):
    path = tmp_path / "traffic.parquet"
    traffic_rows().to_parquet(path)
    states = read(path, altitude="barometric")
    assert states.attrs["altitude"] == "barometric" and states.attrs["altitude_column"] == "altitude"
    np.testing.assert_allclose(states["alt_m"][:2], [3048.0, 3055.62], rtol=0, atol=1e-9)


def test_traffic_parquet_with_datetimes_and_numeric_squawks(tmp_path):
    rows = traffic_rows()
    rows["timestamp"] = pd.to_datetime(rows["timestamp"], format="ISO8601")
    rows["squawk"] = [671, 671, 7000]
    path = tmp_path / "traffic.parquet"
    rows.to_parquet(path)
    states = read(path)
    assert states["time"].tolist() == [T0, T0 + 1.0, T0 + 0.5]
    assert states["squawk"].tolist() == ["0671", "0671", "7000"]


def test_opensky_layout_is_read_in_its_si_units(tmp_path):
    path = tmp_path / "opensky.csv.gz"
    opensky_rows().to_csv(path, index=False)
    states = read(path)
    assert states.attrs["layout"] == "opensky"
    assert states["time"].tolist() == [T0, T0 + 1.0, T0 + 5.0]
    assert states["baro_alt_m"].tolist() == [3000.0, 3005.0, 3010.0]
    assert states["geo_alt_m"].tolist()[:2] == [3100.0, 3105.0]
    # auto: the geometric altitude, missing where the file has none (cleaning drops that row)
    assert states["alt_m"].tolist()[:2] == [3100.0, 3105.0] and np.isnan(states["alt_m"][2])
    assert states["groundspeed_mps"].tolist() == [231.5, 230.0, 229.0]
    assert states["track_deg"].tolist() == [45.0, 46.0, 47.0]
    assert states["vertical_rate_mps"].tolist() == [5.0, -2.5, 0.0]
    assert states["squawk"].tolist() == ["1000"] * 3


def test_json_lines_gzip_with_millisecond_timestamps(tmp_path):
    # pandas' JSON writer (used by the traffic library) stores datetimes in milliseconds
    rows = traffic_rows().assign(squawk=["0671", "0671", "7000"])
    records = rows.assign(timestamp=[T0 * 1000.0, (T0 + 1.0) * 1000.0, (T0 + 0.5) * 1000.0]).to_dict("records")
    path = tmp_path / "traffic.jsonl.gz"
    with gzip.open(path, "wt", encoding="utf-8") as handle:
        for record in records:
            handle.write(json.dumps({k: (None if isinstance(v, float) and np.isnan(v) else v) for k, v in record.items()}) + "\n")
    with pytest.warns(InputWarning, match="epoch milliseconds"):
        states = read_state_vectors(path)
    assert states["time"].tolist() == [T0, T0 + 1.0, T0 + 0.5]
    np.testing.assert_allclose(states["geo_alt_m"], [3200.4, 3208.02, 914.4], rtol=0, atol=1e-9)


def test_json_array_of_records_keeps_digit_only_addresses_as_text(tmp_path):
    rows = opensky_rows().assign(icao24=["393320"] * 3)
    path = tmp_path / "opensky.json"
    path.write_text(rows.to_json(orient="records"))
    states = read(path)
    assert states["icao24"].tolist() == ["393320"] * 3
    assert states["time"].tolist() == [T0, T0 + 1.0, T0 + 5.0]


@pytest.mark.parametrize(
    ("drop", "expected"),
    [
        (["latitude", "longitude"], "unknown state-vector layout"),
        (["latitude"], "missing required column.*latitude"),
        (["icao24"], "missing required column.*icao24"),
        (["timestamp"], "missing required column.*timestamp"),
        (["altitude", "geoaltitude"], "missing required column.*altitude or geoaltitude"),
    ],
)
def test_missing_columns_are_one_line_errors_naming_the_file(tmp_path, drop, expected):
    path = tmp_path / "bad.csv"
    traffic_rows().drop(columns=drop).to_csv(path, index=False)
    with pytest.raises(InputError, match=expected) as info:
        read(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "\n" not in message


def test_unknown_layout_lists_both_layouts_and_what_was_found(tmp_path):
    path = tmp_path / "bad.csv"
    pd.DataFrame({"t": [1.0], "x": [2.0]}).to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read(path)
    message = str(info.value)
    assert "latitude" in message and "baroaltitude" in message and "found: t, x" in message


def test_both_position_pairs_are_ambiguous(tmp_path):
    path = tmp_path / "bad.csv"
    traffic_rows().assign(lat=1.0, lon=2.0).to_csv(path, index=False)
    with pytest.raises(InputError, match="ambiguous state-vector layout"):
        read(path)


def test_a_required_column_without_any_value_is_named(tmp_path):
    path = tmp_path / "bad.parquet"
    opensky_rows().assign(lat=np.nan).to_parquet(path)
    with pytest.raises(InputError, match="column lat: has no value in any row"):
        read(path)
    opensky_rows().assign(geoaltitude=np.nan, baroaltitude=np.nan).to_parquet(path)
    with pytest.raises(InputError, match="column baroaltitude: has no value in any row"):
        read(path)
    with pytest.raises(InputError, match="no geometric altitude column|column geoaltitude: has no value"):
        read(path, altitude="geometric")


def test_bad_cells_are_located_by_row_line_and_column(tmp_path):
    path = tmp_path / "bad.csv"
    rows = opensky_rows().astype({"lat": object})
    rows.loc[1, "lat"] = "north"
    rows.to_csv(path, index=False)
    with pytest.raises(InputError, match=r"bad\.csv, line 3 \(row 1\), column lat: value 'north' is not a number"):
        read(path)
    opensky_rows().assign(lon=[2.5, 200.0, 2.5]).to_csv(path, index=False)
    with pytest.raises(InputError, match=r"row 1\), column lon: value 200.0 is outside \[-180, 180\]"):
        read(path)
    opensky_rows().assign(velocity=[1.0, 1.0, -3.0]).to_csv(path, index=False)
    with pytest.raises(InputError, match=r"row 2\), column velocity: value -3.0 is negative"):
        read(path)
    opensky_rows().assign(icao24=["4ca84d", "4ca84", "4ca84d"]).to_csv(path, index=False)
    with pytest.raises(InputError, match=r"row 1\), column icao24: value '4ca84' is not a 24-bit hex address"):
        read(path)


def test_empty_unsupported_and_broken_files(tmp_path):
    empty = tmp_path / "empty.parquet"
    opensky_rows().iloc[:0].to_parquet(empty)
    with pytest.raises(InputError, match="has no rows"):
        read(empty)
    other = tmp_path / "states.xlsx"
    other.write_text("x")
    with pytest.raises(InputError, match="unsupported file extension for state vectors"):
        read(other)
    broken = tmp_path / "states.jsonl"
    broken.write_text('{"time": 1, "icao24": "4ca84d"}\n{"time": ')
    with pytest.raises(InputError, match=r"states\.jsonl: cannot read as JSON lines"):
        read(broken)
    with pytest.raises(InputError, match="file not found"):
        read(tmp_path / "missing.jsonl")


def test_invalid_squawks_become_no_code_with_a_warning(tmp_path):
    path = tmp_path / "traffic.csv"
    traffic_rows().assign(squawk=["7700", "8888", None]).to_csv(path, index=False)
    with pytest.warns(InputWarning, match="1 value\\(s\\) are not 4 octal digits"):
        states = read_state_vectors(path)
    assert states["squawk"][0] == "7700" and pd.isna(states["squawk"][1]) and pd.isna(states["squawk"][2])


def test_the_bundled_recordings_read_in_the_traffic_layout():
    from skytrack.sim.recorded import bundled_samples, sample_path

    assert bundled_samples() == ["paris_2021-10-07", "switzerland_2018-08-01"]
    paris = read(sample_path("paris_2021-10-07"))
    assert len(paris) == 284505 and paris["icao24"].nunique() == 213
    assert paris.attrs["layout"] == "traffic" and paris.attrs["altitude"] == "barometric"
    swiss = read(sample_path("switzerland_2018-08-01"))
    assert len(swiss) == 52293 and swiss["icao24"].nunique() == 428 and swiss["squawk"].isna().all()

"""Truth: round trips, defaults, malformed rows, and the OpenSky state-vector layout."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pymap3d
import pytest
from io_samples import EPOCH, ORIGIN, make_truth

from skytrack.geo import enu_to_geodetic, geodetic_to_enu
from skytrack.io import STRING_DTYPE, TRUTH_COLUMNS, InputError, InputWarning, read_truth, write_truth


def _o():
    return ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m


@pytest.mark.parametrize("name", ["truth.parquet", "truth.csv", "truth.csv.gz"])
def test_round_trip_with_origin_adds_geodetic(tmp_path, name):
    truth = make_truth()
    path = write_truth(truth, tmp_path / "t" / name, origin=ORIGIN)
    back = read_truth(path)
    assert tuple(back.columns) == TRUTH_COLUMNS
    assert back["target_id"].dtype == STRING_DTYPE and back["segment"].dtype == np.int64
    assert back["visible"].dtype == bool and back["visible"].tolist() == truth["visible"].tolist()
    for column in ("time", "x", "y", "z", "vx", "vy", "vz"):
        np.testing.assert_array_equal(back[column].to_numpy(), truth[column].to_numpy())
    x, y, z = geodetic_to_enu(back["lat"], back["lon"], back["alt_m"], *_o())
    np.testing.assert_allclose(np.c_[x, y, z], truth[["x", "y", "z"]].to_numpy(), atol=1e-6)


def test_round_trip_without_origin_leaves_geodetic_absent(tmp_path):
    back = read_truth(write_truth(make_truth(), tmp_path / "truth.parquet"))
    assert "lat" not in back.columns and len(back) == 30


def test_geodetic_only_truth_is_converted_with_the_origin(tmp_path, sensor_set):
    truth = make_truth()
    lat, lon, alt = enu_to_geodetic(truth["x"], truth["y"], truth["z"], *_o())
    foreign = truth.drop(columns=["x", "y", "z"]).assign(lat=lat, lon=lon, alt_m=alt)
    path = tmp_path / "geo.csv"
    foreign.to_csv(path, index=False)
    back = read_truth(path, sensors=sensor_set)
    np.testing.assert_allclose(back[["x", "y", "z"]].to_numpy(), truth[["x", "y", "z"]].to_numpy(), atol=1e-6)
    with pytest.raises(InputError) as info:
        read_truth(path)
    assert str(info.value) == (
        f"{path}: truth positions are given as lat/lon/alt_m only: an origin (sensors.json) is needed "
        "to convert them to x/y/z"
    )


def test_defaults_segment_visible_and_finite_difference_velocity(tmp_path):
    t = np.array([0.0, 1.0, 3.0, 6.0])
    truth = pd.DataFrame(
        {
            "time": np.r_[t, 50.0],
            "target_id": ["a"] * 4 + ["lone"],
            "x": np.r_[10 + 7 * t, 0],
            "y": np.r_[-3 * t, 0],
            "z": np.r_[100 + 0.5 * t, 0],
        }
    )
    path = tmp_path / "truth.parquet"
    truth.to_parquet(path)
    back, report = read_truth(path, lenient=True)
    assert back["segment"].tolist() == [0] * 5 and back["visible"].all()
    # linear motion: central and one-sided differences are exact, on uneven steps too
    np.testing.assert_allclose(back[["vx", "vy", "vz"]].to_numpy()[:4], np.tile([7.0, -3.0, 0.5], (4, 1)), rtol=1e-12)
    assert back.loc[4, ["vx", "vy", "vz"]].tolist() == [0.0, 0.0, 0.0]
    assert report.warnings == ["1 segment(s) have a single row: their velocity is unknown and set to 0"]


def test_interleaved_targets_are_fine_and_file_order_is_kept(tmp_path):
    truth = make_truth().sample(frac=1.0, random_state=4)
    truth = truth.sort_values("time", kind="stable")  # sorted in time within each segment
    path = tmp_path / "truth.parquet"
    truth.to_parquet(path)
    back = read_truth(path)
    np.testing.assert_array_equal(back["time"].to_numpy(), truth["time"].to_numpy())


TRUTH_BAD = [
    (
        "time",
        0.0,
        "time does not increase within a target",
        "time 0.0 is not after time 12.0 of an earlier row of target 'a' segment 0",
    ),
    ("time", 12.0, "time does not increase within a target", "time 12.0 is not after time 12.0"),
    ("x", np.nan, "x missing", "missing value"),
    ("vx", np.inf, "vx not finite", "value inf is not finite"),
    ("segment", -1, "segment negative", "value -1 is negative"),
    ("segment", 1.5, "segment not an integer", "value 1.5 is not an integer"),
    ("target_id", "", "target_id missing", "missing value"),
    ("visible", "maybe", "visible not a boolean", "value 'maybe' is not true/false"),
]


@pytest.mark.parametrize("column, value, reason, fragment", TRUTH_BAD)
def test_malformed_truth_rows(tmp_path, column, value, reason, fragment):
    truth = make_truth().astype({column: object})
    truth.loc[7, column] = value  # target a, segment 0, times 0..18: row 7 is t = 14
    path = tmp_path / "truth.csv"
    truth.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_truth(path)
    error = info.value
    assert (error.file, error.row, error.line, error.column) == (str(path), 7, 9, column)
    assert fragment in str(error)
    back, report = read_truth(path, lenient=True)
    assert report.skipped[reason].count == 1 and len(back) == 29


def test_latitude_out_of_range(tmp_path):
    truth = make_truth()
    truth["lat"], truth["lon"], truth["alt_m"] = enu_to_geodetic(truth["x"], truth["y"], truth["z"], *_o())
    truth.loc[3, "lat"] = 95.0
    path = tmp_path / "truth.parquet"
    truth.to_parquet(path)
    with pytest.raises(InputError, match=r"row 3, column lat: value 95.0 is outside \[-90, 90\]"):
        read_truth(path)


def test_missing_truth_columns(tmp_path):
    path = tmp_path / "truth.csv"
    pd.DataFrame({"time": [0.0], "x": [1.0]}).to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_truth(path)
    assert str(info.value) == (
        f"{path}: missing required truth column(s): target_id, x/y/z or lat/lon/alt_m (found: time, x)"
    )


# --- OpenSky state vectors ---------------------------------------------------------


def _opensky(n: int = 8, step_s: float = 5.0) -> pd.DataFrame:
    """Two aircraft as the traffic library writes them (ft, kt, ft/min, datetimes)."""
    stamps = pd.Timestamp(EPOCH) + pd.to_timedelta(np.arange(n) * step_s, unit="s")
    rows = []
    for icao, lat0, lon0 in (("3C6444", 48.80, 2.40), ("4ca2b1", 49.20, 3.10)):
        rows.append(
            pd.DataFrame(
                {
                    "timestamp": stamps,
                    "icao24": icao,
                    "latitude": lat0 + 0.01 * np.arange(n),
                    "longitude": np.full(n, lon0),
                    "altitude": np.full(n, 30000.0),
                    "geoaltitude": np.full(n, 31000.0),
                    "callsign": "AFR1234 ",
                    "squawk": "0123",
                    "onground": False,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


def test_opensky_conversion_positions_and_columns(tmp_path, sensor_set):
    raw = _opensky()
    path = tmp_path / "opensky.parquet"
    raw.to_parquet(path)
    truth = read_truth(path, sensors=sensor_set)
    assert tuple(truth.columns[: len(TRUTH_COLUMNS)]) == TRUTH_COLUMNS
    assert {"timestamp", "icao24", "callsign", "squawk", "onground", "altitude"} <= set(truth.columns)
    assert "geoaltitude" not in truth.columns and "latitude" not in truth.columns
    assert truth["target_id"].tolist() == ["3c6444"] * 8 + ["4ca2b1"] * 8
    np.testing.assert_allclose(truth["alt_m"], 31000.0 * 0.3048)  # geoaltitude preferred, ft -> m
    np.testing.assert_allclose(truth["time"], np.tile(np.arange(8) * 5.0, 2))
    x, y, z = pymap3d.geodetic2enu(raw["latitude"], raw["longitude"], 31000.0 * 0.3048, *_o())
    np.testing.assert_allclose(truth[["x", "y", "z"]].to_numpy(), np.c_[x, y, z], atol=1e-6)
    assert truth["visible"].all() and (truth["segment"] == 0).all()
    assert truth["squawk"].tolist()[0] == "0123"


def test_opensky_altitude_column_choice(tmp_path, sensor_set):
    raw = _opensky().drop(columns=["geoaltitude"]).rename(columns={"altitude": "altitude_m"})
    path = tmp_path / "o.parquet"
    raw.to_parquet(path)
    np.testing.assert_allclose(read_truth(path, sensors=sensor_set)["alt_m"], 30000.0)  # already metres
    both = tmp_path / "b.parquet"
    _opensky().to_parquet(both)
    forced = read_truth(both, sensors=sensor_set, altitude_column="altitude")
    np.testing.assert_allclose(forced["alt_m"], 30000.0 * 0.3048)


def test_opensky_reported_velocity_is_rotated_into_the_origin_frame(tmp_path, sensor_set):
    """An aircraft 60 km away: the local ENU step of its reported velocity, seen from the origin."""
    raw = _opensky(n=3).iloc[3:6].reset_index(drop=True)  # second aircraft only
    raw["groundspeed"], raw["track"], raw["vertical_rate"] = 450.0, 73.0, -1200.0
    path = tmp_path / "o.parquet"
    raw.to_parquet(path)
    truth = read_truth(path, sensors=sensor_set)
    speed = 450.0 * 1852.0 / 3600.0
    local = np.array([speed * np.sin(np.radians(73.0)), speed * np.cos(np.radians(73.0)), -1200.0 * 0.3048 / 60.0])
    dt = 1e-3
    for i in range(3):
        lat, lon, alt = raw.loc[i, "latitude"], raw.loc[i, "longitude"], 31000.0 * 0.3048
        lat2, lon2, alt2 = pymap3d.enu2geodetic(*(local * dt), lat, lon, alt)
        p1 = np.array(pymap3d.geodetic2enu(lat, lon, alt, *_o()))
        p2 = np.array(pymap3d.geodetic2enu(lat2, lon2, alt2, *_o()))
        np.testing.assert_allclose(
            truth.loc[i, ["vx", "vy", "vz"]].to_numpy(float), (p2 - p1) / dt, rtol=1e-6, atol=1e-6
        )
    assert np.linalg.norm(truth[["vx", "vy", "vz"]].to_numpy(), axis=1) == pytest.approx(
        np.linalg.norm(local), rel=1e-12
    )


def test_opensky_finite_difference_velocity_without_reports(tmp_path, sensor_set):
    t = np.arange(0.0, 60.0, 10.0)
    x, y, z = 5e3 + 200.0 * t, -2e3 + 50.0 * t, 9000.0 - 5.0 * t
    lat, lon, alt = enu_to_geodetic(x, y, z, *_o())
    raw = pd.DataFrame(
        {"time": 1633608000 + t, "icao24": "abc123", "latitude": lat, "longitude": lon, "geoaltitude_m": alt}
    )
    path = tmp_path / "impala.csv"
    raw.to_csv(path, index=False, float_format="%.12f")
    truth = read_truth(path, sensors=sensor_set)  # POSIX seconds in `time`; epoch from sensors.json
    np.testing.assert_allclose(truth["time"], t, atol=1e-6)
    np.testing.assert_allclose(truth[["vx", "vy", "vz"]].to_numpy(), np.tile([200.0, 50.0, -5.0], (6, 1)), atol=1e-4)


def test_opensky_sorting_duplicates_and_segments(tmp_path, sensor_set):
    raw = _opensky(n=8)
    later = raw["timestamp"] >= pd.Timestamp(EPOCH) + pd.Timedelta(seconds=20)
    raw.loc[later, "timestamp"] += pd.Timedelta(seconds=100)  # a 105 s gap in both tracks
    raw = pd.concat([raw, raw.iloc[[2]]]).sample(frac=1.0, random_state=1)  # repeat + shuffle
    path = tmp_path / "o.parquet"
    raw.to_parquet(path)
    truth, report = read_truth(path, sensors=sensor_set, lenient=True)
    assert len(truth) == 16
    assert report.warnings == ["1 row(s) repeat the time of the previous row of the same icao24; first kept"]
    first = truth[truth["target_id"] == "3c6444"]
    assert first["segment"].tolist() == [0] * 4 + [1] * 4
    assert np.all(np.diff(first["time"].to_numpy()) > 0)
    one_segment = read_truth(path, sensors=sensor_set, max_gap_s=200.0, lenient=True)[0]
    assert (one_segment["segment"] == 0).all()
    with pytest.warns(InputWarning, match="repeat the time"):
        read_truth(path, sensors=sensor_set)


def test_opensky_null_position_is_an_error_or_a_counted_skip(tmp_path, sensor_set):
    raw = _opensky()
    raw.loc[5, "latitude"] = np.nan
    raw["latitude"] = raw["latitude"].astype(float)
    path = tmp_path / "o.csv"
    raw.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_truth(path, sensors=sensor_set)
    assert str(info.value) == f"{path}, line 7 (row 5), column latitude: missing value"
    truth, report = read_truth(path, sensors=sensor_set, lenient=True)
    assert report.skipped["latitude missing"].count == 1 and len(truth) == 15


def test_opensky_needs_an_origin(tmp_path):
    path = tmp_path / "o.parquet"
    _opensky().to_parquet(path)
    with pytest.raises(InputError, match="converting OpenSky state vectors needs an origin"):
        read_truth(path)


def test_write_truth_refuses_unsorted_segments(tmp_path):
    truth = make_truth()
    truth.loc[[3, 4], "time"] = truth.loc[[4, 3], "time"].to_numpy()
    with pytest.raises(InputError) as info:
        write_truth(truth, tmp_path / "t.parquet")
    assert str(info.value).startswith(f"truth to write to {tmp_path / 't.parquet'}, row 4, column time:")

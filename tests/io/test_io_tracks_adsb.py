"""Tracks (writer layout, reader checks) and ADS-B reports."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from io_samples import EPOCH, ORIGIN, make_tracks

from skytrack.geo import enu_to_geodetic, geodetic_to_enu
from skytrack.io import (
    ADSB_COLUMNS,
    STRING_DTYPE,
    TRACK_COLUMNS,
    InputError,
    read_adsb,
    read_table,
    read_tracks,
    write_tracks,
)
from skytrack.io.adsb import write_adsb


@pytest.mark.parametrize("name", ["tracks.parquet", "tracks.csv"])
def test_write_tracks_layout_and_round_trip(tmp_path, name):
    tracks = make_tracks()
    tracks = tracks[["cov_0_1"] + [c for c in tracks.columns if c != "cov_0_1"][::-1]]  # scrambled
    path = write_tracks(tracks, tmp_path / "run" / name, origin=ORIGIN)
    assert list(read_table(path).columns) == list(TRACK_COLUMNS) + ["cov_0_1"]
    back = read_tracks(path)
    assert list(back.columns) == list(TRACK_COLUMNS) + ["cov_0_1"]
    assert back["track_id"].dtype == np.int64 and back["n_updates"].dtype == pd.Int64Dtype()
    assert back["status"].dtype == STRING_DTYPE and back["model_probs"].isna().all()
    assert back["cov_0_1"].dtype == np.float64
    for column in ("time", "x", "y", "z", "vx", "vy", "var_x", "cov_0_1"):
        np.testing.assert_array_equal(back[column].to_numpy(), tracks[column].to_numpy())
    assert back["mode3a"].tolist()[0] == "0123" and pd.isna(back["mode3a"][1])
    # lat/lon/alt_m only where z is known (2-D tracks have z null)
    known = np.isfinite(tracks["z"].to_numpy())
    assert back["lat"].isna().to_numpy().tolist() == (~known).tolist()
    x, y, z = geodetic_to_enu(
        back["lat"][known], back["lon"][known], back["alt_m"][known], ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m
    )
    np.testing.assert_allclose(np.c_[x, y, z], tracks.loc[known, ["x", "y", "z"]].to_numpy(), atol=1e-6)


def test_tracks_parquet_types_for_other_tools(tmp_path):
    schema = pq.read_schema(write_tracks(make_tracks(), tmp_path / "tracks.parquet"))
    assert schema.field("time").type == pa.float64()
    assert schema.field("track_id").type == pa.int64()
    assert schema.field("n_updates").type == pa.int64() and schema.field("n_misses").type == pa.int64()
    assert schema.field("z").type == pa.float64() and schema.field("vz").type == pa.float64()
    for name in ("status", "mode3a", "icao24", "callsign", "iff", "model_probs"):
        assert schema.field(name).type in (pa.string(), pa.large_string()), name


def test_minimal_tracks_from_another_tool(tmp_path):
    path = tmp_path / "theirs.csv"
    pd.DataFrame({"track_id": [1, 2], "y": [0.0, 1.0], "x": [5.0, 6.0], "time": [0, 0], "quality": ["a", "b"]}).to_csv(
        path, index=False
    )
    back = read_tracks(path)
    assert list(back.columns) == ["time", "track_id", "x", "y", "quality"]
    assert back["time"].dtype == np.float64


TRACK_BAD = [
    ("track_id", "T1", "track_id not a number", "value 'T1' is not a number"),
    ("track_id", "1.5", "track_id not an integer", "value 1.5 is not an integer"),
    ("track_id", "", "track_id missing", "missing value"),
    ("time", "inf", "time not finite", "value inf is not finite"),
    ("x", "", "x missing", "missing value"),
    ("var_x", "-1", "var_x negative", "value -1.0 is negative"),
    ("status", "lost", "status not one of confirmed, coasting", "value 'lost' is not one of confirmed, coasting"),
    ("n_misses", "-1", "n_misses negative", "value -1.0 is negative"),
    ("iff", "neutral", "iff not one of friend, foe, undetermined", "value 'neutral' is not one of"),
    ("mode3a", "9999", "mode3a not 4 octal digits", "value '9999' is not 4 octal digits"),
    (
        "icao24",
        "zzzzzz",
        "icao24 not a 24-bit hex address (6 hex digits)",
        "value 'zzzzzz' is not a 24-bit hex address",
    ),
]


@pytest.mark.parametrize("column, text, reason, fragment", TRACK_BAD)
def test_malformed_tracks(tmp_path, column, text, reason, fragment):
    tracks = make_tracks().astype({column: object})
    tracks.loc[4, column] = text
    path = tmp_path / "tracks.csv"
    tracks.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_tracks(path)
    error = info.value
    assert (error.file, error.row, error.line, error.column) == (str(path), 4, 6, column)
    assert fragment in error.message
    back, report = read_tracks(path, lenient=True)
    assert report.skipped[reason].count == 1 and len(back) == 5


def test_write_tracks_refuses_bad_rows(tmp_path):
    tracks = make_tracks()
    tracks.loc[2, "var_y"] = -4.0
    with pytest.raises(InputError, match=r"tracks to write to .*, row 2, column var_y: value -4.0 is negative"):
        write_tracks(tracks, tmp_path / "t.parquet")
    with pytest.raises(InputError, match=r"missing required tracks column\(s\): track_id"):
        write_tracks(tracks.drop(columns=["track_id"]), tmp_path / "t.parquet")


# --- ADS-B ------------------------------------------------------------------------------


def _adsb(n: int = 6) -> pd.DataFrame:
    rng = np.random.default_rng(5)
    x, y, z = rng.normal(0, 3e4, n), rng.normal(0, 3e4, n), rng.uniform(1e3, 1e4, n)
    lat, lon, alt = enu_to_geodetic(x, y, z, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    return pd.DataFrame(
        {
            "time": np.arange(n) * 0.5,
            "icao24": ["3C6444", "4ca2b1"] * (n // 2),
            "lat": lat,
            "lon": lon,
            "alt_m": alt,
            "sigma_m": 30.0,
            "callsign": ["AFR1", None] * (n // 2),
            "vx": 200.0,
            "vy": np.nan,
            "nacp": 8,
        }
    ), np.c_[x, y, z]


def test_adsb_geodetic_converted_with_origin(tmp_path, sensor_set):
    reports, enu = _adsb()
    path = tmp_path / "adsb.csv"
    reports.to_csv(path, index=False)
    back = read_adsb(path, sensors=sensor_set)
    assert list(back.columns) == [c for c in ADSB_COLUMNS if c not in ("vz",)] + ["nacp"]
    np.testing.assert_allclose(back[["x", "y", "z"]].to_numpy(), enu, atol=1e-6)
    assert back["icao24"].tolist()[:2] == ["3c6444", "4ca2b1"]
    assert back["vy"].isna().all()
    with pytest.raises(InputError, match="adsb positions are given as lat/lon/alt_m only: an origin"):
        read_adsb(path)


@pytest.mark.parametrize("name", ["adsb.parquet", "adsb.csv.gz"])
def test_adsb_round_trip_enu(tmp_path, name):
    reports, enu = _adsb()
    reports = reports.drop(columns=["lat", "lon", "alt_m"]).assign(x=enu[:, 0], y=enu[:, 1], z=enu[:, 2])
    back = read_adsb(write_adsb(reports, tmp_path / name))
    np.testing.assert_array_equal(back[["x", "y", "z"]].to_numpy(), enu)
    assert list(back.columns[:5]) == ["time", "icao24", "x", "y", "z"]


def test_adsb_timestamp_column(tmp_path, sensor_set):
    reports, _ = _adsb()
    reports = reports.drop(columns=["time"])
    reports.insert(0, "timestamp", pd.Timestamp(EPOCH) + pd.to_timedelta(np.arange(6) * 0.5, unit="s"))
    path = tmp_path / "adsb.parquet"
    reports.to_parquet(path)
    np.testing.assert_allclose(read_adsb(path, sensors=sensor_set)["time"], np.arange(6) * 0.5)


ADSB_BAD = [
    ("icao24", "xyz", "icao24 not a 24-bit hex address (6 hex digits)", "value 'xyz' is not a 24-bit hex address"),
    ("icao24", "", "icao24 missing", "missing value"),
    ("sigma_m", "0", "sigma_m not > 0", "value 0.0 is not > 0"),
    ("vx", "inf", "vx not finite", "value inf is not finite"),
    ("time", "", "time missing", "missing value"),
    ("lat", "91", "lat outside [-90, 90]", "value 91.0 is outside [-90, 90]"),
    ("alt_m", "", "alt_m missing", "missing value"),
]


@pytest.mark.parametrize("column, text, reason, fragment", ADSB_BAD)
def test_malformed_adsb(tmp_path, sensor_set, column, text, reason, fragment):
    reports, _ = _adsb()
    reports = reports.astype({column: object})
    reports.loc[3, column] = text
    path = tmp_path / "adsb.csv"
    reports.to_csv(path, index=False)
    with pytest.raises(InputError) as info:
        read_adsb(path, sensors=sensor_set)
    assert (info.value.row, info.value.line, info.value.column) == (3, 5, column)
    assert fragment in info.value.message
    back, report = read_adsb(path, sensors=sensor_set, lenient=True)
    assert report.skipped[reason].count == 1 and len(back) == 5

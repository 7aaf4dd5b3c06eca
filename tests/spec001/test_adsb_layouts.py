"""Issue 9 item 1: the ADS-B input layouts of skytrack.io.read_adsb (FORMATS.md with NACp,
the OpenSky database's and the traffic library's state vectors) and where they put the
reports' errors (spec 001 (1): V_η = sigma_m² I per horizontal axis)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.io import InputError, read_adsb, write_adsb
from skytrack.io.adsb import EPU95_PER_SIGMA, NACP_EPU_M, adsb_layout, nacp_sigma_m
from skytrack.io.frames import FT_PER_MIN_TO_MPS, FT_TO_M, KNOT_TO_MPS
from skytrack.sim.adsb import simulate_adsb
from skytrack.sim.earth import local_axes
from skytrack.sim.spec import AdsbAircraftSpec, AdsbSpec

ORIGIN = Origin(46.80, 8.20, 0.0)
EPOCH = "2018-08-01T11:20:00Z"
EPOCH_POSIX = (pd.Timestamp(EPOCH) - pd.Timestamp("1970-01-01", tz="UTC")) / pd.Timedelta(seconds=1)


def sensors() -> SensorSet:
    return SensorSet(origin=ORIGIN, sensors=[], epoch_utc=EPOCH)


def simulated_reports() -> pd.DataFrame:
    """Reports of three aircraft up to 150 km from the origin, climbing and turning."""
    t = np.arange(0.0, 61.0)
    rows = []
    for k, (x0, y0, vx, vy, climb) in enumerate([(-150e3, 20e3, 200.0, 50.0, 5.0), (80e3, -60e3, -120.0, 180.0, -8.0),
                                                 (10e3, 120e3, 0.0, -230.0, 0.0)]):
        rows.append(pd.DataFrame({"time": t, "target_id": f"A{k}", "x": x0 + vx * t, "y": y0 + vy * t,
                                  "alt_m": 9000.0 + climb * t, "vx": vx, "vy": vy, "vz": climb}))
    truth = pd.concat(rows, ignore_index=True)
    aircraft = pd.DataFrame({"target_id": ["A0", "A1", "A2"], "icao24": ["4b1805", "3c6592", "400e4a"],
                             "callsign": ["SWR12", "DLH4A", None]})
    return simulate_adsb(truth, AdsbSpec(p_drop=0.1), np.random.default_rng(4), origin=ORIGIN, aircraft=aircraft,
                         settings={"A2": AdsbAircraftSpec(no_callsign=True)}).reports


def as_state_vectors(reports: pd.DataFrame, layout: str) -> pd.DataFrame:
    """The reports in the OpenSky database's or the traffic library's layout: speed, course
    and climb in each aircraft's own ENU frame."""
    east, north, up = local_axes(reports["lat"].to_numpy(), reports["lon"].to_numpy(), ORIGIN)
    velocity = reports[["vx", "vy", "vz"]].to_numpy()
    ve, vn, vu = (np.sum(velocity * axis, axis=1) for axis in (east, north, up))
    speed, course = np.hypot(ve, vn), np.degrees(np.arctan2(ve, vn)) % 360.0
    posix = EPOCH_POSIX + reports["time"].to_numpy()
    if layout == "opensky":
        return pd.DataFrame({"time": posix, "icao24": reports["icao24"], "lat": reports["lat"], "lon": reports["lon"],
                             "velocity": speed, "heading": course, "vertrate": vu, "callsign": reports["callsign"],
                             "baroaltitude": reports["alt_m"] + 50.0, "geoaltitude": reports["alt_m"],
                             "lastposupdate": posix - 0.3})
    stamps = pd.to_datetime(posix, unit="s", utc=True)
    return pd.DataFrame({"timestamp": stamps, "icao24": reports["icao24"], "latitude": reports["lat"],
                         "longitude": reports["lon"], "geoaltitude": reports["alt_m"] / FT_TO_M,
                         "groundspeed": speed / KNOT_TO_MPS, "track": course, "vertical_rate": vu / FT_PER_MIN_TO_MPS,
                         "callsign": reports["callsign"]})


# ---------------------------------------------------------------------------- NACp


def test_nacp_sigma_is_the_95_percent_radius_of_a_circular_gaussian():
    # the radius holding 95 % of a circular Gaussian is the Rayleigh quantile sqrt(chi2_2(0.95)) sigma
    assert EPU95_PER_SIGMA == pytest.approx(math.sqrt(stats.chi2.ppf(0.95, 2)), rel=1e-12)
    assert EPU95_PER_SIGMA == pytest.approx(2.4477468306808, rel=1e-12)
    sigma = nacp_sigma_m(np.arange(12))
    assert np.isnan(sigma[0])
    for level, epu in NACP_EPU_M.items():
        assert sigma[level] == pytest.approx(epu / 2.4477468306808, rel=1e-12)
        # a draw of that sigma falls inside the EPU with probability 0.95
        assert stats.rayleigh.cdf(epu / sigma[level]) == pytest.approx(0.95, rel=1e-12)
    assert sigma[9] == pytest.approx(12.25617, abs=1e-5) and sigma[10] == pytest.approx(4.08539, abs=1e-5)
    assert NACP_EPU_M[7] == pytest.approx(0.1 * 1852.0) and NACP_EPU_M[1] == pytest.approx(10 * 1852.0)


def test_nacp_gives_sigma_m_where_it_is_missing(tmp_path):
    path = tmp_path / "adsb.csv"
    path.write_text(
        "time,icao24,x,y,z,sigma_m,nacp\n"
        "0,4b1805,1,2,3,,9\n"
        "1,4b1805,1,2,3,25,9\n"
        "2,4b1805,1,2,3,,0\n"
        "3,4b1805,1,2,3,,\n"
    )
    adsb = read_adsb(path)
    np.testing.assert_allclose(adsb["sigma_m"].to_numpy()[:2], [30.0 / EPU95_PER_SIGMA, 25.0])
    assert adsb["sigma_m"].isna().to_numpy()[2:].all() and adsb.attrs["layout"] == "adsb"
    filled = read_adsb(path, default_sigma_m=50.0)
    np.testing.assert_allclose(filled["sigma_m"], [30.0 / EPU95_PER_SIGMA, 25.0, 50.0, 50.0])
    # without a sigma_m column, the NACp one creates it
    pd.DataFrame({"time": [0.0], "icao24": ["abcdef"], "x": [0.0], "y": [0.0], "z": [0.0], "nacp": [11]}).to_parquet(
        tmp_path / "n.parquet")
    assert read_adsb(tmp_path / "n.parquet")["sigma_m"].iloc[0] == pytest.approx(3.0 / EPU95_PER_SIGMA)


@pytest.mark.parametrize("value", ["12", "2.5", "-1", "high"])
def test_a_bad_nacp_is_an_error_naming_row_and_column(tmp_path, value):
    path = tmp_path / "adsb.csv"
    path.write_text(f"time,icao24,x,y,z,nacp\n0,4b1805,1,2,3,8\n1,4b1805,1,2,3,{value}\n")
    with pytest.raises(InputError) as error:
        read_adsb(path)
    assert (error.value.row, error.value.line, error.value.column) == (1, 3, "nacp")
    adsb, report = read_adsb(path, lenient=True)
    assert len(adsb) == 1 and report.rows_skipped == 1


def test_simulated_reports_round_trip_with_truth_id(tmp_path):
    reports = simulated_reports()
    reports.loc[reports.index[:5], "truth_id"] = "007"
    for name in ("adsb.parquet", "adsb.csv"):
        write_adsb(reports, tmp_path / name, origin=ORIGIN)
        back = read_adsb(tmp_path / name, sensors=sensors())
        assert list(back.columns[-1:]) == ["truth_id"] and back["truth_id"].iloc[0] == "007"
        for column in ("time", "x", "y", "z", "sigma_m", "vx", "vy", "vz"):
            np.testing.assert_allclose(back[column], reports[column], rtol=0, atol=1e-9)
        assert back["callsign"].isna().sum() == reports["callsign"].isna().sum() > 0


# ---------------------------------------------------------------------------- state vectors


@pytest.mark.parametrize(("layout", "suffix"), [("opensky", "csv"), ("opensky", "parquet"), ("traffic", "parquet"),
                                                ("traffic", "jsonl")])
def test_state_vector_layouts_round_trip_to_the_reports(tmp_path, layout, suffix):
    reports = simulated_reports()
    states = as_state_vectors(reports, layout)
    path = tmp_path / f"states.{suffix}"
    if suffix == "csv":
        states.to_csv(path, index=False)
    elif suffix == "parquet":
        states.to_parquet(path)
    else:
        states.assign(timestamp=states["timestamp"].map(lambda s: s.isoformat())).to_json(path, orient="records", lines=True)
    back = read_adsb(path, sensors=sensors())
    assert back.attrs["layout"] == layout and len(back) == len(reports)
    np.testing.assert_allclose(back["time"], reports["time"], atol=1e-5)
    np.testing.assert_allclose(back[["x", "y", "z"]], reports[["x", "y", "z"]], atol=1e-3)  # mm after ft/kt in text
    np.testing.assert_allclose(back[["vx", "vy", "vz"]], reports[["vx", "vy", "vz"]], atol=1e-6)
    np.testing.assert_array_equal(back["icao24"], reports["icao24"])
    assert back["sigma_m"].isna().all()
    assert read_adsb(path, sensors=sensors(), default_sigma_m=30.0)["sigma_m"].eq(30.0).all()


def test_layouts_are_told_apart_by_column_names():
    assert adsb_layout(["time", "icao24", "x", "y", "z"]) == "adsb"
    assert adsb_layout(["time", "icao24", "lat", "lon", "alt_m", "geoaltitude"]) == "adsb"
    assert adsb_layout(["time", "icao24", "lat", "lon", "baroaltitude", "velocity"]) == "opensky"
    assert adsb_layout(["timestamp", "icao24", "latitude", "longitude", "altitude"]) == "traffic"


def test_a_state_vector_without_position_is_reported_with_its_row(tmp_path):
    reports = simulated_reports().iloc[:10]
    states = as_state_vectors(reports, "opensky")
    states.loc[3, "lat"] = np.nan
    states.loc[7, "geoaltitude"] = np.nan
    path = tmp_path / "states.csv"
    states.to_csv(path, index=False)
    with pytest.raises(InputError) as error:
        read_adsb(path, sensors=sensors())
    assert (error.value.row, error.value.line) == (3, 5)
    assert "no position" in str(error.value) and "1 more bad row" in str(error.value)
    adsb, report = read_adsb(path, sensors=sensors(), lenient=True)
    assert len(adsb) == 8 and (report.rows_read, report.rows_kept) == (10, 8)
    skipped = report.skipped["no position"]
    assert skipped.count == 2 and [e.row for e in skipped.examples] == [3, 7] and skipped.examples[0].line == 5
    np.testing.assert_allclose(adsb["time"], np.delete(reports["time"].to_numpy(), [3, 7]), atol=1e-5)


def test_state_vectors_need_an_origin_and_time_counts_from_the_epoch(tmp_path):
    path = tmp_path / "states.parquet"
    as_state_vectors(simulated_reports().iloc[:5], "opensky").to_parquet(path)
    with pytest.raises(InputError, match="needs an origin"):
        read_adsb(path)
    with pytest.warns(UserWarning, match="no epoch_utc known"):
        adsb = read_adsb(path, origin=ORIGIN)
    assert adsb["time"].iloc[0] == 0.0
    shifted = read_adsb(path, origin=ORIGIN, epoch_utc="2018-08-01T11:19:00Z")
    np.testing.assert_allclose(shifted["time"], adsb["time"] + 60.0 + simulated_reports()["time"].iloc[0], atol=1e-6)

"""The simulated ASTERIX recording (issue 11 item 2): numpy-assembled CAT048/CAT034 records byte for byte
libasterix's (``encode_asterix``), time order over CAT034/048/021, SAC/SIC assignment, north markers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.io.asterix import encode_asterix
from skytrack.io.asterix.cat062 import blocks_from_records
from skytrack.io.asterix.recording import (
    DEFAULT_ADSB_STATION,
    adsb_station,
    encode_recording,
    north_markers,
    plot_record_bytes,
    with_sac_sic,
)


def random_plots(n: int, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    codes = np.array(["7000", "0017", None], dtype=object)
    addresses = np.array(["abc123", None, None], dtype=object)
    return pd.DataFrame({
        "time": np.round(np.sort(rng.uniform(0, 60, n)), 1),  # ties: several plots at one time
        "sensor": np.array(["west", "east"], dtype=object)[rng.integers(0, 2, n)],
        "range_m": rng.uniform(0, 470_000, n), "azimuth_deg": rng.uniform(0, 360, n),
        "mode3a": codes[rng.integers(0, 3, n)], "mode_c_ft": np.where(rng.random(n) < 0.6, rng.uniform(-1000, 40_000, n),
                                                                        np.nan),
        "mode_s": addresses[rng.integers(0, 3, n)],
    })


SAC_SIC = {"west": (3, 1), "east": (3, 2)}


@pytest.mark.parametrize("seed", [1, 2])
def test_numpy_cat048_cat034_records_are_libasterix_bytes(seed):
    plots = random_plots(300, seed)
    markers = pd.DataFrame({"time": np.arange(0.0, 60.0, 4.0), "sensor": "west", "message": "north_marker"})
    markers.loc[3, "time"] = plots["time"].iloc[10]  # a marker at a plot's time comes first
    settings = {"time_of_day_at_epoch_s": 86_380.0}
    ours = encode_recording(plots, SAC_SIC, service=markers, **settings)
    assert ours == encode_asterix(plots, SAC_SIC, service=markers, **settings)
    ssr_only = blocks_from_records(*plot_record_bytes(plots, SAC_SIC, ssr_only_sensors={"east"}), 128, 48)
    assert ssr_only == encode_asterix(plots, SAC_SIC, ssr_only_sensors={"east"})


def test_records_of_three_categories_are_written_in_time_order():
    plots = pd.DataFrame({"time": [1.0, 3.0], "sensor": "west", "range_m": [1000.0, 2000.0], "azimuth_deg": [10.0, 20.0]})
    markers = pd.DataFrame({"time": [1.0], "sensor": ["west"], "message": ["north_marker"]})
    adsb = pd.DataFrame({"time": [0.5, 1.0, 2.0], "icao24": ["abc123"] * 3, "lat": [48.0] * 3, "lon": [2.0] * 3,
                         "alt_m": [3000.0] * 3})
    data = encode_recording(plots, SAC_SIC, service=markers, adsb=adsb, adsb_sac_sic=(0, 101))
    categories, offset = [], 0
    while offset < len(data):
        categories.append(data[offset])
        offset += int.from_bytes(data[offset + 1:offset + 3], "big")
    assert offset == len(data)
    assert categories == [21, 34, 48, 21, 48]  # 0.5 | 1.0: CAT034, CAT048, then CAT021 at 1.0 and 2.0 in one block | 3.0


def test_a_plot_the_item_cannot_hold_is_named():
    plots = random_plots(5, 3)
    plots.loc[2, "range_m"] = 500_000.0
    with pytest.raises(ValueError, match="plots: row 2, column range_m"):
        plot_record_bytes(plots, SAC_SIC)
    with pytest.raises(ValueError, match="no SAC/SIC for sensor"):
        plot_record_bytes(random_plots(5, 3), {"west": (3, 1)})


def _radar(name: str, **kwargs) -> Sensor:
    return Sensor(name=name, type="radar-2d", x=0.0, y=0.0, z=0.0, scan_period_s=4.0, scan_phase_s=1.5,
                  sigma_range_m=40.0, sigma_azimuth_deg=0.1, **kwargs)


def test_sac_sic_are_assigned_in_sensor_order_around_the_given_ones():
    given = {"sac": 0, "sic": 1} if "sac" in Sensor.__dataclass_fields__ else {"extra": {"sac": 0, "sic": 1}}
    sensors = SensorSet(Origin(48.0, 2.0), [_radar("a"), _radar("b", **given), _radar("c")])
    assigned, pairs = with_sac_sic(sensors, adsb=True)
    assert pairs == {"a": (0, 2), "b": (0, 1), "c": (0, 3)}
    assert adsb_station(assigned) == DEFAULT_ADSB_STATION
    assert "adsb_station" not in with_sac_sic(sensors)[0].extra


def test_one_north_marker_per_revolution():
    sensors = SensorSet(Origin(48.0, 2.0), [_radar("a")])
    times = north_markers(sensors, 0.0, 20.0)["time"].tolist()
    assert times == [1.5, 5.5, 9.5, 13.5, 17.5]

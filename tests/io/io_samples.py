"""Shared builders of the skytrack.io tests: a sensor set and small valid tables."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.geo import Origin, Sensor, SensorSet

ORIGIN = Origin(lat=48.86, lon=2.50, alt_m=0.0)
EPOCH = "2021-10-07T12:00:00Z"


@pytest.fixture
def sensor_set() -> SensorSet:
    return SensorSet(
        origin=ORIGIN,
        epoch_utc=EPOCH,
        sensors=[
            Sensor(
                name="radar1",
                lat=48.86,
                lon=2.50,
                alt_m=0.0,
                scan_period_s=4.0,
                sigma_range_m=40.0,
                sigma_azimuth_deg=0.07,
                max_range_m=250e3,
                p_detection=0.9,
                clutter_per_scan=20.0,
            ),
            Sensor(
                name="radar2",
                type="radar-3d",
                x=30e3,
                y=1e3,
                z=0.0,
                north_offset_deg=0.0,
                scan_period_s=10.0,
                sigma_range_m=50.0,
                sigma_azimuth_deg=0.1,
                sigma_elevation_deg=0.2,
                extra={"vendor": "acme", "platform": {"file": "carrier.parquet"}},
            ),
        ],
    )


def make_plots(n: int = 12, seed: int = 0) -> pd.DataFrame:
    """Valid plots of two sensors with every FORMATS column, time sorted per sensor."""
    rng = np.random.default_rng(seed)
    time = np.sort(rng.uniform(0.0, 100.0, n))
    sensor = np.where(np.arange(n) % 3 == 0, "radar2", "radar1")
    is_3d = sensor == "radar2"
    return pd.DataFrame(
        {
            "time": time,
            "sensor": sensor,
            "range_m": rng.uniform(0.0, 200e3, n),
            "azimuth_deg": rng.uniform(0.0, 360.0, n),
            "scan": (time // 4.0).astype(np.int64),
            "elevation_deg": np.where(is_3d, rng.uniform(-2.0, 30.0, n), np.nan),
            "range_rate_mps": rng.normal(0.0, 100.0, n),
            "mode3a": np.array(["0123", "7000", None, "0001"] * (n // 4 + 1), dtype=object)[:n],
            "mode_c_ft": np.where(np.arange(n) % 4 == 2, np.nan, rng.uniform(0.0, 40e3, n)),
            "mode_s": np.array(["3c6444", None, "4ca2b1"] * (n // 3 + 1), dtype=object)[:n],
            "iff": np.array(["friend", "foe", "undetermined", None] * (n // 4 + 1), dtype=object)[:n],
            "truth_id": np.array(["a", "", "b"] * (n // 3 + 1), dtype=object)[:n],
        }
    )


def make_truth(seed: int = 0) -> pd.DataFrame:
    """Two targets in straight flight, one with two segments."""
    t = np.arange(0.0, 20.0, 2.0)
    rows = []
    for target, segment, x0, v in (("a", 0, 0.0, 200.0), ("a", 1, 10e3, 150.0), ("b", 0, -5e3, -80.0)):
        start = 100.0 * segment
        rows.append(
            pd.DataFrame(
                {
                    "time": start + t,
                    "target_id": target,
                    "segment": segment,
                    "x": x0 + v * t,
                    "y": 2e3 + 0.5 * v * t,
                    "z": np.full(t.size, 3000.0),
                    "vx": np.full(t.size, v),
                    "vy": np.full(t.size, 0.5 * v),
                    "vz": np.zeros(t.size),
                    "visible": t < 15.0,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


def make_tracks(n: int = 6) -> pd.DataFrame:
    rng = np.random.default_rng(3)
    return pd.DataFrame(
        {
            "time": np.repeat(np.arange(n // 2) * 4.0, 2),
            "track_id": np.tile([7, 9], n // 2),
            "x": rng.normal(0, 1e4, n),
            "y": rng.normal(0, 1e4, n),
            "z": np.where(np.arange(n) % 2 == 0, np.nan, 3000.0),
            "vx": rng.normal(0, 100, n),
            "vy": rng.normal(0, 100, n),
            "vz": np.zeros(n),
            "var_x": np.full(n, 100.0),
            "var_y": np.full(n, 120.0),
            "status": np.tile(["confirmed", "coasting"], n // 2),
            "n_updates": np.arange(n),
            "n_misses": np.tile([0, 1], n // 2),
            "mode3a": np.tile(["0123", None], n // 2),
            "icao24": np.tile(["3c6444", None], n // 2),
            "iff": np.tile(["friend", None], n // 2),
            "cov_0_1": rng.normal(0, 10, n),
        }
    )


def split_blocks(data: bytes) -> list[bytes]:
    """ASTERIX bytes cut into their data blocks (by each block's LEN)."""
    blocks, p = [], 0
    while p < len(data):
        n = int.from_bytes(data[p + 1:p + 3], "big")
        blocks.append(data[p:p + n])
        p += n
    return blocks

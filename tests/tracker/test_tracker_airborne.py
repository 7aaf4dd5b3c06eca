"""An airborne (moving) radar: plots carry the platform position and velocity per row.

Without an antenna schedule a plot is due once per scan period since a track's last hit
or miss, so clutter-born tentative tracks still end and lost tracks are still deleted.
"""

import numpy as np
import pandas as pd

from skytrack.geo.polar import cartesian_to_polar
from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.tracker import Tracker, TrackerConfig

PERIOD = 2.0
FT = 0.3048


def airborne_plots(rng, n_scans=60, clutter_per_scan=3, stop_after=None):
    """A target at 8 km height seen from a platform flying east at 9 km, plus clutter."""
    sensors = SensorSet(
        Origin(45.0, 5.0, 0.0),
        [Sensor("awacs", type="radar-airborne", scan_period_s=PERIOD, sigma_range_m=30.0, sigma_azimuth_deg=0.1)],
    )
    rows = []
    for k in range(n_scans):
        t = k * PERIOD + 0.3
        platform = np.array([-20000.0 + 200.0 * t, 0.0, 9000.0])
        target = np.array([30000.0 - 150.0 * t, 40000.0 + 50.0 * t, 8000.0])
        rel = target - platform
        r, az, _ = cartesian_to_polar(*rel)
        if stop_after is None or k < stop_after:
            rows.append((t, float(r + rng.normal(0, 30.0)), float(np.degrees(az + rng.normal(0, np.radians(0.1))) % 360),
                         8000.0 / FT, *platform, 200.0, 0.0, 0.0, "T"))
        for _ in range(rng.poisson(clutter_per_scan)):
            rows.append((t + 0.01, float(rng.uniform(20e3, 150e3)), float(rng.uniform(0, 360)), np.nan,
                         *platform, 200.0, 0.0, 0.0, ""))
    columns = ["time", "range_m", "azimuth_deg", "mode_c_ft", "platform_x", "platform_y", "platform_z",
               "platform_vx", "platform_vy", "platform_vz", "truth_id"]
    plots = pd.DataFrame(rows, columns=columns)
    plots["sensor"] = "awacs"
    return plots, sensors


def test_airborne_radar_tracks_with_the_platform_position():
    plots, sensors = airborne_plots(np.random.default_rng(5))
    tracker = Tracker(sensors, TrackerConfig())
    tracks = tracker.run(plots)
    assert tracks["track_id"].nunique() == 1
    late = tracks[tracks["time"] > 40.0]
    truth_x = 30000.0 - 150.0 * late["time"]
    truth_y = 40000.0 + 50.0 * late["time"]
    error = np.hypot(late["x"] - truth_x, late["y"] - truth_y)
    # sigma_az 0.1 deg at ~55 km is ~96 m cross-range; the filtered error stays well below
    assert np.sqrt(np.mean(error**2)) < 100.0
    # clutter-born tentative tracks end although the radar has no rotation schedule
    assert tracker.stats["tentative_dropped"] > 0.8 * tracker.stats["tracks_started"] - 5


def test_airborne_track_is_deleted_after_the_target_is_lost():
    # clutter keeps plots (and so time) coming after the target is no longer seen
    plots, sensors = airborne_plots(np.random.default_rng(6), clutter_per_scan=2, stop_after=30)
    tracker = Tracker(sensors, TrackerConfig(delete_misses=5))
    tracks = tracker.run(plots)
    target_track = tracks[tracks["time"] < 50.0]["track_id"].mode()[0]
    last_report = tracks.loc[tracks["track_id"] == target_track, "time"].max()
    last_plot = 29 * PERIOD + 0.3
    # five revisit intervals without a plot delete the track, no later than that
    assert last_plot < last_report <= last_plot + 5 * PERIOD + 1.0
    assert tracker.stats["tracks_deleted"] >= 1

"""Tracker input/output contract: FORMATS.md tracks columns, input errors, streaming,
beam phase, several radars (skytrack.tracker.tracker, skytrack.tracker.plots)."""

import numpy as np
import pandas as pd
import pymap3d
import pytest

from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.tracker import Tracker

# FORMATS.md, "tracks — tracker output", in order
FORMATS_TRACK_COLUMNS = [
    "time", "track_id", "x", "y", "z", "vx", "vy", "vz",
    "var_x", "var_y", "var_z", "var_vx", "var_vy", "var_vz",
    "lat", "lon", "alt_m", "status", "n_updates", "n_misses",
    "mode3a", "icao24", "callsign", "iff", "identity_source", "identity_p", "model_probs",
]


@pytest.fixture
def targets(sim):
    return [sim.Target("a", (30000.0, 40000.0, 8000.0), (150.0, -100.0, 0.0)),
            sim.Target("b", (-40000.0, 20000.0, 10000.0), (0.0, -200.0, 0.0))]


@pytest.fixture
def radar2(sim):
    """A second 2-D radar 31.6 km from the origin, 5 s scans with phase 1.3 s."""
    lat, lon, _ = pymap3d.enu2geodetic(30000.0, -10000.0, 0.0, sim.ORIGIN.lat, sim.ORIGIN.lon, sim.ORIGIN.alt_m)
    return sim.Radar("radar2", float(lat), float(lon), 50.0, period=5.0, phase=1.3,
                     sigma_range_m=60.0, sigma_azimuth_deg=0.1)


# ----------------------------------------------------------------------------- output columns


def test_track_columns_are_exactly_formats_columns_in_order(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 60.0, np.random.default_rng(1))
    tracks = Tracker(sim.sensor_set([radar1])).run(plots)
    assert len(tracks) > 0
    assert list(tracks.columns) == FORMATS_TRACK_COLUMNS
    for column in ("track_id", "n_updates", "n_misses"):
        assert tracks[column].dtype == np.int64, column
    for column in ("time", "x", "y", "vx", "vy", "var_x", "var_vy", "lat", "lon", "alt_m"):
        assert tracks[column].dtype == np.float64, column
    assert set(tracks["status"]) <= {"confirmed", "coasting"}
    # 2-D tracking: z, vz and their variances are null
    for column in ("z", "vz", "var_z", "var_vz"):
        assert tracks[column].isna().all(), column
    assert (tracks[["var_x", "var_y", "var_vx", "var_vy"]] > 0).all().all()


def test_full_covariance_columns_follow_the_formats_columns(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 60.0, np.random.default_rng(1))
    tracks = Tracker(sim.sensor_set([radar1]), TrackerConfig(model="cv", full_covariance=True)).run(plots)
    cov = [f"cov_{i}_{j}" for i in range(4) for j in range(i, 4)]
    assert list(tracks.columns) == FORMATS_TRACK_COLUMNS + cov
    # the diagonal columns repeat the var_ columns (state order x, vx, y, vy)
    np.testing.assert_array_equal(tracks["cov_0_0"], tracks["var_x"])
    np.testing.assert_array_equal(tracks["cov_1_1"], tracks["var_vx"])
    np.testing.assert_array_equal(tracks["cov_2_2"], tracks["var_y"])
    np.testing.assert_array_equal(tracks["cov_3_3"], tracks["var_vy"])


def test_no_track_gives_an_empty_table_with_the_formats_columns(sim, radar1):
    plots = sim.radar_plots(radar1, [sim.Target("a", (30000.0, 40000.0, 8000.0), (150.0, 0.0, 0.0))],
                            0.0, 4.0, np.random.default_rng(1))  # one plot: never confirmed
    tracks = Tracker(sim.sensor_set([radar1])).run(plots)
    assert len(tracks) == 0
    assert list(tracks.columns) == FORMATS_TRACK_COLUMNS
    assert tracks["track_id"].dtype == np.int64


def test_empty_table_has_the_same_dtypes_as_a_full_one(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 60.0, np.random.default_rng(1))
    full = Tracker(sim.sensor_set([radar1])).run(plots)
    empty = Tracker(sim.sensor_set([radar1])).run(plots.iloc[:2])
    assert len(empty) == 0 and len(full) > 0
    assert empty.dtypes.to_dict() == full.dtypes.to_dict()


# ----------------------------------------------------------------------------- input errors


def test_unknown_sensor_names_row_and_column(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    plots.loc[6, "sensor"] = "radarX"
    with pytest.raises(ValueError, match=r"row 6, column sensor: unknown sensor 'radarX' \(sensors.json has: radar1\)"):
        Tracker(sim.sensor_set([radar1])).run(plots)


def test_time_going_backwards_names_row_and_column(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    plots.loc[7, "time"] = plots.loc[6, "time"] - 1.0
    with pytest.raises(ValueError, match=r"row 7, column time: time goes backwards for sensor 'radar1'"):
        Tracker(sim.sensor_set([radar1])).run(plots)


def test_time_going_backwards_across_chunks_is_caught(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    tracker = Tracker(sim.sensor_set([radar1]))
    tracker.feed(plots.iloc[:10])
    with pytest.raises(ValueError, match="column time: time goes backwards"):
        tracker.feed(plots.iloc[3:6])


@pytest.mark.parametrize("column, value, message", [
    ("sensor", "radarX", "row 6, column sensor"),
    ("time", -5.0, "row 6, column time"),
    ("range_m", np.nan, "row 6, column range_m"),
])
def test_error_rows_are_rows_of_the_whole_table(sim, radar1, targets, column, value, message):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    plots.loc[6, column] = value
    with pytest.raises(ValueError, match=message):
        Tracker(sim.sensor_set([radar1])).run(plots, chunk_rows=4)


@pytest.mark.parametrize("column", ["range_m", "azimuth_deg", "time"])
def test_non_finite_required_value_names_row_and_column(sim, radar1, targets, column):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    plots.loc[5, column] = np.nan
    with pytest.raises(ValueError, match=f"row 5, column {column}: value is not a finite number"):
        Tracker(sim.sensor_set([radar1])).run(plots)


def test_missing_required_column_is_named(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    with pytest.raises(ValueError, match=r"missing required column\(s\) \['azimuth_deg'\]"):
        Tracker(sim.sensor_set([radar1])).run(plots.drop(columns=["azimuth_deg"]))


def test_extra_columns_are_ignored(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 60.0, np.random.default_rng(1))
    reference = Tracker(sim.sensor_set([radar1])).run(plots)
    plots["my_extra"] = "anything"
    pd.testing.assert_frame_equal(Tracker(sim.sensor_set([radar1])).run(plots), reference)


# ----------------------------------------------------------------------------- streaming


def feed_in_chunks(sensors, plots, cuts, config=None):
    tracker = Tracker(sensors, config)
    parts = []
    for rows in np.split(np.arange(len(plots)), cuts):
        tracker.feed(plots.iloc[rows])
        parts.append(tracker.drain())
    tracker.finish()
    parts.append(tracker.drain())
    return pd.concat([p for p in parts if len(p)], ignore_index=True)


@pytest.mark.parametrize("seed", range(4))
def test_streaming_random_chunks_equals_run(sim, radar1, seed):
    rng = np.random.default_rng(10)
    targets = sim.ring_targets(rng, 12)
    plots = sim.merge_plots([sim.radar_plots(radar1, targets, 0.0, 100.0, rng, p_detection=0.85),
                             sim.isolated_clutter(radar1, 0.0, 100.0, 3, rng)])
    sensors = sim.sensor_set([radar1])
    reference = Tracker(sensors).run(plots)
    split_rng = np.random.default_rng(seed)
    n_cuts = [3, 20, 80, len(plots) - 1][seed]
    cuts = np.sort(split_rng.choice(np.arange(1, len(plots)), size=n_cuts, replace=False))
    streamed = feed_in_chunks(sensors, plots, cuts)
    assert len(reference) > 100
    # plots are converted per chunk and lat/lon per drain, vectorised over arrays whose length
    # depends on the chunking: the same operations, rounded alike to 1e-12
    pd.testing.assert_frame_equal(streamed, reference, check_exact=False, rtol=1e-12, atol=1e-9)


def test_drain_returns_rows_once(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 60.0, np.random.default_rng(1))
    tracker = Tracker(sim.sensor_set([radar1]))
    tracks = tracker.run(plots)
    assert len(tracks) > 0 and len(tracker.drain()) == 0


def polar_point(centre, azimuth_deg, distance):
    a = np.radians(azimuth_deg)
    return (centre[0] + distance * np.sin(a), centre[1] + distance * np.cos(a), 8000.0)


def test_streaming_two_radars_one_plot_at_a_time_equals_run(sim, radar1, radar2):
    """With 8 sectors per scan, radar1 windows are [0.5 k, 0.5 k + 0.5) and radar2 windows
    [1.3 + 0.625 j, ...): radar2's
    window [16.925, 17.55) starts before radar1's [17.0, 17.5) and ends after it.  Targets B
    (radar2 azimuth 88 deg) and C (radar1 azimuth 46.5 deg) give plots in [17.5, 17.55), so
    feeding plot by plot completes radar1's window first; run() processes radar2's first."""
    r2 = (30000.0, -10000.0)
    targets = [sim.Target("A", polar_point(r2, 47.0, 40000.0), (5.0, 0.0, 0.0)),
               sim.Target("B", polar_point(r2, 88.0, 50000.0), (0.0, 5.0, 0.0)),
               sim.Target("C", polar_point((0.0, 0.0), 46.5, 50000.0), (0.0, 5.0, 0.0))]
    rng = np.random.default_rng(0)
    plots = sim.merge_plots([sim.radar_plots(r, targets, 0.0, 30.0, rng) for r in (radar1, radar2)])
    sensors = sim.sensor_set([radar1, radar2])
    config = TrackerConfig(sectors_per_scan=8)
    reference = Tracker(sensors, config).run(plots)
    assert reference["track_id"].nunique() == 3
    streamed = feed_in_chunks(sensors, plots, np.arange(1, len(plots)), config)
    # plots are converted per chunk and lat/lon per drain, vectorised over arrays whose length
    # depends on the chunking: the same operations, rounded alike to 1e-12
    pd.testing.assert_frame_equal(streamed, reference, check_exact=False, rtol=1e-12, atol=1e-9)


# ----------------------------------------------------------------------------- several radars, beam phase


def test_two_radars_with_different_periods_update_the_same_track(sim, radar1, radar2, targets):
    rng = np.random.default_rng(3)
    plots = sim.merge_plots([sim.radar_plots(r, targets, 0.0, 200.0, rng) for r in (radar1, radar2)])
    tracker = Tracker(sim.sensor_set([radar1, radar2]))
    tracks = tracker.run(plots)
    assert tracks["track_id"].nunique() == 2
    mapping = sim.assign_tracks_to_targets(tracks, targets)
    assert sorted(mapping.values()) == ["a", "b"]
    for track_id, name in mapping.items():
        rows = tracks[tracks["track_id"] == track_id]
        own = plots[plots["truth_id"] == name]
        counts = own.groupby("sensor").size()
        assert counts["radar1"] >= 45 and counts["radar2"] >= 35
        # every plot of both radars updated the one track
        assert rows["n_updates"].iloc[-1] == len(own)
        # between outputs (4 s) the count grows by 1 (radar1) plus 0 or 1 (radar2)
        steps = np.diff(rows["n_updates"].to_numpy())
        assert set(steps.tolist()) <= {1, 2} and (steps == 2).sum() >= 20
        # and the track follows the target (plot noise 60-120 m at these ranges)
        truth = [t for t in targets if t.name == name][0].at(rows["time"].to_numpy())
        error = np.hypot(rows["x"] - truth[:, 0], rows["y"] - truth[:, 1])
        assert np.sqrt(np.mean(error**2)) < 120.0 and error.max() < 400.0
    assert tracker.warnings == []


def test_wrong_scan_phase_gives_a_warning_and_tracking_still_works(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 100.0, np.random.default_rng(1))  # 50 plots in one chunk
    tracker = Tracker(sim.sensor_set([radar1], scan_phase_s=1.5))
    tracks = tracker.run(plots)
    assert len(tracker.warnings) == 1
    assert "'radar1'" in tracker.warnings[0] and "scan_phase_s 1.5" in tracker.warnings[0]
    # the tracker uses the phase estimated from the plots (0 s to within ~1e-4 s) instead, so the
    # result is that of the right phase, to the shift of the output instants
    assert abs(tracker.phase[0]) < 1e-3
    reference = Tracker(sim.sensor_set([radar1])).run(plots)
    pd.testing.assert_frame_equal(tracks, reference, check_exact=False, rtol=1e-3, atol=0.1)
    assert tracks["track_id"].nunique() == 2 and tracks.groupby("track_id")["n_updates"].max().tolist() == [25, 25]


def test_right_scan_phase_gives_no_warning(sim, radar1, targets):
    shifted = sim.Radar(**{**radar1.__dict__, "phase": 1.5})
    plots = sim.radar_plots(shifted, targets, 0.0, 100.0, np.random.default_rng(1))
    tracker = Tracker(sim.sensor_set([shifted]))
    tracks = tracker.run(plots)
    assert tracker.warnings == []
    # output instants are the ends of the scans: phase + k * period
    np.testing.assert_allclose(np.remainder(tracks["time"] - 1.5, 4.0), 0.0, atol=1e-9)


def test_negative_range_is_rejected_naming_row_and_column(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1))
    plots.loc[3, "range_m"] = -plots.loc[3, "range_m"]
    with pytest.raises(ValueError, match="row 3, column range_m"):
        Tracker(sim.sensor_set([radar1])).run(plots)


def test_output_interval(sim, radar1):
    target = sim.Target("a", (30000.0, 40000.0, 8000.0), (150.0, -100.0, 0.0))
    plots = sim.radar_plots(radar1, [target], 0.0, 60.0, np.random.default_rng(1))
    tracks = Tracker(sim.sensor_set([radar1]), TrackerConfig(output_interval_s=10.0)).run(plots)
    np.testing.assert_allclose(tracks["time"], [10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    plots_so_far = np.searchsorted(plots["time"].to_numpy(), tracks["time"].to_numpy(), side="right")
    np.testing.assert_array_equal(tracks["n_updates"], plots_so_far)


def test_empty_plots_table_gives_empty_tracks(sim, radar1, targets):
    plots = sim.radar_plots(radar1, targets, 0.0, 40.0, np.random.default_rng(1)).iloc[:0]
    tracker = Tracker(sim.sensor_set([radar1]))
    tracks = tracker.run(plots)
    assert len(tracks) == 0 and list(tracks.columns) == FORMATS_TRACK_COLUMNS
    assert tracker.stats["plots"] == 0


def test_advance_to_releases_the_windows_a_silent_radar_held(sim, radar1, radar2, targets):
    """radar2 falls silent at 60 s: the tracker waits for it (its plots might still come) and
    reports nothing after; ``advance_to`` (a live feed's reorder buffer vouching that nothing older
    will come) lets the windows go: radar1 keeps the same tracks going, and radar2's empty windows
    count as scans without a plot (coasting)."""
    rng = np.random.default_rng(3)
    plots = sim.merge_plots([sim.radar_plots(r, targets, 0.0, 120.0, rng) for r in (radar1, radar2)])
    plots = plots[(plots["sensor"] == "radar1") | (plots["time"] < 60.0)].reset_index(drop=True)
    sensors = sim.sensor_set([radar1, radar2])
    waiting = Tracker(sensors)
    waiting.feed(plots)
    held = waiting.drain()
    assert held["time"].max() < 64.0
    advanced = Tracker(sensors)
    advanced.feed(plots)
    advanced.advance_to(float(plots["time"].max()))
    released = advanced.drain()
    assert released["time"].max() > 112.0
    before = released[released["time"] <= held["time"].max()].reset_index(drop=True)
    pd.testing.assert_frame_equal(before, held.reset_index(drop=True))
    last = released[released["time"] == released["time"].max()]
    assert set(last["track_id"]) == set(held["track_id"]) and len(last) == 2
    assert (released.loc[released["time"] > 64.0, "status"] == "coasting").any()

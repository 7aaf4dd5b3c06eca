"""Issue 9: ADS-B labels in the tracking run (skytrack.app.identification) and track reports.

One simulation of the bundled ``adsb_identification`` scene (shortened to 150 s) is tracked
with ADS-B; the checks are the issue's acceptance on that scene: no wrong label, every
sound equipped aircraft labelled once it has been tracked for a minute, the aircraft whose
ADS-B is 2 km off never labelled, every label change an identity event.
"""

import numpy as np
import pandas as pd
import pytest

from skytrack.app.identification import AdsbIdentificationConfig, TrackLabeler
from skytrack.app.other_systems import adsb_system
from skytrack.app.run import run_tracking
from skytrack.io import read_tracks, write_adsb, write_plots, write_sensors, write_truth
from skytrack.io.identity_events import identity_events_path, read_identity_events
from skytrack.io.track_reports import read_track_reports, track_reports_path
from skytrack.sim import load_scenario, simulate


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("adsb")
    result = simulate(load_scenario("adsb_identification", {"duration_s": 150}))
    paths = {"plots": write_plots(result.plots, folder / "plots.parquet"),
             "sensors": write_sensors(result.sensors, folder / "sensors.json"),
             "adsb": write_adsb(result.adsb, folder / "adsb.parquet", origin=result.sensors.origin),
             "truth": write_truth(result.truth, folder / "truth.parquet", origin=result.sensors.origin)}
    out = folder / "tracks.parquet"
    summary = run_tracking(paths["plots"], paths["sensors"], out, adsb_path=paths["adsb"], write_reports=True)
    return result, paths, out, summary


def _truth_of_rows(tracks, truth):
    """Nearest truth object of every track row (the scene's aircraft are >= 1 km apart)."""
    names, distance = [], []
    groups = {tid: g for tid, g in truth.groupby("target_id")}
    xy = np.stack([[np.interp(tracks.time, g.time, g.x), np.interp(tracks.time, g.time, g.y)] for g in groups.values()])
    d = np.hypot(xy[:, 0] - tracks.x.to_numpy(), xy[:, 1] - tracks.y.to_numpy())
    names = np.array(list(groups))[d.argmin(0)]
    distance = d.min(0)
    return names, distance


def test_labels_are_right_and_come_within_a_minute(scene):
    result, paths, out, summary = scene
    tracks = read_tracks(out)
    owner = result.adsb.groupby("icao24").truth_id.agg(lambda s: s.mode()[0])
    truth_name, distance = _truth_of_rows(tracks, result.truth)
    labelled = tracks[tracks.identity_source == "adsb"]
    assert len(labelled) > 200
    assert (labelled.icao24.map(owner).to_numpy() == truth_name[labelled.index]).all()  # no wrong label
    faulty = result.adsb_aircraft.set_index("target_id").loc["OFS1", "icao24"]
    assert faulty not in set(tracks.icao24.dropna())  # the 2-km offset aircraft is never labelled
    for address, target in owner.items():
        if target == "OFS1":
            continue
        rows = tracks[(truth_name == target) & (distance < 1000)]
        first = rows.time.min()
        later = rows[rows.time >= first + 60]
        assert len(later) and (later.icao24 == address).mean() >= 0.95, target
        named = later[later.icao24 == address]
        assert (named.callsign == result.adsb_aircraft.set_index("target_id").loc[target, "callsign"]).all()
    assert summary.identification["late_radar_reports"] == 0
    assert 0.0 < labelled.identity_p.min() and labelled.identity_p.max() <= 1.0


def test_every_label_change_is_an_identity_event(scene):
    _, _, out, _ = scene
    tracks = read_tracks(out).sort_values(["track_id", "time"])
    events = read_identity_events(identity_events_path(out))
    adsb = events[(events.source == "adsb") & (events.field == "icao24")]
    for track_id, rows in tracks[tracks.identity_source.isin(["adsb"]) | tracks.icao24.isna()].groupby("track_id"):
        shown = [None if pd.isna(value) else value for value in rows.icao24.tolist()]
        changes = sum(1 for before, after in zip([None] + shown[:-1], shown) if before != after)
        assert changes == (adsb.track_id == track_id).sum(), track_id


def test_track_reports_are_the_plots_the_tracks_took(scene):
    result, _, out, summary = scene
    reports = read_track_reports(track_reports_path(out))
    assert len(reports) == summary.report_rows > 0
    tracks = read_tracks(out)
    assert set(reports.track_id) <= set(tracks.track_id)
    # every report is a plot of the simulation: its time is one of the plots' times
    assert np.isin(reports.time.to_numpy(), result.plots.time.to_numpy()).all()
    assert (reports.var_x > 0).all() and (reports.var_x * reports.var_y > reports.cov_xy ** 2).all()


def test_fused_rows_are_closer_to_the_truth(scene, tmp_path):
    result, paths, out, _ = scene
    fused_out = tmp_path / "fused.parquet"
    run_tracking(paths["plots"], paths["sensors"], fused_out, adsb_path=paths["adsb"],
                 identification=AdsbIdentificationConfig(fuse=True))
    plain, fused = read_tracks(out), read_tracks(fused_out)
    rows = (fused.identity_source == "adsb").to_numpy()
    name, _ = _truth_of_rows(fused, result.truth)
    truth_xy = np.array([[np.interp(t, g.time, g.x), np.interp(t, g.time, g.y)] for t, g in
                         zip(fused.time[rows], (result.truth[result.truth.target_id == n] for n in name[rows]))])
    error_fused = np.hypot(*(fused[["x", "y"]].to_numpy()[rows] - truth_xy).T)
    error_plain = np.hypot(*(plain[["x", "y"]].to_numpy()[rows] - truth_xy).T)
    assert np.median(error_fused) < 0.5 * np.median(error_plain)
    assert (fused.var_x[rows] < plain.var_x[rows]).mean() > 0.95


def test_a_mode_s_address_is_not_overwritten():
    """A track whose plots name an address keeps it; an ADS-B decision for another address is a conflict."""
    import pyarrow as pa

    adsb = pd.DataFrame({"time": np.arange(0.0, 60.0), "icao24": "abc123", "x": np.arange(60.0) * 100.0,
                         "y": 0.0, "sigma_m": 10.0, "callsign": "TEST1"})
    labeler = TrackLabeler(adsb_system(adsb), 1e10, AdsbIdentificationConfig(min_updates=2))
    t = np.arange(0.0, 60.0, 4.0) + 0.5
    labeler.add_radar({"track_id": np.full(len(t), 7), "time": t,
                       "position": np.column_stack([t * 100.0, np.zeros(len(t)), np.zeros(len(t))]),
                       "covariance": np.broadcast_to(np.diag([50.0 ** 2, 50.0 ** 2, 1.0]), (len(t), 3, 3)).copy()})
    rows = pa.table({"time": t + 0.1, "track_id": np.full(len(t), 7), "status": ["confirmed"] * len(t),
                     "icao24": ["fff000"] * len(t),
                     "callsign": pa.nulls(len(t), pa.string()), "mode3a": pa.nulls(len(t), pa.string()),
                     "iff": pa.nulls(len(t), pa.string()), "identity_source": ["mode_s"] * len(t),
                     "identity_p": np.full(len(t), 0.9)})
    table, _ = labeler.label(rows, None)
    assert set(table.column("icao24").to_pylist()) == {"fff000"}
    assert labeler.stats.mode_s_conflicts > 0


def test_compiled_and_composed_trackers_record_the_same_plots(scene):
    """Tracker.record_assignments: the compiled window and the composed parts log the same plots."""
    from skytrack.tracker import Tracker, TrackerConfig

    result = scene[0]
    logs = []
    for compiled in (True, False):
        config = TrackerConfig()
        config.association.compiled = compiled
        tracker = Tracker(result.sensors, config)
        tracker.record_assignments()
        tracker.run(result.plots)
        taken = tracker.drain_assignments()
        logs.append(pd.DataFrame({"time": taken["time"], "track_id": taken["track_id"]}).sort_values(["time"]))
    assert len(logs[0]) > 500
    np.testing.assert_array_equal(logs[0]["time"].to_numpy(), logs[1]["time"].to_numpy())
    assert Tracker(result.sensors, TrackerConfig()).drain_assignments() is None

"""The tracking pipeline as a library call (skytrack.app.run.run_tracking)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.app.run import RunSummary, run_tracking
from skytrack.app.simulate import run_simulation, write_simulation
from skytrack.io import read_tracks
from skytrack.tracker import Tracker, TrackerConfig


@pytest.fixture(scope="module")
def crossing(tmp_path_factory):
    """The bundled crossing scenario written as Parquet and CSV inputs."""
    out = tmp_path_factory.mktemp("crossing")
    stages = []
    result = run_simulation("crossing", seed=5, progress=lambda stage, done, total: stages.append((stage, done, total)))
    assert stages[0] == ("simulate", 0.0, 1.0) and stages[-1] == ("simulate", 1.0, 1.0)
    paths = write_simulation(result, out, "parquet")
    csv_paths = write_simulation(result, out / "csv", "csv")
    return result, paths, csv_paths


def _assert_same_tracks(got: pd.DataFrame, want: pd.DataFrame) -> None:
    assert len(got) == len(want) > 0
    for column in want.columns:
        a, b = got[column].to_numpy(), want[column].to_numpy()
        if b.dtype.kind == "f":
            np.testing.assert_allclose(a.astype(float), b, rtol=1e-9, atol=1e-9, equal_nan=True, err_msg=column)
        else:
            assert [None if pd.isna(v) else v for v in a] == [None if pd.isna(v) else v for v in b], column


@pytest.mark.parametrize("chunk_rows", [200_000, 97])
def test_run_tracking_gives_the_tracks_of_tracker_run(crossing, tmp_path, chunk_rows):
    result, paths, _ = crossing
    config = TrackerConfig(full_covariance=True)
    calls = []
    summary = run_tracking(paths["plots"], paths["sensors"], tmp_path / "tracks.parquet", config,
                           chunk_rows=chunk_rows, progress=lambda *args: calls.append(args))
    assert isinstance(summary, RunSummary)
    expected_tracker = Tracker(result.sensors, config)
    expected = expected_tracker.run(result.plots)
    _assert_same_tracks(read_tracks(tmp_path / "tracks.parquet"), read_tracks_like(expected, tmp_path))
    assert summary.plots == len(result.plots)
    assert summary.track_rows == len(expected)
    assert summary.tracks_file == str(tmp_path / "tracks.parquet")
    assert summary.tracking_dim == expected_tracker.dim
    assert summary.stats == dict(expected_tracker.stats)
    assert summary.report is None and summary.elapsed_s > 0
    assert calls[0] == ("track", 0, len(result.plots)) and calls[-1] == ("track", len(result.plots), len(result.plots))
    assert len(calls) == 2 + -(-len(result.plots) // chunk_rows)


def read_tracks_like(tracks: pd.DataFrame, tmp_path) -> pd.DataFrame:
    """``tracks`` after the same write/read round trip as the pipeline's output."""
    from skytrack.io import write_tracks

    return read_tracks(write_tracks(tracks, tmp_path / "expected.parquet"))


def test_csv_input_gives_the_same_tracks_as_parquet(crossing, tmp_path):
    _, paths, csv_paths = crossing
    from_parquet = run_tracking(paths["plots"], paths["sensors"], tmp_path / "a.parquet", chunk_rows=150)
    from_csv = run_tracking(csv_paths["plots"], csv_paths["sensors"], tmp_path / "b.parquet", chunk_rows=150,
                            progress=lambda stage, done, total: None)
    assert from_csv.plots == from_parquet.plots
    _assert_same_tracks(read_tracks(tmp_path / "b.parquet"), read_tracks(tmp_path / "a.parquet"))


def test_lenient_run_reports_skipped_rows(crossing, tmp_path):
    result, paths, _ = crossing
    plots = result.plots.copy()
    plots.loc[[3, 10], "azimuth_deg"] = 400.0
    plots.to_parquet(tmp_path / "plots.parquet", index=False)
    summary = run_tracking(tmp_path / "plots.parquet", paths["sensors"], tmp_path / "t.csv", lenient=True, chunk_rows=64)
    assert summary.report is not None and summary.report.rows_skipped == 2
    assert summary.plots == len(plots) - 2
    data = summary.to_dict()
    assert set(data) == {"plots", "tracks_file", "track_rows", "elapsed_s", "stats", "warnings", "report", "tracking_dim",
                         "no_tracks_reason", "identity_events_file", "identity_event_rows", "no_identity_events_reason",
                         "identification", "reports_file", "report_rows"}
    assert "2 skipped" in data["report"]


def test_bad_chunk_rows_is_refused(crossing, tmp_path):
    _, paths, _ = crossing
    with pytest.raises(ValueError, match="chunk_rows"):
        run_tracking(paths["plots"], paths["sensors"], tmp_path / "t.parquet", chunk_rows=0)


def test_a_run_without_tracks_says_why(crossing, tmp_path):
    """Too few scans to confirm, and no plot at all: the summary names the reason; a run with
    tracks has none."""
    from skytrack.io import write_plots

    result, paths, _ = crossing
    plots = result.plots
    first_two_scans = plots[plots["time"] < plots["time"].min() + 2 * result.sensors.sensors[0].scan_period_s]
    write_plots(first_two_scans, tmp_path / "short.parquet", sensors=result.sensors)
    m_of_n = TrackerConfig(track_logic="m-of-n")
    summary = run_tracking(tmp_path / "short.parquet", paths["sensors"], tmp_path / "short_tracks.parquet", m_of_n)
    assert summary.track_rows == 0 and summary.stats["tracks_started"] > 0
    assert summary.no_tracks_reason == (
        f"{summary.stats['tracks_started']} tentative tracks started but none was confirmed by the 3-of-4 rule: a "
        "track needs plots on 3 of 4 consecutive scans (check the radars' scan_period_s against the plots' times, "
        "and the plots' units)")
    # the track score needs more than one plot: a single scan starts tracks and confirms none
    first_scan = plots[plots["time"] < plots["time"].min() + result.sensors.sensors[0].scan_period_s]
    write_plots(first_scan, tmp_path / "one_scan.parquet", sensors=result.sensors)
    scored = run_tracking(tmp_path / "one_scan.parquet", paths["sensors"], tmp_path / "one_scan_tracks.parquet")
    assert scored.track_rows == 0 and "none reached the confirmation score" in scored.no_tracks_reason
    write_plots(plots.iloc[:0], tmp_path / "empty.parquet", sensors=result.sensors)
    empty = run_tracking(tmp_path / "empty.parquet", paths["sensors"], tmp_path / "empty_tracks.parquet")
    assert empty.no_tracks_reason == "no plot was read"
    full = run_tracking(paths["plots"], paths["sensors"], tmp_path / "tracks.parquet")
    assert full.track_rows > 0 and full.no_tracks_reason is None
    assert full.to_dict()["no_tracks_reason"] is None


def test_an_output_that_is_an_input_is_refused(crossing, tmp_path):
    """`-o` naming the plots or sensors file (even by another path) would destroy the input."""
    from skytrack.app.evaluate import run_evaluation
    from skytrack.io import InputError

    _, paths, _ = crossing
    for victim, option in ((paths["plots"], "plots"), (paths["sensors"], "sensors")):
        before = victim.read_bytes()
        roundabout = victim.parent / "." / victim.name
        with pytest.raises(InputError) as info:
            run_tracking(paths["plots"], paths["sensors"], roundabout)
        assert str(info.value) == (f"{roundabout}: the output file is the {option} input: writing it would "
                                   "overwrite the data being read")
        assert victim.read_bytes() == before
    with pytest.raises(InputError, match="the output file is the truth input"):
        run_evaluation(paths["plots"], paths["truth"], json_out=paths["truth"])


def test_plots_in_kilometres_radians_or_milliseconds_stop_the_run_unless_confirmed(crossing, tmp_path):
    """Tracked as metres and degrees they gave garbage or nothing with exit 0: now a one-line
    error with the hint, before any track is written; --units-confirmed tracks them as given."""
    from skytrack.io import InputError, write_sensors

    simulated = run_simulation("demo", seed=5)
    demo = simulated.plots[simulated.plots["time"] < simulated.plots["time"].min() + 300.0]  # > 1 000 plots
    write_sensors(simulated.sensors, tmp_path / "sensors.json")
    paths = {"sensors": tmp_path / "sensors.json"}
    for column, scale, word in (("range_m", 1e-3, "kilometres"), ("azimuth_deg", np.pi / 180.0, "radians"),
                                ("time", 1e3, "milliseconds")):
        plots = demo.copy()
        plots[column] = plots[column] * scale
        plots.to_parquet(tmp_path / "plots.parquet", index=False)
        with pytest.raises(InputError) as info:
            run_tracking(tmp_path / "plots.parquet", paths["sensors"], tmp_path / "t.parquet", chunk_rows=5000)
        message = str(info.value)
        assert message.startswith(f"{tmp_path / 'plots.parquet'}: ") and word in message
        assert message.endswith("confirm the units: --units-confirmed)")
        assert not (tmp_path / "t.parquet").exists() or len(read_tracks(tmp_path / "t.parquet")) == 0
        if column != "time":  # a thousand-fold scan would walk 300 000 empty windows
            summary = run_tracking(tmp_path / "plots.parquet", paths["sensors"], tmp_path / "t.parquet",
                                   chunk_rows=5000, units_confirmed=True)
            assert summary.plots == len(plots)


@pytest.mark.parametrize("suffix", ["parquet", "csv"])
def test_evaluate_measures_from_the_input_start_stored_with_the_tracks(crossing, tmp_path, suffix):
    """The tracks file keeps the input's time span (Parquet metadata, a sidecar JSON for CSV):
    `evaluate` then counts the time to the first track from the first plot, as the demo does,
    instead of from the first track (which gave 0 s)."""
    from skytrack.app.evaluate import run_evaluation
    from skytrack.io.tracks import read_tracks_metadata, sidecar_path

    result, paths, _ = crossing
    out = tmp_path / f"tracks.{suffix}"
    run_tracking(paths["plots"], paths["sensors"], out)
    metadata = read_tracks_metadata(out)
    assert metadata["input_time_start_s"] == pytest.approx(float(result.plots["time"].min()), abs=1e-9)
    assert metadata["input_time_end_s"] == pytest.approx(float(result.plots["time"].max()), abs=1e-9)
    assert metadata["input_plots"] == len(result.plots) and metadata["input_file"] == paths["plots"].name
    stored = run_evaluation(out, paths["truth"], json_out=tmp_path / "a.json").evaluation
    given = run_evaluation(out, paths["truth"], json_out=tmp_path / "b.json",
                           start_time_s=float(result.plots["time"].min())).evaluation
    assert stored.summary["time_to_first_track_mean_s"] == given.summary["time_to_first_track_mean_s"]
    assert stored.summary["time_to_first_track_mean_s"] > 5.0  # three scans of 4 s to confirm, at least
    if suffix == "csv":
        sidecar_path(out).unlink()  # a file written without the metadata: measured from the first track
        assert read_tracks_metadata(out) is None
        bare = run_evaluation(out, paths["truth"], json_out=tmp_path / "c.json").evaluation
        assert bare.summary["time_to_first_track_mean_s"] < stored.summary["time_to_first_track_mean_s"]

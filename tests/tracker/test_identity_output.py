"""Track identity in the tracker's output (issue 8 item 2; spec 003 R14, TV13 (d)).

Three well-separated targets, seen without noise by one 2-D radar, carry identity replies
written by the test: A Mode 3/A ``0123`` and IFF friend with one flipped reply (foe) and one
corrupted code (``5670``), B a Mode S address only, C nothing.  Expected values are computed
here from the plots alone: the latest definite reply (R14), and the posterior of the shown
value by its closed form with exact fractions,

    P(shown) = rho^n_shown / (sum over seen values of rho^n_value + K - seen values),
    rho = (1 - eps) (K - 1) / eps,

K = 2 (IFF), 4096 (Mode 3/A), 2^24 (Mode S); ``identity_p`` is the product over the shown
attributes.  Tolerance: closed form, 1e-12 relative.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest

from skytrack.app.run import run_tracking
from skytrack.io import identity_events_path, read_identity_events, read_tracks, write_sensors
from skytrack.io.schema import STRING_DTYPE
from skytrack.tracker import Tracker, TrackerConfig

EPS = Fraction(1, 5)
SCANS = 16
FLIP_SCAN, SILENT_SCAN, BACK_SCAN, CORRUPT_SCAN = 5, 6, 7, 11
FIELD_ORDER = ("icao24", "callsign", "mode3a", "iff")
VALUES = {"iff": 2, "mode3a": 4096, "icao24": 2**24}


def _reply_a(index: int) -> dict:
    """Target A's replies on its ``index``-th plot."""
    if index == SILENT_SCAN:
        return {"mode3a": None, "mode_s": None, "iff": None}
    return {"mode3a": "5670" if index == CORRUPT_SCAN else "0123", "mode_s": None,
            "iff": "foe" if index == FLIP_SCAN else "friend"}


@pytest.fixture
def scene(sim, radar1):
    targets = [sim.Target("A", (30000.0, 40000.0, 8000.0), (150.0, -100.0, 0.0)),
               sim.Target("B", (-40000.0, 20000.0, 10000.0), (0.0, -200.0, 0.0)),
               sim.Target("C", (-20000.0, -60000.0, 6000.0), (180.0, 0.0, 0.0))]
    plots = sim.radar_plots(radar1, targets, 0.0, SCANS * radar1.period, np.random.default_rng(3), noise=False)
    index = plots.groupby("truth_id").cumcount().to_numpy()
    replies = {"mode3a": [], "mode_s": [], "iff": []}
    for truth, k in zip(plots["truth_id"], index):
        reply = _reply_a(k) if truth == "A" else {"mode3a": None, "mode_s": "abc123" if truth == "B" else None,
                                                  "iff": None}
        for name in replies:
            replies[name].append(reply[name])
    for name, values in replies.items():
        plots[name] = pd.array(values, dtype=STRING_DTYPE)
    return sim.sensor_set([radar1]), plots, targets


def _posterior(counts: dict[str, int], shown: str, values: int) -> Fraction:
    rho = (1 - EPS) * (values - 1) / EPS
    return rho ** counts[shown] / (sum(rho ** n for n in counts.values()) + values - len(counts))


def _state_after(plots: pd.DataFrame, truth: str, until: float, inclusive: bool):
    """(shown values, identity_p) of ``truth``'s track after its plots before ``until``."""
    rows = plots[(plots["truth_id"] == truth) & ((plots["time"] <= until) if inclusive else (plots["time"] < until))]
    shown: dict[str, str | None] = {"mode3a": None, "icao24": None, "iff": None}
    counts: dict[str, dict[str, int]] = {"mode3a": {}, "icao24": {}, "iff": {}}
    for mode3a, mode_s, iff in zip(rows["mode3a"], rows["mode_s"], rows["iff"]):
        for field, value in (("mode3a", mode3a), ("icao24", mode_s)):
            if not pd.isna(value):
                shown[field] = value
                counts[field][value] = counts[field].get(value, 0) + 1
        if not pd.isna(iff):
            shown["iff"] = iff  # only friend/foe occur here: every reply is definite
            counts["iff"][iff] = counts["iff"].get(iff, 0) + 1
    p = Fraction(1)
    for field, value in shown.items():
        if value is not None:
            p *= _posterior(counts[field], value, VALUES[field])
    source = "mode_s" if shown["icao24"] else "iff" if shown["mode3a"] or shown["iff"] else None
    return shown, (float(p) if source else math.nan), source


def _expected_events(plots: pd.DataFrame, tracks: pd.DataFrame, owner: dict[int, str]) -> pd.DataFrame:
    rows = []
    for track_id, truth in owner.items():
        first_report = tracks.loc[tracks["track_id"] == track_id, "time"].min()
        own = plots[plots["truth_id"] == truth]
        confirmed_at = own.loc[own["time"] < first_report, "time"].max()
        before: dict[str, str | None] = {"mode3a": None, "icao24": None, "iff": None}
        for t in own.loc[own["time"] >= confirmed_at, "time"]:
            shown, p, source = _state_after(plots, truth, t, inclusive=True)
            for field in ("icao24", "mode3a", "iff"):
                if shown[field] != before[field]:
                    rows.append({"time": t, "track_id": track_id, "field": field, "old": before[field],
                                 "new": shown[field], "source": "mode_s" if field == "icao24" else "iff",
                                 "identity_p": p})
            before = shown
    expected = pd.DataFrame(rows)
    expected["order"] = expected["field"].map(FIELD_ORDER.index)
    return expected.sort_values(["time", "track_id", "order"]).drop(columns="order").reset_index(drop=True)


def _plain(values: pd.Series) -> list:
    return [None if pd.isna(v) else v for v in values]


def _run(sensors, plots, **flat):
    tracker = Tracker(sensors, TrackerConfig(identity_error_p=float(EPS), **flat))
    tracks = tracker.run(plots)
    table = tracker.drain_identity_events()
    return tracker, tracks, table.to_pandas() if table is not None else None


def _check(sim, plots, targets, tracks, events):
    owner = sim.assign_tracks_to_targets(tracks, targets)
    assert sorted(owner.values()) == ["A", "B", "C"]
    # every row: the latest definite replies and the closed-form posterior of what it shows
    for row in tracks.itertuples():
        shown, p, source = _state_after(plots, owner[row.track_id], row.time, inclusive=False)
        assert [None if pd.isna(v) else v for v in (row.mode3a, row.icao24, row.iff)] == \
            [shown["mode3a"], shown["icao24"], shown["iff"]]
        assert (None if pd.isna(row.identity_source) else row.identity_source) == source
        if source is None:
            assert math.isnan(row.identity_p)
        else:
            assert row.identity_p == pytest.approx(p, rel=1e-12, abs=0.0)
    # every change exactly once, with its time, old and new values and identity_p
    expected = _expected_events(plots, tracks, owner)
    assert list(events.columns) == ["time", "track_id", "field", "old", "new", "source", "identity_p"]
    for column in ("track_id", "field", "old", "new", "source"):
        assert _plain(events[column]) == _plain(expected[column]), column
    np.testing.assert_allclose(events["time"].to_numpy(), expected["time"].to_numpy(), rtol=0, atol=0)
    np.testing.assert_allclose(events["identity_p"].to_numpy(), expected["identity_p"].to_numpy(), rtol=1e-12)
    return owner


def test_identity_follows_the_latest_reply_with_its_posterior(sim, scene):
    sensors, plots, targets = scene
    _, tracks, events = _run(sensors, plots)
    owner = _check(sim, plots, targets, tracks, events)
    track_a = next(k for k, v in owner.items() if v == "A")
    # TV13 (d): friend relabelled foe by the flipped reply, kept by the silent plot, then back
    plot_a = plots[plots["truth_id"] == "A"]["time"].to_numpy()
    rows = tracks[tracks["track_id"] == track_a]
    iff_at = dict(zip(rows["time"], rows["iff"]))
    p_at = dict(zip(rows["time"], rows["identity_p"]))

    def after(scan):  # the first output row after A's plot of that scan
        return min(t for t in iff_at if t > plot_a[scan])

    assert plot_a[FLIP_SCAN] > rows["time"].min()  # the flip comes after confirmation
    assert iff_at[after(FLIP_SCAN)] == "foe" and iff_at[after(SILENT_SCAN)] == "foe"
    assert iff_at[after(BACK_SCAN)] == "friend"
    # identity_p drops with the contradicting reply and rises with each agreeing one after
    assert p_at[after(FLIP_SCAN)] < 0.01 and p_at[after(FLIP_SCAN - 1)] > 0.99  # 1 / (1 + 4^4) after it
    rising = [p_at[after(scan)] for scan in range(BACK_SCAN, CORRUPT_SCAN)]
    assert all(b > a for a, b in zip(rising, rising[1:]))
    assert p_at[after(CORRUPT_SCAN)] < p_at[after(CORRUPT_SCAN - 1)]
    # A: one confirmation pair, iff friend->foe->friend, mode3a 0123->5670->0123; B: one address
    changes = events.groupby(["track_id", "field"]).size().to_dict()
    assert changes == {(track_a, "iff"): 3, (track_a, "mode3a"): 3,
                       (next(k for k, v in owner.items() if v == "B"), "icao24"): 1}


def test_reference_path_and_imm_give_the_same_identity(sim, scene):
    sensors, plots, targets = scene
    compiled, tracks, events = _run(sensors, plots)
    config = TrackerConfig(compiled=False, identity_error_p=float(EPS))
    config.filter.options["compiled"] = False
    reference = Tracker(sensors, config)
    pd.testing.assert_frame_equal(reference.run(plots), tracks, check_exact=False, rtol=1e-9, atol=1e-6)
    pd.testing.assert_frame_equal(reference.drain_identity_events().to_pandas(), events)
    np.testing.assert_array_equal(reference.bank.identity, compiled.bank.identity)
    # the compiled IMM stage writes the same identity bookkeeping
    imm, imm_tracks, imm_events = _run(sensors, plots, filter_kind="imm")
    assert imm.scan.fused_imm is not None
    _check(sim, plots, targets, imm_tracks, imm_events)


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_files_carry_identity_and_events(sim, scene, tmp_path, suffix):
    sensors, plots, targets = scene
    plots.to_parquet(tmp_path / "plots.parquet", index=False)
    write_sensors(sensors, tmp_path / "sensors.json")
    out = tmp_path / f"tracks{suffix}"
    summary = run_tracking(tmp_path / "plots.parquet", tmp_path / "sensors.json", out,
                           TrackerConfig(identity_error_p=float(EPS)))
    events_file = tmp_path / f"tracks.identity{suffix}"
    assert identity_events_path(out) == events_file and summary.identity_events_file == str(events_file)
    tracks = read_tracks(out)
    assert tracks["identity_source"].dtype == STRING_DTYPE and tracks["identity_p"].dtype == np.float64
    assert tracks["mode3a"].dtype == STRING_DTYPE and set(tracks["mode3a"].dropna()) == {"0123", "5670"}
    events = read_identity_events(events_file)
    assert summary.identity_event_rows == len(events) == 7
    assert events["time"].dtype == np.float64 and events["track_id"].dtype == np.int64
    assert all(events[c].dtype == STRING_DTYPE for c in ("field", "old", "new", "source"))
    _check(sim, plots, targets, tracks, events)


def test_run_without_identity_writes_no_events(sim, scene, tmp_path):
    sensors, plots, _ = scene
    plots.drop(columns=["mode3a", "mode_s", "iff"]).to_parquet(tmp_path / "plots.parquet", index=False)
    write_sensors(sensors, tmp_path / "sensors.json")
    stale = tmp_path / "tracks.identity.parquet"
    stale.write_bytes(b"from an earlier run")
    summary = run_tracking(tmp_path / "plots.parquet", tmp_path / "sensors.json", tmp_path / "tracks.parquet")
    assert summary.track_rows > 0 and not stale.exists()
    assert summary.identity_events_file is None and summary.identity_event_rows == 0
    assert "no plot carried" in summary.no_identity_events_reason
    tracks = read_tracks(tmp_path / "tracks.parquet")
    assert tracks["identity_source"].isna().all() and tracks["identity_p"].isna().all()


def test_plots_with_identity_but_no_change_leave_an_empty_events_file(sim, scene, tmp_path):
    """Identity seen but no confirmed track: the events file exists, with no rows."""
    sensors, plots, _ = scene
    plots.iloc[:2].to_parquet(tmp_path / "plots.parquet", index=False)
    write_sensors(sensors, tmp_path / "sensors.json")
    summary = run_tracking(tmp_path / "plots.parquet", tmp_path / "sensors.json", tmp_path / "tracks.csv")
    events = read_identity_events(tmp_path / "tracks.identity.csv")
    assert summary.identity_events_file is not None and len(events) == 0
    assert list(events.columns) == ["time", "track_id", "field", "old", "new", "source", "identity_p"]


def replayed_identity(tracks: pd.DataFrame, events: pd.DataFrame) -> pd.DataFrame:
    """Each track row's identity rebuilt from the events at or before its time."""
    out = tracks[["time", "track_id"]].reset_index().sort_values("time")
    for field in ("mode3a", "icao24", "iff"):
        changes = events.loc[events["field"] == field, ["time", "track_id", "new"]].sort_values("time")
        out = pd.merge_asof(out, changes.rename(columns={"new": field}), on="time", by="track_id",
                            direction="backward")
    return out.set_index("index").sort_index()


def test_skytrack_track_writes_the_events_of_a_simulated_scenario(tmp_path):
    from typer.testing import CliRunner

    from skytrack.cli.main import app

    runner = CliRunner()
    result = runner.invoke(app, ["simulate", "crossing", "-o", str(tmp_path / "sim")], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    out = tmp_path / "tracks.parquet"
    result = runner.invoke(app, ["track", str(tmp_path / "sim" / "plots.parquet"), "--sensors",
                                 str(tmp_path / "sim" / "sensors.json"), "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    tracks, events = read_tracks(out), read_identity_events(tmp_path / "tracks.identity.parquet")
    assert len(events) >= tracks["mode3a"].notna().groupby(tracks["track_id"]).any().sum() > 0
    assert events.groupby(["track_id", "field"])["old"].apply(lambda s: s.isna().sum() == 1).all()
    # the history is recoverable: replaying the events gives every row's identity
    replay = replayed_identity(tracks, events)
    for field in ("mode3a", "icao24", "iff"):
        assert replay[field].fillna("-").tolist() == tracks[field].fillna("-").tolist(), field

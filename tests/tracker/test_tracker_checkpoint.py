"""Tracker checkpoints in memory (issue 11 item 3): :meth:`Tracker.checkpoint` and
:meth:`Tracker.restore` keep the whole state, so that a restored tracker fed the rest of the plots
produces exactly the tracks the original does — for the default filter, the IMM and the other
filter families whose states differ (psi switch, mixtures, adaptive noise estimators, per-axis
blocks, order-3 filters).

The scenario is the demo (turns, climbs, clutter, Mode 3/A / Mode S / IFF replies, one 4-s
radar, 600 s), fed in chunks of 700 plots; the checkpoint is taken at a chunk boundary while
tracks are confirmed, tentative and coasting and plots of open windows wait.
"""

from __future__ import annotations

import numpy as np
import pytest
from checkpoint_support import assert_same_tracks, chunks_of

from skytrack.sim import load_scenario, simulate
from skytrack.tracker.bank import CONFIRMED
from skytrack.tracker.config import FilterConfig, TrackerConfig
from skytrack.tracker.tracker import Tracker


@pytest.fixture(scope="module")
def demo():
    return simulate(load_scenario("demo"))


def config_of(kind: str, model: str = "cv") -> TrackerConfig:
    config = TrackerConfig(model=model)
    config.filter = FilterConfig(kind=kind)
    return config


def run_split(sensors, plots, config, split: int, drain_before: bool):
    """The original fed everything, and a tracker restored at chunk ``split`` fed the rest;
    returns (original's rows from the checkpoint on, restored's rows, original at the checkpoint)."""
    chunks = chunks_of(plots)
    original = Tracker(sensors, config)
    for chunk in chunks[:split]:
        original.feed(chunk)
    if drain_before:
        original.drain()
        original.drain_identity_events()
    confirmed_ids = set(original.bank.track_id[original.bank.status == CONFIRMED].tolist())
    arrays, meta = original.checkpoint()
    assert all(isinstance(value, np.ndarray) and value.dtype != object for value in arrays.values())
    restored = Tracker.restore(sensors, config, arrays, meta)
    for chunk in chunks[split:]:
        original.feed(chunk)
        restored.feed(chunk)
    original.finish()
    restored.finish()
    assert dict(restored.stats) == dict(original.stats)
    return original.drain(), restored.drain(), confirmed_ids, (original, restored)


@pytest.mark.parametrize("kind, model", [
    ("kalman-psi", "cv"), ("imm", "cv"), ("static-bank", "cv"), ("kalman", "cv"), ("kalman-adaptive", "cv"),
    ("ct-omega-adaptive", "cv"), ("kalman-per-axis", "cv"), ("variable-dimension", "singer"),
])
def test_restored_tracker_continues_exactly(demo, kind, model):
    expected, actual, confirmed_ids, (original, restored) = run_split(
        demo.sensors, demo.plots, config_of(kind, model), split=4, drain_before=True)
    assert_same_tracks(expected, actual)
    # every track confirmed at the checkpoint is reported by the restored tracker, under its own id
    assert len(confirmed_ids) >= 10, len(confirmed_ids)
    assert confirmed_ids <= set(actual["track_id"].tolist())
    assert restored.scan.next_track_id == original.scan.next_track_id
    events_original, events_restored = original.drain_identity_events(), restored.drain_identity_events()
    assert events_original is not None and events_restored.equals(events_original)


def test_rows_not_drained_are_part_of_the_state(demo):
    """A checkpoint taken before draining keeps the rows produced so far: the restored tracker
    drains them with the rest, and the whole table equals an uninterrupted run's."""
    expected, actual, _, (_, restored) = run_split(demo.sensors, demo.plots, TrackerConfig(), split=5,
                                                   drain_before=False)
    uninterrupted = Tracker(demo.sensors, TrackerConfig())
    for chunk in chunks_of(demo.plots):
        uninterrupted.feed(chunk)
    uninterrupted.finish()
    assert_same_tracks(uninterrupted.drain(), actual)
    assert_same_tracks(expected, actual)
    # the identity events found before the checkpoint too
    events = uninterrupted.drain_identity_events()
    assert events.num_rows > 100 and restored.drain_identity_events().equals(events)


def test_state_holds_the_learnt_clutter_map_and_pending_plots(demo):
    tracker = Tracker(demo.sensors, TrackerConfig())
    for chunk in chunks_of(demo.plots)[:4]:
        tracker.feed(chunk)
    arrays, meta = tracker.checkpoint()
    clutter_map = tracker.scan.scoring.maps[0]
    np.testing.assert_array_equal(arrays["scoring.0.grid"], clutter_map.grid)
    assert clutter_map.params[0] > 0  # exposure: the map has learnt
    assert len(arrays["pending.time"]) == len(tracker.pending) > 0  # the open windows' plots
    assert meta["next_track_id"] == tracker.scan.next_track_id
    # the restored tracker's learnt state is the original's, not a fresh prior
    restored = Tracker.restore(demo.sensors, TrackerConfig(), arrays, meta)
    np.testing.assert_array_equal(restored.scan.scoring.maps[0].grid, clutter_map.grid)
    np.testing.assert_array_equal(restored.scan.scoring.code_counts[0], tracker.scan.scoring.code_counts[0])
    assert restored.clock.next == tracker.clock.next


def test_state_of_another_filter_is_refused(demo):
    tracker = Tracker(demo.sensors, TrackerConfig())
    for chunk in chunks_of(demo.plots)[:3]:
        tracker.feed(chunk)
    arrays, meta = tracker.checkpoint()
    with pytest.raises(ValueError, match="ManoeuvreState filter states; this tracker's filter keeps MixtureState"):
        Tracker.restore(demo.sensors, config_of("imm"), arrays, meta)


@pytest.mark.parametrize("scenario", ["two_radars", "radar3d", "airborne_crossing"])
def test_restored_tracker_continues_exactly_on_other_sensors(scenario):
    """Two merged radars (sectors, several clutter maps), a 3-D radar with range rates, and an
    airborne radar (no antenna schedule: the composed, not the compiled, window path)."""
    run = simulate(load_scenario(scenario))
    step = max(200, len(run.plots) // 12)
    chunks = [run.plots.iloc[start:start + step] for start in range(0, len(run.plots), step)]
    original = Tracker(run.sensors, TrackerConfig())
    for chunk in chunks[:5]:
        original.feed(chunk)
    original.drain()
    restored = Tracker.restore(run.sensors, TrackerConfig(), *original.checkpoint())
    for chunk in chunks[5:]:
        original.feed(chunk)
        restored.feed(chunk)
    original.finish()
    restored.finish()
    expected, actual = original.drain(), restored.drain()
    assert expected["track_id"].nunique() >= 2
    assert_same_tracks(expected, actual)


def test_state_is_a_snapshot(demo):
    """The arrays are copies: the tracker going on does not change a checkpoint being written."""
    chunks = chunks_of(demo.plots)
    tracker = Tracker(demo.sensors, TrackerConfig())
    for chunk in chunks[:4]:
        tracker.feed(chunk)
    arrays, _ = tracker.checkpoint()
    kept = {name: value.copy() for name, value in arrays.items()}
    tracker.feed(chunks[4])
    for name, value in arrays.items():
        np.testing.assert_array_equal(value, kept[name], err_msg=name)

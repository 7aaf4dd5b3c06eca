"""The tracker's compiled paths against the composed numpy reference.

The same plots tracked with (a) the compiled stage (fused gate kernel, compiled GNN, compiled
Kalman kernels) and (b) the reference parts (k-d tree search, scipy assignment per cluster,
numpy Kalman steps) give the same tracks table to 1e-9.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.sim import load_scenario, simulate
from skytrack.tracker import Tracker, TrackerConfig


def _reference(**flat) -> TrackerConfig:
    config = TrackerConfig(compiled=False, **flat)
    config.filter.options["compiled"] = False
    return config


@pytest.fixture(scope="module")
def crossing():
    return simulate(load_scenario("crossing"))


@pytest.mark.parametrize("flat", [{}, {"model": "singer"}, {"init": "two-point", "full_covariance": True}])
def test_compiled_tracker_equals_the_reference(crossing, flat):
    compiled = Tracker(crossing.sensors, TrackerConfig(**flat))
    tracks = compiled.run(crossing.plots)
    composed = Tracker(crossing.sensors, _reference(**flat))
    reference = composed.run(crossing.plots)
    assert len(tracks) > 100
    pd.testing.assert_frame_equal(tracks, reference, check_exact=False, rtol=1e-9, atol=1e-6)
    # the track scores and what the clutter map and the code counts learned are the same too
    np.testing.assert_allclose(compiled.bank.score, composed.bank.score, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(compiled.bank.score_max, composed.bank.score_max, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(compiled.scan.scoring.maps[0].counts, composed.scan.scoring.maps[0].counts,
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(compiled.scan.scoring.code_counts[0], composed.scan.scoring.code_counts[0])
    if not flat:
        assert compiled.scan.fused[0]  # the default configuration takes the fused stage


def test_imm_runs_inside_the_tracker(crossing):
    """A filter whose state is a mixture (IMM) tracks the crossing scenario through the same parts."""
    tracker = Tracker(crossing.sensors, TrackerConfig.from_dict({"filter": {"kind": "imm"}}))
    tracks = tracker.run(crossing.plots)
    baseline = Tracker(crossing.sensors, TrackerConfig()).run(crossing.plots)
    assert type(tracker.bank.state).__name__ == "MixtureState"
    assert not tracker.scan.fused[0]
    assert tracks["track_id"].nunique() >= 0.8 * baseline["track_id"].nunique()
    mu = tracker.bank.state.mu
    np.testing.assert_allclose(mu.sum(axis=1), 1.0, rtol=1e-12)


@pytest.mark.parametrize("scenario", ["radar3d", "two_radars"])
def test_compiled_parts_equal_the_reference_on_other_radars(scenario):
    """A 3-D radar with Doppler (composed path with compiled search, assignment and Kalman
    kernels) and two merged radars in sectors (the fused path): the same tracks as the reference."""
    result = simulate(load_scenario(scenario))
    tracks = Tracker(result.sensors, TrackerConfig()).run(result.plots)
    reference = Tracker(result.sensors, _reference()).run(result.plots)
    assert len(tracks) > 100
    pd.testing.assert_frame_equal(tracks, reference, check_exact=False, rtol=1e-9, atol=1e-6)


def test_large_clusters_through_the_sparse_solver_equal_the_reference(crossing, monkeypatch):
    """With the dense limit lowered, every multi-pair cluster of the compiled window goes back to
    Python's sparse matching and its update: the tracks stay those of the reference."""
    import skytrack.tracker.compiled as compiled

    monkeypatch.setattr(compiled, "MAX_DENSE_CLUSTER", 2)
    tracks = Tracker(crossing.sensors, TrackerConfig()).run(crossing.plots)
    reference = Tracker(crossing.sensors, _reference()).run(crossing.plots)
    pd.testing.assert_frame_equal(tracks, reference, check_exact=False, rtol=1e-9, atol=1e-6)


@pytest.fixture(scope="module")
def crossing_with_iff(crossing):
    """The crossing scenario's plots with IFF replies: each aircraft friend or foe, 30 % of plots
    without a reply, 10 % of replies flipped; false plots never reply."""
    plots = crossing.plots.copy()
    rng = np.random.default_rng(8)
    truth = plots["truth_id"].to_numpy()
    ids = pd.unique(truth[pd.notna(truth)])
    status = dict(zip(ids, rng.choice(["friend", "foe"], len(ids))))
    iff = np.array([status.get(t) if pd.notna(t) else None for t in truth], dtype=object)
    flip = rng.random(len(plots)) < 0.1
    iff[flip & (iff == "friend")], iff[flip & (iff == "foe")] = "foe", "friend"
    iff[rng.random(len(plots)) < 0.3] = None
    plots["iff"] = pd.array(iff, dtype="str")
    return plots


@pytest.mark.parametrize("rule", ["fuzzy", "crisp", "ml", "nn"])
def test_identity_rules_compiled_equal_the_reference(crossing, crossing_with_iff, rule):
    """Spec 003's rules in the tracker: the compiled stage's costs (pair_evidence) and the
    reference scorer (IdentityRuleScorer with the pairs' identity features) give the same tracks."""
    config = TrackerConfig(association_rule=rule)
    compiled = Tracker(crossing.sensors, config)
    tracks = compiled.run(crossing_with_iff)
    reference = Tracker(crossing.sensors, _reference(association_rule=rule)).run(crossing_with_iff)
    assert compiled.scan.fused[0]
    assert len(tracks) > 100
    pd.testing.assert_frame_equal(tracks, reference, check_exact=False, rtol=1e-9, atol=1e-6)
    if rule in ("fuzzy", "crisp"):  # the identity terms act: other tracks than coordinates alone
        coordinates = Tracker(crossing.sensors, TrackerConfig(association_rule="nn")).run(crossing_with_iff)
        assert not tracks[["x", "y"]].equals(coordinates[["x", "y"]])


def test_sequential_mode_takes_plots_one_at_a_time(crossing):
    """--association-mode sequential: the reference parts plot by plot; the tracks differ from the
    global assignment's only where plots compete."""
    sequential = Tracker(crossing.sensors, TrackerConfig(association_rule="nn", association_mode="sequential"))
    tracks = sequential.run(crossing.plots)
    assert not sequential.scan.fused[0]
    glob = Tracker(crossing.sensors, TrackerConfig(association_rule="nn")).run(crossing.plots)
    assert abs(tracks["track_id"].nunique() - glob["track_id"].nunique()) <= 0.1 * glob["track_id"].nunique()
    assert len(tracks) > 0.9 * len(glob)

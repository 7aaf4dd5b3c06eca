"""Spec 003 studies' tracker: rule equivalences (TV12) and secondary-radar behaviour (TV13)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from skytrack.association.features import CRISP_TABLES, FOE, FRIEND, UNDETERMINED, UNIT_TABLES
from skytrack.association.identity_rules import RuleConfig
from skytrack.sim.airborne import crossing_scenario
from skytrack.studies.fuzzy.crossing import CrossingCase, run_case
from skytrack.studies.fuzzy.paper_tracker import PaperTracker, PaperTrackerConfig
from skytrack.studies.fuzzy.runs import IffSettings, simulate_runs


def _run(plots, rule="fuzzy", mode="greedy", policy="track", tables=None, p_gate=0.99):
    rule_config = RuleConfig(rule=rule, mode=mode, p_gate=p_gate, **({} if tables is None else {"tables": tables}))
    return PaperTracker(PaperTrackerConfig(rule=rule_config, iff_policy=policy)).run(plots)


@pytest.fixture(scope="module")
def errors_always():
    """E4 reference scenario, 5 seeds, p_flip = p_code = 0.1 (TV12)."""
    return simulate_runs(crossing_scenario(5.0), 5, 7, IffSettings(0.9, 0.1, 0.1))


@pytest.mark.parametrize("mode", ["greedy", "global"])
def test_tv12_nn_is_fuzzy_with_unit_tables(errors_always, mode):
    nn = _run(errors_always.plots, "nn", mode, "always")
    unit = _run(errors_always.plots, "fuzzy", mode, "always", UNIT_TABLES)
    assert np.array_equal(nn.track_id, unit.track_id)
    paper = _run(errors_always.plots, "fuzzy", mode, "always")
    assert not np.array_equal(nn.track_id, paper.track_id)  # the features do act on these runs


@pytest.mark.parametrize("mode", ["greedy", "global"])
def test_tv12_crisp_is_fuzzy_with_zero_one_tables(errors_always, mode):
    crisp = _run(errors_always.plots, "crisp", mode, "always")
    zero_one = _run(errors_always.plots, "fuzzy", mode, "always", CRISP_TABLES)
    assert np.array_equal(crisp.track_id, zero_one.track_id)
    assert crisp.started.sum() > _run(errors_always.plots, "nn", mode, "always").started.sum()  # vetoes start tracks


@pytest.fixture(scope="module")
def parallel():
    """TV13 (a): two targets flying parallel 20 km apart, p_reply = 1, no errors."""
    return simulate_runs(crossing_scenario(0.0, d_e=20_000.0), 20, 3, IffSettings(1.0, 0.0, 0.0))


def test_tv13a_interrogation_follows_the_tracks(parallel):
    # rule nn: a plot starts a track exactly when no track gates it, and goes to its nearest gating
    # track, so the gating of (ii) can be read from the decisions
    decisions = _run(parallel.plots, rule="nn", policy="track")
    valid = parallel.plots.valid
    carries = decisions.plot_iff >= 0
    assert np.array_equal(carries, decisions.requested)  # p_reply = 1
    # (i) each object's first plot carries IFF
    for r in range(valid.shape[0]):
        for obj in (0, 1):
            scans, slots = np.nonzero(parallel.truth[r] == obj)
            assert carries[r, scans[0], slots[0]]
    # (ii) a plot carries IFF iff it started a track (no gating track) or went to a still undetermined one
    before = np.full(decisions.track_iff.shape, UNDETERMINED)
    for r in range(valid.shape[0]):
        label = {}
        for k, j in zip(*np.nonzero(valid[r])):
            tid = decisions.track_id[r, k, j]
            before[r, k, j] = label.get(tid, UNDETERMINED)
            label[tid] = decisions.track_iff[r, k, j]
    expected = decisions.started | (before == UNDETERMINED)
    assert np.array_equal(carries[valid], expected[valid])


def test_tv13a_iii_one_reply_per_object_with_a_wide_gate(parallel):
    decisions = _run(parallel.plots, policy="track", p_gate=1 - 1e-9)
    carries = decisions.plot_iff >= 0
    for obj in (0, 1):
        per_run = (carries & (parallel.truth == obj)).sum(axis=(1, 2))
        assert per_run.tolist() == [1] * len(per_run)


def test_tv13b_interrogations_until_the_first_reply_are_geometric():
    runs = 2000
    simulated = simulate_runs(replace(crossing_scenario(0.0, d_e=20_000.0), n_scans=21), runs, 5,
                              IffSettings(0.5, 0.0, 0.0))
    decisions = _run(simulated.plots, policy="track", p_gate=1 - 1e-9)
    counts = []
    for obj in (0, 1):
        mine = simulated.truth == obj
        requested = (decisions.requested & mine).reshape(runs, -1)
        replied = (decisions.plot_iff >= 0) & mine
        first = np.argmax(replied.reshape(runs, -1), axis=1)  # flat order = scan order
        assert replied.reshape(runs, -1).any(axis=1).all()
        upto = np.arange(requested.shape[1])[None, :] <= first[:, None]
        counts.append((requested & upto).sum(axis=1))
    counts = np.concatenate(counts)
    assert abs(counts.mean() - 2.0) <= 0.09
    assert counts.min() >= 1


def test_tv13c_reply_fraction_and_coordinate_rules_ignore_iff():
    kept, reply = [], []
    for case in (CrossingCase(policy="always"), CrossingCase(policy="always", p_reply=0.6, p_flip=0.2, p_code=0.3),
                 CrossingCase(policy="track", p_flip=0.1), CrossingCase(policy="never")):
        decisions = {}
        run_case(case, ("nn", "ml"), 30, 4, keep=decisions)
        kept.append(decisions)
        if case.policy == "always":
            got = decisions["nn"]
            n = int(got.requested.sum())
            fraction = (got.plot_iff >= 0).sum() / n
            reply.append(abs(fraction - case.p_reply) <= 4 * math.sqrt(case.p_reply * (1 - case.p_reply) / n))
    assert all(reply)
    for method in ("nn", "ml"):
        assert all(np.array_equal(kept[0][method].track_id, k[method].track_id) for k in kept[1:])


def _single_target(valid_scans=None, replies=None):
    """One run of target A alone (B withheld), with chosen replies per scan."""
    simulated = simulate_runs(crossing_scenario(0.0, d_e=20_000.0), 1, 9, IffSettings(1.0, 0.0, 0.0))
    plots = simulated.plots
    plots.valid &= simulated.truth == 0
    if valid_scans is not None:
        plots.valid[:, ~valid_scans] = False
    if replies is not None:
        for k, status in replies.items():
            plots.reply_iff[0, k] = status
    return plots, simulated


def test_tv13d_latest_definite_reply_wins():
    plots, _ = _single_target(replies={1: FOE, 2: -1})
    plots.reply_iff[0, 0] = np.where(plots.valid[0, 0], FRIEND, -1)
    always = _run(plots, policy="always")
    slot = lambda k: np.flatnonzero(plots.valid[0, k])[0]  # noqa: E731
    assert always.track_iff[0, 0, slot(0)] == FRIEND
    assert always.track_iff[0, 1, slot(1)] == FOE  # flipped reply relabels the track
    assert always.plot_iff[0, 2, slot(2)] == -1
    assert always.track_iff[0, 2, slot(2)] == FOE  # no reply: the label stays
    assert len(np.unique(always.track_id[plots.valid])) == 1
    track = _run(plots, policy="track")
    assert track.requested[0, 0].any() and not track.requested[0, 1:].any()  # determined: not re-interrogated


def test_tv13e_deleted_track_is_interrogated_again():
    keep = np.ones(61, dtype=bool)
    keep[10:13] = False  # max_misses = 3 scans without plots
    plots, _ = _single_target(valid_scans=keep)
    decisions = _run(plots, policy="track")
    slot13 = np.flatnonzero(plots.valid[0, 13])[0]
    assert decisions.started[0, 13, slot13] and decisions.requested[0, 13, slot13]
    assert decisions.requested[0].sum() == 2
    keep[12] = True  # two misses only: the track survives and is not interrogated
    plots, _ = _single_target(valid_scans=keep)
    decisions = _run(plots, policy="track")
    assert decisions.requested[0].sum() == 1 and len(np.unique(decisions.track_id[plots.valid])) == 1


def test_r3_track_overhead_of_the_own_ship_is_left_out_and_counted():
    """A track straight above the own-ship (rho < 1e-6 D) is no hypothesis: the next plot starts a
    new track, and the excluded pair is counted."""
    from skytrack.studies.fuzzy.paper_tracker import RunPlots

    own_p = np.zeros((1, 3, 3))
    own_p[..., 2] = 8000.0
    own_v = np.zeros((1, 3, 3))
    z = np.zeros((1, 3, 1, 4))
    z[0, :, 0] = [2000.0, 0.0, np.pi / 2, 0.0]  # straight up, not moving
    noise = np.diag([30.0, 0.005, 0.005, 2.0]) ** 2
    plots = RunPlots(np.array([0.0, 2.0, 4.0]), z, np.ones((1, 3, 1), bool), own_p, own_v, noise,
                     np.full((1, 3, 1), -1), np.full((1, 3, 1), -1))
    decisions = _run(plots, rule="nn", policy="never")
    assert decisions.started[0, :, 0].tolist() == [True, True, True]
    assert decisions.degenerate_pairs == 1 + 2  # scan 1: one overhead track; scan 2: two


def test_r13_diagnostic_rows_of_the_studies_tracker(errors_always):
    """One row per (plot, hypothesis) with the new object as track -1; exactly one chosen per plot,
    the one the decision took; ln mu = -d2/2 + ln(mu_G mu_N) (D3)."""
    tracker = PaperTracker(PaperTrackerConfig(rule=RuleConfig(rule="fuzzy", mode="global"), iff_policy="always"),
                           diagnostics=True)
    decisions = tracker.run(errors_always.plots)
    rows = decisions.diagnostics
    chosen = rows[rows.chosen].set_index(["run", "scan", "plot_slot"]).sort_index()
    assert chosen.index.is_unique and len(chosen) == int(errors_always.plots.valid.sum())
    run, scan, slot = (chosen.index.get_level_values(i).to_numpy() for i in range(3))
    took = decisions.track_id[run, scan, slot]
    started = decisions.started[run, scan, slot]
    np.testing.assert_array_equal(np.where(started, -1, took), chosen["track_id"].to_numpy())
    tracks = rows[rows.track_id >= 0]
    np.testing.assert_allclose(tracks.ln_mu, -0.5 * tracks.d2 + np.log(tracks.mu_G * tracks.mu_N), rtol=1e-12)

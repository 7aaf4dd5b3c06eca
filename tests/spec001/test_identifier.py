"""Spec 001 R13, R14, R17: many-to-many identification (TV-6, TV-7), compiled loop vs numpy reference."""

import numpy as np
import pytest

from skytrack.identify.assignment import PairTable, assign_pairs
from skytrack.identify.identifier import IdentifierConfig, TrackIdentifier
from skytrack.identify.threshold import Threshold


def _tv6_table():
    radar = np.array([[0.0, 0.0], [150.0, 0.0], [5000.0, 5000.0]])
    adsb = np.array([[90.0, 0.0], [240.0, 0.0], [-3000.0, 0.0]])
    first, second = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    first, second = first.ravel(), second.ravel()
    lam = np.sum((radar[first] - adsb[second]) ** 2, axis=1) / 2900.0
    h = Threshold(p_correct=0.99).value(np.full(9, 2))
    return PairTable(first, second, lam, np.full(9, 2), h, lam <= h, lam - h), lam, h


def test_tv6_global_and_greedy():
    table, lam, h = _tv6_table()
    assert h[0] == pytest.approx(9.210340, abs=1e-6)
    np.testing.assert_allclose(lam[[0, 1, 3, 4]], [2.793103, 19.862069, 1.241379, 2.793103], atol=1e-6)
    assert np.all(np.delete(lam, [0, 1, 3, 4]) > 3000)
    chosen = assign_pairs(table, 3, 3, "global")
    assert sorted(zip(table.first[chosen], table.second[chosen])) == [(0, 0), (1, 1)]
    assert table.cost[chosen].sum() == pytest.approx(-12.834474, abs=1e-6)
    greedy = assign_pairs(table, 3, 3, "greedy")
    assert list(zip(table.first[greedy], table.second[greedy])) == [(1, 0)]
    assert table.cost[greedy].sum() == pytest.approx(-7.968961, abs=1e-6)


def _feed_tv7(identifier, adsb, radar):
    reports = sorted([(t, 1, "R", x, y, 2500.0) for t, x, y in radar] + [(t, 2, "A", x, y, 400.0) for t, x, y in adsb])

    def feed(rows):
        identifier.process([r[1] for r in rows], [r[2] for r in rows], [r[0] for r in rows],
                           [[r[3], r[4]] for r in rows], [np.eye(2) * r[5] for r in rows])

    feed([r for r in reports if r[0] <= 1.3])  # the pair is made at 1.3, when both tracks have rank n
    values = [identifier.pairs.statistic[0]]
    for r in reports:
        if r[0] > 1.3:
            feed([r])
            values.append(identifier.pairs.statistic[0])
    return values


TV7 = {  # (init, q, case) -> Lambda after reports 1.3, 2.0, 2.3, 3.0, 3.3
    ("fuse", 0, "same"): [2.975266, 2.486850, 1.138368, 3.499557, 2.146285],
    ("fuse", 0, "diff"): [21.332392, 38.191251, 36.745507, 44.228133, 43.622824],
    ("fuse", 25, "same"): [2.970700, 2.479687, 1.138780, 3.495882, 2.156411],
    ("fuse", 25, "diff"): [21.240623, 38.097059, 36.675035, 44.114638, 43.559664],
    ("replay", 25, "same"): [2.974757, 2.483739, 1.142691, 3.498541, 2.157224],
    ("replay", 25, "diff"): [21.330530, 38.154683, 36.744075, 44.160816, 43.620694],
    ("replay", 0, "same"): [2.975266, 2.486850, 1.138368, 3.499557, 2.146285],
}


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("init,q,case", sorted(TV7))
def test_tv7_online_pair_initialisation(tv3, init, q, case, compiled):
    time, system, z, _ = tv3(case)
    radar = [(t, *p) for t, s, p in zip(time, system, z) if s == 1]
    adsb = [(t, *p) for t, s, p in zip(time, system, z) if s == 2]
    identifier = TrackIdentifier(IdentifierConfig(q=q, pair_init=init, batch_s=100.0, compiled=compiled,
                                                  drop_count=100))
    np.testing.assert_allclose(_feed_tv7(identifier, adsb, radar), TV7[(init, q, case)], atol=1e-6)


def _crossing_reports(seed=3, n_pairs=12, duration=60.0):
    """Radar tracks (1 s, 50 m) and ADS-B tracks (1 s, offset phase, 20 m) of objects 300 m apart."""
    rng = np.random.default_rng(seed)
    start = np.column_stack([np.arange(n_pairs) * 300.0, np.zeros(n_pairs)])
    velocity = np.column_stack([np.full(n_pairs, 150.0), rng.normal(0, 5, n_pairs)])
    rows = []
    for side, sigma, phase in ((1, 50.0, 0.0), (2, 20.0, 0.4)):
        t = np.arange(phase, duration, 1.0)
        for k in range(n_pairs):
            pos = start[k] + velocity[k] * t[:, None] + rng.normal(0, sigma, (len(t), 2))
            for ti, p in zip(t, pos):
                rows.append((ti, side, f"{'R' if side == 1 else 'A'}{k}", p, sigma ** 2 * np.eye(2)))
    rows.sort(key=lambda r: (r[0], r[1]))
    return rows


def _run_identifier(rows, compiled, chunk=7, **settings):
    identifier = TrackIdentifier(IdentifierConfig(q=0.5, gate_m=1000.0, batch_s=2.0, compiled=compiled, **settings))
    for start in range(0, len(rows), chunk):
        part = rows[start:start + chunk]
        identifier.process([r[1] for r in part], [r[2] for r in part], [r[0] for r in part],
                           [r[3] for r in part], [r[4] for r in part])
    return identifier


@pytest.mark.parametrize("settings", [{}, {"report_gate": 0.99, "horizon_s": 10.0}])
def test_compiled_loop_equals_numpy_reference(settings):
    rows = _crossing_reports()
    fast, slow = _run_identifier(rows, True, **settings), _run_identifier(rows, False, **settings)
    size = fast.pairs.size
    assert size == slow.pairs.size > 12  # neighbours 300 m apart are candidates too
    np.testing.assert_allclose(fast.pairs.statistic[:size], slow.pairs.statistic[:size], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(fast.pairs.alive[:size], slow.pairs.alive[:size])
    np.testing.assert_allclose(fast.tracks.J, slow.tracks.J, rtol=1e-9)
    np.testing.assert_allclose(fast.pairs.joint.P[:size], slow.pairs.joint.P[:size], rtol=1e-8, atol=1e-9)
    assert fast.stats == slow.stats
    if settings:
        assert fast.stats["reports_gated"] > 0 and fast.stats["pairs_refreshed"] > 0


def test_assignment_identifies_every_pair_and_drops_neighbours():
    identifier = _run_identifier(_crossing_reports(), True)
    result = identifier.assign()
    assert sorted(zip(result.first_id, result.second_id)) == sorted((f"R{k}", f"A{k}") for k in range(12))
    assert len(result.unmatched_first) == len(result.unmatched_second) == 0
    # 300 m apart with 50 m / 20 m reports for a minute: neighbours' pairs were dropped
    alive = identifier.pairs.alive[:identifier.pairs.size]
    assert alive.sum() == 12 and identifier.stats["pairs_dropped"] > 0
    assert identifier.mean_pairs_per_report > 0


def test_fusion_joint_and_information():
    identifier = _run_identifier(_crossing_reports(), True)
    result = identifier.assign()
    x_joint, P_joint = identifier.fused(result.pair, "joint", t=60.0)
    x_info, P_info = identifier.fused(result.pair, "information", t=60.0)
    assert np.abs(x_joint[:, :2] - x_info[:, :2]).max() < 20.0
    # with process noise the joint covariance is the larger one (R14: P_joint - P_information >= 0)
    assert np.linalg.eigvalsh(P_joint - P_info).min() > -1e-9


def test_bayesian_cost_needs_density_and_gives_posteriors():
    with pytest.raises(ValueError, match="object_density"):
        IdentifierConfig(cost="bayes")
    rows = _crossing_reports()
    identifier = TrackIdentifier(IdentifierConfig(q=0.5, gate_m=1000.0, cost="bayes", object_density=1e-12))
    identifier.process([r[1] for r in rows], [r[2] for r in rows], [r[0] for r in rows],
                       [r[3] for r in rows], [r[4] for r in rows])
    result = identifier.assign()
    assert len(result.first_id) == 12 and np.all(result.p_same > 0.99)


def test_report_errors_name_the_report():
    identifier = TrackIdentifier()
    with pytest.raises(ValueError, match="report 1: unknown system 3"):
        identifier.process([1, 3], ["a", "b"], [0.0, 0.0], np.zeros((2, 2)), np.stack([np.eye(2)] * 2))
    with pytest.raises(ValueError, match="report 0: NaN"):
        identifier.process([1], ["a"], [0.0], [[np.nan, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="singular"):
        identifier.process([1], ["a"], [0.0], [[0.0, 0.0]], [np.zeros((2, 2))])
    identifier.process([1], ["a"], [5.0], [[0.0, 0.0]], [np.eye(2)])
    with pytest.raises(ValueError, match="goes back"):
        identifier.process([1], ["a"], [4.0], [[0.0, 0.0]], [np.eye(2)])
    identifier.end_tracks(1, ["a"])
    with pytest.raises(ValueError, match="has ended"):
        identifier.process([1], ["a"], [6.0], [[0.0, 0.0]], [np.eye(2)])


def test_replay_uses_the_last_reports_of_each_track(tv3):
    """With a 3-report buffer the replayed pair equals the sequential test on the last 3 reports of
    each track (the buffer wrapped), merged in time order."""
    from skytrack.identify.model import cv_model
    from skytrack.identify.sequential import SequentialPairTest

    time, system, z, V = tv3("same")
    identifier = TrackIdentifier(IdentifierConfig(q=25.0, pair_init="replay", history=3, batch_s=100.0))
    identifier.process(system, np.where(system == 1, "R", "A"), time, z, V)
    keep = np.r_[1, 2, 3, 5, 6, 7]  # the last three of each system
    expected = SequentialPairTest(cv_model(2, 25.0))
    expected.run(time[keep], system[keep], z[keep], V[keep])
    assert identifier.pairs.size == 1
    assert identifier.pairs.statistic[0] == pytest.approx(expected.statistic[0], abs=1e-9)
    np.testing.assert_allclose(identifier.pairs.joint.x[0], expected.joint.x[0], atol=1e-9)

"""Spec 003 R19: association metrics (owner, CAR, pre/post windows, kept / swapped / broken, SEs)
on small hand-built crossing runs with k_c = 30 (pre window scans 20-24, post window 35-39)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skytrack.analysis.association_metrics import association_metrics, binomial_se

K_C = 30
SCANS = range(61)


def plots_of(run: int, assignment: dict[int, dict[int, int]]) -> list[tuple[int, int, int, int]]:
    """Rows (run, scan, truth, track) from {object: {scan: track}}; scans in order, objects in order."""
    rows = []
    for scan in SCANS:
        for obj in sorted(assignment):
            if scan in assignment[obj]:
                rows.append((run, scan, obj, assignment[obj][scan]))
    return rows


def steady(track: int, scans=SCANS) -> dict[int, int]:
    return {k: track for k in scans}


def metrics(rows, **kwargs):
    run, scan, truth, track = (np.array(col) for col in zip(*rows))
    return association_metrics(run, scan, truth, track, K_C, **kwargs)


def outcomes(result) -> dict[tuple[int, int], str]:
    return {(r.run, r.object): r.outcome for r in result.objects.itertuples()}


def test_kept_tracks_all_plots_correct():
    result = metrics(plots_of(0, {0: steady(0), 1: steady(1)}))
    assert outcomes(result) == {(0, 0): "kept", (0, 1): "kept"}
    assert result.summary["car"] == 1.0
    assert result.summary["kept"] == 1.0 and result.summary["swapped"] == 0.0
    assert result.objects[["t_pre", "t_post"]].to_numpy().tolist() == [[0, 0], [1, 1]]


def test_swap_at_the_crossing():
    a = {k: (0 if k <= K_C else 1) for k in SCANS}
    b = {k: (1 if k <= K_C else 0) for k in SCANS}
    result = metrics(plots_of(0, {0: a, 1: b}))
    assert outcomes(result) == {(0, 0): "swapped", (0, 1): "swapped"}
    # scans 31..60 of both objects go to the other object's track
    assert result.summary["target_plots"] == 122
    assert result.summary["car"] == pytest.approx(62 / 122, rel=1e-15)
    assert result.summary["swapped"] == 1.0


def test_broken_by_an_empty_post_window():
    a = {k: 0 for k in SCANS if not 35 <= k <= 39}
    result = metrics(plots_of(0, {0: a, 1: steady(1)}))
    assert outcomes(result) == {(0, 0): "broken", (0, 1): "kept"}
    assert result.objects.loc[0, "t_post"] == -1
    assert result.summary["broken"] == 0.5


def test_empty_pre_window_swapped_only_onto_another_objects_pre_track():
    # object 0 has no plot in scans 20-24; its post-window track is object 1's pre track (R19's
    # "swapped if T_post(o) = T_pre(o') for another object o'" does not need T_pre(o))
    a = {k: (0 if k < 20 else 1) for k in SCANS if not 20 <= k <= 24}
    result = metrics(plots_of(0, {0: a, 1: steady(1)}))
    assert outcomes(result) == {(0, 0): "swapped", (0, 1): "kept"}
    # ...but with object 1 absent from the pre window too, nothing is left to swap with: broken
    b = {k: 1 for k in SCANS if not 20 <= k <= 24}
    result = metrics(plots_of(0, {0: a, 1: b}))
    assert outcomes(result) == {(0, 0): "broken", (0, 1): "broken"}


def test_new_track_after_the_crossing_is_broken_and_its_start_is_incorrect():
    # object 0 starts track 5 at scan 31 while its track 0 is alive: one incorrect plot; the
    # later plots of track 5 are correct (track 5 is owned by object 0)
    a = {k: (0 if k <= K_C else 5) for k in SCANS}
    result = metrics(plots_of(0, {0: a, 1: steady(1)}))
    assert outcomes(result) == {(0, 0): "broken", (0, 1): "kept"}
    wrong = result.plots[~result.plots["correct"]]
    assert wrong[["scan", "truth", "track"]].to_numpy().tolist() == [[31, 0, 5]]
    assert bool(wrong["starts_track"].iloc[0])
    assert result.summary["car"] == pytest.approx(121 / 122, rel=1e-15)


@pytest.mark.parametrize("post_track, expected", [(1, "kept"), (3, "broken")])
def test_tie_in_the_window_goes_to_the_lower_track_id(post_track, expected):
    # pre window: scans 20, 21 on track 3 (started first), 22, 23 on track 1, 24 missing: 2 - 2 tie -> 1
    a = {k: 3 for k in range(22)}
    a.update({22: 1, 23: 1})
    a.update({k: post_track for k in range(25, 61)})
    result = metrics(plots_of(0, {0: a}))
    assert result.objects.loc[0, "t_pre"] == 1
    assert result.objects.loc[0, "t_post"] == post_track
    assert outcomes(result)[(0, 0)] == expected


def test_majority_beats_lower_id():
    a = {k: 4 for k in SCANS}
    a[20] = 2  # one plot of track 2 in the pre window, four of track 4
    result = metrics(plots_of(0, {0: a}))
    assert result.objects.loc[0, "t_pre"] == 4
    assert outcomes(result)[(0, 0)] == "kept"


def test_new_track_while_the_objects_track_is_alive_is_incorrect():
    # track 0 has its last plot at scan 9; max_misses = 3 deletes it after scan 12
    alive = {**{k: 0 for k in range(10)}, **{k: 1 for k in range(12, 61)}}
    dead = {**{k: 0 for k in range(10)}, **{k: 1 for k in range(13, 61)}}
    got_alive = metrics(plots_of(0, {0: alive}))
    got_dead = metrics(plots_of(0, {0: dead}))
    start_alive = got_alive.plots[got_alive.plots["scan"] == 12].iloc[0]
    start_dead = got_dead.plots[got_dead.plots["scan"] == 13].iloc[0]
    assert start_alive["starts_track"] and not start_alive["correct"]
    assert start_dead["starts_track"] and start_dead["correct"]
    assert got_dead.summary["car"] == 1.0
    # with a longer miss limit the track at scan 13 is still alive
    assert not metrics(plots_of(0, {0: dead}), max_misses=4).plots.query("scan == 13")["correct"].iloc[0]


def test_new_track_while_only_another_objects_track_is_alive_is_correct():
    # object 1 appears at scan 10 and starts track 1 while object 0's track 0 is alive
    result = metrics(plots_of(0, {0: steady(0), 1: steady(1, range(10, 61))}))
    assert result.summary["car"] == 1.0


def test_false_plots_own_tracks_and_are_not_counted():
    rows = plots_of(0, {0: {**{k: 0 for k in range(5)}, **{k: 7 for k in range(6, 61)}}})
    rows.insert(5, (0, 5, -1, 7))  # a false plot at scan 5 starts track 7, which object 0 then joins
    result = metrics(rows)
    assert result.summary["target_plots"] == 60
    plots = result.plots
    assert (plots.loc[plots["track"] == 7, "owner"] == -1).all()
    assert result.summary["car"] == pytest.approx(5 / 60, rel=1e-15)
    assert outcomes(result) == {(0, 0): "kept"}  # a window outcome ignores ownership


def test_runs_at_once_equal_runs_alone_and_row_order_across_scans_is_irrelevant():
    a_swap = {k: (0 if k <= K_C else 1) for k in SCANS}
    b_swap = {k: (1 if k <= K_C else 0) for k in SCANS}
    runs = [plots_of(0, {0: steady(0), 1: steady(1)}), plots_of(1, {0: a_swap, 1: b_swap}),
            plots_of(2, {0: {k: 0 for k in SCANS if k < 35}, 1: steady(1)}),
            plots_of(3, {0: steady(0), 1: steady(1)})]
    rows = [row for rows in runs for row in rows]
    rng = np.random.default_rng(0)
    shuffled = [rows[i] for i in rng.permutation(len(rows))]
    # the shuffle also permutes plots within a scan; in these runs no two plots of one scan share
    # a track, so no track's first plot changes
    together = metrics(shuffled)
    alone = [metrics(r) for r in runs]
    assert outcomes(together) == {key: value for r in alone for key, value in outcomes(r).items()}
    correct = sum(r.summary["car"] * r.summary["target_plots"] for r in alone)
    assert together.summary["car"] == pytest.approx(correct / together.summary["target_plots"], rel=1e-12)
    s = together.summary
    assert (s["runs"], s["object_runs"], s["kept_count"], s["swapped_count"], s["broken_count"]) == (4, 8, 5, 2, 1)


def test_rates_carry_binomial_standard_errors():
    a_swap = {k: (0 if k <= K_C else 1) for k in SCANS}
    b_swap = {k: (1 if k <= K_C else 0) for k in SCANS}
    rows = plots_of(0, {0: a_swap, 1: b_swap}) + plots_of(1, {0: steady(0), 1: steady(1)}) \
        + plots_of(2, {0: steady(0), 1: steady(1)}) + plots_of(3, {0: steady(0), 1: steady(1)})
    s = metrics(rows).summary
    assert s["swapped"] == 0.25 and s["kept"] == 0.75 and s["broken"] == 0.0
    assert s["swapped_se"] == pytest.approx(math.sqrt(0.25 * 0.75 / 8), rel=1e-15)
    assert s["kept_se"] == pytest.approx(math.sqrt(0.75 * 0.25 / 8), rel=1e-15)
    assert s["broken_se"] == 0.0
    car = (62 + 3 * 122) / (4 * 122)
    assert s["car"] == pytest.approx(car, rel=1e-15)
    assert s["car_se"] == pytest.approx(math.sqrt(car * (1 - car) / 488), rel=1e-12)
    per_run = np.array([62 / 122, 1.0, 1.0, 1.0])
    assert s["car_se_runs"] == pytest.approx(per_run.std(ddof=1) / 2.0, rel=1e-12)
    assert binomial_se(3, 12) == pytest.approx(math.sqrt(0.25 * 0.75 / 12), rel=1e-15)
    assert np.allclose(binomial_se(np.array([0, 5]), np.array([10, 10])), [0.0, math.sqrt(0.25 / 10)])


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="track ids"):
        association_metrics([0], [0], [0], [-1], K_C)
    with pytest.raises(ValueError, match="scan has 2 entries"):
        association_metrics([0], [0, 1], [0], [0], K_C)
    with pytest.raises(ValueError, match="integers"):
        association_metrics([0], [np.nan], [0], [0], K_C)

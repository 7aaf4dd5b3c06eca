"""skytrack.analysis.evaluate on constructed truth / track tables (FORMATS.md layouts)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from skytrack.analysis import coverage_check, evaluate, infer_output_times, truth_visible_runs

DT = 4.0
STEPS = np.arange(20) * DT  # output instants 0 .. 76 s


def truth_rows(target_id, p0, v, times, visible=True, segment=0):
    """Straight-line truth sampled at ``times``."""
    times = np.asarray(times, float)
    p = np.asarray(p0, float) + times[:, None] * np.asarray(v, float)
    vis = np.broadcast_to(np.asarray(visible, bool), times.shape)
    return pd.DataFrame(
        {
            "time": times, "target_id": target_id, "segment": segment,
            "x": p[:, 0], "y": p[:, 1], "z": p[:, 2],
            "vx": float(v[0]), "vy": float(v[1]), "vz": float(v[2]), "visible": vis,
        }
    )


def track_rows(track_id, p0, v, times, offset=(0.0, 0.0, 0.0), vel_offset=(0.0, 0.0, 0.0), variances=(100.0, 4.0)):
    times = np.asarray(times, float)
    p = np.asarray(p0, float) + times[:, None] * np.asarray(v, float) + np.asarray(offset, float)
    vel = np.asarray(v, float) + np.asarray(vel_offset, float)
    frame = pd.DataFrame(
        {
            "time": times, "track_id": np.int64(track_id),
            "x": p[:, 0], "y": p[:, 1], "z": p[:, 2],
            "vx": vel[0], "vy": vel[1], "vz": vel[2],
        }
    )
    for a in "xyz":
        frame[f"var_{a}"] = variances[0]
        frame[f"var_v{a}"] = variances[1]
    frame["status"] = "confirmed"
    frame["n_updates"] = np.arange(len(frame), dtype=np.int64) + 3
    return frame


V = (150.0, 0.0, 0.0)


def test_rmse_of_known_offsets_with_interpolated_truth():
    # truth rows every 3 s (never at the 4 s instants except multiples of 12 s): linear
    # motion, so the interpolated truth is exact and errors are exactly the offsets
    t_truth = np.arange(0.0, 79.0, 3.0)
    truth = pd.concat(
        [
            truth_rows("a", (0, 0, 5000), V, t_truth),
            truth_rows("b", (0, 50e3, 6000), V, t_truth),
            truth_rows("c", (0, 100e3, 7000), V, t_truth),
        ]
    )
    tracks = pd.concat(
        [
            track_rows(1, (0, 0, 5000), V, STEPS[STEPS <= 78], offset=(30, 40, 0), vel_offset=(3, 4, 0)),
            track_rows(2, (0, 50e3, 6000), V, STEPS, offset=(0, 0, 120)),
            track_rows(3, (0, 100e3, 7000), V, STEPS),
        ]
    )
    ev = evaluate(tracks, truth)
    s = ev.summary
    assert ev.dimension == "3-D"
    assert s["position_rmse_m"] == pytest.approx(math.sqrt((50**2 + 120**2) / 3), rel=1e-9)
    assert s["position_rmse_horizontal_m"] == pytest.approx(math.sqrt(50**2 / 3), rel=1e-9)
    assert s["position_rmse_vertical_m"] == pytest.approx(math.sqrt(120**2 / 3), rel=1e-9)
    assert s["velocity_rmse_mps"] == pytest.approx(math.sqrt(25 / 3), rel=1e-9)
    per = ev.per_target.set_index("target_id")
    np.testing.assert_allclose(per.loc[["a", "b", "c"], "position_rmse_m"], [50.0, 120.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(per.loc[["a", "b", "c"], "velocity_rmse_mps"], [5.0, 0.0, 0.0], atol=1e-9)
    assert s["n_assigned"] == 60 and s["continuity_mean"] == 1.0
    # OSPA with c = 2 km, p = 2 at every instant: all assigned, sqrt(mean d^2)
    np.testing.assert_allclose(ev.series["ospa_m"], math.sqrt((50**2 + 120**2) / 3), rtol=1e-9)
    np.testing.assert_allclose(ev.series["gospa_m"], math.sqrt(50**2 + 120**2), rtol=1e-9)


def test_piecewise_linear_truth_is_interpolated_between_rows():
    # truth turns at t = 10 s: rows at 0, 10, 20; instant 4 s lies on the first leg, 12 s on the second
    truth = pd.DataFrame(
        {"time": [0.0, 10.0, 20.0], "target_id": "a", "segment": 0, "x": [0.0, 1000.0, 1000.0], "y": [0.0, 0.0, 2000.0],
         "z": 0.0, "vx": [100.0, 100.0, 0.0], "vy": [0.0, 200.0, 200.0], "vz": 0.0, "visible": True}
    )
    tracks = pd.DataFrame({"time": [4.0, 12.0], "track_id": 7, "x": [400.0, 1000.0], "y": [0.0, 400.0], "z": 0.0,
                           "vx": [100.0, 20.0], "vy": [0.0, 200.0], "vz": 0.0})
    ev = evaluate(tracks, truth, output_times=[4.0, 12.0])
    np.testing.assert_allclose(ev.assignments["distance_m"], [0.0, 0.0], atol=1e-9)
    # velocity truth at 4 s = 0.6 (100, 0) + 0.4 (100, 200) = (100, 80),
    # at 12 s = 0.8 (100, 200) + 0.2 (0, 200) = (80, 200)
    np.testing.assert_allclose(ev.assignments["velocity_error_mps"], [80.0, 60.0], atol=1e-9)
    assert ev.nees["covariance"].startswith("unavailable")


def test_horizontal_evaluation_for_2d_tracks():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, STEPS, offset=(0, 30, 900))
    tracks["z"] = np.nan
    tracks["vz"] = np.nan
    ev = evaluate(tracks, truth)
    assert ev.dimension.startswith("horizontal")
    assert ev.to_dict()["dimension"].startswith("horizontal")
    assert ev.summary["position_rmse_m"] == pytest.approx(30.0)
    assert ev.summary["position_rmse_vertical_m"] is None
    assert ev.nees["dimension"] == 4 and ev.nees["state"] == "position+velocity"
    with pytest.raises(ValueError, match="'z'"):
        evaluate(tracks, truth, horizontal=False)


NAMES = ["x", "y", "z", "vx", "vy", "vz"]
# where x, y, z, vx, vy, vz sit in the tracker's per-axis state vector (spec 000 R1)
STATE_INDEX = {"cv": [0, 2, 4, 1, 3, 5], "ca": [0, 3, 6, 1, 4, 7]}


def _nees_scenario(layout: str, seed: int):
    """300 separated targets x 10 instants; every track has its own covariance P and errors
    ~ N(0, P) on (x, y, z, vx, vy, vz).  ``layout`` is how P is written: ``named`` cov_x_vy
    columns, ``cv`` / ``ca`` skytrack's indexed cov_i_j over a 6- / 9-state filter, or
    ``diagonal`` (P diagonal, var_* columns only)."""
    rng = np.random.default_rng(seed)
    n_state = {"cv": 6, "ca": 9}.get(layout, 6)
    scale = np.sqrt(np.array([900.0, 4.0, 0.25] if layout == "ca" else [900.0, 4.0]))
    scale = np.tile(scale, 3)  # per-axis blocks
    times = np.arange(10) * DT
    truths, tracks = [], []
    for i in range(300):
        p0 = (40e3 * (i % 20), 40e3 * (i // 20), 8000.0)
        truth = truth_rows(f"t{i:03d}", p0, V, times)
        A = rng.normal(size=(n_state, n_state))
        state_P = (A @ A.T / n_state + 0.5 * np.eye(n_state)) * np.outer(scale, scale)
        if layout == "diagonal":
            state_P = np.diag(np.diag(state_P))
        index = STATE_INDEX.get(layout, [0, 2, 4, 1, 3, 5])
        P = state_P[np.ix_(index, index)]  # covariance of (x, y, z, vx, vy, vz)
        trk = truth[["time", *NAMES]].copy()
        trk[NAMES] = trk[NAMES].to_numpy() + rng.multivariate_normal(np.zeros(6), P, size=times.size)
        trk["track_id"] = i
        extra = {f"var_{name}": P[a, a] for a, name in enumerate(NAMES)}
        if layout == "named":
            extra.update({f"cov_{NAMES[a]}_{NAMES[b]}": P[a, b] for a in range(6) for b in range(a + 1, 6)})
        elif layout in STATE_INDEX:
            extra.update({f"cov_{a}_{b}": state_P[a, b] for a in range(n_state) for b in range(a, n_state)})
        trk = trk.assign(**extra)
        truths.append(truth)
        tracks.append(trk)
    return pd.concat(tracks, ignore_index=True), pd.concat(truths, ignore_index=True)


@pytest.mark.parametrize("layout", ["named", "cv", "ca", "diagonal"])
def test_nees_of_gaussian_errors_is_the_dimension(layout):
    tracks, truth = _nees_scenario(layout, seed=11)
    ev = evaluate(tracks, truth, association_gate_m=5000.0)
    n = ev.nees
    assert n["covariance"].split(" ")[0] == ("diagonal" if layout == "diagonal" else "full")
    if layout in STATE_INDEX:
        order = {"cv": 2, "ca": 3}[layout]
        assert f"3 axes x {order} derivatives, checked against var_*" in n["covariance"]
    assert n["n_samples"] == 3000 and n["dimension"] == 6 and n["expected"] == 6.0
    # mean of 3000 chi2(6) samples: standard deviation sqrt(2 * 6 / 3000) = 0.063; allow 4 sigma
    assert abs(n["mean"] - 6.0) < 4 * math.sqrt(12 / 3000)
    assert abs(n["position_mean"] - 3.0) < 4 * math.sqrt(6 / 3000)
    assert n["band_95"][0] < 6.0 < n["band_95"][1]


def test_indexed_covariance_with_a_wrong_layout_falls_back_to_the_diagonal():
    tracks, truth = _nees_scenario("cv", seed=2)
    # var_* no longer match any per-axis layout of the cov_i_j columns
    shuffled = tracks.rename(columns={"cov_0_0": "cov_2_2", "cov_2_2": "cov_0_0"})
    n = evaluate(shuffled, truth, association_gate_m=5000.0).nees
    assert n["covariance"].startswith("diagonal (cov_* columns present")


def test_full_covariance_matters_for_correlated_errors():
    # errors strongly correlated between x and y: evaluating with the diagonal alone is wrong
    rng = np.random.default_rng(3)
    times = np.arange(10) * DT
    P = np.array([[100.0, 95.0], [95.0, 100.0]])
    truths, tracks = [], []
    for i in range(200):
        truth = truth_rows(f"t{i}", (30e3 * i, 0, 0), V, times)
        trk = truth[["time", "x", "y", "z"]].copy()
        trk[["x", "y"]] += rng.multivariate_normal([0, 0], P, size=times.size)
        trk["track_id"] = i
        trk["var_x"], trk["var_y"], trk["var_z"], trk["cov_x_y"] = 100.0, 100.0, 1.0, 95.0
        trk.loc[:, "cov_x_z"] = 0.0
        trk.loc[:, "cov_y_z"] = 0.0
        truths.append(truth)
        tracks.append(trk)
    tracks, truth = pd.concat(tracks, ignore_index=True), pd.concat(truths, ignore_index=True)
    full = evaluate(tracks, truth).nees
    assert full["covariance"] == "full" and full["state"] == "position" and full["dimension"] == 3
    # z errors are zero, so the mean is that of chi2(2): 2 +- 4 * sqrt(4 / 2000)
    assert abs(full["mean"] - 2.0) < 4 * math.sqrt(4 / 2000)
    diagonal = evaluate(tracks.drop(columns=["cov_x_y", "cov_x_z", "cov_y_z"]), truth).nees
    assert diagonal["covariance"] == "diagonal"
    assert diagonal["mean"] == pytest.approx(2.0, abs=4 * math.sqrt(4 / 2000))  # same trace, so same mean
    # but not the same distribution: with the full covariance NEES ~ chi2(2), variance 4 (the
    # sample variance of 2000 draws has a standard deviation of about 0.25); with the diagonal
    # alone the variance is 4 (1 + rho^2) = 7.61 for rho = 0.95
    full_var = np.var(evaluate(tracks, truth).assignments["nees"])
    diagonal_var = np.var(evaluate(tracks.drop(columns=["cov_x_y"]), truth).assignments["nees"])
    assert abs(full_var - 4.0) < 1.0
    assert diagonal_var > 1.5 * full_var


def test_replaced_track_is_one_break():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = pd.concat([track_rows(1, (0, 0, 5000), V, STEPS[:10]), track_rows(2, (0, 0, 5000), V, STEPS[10:])])
    ev = evaluate(tracks, truth)
    row = ev.per_target.iloc[0]
    assert (row["track_breaks"], row["track_swaps"], row["n_tracks"], row["continuity"]) == (1, 0, 2, 1.0)
    assert ev.summary["track_swaps"] == 0 and ev.summary["n_false_tracks"] == 0


def test_gap_is_a_break_and_lowers_continuity():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    gap = pd.concat([track_rows(1, (0, 0, 5000), V, STEPS[:8]), track_rows(2, (0, 0, 5000), V, STEPS[10:])])
    ev = evaluate(gap, truth, output_times=STEPS)
    row = ev.per_target.iloc[0]
    assert (row["track_breaks"], row["n_tracks"]) == (1, 2)
    assert row["continuity"] == pytest.approx(18 / 20)
    same_id = pd.concat([track_rows(1, (0, 0, 5000), V, STEPS[:5]), track_rows(1, (0, 0, 5000), V, STEPS[7:])])
    row = evaluate(same_id, truth, output_times=STEPS).per_target.iloc[0]
    assert (row["track_breaks"], row["n_tracks"], row["continuity"]) == (1, 1, pytest.approx(18 / 20))


def test_two_tracks_exchanging_truths_are_swaps():
    truth = pd.concat([truth_rows("a", (0, 0, 5000), V, STEPS), truth_rows("b", (0, 1500, 5000), V, STEPS)])
    first, second = STEPS[:10], STEPS[10:]
    tracks = pd.concat(
        [
            track_rows(1, (0, 0, 5000), V, first), track_rows(1, (0, 1500, 5000), V, second),
            track_rows(2, (0, 1500, 5000), V, first), track_rows(2, (0, 0, 5000), V, second),
        ]
    )
    ev = evaluate(tracks, truth, association_gate_m=1000.0)
    assert ev.summary["track_swaps"] == 2 and ev.summary["n_swapped_tracks"] == 2
    assert ev.per_track["swaps"].tolist() == [1, 1]
    assert ev.per_track["n_truths"].tolist() == [2, 2]
    per = ev.per_target.set_index("target_id")
    assert per["track_swaps"].tolist() == [1, 1] and per["track_breaks"].tolist() == [1, 1]
    assert per["continuity"].tolist() == [1.0, 1.0]


def test_far_track_and_duplicate_track_are_false():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = pd.concat(
        [
            track_rows(1, (0, 0, 5000), V, STEPS),
            track_rows(2, (500e3, 500e3, 5000), V, STEPS),  # far from everything
            track_rows(3, (0, 0, 5000), V, STEPS[:10], offset=(300, 0, 0)),  # duplicate: loses to track 1
        ]
    )
    ev = evaluate(tracks, truth)
    assert ev.false_track_ids == [2, 3]
    per = ev.per_track.set_index("track_id")
    assert per["n_assigned"].tolist() == [20, 0, 0]
    d = ev.to_dict()
    assert d["false_tracks"]["count"] == 2
    assert d["false_tracks"]["fraction_of_tracks"] == pytest.approx(2 / 3)
    assert d["false_tracks"]["fraction_of_track_time"] == pytest.approx(30 / 50)
    assert ev.series["gospa_false"].tolist() == [2] * 10 + [1] * 10


def test_false_threshold_on_assigned_fraction():
    # two truths far apart; track 3 is on truth b for 6 of its 10 instants (not false),
    # track 4 on truth c for 3 of 10 (false)
    truth = pd.concat([truth_rows("b", (0, 50e3, 5000), V, STEPS), truth_rows("c", (0, 100e3, 5000), V, STEPS)])
    tracks = pd.concat(
        [
            track_rows(3, (0, 50e3, 5000), V, STEPS[:6]), track_rows(3, (0, 75e3, 5000), V, STEPS[6:10]),
            track_rows(4, (0, 100e3, 5000), V, STEPS[:3]), track_rows(4, (0, 125e3, 5000), V, STEPS[3:10]),
        ]
    )
    ev = evaluate(tracks, truth, output_times=STEPS)
    per = ev.per_track.set_index("track_id")
    assert per.loc[3, "assigned_fraction"] == pytest.approx(0.6) and not per.loc[3, "is_false"]
    assert per.loc[4, "assigned_fraction"] == pytest.approx(0.3) and per.loc[4, "is_false"]
    assert ev.summary["false_track_time_fraction"] == pytest.approx(10 / 20)
    assert ev.summary["unassigned_track_time_fraction"] == pytest.approx(11 / 20)


def test_time_to_first_track_and_visibility():
    # 'a' visible from the start, tracked from 20 s; 'b' becomes visible at 10 s (row times
    # every 2 s), tracked from 24 s; 'c' is never visible and must not count anywhere
    t_rows = np.arange(0.0, 77.0, 2.0)
    truth = pd.concat(
        [
            truth_rows("a", (0, 0, 5000), V, t_rows),
            truth_rows("b", (0, 50e3, 5000), V, t_rows, visible=t_rows >= 10.0),
            truth_rows("c", (0, 100e3, 5000), V, t_rows, visible=False),
        ]
    )
    tracks = pd.concat([track_rows(1, (0, 0, 5000), V, STEPS[5:]), track_rows(2, (0, 50e3, 5000), V, STEPS[6:])])
    ev = evaluate(tracks, truth, output_times=STEPS)
    per = ev.per_target.set_index("target_id")
    assert list(per.index) == ["a", "b"]
    assert per.loc["a", "time_to_first_track_s"] == pytest.approx(20.0)
    assert per.loc["b", "first_visible_time"] == pytest.approx(10.0)
    assert per.loc["b", "time_to_first_track_s"] == pytest.approx(14.0)
    # b is visible at instants 12 s .. 76 s (17 instants), covered from 24 s (14 instants)
    assert per.loc["b", "n_visible_instants"] == 17
    assert per.loc["b", "continuity"] == pytest.approx(14 / 17)
    assert ev.series["n_truth_visible"].tolist() == [1, 1, 1] + [2] * 17
    assert ev.series["gospa_missed"].tolist()[:7] == [1, 1, 1, 2, 2, 1, 0]


def test_interpolated_visibility_needs_both_rows():
    # rows at 0, 10, 20 s with the middle row invisible: visible only exactly at 0 and 20 s
    truth = truth_rows("a", (0, 0, 0), V, [0.0, 10.0, 20.0], visible=[True, False, True])
    tracks = track_rows(1, (0, 0, 0), V, [0.0, 5.0, 10.0, 15.0, 20.0])
    ev = evaluate(tracks, truth)
    assert ev.series["n_truth_visible"].tolist() == [1, 0, 0, 0, 1]
    assert ev.series["gospa_false"].tolist() == [0, 1, 1, 1, 0]


def test_coverage_check_for_two_minutes():
    t_rows = np.arange(0.0, 241.0, 4.0)
    truth = pd.concat(
        [
            truth_rows("tracked", (0, 0, 5000), V, t_rows, visible=t_rows <= 200),
            truth_rows("missed", (0, 50e3, 5000), V, t_rows, visible=(t_rows >= 40) & (t_rows <= 190)),
            truth_rows("short", (0, 100e3, 5000), V, t_rows, visible=t_rows <= 60),
        ]
    )
    tracks = track_rows(1, (0, 0, 5000), V, t_rows[(t_rows >= 24) & (t_rows <= 200)])
    ev = evaluate(tracks, truth, output_times=t_rows)
    cov = ev.coverage.set_index("target_id")
    assert list(cov.index) == ["tracked", "missed"]
    assert cov.loc["tracked", "tracked"] and not cov.loc["missed", "tracked"]
    assert cov.loc["tracked", "time_to_track_s"] == pytest.approx(24.0)
    assert cov.loc["missed", "duration_s"] == pytest.approx(148.0)  # visible rows 40 .. 188 s
    d = ev.to_dict()["coverage"]
    assert (d["n_objects"], d["n_tracked"], d["all_tracked"]) == (2, 1, False)
    assert [u["target_id"] for u in d["untracked"]] == ["missed"]
    # a stricter requirement leaves only the longer object, a window clips the intervals
    assert coverage_check(truth, ev.assignments, min_visible_s=180.0)["target_id"].tolist() == ["tracked"]
    clipped = coverage_check(truth, ev.assignments, min_visible_s=120.0, window=(100.0, 240.0))
    assert clipped["target_id"].tolist() == []
    runs = truth_visible_runs(truth)
    assert runs.set_index("target_id").loc["short", "duration_s"] == pytest.approx(60.0)


def test_touching_segments_are_one_visible_interval():
    t_rows = np.arange(0.0, 201.0, 4.0)
    first, second = t_rows[t_rows <= 100], t_rows[t_rows >= 100]
    truth = pd.concat([truth_rows("a", (0, 0, 5000), V, first), truth_rows("a", (0, 0, 5000), V, second, segment=1)])
    runs = truth_visible_runs(truth)
    assert runs[["segment", "start", "end", "duration_s"]].values.tolist() == [[0, 0.0, 200.0, 200.0]]
    ev = evaluate(track_rows(1, (0, 0, 5000), V, t_rows), truth)
    assert ev.summary["n_truth_visible_instants"] == t_rows.size  # the shared instant counted once
    assert ev.summary["track_breaks"] == 0
    assert ev.coverage["tracked"].tolist() == [True]


def test_empty_track_output_counts_every_truth_as_missed():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    empty = track_rows(1, (0, 0, 5000), V, STEPS).iloc[:0]
    ev = evaluate(empty, truth, output_times=STEPS)
    assert ev.dimension == "3-D"
    assert ev.summary["n_truth_never_tracked"] == 1 and ev.summary["n_tracks"] == 0
    np.testing.assert_allclose(ev.series["ospa_m"], 2000.0)
    assert ev.to_dict()["position_rmse_m"] is None
    with pytest.raises(ValueError, match="no confirmed rows"):
        evaluate(empty, truth)


def test_output_instants_without_tracks_are_filled_in():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, np.delete(STEPS, [3, 4]))
    grid, source = infer_output_times(tracks["time"])
    np.testing.assert_array_equal(grid, STEPS)
    assert "2 empty instant" in source
    ev = evaluate(tracks, truth)
    assert ev.summary["n_output_times"] == 20
    assert ev.per_target.iloc[0]["continuity"] == pytest.approx(18 / 20)
    assert ev.series["gospa_missed"].tolist()[3:5] == [1, 1]


def test_instants_after_the_truth_ends_are_left_out():
    # a run whose last plot opens one more scan reports its tracks 4 s past the truth's end: the
    # truth does not say what flew then, so those rows are not false tracks
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, STEPS, offset=(30.0, 40.0, 0.0))
    longer = pd.concat([tracks, track_rows(1, (0, 0, 5000), V, [STEPS[-1] + 4.0], offset=(30.0, 40.0, 0.0))])
    ev, ev_longer = evaluate(tracks, truth), evaluate(longer, truth)
    assert ev_longer.summary["n_output_times"] == ev.summary["n_output_times"] == STEPS.size
    assert ev_longer.summary["gospa_mean_m"] == pytest.approx(ev.summary["gospa_mean_m"]) == pytest.approx(50.0)
    assert ev_longer.summary["n_false_tracks"] == 0
    assert any("1 output instant(s) after the truth's last time" in note for note in ev_longer.notes)
    # instants given explicitly are evaluated as given: the extra one has a track and no truth
    given = evaluate(longer, truth, output_times=np.append(STEPS, STEPS[-1] + 4.0))
    assert given.summary["n_output_times"] == STEPS.size + 1 and given.series["gospa_false"].tolist()[-1] == 1


def test_start_time_extends_the_grid_back_and_times_first_tracks_from_it():
    # the tracker started at 0 s but confirmed its first track at 12 s: without start_time_s
    # the evaluation cannot know about 0 .. 8 s
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, STEPS[3:])
    late = evaluate(tracks, truth)
    assert late.summary["n_output_times"] == 17 and late.per_target.iloc[0]["time_to_first_track_s"] == 0.0
    ev = evaluate(tracks, truth, start_time_s=0.0)
    np.testing.assert_array_equal(ev.times, STEPS)
    assert "3 of them before the first track" in ev.output_times_source
    row = ev.per_target.iloc[0]
    assert row["time_to_first_track_s"] == pytest.approx(12.0)
    assert row["continuity"] == pytest.approx(17 / 20)
    assert ev.parameters["start_time_s"] == 0.0


def test_non_confirmed_rows_are_ignored_and_reported():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, STEPS)
    tracks.loc[tracks.index[:2], "status"] = "tentative"
    tracks.loc[tracks.index[2:5], "status"] = "coasting"
    ev = evaluate(tracks, truth, output_times=STEPS)
    assert ev.summary["n_track_rows"] == 18
    assert any("2 track rows ignored" in note and "tentative=2" in note for note in ev.notes)


def test_bad_input_names_row_and_column():
    truth = truth_rows("a", (0, 0, 5000), V, STEPS)
    tracks = track_rows(1, (0, 0, 5000), V, STEPS)
    with pytest.raises(ValueError, match="tracks table: missing required column.*track_id"):
        evaluate(tracks.drop(columns=["track_id"]), truth)
    bad = tracks.copy()
    bad.loc[bad.index[4], "y"] = np.nan
    with pytest.raises(ValueError, match=r"tracks table, row 4, column 'y'"):
        evaluate(bad, truth)
    with pytest.raises(ValueError, match=r"tracks table, row 0, column 'time'.*not one of the output instants"):
        evaluate(tracks.assign(time=tracks["time"] + 1.0), truth, output_times=STEPS)
    dup = pd.concat([truth, truth.iloc[[3]]])
    with pytest.raises(ValueError, match="two rows at time 12.0"):
        evaluate(tracks, dup)
    with pytest.raises(ValueError, match="appears twice"):
        evaluate(pd.concat([tracks, tracks.iloc[[0]]]), truth)


def test_to_dict_is_json_and_summary_rows_are_strings():
    truth = pd.concat([truth_rows("a", (0, 0, 5000), V, STEPS), truth_rows("b", (0, 50e3, 5000), V, STEPS)])
    tracks = track_rows(1, (0, 0, 5000), V, STEPS, offset=(10, 0, 0))
    ev = evaluate(tracks, truth)
    d = ev.to_dict()
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text)["per_target"][1]["position_rmse_m"] is None  # b was never tracked: null, not NaN
    for key in ("units", "dimension", "parameters", "position_rmse_m", "velocity_rmse_mps", "nees", "continuity_mean",
                "track_breaks", "track_swaps", "false_tracks", "ospa_mean_m", "gospa_mean_m", "coverage", "per_target"):
        assert key in d
    assert d["n_truth_never_tracked"] == 1
    rows = ev.summary_rows()
    assert all(len(r) == 3 and all(isinstance(x, str) for x in r) for r in rows)
    # the GOSPA identity holds in the reported series
    s = ev.series
    c, p = ev.parameters["cutoff_m"], ev.parameters["order"]
    np.testing.assert_allclose(s["gospa_m"] ** p, s["gospa_localisation"] + c**p / 2 * (s["gospa_missed"] + s["gospa_false"]))


def test_many_targets_consistency():
    # 400 targets x 40 instants with N(0, 100 m) errors per axis: RMSE ~ 100 sqrt(3)
    rng = np.random.default_rng(5)
    n, steps = 400, np.arange(40) * DT
    p0 = rng.uniform(-200e3, 200e3, (n, 2))
    v = rng.normal(0, 150, (n, 2))
    T = np.tile(steps, n)
    x = np.repeat(p0[:, 0], steps.size) + np.repeat(v[:, 0], steps.size) * T
    y = np.repeat(p0[:, 1], steps.size) + np.repeat(v[:, 1], steps.size) * T
    truth = pd.DataFrame({"time": T, "target_id": np.repeat([f"{i:06x}" for i in range(n)], steps.size), "segment": 0,
                          "x": x, "y": y, "z": 5000.0, "vx": np.repeat(v[:, 0], steps.size),
                          "vy": np.repeat(v[:, 1], steps.size), "vz": 0.0, "visible": True})
    e = rng.normal(0, 100, (T.size, 3))
    tracks = truth[["time", "x", "y", "z", "vx", "vy", "vz"]].copy()
    tracks[["x", "y", "z"]] += e
    tracks["track_id"] = np.repeat(np.arange(n), steps.size)
    ev = evaluate(tracks, truth)
    # nearby targets can steal each other's tracks only if closer than a few hundred metres
    assert ev.summary["n_assigned"] >= 0.99 * T.size
    assert ev.summary["position_rmse_m"] == pytest.approx(100 * math.sqrt(3), rel=0.03)
    assert ev.summary["n_false_tracks"] == 0


def _manoeuvre_case():
    """Objects a and b fly straight (rows every 4 s, t = 0..76 s).  Track 1 follows a with a
    velocity error of (3, 4, 0) m/s (5 m/s) and a position error of 30 m at t = 20..40 s
    (6 instants) and (5, 12, 0) m/s (13 m/s), no position error elsewhere (14 instants);
    track 2 follows b exactly."""
    truth = pd.concat([truth_rows("a", (0, 0, 5000), V, STEPS), truth_rows("b", (0, 50e3, 6000), V, STEPS)])
    inside = (STEPS >= 20) & (STEPS <= 40)
    track_a = pd.concat([track_rows(1, (0, 0, 5000), V, STEPS[inside], offset=(30, 0, 0), vel_offset=(3, 4, 0)),
                         track_rows(1, (0, 0, 5000), V, STEPS[~inside], vel_offset=(5, 12, 0))])
    return truth, pd.concat([track_a, track_rows(2, (0, 50e3, 6000), V, STEPS)]), int(inside.sum())


def test_errors_in_manoeuvre_segments_are_the_in_segment_offsets():
    truth, tracks, n_inside = _manoeuvre_case()
    # a's segment holds its 6 instants 20..40 s (ends included); b's lies after the window; c is no truth object
    segments = [("a", 20.0, 40.0), ("b", 100.0, 120.0), ("c", 0.0, 76.0)]
    ev = evaluate(tracks, truth, manoeuvre_segments=segments)
    s = ev.summary
    assert s["velocity_rmse_manoeuvre_mps"] == pytest.approx(5.0, rel=1e-12)
    assert s["position_rmse_manoeuvre_m"] == pytest.approx(30.0, rel=1e-12)
    # the whole-run figures mix both offsets over a's 20 and b's 20 assigned instants
    assert s["velocity_rmse_mps"] == pytest.approx(math.sqrt((6 * 25 + 14 * 169) / 40), rel=1e-12)
    assert n_inside == 6
    assert (s["n_manoeuvre_segments"], s["n_manoeuvre_segments_visible"]) == (2, 1)
    assert (s["n_manoeuvre_truth_instants"], s["n_manoeuvre_assigned"], s["n_manoeuvre_velocity_samples"]) == (6, 6, 6)
    flagged = ev.assignments[ev.assignments["in_manoeuvre"]]
    assert sorted(flagged["time"]) == [20.0, 24.0, 28.0, 32.0, 36.0, 40.0]
    assert set(flagged["target_id"]) == {"a"}
    assert any("1 of 3 manoeuvre segments" in note for note in ev.notes)
    assert any(row[0].startswith("  in manoeuvres (1 segments, 6 samples)") for row in ev.summary_rows())
    # the same segments as a table give the same figures; without segments no such keys
    table = pd.DataFrame(segments, columns=["target_id", "start", "end"])
    assert evaluate(tracks, truth, manoeuvre_segments=table).summary == s
    assert "velocity_rmse_manoeuvre_mps" not in evaluate(tracks, truth).summary


def test_manoeuvre_segment_of_an_untracked_instant_and_bad_segments():
    truth, tracks, _ = _manoeuvre_case()
    # track 1 is missing at 20 and 24 s: the segment still has 6 visible truth instants, 4 assigned
    tracks = tracks[~((tracks["track_id"] == 1) & tracks["time"].isin([20.0, 24.0]))]
    s = evaluate(tracks, truth, manoeuvre_segments=[("a", 18.0, 41.0)]).summary
    assert (s["n_manoeuvre_truth_instants"], s["n_manoeuvre_assigned"]) == (6, 4)
    assert s["velocity_rmse_manoeuvre_mps"] == pytest.approx(5.0, rel=1e-12)
    empty = evaluate(tracks, truth, manoeuvre_segments=[]).summary
    assert empty["n_manoeuvre_segments"] == 0 and math.isnan(empty["velocity_rmse_manoeuvre_mps"])
    with pytest.raises(ValueError, match="before start"):
        evaluate(tracks, truth, manoeuvre_segments=[("a", 40.0, 20.0)])
    with pytest.raises(ValueError, match="target_id, start, end"):
        evaluate(tracks, truth, manoeuvre_segments=[("a", 20.0)])

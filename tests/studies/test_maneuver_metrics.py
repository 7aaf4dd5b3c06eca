"""Spec 004 R20 metrics aligned on onsets (e_pre, e_peak, settling from the peak and from the manoeuvre end,
NEES band of TV19, kept vs all runs, loss rates) on runs with known errors."""

import math

import numpy as np
import pytest

from skytrack.analysis.metrics import nees_band
from skytrack.studies.maneuver.metrics import MetricSettings, evaluate_run, settling_time, windows
from skytrack.studies.maneuver.runner import FIRST_SCAN, FilterRun
from skytrack.studies.maneuver.scenarios import Case, named_cases
from skytrack.studies.maneuver.trajectory import Kinematics


@pytest.mark.parametrize("runs, dim, low, high", [(100, 4, 3.464818, 4.573055), (100, 6, 5.340186, 6.697692),
                                                  (200, 6, 5.529449, 6.489491), (500, 9, 8.631926, 9.375651)])
def test_nees_band_tv19(runs, dim, low, high):
    assert nees_band(runs, dim) == (pytest.approx(low, abs=1e-6), pytest.approx(high, abs=1e-6))


def synthetic_case(maneuvers, scans=120):
    t = np.arange(scans, dtype=float)
    zeros = np.zeros((scans, 3))
    return Case("synthetic", "synthetic", 1.0, Kinematics(t, zeros, zeros, zeros), maneuvers, params={"n": 3.0})


def synthetic_run(case, rms_pos, runs=4, lost=None, nees_value=6.0):
    scans = case.scans
    pos = np.zeros((scans, runs, 3))
    pos[:, :, 0] = np.asarray(rms_pos)[:, None]  # every run has the same error: RMS = |error|
    pos[:FIRST_SCAN] = np.nan
    nees = np.full((scans, runs), nees_value)
    nees[:FIRST_SCAN] = np.nan
    lost = np.zeros(runs, dtype=bool) if lost is None else np.asarray(lost)
    nan = np.full((scans, runs), np.nan)
    return FilterRun("f", "kalman", case.label, "off", 2, "gaussian", case.truth.time, pos, pos / 10, nees, nan, nan,
                     np.ones((scans, runs), bool), np.ones((scans, runs), bool), nan, lost, np.where(lost, 50, -1),
                     np.full(scans, 100.0), np.full(scans, 1.0))


def test_onset_metrics_on_a_known_error_profile():
    case = synthetic_case([(40.0, 60.0)])
    t = case.truth.time
    rms = np.full(len(t), 10.0)
    rms[40:46] = [20, 40, 60, 80, 100, 90]  # peak 100 at t_rel = 4
    rms[46:50] = [70, 50, 30, 27]           # threshold e_pre + 0.2 (100 - 10) = 28: first stays-below from t = 49
    run = synthetic_run(case, rms)
    [summary_all, summary_kept], series = evaluate_run(case, run, MetricSettings(), {"off": 0.25, "on": 0.5})
    row = summary_all
    assert row["e_pre_pos"] == 10.0 and row["e_peak_pos"] == 100.0 and row["t_peak_pos"] == 4.0
    assert row["settle_peak_pos"] == 5.0          # t = 49 minus the peak at t = 44
    assert row["settle_end_pos"] == 0.0           # at the end (t = 60) the error is already back
    assert row["e_man_pos"] == pytest.approx(np.mean(rms[40:61]))
    assert row["e_peak_vel"] == pytest.approx(10.0) and row["nees_mean"] == 6.0 and row["nees_in_band"] == 1.0
    assert (row["nees_band_low"], row["nees_band_high"]) == nees_band(4, 6)
    assert row["loss_rate_off"] == 0.25 and row["loss_rate_on"] == 0.5 and row["madds_per_update"] == 100.0
    assert row["n"] == 3.0 and summary_kept["basis"] == "kept"
    rms_rows = [frame for frame in series if frame["quantity"].iloc[0] == "rms_pos" and frame["basis"].iloc[0] == "all"][0]
    assert rms_rows["t_rel"].min() == -20.0 and rms_rows["t_rel"].max() == 60.0
    assert np.allclose(rms_rows["value"], rms[20:101])


def test_settling_never_reached_is_infinite():
    t = np.arange(-5.0, 10.0)
    rms = np.r_[np.full(5, 1.0), np.full(10, 50.0)]
    assert settling_time(t, rms, 0.0, 2.0, 5) == math.inf
    assert math.isnan(settling_time(t, rms, math.nan, 2.0, 5))


def test_kept_basis_excludes_lost_runs():
    case = synthetic_case([(40.0, 50.0)])
    run = synthetic_run(case, np.full(case.scans, 10.0), runs=4, lost=[False, True, False, True])
    run.position_error[:, [1, 3], 0] = np.where(np.isnan(run.position_error[:, [1, 3], 0]), np.nan, 1000.0)
    all_row, kept_row = evaluate_run(case, run)[0]
    assert kept_row["runs_basis"] == 2 and kept_row["e_pre_pos"] == pytest.approx(10.0)
    assert all_row["e_pre_pos"] == pytest.approx(math.sqrt((2 * 100 + 2 * 1000**2) / 4))
    assert kept_row["nees_band_low"] == nees_band(2, 6)[0]


def test_windows_stop_at_the_next_onset_and_cases_without_manoeuvre():
    weave = named_cases("weave")[0]
    found = windows(weave, FIRST_SCAN, MetricSettings())
    assert len(found) == 4
    for w, (onset, _) in zip(found[:-1], weave.maneuvers[1:]):
        assert weave.truth.time[w.scans].max() < onset and w.t_rel.min() >= -20.0
    [whole] = windows(synthetic_case([]), FIRST_SCAN, MetricSettings())
    assert whole.onset_index == -1 and whole.scans[0] == FIRST_SCAN
    with pytest.raises(ValueError, match="settle_scans"):
        MetricSettings(settle_scans=0)
    with pytest.raises(ValueError, match="unknown key"):
        MetricSettings.from_dict({"window": 3})

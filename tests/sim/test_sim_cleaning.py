"""Cleaning of recorded state vectors: each step on a synthetic track with one injected fault,
asserting exactly which rows go (or which altitudes change) and the counts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.sim.cleaning import REMOVAL_STEPS, CleaningOptions, clean_states, segment_spans

EARTH_RADIUS_M = 6_371_008.8
#: 5 km north, in degrees of latitude
FIVE_KM_DEG = np.degrees(5000.0 / EARTH_RADIUS_M)


def track(n: int = 60, icao24: str = "abc123", t0: float = 1000.0, dt: float = 1.0, speed: float = 200.0,
          lat0: float = 48.0, lon0: float = 2.0, alt: float = 9000.0, climb: float = 0.0) -> pd.DataFrame:
    """A straight northbound flight sampled every ``dt`` seconds, in read_state_vectors' columns."""
    t = t0 + dt * np.arange(n)
    height = alt + climb * (t - t0)
    return pd.DataFrame(
        {
            "time": t,
            "icao24": pd.array([icao24] * n, dtype="str"),
            "callsign": pd.array(["TEST1"] * n, dtype="str"),
            "squawk": pd.array(["1234"] * n, dtype="str"),
            "onground": np.zeros(n, dtype=bool),
            "lat": lat0 + np.degrees(speed * (t - t0) / EARTH_RADIUS_M),
            "lon": np.full(n, lon0),
            "alt_m": height,
            "baro_alt_m": height,
            "geo_alt_m": np.full(n, np.nan),
            "groundspeed_mps": np.full(n, speed),
            "track_deg": np.zeros(n),
            "vertical_rate_mps": np.full(n, climb),
        }
    )


def removed_times(states: pd.DataFrame, cleaned: pd.DataFrame) -> list[float]:
    return sorted(set(states["time"]) - set(cleaned["time"]))


def only(report, **expected) -> None:
    """The report's removals are exactly ``expected`` (zero for every other step)."""
    assert report.removed == {step: expected.get(step, 0) for step in REMOVAL_STEPS}
    assert report.rows_read == report.rows_kept + sum(report.removed.values())


def test_a_clean_track_is_kept_whole_as_one_segment():
    states = track()
    cleaned, report = clean_states(states)
    only(report)
    assert report.reordered == 0 and report.gaps == 0 and report.altitudes_replaced == 0
    assert cleaned["segment_id"].unique().tolist() == ["abc123-1"] and cleaned["segment"].unique().tolist() == [1]
    np.testing.assert_array_equal(cleaned["time"], states["time"])
    np.testing.assert_array_equal(cleaned["alt_m"], states["alt_m"])
    assert (report.rows_kept, report.segments, report.aircraft_kept) == (60, 1, 1)


def test_on_ground_rows_go():
    states = track()
    states.loc[:4, "onground"] = True
    cleaned, report = clean_states(states)
    only(report, onground=5)
    assert removed_times(states, cleaned) == [1000.0, 1001.0, 1002.0, 1003.0, 1004.0]
    _, kept = clean_states(states, CleaningOptions(keep_onground=True))
    only(kept)


def test_rows_without_a_position_go():
    states = track()
    states.loc[10, "lat"] = np.nan
    states.loc[20, "alt_m"] = np.nan
    cleaned, report = clean_states(states)
    only(report, no_position=2)
    assert removed_times(states, cleaned) == [1010.0, 1020.0]


def test_a_repeated_time_stamp_keeps_the_first_row():
    states = track()
    repeat = states.iloc[[10]].assign(lat=states["lat"][10] + 0.001)
    states = pd.concat([states.iloc[:11], repeat, states.iloc[11:]], ignore_index=True)
    cleaned, report = clean_states(states)
    only(report, duplicate_time=1)
    assert cleaned["lat"][10] == states["lat"][10] and cleaned["time"].is_unique
    # with a minimum interval, a sample 0.05 s after another counts as the same instant
    close = track()
    close.loc[11, "time"] = 1010.05
    cleaned, report = clean_states(close, CleaningOptions(min_interval_s=0.1))
    only(report, duplicate_time=1)
    assert removed_times(close, cleaned) == [1010.05]


def test_stale_positions_keep_the_first_time_the_position_was_seen():
    states = track()
    states.loc[20:22, ["lat", "lon"]] = states.loc[19, ["lat", "lon"]].to_numpy()
    cleaned, report = clean_states(states)
    only(report, stale_position=3)
    assert removed_times(states, cleaned) == [1020.0, 1021.0, 1022.0]


def test_one_position_several_km_off_goes_and_nothing_else():
    states = track()
    states.loc[30, "lat"] += FIVE_KM_DEG
    cleaned, report = clean_states(states)
    only(report, position_glitch=1)
    assert removed_times(states, cleaned) == [1030.0]


def test_two_consecutive_glitches_are_a_detour_and_go():
    states = track()
    states.loc[30:31, "lon"] += 0.1  # about 7 km east
    cleaned, report = clean_states(states)
    only(report, position_glitch=2)
    assert removed_times(states, cleaned) == [1030.0, 1031.0]


def test_garbage_at_the_start_of_a_recording_goes():
    states = track()
    states.loc[:1, "lat"] -= 4 * FIVE_KM_DEG
    cleaned, report = clean_states(states)
    only(report, position_glitch=2)
    assert removed_times(states, cleaned) == [1000.0, 1001.0]


def test_a_single_jump_between_two_long_runs_is_left_alone():
    states = track()
    states.loc[30:, "lat"] += FIVE_KM_DEG  # which side is wrong is unknown
    cleaned, report = clean_states(states)
    only(report)
    assert len(cleaned) == len(states) and removed_times(states, cleaned) == []


def test_an_altitude_spike_is_replaced_by_interpolation():
    states = track(climb=10.0)
    true_height = states.loc[40, "alt_m"]
    states.loc[40, "alt_m"] += 3000.0
    cleaned, report = clean_states(states)
    only(report)
    assert report.altitudes_replaced == 1
    assert cleaned["alt_m"][40] == pytest.approx(true_height, abs=1e-9)
    np.testing.assert_array_equal(cleaned["time"], states["time"])


def test_a_held_wrong_altitude_is_replaced_over_its_whole_run():
    states = track(n=200, climb=-5.0)
    truth = states["alt_m"].copy()
    states.loc[60:99, "alt_m"] = 18562.32  # a transponder stuck at 60 900 ft for 40 s
    cleaned, report = clean_states(states)
    only(report)
    assert report.altitudes_replaced == 40
    np.testing.assert_allclose(cleaned["alt_m"], truth, rtol=0, atol=1e-9)
    # a wrong stretch longer than the good one before it is not known to be the wrong one
    states = track(n=200, climb=-5.0)
    states.loc[30:99, "alt_m"] = 18562.32
    _, report = clean_states(states)
    assert report.altitudes_replaced == 0


def test_an_altitude_spike_on_the_last_row_cannot_be_interpolated_and_goes():
    states = track()
    states.loc[59, "alt_m"] += 3000.0
    cleaned, report = clean_states(states)
    only(report, altitude_spike=1)
    assert report.altitudes_replaced == 0 and removed_times(states, cleaned) == [1059.0]


def test_a_gap_cuts_the_aircraft_into_numbered_segments():
    states = track()
    states.loc[30:, "time"] += 120.0
    cleaned, report = clean_states(states)
    only(report)
    assert report.gaps == 1 and report.segments == 2
    spans = segment_spans(cleaned)
    assert spans.index.tolist() == ["abc123-1", "abc123-2"]
    assert spans["rows"].tolist() == [30, 30]
    assert spans["start"].tolist() == [1000.0, 1150.0] and spans["end"].tolist() == [1029.0, 1179.0]
    # a gap of exactly max_gap_s does not cut
    _, report = clean_states(states, CleaningOptions(max_gap_s=121.0))
    assert report.gaps == 0 and report.segments == 1


def test_a_lone_sample_after_a_gap_is_too_short_to_interpolate():
    states = track()
    states.loc[0, "time"] = 900.0  # 100 s before the rest: a segment of one row
    states.loc[0, "lat"] = states.loc[1, "lat"] - np.degrees(200.0 * 100.0 / EARTH_RADIUS_M)
    cleaned, report = clean_states(states)
    only(report, short_segment=1)
    assert report.gaps == 1 and report.segments == 1
    # the segments kept are numbered from 1
    assert cleaned["segment_id"].unique().tolist() == ["abc123-1"]


def test_rows_out_of_time_order_are_sorted_and_counted():
    states = track()
    swapped = states.iloc[[*range(10), 11, 10, *range(12, 60)]].reset_index(drop=True)
    cleaned, report = clean_states(swapped)
    only(report)
    assert report.reordered == 1
    np.testing.assert_array_equal(cleaned["time"], states["time"])
    reversed_rows = states.iloc[::-1].reset_index(drop=True)
    cleaned, report = clean_states(reversed_rows)
    assert report.reordered == 59
    np.testing.assert_array_equal(cleaned["time"], states["time"])


def test_aircraft_are_cleaned_apart_even_when_their_rows_interleave():
    a = track(icao24="aaaaaa")
    b = track(icao24="bbbbbb", lat0=52.0)  # 450 km away: a jump only if rows were mixed up
    both = pd.concat([a, b]).sort_values("time", kind="stable").reset_index(drop=True)
    cleaned, report = clean_states(both)
    only(report)
    assert report.reordered == 0 and report.segments == 2 and report.aircraft_kept == 2
    assert cleaned["segment_id"].unique().tolist() == ["aaaaaa-1", "bbbbbb-1"]


def test_all_faults_at_once_add_up():
    states = track(n=200)
    states.loc[:2, "onground"] = True
    states.loc[50, "lat"] = np.nan
    states.loc[60:61, ["lat", "lon"]] = states.loc[59, ["lat", "lon"]].to_numpy()
    states.loc[80, "lon"] += 0.2
    states.loc[100, "alt_m"] -= 2000.0
    states.loc[150:, "time"] += 90.0
    cleaned, report = clean_states(states)
    only(report, onground=3, no_position=1, stale_position=2, position_glitch=1)
    assert report.altitudes_replaced == 1 and report.gaps == 1 and report.segments == 2
    assert removed_times(states, cleaned) == [1000.0, 1001.0, 1002.0, 1050.0, 1060.0, 1061.0, 1080.0]


def turning_track(rate_deg_s: float, dt: float, n: int, speed: float = 250.0, jitter_m: float = 0.0,
                  seed: int = 0) -> pd.DataFrame:
    """A coordinated turn at ``rate_deg_s`` sampled every ``dt`` s, recorded velocity exact, positions
    with white jitter of ``jitter_m`` per axis (local flat Earth at 48 N)."""
    states = track(n=n, dt=dt, speed=speed)
    t = states["time"].to_numpy() - states["time"].iloc[0]
    omega = np.radians(rate_deg_s)
    heading = omega * t  # clockwise from north
    east = speed * (1.0 - np.cos(heading)) / omega if omega else np.zeros(n)
    north = speed * np.sin(heading) / omega if omega else speed * t
    noise = np.random.default_rng(seed).normal(0.0, jitter_m, (2, n))
    states["lat"] = 48.0 + np.degrees((north + noise[1]) / EARTH_RADIUS_M)
    states["lon"] = 2.0 + np.degrees((east + noise[0]) / (EARTH_RADIUS_M * np.cos(np.radians(48.0))))
    states["track_deg"] = np.degrees(heading) % 360.0
    return states


def test_a_stale_recorded_velocity_is_replaced_and_counted():
    """Rows 20-29 repeat an old velocity (499 kt at 165 deg) while the aircraft flies north at
    200 m/s: their ground speed and track become unknown; no row is removed."""
    states = track(n=60, dt=10.0)
    states.loc[20:29, "groundspeed_mps"] = 499 * 0.514444
    states.loc[20:29, "track_deg"] = 165.0
    cleaned, report = clean_states(states)
    only(report)
    assert report.velocities_replaced == 10
    unknown = cleaned["groundspeed_mps"].isna().to_numpy()
    np.testing.assert_array_equal(np.flatnonzero(unknown), np.arange(20, 30))
    assert cleaned["track_deg"].isna().sum() == 10
    assert "10 velocities replaced" in str(report)


@pytest.mark.parametrize("rate_deg_s,dt,jitter_m", [(3.0, 10.0, 0.0), (3.0, 1.0, 20.0), (0.0, 1.0, 20.0)])
def test_turns_and_position_jitter_keep_the_recorded_velocity(rate_deg_s, dt, jitter_m):
    """A 3 deg/s turn at 250 m/s sampled every 10 s, or every second with 20 m position jitter
    (next-row differences would scatter by ~14 m/s), keeps every recorded velocity: the
    difference is taken over +-10 s."""
    cleaned, report = clean_states(turning_track(rate_deg_s, dt, n=int(600 / dt), jitter_m=jitter_m))
    assert report.velocities_replaced == 0
    assert cleaned["groundspeed_mps"].notna().all()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"max_gap_s": 0.0}, "max_gap_s must be > 0"),
        ({"max_speed_mps": -1.0}, "max_speed_mps must be > 0"),
        ({"position_tolerance_m": -1.0}, "position_tolerance_m must be >= 0"),
        ({"min_segment_rows": 1}, "min_segment_rows must be >= 2"),
        ({"max_velocity_mismatch_mps": 0.0}, "max_velocity_mismatch_mps must be > 0"),
        ({"velocity_baseline_s": -1.0}, "velocity_baseline_s must be >= 0"),
    ],
)
def test_invalid_options_are_refused(options, message):
    with pytest.raises(ValueError, match=message):
        CleaningOptions(**options)

"""Cleaning recorded state vectors the way they come, before they become simulation truth.

:func:`clean_states` takes the SI table of :func:`skytrack.io.read_state_vectors`
(columns ``time``, ``icao24``, ``lat``, ``lon``, ``alt_m``, ... in any row order) and
returns the cleaned rows cut into continuous segments, with a :class:`CleaningReport`
that counts what each step did.  The steps, in this order (each sees what the previous
ones kept; every one is a handful of vectorised numpy/pandas operations over all
aircraft at once):

1. ``reordered``: rows are sorted by (aircraft, time), stable in file order; the count is
   the rows whose time was earlier than an earlier row of the same aircraft (time-stamp
   jitter).  Nothing is removed by sorting.
2. ``no_position``: rows without latitude, longitude or altitude (recorded data have
   rows with a velocity only).
3. ``onground``: rows flagged on the ground (taxiing aircraft are not radar truth).
4. ``duplicate_time``: rows less than ``min_interval_s`` after the previous row of the
   same aircraft (default 0: the same time stamp); the first is kept.
5. ``stale_position``: rows repeating the previous row's latitude and longitude exactly
   while time advances (the receiver re-reports an old position); the first is kept, so
   the position keeps the time it was new.
6. ``position_glitch``: outlier runs in position.  Going from one row to the next is a
   jump when the horizontal distance exceeds ``max_speed_mps * dt + position_tolerance_m``.
   A run of rows between jumps lasting at most ``max_outlier_s`` is dropped when it is a
   *detour* (jumps on both sides, the rows just before and after it plausible neighbours
   of each other, and no more rows than the runs on either side: a single sample several
   km off, impossible from both neighbours, is the shortest one) or *short* (at most ``max_short_run_rows`` rows,
   fewer than the run on the other side of each of its jumps: garbage at the start or
   end of a recording).  A single jump between two long runs is left alone: neither
   side is known to be the wrong one.
7. ``altitude_spike``: the same test on the altitude with ``max_vertical_rate_mps`` and
   ``altitude_tolerance_m``: one-sample spikes and held wrong values (a transponder
   reporting 60 900 ft for two minutes in the middle of a descent).  The position of
   these rows is good, so their altitude is replaced by linear interpolation in time
   between the nearest good rows of the aircraft (rows with no good row on one side are
   dropped, and counted as removed; the altitudes replaced are counted apart).
8. ``gaps``: a time gap longer than ``max_gap_s`` cuts an aircraft into segments, each a
   separate truth object ``<icao24>-1``, ``<icao24>-2``, ... (the count is the cuts).
9. ``short_segment``: segments with fewer than ``min_segment_rows`` rows (nothing to
   interpolate between) are dropped.
10. ``velocities_replaced``: a recorded horizontal velocity (ground speed and track) that
   differs from the central difference of the segment's positions about ``+-velocity_baseline_s``
   away (the nearest rows at least that far; rows closer than that to their segment's ends are
   not judged) by more than
   ``max_velocity_mismatch_mps`` is stale or wrong (receivers repeat an old velocity while
   the position moves on, e.g. 499 kt at 165 deg for an aircraft flying north-west); its
   ground speed and track become unknown, so the trajectory takes the finite difference
   there (:mod:`skytrack.sim.recorded_motion`).  Rows are kept; the count is reported.  The
   baseline keeps position jitter out of the difference (at 1 s sampling, next-row
   differences of ADS-B positions scatter by tens of m/s), and the threshold is far above
   what a turn does to it (a chord over +-10 s of a 3 deg/s turn at 250 m/s is 11 m/s shorter
   than the tangent, in the tangent's direction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

#: rows removed by these steps, in this order (see the module docstring)
REMOVAL_STEPS = (
    "no_position", "onground", "duplicate_time", "stale_position", "position_glitch", "altitude_spike", "short_segment",
)
#: columns of the cleaned table, in order
CLEAN_COLUMNS = (
    "segment_id", "icao24", "segment", "time", "lat", "lon", "alt_m", "groundspeed_mps", "track_deg",
    "vertical_rate_mps", "callsign", "squawk",
)
_EARTH_RADIUS_M = 6_371_008.8
#: outlier runs are looked for again after removing some, at most this often
_MAX_OUTLIER_PASSES = 5


@dataclass(frozen=True)
class CleaningOptions:
    """Thresholds of :func:`clean_states` (defaults suit airliner ADS-B data at 1-10 s)."""

    max_gap_s: float = 60.0
    max_speed_mps: float = 400.0
    position_tolerance_m: float = 100.0
    max_vertical_rate_mps: float = 100.0
    altitude_tolerance_m: float = 100.0
    max_outlier_s: float = 300.0
    max_short_run_rows: int = 3
    min_interval_s: float = 0.0
    min_segment_rows: int = 2
    keep_onground: bool = False
    max_velocity_mismatch_mps: float = 50.0
    velocity_baseline_s: float = 10.0

    def __post_init__(self) -> None:
        for name in ("max_gap_s", "max_speed_mps", "max_vertical_rate_mps", "max_velocity_mismatch_mps"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("position_tolerance_m", "altitude_tolerance_m", "max_outlier_s", "min_interval_s",
                     "velocity_baseline_s"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if self.max_short_run_rows < 0:
            raise ValueError(f"max_short_run_rows must be >= 0, got {self.max_short_run_rows}")
        if self.min_segment_rows < 2:
            raise ValueError(f"min_segment_rows must be >= 2 (a segment is interpolated between rows), got {self.min_segment_rows}")


@dataclass
class CleaningReport:
    """What :func:`clean_states` did: rows in and out, reordered rows, rows removed per step,
    altitudes replaced (step 7), gaps cut and segments made.  ``rows_read`` equals
    ``rows_kept`` plus the sum of ``removed``."""

    rows_read: int = 0
    aircraft_read: int = 0
    reordered: int = 0
    removed: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REMOVAL_STEPS, 0))
    altitudes_replaced: int = 0
    velocities_replaced: int = 0
    gaps: int = 0
    rows_kept: int = 0
    aircraft_kept: int = 0
    segments: int = 0

    def as_dict(self) -> dict[str, int]:
        """Flat counts, in step order (for printing and JSON)."""
        return {
            "rows_read": self.rows_read, "aircraft_read": self.aircraft_read, "reordered": self.reordered,
            **{f"removed_{step}": count for step, count in self.removed.items()},
            "altitudes_replaced": self.altitudes_replaced, "velocities_replaced": self.velocities_replaced,
            "gaps_cut": self.gaps, "rows_kept": self.rows_kept, "aircraft_kept": self.aircraft_kept,
            "segments": self.segments,
        }

    def __str__(self) -> str:
        removed = ", ".join(f"{step.replace('_', ' ')} {count}" for step, count in self.removed.items())
        return (
            f"{self.rows_read} rows of {self.aircraft_read} aircraft read ({self.reordered} out of time order); "
            f"removed: {removed}; {self.altitudes_replaced} altitudes replaced; "
            f"{self.velocities_replaced} velocities replaced; {self.gaps} gaps cut; kept {self.rows_kept} rows in {self.segments} segments "
            f"of {self.aircraft_kept} aircraft"
        )


def _group_starts(codes: np.ndarray) -> np.ndarray:
    """True on the first row of each group (rows sorted by group)."""
    starts = np.ones(codes.size, dtype=bool)
    starts[1:] = codes[1:] != codes[:-1]
    return starts


def _step_back(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Difference to the previous row of the same group (NaN on a group's first row)."""
    diff = np.full(values.size, np.nan)
    diff[1:] = values[1:] - values[:-1]
    diff[starts] = np.nan
    return diff


def _great_circle_m(lat1, lon1, lat2, lon2) -> np.ndarray:
    """Great-circle distance (m) on the mean sphere (haversine)."""
    phi1, phi2 = np.radians(lat1), np.radians(lat2)
    a = np.sin((phi2 - phi1) / 2.0) ** 2 + np.cos(phi1) * np.cos(phi2) * np.sin(np.radians(lon2 - lon1) / 2.0) ** 2
    return 2.0 * _EARTH_RADIUS_M * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


def outlier_runs(codes: np.ndarray, time: np.ndarray, implausible, max_run_s: float, max_short_rows: int) -> np.ndarray:
    """Rows of outlier runs (rows sorted by group and time; steps 6-7 of the module docstring).

    ``implausible(i, j)`` says, for arrays of row positions ``i < j`` of the same group,
    whether going from row ``i`` to row ``j`` is impossible.  Runs are the stretches
    between such jumps of consecutive rows.  A run is an outlier when it lasts at most
    ``max_run_s`` and either is a *detour* (jumps on both sides, the rows just before and
    after it plausible neighbours of each other, and no more rows than each neighbouring
    run: a good stretch between two identical wrong values is not one) or is *short* (touches a
    jump, has at most ``max_short_rows`` rows and fewer rows than each run on the other
    side of its jumps: garbage at the start or end of a recording).
    """
    n = codes.size
    if n == 0:
        return np.zeros(0, dtype=bool)
    starts = _group_starts(codes)
    jump = np.zeros(n, dtype=bool)
    jump[1:] = implausible(np.arange(n - 1), np.arange(1, n))
    jump &= ~starts
    first = np.flatnonzero(starts | jump)
    run = np.cumsum(starts | jump) - 1
    counts = np.diff(np.append(first, n))
    last = np.append(first[1:], n) - 1
    brief = time[last] - time[first] <= max_run_s
    starts_with_jump = jump[first]
    # the next run begins with a jump only inside the same group (jumps are never on a group start)
    ends_with_jump = np.append(starts_with_jump[1:], False)
    previous_count = np.append(np.inf, counts[:-1])
    next_count = np.append(counts[1:], np.inf)
    detour = starts_with_jump & ends_with_jump & (counts <= previous_count) & (counts <= next_count)
    inside = np.flatnonzero(detour)
    detour[inside] = ~implausible(first[inside] - 1, last[inside] + 1)
    short = (
        (starts_with_jump | ends_with_jump)
        & (counts <= max_short_rows)
        & (~starts_with_jump | (counts < previous_count))
        & (~ends_with_jump | (counts < next_count))
    )
    return (brief & (detour | short))[run]


def _outliers(df: pd.DataFrame, implausible_in, options: CleaningOptions) -> np.ndarray:
    """Mask of the outlier rows of ``df``: runs are looked for again without those found, a few passes at most."""
    bad = np.zeros(len(df), dtype=bool)
    for _ in range(_MAX_OUTLIER_PASSES):
        rest = np.flatnonzero(~bad)
        frame = df.iloc[rest]
        found = outlier_runs(
            frame["_aircraft"].to_numpy(), frame["time"].to_numpy(), implausible_in(frame), options.max_outlier_s,
            options.max_short_run_rows,
        )
        if not found.any():
            break
        bad[rest[found]] = True
    return bad


def _interpolate_altitude(df: pd.DataFrame, bad: np.ndarray) -> tuple[pd.DataFrame, np.ndarray]:
    """Altitudes of the ``bad`` rows replaced linearly in time between the nearest good rows of
    the same aircraft; returns the frame and the rows that have no good row on one side."""
    codes, time = df["_aircraft"].to_numpy(), df["time"].to_numpy()
    good = np.flatnonzero(~bad)
    rows = np.flatnonzero(bad)
    after = np.searchsorted(good, rows)  # rows are sorted by aircraft and time, like good
    has_both = (after > 0) & (after < good.size)
    before_row = good[np.clip(after - 1, 0, max(good.size - 1, 0))] if good.size else rows
    after_row = good[np.clip(after, 0, max(good.size - 1, 0))] if good.size else rows
    has_both &= (codes[before_row] == codes[rows]) & (codes[after_row] == codes[rows])
    alt = df["alt_m"].to_numpy().copy()
    inner = rows[has_both]
    t0, t1 = time[before_row[has_both]], time[after_row[has_both]]
    h0, h1 = alt[before_row[has_both]], alt[after_row[has_both]]
    alt[inner] = h0 + (h1 - h0) * (time[inner] - t0) / (t1 - t0)
    unbounded = np.zeros(len(df), dtype=bool)
    unbounded[rows[~has_both]] = True
    return df.assign(alt_m=alt), unbounded


def _position_test(options: CleaningOptions):
    def implausible_in(frame: pd.DataFrame):
        t, lat, lon = (frame[name].to_numpy() for name in ("time", "lat", "lon"))

        def implausible(i: np.ndarray, j: np.ndarray) -> np.ndarray:
            distance = _great_circle_m(lat[i], lon[i], lat[j], lon[j])
            return distance > options.max_speed_mps * (t[j] - t[i]) + options.position_tolerance_m

        return implausible

    return implausible_in


def _altitude_test(options: CleaningOptions):
    def implausible_in(frame: pd.DataFrame):
        t, alt = frame["time"].to_numpy(), frame["alt_m"].to_numpy()

        def implausible(i: np.ndarray, j: np.ndarray) -> np.ndarray:
            return np.abs(alt[j] - alt[i]) > options.max_vertical_rate_mps * (t[j] - t[i]) + options.altitude_tolerance_m

        return implausible

    return implausible_in


def clean_states(states: pd.DataFrame, options: CleaningOptions | None = None) -> tuple[pd.DataFrame, CleaningReport]:
    """Clean recorded state vectors and cut them into segments (see the module docstring).

    Returns the cleaned rows (:data:`CLEAN_COLUMNS`, sorted by aircraft and time, index
    reset) and the :class:`CleaningReport`.
    """
    options = options or CleaningOptions()
    report = CleaningReport(rows_read=len(states))
    df = pd.DataFrame({name: states[name] for name in CLEAN_COLUMNS[1:] if name in states.columns and name != "segment"})
    for name in ("groundspeed_mps", "track_deg", "vertical_rate_mps"):
        if name not in df.columns:
            df[name] = np.nan
    for name in ("callsign", "squawk"):
        if name not in df.columns:
            df[name] = pd.Series([None] * len(df), index=df.index, dtype="str")
    onground = states["onground"].to_numpy(dtype=bool) if "onground" in states.columns else np.zeros(len(states), bool)
    codes, aircraft = pd.factorize(df["icao24"])
    df["_aircraft"] = np.asarray(codes, dtype=np.int64)
    report.aircraft_read = len(aircraft)

    # 1. time order: rows earlier than the running latest time of their aircraft (input order)
    time = df["time"].to_numpy()
    latest_before = pd.Series(time).groupby(codes, sort=False).cummax().groupby(codes, sort=False).shift(1)
    report.reordered = int((time < latest_before.to_numpy(dtype=float, na_value=np.nan)).sum())
    df["_onground"] = onground
    df = df.sort_values(["_aircraft", "time"], kind="stable")

    def drop(step: str, mask: np.ndarray) -> None:
        nonlocal df
        report.removed[step] += int(mask.sum())
        if mask.any():
            df = df.loc[~mask]

    # 2.-3. rows without a position, rows on the ground
    drop("no_position", df[["lat", "lon", "alt_m"]].isna().any(axis=1).to_numpy())
    if not options.keep_onground:
        drop("onground", df["_onground"].to_numpy())

    # 4. repeated or too close time stamps: the first of them is kept
    starts = _group_starts(df["_aircraft"].to_numpy())
    drop("duplicate_time", _step_back(df["time"].to_numpy(), starts) <= options.min_interval_s)

    # 5. stale positions: the same latitude and longitude as the previous row, time advancing
    starts = _group_starts(df["_aircraft"].to_numpy())
    same_lat = _step_back(df["lat"].to_numpy(), starts) == 0.0
    same_lon = _step_back(df["lon"].to_numpy(), starts) == 0.0
    drop("stale_position", same_lat & same_lon)

    # 6. position glitches: the rows are dropped (where the aircraft was is unknown)
    drop("position_glitch", _outliers(df, _position_test(options), options))
    # 7. altitude spikes: the position is good, so only the altitude is replaced
    spikes = _outliers(df, _altitude_test(options), options)
    df, unbounded = _interpolate_altitude(df, spikes)
    report.altitudes_replaced = int(spikes.sum() - unbounded.sum())
    drop("altitude_spike", unbounded)

    # 8. gaps cut segments; 9. segments too short to interpolate are dropped
    starts = _group_starts(df["_aircraft"].to_numpy())
    cut = _step_back(df["time"].to_numpy(), starts) > options.max_gap_s
    report.gaps = int(cut.sum())
    global_segment = np.cumsum(starts | cut)
    drop("short_segment", np.bincount(global_segment)[global_segment] < options.min_segment_rows)
    # numbered 1, 2, ... within each aircraft among the segments kept
    kept_segment = global_segment[np.bincount(global_segment)[global_segment] >= options.min_segment_rows]
    starts = _group_starts(df["_aircraft"].to_numpy())
    new_segment = starts | _group_starts(kept_segment)
    count = np.cumsum(new_segment)
    first_of_aircraft = np.maximum.accumulate(np.where(starts, np.arange(count.size), 0))
    segment = (count - count[first_of_aircraft] + 1).astype(np.int64)

    df = df.assign(segment=segment)
    # 10. stale or wrong recorded velocities become unknown (the trajectory differences positions)
    wrong = _velocity_mismatch(df, new_segment, options.max_velocity_mismatch_mps, options.velocity_baseline_s)
    report.velocities_replaced = int(wrong.sum())
    if wrong.any():
        df.loc[df.index[wrong], ["groundspeed_mps", "track_deg"]] = np.nan
    df["segment_id"] = (df["icao24"].astype(str) + "-" + df["segment"].astype(str)).astype("str")
    out = df.loc[:, list(CLEAN_COLUMNS)].reset_index(drop=True)
    report.rows_kept = len(out)
    report.aircraft_kept = int(out["icao24"].nunique())
    report.segments = int(out["segment_id"].nunique())
    return out, report


def _velocity_mismatch(df: pd.DataFrame, segment_start: np.ndarray, limit_mps: float, baseline_s: float) -> np.ndarray:
    """Rows whose recorded horizontal velocity is more than ``limit_mps`` from the central
    difference of their segment's positions ``baseline_s`` away on each side (the nearest rows at
    least that far, clipped to the segment; local flat Earth).  Rows less than ``baseline_s`` from
    their segment's ends have no centred difference and are not judged."""
    count = len(df)
    if count == 0:
        return np.zeros(0, bool)
    index = np.arange(count)
    t = df["time"].to_numpy(dtype=float)
    segment = np.cumsum(segment_start)
    first = np.maximum.accumulate(np.where(segment_start, index, 0))
    segment_end = np.r_[segment_start[1:], True]
    last = np.minimum.accumulate(np.where(segment_end, index, count - 1)[::-1])[::-1]
    # rows are sorted by (segment, time): one key orders both
    key = segment * (2.0 * (np.ptp(t) + 2.0 * baseline_s + 1.0)) + (t - t.min())
    before = np.clip(np.searchsorted(key, key - baseline_s, side="right") - 1, first, last)
    after = np.clip(np.searchsorted(key, key + baseline_s, side="left"), first, last)
    lat = np.radians(df["lat"].to_numpy(dtype=float))
    lon = np.radians(df["lon"].to_numpy(dtype=float))
    span = t[after] - t[before]
    with np.errstate(invalid="ignore", divide="ignore"):
        east = _EARTH_RADIUS_M * np.cos(lat) * np.angle(np.exp(1j * (lon[after] - lon[before]))) / span
        north = _EARTH_RADIUS_M * (lat[after] - lat[before]) / span
    speed = df["groundspeed_mps"].to_numpy(dtype=float)
    course = np.radians(df["track_deg"].to_numpy(dtype=float))
    mismatch = np.hypot(speed * np.sin(course) - east, speed * np.cos(course) - north)
    # only differences reaching the baseline on both sides judge: a lopsided one near a segment's
    # end is off by up to half the turn over the baseline
    centred = (t - t[before] >= baseline_s) & (t[after] - t >= baseline_s) & (before < index) & (index < after)
    return centred & np.isfinite(mismatch) & (span > 0) & (mismatch > limit_mps)


def segment_spans(cleaned: pd.DataFrame) -> pd.DataFrame:
    """First and last time and row count of every segment of a cleaned table (one row each)."""
    spans = cleaned.groupby("segment_id", sort=False)["time"].agg(["min", "max", "size"])
    return spans.rename(columns={"min": "start", "max": "end", "size": "rows"})


__all__ = [
    "CLEAN_COLUMNS",
    "REMOVAL_STEPS",
    "CleaningOptions",
    "CleaningReport",
    "clean_states",
    "outlier_runs",
    "segment_spans",
]

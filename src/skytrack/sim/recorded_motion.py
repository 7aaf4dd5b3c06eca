"""Recorded segments turned into the simulator's trajectories (:class:`TrajectorySet`).

The interpolation, and why it is this one: each segment's horizontal position in the
common ENU frame is a **cubic Hermite spline** (:class:`scipy.interpolate.CubicHermiteSpline`)
through the recorded positions, with the **recorded velocity** as its derivative at each
sample: ground speed and track (and the vertical rate, whose tilt into the common frame
far from the origin matters at the 1 % level) rotated from the aircraft's own ENU frame
into the common one.  Where a sample has no recorded ground speed or track, its velocity
is the central finite difference of the neighbouring positions (one-sided at a segment's
ends).  The curve passes exactly through every cleaned sample, has a continuous
velocity, and follows a turn between two samples with the recorded headings instead of
cutting the corner as a linear interpolation would; unlike a smoothing spline it
invents no position the recording did not have.  The height is linear in time between
two samples (the pieces of :class:`TrajectorySet` carry a linear height), so the
vertical speed is constant between samples.

Each Hermite interval becomes one polynomial piece of a :class:`TrajectorySet`
(``kind = POLY``, coefficients in ascending powers of the time since the piece start),
so the radar model evaluates recorded aircraft exactly as it evaluates scripted legs.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.interpolate import CubicHermiteSpline

from skytrack.geo.sensors import Origin
from skytrack.geo.wgs84 import geodetic_to_enu
from skytrack.sim.earth import local_axes
from skytrack.sim.trajectories import POLY, TrajectorySet


def recorded_velocity(rows: pd.DataFrame, origin: Origin) -> tuple[np.ndarray, np.ndarray]:
    """Recorded velocity ``[N, 3]`` in the common ENU frame and the mask of rows that have a
    horizontal one (ground speed and track); a missing vertical rate counts as level."""
    speed = rows["groundspeed_mps"].to_numpy(dtype=float)
    course = np.radians(rows["track_deg"].to_numpy(dtype=float))
    climb = np.nan_to_num(rows["vertical_rate_mps"].to_numpy(dtype=float), nan=0.0)
    has = np.isfinite(speed) & np.isfinite(course)
    east, north, up = local_axes(rows["lat"].to_numpy(), rows["lon"].to_numpy(), origin)
    local = np.where(has[:, None], np.column_stack([speed * np.sin(course), speed * np.cos(course), climb]), 0.0)
    velocity = local[:, :1] * east + local[:, 1:2] * north + local[:, 2:] * up
    return velocity, has


def _difference_velocity(t: np.ndarray, xy: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Central differences inside each segment, one-sided at its ends (rows grouped by segment)."""
    index = np.arange(t.size)
    segment = np.repeat(np.arange(first.size), last - first + 1)
    before = np.maximum(index - 1, first[segment])
    after = np.minimum(index + 1, last[segment])
    return (xy[after] - xy[before]) / (t[after] - t[before])[:, None]


def _time_span(t0: np.ndarray, duration_s: float) -> float:
    """A power of two well above every time used, so that ``target * span + t`` orders (target, time)."""
    reach = max(duration_s, float(np.max(np.abs(t0), initial=0.0)))
    return 2.0 ** math.ceil(math.log2(reach + 2.0)) * 4.0


def segment_trajectories(
    knots: pd.DataFrame,
    origin: Origin,
    duration_s: float,
    *,
    mode3a: np.ndarray,
    icao24: np.ndarray,
) -> TrajectorySet:
    """Trajectories of the segments of ``knots`` (rows grouped by ``segment_id`` in time order).

    ``knots`` holds the cleaned rows with ``time`` in seconds since the scenario epoch
    (the samples just outside [0, duration_s] included, so the curve is exact at the
    window's edges).  Each segment is alive from its first sample (or 0) to its last
    (or ``duration_s``).
    """
    codes, ids = pd.factorize(knots["segment_id"], sort=False)
    codes = np.asarray(codes, dtype=np.int64)
    n_targets = len(ids)
    t = knots["time"].to_numpy(dtype=float)
    first = np.searchsorted(codes, np.arange(n_targets), side="left")
    last = np.searchsorted(codes, np.arange(n_targets), side="right") - 1
    if np.any(last - first < 1):
        raise ValueError("every recorded segment needs at least two samples to be interpolated")

    x, y, _ = geodetic_to_enu(knots["lat"].to_numpy(), knots["lon"].to_numpy(), knots["alt_m"].to_numpy(),
                              origin.lat, origin.lon, origin.alt_m)
    xy = np.column_stack([np.atleast_1d(x), np.atleast_1d(y)])
    h = knots["alt_m"].to_numpy(dtype=float)
    velocity, has_velocity = recorded_velocity(knots, origin)
    slope = np.where(has_velocity[:, None], velocity[:, :2], _difference_velocity(t, xy, first, last))

    # one spline over all segments laid end to end on a (segment, time) key; the intervals
    # joining two segments are not pieces of either and are left out below
    span = _time_span(t, duration_s)
    key = codes * span + t
    spline = CubicHermiteSpline(key, xy, slope, axis=0)
    inside = np.ones(t.size - 1, dtype=bool)
    inside[last[:-1]] = False
    start = np.flatnonzero(inside)
    c = spline.c[:, start, :]  # descending powers: c[0] tau^3 + c[1] tau^2 + c[2] tau + c[3]
    coef = np.column_stack([c[3, :, 0], c[2, :, 0], c[1, :, 0], c[0, :, 0], c[3, :, 1], c[2, :, 1], c[1, :, 1], c[0, :, 1]])
    dt = t[start + 1] - t[start]
    piece_target = codes[start]
    piece_first = np.searchsorted(piece_target, np.arange(n_targets), side="left")
    piece_last = np.searchsorted(piece_target, np.arange(n_targets), side="right") - 1
    start_time = np.maximum(t[first], 0.0)
    end_time = np.minimum(t[last], duration_s)
    return TrajectorySet(
        ids=np.asarray(ids, dtype=object),
        start_time=start_time,
        end_time=end_time,
        legs_end_time=end_time.copy(),
        transponder=np.ones(n_targets, dtype=bool),
        mode3a=np.asarray(mode3a, dtype=object),
        icao24=np.asarray(icao24, dtype=object),
        origin=origin,
        piece_target=piece_target,
        piece_t0=t[start],
        piece_kind=np.full(start.size, POLY, dtype=np.int8),
        piece_coef=coef,
        piece_h0=h[start],
        piece_hdot=(h[start + 1] - h[start]) / dt,
        first_piece=piece_first,
        last_piece=piece_last,
        time_span=span,
    )


def concatenate_trajectories(a: TrajectorySet, b: TrajectorySet, duration_s: float) -> TrajectorySet:
    """The targets of ``a`` followed by those of ``b`` in one set (same origin; ids must differ)."""
    repeated = sorted(set(a.ids.tolist()) & set(b.ids.tolist()))
    if repeated:
        raise ValueError(f"target id(s) used by both scripted and recorded traffic: {', '.join(map(str, repeated[:5]))}")
    offset = len(a)
    piece_offset = a.piece_t0.size
    t0 = np.concatenate([a.piece_t0, b.piece_t0])
    return TrajectorySet(
        ids=np.concatenate([a.ids, b.ids]),
        start_time=np.concatenate([a.start_time, b.start_time]),
        end_time=np.concatenate([a.end_time, b.end_time]),
        legs_end_time=np.concatenate([a.legs_end_time, b.legs_end_time]),
        transponder=np.concatenate([a.transponder, b.transponder]),
        mode3a=np.concatenate([a.mode3a, b.mode3a]),
        icao24=np.concatenate([a.icao24, b.icao24]),
        origin=a.origin,
        piece_target=np.concatenate([a.piece_target, b.piece_target + offset]),
        piece_t0=t0,
        piece_kind=np.concatenate([a.piece_kind, b.piece_kind]),
        piece_coef=np.concatenate([a.piece_coef, b.piece_coef]),
        piece_h0=np.concatenate([a.piece_h0, b.piece_h0]),
        piece_hdot=np.concatenate([a.piece_hdot, b.piece_hdot]),
        first_piece=np.concatenate([a.first_piece, b.first_piece + piece_offset]),
        last_piece=np.concatenate([a.last_piece, b.last_piece + piece_offset]),
        time_span=max(_time_span(t0, duration_s), a.time_span, b.time_span),
    )

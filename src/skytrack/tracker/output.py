"""Track output: output instants and the rows of the tracks table (docs/formats.md).

Confirmed tracks are reported at output instants — the end of every scan of the first
radar, or every ``output_interval_s`` — predicted to the instant.  Rows are kept as column
arrays per instant; one table is built per :meth:`~skytrack.tracker.tracker.Tracker.drain`,
with one geodetic conversion for all its rows.
2-D tracks carry ``z`` null and their last Mode C altitude as ``alt_m``; lat/lon come from
the ENU position (at the last plot's height for 2-D tracks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skytrack.core.plots import decode_icao24, decode_iff, decode_mode3a
from skytrack.core.tracks import covariance_columns
from skytrack.geo.wgs84 import enu_to_geodetic
from skytrack.tracker.bank import TrackBank


@dataclass
class OutputConfig:
    output_interval_s: float | None = None
    full_covariance: bool = False

    def __post_init__(self) -> None:
        if self.output_interval_s is not None and not self.output_interval_s > 0:
            raise ValueError(f"output_interval_s must be > 0, got {self.output_interval_s}")


class OutputClock:
    """When to report: every output interval, else every scan of the first radar, else every window."""

    def __init__(self, config: OutputConfig, rotating: bool, period: float, window_s: float) -> None:
        self.config = config
        self.rotating = rotating
        self.period = period
        self.window_s = window_s
        self.next: float | None = None

    def start(self, first_time: float, phase: float) -> None:
        step = self.config.output_interval_s
        if step is not None:
            self.next = math.floor(first_time / step) * step + step
        elif self.rotating and not np.isnan(phase):
            self.next = phase + (math.floor((first_time - phase) / self.period) + 1) * self.period
        else:
            self.next = first_time + self.window_s

    @property
    def step(self) -> float:
        if self.config.output_interval_s is not None:
            return self.config.output_interval_s
        return float(self.period) if self.rotating else self.window_s

    def instants_until(self, limit: float):
        """Output instants not after ``limit`` (advances the clock)."""
        if self.next is None:
            return
        while self.next <= limit + 1e-9:
            yield self.next
            self.next += self.step


#: working column: the ENU z used for lat/lon (dropped by finish_rows)
GEODETIC_Z = "_z_geodetic"


def finish_rows(columns: dict[str, np.ndarray], origin, dim: int) -> dict[str, np.ndarray]:
    """Fill lat, lon (and alt_m in 3-D) of concatenated track rows and decode their identity codes;
    drops the working column."""
    z = columns.pop(GEODETIC_Z)
    columns["mode3a"] = decode_mode3a(columns["mode3a"])
    columns["icao24"] = decode_icao24(columns["icao24"])
    columns["iff"] = decode_iff(columns["iff"])
    lat, lon, alt = enu_to_geodetic(columns["x"], columns["y"], z, origin.lat, origin.lon, origin.alt_m)
    columns["lat"], columns["lon"] = lat, lon
    if dim == 3:
        columns["alt_m"] = alt
    return columns


def track_rows(instant: float, rows: np.ndarray, x: np.ndarray, P: np.ndarray, bank: TrackBank, dim: int,
               order: int, origin, full_covariance: bool) -> dict[str, np.ndarray]:
    """The tracks-table columns of ``rows`` of ``bank`` with states ``x``, ``P`` at ``instant``."""
    count = len(rows)
    nan = np.full(count, np.nan)
    pos = np.arange(dim) * order
    vel = pos + 1
    columns: dict[str, object] = {"time": np.full(count, instant), "track_id": bank.track_id[rows]}
    for axis, name in enumerate("xyz"):
        columns[name] = x[:, pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[name] = x[:, vel[axis]] if axis < dim else nan
    for axis, name in enumerate("xyz"):
        columns[f"var_{name}"] = P[:, pos[axis], pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[f"var_{name}"] = P[:, vel[axis], vel[axis]] if axis < dim else nan
    # lat/lon are filled by finish_rows, once per drain: one geodetic conversion, not one per instant
    columns["lat"] = columns["lon"] = nan
    columns["alt_m"] = nan if dim == 3 else bank.alt_m[rows]
    columns["status"] = np.where(bank.n_misses[rows] > 0, "coasting", "confirmed")
    columns["n_updates"] = bank.n_updates[rows]
    columns["n_misses"] = bank.n_misses[rows]
    # identity stays integer-coded until finish_rows decodes all rows of a drain at once
    columns["mode3a"] = bank.mode3a[rows]
    columns["icao24"] = bank.icao24[rows]
    columns["callsign"] = np.full(count, None, dtype=object)
    columns["iff"] = bank.iff[rows]
    columns["model_probs"] = np.full(count, None, dtype=object)
    columns[GEODETIC_Z] = x[:, pos[2]] if dim == 3 else np.nan_to_num(bank.z_hint[rows])
    if full_covariance:
        n = x.shape[1]
        iu, ju = np.triu_indices(n)
        upper = P[:, iu, ju]
        for k, name in enumerate(covariance_columns(n)):
            columns[name] = upper[:, k]
    return columns

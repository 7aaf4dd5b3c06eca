"""Track output: output instants and the rows of the tracks table (docs/formats.md).

Confirmed tracks are reported at output instants — the end of every scan of the first
radar, or every ``output_interval_s`` — predicted to the instant.  Each instant keeps a compact record
(:func:`instant_record`); one table is built per :meth:`~skytrack.tracker.tracker.Tracker.drain`
(:func:`build_table`), with one geodetic conversion and one identity decoding for all its rows.
2-D tracks carry ``z`` null and their last Mode C altitude as ``alt_m``; lat/lon come from
the ENU position (at the last plot's height for 2-D tracks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

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


def instant_record(instant: float, rows: np.ndarray, x: np.ndarray, P: np.ndarray, bank: TrackBank,
                   full_covariance: bool) -> dict[str, np.ndarray]:
    """What one output instant contributes: the bank's rows ``rows`` with states ``x``, ``P`` at
    ``instant``, kept compact (variances, or the covariance's upper triangle) until
    :func:`build_table` makes the table's columns for a whole drain at once."""
    n = x.shape[1]
    record = {
        "time": np.full(len(rows), instant), "track_id": bank.track_id[rows], "x": x,
        "var": np.diagonal(P, axis1=1, axis2=2), "n_updates": bank.n_updates[rows],
        "n_misses": bank.n_misses[rows], "alt_m": bank.alt_m[rows], "z_hint": bank.z_hint[rows],
        "mode3a": bank.mode3a[rows], "icao24": bank.icao24[rows], "iff": bank.iff[rows],
    }
    if full_covariance:
        iu, ju = np.triu_indices(n)
        record["upper"] = P[:, iu, ju]
    return record


def _status_text(coasting: np.ndarray):
    import pyarrow as pa

    return pd.array(pa.array(["confirmed", "coasting"]).take(pa.array(coasting.astype(np.int8))), dtype="str")


def build_table(records: list[dict[str, np.ndarray]], dim: int, order: int, origin) -> dict[str, np.ndarray]:
    """The tracks-table columns (docs/formats.md order) of concatenated instant records."""
    parts = {name: np.concatenate([r[name] for r in records]) for name in records[0]}
    x, var = parts["x"], parts["var"]
    count = len(x)
    nan = np.full(count, np.nan)
    pos = np.arange(dim) * order
    vel = pos + 1
    columns: dict[str, np.ndarray] = {"time": parts["time"], "track_id": parts["track_id"]}
    for axis, name in enumerate("xyz"):
        columns[name] = x[:, pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[name] = x[:, vel[axis]] if axis < dim else nan
    for axis, name in enumerate("xyz"):
        columns[f"var_{name}"] = var[:, pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[f"var_{name}"] = var[:, vel[axis]] if axis < dim else nan
    z = x[:, pos[2]] if dim == 3 else np.nan_to_num(parts["z_hint"])
    lat, lon, alt = enu_to_geodetic(x[:, pos[0]], x[:, pos[1]], z, origin.lat, origin.lon, origin.alt_m)
    columns["lat"], columns["lon"] = lat, lon
    columns["alt_m"] = alt if dim == 3 else parts["alt_m"]
    columns["status"] = _status_text(parts["n_misses"] > 0)
    columns["n_updates"] = parts["n_updates"]
    columns["n_misses"] = parts["n_misses"]
    columns["mode3a"] = decode_mode3a(parts["mode3a"])
    columns["icao24"] = decode_icao24(parts["icao24"])
    columns["callsign"] = np.full(count, None, dtype=object)
    columns["iff"] = decode_iff(parts["iff"])
    columns["model_probs"] = np.full(count, None, dtype=object)
    if "upper" in parts:
        upper = parts["upper"]
        for k, name in enumerate(covariance_columns(x.shape[1])):
            columns[name] = upper[:, k]
    return columns

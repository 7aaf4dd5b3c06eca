"""Plot columns as numpy arrays, input checks, beam phase and processing windows.

The tracker reads plots once into :class:`PlotColumns` (one array per FORMATS.md
column, SI units) and then only slices arrays.  Plots of every sensor are cut into
processing windows: a rotating radar's window is its scan (or ``sectors_per_scan``
equal sectors of it when several sensors are merged), aligned with the beam's north
crossing; windows of all sensors are processed in order of their start time.

Beam phase: the antenna points north at ``phase + k * period`` and turns clockwise, so
each plot of a rotating radar satisfies ``time = phase + (az / 2 pi + k) * period``.
:func:`estimate_beam_phase` recovers the phase from plots as the circular mean of
``time - az / (2 pi) * period`` modulo the period; it is used when ``sensors.json`` has
no ``scan_phase_s`` and to check the one it has.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from skytrack.geo.sensors import SensorSet

FT_TO_M = 0.3048


@dataclass
class PlotColumns:
    """Plots as arrays: time (s), sensor index, range (m), azimuth / elevation (rad), ..."""

    time: np.ndarray
    sensor: np.ndarray
    range_m: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    range_rate: np.ndarray
    mode_c_m: np.ndarray
    mode3a: np.ndarray
    mode_s: np.ndarray
    iff: np.ndarray
    platform: np.ndarray  # [N, 6] platform position and velocity (moving sensors), NaN otherwise

    def __len__(self) -> int:
        return len(self.time)

    def take(self, index) -> "PlotColumns":
        return PlotColumns(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def concat(parts: list["PlotColumns"]) -> "PlotColumns":
        return PlotColumns(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PlotColumns)})

    @staticmethod
    def empty() -> "PlotColumns":
        return PlotColumns.from_frame(pd.DataFrame({"time": [], "sensor": [], "range_m": [], "azimuth_deg": []}), None)

    @staticmethod
    def from_frame(frame: pd.DataFrame, sensors: SensorSet | None, source: str = "plots", first_row: int = 0) -> "PlotColumns":
        """Convert a FORMATS.md plots table; bad values raise ValueError naming the row and column.

        ``first_row`` is the row number of the frame's first row in the whole input (chunks).
        Checked here (the io readers check more): unknown sensors, non-finite or negative
        ranges, non-finite times and azimuths, and 3-D radar plots without an elevation.
        """
        count = len(frame)
        missing = [c for c in ("time", "sensor", "range_m", "azimuth_deg") if c not in frame.columns]
        if missing:
            raise ValueError(f"{source}: missing required column(s) {missing}; found {list(frame.columns)}")
        time = frame["time"].to_numpy(dtype=float)
        names = frame["sensor"].astype(str).to_numpy()
        if sensors is None:
            sensor_index = np.zeros(count, dtype=np.int16)
        else:
            lookup = {name: i for i, name in enumerate(sensors.names)}
            codes, uniques = pd.factorize(names)
            unknown = [u for u in uniques if u not in lookup]
            if unknown:
                first = first_row + int(np.flatnonzero(names == unknown[0])[0])
                raise ValueError(
                    f"{source}, row {first}, column sensor: unknown sensor {unknown[0]!r} "
                    f"(sensors.json has: {', '.join(sensors.names)})"
                )
            sensor_index = np.array([lookup[u] for u in uniques], dtype=np.int16)[codes] if count else np.zeros(0, np.int16)

        def numeric(column: str, scale: float = 1.0) -> np.ndarray:
            if column not in frame.columns:
                return np.full(count, np.nan)
            return frame[column].to_numpy(dtype=float, na_value=np.nan) * scale

        def text(column: str) -> np.ndarray:
            if column not in frame.columns:
                return np.full(count, None, dtype=object)
            values = frame[column].astype(object).to_numpy()
            return np.where(pd.isna(values), None, values)

        plots = PlotColumns(
            time=time,
            sensor=sensor_index,
            range_m=numeric("range_m"),
            azimuth=np.radians(numeric("azimuth_deg")),
            elevation=np.radians(numeric("elevation_deg")),
            range_rate=numeric("range_rate_mps"),
            mode_c_m=numeric("mode_c_ft", FT_TO_M),
            mode3a=text("mode3a"),
            mode_s=text("mode_s"),
            iff=text("iff"),
            platform=np.column_stack([numeric(f"platform_{c}") for c in ("x", "y", "z", "vx", "vy", "vz")])
            if count
            else np.zeros((0, 6)),
        )
        problems = (
            ("time", ~np.isfinite(plots.time), "value is not a finite number"),
            ("range_m", ~np.isfinite(plots.range_m), "value is not a finite number"),
            ("range_m", plots.range_m < 0, "value is negative"),
            ("azimuth_deg", ~np.isfinite(plots.azimuth), "value is not a finite number"),
        )
        if sensors is not None and count:
            is_3d = np.array([s.is_3d for s in sensors.sensors])[sensor_index]
            problems += (("elevation_deg", is_3d & ~np.isfinite(plots.elevation), "value is missing for a radar-3d plot"),)
        for name, bad, what in problems:
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                given = frame[name].iloc[row] if name in frame.columns else None
                shown = "" if given is None else f" (got {given})"
                raise ValueError(f"{source}, row {first_row + row}, column {name}: {what}{shown}")
        return plots


def check_time_order(plots: PlotColumns, sensors: SensorSet, last_times: np.ndarray, source: str = "plots",
                     first_row: int = 0) -> None:
    """Raise if time goes backwards within a sensor (across chunks too, via ``last_times``)."""
    for s in np.unique(plots.sensor):
        rows = np.flatnonzero(plots.sensor == s)
        times = np.concatenate([[last_times[s]], plots.time[rows]])
        back = np.flatnonzero(np.diff(times) < 0)
        if back.size:
            row = first_row + int(rows[back[0]])
            raise ValueError(
                f"{source}, row {row}, column time: time goes backwards for sensor {sensors.sensors[s].name!r} "
                f"({times[back[0] + 1]:.6f} s after {times[back[0]]:.6f} s); plots must be sorted by time per sensor"
            )
        last_times[s] = times[-1]


def estimate_beam_phase(time: np.ndarray, azimuth: np.ndarray, period: float) -> float:
    """Beam north-crossing phase in [0, period) from plot times and azimuths (rad)."""
    phase = np.remainder(time - azimuth / (2.0 * np.pi) * period, period)
    angle = 2.0 * np.pi * phase / period
    mean = np.arctan2(np.mean(np.sin(angle)), np.mean(np.cos(angle)))
    return float(np.remainder(mean / (2.0 * np.pi) * period, period))


def beam_crossing_time(azimuth: np.ndarray, phase: float, period: float, window_start: float) -> np.ndarray:
    """First time at or after ``window_start`` at which the beam points at ``azimuth`` (rad)."""
    crossing = phase + azimuth / (2.0 * np.pi) * period
    return window_start + np.remainder(crossing - window_start, period)

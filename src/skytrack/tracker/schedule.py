"""Processing schedule: beam phase, processing windows and which tracks expect a plot.

Plots of every sensor are cut into processing windows: a rotating radar's window is its
scan (or ``sectors_per_scan`` equal sectors of it when several sensors are merged), aligned
with the beam's north crossing; windows of all sensors are processed in order of their
start time, and a window is processed only once no later plot can fall into it, so the
order never depends on how the input was chunked.

Beam phase: the antenna points north at ``phase + k * period`` and turns clockwise, so each
plot of a rotating radar satisfies ``time = phase + (az / 2 pi + k) * period``.
:func:`estimate_beam_phase` recovers the phase as the circular mean of
``time - az / (2 pi) * period`` modulo the period; it is used when ``sensors.json`` has no
``scan_phase_s`` and to check the one it has.

Expectation (spec 000 R4: a missed detection is an expected plot that did not come): a
track is expected in a rotating radar's window when the beam crosses its predicted azimuth
inside it and it is within the radar's range (or outside every radar's coverage, so that it
is deleted once it has left); sensors without an antenna schedule (airborne radars) expect
a plot once per revisit interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.core.plots import PlotBatch
from skytrack.core.validate import require_positive
from skytrack.geo.polar import azimuth_of
from skytrack.geo.sensors import SensorSet
from skytrack.models.height import radar_horizon_m

#: plots needed before the beam phase of a sensor is estimated from data
PHASE_MIN_PLOTS = 20
#: allowed disagreement between sensors.json's scan_phase_s and the plots (fraction of a scan)
PHASE_TOLERANCE = 0.02
#: tracks whose beam crossing is this fraction of a scan outside a sector still take part
SECTOR_MARGIN = 0.05


@dataclass
class ScheduleConfig:
    """``sectors_per_scan`` (None: 1 for one radar, 4 when several are merged); ``window_s`` for
    sensors without a scan period."""

    sectors_per_scan: int | None = None
    window_s: float = 1.0

    def __post_init__(self) -> None:
        if self.sectors_per_scan is not None and self.sectors_per_scan < 1:
            raise ValueError(f"sectors_per_scan must be >= 1, got {self.sectors_per_scan}")
        require_positive(self, "window_s")


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


#: plot times beyond this many seconds from the epoch are refused: at 1e12 s a double still
#: resolves 0.1 ms, at 3.6e16 s adding a 4 s scan no longer changes the time
MAX_ABS_TIME_S = 1e12


def check_time_range(plots: PlotBatch, source: str = "plots") -> None:
    """Raise on a plot time the windows cannot resolve (|time| > :data:`MAX_ABS_TIME_S`)."""
    far = np.flatnonzero(~(np.abs(plots.time) <= MAX_ABS_TIME_S))
    if far.size:
        row = int(plots.row[far[0]])
        raise ValueError(f"{source}, row {row}, column time: {plots.time[far[0]]:g} s is beyond the tracker's range "
                         f"(|time| <= {MAX_ABS_TIME_S:g} s from the epoch; is the time in another unit or the epoch "
                         "wrong?)")


def check_time_order(plots: PlotBatch, sensors: SensorSet, last_times: np.ndarray, source: str = "plots") -> None:
    """Raise if time goes backwards within a sensor (across chunks too, via ``last_times``)."""
    for s in np.unique(plots.sensor):
        rows = np.flatnonzero(plots.sensor == s)
        times = np.concatenate([[last_times[s]], plots.time[rows]])
        back = np.flatnonzero(np.diff(times) < 0)
        if back.size:
            row = int(plots.row[rows[back[0]]])
            raise ValueError(
                f"{source}, row {row}, column time: time goes backwards for sensor {sensors.sensors[s].name!r} "
                f"({times[back[0] + 1]:.6f} s after {times[back[0]]:.6f} s); plots must be sorted by time per sensor"
            )
        last_times[s] = times[-1]


class Schedule:
    """Per-sensor scan geometry and window bookkeeping of one tracking run."""

    def __init__(self, sensors: SensorSet, config: ScheduleConfig) -> None:
        self.sensors = sensors
        radars = [s for s in sensors.sensors if s.is_radar]
        count = len(sensors.sensors)
        sectors = config.sectors_per_scan or (1 if len(radars) == 1 else 4)
        self.period = np.array([s.scan_period_s if s.scan_period_s else np.nan for s in sensors.sensors])
        self.rotating = np.array([bool(s.scan_period_s) and not s.is_moving for s in sensors.sensors])
        self.window_length = np.where(self.rotating, self.period / sectors, config.window_s)
        self.phase = np.full(count, np.nan)
        self.last_time = np.full(count, -np.inf)
        self.seen = np.zeros(count, dtype=bool)
        self.next_window = np.zeros(count, dtype=np.int64)
        self.warnings: list[str] = []

    # ------------------------------------------------------------------ input
    def admit(self, chunk: PlotBatch, source: str) -> None:
        """Check a new chunk's times, settle beam phases and start new sensors' windows."""
        check_time_range(chunk, source)
        check_time_order(chunk, self.sensors, self.last_time, source)
        if len(chunk) == 0:
            return
        new_sensors = np.unique(chunk.sensor)
        self._settle_phases(chunk)
        for s in new_sensors[~self.seen[new_sensors]]:
            first = chunk.time[chunk.sensor == s].min()
            self.next_window[s] = self.window_index(s, first)
        self.seen[new_sensors] = True

    def _settle_phases(self, chunk: PlotBatch) -> None:
        for s in np.flatnonzero(self.rotating & np.isnan(self.phase)):
            rows = chunk.sensor == s
            sensor = self.sensors.sensors[s]
            period = self.period[s]
            if rows.sum() < PHASE_MIN_PLOTS and sensor.scan_phase_s is not None:
                self.phase[s] = sensor.scan_phase_s % period
                continue
            if not rows.any():
                continue
            estimate = estimate_beam_phase(chunk.time[rows], chunk.azimuth[rows], period)
            given = sensor.scan_phase_s
            if given is not None:
                gap = abs((estimate - given + period / 2) % period - period / 2)
                if gap > PHASE_TOLERANCE * period:
                    self.warnings.append(
                        f"sensor {sensor.name!r}: scan_phase_s {given} s disagrees with the plots "
                        f"(beam north crossing at {estimate:.3f} s modulo the scan); using the plots' phase"
                    )
                else:
                    estimate = given % period
            self.phase[s] = estimate

    # ------------------------------------------------------------------ windows
    def window_index(self, s, time):
        """Index of the processing window of sensor(s) ``s`` holding ``time``."""
        phase = np.nan_to_num(self.phase[s])
        return np.floor((np.asarray(time) - phase) / self.window_length[s]).astype(np.int64)

    def window_start(self, s, index):
        return np.nan_to_num(self.phase[s]) + index * self.window_length[s]

    def skip_idle(self, until: float) -> bool:
        """Move every sensor's next window to the one holding time ``until``: when no track is
        alive and no plot comes before ``until``, the windows before it have nothing to do (a
        gap of days in a recording is not walked a scan at a time).  Returns whether a gap was
        skipped."""
        skipped = False
        for s in np.flatnonzero(self.seen):
            target = int(self.window_index(s, until))
            if target > self.next_window[s]:
                self.next_window[s] = target
                skipped = True
        return skipped

    def complete_windows(self, pending: PlotBatch, final: bool,
                         max_windows: int | None = None) -> tuple[np.ndarray, list, np.ndarray]:
        """Windows that can no longer receive plots, in start order, at most ``max_windows`` of them
        (the earliest; the caller asks again for the rest).

        Returns ``(order, windows, leftover)``: ``order`` sorts the pending plots by sensor,
        window and time, so that each window's plots are the contiguous slice ``rows`` of the
        sorted plots; ``windows`` lists ``(sensor, index, start, end, rows)``, windows without
        plots included (tracks expected in them record their misses); ``leftover`` are the
        positions, in the sorted plots, of those no window took.
        """
        sensors = np.flatnonzero(self.seen)
        plot_window = self.window_index(pending.sensor, pending.time)
        order = np.lexsort((pending.time, plot_window, pending.sensor))
        none = (order, [], np.arange(len(pending)))
        if len(sensors) == 0:
            return none
        last = self.window_index(sensors, self.last_time[sensors])
        # the window holding a sensor's latest plot may still grow, unless this is the end
        complete_until = last if final else last - 1
        first = self.next_window[sensors]
        counts = np.maximum(complete_until - first + 1, 0)
        if counts.sum() == 0:
            return none
        if max_windows is not None:
            # the earliest max_windows windows are among each sensor's first max_windows
            counts = np.minimum(counts, max_windows)
        window_sensor = np.repeat(sensors, counts)
        window_index = np.repeat(first, counts) + (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts))
        window_start = self.window_start(window_sensor, window_index)
        if not final:
            # the first incomplete window of each sensor bounds what may be processed now
            blocking_start = self.window_start(sensors, complete_until + 1)
            limit = (blocking_start.min(), sensors[np.argmin(blocking_start)])
            allowed = (window_start < limit[0]) | ((window_start == limit[0]) & (window_sensor < limit[1]))
            window_sensor, window_index, window_start = window_sensor[allowed], window_index[allowed], window_start[allowed]
        if len(window_sensor) == 0:
            return none
        by_start = np.lexsort((window_sensor, window_start))
        if max_windows is not None:
            by_start = by_start[:max_windows]
        # one sorted key per plot, (sensor, window), so every window's slice comes from two searches
        base = min(int(plot_window.min()) if len(plot_window) else 0, int(window_index.min()))
        span = max(int(plot_window.max()) if len(plot_window) else 0, int(window_index.max())) - base + 1
        plot_keys = pending.sensor[order].astype(np.int64) * span + (plot_window[order] - base)
        chosen_sensor, chosen_index = window_sensor[by_start], window_index[by_start]
        window_keys = chosen_sensor.astype(np.int64) * span + (chosen_index - base)
        starts = np.searchsorted(plot_keys, window_keys, side="left").tolist()
        ends = np.searchsorted(plot_keys, window_keys, side="right").tolist()
        taken = np.zeros(len(pending), dtype=bool)
        windows = []
        for s, k, start, a, b in zip(chosen_sensor.tolist(), chosen_index.tolist(), window_start[by_start].tolist(),
                                     starts, ends):
            taken[a:b] = True
            self.next_window[s] = k + 1
            windows.append((s, k, start, start + self.window_length[s], slice(a, b)))
        return order, windows, np.flatnonzero(~taken)

    def time_margin(self, s: int) -> float:
        """How far (s) a plot's time may be from a track's reference time in a window of sensor ``s``:
        a hundredth of the scan plus 50 ms for a rotating radar, half a window otherwise."""
        if self.rotating[s]:
            return 0.01 * self.period[s] + 0.05
        return 0.5 * self.window_length[s]

    # ------------------------------------------------------------------ expectations
    def expectations(self, s: int, w_start: float, w_end: float, position: np.ndarray, last_event: np.ndarray,
                     created: np.ndarray, altitude: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Reference time of every track in this window, whether a plot is expected, whether the
        track is near enough to the swept sector to take part in association, and whether it is
        outside every radar's coverage (range, and the radar horizon at its Mode C ``altitude``).

        ``position`` is each track's 3-D position extrapolated to the window's middle.
        """
        sensor = self.sensors.sensors[s]
        mid = 0.5 * (w_start + w_end)
        count = len(position)
        local = sensor.to_local(position)
        ground = np.hypot(local[:, 0], local[:, 1])
        if self.rotating[s]:
            period = self.period[s]
            azimuth = azimuth_of(local[:, 0], local[:, 1])
            t_ref = beam_crossing_time(azimuth, self.phase[s], period, w_start)
            expected = t_ref < w_end
            # tracks crossed just outside a sector may still have their plot in it
            margin = SECTOR_MARGIN * period
            late = t_ref >= w_start + period - margin
            nearby = expected | late | (t_ref < w_end + margin)
            t_ref = np.where(expected, t_ref, np.clip(t_ref - np.where(late, period, 0.0), w_start, w_end))
        else:
            # no antenna schedule (e.g. an airborne radar): a plot is due once per revisit
            # interval (the scan period, else the window) since the track's last hit or miss.
            # Events are dated by their window's end, so a new track is dated by the end of the
            # window of its first plot, not by the plot's time: with plots on window starts the
            # next scan's plot then falls in the window where it is due, not one window later
            revisit = self.period[s] if np.isfinite(self.period[s]) else self.window_length[s]
            t_ref = np.full(count, mid)
            created_end = self.window_start(s, self.window_index(s, created) + 1)
            since = w_end - np.maximum(last_event, created_end)
            expected = since >= revisit * (1.0 - 1e-9)
            nearby = np.ones(count, dtype=bool)
        outside = np.zeros(count, dtype=bool)
        if sensor.max_range_m and not sensor.is_moving:
            # out of this sensor's coverage no plot is due; a track that no radar covers any more
            # has left the picture and is deleted (outside)
            beyond = (ground > sensor.max_range_m) | (ground > radar_horizon_m(sensor.alt_m or 0.0, altitude))
            covered = self.in_any_coverage(position, altitude)
            expected &= ~beyond | ~covered
            outside = beyond & ~covered
        return t_ref, expected, nearby, outside

    def in_any_coverage(self, position: np.ndarray, altitude: np.ndarray) -> np.ndarray:
        """Whether some radar covers each position (its range and horizon at ``altitude``)."""
        inside = np.zeros(len(position), dtype=bool)
        for sensor in self.sensors.sensors:
            if not sensor.is_radar:
                continue
            if not sensor.max_range_m or sensor.is_moving:
                return np.ones(len(position), dtype=bool)
            offset = position[:, :2] - sensor.position[:2]
            reach = np.minimum(sensor.max_range_m, radar_horizon_m(sensor.alt_m or 0.0, altitude))
            inside |= np.einsum("ki,ki->k", offset, offset) <= reach**2
        return inside

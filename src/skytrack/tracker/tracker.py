"""Multi-target tracker: scan processing over a structure-of-arrays track bank.

Per processing window (one scan of a rotating radar, or a sector of it when several
sensors are merged; see :mod:`skytrack.tracker.plots`):

1. plots are converted to common-frame positions (:mod:`skytrack.models.conversion`);
2. every track gets a reference time — when the beam crosses its predicted azimuth —
   and is *expected* in the window if that time falls inside it and the track is within
   the sensor's range;
3. association in two stages, confirmed tracks first, then tentative tracks on the
   plots left over: candidate pairs from a k-d tree (sparse gating), each candidate
   predicted to the plot's own time (spec 000 Theorem 2 / R7), chi-square gate on the
   Mahalanobis distance, global nearest neighbour per cluster;
4. Kalman update of the assigned pairs (Joseph form), misses recorded for expected
   tracks without a plot (no update: spec 000 R4);
5. plots left over start tentative tracks (one plot with a velocity prior, or two-point);
6. M-of-N confirmation, deletion after K consecutive misses or covariance growth.

Confirmed tracks are reported at output instants (end of every scan of the first radar,
or every ``output_interval_s``), predicted to the instant.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable

import numpy as np
import pandas as pd

from skytrack.association.candidates import candidate_pairs, max_eigenvalue_sym
from skytrack.association.gate import gate_threshold
from skytrack.association.gnn import assign_gnn
from skytrack.filters.ekf import predict as kf_predict
from skytrack.filters.ekf import update as kf_update
from skytrack.geo.polar import azimuth_of
from skytrack.geo.sensors import SensorSet
from skytrack.geo.wgs84 import enu_to_geodetic
from skytrack.models.measurement import PolarMeasurementModel
from skytrack.tracker.bank import CONFIRMED, TENTATIVE, TrackBank
from skytrack.tracker.config import TrackerConfig
from skytrack.models.conversion import convert_plots, sensor_positions
from skytrack.tracker.plots import (
    PlotColumns,
    beam_crossing_time,
    check_time_order,
    estimate_beam_phase,
)

TRACK_OUTPUT_COLUMNS = [
    "time", "track_id", "x", "y", "z", "vx", "vy", "vz",
    "var_x", "var_y", "var_z", "var_vx", "var_vy", "var_vz",
    "lat", "lon", "alt_m", "status", "n_updates", "n_misses",
    "mode3a", "icao24", "callsign", "iff", "model_probs",
]

#: plots needed before the beam phase of a sensor is estimated from data
_PHASE_MIN_PLOTS = 20
#: allowed disagreement between sensors.json's scan_phase_s and the plots (fraction of a scan)
_PHASE_TOLERANCE = 0.02
#: search-radius safety factor over the exact Mahalanobis bound
_RADIUS_FACTOR = 1.05
#: tracks whose beam crossing is this fraction of a scan outside a sector still take part
_SECTOR_MARGIN = 0.05


class Tracker:
    """Multi-target tracker over plots of one or more radars.

    Use :meth:`run` on a whole plots table, or :meth:`feed` chunks (time-ordered per sensor)
    and :meth:`finish`; :meth:`drain` returns the track rows produced so far, so long
    recordings can be written incrementally with bounded memory.
    """

    def __init__(self, sensors: SensorSet, config: TrackerConfig | None = None):
        self.sensors = sensors
        self.config = config or TrackerConfig()
        radars = [s for s in sensors.sensors if s.is_radar]
        if not radars:
            raise ValueError("sensors.json describes no radar: nothing to track with")
        for s in radars:
            if s.sigma_range_m is None or s.sigma_azimuth_deg is None:
                raise ValueError(f"sensor {s.name!r}: sigma_range_m and sigma_azimuth_deg are needed for tracking")
            if s.is_3d and s.sigma_elevation_deg is None:
                raise ValueError(f"sensor {s.name!r} is radar-3d but has no sigma_elevation_deg")
        cfg = self.config
        self.dim = cfg.tracking_dim or (3 if all(s.is_3d for s in radars) else 2)
        self.model = cfg.motion_model(self.dim)
        self.order = self.model.order
        self.pos_idx = self.model.position_index
        self.vel_idx = self.model.velocity_index
        self.bank = TrackBank(self.model.dim)
        self.next_track_id = 1
        n_sensors = len(sensors.sensors)
        sectors = cfg.sectors_per_scan or (1 if len(radars) == 1 else 4)
        self.period = np.array([s.scan_period_s if s.scan_period_s else np.nan for s in sensors.sensors])
        self.rotating = np.array([bool(s.scan_period_s) and not s.is_moving for s in sensors.sensors])
        self.window_length = np.where(self.rotating, self.period / sectors, cfg.window_s)
        self.phase = np.array([np.nan] * n_sensors)
        self.last_time = np.full(n_sensors, -np.inf)
        self.seen = np.zeros(n_sensors, dtype=bool)
        self.next_window = np.zeros(n_sensors, dtype=np.int64)
        self.rows_fed = 0
        self.pending = PlotColumns.empty()
        self.output_sensor = sensors.sensors.index(radars[0])
        self.next_output: float | None = None
        self.last_window_end = -np.inf
        # track rows per output instant, as column arrays; one DataFrame is built in drain()
        self.outputs: list[dict[str, np.ndarray]] = []
        self.stats: Counter = Counter()
        self.warnings: list[str] = []
        self._gate_cache: dict[int, float] = {}
        self._max_gate = max(self.gate(m) for m in range(self.dim, self.dim + 2))

    # ------------------------------------------------------------------ public API
    def gate(self, m: int) -> float:
        """Gate threshold for ``m`` measured components (chi-square quantile, spec 000 R7)."""
        if self.config.gate_threshold is not None:
            return self.config.gate_threshold
        if m not in self._gate_cache:
            self._gate_cache[m] = float(gate_threshold(m, self.config.p_gate))
        return self._gate_cache[m]

    def run(self, plots: pd.DataFrame, progress: Callable[[float], None] | None = None,
            chunk_rows: int = 200_000) -> pd.DataFrame:
        """Track a whole plots table; returns the tracks table (FORMATS.md columns)."""
        total = len(plots)
        for start in range(0, max(total, 1), chunk_rows):
            self.feed(plots.iloc[start : start + chunk_rows])
            if progress is not None:
                progress(min(1.0, (start + chunk_rows) / max(total, 1)))
        self.finish()
        return self.drain()

    def feed(self, frame: pd.DataFrame, source: str = "plots") -> None:
        """Add a chunk of plots (sorted by time per sensor) and process every complete window.

        Errors name rows of the whole input: chunks are numbered on from earlier ones.
        """
        chunk = PlotColumns.from_frame(frame, self.sensors, source, first_row=self.rows_fed)
        check_time_order(chunk, self.sensors, self.last_time, source, first_row=self.rows_fed)
        self.rows_fed += len(frame)
        if len(chunk) == 0:
            return
        new_sensors = np.unique(chunk.sensor)
        self._settle_phases(chunk)
        for s in new_sensors[~self.seen[new_sensors]]:
            first = chunk.time[chunk.sensor == s].min()
            self.next_window[s] = self._window_index(s, first)
        self.seen[new_sensors] = True
        self.pending = PlotColumns.concat([self.pending, chunk])
        self.stats["plots"] += len(chunk)
        self._process_pending(final=False)

    def finish(self) -> None:
        """Process the remaining plots and emit the last output instants."""
        self._process_pending(final=True)
        self._emit_until(self.last_window_end)

    def drain(self) -> pd.DataFrame:
        """Track rows produced so far (and forget them)."""
        if not self.outputs:
            return _empty_tracks(self.config.full_covariance, self.dim, self.order)
        outputs, self.outputs = self.outputs, []
        return pd.DataFrame({name: np.concatenate([o[name] for o in outputs]) for name in outputs[0]})

    # ------------------------------------------------------------------ windows
    def _settle_phases(self, chunk: PlotColumns) -> None:
        for s in np.flatnonzero(self.rotating & np.isnan(self.phase)):
            rows = chunk.sensor == s
            sensor = self.sensors.sensors[s]
            if rows.sum() < _PHASE_MIN_PLOTS and sensor.scan_phase_s is not None:
                self.phase[s] = sensor.scan_phase_s % self.period[s]
                continue
            if not rows.any():
                continue
            estimate = estimate_beam_phase(chunk.time[rows], chunk.azimuth[rows], self.period[s])
            given = sensor.scan_phase_s
            if given is not None:
                gap = abs((estimate - given + self.period[s] / 2) % self.period[s] - self.period[s] / 2)
                if gap > _PHASE_TOLERANCE * self.period[s]:
                    self.warnings.append(
                        f"sensor {sensor.name!r}: scan_phase_s {given} s disagrees with the plots "
                        f"(beam north crossing at {estimate:.3f} s modulo the scan); using the plots' phase"
                    )
                else:
                    estimate = given % self.period[s]
            self.phase[s] = estimate

    def _window_index(self, s, time):
        """Index of the processing window of sensor(s) ``s`` holding ``time``."""
        phase = np.nan_to_num(self.phase[s])
        return np.floor((np.asarray(time) - phase) / self.window_length[s]).astype(np.int64)

    def _window_start(self, s, index):
        return np.nan_to_num(self.phase[s]) + index * self.window_length[s]

    def _process_pending(self, final: bool) -> None:
        """Process, in order of start time, every window that can no longer receive plots.

        A window of sensor s is complete once a later plot of s has arrived; windows of all
        sensors are taken in start order, stopping at the first incomplete one, so the order
        never depends on how the input was chunked.  Windows without plots are processed
        too: tracks expected in them record their misses.  At ``final`` every sensor's
        windows up to its last plot are complete.
        """
        sensors = np.flatnonzero(self.seen)
        if len(sensors) == 0:
            return
        last = self._window_index(sensors, self.last_time[sensors])
        # the window holding a sensor's latest plot may still grow, unless this is the end
        complete_until = last if final else last - 1
        first = self.next_window[sensors]
        counts = np.maximum(complete_until - first + 1, 0)
        if counts.sum() == 0:
            return
        window_sensor = np.repeat(sensors, counts)
        window_index = np.repeat(first, counts) + (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts))
        window_start = self._window_start(window_sensor, window_index)
        if not final:
            # the first incomplete window of each sensor bounds what may be processed now
            blocking_start = self._window_start(sensors, complete_until + 1)
            limit = (blocking_start.min(), sensors[np.argmin(blocking_start)])
            allowed = (window_start < limit[0]) | ((window_start == limit[0]) & (window_sensor < limit[1]))
            window_sensor, window_index, window_start = window_sensor[allowed], window_index[allowed], window_start[allowed]
        order = np.lexsort((window_sensor, window_start))
        window_sensor, window_index, window_start = window_sensor[order], window_index[order], window_start[order]
        plots = self.pending
        plot_window = self._window_index(plots.sensor, plots.time)
        plot_order = np.lexsort((plots.time, plot_window, plots.sensor))
        keys_sensor = plots.sensor[plot_order]
        keys_window = plot_window[plot_order]
        taken = np.zeros(len(plots), dtype=bool)
        for s, k, start in zip(window_sensor.tolist(), window_index.tolist(), window_start.tolist()):
            lo = np.searchsorted(keys_sensor, s, side="left")
            hi = np.searchsorted(keys_sensor, s, side="right")
            a = lo + np.searchsorted(keys_window[lo:hi], k, side="left")
            b = lo + np.searchsorted(keys_window[lo:hi], k, side="right")
            rows = plot_order[a:b]
            taken[rows] = True
            end = start + self.window_length[s]
            self._emit_until(start)
            self._process_window(s, start, end, plots.take(rows))
            self.last_window_end = max(self.last_window_end, end)
            self.next_window[s] = k + 1
        self.pending = plots.take(np.flatnonzero(~taken))

    # ------------------------------------------------------------------ one window
    def _process_window(self, s: int, w_start: float, w_end: float, plots: PlotColumns) -> None:
        cfg = self.config
        sensor = self.sensors.sensors[s]
        self.stats["windows"] += 1
        if self.next_output is None:
            self._init_outputs(float(plots.time.min()) if len(plots) else w_start)
        has_mode_c = np.isfinite(plots.mode_c_m)
        altitude = np.where(has_mode_c, plots.mode_c_m, cfg.default_altitude_m)
        altitude_sigma = np.where(has_mode_c, cfg.mode_c_sigma_m, cfg.default_altitude_sigma_m)
        converted = convert_plots(sensor, plots.range_m, plots.azimuth, plots.elevation,
                                  altitude, altitude_sigma, plots.platform)
        inconsistent = ~converted.consistent
        if inconsistent.any():
            self.stats["plots_height_above_slant_range"] += int(inconsistent.sum())
        n_tracks = len(self.bank)
        hit = np.zeros(n_tracks, dtype=bool)
        plot_used = np.zeros(len(plots), dtype=bool)
        if n_tracks:
            t_ref, expected, nearby = self._expectations(s, w_start, w_end)
            status = np.where(nearby, self.bank.status[:n_tracks], -1)
            confirmed = status == CONFIRMED
            # confirmed tracks first; then confirmed quiet tracks that found nothing try the
            # manoeuvre gate (psi = 1); then tentative tracks on what is left
            stages = (
                (lambda: confirmed, False),
                (lambda: confirmed & expected & ~hit & ~self.bank.manoeuvring[:n_tracks], True),
                (lambda: status == TENTATIVE, False),
            )
            for members, manoeuvre in stages:
                if manoeuvre and cfg.manoeuvre_scale == 1.0:
                    continue
                tracks = np.flatnonzero(members())
                free = np.flatnonzero(~plot_used)
                if len(tracks) == 0 or len(free) == 0:
                    continue
                assigned_tracks, assigned_plots = self._associate(
                    s, tracks, free, t_ref[tracks], plots, converted, manoeuvre
                )
                hit[assigned_tracks] = True
                plot_used[assigned_plots] = True
            self._record_events(hit, expected, w_end)
        self.stats["plots_assigned"] += int(plot_used.sum())
        self._initiate(plots.take(~plot_used), converted.position[~plot_used], converted.covariance[~plot_used])
        self._manage()

    def _expectations(self, s: int, w_start: float, w_end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference time of every track in this window, whether a plot is expected, and
        whether the track is near enough to the swept sector to take part in association."""
        sensor = self.sensors.sensors[s]
        bank = self.bank
        mid = 0.5 * (w_start + w_end)
        position = self._extrapolate_positions(mid)
        local = sensor.to_local(self._as_3d(position, bank.z_hint))
        ground = np.hypot(local[:, 0], local[:, 1])
        if self.rotating[s]:
            period = self.period[s]
            azimuth = azimuth_of(local[:, 0], local[:, 1])
            t_ref = beam_crossing_time(azimuth, self.phase[s], period, w_start)
            expected = t_ref < w_end
            # tracks crossed just outside a sector may still have their plot in it
            margin = _SECTOR_MARGIN * period
            nearby = expected | (t_ref >= w_start + period - margin) | (t_ref < w_end + margin)
            t_ref = np.where(expected, t_ref, np.clip(t_ref - np.where(t_ref >= w_start + period - margin, period, 0.0), w_start, w_end))
        else:
            # no antenna schedule (e.g. an airborne radar): a plot is due once per revisit
            # interval (the scan period, else the window) since the track's last hit or miss
            revisit = self.period[s] if np.isfinite(self.period[s]) else self.window_length[s]
            t_ref = np.full(len(bank), mid)
            expected = w_end - np.maximum(bank.last_event, bank.created) >= revisit
            nearby = np.ones(len(bank), dtype=bool)
        if sensor.max_range_m:
            # out of this sensor's range no plot is due, unless no sensor covers the track:
            # then the misses pile up and the track is deleted (it has left the coverage)
            expected &= (ground <= sensor.max_range_m) | ~self._in_any_coverage(position)
        return t_ref, expected, nearby

    def _in_any_coverage(self, position: np.ndarray) -> np.ndarray:
        inside = np.zeros(len(position), dtype=bool)
        for sensor in self.sensors.sensors:
            if not sensor.is_radar:
                continue
            if not sensor.max_range_m or sensor.is_moving:
                return np.ones(len(position), dtype=bool)
            offset = position[:, :2] - sensor.position[:2]
            inside |= np.einsum("ki,ki->k", offset, offset) <= sensor.max_range_m**2
        return inside

    def _extrapolate_positions(self, t: float) -> np.ndarray:
        """Deterministic position extrapolation of every track (no covariance), for geometry."""
        bank = self.bank
        dt = t - bank.t
        x = bank.x
        pos = x[:, self.pos_idx] + x[:, self.vel_idx] * dt[:, None]
        if self.order == 3:
            pos = pos + 0.5 * x[:, self.pos_idx + 2] * np.square(dt)[:, None]
        return pos

    def _as_3d(self, position: np.ndarray, z: np.ndarray) -> np.ndarray:
        if self.dim == 3:
            return position
        return np.column_stack([position, np.nan_to_num(z, nan=0.0)])

    def _transition(self, dt: np.ndarray, tracks: np.ndarray, manoeuvre: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """F(dt), Q(|dt|) for the given tracks; manoeuvring ones (or all, with ``manoeuvre``)
        get the manoeuvre process noise.  A negative dt (sectors of merged sensors overlap)
        extrapolates backwards."""
        step = np.abs(dt)
        F = self.model.F_batch(step)
        Q = self.model.Q_batch(step)
        if manoeuvre or self.config.manoeuvre_scale != 1.0:
            flag = np.ones(len(tracks), bool) if manoeuvre else self.bank.manoeuvring[tracks]
            Q *= np.where(flag, self.config.manoeuvre_scale, 1.0)[:, None, None]
        backwards = dt < 0
        if backwards.any():
            F[backwards] = np.linalg.inv(F[backwards])
        return F, Q

    def _associate(self, s, tracks, free, t_ref, plots: PlotColumns, converted, manoeuvre: bool = False):
        """Gate and assign one stage; returns (track indices, plot indices) assigned.

        With ``manoeuvre`` the tracks are predicted with the manoeuvre process noise
        (psi = 1) and those that get a plot switch to it.
        """
        cfg = self.config
        sensor = self.sensors.sensors[s]
        bank = self.bank
        dim = self.dim
        # --- sparse candidate search around the predicted position at the reference time
        F_ref, Q_ref = self._transition(t_ref - bank.t[tracks], tracks, manoeuvre)
        x_ref, P_ref = kf_predict(bank.x[tracks], bank.P[tracks], F_ref, Q_ref)
        pos_cov = P_ref[:, self.pos_idx[:, None], self.pos_idx]
        sigma_track = np.sqrt(np.maximum(max_eigenvalue_sym(pos_cov), 0.0))
        plot_cov = converted.covariance[free][:, :dim, :dim]
        sigma_plot = np.sqrt(np.maximum(max_eigenvalue_sym(plot_cov), 0.0))
        speed = np.linalg.norm(x_ref[:, self.vel_idx], axis=1)
        margin_s = 0.01 * self.period[s] + 0.05 if self.rotating[s] else 0.5 * self.window_length[s]
        ti_local, pj_local = candidate_pairs(
            x_ref[:, self.pos_idx], sigma_track, speed * margin_s + 1.0,
            converted.position[free][:, :dim], sigma_plot, _RADIUS_FACTOR * math.sqrt(self._max_gate),
        )
        if len(ti_local) == 0:
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        ti = tracks[ti_local]
        pj = free[pj_local]
        self.stats["candidate_pairs"] += len(ti)
        # --- exact gate: each candidate predicted to its plot's own time
        dt = plots.time[pj] - bank.t[ti]
        F, Q = self._transition(dt, ti, manoeuvre)
        x_pred, P_pred = kf_predict(bank.x[ti], bank.P[ti], F, Q)
        pair_position, pair_covariance = self._pair_measurements(sensor, ti, pj, plots, converted)
        z, R = pair_position[:, :dim], pair_covariance[:, :dim, :dim]
        n_state = self.model.dim
        use_rdot = (dim == 3 and cfg.use_range_rate and sensor.sigma_range_rate_mps is not None)
        m = dim + (1 if use_rdot else 0)
        H = np.zeros((len(ti), m, n_state))
        H[:, np.arange(dim), self.pos_idx] = 1.0
        nu = np.zeros((len(ti), m))
        nu[:, :dim] = z - x_pred[:, self.pos_idx]
        R_full = np.zeros((len(ti), m, m))
        R_full[:, :dim, :dim] = R
        n_measured = np.full(len(ti), dim)
        if use_rdot:
            self._add_range_rate(sensor, x_pred, plots, pj, H, nu, R_full, n_measured)
        S = H @ P_pred @ np.swapaxes(H, -1, -2) + R_full
        d2 = np.einsum("ki,ki->k", nu, np.linalg.solve(S, nu[..., None])[..., 0])
        thresholds = np.array([self.gate(int(k)) for k in range(dim, m + 1)])[n_measured - dim]
        inside = d2 <= thresholds
        if not inside.any():
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        ti, pj, d2 = ti[inside], pj[inside], d2[inside]
        x_pred, P_pred, H, nu, R_full = x_pred[inside], P_pred[inside], H[inside], nu[inside], R_full[inside]
        pair_position, pair_covariance = pair_position[inside], pair_covariance[inside]
        # --- global nearest neighbour per cluster; leaving a track unassigned costs its gate
        chosen = assign_gnn(ti, pj, d2, len(bank), len(plots), miss_cost=self._max_gate)
        ti, pj = ti[chosen], pj[chosen]
        if manoeuvre:
            bank.manoeuvring[ti] = True
            bank.nis_avg[ti] = np.maximum(bank.nis_avg[ti], self.config.manoeuvre_on_nis)
            self.stats["manoeuvre_gate_hits"] += len(ti)
        else:
            self._detect_manoeuvres(ti, d2[chosen] / n_measured[inside][chosen])
        result = kf_update(x_pred[chosen], P_pred[chosen], nu[chosen], H[chosen], R_full[chosen])
        self._write_updates(ti, pj, result.x, result.P, plots, pair_position[chosen], pair_covariance[chosen])
        return ti, pj

    def _detect_manoeuvres(self, tracks: np.ndarray, nis: np.ndarray) -> None:
        """Update the manoeuvre flag psi from the smoothed NIS (with hysteresis)."""
        cfg = self.config
        bank = self.bank
        memory = cfg.manoeuvre_memory
        first = bank.n_updates[tracks] <= 1
        smoothed = np.where(first, nis, memory * bank.nis_avg[tracks] + (1.0 - memory) * nis)
        bank.nis_avg[tracks] = smoothed
        flag = bank.manoeuvring[tracks]
        bank.manoeuvring[tracks] = np.where(flag, smoothed > cfg.manoeuvre_off_nis, smoothed > cfg.manoeuvre_on_nis)

    def _pair_measurements(self, sensor, ti, pj, plots: PlotColumns, converted):
        """Converted 3-D position and covariance per pair; a 2-D plot without Mode C is
        placed at its track's last Mode C altitude when the track has one."""
        position = converted.position[pj]
        covariance = converted.covariance[pj]
        if not sensor.is_3d:
            reuse = ~np.isfinite(plots.mode_c_m[pj]) & np.isfinite(self.bank.alt_m[ti])
            if reuse.any():
                redo = convert_plots(
                    sensor, plots.range_m[pj[reuse]], plots.azimuth[pj[reuse]], plots.elevation[pj[reuse]],
                    self.bank.alt_m[ti[reuse]], np.full(int(reuse.sum()), self.config.mode_c_sigma_m),
                    plots.platform[pj[reuse]],
                )
                position = position.copy()
                covariance = covariance.copy()
                position[reuse] = redo.position
                covariance[reuse] = redo.covariance
        return position, covariance

    def _add_range_rate(self, sensor, x_pred, plots: PlotColumns, pj, H, nu, R_full, n_measured):
        """Append the Doppler range rate (spec 000 R9) to pairs whose plot carries one."""
        has = np.isfinite(plots.range_rate[pj])
        if not has.any():
            R_full[:, -1, -1] = 1.0  # padding row: zero H and zero innovation leave d^2 and K exact
            return
        model = PolarMeasurementModel(("rdot",), (sensor.sigma_range_rate_mps,), self.order)
        p_s, v_s = sensor_positions(sensor, plots.platform[pj])
        h, J = model.evaluate(x_pred, sensor_position=p_s, rotation=sensor.rotation, sensor_velocity=v_s)
        H[has, -1, :] = J[has, 0, :]
        nu[has, -1] = plots.range_rate[pj][has] - h[has, 0]
        R_full[:, -1, -1] = np.where(has, sensor.sigma_range_rate_mps**2, 1.0)
        n_measured[has] += 1

    def _write_updates(self, ti, pj, x_new, P_new, plots: PlotColumns, position, covariance) -> None:
        """Store updated states and attributes; ``position``/``covariance`` are the pairs' plots."""
        bank = self.bank
        cfg = self.config
        if cfg.init == "two-point":
            second = (bank.n_updates[ti] == 1) & (bank.status[ti] == TENTATIVE)
            if second.any():
                x_new, P_new = x_new.copy(), P_new.copy()
                self._two_point(ti[second], plots.time[pj[second]], position[second], covariance[second],
                                x_new, P_new, second)
        bank.x[ti] = x_new
        bank.P[ti] = P_new
        bank.t[ti] = plots.time[pj]
        bank.n_updates[ti] += 1
        bank.n_misses[ti] = 0
        bank.z_hint[ti] = position[:, 2]
        mode_c = plots.mode_c_m[pj]
        bank.alt_m[ti] = np.where(np.isfinite(mode_c), mode_c, bank.alt_m[ti])
        for attribute, values in (("mode3a", plots.mode3a), ("icao24", plots.mode_s), ("iff", plots.iff)):
            new = values[pj]
            known = new != None  # noqa: E711 - object arrays compare element-wise
            column = getattr(bank, attribute)
            column[ti[known]] = new[known]

    def _two_point(self, ti, times, position, covariance, x_new, P_new, rows) -> None:
        """Replace the state after a tentative track's second plot by the two-point difference."""
        bank = self.bank
        dim, n = self.dim, self.model.dim
        dt = np.maximum(times - bank.t[ti], 1e-3)
        z2 = position[:, :dim]
        R2 = covariance[:, :dim, :dim]
        z1 = bank.x[ti][:, self.pos_idx]
        R1 = bank.P[ti][:, self.pos_idx[:, None], self.pos_idx]
        x = np.zeros((len(ti), n))
        x[:, self.pos_idx] = z2
        x[:, self.vel_idx] = (z2 - z1) / dt[:, None]
        P = np.zeros((len(ti), n, n))
        P[:, self.pos_idx[:, None], self.pos_idx] = R2
        P[:, self.vel_idx[:, None], self.vel_idx] = (R1 + R2) / np.square(dt)[:, None, None]
        cross = R2 / dt[:, None, None]
        P[:, self.pos_idx[:, None], self.vel_idx] = cross
        P[:, self.vel_idx[:, None], self.pos_idx] = np.swapaxes(cross, -1, -2)
        if self.order == 3:
            acc = self.pos_idx + 2
            P[:, acc, acc] = self.config.singer_sigma_a**2
        x_new[rows] = x
        P_new[rows] = P

    def _record_events(self, hit: np.ndarray, expected: np.ndarray, w_end: float) -> None:
        """M-of-N history and consecutive misses for tracks expected (or hit) in this window."""
        bank = self.bank
        n = len(hit)
        event = hit | expected
        bank.last_event[:n][event] = w_end
        window_mask = np.uint32((1 << self.config.confirm_n) - 1)
        bits = bank.hit_bits[:n]
        bits[event] = ((bits[event] << np.uint32(1)) | hit[event].astype(np.uint32)) & window_mask
        bank.n_events[:n][event] += 1
        missed = expected & ~hit
        bank.n_misses[:n][missed] += 1
        self.stats["misses"] += int(missed.sum())

    def _initiate(self, plots: PlotColumns, position: np.ndarray, covariance: np.ndarray) -> None:
        """Start tentative tracks from unassigned plots (one plot, velocity prior)."""
        count = len(plots)
        if count == 0:
            return
        cfg = self.config
        n, dim = self.model.dim, self.dim
        x = np.zeros((count, n))
        x[:, self.pos_idx] = position[:, :dim]
        P = np.zeros((count, n, n))
        P[:, self.pos_idx[:, None], self.pos_idx] = covariance[:, :dim, :dim]
        P[:, self.vel_idx, self.vel_idx] = cfg.init_sigma_v**2
        if self.order == 3:
            acc = self.pos_idx + 2
            P[:, acc, acc] = cfg.singer_sigma_a**2 if cfg.model == "singer" else 10.0**2
        ids = np.arange(self.next_track_id, self.next_track_id + count, dtype=np.int64)
        self.next_track_id += count
        mode_c = plots.mode_c_m
        self.bank.append(
            x, P, t=plots.time, track_id=ids, status=TENTATIVE, hit_bits=1, n_events=1, n_updates=1,
            n_misses=0, created=plots.time, alt_m=mode_c, z_hint=position[:, 2],
            mode3a=plots.mode3a, icao24=plots.mode_s, iff=plots.iff,
        )
        self.stats["tracks_started"] += count

    def _manage(self) -> None:
        cfg = self.config
        bank = self.bank
        if len(bank) == 0:
            return
        hits = np.bitwise_count(bank.hit_bits).astype(np.int64)
        tentative = bank.status == TENTATIVE
        confirm = tentative & (hits >= cfg.confirm_m)
        bank.status[confirm] = CONFIRMED
        bank.confirmed_at[confirm] = bank.t[confirm]
        self.stats["tracks_confirmed"] += int(confirm.sum())
        observed = np.minimum(bank.n_events, cfg.confirm_n)
        hopeless = tentative & ~confirm & ((observed - hits) > (cfg.confirm_n - cfg.confirm_m))
        pos_cov = bank.P[:, self.pos_idx[:, None], self.pos_idx]
        too_uncertain = np.sqrt(np.maximum(max_eigenvalue_sym(pos_cov), 0)) > cfg.max_position_sigma_m
        lost = (bank.status == CONFIRMED) & ((bank.n_misses >= cfg.delete_misses) | too_uncertain)
        self.stats["tentative_dropped"] += int(hopeless.sum())
        self.stats["tracks_deleted"] += int(lost.sum())
        bank.keep(~(hopeless | lost))

    # ------------------------------------------------------------------ output
    def _init_outputs(self, first_time: float) -> None:
        s = self.output_sensor
        if self.config.output_interval_s is not None:
            step = self.config.output_interval_s
            self.next_output = math.floor(first_time / step) * step + step
        elif self.rotating[s] and not np.isnan(self.phase[s]):
            period, phase = self.period[s], self.phase[s]
            self.next_output = phase + (math.floor((first_time - phase) / period) + 1) * period
        else:
            self.next_output = first_time + self.config.window_s

    def _output_step(self) -> float:
        s = self.output_sensor
        if self.config.output_interval_s is not None:
            return self.config.output_interval_s
        if self.rotating[s]:
            return float(self.period[s])
        return self.config.window_s

    def _emit_until(self, limit: float) -> None:
        if self.next_output is None:
            return
        step = self._output_step()
        while self.next_output <= limit + 1e-9:
            self._emit(self.next_output)
            self.next_output += step

    def _emit(self, instant: float) -> None:
        bank = self.bank
        rows = np.flatnonzero(bank.status == CONFIRMED)
        self.stats["output_instants"] += 1
        if len(rows) == 0:
            return
        F, Q = self._transition(instant - bank.t[rows], rows)
        x, P = kf_predict(bank.x[rows], bank.P[rows], F, Q)
        self.outputs.append(self._track_rows(instant, rows, x, P))

    def _track_rows(self, instant: float, rows: np.ndarray, x: np.ndarray, P: np.ndarray) -> dict[str, np.ndarray]:
        bank = self.bank
        count = len(rows)
        nan = np.full(count, np.nan)
        pos, vel = self.pos_idx, self.vel_idx
        columns: dict[str, object] = {"time": np.full(count, instant), "track_id": bank.track_id[rows]}
        for axis, name in enumerate("xyz"):
            columns[name] = x[:, pos[axis]] if axis < self.dim else nan
        for axis, name in enumerate(("vx", "vy", "vz")):
            columns[name] = x[:, vel[axis]] if axis < self.dim else nan
        for axis, name in enumerate("xyz"):
            columns[f"var_{name}"] = P[:, pos[axis], pos[axis]] if axis < self.dim else nan
        for axis, name in enumerate(("vx", "vy", "vz")):
            columns[f"var_{name}"] = P[:, vel[axis], vel[axis]] if axis < self.dim else nan
        z_for_geodetic = x[:, pos[2]] if self.dim == 3 else np.nan_to_num(bank.z_hint[rows])
        origin = self.sensors.origin
        lat, lon, alt = enu_to_geodetic(x[:, pos[0]], x[:, pos[1]], z_for_geodetic, origin.lat, origin.lon, origin.alt_m)
        columns["lat"], columns["lon"] = lat, lon
        columns["alt_m"] = alt if self.dim == 3 else bank.alt_m[rows]
        columns["status"] = np.where(bank.n_misses[rows] > 0, "coasting", "confirmed")
        columns["n_updates"] = bank.n_updates[rows]
        columns["n_misses"] = bank.n_misses[rows]
        columns["mode3a"] = bank.mode3a[rows]
        columns["icao24"] = bank.icao24[rows]
        columns["callsign"] = np.full(count, None, dtype=object)
        columns["iff"] = bank.iff[rows]
        columns["model_probs"] = np.full(count, None, dtype=object)
        if self.config.full_covariance:
            for i in range(self.model.dim):
                for j in range(i, self.model.dim):
                    columns[f"cov_{i}_{j}"] = P[:, i, j]
        return columns


def _empty_tracks(full_covariance: bool, dim: int, order: int) -> pd.DataFrame:
    """A tracks table without rows, with the dtypes of a full one (so chunks concatenate)."""
    integer = {"track_id", "n_updates", "n_misses"}
    text = {"mode3a", "icao24", "callsign", "iff", "model_probs"}
    columns = {
        c: pd.Series(dtype="int64" if c in integer else object if c in text else "str" if c == "status" else float)
        for c in TRACK_OUTPUT_COLUMNS
    }
    if full_covariance:
        n = dim * order
        for i in range(n):
            for j in range(i, n):
                columns[f"cov_{i}_{j}"] = pd.Series(dtype=float)
    return pd.DataFrame(columns)

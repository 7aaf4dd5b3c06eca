"""The tracker facade: feed plots, get tracks; the parts do the work.

:class:`Tracker` wires the components of one run — the schedule (windows, beam phase,
expectations), the filter (from the registry, by the configuration's ``filter`` section),
the track bank, the scan processor (association parts, update, initiation), the life cycle
and the output clock — and offers ``feed`` / ``finish`` / ``drain`` for streaming input,
``run`` for a whole table, and ``snapshot(t)`` for a live display.  Once a plot has carried
an identity (Mode 3/A, Mode S, IFF), every change of a confirmed track's identity is an
identity event (:mod:`skytrack.tracker.identity`; ``drain_identity_events``).
``checkpoint`` / ``restore`` save and rebuild the whole state (issue 11 item 3, for the live service).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import numpy as np
import pandas as pd

from skytrack.core.plots import PlotBatch
from skytrack.core.tracks import TRACK_OUTPUT_COLUMNS, empty_tracks
from skytrack.geo.sensors import SensorSet
from skytrack.models.conversion import ConvertedPlots
from skytrack.filters.imm_kernels import imm_predict_matched
from skytrack.filters.maneuver import ManoeuvreState
from skytrack.tracker.bank import CONFIRMED, TrackBank
from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.identity import IdentityEvents, changed_rows, log_rho
from skytrack.tracker.initiation import Initiator
from skytrack.tracker.lifecycle import Lifecycle
from skytrack.tracker.output import OutputClock, build_table, instant_record, reported_rows, tracks_arrow, tracks_frame
from skytrack.tracker.scan import ScanProcessor
from skytrack.tracker.schedule import Schedule
from skytrack.tracker.window_kernels import report_cv

__all__ = ["TRACK_OUTPUT_COLUMNS", "Tracker"]

#: windows processed per schedule call; between calls an empty tracker skips idle gaps
WINDOWS_PER_STEP = 4096
#: windows of the first step after an idle gap; steps double up to WINDOWS_PER_STEP while tracks live
FIRST_WINDOWS_PER_STEP = 16


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
        self.dim = cfg.geometry.tracking_dim or (3 if all(s.is_3d for s in radars) else 2)
        self.model = cfg.motion.build(self.dim)
        self.order = self.model.order
        self.filter = cfg.filter.build(self.model, cfg.motion)
        self.bank = TrackBank(self.filter)
        self.stats: Counter = Counter()
        self.schedule = Schedule(sensors, cfg.schedule)
        acceleration_sigma = cfg.motion.singer_sigma_a if cfg.motion.model == "singer" else 10.0
        self.initiator = Initiator(cfg.initiation, self.dim, self.order, acceleration_sigma)
        self.lifecycle = Lifecycle(cfg.lifecycle, np.arange(self.dim) * self.order, self.stats)
        self.scan = ScanProcessor(sensors, self.schedule, cfg, self.filter, self.bank, self.initiator,
                                  self.lifecycle, self.stats, self.dim, self.order)
        self.output_sensor = sensors.sensors.index(radars[0])
        s = self.output_sensor
        self.clock = OutputClock(cfg.output, bool(self.schedule.rotating[s]), float(self.schedule.period[s]),
                                 cfg.schedule.window_s)
        self.sensor_names = sensors.names
        self.sensor_is_3d = [s.is_3d for s in sensors.sensors]
        self.rows_fed = 0
        self.pending = PlotBatch.empty()
        self.pending_converted = ConvertedPlots.empty()
        self.last_window_end = -np.inf
        # track rows per output instant, as column arrays; one DataFrame is built in drain()
        self.outputs: list[dict[str, np.ndarray]] = []
        #: whether any plot fed so far carried Mode 3/A, Mode S or IFF (then identity events are kept)
        self.identity_seen = False
        self.identity_events = IdentityEvents(cfg.output.identity_error_p)
        self._log_rho = log_rho(cfg.output.identity_error_p)

    # ------------------------------------------------------------------ public API
    @property
    def warnings(self) -> list[str]:
        return self.schedule.warnings

    @property
    def phase(self) -> np.ndarray:
        """Beam north-crossing phase per sensor (s), NaN until known."""
        return self.schedule.phase

    def gate(self, m: int) -> float:
        """Gate threshold for ``m`` measured components (chi-square quantile, spec 000 R7)."""
        return self.scan.scorer.gate(m)

    def run(self, plots: pd.DataFrame | PlotBatch, progress: Callable[[float], None] | None = None,
            chunk_rows: int = 200_000) -> pd.DataFrame:
        """Track a whole plots table (or batch); returns the tracks table (docs/formats.md columns)."""
        total = len(plots)
        for start in range(0, max(total, 1), chunk_rows):
            if isinstance(plots, PlotBatch):
                self.feed(plots.take(slice(start, start + chunk_rows)))
            else:
                self.feed(plots.iloc[start : start + chunk_rows])
            if progress is not None:
                progress(min(1.0, (start + chunk_rows) / max(total, 1)))
        self.finish()
        return self.drain()

    def feed(self, chunk: pd.DataFrame | PlotBatch, source: str = "plots") -> None:
        """Add a chunk of plots (sorted by time per sensor) and process every complete window.

        A :class:`PlotBatch` (from the io readers) is taken as it is; a DataFrame is converted
        and checked first.  Errors name rows of the whole input.
        """
        if not isinstance(chunk, PlotBatch):
            chunk = PlotBatch.from_frame(chunk, self.sensor_names, self.sensor_is_3d, source, first_row=self.rows_fed)
        self.rows_fed += len(chunk)
        self.schedule.admit(chunk, source)
        if len(chunk) == 0:
            return
        if not self.identity_seen:
            self.identity_seen = bool((chunk.mode3a >= 0).any() or (chunk.mode_s >= 0).any() or (chunk.iff >= 0).any())
        self.pending = PlotBatch.concat([self.pending, chunk])
        self.pending_converted = ConvertedPlots.concat([self.pending_converted, self.scan.convert(chunk)])
        self.stats["plots"] += len(chunk)
        self._process_pending(final=False)

    def advance_to(self, time_s: float) -> None:
        """Declare that no plot older than ``time_s`` will come from any sensor seen so far (a live
        feed's reorder buffer vouches for it): the windows of the other sensors then need not wait
        for a radar that went silent."""
        seen = self.schedule.seen
        self.schedule.last_time[seen] = np.maximum(self.schedule.last_time[seen], float(time_s))
        self._process_pending(final=False)

    def finish(self) -> None:
        """Process the remaining plots and emit the last output instants."""
        self._process_pending(final=True)
        self._emit_until(self.last_window_end)

    def drain(self) -> pd.DataFrame:
        """Track rows produced so far (and forget them)."""
        if not self.outputs:
            return empty_tracks(self.config.output.full_covariance, self.model.dim)
        outputs, self.outputs = self.outputs, []
        return tracks_frame(self._table(outputs))

    def drain_arrow(self):
        """:meth:`drain` as a pyarrow Table (typed as the tracks file stores it), for a writer:
        no DataFrame is built.  ``None`` when there are no rows."""
        if not self.outputs:
            return None
        outputs, self.outputs = self.outputs, []
        return tracks_arrow(self._table(outputs))

    def record_assignments(self) -> None:
        """From now on, keep every plot a confirmed track takes, for :meth:`drain_assignments`."""
        if self.scan.assignment_log is None:
            self.scan.assignment_log = []

    def drain_assignments(self) -> dict[str, np.ndarray] | None:
        """The plots confirmed tracks took since the last call (after :meth:`record_assignments`):
        ``track_id``, ``time``, ``sensor`` (index), ``position`` ``[K, 3]`` and ``covariance``
        ``[K, 3, 3]`` in the common frame, in processing order; ``None`` when not recording."""
        log = self.scan.assignment_log
        if log is None:
            return None
        self.scan.assignment_log = []
        dim = 3
        if not log:
            return {"track_id": np.zeros(0, np.int64), "time": np.zeros(0), "sensor": np.zeros(0, np.int64),
                    "position": np.zeros((0, dim)), "covariance": np.zeros((0, dim, dim))}
        ids, times, sensors, positions, covariances = zip(*log)
        return {"track_id": np.concatenate(ids), "time": np.concatenate(times), "sensor": np.concatenate(sensors),
                "position": np.concatenate(positions), "covariance": np.concatenate(covariances)}

    def drain_identity_events(self):
        """The identity events found so far (docs/formats.md "identity events") as a pyarrow
        Table, and forget them; ``None`` when there are none."""
        return self.identity_events.drain()

    def _table(self, outputs: list[dict[str, np.ndarray]]) -> dict[str, object]:
        return build_table(outputs, self.dim, self.order, self.sensors.origin, self.model_names)

    def snapshot(self, t: float, confirmed_only: bool = True) -> pd.DataFrame:
        """The live picture at time ``t``: tracks predicted to ``t`` (a live display's frame)."""
        rows = np.flatnonzero(self.bank.status == CONFIRMED) if confirmed_only else np.arange(len(self.bank))
        if len(rows) == 0:
            return empty_tracks(self.config.output.full_covariance, self.model.dim)
        return tracks_frame(self._table([self._rows_at(t, rows)]))

    # ------------------------------------------------------------------ checkpoints
    def checkpoint(self) -> tuple[dict[str, np.ndarray], dict]:
        """The whole state (track bank with every filter state, clutter maps, learned codes,
        identities, open windows' plots, output clock, undrained rows, counters) as ``(arrays,
        meta)``: a flat dict of numpy arrays and a JSON-able dict (:mod:`skytrack.tracker.state`;
        :mod:`skytrack.app.checkpoint` writes them to a file)."""
        from skytrack.tracker.state import tracker_state

        return tracker_state(self)

    @classmethod
    def restore(cls, sensors: SensorSet, config: TrackerConfig | None, arrays: dict[str, np.ndarray],
                meta: dict) -> "Tracker":
        """A tracker of ``sensors`` and ``config`` in the state :meth:`checkpoint` returned: fed the
        same plots afterwards, it produces the same tracks as the tracker that was saved."""
        from skytrack.tracker.state import restore_tracker_state

        tracker = cls(sensors, config)
        restore_tracker_state(tracker, arrays, meta)
        return tracker

    # ------------------------------------------------------------------ windows
    def _process_pending(self, final: bool) -> None:
        # every step sorts the pending plots again: small steps only right after an idle gap
        step = WINDOWS_PER_STEP
        while True:
            if len(self.bank) == 0 and len(self.pending) and self.schedule.skip_idle(float(self.pending.time.min())):
                # a lone plot's tentative track dies within a few windows: a small step lets the
                # next skip_idle jump the gap (plots 1e8 s apart took 80 ms each in 4096-window steps)
                step = FIRST_WINDOWS_PER_STEP
            order, windows, leftover = self.schedule.complete_windows(self.pending, final, step)
            if not windows:
                return
            pending, converted = self.pending.take(order), self.pending_converted.take(order)
            for s, _, start, end, rows in windows:
                if self.clock.next is None:
                    first = float(pending.time[rows].min()) if rows.stop > rows.start else start
                    self.clock.start(first, self.schedule.phase[self.output_sensor])
                self._emit_until(start)
                if rows.stop == rows.start and len(self.bank) == 0:
                    continue  # nothing alive, nothing seen: the window has nothing to do
                self.stats["windows"] += 1
                self.scan.process(s, start, end, pending.take(rows), converted.take(rows))
                if self.identity_seen:
                    changed = self.scan.identity_changed
                    if changed is None:
                        changed = changed_rows(self.bank, self.bank.status == CONFIRMED)
                    self.identity_events.record(self.bank, changed)
                self.last_window_end = max(self.last_window_end, end)
            self.pending, self.pending_converted = pending.take(leftover), converted.take(leftover)
            if len(windows) < step:
                return
            step = min(2 * step, WINDOWS_PER_STEP)

    # ------------------------------------------------------------------ output
    def _emit_until(self, limit: float) -> None:
        if not (self.bank.status == CONFIRMED).any():
            self.clock.skip_to(limit)  # no confirmed track: no row to report until then
            return
        for instant in self.clock.instants_until(limit):
            self.stats["output_instants"] += 1
            if self.scan.fused_q is not None:
                record = self._report_compiled(instant)
                if record is not None:
                    self.outputs.append(record)
                continue
            rows = reported_rows(self.bank, self.config.output.report_max_misses)
            if len(rows):
                self.outputs.append(self._rows_at(instant, rows))

    def _report_compiled(self, instant: float) -> dict[str, np.ndarray] | None:
        """:meth:`_rows_at` of the confirmed tracks for the fused constant-velocity filters, compiled."""
        bank = self.bank
        storage, columns = bank.storage, bank.column_storage
        with_psi = isinstance(storage, ManoeuvreState)
        full = self.config.output.full_covariance
        (rows, x, var, upper, track_id, n_updates, n_misses, alt_m, z_hint, mode3a, icao24, iff, source,
         identity_p) = report_cv(instant, len(bank), storage.x, storage.P, columns["t"], storage.psi if with_psi else
                          self.scan._no_psi, with_psi, self.scan.fused_q,
                          float(self.filter.scale) if with_psi else 1.0, full, columns["status"], columns["track_id"],
                          columns["n_updates"], columns["n_misses"], columns["alt_m"], columns["z_hint"],
                          columns["mode3a"], columns["icao24"], columns["iff"], columns["identity"],
                          self._log_rho, self.config.output.report_max_misses)
        if len(rows) == 0:
            return None
        record = {"time": np.full(len(rows), instant), "track_id": track_id, "x": x, "var": var,
                  "n_updates": n_updates, "n_misses": n_misses, "alt_m": alt_m, "z_hint": z_hint,
                  "mode3a": mode3a, "icao24": icao24, "iff": iff, "identity_source": source,
                  "identity_p": identity_p}
        if full:
            record["upper"] = upper
        return record

    def _rows_at(self, instant: float, rows: np.ndarray) -> dict[str, np.ndarray]:
        bank = self.bank
        if self.scan.fused_imm is not None:
            # the compiled IMM: mixing, prediction and moment matching in one call
            storage = bank.storage
            x, P, probabilities = imm_predict_matched(storage.x, storage.P, storage.mu, rows, instant - bank.t[rows],
                                                      *self.scan.fused_imm)
            return instant_record(instant, rows, x, P, bank, self.config.output.full_covariance, probabilities,
                                  self.config.output.identity_error_p)
        predicted = self.filter.predict(bank.state.take(rows), instant - bank.t[rows])
        estimate = predicted.estimate()
        # a multiple-model filter's probabilities (IMM: predicted to the instant, as the state is)
        probabilities = getattr(predicted, "mu", None) if self.model_names is not None else None
        return instant_record(instant, rows, estimate.x, estimate.P, bank, self.config.output.full_covariance,
                              probabilities, self.config.output.identity_error_p)

    @property
    def model_names(self) -> tuple[str, ...] | None:
        """Names of the filter's models when it is a multiple-model filter (for ``model_probs``)."""
        return getattr(self.filter, "names", None) if self.filter.capabilities.multiple_model else None

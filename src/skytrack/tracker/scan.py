"""Scan processing: one window's association, update, initiation and life cycle.

A window of one sensor is processed as a composition of parts:

1. plots are converted to common-frame positions (:func:`skytrack.models.conversion.convert_plots`);
2. the schedule says which tracks are expected and when the beam crossed each (reference time);
3. association in stages — confirmed tracks; confirmed quiet tracks that found nothing, through
   the manoeuvre gate (filters that support it, psi = 1); tentative tracks on the plots left —
   each stage: the filter predicts the tracks to their reference time, the gate's candidate search
   (k-d tree reference or compiled grid) bounds the pairs, the filter predicts each
   pair to its plot's own time (spec 000 Theorem 2 / R7; an IMM mixes over the interval to the
   reference time, ``context["mixing_dt"]``, once per scan as in the standard cycle) and
   innovates it, the scorer gates and costs the pairs, the assigner chooses, and the filter
   updates the chosen pairs;
4. expected tracks without a plot record a miss (no update: spec 000 R4);
5. plots left over start tentative tracks; M-of-N confirmation and deletion.

A hit also updates the track's identity by spec 003 R14 (latest definite reply) and counts the
replies behind it (:mod:`skytrack.tracker.identity`).

This composition works for every registered filter, scorer and assigner and is the reference.
The common configuration runs the same steps through compiled kernels instead
(:mod:`skytrack.tracker.compiled`, mixed in here); tests hold the two equal.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from skytrack.association.grid_kernels import grid_candidates
from skytrack.association.base import Pairs
from skytrack.association.candidates import candidate_pairs
from skytrack.association.features import FeatureTables
from skytrack.association.identity_scorer import IDENTITY_RULES, PairFeatures
from skytrack.association.registry import build_assigner, build_scorer
from skytrack.core.linalg import max_eigenvalue_sym
from skytrack.core.plots import PlotBatch
from skytrack.core.validate import require_positive
from skytrack.geo.sensors import SensorSet
from skytrack.models.conversion import ConvertedPlots, convert_plots, sensor_positions
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.height import bounded_height
from skytrack.tracker.compiled import CompiledStages, cost_rule_vector, extra_start, fused_adaptive, fused_cv_q, fused_imm
from skytrack.tracker.bank import CONFIRMED, STANDARD_COLUMNS, TENTATIVE, TrackBank
from skytrack.tracker.evidence import TrackScoring, ssr_log_ratio_reference
from skytrack.tracker.identity import initial_identity, remember_replies_reference
from skytrack.tracker.initiation import Initiator
from skytrack.tracker.lifecycle import Lifecycle
from skytrack.tracker.schedule import Schedule

ASSOCIATION_MODES = ("global", "sequential")
#: search-radius safety factor over the exact Mahalanobis bound
RADIUS_FACTOR = 1.05


@dataclass
class AssociationConfig:
    """Gate probability ``p_gate`` (threshold: chi-square quantile for the measured components,
    spec 000 R7) or a fixed ``gate_threshold``; ``scorer`` — the association rule — and ``assigner``
    by registered name: "llr" (likelihood ratio against the local clutter density, the default),
    "nn" (= "d2", coordinate-only nearest neighbour), "loglik", and spec 003's "fuzzy" (identity
    features through the membership tables; ``missing_iff`` is their rule for a plot without an
    IFF reply), "crisp" (identity vetoes) and "ml" (Gaussian likelihood against the clutter
    density); ``mode`` "global" (one assignment per stage) or "sequential" (spec 003's plot-by-plot
    processing: each plot, in time order, takes its best track, which is updated before the next
    plot; a track may take several plots of a window); ``compiled`` selects the numba kernels
    (False: the numpy/scipy reference)."""

    p_gate: float = 0.9995
    gate_threshold: float | None = None
    scorer: str = "llr"
    assigner: str = "gnn"
    mode: str = "global"
    missing_iff: str = "undetermined"
    compiled: bool = True

    def __post_init__(self) -> None:
        if self.mode not in ASSOCIATION_MODES:
            raise ValueError(f"association mode must be one of {', '.join(ASSOCIATION_MODES)}, got {self.mode!r}")
        if not 0.0 < self.p_gate < 1.0:
            raise ValueError(f"p_gate must be in (0, 1), got {self.p_gate}")
        if self.gate_threshold is not None and not self.gate_threshold > 0:
            raise ValueError(f"gate_threshold must be > 0, got {self.gate_threshold}")


@dataclass
class GeometryConfig:
    """``tracking_dim`` 2 (horizontal plane) or 3; None picks 3 when every radar is 3-D.
    A 2-D plot is placed at its Mode C altitude, else at its track's last Mode C, else by the
    bounded height model (:mod:`skytrack.models.height`: between the radar horizon and
    ``max_elevation_deg``, capped at ``max_altitude_m``) — or at a fixed ``default_altitude_m``
    (± ``default_altitude_sigma_m``) when one is given.  ``use_range_rate`` adds the Doppler
    range rate of 3-D radars that measure it (spec 000 R9)."""

    tracking_dim: int | None = None
    default_altitude_m: float | None = None
    default_altitude_sigma_m: float = 3000.0
    max_elevation_deg: float = 30.0
    max_altitude_m: float = 13_700.0
    mode_c_sigma_m: float = 30.0
    use_range_rate: bool = True

    def __post_init__(self) -> None:
        if self.tracking_dim not in (None, 2, 3):
            raise ValueError(f"tracking_dim must be 2, 3 or None, got {self.tracking_dim}")
        require_positive(self, "default_altitude_sigma_m", "mode_c_sigma_m", "max_altitude_m")
        if not 0.0 < self.max_elevation_deg <= 90.0:
            raise ValueError(f"max_elevation_deg must be in (0, 90], got {self.max_elevation_deg}")
        if self.default_altitude_m is not None and not math.isfinite(self.default_altitude_m):
            raise ValueError(f"default_altitude_m must be finite, got {self.default_altitude_m}")

    def assumed_heights(self, range_m: np.ndarray, sensor_alt_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Height and its standard deviation for 2-D plots without Mode C at ``range_m``."""
        if self.default_altitude_m is not None:
            return (np.full(len(range_m), self.default_altitude_m),
                    np.full(len(range_m), self.default_altitude_sigma_m))
        return bounded_height(range_m, sensor_alt_m, self.max_elevation_deg, self.max_altitude_m,
                              self.mode_c_sigma_m)


class ScanProcessor(CompiledStages):
    """Processes windows over a :class:`TrackBank` with one filter and the association parts."""

    def __init__(self, sensors: SensorSet, schedule: Schedule, config, filter, bank: TrackBank,
                 initiator: Initiator, lifecycle: Lifecycle, stats: Counter, dim: int, order: int) -> None:
        self.sensors = sensors
        self.schedule = schedule
        self.config = config
        self.filter = filter
        self.bank = bank
        self.initiator = initiator
        self.lifecycle = lifecycle
        self.stats = stats
        self.dim = dim
        self.order = order
        self.pos = np.arange(dim) * order
        self.vel = self.pos + 1
        self.next_track_id = 1
        assoc = config.association
        options = {"p_gate": assoc.p_gate, "threshold": assoc.gate_threshold, "max_components": dim + 1}
        tables = FeatureTables(missing_iff=assoc.missing_iff)
        if assoc.scorer in IDENTITY_RULES:
            options["tables"] = tables
        self.scorer = build_scorer(assoc.scorer, **options)
        self.cost_rule = cost_rule_vector(assoc.scorer, tables)
        self.assigner = build_assigner(assoc.assigner, compiled=assoc.compiled) if assoc.assigner == "gnn" \
            else build_assigner(assoc.assigner)
        self.llr_cost = assoc.scorer == "llr"
        self.sequential = assoc.mode == "sequential"
        self.scoring = TrackScoring(config.score, sensors.sensors, schedule.period, dim, config.lifecycle.delete_misses)
        self.manoeuvre_gate = getattr(filter, "supports_manoeuvre_gate", False)
        geometry = config.geometry
        self.measurements = [
            ConvertedPositionModel(dim, order, s.sigma_range_rate_mps
                                   if dim == 3 and geometry.use_range_rate and s.sigma_range_rate_mps is not None else None)
            for s in sensors.sensors
        ]
        # The position bound needs only the gate of the sensor's own measurement, but a 2-D plot
        # without Mode C is gated where its track's altitude puts it, not where the search found it,
        # and a plot's time may fall outside the schedule's margin: the dim + 1 quantile for every
        # sensor keeps the slack that covers most of these (the dim quantile changed 21 of 3 516
        # confirmed tracks of clutter-2000).  With the bounded height model the re-placed plots are
        # covered (docs/methods/association.md); a 20x wider search assigns 13 more of 13 021 plots
        # on the terminal scenario.
        scale = RADIUS_FACTOR * math.sqrt(max(self.scorer.gate(m) for m in (dim, dim + 1)))
        self.search_scales = [scale for _ in self.measurements]
        self.fused_q = fused_cv_q(filter, assoc)
        self.fused = [self.fused_q is not None and model.linear and not sensor.is_moving
                      for model, sensor in zip(self.measurements, sensors.sensors)]
        # the IMM's compiled stage (the rest of its window runs through the composed parts)
        self.fused_imm = fused_imm(filter, assoc)
        self.fused_imm_sensor = [self.fused_imm is not None and model.linear and not sensor.is_moving
                                 for model, sensor in zip(self.measurements, sensors.sensors)]
        # the adaptive augmented filters' compiled stage (spec 002 R14), likewise
        self.fused_adaptive = fused_adaptive(filter, assoc)
        self.fused_adaptive_sensor = [self.fused_adaptive is not None and model.linear and not sensor.is_moving
                                      for model, sensor in zip(self.measurements, sensors.sensors)]
        self._extra_start = extra_start(filter)
        self._rotation = [np.ascontiguousarray(sensor.rotation, dtype=float) for sensor in sensors.sensors]
        self._origin = [np.asarray(sensor.position, dtype=float) for sensor in sensors.sensors]
        self._no_psi = np.zeros(1, dtype=bool)
        #: bank rows whose identity changed in the last window, when the compiled end of window
        #: listed them (None: :func:`skytrack.tracker.identity.changed_rows` finds them)
        self.identity_changed: np.ndarray | None = None
        #: with :meth:`record_assignments`: (track_id, time, sensor, position, covariance) of every plot
        #: a confirmed track took, for identification against other systems (spec 001)
        self.assignment_log: list | None = None
        self._standard_columns = set(STANDARD_COLUMNS)
        # coverage of every radar, for "no plot is due outside coverage" (Schedule.in_any_coverage)
        radars = [r for r in sensors.sensors if r.is_radar]
        self._cover_all = any(not r.max_range_m or r.is_moving for r in radars)
        bounded = [r for r in radars if r.max_range_m and not r.is_moving]
        self._cover_xy = np.array([r.position[:2] for r in bounded], dtype=float).reshape(-1, 2)
        self._cover_r2 = np.array([r.max_range_m**2 for r in bounded], dtype=float)
        self._cover_alt = np.array([r.alt_m or 0.0 for r in bounded], dtype=float)

    def convert(self, plots: PlotBatch) -> ConvertedPlots:
        """Common-frame positions of a chunk of plots (all sensors), at their Mode C altitude or the
        assumed height (:meth:`GeometryConfig.assumed_heights`)."""
        geometry = self.config.geometry
        has_mode_c = np.isfinite(plots.mode_c_m)
        altitude = plots.mode_c_m.copy()
        altitude_sigma = np.full(len(plots), geometry.mode_c_sigma_m)
        for s in np.unique(plots.sensor[~has_mode_c]):
            rows = np.flatnonzero((plots.sensor == s) & ~has_mode_c)
            altitude[rows], altitude_sigma[rows] = geometry.assumed_heights(
                plots.range_m[rows], float(self.sensors.sensors[s].alt_m or 0.0))
        converted = ConvertedPlots(np.empty((len(plots), 3)), np.empty((len(plots), 3, 3)),
                                   np.empty(len(plots), dtype=bool))
        for s in np.unique(plots.sensor):
            rows = np.flatnonzero(plots.sensor == s)
            sensor = self.sensors.sensors[s]
            if self.config.association.compiled and not sensor.is_moving:
                part = self._convert_compiled(s, plots.range_m[rows], plots.azimuth[rows], plots.elevation[rows],
                                              altitude[rows], altitude_sigma[rows])
            else:
                part = convert_plots(sensor, plots.range_m[rows], plots.azimuth[rows], plots.elevation[rows],
                                     altitude[rows], altitude_sigma[rows], plots.platform[rows])
            converted.position[rows], converted.covariance[rows], converted.consistent[rows] = (
                part.position, part.covariance, part.consistent)
        inconsistent = int((~converted.consistent).sum())
        if inconsistent:
            self.stats["plots_height_above_slant_range"] += inconsistent
        return converted

    def process(self, s: int, w_start: float, w_end: float, plots: PlotBatch, converted: ConvertedPlots) -> None:
        self._window_evidence(s)
        self.identity_changed = None
        if self.fused[s] and self.schedule.rotating[s] and set(self.bank.column_storage) == self._standard_columns:
            self._process_compiled(s, w_start, w_end, plots, converted)
            return
        bank = self.bank
        n_tracks = len(bank)
        hit = np.zeros(n_tracks, dtype=bool)
        plot_used = np.zeros(len(plots), dtype=bool)
        plot_stage = np.full(len(plots), -1, np.int8)
        compiled_window = (self.fused[s] or self.fused_imm_sensor[s] or self.fused_adaptive_sensor[s]) \
            and self.schedule.rotating[s]
        expected = outside = hit
        if n_tracks:
            if compiled_window:
                t_ref, expected, nearby, outside = self._expect_compiled(s, w_start, w_end)
            else:
                position = self._positions_at(0.5 * (w_start + w_end))
                t_ref, expected, nearby, outside = self.schedule.expectations(
                    s, w_start, w_end, position, bank.last_event, bank.created, bank.alt_m)
            status = np.where(nearby, bank.status, -1)
            confirmed = status == CONFIRMED
            # confirmed tracks first; then confirmed quiet tracks that found nothing try the
            # manoeuvre gate (psi = 1); then tentative tracks on what is left
            for stage_index, stage in enumerate(("confirmed", "manoeuvre", "tentative")):
                if stage == "confirmed":
                    members = confirmed
                elif stage == "manoeuvre":
                    if not self.manoeuvre_gate:
                        continue
                    members = confirmed & expected & ~hit & ~self.filter.in_manoeuvre(bank.state)
                else:
                    members = status == TENTATIVE
                tracks = np.flatnonzero(members)
                free = np.flatnonzero(~plot_used)
                if len(tracks) == 0 or len(free) == 0:
                    continue
                assigned_tracks, assigned_plots = self._associate(s, tracks, free, t_ref[tracks], plots, converted,
                                                                  stage == "manoeuvre")
                hit[assigned_tracks] = True
                plot_used[assigned_plots] = True
                plot_stage[assigned_plots] = stage_index
                if self.assignment_log is not None and stage != "tentative":
                    self._log_assignments(assigned_tracks, assigned_plots, plots, converted)
            if not compiled_window:
                self.lifecycle.record_events(bank, hit, expected, w_end, self.scoring.log_miss[s])
        self.stats["plots_assigned"] += int(plot_used.sum())
        if compiled_window and set(bank.column_storage) == self._standard_columns:
            self._initiate_manage_compiled(s, plots, converted, np.flatnonzero(~plot_used), hit, expected, outside,
                                           w_start, w_end, plot_stage)
            return
        self._learn(s, w_start, w_end, plots, plot_stage)
        self._initiate(plots.take(~plot_used), converted.position[~plot_used], converted.covariance[~plot_used])
        if compiled_window:
            self._manage_compiled(s, hit, expected, outside, w_end)
        else:
            self.lifecycle.manage(bank, outside, *self._score_settings(s)[1:])

    def _log_assignments(self, track_rows: np.ndarray, plot_rows: np.ndarray, plots: PlotBatch,
                         converted: ConvertedPlots) -> None:
        if len(plot_rows):
            self.assignment_log.append((self.bank.track_id[track_rows].copy(), plots.time[plot_rows],
                                        plots.sensor[plot_rows], converted.position[plot_rows],
                                        converted.covariance[plot_rows]))

    def _positions_at(self, t: float) -> np.ndarray:
        """Deterministic 3-D position extrapolation of every track (no covariance), for geometry."""
        bank = self.bank
        x = bank.estimate().x
        dt = t - bank.t
        pos = x[:, self.pos] + x[:, self.vel] * dt[:, None]
        if self.order == 3:
            pos = pos + 0.5 * x[:, self.pos + 2] * np.square(dt)[:, None]
        if self.dim == 3:
            return pos
        return np.column_stack([pos, np.nan_to_num(bank.z_hint, nan=0.0)])

    # ------------------------------------------------------------------ one stage
    def _associate(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots, manoeuvre: bool):
        """Gate, score, assign and update one stage; returns (track rows, plot rows) assigned."""
        if self.fused[s]:
            return self._associate_fused(s, tracks, free, t_ref, plots, converted, manoeuvre)
        if self.fused_imm_sensor[s]:
            return self._associate_fused_imm(s, tracks, free, t_ref, plots, converted, manoeuvre)
        if self.fused_adaptive_sensor[s]:
            return self._associate_fused_adaptive(s, tracks, free, t_ref, plots, converted, manoeuvre)
        if self.sequential and len(free) > 1:
            return self._associate_sequential(s, tracks, free, t_ref, plots, converted, manoeuvre)
        return self._associate_pairs(s, tracks, free, t_ref, plots, converted, manoeuvre)

    def _associate_sequential(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots,
                              manoeuvre: bool):
        """Spec 003's plot-by-plot processing (R11 greedy): each plot in time order (ties in input
        order) is scored against the stage's tracks as they are after the plots before it, takes
        its best one, and that track is updated at once; a track may take several plots."""
        taken_tracks, taken_plots = [], []
        for j in free[np.argsort(plots.time[free], kind="stable")]:
            ti, pj = self._associate_pairs(s, tracks, np.array([j]), t_ref, plots, converted, manoeuvre)
            taken_tracks.append(ti)
            taken_plots.append(pj)
        return np.concatenate(taken_tracks), np.concatenate(taken_plots)

    def _associate_pairs(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots, manoeuvre: bool):
        """The composed parts of one stage (or, in sequential mode, of one plot)."""
        bank = self.bank
        dim = self.dim
        context = {"manoeuvre": True} if manoeuvre else None
        empty = np.zeros(0, np.intp)
        # --- candidate search around the predicted position at the reference time
        reference = self.filter.predict(bank.state.take(tracks), t_ref - bank.t[tracks], context).estimate()
        sigma_track = np.sqrt(np.maximum(max_eigenvalue_sym(reference.P[:, self.pos[:, None], self.pos]), 0.0))
        plot_cov = converted.covariance[free][:, :dim, :dim]
        sigma_plot = np.sqrt(np.maximum(max_eigenvalue_sym(plot_cov), 0.0))
        speed = np.linalg.norm(reference.x[:, self.vel], axis=1)
        schedule = self.schedule
        margin_s = schedule.time_margin(s)
        plot_positions = converted.position[free][:, :dim]
        search = grid_candidates if self.config.association.compiled else candidate_pairs
        ti_local, pj_local = search(reference.x[:, self.pos], sigma_track, speed * margin_s + 1.0, plot_positions,
                                    sigma_plot, self.search_scales[s])
        if len(ti_local) == 0:
            return empty, empty
        ti = tracks[ti_local]
        pj = free[pj_local]
        self.stats["candidate_pairs"] += len(ti)
        # --- each candidate predicted to its plot's own time, innovated and scored
        # an IMM mixes each track once, over the interval to its reference time (mixing_dt)
        mixing = {**(context or {}), "mixing_dt": t_ref[ti_local] - bank.t[ti]}
        predicted = self.filter.predict(bank.state.take(ti), plots.time[pj] - bank.t[ti], mixing)
        position, covariance = self._pair_measurements(s, ti, pj, plots, converted)
        model = self.measurements[s]
        z, measurement_context = self._measurement(s, model, pj, plots, position, covariance)
        innovation = self.filter.innovate(predicted, z, model, measurement_context if context is None
                                          else {**measurement_context, **context})
        evidence = self._pair_evidence(s, ti, pj, plots)
        if self.llr_cost:
            scores = self.scorer.score(innovation, Pairs(ti, pj), len(bank), evidence, self.scoring.log_miss[s])
        elif getattr(self.scorer, "uses_identity", False):
            features = PairFeatures.from_codes(bank.iff[ti], plots.iff[pj], bank.mode3a[ti], plots.mode3a[pj],
                                               bank.icao24[ti], plots.mode_s[pj])
            log_clutter = self.scoring.maps[s].log_density(plots.range_m[pj], plots.azimuth[pj])
            scores = self.scorer.score(innovation, Pairs(ti, pj), len(bank), features, log_clutter)
        else:
            scores = self.scorer.score(innovation, Pairs(ti, pj), len(bank))
        chosen = self.assigner.assign(scores, len(bank), len(plots))
        if len(chosen) == 0:
            return empty, empty
        gain = innovation.loglik[chosen] + evidence[chosen]
        ti, pj = ti[chosen], pj[chosen]
        updated, _ = self.filter.update(predicted.take(chosen), z[chosen], innovation.take(chosen))
        if manoeuvre:
            self.stats["manoeuvre_gate_hits"] += len(ti)
        self._write_updates(ti, pj, updated, plots, position[chosen], covariance[chosen], gain)
        return ti, pj

    def _pair_evidence(self, s, ti, pj, plots: PlotBatch) -> np.ndarray:
        """Per pair: ln P_D - ln beta_j + ln(SSR ratio), the part of a hit's score gain beyond
        ln N(nu; 0, S) (:mod:`skytrack.tracker.evidence`)."""
        bank = self.bank
        ssr = ssr_log_ratio_reference(plots.mode3a[pj], plots.mode_c_m[pj], bank.mode3a[ti], bank.alt_m[ti],
                                      plots.time[pj] - bank.t[ti], self._evidence[0])
        log_clutter = self.scoring.maps[s].log_density(plots.range_m[pj], plots.azimuth[pj])
        return self.scoring.log_pd[s] - log_clutter + ssr

    def _measurement(self, s, model: ConvertedPositionModel, pj, plots: PlotBatch, position, covariance):
        dim = self.dim
        context = {"R": covariance[:, :dim, :dim]}
        if model.range_rate_sigma is None:
            return position[:, :dim], context
        sensor = self.sensors.sensors[s]
        rate = plots.range_rate[pj]
        has = np.isfinite(rate)
        p_s, v_s = sensor_positions(sensor, plots.platform[pj])
        context.update(has_range_rate=has, sensor_position=p_s, sensor_velocity=v_s, rotation=sensor.rotation)
        return np.column_stack([position[:, :dim], np.where(has, rate, 0.0)]), context

    def _pair_measurements(self, s, ti, pj, plots: PlotBatch, converted: ConvertedPlots):
        """Converted 3-D position and covariance per pair; a 2-D plot without Mode C is placed at
        its track's last Mode C altitude when the track has one."""
        sensor = self.sensors.sensors[s]
        position = converted.position[pj]
        covariance = converted.covariance[pj]
        if not sensor.is_3d:
            reuse = ~np.isfinite(plots.mode_c_m[pj]) & np.isfinite(self.bank.alt_m[ti])
            if reuse.any():
                redo = convert_plots(
                    sensor, plots.range_m[pj[reuse]], plots.azimuth[pj[reuse]], plots.elevation[pj[reuse]],
                    self.bank.alt_m[ti[reuse]], np.full(int(reuse.sum()), self.config.geometry.mode_c_sigma_m),
                    plots.platform[pj[reuse]],
                )
                position[reuse] = redo.position
                covariance[reuse] = redo.covariance
        return position, covariance

    def _write_updates(self, ti, pj, updated, plots: PlotBatch, position, covariance, gain) -> None:
        """Store updated states and attributes; ``position``/``covariance`` are the pairs' plots,
        ``gain`` their score gains."""
        bank = self.bank
        bank.score[ti] += gain
        bank.score_max[ti] = np.maximum(bank.score_max[ti], bank.score[ti])
        if self.config.initiation.method == "two-point":
            second = (bank.n_updates[ti] == 1) & (bank.status[ti] == TENTATIVE)
            if second.any():
                first = bank.estimate(ti[second])
                x, P = self.initiator.two_point(first.x[:, self.pos], first.P[:, self.pos[:, None], self.pos],
                                                plots.time[pj[second]] - bank.t[ti[second]],
                                                position[second], covariance[second])
                updated.reset_estimate(np.flatnonzero(second), x, P)
        bank.state.put(ti, updated)
        bank.t[ti] = plots.time[pj]
        bank.n_updates[ti] += 1
        bank.n_misses[ti] = 0
        bank.z_hint[ti] = position[:, 2]
        mode_c = plots.mode_c_m[pj]
        bank.alt_m[ti] = np.where(np.isfinite(mode_c), mode_c, bank.alt_m[ti])
        remember_replies_reference(bank, ti, plots.mode3a[pj], plots.mode_s[pj], plots.iff[pj])

    def _initiate(self, plots: PlotBatch, position: np.ndarray, covariance: np.ndarray) -> None:
        """Start tentative tracks from unassigned plots."""
        count = len(plots)
        if count == 0:
            return
        x, P = self.initiator.one_point(position, covariance)
        ids = np.arange(self.next_track_id, self.next_track_id + count, dtype=np.int64)
        self.next_track_id += count
        self.bank.append(
            self.filter.initiate(x, P), t=plots.time, track_id=ids, status=TENTATIVE, hit_bits=1, n_events=1,
            n_updates=1, n_misses=0, created=plots.time, alt_m=plots.mode_c_m, z_hint=position[:, 2],
            mode3a=plots.mode3a, icao24=plots.mode_s, iff=plots.iff,
            identity=initial_identity(plots.mode3a, plots.mode_s, plots.iff),
        )
        self.stats["tracks_started"] += count

"""The compiled path of the scan processor for the common case (a mixin of ScanProcessor).

It applies when :func:`fused_cv_q` finds a compiled Kalman filter (plain or with the psi
switch) on a constant-velocity model with the same noise on every axis, a compiled scorer and
the ``gnn`` assigner, for a ground radar without range rate.  A rotating radar's window is then
expectations (:func:`~skytrack.tracker.window_kernels.expect_rotating`), every association stage
(:func:`~skytrack.tracker.stage_kernel.stages_cv`) and the end of the window
(:func:`~skytrack.tracker.window_kernels.initiate_manage`): three compiled calls.  Other
sensors use one compiled call per stage (:meth:`CompiledStages._associate_fused`).

An IMM of continuous-noise CV/CT modes (:func:`fused_imm`) has one compiled call per stage
(:func:`~skytrack.tracker.imm_stage_kernel.stage_imm`) and, for a rotating radar, the same
compiled expectations and end of window: the window kernels take every bank in mixture form
(:meth:`CompiledStages._mixture_arrays`; a Gaussian bank is one mode of probability 1).

The composed parts in :mod:`skytrack.tracker.scan` are the reference; tests hold the two equal.
"""

from __future__ import annotations

import numpy as np

from skytrack.association.features import FeatureTables
from skytrack.association.gnn import MAX_DENSE_CLUSTER
from skytrack.core.plots import PlotBatch
from skytrack.filters.base import GaussianState, MixtureState
from skytrack.filters.adaptive_tracking import AdaptiveTrackingFilter
from skytrack.filters.adaptive_tracking_kernels import settings_vector
from skytrack.filters.imm import IMMFilter, SojournTransition
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.maneuver import ManoeuvreState
from skytrack.geo.polar import EARTH_RADIUS_M
from skytrack.models.conversion import ConvertedPlots
from skytrack.models.conversion_kernels import convert_2d_batch, convert_3d_batch
from skytrack.models.motion import ConstantVelocityAxis
from skytrack.tracker.schedule import SECTOR_MARGIN
from skytrack.tracker.imm_stage_kernel import stage_imm
from skytrack.tracker.adaptive_stage_kernel import stage_adaptive
from skytrack.tracker.stage_kernel import (COST_RULE_SIZE, RULE_CRISP, RULE_FUZZY, RULE_LLR, RULE_ML, RULE_NN, stage_cv,
                                           stages_cv)
from skytrack.tracker.window_kernels import expect_rotating, initiate_manage, record_and_manage

#: scorers whose costs the compiled stages compute (:func:`~skytrack.tracker.stage_kernel.pair_evidence`)
COMPILED_SCORERS = {"d2": RULE_NN, "nn": RULE_NN, "llr": RULE_LLR, "fuzzy": RULE_FUZZY, "crisp": RULE_CRISP,
                    "ml": RULE_ML}


def cost_rule_vector(scorer: str, tables: FeatureTables) -> np.ndarray:
    """The compiled stages' cost rule: its kind, the fuzzy ``ln mu_G`` table (3 x 4) and ``ln mu_N``
    for a match and a mismatch (:func:`~skytrack.tracker.stage_kernel.identity_log_membership`)."""
    vector = np.zeros(COST_RULE_SIZE)
    vector[0] = COMPILED_SCORERS.get(scorer, RULE_NN)
    vector[1:13] = tables.log_g.reshape(-1)
    vector[13:15] = tables.log_n
    return vector


class CompiledStages:
    """Compiled counterparts of :class:`~skytrack.tracker.scan.ScanProcessor`'s steps."""

    def _convert_compiled(self, s, range_m, azimuth, elevation, altitude, altitude_sigma) -> ConvertedPlots:
        """:func:`convert_plots` of a ground radar by the compiled kernels."""
        sensor = self.sensors.sensors[s]
        if sensor.is_3d:
            position, covariance, consistent = convert_3d_batch(
                range_m, azimuth, elevation, sensor.sigma_range_m**2, sensor.sigma_azimuth_rad**2,
                sensor.sigma_elevation_rad**2, self._rotation[s], self._origin[s])
        else:
            position, covariance, consistent = convert_2d_batch(
                range_m, azimuth, altitude, np.square(altitude_sigma), float(sensor.alt_m or 0.0), EARTH_RADIUS_M,
                sensor.sigma_range_m**2, sensor.sigma_azimuth_rad**2, self._rotation[s], self._origin[s])
        return ConvertedPlots(position, covariance, consistent)

    # ------------------------------------------------------------------ one window

    def _process_compiled(self, s: int, w_start: float, w_end: float, plots: PlotBatch,
                          converted: ConvertedPlots) -> None:
        """:meth:`process` of the common case: expectations, every association stage, then
        initiation and life cycle, each one compiled call (:func:`~skytrack.tracker.stage_kernel.stages_cv`)."""
        bank = self.bank
        n_tracks = len(bank)
        hit = np.zeros(n_tracks, dtype=bool)
        plot_used = np.zeros(len(plots), dtype=bool)
        expected = hit
        plot_stage = np.full(len(plots), -1, np.int8)
        outside = hit
        if n_tracks:
            t_ref, expected, nearby, outside = self._expect_compiled(s, w_start, w_end)
            status_now = np.where(nearby, bank.status, -1).astype(np.int8)
            plot_track = np.full(len(plots), -1, np.int64)
            self._stages_compiled(s, plots, converted, status_now, expected, t_ref, hit, plot_used, plot_stage,
                                  plot_track)
            if self.assignment_log is not None:
                # stages 0 and 1 are confirmed tracks; identification ignores tentative ones
                taken = np.flatnonzero((plot_stage >= 0) & (plot_stage < 2))
                self._log_assignments(plot_track[taken], taken, plots, converted)
        self.stats["plots_assigned"] += int(plot_used.sum())
        self._initiate_manage_compiled(s, plots, converted, np.flatnonzero(~plot_used), hit, expected, outside,
                                       w_start, w_end, plot_stage)

    def _stages_compiled(self, s, plots, converted, status_now, expected, t_ref, hit, plot_used, plot_stage,
                         plot_track) -> None:
        storage, columns = self.bank.storage, self.bank.column_storage
        _, psi, _, _, q_big, *_ = self._switch_arrays()
        candidates, manoeuvre_hits = stages_cv(
            self.manoeuvre_gate, status_now, expected, t_ref, hit, plot_used, storage.x, storage.P, columns["t"],
            columns["alt_m"], psi, q_big, *self._stage_arguments(s, plots, converted), plot_stage, plot_track,
        )
        self.stats["candidate_pairs"] += candidates
        self.stats["manoeuvre_gate_hits"] += manoeuvre_hits

    def _stage_arguments(self, s, plots: PlotBatch, converted: ConvertedPlots) -> tuple:
        """The arguments that :func:`~skytrack.tracker.stage_kernel.stage_cv` and
        :func:`~skytrack.tracker.stage_kernel.stages_cv` share, from ``plot_time`` on: the window's
        plots, the model, the gate and search, the sensor's geometry, the assignment, the psi
        switch, the bank columns the update writes and the window's evidence (:meth:`_window_evidence`)."""
        dim = self.dim
        sensor = self.sensors.sensors[s]
        columns = self.bank.column_storage
        psi_enabled, _, nis_avg, filter_updates, _, on, off, memory = self._switch_arrays()
        replace_height = not sensor.is_3d
        return (
            plots.time, converted.position, converted.covariance, plots.mode_c_m, plots.range_m, plots.azimuth,
            self.fused_q, dim, self.search_scales[s], self.schedule.time_margin(s), self.scorer.gate(dim),
            replace_height, float(sensor.alt_m or 0.0) if replace_height else 0.0, EARTH_RADIUS_M,
            sensor.sigma_range_m**2, sensor.sigma_azimuth_rad**2, self.config.geometry.mode_c_sigma_m**2,
            self._rotation[s], self._origin[s], self.scorer.gate(dim + 1), MAX_DENSE_CLUSTER, psi_enabled, on, off,
            memory, self.config.initiation.method == "two-point", nis_avg, filter_updates, columns["n_updates"],
            columns["n_misses"], columns["z_hint"], columns["status"], columns["mode3a"], columns["icao24"],
            columns["iff"], columns["identity"], plots.mode3a, plots.mode_s, plots.iff,
            *self.scoring.clutter_arguments(s), self.cost_rule,
            self.scoring.log_pd[s], self.scoring.log_miss[s], self._evidence[0], columns["score"], columns["score_max"],
        )

    def _window_evidence(self, s: int) -> None:
        """The window's SSR parameters and score thresholds (:meth:`TrackScoring.window`)."""
        self._evidence = self.scoring.window(s)

    def _learn(self, s: int, w_start: float, w_end: float, plots: PlotBatch, plot_stage: np.ndarray) -> None:
        """The clutter map and code probabilities learn from the window's plots (numpy reference)."""
        scans = (w_end - w_start) / self.scoring.periods[s]
        self.scoring.observe(s, plots.range_m, plots.azimuth, plots.mode3a, plots.mode_c_m, plot_stage, scans)

    def _score_settings(self, s: int) -> tuple:
        """(log_miss, score_logic, confirm_score, drop_score, delete_drop, min_plots) of sensor ``s``'s window."""
        scoring = self.scoring
        return (scoring.log_miss[s], self.config.score.track_logic == "score", self._evidence[1], self._evidence[2],
                scoring.delete_drop[s], min(self.config.score.confirm_min_plots, self.config.lifecycle.confirm_n))

    def _switch_arrays(self):
        """The psi switch's arrays and settings for the kernels (dummies for a plain Kalman filter)."""
        storage = self.bank.storage
        if isinstance(storage, ManoeuvreState):
            filt = self.filter
            return (True, storage.psi, storage.nis_avg, storage.n_updates, float(filt.scale), filt.on, filt.off,
                    filt.memory)
        return False, self._no_psi, np.zeros(1), np.zeros(1, np.int64), 1.0, 0.0, 0.0, 0.0

    def _expect_compiled(self, s: int, w_start: float, w_end: float):
        bank = self.bank
        sensor = self.sensors.sensors[s]
        schedule = self.schedule
        columns = bank.column_storage
        # a mixture's position is its moment-matched mean (ScanProcessor._positions_at)
        x = bank.storage.x if isinstance(bank.storage, GaussianState) else bank.estimate().x
        return expect_rotating(x, columns["t"], columns["z_hint"], columns["alt_m"], len(bank), self.dim,
                               self.order, 0.5 * (w_start + w_end), w_start, w_end, float(schedule.phase[s]),
                               float(schedule.period[s]), self._rotation[s], self._origin[s],
                               float(sensor.max_range_m or 0.0), float(sensor.alt_m or 0.0), self._cover_xy,
                               self._cover_r2, self._cover_alt, self._cover_all, SECTOR_MARGIN)

    def _initiate_manage_compiled(self, s: int, plots: PlotBatch, converted: ConvertedPlots, new: np.ndarray,
                                  hit: np.ndarray, expected: np.ndarray, outside: np.ndarray, w_start: float,
                                  w_end: float, plot_stage: np.ndarray) -> None:
        """Initiation, events, life cycle and compaction in one compiled call (standard columns only)."""
        bank = self.bank
        bank.reserve(len(bank) + len(new))
        storage, columns = bank.storage, bank.column_storage
        with_psi = isinstance(storage, ManoeuvreState)
        cfg = self.config.lifecycle
        x, P, mu, mu0 = self._mixture_arrays()
        size, misses, confirmed, hopeless, lost, self.identity_changed = initiate_manage(
            len(bank), new, plots.time, converted.position, converted.covariance, plots.mode_c_m, plots.mode3a,
            plots.mode_s, plots.iff, self.next_track_id, self.config.initiation.sigma_v, self.dim, with_psi, hit,
            expected, w_end, cfg.confirm_m, cfg.confirm_n, cfg.delete_misses, cfg.max_position_sigma_m, self.pos,
            x, P, mu, mu0, storage.psi if with_psi else self._no_psi,
            storage.nis_avg if with_psi else np.zeros(1), storage.n_updates if with_psi else np.zeros(1, np.int64),
            columns["t"], columns["track_id"], columns["status"], columns["hit_bits"], columns["n_events"],
            columns["n_updates"], columns["n_misses"], columns["created"], columns["last_event"],
            columns["confirmed_at"], columns["alt_m"], columns["z_hint"], columns["mode3a"], columns["icao24"],
            columns["iff"], columns["identity"], columns["score"], columns["score_max"], *self._score_settings(s),
            plots.range_m, plots.azimuth, plot_stage, (w_end - w_start) / self.scoring.periods[s], *self.scoring.clutter_arguments(s),
            self.scoring.code_counts[s], outside, *self._extra_start,
        )
        bank.size = size
        self.next_track_id += len(new)
        self.stats["tracks_started"] += len(new)
        self.stats["misses"] += misses
        self.stats["tracks_confirmed"] += confirmed
        self.stats["tentative_dropped"] += hopeless
        self.stats["tracks_deleted"] += lost

    def _mixture_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The bank's storage in the window kernels' mixture form: ``x[N, M, n]``, ``P[N, M, n, n]``,
        ``mu[N, M]`` and the initial probabilities; a Gaussian bank is one mode of probability 1
        (views of its arrays: the kernels write through them)."""
        storage = self.bank.storage
        if isinstance(storage, MixtureState):
            return storage.x, storage.P, storage.mu, np.asarray(self.filter.initial_probabilities, dtype=float)
        count, n = storage.x.shape
        return (storage.x.reshape(count, 1, n, copy=False), storage.P.reshape(count, 1, n, n, copy=False),
                np.ones((count, 1)), np.ones(1))

    def _manage_compiled(self, s: int, hit: np.ndarray, expected: np.ndarray, outside: np.ndarray,
                         w_end: float) -> None:
        bank = self.bank
        cfg = self.config.lifecycle
        columns = bank.columns
        x, P, mu, _ = self._mixture_arrays()
        keep, misses, confirmed, hopeless, lost = record_and_manage(
            hit, expected, w_end, cfg.confirm_m, cfg.confirm_n, cfg.delete_misses, cfg.max_position_sigma_m, self.pos,
            x, P, mu, columns["t"], columns["status"], columns["hit_bits"], columns["n_events"],
            columns["n_misses"], columns["last_event"], columns["confirmed_at"], columns["score"],
            columns["score_max"], *self._score_settings(s), outside,
        )
        self.stats["misses"] += misses
        self.stats["tracks_confirmed"] += confirmed
        self.stats["tentative_dropped"] += hopeless
        self.stats["tracks_deleted"] += lost
        bank.keep(keep)

    def _associate_fused(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots, manoeuvre: bool):
        """:meth:`_associate` in one compiled call (:func:`skytrack.tracker.stage_kernel.stage_cv`)."""
        storage, columns = self.bank.storage, self.bank.column_storage
        _, psi, _, _, q_big, *_ = self._switch_arrays()
        rows, plot_rows, candidates = stage_cv(
            tracks, free, storage.x, storage.P, columns["t"], columns["alt_m"], psi, q_big, manoeuvre, t_ref,
            *self._stage_arguments(s, plots, converted),
        )
        self.stats["candidate_pairs"] += candidates
        if manoeuvre:
            self.stats["manoeuvre_gate_hits"] += len(rows)
        return rows, plot_rows

    def _associate_fused_adaptive(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots,
                                  manoeuvre: bool):
        """:meth:`_associate` of an adaptive augmented filter in one compiled call
        (:func:`skytrack.tracker.adaptive_stage_kernel.stage_adaptive`)."""
        storage, columns = self.bank.storage, self.bank.column_storage
        code, p, settings = self.fused_adaptive
        (plot_time, plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, _, dim, search_scale, margin_s, gate,
         replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense, _, _, _, _,
         two_point, _, _, n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s,
         plot_iff, clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score,
         score_max) = self._stage_arguments(s, plots, converted)
        rows, plot_rows, candidates = stage_adaptive(
            tracks, free, storage.x, storage.P, columns["t"], columns["alt_m"], manoeuvre, code, dim, p, settings,
            t_ref, plot_time, plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, search_scale, margin_s, gate,
            replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense, two_point,
            n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s, plot_iff,
            clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max,
        )
        self.stats["candidate_pairs"] += candidates
        if manoeuvre:
            self.stats["manoeuvre_gate_hits"] += len(rows)
        return rows, plot_rows

    def _associate_fused_imm(self, s, tracks, free, t_ref, plots: PlotBatch, converted: ConvertedPlots,
                             manoeuvre: bool):
        """:meth:`_associate` of an IMM in one compiled call (:func:`skytrack.tracker.imm_stage_kernel.stage_imm`)."""
        storage, columns = self.bank.storage, self.bank.column_storage
        modes, sojourn, fixed = self.fused_imm
        forced = self.filter.manoeuvre_mode if manoeuvre and self.filter.manoeuvre_mode is not None else -1
        arguments = self._stage_arguments(s, plots, converted)
        (plot_time, plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, _, dim, search_scale, margin_s, gate,
         replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense, _, _, _, _,
         two_point, _, _, n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s,
         plot_iff, clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max) = arguments
        rows, plot_rows, candidates = stage_imm(
            tracks, free, storage.x, storage.P, storage.mu, columns["t"], columns["alt_m"], forced, modes, sojourn,
            fixed, t_ref, plot_time, plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, dim, search_scale,
            margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense,
            two_point, n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s,
            plot_iff, clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max,
        )
        self.stats["candidate_pairs"] += candidates
        if manoeuvre:
            self.stats["manoeuvre_gate_hits"] += len(rows)
        return rows, plot_rows


def compiled_association(association) -> bool:
    """Whether the association runs through the compiled stages: compiled, a scorer of
    :data:`COMPILED_SCORERS`, the ``gnn`` assigner, global mode."""
    return bool(association.compiled and association.scorer in COMPILED_SCORERS and association.assigner == "gnn"
                and association.mode == "global")


def fused_adaptive(filter, association) -> tuple | None:
    """``(code, p, settings)`` for :func:`~skytrack.tracker.adaptive_stage_kernel.stage_adaptive` when
    the compiled stage applies: a compiled adaptive augmented filter (spec 002 R14) without a
    recorder, and the compiled GNN association with a scorer of :data:`COMPILED_SCORERS` in global mode."""
    if not (isinstance(filter, AdaptiveTrackingFilter) and filter.compiled) or filter.recorder.active:
        return None
    if not compiled_association(association):
        return None
    return filter.code, filter.p, settings_vector(filter.code, filter.preset)


def extra_start(filter) -> tuple[np.ndarray, np.ndarray]:
    """Start values and variances of the state components beyond the CV ones of a new track (the
    compiled initiation's ``extra_x0``, ``extra_var``): an adaptive filter's parameters and memory."""
    if not isinstance(filter, AdaptiveTrackingFilter):
        return np.zeros(0), np.zeros(0)
    probe = filter.initiate(np.zeros((1, filter.n_motion)), np.zeros((1, filter.n_motion, filter.n_motion)))
    n = filter.n_motion
    return probe.x[0, n:].copy(), np.diagonal(probe.P[0])[n:].copy()


def fused_imm(filter, association) -> tuple | None:
    """``(modes, sojourn, fixed)`` for :func:`~skytrack.tracker.imm_stage_kernel.stage_imm` when the
    compiled IMM stage applies: an IMM whose modes are all continuous-noise CV/CT models
    (:func:`skytrack.filters.imm_kernels.mode_table`), no recorder, and the compiled GNN association
    with a scorer of :data:`COMPILED_SCORERS` in global mode."""
    if not isinstance(filter, IMMFilter) or filter._modes is None or filter.recorder.active:
        return None
    if any(mode.recorder.active or mode.form != "joseph" for mode in filter.modes):
        return None
    if not compiled_association(association):
        return None
    M = filter.n_modes
    if isinstance(filter.transition, SojournTransition):
        return filter._modes, np.array(filter.transition.sojourn_s), np.zeros((M, M))
    return filter._modes, np.zeros(0), np.ascontiguousarray(filter.transition.matrix)


def fused_cv_q(filter, association) -> float | None:
    """The CV process-noise PSD when the compiled stage applies to this filter and association, else None.

    It applies to compiled Kalman filters (plain or with the psi switch) in Joseph form on a
    constant-velocity model with the same noise on every axis, with a scorer of :data:`COMPILED_SCORERS`
    and the GNN assigner in global mode.
    """
    kalman = getattr(filter, "kalman", filter)
    if not (isinstance(kalman, KalmanFilter) and kalman.compiled and kalman.form == "joseph"):
        return None
    if not issubclass(filter.state_type, GaussianState) or filter.recorder.active or kalman.recorder.active:
        return None
    motion = kalman.transition
    axis = motion.axes[0]
    if not (motion.identical_axes and type(axis) is ConstantVelocityAxis):
        return None
    if not compiled_association(association):
        return None
    return float(axis.q)

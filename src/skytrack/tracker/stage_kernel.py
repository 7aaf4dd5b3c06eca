"""One association stage of the common case in a single compiled call (numba, cached).

:func:`stage_cv` chains :func:`skytrack.tracker.kernels.gate_stage_cv` (prediction, search,
chi-square gate), :func:`skytrack.association.kernels.assign_clusters` (global nearest
neighbour: lone pairs, dense clusters up to ``max_dense`` nodes, sparse shortest paths above)
and :func:`skytrack.tracker.kernels.update_write_cv` (Kalman update, psi switch, bank
columns) so that a stage costs one dispatch from Python; :func:`stages_cv` runs every stage of
a window in one call.  Between gate and assignment, :func:`pair_evidence` gives each pair its
score gain and cost (:mod:`skytrack.tracker.evidence`): ``d^2`` with the gate as the cost of a
miss, or (``llr_cost``) the log-likelihood ratio against a miss, pairs worse than a miss left out.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.association.kernels import assign_clusters
from skytrack.tracker.clutter_map import log_density_at
from skytrack.tracker.evidence import LOG_2PI, ssr_log_ratio
from skytrack.tracker.kernels import gate_stage_cv, update_write_cv


@njit(cache=True, nogil=True)
def stage_cv(tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos,
             plot_cov, plot_mode_c, plot_range, plot_azimuth, q, ndim, search_scale,
             margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense,
             psi_enabled, psi_on, psi_off, psi_memory, two_point, nis_avg, filter_updates, n_updates, n_misses,
             z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s, plot_iff, clutter_grid,
             clutter_params, clutter_log_area, llr_cost, log_pd, log_miss, ssr, score, score_max):
    """Returns the bank rows and plot rows updated, and the number of candidate pairs."""
    kt, kp, d2, logdet, position, covariance, candidates = gate_stage_cv(
        tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos, plot_cov,
        plot_mode_c, plot_range, plot_azimuth, q, ndim, search_scale, margin_s, gate,
        replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin)
    gain, cost, offered, miss_cost = pair_evidence(
        tracks, free, kt, kp, d2, logdet, ndim, miss, llr_cost, log_pd, log_miss, clutter_grid, clutter_params,
        clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c, mode3a, alt_all, t_all)
    chosen = assign_clusters(kt[offered], kp[offered], cost[offered], miss_cost, len(tracks), len(free), max_dense)
    pick, rows, plot_rows = chosen_rows(offered, chosen, kt, kp, tracks, free)
    update_write_cv(rows, plot_rows, d2[pick], position[pick], covariance[pick], q, q_big, ndim, forced, psi_enabled,
                    psi_on, psi_off, psi_memory, two_point, x_all, P_all, psi_all, nis_avg, filter_updates, t_all,
                    n_updates, n_misses, z_hint, alt_all, status, mode3a, icao24, iff, identity, plot_time, plot_mode_c,
                    plot_mode3a, plot_mode_s, plot_iff, gain[pick], score, score_max)
    return rows, plot_rows, candidates


@njit(cache=True, nogil=True, inline="always")
def chosen_rows(offered, chosen, kt, kp, tracks, free):
    """The pairs the assignment chose (indices into the gated pairs) and their bank and plot rows."""
    pick = offered[np.flatnonzero(chosen)]
    rows = np.empty(len(pick), np.int64)
    plot_rows = np.empty(len(pick), np.int64)
    for c in range(len(pick)):
        rows[c] = tracks[kt[pick[c]]]
        plot_rows[c] = free[kp[pick[c]]]
    return pick, rows, plot_rows


@njit(cache=True, nogil=True)
def pair_evidence(tracks, free, kt, kp, d2, logdet, ndim, gate_miss, llr_cost, log_pd, log_miss, clutter_grid,
                  clutter_params, clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c,
                  mode3a, alt_m, t):
    """Per gated pair: the score gain of a hit, the assignment cost, the pairs offered to the
    assignment (indices) and the cost of a miss per track (see the module docstring).

    With ``llr_cost`` the cost of pair (i, j) is ``-2 (gain_ij - ln(1 - P_D))``; pairs with a cost
    >= 0 are not offered, and each track's costs are shifted by its cheapest pair so that they
    are >= 0 (the assignment's shortest paths need that; a track takes one pair or its miss, so
    the shift does not change the choice): the miss then costs minus that cheapest cost."""
    count = len(kt)
    gain = np.empty(count)
    cost = np.empty(count)
    for c in range(count):
        row = tracks[kt[c]]
        j = free[kp[c]]
        evidence = ssr_log_ratio(plot_mode3a[j], plot_mode_c[j], mode3a[row], alt_m[row], plot_time[j] - t[row], ssr)
        log_clutter = log_density_at(plot_range[j], plot_azimuth[j], clutter_grid, clutter_params, clutter_log_area)
        gain[c] = log_pd - 0.5 * (d2[c] + logdet[c] + ndim * LOG_2PI) - log_clutter + evidence
        cost[c] = -2.0 * (gain[c] - log_miss) if llr_cost else d2[c]
    miss_cost = np.full(len(tracks), gate_miss)
    if not llr_cost:
        return gain, cost, np.arange(count), miss_cost
    cheapest = np.zeros(len(tracks))
    offered = np.empty(count, np.int64)
    m = 0
    for c in range(count):
        if cost[c] < 0.0:
            cheapest[kt[c]] = min(cheapest[kt[c]], cost[c])
            offered[m] = c
            m += 1
    for c in range(count):
        cost[c] -= cheapest[kt[c]]
    for k in range(len(tracks)):
        miss_cost[k] = -cheapest[k]
    return gain, cost, offered[:m], miss_cost


@njit(cache=True, nogil=True)
def stages_cv(manoeuvre_gate, status_now, expected, t_ref, hit, plot_used, x_all, P_all, t_all, alt_all, psi_all, q_big, plot_time, plot_pos, plot_cov, plot_mode_c,
              plot_range, plot_azimuth, q, ndim, search_scale, margin_s, gate, replace_height, sensor_alt, earth,
              var_r, var_az, var_h, rot, origin, miss, max_dense, psi_enabled, psi_on, psi_off, psi_memory, two_point,
              nis_avg, filter_updates, n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a,
              plot_mode_s, plot_iff, clutter_grid, clutter_params, clutter_log_area, llr_cost, log_pd, log_miss, ssr, score, score_max, plot_stage):
    """The association stages of a window in one call: 0 confirmed tracks,
    1 quiet confirmed tracks that found nothing through the manoeuvre gate (when
    ``manoeuvre_gate``), 2 tentative tracks — each on the plots left by the stages before
    (:meth:`skytrack.tracker.scan.ScanProcessor.process`).  ``status_now`` is each track's status,
    or -1 when it is too far from the swept sector; ``hit``, ``plot_used`` and ``plot_stage`` (the
    stage that took each plot) are updated.
    Returns the number of candidate pairs and of manoeuvre-gate hits.
    """
    n_tracks = len(status_now)
    n_plots = len(plot_used)
    candidates = 0
    manoeuvre_hits = 0
    for stage in range(3):
        if stage == 1 and not manoeuvre_gate:
            continue
        count = 0
        for k in range(n_tracks):
            if _member(stage, status_now[k], expected[k], hit[k], psi_enabled and psi_all[k]):
                count += 1
        free_count = 0
        for j in range(n_plots):
            if not plot_used[j]:
                free_count += 1
        if count == 0 or free_count == 0:
            continue
        tracks = np.empty(count, np.int64)
        stage_t_ref = np.empty(count)
        m = 0
        for k in range(n_tracks):
            if _member(stage, status_now[k], expected[k], hit[k], psi_enabled and psi_all[k]):
                tracks[m] = k
                stage_t_ref[m] = t_ref[k]
                m += 1
        free = np.empty(free_count, np.int64)
        m = 0
        for j in range(n_plots):
            if not plot_used[j]:
                free[m] = j
                m += 1
        forced = stage == 1
        rows, plot_rows, found = stage_cv(
            tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, stage_t_ref, plot_time, plot_pos,
            plot_cov, plot_mode_c, plot_range, plot_azimuth, q, ndim, search_scale, margin_s,
            gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense,
            psi_enabled, psi_on, psi_off, psi_memory, two_point, nis_avg, filter_updates, n_updates, n_misses,
            z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s, plot_iff, clutter_grid,
            clutter_params, clutter_log_area, llr_cost, log_pd, log_miss, ssr, score, score_max)
        candidates += found
        for c in range(len(rows)):
            hit[rows[c]] = True
            plot_used[plot_rows[c]] = True
            plot_stage[plot_rows[c]] = stage
        if forced:
            manoeuvre_hits += len(rows)
    return candidates, manoeuvre_hits


@njit(cache=True, nogil=True, inline="always")
def _member(stage, status_now, expected, hit, psi):
    if stage == 0:
        return status_now == 1
    if stage == 1:
        return status_now == 1 and expected and not hit and not psi
    return status_now == 0

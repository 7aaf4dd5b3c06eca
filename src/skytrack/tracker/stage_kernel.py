"""One association stage of the common case in a single compiled call (numba, cached).

:func:`stage_cv` chains :func:`skytrack.tracker.kernels.gate_stage_cv` (prediction, search,
chi-square gate), :func:`skytrack.association.kernels.assign_clusters` (global nearest
neighbour: lone pairs, dense clusters up to ``max_dense`` nodes, sparse shortest paths above)
and :func:`skytrack.tracker.kernels.update_write_cv` (Kalman update, psi switch, bank
columns) so that a stage costs one dispatch from Python; :func:`stages_cv` runs every stage of
a window in one call.  Between gate and assignment, :func:`pair_evidence` gives each pair its
score gain and cost (:mod:`skytrack.tracker.evidence`): ``d^2`` with the gate as the cost of a
miss (nn), the log-likelihood ratio against a miss (llr), or one of spec 003's rules (fuzzy, crisp,
ml: :mod:`skytrack.association.identity_scorer`), pairs worse than the alternative left out.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.association.kernels import assign_clusters
from skytrack.tracker.clutter_map import log_density_at
from skytrack.tracker.evidence import LOG_2PI, ssr_log_ratio

#: kinds of association cost (the first entry of the cost-rule vector)
RULE_NN, RULE_LLR, RULE_FUZZY, RULE_CRISP, RULE_ML = 0.0, 1.0, 2.0, 3.0, 4.0
COST_RULE_SIZE = 15
from skytrack.tracker.kernels import gate_stage_cv, update_write_cv


@njit(cache=True, nogil=True)
def stage_cv(tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos,
             plot_cov, plot_mode_c, plot_range, plot_azimuth, q, ndim, search_scale,
             margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense,
             psi_enabled, psi_on, psi_off, psi_memory, two_point, nis_avg, filter_updates, n_updates, n_misses,
             z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s, plot_iff, clutter_grid,
             clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max):
    """Returns the bank rows and plot rows updated, and the number of candidate pairs."""
    kt, kp, d2, logdet, position, covariance, candidates = gate_stage_cv(
        tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos, plot_cov,
        plot_mode_c, plot_range, plot_azimuth, q, ndim, search_scale, margin_s, gate,
        replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin)
    gain, pick, rows, plot_rows = assign_pairs(
        tracks, free, kt, kp, d2, logdet, ndim, gate, miss, cost_rule, log_pd, log_miss, clutter_grid, clutter_params,
        clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c, mode3a, alt_all, t_all,
        iff, plot_iff, icao24, plot_mode_s, max_dense)
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


@njit(cache=True, nogil=True, inline="always")
def identity_log_membership(track_iff, plot_iff, track_mode3a, plot_mode3a, track_mode_s, plot_mode_s, cost_rule):
    """``ln(mu_G mu_N)`` of one pair for the fuzzy rule, or 0 / ``-inf`` (the veto) for the crisp one
    (:mod:`skytrack.association.identity_scorer`; the number is the Mode S address when both have one)."""
    if track_mode_s >= 0 and plot_mode_s >= 0:
        h_n, z_n = track_mode_s + 4096, plot_mode_s + 4096
    else:
        h_n, z_n = track_mode3a, plot_mode3a
    if cost_rule[0] == RULE_CRISP:
        definite = track_iff >= 0 and track_iff != 2 and plot_iff >= 0 and plot_iff != 2
        if (definite and track_iff != plot_iff) or (h_n >= 0 and z_n >= 0 and h_n != z_n):
            return -np.inf
        return 0.0
    h_g = 2 if track_iff < 0 else track_iff
    z_g = 3 if plot_iff < 0 else plot_iff
    total = cost_rule[1 + 4 * h_g + z_g]
    if h_n >= 0 and z_n >= 0:
        total += cost_rule[13] if h_n == z_n else cost_rule[14]
    return total


@njit(cache=True, nogil=True)
def pair_evidence(tracks, free, kt, kp, d2, logdet, ndim, gate, gate_miss, cost_rule, log_pd, log_miss, clutter_grid,
                  clutter_params, clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c,
                  mode3a, alt_m, t, track_iff, plot_iff, track_mode_s, plot_mode_s):
    """Per gated pair: the score gain of a hit, the assignment cost, the pairs offered to the
    assignment (indices) and the cost of a miss per track (see the module docstring).

    ``cost_rule`` (:func:`skytrack.tracker.scan.cost_rule_vector`): its kind, then the fuzzy
    rule's ``ln mu_G`` table (3 x 4, the last column a plot without reply) and ``ln mu_N`` for a
    match and a mismatch.  Costs: ``d2`` (nn) with the gate as the miss; otherwise a pair's cost
    against the alternative of its plot being new or false and its track missed — the likelihood
    ratio ``-2 (gain_ij - ln(1 - P_D))`` (llr), ``-2 (ln N - ln beta_j)`` (ml), ``d^2 - gamma - 2
    ln(mu_G mu_N)`` (fuzzy, crisp) — where only pairs below 0 (llr, ml) or at most 0 (fuzzy,
    crisp) are offered, and each track's costs are shifted by its cheapest pair so that they are
    >= 0 (the assignment's shortest paths need that; a track takes one pair or its miss, so the
    shift does not change the choice): the miss then costs minus that cheapest cost."""
    count = len(kt)
    gain = np.empty(count)
    cost = np.empty(count)
    kind = cost_rule[0]
    for c in range(count):
        row = tracks[kt[c]]
        j = free[kp[c]]
        evidence = ssr_log_ratio(plot_mode3a[j], plot_mode_c[j], mode3a[row], alt_m[row], plot_time[j] - t[row], ssr)
        log_clutter = log_density_at(plot_range[j], plot_azimuth[j], clutter_grid, clutter_params, clutter_log_area)
        log_gaussian = -0.5 * (d2[c] + logdet[c] + ndim * LOG_2PI)
        gain[c] = log_pd + log_gaussian - log_clutter + evidence
        if kind == RULE_LLR:
            cost[c] = -2.0 * (gain[c] - log_miss)
        elif kind == RULE_NN:
            cost[c] = d2[c]
        elif kind == RULE_ML:
            cost[c] = -2.0 * (log_gaussian - log_clutter)
        else:
            cost[c] = d2[c] - gate - 2.0 * identity_log_membership(
                track_iff[row], plot_iff[j], mode3a[row], plot_mode3a[j], track_mode_s[row], plot_mode_s[j], cost_rule)
    miss_cost = np.full(len(tracks), gate_miss)
    if kind == RULE_NN:
        return gain, cost, np.arange(count), miss_cost
    # fuzzy and crisp offer a tie with the new object (cost 0): a track beats "new" (spec 003 R12)
    bound = 1e-300 if kind == RULE_FUZZY or kind == RULE_CRISP else 0.0
    cheapest = np.zeros(len(tracks))
    offered = np.empty(count, np.int64)
    m = 0
    for c in range(count):
        if cost[c] < bound:
            cheapest[kt[c]] = min(cheapest[kt[c]], cost[c])
            offered[m] = c
            m += 1
    for c in range(count):
        cost[c] -= cheapest[kt[c]]
    for k in range(len(tracks)):
        miss_cost[k] = -cheapest[k]
    return gain, cost, offered[:m], miss_cost


@njit(cache=True, nogil=True)
def assign_pairs(tracks, free, kt, kp, d2, logdet, ndim, gate, miss, cost_rule, log_pd, log_miss, clutter_grid,
                 clutter_params, clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c,
                 mode3a, alt_all, t_all, iff, plot_iff, icao24, plot_mode_s, max_dense):
    """The part every compiled stage shares after its gate: the gated pairs' score gains and costs
    (:func:`pair_evidence`), the assignment of small clusters and large ones
    (:func:`~skytrack.association.kernels.assign_clusters`) and the chosen pairs: returns the gains, the
    chosen indices into the gated pairs and their bank and plot rows."""
    gain, cost, offered, miss_cost = pair_evidence(
        tracks, free, kt, kp, d2, logdet, ndim, gate, miss, cost_rule, log_pd, log_miss, clutter_grid, clutter_params,
        clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c, mode3a, alt_all, t_all,
        iff, plot_iff, icao24, plot_mode_s)
    chosen = assign_clusters(kt[offered], kp[offered], cost[offered], miss_cost, len(tracks), len(free), max_dense)
    pick, rows, plot_rows = chosen_rows(offered, chosen, kt, kp, tracks, free)
    return gain, pick, rows, plot_rows


@njit(cache=True, nogil=True)
def stages_cv(manoeuvre_gate, status_now, expected, t_ref, hit, plot_used, x_all, P_all, t_all, alt_all, psi_all, q_big, plot_time, plot_pos, plot_cov, plot_mode_c,
              plot_range, plot_azimuth, q, ndim, search_scale, margin_s, gate, replace_height, sensor_alt, earth,
              var_r, var_az, var_h, rot, origin, miss, max_dense, psi_enabled, psi_on, psi_off, psi_memory, two_point,
              nis_avg, filter_updates, n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a,
              plot_mode_s, plot_iff, clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max, plot_stage, plot_track):
    """The association stages of a window in one call: 0 confirmed tracks,
    1 quiet confirmed tracks that found nothing through the manoeuvre gate (when
    ``manoeuvre_gate``), 2 tentative tracks — each on the plots left by the stages before
    (:meth:`skytrack.tracker.scan.ScanProcessor.process`).  ``status_now`` is each track's status,
    or -1 when it is too far from the swept sector; ``hit``, ``plot_used``, ``plot_stage`` (the
    stage that took each plot) and ``plot_track`` (the bank row that took it) are updated.
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
            clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max)
        candidates += found
        for c in range(len(rows)):
            hit[rows[c]] = True
            plot_used[plot_rows[c]] = True
            plot_stage[plot_rows[c]] = stage
            plot_track[plot_rows[c]] = rows[c]
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

"""One association stage of the tracker's IMM in a single compiled call (numba, cached).

:func:`stage_imm` does for an IMM bank (``x[N, M, n]``, ``P[N, M, n, n]``, ``mu[N, M]``, the
continuous-noise CV/CT modes of :mod:`skytrack.filters.imm_kernels`) what
:meth:`skytrack.tracker.scan.ScanProcessor._associate` composes from the filter's steps:

1. each track mixed once, over ``Pi`` of the interval to its reference time (one IMM cycle per
   scan), and predicted to that time; the moment-matched position and the spread
   ``sqrt(lambda_max)`` of its covariance bound the candidate search (the compiled grid of
   :mod:`skytrack.association.grid_kernels`);
2. each candidate's modes predicted from the track's mixed ones to its plot's own time (the
   mean and position block only: all the gate and the likelihood use); the pair's measurement (a 2-D
   plot without Mode C re-placed at its track's Mode C altitude, as
   :func:`skytrack.tracker.kernels.gate_stage_cv` does); the gate on ``d^2`` of the moment-
   matched prediction (weights ``c``, spread of means included), and the mixture likelihood
   ``ln sum_j c_j N(nu_j; 0, S_j)`` for the score (spec 004 §3.3 O; the reference's
   ``innovation.loglik``);
3. the score gains, costs and the assignment (:func:`skytrack.tracker.stage_kernel.pair_evidence`
   and :func:`skytrack.association.kernels.assign_clusters`, as for the CV stage);
4. the chosen pairs predicted in full and updated mode by mode (Joseph form), ``mu_j = c_j L_j / sum_i c_i L_i``, the
   two-point start of a tentative track's second plot, and the bank's columns.

``forced_mode >= 0`` is the manoeuvre gate: the prediction of that mode alone (``c`` one-hot).
The composed path with ``IMMFilter`` is the reference (its ``mixing_dt`` context is the mixing
interval of step 1); tests hold the two equal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.filters.imm_kernels import mix_row, mix_scratch, predict_mode, predict_mode_position
from skytrack.tracker.evidence import LOG_2PI
from skytrack.tracker.kernels import (
    _innovation_factor,
    _max_eig_sym,
    gate_buffers,
    joseph_position_update,
    pair_plot,
    search_candidates,
    solve_d2,
    window_plots,
    write_hits,
)
from skytrack.tracker.stage_kernel import assign_pairs
from skytrack.tracker.window_kernels import matched_position_block


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _matched_position(xp, P_pos, c, ndim, x_pos, P_match):
    """Moment-matched position ``x_pos`` and covariance ``P_match`` of predicted modes ``xp[M, n]``
    with position blocks ``P_pos[M, ndim, ndim]``."""
    M = xp.shape[0]
    for a in range(ndim):
        acc = 0.0
        for j in range(M):
            acc += c[j] * xp[j, 2 * a]
        x_pos[a] = acc
    for a in range(ndim):
        for b in range(a, ndim):
            acc = 0.0
            for j in range(M):
                acc += c[j] * (P_pos[j, a, b] + (xp[j, 2 * a] - x_pos[a]) * (xp[j, 2 * b] - x_pos[b]))
            P_match[a, b] = acc
            P_match[b, a] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def gate_stage_imm(tracks, free, x_all, P_all, mu_all, t_all, alt_all, forced_mode, modes, sojourn, fixed, t_ref,
                   plot_time_all, plot_pos_all, plot_cov_all, plot_mode_c_all, plot_range_all, plot_azimuth_all, ndim,
                   search_scale, margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot,
                   origin):
    """Gated pairs (indices into ``tracks``/``free``), their ``d^2``, the ``ln det`` that makes
    ``-(d^2 + ln det + m ln 2 pi) / 2`` the mixture log-likelihood, their measurements, their
    tracks' mixed modes ``x0``, ``P0`` and predicted weights ``c`` (per track, not per pair), and
    the number of candidates searched.  Each track is mixed once, over ``Pi`` of the interval to
    its reference time; each candidate's modes are predicted from the mixed ones to the plot's own
    time (the reference's ``mixing_dt``).  Only each mode's mean and position block are predicted
    here (all the gate and the likelihood use); the update predicts the chosen pairs in full."""
    n_tracks = len(tracks)
    M = x_all.shape[1]
    n = 2 * ndim
    scratch = mix_scratch(M, n)
    G = scratch[2]
    # every track mixed once, at its reference time; candidates are predicted from these
    mixed_x = np.empty((n_tracks, M, n))
    mixed_P = np.empty((n_tracks, M, n, n))
    mixed_c = np.empty((n_tracks, M))
    xp = np.empty((M, n))
    mode_blocks = np.empty((M, ndim, ndim))
    c = np.empty(M)
    x_pos = np.empty(ndim)
    P_pos = np.empty((ndim, ndim))
    # 1. reference prediction and search radius per track
    ref_pos = np.empty((n_tracks, ndim))
    sigma_t = np.empty(n_tracks)
    margin = np.empty(n_tracks)
    for k in range(n_tracks):
        row = tracks[k]
        dt = t_ref[k] - t_all[row]
        mix_row(x_all[row], P_all[row], mu_all[row], dt, sojourn, fixed, forced_mode, mixed_x[k], mixed_P[k],
                mixed_c[k], scratch)
        c = mixed_c[k]
        for jm in range(M):
            predict_mode_position(modes[jm], mixed_x[k, jm], mixed_P[k, jm], dt, ndim, xp[jm], mode_blocks[jm], G)
        _matched_position(xp, mode_blocks, c, ndim, x_pos, P_pos)
        speed2 = 0.0
        for a in range(ndim):
            ref_pos[k, a] = x_pos[a]
            v = 0.0
            for j in range(M):
                v += c[j] * xp[j, 2 * a + 1]
            speed2 += v * v
        sigma_t[k] = np.sqrt(max(_max_eig_sym(P_pos, ndim), 0.0))
        margin[k] = np.sqrt(speed2) * margin_s + 1.0
    plot_pos, plot_cov = window_plots(free, plot_pos_all, plot_cov_all)
    out_t, out_p = search_candidates(ref_pos, sigma_t, margin, plot_pos, plot_cov, ndim, search_scale)
    count = len(out_t)
    # 2. every candidate at its plot's time: the moment-matched gate and the mixture likelihood
    pair_pos, pair_cov, d2_out, logdet_out, kept_t, kept_p, L, w = gate_buffers(count, ndim)
    mode_pos = np.empty(ndim)
    log_terms = np.empty(M)
    m = 0
    for cand in range(count):
        k = out_t[cand]
        j = out_p[cand]
        row = tracks[k]
        col = free[j]
        dt = plot_time_all[col] - t_all[row]
        c = mixed_c[k]
        for jm in range(M):
            predict_mode_position(modes[jm], mixed_x[k, jm], mixed_P[k, jm], dt, ndim, xp[jm], mode_blocks[jm], G)
        pair_plot(replace_height, np.isfinite(plot_mode_c_all[col]), alt_all[row], col, plot_pos_all, plot_cov_all,
                  plot_range_all, plot_azimuth_all, sensor_alt, earth, var_r, var_az, var_h, rot, origin, pair_pos,
                  pair_cov, m)
        _matched_position(xp, mode_blocks, c, ndim, x_pos, P_pos)
        if not _innovation_factor(P_pos, pair_cov[m], ndim, L):
            continue
        total, _ = solve_d2(L, pair_pos, m, x_pos, ndim, w)
        if total > gate:
            continue
        best = -np.inf
        for jm in range(M):
            if c[jm] <= 0.0:
                log_terms[jm] = -np.inf
                continue
            for a in range(ndim):
                mode_pos[a] = xp[jm, 2 * a]
            if not _innovation_factor(mode_blocks[jm], pair_cov[m], ndim, L):
                log_terms[jm] = -np.inf
                continue
            d2_j, logdet_j = solve_d2(L, pair_pos, m, mode_pos, ndim, w)
            log_terms[jm] = np.log(c[jm]) - 0.5 * (d2_j + logdet_j + ndim * LOG_2PI)
            best = max(best, log_terms[jm])
        if best == -np.inf:
            continue
        acc = 0.0
        for jm in range(M):
            acc += np.exp(log_terms[jm] - best)
        loglik = best + np.log(acc)
        d2_out[m] = total
        logdet_out[m] = -2.0 * loglik - total - ndim * LOG_2PI
        kept_t[m] = k
        kept_p[m] = j
        m += 1
    return (kept_t[:m], kept_p[:m], d2_out[:m], logdet_out[:m], pair_pos[:m], pair_cov[:m], mixed_x, mixed_P, mixed_c,
            count)


@njit(cache=True, nogil=True, error_model="numpy")
def update_write_imm(rows, plot_rows, pair_pos, pair_cov, pair_x, pair_P, pair_c, modes, x_all, P_all, mu_all, ndim,
                     two_point, t, n_updates, n_misses, z_hint, alt_m, status, mode3a, icao24, iff, identity, plot_time,
                     plot_mode_c, plot_mode3a, plot_mode_s, plot_iff, gain, score, score_max):
    """Mode-matched updates (Joseph form) of the chosen pairs: each mode predicted in full from the
    pair's mixed modes (``pair_x``, ``pair_P``, weights ``pair_c``, as the gate mixed them), mode probabilities,
    the two-point start of a tentative track's second plot, and the bank's columns, in place."""
    M = x_all.shape[1]
    n = 2 * ndim
    m = ndim
    K = np.empty((n, m))
    y = np.empty(m)
    AP = np.empty((n, n))
    KR = np.empty((n, m))
    L = np.zeros((m, m))
    w = np.empty(m)
    mode_pos = np.empty(m)
    mode_cov = np.empty((m, m))
    log_post = np.empty(M)
    first_pos = np.empty(m)
    first_cov = np.empty((m, m))
    position_index = np.arange(0, n, 2)
    xp = np.empty(n)
    Pp = np.empty((n, n))
    G = np.empty((n, n))
    column = np.empty(n)
    result = np.empty(n)
    for pair in range(len(rows)):
        k = rows[pair]
        j = plot_rows[pair]
        dt = plot_time[j] - t[k]
        second_plot = two_point and n_updates[k] == 1 and status[k] == 0
        if second_plot:
            # the stored estimate before the update: the first point of the two-point start
            matched_position_block(x_all[k], P_all[k], mu_all[k], position_index, first_pos, first_cov)
        c = pair_c[pair]
        best = -np.inf
        for jm in range(M):
            predict_mode(modes[jm], pair_x[pair, jm], pair_P[pair, jm], dt, ndim, xp, Pp, G, column, result)
            for a in range(m):
                mode_pos[a] = xp[2 * a]
                for b in range(m):
                    mode_cov[a, b] = Pp[2 * a, 2 * b]
            if not _innovation_factor(mode_cov, pair_cov[pair], m, L):
                log_post[jm] = -np.inf
                for a in range(n):
                    x_all[k, jm, a] = xp[a]
                    for b in range(n):
                        P_all[k, jm, a, b] = Pp[a, b]
                continue
            d2_j, logdet_j = solve_d2(L, pair_pos, pair, mode_pos, m, w)
            log_post[jm] = (np.log(c[jm]) if c[jm] > 0.0 else -np.inf) - 0.5 * (d2_j + logdet_j + m * LOG_2PI)
            best = max(best, log_post[jm])
            joseph_position_update(xp, Pp, pair_pos[pair], pair_cov[pair], L, m, K, y, AP, KR, x_all[k, jm],
                                   P_all[k, jm])
        total = 0.0
        for jm in range(M):
            total += np.exp(log_post[jm] - best)
        for jm in range(M):
            mu_all[k, jm] = np.exp(log_post[jm] - best) / total
        if second_plot:
            dt = max(plot_time[j] - t[k], 1e-3)
            for jm in range(M):
                for i in range(n):
                    for jj in range(n):
                        P_all[k, jm, i, jj] = 0.0
                for a in range(m):
                    x_all[k, jm, 2 * a] = pair_pos[pair, a]
                    x_all[k, jm, 2 * a + 1] = (pair_pos[pair, a] - first_pos[a]) / dt
                for a in range(m):
                    for b in range(m):
                        r2 = pair_cov[pair, a, b]
                        P_all[k, jm, 2 * a, 2 * b] = r2
                        P_all[k, jm, 2 * a + 1, 2 * b + 1] = (first_cov[a, b] + r2) / (dt * dt)
                        P_all[k, jm, 2 * a, 2 * b + 1] = r2 / dt
                        P_all[k, jm, 2 * a + 1, 2 * b] = pair_cov[pair, b, a] / dt
    write_hits(rows, plot_rows, pair_pos[:, 2], gain, t, n_updates, n_misses, score, score_max, z_hint, alt_m, mode3a,
               icao24, iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff)


@njit(cache=True, nogil=True)
def stage_imm(tracks, free, x_all, P_all, mu_all, t_all, alt_all, forced_mode, modes, sojourn, fixed, t_ref,
              plot_time, plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, ndim, search_scale, margin_s, gate,
              replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense, two_point,
              n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s, plot_iff,
              clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score, score_max):
    """Returns the bank rows and plot rows updated, and the number of candidate pairs."""
    kt, kp, d2, logdet, position, covariance, mixed_x, mixed_P, mixed_c, candidates = gate_stage_imm(
        tracks, free, x_all, P_all, mu_all, t_all, alt_all, forced_mode, modes, sojourn, fixed, t_ref, plot_time,
        plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, ndim, search_scale, margin_s, gate,
        replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin)
    gain, pick, rows, plot_rows = assign_pairs(
        tracks, free, kt, kp, d2, logdet, ndim, gate, miss, cost_rule, log_pd, log_miss, clutter_grid, clutter_params,
        clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c, mode3a, alt_all, t_all,
        iff, plot_iff, icao24, plot_mode_s, max_dense)
    track_of_pair = kt[pick]
    update_write_imm(rows, plot_rows, position[pick], covariance[pick], mixed_x[track_of_pair], mixed_P[track_of_pair],
                     mixed_c[track_of_pair], modes, x_all,
                     P_all, mu_all, ndim, two_point, t_all, n_updates, n_misses, z_hint, alt_all, status, mode3a,
                     icao24, iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff, gain[pick], score,
                     score_max)
    return rows, plot_rows, candidates

"""One association stage of the tracker's adaptive augmented filters in a single compiled call (numba, cached).

:func:`stage_adaptive` does for a bank of ``ct-omega-adaptive`` / ``ca-accel-adaptive`` rows (spec 002
R14; layout and steps in :mod:`skytrack.filters.adaptive_tracking`) what
:meth:`skytrack.tracker.scan.ScanProcessor._associate` composes from that filter's numpy steps:

1. each track predicted to its reference time with V̂_w = Π(V̄) of its memory (A1, A3, A6); the
   position and the spread ``sqrt(lambda_max)`` of its covariance bound the candidate search;
2. each candidate predicted to its plot's own time, its measurement (a 2-D plot without Mode C
   re-placed at its track's Mode C altitude), the gate on ``d^2`` and the Gaussian likelihood;
3. the score gains, costs and assignment shared with the other stages
   (:func:`~skytrack.tracker.stage_kernel.pair_evidence`, :func:`~skytrack.association.kernels.assign_clusters`);
4. the chosen pairs: A4-A5 (:func:`~skytrack.filters.adaptive_tracking_kernels.adapt_row`), the prior
   covariance with the new V̂_w, the Joseph update, the psi switch on Q_dep (spec 000 S3), the
   two-point start of a tentative track's second plot and the bank's columns.

``forced`` is the manoeuvre gate: Q_dep with the manoeuvre PSD for every track of the stage.
The composed path with the numpy filter (``compiled=False``) is the reference; tests hold the two equal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.filters.adaptive_tracking_kernels import (S_MEMORY, S_MQ, S_OFF, S_ON, S_QA, S_SMAX, S_SMIN, adapt_row,
                                                        predict_row, prior_covariance, project_row)
from skytrack.tracker.kernels import (_innovation_factor, gate_buffers, joseph_position_update, pair_plot,
                                      search_candidates, search_row, solve_d2, window_plots, write_hits)
from skytrack.tracker.stage_kernel import assign_pairs


@njit(cache=True, nogil=True, error_model="numpy")
def _row_prediction(x_row, P_row, T, forced, code, ndim, p, settings, scratch, position_only):
    """The row predicted by ``T`` with its own V̂_w and psi: fills ``scratch`` = (x, F, A, G, V_x, V̂_w, ...)."""
    x_out, F, A, G, Vx, vw, memory, FP = scratch
    nm = 2 * ndim
    for i in range(p):
        for j in range(p):
            memory[i, j] = x_row[nm + p + i * p + j]
    project_row(memory, p, settings[S_SMIN], settings[S_SMAX], vw)
    psi = forced or x_row[nm + p + p * p + 2] > 0.5
    q = settings[S_MQ] if psi else settings[S_QA]
    predict_row(code, x_row, P_row, T, ndim, p, q, vw, x_out, F, A, G, Vx, FP, position_only)


def _scratch(n_total, n, p):
    return (np.empty(n_total), np.empty((n, n)), np.empty((n, n)), np.empty((n, p)), np.empty((n, n)),
            np.empty((p, p)), np.empty((p, p)), np.empty((n, n)))


_scratch_compiled = njit(cache=True, nogil=True)(_scratch)


@njit(cache=True, nogil=True, error_model="numpy")
def gate_stage_adaptive(tracks, free, x_all, P_all, t_all, alt_all, forced, code, ndim, p, settings, t_ref,
                        plot_time_all, plot_pos_all, plot_cov_all, plot_mode_c_all, plot_range_all, plot_azimuth_all,
                        search_scale, margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot,
                        origin):
    """Gated pairs (indices into ``tracks``/``free``), their ``d^2`` and ``ln det S``, their measurements
    and the number of candidates searched."""
    n_tracks = len(tracks)
    n = 2 * ndim + p
    scratch = _scratch_compiled(x_all.shape[1], n, p)
    x_pred, Vx = scratch[0], scratch[4]
    ref_pos = np.empty((n_tracks, ndim))
    sigma_t = np.empty(n_tracks)
    margin = np.empty(n_tracks)
    P_pos = np.empty((ndim, ndim))
    for k in range(n_tracks):
        row = tracks[k]
        _row_prediction(x_all[row], P_all[row], t_ref[k] - t_all[row], forced, code, ndim, p, settings, scratch,
                        True)
        search_row(x_pred, Vx, ndim, margin_s, k, ref_pos, sigma_t, margin, P_pos)
    plot_pos, plot_cov = window_plots(free, plot_pos_all, plot_cov_all)
    out_t, out_p = search_candidates(ref_pos, sigma_t, margin, plot_pos, plot_cov, ndim, search_scale)
    count = len(out_t)
    pair_pos, pair_cov, d2_out, logdet_out, kept_t, kept_p, L, w = gate_buffers(count, ndim)
    x_pos = np.empty(ndim)
    m = 0
    for cand in range(count):
        k = out_t[cand]
        j = out_p[cand]
        row = tracks[k]
        col = free[j]
        _row_prediction(x_all[row], P_all[row], plot_time_all[col] - t_all[row], forced, code, ndim, p, settings,
                        scratch, True)
        pair_plot(replace_height, np.isfinite(plot_mode_c_all[col]), alt_all[row], col, plot_pos_all, plot_cov_all,
                  plot_range_all, plot_azimuth_all, sensor_alt, earth, var_r, var_az, var_h, rot, origin, pair_pos,
                  pair_cov, m)
        for a in range(ndim):
            x_pos[a] = x_pred[2 * a]
            for b in range(ndim):
                P_pos[a, b] = Vx[2 * a, 2 * b]
        if not _innovation_factor(P_pos, pair_cov[m], ndim, L):
            continue
        total, logdet = solve_d2(L, pair_pos, m, x_pos, ndim, w)
        if total > gate:
            continue
        d2_out[m] = total
        logdet_out[m] = logdet
        kept_t[m] = k
        kept_p[m] = j
        m += 1
    return kept_t[:m], kept_p[:m], d2_out[:m], logdet_out[:m], pair_pos[:m], pair_cov[:m], count


@njit(cache=True, nogil=True, error_model="numpy")
def update_write_adaptive(rows, plot_rows, pair_pos, pair_cov, pair_d2, forced, code, ndim, p, settings, x_all, P_all,
                          two_point, t, n_updates, n_misses, z_hint, alt_m, status, mode3a, icao24, iff, identity,
                          plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff, gain, score, score_max):
    """A2-A8 of the chosen pairs, the psi switch, two-point starts and the bank's columns, in place."""
    nm = 2 * ndim
    n = nm + p
    m = ndim
    count_index = n + p * p
    scratch = _scratch_compiled(x_all.shape[1], n, p)
    x_pred, F, A, G, Vx, vw, memory, _ = scratch
    K = np.empty((n, m))
    y = np.empty(m)
    AP = np.empty((n, n))
    KR = np.empty((n, m))
    L = np.zeros((m, m))
    R = np.empty((m, m))
    nu = np.empty(m)
    first_pos = np.empty(m)
    first_cov = np.empty((m, m))
    for pair in range(len(rows)):
        k = rows[pair]
        j = plot_rows[pair]
        dt = plot_time[j] - t[k]
        second_plot = two_point and n_updates[k] == 1 and status[k] == 0
        if second_plot:
            for a in range(m):
                first_pos[a] = x_all[k, 2 * a]
                for b in range(m):
                    first_cov[a, b] = P_all[k, 2 * a, 2 * b]
        _row_prediction(x_all[k], P_all[k], dt, forced, code, ndim, p, settings, scratch, False)
        for a in range(m):
            nu[a] = pair_pos[pair, a] - x_pred[a * 2]
            for b in range(m):
                R[a, b] = pair_cov[pair, a, b]
        adapted = adapt_row(nu, A, G, R, m, ndim, p, settings, memory, x_pred, count_index, count_index + 1)
        if not adapted:
            x_pred[count_index + 1] += 1.0
        project_row(memory, p, settings[S_SMIN], settings[S_SMAX], vw)
        prior_covariance(A, G, vw, 1, n, p, Vx)
        for a in range(m):
            for b in range(m):
                R[a, b] = Vx[2 * a, 2 * b]
        if not _innovation_factor(R, pair_cov[pair], m, L):
            continue  # not positive definite: the reference raises; the gate never offers such a pair
        joseph_position_update(x_pred[:n], Vx, pair_pos[pair], pair_cov[pair], L, m, K, y, AP, KR, x_all[k, :n],
                               P_all[k, :n, :n])
        for i in range(n, x_all.shape[1]):
            x_all[k, i] = x_pred[i]
        # spec 000 S3's psi on Q_dep from the gate's NIS per component
        psi_index = count_index + 2
        smoothed = settings[S_MEMORY] * x_pred[psi_index + 1] + (1.0 - settings[S_MEMORY]) * pair_d2[pair] / m
        if forced:
            x_all[k, psi_index] = 1.0
            x_all[k, psi_index + 1] = max(smoothed, settings[S_ON])
        else:
            was = x_pred[psi_index] > 0.5
            on = smoothed > settings[S_OFF] if was else smoothed > settings[S_ON]
            x_all[k, psi_index] = 1.0 if on else 0.0
            x_all[k, psi_index + 1] = smoothed
        if second_plot:
            dt = max(plot_time[j] - t[k], 1e-3)
            for i in range(nm):
                for jj in range(n):
                    P_all[k, i, jj] = 0.0
                    P_all[k, jj, i] = 0.0
            for a in range(m):
                x_all[k, 2 * a] = pair_pos[pair, a]
                x_all[k, 2 * a + 1] = (pair_pos[pair, a] - first_pos[a]) / dt
            for a in range(m):
                for b in range(m):
                    r2 = pair_cov[pair, a, b]
                    P_all[k, 2 * a, 2 * b] = r2
                    P_all[k, 2 * a + 1, 2 * b + 1] = (first_cov[a, b] + r2) / (dt * dt)
                    P_all[k, 2 * a, 2 * b + 1] = r2 / dt
                    P_all[k, 2 * a + 1, 2 * b] = pair_cov[pair, b, a] / dt
    write_hits(rows, plot_rows, pair_pos[:, 2], gain, t, n_updates, n_misses, score, score_max, z_hint, alt_m, mode3a,
               icao24, iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff)


@njit(cache=True, nogil=True)
def stage_adaptive(tracks, free, x_all, P_all, t_all, alt_all, forced, code, ndim, p, settings, t_ref, plot_time,
                   plot_pos, plot_cov, plot_mode_c, plot_range, plot_azimuth, search_scale, margin_s, gate,
                   replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense, two_point,
                   n_updates, n_misses, z_hint, status, mode3a, icao24, iff, identity, plot_mode3a, plot_mode_s,
                   plot_iff, clutter_grid, clutter_params, clutter_log_area, cost_rule, log_pd, log_miss, ssr, score,
                   score_max):
    """Returns the bank rows and plot rows updated, and the number of candidate pairs."""
    kt, kp, d2, logdet, position, covariance, candidates = gate_stage_adaptive(
        tracks, free, x_all, P_all, t_all, alt_all, forced, code, ndim, p, settings, t_ref, plot_time, plot_pos,
        plot_cov, plot_mode_c, plot_range, plot_azimuth, search_scale, margin_s, gate, replace_height, sensor_alt,
        earth, var_r, var_az, var_h, rot, origin)
    gain, pick, rows, plot_rows = assign_pairs(
        tracks, free, kt, kp, d2, logdet, ndim, gate, miss, cost_rule, log_pd, log_miss, clutter_grid, clutter_params,
        clutter_log_area, ssr, plot_time, plot_range, plot_azimuth, plot_mode3a, plot_mode_c, mode3a, alt_all, t_all,
        iff, plot_iff, icao24, plot_mode_s, max_dense)
    update_write_adaptive(rows, plot_rows, position[pick], covariance[pick], d2[pick], forced, code, ndim, p, settings,
                          x_all, P_all, two_point, t_all, n_updates, n_misses, z_hint, alt_all, status, mode3a, icao24,
                          iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff, gain[pick], score,
                          score_max)
    return rows, plot_rows, candidates

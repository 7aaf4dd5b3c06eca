"""Compiled gate of one association stage for the common case (numba, cached).

For a Kalman-family filter on a constant-velocity model with identical axes and linear
position measurements (converted plots of a ground radar), :func:`gate_stage_cv` does in one
call what :meth:`skytrack.tracker.scan.ScanProcessor._associate` composes from parts:

1. each track predicted to its reference time (process-noise factor per track), its position
   spread ``sqrt(lambda_max)``;
2. candidate plots within ``scale (s_t + s_p) + margin_t``, found in a grid of spread classes,
   columns of x and sorted y (:mod:`skytrack.association.grid_kernels`);
3. each candidate's position predicted to its plot's own time (spec 000 Theorem 2 / R7; the
   update predicts the chosen pairs in full, with the same arithmetic);
4. the pair's measurement: the plot's converted position, or — a 2-D plot without Mode C whose
   track has a Mode C altitude — the plot placed again at that altitude on the sphere model
   (the same formulas as :func:`skytrack.geo.polar.slant_to_local` and
   :func:`skytrack.models.conversion.convert_plots`);
5. ``S = P_pos + R``, its Cholesky factor, ``d^2``; pairs with ``d^2 <= gate`` are returned
   with their measurement.

The composed path (numpy reference parts) is kept and tested equal to this kernel.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.association.grid_kernels import search_grid, spread_classes
from skytrack.models.conversion_kernels import place_2d
from skytrack.tracker.identity import ICAO24_N, MODE3A_N, remember_code, remember_status


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _predict_cv_row(x, P, dt, q, scale, ndim, x_out, P_out):
    step = abs(dt)
    f = dt  # F(|dt|)^-1 = F(-|dt|) for constant velocity
    q00 = q * step * step * step / 3.0 * scale
    q01 = q * step * step / 2.0 * scale
    q11 = q * step * scale
    n = 2 * ndim
    for a in range(ndim):
        i = 2 * a
        x_out[i] = x[i] + f * x[i + 1]
        x_out[i + 1] = x[i + 1]
    for a in range(ndim):
        for b in range(ndim):
            i = 2 * a
            j = 2 * b
            m00 = P[i, j]
            m01 = P[i, j + 1]
            m10 = P[i + 1, j]
            m11 = P[i + 1, j + 1]
            r00 = m00 + f * m10
            r01 = m01 + f * m11
            P_out[i, j] = r00 + r01 * f
            P_out[i, j + 1] = r01
            P_out[i + 1, j] = m10 + m11 * f
            P_out[i + 1, j + 1] = m11
            if a == b:
                P_out[i, j] += q00
                P_out[i, j + 1] += q01
                P_out[i + 1, j] += q01
                P_out[i + 1, j + 1] += q11
    _symmetrise(P_out, n)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _symmetrise(M, n):
    """Replace the upper-left ``n x n`` block of ``M`` by the mean of it and its transpose."""
    for i in range(n):
        for j in range(i + 1, n):
            mean = 0.5 * (M[i, j] + M[j, i])
            M[i, j] = mean
            M[j, i] = mean


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _max_eig_sym(M, dim):
    if dim == 2:
        a = M[0, 0]
        b = M[0, 1]
        c = M[1, 1]
        return 0.5 * (a + c) + np.sqrt(max(0.25 * (a - c) ** 2 + b * b, 0.0))
    best = 0.0
    for i in range(dim):
        total = 0.0
        for j in range(dim):
            total += abs(M[i, j])
        best = max(best, total)
    return best


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def solve_d2(L, z, row, x_pos, ndim, w):
    """``d^2`` and ``ln det S`` from the Cholesky factor ``L`` of ``S`` and the innovation ``z[row] - x_pos``
    (rows of 2-D arrays are indexed, not sliced: a slice in a compiled hot loop costs reference counting)."""
    total = 0.0
    logdet = 0.0
    for a in range(ndim):
        logdet += 2.0 * np.log(L[a, a])
        acc = z[row, a] - x_pos[a]
        for l in range(a):
            acc -= L[a, l] * w[l]
        w[a] = acc / L[a, a]
        total += w[a] * w[a]
    return total, logdet


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def pair_plot(replace_height, has_mode_c, track_alt, j, plot_pos, plot_cov, plot_range, plot_azimuth, sensor_alt,
              earth, var_r, var_az, var_h, rot, origin, pair_pos, pair_cov, m):
    """Row ``m`` of a pair's measurement: plot ``j``'s converted position and covariance, or, for a
    2-D plot without Mode C, the plot re-placed at its track's Mode C altitude ``track_alt`` when it
    has one (rows indexed, not sliced, on the common path: see :func:`solve_d2`)."""
    if replace_height and not has_mode_c and np.isfinite(track_alt):
        place_2d(plot_range[j], plot_azimuth[j], track_alt, sensor_alt, earth, var_r, var_az, var_h, rot, origin,
                 pair_pos[m], pair_cov[m])
        return
    for a in range(3):
        pair_pos[m, a] = plot_pos[j, a]
        for b in range(3):
            pair_cov[m, a, b] = plot_cov[j, a, b]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def search_row(x_pred, P_pred, ndim, margin_s, k, ref_pos, sigma_t, margin, block):
    """Row ``k`` of the candidate search from a prediction in the ``[x, vx, ...]`` layout: its position,
    the spread ``sqrt(lambda_max)`` of its position block (``block`` is scratch) and its speed margin."""
    speed2 = 0.0
    for a in range(ndim):
        ref_pos[k, a] = x_pred[2 * a]
        speed2 += x_pred[2 * a + 1] ** 2
        for b in range(ndim):
            block[a, b] = P_pred[2 * a, 2 * b]
    sigma_t[k] = np.sqrt(max(_max_eig_sym(block, ndim), 0.0))
    margin[k] = np.sqrt(speed2) * margin_s + 1.0


@njit(cache=True, nogil=True)
def gate_buffers(count, ndim):
    """The exact gate's outputs for ``count`` candidates (each pair's measurement ``[count, 3]`` and
    ``[count, 3, 3]``, ``d^2``, ``ln det S``, track and plot indices) and its Cholesky scratch ``L``, ``w``."""
    return (np.empty((count, 3)), np.empty((count, 3, 3)), np.empty(count), np.empty(count),
            np.empty(count, np.int64), np.empty(count, np.int64), np.zeros((ndim, ndim)), np.empty(ndim))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def window_plots(free, plot_pos_all, plot_cov_all):
    """Positions ``[F, 3]`` and covariances ``[F, 3, 3]`` of the window's free plots."""
    plot_pos = np.empty((len(free), 3))
    plot_cov = np.empty((len(free), 3, 3))
    for j in range(len(free)):
        col = free[j]
        for a in range(3):
            plot_pos[j, a] = plot_pos_all[col, a]
            for b in range(3):
                plot_cov[j, a, b] = plot_cov_all[col, a, b]
    return plot_pos, plot_cov


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def search_candidates(ref_pos, sigma_t, margin, plot_pos, plot_cov, ndim, search_scale):
    """Candidate (track, plot) pairs: plots within ``scale (s_t + s_p) + margin_t`` of each track's
    reference position, ``s`` the square root of the largest eigenvalue of the position covariance
    (:mod:`skytrack.association.grid_kernels`)."""
    n_plots = len(plot_pos)
    sigma_p = np.empty(n_plots)
    block = np.empty((ndim, ndim))
    for j in range(n_plots):
        for a in range(ndim):
            for b in range(ndim):
                block[a, b] = plot_cov[j, a, b]
        sigma_p[j] = np.sqrt(max(_max_eig_sym(block, ndim), 0.0))
    out_t, out_p, _ = search_grid(ref_pos, sigma_t, margin, plot_pos, sigma_p, spread_classes(sigma_p), search_scale,
                                  ndim)
    return out_t, out_p


@njit(cache=True, nogil=True, error_model="numpy")
def gate_stage_cv(tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time_all,
                  plot_pos_all, plot_cov_all, plot_mode_c_all, plot_range_all, plot_azimuth_all, q,
                  ndim, search_scale, margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin):
    """``tracks`` index the bank rows (``*_all``), ``free`` the window's plots; the process noise of
    a track is ``q_big`` times the model's while its psi is set or when ``forced``.  Returns the
    gated pairs (track, plot indices into ``tracks``/``free``), their ``d^2`` and ``ln det S``, the
    pairs' measurements and the number of candidates searched."""
    n_tracks = len(tracks)
    n_plots = len(free)
    n = 2 * ndim
    x = np.empty((n_tracks, n))
    P = np.empty((n_tracks, n, n))
    t = np.empty(n_tracks)
    alt_m = np.empty(n_tracks)
    scale = np.empty(n_tracks)
    for k in range(n_tracks):
        row = tracks[k]
        for i in range(n):
            x[k, i] = x_all[row, i]
            for j in range(n):
                P[k, i, j] = P_all[row, i, j]
        t[k] = t_all[row]
        alt_m[k] = alt_all[row]
        scale[k] = q_big if (forced or psi_all[row]) else 1.0
    plot_time = np.empty(n_plots)
    plot_pos = np.empty((n_plots, 3))
    plot_cov = np.empty((n_plots, 3, 3))
    plot_has_mode_c = np.empty(n_plots, np.bool_)
    plot_range = np.empty(n_plots)
    plot_azimuth = np.empty(n_plots)
    for j in range(n_plots):
        col = free[j]
        plot_time[j] = plot_time_all[col]
        for a in range(3):
            plot_pos[j, a] = plot_pos_all[col, a]
            for b in range(3):
                plot_cov[j, a, b] = plot_cov_all[col, a, b]
        plot_has_mode_c[j] = np.isfinite(plot_mode_c_all[col])
        plot_range[j] = plot_range_all[col]
        plot_azimuth[j] = plot_azimuth_all[col]
    # 1. reference prediction and search radius per track
    ref_pos = np.empty((n_tracks, ndim))
    sigma_t = np.empty(n_tracks)
    margin = np.empty(n_tracks)
    xr = np.empty(n)
    Pr = np.empty((n, n))
    block = np.empty((ndim, ndim))
    for k in range(n_tracks):
        _predict_cv_row(x[k], P[k], t_ref[k] - t[k], q, scale[k], ndim, xr, Pr)
        # search_row and pair_plot written out: inlined here they cost 7 % of the default tracker
        # loop (benchmarks/against_core.py, 2026-11-25), though they are the same statements
        speed2 = 0.0
        for a in range(ndim):
            ref_pos[k, a] = xr[2 * a]
            speed2 += xr[2 * a + 1] ** 2
            for b in range(ndim):
                block[a, b] = Pr[2 * a, 2 * b]
        sigma_t[k] = np.sqrt(max(_max_eig_sym(block, ndim), 0.0))
        margin[k] = np.sqrt(speed2) * margin_s + 1.0
    # 2. candidates: plots within ``scale (s_t + s_p) + margin_t`` of the reference position
    out_t, out_p = search_candidates(ref_pos, sigma_t, margin, plot_pos, plot_cov, ndim, search_scale)
    count = len(out_t)
    # 3.-5. exact gate of every candidate at its plot's time, on the position block of the
    #       prediction only (the update predicts the chosen pairs in full); pairs inside are
    #       written to the next free slot ``m`` (compaction as we go)
    pair_pos, pair_cov, d2_out, logdet_out, kept_t, kept_p, L, w = gate_buffers(count, ndim)
    x_pos = np.empty(ndim)
    P_pos = np.empty((ndim, ndim))
    m = 0
    for c in range(count):
        k = out_t[c]
        j = out_p[c]
        if ndim != 2:
            _predict_cv_position(x[k], P[k], plot_time[j] - t[k], q, scale[k], ndim, x_pos, P_pos)
        if replace_height and not plot_has_mode_c[j] and np.isfinite(alt_m[k]):
            place_2d(plot_range[j], plot_azimuth[j], alt_m[k], sensor_alt, earth, var_r, var_az, var_h, rot, origin,
                     pair_pos[m], pair_cov[m])
        else:
            for a in range(3):
                pair_pos[m, a] = plot_pos[j, a]
                for b in range(3):
                    pair_cov[m, a, b] = plot_cov[j, a, b]
        if ndim == 2:
            total, logdet = _d2_planar(x[k], P[k], plot_time[j] - t[k], q, scale[k], pair_pos[m], pair_cov[m])
        else:
            if not _innovation_factor(P_pos, pair_cov[m], ndim, L):
                continue  # S not positive definite: the pair cannot be gated
            total, logdet = solve_d2(L, pair_pos, m, x_pos, ndim, w)
        if total <= gate:
            d2_out[m] = total
            logdet_out[m] = logdet
            kept_t[m] = k
            kept_p[m] = j
            m += 1
    return kept_t[:m], kept_p[:m], d2_out[:m], logdet_out[:m], pair_pos[:m], pair_cov[:m], count


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _predict_cv_position(x, P, dt, q, scale, ndim, x_out, P_out):
    """The position part of :func:`_predict_cv_row` (same operations, so the same bits): the
    predicted position and its covariance block, symmetrised as there."""
    step = abs(dt)
    f = dt
    q00 = q * step * step * step / 3.0 * scale
    for a in range(ndim):
        x_out[a] = x[2 * a] + f * x[2 * a + 1]
    for a in range(ndim):
        for b in range(ndim):
            i = 2 * a
            j = 2 * b
            r00 = P[i, j] + f * P[i + 1, j]
            r01 = P[i, j + 1] + f * P[i + 1, j + 1]
            P_out[a, b] = r00 + r01 * f
            if a == b:
                P_out[a, b] += q00
    _symmetrise(P_out, ndim)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _d2_planar(x, P, dt, q, scale, z, R):
    """``d^2`` and ``ln det S`` of a horizontal pair on scalars: :func:`_predict_cv_position`,
    :func:`_innovation_factor` and the triangular solve with the same operations (so the same
    bits); ``inf`` when S is not positive definite."""
    step = abs(dt)
    f = dt
    q00 = q * step * step * step / 3.0 * scale
    x0 = x[0] + f * x[1]
    x1 = x[2] + f * x[3]
    p00 = (P[0, 0] + f * P[1, 0]) + (P[0, 1] + f * P[1, 1]) * f + q00
    p01 = (P[0, 2] + f * P[1, 2]) + (P[0, 3] + f * P[1, 3]) * f
    p10 = (P[2, 0] + f * P[3, 0]) + (P[2, 1] + f * P[3, 1]) * f
    p11 = (P[2, 2] + f * P[3, 2]) + (P[2, 3] + f * P[3, 3]) * f + q00
    p_mean = 0.5 * (p01 + p10)
    s00 = p00 + R[0, 0]
    s10 = 0.5 * ((p_mean + R[1, 0]) + (p_mean + R[0, 1]))
    s11 = p11 + R[1, 1]
    if s00 <= 0.0:
        return np.inf, np.inf
    l00 = np.sqrt(s00)
    l10 = s10 / l00
    rest = s11 - l10 * l10
    if rest <= 0.0:
        return np.inf, np.inf
    l11 = np.sqrt(rest)
    w0 = (z[0] - x0) / l00
    w1 = ((z[1] - x1) - l10 * w0) / l11
    return w0 * w0 + w1 * w1, np.log(s00 * rest)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _innovation_factor(P_pos, R, ndim, L):
    """Lower Cholesky factor of ``S = P_pos + R`` (symmetrised) into ``L``; False when S is not
    positive definite."""
    for a in range(ndim):
        for b in range(a + 1):
            if a == b:
                s_ab = P_pos[a, a] + R[a, a]
            else:
                s_ab = 0.5 * ((P_pos[a, b] + R[a, b]) + (P_pos[b, a] + R[b, a]))
            acc = s_ab
            for l in range(b):
                acc -= L[a, l] * L[b, l]
            if a == b:
                if acc <= 0.0:
                    return False
                L[a, a] = np.sqrt(acc)
            else:
                L[a, b] = acc / L[b, b]
    return True


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def joseph_position_update(xp, Pp, z, R, L, m, K, y, AP, KR, x_out, P_out):
    """Kalman update of a prediction ``xp``, ``Pp`` (layout ``[x, vx, ...]``) by a position
    measurement ``z`` with noise ``R``, ``L`` the Cholesky factor of ``S = P_pos + R``: gain, state
    and the Joseph form into ``x_out``, ``P_out`` (its upper triangle, mirrored); ``K``, ``y``, ``AP``, ``KR``
    are scratch."""
    n = len(xp)
    # K = P H^T S^-1 with H selecting positions: P H^T is the position columns of P
    for i in range(n):
        for a in range(m):
            acc = Pp[i, 2 * a]
            for l in range(a):
                acc -= L[a, l] * y[l]
            y[a] = acc / L[a, a]
        for a in range(m - 1, -1, -1):
            acc = y[a]
            for l in range(a + 1, m):
                acc -= L[l, a] * K[i, l]
            K[i, a] = acc / L[a, a]
    for i in range(n):
        acc = xp[i]
        for a in range(m):
            acc += K[i, a] * (z[a] - xp[2 * a])
        x_out[i] = acc
    # Joseph form with A = I - K H and H selecting positions, without the products by 0 and 1:
    # A P = P - K (H P);  A P A^T + K R K^T = A P + sum_a (K R - A P H^T)[:, a] K[:, a]^T
    for i in range(n):
        for jj in range(n):
            acc = Pp[i, jj]
            for a in range(m):
                acc -= K[i, a] * Pp[2 * a, jj]
            AP[i, jj] = acc
    for i in range(n):
        for a in range(m):
            acc = 0.0
            for b in range(m):
                acc += K[i, b] * R[b, a]
            KR[i, a] = acc - AP[i, 2 * a]
    # the result is symmetric: its upper triangle is computed and mirrored
    for i in range(n):
        for jj in range(i, n):
            acc = AP[i, jj]
            for a in range(m):
                acc += KR[i, a] * K[jj, a]
            P_out[i, jj] = acc
            P_out[jj, i] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def write_hits(rows, plot_rows, heights, gains, t, n_updates, n_misses, score, score_max, z_hint, alt_m, mode3a, icao24,
               iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff):
    """The bank columns of tracks ``rows`` after their hits by plots ``plot_rows``
    (:meth:`ScanProcessor._write_updates`): time, counts, score (``gains``), the plots' heights,
    and the Mode C, Mode 3/A, Mode S and IFF they carry (spec 003 R14 and the reply counts:
    :mod:`skytrack.tracker.identity`).  One call per stage, after the state
    updates: called per hit, the array arguments cost more than the writes."""
    for c in range(len(rows)):
        k = rows[c]
        j = plot_rows[c]
        t[k] = plot_time[j]
        n_updates[k] += 1
        n_misses[k] = 0
        score[k] += gains[c]
        score_max[k] = max(score_max[k], score[k])
        z_hint[k] = heights[c]
        if np.isfinite(plot_mode_c[j]):
            alt_m[k] = plot_mode_c[j]
        remember_status(identity, k, iff, plot_iff[j])
        if plot_mode3a[j] >= 0:
            mode3a[k] = remember_code(identity, k, MODE3A_N, mode3a[k], plot_mode3a[j])
        if plot_mode_s[j] >= 0:
            icao24[k] = remember_code(identity, k, ICAO24_N, icao24[k], plot_mode_s[j])


@njit(cache=True, nogil=True, error_model="numpy")
def update_write_cv(rows, plot_rows, d2, pair_pos, pair_cov, q, q_big, ndim, manoeuvre, psi_enabled,
                    psi_on, psi_off, psi_memory, two_point, x, P, psi, nis_avg, filter_updates, t, n_updates, n_misses,
                    z_hint, alt_m, status, mode3a, icao24, iff, identity, plot_time, plot_mode_c, plot_mode3a,
                    plot_mode_s, plot_iff, gain, score, score_max):
    """Kalman update (Joseph form) of the chosen pairs, the psi switch, and the bank's columns, in place.

    Each chosen pair is predicted to its plot's time (process noise ``q_big`` times the model's
    while the track's psi is set or when ``manoeuvre``), with the gate's arithmetic, so ``S``
    and its factor are the gate's to the bit.  Same arithmetic as :func:`skytrack.filters.kernels.update_dense` with the position-selecting
    ``H``, then the spec 000 S3 switch of :class:`~skytrack.filters.maneuver.ManoeuvreSwitchFilter`
    and :meth:`skytrack.tracker.scan.ScanProcessor._write_updates` (two-point initiation after a
    tentative track's second plot, hit bookkeeping, altitude and identity); the track score
    grows by each pair's ``gain`` (:mod:`skytrack.tracker.evidence`).
    """
    n = 2 * ndim
    m = ndim
    K = np.empty((n, m))
    y = np.empty(m)
    AP = np.empty((n, n))
    KR = np.empty((n, m))
    x_new = np.empty(n)
    P_new = np.empty((n, n))
    xp = np.empty(n)
    Pp = np.empty((n, n))
    P_pos = np.empty((m, m))
    L = np.zeros((m, m))
    for c in range(len(rows)):
        k = rows[c]
        j = plot_rows[c]
        _predict_cv_row(x[k], P[k], plot_time[j] - t[k], q, q_big if (manoeuvre or psi[k]) else 1.0, ndim, xp, Pp)
        for a in range(m):
            for b in range(m):
                P_pos[a, b] = Pp[2 * a, 2 * b]
        _innovation_factor(P_pos, pair_cov[c], m, L)  # positive definite: the gate factored it
        joseph_position_update(xp, Pp, pair_pos[c], pair_cov[c], L, m, K, y, AP, KR, x_new, P_new)
        if psi_enabled:
            nis = d2[c] / m
            if manoeuvre:
                psi[k] = True
                nis_avg[k] = max(nis_avg[k], psi_on)
            else:
                if filter_updates[k] == 0:
                    smoothed = nis
                else:
                    smoothed = psi_memory * nis_avg[k] + (1.0 - psi_memory) * nis
                psi[k] = smoothed > psi_off if psi[k] else smoothed > psi_on
                nis_avg[k] = smoothed
            filter_updates[k] += 1
        if two_point and n_updates[k] == 1 and status[k] == 0:
            dt = max(plot_time[j] - t[k], 1e-3)
            for a in range(m):
                x_new[2 * a] = pair_pos[c, a]
                x_new[2 * a + 1] = (pair_pos[c, a] - x[k, 2 * a]) / dt
            for a in range(m):
                for b in range(m):
                    r2 = pair_cov[c, a, b]
                    r1 = P[k, 2 * a, 2 * b]
                    P_new[2 * a, 2 * b] = r2
                    P_new[2 * a + 1, 2 * b + 1] = (r1 + r2) / (dt * dt)
                    P_new[2 * a, 2 * b + 1] = r2 / dt
                    P_new[2 * a + 1, 2 * b] = pair_cov[c, b, a] / dt
        for i in range(n):
            x[k, i] = x_new[i]
            for jj in range(n):
                P[k, i, jj] = P_new[i, jj]
    write_hits(rows, plot_rows, pair_pos[:, 2], gain, t, n_updates, n_misses, score, score_max, z_hint, alt_m, mode3a,
               icao24, iff, identity, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff)

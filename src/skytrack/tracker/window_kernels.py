"""Compiled per-window bookkeeping for Gaussian-state banks (numba, cached).

* :func:`expect_rotating` — :meth:`skytrack.tracker.schedule.Schedule.expectations` for a
  rotating radar, with the tracks' positions extrapolated to the window's middle
  (:meth:`~skytrack.tracker.scan.ScanProcessor._positions_at`) in the same call;
* :func:`record_and_manage` — :meth:`skytrack.tracker.lifecycle.Lifecycle.record_events` then
  the decisions of :meth:`~skytrack.tracker.lifecycle.Lifecycle.manage` (confirmation, hopeless
  tentative tracks, lost confirmed tracks, by hit counts or by the track score of
  :mod:`skytrack.tracker.evidence`).

The numpy methods named are the reference; tests hold the two equal.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.geo.polar import EARTH_RADIUS_M
from skytrack.models.height import REFRACTION_K
from skytrack.tracker.clutter_map import observe_kernel
from skytrack.tracker.evidence import count_codes
from skytrack.tracker.identity import (
    ICAO24_N,
    IDENTITY_WIDTH,
    MODE3A_N,
    N_FOE,
    N_FRIEND,
    SHOWN_ICAO24,
    SHOWN_IFF,
    SHOWN_MODE3A,
    identity_rows,
)
from skytrack.tracker.kernels import _max_eig_sym, _predict_cv_row

_BELOW_TWO_PI = np.nextafter(2.0 * np.pi, 0.0)
_TWO_K_R = 2.0 * REFRACTION_K * EARTH_RADIUS_M


@njit(cache=True, nogil=True)
def expect_rotating(x, t, z_hint, alt_m, n, dim, order, mid, w_start, w_end, phase, period, rot, origin, max_range,
                    sensor_alt, cover_xy, cover_r2, cover_alt, cover_all, sector_margin):
    """Reference time, expected, nearby and outside-every-coverage flags of the first ``n`` bank
    rows (coverage: range, and the radar horizon for tracks with a Mode C altitude)."""
    t_ref = np.empty(n)
    expected = np.empty(n, np.bool_)
    nearby = np.empty(n, np.bool_)
    outside = np.zeros(n, np.bool_)
    point = np.empty(3)
    local = np.empty(3)
    margin = sector_margin * period
    two_pi = 2.0 * np.pi
    for k in range(n):
        dt = mid - t[k]
        for a in range(dim):
            p = x[k, a * order] + x[k, a * order + 1] * dt
            if order == 3:
                p += 0.5 * x[k, a * order + 2] * dt * dt
            point[a] = p
        if dim == 2:
            point[2] = z_hint[k] if np.isfinite(z_hint[k]) else 0.0
        for j in range(3):
            acc = 0.0
            for l in range(3):
                acc += (point[l] - origin[l]) * rot[j, l]
            local[j] = acc
        ground = np.hypot(local[0], local[1])
        az = np.arctan2(local[0], local[1]) % two_pi
        if az >= two_pi:
            az = _BELOW_TWO_PI
        crossing = phase + az / two_pi * period
        tr = w_start + (crossing - w_start) % period
        exp = tr < w_end
        late = tr >= w_start + period - margin
        nearby[k] = exp or late or tr < w_end + margin
        if not exp:
            shifted = tr - period if late else tr
            tr = min(max(shifted, w_start), w_end)
        if max_range > 0.0 and (ground > max_range or ground > _horizon(sensor_alt, alt_m[k])):
            covered = cover_all
            for r in range(len(cover_r2)):
                dx = point[0] - cover_xy[r, 0]
                dy = point[1] - cover_xy[r, 1]
                if dx * dx + dy * dy <= min(cover_r2[r], _horizon(cover_alt[r], alt_m[k]) ** 2):
                    covered = True
            exp = exp and not covered
            outside[k] = not covered
        t_ref[k] = tr
        expected[k] = exp
    return t_ref, expected, nearby, outside


@njit(cache=True, nogil=True, inline="always")
def _horizon(sensor_alt, target_alt):
    """4/3-Earth radar horizon distance (m); infinite for an unknown target height
    (:func:`skytrack.models.height.radar_horizon_m`)."""
    if not target_alt == target_alt:
        return np.inf
    hs = max(sensor_alt, 0.0)
    ht = max(target_alt, 0.0)
    return np.sqrt(_TWO_K_R * hs + hs * hs) + np.sqrt(_TWO_K_R * ht + ht * ht)


@njit(cache=True, nogil=True, inline="always")
def matched_position_block(x, P, mu, pos_index, mean, block):
    """The position mean and covariance block of one row's moment-matched mixture ``x[M, n]``,
    ``P[M, n, n]``, ``mu[M]`` (the arithmetic of :func:`skytrack.filters.imm_kernels.moment_match_rows`;
    exact for one mode of probability 1)."""
    M = x.shape[0]
    dim = len(pos_index)
    if M == 1 and mu[0] == 1.0:
        # one mode: the matched moments are the mode's own (what the sums give, exactly)
        for a in range(dim):
            mean[a] = x[0, pos_index[a]]
            for b in range(dim):
                block[a, b] = P[0, pos_index[a], pos_index[b]]
        return
    for a in range(dim):
        acc = 0.0
        for j in range(M):
            acc += mu[j] * x[j, pos_index[a]]
        mean[a] = acc
    for a in range(dim):
        pa = pos_index[a]
        for b in range(a, dim):
            pb = pos_index[b]
            acc = 0.0
            for j in range(M):
                acc += mu[j] * (P[j, pa, pb] + (x[j, pa] - mean[a]) * (x[j, pb] - mean[b]))
            block[a, b] = acc
            block[b, a] = acc


@njit(cache=True, nogil=True)
def record_and_manage(hit, expected, w_end, confirm_m, confirm_n, delete_misses, max_sigma, pos_index, x, P, mu, t,
                      status, hit_bits, n_events, n_misses, last_event, confirmed_at, score, score_max, log_miss,
                      score_logic, confirm_score, drop_score, delete_drop, min_plots, outside):
    """Events of this window, then the life-cycle decisions; returns the keep mask and counts
    (misses, confirmed, hopeless, lost).  The states are in mixture form (``x[N, M, n]``,
    ``P[N, M, n, n]``, ``mu[N, M]``; a Gaussian bank is ``M = 1``, ``mu = 1``): a confirmed track
    whose moment-matched position covariance has a standard deviation above ``max_sigma`` is lost.  ``hit``/``expected`` cover the rows that existed before
    the window's new tracks; the decisions cover all ``len(status)`` rows.  A miss adds
    ``log_miss`` to the score; with ``score_logic`` a tentative track is confirmed at
    ``confirm_score`` once it has ``min_plots`` plots among its last ``confirm_n`` events, and
    dropped below ``drop_score``, a confirmed one deleted when its score is
    ``delete_drop`` below its maximum (else M-of-N and ``delete_misses``).  A track ``outside``
    every radar's coverage is deleted at once (counted in ``lost``)."""
    mask = np.uint32((1 << confirm_n) - 1)
    misses = 0
    for k in range(len(hit)):
        if hit[k] or expected[k]:
            last_event[k] = w_end
            hit_bits[k] = ((hit_bits[k] << np.uint32(1)) | np.uint32(1 if hit[k] else 0)) & mask
            n_events[k] += 1
        if expected[k] and not hit[k]:
            n_misses[k] += 1
            misses += 1
            score[k] += log_miss
    rows = len(status)
    keep = np.ones(rows, np.bool_)
    confirmed = 0
    hopeless = 0
    lost = 0
    dim = len(pos_index)
    block = np.empty((dim, dim))
    mean = np.empty(dim)
    for k in range(rows):
        if k < len(outside) and outside[k]:
            keep[k] = False
            if status[k] == 1:
                lost += 1
            else:
                hopeless += 1
            continue
        bits = hit_bits[k]
        hits = 0
        while bits:
            hits += bits & np.uint32(1)
            bits >>= np.uint32(1)
        if status[k] == 0:
            if (score[k] >= confirm_score and hits >= min_plots) if score_logic else (hits >= confirm_m):
                status[k] = 1
                confirmed_at[k] = t[k]
                confirmed += 1
            else:
                observed = min(n_events[k], confirm_n)
                if (score[k] < drop_score) if score_logic else (observed - hits > confirm_n - confirm_m):
                    keep[k] = False
                    hopeless += 1
                continue
        matched_position_block(x[k], P[k], mu[k], pos_index, mean, block)
        largest = _max_eig_sym(block, dim)
        faded = (score_max[k] - score[k] >= delete_drop) if score_logic else (n_misses[k] >= delete_misses)
        if faded or np.sqrt(max(largest, 0.0)) > max_sigma:
            keep[k] = False
            lost += 1
    return keep, misses, confirmed, hopeless, lost


@njit(cache=True, nogil=True)
def initiate_manage(size, new_plots, plot_time, plot_pos, plot_cov, plot_mode_c, plot_mode3a, plot_mode_s,
                    plot_iff, first_id, sigma_v, dim, with_psi, hit, expected, w_end, confirm_m, confirm_n, delete_misses,
                    max_sigma, pos_index, x, P, mu, mu0, psi, nis_avg, filter_updates, t, track_id, status, hit_bits, n_events,
                       n_updates, n_misses, created, last_event, confirmed_at, alt_m, z_hint, mode3a, icao24, iff,
                       identity, score, score_max, log_miss, score_logic, confirm_score, drop_score, delete_drop, min_plots, plot_range,
                       plot_azimuth,
                       plot_stage, scans, clutter_grid, clutter_params, clutter_log_area, code_counts, outside,
                       extra_x0, extra_var):
    """The end of a window for a bank of constant-velocity-layout states with the standard columns,
    in place: one-point initiation of ``new_plots`` (:class:`~skytrack.tracker.initiation.Initiator`;
    every mode of a mixture starts from it with probabilities ``mu0``, as
    :meth:`skytrack.filters.imm.IMMFilter.initiate`), the
    window's events and life-cycle decisions (:func:`record_and_manage`) and the compaction of the
    kept rows (:meth:`~skytrack.tracker.bank.TrackBank.keep`).  The arrays must have room for
    ``size + len(new_plots)`` rows; the states are in mixture form (:func:`record_and_manage`);
    without ``with_psi`` the psi arrays are not touched.  State components beyond the CV ones
    (an augmented filter's parameters and memory, :mod:`skytrack.filters.adaptive_tracking`) start at
    ``extra_x0`` with variances ``extra_var`` (uncorrelated) and move with their rows.
    First the clutter map and the code counts learn from the window's plots
    (:meth:`skytrack.tracker.evidence.TrackScoring.observe`).
    Returns the new size, the counts (misses, confirmed, hopeless, lost) and the kept rows (new
    indices) of confirmed tracks whose identity differs from what the events last showed
    (:func:`skytrack.tracker.identity.changed_rows`)."""
    count_codes(plot_stage, plot_mode3a, plot_mode_c, code_counts)
    observe_kernel(plot_range, plot_azimuth, plot_stage, scans, clutter_grid, clutter_params, clutter_log_area)
    n_cv = 2 * dim
    n = x.shape[2]
    for c in range(len(new_plots)):
        j = new_plots[c]
        k = size + c
        for mode in range(x.shape[1]):
            mu[k, mode] = mu0[mode]
            for i in range(n):
                x[k, mode, i] = 0.0
                for l in range(n):
                    P[k, mode, i, l] = 0.0
            for i in range(n_cv, n):
                x[k, mode, i] = extra_x0[i - n_cv]
                P[k, mode, i, i] = extra_var[i - n_cv]
            for a in range(dim):
                x[k, mode, 2 * a] = plot_pos[j, a]
                for b in range(dim):
                    P[k, mode, 2 * a, 2 * b] = plot_cov[j, a, b]
                P[k, mode, 2 * a + 1, 2 * a + 1] = sigma_v * sigma_v
        if with_psi:
            psi[k] = False
            nis_avg[k] = 0.0
            filter_updates[k] = 0
        t[k] = plot_time[j]
        track_id[k] = first_id + c
        status[k] = 0
        hit_bits[k] = 1
        n_events[k] = 1
        n_updates[k] = 1
        n_misses[k] = 0
        created[k] = plot_time[j]
        last_event[k] = 0.0
        confirmed_at[k] = np.nan
        alt_m[k] = plot_mode_c[j]
        z_hint[k] = plot_pos[j, 2]
        mode3a[k] = plot_mode3a[j]
        icao24[k] = plot_mode_s[j]
        iff[k] = plot_iff[j]
        for i in range(IDENTITY_WIDTH):
            identity[k, i] = 0
        identity[k, N_FRIEND] = 1 if plot_iff[j] == 0 else 0
        identity[k, N_FOE] = 1 if plot_iff[j] == 1 else 0
        identity[k, MODE3A_N] = 1 if plot_mode3a[j] >= 0 else 0
        identity[k, ICAO24_N] = 1 if plot_mode_s[j] >= 0 else 0
        identity[k, MODE3A_N + 1] = -1
        identity[k, ICAO24_N + 1] = -1
        identity[k, SHOWN_MODE3A] = -1
        identity[k, SHOWN_ICAO24] = -1
        identity[k, SHOWN_IFF] = -1
        score[k] = 0.0
        score_max[k] = 0.0
    rows = size + len(new_plots)
    keep, misses, confirmed, hopeless, lost = record_and_manage(
        hit, expected, w_end, confirm_m, confirm_n, delete_misses, max_sigma, pos_index, x, P, mu, t[:rows], status[:rows],
        hit_bits[:rows], n_events[:rows], n_misses[:rows], last_event[:rows], confirmed_at[:rows], score[:rows],
        score_max[:rows], log_miss, score_logic, confirm_score, drop_score, delete_drop, min_plots, outside)
    m = 0
    changed = np.empty(rows, np.int64)
    n_changed = 0
    for k in range(rows):
        if not keep[k]:
            continue
        if m != k:
            for mode in range(x.shape[1]):
                mu[m, mode] = mu[k, mode]
                for i in range(n):
                    x[m, mode, i] = x[k, mode, i]
                    for l in range(n):
                        P[m, mode, i, l] = P[k, mode, i, l]
            if with_psi:
                psi[m] = psi[k]
                nis_avg[m] = nis_avg[k]
                filter_updates[m] = filter_updates[k]
            t[m] = t[k]
            track_id[m] = track_id[k]
            status[m] = status[k]
            hit_bits[m] = hit_bits[k]
            n_events[m] = n_events[k]
            n_updates[m] = n_updates[k]
            n_misses[m] = n_misses[k]
            created[m] = created[k]
            last_event[m] = last_event[k]
            confirmed_at[m] = confirmed_at[k]
            alt_m[m] = alt_m[k]
            z_hint[m] = z_hint[k]
            mode3a[m] = mode3a[k]
            icao24[m] = icao24[k]
            iff[m] = iff[k]
            for i in range(IDENTITY_WIDTH):
                identity[m, i] = identity[k, i]
            score[m] = score[k]
            score_max[m] = score_max[k]
        if status[m] == 1 and (mode3a[m] != identity[m, SHOWN_MODE3A] or icao24[m] != identity[m, SHOWN_ICAO24]
                               or iff[m] != identity[m, SHOWN_IFF]):
            changed[n_changed] = m
            n_changed += 1
        m += 1
    return m, misses, confirmed, hopeless, lost, changed[:n_changed]


@njit(cache=True, nogil=True)
def report_cv(instant, size, x, P, t, psi, with_psi, q, q_big, full_covariance, status, track_id, n_updates,
              n_misses, alt_m, z_hint, mode3a, icao24, iff, identity, log_rho, max_misses):
    """One output instant of a constant-velocity Gaussian bank: every reported track
    (:func:`skytrack.tracker.output.reported_rows`: confirmed, fewer than ``max_misses``
    consecutive misses unless that is 0) predicted to ``instant`` (the filter's process noise,
    psi included) and its record columns (:func:`skytrack.tracker.output.instant_record`; identity
    source and probability by :func:`skytrack.tracker.identity.identity_rows` with ``log_rho``)."""
    n = x.shape[1]
    count = 0
    for k in range(size):
        if status[k] == 1 and (max_misses <= 0 or n_misses[k] < max_misses):
            count += 1
    rows = np.empty(count, np.int64)
    m = 0
    for k in range(size):
        if status[k] == 1 and (max_misses <= 0 or n_misses[k] < max_misses):
            rows[m] = k
            m += 1
    x_out = np.empty((count, n))
    var = np.empty((count, n))
    upper = np.empty((count, n * (n + 1) // 2 if full_covariance else 0))
    xr = np.empty(n)
    Pr = np.empty((n, n))
    for c in range(count):
        k = rows[c]
        scale = q_big if (with_psi and psi[k]) else 1.0
        _predict_cv_row(x[k], P[k], instant - t[k], q, scale, n // 2, xr, Pr)
        for i in range(n):
            x_out[c, i] = xr[i]
            var[c, i] = Pr[i, i]
        if full_covariance:
            u = 0
            for i in range(n):
                for j in range(i, n):
                    upper[c, u] = Pr[i, j]
                    u += 1
    source = np.empty(count, np.int8)
    identity_p = np.empty(count)
    identity_rows(identity, mode3a, icao24, iff, rows, log_rho, source, identity_p)
    return (rows, x_out, var, upper, track_id[rows], n_updates[rows], n_misses[rows], alt_m[rows], z_hint[rows],
            mode3a[rows], icao24[rows], iff[rows], source, identity_p)

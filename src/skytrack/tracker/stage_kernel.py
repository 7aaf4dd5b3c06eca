"""One association stage of the common case in a single compiled call (numba, cached).

:func:`stage_cv` chains :func:`skytrack.tracker.kernels.gate_stage_cv` (prediction, search,
chi-square gate), :func:`skytrack.association.kernels.assign_clusters` (global nearest
neighbour: lone pairs and clusters up to ``max_dense`` nodes) and
:func:`skytrack.tracker.kernels.update_write_cv` (Kalman update, psi switch, bank columns) so
that a stage costs one dispatch from Python.  Pairs of larger clusters are returned, with what
their update needs, for the sparse solver in Python; they are rare.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.association.kernels import assign_clusters
from skytrack.tracker.kernels import gate_stage_cv, update_write_cv


@njit(cache=True, nogil=True)
def stage_cv(tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos,
             plot_cov, plot_mode_c, plot_range, plot_azimuth, plot_order, bucket_start, q, ndim, search_scale,
             margin_s, gate, replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin, miss, max_dense,
             psi_enabled, psi_on, psi_off, psi_memory, two_point, nis_avg, filter_updates, n_updates, n_misses,
             z_hint, status, mode3a, icao24, iff, plot_mode3a, plot_mode_s, plot_iff):
    """Returns (bank rows, plot rows) updated, the number of candidates, and the big-cluster pairs
    (local track and plot indices, ``d^2``, predicted state, Cholesky factor, measurement)."""
    kt, kp, d2, x_pred, P_pred, position, covariance, chol, candidates = gate_stage_cv(
        tracks, free, x_all, P_all, t_all, alt_all, psi_all, q_big, forced, t_ref, plot_time, plot_pos, plot_cov,
        plot_mode_c, plot_range, plot_azimuth, plot_order, bucket_start, q, ndim, search_scale, margin_s, gate,
        replace_height, sensor_alt, earth, var_r, var_az, var_h, rot, origin)
    chosen, big = assign_clusters(kt, kp, d2, np.full(len(tracks), miss), len(tracks), len(free), max_dense)
    pick = np.flatnonzero(chosen)
    rows = np.empty(len(pick), np.int64)
    plot_rows = np.empty(len(pick), np.int64)
    for c in range(len(pick)):
        rows[c] = tracks[kt[pick[c]]]
        plot_rows[c] = free[kp[pick[c]]]
    update_write_cv(rows, plot_rows, x_pred[pick], P_pred[pick], chol[pick], d2[pick], position[pick],
                    covariance[pick], ndim, forced, psi_enabled, psi_on, psi_off, psi_memory, two_point, x_all, P_all,
                    psi_all, nis_avg, filter_updates, t_all, n_updates, n_misses, z_hint, alt_all, status, mode3a,
                    icao24, iff, plot_time, plot_mode_c, plot_mode3a, plot_mode_s, plot_iff)
    rest = np.flatnonzero(big)
    return (rows, plot_rows, candidates, kt[rest], kp[rest], d2[rest], x_pred[rest], P_pred[rest], chol[rest],
            position[rest], covariance[rest])

"""Sparse gating: candidate (track, plot) pairs from a spatial index (DESIGN.md rule 2).

The exact gate of spec 000 (R7) is a Mahalanobis test ``d^2 = nu^T S^-1 nu <= g`` with
``S = H P H^T + R``.  Since ``|nu|^2 <= lambda_max(S) d^2`` and
``sqrt(lambda_max(P + R)) <= sqrt(lambda_max P) + sqrt(lambda_max R)``, every pair inside
the gate lies within the Euclidean radius ``sqrt(g) (sigma_track + sigma_plot)`` of the
track's predicted position.  A ``scipy.spatial.cKDTree`` over the plot positions returns
the pairs within each track's radius; only those pairs get the exact test.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from skytrack.core.linalg import max_eigenvalue_sym  # noqa: F401  (re-exported)


def candidate_pairs(
    track_positions: np.ndarray,
    track_sigma: np.ndarray,
    track_margin: np.ndarray,
    plot_positions: np.ndarray,
    plot_sigma: np.ndarray,
    scale: float,
    wide_quantile: float = 0.95,
) -> tuple[np.ndarray, np.ndarray]:
    """All pairs ``(track, plot)`` with ``|p_track - p_plot| <= scale (s_track + s_plot) + margin``.

    ``track_sigma``/``plot_sigma`` bound the standard deviations of the positions (square
    roots of the largest covariance eigenvalues), ``track_margin`` adds a distance per
    track (motion during the time uncertainty), ``scale`` is sqrt of the gate threshold
    times a safety factor.  Plots with unusually wide uncertainty (above the
    ``wide_quantile`` of the batch, e.g. plots that cannot be placed) are searched
    from their own side so that they do not inflate every track's search radius.
    Returns two int arrays (track index, plot index), in no particular order.
    """
    n_tracks, n_plots = len(track_positions), len(plot_positions)
    if n_tracks == 0 or n_plots == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    limit = np.quantile(plot_sigma, wide_quantile) if n_plots > 20 else np.inf
    wide = plot_sigma > limit
    narrow = np.flatnonzero(~wide)
    narrow_sigma = plot_sigma[narrow].max() if len(narrow) else 0.0
    radius = scale * (track_sigma + narrow_sigma) + track_margin
    tracks, plots = _ball_pairs(track_positions, radius, plot_positions[narrow])
    plots = narrow[plots]
    if wide.any():
        wide_index = np.flatnonzero(wide)
        wide_radius = scale * (plot_sigma[wide_index] + track_sigma.max()) + track_margin.max()
        wide_plots, wide_tracks = _ball_pairs(plot_positions[wide_index], wide_radius, track_positions)
        tracks = np.concatenate([tracks, wide_tracks])
        plots = np.concatenate([plots, wide_index[wide_plots]])
    return tracks, plots


def _ball_pairs(centres: np.ndarray, radii: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (centre index, point index) with the point within the centre's radius.

    Two k-d trees are joined at the largest radius in one C call
    (``sparse_distance_matrix``), then each pair is checked against its own radius.
    """
    if len(centres) == 0 or len(points) == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    found = cKDTree(centres).sparse_distance_matrix(cKDTree(points), float(np.max(radii)), output_type="ndarray")
    keep = found["v"] <= radii[found["i"]]
    return found["i"][keep].astype(np.intp), found["j"][keep].astype(np.intp)

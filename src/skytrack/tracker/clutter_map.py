"""The clutter map: false-plot density per range-azimuth cell of each radar, learned online.

A track score and a likelihood-ratio association cost need the spatial density ``beta`` of
false plots where each plot lies (issue 6; Blackman & Popoli, *Design and Analysis of Modern
Tracking Systems*, 6.2).  A real radar's false plots are far from uniform: roughly uniform in
range and azimuth, so dense near the antenna, plus patches (ground clutter, weather).  Each
radar gets a grid of ``range_cells x azimuth_cells`` cells out to its instrumented range; after
every window the plots that no confirmed or tentative track took (clutter and the first plots
of new aircraft) are counted in their cells, and the counts and the elapsed scans are
forgotten exponentially with a memory of ``memory_scans`` scans.

The density of cell ``c`` is a gamma-Poisson estimate with the sensor's prior
(``clutter_per_scan`` of sensors.json, spread uniformly over the cells, weighted as
``prior_scans`` scans of data, never forgotten):

    rate_c = (prior_scans * prior_rate_c + counts_c) / (prior_scans + exposure_scans)   [plots/scan]
    beta_c = rate_c / area_c          area_c = (r_hi^2 - r_lo^2) / 2 * d_az             [plots/m^2]

The forgetting is kept as one scale factor (the counts are stored divided by it, and folded
back when it gets small), so that a window costs time in its plots, not in the cells.

For 3-D tracking the density is per m^3: the area is multiplied by the height the cell spans
between elevations 0 and ``elevation_span_deg`` at the cell's middle range (at least 1 km).
Plots beyond the last cell count in it.  :func:`log_density_at` and
:func:`observe_kernel` are the compiled forms (the association stage looks the density up
for the plots of its gated pairs only); :meth:`ClutterMap.log_density` and
:meth:`ClutterMap.observe` are the numpy reference they are tested against.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: range used for the map of a radar without an instrumented range (m)
DEFAULT_RANGE_M = 500_000.0


# layout of a map's parameter vector (one array, so that a kernel takes a map as three arguments)
EXPOSURE, SCALE, PRIOR_SCANS, CELL_RANGE, MEMORY_SCANS = range(5)


class ClutterMap:
    """Clutter density of one sensor's range-azimuth cells (see the module docstring).

    ``grid[0]`` holds the prior counts, ``grid[1]`` the learned counts divided by
    ``params[SCALE]``; ``params`` also holds the exposure in scans, the prior's weight, the cell
    length and the memory; ``log_area`` the log area (or volume) of each range ring's cells."""

    def __init__(self, max_range_m: float | None, prior_per_scan: float, range_cells: int, azimuth_cells: int,
                 prior_scans: float, memory_scans: float, dim: int, elevation_span_deg: float) -> None:
        self.max_range_m = float(max_range_m or DEFAULT_RANGE_M)
        self.range_cells = range_cells
        self.azimuth_cells = azimuth_cells
        cell_range = self.max_range_m / range_cells
        edges = np.arange(range_cells + 1) * cell_range
        d_az = 2.0 * math.pi / azimuth_cells
        area = 0.5 * (edges[1:] ** 2 - edges[:-1] ** 2) * d_az
        if dim == 3:
            middle = 0.5 * (edges[1:] + edges[:-1])
            area = area * np.maximum(middle * math.sin(math.radians(elevation_span_deg)), 1000.0)
        self.log_area = np.log(area)
        self.grid = np.zeros((2, range_cells, azimuth_cells))
        self.grid[0] = prior_scans * prior_per_scan / (range_cells * azimuth_cells)
        self.params = np.array([0.0, 1.0, float(prior_scans), cell_range, float(memory_scans)])

    @property
    def counts(self) -> np.ndarray:
        """Forgotten counts of false plots per cell."""
        return self.grid[1] * self.params[SCALE]

    def cells(self, range_m: np.ndarray, azimuth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(invalid="ignore"):
            rc = np.clip(np.nan_to_num(range_m / self.params[CELL_RANGE]), 0, self.range_cells - 1).astype(np.int64)
            turn = np.nan_to_num(np.mod(azimuth, 2 * math.pi) / (2 * math.pi))
        ac = np.clip((turn * self.azimuth_cells).astype(np.int64), 0, self.azimuth_cells - 1)
        return rc, ac

    def log_density(self, range_m: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
        """ln beta at each plot (numpy reference of :func:`log_density_at`)."""
        rc, ac = self.cells(range_m, azimuth)
        rate = (self.grid[0][rc, ac] + self.counts[rc, ac]) / (self.params[PRIOR_SCANS] + self.params[EXPOSURE])
        return np.log(rate) - self.log_area[rc]

    def observe(self, range_m: np.ndarray, azimuth: np.ndarray, plot_stage: np.ndarray, scans: float) -> None:
        """Forget by ``scans`` elapsed scans, then count the plots no confirmed track took
        (``plot_stage`` not 0 or 1; numpy reference of :func:`observe_kernel`)."""
        keep = math.exp(-scans / self.params[MEMORY_SCANS])
        counts = self.counts * keep
        false = (plot_stage != 0) & (plot_stage != 1)
        rc, ac = self.cells(range_m[false], azimuth[false])
        np.add.at(counts, (rc, ac), 1.0)
        self.grid[1] = counts
        self.params[EXPOSURE] = self.params[EXPOSURE] * keep + scans
        self.params[SCALE] = 1.0

    def total_rate(self) -> float:
        """Estimated false plots per scan over the whole map."""
        return float((self.grid[0].sum() + self.counts.sum()) / (self.params[PRIOR_SCANS] + self.params[EXPOSURE]))


@njit(cache=True, nogil=True, inline="always")
def _cell_of(r, az, range_cells, azimuth_cells, cell_range):
    """The (range, azimuth) cell of a plot (:meth:`ClutterMap.cells`); NaN goes to cell 0."""
    rc = 0
    if r == r:
        rc = min(max(int(min(r / cell_range, range_cells)), 0), range_cells - 1)
    ac = 0
    if az == az:
        turn = az / (2.0 * np.pi)
        turn -= np.floor(turn)
        ac = min(max(int(turn * azimuth_cells), 0), azimuth_cells - 1)
    return rc, ac


@njit(cache=True, nogil=True, inline="always")
def log_density_at(r, az, grid, params, log_area):
    """ln beta of one plot (:meth:`ClutterMap.log_density`)."""
    rc, ac = _cell_of(r, az, grid.shape[1], grid.shape[2], params[CELL_RANGE])
    rate = (grid[0, rc, ac] + grid[1, rc, ac] * params[SCALE]) / (params[PRIOR_SCANS] + params[EXPOSURE])
    return np.log(rate) - log_area[rc]


@njit(cache=True, nogil=True)
def observe_kernel(range_m, azimuth, plot_stage, scans, grid, params, log_area):
    """:meth:`ClutterMap.observe` in place."""
    keep = np.exp(-scans / params[MEMORY_SCANS])
    params[EXPOSURE] = params[EXPOSURE] * keep + scans
    params[SCALE] *= keep
    if params[SCALE] < 1e-100:
        grid[1] *= params[SCALE]
        params[SCALE] = 1.0
    for j in range(len(range_m)):
        if plot_stage[j] != 0 and plot_stage[j] != 1:
            rc, ac = _cell_of(range_m[j], azimuth[j], grid.shape[1], grid.shape[2], params[CELL_RANGE])
            grid[1, rc, ac] += 1.0 / params[SCALE]

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

For 3-D tracking the density is per m^3: the area is multiplied by the height the cell spans
between elevations 0 and ``elevation_span_deg`` at the cell's middle range (at least 1 km).
Plots beyond the last cell count in it.  :func:`log_density_kernel` and
:func:`observe_kernel` are the compiled forms used per window; :meth:`ClutterMap.log_density`
is the numpy reference they are tested against.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: range used for the map of a radar without an instrumented range (m)
DEFAULT_RANGE_M = 500_000.0


class ClutterMap:
    """Clutter density of one sensor's range-azimuth cells (see the module docstring)."""

    def __init__(self, max_range_m: float | None, prior_per_scan: float, range_cells: int, azimuth_cells: int,
                 prior_scans: float, memory_scans: float, dim: int, elevation_span_deg: float) -> None:
        self.max_range_m = float(max_range_m or DEFAULT_RANGE_M)
        self.range_cells = range_cells
        self.azimuth_cells = azimuth_cells
        self.memory_scans = memory_scans
        self.cell_range_m = self.max_range_m / range_cells
        edges = np.arange(range_cells + 1) * self.cell_range_m
        d_az = 2.0 * math.pi / azimuth_cells
        area = 0.5 * (edges[1:] ** 2 - edges[:-1] ** 2) * d_az
        if dim == 3:
            middle = 0.5 * (edges[1:] + edges[:-1])
            area = area * np.maximum(middle * math.sin(math.radians(elevation_span_deg)), 1000.0)
        self.log_area = np.log(area)
        self.prior_counts = np.full((range_cells, azimuth_cells), prior_scans * prior_per_scan
                                    / (range_cells * azimuth_cells))
        self.prior_scans = float(prior_scans)
        self.counts = np.zeros((range_cells, azimuth_cells))
        self.exposure = np.zeros(1)

    def cells(self, range_m: np.ndarray, azimuth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rc = np.clip((range_m / self.cell_range_m).astype(np.int64), 0, self.range_cells - 1)
        ac = np.clip((np.mod(azimuth, 2 * math.pi) / (2 * math.pi) * self.azimuth_cells).astype(np.int64), 0,
                     self.azimuth_cells - 1)
        return rc, ac

    def log_density(self, range_m: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
        """ln beta at each plot (numpy reference of :func:`log_density_kernel`)."""
        rc, ac = self.cells(range_m, azimuth)
        rate = (self.prior_counts[rc, ac] + self.counts[rc, ac]) / (self.prior_scans + self.exposure[0])
        return np.log(rate) - self.log_area[rc]

    def observe(self, range_m: np.ndarray, azimuth: np.ndarray, scans: float) -> None:
        """Forget by ``scans`` elapsed scans, then count the given false plots (numpy reference)."""
        keep = math.exp(-scans / self.memory_scans)
        self.counts *= keep
        self.exposure[0] = self.exposure[0] * keep + scans
        rc, ac = self.cells(range_m, azimuth)
        np.add.at(self.counts, (rc, ac), 1.0)

    def total_rate(self) -> float:
        """Estimated false plots per scan over the whole map."""
        return float((self.prior_counts.sum() + self.counts.sum()) / (self.prior_scans + self.exposure[0]))

    def arguments(self) -> tuple:
        """The map's arrays and constants in the order the kernels take them."""
        return (self.prior_counts, self.counts, self.exposure, self.prior_scans, self.log_area, self.cell_range_m,
                self.range_cells, self.azimuth_cells)


@njit(cache=True, nogil=True)
def _cell(r, az, cell_range, range_cells, azimuth_cells):
    rc = min(max(int(r / cell_range), 0), range_cells - 1) if r == r else 0
    turn = az / (2.0 * np.pi)
    turn -= np.floor(turn)
    ac = min(max(int(turn * azimuth_cells), 0), azimuth_cells - 1) if az == az else 0
    return rc, ac


@njit(cache=True, nogil=True)
def log_density_kernel(range_m, azimuth, prior_counts, counts, exposure, prior_scans, log_area, cell_range,
                       range_cells, azimuth_cells):
    """ln beta of every plot of a window (:meth:`ClutterMap.log_density`)."""
    out = np.empty(len(range_m))
    scans = prior_scans + exposure[0]
    for j in range(len(range_m)):
        rc, ac = _cell(range_m[j], azimuth[j], cell_range, range_cells, azimuth_cells)
        out[j] = np.log((prior_counts[rc, ac] + counts[rc, ac]) / scans) - log_area[rc]
    return out


@njit(cache=True, nogil=True)
def observe_kernel(range_m, azimuth, false_plot, scans, memory_scans, prior_counts, counts, exposure, prior_scans,
                   log_area, cell_range, range_cells, azimuth_cells):
    """:meth:`ClutterMap.observe` of the plots flagged ``false_plot``."""
    keep = np.exp(-scans / memory_scans)
    for rc in range(range_cells):
        for ac in range(azimuth_cells):
            counts[rc, ac] *= keep
    exposure[0] = exposure[0] * keep + scans
    for j in range(len(range_m)):
        if false_plot[j]:
            rc, ac = _cell(range_m[j], azimuth[j], cell_range, range_cells, azimuth_cells)
            counts[rc, ac] += 1.0

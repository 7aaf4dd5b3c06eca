"""The reorder buffer of ``skytrack serve`` (issue 11 item 3): plots from UDP datagrams, held until they are
older than the newest plot time minus a window, then released to the tracker in time order.

Datagrams from several radars (and one radar's datagrams) may arrive out of order; the tracker needs plots
in time order per sensor and cannot take time going backwards.  The buffer holds plots for ``window_s``
seconds of plot time: everything older than ``newest - window_s`` is released, sorted by time.  The release
time is one clock for all sensors (a radar that went silent does not hold the others back).  A plot older
than what was already released is **late**: it is counted per sensor (``late_per_sensor``, the service's
``/metrics`` and ``/health``), never silently dropped, and never given to the tracker.

When no plot has arrived for ``idle_flush_s`` of wall time, everything held is released (the end of a
replay, a pause of the feed): plots older than it that come later are late, as above.
"""

from __future__ import annotations

import numpy as np

from skytrack.core.plots import PlotBatch


class ReorderBuffer:
    """Plots held for ``window_s`` of plot time, released in time order; late plots counted per sensor."""

    def __init__(self, n_sensors: int, window_s: float, idle_flush_s: float | None = None) -> None:
        if not window_s >= 0:
            raise ValueError(f"the reorder window must be >= 0 s, got {window_s}")
        self.window_s = float(window_s)
        self.idle_flush_s = max(self.window_s, 1.0) if idle_flush_s is None else float(idle_flush_s)
        self.held = PlotBatch.empty()
        self.held_received = np.zeros(0)
        #: plot time up to which plots went to the tracker (a plot older than this is late)
        self.released_until = -np.inf
        self.newest = -np.inf
        self.last_arrival_wall = -np.inf
        self.late_per_sensor = np.zeros(n_sensors, np.int64)
        self.released_total = 0

    def __len__(self) -> int:
        return len(self.held)

    @property
    def late(self) -> int:
        return int(self.late_per_sensor.sum())

    def add(self, plots: PlotBatch, received_wall: np.ndarray | float, now_wall: float) -> int:
        """Hold ``plots`` (any order), each received at ``received_wall`` (wall clock); returns how many
        of them were late (older than the plots already released) and were counted, not held."""
        if len(plots) == 0:
            return 0
        received = np.broadcast_to(np.asarray(received_wall, float), (len(plots),))
        late = plots.time < self.released_until
        n_late = int(late.sum())
        if n_late:
            self.late_per_sensor += np.bincount(plots.sensor[late].astype(np.int64),
                                                minlength=len(self.late_per_sensor))
            plots, received = plots.take(~late), received[~late]
        if len(plots):
            self.held = PlotBatch.concat([self.held, plots])
            self.held_received = np.concatenate([self.held_received, received])
            self.newest = max(self.newest, float(plots.time.max()))
            self.last_arrival_wall = now_wall
        return n_late

    def release(self, now_wall: float) -> tuple[PlotBatch, np.ndarray]:
        """The plots older than ``newest - window_s`` (all of them once the feed has been idle for
        ``idle_flush_s``), sorted by time, with their receive wall times."""
        if len(self.held) == 0:
            return PlotBatch.empty(), np.zeros(0)
        idle = now_wall - self.last_arrival_wall >= self.idle_flush_s
        until = self.newest if idle else self.newest - self.window_s
        ready = self.held.time <= until if idle else self.held.time < until
        if not ready.any():
            return PlotBatch.empty(), np.zeros(0)
        rows = np.flatnonzero(ready)
        rows = rows[np.argsort(self.held.time[rows], kind="stable")]
        out, received = self.held.take(rows), self.held_received[rows]
        keep = ~ready
        self.held, self.held_received = self.held.take(keep), self.held_received[keep]
        self.released_until = max(self.released_until, until)
        self.released_total += len(out)
        return out, received

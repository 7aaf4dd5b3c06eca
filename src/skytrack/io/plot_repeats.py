"""Plot rows that repeat an earlier row exactly (same sensor, time, range and azimuth).

A recording that was concatenated twice, or a feed replayed into the same file, gives
such rows; the tracker would take each as a second detection.  They are reported, not
dropped (FORMATS.md has no rule that forbids them).  Because time does not go backwards
within a sensor, a repeat across a chunk boundary has the time of the previous chunk's
last plot of that sensor: only those plots are carried from chunk to chunk.
"""

from __future__ import annotations

import numpy as np


class RepeatedRows:
    """Counts repeated plot rows over the chunks of a file."""

    def __init__(self) -> None:
        self._codes: dict[str, int] = {}
        self.count = 0
        self.first: tuple[int, int] | None = None  # (repeating row, the row it repeats)
        self._carried = np.zeros((0, 5))  # sensor, time, range, azimuth, row of the last plots

    def add(self, sensor: np.ndarray, time: np.ndarray, range_m: np.ndarray, azimuth: np.ndarray,
            row: np.ndarray) -> None:
        """One chunk's plots (``sensor`` as integer codes stable over the file, ``row`` their rows)."""
        carried = self._carried
        columns = [np.asarray(values) for values in (sensor, time, range_m, azimuth, row)]
        times = np.concatenate([carried[:, 1], columns[1].astype(float, copy=False)])
        # a repeat shares its time with the row it repeats: only rows whose time occurs more
        # than once need the full comparison (a stable sort of nearly sorted times is cheap)
        if len(times) < 2 or bool(np.all(times[1:] > times[:-1])):
            tie = np.zeros(0, dtype=np.intp)  # strictly increasing times (the common case): no tie
        else:
            by_time = np.argsort(times, kind="stable")
            in_order = times[by_time]
            tie = np.flatnonzero(in_order[1:] == in_order[:-1])
        if len(tie):
            members = by_time[np.unique(np.concatenate([tie, tie + 1]))]
            old = members < len(carried)
            rows = np.empty((len(members), 5))
            rows[old] = carried[members[old]]
            fresh = members[~old] - len(carried)
            rows[~old] = np.column_stack([values[fresh] for values in columns])
            self._count(rows, ~old)
        last = _last_time(columns[0], columns[1])
        self._carried = np.column_stack([values[last] for values in columns]) if len(columns[1]) else carried

    def _count(self, rows: np.ndarray, new: np.ndarray) -> None:
        """Count the repeats among ``rows`` whose repeating row is ``new`` (pairs of carried rows
        were counted with their own chunk)."""
        # sorted by the key, then by row: a repeat follows the row it repeats
        order = np.lexsort((rows[:, 4], rows[:, 3], rows[:, 2], rows[:, 1], rows[:, 0]))
        key = rows[order, :4]
        same = np.all(key[1:] == key[:-1], axis=1) & new[order[1:]]
        if same.any():
            self.count += int(same.sum())
            # the earliest repeating row of the file, with the row it repeats
            repeats = rows[order[1:][same], 4]
            originals = rows[order[:-1][same], 4]
            at = int(np.argmin(repeats))
            candidate = (int(repeats[at]), int(originals[at]))
            if self.first is None or candidate[0] < self.first[0]:
                self.first = candidate

    def add_batch(self, plots, sensor_names: list[str], first_row: int) -> None:
        """A :class:`~skytrack.core.plots.PlotBatch` chunk whose first plot is row ``first_row``."""
        codes = np.array([self._code(name) for name in sensor_names], dtype=np.int64)
        self.add(codes[plots.sensor] if len(codes) else plots.sensor, plots.time, plots.range_m, plots.azimuth,
                 first_row + np.arange(len(plots)))

    def add_frame(self, frame, first_row: int) -> None:
        """A validated plots DataFrame chunk whose first plot is row ``first_row``."""
        import pandas as pd

        local, names = pd.factorize(frame["sensor"].to_numpy(dtype=object))
        codes = np.array([self._code(str(name)) for name in names], dtype=np.int64)
        self.add(codes[local] if len(codes) else local, frame["time"].to_numpy(dtype=float),
                 frame["range_m"].to_numpy(dtype=float), np.radians(frame["azimuth_deg"].to_numpy(dtype=float)),
                 first_row + np.arange(len(frame)))

    def _code(self, name: str) -> int:
        return self._codes.setdefault(name, len(self._codes))

    def message(self) -> str | None:
        """The warning for the file, or ``None`` when no row repeats."""
        if not self.count:
            return None
        repeat, original = self.first
        return (f"{self.count} plot rows repeat an earlier row exactly (sensor, time, range, azimuth), first row "
                f"{repeat} repeating row {original}: a file concatenated twice? They are tracked as detections")


def _last_time(sensor: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Which plots are at their sensor's latest time (where a repeat in the next chunk can only be)."""
    keep = np.zeros(len(time), dtype=bool)
    for code in np.flatnonzero(np.bincount(sensor)):  # the codes present: a handful of sensors
        of_sensor = sensor == code
        keep |= of_sensor & (time == time[of_sensor].max())
    return keep

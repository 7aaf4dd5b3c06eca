"""Do the plots' times run in seconds?  A rotating radar's beam tells.

The beam of a radar with ``scan_period_s`` P turns 360 / P degrees per second, and every plot
(aircraft or clutter) is seen where the beam points.  Consecutive plots of one sweep are a
few degrees apart, so the median of (azimuth step / time step) over such pairs estimates the
turning rate in the file's own time unit.  Times in milliseconds make it about 1 000 times
too slow; the tracker would then wait a thousand scans for each plot.
"""

from __future__ import annotations

import numpy as np

#: plots kept per sensor for the estimate, and pairs needed for it
_SAMPLE = 2000
_MIN_PAIRS = 50
#: consecutive plots further apart than this in azimuth are not of one sweep
_MAX_STEP_DEG = 20.0
#: a rate this far from the expected one (either way) is reported
_TOLERANCE = 10.0


class BeamRateCheck:
    """Collects the first plots of every rotating radar and compares the beam's turning rate
    in the file's times with its ``scan_period_s``."""

    def __init__(self, sensors) -> None:
        self._period = {s.name: s.scan_period_s for s in sensors.sensors
                        if s.scan_period_s and not s.is_moving and s.is_radar} if sensors is not None else {}
        self._times: dict[str, list[np.ndarray]] = {name: [] for name in self._period}
        self._azimuths: dict[str, list[np.ndarray]] = {name: [] for name in self._period}

    @property
    def sampled(self) -> dict[str, int]:
        """Plots kept so far per rotating radar."""
        return {name: sum(len(t) for t in times) for name, times in self._times.items()}

    @property
    def wants_more(self) -> bool:
        """Whether some radar has fewer plots than the estimate uses."""
        return any(count < _SAMPLE for count in self.sampled.values())

    def add(self, sensor_names: np.ndarray, time: np.ndarray, azimuth_deg: np.ndarray) -> None:
        """One chunk's plots (sensor name per row, time, azimuth in degrees)."""
        for name in self._period:
            have = sum(len(t) for t in self._times[name])
            if have >= _SAMPLE:
                continue
            mine = np.flatnonzero(sensor_names == name)[: _SAMPLE - have]
            self._times[name].append(np.asarray(time, dtype=float)[mine])
            self._azimuths[name].append(np.asarray(azimuth_deg, dtype=float)[mine])

    def problems(self) -> list[str]:
        """One sentence per radar whose plots' times do not turn its beam at its scan period."""
        found = []
        for name, period in self._period.items():
            rate = _turning_rate(np.concatenate(self._times[name] or [np.zeros(0)]),
                                 np.concatenate(self._azimuths[name] or [np.zeros(0)]))
            if rate is None:
                continue
            expected = 360.0 / period
            ratio = expected / rate
            if ratio > _TOLERANCE or ratio < 1.0 / _TOLERANCE:
                unit = " (are the times in milliseconds instead of seconds?)" if 300.0 <= ratio <= 3000.0 else ""
                found.append(f"by the plots' times the beam of {name} turns {rate:.3g} deg/s, by its scan_period_s "
                             f"of {period:g} s it turns {expected:.3g} deg/s{unit}")
        return found


def _turning_rate(time: np.ndarray, azimuth_deg: np.ndarray) -> float | None:
    """Median azimuth step per time step over consecutive plots of one sweep (deg per time unit)."""
    if len(time) <= _MIN_PAIRS:
        return None
    order = np.argsort(time, kind="stable")
    dt = np.diff(time[order])
    step = np.mod(np.diff(azimuth_deg[order]), 360.0)
    one_sweep = (dt > 0) & (step > 0) & (step < _MAX_STEP_DEG)
    if one_sweep.sum() < _MIN_PAIRS:
        return None
    return float(np.median(step[one_sweep] / dt[one_sweep]))

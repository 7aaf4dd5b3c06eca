"""Track score and association evidence: log-likelihood ratios against the local clutter density.

The score of a track is the log-likelihood ratio of "a target" against "false plots" over the
plots it took and the plots it missed (the sequential probability ratio test of Blackman &
Popoli, *Design and Analysis of Modern Tracking Systems*, 6.2; Wald's thresholds).  Per event:

* a hit by plot ``j``:  ``dL = ln P_D + ln N(nu; 0, S) - ln beta_j + ln(SSR ratio)``, with
  ``ln N = -(d^2 + ln det(2 pi S)) / 2`` and ``beta_j`` the clutter map's density at the plot
  (:mod:`skytrack.tracker.clutter_map`);
* an expected plot that did not come: ``dL = ln(1 - P_D)``.

A new track starts at score 0.  Wald's thresholds come from the stated false-track rate
``false_tracks_per_hour`` of each radar and the probability ``p_reject_true`` of dropping a
true target: every false plot that no track takes starts a tentative track, so with ``C`` false
plots per scan (the map's estimate) and a scan period ``T`` the probability of confirming one
may be ``alpha = rate * T / (3600 C)``; a tentative track is confirmed when its score reaches
``ln((1 - beta) / alpha)`` and dropped below ``ln(beta / (1 - alpha))``.  A confirmed track is
deleted when its score falls ``delete_misses * -ln(1 - P_D)`` below its maximum: the drop of
that many misses in a row, or of a run of weak hits on clutter.

The association cost of a pair is ``-2 (dL_hit - dL_miss)``: the negative log-likelihood ratio
of "plot j from track i" against "plot j false and track i missed".  It includes ``ln det S``
and ``beta_j``, so a wide covariance no longer wins a plot by its small ``d^2`` and plots in
dense clutter need a closer fit; a pair with a cost >= 0 is worse than a miss and is not
offered to the assignment.

SSR evidence (issue 6 item 5): a plot's Mode 3/A and Mode C are compared with the track's last
ones.  With ``q_t`` the probability that a target's plot carries the code and ``q_c`` the
probability that a false plot does (both learned from the plots, counts with a prior), the
ratio is ``q_t (1 - eps) / (q_c / 4096)`` for the same code, ``q_t eps / q_c`` for another code
(``eps`` the chance of a code change or garble) and ``(1 - q_t) / (1 - q_c)`` for a plot without
one; Mode C: ``q_t ((1 - g) N(dh; 0, s^2) + g / H) / (q_c / H)`` (``s^2 = sigma_h^2 + (sigma_vz
dt)^2``, ``H`` the span of false heights, ``g`` a garble probability).  Tracks without a known
code or height get no SSR term, so primary-only aircraft are not penalised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from skytrack.core.validate import require_positive

LOG_2PI = math.log(2.0 * math.pi)
#: learned code probabilities are kept inside this interval
_Q_RANGE = (0.01, 0.99)
#: P_D used by the score is kept inside this interval (ln(1 - P_D) must stay finite)
_PD_RANGE = (0.05, 0.99)
# layout of the SSR parameter vector the kernels read
(SSR_ON, T3_HAS, T3_NONE, C3_HAS, C3_NONE, TC_HAS, TC_NONE, CC_HAS, CC_NONE, SAME_CODE, OTHER_CODE, CODE_SPACE,
 ALT_VAR, VZ_VAR, LOG_SPAN, LOG_GARBLE, LOG_KEEP) = range(17)
SSR_SIZE = 17
# layout of the code counts: target plots, with Mode 3/A, with Mode C; false plots, idem
(TN, T3, TC, CN, C3, CC) = range(6)


@dataclass
class ScoreConfig:
    """Track score, clutter map and SSR evidence (see the module docstring).

    ``track_logic`` "score" confirms and deletes by the track score; "m-of-n" by the lifecycle's
    hit counts (the score is still kept and reported); with the score a track also needs
    ``confirm_min_plots`` plots among its last ``confirm_n`` events (3 makes its velocity rest
    on more than two plots; on the terminal scenario that cost 10 % GOSPA in later tracks and
    gained 3 % velocity error, so the default is 2).  ``p_detection`` and ``clutter_per_scan``
    are used for radars whose sensors.json does not give them."""

    track_logic: str = "score"
    false_tracks_per_hour: float = 1.0
    confirm_min_plots: int = 2
    p_reject_true: float = 0.05
    p_detection: float = 0.9
    clutter_per_scan: float = 10.0
    range_cells: int = 64
    azimuth_cells: int = 64
    prior_scans: float = 10.0
    memory_scans: float = 50.0
    elevation_span_deg: float = 20.0
    ssr: bool = True
    code_change_p: float = 0.01
    altitude_sigma_m: float = 60.0
    vertical_speed_sigma_mps: float = 10.0
    false_altitude_span_m: float = 15_000.0
    altitude_garble_p: float = 0.01
    prior_plots: float = 20.0
    prior_target_code_p: float = 0.9
    prior_false_code_p: float = 0.05

    def __post_init__(self) -> None:
        if self.track_logic not in ("score", "m-of-n"):
            raise ValueError(f"track_logic must be 'score' or 'm-of-n', got {self.track_logic!r}")
        require_positive(self, "false_tracks_per_hour", "prior_scans", "memory_scans", "elevation_span_deg",
                         "altitude_sigma_m", "false_altitude_span_m", "prior_plots")
        for name in ("p_reject_true", "p_detection", "code_change_p", "altitude_garble_p", "prior_target_code_p",
                     "prior_false_code_p"):
            value = getattr(self, name)
            if not 0.0 < value < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {value}")
        if not (self.clutter_per_scan >= 0 and math.isfinite(self.clutter_per_scan)):
            raise ValueError(f"clutter_per_scan must be finite and >= 0, got {self.clutter_per_scan}")
        if not 1 <= self.confirm_min_plots <= 32:
            raise ValueError(f"confirm_min_plots must be in [1, 32], got {self.confirm_min_plots}")
        if self.range_cells < 1 or self.azimuth_cells < 1:
            raise ValueError("range_cells and azimuth_cells must be >= 1")
        if self.vertical_speed_sigma_mps < 0:
            raise ValueError(f"vertical_speed_sigma_mps must be >= 0, got {self.vertical_speed_sigma_mps}")

    def detection_probability(self, sensor) -> float:
        value = sensor.p_detection if sensor.p_detection is not None else self.p_detection
        return min(max(float(value), _PD_RANGE[0]), _PD_RANGE[1])

    def prior_clutter(self, sensor) -> float:
        """False plots per scan before the map has data (at least 0.1: the score needs beta > 0)."""
        value = sensor.clutter_per_scan if sensor.clutter_per_scan is not None else self.clutter_per_scan
        return max(float(value), 0.1)

    def thresholds(self, clutter_per_scan: float, scan_period_s: float) -> tuple[float, float]:
        """Wald's (confirm, drop) thresholds of a tentative track's score for this radar."""
        alpha = self.false_tracks_per_hour * scan_period_s / (3600.0 * max(clutter_per_scan, 1e-9))
        alpha = min(max(alpha, 1e-12), 0.5)
        beta = self.p_reject_true
        return math.log((1.0 - beta) / alpha), math.log(beta / (1.0 - alpha))

    def new_code_counts(self) -> np.ndarray:
        """Prior pseudo-counts of the code probabilities (:data:`TN`... layout)."""
        n = self.prior_plots
        t, c = self.prior_target_code_p, self.prior_false_code_p
        return np.array([n, n * t, n * t, n, n * c, n * c])

    def ssr_parameters(self, counts: np.ndarray) -> np.ndarray:
        """The SSR parameter vector of the kernels from learned code counts."""
        out = np.zeros(SSR_SIZE)
        if not self.ssr:
            return out

        def q(hits, total):
            return min(max(hits / total, _Q_RANGE[0]), _Q_RANGE[1])

        t3, tc = q(counts[T3], counts[TN]), q(counts[TC], counts[TN])
        c3, cc = q(counts[C3], counts[CN]), q(counts[CC], counts[CN])
        out[SSR_ON] = 1.0
        out[T3_HAS], out[T3_NONE], out[C3_HAS], out[C3_NONE] = math.log(t3), math.log1p(-t3), math.log(c3), math.log1p(-c3)
        out[TC_HAS], out[TC_NONE], out[CC_HAS], out[CC_NONE] = math.log(tc), math.log1p(-tc), math.log(cc), math.log1p(-cc)
        out[SAME_CODE], out[OTHER_CODE] = math.log1p(-self.code_change_p), math.log(self.code_change_p)
        out[CODE_SPACE] = math.log(4096.0)
        out[ALT_VAR], out[VZ_VAR] = self.altitude_sigma_m**2, self.vertical_speed_sigma_mps**2
        out[LOG_SPAN] = math.log(self.false_altitude_span_m)
        out[LOG_GARBLE], out[LOG_KEEP] = math.log(self.altitude_garble_p), math.log1p(-self.altitude_garble_p)
        return out


@njit(cache=True, nogil=True, inline="always")
def ssr_log_ratio(plot_code, plot_alt, track_code, track_alt, dt, ssr):
    """ln of the SSR likelihood ratio of one pair (see the module docstring)."""
    if ssr[SSR_ON] == 0.0:
        return 0.0
    total = 0.0
    if track_code >= 0:
        if plot_code >= 0:
            if plot_code == track_code:
                total += ssr[T3_HAS] + ssr[SAME_CODE] - ssr[C3_HAS] + ssr[CODE_SPACE]
            else:
                total += ssr[T3_HAS] + ssr[OTHER_CODE] - ssr[C3_HAS]
        else:
            total += ssr[T3_NONE] - ssr[C3_NONE]
    if track_alt == track_alt:
        if plot_alt == plot_alt:
            var = ssr[ALT_VAR] + ssr[VZ_VAR] * dt * dt
            d = plot_alt - track_alt
            near = ssr[LOG_KEEP] - 0.5 * (d * d / var + np.log(2.0 * np.pi * var)) + ssr[LOG_SPAN]
            far = ssr[LOG_GARBLE]  # g / H against 1 / H
            gap = abs(near - far)
            # ln(e^near + e^far); beyond a gap of 40 the smaller term is below 4e-18 of the larger
            total += ssr[TC_HAS] - ssr[CC_HAS] + max(near, far) + (np.log1p(np.exp(-gap)) if gap < 40.0 else 0.0)
        else:
            total += ssr[TC_NONE] - ssr[CC_NONE]
    return total


def ssr_log_ratio_reference(plot_code, plot_alt, track_code, track_alt, dt, ssr) -> np.ndarray:
    """Numpy reference of :func:`ssr_log_ratio` over arrays of pairs."""
    n = len(plot_code)
    if ssr[SSR_ON] == 0.0:
        return np.zeros(n)
    has_track_code, has_plot_code = track_code >= 0, plot_code >= 0
    code = np.where(plot_code == track_code, ssr[T3_HAS] + ssr[SAME_CODE] - ssr[C3_HAS] + ssr[CODE_SPACE],
                    ssr[T3_HAS] + ssr[OTHER_CODE] - ssr[C3_HAS])
    code = np.where(has_plot_code, code, ssr[T3_NONE] - ssr[C3_NONE])
    var = ssr[ALT_VAR] + ssr[VZ_VAR] * dt * dt
    near = ssr[LOG_KEEP] - 0.5 * ((plot_alt - track_alt) ** 2 / var + np.log(2.0 * np.pi * var)) + ssr[LOG_SPAN]
    with np.errstate(invalid="ignore"):  # plots without Mode C (NaN) are replaced just below
        height = ssr[TC_HAS] - ssr[CC_HAS] + np.logaddexp(near, ssr[LOG_GARBLE])
    height = np.where(np.isfinite(plot_alt), height, ssr[TC_NONE] - ssr[CC_NONE])
    return np.where(has_track_code, code, 0.0) + np.where(np.isfinite(track_alt), height, 0.0)


@njit(cache=True, nogil=True)
def count_codes(plot_stage, mode3a, mode_c, counts):
    """Add a window's plots to the code counts (:data:`TN`... layout): plots of confirmed tracks
    (``plot_stage`` 0 or 1) as targets', plots no track took (-1) as false."""
    for j in range(len(mode3a)):
        if plot_stage[j] == 0 or plot_stage[j] == 1:
            base = 0
        elif plot_stage[j] == -1:
            base = 3
        else:
            continue
        counts[base] += 1.0
        if mode3a[j] >= 0:
            counts[base + 1] += 1.0
        if mode_c[j] == mode_c[j]:
            counts[base + 2] += 1.0


#: windows between refreshes of the learned SSR probabilities and the confirmation thresholds
REFRESH_WINDOWS = 16


class TrackScoring:
    """Per radar: the clutter map, the learned code probabilities, P_D and the thresholds,
    handed to the association and life cycle window by window."""

    def __init__(self, config: ScoreConfig, sensors, periods: np.ndarray, dim: int, delete_misses: int) -> None:
        from skytrack.tracker.clutter_map import ClutterMap

        self.config = config
        self.maps: list[ClutterMap] = []
        self.log_pd, self.log_miss, self.delete_drop = [], [], []
        self.code_counts = [config.new_code_counts() for _ in sensors]
        self.periods = [float(p) if p and np.isfinite(p) and p > 0 else 1.0 for p in periods]
        self._cache: list[tuple | None] = [None for _ in sensors]
        self._age = [0 for _ in sensors]
        for sensor in sensors:
            # a sensor without range and azimuth (ADS-B) gets one cell: a uniform density
            cells = (config.range_cells, config.azimuth_cells) if sensor.is_radar else (1, 1)
            self.maps.append(ClutterMap(sensor.max_range_m, config.prior_clutter(sensor), *cells, config.prior_scans,
                                        config.memory_scans, dim, config.elevation_span_deg))
            p_d = config.detection_probability(sensor)
            self.log_pd.append(math.log(p_d))
            self.log_miss.append(math.log1p(-p_d))
            # a hair below the drop of delete_misses misses, so that rounding cannot add one
            self.delete_drop.append(-delete_misses * math.log1p(-p_d) * (1.0 - 1e-9))

    def window(self, s: int) -> tuple:
        """(ssr parameters, confirm threshold, drop threshold) of sensor ``s``, refreshed every
        :data:`REFRESH_WINDOWS` windows."""
        self._age[s] -= 1
        if self._age[s] <= 0 or self._cache[s] is None:
            confirm, drop = self.config.thresholds(self.maps[s].total_rate(), self.periods[s])
            self._cache[s] = (self.config.ssr_parameters(self.code_counts[s]), confirm, drop)
            self._age[s] = REFRESH_WINDOWS
        return self._cache[s]

    def clutter_arguments(self, s: int) -> tuple:
        """Sensor ``s``'s clutter map as the kernels take it (grid, params, log_area)."""
        clutter_map = self.maps[s]
        return clutter_map.grid, clutter_map.params, clutter_map.log_area

    def observe(self, s: int, range_m: np.ndarray, azimuth: np.ndarray, mode3a: np.ndarray, mode_c: np.ndarray,
                plot_stage: np.ndarray, scans: float) -> None:
        """Learn from a window's plots (numpy reference of the learning in
        :func:`~skytrack.tracker.window_kernels.initiate_manage`): ``plot_stage`` 0/1 = taken by
        a confirmed track (a target's plot), 2 = by a tentative track, -1 = by none (false, or a new
        aircraft's first plot)."""
        counts = self.code_counts[s]
        for base, rows in ((TN, (plot_stage == 0) | (plot_stage == 1)), (CN, plot_stage == -1)):
            counts[base] += rows.sum()
            counts[base + 1] += (rows & (mode3a >= 0)).sum()
            counts[base + 2] += (rows & np.isfinite(mode_c)).sum()
        self.maps[s].observe(range_m, azimuth, plot_stage, scans)

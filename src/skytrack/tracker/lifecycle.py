"""Track life cycle: M-of-N confirmation, deletion after misses or covariance growth.

Per window, every track that was expected or hit records the event in its hit history
(``hit_bits``, newest in bit 0, last ``confirm_n`` kept) and consecutive misses (spec 000 R4:
a miss is an expected plot that did not come; it changes no state).  A tentative track is
confirmed when ``confirm_m`` of its last ``confirm_n`` events were hits and dropped as soon
as that cannot happen any more; a confirmed track is deleted after ``delete_misses``
consecutive misses or when its position standard deviation exceeds ``max_position_sigma_m``.
With the track score (:mod:`skytrack.tracker.evidence`) the score's thresholds decide instead
of the counts.  A track outside every radar's coverage (range, radar horizon) is deleted.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from skytrack.core.linalg import max_eigenvalue_sym
from skytrack.core.validate import require_positive
from skytrack.tracker.bank import CONFIRMED, TENTATIVE, TrackBank


@dataclass
class LifecycleConfig:
    confirm_m: int = 3
    confirm_n: int = 4
    delete_misses: int = 5
    max_position_sigma_m: float = 5000.0

    def __post_init__(self) -> None:
        if not (1 <= self.confirm_m <= self.confirm_n <= 32):
            raise ValueError(f"need 1 <= confirm_m <= confirm_n <= 32, got {self.confirm_m}/{self.confirm_n}")
        if self.delete_misses < 1:
            raise ValueError(f"delete_misses must be >= 1, got {self.delete_misses}")
        require_positive(self, "max_position_sigma_m")


class Lifecycle:
    def __init__(self, config: LifecycleConfig, position_index: np.ndarray, stats: Counter) -> None:
        self.config = config
        self.pos = position_index
        self.stats = stats

    def record_events(self, bank: TrackBank, hit: np.ndarray, expected: np.ndarray, w_end: float,
                      log_miss: float = 0.0) -> None:
        """M-of-N history, consecutive misses and the score of a miss (``log_miss`` = ln(1 - P_D))
        for tracks expected (or hit) in this window."""
        n = len(hit)
        event = hit | expected
        bank.last_event[:n][event] = w_end
        window_mask = np.uint32((1 << self.config.confirm_n) - 1)
        bits = bank.hit_bits[:n]
        bits[event] = ((bits[event] << np.uint32(1)) | hit[event].astype(np.uint32)) & window_mask
        bank.n_events[:n][event] += 1
        missed = expected & ~hit
        bank.n_misses[:n][missed] += 1
        bank.score[:n][missed] += log_miss
        self.stats["misses"] += int(missed.sum())

    def manage(self, bank: TrackBank, outside: np.ndarray | None = None, score_logic: bool = False,
               confirm_score: float = np.inf, drop_score: float = -np.inf, delete_drop: float = np.inf,
               min_plots: int = 1) -> None:
        """Confirm, drop hopeless tentative tracks, delete lost confirmed ones: by hit counts, or
        with ``score_logic`` by the track score (thresholds of :mod:`skytrack.tracker.evidence`;
        at least ``min_plots`` plots among the last ``confirm_n`` events to confirm).
        Tracks flagged ``outside`` every radar's coverage (the rows before this window's new
        tracks) are deleted at once."""
        cfg = self.config
        if len(bank) == 0:
            return
        gone = np.zeros(len(bank), dtype=bool)
        if outside is not None:
            gone[: len(outside)] = outside
        hits = np.bitwise_count(bank.hit_bits).astype(np.int64)
        tentative = (bank.status == TENTATIVE) & ~gone
        confirm = tentative & (((bank.score >= confirm_score) & (hits >= min_plots)) if score_logic
                               else (hits >= cfg.confirm_m))
        bank.status[confirm] = CONFIRMED
        bank.confirmed_at[confirm] = bank.t[confirm]
        self.stats["tracks_confirmed"] += int(confirm.sum())
        observed = np.minimum(bank.n_events, cfg.confirm_n)
        hopeless = tentative & ~confirm & ((bank.score < drop_score) if score_logic
                                           else ((observed - hits) > (cfg.confirm_n - cfg.confirm_m)))
        P = bank.estimate().P
        pos_cov = P[:, self.pos[:, None], self.pos]
        too_uncertain = np.sqrt(np.maximum(max_eigenvalue_sym(pos_cov), 0)) > cfg.max_position_sigma_m
        faded = (bank.score_max - bank.score >= delete_drop) if score_logic else (bank.n_misses >= cfg.delete_misses)
        lost = (bank.status == CONFIRMED) & (faded | too_uncertain | gone)
        hopeless |= (bank.status == TENTATIVE) & gone
        self.stats["tentative_dropped"] += int(hopeless.sum())
        self.stats["tracks_deleted"] += int(lost.sum())
        bank.keep(~(hopeless | lost))

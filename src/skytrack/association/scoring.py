"""Pair scorers: the chi-square gate on ``d^2`` (spec 000 R7) with two cost rules.

* :class:`MahalanobisScorer` (``"d2"``) — cost ``d^2 = nu^T S^-1 nu``; a pair is inside when
  ``d^2 <= g_m``, the chi-square quantile at ``p_gate`` for the ``m`` components the pair's
  plot measures; leaving a track unassigned costs the gate of ``max_components``, the largest
  in use (so a track takes any gated plot rather than none).
* :class:`LogLikelihoodScorer` (``"loglik"``) — cost ``-ln N(nu; 0, S)``, same gate; leaving
  a track unassigned costs the negative log-likelihood at the gate's edge of the widest
  innovation in the window, i.e. the pair that is just inside the gate.

* :class:`LikelihoodRatioScorer` (``"llr"``) — the log-likelihood ratio of "plot j from
  track i" against "plot j false, track i missed" (:mod:`skytrack.tracker.evidence`): cost
  ``-2 (ln N(nu; 0, S) + evidence - ln(1 - P_D))`` with ``evidence = ln P_D - ln beta_j + ln(SSR
  ratio)`` given per pair by the tracker; same gate, and a pair worse than a miss is outside.
  Each track's costs are shifted by its cheapest pair (the miss then costs minus that), which
  keeps them >= 0 for the assignment and changes no choice.

All report ``d2`` and ``loglik`` as per-pair diagnostic columns.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.association.base import PairScores, Pairs
from skytrack.association.gate import gate_threshold


@dataclass
class _ChiSquareGate:
    p_gate: float = 0.9995
    threshold: float | None = None
    max_components: int = 4
    _cache: dict = field(default_factory=dict, init=False, repr=False)

    def gate(self, m: int) -> float:
        if self.threshold is not None:
            return self.threshold
        if m not in self._cache:
            self._cache[m] = float(gate_threshold(m, self.p_gate))
        return self._cache[m]

    def thresholds(self, m: np.ndarray) -> np.ndarray:
        lo, hi = int(m.min()), int(m.max())
        table = np.array([self.gate(k) for k in range(lo, hi + 1)])
        return table[m - lo]


@dataclass
class MahalanobisScorer(_ChiSquareGate):
    name = "d2"

    def score(self, innovation, pairs: Pairs, n_tracks: int) -> PairScores:
        d2 = innovation.d2
        inside = d2 <= self.thresholds(innovation.m)
        miss = self.gate(self.max_components)
        return PairScores(pairs, d2, inside, np.full(n_tracks, miss),
                          columns={"d2": d2, "loglik": innovation.loglik})


@dataclass
class LogLikelihoodScorer(_ChiSquareGate):
    name = "loglik"

    def score(self, innovation, pairs: Pairs, n_tracks: int) -> PairScores:
        g = self.thresholds(innovation.m)
        inside = innovation.d2 <= g
        cost = -innovation.loglik
        edge = cost + 0.5 * (g - innovation.d2)  # -ln N at the gate's edge, same S
        miss = np.full(n_tracks, float(edge.max()) if len(edge) else 0.0)
        return PairScores(pairs, cost, inside, miss, columns={"d2": innovation.d2, "loglik": innovation.loglik})


@dataclass
class LikelihoodRatioScorer(_ChiSquareGate):
    name = "llr"

    def score(self, innovation, pairs: Pairs, n_tracks: int, evidence: np.ndarray | None = None,
              log_miss: float = 0.0) -> PairScores:
        """``evidence`` per pair and ``log_miss`` = ln(1 - P_D) (see the module docstring); without
        evidence the ratio is against a unit clutter density and P_D = 1/2."""
        gain = innovation.loglik + (0.0 if evidence is None else evidence)
        cost = -2.0 * (gain - log_miss)
        inside = (innovation.d2 <= self.thresholds(innovation.m)) & (cost < 0.0)
        cheapest = np.zeros(n_tracks)
        np.minimum.at(cheapest, pairs.track[inside], cost[inside])
        return PairScores(pairs, cost - cheapest[pairs.track], inside, -cheapest,
                          columns={"d2": innovation.d2, "loglik": innovation.loglik, "gain": gain})

"""Spec 003's rules as scorers of the tracker's association parts: ``fuzzy``, ``crisp``, ``ml`` (``nn`` is
the Mahalanobis scorer ``d2``).

The tracker gives each gated pair its innovation and, for these scorers, the identity features of
the track and the plot (:class:`PairFeatures`: IFF status, and the transponder number: the Mode S
address when both carry one, else the Mode 3/A code).  The costs implement spec 003 R11's global
mode on the tracker's sparse assignment (:class:`~skytrack.association.gnn.GNNAssigner`): with the
rule's score ``s_ij`` (:mod:`skytrack.association.identity_rules`) and the new-object score
``s_new`` of the plot, the pair costs ``c_ij = -2 (s_ij - s_new)``; a plot left over starts a track
(cost 0) and a track left without a plot costs nothing either.  Minimising the sum of ``c`` over the
chosen pairs is R11's ``[m x (n + m)]`` problem (the ``-2 s_new`` of every plot is a constant), and a
pair with ``c > 0`` can always be replaced by its plot's new object, so only pairs with ``c <= 0``
are offered (ties go to the track, R12).  As in the likelihood-ratio scorer, each track's costs are
shifted by its cheapest pair to keep them >= 0 for the shortest-path solver.

* ``fuzzy``: ``s = ln mu = -d^2/2 + ln mu_G + ln mu_N`` (D3), ``s_new = -gamma/2`` with ``gamma`` the
  gate's chi-square quantile of the pair's components: ``c = d^2 - gamma - 2 ln(mu_G mu_N)``;
* ``crisp``: the same with the veto of R10 instead of the tables;
* ``ml``: ``s = ln p = ln N(nu; 0, S)`` (D1) inside the gate, and the new object's density is the
  local clutter density ``beta_j`` of the plot (the tracker's estimate of false plots per unit
  volume; spec 003's ``ml_new_density``): ``c = -2 (ln N - ln beta_j)``.

The feature tables are :class:`~skytrack.association.features.FeatureTables` (the paper's (15), (16)
by default).  Per-pair diagnostic columns (R13): ``d2``, ``logdet``, ``ln_mu``, ``mu_G``, ``mu_N``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.association.base import PairScores, Pairs
from skytrack.association.features import PAPER_TABLES, FeatureTables
from skytrack.association.identity_rules import LOG_2PI, RuleConfig, feature_logs
from skytrack.association.scoring import _ChiSquareGate

IDENTITY_RULES = ("fuzzy", "crisp", "ml")


@dataclass
class PairFeatures:
    """Identity of each pair's track and plot: IFF status codes and transponder numbers (-1 = none)."""

    track_iff: np.ndarray
    plot_iff: np.ndarray
    track_code: np.ndarray
    plot_code: np.ndarray

    @staticmethod
    def from_codes(track_iff, plot_iff, track_mode3a, plot_mode3a, track_mode_s, plot_mode_s) -> "PairFeatures":
        """The number compared is the Mode S address when both carry one, else the Mode 3/A code."""
        both_s = (np.asarray(track_mode_s) >= 0) & (np.asarray(plot_mode_s) >= 0)
        # Mode S addresses and Mode 3/A codes live in separate ranges: an address is offset past 4096
        track_code = np.where(both_s, np.asarray(track_mode_s, dtype=np.int64) + 4096, track_mode3a)
        plot_code = np.where(both_s, np.asarray(plot_mode_s, dtype=np.int64) + 4096, plot_mode3a)
        return PairFeatures(np.asarray(track_iff), np.asarray(plot_iff), track_code, plot_code)


@dataclass
class IdentityRuleScorer(_ChiSquareGate):
    """Spec 003's ``fuzzy``, ``crisp`` or ``ml`` rule over gated pairs (see the module docstring)."""

    rule: str = "fuzzy"
    tables: FeatureTables = field(default_factory=lambda: PAPER_TABLES)
    uses_identity = True

    def __post_init__(self) -> None:
        if self.rule not in IDENTITY_RULES:
            raise ValueError(f"identity rule must be one of {', '.join(IDENTITY_RULES)}, got {self.rule!r}")
        self._config = RuleConfig(rule=self.rule, mode="greedy", tables=self.tables)

    @property
    def name(self) -> str:
        return self.rule

    def score(self, innovation, pairs: Pairs, n_tracks: int, features: PairFeatures | None = None,
              log_new_density: np.ndarray | None = None) -> PairScores:
        """``features`` per pair (None: no identity on either side); ``log_new_density`` per pair is
        ``ln beta_j`` for ``ml`` (None: a unit density)."""
        d2 = innovation.d2
        gamma = self.thresholds(innovation.m)
        inside = d2 <= gamma
        if self.rule == "ml":
            log_new = np.zeros(len(d2)) if log_new_density is None else log_new_density
            cost = -2.0 * (innovation.loglik - log_new)
            ln_g = ln_n = np.zeros(len(d2))
        else:
            if features is None:
                ln_g = ln_n = np.zeros(len(d2))
            else:
                ln_g, ln_n = feature_logs(self._config, features.track_iff, features.plot_iff, features.track_code,
                                          features.plot_code)
            with np.errstate(invalid="ignore"):  # -inf (a veto or a 0 entry) stays +inf below
                cost = d2 - gamma - 2.0 * (ln_g + ln_n)
        inside &= cost <= 0.0
        cheapest = np.zeros(n_tracks)
        np.minimum.at(cheapest, pairs.track[inside], cost[inside])
        shifted = np.where(inside, cost - cheapest[pairs.track], np.inf)
        ln_mu = -0.5 * d2 + ln_g + ln_n
        logdet = -2.0 * innovation.loglik - d2 - innovation.m * LOG_2PI
        return PairScores(pairs, shifted, inside, -cheapest,
                          columns={"d2": d2, "loglik": innovation.loglik, "logdet": logdet, "ln_mu": ln_mu,
                                   "mu_G": np.exp(ln_g), "mu_N": np.exp(ln_n)})

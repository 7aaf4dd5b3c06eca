"""Association rules of spec 003: maximum likelihood, fuzzy membership, nearest neighbour, crisp.

Every hypothesis "plot k belongs to track r" is scored in the log domain from the pair's
residual ``nu`` and innovation covariance ``S`` (R7) and the identity features (R8,
:mod:`skytrack.association.features`):

* ``d^2 = nu^T S^-1 nu = |L^-1 nu|^2`` and ``ln det S = 2 sum ln L_ii`` from one batched
  Cholesky factor ``S = L L^T`` per track (:func:`whitening`), shared by all its plots; ``innovation_cov="diagonal"`` replaces ``S`` by ``diag(S)`` in both (the
  paper's literal product forms (9), (13); gap G3);
* (D1) ``ln p = -d^2/2 - n_c ln(2 pi)/2 - ln det S / 2`` — the Gaussian likelihood (8);
* (D2) ``ln mu_coord = -d^2/2`` — the coordinate membership (14);
* (D3) ``ln mu = ln mu_coord + ln mu_G + ln mu_N`` — the membership (13).

The new-object hypothesis (R9, gap G4) scores ``ln mu_new = -gamma/2`` with ``gamma`` the
chi-square quantile of ``n_c`` degrees of freedom at ``P_G`` (default 0.99); the plot's
features do not enter it.  The rules (R10), each choosing a track or ``new`` per plot:

* ``ml`` (8)-(11): score ``ln p``; tracks with ``d^2 > gamma`` are no hypotheses (a project
  gate); ``new`` when none is left, or with ``ml_new_density`` ``lambda > 0`` the literal
  argmax against a constant new-object density (score ``ln lambda``);
* ``fuzzy`` (12)-(18): score ``ln mu``; ``new`` iff every track scores below ``ln mu_new``;
* ``nn``: ``fuzzy`` with every feature factor 1 (the Mahalanobis nearest neighbour, D4);
* ``crisp``: ``nn`` with a veto (:func:`crisp_veto`: a definite status or a number that
  differs from the track's forbids the pair) — the same decisions as ``fuzzy`` with the 0/1
  tables :data:`~skytrack.association.features.CRISP_TABLES` (TV12).

Processing modes (R11): ``greedy`` decides each plot alone (:func:`decide_greedy` on a fixed
score matrix; the literal paper's tracker also updates the chosen track before the next plot)
and ``global`` solves one assignment per scan (:func:`decide_global`, cost matrix
``[m x (n + m)]`` with the new-object diagonal, ``scipy.optimize.linear_sum_assignment``).
Determinism (R12): on an exact tie a track beats ``new`` and the lower track id wins.
:func:`diagnostics` gives the per-(plot, hypothesis) rows of R13.
"""

from __future__ import annotations

import math
from functools import lru_cache
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from skytrack.association.features import CRISP_TABLES, PAPER_TABLES, UNDETERMINED, UNIT_TABLES, FeatureTables
from skytrack.core.chi2 import chi2_quantile

RULES = ("ml", "fuzzy", "nn", "crisp")
MODES = ("greedy", "global")
INNOVATION_COVARIANCES = ("full", "diagonal")
LOG_2PI = math.log(2.0 * math.pi)
#: the choice of a plot that starts a new object
NEW = -1


@lru_cache(maxsize=64)
def gate_gamma(n_c: int, p_gate: float = 0.99) -> float:
    """``gamma``: the chi-square quantile of ``n_c`` degrees of freedom at ``p_gate`` (R9)."""
    return float(chi2_quantile(p_gate, n_c))


@dataclass(frozen=True)
class RuleConfig:
    """One association rule and its settings (spec 003 §4 defaults)."""

    rule: str = "fuzzy"
    mode: str = "global"
    p_gate: float = 0.99
    innovation_cov: str = "full"
    tables: FeatureTables = field(default_factory=lambda: PAPER_TABLES)
    ml_new_density: float = 0.0

    def __post_init__(self) -> None:
        for name, allowed in (("rule", RULES), ("mode", MODES), ("innovation_cov", INNOVATION_COVARIANCES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"association {name} must be one of {', '.join(allowed)}, got {getattr(self, name)!r}")
        if not 0.0 < self.p_gate < 1.0:
            raise ValueError(f"p_gate must be in (0, 1), got {self.p_gate!r}")
        if self.ml_new_density < 0.0:
            raise ValueError(f"ml_new_density must be >= 0, got {self.ml_new_density!r}")
        if self.rule == "ml" and self.mode == "global" and self.ml_new_density == 0.0:
            raise ValueError("rule 'ml' in mode 'global' needs ml_new_density > 0: without it the new-object "
                             "hypothesis has no finite score (spec 003 R11)")

    @property
    def effective_tables(self) -> FeatureTables:
        """The tables the rule scores with: the configured ones for ``fuzzy``, unit or 0/1 tables otherwise."""
        if self.rule == "crisp":
            return CRISP_TABLES
        return self.tables if self.rule == "fuzzy" else UNIT_TABLES


def crisp_veto(track_iff, plot_iff, track_code, plot_code) -> np.ndarray:
    """The ``crisp`` rule's veto (R10): a definite status (friend / foe) on both sides that differs,
    or a number on both sides that differs."""
    h_g, z_g = np.asarray(track_iff), np.asarray(plot_iff)
    h_n, z_n = np.asarray(track_code), np.asarray(plot_code)
    definite = (h_g >= 0) & (h_g != UNDETERMINED) & (z_g >= 0) & (z_g != UNDETERMINED)
    return (definite & (h_g != z_g)) | ((h_n >= 0) & (z_n >= 0) & (h_n != z_n))


def feature_logs(config: RuleConfig, track_iff, plot_iff, track_code, plot_code) -> tuple[np.ndarray, np.ndarray]:
    """``(ln mu_G, ln mu_N)`` per pair as the rule uses them: the tables for ``fuzzy``, 0 for
    ``nn`` and ``ml``, 0 or ``-inf`` (the veto, in ``ln mu_G``) for ``crisp``."""
    shape = np.broadcast(np.asarray(track_iff), np.asarray(plot_iff)).shape
    if config.rule == "fuzzy":
        return (config.tables.log_mu_g(track_iff, plot_iff), config.tables.log_mu_n(track_code, plot_code))
    zero = np.zeros(shape)
    if config.rule == "crisp":
        return np.where(crisp_veto(track_iff, plot_iff, track_code, plot_code), -np.inf, 0.0), zero
    return zero, zero


def whitening(S: np.ndarray, innovation_cov: str = "full",
              track_id: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(W, ln det S)`` per covariance ``S[K, m, m]`` with ``W = L^-1`` from the Cholesky factor
    ``S = L L^T`` (R7), so that ``d^2 = |W nu|^2`` for any residual of that track: one factorisation
    per track serves all its plots.  ``innovation_cov="diagonal"`` uses ``diag(S)``.  A covariance
    that is not positive definite is an error naming its track (``track_id``, else its row)."""
    S = np.asarray(S, dtype=float)
    if innovation_cov == "diagonal":
        var = np.diagonal(S, axis1=-2, axis2=-1)
        bad = ~(var > 0.0).all(axis=-1)
        if bad.any():
            _not_positive_definite(np.flatnonzero(bad)[0], track_id)
        W = np.zeros(S.shape)
        idx = np.arange(S.shape[-1])
        W[..., idx, idx] = 1.0 / np.sqrt(var)
        return W, np.sum(np.log(var), axis=-1)
    if innovation_cov != "full":
        raise ValueError(f"innovation_cov must be one of {', '.join(INNOVATION_COVARIANCES)}, got {innovation_cov!r}")
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        rows = [k for k in range(len(S)) if not _is_positive_definite(S[k])]
        _not_positive_definite(rows[0] if rows else 0, track_id)
    eye = np.broadcast_to(np.eye(S.shape[-1]), S.shape)
    W = np.linalg.solve(L, eye)
    return W, 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)


def mahalanobis(W: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``d^2 = |W nu|^2`` with ``W`` of :func:`whitening` (broadcast over leading axes)."""
    y = np.einsum("...ij,...j->...i", W, nu)
    return np.einsum("...i,...i->...", y, y)


def coordinate_terms(nu: np.ndarray, S: np.ndarray, innovation_cov: str = "full",
                     track_id: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``d^2`` and ``ln det S`` per pair ``nu[K, m]``, ``S[K, m, m]`` (R7; :func:`whitening`)."""
    W, logdet = whitening(S, innovation_cov, track_id)
    return mahalanobis(W, np.asarray(nu, dtype=float)), logdet


def _is_positive_definite(S: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return False
    return True


def _not_positive_definite(row: int, track_id: np.ndarray | None):
    who = f"track {int(track_id[row])}" if track_id is not None else f"pair {int(row)}"
    raise ValueError(f"innovation covariance of {who} is not positive definite")


@dataclass
class RuleScores:
    """Per-pair scores of one rule: ``score`` (the rule's log score), ``hypothesis`` (the pair
    takes part in the decision) and the R13 columns."""

    score: np.ndarray
    hypothesis: np.ndarray
    columns: dict[str, np.ndarray]


def score_pairs(config: RuleConfig, d2: np.ndarray, logdet: np.ndarray, n_c: np.ndarray | int,
                log_mu_g: np.ndarray | None = None, log_mu_n: np.ndarray | None = None,
                log_mu_extra: np.ndarray | None = None) -> RuleScores:
    """Scores of pairs from their coordinate terms and feature log-memberships (R7-R10).

    ``log_mu_g`` / ``log_mu_n`` come from :func:`feature_logs` (or, the same numbers, from the
    rule's :attr:`RuleConfig.effective_tables`; None = factor 1).  A pair is a hypothesis when
    ``ml``'s gate ``d^2 <= gamma`` holds, or, for the membership rules, when its score reaches
    ``ln mu_new`` (a pair below it can never beat the plot's own new object: R11's lossless
    pruning)."""
    d2 = np.asarray(d2, dtype=float)
    n_c = np.broadcast_to(np.asarray(n_c), d2.shape)
    zero = np.zeros_like(d2)
    ln_g = zero if log_mu_g is None else np.asarray(log_mu_g, dtype=float)
    ln_n = zero if log_mu_n is None else np.asarray(log_mu_n, dtype=float)
    ln_extra = zero if log_mu_extra is None else np.asarray(log_mu_extra, dtype=float)
    ln_p = -0.5 * (d2 + n_c * LOG_2PI + logdet)
    ln_mu_coord = -0.5 * d2
    ln_mu = ln_mu_coord + ln_g + ln_n + ln_extra
    gamma = gamma_of(n_c, config.p_gate)
    if config.rule == "ml":
        score, hypothesis = ln_p, d2 <= gamma
    else:
        score = ln_mu
        hypothesis = score >= -0.5 * gamma
    columns = {"d2": d2, "logdet": np.asarray(logdet, dtype=float), "ln_p": ln_p, "ln_mu_coord": ln_mu_coord,
               "mu_G": np.exp(ln_g), "mu_N": np.exp(ln_n), "ln_mu": ln_mu}
    return RuleScores(score, hypothesis, columns)


def gamma_of(n_c: np.ndarray | int, p_gate: float) -> np.ndarray:
    """``gamma`` per entry of ``n_c``."""
    n_c = np.asarray(n_c)
    if n_c.size and (n_c == n_c.flat[0]).all():
        return np.full(n_c.shape, gate_gamma(int(n_c.flat[0]), float(p_gate)))
    return np.asarray(chi2_quantile(p_gate, n_c), dtype=float)


def new_object_score(config: RuleConfig, n_c: np.ndarray | int) -> np.ndarray:
    """Score of the new-object hypothesis per plot: ``ln mu_new = -gamma/2`` for the membership
    rules (R9), ``ln lambda_new`` for ``ml`` (``-inf``, i.e. "only when no track gates", if 0)."""
    n_c = np.asarray(n_c)
    if config.rule == "ml":
        value = math.log(config.ml_new_density) if config.ml_new_density > 0 else -math.inf
        return np.full(n_c.shape, value)
    return -0.5 * gamma_of(n_c, config.p_gate)


def decide_greedy(score: np.ndarray, hypothesis: np.ndarray, new_score: np.ndarray,
                  track_id: np.ndarray | None = None) -> np.ndarray:
    """Each plot alone on a fixed ``[m, n]`` score matrix: the best hypothesis track, or :data:`NEW`
    when none is left or ``new`` scores strictly higher; ties go to the lower track id (R12)."""
    score = np.asarray(score, dtype=float)
    m, n = score.shape
    if n == 0:
        return np.full(m, NEW)
    order = np.argsort(np.arange(n) if track_id is None else np.asarray(track_id), kind="stable")
    masked = np.where(hypothesis, score, -np.inf)[:, order]
    best = np.argmax(masked, axis=1)  # first maximum: the lowest track id among equals
    best_score = masked[np.arange(m), best]
    take = np.isfinite(best_score) & (best_score >= new_score)
    return np.where(take, order[best], NEW)


def decide_global(score: np.ndarray, hypothesis: np.ndarray, new_score: np.ndarray) -> np.ndarray:
    """One assignment per scan (R11 global): each plot to at most one track and each track to at
    most one plot, or :data:`NEW`, maximising the total score.

    Cost matrix ``[m x (n + m)]``: ``-score`` on hypothesis pairs, ``-new_score`` on the
    new-object diagonal, ``+inf`` elsewhere."""
    score = np.asarray(score, dtype=float)
    m, n = score.shape
    new_score = np.broadcast_to(np.asarray(new_score, dtype=float), (m,))
    if not np.isfinite(new_score).all():
        raise ValueError("global assignment needs a finite new-object score for every plot (rule 'ml' needs "
                         "ml_new_density > 0)")
    cost = np.full((m, n + m), np.inf)
    cost[:, :n] = np.where(hypothesis & (score >= new_score[:, None]), -score, np.inf)
    cost[np.arange(m), n + np.arange(m)] = -new_score
    rows, cols = linear_sum_assignment(cost)
    choice = np.full(m, NEW)
    real = cols < n
    choice[rows[real]] = cols[real]
    return choice


def diagnostics(plot: np.ndarray, track_id: np.ndarray, scores: RuleScores, chosen: np.ndarray) -> dict[str, np.ndarray]:
    """R13: one row per (plot, hypothesis) with ``track_id``, the R13 columns and the ``chosen`` flag."""
    return {"plot": np.asarray(plot), "track_id": np.asarray(track_id), **scores.columns,
            "score": scores.score, "hypothesis": scores.hypothesis, "chosen": np.asarray(chosen, dtype=bool)}

"""The tracker of spec 003's studies, batched over Monte Carlo runs: airborne EKF, identity features,
interrogation policy, and the association rules in greedy or global mode.

Every run of a sweep is a row: tracks are slots of arrays ``x[R, K, 6]``, ``P[R, K, 6, 6]``
(``K`` grows as runs need more), and a scan is processed for all runs at once.

Per scan (all plots of a scan share its time, R17):

1. every live track is predicted to the scan time (CV, R5: ``F``, ``Q`` of the white-acceleration
   density ``q``);
2. interrogation (R16), decided against the tracks as predicted at scan start: policy ``track``
   requests a plot's IFF iff no track gates it (``d^2 <= gamma``) or its smallest-``d^2`` gating
   track is undetermined; ``always``; ``never``.  A requested plot carries the reply its object
   would give (drawn by the responder for every plot, :func:`skytrack.sim.iff.respond`);
3. association (R10, R11) with the rule's scores (:mod:`skytrack.association.identity_rules`):
   ``greedy`` takes the plots one at a time in their emission order, scores each against every
   live track (including tracks updated or started by earlier plots of the scan), and updates the
   chosen track (or starts one, R6) before the next plot; ``global`` scores every plot against the
   pre-scan tracks and solves one assignment per run (only runs where two plots want the same
   track need the solver: elsewhere each plot's own best choice is the optimum);
4. the chosen tracks are updated (EKF, Joseph form, R5) and take the plot's features (R14: the
   latest definite status wins, a number replaces the old one); a plot choosing ``new`` starts a
   track from itself (R6);
5. life cycle (R15): every live track is a hypothesis (no tentative stage); a track is deleted
   after ``max_misses`` consecutive scans without a plot.

Pairs with the object overhead of the own-ship (R3: ``rho < 1e-6 D``) are left out of the
association and counted (``degenerate_pairs``).  Ties (R12): a track beats ``new`` and the
lower track id wins.  With ``diagnostics=True`` every scoring is kept as R13's rows: per
(plot, hypothesis) the track id (-1 for the new object), ``d2``, ``logdet``, ``ln_p``,
``ln_mu_coord``, ``mu_G``, ``mu_N``, ``ln_mu`` and whether it was chosen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from skytrack.association.features import UNDETERMINED
from skytrack.association.identity_rules import (NEW, RuleConfig, decide_global, feature_logs, gate_gamma,
                                                 mahalanobis, new_object_score, score_pairs, whitening)
from skytrack.filters.airborne_ekf import DEFAULT_SIGMA_V0, initiate_from_plot, predict
from skytrack.filters.ekf import update as ekf_update_arrays
from skytrack.models.airborne import airborne_measurement, degenerate_pairs, wrap_residual

IFF_POLICIES = ("track", "always", "never")
#: free slots are evaluated at this offset from the own-ship (their results are masked)
_PARKED_OFFSET = np.array([1.0e5, 0.0, 0.0])


@dataclass(frozen=True)
class PaperTrackerConfig:
    """Settings of the studies' tracker (spec 003 §6 E4 defaults)."""

    rule: RuleConfig = field(default_factory=RuleConfig)
    q: float = 25.0
    sigma_v0: float = DEFAULT_SIGMA_V0
    max_misses: int = 3
    iff_policy: str = "track"

    def __post_init__(self) -> None:
        if self.iff_policy not in IFF_POLICIES:
            raise ValueError(f"iff_policy must be one of {', '.join(IFF_POLICIES)}, got {self.iff_policy!r}")
        if self.max_misses < 1:
            raise ValueError(f"max_misses must be >= 1, got {self.max_misses}")
        if not self.q >= 0.0:
            raise ValueError(f"q must be >= 0, got {self.q}")


@dataclass
class RunPlots:
    """Plots of R runs of S scans with up to M plots per scan (slot order = emission order).

    ``z[R, S, M, m]``, ``valid[R, S, M]``, ``own_p`` / ``own_v`` ``[R, S, 3]`` (the own-ship at
    the scan time), ``time[S]``, ``noise[m, m]`` and the reply each plot would carry if it were
    interrogated: ``reply_iff[R, S, M]`` (-1 none) and ``reply_code[R, S, M]`` (-1 none)."""

    time: np.ndarray
    z: np.ndarray
    valid: np.ndarray
    own_p: np.ndarray
    own_v: np.ndarray
    noise: np.ndarray
    reply_iff: np.ndarray
    reply_code: np.ndarray


@dataclass
class RunDecisions:
    """What the tracker did with each plot ``[R, S, M]``: the track id it went to (a new track's
    id when it started one; -1 for an empty slot), whether it was interrogated, and the IFF it
    carried; ``track_iff`` / ``track_code`` are each plot's track's features after the plot."""

    track_id: np.ndarray
    started: np.ndarray
    requested: np.ndarray
    plot_iff: np.ndarray
    plot_code: np.ndarray
    track_iff: np.ndarray
    track_code: np.ndarray
    degenerate_pairs: int = 0
    #: R13 rows (with ``diagnostics=True``): one per (plot, hypothesis), the new object as track -1
    diagnostics: pd.DataFrame | None = None


class _Bank:
    """Track slots of all runs."""

    def __init__(self, runs: int, capacity: int = 8) -> None:
        self.x = np.zeros((runs, capacity, 6))
        self.P = np.tile(np.eye(6), (runs, capacity, 1, 1))
        self.alive = np.zeros((runs, capacity), dtype=bool)
        self.track_id = np.full((runs, capacity), -1, dtype=np.int64)
        self.iff = np.full((runs, capacity), UNDETERMINED, dtype=np.int64)
        self.code = np.full((runs, capacity), -1, dtype=np.int64)
        self.misses = np.zeros((runs, capacity), dtype=np.int64)
        self.hit = np.zeros((runs, capacity), dtype=bool)
        self.born = np.zeros((runs, capacity), dtype=bool)
        self.next_id = np.ones(runs, dtype=np.int64)

    def allocate(self, runs: np.ndarray) -> np.ndarray:
        """One free slot per entry of ``runs`` (a run may appear several times: distinct slots),
        growing the arrays until every run has room."""
        order = np.argsort(runs, kind="stable")
        sorted_runs = runs[order]
        first = np.searchsorted(sorted_runs, sorted_runs, side="left")
        rank = np.empty(len(runs), dtype=np.int64)
        rank[order] = np.arange(len(runs)) - first
        while (self.alive[runs].sum(axis=1) + rank >= self.alive.shape[1]).any():
            self._grow()
        free_first = np.argsort(self.alive[runs], axis=1, kind="stable")
        return free_first[np.arange(len(runs)), rank]

    def _grow(self) -> None:
        runs, capacity = self.alive.shape
        for name, fill in (("x", None), ("P", None), ("alive", False), ("track_id", -1), ("iff", UNDETERMINED),
                           ("code", -1), ("misses", 0), ("hit", False), ("born", False)):
            old = getattr(self, name)
            if name == "x":
                extra = np.zeros((runs, capacity, 6))
            elif name == "P":
                extra = np.tile(np.eye(6), (runs, capacity, 1, 1))
            else:
                extra = np.full((runs, capacity), fill, dtype=old.dtype)
            setattr(self, name, np.concatenate([old, extra], axis=1))


class PaperTracker:
    """Runs :class:`PaperTrackerConfig` over a batch of runs (see the module docstring);
    ``diagnostics=True`` also returns R13's per-(plot, hypothesis) rows."""

    def __init__(self, config: PaperTrackerConfig, diagnostics: bool = False) -> None:
        self.config = config
        self.diagnostics = diagnostics

    def run(self, plots: RunPlots) -> RunDecisions:
        config = self.config
        runs, scans, slots = plots.valid.shape
        n_c = plots.z.shape[-1]
        bank = _Bank(runs)
        shape = (runs, scans, slots)
        out = RunDecisions(np.full(shape, -1, np.int64), np.zeros(shape, bool), np.zeros(shape, bool),
                           np.full(shape, -1, np.int64), np.full(shape, -1, np.int64),
                           np.full(shape, -1, np.int64), np.full(shape, -1, np.int64))
        self._gamma = gate_gamma(n_c, config.rule.p_gate)
        self._new_score = float(new_object_score(config.rule, n_c))
        self._noise = np.asarray(plots.noise, dtype=float)
        self._h = np.zeros((0, 0, n_c))
        self._rows: list[pd.DataFrame] = []
        for k in range(scans):
            if k:
                dt = plots.time[k] - plots.time[k - 1]
                flat_x, flat_P = predict(bank.x.reshape(-1, 6), bank.P.reshape(-1, 6, 6), dt, config.q)
                live = bank.alive.reshape(-1)
                bank.x.reshape(-1, 6)[live] = flat_x[live]
                bank.P.reshape(-1, 6, 6)[live] = flat_P[live]
            bank.hit[:] = False
            bank.born[:] = False
            z, valid = plots.z[:, k], plots.valid[:, k]
            own_p, own_v = plots.own_p[:, k], plots.own_v[:, k]
            self._refresh(bank, own_p, own_v)
            terms = self._pair_terms(z)
            requested = self._interrogate(bank, terms, valid)
            iff = np.where(requested, plots.reply_iff[:, k], -1)
            code = np.where(requested, plots.reply_code[:, k], -1)
            out.requested[:, k], out.plot_iff[:, k], out.plot_code[:, k] = requested, iff, code
            if config.rule.mode == "greedy":
                for j in range(slots):
                    if j:
                        terms = self._pair_terms(z[:, j:j + 1])
                    else:
                        terms = tuple(a[:, :1] for a in terms)
                    score, hypothesis = self._scores(bank, terms, iff[:, j:j + 1], code[:, j:j + 1],
                                                     valid[:, j:j + 1], out)
                    choice = self._best(bank, score[:, 0], hypothesis[:, 0])
                    if self.diagnostics:
                        self._record(bank, k, np.array([j]), choice[:, None], valid[:, j:j + 1])
                    runs_j = np.flatnonzero(valid[:, j])
                    changed = self._apply(bank, k, runs_j, np.full(len(runs_j), j), choice[runs_j], z, own_p, own_v,
                                          iff, code, out)
                    self._refresh(bank, own_p, own_v, *changed)  # the next plot sees the updated tracks
            else:
                score, hypothesis = self._scores(bank, terms, iff, code, valid, out)
                choices = self._global(bank, score, hypothesis)
                if self.diagnostics:
                    self._record(bank, k, np.arange(slots), choices, valid)
                runs_k, plots_k = np.nonzero(valid)  # sorted by run, as _apply needs
                self._apply(bank, k, runs_k, plots_k, choices[runs_k, plots_k], z, own_p, own_v, iff, code, out)
            missed = bank.alive & ~bank.hit & ~bank.born
            bank.misses[missed] += 1
            bank.alive &= bank.misses < config.max_misses
        if self.diagnostics:
            out.diagnostics = pd.concat(self._rows, ignore_index=True) if self._rows else None
        return out

    def _record(self, bank: _Bank, k: int, slots: np.ndarray, choice: np.ndarray, valid: np.ndarray) -> None:
        """R13: the last scoring's rows for the live tracks and the new object, with the choice."""
        columns, usable = self._last_columns, self._last_usable
        run, plot, slot = np.nonzero(usable & valid[:, :, None])
        rows = {"run": run, "scan": np.full(len(run), k), "plot_slot": slots[plot], "track_id": bank.track_id[run, slot],
                **{name: values[run, plot, slot] for name, values in columns.items()},
                "chosen": choice[run, plot] == slot}
        new_run, new_plot = np.nonzero(valid)
        nan = np.full(len(new_run), np.nan)
        new = {"run": new_run, "scan": np.full(len(new_run), k), "plot_slot": slots[new_plot],
               "track_id": np.full(len(new_run), -1), **{name: nan for name in columns},
               "chosen": choice[new_run, new_plot] == NEW}
        new["ln_mu"] = np.full(len(new_run), self._new_score)
        self._rows += [pd.DataFrame(rows), pd.DataFrame(new)]

    # ------------------------------------------------------------------ scoring

    def _refresh(self, bank: _Bank, own_p: np.ndarray, own_v: np.ndarray, runs: np.ndarray | None = None,
                 slots: np.ndarray | None = None) -> None:
        """Per track slot: predicted measurement ``h``, the whitening ``W`` of its innovation covariance
        and ``ln det S`` (one Cholesky factor per track, R7), and whether it may be a hypothesis (live,
        not overhead of the own-ship, R3).  All slots, or only ``(runs, slots)``."""
        m = self._noise.shape[0]
        if runs is None or self._h.shape[1] != bank.alive.shape[1]:
            runs, slots = (a.reshape(-1) for a in np.indices(bank.alive.shape))
            capacity = bank.alive.shape
            self._h = np.zeros(capacity + (m,))
            self._W = np.zeros(capacity + (m, m))
            self._logdet = np.zeros(capacity)
            self._usable = np.zeros(capacity, dtype=bool)
        if len(runs) == 0:
            return
        x, P = bank.x[runs, slots], bank.P[runs, slots]
        p_o, v_o = own_p[runs], own_v[runs]
        usable = bank.alive[runs, slots] & ~degenerate_pairs(x, p_o)
        parked = np.concatenate([p_o + _PARKED_OFFSET, np.zeros_like(p_o)], axis=1)
        h, H = airborne_measurement(np.where(usable[:, None], x, parked), p_o, v_o, with_range_rate=m == 4)
        S = np.where(usable[:, None, None], H @ P @ np.swapaxes(H, -1, -2) + self._noise, np.eye(m))
        W, logdet = whitening(S, self.config.rule.innovation_cov, bank.track_id[runs, slots])
        self._h[runs, slots], self._W[runs, slots] = h, W
        self._logdet[runs, slots], self._usable[runs, slots] = logdet, usable

    def _pair_terms(self, z: np.ndarray):
        """``d^2``, ``ln det S`` ``[R, M, K]`` of every (plot, track slot) pair and whether the pair
        may be a hypothesis, from the per-track terms of :meth:`_refresh`."""
        nu = wrap_residual(z[:, :, None, :] - self._h[:, None])
        d2 = mahalanobis(self._W[:, None], nu)
        return d2, np.broadcast_to(self._logdet[:, None], d2.shape), np.broadcast_to(self._usable[:, None], d2.shape)

    def _scores(self, bank: _Bank, terms, iff: np.ndarray, code: np.ndarray, valid: np.ndarray, out: RunDecisions):
        d2, logdet, usable = terms
        out.degenerate_pairs += int((bank.alive[:, None, :] & ~usable & valid[:, :, None]).sum())
        ln_g, ln_n = feature_logs(self.config.rule, bank.iff[:, None, :], iff[:, :, None], bank.code[:, None, :],
                                  code[:, :, None])
        scores = score_pairs(self.config.rule, d2, logdet, self._noise.shape[0], ln_g, ln_n)
        if self.diagnostics:
            self._last_columns = {name: np.broadcast_to(values, d2.shape) for name, values in scores.columns.items()}
            self._last_usable = usable & bank.alive[:, None, :]
        return scores.score, scores.hypothesis & usable & valid[:, :, None]

    def _interrogate(self, bank: _Bank, terms, valid: np.ndarray) -> np.ndarray:
        policy = self.config.iff_policy
        if policy == "always":
            return valid.copy()
        if policy == "never":
            return np.zeros_like(valid)
        d2, _, usable = terms
        gated = usable & (d2 <= self._gamma)
        nearest = np.argmin(np.where(gated, d2, np.inf), axis=2)
        nearest_iff = np.take_along_axis(np.broadcast_to(bank.iff[:, None, :], d2.shape), nearest[..., None], 2)[..., 0]
        return valid & (~gated.any(axis=2) | (nearest_iff == UNDETERMINED))

    def _best(self, bank: _Bank, score: np.ndarray, hypothesis: np.ndarray) -> np.ndarray:
        """Each run's choice for one plot: the best hypothesis slot (ties: lower track id) or NEW."""
        masked = np.where(hypothesis, score, -np.inf)
        best = masked.max(axis=1)
        tied = hypothesis & (masked == best[:, None])
        slot = np.argmin(np.where(tied, bank.track_id, np.iinfo(np.int64).max), axis=1)
        take = np.isfinite(best) & (best >= self._new_score)
        return np.where(take, slot, NEW)

    def _global(self, bank: _Bank, score: np.ndarray, hypothesis: np.ndarray) -> np.ndarray:
        """Choices ``[R, M]``: each plot's own best choice, and one assignment where two collide."""
        runs, slots, _ = score.shape
        choices = np.stack([self._best(bank, score[:, j], hypothesis[:, j]) for j in range(slots)], axis=1)
        taken = np.where(choices >= 0, choices, -1 - np.arange(slots))
        collide = np.flatnonzero([len(np.unique(row)) < slots for row in taken]) if slots > 1 else []
        for r in collide:
            order = np.argsort(bank.track_id[r], kind="stable")  # lower ids first: the solver's ties go to them
            columns = order[bank.alive[r, order]]
            new = np.full(slots, self._new_score)
            choice = decide_global(score[r][:, columns], hypothesis[r][:, columns], new)
            choices[r] = np.where(choice == NEW, NEW, columns[np.maximum(choice, 0)])
        return choices

    # ------------------------------------------------------------------ updates

    def _apply(self, bank: _Bank, k: int, runs: np.ndarray, plots: np.ndarray, choice: np.ndarray, z: np.ndarray,
               own_p: np.ndarray, own_v: np.ndarray, iff: np.ndarray, code: np.ndarray,
               out: RunDecisions) -> tuple[np.ndarray, np.ndarray]:
        """Apply the decisions ``choice`` (a track slot or NEW) of plots ``(runs, plots)`` of scan ``k``
        (``z``, ``iff``, ``code`` ``[R, M, ...]``): update the chosen tracks or start new ones, and record
        the decisions.  Each track takes at most one of these plots.  Returns the (runs, slots) changed."""
        update = choice >= 0
        slot = np.where(update, choice, 0)
        start = np.flatnonzero(~update)
        if len(start):
            slot[start] = bank.allocate(runs[start])
        r, j, s = runs[update], plots[update], slot[update]
        if len(r):
            bank.x[r, s], bank.P[r, s] = self._update(bank.x[r, s], bank.P[r, s], z[r, j], own_p[r], own_v[r])
            bank.misses[r, s] = 0
            bank.hit[r, s] = True
        if len(start):
            r, j, s = runs[start], plots[start], slot[start]
            bank.x[r, s], bank.P[r, s] = initiate_from_plot(z[r, j], own_p[r], own_v[r] if z.shape[-1] == 4 else None,
                                                            self._noise, self.config.sigma_v0)
            bank.alive[r, s] = True
            bank.born[r, s] = True
            bank.misses[r, s] = 0
            bank.track_id[r, s] = bank.next_id[r] + np.arange(len(r)) - np.searchsorted(r, r)  # r is sorted
            np.add.at(bank.next_id, r, 1)
            bank.iff[r, s] = UNDETERMINED
            bank.code[r, s] = -1
            out.started[r, k, j] = True
        self._take_features(bank, runs, slot, iff[runs, plots], code[runs, plots])
        out.track_id[runs, k, plots] = bank.track_id[runs, slot]
        out.track_iff[runs, k, plots] = bank.iff[runs, slot]
        out.track_code[runs, k, plots] = bank.code[runs, slot]
        return runs, slot

    def _update(self, x, P, z, own_p, own_v):
        h, H = airborne_measurement(x, own_p, own_v, with_range_rate=z.shape[-1] == 4)
        result = ekf_update_arrays(x, P, wrap_residual(z - h), H, self._noise)
        return result.x, result.P

    @staticmethod
    def _take_features(bank: _Bank, runs: np.ndarray, slot: np.ndarray, iff: np.ndarray, code: np.ndarray) -> None:
        """R14: the latest definite status wins; a number replaces the old one."""
        definite = (iff >= 0) & (iff != UNDETERMINED)
        bank.iff[runs[definite], slot[definite]] = iff[definite]
        has_code = code >= 0
        bank.code[runs[has_code], slot[has_code]] = code[has_code]

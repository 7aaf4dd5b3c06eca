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
lower track id wins.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from skytrack.association.features import UNDETERMINED
from skytrack.association.identity_rules import (NEW, RuleConfig, coordinate_terms, decide_global, feature_logs,
                                                 gate_gamma, new_object_score, score_pairs)
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

    def free_slots(self, runs: np.ndarray) -> np.ndarray:
        """A free slot in each of ``runs`` (distinct runs), growing the arrays when one is full."""
        full = self.alive[runs].all(axis=1)
        if full.any():
            self._grow()
        return np.argmin(self.alive[runs], axis=1)

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
    """Runs :class:`PaperTrackerConfig` over a batch of runs (see the module docstring)."""

    def __init__(self, config: PaperTrackerConfig) -> None:
        self.config = config

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
            terms = self._pair_terms(bank, z, own_p, own_v, out)
            requested = self._interrogate(bank, terms, valid)
            iff = np.where(requested, plots.reply_iff[:, k], -1)
            code = np.where(requested, plots.reply_code[:, k], -1)
            out.requested[:, k], out.plot_iff[:, k], out.plot_code[:, k] = requested, iff, code
            if config.rule.mode == "greedy":
                for j in range(slots):
                    if j:
                        terms = self._pair_terms(bank, z[:, j:j + 1], own_p, own_v, out)
                        score, hypothesis = self._scores(bank, terms, iff[:, j:j + 1], code[:, j:j + 1])
                    else:
                        score, hypothesis = self._scores(bank, terms, iff, code)
                        score, hypothesis = score[:, :1], hypothesis[:, :1]
                    choice = self._best(bank, score[:, 0], hypothesis[:, 0] & valid[:, j, None])
                    self._apply(bank, k, j, choice, valid[:, j], z[:, j], own_p, own_v, iff[:, j], code[:, j], out)
            else:
                score, hypothesis = self._scores(bank, terms, iff, code)
                hypothesis &= valid[:, :, None]
                choices = self._global(bank, score, hypothesis)
                for j in range(slots):
                    self._apply(bank, k, j, choices[:, j], valid[:, j], z[:, j], own_p, own_v, iff[:, j], code[:, j],
                                out)
            missed = bank.alive & ~bank.hit & ~bank.born
            bank.misses[missed] += 1
            bank.alive &= bank.misses < config.max_misses
        return out

    # ------------------------------------------------------------------ scoring

    def _pair_terms(self, bank: _Bank, z: np.ndarray, own_p: np.ndarray, own_v: np.ndarray, out: RunDecisions):
        """``d^2``, ``ln det S`` ``[R, M, K]`` of every (plot, track slot) pair and the pairs that may
        be hypotheses (live track, not overhead of the own-ship)."""
        runs, capacity = bank.alive.shape
        slots, m = z.shape[1], z.shape[-1]
        x = bank.x.reshape(-1, 6)
        p_o = np.repeat(own_p, capacity, axis=0)
        v_o = np.repeat(own_v, capacity, axis=0)
        overhead = degenerate_pairs(x, p_o)
        usable = bank.alive.reshape(-1) & ~overhead
        out.degenerate_pairs += int((bank.alive.reshape(-1) & overhead).sum()) * slots
        parked = np.concatenate([p_o + _PARKED_OFFSET, np.zeros_like(p_o)], axis=1)
        x_eval = np.where(usable[:, None], x, parked)
        h, H = airborne_measurement(x_eval, p_o, v_o, with_range_rate=m == 4)
        S = H @ bank.P.reshape(-1, 6, 6) @ np.swapaxes(H, -1, -2) + self._noise
        S = np.where(usable[:, None, None], S, np.eye(m))
        nu = wrap_residual(z[:, :, None, :] - h.reshape(runs, 1, capacity, m))
        d2, logdet = coordinate_terms(nu.reshape(-1, m), np.broadcast_to(
            S.reshape(runs, 1, capacity, m, m), (runs, slots, capacity, m, m)).reshape(-1, m, m),
            self.config.rule.innovation_cov)
        shape = (runs, slots, capacity)
        return d2.reshape(shape), logdet.reshape(shape), np.broadcast_to(usable.reshape(runs, 1, capacity), shape)

    def _scores(self, bank: _Bank, terms, iff: np.ndarray, code: np.ndarray):
        d2, logdet, usable = terms
        ln_g, ln_n = feature_logs(self.config.rule, bank.iff[:, None, :], iff[:, :, None], bank.code[:, None, :],
                                  code[:, :, None])
        scores = score_pairs(self.config.rule, d2, logdet, self._noise.shape[0], ln_g, ln_n)
        return scores.score, scores.hypothesis & usable

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

    def _apply(self, bank: _Bank, k: int, j: int, choice: np.ndarray, valid: np.ndarray, z: np.ndarray,
               own_p: np.ndarray, own_v: np.ndarray, iff: np.ndarray, code: np.ndarray, out: RunDecisions) -> None:
        """Update the chosen tracks with plot slot ``j`` (or start new ones) and record the decision."""
        update = np.flatnonzero(valid & (choice >= 0))
        if len(update):
            slot = choice[update]
            result = self._update(bank.x[update, slot], bank.P[update, slot], z[update], own_p[update], own_v[update])
            bank.x[update, slot], bank.P[update, slot] = result
            bank.misses[update, slot] = 0
            bank.hit[update, slot] = True
            self._take_features(bank, update, slot, iff[update], code[update])
            out.track_id[update, k, j] = bank.track_id[update, slot]
        start = np.flatnonzero(valid & (choice == NEW))
        if len(start):
            slot = bank.free_slots(start)
            x0, P0 = initiate_from_plot(z[start], own_p[start], own_v[start] if z.shape[-1] == 4 else None,
                                        self._noise, self.config.sigma_v0)
            bank.x[start, slot], bank.P[start, slot] = x0, P0
            bank.alive[start, slot] = True
            bank.misses[start, slot] = 0
            bank.track_id[start, slot] = bank.next_id[start]
            bank.next_id[start] += 1
            bank.iff[start, slot] = UNDETERMINED
            bank.code[start, slot] = -1
            self._take_features(bank, start, slot, iff[start], code[start])
            out.track_id[start, k, j] = bank.track_id[start, slot]
            out.started[start, k, j] = True
            bank.born[start, slot] = True
        rows = np.flatnonzero(valid)
        if len(rows):
            slot_index = np.argmax(bank.track_id[rows] == out.track_id[rows, k, j][:, None], axis=1)
            out.track_iff[rows, k, j] = bank.iff[rows, slot_index]
            out.track_code[rows, k, j] = bank.code[rows, slot_index]

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

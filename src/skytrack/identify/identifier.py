"""Many-to-many identification of two sets of tracks: spec 001 R13 (TV-6, TV-7), R14 and R17.

:class:`TrackIdentifier` takes the reports of two sets of tracks — all radar tracks (system
1) and all ADS-B tracks (system 2), say — each report tagged with its track id, online and
in time order:

1. one filter per track (the identification model of R1, not the tracker's own filter),
   shared by every pair the track is in (:class:`~skytrack.identify.kalman.FilterBank`);
2. candidate pairs from a coarse spatial gate on predicted positions (``cKDTree``), made when
   both tracks have full information rank, at the end of a processing batch.
   ``pair_init="fuse"`` starts the joint filter from (24) on the two track states with
   Λ₀ = d^T (P_i + P_j)^{-1} d (exact for Q = 0, approximate for Q > 0: TV-7); with
   ``screen_pairs`` a candidate whose Λ₀ already exceeds the drop gate of step 5 is not made;
   ``pair_init="replay"`` rebuilds the pair's three filters from the tracks' stored reports
   (exact while the buffer of ``history`` reports per track holds the whole track);
3. every report of track i updates i's filter and the joint filter of every live pair
   (i, ·): Λ_ij += q_joint − q_i (:func:`skytrack.identify.kernels.process_reports`, one
   compiled call per batch; ``compiled=False`` runs the numpy reference report by report);
4. :meth:`TrackIdentifier.assign` is the global one-to-one assignment with a "no match"
   option (:mod:`skytrack.identify.assignment`), Neyman–Pearson or Bayesian;
5. a pair dies when Λ exceeds the drop gate (χ²_dof quantile 1 − 1e−6) on 3 consecutive
   updates, or with either track; it may be made again after ``recreate_after_s``;
6. :meth:`TrackIdentifier.fused` is R14: the pair's joint estimate (``fusion="joint"``,
   exact under the model) or literal (24) on the two track estimates (``"information"``,
   overconfident for Q > 0).

The pairs update loop is vectorised over pairs (R17): no Python object per pair or report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from skytrack.identify.assignment import PairTable, assign_pairs
from skytrack.identify.kalman import FilterBank
from skytrack.identify.kernels import MAX_CONSECUTIVE_GATED
from skytrack.identify.model import IdentificationModel, cv_model
from skytrack.identify.pairing import PairBank, ReportHistory, replay_pairs
from skytrack.identify.sequential import DIFFERENT, INSUFFICIENT, SAME, merge_order
from skytrack.identify.single_shot import fuse_information, track_states_test
from skytrack.identify.threshold import Threshold, drop_gate

PAIR_INITS = ("fuse", "replay")
COSTS = ("np", "bayes")
FUSIONS = ("joint", "information")


@dataclass(frozen=True)
class IdentifierConfig:
    """Settings of :class:`TrackIdentifier` (R13); the defaults are R13's."""

    q: float = 1.0
    """process-noise PSD of the CV identification model (m²/s³), used when ``model`` is None"""
    ndim: int = 2
    model: IdentificationModel | None = None
    gate_m: float = 10_000.0
    """coarse pair-creation gate on predicted positions (m)"""
    pair_init: str = "fuse"
    threshold: Threshold = field(default_factory=lambda: Threshold(p_correct=0.99))
    cost: str = "np"
    """"np": cost Λ − h; "bayes": cost −ln BF (needs ``object_density``)"""
    object_density: float | None = None
    prior_same: float = 0.5
    solver: str = "global"
    dof_min: int | None = None
    drop_quantile: float = 1.0 - 1e-6
    drop_count: int = 3
    history: int = 256
    """reports kept per track for ``pair_init="replay"``"""
    recreate_after_s: float = 60.0
    batch_s: float = 1.0
    """reports are processed in batches of this length; pairs are made at each batch's end"""
    horizon_s: float | None = None
    """re-initialise every pair by ``fuse`` when its sequential evidence is this old (None: never).
    With process noise in the model and smoother true motion, Λ of true pairs drifts upwards with
    the number of reports (its variance grows even when the model holds, TV-5c); a horizon
    bounds that drift at the price of the evidence older than the horizon (skytrack addition)"""
    screen_pairs: bool = False
    """``fuse`` only: do not make a pair whose two track states already fail the drop gate (it
    would be dropped after drop_count updates; with short re-creation delays such pairs churn)"""
    report_gate: float | None = None
    """leave out a report whose normalised innovation in its own track's filter exceeds the
    χ²_m quantile of this probability (e.g. 0.9999): a clutter plot a radar track took would
    otherwise condemn every pair of the track at once; the third such report in a row is taken
    (a manoeuvre, not an outlier) (skytrack addition; None: keep all)"""
    compiled: bool = True

    def __post_init__(self):
        if self.pair_init not in PAIR_INITS:
            raise ValueError(f"pair_init must be one of {PAIR_INITS}, got {self.pair_init!r}")
        if self.cost not in COSTS:
            raise ValueError(f"cost must be one of {COSTS}, got {self.cost!r}")
        if self.cost == "bayes" and not (self.object_density and self.object_density > 0):
            raise ValueError("cost='bayes' needs object_density (objects per unit of state space, > 0)")
        if self.report_gate is not None and not 0.0 < self.report_gate < 1.0:
            raise ValueError(f"report_gate must be a probability in (0, 1) or None, got {self.report_gate}")
        if self.horizon_s is not None and not self.horizon_s > 0:
            raise ValueError(f"horizon_s must be > 0 or None, got {self.horizon_s}")
        for name in ("gate_m", "batch_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.drop_count < 1:
            raise ValueError(f"drop_count must be >= 1, got {self.drop_count}")

    def identification_model(self) -> IdentificationModel:
        return self.model if self.model is not None else cv_model(self.ndim, self.q)


@dataclass(frozen=True)
class Identification:
    """R13 step 6: the outcome of one assignment."""

    time: float
    first_id: np.ndarray
    second_id: np.ndarray
    statistic: np.ndarray
    dof: np.ndarray
    threshold: np.ndarray
    p_same: np.ndarray
    """posterior P(same) when a Bayesian cost or an object density is configured, else NaN"""
    pair: np.ndarray
    """pair rows (for :meth:`TrackIdentifier.fused`)"""
    unmatched_first: np.ndarray
    unmatched_second: np.ndarray

    def table(self):
        """The matches as a pandas DataFrame (one row per identified pair)."""
        import pandas as pd

        return pd.DataFrame({"time": self.time, "track_1": self.first_id, "track_2": self.second_id,
                             "statistic": self.statistic, "dof": self.dof, "threshold": self.threshold,
                             "p_same": self.p_same, "decision": SAME})


def _compiled_model(model: IdentificationModel) -> float | None:
    """The PSD q when the model is the CV one the kernel implements, else None."""
    from skytrack.models.motion import ConstantVelocityAxis

    axes = model.motion.axes
    if all(type(axis) is ConstantVelocityAxis for axis in axes) and len({axis.q for axis in axes}) == 1:
        return float(axes[0].q)
    return None


class TrackIdentifier:
    """Online many-to-many identification of system-1 tracks against system-2 tracks (R13)."""

    def __init__(self, config: IdentifierConfig | None = None):
        self.config = config = config if config is not None else IdentifierConfig()
        self.model = config.identification_model()
        self.kernel_q = _compiled_model(self.model) if config.compiled else None
        self.tracks = FilterBank(self.model, 0)
        self.track_side = np.zeros(0, dtype=np.int8)
        self.track_alive = np.zeros(0, dtype=bool)
        self.gated_in_row = np.zeros(0, dtype=np.int64)
        self.track_ids: list = []
        self._rows: tuple[dict, dict] = ({}, {})
        self.pairs = PairBank(self.model)
        self.history = ReportHistory(self.model.n, config.history) if config.pair_init == "replay" else None
        self.time = -np.inf
        self.stats = {"reports": 0, "pair_updates": 0, "pairs_created": 0, "pairs_dropped": 0, "batches": 0,
                      "reports_gated": 0, "pairs_refreshed": 0, "pairs_not_made": 0}
        dof = self.model.n
        self._drop_gate = float(drop_gate(dof, config.drop_quantile)[0])

    # ------------------------------------------------------------------ tracks
    def _track_rows(self, side: int, ids: np.ndarray) -> np.ndarray:
        """Rows of the tracks ``ids`` of ``side``, registering new tracks (one dict lookup per track)."""
        unique, inverse = np.unique(ids, return_inverse=True)
        lookup = self._rows[side - 1]
        rows = np.empty(len(unique), dtype=np.intp)
        new = []
        for i, track_id in enumerate(unique.tolist()):
            row = lookup.get(track_id)
            if row is None:
                row = len(self.track_ids) + len(new)
                lookup[track_id] = row
                new.append(track_id)
            rows[i] = row
        if new:
            start = len(self.track_ids)
            size = start + len(new)
            self.track_ids.extend(new)
            if size > len(self.tracks):
                self.tracks.grow(max(size, 2 * len(self.tracks), 64))
            self.track_side = _grown(self.track_side, len(self.tracks), 0)
            self.track_alive = _grown(self.track_alive, len(self.tracks), False)
            self.gated_in_row = _grown(self.gated_in_row, len(self.tracks), 0)
            self.track_side[start:size] = side
            self.track_alive[start:size] = True
            if self.history is not None:
                self.history.grow(len(self.tracks))
        return rows[inverse]

    def end_tracks(self, side: int, ids) -> None:
        """Tracks that ended (deleted by their tracker): their pairs die with them (R13 step 5)."""
        lookup = self._rows[side - 1]
        rows = np.array([lookup[i] for i in np.atleast_1d(ids).tolist() if i in lookup], dtype=np.intp)
        if len(rows):
            self.track_alive[rows] = False
            self.pairs.kill_tracks(rows, self.time)

    # ------------------------------------------------------------------ reports
    def process(self, side, track_id, time, z, V) -> None:
        """Reports of both systems: ``side`` 1 or 2 per report, ``z`` ``[R, m]`` measuring the first m
        state components (positions, then velocities), ``V`` ``[R, m, m]``.  Times must not go
        back before reports already processed; within a call any order is fine (merge order)."""
        side = np.asarray(side, dtype=np.int8).reshape(-1)
        time = np.asarray(time, float).reshape(-1)
        z = np.asarray(z, float).reshape(len(time), -1)
        V = np.asarray(V, float).reshape(len(time), z.shape[1], z.shape[1])
        track_id = np.asarray(track_id).reshape(-1)
        _check_reports(side, time, z, V, self.time, self.model.n)
        if len(time) == 0:
            return
        order = merge_order(time, side)
        side, time, z, V, track_id = side[order], time[order], z[order], V[order], track_id[order]
        rows = np.empty(len(time), dtype=np.intp)
        for s in (1, 2):
            mine = side == s
            if mine.any():
                rows[mine] = self._track_rows(s, track_id[mine])
        if np.any(~self.track_alive[rows]):
            bad = int(np.flatnonzero(~self.track_alive[rows])[0])
            raise ValueError(f"report {order[bad]}: track {track_id[bad]!r} of system {side[bad]} has ended")
        batch = np.floor((time - time[0]) / self.config.batch_s).astype(np.int64)
        bounds = np.flatnonzero(np.diff(batch)) + 1
        for start, stop in zip(np.r_[0, bounds], np.r_[bounds, len(time)]):
            self._process_batch(rows[start:stop], time[start:stop], z[start:stop], V[start:stop])
            self._make_pairs(float(time[stop - 1]))
        self.time = float(time[-1])

    def _process_batch(self, rows, time, z, V) -> None:
        n = self.model.n
        m = z.shape[1]
        self.stats["reports"] += len(rows)
        self.stats["batches"] += 1
        if self.history is not None:
            self.history.append(rows, time, z, V)
        ptr, adjacency = self.pairs.adjacency(len(self.tracks))
        alive_before = int(self.pairs.alive.sum())
        if self.kernel_q is not None:
            from skytrack.identify.kernels import process_reports

            z_pad = np.zeros((len(rows), n))
            z_pad[:, :m] = z
            V_pad = np.zeros((len(rows), n, n))
            V_pad[:, :m, :m] = V
            bank, pairs = self.tracks, self.pairs
            updates, gated = process_reports(
                rows, time, z_pad, np.full(len(rows), m, dtype=np.int64), V_pad, self.model.ndim, self.kernel_q,
                bank.t, bank.full, bank.Y, bank.y, bank.c0, bank.x, bank.P, bank.J, bank.L, bank.m, bank.rank,
                ptr, adjacency, pairs.alive, pairs.joint.t, pairs.joint.x, pairs.joint.P, pairs.statistic,
                pairs.updates, pairs.exceed, pairs.dropped_at, self._drop_gate, self.config.drop_count,
                self._report_gate(m), self.gated_in_row)
            self.stats["pair_updates"] += int(updates)
            self.stats["reports_gated"] += int(gated)
        else:
            self._process_reference(rows, time, z, V, ptr, adjacency)
        self.stats["pairs_dropped"] += alive_before - int(self.pairs.alive.sum())

    def _report_gate(self, m: int) -> float:
        if self.config.report_gate is None:
            return 0.0
        return float(drop_gate(m, self.config.report_gate)[0])

    def _process_reference(self, rows, time, z, V, ptr, adjacency) -> None:
        """The numpy reference of the compiled loop: report by report, every pair of the report's track."""
        H = np.eye(z.shape[1], self.model.n)
        pairs = self.pairs
        gate = self._report_gate(z.shape[1])
        for r in range(len(rows)):
            k = rows[r:r + 1]
            self.tracks.predict(k, time[r])
            if gate > 0 and self.tracks.full[k[0]]:
                if self.tracks.normalised_innovation(k, z[r:r + 1], V[r:r + 1], H)[0] > gate and \
                        self.gated_in_row[k[0]] < MAX_CONSECUTIVE_GATED:
                    self.gated_in_row[k[0]] += 1
                    self.stats["reports_gated"] += 1
                    continue
                self.gated_in_row[k[0]] = 0
            own = self.tracks.update(k, z[r:r + 1], V[r:r + 1], H).quadratic[0]
            members = adjacency[ptr[k[0]]:ptr[k[0] + 1]]
            members = members[pairs.alive[members]]
            if len(members) == 0:
                continue
            pairs.joint.predict(members, time[r])
            joint = pairs.joint.update(members, np.repeat(z[r:r + 1], len(members), 0), V[r], H).quadratic
            pairs.statistic[members] += joint - own
            pairs.updates[members] += 1
            self.stats["pair_updates"] += len(members)
            over = pairs.statistic[members] > self._drop_gate
            pairs.exceed[members] = np.where(over, pairs.exceed[members] + 1, 0)
            dying = members[pairs.exceed[members] >= self.config.drop_count]
            pairs.alive[dying] = False
            pairs.dropped_at[dying] = time[r]

    # ------------------------------------------------------------------ pairs
    def _make_pairs(self, t: float) -> None:
        """R13 step 2: pairs of full-rank tracks of the two systems within the gate at time ``t``
        (and, with a horizon, the re-initialisation of pairs whose evidence reached it)."""
        if self.config.horizon_s is not None:
            self._refresh_pairs(t)
        ready = self.track_alive & self.tracks.full
        first = np.flatnonzero(ready & (self.track_side == 1))
        second = np.flatnonzero(ready & (self.track_side == 2))
        if len(first) == 0 or len(second) == 0:
            return
        pos_first = self._predicted_positions(first, t)
        pos_second = self._predicted_positions(second, t)
        tree = cKDTree(pos_second)
        near = tree.query_ball_point(pos_first, self.config.gate_m, return_length=True)
        if near.sum() == 0:
            return
        hits = cKDTree(pos_first).sparse_distance_matrix(tree, self.config.gate_m, output_type="coo_matrix")
        i, j = first[hits.row], second[hits.col]
        keep = self.pairs.new_keys(i, j, t, self.config.recreate_after_s)
        i, j = i[keep], j[keep]
        if len(i) == 0:
            return
        if self.config.pair_init == "fuse":
            x_i, P_i = self.tracks.estimate_at(i, t)
            x_j, P_j = self.tracks.estimate_at(j, t)
            statistic = track_states_test(x_i, P_i, x_j, P_j)
            # with screening, a pair whose tracks already disagree beyond the drop gate is not made:
            # it would only be dropped again (the spec makes every gated pair; E9 counts them)
            fits = statistic <= self._drop_gate if self.config.screen_pairs else np.ones(len(i), dtype=bool)
            self.stats["pairs_not_made"] += int((~fits).sum())
            if not fits.any():
                return
            i, j, statistic = i[fits], j[fits], statistic[fits]
            x, _, P = fuse_information(x_i[fits], P_i[fits], x_j[fits], P_j[fits])
            self.pairs.add(i, j, t, x, P, statistic, self.model.n)
        else:
            x, P, t_joint, statistic, dof = replay_pairs(self.model, self.history, i, j)
            self.pairs.add(i, j, t_joint, x, P, statistic, dof)
        self.stats["pairs_created"] += len(i)

    def _refresh_pairs(self, t: float) -> None:
        pairs = self.pairs
        old = np.flatnonzero(pairs.alive[:pairs.size] & (t - pairs.created_at[:pairs.size] >= self.config.horizon_s))
        if len(old) == 0:
            return
        x_i, P_i = self.tracks.estimate_at(pairs.first[old], t)
        x_j, P_j = self.tracks.estimate_at(pairs.second[old], t)
        x, _, P = fuse_information(x_i, P_i, x_j, P_j)
        pairs.joint.x[old], pairs.joint.P[old], pairs.joint.t[old] = x, P, t
        pairs.statistic[old] = track_states_test(x_i, P_i, x_j, P_j)
        pairs.created_at[old] = t
        self.stats["pairs_refreshed"] += len(old)

    def _predicted_positions(self, rows: np.ndarray, t: float) -> np.ndarray:
        nd = self.model.ndim
        x = self.tracks.x[rows]
        return x[:, :nd] + x[:, nd:2 * nd] * (t - self.tracks.t[rows])[:, None]

    # ------------------------------------------------------------------ decisions
    def pair_table(self, t: float | None = None) -> tuple[PairTable, np.ndarray]:
        """Live pairs of live tracks with Λ, dof, threshold, allowed flag and cost (R13 step 4)."""
        config = self.config
        pairs = self.pairs
        live = np.flatnonzero(pairs.alive)
        live = live[self.track_alive[pairs.first[live]] & self.track_alive[pairs.second[live]]]
        statistic, dof = pairs.statistic[live], pairs.dof[live]
        dof_min = self.model.n if config.dof_min is None else config.dof_min
        covariance = self.covariance_sum(live, t) if config.threshold.needs_covariance else None
        h = config.threshold.value(dof, covariance_sum=covariance)
        if config.cost == "np":
            allowed = (dof >= dof_min) & (statistic <= h)
            cost = statistic - h
        else:
            log_bf = self.log_bayes_factor(live, t)
            allowed = (dof >= dof_min) & (log_bf > 0)
            cost = -log_bf
        return PairTable(pairs.first[live], pairs.second[live], statistic, dof, h, allowed, cost), live

    def covariance_sum(self, live: np.ndarray, t: float | None = None) -> np.ndarray:
        """P_i + P_j of pairs ``live`` at one common time (their later report, or ``t``): R5's and R6's S."""
        first, second = self.pairs.first[live], self.pairs.second[live]
        common = np.maximum(self.tracks.t[first], self.tracks.t[second]) if t is None else np.full(len(live), t)
        return self.tracks.estimate_at(first, common)[1] + self.tracks.estimate_at(second, common)[1]

    def log_bayes_factor(self, live: np.ndarray, t: float | None = None) -> np.ndarray:
        """R6 density mode per pair: −Λ/2 − ½ ln det(2π(P_i + P_j)) − ln β, plus the prior log-odds."""
        beta = self.config.object_density
        if beta is None:
            raise ValueError("the posterior needs object_density (beta > 0); it has no default (spec 001 R6)")
        prior = self.config.prior_same
        _, logdet = np.linalg.slogdet(2.0 * np.pi * self.covariance_sum(live, t))
        return (np.log(prior) - np.log1p(-prior) - 0.5 * self.pairs.statistic[live] - 0.5 * logdet
                - np.log(beta))

    def assign(self, t: float | None = None) -> Identification:
        """R13 steps 4 and 6: the one-to-one identification now (or with states predicted to ``t``)."""
        table, live = self.pair_table(t)
        n_tracks = len(self.track_ids)
        chosen = assign_pairs(table, n_tracks, n_tracks, self.config.solver)
        p_same = np.full(len(chosen), np.nan)
        if self.config.object_density is not None and len(chosen):
            from skytrack.identify.sequential import logistic

            p_same = logistic(self.log_bayes_factor(live[chosen], t))
        ids = np.array(self.track_ids + [None], dtype=object)
        matched = np.zeros(n_tracks, dtype=bool)
        matched[table.first[chosen]] = matched[table.second[chosen]] = True
        alive_unmatched = self.track_alive[:n_tracks] & ~matched
        sides = self.track_side[:n_tracks]
        return Identification(
            time=self.time if t is None else float(t), first_id=ids[table.first[chosen]],
            second_id=ids[table.second[chosen]], statistic=table.statistic[chosen], dof=table.dof[chosen],
            threshold=table.threshold[chosen], p_same=p_same, pair=live[chosen],
            unmatched_first=ids[:n_tracks][alive_unmatched & (sides == 1)],
            unmatched_second=ids[:n_tracks][alive_unmatched & (sides == 2)])

    def decisions(self) -> tuple[np.ndarray, np.ndarray]:
        """The per-pair NP decision (20a) of every live pair, and their rows (no assignment)."""
        table, live = self.pair_table()
        dof_min = self.model.n if self.config.dof_min is None else self.config.dof_min
        decision = np.where(table.statistic > table.threshold, DIFFERENT, SAME).astype(object)
        decision[table.dof < dof_min] = INSUFFICIENT
        return decision, live

    def fused(self, pair_rows, fusion: str = "joint", t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """R14: fused states and covariances of pairs (at their last report, or predicted to ``t``)."""
        if fusion not in FUSIONS:
            raise ValueError(f"fusion must be one of {FUSIONS}, got {fusion!r}")
        pair_rows = np.asarray(pair_rows, dtype=np.intp)
        times = self.pairs.joint.t[pair_rows] if t is None else np.full(len(pair_rows), float(t))
        if fusion == "joint":
            return self.pairs.joint.estimate_at(pair_rows, times)
        x_i, P_i = self.tracks.estimate_at(self.pairs.first[pair_rows], times)
        x_j, P_j = self.tracks.estimate_at(self.pairs.second[pair_rows], times)
        x, _, P = fuse_information(x_i, P_i, x_j, P_j)
        return x, P

    @property
    def mean_pairs_per_report(self) -> float:
        reports = self.stats["reports"]
        return self.stats["pair_updates"] / reports if reports else 0.0


def _grown(array: np.ndarray, size: int, fill) -> np.ndarray:
    if len(array) >= size:
        return array
    grown = np.full(size, fill, dtype=array.dtype)
    grown[:len(array)] = array
    return grown


def _check_reports(side, time, z, V, after: float, n: int) -> None:
    """Clear errors naming the report (R1): unknown system, NaN, singular V, time going backwards."""
    if not (len(side) == len(time) == len(z) == len(V)):
        raise ValueError("side, track_id, time, z and V must have one entry per report")
    bad = np.flatnonzero((side != 1) & (side != 2))
    if len(bad):
        raise ValueError(f"report {bad[0]}: unknown system {side[bad[0]]} (expected 1 or 2)")
    if z.shape[1] > n or z.shape[1] < 1:
        raise ValueError(f"reports measure {z.shape[1]} components; the state has {n}")
    finite = np.isfinite(time) & np.isfinite(z).all(axis=1) & np.isfinite(V).all(axis=(1, 2))
    if not finite.all():
        raise ValueError(f"report {np.flatnonzero(~finite)[0]}: NaN or infinite time, position or covariance")
    if len(V) and np.any(np.linalg.eigvalsh(0.5 * (V + np.swapaxes(V, 1, 2)))[:, 0] <= 0):
        first = np.flatnonzero(np.linalg.eigvalsh(0.5 * (V + np.swapaxes(V, 1, 2)))[:, 0] <= 0)[0]
        raise ValueError(f"report {first}: the covariance is singular or not positive definite")
    if len(time) and time.min() < after:
        first = int(np.argmin(time))
        raise ValueError(f"report {first}: time {time[first]:.6g} s goes back before reports already processed "
                         f"(up to {after:.6g} s)")

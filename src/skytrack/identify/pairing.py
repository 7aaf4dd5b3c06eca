"""The pair bank of the many-to-many identifier and the exact pair initialisation (spec 001 R13 step 2).

* :class:`PairBank` — every candidate pair as a row: the joint filter (a
  :class:`~skytrack.identify.kalman.FilterBank` row in covariance form), Λ, dof, the drop
  counter, and the two track rows.  Pairs are found by an integer key (first, second)
  with ``searchsorted`` on sorted keys: no Python object per pair.
* :class:`ReportHistory` — the last ``history`` reports of every track, for
  ``pair_init="replay"``.
* :func:`replay_pairs` — rebuilds pairs from those histories with the sequential test of
  (20a) (:class:`~skytrack.identify.sequential.SequentialPairTest`), batched over the new
  pairs.  It is exact (TV-7's replay values) while the buffers hold the whole tracks.
"""

from __future__ import annotations

import numpy as np

from skytrack.identify.kalman import FilterBank
from skytrack.identify.model import IdentificationModel
from skytrack.identify.sequential import SequentialPairTest

_KEY_BASE = np.int64(1) << 32


class PairBank:
    """Candidate pairs, row by row; rows are appended, never reused (a recreated pair is a new row)."""

    def __init__(self, model: IdentificationModel):
        self.model = model
        self.joint = FilterBank(model, 0)
        self.first = np.zeros(0, dtype=np.intp)
        self.second = np.zeros(0, dtype=np.intp)
        self.alive = np.zeros(0, dtype=bool)
        self.statistic = np.zeros(0)
        self.dof = np.zeros(0, dtype=np.int64)
        self.updates = np.zeros(0, dtype=np.int64)
        self.exceed = np.zeros(0, dtype=np.int64)
        self.dropped_at = np.zeros(0)
        self.created_at = np.zeros(0)
        self.size = 0

    def _grow(self, size: int) -> None:
        capacity = len(self.first)
        if size <= capacity:
            return
        capacity = max(size, 2 * capacity, 64)
        self.joint.grow(capacity)
        for name, fill in (("first", -1), ("second", -1), ("alive", False), ("statistic", 0.0), ("dof", 0),
                           ("updates", 0), ("exceed", 0), ("dropped_at", np.nan), ("created_at", np.nan)):
            array = getattr(self, name)
            grown = np.full(capacity, fill, dtype=array.dtype)
            grown[:len(array)] = array
            setattr(self, name, grown)

    def keys(self, first: np.ndarray, second: np.ndarray) -> np.ndarray:
        return np.asarray(first, np.int64) * _KEY_BASE + np.asarray(second, np.int64)

    def new_keys(self, first: np.ndarray, second: np.ndarray, t: float, recreate_after_s: float) -> np.ndarray:
        """Which (first, second) candidates need a pair: no pair yet, or the last one was dropped
        at least ``recreate_after_s`` ago."""
        wanted = self.keys(first, second)
        if self.size == 0:
            return np.ones(len(wanted), dtype=bool)
        existing = self.keys(self.first[:self.size], self.second[:self.size])
        order = np.lexsort((np.arange(self.size), existing))  # by key, latest row last
        sorted_keys = existing[order]
        last = np.searchsorted(sorted_keys, wanted, side="right") - 1
        found = (last >= 0) & (sorted_keys[np.maximum(last, 0)] == wanted)
        latest = order[np.maximum(last, 0)]
        cooled = ~self.alive[latest] & (t - self.dropped_at[latest] >= recreate_after_s)
        return ~found | cooled

    def add(self, first, second, t, x, P, statistic, dof) -> np.ndarray:
        """Append pairs with their joint state at time(s) ``t``; returns their rows."""
        k = len(first)
        rows = np.arange(self.size, self.size + k)
        self._grow(self.size + k)
        self.size += k
        joint = self.joint
        joint.reset(rows)
        joint.t[rows], joint.x[rows], joint.P[rows] = t, x, P
        joint.full[rows], joint.rank[rows] = True, self.model.n
        self.first[rows], self.second[rows] = first, second
        self.alive[rows] = True
        self.statistic[rows], self.dof[rows] = statistic, dof
        self.updates[rows] = self.exceed[rows] = 0
        self.created_at[rows] = np.min(t) if np.ndim(t) else t
        return rows

    def kill_tracks(self, track_rows: np.ndarray, t: float) -> None:
        """Pairs of ended tracks die (they are never recreated: the tracks are gone)."""
        used = slice(0, self.size)
        hit = np.isin(self.first[used], track_rows) | np.isin(self.second[used], track_rows)
        rows = np.flatnonzero(hit & self.alive[used])
        self.alive[rows] = False
        self.dropped_at[rows] = t

    def adjacency(self, n_tracks: int) -> tuple[np.ndarray, np.ndarray]:
        """CSR lists of the live pairs of each track: ``pairs[ptr[k]:ptr[k+1]]``."""
        live = np.flatnonzero(self.alive[:self.size])
        owners = np.concatenate([self.first[live], self.second[live]])
        members = np.concatenate([live, live])
        order = np.argsort(owners, kind="stable")
        ptr = np.zeros(n_tracks + 1, dtype=np.int64)
        np.cumsum(np.bincount(owners, minlength=n_tracks), out=ptr[1:])
        return ptr, members[order].astype(np.int64)


class ReportHistory:
    """The last ``length`` reports of every track (ring buffers), for the replay initialisation."""

    def __init__(self, n: int, length: int):
        if length < 1:
            raise ValueError(f"history must be >= 1, got {length}")
        self.n, self.length = n, length
        self.t = np.zeros((0, length))
        self.z = np.zeros((0, length, n))
        self.V = np.zeros((0, length, n, n))
        self.m = np.zeros((0, length), dtype=np.int64)
        self.count = np.zeros(0, dtype=np.int64)

    def grow(self, size: int) -> None:
        old = len(self.count)
        if size <= old:
            return
        for name in ("t", "z", "V", "m", "count"):
            array = getattr(self, name)
            grown = np.zeros((size,) + array.shape[1:], dtype=array.dtype)
            grown[:old] = array
            setattr(self, name, grown)

    def append(self, rows: np.ndarray, time: np.ndarray, z: np.ndarray, V: np.ndarray) -> None:
        """Store reports (in time order) of tracks ``rows``."""
        order = np.argsort(rows, kind="stable")
        sorted_rows = rows[order]
        first_of_group = np.r_[True, sorted_rows[1:] != sorted_rows[:-1]]
        group_start = np.maximum.accumulate(np.where(first_of_group, np.arange(len(rows)), 0))
        rank = np.empty(len(rows), dtype=np.int64)
        rank[order] = np.arange(len(rows)) - group_start
        slot = (self.count[rows] + rank) % self.length
        m = z.shape[1]
        self.t[rows, slot] = time
        self.z[rows, slot] = 0.0
        self.z[rows, slot, :m] = z
        self.V[rows, slot] = 0.0
        self.V[rows, slot, :m, :m] = V
        self.m[rows, slot] = m
        np.add.at(self.count, rows, 1)

    def reports(self, row: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The stored reports of one track in time order: (t, z, V, m)."""
        count = int(self.count[row])
        kept = min(count, self.length)
        slots = (np.arange(count - kept, count)) % self.length
        return self.t[row, slots], self.z[row, slots], self.V[row, slots], self.m[row, slots]


def replay_pairs(model: IdentificationModel, history: ReportHistory, first: np.ndarray, second: np.ndarray):
    """Exact pair initialisation: the sequential test replayed on the stored reports of both tracks.

    The merged streams of the new pairs are laid side by side (padded); step s feeds every pair's
    s-th report at once, one call per (system, measured dimension).  Returns (x, P, t) of each
    pair's joint filter after its last report, Λ and dof.
    """
    k = len(first)
    count = np.minimum(history.count, history.length)
    n1, n2 = count[first], count[second]
    length = int((n1 + n2).max()) if k else 0
    n = history.n
    time = np.full((k, length), np.inf)
    system = np.zeros((k, length), np.int8)
    z = np.zeros((k, length, n))
    V = np.zeros((k, length, n, n))
    m = np.zeros((k, length), np.int64)
    for rows, counts, label in ((first, n1, 1), (second, n2, 2)):
        offset = 0 if label == 1 else n1
        # slot of the j-th oldest stored report of each track, for j < its count
        j = np.arange(history.length)
        valid = j[None, :] < counts[:, None]
        slots = (history.count[rows][:, None] - counts[:, None] + j[None, :]) % history.length
        pair, step = np.nonzero(valid)
        where = offset[pair] + step if label == 2 else step
        track_rows, slot = rows[pair], slots[pair, step]
        time[pair, where] = history.t[track_rows, slot]
        system[pair, where] = label
        z[pair, where] = history.z[track_rows, slot]
        V[pair, where] = history.V[track_rows, slot]
        m[pair, where] = history.m[track_rows, slot]
    # merge order per pair: by time, system 1 first at equal times (stable sort keeps report order)
    order = np.lexsort((system, time), axis=1) if length else np.zeros((k, 0), np.intp)
    take = np.arange(k)[:, None]
    time, system, z, V, m = time[take, order], system[take, order], z[take, order], V[take, order], m[take, order]
    test = SequentialPairTest(model, k)
    for step in range(length):
        for label in (1, 2):
            for dim in np.unique(m[:, step][system[:, step] == label]):
                rows = np.flatnonzero((system[:, step] == label) & (m[:, step] == dim))
                test.add(label, time[rows, step], z[rows, step, :dim], V[rows, step, :dim, :dim], rows=rows)
    forms = test.forms()
    return test.joint.x.copy(), test.joint.P.copy(), test.joint.t.copy(), forms.statistic, forms.dof

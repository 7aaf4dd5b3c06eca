"""Identification inside a tracking run: radar tracks labelled with the address and callsign of the
aircraft ADS-B reports for them, or with what another radar's (an interrogator's) paired tracks carry
(issue 9; spec 001 R13 applied to the tracker's output).

:class:`TrackLabeler` sits beside :func:`skytrack.app.run.run_tracking`.  The tracker records
every plot a confirmed track takes (:meth:`skytrack.tracker.Tracker.record_assignments`: the
plot's common-frame position and covariance); those are the radar tracks' reports (system 1),
the ADS-B reports grouped by ``icao24`` are the other system's (system 2).  At every output
instant of the tracks table the :class:`~skytrack.identify.identifier.TrackIdentifier` has taken
every report up to that instant and the global assignment (R13 step 4) decides; a track is
labelled when

* its pair with the ADS-B track is assigned (Λ ≤ h = χ²⁻¹_dof(``p_correct``), dof ≥ n; a label
  is kept, or taken back within ``relabel_s``, while Λ ≤ χ²⁻¹_dof(``p_keep``)),
* the aircraft has reported within ``silent_after`` of its typical report intervals,
* the pair has taken at least ``min_updates`` reports since it was made (a fresh pair's Λ₀ is
  one snapshot of the two track states), and
* with ``unique`` (default), neither track has another pair that also passes the test after as
  many reports: a careful operator does not label a track that two aircraft could both explain.

ADS-B decides only through this test; a Mode S address the track's own plots carry (source
``mode_s``) stays, and an ADS-B label that contradicts it is counted as a conflict, not written.
``identity_p`` of an ADS-B label is R6's density-mode posterior with the object density β of the
live ADS-B tracks over the covered area and a disc of ground speeds (approximate with process
noise, as R6 says).  Every label change is an identity event (source ``adsb``).  With
``fuse`` the rows of labelled tracks carry the pair's joint estimate (R14 ``fusion="joint"``).

Identification model: CV with ``q`` (m²/s³); pairs are re-made by ``fuse`` every ``horizon_s``
(:class:`~skytrack.identify.identifier.IdentifierConfig`): with process noise, Λ of a true pair
drifts upwards over long tracks, so evidence older than the horizon is summarised by the track
states instead of being accumulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import pyarrow as pa

from skytrack.app.other_systems import OtherSystem
from skytrack.identify.identifier import IdentifierConfig, TrackIdentifier
from skytrack.identify.threshold import Threshold

#: identity fields a label sets (the first two) or fills when the track shows none (the last two)
LABEL_FIELDS = ("icao24", "callsign", "mode3a", "iff")


@dataclass(frozen=True)
class AdsbIdentificationConfig:
    """Settings of the ADS-B labelling of a tracking run."""

    q: float = 300.0
    """process-noise PSD (m²/s³) of the CV identification model: large enough for the radar track's
    filter to follow a 3 g turn between 4-s scans, which is what keeps true pairs through manoeuvres"""
    gate_m: float = 10_000.0
    horizon_s: float | None = 20.0
    p_correct: float = 0.99
    """a new label needs Λ ≤ χ²⁻¹_dof(p_correct)"""
    p_keep: float = 0.9999
    """a label is kept while Λ ≤ χ²⁻¹_dof(p_keep) (hysteresis: Λ of a true pair fluctuates)"""
    min_updates: int = 8
    unique: bool = True
    stale_s: float = 30.0
    """a track (of either system) silent this long ends: its pairs die (a radar track that misses a
    few scans in a row keeps its pairs)"""
    fuse: bool = False
    ground_speed_mps: float = 300.0
    """radius of the disc of ground velocities in the object density β of ``identity_p``"""
    batch_s: float = 1.0
    report_gate: float | None = 0.9999
    """a plot (or ADS-B report) this improbable under its own track's filter is left out"""
    recreate_after_s: float = 4.0
    """a dropped pair may be made again after this long (one scan of a 4-s radar)"""
    relabel_s: float = 60.0
    """a track labelled by a pair within this long takes the label back at the keep threshold
    (a scan or two of doubt after a coast should not cost a minute without a label)"""
    silent_after: float = 5.0
    """a label needs the other system's track to have reported within this many of its typical
    report intervals (the median gap between its reports): no word from the aircraft, no label"""

    def __post_init__(self):
        if not 0.0 < self.p_correct <= self.p_keep < 1.0:
            raise ValueError(f"need 0 < p_correct <= p_keep < 1, got {self.p_correct} and {self.p_keep}")
        if self.min_updates < 0:
            raise ValueError(f"min_updates must be >= 0, got {self.min_updates}")
        if not self.stale_s > 0:
            raise ValueError(f"stale_s must be > 0, got {self.stale_s}")

    def identifier_config(self) -> IdentifierConfig:
        return IdentifierConfig(q=self.q, gate_m=self.gate_m, horizon_s=self.horizon_s, batch_s=self.batch_s,
                                threshold=Threshold(p_correct=self.p_keep), report_gate=self.report_gate,
                                recreate_after_s=self.recreate_after_s, screen_pairs=True)


@dataclass
class LabelStats:
    """What the labelling did, for the run summary."""

    adsb_reports: int = 0
    adsb_addresses: int = 0
    radar_reports: int = 0
    late_radar_reports: int = 0
    """radar plots older than reports already identified (processed by the tracker late); skipped"""
    labelled_rows: int = 0
    labelled_tracks: set = field(default_factory=set)
    mode_s_conflicts: int = 0
    label_changes: int = 0

    def to_dict(self) -> dict:
        return {"adsb_reports": self.adsb_reports, "adsb_addresses": self.adsb_addresses,
                "radar_reports": self.radar_reports, "late_radar_reports": self.late_radar_reports,
                "labelled_rows": self.labelled_rows, "labelled_tracks": len(self.labelled_tracks),
                "mode_s_conflicts": self.mode_s_conflicts, "label_changes": self.label_changes}


class TrackLabeler:
    """Labels tracks-table chunks with the identities another system's tracks carry, as the tracker
    produces them (:mod:`skytrack.app.other_systems`: ADS-B, another radar or an interrogator)."""

    def __init__(self, other: OtherSystem, covered_area_m2: float, config: AdsbIdentificationConfig | None = None):
        self.config = config = config if config is not None else AdsbIdentificationConfig()
        self.identifier = TrackIdentifier(config.identifier_config())
        self.other = other
        self.other_next = 0
        self.label_of: dict[str, tuple] = {}  # other track key -> (icao24, callsign) it last named
        self.radar_gen: dict = {}
        self.other_gen: dict = {}
        self.radar_heard: dict = {}
        self.other_heard: dict = {}
        self.ended: dict[int, set] = {1: set(), 2: set()}
        self.covered_area_m2 = covered_area_m2
        self.pending = None
        self.labels: dict[int, tuple] = {}  # track id -> the LABEL_FIELDS values last written
        self.held: dict[int, tuple] = {}  # track id -> (other track key, last time it labelled the track)
        self.pairs_log: list[tuple] = []
        self.stats = LabelStats(adsb_reports=len(other.time), adsb_addresses=other.keys)
        self.other_interval = typical_interval(other.key, other.time, 1.0)
        self.silent_s = config.silent_after * self.other_interval

    # ------------------------------------------------------------------ reports
    def add_radar(self, assignments: dict[str, np.ndarray] | None) -> None:
        """Plots confirmed tracks took (:meth:`skytrack.tracker.Tracker.drain_assignments`)."""
        if assignments is None or len(assignments["time"]) == 0:
            return
        part = {"track_id": assignments["track_id"], "time": assignments["time"],
                "z": assignments["position"][:, :2], "V": assignments["covariance"][:, :2, :2]}
        if self.pending is None:
            self.pending = part
        else:
            self.pending = {k: np.concatenate([self.pending[k], part[k]]) for k in part}
        self.stats.radar_reports += len(part["time"])

    def _advance(self, t: float) -> None:
        """Feed the identifier every report up to ``t``."""
        ident = self.identifier
        other = self.other
        stop = int(np.searchsorted(other.time, t, side="right"))
        a = slice(self.other_next, stop)
        self.other_next = stop
        radar_id = radar_t = radar_z = radar_V = None
        if self.pending is not None:
            take = self.pending["time"] <= t
            late = take & (self.pending["time"] < ident.time)
            if late.any():
                self.stats.late_radar_reports += int(late.sum())
                take &= ~late
            radar_t, radar_id = self.pending["time"][take], self.pending["track_id"][take]
            radar_z, radar_V = self.pending["z"][take], self.pending["V"][take]
            keep = ~(self.pending["time"] <= t)
            self.pending = {k: v[keep] for k, v in self.pending.items()}
        adsb_ids = other.key[a]
        for key, *identity in zip(adsb_ids, other.icao24[a], other.callsign[a], other.mode3a[a], other.iff[a]):
            if any(v is not None for v in identity):
                self.label_of[key] = tuple(identity)
        n_adsb = len(adsb_ids)
        n_radar = 0 if radar_t is None else len(radar_t)
        if n_adsb + n_radar == 0:
            return
        side = np.r_[np.full(n_adsb, 2, np.int8), np.ones(n_radar, np.int8)]
        ids = np.r_[adsb_ids.astype(object), (radar_id if n_radar else np.zeros(0)).astype(object)]
        times = np.r_[other.time[a], radar_t if n_radar else np.zeros(0)]
        z = np.concatenate([other.z[a]] + ([radar_z] if n_radar else []))
        V = np.concatenate([other.V[a]] + ([radar_V] if n_radar else []))
        ident.process(side, self._keys(side, ids, times), times, z, V)

    def _keys(self, side: np.ndarray, ids: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Identifier track keys: ``r:ID:GEN`` / ``a:ADDRESS:GEN``; a track heard again after it was
        ended (stale) starts a new generation, so the identifier sees a new track."""
        keys = np.empty(len(ids), dtype=object)
        for s, prefix, gen, heard in ((1, "r", self.radar_gen, self.radar_heard),
                                      (2, "a", self.other_gen, self.other_heard)):
            mine = side == s
            if not mine.any():
                continue
            frame = pd.DataFrame({"id": ids[mine], "time": times[mine]})
            last = frame.groupby("id", sort=False)["time"].max()
            for track_id in last.index[[i in self.ended[s] for i in last.index]]:
                gen[track_id] = gen.get(track_id, 0) + 1  # one step per ended track, not per report
                self.ended[s].discard(track_id)
            heard.update(last.to_dict())
            generation = frame["id"].map(lambda i: gen.get(i, 0))
            keys[mine] = (prefix + ":" + frame["id"].astype(str) + ":" + generation.astype(str)).to_numpy(object)
        return keys

    def _end_stale(self, t: float) -> None:
        """Tracks silent for ``stale_s`` end (their pairs die); a later report starts a new generation."""
        for s, prefix, gen, heard in ((1, "r", self.radar_gen, self.radar_heard),
                                      (2, "a", self.other_gen, self.other_heard)):
            stale = [i for i, last in heard.items() if last < t - self.config.stale_s and i not in self.ended[s]]
            if stale:
                self.identifier.end_tracks(s, [f"{prefix}:{i}:{gen.get(i, 0)}" for i in stale])
                self.ended[s].update(stale)
                for i in stale:
                    del heard[i]

    # ------------------------------------------------------------------ decisions
    def _decide(self, t: float, shown: set[int]) -> dict[int, tuple[str, float, int]]:
        """Radar track id -> (icao24, identity_p, pair row) of the tracks labelled at ``t``; ``shown``
        are the radar tracks the tracks table reports confirmed (with a plot on their last scan) at ``t``."""
        ident = self.identifier
        result = ident.assign()
        if len(result.pair) == 0:
            return {}
        pairs = ident.pairs
        ok = pairs.updates[result.pair] >= self.config.min_updates
        if self.config.unique:
            table, live = ident.pair_table()
            # a pair younger than min_updates has not yet shown it fits, and a radar track the tracker
            # no longer reports (deleted, or coasting past reporting) is not in the picture: neither
            # makes a label ambiguous
            radar_shown = np.array([int(ident.track_ids[i].split(":")[1]) in shown for i in table.first], dtype=bool)
            passing = table.allowed & (pairs.updates[live] >= self.config.min_updates) & radar_shown
            count_first = np.bincount(table.first[passing], minlength=len(ident.track_ids))
            count_second = np.bincount(table.second[passing], minlength=len(ident.track_ids))
            own = np.isin(result.pair, live[passing]).astype(np.int64)  # the chosen pair itself
            ok &= (count_first[pairs.first[result.pair]] - own == 0) & (count_second[pairs.second[result.pair]] - own == 0)
        first = [ident.track_ids[i] for i in pairs.first[result.pair]]
        second = [ident.track_ids[j] for j in pairs.second[result.pair]]
        # a pair that labelled its track within relabel_s holds: Λ ≤ the keep threshold is enough
        held = [self.held.get(int(f.split(":")[1]), (None, -np.inf)) for f in first]
        holding = np.array([key == a.split(":")[1] and t - when <= self.config.relabel_s
                            for (key, when), a in zip(held, second)], dtype=bool)
        giving = Threshold(p_correct=self.config.p_correct).value(pairs.dof[result.pair])
        ok &= holding | (pairs.statistic[result.pair] <= giving)
        heard = np.array([self.other_heard.get(a.split(":")[1], -np.inf) for a in second])
        ok &= t - heard <= self.silent_s
        rows = result.pair[ok]
        if len(rows) == 0:
            return {}
        live_adsb = max(1, len(self.other_heard))
        beta = live_adsb / (self.covered_area_m2 * math.pi * self.config.ground_speed_mps ** 2)
        from skytrack.identify.sequential import logistic

        log_bf = (-0.5 * pairs.statistic[rows]
                  - 0.5 * np.linalg.slogdet(2 * np.pi * ident.covariance_sum(rows, t))[1] - math.log(beta))
        p_same = logistic(log_bf)
        first = [ident.track_ids[i] for i in pairs.first[rows]]
        second = [ident.track_ids[j] for j in pairs.second[rows]]
        return {int(f.split(":")[1]): (s.split(":")[1], float(p), int(r))
                for f, s, p, r in zip(first, second, p_same, rows)}

    def label(self, table: pa.Table | None, assignments) -> tuple[pa.Table | None, pa.Table | None]:
        """Label a chunk of track rows (all its output instants); returns it and its identity events."""
        self.add_radar(assignments)
        if table is None or table.num_rows == 0:
            return table, None
        frame = table.select(["time", "track_id", "status", *LABEL_FIELDS, "identity_source", "identity_p"]).to_pandas()
        status = frame["status"].astype(object).to_numpy()
        value = {name: frame[name].astype(object).where(frame[name].notna(), None).to_numpy(object).copy()
                 for name in (*LABEL_FIELDS, "identity_source")}
        source, probability = value["identity_source"], frame["identity_p"].to_numpy(float).copy()
        fused = _FusedRows(table.num_rows) if self.config.fuse else None
        events = []
        times = frame["time"].to_numpy(float)
        for t in np.unique(times):
            at = np.flatnonzero(times == t)
            self._advance(float(t))
            self._end_stale(float(t))
            # a coasting track (no plot on its last scan) does not make its confirmed neighbour's label ambiguous
            confirmed = at[status[at] == "confirmed"]
            decided = self._decide(float(t), set(frame["track_id"].to_numpy()[confirmed].tolist()))
            fused_now: dict[int, int] = {}
            for row, track in zip(at, frame["track_id"].to_numpy()[at].tolist()):
                label = decided.get(track)
                named = None
                if label is not None:
                    named = self.label_of.get(label[0], (label[0] if self.other.source == "adsb" else None,
                                                         None, None, None))
                    self.pairs_log.append((float(t), track, label[0], label[1], label[2]))
                    self.held[track] = (label[0], float(t))
                    self.stats.labelled_rows += 1
                    self.stats.labelled_tracks.add(track)
                    if fused is not None:
                        fused_now[row] = label[2]
                new = self._label_row(row, named, label, value, source, probability)
                events += self._events(float(t), track, new, probability[row] if label is not None else None)
            if fused_now:
                # the pairs' joint estimates now, before later reports move them on (R14)
                rows = np.fromiter(fused_now.keys(), np.int64)
                x, P = self.identifier.pairs.joint.estimate_at(np.fromiter(fused_now.values(), np.int64),
                                                               np.full(len(rows), float(t)))
                fused[rows] = (x, P)
        table = _replace(table, {**{name: pa.array(value[name], pa.string()) for name in LABEL_FIELDS},
                                 "identity_source": pa.array(source, pa.string()),
                                 "identity_p": pa.array(probability, pa.float64())})
        if fused is not None and fused.rows.any():
            table = fused.apply(table)
        return table, _events_table(events)

    def _label_row(self, row: int, named, label, value: dict, source, probability) -> tuple:
        """Write one row's label; returns the values this labeller gave it, per :data:`LABEL_FIELDS`."""
        name = self.other.source
        icao24, callsign, mode3a, iff = (value[f] for f in LABEL_FIELDS)
        if source[row] == "mode_s":  # the track's own Mode S address stays
            if named is not None and named[0] == icao24[row]:
                callsign[row] = named[1]
            elif named is not None and named[0] is not None:
                self.stats.mode_s_conflicts += 1
            given = [None, callsign[row] if named is not None and named[0] == icao24[row] else None]
        elif named is not None and (named[0] is not None or named[1] is not None):
            icao24[row], callsign[row] = named[0], named[1]
            source[row], probability[row] = name, label[1]
            given = [named[0], named[1]]
        else:
            given = [None, None]
        for k, column in ((2, mode3a), (3, iff)):  # filled only where the track's own replies show none
            filled = named is not None and named[k] is not None and column[row] is None
            if filled:
                column[row] = named[k]
                if source[row] is None:
                    source[row], probability[row] = name, label[1]
            given.append(named[k] if filled else None)
        return tuple(given)

    def _events(self, t: float, track: int, new: tuple, probability) -> list[tuple]:
        """Identity events of the values this labeller gave a track (a Mode S track's address is the
        tracker's, not ours: it has its own events)."""
        old = self.labels.get(track, (None,) * len(LABEL_FIELDS))
        self.labels[track] = new
        changed = [(field, before, after) for field, before, after in zip(LABEL_FIELDS, old, new)
                   if before != after and (field in ("icao24", "callsign") or after is not None)]
        if changed:
            self.stats.label_changes += 1
        return [(t, track, field, before, after, self.other.source, probability) for field, before, after in changed]

    # ------------------------------------------------------------------ checkpoints
    def state(self) -> dict[str, np.ndarray]:
        """The whole labelling state for a checkpoint (issue 11 item 3) as a flat dict of arrays:
        the identifier's tracks and pairs (joint filters, sequential test statistics), the other
        system's reports and how far they were taken, the labels held, the statistics
        (:mod:`skytrack.app.labeler_state`; no pickle)."""
        from skytrack.app.labeler_state import labeler_state

        return labeler_state(self)

    @classmethod
    def restore(cls, state: dict[str, np.ndarray]) -> "TrackLabeler":
        """The labeller :meth:`state` saved: labelling the same track rows afterwards gives the same labels."""
        from skytrack.app.labeler_state import read_labeler_state, restore_identifier

        config, other, rest, identifier = read_labeler_state(state)
        labeler = cls(OtherSystem(**other), float(rest["covered_area_m2"]), AdsbIdentificationConfig(**config))
        for name, value in rest.items():
            setattr(labeler, name, LabelStats(**value) if name == "stats" else value)
        restore_identifier(labeler.identifier, identifier, state)
        return labeler

    def pairs_table(self) -> pd.DataFrame:
        """Every (time, track, other track, P(same), pair) the labelling decided, for ``identify tracks``."""
        return pd.DataFrame(self.pairs_log, columns=["time", "track_id", "other_track", "identity_p", "pair"])

def typical_interval(key: np.ndarray, time: np.ndarray, default: float | None) -> float | None:
    """The median gap between consecutive reports of the same track (``default`` when there is none)."""
    gaps = pd.DataFrame({"key": key, "time": time}).groupby("key")["time"].diff().dropna()
    gaps = gaps[gaps > 0]
    return float(gaps.median()) if len(gaps) else default


class _FusedRows:
    """The joint estimates (R14 ``fusion="joint"``) of the identified rows of one chunk."""

    def __init__(self, n_rows: int):
        self.rows = np.zeros(n_rows, dtype=bool)
        self.x = np.zeros((n_rows, 4))
        self.var = np.zeros((n_rows, 4))

    def __setitem__(self, rows: np.ndarray, estimate) -> None:
        x, P = estimate
        self.rows[rows] = True
        self.x[rows] = x[:, :4]
        self.var[rows] = np.diagonal(P, axis1=1, axis2=2)[:, :4]

    def apply(self, table: pa.Table) -> pa.Table:
        columns = {}
        for k, name in enumerate(("x", "y", "vx", "vy")):
            for column, values in ((name, self.x[:, k]), ("var_" + name, self.var[:, k])):
                old = table.column(column).to_numpy().astype(float)
                columns[column] = pa.array(np.where(self.rows, values, old), pa.float64())
        return _replace(table, columns)


def _replace(table: pa.Table, columns: dict[str, pa.Array]) -> pa.Table:
    for name, array in columns.items():
        index = table.schema.get_field_index(name)
        table = table.set_column(index, pa.field(name, array.type), array)
    return table


def _events_table(events: list[tuple]) -> pa.Table | None:
    if not events:
        return None
    from skytrack.io.identity_events import EVENT_ARROW_SCHEMA

    columns = list(zip(*events))
    return pa.table([pa.array(c, type=f.type) for c, f in zip(columns, EVENT_ARROW_SCHEMA)], schema=EVENT_ARROW_SCHEMA)

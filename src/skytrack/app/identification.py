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

* its pair with the ADS-B track is assigned (Λ ≤ h = χ²⁻¹_dof(``p_correct``), dof ≥ n),
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

from skytrack.identify.identifier import IdentifierConfig, TrackIdentifier
from skytrack.identify.threshold import Threshold

#: sigma (m, per axis) of ADS-B reports that give neither sigma_m nor a NACp
DEFAULT_ADSB_SIGMA_M = 40.0


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
    """an ADS-B address silent this long ends its track (its pairs die)"""
    fuse: bool = False
    ground_speed_mps: float = 300.0
    """radius of the disc of ground velocities in the object density β of ``identity_p``"""
    batch_s: float = 1.0
    report_gate: float | None = 0.9999
    """a plot (or ADS-B report) this improbable under its own track's filter is left out"""
    recreate_after_s: float = 4.0
    """a dropped pair may be made again after this long (one scan of a 4-s radar)"""

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
                                recreate_after_s=self.recreate_after_s)


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


@dataclass(frozen=True)
class OtherSystem:
    """The second observation system's reports (spec 001's ξ): one row per report."""

    source: str
    """``adsb``, ``radar`` or ``iff``: the ``identity_source`` of the labels it gives"""
    time: np.ndarray
    key: np.ndarray
    """track of the report: the ADS-B address, or the other radar's track id (as text)"""
    z: np.ndarray
    """horizontal positions ``[N, 2]`` in the common frame"""
    V: np.ndarray
    """their covariances ``[N, 2, 2]``"""
    icao24: np.ndarray
    """address the report names (null when unknown)"""
    callsign: np.ndarray

    @property
    def keys(self) -> int:
        return len(np.unique(self.key))


def _text(values) -> np.ndarray:
    series = pd.Series(values, dtype=object)
    return series.where(series.notna(), None).to_numpy(object)


def adsb_system(adsb: pd.DataFrame) -> OtherSystem:
    """ADS-B reports (:func:`skytrack.io.read_adsb`) as the other system, tracked per address."""
    adsb = adsb.sort_values("time", kind="stable")
    sigma = adsb["sigma_m"].to_numpy(float) if "sigma_m" in adsb else np.full(len(adsb), np.nan)
    sigma = np.where(np.isfinite(sigma), sigma, DEFAULT_ADSB_SIGMA_M)
    address = adsb["icao24"].astype(str).to_numpy(object)
    callsign = adsb["callsign"] if "callsign" in adsb else [None] * len(adsb)
    return OtherSystem("adsb", adsb["time"].to_numpy(float), address, adsb[["x", "y"]].to_numpy(float),
                       sigma[:, None, None] ** 2 * np.eye(2), address, _text(callsign))


def track_system(reports: pd.DataFrame, tracks: pd.DataFrame | None, source: str = "radar") -> OtherSystem:
    """Another radar's (or an interrogator's) track reports (:func:`skytrack.io.read_track_reports`)
    as the other system; each report names the identity its track carried at that time."""
    reports = reports.sort_values("time", kind="stable").reset_index(drop=True)
    V = np.empty((len(reports), 2, 2))
    V[:, 0, 0], V[:, 1, 1] = reports["var_x"], reports["var_y"]
    V[:, 0, 1] = V[:, 1, 0] = reports["cov_xy"]
    icao24 = callsign = np.full(len(reports), None, dtype=object)
    if tracks is not None and len(tracks) and len(reports):
        labels = tracks[["time", "track_id", "icao24", "callsign"]].sort_values("time", kind="stable")
        joined = pd.merge_asof(reports[["time", "track_id"]].reset_index(), labels, on="time", by="track_id",
                               direction="backward").sort_values("index")
        icao24, callsign = _text(joined["icao24"]), _text(joined["callsign"])
    key = reports["track_id"].astype(np.int64).astype(str).to_numpy(object)
    return OtherSystem(source, reports["time"].to_numpy(float), key, reports[["x", "y"]].to_numpy(float), V,
                       icao24, callsign)


class TrackLabeler:
    """Labels tracks-table chunks with the identities another system's tracks carry, as the tracker
    produces them (ADS-B: :func:`adsb_system`; another radar or an interrogator: :func:`track_system`)."""

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
        self.labels: dict[int, tuple] = {}  # track id -> (icao24, callsign) last written
        self.pairs_log: list[tuple] = []
        self.stats = LabelStats(adsb_reports=len(other.time), adsb_addresses=other.keys)

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
        for key, address, callsign in zip(adsb_ids, other.icao24[a], other.callsign[a]):
            if address is not None or callsign is not None:
                self.label_of[key] = (address, callsign)
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
    def _decide(self, t: float) -> dict[int, tuple[str, float, int]]:
        """Radar track id -> (icao24, identity_p, pair row) of the tracks labelled at ``t``."""
        ident = self.identifier
        result = ident.assign()
        if len(result.pair) == 0:
            return {}
        pairs = ident.pairs
        ok = pairs.updates[result.pair] >= self.config.min_updates
        if self.config.unique:
            table, live = ident.pair_table()
            # a pair younger than min_updates has not yet shown it fits: it cannot make a label ambiguous
            passing = table.allowed & (pairs.updates[live] >= self.config.min_updates)
            count_first = np.bincount(table.first[passing], minlength=len(ident.track_ids))
            count_second = np.bincount(table.second[passing], minlength=len(ident.track_ids))
            ok &= (count_first[pairs.first[result.pair]] == 1) & (count_second[pairs.second[result.pair]] == 1)
        first = [ident.track_ids[i] for i in pairs.first[result.pair]]
        second = [ident.track_ids[j] for j in pairs.second[result.pair]]
        holding = np.array([self.labels.get(int(f.split(":")[1]), (None,))[0] == a.split(":")[1]
                            for f, a in zip(first, second)], dtype=bool)
        giving = Threshold(p_correct=self.config.p_correct).value(pairs.dof[result.pair])
        ok &= holding | (pairs.statistic[result.pair] <= giving)
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
        frame = table.select(["time", "track_id", "icao24", "callsign", "identity_source", "identity_p"]).to_pandas()
        icao24, callsign, source = (frame[name].astype(object).where(frame[name].notna(), None).to_numpy(object).copy()
                                    for name in ("icao24", "callsign", "identity_source"))
        probability = frame["identity_p"].to_numpy(float).copy()
        fused = _FusedRows(table.num_rows) if self.config.fuse else None
        events = []
        times = frame["time"].to_numpy(float)
        for t in np.unique(times):
            at = np.flatnonzero(times == t)
            self._advance(float(t))
            track_ids = frame["track_id"].to_numpy()[at]
            self._end_stale(float(t))
            decided = self._decide(float(t))
            name = self.other.source
            fused_now: dict[int, int] = {}
            for row, track in zip(at, track_ids.tolist()):
                label = decided.get(track)
                named = None
                if label is not None:
                    named = self.label_of.get(label[0], (label[0] if name == "adsb" else None, None))
                    self.pairs_log.append((float(t), track, label[0], label[1], label[2]))
                    if fused is not None:
                        fused_now[row] = label[2]
                if source[row] == "mode_s":
                    if named is not None and named[0] == icao24[row]:
                        callsign[row] = named[1]
                    elif named is not None and named[0] is not None:
                        self.stats.mode_s_conflicts += 1
                    new = (icao24[row], callsign[row])
                elif named is not None and (named[0] is not None or named[1] is not None):
                    icao24[row], callsign[row] = named
                    source[row], probability[row] = name, label[1]
                    new = named
                else:
                    new = (None, None) if source[row] in (None, name) else (icao24[row], callsign[row])
                if label is not None:
                    self.stats.labelled_rows += 1
                    self.stats.labelled_tracks.add(track)
                old = self.labels.get(track, (None, None))
                if source[row] != "mode_s" and new != old:
                    for field_name, before, after in (("icao24", old[0], new[0]), ("callsign", old[1], new[1])):
                        if before != after:
                            events.append((float(t), track, field_name, before, after, name,
                                           probability[row] if label is not None else None))
                    self.stats.label_changes += 1
                self.labels[track] = new
            if fused_now:
                # the pairs' joint estimates now, before later reports move them on (R14)
                rows = np.fromiter(fused_now.keys(), np.int64)
                x, P = self.identifier.pairs.joint.estimate_at(np.fromiter(fused_now.values(), np.int64),
                                                               np.full(len(rows), float(t)))
                fused[rows] = (x, P)
        table = _replace(table, {"icao24": pa.array(icao24, pa.string()), "callsign": pa.array(callsign, pa.string()),
                                 "identity_source": pa.array(source, pa.string()),
                                 "identity_p": pa.array(probability, pa.float64())})
        if fused is not None and fused.rows.any():
            table = fused.apply(table)
        return table, _events_table(events)

    def pairs_table(self) -> pd.DataFrame:
        """Every (time, track, other track, P(same), pair) the labelling decided, for ``identify tracks``."""
        return pd.DataFrame(self.pairs_log, columns=["time", "track_id", "other_track", "identity_p", "pair"])

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


def covered_area(sensor_set, adsb: pd.DataFrame) -> float:
    """The area (m²) the object density of ``identity_p`` spreads over: the radars' coverage discs,
    or, without ranges, the ADS-B reports' bounding box."""
    radii = [] if sensor_set is None else [s.max_range_m for s in sensor_set.sensors if s.is_radar and s.max_range_m]
    if radii:
        return float(sum(math.pi * r ** 2 for r in radii))
    span = adsb[["x", "y"]].max() - adsb[["x", "y"]].min()
    return float(max(span["x"], 1e4) * max(span["y"], 1e4))

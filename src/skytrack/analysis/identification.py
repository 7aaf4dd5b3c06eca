"""The identification report against truth: how well the ``icao24`` labels of a tracks table
name the aircraft that the tracks follow (spec 001 §1/§4 R13-R14 applied to the tracker;
issue 9, item 3 "identification report against truth: correct, wrong and missing
identifications, time to identify", item 7 "the identification summary" and its acceptance:
"every ADS-B-equipped aircraft tracked for 1 minute is identified correctly, no track gets a
wrong label, the offset aircraft is left unidentified or flagged, and the report says so").

:func:`identification_report` reads three FORMATS.md tables and judges, nothing more:

* ``tracks``: ``track_id, time, x, y[, z]`` with ``icao24`` (a row's label at that time, null =
  unlabelled), ``identity_source`` (``mode_s | adsb | iff | radar``, optional) and ``status``
  (optional; only ``confirmed``/``coasting`` rows count, as in :func:`~skytrack.analysis.evaluate`);
* ``truth``: ``target_id, [segment,] time, x, y[, z]``;
* ``adsb``: the reports ``time, icao24, x, y`` with ``truth_id`` (the simulator's id of the
  aircraft that transmitted; reports without it are left out, with a note).

Steps:

1. **Association.**  At every track time the rows are assigned to the truth objects that
   exist then (linear interpolation within a segment, visible or not: a labelled track of an
   aircraft that has just left coverage is not a false track) by the gated least-squares
   assignment of :func:`~skytrack.analysis.evaluate.evaluate` (:func:`metrics.cutoff_matching`,
   order 2, gate ``cutoff_m``, default :data:`~skytrack.analysis.evaluate.DEFAULT_GATE_M`),
   horizontally when the tracks have no ``z`` (2-D tracking), else in 3-D.  Then each row takes
   the object that most of its track's rows within ±3 instants are associated to
   (:func:`skytrack.analysis.row_association.smooth_along_tracks`): a one-instant swap of two tracks at a close crossing, or a
   coasting row that lags outside the gate in a turn, is not the track following another object.
2. **Addresses.**  Each address of the reports belongs to the truth object that sent most of
   its reports, unless it is some object's *own* address (below), which then owns it.  An
   object's own address comes from ``aircraft`` (``target_id, icao24``: the simulator's
   ``result.targets`` or ``result.adsb_aircraft``), else from an ``icao24`` column of the truth,
   else from its ``target_id`` when that is 6 hex digits that some report sends (recorded aircraft).  The *correct
   label* of an object is its own address when known, else the address it owns among those
   it sends (the one it sends most).  An ADS-B-equipped aircraft is a truth object with reports.
3. **Per equipped aircraft**, over its associated rows: ``t0`` = the first one, ``tracked_s``
   = last − first, ``first_correct_s`` = the first carrying its correct label,
   ``time_to_identify_s = first_correct_s − t0``; with ``t1 = t0 + min_tracked_s``,
   ``correct_fraction_after`` = the fraction of its instants at ``t ≥ t1`` at which one of its
   tracks carries the correct label (a duplicate track carrying it counts: the aircraft's
   identity is on the picture).  Status, the first rule that applies:

   - ``not tracked long enough``: ``tracked_s < min_tracked_s`` (never tracked included);
   - ``not identified``: no associated row ever carries the correct label;
   - ``late``: the correct label first appears after ``t1``;
   - ``identified``: the correct label appeared by ``t1`` and is on at least ``hold_fraction``
     (default 95 %) of its associated rows from ``t1`` on;
   - ``unstable``: it appeared by ``t1`` but is on fewer of them.
4. **Wrong labels.**  A labelled row associated to an object is *wrong* when its address is
   not the object's correct label (an object without one, e.g. not equipped and no own
   address known, has no right label).  A labelled row associated to no object is wrong when
   its label came from identification (``identity_source`` ``adsb`` or ``radar``, null or
   absent), except a *duplicate*: an object within the gate at that instant has that label
   (a second track on the same aircraft is not a wrong identity), and a track that *outlived*
   its aircraft: the label is that of the object the track last followed (a track coasting a
   scan or two after its aircraft's recording ends still names the aircraft it followed).  Mode S/IFF labels of
   unassociated rows are not judged (counted).  Wrong rows are grouped by (track, label,
   associated object); the aircraft affected are the associated objects and the owners of
   the wrong addresses.
5. **Faulty ADS-B.**  An equipped aircraft has a *position offset* when the mean horizontal
   distance between its reports and its truth at the report times exceeds
   ``offset_threshold_m`` (500 m), and a *wrong identity* when it sends an address owned by
   another object or, its own address being known, any other address.  It is *left
   unidentified* when none of its associated rows carries an address it sent with an
   ``adsb`` (or unknown) source: ADS-B's word was not taken.
6. **Totals** and the acceptance verdicts of issue 9 (:attr:`IdentificationReport.acceptance`).

Times are s, distances m.  The rich view is :func:`skytrack.cli.identification_view.identification_table`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import pandas as pd

from skytrack.analysis.checks import _require_columns, _require_finite, _require_not_null
from skytrack.analysis.evaluate import CONFIRMED_STATUSES, DEFAULT_GATE_M, _dimension
from skytrack.analysis.evaluation import _jsonable, _records
from skytrack.analysis.metrics import _candidate_pairs
from skytrack.analysis.row_association import (
    associate_rows,
    existing_objects,
    last_followed,
    smooth_along_tracks,
)
from skytrack.analysis.truth import _prepare_truth

__all__ = ["IdentificationReport", "identification_report", "STATUSES", "DEFAULT_HOLD_FRACTION",
           "DEFAULT_OFFSET_THRESHOLD_M"]

STATUSES = ("identified", "late", "unstable", "not identified", "not tracked long enough")
DEFAULT_HOLD_FRACTION = 0.95
DEFAULT_OFFSET_THRESHOLD_M = 500.0
#: identity sources whose labels come from identification (a false track with one is wrong)
IDENTIFICATION_SOURCES = ("adsb", "radar")
_HEX_ADDRESS = re.compile(r"[0-9a-f]{6}")

PER_AIRCRAFT_COLUMNS = (
    "target_id", "icao24", "callsign", "sent_icao24", "n_reports", "adsb_fault", "adsb_offset_m",
    "first_tracked_s", "last_tracked_s", "tracked_s", "tracked_long_enough", "n_tracks", "n_rows",
    "first_correct_s", "time_to_identify_s", "n_rows_after", "correct_fraction_after", "wrong_label_rows",
    "left_unidentified", "status",
)
WRONG_LABEL_COLUMNS = ("track_id", "icao24", "target_id", "label_owner", "identity_source", "n_rows",
                       "first_s", "last_s")
FAULTY_COLUMNS = ("target_id", "adsb_fault", "adsb_offset_m", "own_icao24", "sent_icao24",
                  "adsb_labelled_rows", "left_unidentified", "status")


@dataclass(frozen=True, eq=False)
class IdentificationReport:
    """Result of :func:`identification_report` (see the module docstring for every rule).

    * ``per_aircraft``: one row per ADS-B-equipped aircraft (:data:`PER_AIRCRAFT_COLUMNS`);
    * ``wrong_labels``: one row per (track, wrong label, associated object or null);
    * ``adsb_faulty``: one row per equipped aircraft with a position offset or a wrong identity;
    * ``totals``: the counts and times (``equipped_aircraft``, ``tracked_long_enough``,
      ``identified``, ``late``, ``unstable``, ``not_identified``, ``not_tracked_long_enough``,
      ``wrong_label_rows``/``_tracks``/``_aircraft``, ``median``/``max_time_to_identify_s``, ...);
    * ``findings``: one sentence per problem (faulty ADS-B, wrong labels, aircraft not identified);
    * ``parameters``, ``dimension`` and ``notes`` (rows left out and why).
    """

    parameters: dict[str, Any]
    dimension: str
    totals: dict[str, Any]
    per_aircraft: pd.DataFrame
    wrong_labels: pd.DataFrame
    adsb_faulty: pd.DataFrame
    findings: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def acceptance(self) -> dict[str, bool]:
        """Issue 9's acceptance on this run, in its words: every sound (not faulty) equipped aircraft
        tracked for ``min_tracked_s`` is identified correctly (its correct label by then: status
        ``identified`` or ``unstable``; how well the label is then held is reported beside it, in
        ``totals["sound_label_held"]``), no wrong label, every faulty aircraft left unidentified."""
        frame = self.per_aircraft
        sound = frame[frame["adsb_fault"].isna() & frame["tracked_long_enough"]]
        identified = sound["status"].isin(["identified", "unstable"])
        return {
            "every sound equipped aircraft tracked long enough is identified": bool(identified.all()),
            "no track row has a wrong label": self.totals["wrong_label_rows"] == 0,
            "every aircraft with faulty ADS-B is left unidentified": bool(self.adsb_faulty["left_unidentified"].all()),
        }

    @property
    def passed(self) -> bool:
        return all(self.acceptance.values())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: parameters, dimension, totals, acceptance, per-aircraft, wrong labels,
        faulty ADS-B, findings and notes (NaN as null)."""
        return _jsonable({
            "parameters": self.parameters,
            "dimension": self.dimension,
            "totals": self.totals,
            "acceptance": self.acceptance,
            "passed": self.passed,
            "per_aircraft": _records(self.per_aircraft),
            "wrong_labels": _records(self.wrong_labels),
            "adsb_faulty": _records(self.adsb_faulty),
            "findings": list(self.findings),
            "notes": list(self.notes),
        })


# --------------------------------------------------------------------------- inputs


def _addresses(values) -> np.ndarray:
    """Labels as lower-case stripped strings, None for null or empty."""
    text = pd.Series(values, dtype=object).astype("string").str.strip().str.lower().fillna("")
    out = text.to_numpy(dtype=object)
    out[out == ""] = None
    return out


def _texts(values) -> pd.Series:
    """A text column that keeps None for missing values (pandas would otherwise infer a string
    dtype with NaN), so that tables and JSON read ``None``."""
    return pd.Series(list(values), dtype=object)


def _sources(tracks: pd.DataFrame) -> np.ndarray:
    if "identity_source" not in tracks.columns:
        return np.full(len(tracks), None, dtype=object)
    return _addresses(tracks["identity_source"].to_numpy(dtype=object))


def _is_source(source: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """Whether each row's identity source is one of ``names`` or unknown (null)."""
    return pd.Series(source, dtype=object).isin(list(names)).to_numpy() | pd.isna(source)


def identification_source_of(source: np.ndarray) -> np.ndarray:
    """Rows whose label came from identification (not from the aircraft's own Mode S/IFF replies)."""
    return _is_source(source, IDENTIFICATION_SOURCES)


def _own_addresses(target_ids: np.ndarray, truth: pd.DataFrame, aircraft: pd.DataFrame | None,
                   sent: set[str]) -> np.ndarray:
    """Each truth object's own address, None when unknown (module docstring, step 2).  A target id
    of 6 hex digits counts as an address only when some ADS-B report sends it: a simulated id such
    as "AC0001" is hex too but names nothing."""
    index = pd.Index(target_ids.astype(str))
    ids = _addresses(target_ids)
    own = np.array([a if a is not None and _HEX_ADDRESS.fullmatch(a) and a in sent else None for a in ids],
                   dtype=object)
    tables = []
    if "icao24" in truth.columns:
        tables.append(truth[["target_id", "icao24"]])
    if aircraft is not None:
        _require_columns(aircraft, "aircraft", ["target_id", "icao24"])
        tables.append(aircraft[["target_id", "icao24"]])
    for table in tables:  # the aircraft table is applied last: it wins
        address = _addresses(table["icao24"].to_numpy(dtype=object))
        code = index.get_indexer(table["target_id"].astype(str))
        valid = (code >= 0) & np.array([a is not None for a in address], dtype=bool)
        own[code[valid]] = address[valid]
    return own


@dataclass
class _Adsb:
    """ADS-B per truth object (arrays over the truth's target codes) and the address owners."""

    n_reports: np.ndarray
    label: np.ndarray  # object: correct label
    own: np.ndarray  # object: own address or None
    sent: list[list[str]]  # addresses sent, most used first
    callsign: np.ndarray  # object: most sent callsign
    offset_m: np.ndarray  # mean horizontal report-to-truth distance, NaN without reports
    wrong_identity: np.ndarray
    owner: dict[str, int]  # address -> target code


def _truth_xy_at(prepared, code: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Truth (x, y) of object ``code`` at ``time`` (linear within a segment), NaN outside its segments."""
    out = np.full((time.size, 2), np.nan)
    n_rows = prepared.time.size
    if n_rows == 0 or time.size == 0:
        return out
    # one sorted key over (object, time): objects are spaced farther apart than any time span
    t0 = min(prepared.time.min(), time.min())
    width = max(prepared.time.max(), time.max()) - t0 + 1.0
    row_key = prepared.target_code * width + (prepared.time - t0)
    order = np.argsort(row_key, kind="stable")
    key = row_key[order]
    query = code * width + (time - t0)
    right = np.searchsorted(key, query, side="left")
    exact = (right < n_rows) & (key[np.minimum(right, n_rows - 1)] == query)
    left = np.where(exact, right, right - 1)
    valid = (left >= 0) & (right < n_rows)
    left_row = order[np.clip(left, 0, n_rows - 1)]
    right_row = order[np.clip(right, 0, n_rows - 1)]
    valid &= prepared.segment_code[left_row] == prepared.segment_code[right_row]
    span = prepared.time[right_row] - prepared.time[left_row]
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = np.where(span > 0, (time - prepared.time[left_row]) / span, 0.0)
    xy = prepared.frame[["x", "y"]].to_numpy(dtype=float)
    values = xy[left_row] + weight[:, None] * (xy[right_row] - xy[left_row])
    out[valid] = values[valid]
    return out


def _adsb_identities(adsb: pd.DataFrame, prepared, own: np.ndarray, notes: list[str]) -> _Adsb:
    n_targets = prepared.target_ids.size
    truth_id = adsb["truth_id"]
    known_id = truth_id.notna().to_numpy() & (truth_id.astype(str).str.strip() != "").to_numpy()
    code = np.full(len(adsb), -1, np.int64)
    code[known_id] = pd.Index(prepared.target_ids.astype(str)).get_indexer(truth_id[known_id].astype(str))
    address = _addresses(adsb["icao24"].to_numpy(dtype=object))
    usable = (code >= 0) & np.array([a is not None for a in address], dtype=bool)
    if not usable.all():
        notes.append(f"{int((~usable).sum())} of {len(adsb)} ADS-B reports left out (no truth_id, a truth_id "
                     "that is not in the truth, or no icao24)")
    code, address = code[usable], address[usable]
    counts = (pd.DataFrame({"code": code, "address": address}).groupby(["code", "address"]).size()
              .rename("n").reset_index().sort_values(["n", "code", "address"], ascending=[False, True, True]))
    # the object that sent most reports of an address owns it, unless it is someone's own address
    owner = dict(zip(counts.drop_duplicates("address")["address"], counts.drop_duplicates("address")["code"]))
    owner.update({a: k for k, a in enumerate(own.tolist()) if a is not None})
    sent: list[list[str]] = [[] for _ in range(n_targets)]
    for k, a in zip(counts["code"].to_numpy(), counts["address"].to_numpy()):
        sent[int(k)].append(a)
    label = own.copy()
    wrong_identity = np.zeros(n_targets, dtype=bool)
    for k in range(n_targets):  # per aircraft, not per report
        owned = [a for a in sent[k] if owner[a] == k]
        if label[k] is None and owned:
            label[k] = owned[0]
        wrong_identity[k] = len(owned) < len(sent[k]) or (own[k] is not None and any(a != own[k] for a in sent[k]))
    n_reports = np.bincount(code, minlength=n_targets)
    callsign = np.full(n_targets, None, dtype=object)
    if "callsign" in adsb.columns:
        names = pd.Series(adsb["callsign"].to_numpy(dtype=object)[usable], dtype=object)
        named = names.notna().to_numpy() & (names.astype(str).str.strip() != "").to_numpy()
        if named.any():
            most = (pd.DataFrame({"code": code[named], "callsign": names[named].astype(str).str.strip().to_numpy()})
                    .groupby(["code", "callsign"]).size().rename("n").reset_index()
                    .sort_values(["n", "callsign"], ascending=[False, True]).drop_duplicates("code"))
            callsign[most["code"].to_numpy()] = most["callsign"].to_numpy()
    xy = adsb[["x", "y"]].to_numpy(dtype=float)[usable]
    truth_xy = _truth_xy_at(prepared, code, adsb["time"].to_numpy(dtype=float)[usable])
    distance = np.hypot(*(xy - truth_xy).T) if xy.size else np.zeros(0)
    inside = np.isfinite(distance)
    if (~inside).any():
        notes.append(f"{int((~inside).sum())} ADS-B reports outside their aircraft's truth span are not in the "
                     "position-offset means")
    with np.errstate(invalid="ignore", divide="ignore"):
        offset = (np.bincount(code[inside], weights=distance[inside], minlength=n_targets)
                  / np.bincount(code[inside], minlength=n_targets))
    return _Adsb(n_reports, label, own, sent, callsign, offset, wrong_identity, owner)


# --------------------------------------------------------------------------- association


# --------------------------------------------------------------------------- the report


def identification_report(
    tracks: pd.DataFrame,
    truth: pd.DataFrame,
    adsb: pd.DataFrame,
    *,
    min_tracked_s: float = 60.0,
    cutoff_m: float | None = None,
    hold_fraction: float = DEFAULT_HOLD_FRACTION,
    offset_threshold_m: float = DEFAULT_OFFSET_THRESHOLD_M,
    aircraft: pd.DataFrame | None = None,
    confirmed_statuses: Sequence[str] = CONFIRMED_STATUSES,
    time_tolerance_s: float = 1e-3,
) -> IdentificationReport:
    """Score the ``icao24`` labels of ``tracks`` against ``truth`` and the ADS-B ``adsb`` reports.

    Every rule is in the module docstring.  ``min_tracked_s``: how long an aircraft must be
    tracked before it must be identified (issue 9: 1 minute); ``cutoff_m``: track-to-truth gate
    (default :data:`~skytrack.analysis.evaluate.DEFAULT_GATE_M`); ``hold_fraction``: the share of
    rows from ``t1`` on that must carry the correct label; ``offset_threshold_m``: the mean
    report-to-truth distance that makes a position-offset fault; ``aircraft``: optional
    ``target_id, icao24`` table of own addresses.
    """
    notes: list[str] = []
    cutoff = float(DEFAULT_GATE_M if cutoff_m is None else cutoff_m)
    if not (np.isfinite(cutoff) and cutoff > 0):
        raise ValueError(f"cutoff_m must be a finite positive distance, got {cutoff_m!r}")
    if not (np.isfinite(min_tracked_s) and min_tracked_s >= 0):
        raise ValueError(f"min_tracked_s must be a finite time >= 0, got {min_tracked_s!r}")
    if not 0.0 <= hold_fraction <= 1.0:
        raise ValueError(f"hold_fraction must be in [0, 1], got {hold_fraction!r}")
    _require_columns(tracks, "tracks", ["time", "track_id", "x", "y"])
    _require_not_null(tracks, "tracks", "track_id")
    _require_finite(tracks, "tracks", ["time"])
    _require_columns(adsb, "adsb", ["time", "icao24", "x", "y", "truth_id"])
    _require_finite(adsb, "adsb", ["time", "x", "y"])
    if "icao24" not in tracks.columns:
        notes.append("tracks have no icao24 column: every row is unlabelled")
    if "status" in tracks.columns:
        confirmed = tracks["status"].isin(list(confirmed_statuses)).to_numpy()
        if not confirmed.all():
            notes.append(f"{int((~confirmed).sum())} track rows ignored (status not in {list(confirmed_statuses)})")
        tracks = tracks[confirmed]
    tracks = tracks.reset_index(drop=True)
    dim, dimension = _dimension(tracks, None)
    axes = ["x", "y", "z"][:dim]
    _require_finite(tracks, "tracks", axes)
    prepared, truth_notes = _prepare_truth(truth, axes, [])
    notes += [n for n in truth_notes if "visible" not in n]  # visibility is not used here
    own = _own_addresses(prepared.target_ids, truth, aircraft,
                         {a for a in _addresses(adsb["icao24"].to_numpy(dtype=object)).tolist() if a is not None})
    ads = _adsb_identities(adsb, prepared, own, notes)

    row_target, step, position, t_target, t_step, t_pos = associate_rows(tracks, prepared, axes, cutoff, time_tolerance_s)
    times = tracks["time"].to_numpy(dtype=float)
    track_id = tracks["track_id"].to_numpy()
    row_target = existing_objects(step, smooth_along_tracks(row_target, track_id, times), t_step, t_target)
    last_object = last_followed(row_target, track_id, times)
    label = _addresses(tracks["icao24"].to_numpy(dtype=object)) if "icao24" in tracks.columns \
        else np.full(len(tracks), None, dtype=object)
    source = _sources(tracks)
    # addresses as integer codes (-1 = none) so that every comparison below is vectorised
    vocabulary = pd.Index(sorted({a for a in label.tolist() if a is not None}
                                 | {a for a in ads.label.tolist() if a is not None} | set(ads.owner)))
    row_code = vocabulary.get_indexer(label).astype(np.int64)
    target_code = vocabulary.get_indexer(ads.label).astype(np.int64)

    labelled = row_code >= 0
    associated = row_target >= 0
    correct = associated & labelled & (row_code == target_code[np.maximum(row_target, 0)])
    # a Mode S/IFF label is the aircraft's own reply: wrong only against a known own address
    no_own = np.array([a is None for a in ads.own], dtype=bool)
    own_reply_unknown = associated & labelled & ~identification_source_of(source) & no_own[np.maximum(row_target, 0)]
    wrong_associated = associated & labelled & ~correct & ~own_reply_unknown
    identification_source = _is_source(source, IDENTIFICATION_SOURCES)
    loose = np.flatnonzero(~associated & labelled)
    duplicate = np.zeros(len(tracks), dtype=bool)
    served = np.zeros(len(tracks), dtype=bool)  # the aircraft's label is on a duplicate track at that instant
    if loose.size and t_step.size:
        i, j, _ = _candidate_pairs(t_step, t_pos, step[loose], position[loose], cutoff)
        same = target_code[t_target[i]] == row_code[loose][j]
        duplicate[loose[j[same]]] = True
        width = int(step.max(initial=0)) + 1
        served = associated & np.isin(row_target * width + step, t_target[i[same]] * width + step[loose[j[same]]])
    # a track that outlives its aircraft by a few instants still names the aircraft it followed
    outlived = ~associated & labelled & ~duplicate & (row_code == target_code[np.maximum(last_object, 0)]) \
        & (last_object >= 0)
    loose_mask = ~associated & labelled & ~duplicate & ~outlived
    wrong = wrong_associated | (loose_mask & identification_source)
    unjudged = (loose_mask & ~identification_source) | (own_reply_unknown & ~correct)
    if unjudged.any():
        notes.append(f"{int(unjudged.sum())} labelled rows carry a Mode S/IFF label of a false track or of an "
                     "aircraft whose own address is unknown: not judged")

    per_aircraft, adsb_labelled = _per_aircraft(prepared, ads, row_target, times, track_id, correct | served, wrong,
                                                row_code, source,
                                 vocabulary, min_tracked_s, hold_fraction, offset_threshold_m, time_tolerance_s)
    wrong_labels = _wrong_label_table(tracks, label, source, row_target, prepared, ads, wrong)
    faulty = per_aircraft.loc[per_aircraft["adsb_fault"].notna(),
                              ["target_id", "adsb_fault", "adsb_offset_m", "sent_icao24", "left_unidentified",
                               "status"]].reset_index(drop=True)
    code_of = pd.Index(prepared.target_ids.astype(str)).get_indexer(faulty["target_id"])
    faulty.insert(3, "own_icao24", _texts(own[code_of]))
    faulty.insert(5, "adsb_labelled_rows", adsb_labelled[per_aircraft["adsb_fault"].notna().to_numpy()])
    faulty = faulty[list(FAULTY_COLUMNS)]

    totals = _totals(per_aircraft, wrong_labels, faulty, len(tracks), associated, labelled, correct, wrong,
                     duplicate, unjudged, prepared)
    parameters = {"min_tracked_s": float(min_tracked_s), "cutoff_m": cutoff, "hold_fraction": float(hold_fraction),
                  "offset_threshold_m": float(offset_threshold_m), "confirmed_statuses": list(confirmed_statuses),
                  "time_tolerance_s": float(time_tolerance_s)}
    findings = _findings(per_aircraft, wrong_labels, faulty, min_tracked_s)
    return IdentificationReport(parameters, dimension, totals, per_aircraft, wrong_labels, faulty,
                                tuple(findings), tuple(notes))


def _per_aircraft(prepared, ads: _Adsb, row_target, times, track_id, correct, wrong, row_code, source, vocabulary,
                  min_tracked_s, hold_fraction, offset_threshold_m, tolerance) -> tuple[pd.DataFrame, np.ndarray]:
    """The per-aircraft table (equipped aircraft only) and each one's rows labelled from its ADS-B."""
    n_targets = prepared.target_ids.size
    inf = np.inf
    on = row_target >= 0
    target, t = row_target[on], times[on]
    first = np.full(n_targets, inf)
    last = np.full(n_targets, -inf)
    np.minimum.at(first, target, t)
    np.maximum.at(last, target, t)
    first_correct = np.full(n_targets, inf)
    np.minimum.at(first_correct, target[correct[on]], t[correct[on]])
    deadline = first + min_tracked_s
    # per instant: the aircraft is labelled when any of its tracks there carries its label
    instants = pd.DataFrame({"target": target, "t": t, "correct": correct[on]}).groupby(
        ["target", "t"], sort=False)["correct"].any().reset_index()
    i_target, i_correct = instants["target"].to_numpy(np.int64), instants["correct"].to_numpy(bool)
    after = instants["t"].to_numpy(float) >= deadline[i_target] - tolerance
    n_after = np.bincount(i_target[after], minlength=n_targets)
    correct_after = np.bincount(i_target[after & i_correct], minlength=n_targets)
    n_rows = np.bincount(target, minlength=n_targets)
    wrong_rows = np.bincount(target[wrong[on]], minlength=n_targets)
    pairs = pd.DataFrame({"target": target, "track": track_id[on]}).drop_duplicates()
    n_tracks = np.bincount(pairs["target"].to_numpy(np.int64), minlength=n_targets)
    # ADS-B's word taken: a row carrying an address the aircraft sent, from adsb (or unknown) identification
    width = len(vocabulary) + 1  # (aircraft, address) pairs as one integer key
    sent_keys = np.concatenate([k * width + vocabulary.get_indexer(s) for k, s in enumerate(ads.sent)] + [[]])
    takes_adsb = np.isin(target * width + row_code[on], sent_keys) & (row_code[on] >= 0)
    from_adsb = _is_source(source, ["adsb"])[on]
    adsb_labelled = np.bincount(target[takes_adsb & from_adsb], minlength=n_targets)

    tracked = np.isfinite(first)
    tracked_s = np.where(tracked, last - first, 0.0)
    long_enough = tracked & (tracked_s >= min_tracked_s - tolerance)
    has_correct = np.isfinite(first_correct)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(n_after > 0, correct_after / n_after, np.nan)
        to_identify = np.where(has_correct, first_correct - first, np.nan)
    status = np.select(
        [~long_enough, ~has_correct, first_correct > deadline + tolerance, fraction >= hold_fraction],
        ["not tracked long enough", "not identified", "late", "identified"], "unstable").astype(object)
    offset_fault = ads.offset_m > offset_threshold_m
    fault = np.array([", ".join(name for name, on_k in (("position offset", o), ("wrong identity", w)) if on_k) or None
                      for o, w in zip(offset_fault, ads.wrong_identity)], dtype=object)
    equipped = np.flatnonzero(ads.n_reports > 0)
    nan_if = lambda ok, values: np.where(ok, values, np.nan)  # noqa: E731
    frame = pd.DataFrame({
        "target_id": prepared.target_ids.astype(str),
        "icao24": _texts(ads.label),
        "callsign": _texts(ads.callsign),
        "sent_icao24": _texts([",".join(s) for s in ads.sent]),
        "n_reports": ads.n_reports,
        "adsb_fault": _texts(fault),
        "adsb_offset_m": ads.offset_m,
        "first_tracked_s": nan_if(tracked, first),
        "last_tracked_s": nan_if(tracked, last),
        "tracked_s": tracked_s,
        "tracked_long_enough": long_enough,
        "n_tracks": n_tracks,
        "n_rows": n_rows,
        "first_correct_s": nan_if(has_correct, first_correct),
        "time_to_identify_s": to_identify,
        "n_rows_after": n_after,
        "correct_fraction_after": fraction,
        "wrong_label_rows": wrong_rows,
        "left_unidentified": adsb_labelled == 0,
        "status": _texts(status),
    }).iloc[equipped].reset_index(drop=True)
    return frame[list(PER_AIRCRAFT_COLUMNS)], adsb_labelled[equipped]


def _wrong_label_table(tracks, label, source, row_target, prepared, ads: _Adsb, wrong) -> pd.DataFrame:
    rows = np.flatnonzero(wrong)
    ids = prepared.target_ids.astype(str)
    owner = np.array([ads.owner.get(a, -1) for a in label[rows]], dtype=np.int64)
    frame = pd.DataFrame({
        "track_id": tracks["track_id"].to_numpy()[rows],
        "icao24": label[rows].astype(object),
        "target_id": np.array([ids[k] if k >= 0 else None for k in row_target[rows]], dtype=object),
        "label_owner": np.array([ids[k] if k >= 0 else None for k in owner], dtype=object),
        "identity_source": source[rows].astype(object),
        "time": tracks["time"].to_numpy(dtype=float)[rows],
    })
    keys = ["track_id", "icao24", "target_id", "label_owner", "identity_source"]
    grouped = (frame.groupby(keys, dropna=False, sort=True)
               .agg(n_rows=("time", "size"), first_s=("time", "min"), last_s=("time", "max")).reset_index())
    grouped = grouped.astype({k: object for k in keys[1:]})
    grouped[keys[1:]] = grouped[keys[1:]].where(grouped[keys[1:]].notna(), None)
    return grouped[list(WRONG_LABEL_COLUMNS)].sort_values(["first_s", "track_id"]).reset_index(drop=True)


def _totals(per_aircraft, wrong_labels, faulty, n_rows, associated, labelled, correct, wrong, duplicate, unjudged,
            prepared) -> dict[str, Any]:
    status = per_aircraft["status"]
    got_label = per_aircraft[status.isin(["identified", "late", "unstable"])]["time_to_identify_s"]
    affected = set(wrong_labels["target_id"].dropna()) | set(wrong_labels["label_owner"].dropna())
    sound = per_aircraft["adsb_fault"].isna() & per_aircraft["tracked_long_enough"]
    return {
        "equipped_aircraft": len(per_aircraft),
        "tracked_long_enough": int(per_aircraft["tracked_long_enough"].sum()),
        "identified": int((status == "identified").sum()),
        "late": int((status == "late").sum()),
        "unstable": int((status == "unstable").sum()),
        "not_identified": int((status == "not identified").sum()),
        "not_tracked_long_enough": int((status == "not tracked long enough").sum()),
        "sound_tracked_long_enough": int(sound.sum()),
        "sound_identified": int((sound & np.isin(status, ["identified", "unstable"])).sum()),
        "sound_label_held": int((sound & (status == "identified")).sum()),
        "adsb_faulty_aircraft": len(faulty),
        "adsb_faulty_left_unidentified": int(faulty["left_unidentified"].sum()),
        "median_time_to_identify_s": float(got_label.median()) if len(got_label) else None,
        "max_time_to_identify_s": float(got_label.max()) if len(got_label) else None,
        "track_rows": int(n_rows),
        "associated_rows": int(associated.sum()),
        "false_track_rows": int((~associated).sum()),
        "labelled_rows": int(labelled.sum()),
        "correct_label_rows": int(correct.sum()),
        "wrong_label_rows": int(wrong.sum()),
        "wrong_label_tracks": int(wrong_labels["track_id"].nunique()),
        "wrong_label_aircraft": len(affected),
        "wrong_label_aircraft_ids": sorted(affected),
        "duplicate_label_rows": int(duplicate.sum()),
        "unjudged_label_rows": int(unjudged.sum()),
        "truth_objects": int(prepared.target_ids.size),
    }


def _fmt_s(value) -> str:
    return "-" if value is None or not np.isfinite(value) else f"{value:.0f} s"


def _findings(per_aircraft, wrong_labels, faulty, min_tracked_s) -> list[str]:
    lines = []
    for row in faulty.itertuples(index=False):
        what = [f"ADS-B positions {row.adsb_offset_m:.0f} m from its truth"] if "offset" in row.adsb_fault else []
        if "identity" in row.adsb_fault:
            what.append(f"sends {row.sent_icao24}" + (f" (own address {row.own_icao24})" if isinstance(row.own_icao24, str) else "")
                        + " (wrong identity)")
        outcome = "left unidentified" if row.left_unidentified else \
            f"NOT left unidentified: {row.adsb_labelled_rows} rows carry its ADS-B address"
        lines.append(f"{row.target_id}: faulty ADS-B, {'; '.join(what)}: {outcome}")
    for row in wrong_labels.itertuples(index=False):
        on = f"aircraft {row.target_id}" if isinstance(row.target_id, str) else "a false track"
        owner = f" (address of {row.label_owner})" if isinstance(row.label_owner, str) else ""
        lines.append(f"track {row.track_id} ({on}) wrongly labelled {row.icao24}{owner} on {row.n_rows} rows, "
                     f"{row.first_s:.0f}-{row.last_s:.0f} s")
    problems = per_aircraft[per_aircraft["adsb_fault"].isna() & per_aircraft["tracked_long_enough"]
                            & (per_aircraft["status"] != "identified")]
    for row in problems.itertuples(index=False):
        lines.append(f"{row.target_id} ({row.icao24}): {row.status}; tracked {row.tracked_s:.0f} s, time to identify "
                     f"{_fmt_s(row.time_to_identify_s)}, correct label on {row.correct_fraction_after:.0%} of its "
                     f"rows from {min_tracked_s:g} s after first tracked")
    return lines

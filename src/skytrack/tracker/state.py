"""A tracker's whole state as plain arrays, and a tracker rebuilt from them (issue 11 item 3:
checkpoints of the live service).

:func:`tracker_state` gathers everything a :class:`~skytrack.tracker.tracker.Tracker` has learnt
or holds between two ``feed`` calls into a flat ``{name: numpy array}`` dict plus a small
JSON-able dict; :func:`restore_tracker_state` writes them into a tracker newly built from the
same sensors and configuration.  What is saved:

* the track bank: every filter state field of every live track (a Kalman filter's ``x``/``P``,
  the psi switch's memory, an IMM's mixture ``x``/``P``/``mu``, the adaptive filters' noise
  estimators...) and every bank column (track ids, statuses, M-of-N bits, scores, identities);
* the scan processor's next track id, each radar's clutter map (``grid`` and ``params``), its
  learned SSR code counts and the score thresholds cached from them (with their age, so the
  restored tracker refreshes them at the same window as the original);
* the schedule (beam phases, last plot times, next windows, warnings), the output clock, the
  plots fed but not yet processed (the open windows) with their converted positions;
* the track rows and identity events produced but not yet drained, the assignment log when it
  is recorded, the statistics counters and the count of rows fed.

Nothing is derived from the data alone outside these: the filter, scorer, assigner, measurement
models and compiled-kernel settings are rebuilt from the configuration.  A restored tracker fed
the same plots produces the same tracks to the last bit (tests/tracker/test_tracker_checkpoint.py).
"""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np

from skytrack.core.plots import PlotBatch
from skytrack.models.conversion import ConvertedPlots

#: version of the layout below; a checkpoint of another version is refused
STATE_FORMAT = 1


def _dataclass_arrays(prefix: str, value) -> dict[str, np.ndarray]:
    """Copies of the array fields of a dataclass of arrays (``None`` fields are left out)."""
    return {f"{prefix}.{f.name}": np.array(getattr(value, f.name), copy=True) for f in dataclasses.fields(value)
            if getattr(value, f.name) is not None}


def _dataclass_from(prefix: str, cls, arrays: dict[str, np.ndarray]):
    values = {}
    for f in dataclasses.fields(cls):
        key = f"{prefix}.{f.name}"
        if key in arrays:
            values[f.name] = np.array(arrays[key])
        elif f.default is None:
            values[f.name] = None
        else:
            raise ValueError(f"tracker state lacks {key!r}")
    return cls(**values)


def _records_arrays(prefix: str, records: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """A list of same-keyed records of row arrays, joined into one record (rows kept in order)."""
    if not records:
        return {}
    return {f"{prefix}.{name}": np.concatenate([r[name] for r in records]) for name in records[0]}


def _records_from(prefix: str, arrays: dict[str, np.ndarray]) -> list[dict[str, np.ndarray]]:
    record = {k[len(prefix) + 1:]: np.array(v) for k, v in arrays.items() if k.startswith(prefix + ".")}
    return [record] if record else []


def tracker_state(tracker) -> tuple[dict[str, np.ndarray], dict]:
    """``(arrays, meta)``: the tracker's state as a flat dict of arrays and a JSON-able dict.

    Every array is a copy: the snapshot stays as it was while the tracker goes on (a writer
    thread may save it)."""
    bank, scan, schedule = tracker.bank, tracker.scan, tracker.schedule
    scoring = scan.scoring
    arrays: dict[str, np.ndarray] = {}
    arrays.update(_dataclass_arrays("bank.state", bank.state))
    arrays.update({f"bank.column.{name}": column.copy() for name, column in bank.columns.items()})
    for s, clutter_map in enumerate(scoring.maps):
        arrays[f"scoring.{s}.grid"] = clutter_map.grid.copy()
        arrays[f"scoring.{s}.params"] = clutter_map.params.copy()
        arrays[f"scoring.{s}.code_counts"] = np.array(scoring.code_counts[s])
        cache = scoring._cache[s]
        if cache is not None:
            arrays[f"scoring.{s}.cache_ssr"] = np.array(cache[0])
            arrays[f"scoring.{s}.cache_thresholds"] = np.array(cache[1:], dtype=float)
    for name in ("phase", "last_time", "seen", "next_window"):
        arrays[f"schedule.{name}"] = np.array(getattr(schedule, name))
    arrays.update(_dataclass_arrays("pending", tracker.pending))
    arrays.update(_dataclass_arrays("pending_converted", tracker.pending_converted))
    arrays.update(_records_arrays("outputs", tracker.outputs))
    arrays.update(_records_arrays("identity_events", tracker.identity_events.parts))
    log = scan.assignment_log
    if log:
        for k, name in enumerate(("track_id", "time", "sensor", "position", "covariance")):
            arrays[f"assignment_log.{name}"] = np.concatenate([entry[k] for entry in log])
    meta = {
        "state_format": STATE_FORMAT,
        "filter_state_type": type(bank.storage).__name__,
        "columns": list(bank.column_storage),
        "sensors": len(scoring.maps),
        "scoring_age": [int(a) for a in scoring._age],
        "next_track_id": int(scan.next_track_id),
        "clock_next": tracker.clock.next,
        "warnings": list(schedule.warnings),
        "rows_fed": int(tracker.rows_fed),
        "last_window_end": float(tracker.last_window_end),
        "identity_seen": bool(tracker.identity_seen),
        "identity_events_count": int(tracker.identity_events.count),
        "recording_assignments": log is not None,
        "stats": {str(k): int(v) for k, v in tracker.stats.items()},
    }
    return arrays, meta


def restore_tracker_state(tracker, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """Write what :func:`tracker_state` saved into ``tracker``, newly built from the same sensors
    and configuration (raises ``ValueError`` naming what does not fit)."""
    if meta.get("state_format") != STATE_FORMAT:
        raise ValueError(f"tracker state format {meta.get('state_format')!r} is not {STATE_FORMAT}")
    bank, scan, schedule = tracker.bank, tracker.scan, tracker.schedule
    scoring = scan.scoring
    state_type = type(bank.storage)
    if meta["filter_state_type"] != state_type.__name__:
        raise ValueError(f"tracker state holds {meta['filter_state_type']} filter states; this tracker's filter "
                         f"keeps {state_type.__name__}")
    if meta["columns"] != list(bank.column_storage):
        raise ValueError(f"tracker state has track bank columns {meta['columns']}, this tracker "
                         f"{list(bank.column_storage)}")
    if meta["sensors"] != len(scoring.maps):
        raise ValueError(f"tracker state is of {meta['sensors']} sensors, this tracker has {len(scoring.maps)}")
    bank.state = _dataclass_from("bank.state", state_type, arrays)
    for name, column in bank.column_storage.items():
        column[: bank.size] = arrays[f"bank.column.{name}"]
    for s, clutter_map in enumerate(scoring.maps):
        grid, params = arrays[f"scoring.{s}.grid"], arrays[f"scoring.{s}.params"]
        if grid.shape != clutter_map.grid.shape:
            raise ValueError(f"tracker state: clutter map of sensor {s} has {grid.shape[1:]} cells, the configuration "
                             f"{clutter_map.grid.shape[1:]}")
        clutter_map.grid[...] = grid
        clutter_map.params[...] = params
        scoring.code_counts[s] = np.array(arrays[f"scoring.{s}.code_counts"])
        if f"scoring.{s}.cache_ssr" in arrays:
            confirm, drop = (float(v) for v in arrays[f"scoring.{s}.cache_thresholds"])
            scoring._cache[s] = (np.array(arrays[f"scoring.{s}.cache_ssr"]), confirm, drop)
        else:
            scoring._cache[s] = None
        scoring._age[s] = int(meta["scoring_age"][s])
    for name in ("phase", "last_time", "seen", "next_window"):
        getattr(schedule, name)[...] = arrays[f"schedule.{name}"]
    schedule.warnings[:] = meta["warnings"]
    scan.next_track_id = int(meta["next_track_id"])
    tracker.clock.next = None if meta["clock_next"] is None else float(meta["clock_next"])
    tracker.pending = _dataclass_from("pending", PlotBatch, arrays)
    tracker.pending_converted = _dataclass_from("pending_converted", ConvertedPlots, arrays)
    tracker.outputs = _records_from("outputs", arrays)
    tracker.identity_events.parts = _records_from("identity_events", arrays)
    tracker.identity_events.count = int(meta["identity_events_count"])
    if meta["recording_assignments"]:
        entry = tuple(np.array(arrays[f"assignment_log.{name}"]) for name in
                      ("track_id", "time", "sensor", "position", "covariance")
                      if f"assignment_log.{name}" in arrays)
        scan.assignment_log = [entry] if len(entry) == 5 else []
    else:
        scan.assignment_log = None
    tracker.rows_fed = int(meta["rows_fed"])
    tracker.last_window_end = float(meta["last_window_end"])
    tracker.identity_seen = bool(meta["identity_seen"])
    # the tracker's components share one Counter: fill it in place
    tracker.stats.clear()
    tracker.stats.update(Counter({k: int(v) for k, v in meta["stats"].items()}))

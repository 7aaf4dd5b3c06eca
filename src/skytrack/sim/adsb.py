"""Simulated ADS-B reports from truth, and the scenario's ``adsb`` section (issue 9, item 1).

These are the reports η_μ of the second observation system of spec 001 (§1, (0a)/(1):
a position measured with zero-mean Gaussian error of covariance V_η, at the system's own
instants t_μ), with the faults that the identification must survive: a position offset
(a report that (1) does not describe: H X + ε with a constant bias), a wrong or missing
identity, dropouts.  Nothing here decides anything; :mod:`skytrack.identify` does.

:func:`simulate_adsb` turns a truth table (FORMATS.md "truth": ``time``, ``target_id``,
optional ``segment``, ``x, y``, ``alt_m``, ``vx, vy, vz``; linear interpolation between
the rows of a segment) into reports (FORMATS.md "adsb" plus ``truth_id``):

* times: every ``interval_s`` from a phase uniform in [0, interval_s) per aircraft, each
  moved by a jitter uniform in [-jitter_s, jitter_s], inside the aircraft's truth span;
* position: the true ENU (x, y) plus the aircraft's ``offset_m`` plus N(0, sigma_m²) per
  axis; height: the true ``alt_m`` plus N(0, sigma_alt_m²); ``z``, ``lat``, ``lon`` are
  the point at that (x, y) and height (:func:`skytrack.sim.earth.place_at_height`);
  ``sigma_m`` is written as the configured value, also for an offset aircraft (its
  transponder claims the accuracy it does not have);
* velocity (``velocities``): the true ENU velocity plus N(0, sigma_velocity_mps²) per axis;
* losses: each report independently with ``p_drop``, every report inside an outage
  window, every report whose true horizontal distance from the frame origin (the ground
  station) exceeds ``coverage_m``;
* equipage: an aircraft transmits when its settings say so, else it is among the
  ``round(equipage × n)`` aircraft drawn from the n undecided ones that have a
  transponder (an aircraft without one transmits only when told to);
* identity: ``icao24`` is the aircraft's Mode S address, else a deterministic address
  derived from its id (:func:`derived_icao24`, distinct from every other address);
  ``callsign`` likewise (the id in capitals when it is 1-8 letters and digits); a
  ``wrong_icao24`` / ``wrong_callsign`` replaces the transmitted value, ``no_callsign``
  leaves it null.  ``truth_id`` is always the true target id.

Random streams: the caller's generator is split (:meth:`numpy.random.Generator.spawn`)
into one stream per quantity (phases, jitter, losses, horizontal noise, height noise,
velocity noise), and every candidate report of every aircraft draws from each of them,
equipped or not, lost or not: changing equipage, faults, losses or coverage changes which
reports are kept, never the draws of the others.  The simulator gives ADS-B a child
spawned from its sensor generator after the radars, so turning ADS-B on leaves the radar
plots of a seed bit-identical; equipage comes from the scenario seed (stream ``adsb`` of
:func:`skytrack.sim.traffic.seed_stream`), so Monte Carlo runs share the equipped set.
Everything is vectorised over reports; only the per-aircraft identities loop.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.sim._validate import Fields, ScenarioError, describe, join_path
from skytrack.sim.earth import place_at_height
from skytrack.sim.recorded import ADSB_REPORT_COLUMNS
from skytrack.sim.spec import AdsbAircraftSpec, AdsbSpec

ADSB_KEYS = (
    "enabled", "interval_s", "jitter_s", "sigma_m", "sigma_alt_m", "velocities", "sigma_velocity_mps",
    "p_drop", "outages", "equipage", "coverage_m", "equipped", "unequipped", "aircraft",
)
ADSB_AIRCRAFT_KEYS = ("equipped", "offset_m", "wrong_icao24", "wrong_callsign", "no_callsign")
#: one row per aircraft of :attr:`AdsbSimulation.aircraft`
AIRCRAFT_COLUMNS = (
    "target_id", "equipped", "icao24", "callsign", "sent_icao24", "sent_callsign",
    "offset_x_m", "offset_y_m", "fault", "reports",
)
_ICAO24 = re.compile(r"[0-9a-f]{6}")
_CALLSIGN = re.compile(r"[A-Z0-9]{1,8}")
_STREAMS = ("phase", "jitter", "loss", "horizontal", "height", "velocity")


# ---------------------------------------------------------------------------------
# scenario section
# ---------------------------------------------------------------------------------


def parse_adsb(top: Fields) -> AdsbSpec | None:
    """The scenario's ``adsb`` section (a mapping, or ``true`` / ``false`` for the defaults / off)."""
    raw = top.data.get("adsb")
    if raw is None:
        return None
    if isinstance(raw, bool):
        return AdsbSpec(enabled=raw)
    f = top.sub("adsb", ADSB_KEYS)
    interval = f.number("interval_s", 1.0, gt=0.0)
    jitter = f.number("jitter_s", 0.05, ge=0.0)
    if jitter >= interval / 2.0:
        raise f.error("jitter_s", f"must be < interval_s / 2 = {interval / 2.0:g} (an aircraft's reports stay in order), got {jitter:g}")
    return AdsbSpec(
        enabled=f.boolean("enabled", True),
        interval_s=interval,
        jitter_s=jitter,
        sigma_m=f.number("sigma_m", 10.0, gt=0.0),
        sigma_alt_m=f.number("sigma_alt_m", 15.0, ge=0.0),
        velocities=f.boolean("velocities", True),
        sigma_velocity_mps=f.number("sigma_velocity_mps", 1.0, ge=0.0),
        p_drop=f.number("p_drop", 0.0, ge=0.0, le=1.0),
        outages=_windows(f, "outages"),
        equipage=f.number("equipage", 1.0, ge=0.0, le=1.0),
        coverage_m=f.number("coverage_m", None, gt=0.0),
        aircraft=_aircraft_entries(f),
    )


def _windows(f: Fields, key: str) -> tuple[tuple[float, float], ...]:
    windows = []
    for path, window in f.items(key, None):
        if not isinstance(window, list) or len(window) != 2:
            raise f.error_at(path, f"must be a [start, end] pair of seconds, got {describe(window)}")
        start, end = (f.check_number(join_path(path, i), value, ge=0.0) for i, value in enumerate(window))
        if end < start:
            raise f.error_at(path, f"start must be <= end, got [{start:g}, {end:g}]")
        windows.append((start, end))
    return tuple(windows)


def _target_id(f: Fields, path: str, value) -> str:
    if isinstance(value, bool) or not isinstance(value, (str, int)) or str(value) == "":
        raise f.error_at(path, f"must be a target id (text), got {describe(value)}")
    return str(value)


def _aircraft_entries(f: Fields) -> tuple[tuple[str, str, AdsbAircraftSpec], ...]:
    """``equipped`` / ``unequipped`` lists and the ``aircraft`` mapping, one entry per id."""
    entries: dict[str, tuple[str, AdsbAircraftSpec]] = {}

    def add(name: str, path: str, spec: AdsbAircraftSpec) -> None:
        if name in entries:
            raise f.error_at(path, f"aircraft {name!r} is already set at {entries[name][0]}; give each aircraft once")
        entries[name] = (path, spec)

    for key, flag in (("equipped", True), ("unequipped", False)):
        for path, value in f.items(key, None):
            add(_target_id(f, path, value), path, AdsbAircraftSpec(equipped=flag))
    raw = f.raw("aircraft", None)
    if raw is not None:
        if not isinstance(raw, dict):
            raise f.error("aircraft", f"must be a mapping of target id -> settings ({', '.join(ADSB_AIRCRAFT_KEYS)}), got {describe(raw)}")
        for name, value in raw.items():
            path = join_path(join_path(f.path, "aircraft"), str(name))
            add(_target_id(f, path, name), path, parse_adsb_aircraft(Fields(value, path, f.source, ADSB_AIRCRAFT_KEYS)))
    return tuple((name, path, spec) for name, (path, spec) in entries.items())


def parse_adsb_aircraft(f: Fields) -> AdsbAircraftSpec:
    """One aircraft's ADS-B settings (a target's ``adsb`` mapping or ``adsb.aircraft.<id>``)."""
    offset = (0.0, 0.0)
    if f.has("offset_m"):
        raw = f.raw("offset_m")
        if not isinstance(raw, list) or len(raw) != 2:
            raise f.error("offset_m", f"must be an [east, north] pair of metres, got {describe(raw)}")
        path = join_path(f.path, "offset_m")
        offset = tuple(f.check_number(join_path(path, i), value) for i, value in enumerate(raw))
    wrong_icao24 = _wrong_identity(f, "wrong_icao24", _ICAO24, "6 hexadecimal digits such as 'a1b2c3'", str.lower)
    wrong_callsign = _wrong_identity(f, "wrong_callsign", _CALLSIGN, "1-8 letters or digits such as 'AFR123'", str.upper)
    no_callsign = f.boolean("no_callsign", False)
    if no_callsign and wrong_callsign is not None:
        raise f.error("no_callsign", "give at most one of no_callsign or wrong_callsign")
    equipped = f.boolean("equipped", None) if f.has("equipped") else None
    if equipped is False:
        for key in ("offset_m", "wrong_icao24", "wrong_callsign", "no_callsign"):
            if f.has(key) and f.raw(key) is not False:
                raise f.error(key, "has no effect: equipped is false (the aircraft transmits no ADS-B)")
    return AdsbAircraftSpec(equipped, offset, wrong_icao24, wrong_callsign, no_callsign)


def _wrong_identity(f: Fields, key: str, pattern: re.Pattern, expected: str, normalise) -> str | bool | None:
    value = f.raw(key, None)
    if value is None or value is False:
        return None
    if value is True:
        return True
    if not isinstance(value, str) or not pattern.fullmatch(normalise(value.strip())):
        raise f.error(key, f"must be true (a derived other value) or {expected}, got {describe(value)}")
    return normalise(value.strip())


def check_target_settings(spec: AdsbSpec | None, target_settings: dict[str, str], source: str) -> None:
    """Scripted targets' own ``adsb`` mappings (id -> key path) need the section and may not
    repeat an id of the section."""
    if not target_settings:
        return
    if spec is None:
        path = next(iter(target_settings.values()))
        raise ScenarioError(f"{source}: {path}: needs the scenario's adsb section (ADS-B is simulated only with it)")
    for name, path, _ in spec.aircraft:
        if name in target_settings:
            raise ScenarioError(f"{source}: {path}: aircraft {name!r} already has its own settings at {target_settings[name]}")


def resolve_settings(
    entries: tuple[tuple[str, str, AdsbAircraftSpec], ...], ids: np.ndarray, icao24: np.ndarray, source: str
) -> dict[str, AdsbAircraftSpec]:
    """Per target id, the settings of ``entries`` (id, key path, settings): a key is a target
    id, or a Mode S address that applies to every target with it (the segments of a recorded
    aircraft).  An unknown key is a :class:`ScenarioError` naming its path."""
    known = set(ids.tolist())
    by_address: dict[str, list[str]] = {}
    for name, address in zip(ids.tolist(), icao24.tolist(), strict=True):
        if isinstance(address, str):
            by_address.setdefault(address, []).append(name)
    settings: dict[str, AdsbAircraftSpec] = {}
    for key, path, spec in entries:
        targets = [key] if key in known else by_address.get(key.lower(), [])
        if not targets:
            shown = ", ".join(sorted(known)[:8]) + (", ..." if len(known) > 8 else "")
            raise ScenarioError(f"{source}: {path}: no target with the id or Mode S address {key!r} (targets: {shown})")
        settings.update(dict.fromkeys(targets, spec))
    return settings


# ---------------------------------------------------------------------------------
# identities
# ---------------------------------------------------------------------------------


def _digest(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big")


def derived_icao24(key: str, used: set[str]) -> str:
    """A 24-bit address derived from ``key`` (SHA-256), not in ``used`` nor 000000/ffffff."""
    counter = 0
    while True:
        value = _digest(f"{key}#{counter}") >> 40
        text = f"{value:06x}"
        if 0 < value < 0xFFFFFF and text not in used:
            return text
        counter += 1


def derived_callsign(key: str, used: set[str]) -> str:
    """``key`` in capitals without other characters when that is 1-8 letters/digits and unused,
    else ``SKY`` and five digits derived from it."""
    plain = re.sub(r"[^A-Z0-9]", "", key.upper())
    if _CALLSIGN.fullmatch(plain) and plain not in used:
        return plain
    counter = 0
    while True:
        text = f"SKY{_digest(f'{key}#{counter}') % 100_000:05d}"
        if text not in used:
            return text
        counter += 1


def _valid(value, pattern: re.Pattern) -> bool:
    return isinstance(value, str) and pattern.fullmatch(value) is not None


@dataclass
class _Identities:
    icao24: np.ndarray  # [A] object: true address
    callsign: np.ndarray  # [A] object: true flight identification
    sent_icao24: np.ndarray  # [A] object: transmitted address
    sent_callsign: np.ndarray  # [A] object, None = none transmitted


def _identities(ids: np.ndarray, given_icao24: np.ndarray, given_callsign: np.ndarray,
                settings: dict[str, AdsbAircraftSpec]) -> _Identities:
    addresses = [a.strip().lower() if isinstance(a, str) else None for a in given_icao24]
    icao24 = np.array([a if _valid(a, _ICAO24) else None for a in addresses], dtype=object)
    callsign = np.array([c.strip().upper() if isinstance(c, str) and c.strip() else None for c in given_callsign],
                        dtype=object)
    used_addresses = {a for a in icao24 if a is not None}
    used_callsigns = {c for c in callsign if c is not None}
    for k, name in enumerate(ids.tolist()):
        if icao24[k] is None:
            icao24[k] = derived_icao24(name, used_addresses)
            used_addresses.add(icao24[k])
        if callsign[k] is None:
            callsign[k] = derived_callsign(name, used_callsigns)
            used_callsigns.add(callsign[k])
    sent_icao24, sent_callsign = icao24.copy(), callsign.copy()
    for k, name in enumerate(ids.tolist()):
        spec = settings.get(name)
        if spec is None:
            continue
        if spec.wrong_icao24 is True:
            sent_icao24[k] = derived_icao24(f"wrong:{name}", used_addresses)
            used_addresses.add(sent_icao24[k])
        elif spec.wrong_icao24 is not None:
            sent_icao24[k] = spec.wrong_icao24
        if spec.wrong_callsign is True:
            sent_callsign[k] = derived_callsign(f"wrong:{name}#", used_callsigns)
            used_callsigns.add(sent_callsign[k])
        elif spec.wrong_callsign is not None:
            sent_callsign[k] = spec.wrong_callsign
        if spec.no_callsign:
            sent_callsign[k] = None
    return _Identities(icao24, callsign, sent_icao24, sent_callsign)


def _equipped(ids: np.ndarray, transponder: np.ndarray, settings: dict[str, AdsbAircraftSpec], equipage: float,
              rng: np.random.Generator) -> np.ndarray:
    """Exactly round(equipage × undecided transponder aircraft) of them, by keys drawn for every aircraft."""
    keys = rng.random(ids.size)
    decided = np.array([settings.get(name, AdsbAircraftSpec()).equipped for name in ids.tolist()], dtype=object)
    undecided = np.array([d is None for d in decided], dtype=bool)
    equipped = np.array([d is True for d in decided], dtype=bool)
    candidates = np.flatnonzero(undecided & transponder)
    count = int(math.floor(equipage * candidates.size + 0.5))
    chosen = candidates[np.argsort(keys[candidates], kind="stable")[:count]]
    equipped[chosen] = True
    return equipped


# ---------------------------------------------------------------------------------
# reports
# ---------------------------------------------------------------------------------


@dataclass
class AdsbSimulation:
    """Reports (FORMATS.md "adsb" + ``truth_id``, in time order) and one row per aircraft
    (:data:`AIRCRAFT_COLUMNS`: equipage, true and transmitted identity, offset, faults,
    number of reports)."""

    reports: pd.DataFrame
    aircraft: pd.DataFrame


def _aircraft_table(ids: np.ndarray, aircraft: pd.DataFrame | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Given Mode S address, callsign and transponder flag per id (None / True when unknown)."""
    count = ids.size
    icao24 = np.full(count, None, dtype=object)
    callsign = np.full(count, None, dtype=object)
    transponder = np.ones(count, dtype=bool)
    if aircraft is None:
        return icao24, callsign, transponder
    if "target_id" not in aircraft.columns:
        raise ValueError("aircraft table needs a target_id column")
    table = aircraft.drop_duplicates("target_id")
    rows = pd.Index(table["target_id"].astype(str).to_numpy(dtype=object)).get_indexer(pd.Index(ids))
    found = rows >= 0
    for name, out in (("icao24", icao24), ("callsign", callsign)):
        if name in table.columns:
            values = table[name].astype(object).to_numpy()
            out[found] = [None if pd.isna(v) else v for v in values[rows[found]]]
    if "transponder" in table.columns:
        transponder[found] = table["transponder"].to_numpy(dtype=bool)[rows[found]]
    return icao24, callsign, transponder


def _sorted_truth(truth: pd.DataFrame, velocities: bool) -> tuple[pd.DataFrame, np.ndarray, np.ndarray, np.ndarray]:
    """Truth rows sorted by (target, segment, time); the sorted ids, and each row's target and
    group (one group per (target, segment)) index."""
    needed = ["time", "target_id", "x", "y", "alt_m"] + (["vx", "vy", "vz"] if velocities else [])
    missing = [name for name in needed if name not in truth.columns]
    if missing:
        raise ValueError(f"truth table lacks column(s) {', '.join(missing)} (FORMATS.md truth; velocities need vx, vy, vz)")
    segment = truth["segment"].to_numpy(dtype=np.int64) if "segment" in truth.columns else np.zeros(len(truth), dtype=np.int64)
    ids, target = np.unique(truth["target_id"].astype(str).to_numpy(dtype=object), return_inverse=True)
    time = truth["time"].to_numpy(dtype=float)
    order = np.lexsort((time, segment, target))
    rows = truth.iloc[order].reset_index(drop=True)
    target, segment = target[order], segment[order]
    new_group = np.ones(len(rows), dtype=bool)
    new_group[1:] = (target[1:] != target[:-1]) | (segment[1:] != segment[:-1])
    group = np.cumsum(new_group) - 1
    return rows, ids, target, group


def _group_bounds(group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last row of each group (rows grouped contiguously)."""
    first_row = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    return first_row, np.r_[first_row[1:] - 1, group.size - 1]


def _report_times(t: np.ndarray, first_row: np.ndarray, last_row: np.ndarray, group_target: np.ndarray,
                  phase: np.ndarray, interval: float) -> tuple[np.ndarray, np.ndarray]:
    """(group, nominal time) of every candidate report: phase + k interval inside each group's span."""
    offset = phase[group_target]
    k_first = np.ceil((t[first_row] - offset) / interval)
    k_last = np.floor((t[last_row] - offset) / interval)
    count = np.maximum(k_last - k_first + 1.0, 0.0).astype(np.int64)
    report_group = np.repeat(np.arange(first_row.size), count)
    step = np.arange(report_group.size) - np.repeat(np.cumsum(count) - count, count)
    return report_group, offset[report_group] + (k_first[report_group] + step) * interval


def _interpolate(t: np.ndarray, group: np.ndarray, values: np.ndarray, report_group: np.ndarray,
                 report_time: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``values`` [rows, m] of each report's group at its time."""
    first_row, last_row = _group_bounds(group)
    # a power of two above every time: group * span + time orders (group, time) exactly enough
    span = 2.0 ** math.ceil(math.log2(float(np.max(np.abs(t), initial=1.0)) + 2.0)) * 4.0
    index = np.searchsorted(group * span + t, report_group * span + report_time, side="right") - 1
    lower = np.clip(index, first_row[report_group], np.maximum(last_row[report_group] - 1, first_row[report_group]))
    upper = np.minimum(lower + 1, last_row[report_group])
    gap = t[upper] - t[lower]
    weight = np.clip(np.divide(report_time - t[lower], gap, out=np.zeros_like(gap), where=gap > 0.0), 0.0, 1.0)
    return values[lower] + weight[:, None] * (values[upper] - values[lower])


def simulate_adsb(
    truth: pd.DataFrame,
    spec: AdsbSpec,
    rng: np.random.Generator,
    *,
    origin: Origin,
    aircraft: pd.DataFrame | None = None,
    settings: dict[str, AdsbAircraftSpec] | None = None,
    equipage_rng: np.random.Generator | None = None,
) -> AdsbSimulation:
    """ADS-B reports of the aircraft of ``truth`` (module docstring).

    ``truth``: FORMATS.md truth rows (``time``, ``target_id``, ``x``, ``y``, ``alt_m``, with
    ``vx, vy, vz`` when ``spec.velocities``; optional ``segment``); any row order.
    ``aircraft``: optional table with ``target_id`` and any of ``icao24``, ``callsign``,
    ``transponder`` (the simulator's ``result.targets``).  ``settings``: per target id
    (default: ``spec.aircraft`` resolved by :func:`resolve_settings`; the simulator passes
    them resolved, with the targets' own).
    ``rng`` draws the reports; ``equipage_rng`` (default: a child of ``rng``) the equipage.
    """
    rows, ids, target, group = _sorted_truth(truth, spec.velocities)
    if rows.empty:
        truth = pd.DataFrame({"time": [0.0], "target_id": ["-"], "x": [0.0], "y": [0.0], "alt_m": [0.0],
                              "vx": [0.0], "vy": [0.0], "vz": [0.0]})
        empty = simulate_adsb(truth, spec, rng, origin=origin, settings={"-": AdsbAircraftSpec(equipped=False)})
        return AdsbSimulation(empty.reports.iloc[:0].reset_index(drop=True), empty.aircraft.iloc[:0].reset_index(drop=True))
    given_icao24, given_callsign, transponder = _aircraft_table(ids, aircraft)
    resolved = resolve_settings(spec.aircraft, ids, given_icao24, "adsb") if settings is None else settings
    streams = dict(zip(_STREAMS, rng.spawn(len(_STREAMS)), strict=True))
    if equipage_rng is None:
        equipage_rng = rng.spawn(1)[0]
    equipped = _equipped(ids, transponder, resolved, spec.equipage, equipage_rng)
    identity = _identities(ids, given_icao24, given_callsign, resolved)
    offset = np.array([resolved.get(name, AdsbAircraftSpec()).offset_m for name in ids.tolist()], dtype=float).reshape(-1, 2)

    t = rows["time"].to_numpy(dtype=float)
    first_row, last_row = _group_bounds(group)
    group_target = target[first_row]
    phase = streams["phase"].uniform(0.0, spec.interval_s, ids.size)
    report_group, nominal = _report_times(t, first_row, last_row, group_target, phase, spec.interval_s)
    n = nominal.size
    # every candidate report draws from every stream (module docstring, "Random streams")
    jitter = streams["jitter"].uniform(-spec.jitter_s, spec.jitter_s, n)
    loss = streams["loss"].random(n)
    horizontal = streams["horizontal"].standard_normal((n, 2))
    height = streams["height"].standard_normal(n)
    velocity_noise = streams["velocity"].standard_normal((n, 3))

    time = nominal + jitter
    report_target = group_target[report_group]
    keep = (time >= t[first_row][report_group]) & (time <= t[last_row][report_group])
    keep &= equipped[report_target] & (loss >= spec.p_drop)
    for start, end in spec.outages:
        keep &= ~((time >= start) & (time <= end))
    columns = ["x", "y", "alt_m"] + (["vx", "vy", "vz"] if spec.velocities else [])
    true_state = _interpolate(t, group, rows[columns].to_numpy(dtype=float), report_group[keep], time[keep])
    if spec.coverage_m is not None:
        inside = np.hypot(true_state[:, 0], true_state[:, 1]) <= spec.coverage_m
        keep[np.flatnonzero(keep)[~inside]] = False
        true_state = true_state[inside]
    reports = _report_frame(time[keep], report_target[keep], true_state, offset, horizontal[keep], height[keep],
                            velocity_noise[keep], spec, origin, ids, identity)
    counts = np.bincount(report_target[keep], minlength=ids.size)
    return AdsbSimulation(reports, _summary(ids, equipped, identity, offset, resolved, counts))


def _report_frame(time, target, true_state, offset, horizontal, height, velocity_noise, spec: AdsbSpec,
                  origin: Origin, ids: np.ndarray, identity: _Identities) -> pd.DataFrame:
    x = true_state[:, 0] + offset[target, 0] + spec.sigma_m * horizontal[:, 0]
    y = true_state[:, 1] + offset[target, 1] + spec.sigma_m * horizontal[:, 1]
    alt = true_state[:, 2] + spec.sigma_alt_m * height
    z, lat, lon, _ = place_at_height(x, y, alt, origin)
    if spec.velocities:
        velocity = true_state[:, 3:6] + spec.sigma_velocity_mps * velocity_noise
    else:
        velocity = np.full((time.size, 3), np.nan)
    order = np.lexsort((target, time))
    data = {
        "time": time, "icao24": identity.sent_icao24[target], "lat": np.atleast_1d(lat), "lon": np.atleast_1d(lon),
        "alt_m": alt, "x": x, "y": y, "z": np.atleast_1d(z), "sigma_m": np.full(time.size, spec.sigma_m),
        "callsign": identity.sent_callsign[target],
        "vx": velocity[:, 0], "vy": velocity[:, 1], "vz": velocity[:, 2], "truth_id": ids[target],
    }
    frame = pd.DataFrame({name: np.asarray(data[name])[order] for name in ADSB_REPORT_COLUMNS})
    for name in ("icao24", "callsign", "truth_id"):
        frame[name] = pd.array(frame[name].to_numpy(dtype=object), dtype="str")
    return frame


def _summary(ids, equipped, identity: _Identities, offset, settings: dict[str, AdsbAircraftSpec],
             counts) -> pd.DataFrame:
    faults = []
    for k, name in enumerate(ids.tolist()):
        spec = settings.get(name, AdsbAircraftSpec())
        kinds = [kind for kind, on in (("offset", bool(np.any(offset[k] != 0.0))),
                                        ("wrong_icao24", identity.sent_icao24[k] != identity.icao24[k]),
                                        ("wrong_callsign", spec.wrong_callsign is not None),
                                        ("no_callsign", spec.no_callsign)) if on]
        faults.append(",".join(kinds) if equipped[k] else "")
    data = {
        "target_id": ids, "equipped": equipped, "icao24": identity.icao24, "callsign": identity.callsign,
        "sent_icao24": np.where(equipped, identity.sent_icao24, None),
        "sent_callsign": np.where(equipped, identity.sent_callsign, None),
        "offset_x_m": offset[:, 0], "offset_y_m": offset[:, 1], "fault": np.array(faults, dtype=object),
        "reports": counts.astype(np.int64),
    }
    frame = pd.DataFrame({name: data[name] for name in AIRCRAFT_COLUMNS})
    for name in ("target_id", "icao24", "callsign", "sent_icao24", "sent_callsign", "fault"):
        frame[name] = pd.array(frame[name].to_numpy(dtype=object), dtype="str")
    return frame

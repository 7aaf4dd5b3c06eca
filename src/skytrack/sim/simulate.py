"""Running a scenario: trajectories -> truth table -> plots of every radar, merged in time.

``simulate(scenario, rng=None, progress=None, recorded=None)`` returns a
:class:`SimulationResult` with ``plots`` and ``truth`` in the FORMATS.md layouts, the
:class:`SensorSet` that ``skytrack.io`` writes as sensors.json, the scenario, and the
trajectories themselves (``result.trajectories.state(target_index, t)`` gives the exact
state at any time).

Recorded traffic: ``recorded`` takes the state vectors of
:func:`skytrack.io.read_state_vectors` (required when the scenario has a ``recorded``
section; without one, the recording is used with the section's defaults).  Its cleaned
segments join the scripted targets and random traffic as targets after them
(:mod:`skytrack.sim.recorded`); the result then also holds the cleaning counts and the
window (``result.recorded``), the ADS-B reports of the recorded samples (``result.adsb``)
and sensors.json's ``epoch_utc`` is the window's start.

ADS-B (issue 9): with the scenario's ``adsb`` section, ``result.adsb`` holds the simulated
reports of every equipped aircraft, recorded ones included (:mod:`skytrack.sim.adsb`), and
``result.adsb_aircraft`` one row per aircraft (equipage, true and transmitted identity,
faults).  Their generator is spawned from ``rng`` after the radars (equipage: the scenario
seed's ``adsb`` stream), so the plots of a seed are the same with and without ADS-B.

Airborne radars (``radar-airborne``, :mod:`skytrack.sim.carrier`) measure from their
carrier's flight; their plots carry the carrier's state in the ``platform_*`` columns
(present in the table only when the scenario has an airborne radar; NaN on the plots of
ground radars), and ``result.carriers`` holds the carriers' trajectories.

IFF (spec 003 R16, R18): a radar with an ``iff`` section interrogates its plots by its
policy (``always``, ``never`` or time windows) and :func:`skytrack.sim.iff.respond` fills
the ``iff`` column and the ``mode3a`` column (the reply's code replaces the SSR Mode 3/A of
that radar, so uninterrogated plots carry none) from each target's true ``iff`` status and
``mode3a`` code.  Without an ``iff`` section the ``iff`` column stays empty.

Randomness: trajectories (traffic, Singer legs, carriers) come from the scenario seed alone;
detections, noise, SSR replies, clutter and plot order come from ``rng`` (default: a
Generator derived from the scenario seed), so Monte Carlo runs over one scenario share the
same truth.  IFF replies come from a generator spawned from ``rng`` (one child per radar,
:meth:`numpy.random.Generator.spawn`, which draws nothing from ``rng``): adding, removing or
changing an ``iff`` section leaves every other column bit-identical.

Interrogators (``secondary_only``, :mod:`skytrack.sim.radar`): the targets that reply are those
with a transponder, and, when the interrogator has an ``iff`` section, those with an IFF
status.  An interrogator draws its detections, noise, replies and fruit from a generator of its
own, spawned after the IFF children (only when the scenario has an interrogator), so the
plots of every other sensor are the same with or without it.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.core.plots import IFF_VALUES, PLATFORM_COLUMNS
from skytrack.geo.sensors import SensorSet
from skytrack.sim._validate import ScenarioError
from skytrack.sim.adsb import AdsbSimulation, resolve_settings, simulate_adsb
from skytrack.sim.carrier import Carriers, airborne_plots, build_carriers
from skytrack.sim.iff import interrogation_mask, mode3a_int, respond
from skytrack.sim.radar import MODE3A_CODES, PLOT_COLUMNS, clutter_plots, radar_plots
from skytrack.sim.recorded import RecordedSpec, RecordedTraffic, prepare_recorded
from skytrack.sim.recorded_motion import concatenate_trajectories
from skytrack.sim.scenario import Scenario
from skytrack.sim.spec import TARGET_IFF_STATUSES, AdsbAircraftSpec, RadarSimParams, TargetSpec
from skytrack.sim.traffic import seed_stream
from skytrack.sim.trajectories import TrajectorySet, build_trajectories
from skytrack.sim.truth import TruthTable, sample_truth

TRUTH_COLUMNS = ("time", "target_id", "segment", "x", "y", "z", "vx", "vy", "vz", "lat", "lon", "alt_m", "visible")

# share of the progress bar spent on each stage
_PROGRESS_TRAJECTORIES = 0.05
_PROGRESS_TRUTH = 0.45


@dataclass
class SimulationResult:
    plots: pd.DataFrame
    truth: pd.DataFrame
    sensors: SensorSet
    scenario: Scenario
    trajectories: TrajectorySet
    targets: pd.DataFrame  # one row per target: target_id, mode3a, icao24, transponder, start/end time, callsign
    adsb: pd.DataFrame | None = None  # ADS-B reports (FORMATS.md "adsb" + truth_id): simulated, or recorded samples
    recorded: RecordedTraffic | None = None  # cleaning counts, window and samples of recorded traffic
    carriers: Carriers | None = None  # flights of the airborne radars' carriers
    adsb_aircraft: pd.DataFrame | None = None  # simulated ADS-B: one row per aircraft (skytrack.sim.adsb.AIRCRAFT_COLUMNS)


def simulate(
    scenario: Scenario,
    rng: np.random.Generator | None = None,
    progress: Callable[[float], None] | None = None,
    recorded: pd.DataFrame | None = None,
) -> SimulationResult:
    """Simulate the scenario; ``progress(fraction)`` is called as the work advances (0 < fraction <= 1).

    ``recorded``: state vectors (:func:`skytrack.io.read_state_vectors`) flown as truth.
    """
    report = progress or (lambda fraction: None)
    sensor_rng = seed_stream(scenario.seed, "sensors") if rng is None else rng
    targets = scenario.all_targets()
    traj = build_trajectories(targets, scenario.duration_s, scenario.origin, seed_stream(scenario.seed, "motion"))
    sensors = scenario.sensors
    from_recording = None
    if scenario.recorded is not None or recorded is not None:
        if recorded is None:
            raise ScenarioError(
                f"{scenario.source}: recorded: the scenario flies recorded traffic; read the file with "
                "skytrack.io.read_state_vectors and pass it as simulate(..., recorded=states), or use "
                "skytrack.app.simulate.run_simulation"
            )
        recorded_spec = scenario.recorded or RecordedSpec()
        if _adsb_on(scenario):
            # the adsb section simulates these aircraft's reports (adsb_sigma_m is refused with it: no draw skipped)
            recorded_spec = dataclasses.replace(recorded_spec, adsb=False)
        from_recording = prepare_recorded(
            recorded, recorded_spec, scenario.origin, scenario.duration_s, scenario.epoch_utc,
            sensor_rng, source=f"{scenario.source}: recorded",
        )
        try:
            traj = concatenate_trajectories(traj, from_recording.trajectories, scenario.duration_s)
        except ValueError as exc:
            raise ScenarioError(f"{scenario.source}: {exc}") from None
        # the recording places time 0: sensors.json tells when that was
        sensors = copy.copy(scenario.sensors)
        sensors.epoch_utc = from_recording.epoch_utc
    carrier_specs = {name: p.carrier for name, p in scenario.radar_params.items() if p.carrier is not None}
    carriers = build_carriers(carrier_specs, scenario.duration_s, scenario.origin, seed_stream(scenario.seed, "carriers"))
    report(_PROGRESS_TRAJECTORIES)
    truth = sample_truth(
        traj,
        sensors,
        scenario.truth_sample_s,
        progress=lambda f: report(_PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH * f),
        carriers=carriers,
    )
    report(_PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH)
    parts = []
    radars = sensors.sensors
    interrogators = any(scenario.radar_params[s.name].secondary_only for s in radars)
    # one spawn for both: children 0..n-1 are the IFF streams whether or not there are interrogators
    streams = _spawn(sensor_rng, len(radars) * (2 if interrogators else 1))
    iff_streams, reply_streams = streams[: len(radars)], streams[len(radars):]
    responder = _Responder(targets, traj)
    done = _PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH
    for number, sensor in enumerate(radars):
        params = scenario.radar_params[sensor.name]
        if sensor.is_moving:
            generated = [airborne_plots(sensor, params, carriers, traj, scenario.duration_s, sensor_rng)]
        elif params.secondary_only:
            own = reply_streams[number]
            generated = [radar_plots(sensor, params, traj, truth.samples, own, replying=responder.replying(params)),
                         clutter_plots(sensor, params, scenario.duration_s, own)]
        else:
            generated = [radar_plots(sensor, params, traj, truth.samples, sensor_rng),
                         clutter_plots(sensor, params, scenario.duration_s, sensor_rng)]
        for columns in generated:
            columns["sensor_number"] = np.full(columns["time"].size, number, dtype=np.int64)
            responder.fill(columns, params, iff_streams[number])
            parts.append(columns)
        report(done + (1.0 - done) * (number + 1) / len(radars) * 0.95)
    plots = _plot_frame(parts, [s.name for s in radars])
    truth_frame = _truth_frame(truth, traj)
    target_frame = _target_frame(targets, traj, from_recording)
    adsb = None if from_recording is None else from_recording.adsb
    adsb_aircraft = None
    if _adsb_on(scenario):
        # spawned after the radars' draws and IFF children: the plots do not depend on ADS-B
        simulated = _simulate_adsb(scenario, targets, truth_frame, target_frame, _spawn(sensor_rng, 1)[0])
        adsb, adsb_aircraft = simulated.reports, simulated.aircraft
    result = SimulationResult(
        plots=plots,
        truth=truth_frame,
        sensors=sensors,
        scenario=scenario,
        trajectories=traj,
        targets=target_frame,
        adsb=adsb,
        recorded=from_recording,
        carriers=carriers,
        adsb_aircraft=adsb_aircraft,
    )
    report(1.0)
    return result


def _adsb_on(scenario: Scenario) -> bool:
    return scenario.adsb is not None and scenario.adsb.enabled


def _simulate_adsb(scenario: Scenario, targets: list[TargetSpec], truth: pd.DataFrame, target_frame: pd.DataFrame,
                   rng: np.random.Generator) -> AdsbSimulation:
    """The scenario's ADS-B reports: settings of the section and of the targets, recorded
    aircraft unequipped when their section says ``adsb: false``."""
    spec = scenario.adsb
    ids = target_frame["target_id"].to_numpy(dtype=object)
    icao24 = target_frame["icao24"].to_numpy(dtype=object)
    settings: dict[str, AdsbAircraftSpec] = {}
    if scenario.recorded is not None and not scenario.recorded.adsb:
        settings.update(dict.fromkeys(ids[len(targets):].tolist(), AdsbAircraftSpec(equipped=False)))
    settings.update(resolve_settings(spec.aircraft, ids, icao24, scenario.source))
    settings.update({target.id: target.adsb for target in targets if target.adsb is not None})
    return simulate_adsb(truth, spec, rng, origin=scenario.origin, aircraft=target_frame, settings=settings,
                         equipage_rng=seed_stream(scenario.seed, "adsb"))


def _spawn(rng: np.random.Generator, count: int) -> list[np.random.Generator]:
    """``count`` independent child generators of ``rng``; spawning draws nothing from ``rng``."""
    try:
        return rng.spawn(count)
    except (TypeError, ValueError):  # a bit generator without a seed sequence: derive one from its state
        digest = hashlib.sha256(repr(rng.bit_generator.state).encode()).digest()
        seed = np.random.SeedSequence(int.from_bytes(digest[:16], "little"))
        return [np.random.default_rng(child) for child in seed.spawn(count)]


def _is_mode3a(code) -> bool:
    return isinstance(code, str) and len(code) == 4 and all(c in "01234567" for c in code)


class _Responder:
    """The targets' true IFF (status and Mode 3/A code) and each radar's interrogation."""

    def __init__(self, targets: list[TargetSpec], traj: TrajectorySet):
        n_objects = len(traj)
        self.status = np.full(n_objects, -1, dtype=np.int64)  # recorded traffic: no IFF transponder
        # a recorded squawk that is no 4-digit octal code cannot be replied
        self.code = np.array([mode3a_int(code) if _is_mode3a(code) else -1 for code in traj.mode3a], dtype=np.int64)
        self.p_reply = np.full(n_objects, np.nan)
        for k, target in enumerate(targets):
            if target.iff is not None:
                self.status[k] = TARGET_IFF_STATUSES.index(target.iff)
            if target.iff_p_reply is not None:
                self.p_reply[k] = target.iff_p_reply
        self.ids = pd.Index(traj.ids)
        self.transponder = traj.transponder

    def replying(self, params: RadarSimParams) -> np.ndarray:
        """Targets that answer an interrogator: a transponder, or an IFF status when it interrogates IFF."""
        return self.transponder | (self.status >= 0) if params.iff is not None else self.transponder.copy()

    def fill(self, columns: dict[str, np.ndarray], params: RadarSimParams, rng: np.random.Generator) -> None:
        """Set the ``iff`` column and, for a radar with an interrogator, its ``mode3a`` column."""
        count = columns["time"].size
        if params.iff is None:
            columns["iff"] = np.full(count, None, dtype=object)
            return
        spec = params.iff
        objects = self.ids.get_indexer(pd.Index(columns["truth_id"].astype(object)))
        status, code = respond(
            objects,
            interrogation_mask(columns["time"], spec.interrogate),
            self.status,
            self.code,
            rng,
            p_reply=np.where(np.isnan(self.p_reply), spec.p_reply, self.p_reply),
            p_flip=spec.p_flip,
            p_code=spec.p_code,
            false_reply_p=spec.false_reply_p,
        )
        replied = status >= 0
        columns["iff"] = np.where(replied, np.asarray(IFF_VALUES, dtype=object)[np.maximum(status, 0)], None)
        columns["mode3a"] = np.where(code >= 0, MODE3A_CODES[np.maximum(code, 0)], None)


def _plot_frame(parts: list[dict[str, np.ndarray]], sensor_names: list[str]) -> pd.DataFrame:
    """Merge the radars' plots in time order (ties: sensor order, then generation order); the
    platform columns follow when any radar is airborne (NaN on ground radars' plots)."""
    airborne = any(PLATFORM_COLUMNS[0] in p for p in parts)
    if airborne:
        parts = [p if PLATFORM_COLUMNS[0] in p else {**p, **{c: np.full(p["time"].size, np.nan) for c in PLATFORM_COLUMNS}}
                 for p in parts]
    merged = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    order = np.lexsort((merged["sensor_number"], merged["time"]))
    names = np.asarray(sensor_names, dtype=object)
    data = {
        "time": merged["time"][order],
        "sensor": pd.array(names[merged["sensor_number"][order]], dtype="str"),
        "range_m": merged["range_m"][order],
        "azimuth_deg": merged["azimuth_deg"][order],
        "scan": merged["scan"][order].astype(np.int64),
        "elevation_deg": merged["elevation_deg"][order],
        "range_rate_mps": merged["range_rate_mps"][order],
        "mode3a": pd.array(merged["mode3a"][order], dtype="str"),
        "mode_c_ft": merged["mode_c_ft"][order],
        "mode_s": pd.array(merged["mode_s"][order], dtype="str"),
        "iff": pd.array(merged["iff"][order], dtype="str"),
        "truth_id": pd.array(merged["truth_id"][order], dtype="str"),
    }
    column_names = PLOT_COLUMNS + (PLATFORM_COLUMNS if airborne else ())
    data.update({name: merged[name][order] for name in PLATFORM_COLUMNS if airborne})
    return pd.DataFrame({name: data[name] for name in column_names}, copy=False)


def _truth_frame(truth: TruthTable, traj: TrajectorySet) -> pd.DataFrame:
    s = truth.samples
    data = {
        "time": s.time,
        "target_id": pd.array(traj.ids[s.target], dtype="str"),
        "segment": np.zeros(s.time.size, dtype=np.int64),
        "x": s.position[:, 0],
        "y": s.position[:, 1],
        "z": s.position[:, 2],
        "vx": s.velocity[:, 0],
        "vy": s.velocity[:, 1],
        "vz": s.velocity[:, 2],
        "lat": truth.lat,
        "lon": truth.lon,
        "alt_m": truth.alt_m,
        "visible": truth.visible,
    }
    return pd.DataFrame({name: data[name] for name in TRUTH_COLUMNS}, copy=False)


def _target_frame(targets: list[TargetSpec], traj: TrajectorySet, from_recording: RecordedTraffic | None) -> pd.DataFrame:
    n_recorded = len(traj) - len(targets)
    legs = np.array([len(t.legs) for t in targets] + [0] * n_recorded, dtype=np.int64)
    callsign = np.full(len(traj), None, dtype=object)
    callsign[: len(targets)] = [t.callsign for t in targets]
    if from_recording is not None:
        callsign[len(targets):] = from_recording.callsign
    return pd.DataFrame(
        {
            "target_id": pd.array(traj.ids, dtype="str"),
            "transponder": traj.transponder,
            "mode3a": pd.array(traj.mode3a, dtype="str"),
            "icao24": pd.array(traj.icao24, dtype="str"),
            "start_time": traj.start_time,
            "end_time": traj.end_time,
            "n_legs": legs,
            "callsign": pd.array(callsign, dtype="str"),
        }
    )

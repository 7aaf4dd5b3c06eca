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

Randomness: trajectories (traffic, Singer legs) come from the scenario seed alone;
detections, noise, SSR replies and clutter come from ``rng`` (default: a Generator derived
from the scenario seed), so Monte Carlo runs over one scenario share the same truth.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.geo.sensors import SensorSet
from skytrack.sim._validate import ScenarioError
from skytrack.sim.radar import PLOT_COLUMNS, clutter_plots, radar_plots
from skytrack.sim.recorded import RecordedSpec, RecordedTraffic, prepare_recorded
from skytrack.sim.recorded_motion import concatenate_trajectories
from skytrack.sim.scenario import Scenario
from skytrack.sim.spec import TargetSpec
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
    adsb: pd.DataFrame | None = None  # ADS-B reports of recorded traffic (FORMATS.md "adsb" + truth_id)
    recorded: RecordedTraffic | None = None  # cleaning counts, window and samples of recorded traffic


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
        from_recording = prepare_recorded(
            recorded, scenario.recorded or RecordedSpec(), scenario.origin, scenario.duration_s, scenario.epoch_utc,
            sensor_rng, source=f"{scenario.source}: recorded",
        )
        try:
            traj = concatenate_trajectories(traj, from_recording.trajectories, scenario.duration_s)
        except ValueError as exc:
            raise ScenarioError(f"{scenario.source}: {exc}") from None
        # the recording places time 0: sensors.json tells when that was
        sensors = copy.copy(scenario.sensors)
        sensors.epoch_utc = from_recording.epoch_utc
    report(_PROGRESS_TRAJECTORIES)
    truth = sample_truth(
        traj,
        sensors,
        scenario.truth_sample_s,
        progress=lambda f: report(_PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH * f),
    )
    report(_PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH)
    parts = []
    radars = sensors.sensors
    done = _PROGRESS_TRAJECTORIES + _PROGRESS_TRUTH
    for number, sensor in enumerate(radars):
        params = scenario.radar_params[sensor.name]
        for columns in (radar_plots(sensor, params, traj, truth.samples, sensor_rng), clutter_plots(sensor, params, scenario.duration_s, sensor_rng)):
            columns["sensor_number"] = np.full(columns["time"].size, number, dtype=np.int64)
            parts.append(columns)
        report(done + (1.0 - done) * (number + 1) / len(radars) * 0.95)
    plots = _plot_frame(parts, [s.name for s in radars])
    result = SimulationResult(
        plots=plots,
        truth=_truth_frame(truth, traj),
        sensors=sensors,
        scenario=scenario,
        trajectories=traj,
        targets=_target_frame(targets, traj, from_recording),
        adsb=None if from_recording is None else from_recording.adsb,
        recorded=from_recording,
    )
    report(1.0)
    return result


def _plot_frame(parts: list[dict[str, np.ndarray]], sensor_names: list[str]) -> pd.DataFrame:
    """Merge the radars' plots in time order (ties: sensor order, then generation order)."""
    merged = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    order = np.lexsort((merged["sensor_number"], merged["time"]))
    n = order.size
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
        "iff": pd.array(np.full(n, None, dtype=object), dtype="str"),
        "truth_id": pd.array(merged["truth_id"][order], dtype="str"),
    }
    return pd.DataFrame({name: data[name] for name in PLOT_COLUMNS}, copy=False)


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

"""skytrack.sim — scenario simulator: scripted and random trajectories, rotating and airborne radars, SSR, IFF, clutter.

* :func:`load_scenario` reads a scenario (YAML file, bundled name such as ``"demo"``, or dict)
  into a validated :class:`Scenario`; the key reference is the docstring of
  :mod:`skytrack.sim.scenario`.
* :func:`simulate` runs it: ``result.plots`` / ``result.truth`` follow FORMATS.md,
  ``result.sensors`` is the :class:`~skytrack.geo.SensorSet` written as sensors.json.
* :func:`scale_traffic` changes the number of random aircraft (throughput benchmark).
* Recorded aircraft as truth: a scenario's ``recorded`` section, with the state vectors of
  :func:`skytrack.io.read_state_vectors` passed as ``simulate(..., recorded=states)``.

Modules: ``scenario`` (:class:`Scenario`, loading), ``spec`` (the scenario section
dataclasses), ``parse`` (section parsers and validation), ``traffic`` (random aircraft), ``trajectories``
(exact arcs, Singer legs, waypoints), ``truth`` (sampling, coverage exit), ``radar``
(beam crossings, detection, noise, SSR, clutter), ``carrier`` (airborne radars: the carrier's
flight and the plots measured from it), ``iff`` (the IFF responder and interrogation
policies of spec 003), ``earth`` (heights above the ellipsoid
in the ENU frame, radar horizon), ``simulate`` (the pipeline), ``cleaning`` (recorded
state vectors cleaned and cut into segments), ``recorded`` (the ``recorded`` section, the
bundled recordings, the window, ADS-B reports), ``recorded_motion`` (segments as cubic
Hermite trajectories).
"""

from skytrack.sim._validate import ScenarioError
from skytrack.sim.radar import PLOT_COLUMNS, beam_azimuth_deg, scan_index
from skytrack.sim.scenario import (
    Scenario,
    TargetSpec,
    bundled_scenario_path,
    bundled_scenarios,
    load_scenario,
    scale_traffic,
)
from skytrack.sim.simulate import TRUTH_COLUMNS, SimulationResult, simulate
from skytrack.sim.trajectories import TrajectorySet

# singer_truth (spec 000, R14) is owned separately; its export may be added here, nothing is imported from it.

__all__ = [
    "PLOT_COLUMNS",
    "TRUTH_COLUMNS",
    "Scenario",
    "ScenarioError",
    "SimulationResult",
    "TargetSpec",
    "TrajectorySet",
    "beam_azimuth_deg",
    "bundled_scenario_path",
    "bundled_scenarios",
    "load_scenario",
    "scale_traffic",
    "scan_index",
    "simulate",
]

"""The simulation pipeline: a scenario (file or bundled name) to plots, truth and sensors.json,
and ADS-B reports when the scenario has an ``adsb`` section (simulated reports, with the
true target id as ``truth_id``) or flies recorded traffic.

Recorded traffic is read here (:func:`skytrack.io.read_state_vectors`: the simulator in
``skytrack.sim`` sits below ``skytrack.io`` and reads no files) from the scenario's
``recorded`` section or from ``trajectories``, which replaces the section's file.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from skytrack.app.run import ProgressCallback

if TYPE_CHECKING:
    from skytrack.sim import SimulationResult

TABLE_FORMATS = ("parquet", "csv")


def _recorded_overrides(trajectories: str | Path | None, start: str | float | None) -> dict:
    """The ``recorded`` keys that ``trajectories`` and ``start`` replace (see :func:`run_simulation`)."""
    from skytrack.io import InputError
    from skytrack.sim.recorded import bundled_samples

    section: dict = {}
    if trajectories is not None:
        path = Path(trajectories).expanduser()
        if path.is_file():
            section.update(path=str(path.resolve()), sample=None)
        elif str(trajectories) in bundled_samples():
            section.update(sample=str(trajectories), path=None)
        else:
            raise InputError(
                f"file not found (nor a bundled recording: {', '.join(bundled_samples())})", file=str(trajectories)
            )
    if start is not None:
        try:
            seconds = float(start)
        except (TypeError, ValueError):
            section.update(start_utc=str(start), start_s=None)
        else:
            if not math.isfinite(seconds) or seconds < 0.0:
                raise ValueError(f"--start in seconds must be a finite number >= 0, got {start!r}")
            section.update(start_s=seconds, start_utc=None)
    return section


def run_simulation(
    scenario_source: str | Path,
    seed: int | None = None,
    *,
    progress: ProgressCallback | None = None,
    trajectories: str | Path | None = None,
    start: str | float | None = None,
    duration: float | None = None,
) -> SimulationResult:
    """Load a scenario (YAML file or bundled name) and simulate it.

    ``seed`` replaces the scenario's seed of the measurement noise; ``progress("simulate",
    fraction, 1.0)`` is called as the work advances.  Recorded traffic:
    ``trajectories`` (a state-vector file or a bundled recording's name) is flown as truth,
    replacing the file of the scenario's ``recorded`` section or adding one;
    ``start`` places time 0 on the recording (ISO-8601 UTC text for ``start_utc``, a
    number for ``start_s`` seconds after its first time stamp); ``duration`` replaces the
    scenario's ``duration_s``.
    """
    import numpy as np

    from skytrack.io import read_state_vectors
    from skytrack.sim import load_scenario, simulate

    report = progress or (lambda stage, completed, total: None)
    overrides: dict = {}
    if duration is not None:
        overrides["duration_s"] = duration
    section = _recorded_overrides(trajectories, start)
    if section:
        if trajectories is None and load_scenario(scenario_source).recorded is None:
            raise ValueError("--start places recorded traffic: give --trajectories or a scenario with a recorded section")
        if start is not None:
            # the command line places the window: the scenario's epoch_utc gives way to it
            overrides["epoch_utc"] = None
        overrides["recorded"] = section
    scenario = load_scenario(scenario_source, overrides=overrides)
    states = None
    if scenario.recorded is not None:
        states = read_state_vectors(scenario.recorded.file, altitude=scenario.recorded.altitude)
    rng = None if seed is None else np.random.default_rng(seed)
    report("simulate", 0.0, 1.0)
    result = simulate(scenario, rng=rng, progress=lambda fraction: report("simulate", fraction, 1.0), recorded=states)
    report("simulate", 1.0, 1.0)
    return result


def write_simulation(result: SimulationResult, out: str | Path, fmt: str = "parquet") -> dict[str, Path]:
    """Write ``plots.<fmt>``, ``truth.<fmt>`` and ``sensors.json`` into ``out`` (and
    ``adsb.<fmt>`` when the result has ADS-B reports: an ``adsb`` section, or recorded
    traffic); returns their paths."""
    from skytrack.io import write_adsb, write_plots, write_sensors, write_truth

    if fmt not in TABLE_FORMATS:
        raise ValueError(f"table format must be parquet or csv, got {fmt!r}")
    out = Path(out)
    paths = {
        "plots": write_plots(result.plots, out / f"plots.{fmt}", sensors=result.sensors),
        "truth": write_truth(result.truth, out / f"truth.{fmt}"),
        "sensors": write_sensors(result.sensors, out / "sensors.json"),
    }
    if result.adsb is not None:
        paths["adsb"] = write_adsb(result.adsb, out / f"adsb.{fmt}", origin=result.sensors.origin)
    return paths

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
#: what ``skytrack simulate --format`` writes: the table formats, or ``asterix`` (plots.ast: CAT048 plots,
#: CAT034 north markers and CAT021 ADS-B reports; truth.parquet; sensors.json with SAC/SIC; issue 11 item 2)
SIMULATION_FORMATS = (*TABLE_FORMATS, "asterix")


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


def write_simulation(result: SimulationResult, out: str | Path, fmt: str = "parquet", *,
                     progress: ProgressCallback | None = None) -> dict[str, Path]:
    """Write ``plots.<fmt>``, ``truth.<fmt>`` and ``sensors.json`` into ``out`` (and
    ``adsb.<fmt>`` when the result has ADS-B reports: an ``adsb`` section, or recorded
    traffic); returns their paths.  ``fmt="asterix"`` writes :func:`write_asterix_simulation`'s files."""
    from skytrack.io import write_adsb, write_plots, write_sensors, write_truth

    if fmt == "asterix":
        return write_asterix_simulation(result, out, progress=progress)
    if fmt not in TABLE_FORMATS:
        raise ValueError(f"format must be parquet or csv (tables) or asterix, got {fmt!r}")
    out = Path(out)
    paths = {
        "plots": write_plots(result.plots, out / f"plots.{fmt}", sensors=result.sensors),
        "truth": write_truth(result.truth, out / f"truth.{fmt}"),
        "sensors": write_sensors(result.sensors, out / "sensors.json"),
    }
    if result.adsb is not None:
        paths["adsb"] = write_adsb(result.adsb, out / f"adsb.{fmt}", origin=result.sensors.origin)
    return paths


def write_asterix_simulation(result: SimulationResult, out: str | Path, *,
                             progress: ProgressCallback | None = None) -> dict[str, Path]:
    """Write ``plots.ast`` (CAT034 north markers, one per revolution of every rotating radar over
    the simulated span, CAT048 plots, CAT021 ADS-B reports when the result has them, in time
    order), ``truth.parquet`` and ``sensors.json`` with every sensor's ``sac``/``sic`` (assigned
    in sensor order when the scenario gives none) and, with ADS-B, ``adsb_station``.

    Not representable in CAT048 and not written: ``elevation_deg``, ``range_rate_mps``, ``iff``,
    ``scan``, ``truth_id``; the ADS-B reports' ``truth_id``.  A scenario whose 3-D or airborne
    radars have plots is refused (their plots need the elevation or the carrier's position)."""
    from skytrack.io import write_sensors, write_truth
    from skytrack.io.asterix.cat062 import time_of_day_at_epoch
    from skytrack.io.asterix.recording import (
        SECTOR_BLOCK_S, adsb_station, encode_recording, north_markers, with_sac_sic,
    )

    report = progress or (lambda stage, completed, total: None)
    out = Path(out)
    has_adsb = result.adsb is not None and len(result.adsb) > 0
    plotted = set(result.plots["sensor"].astype(str)) if len(result.plots) else set()
    for sensor in result.sensors.sensors:
        if sensor.name in plotted and sensor.type in ("radar-3d", "radar-airborne"):
            what = "elevation" if sensor.type == "radar-3d" else "carrier position"
            raise ValueError(f"sensor {sensor.name} ({sensor.type}): the CAT048 plots written carry no {what}, so its "
                             "plots could not be tracked from plots.ast; use --format parquet for this scenario")
    sensors, sac_sic = with_sac_sic(result.sensors, adsb=has_adsb)
    end = max([float(result.scenario.duration_s)] + [float(t["time"].max()) for t in (result.plots, result.adsb)
                                                     if t is not None and len(t)])
    markers = north_markers(sensors, 0.0, end)
    report("write", 0.0, 1.0)
    data = encode_recording(result.plots, sac_sic, service=markers, adsb=result.adsb if has_adsb else None,
                            adsb_sac_sic=adsb_station(sensors), origin=sensors.origin,
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc),
                            block_span_s=SECTOR_BLOCK_S, progress=lambda fraction: report("write", fraction, 1.0))
    out.mkdir(parents=True, exist_ok=True)
    (out / "plots.ast").write_bytes(data)
    report("write", 1.0, 1.0)
    return {"plots": out / "plots.ast", "truth": write_truth(result.truth, out / "truth.parquet"),
            "sensors": write_sensors(sensors, out / "sensors.json")}

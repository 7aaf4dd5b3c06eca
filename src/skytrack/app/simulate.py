"""The simulation pipeline: a scenario (file or bundled name) to plots, truth and sensors.json."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from skytrack.app.run import ProgressCallback

if TYPE_CHECKING:
    from skytrack.sim import SimulationResult

TABLE_FORMATS = ("parquet", "csv")


def run_simulation(
    scenario_source: str | Path, seed: int | None = None, *, progress: ProgressCallback | None = None
) -> SimulationResult:
    """Load a scenario (YAML file or bundled name) and simulate it.

    ``seed`` replaces the scenario's seed of the measurement noise; ``progress("simulate",
    fraction, 1.0)`` is called as the work advances.
    """
    import numpy as np

    from skytrack.sim import load_scenario, simulate

    report = progress or (lambda stage, completed, total: None)
    scenario = load_scenario(scenario_source)
    rng = None if seed is None else np.random.default_rng(seed)
    report("simulate", 0.0, 1.0)
    result = simulate(scenario, rng=rng, progress=lambda fraction: report("simulate", fraction, 1.0))
    report("simulate", 1.0, 1.0)
    return result


def write_simulation(result: SimulationResult, out: str | Path, fmt: str = "parquet") -> dict[str, Path]:
    """Write ``plots.<fmt>``, ``truth.<fmt>`` and ``sensors.json`` into ``out``; returns their paths."""
    from skytrack.io import write_plots, write_sensors, write_truth

    if fmt not in TABLE_FORMATS:
        raise ValueError(f"table format must be parquet or csv, got {fmt!r}")
    out = Path(out)
    return {
        "plots": write_plots(result.plots, out / f"plots.{fmt}", sensors=result.sensors),
        "truth": write_truth(result.truth, out / f"truth.{fmt}"),
        "sensors": write_sensors(result.sensors, out / "sensors.json"),
    }

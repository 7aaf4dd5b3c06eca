"""The seeded demo run that the golden regression test compares against.

``python tests/golden/golden_demo.py`` rewrites the stored reference
(``demo_tracks.parquet``, ``demo_metrics.json``).  Do that only in a commit whose message
states which behaviour changed and why; every other commit must leave the test green.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.analysis import evaluate
from skytrack.sim import load_scenario, simulate
from skytrack.tracker import Tracker, TrackerConfig

HERE = Path(__file__).parent
TRACKS_FILE = HERE / "demo_tracks.parquet"
METRICS_FILE = HERE / "demo_metrics.json"


def run_demo() -> tuple[pd.DataFrame, dict]:
    """Track the bundled demo scenario (its own seed) and evaluate it; returns tracks and summary."""
    result = simulate(load_scenario("demo"))
    tracks = Tracker(result.sensors, TrackerConfig(full_covariance=True)).run(result.plots)
    evaluation = evaluate(tracks, result.truth, start_time_s=float(result.plots["time"].min()),
                          coverage_min_visible_s=120.0)
    summary = {k: (float(v) if isinstance(v, (int, float, np.number)) else v)
               for k, v in evaluation.summary.items()}
    return tracks, summary


if __name__ == "__main__":
    tracks, summary = run_demo()
    tracks.to_parquet(TRACKS_FILE, index=False)
    METRICS_FILE.write_text(json.dumps(summary, indent=2, sort_keys=True, default=str) + "\n")
    print(f"wrote {len(tracks)} track rows to {TRACKS_FILE} and {len(summary)} metrics to {METRICS_FILE}")

"""An airborne radar (no antenna schedule) expects a plot once per revisit interval, wherever its
scans fall relative to the processing windows."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest
import yaml

from skytrack.sim import load_scenario, simulate
from skytrack.tracker import Tracker, TrackerConfig


@pytest.mark.parametrize("phase", [0.0, 0.5, 1.0])
def test_scans_on_window_boundaries_are_tracked(phase):
    """Scans at whole seconds (phase 0: plot times on window starts) used to record a miss one
    window before each plot was due, so no tentative track survived (P_D 0.95)."""
    source = yaml.safe_load(resources.files("skytrack.scenarios").joinpath("airborne_crossing.yaml").read_text())
    source["sensors"][0]["scan_phase_s"] = phase
    result = simulate(load_scenario(source), rng=np.random.default_rng(1))
    tracker = Tracker(result.sensors, TrackerConfig())
    tracker.run(result.plots)
    targets = (result.plots["truth_id"] != "").sum()
    assert tracker.stats["tracks_confirmed"] == 6
    assert tracker.stats["plots_assigned"] >= 0.95 * targets

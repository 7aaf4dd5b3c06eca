"""A small simulated scene for the service tests: the demo radar (4 s scan, SSR) with 8 random aircraft plus the
demo's scripted ones, all airborne from t = 0, 120 s, no ADS-B."""

from __future__ import annotations

import dataclasses

import pytest


@pytest.fixture(scope="session")
def small_scene():
    from skytrack.sim import load_scenario, scale_traffic, simulate

    scenario = scale_traffic(load_scenario("demo"), 8)
    scenario = dataclasses.replace(scenario, traffic=dataclasses.replace(scenario.traffic, start_time_s=(0.0, 0.0)),
                                   duration_s=120.0, adsb=None, seed=7)
    result = simulate(scenario)
    return result.sensors, result.plots.reset_index(drop=True)

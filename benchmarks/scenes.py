"""Scene builders shared by the benchmarks: variations of the bundled demo scenario.

Every scene keeps the demo's radar (4 s scan, 250 km, P_D 0.9, SSR), its scripted aircraft
(four before issue 9, six since) and its random-traffic settings (speeds 110-250 m/s, altitudes 1.5-11.5 km, a
quarter manoeuvring), with the random traffic resized and all of it airborne from t = 0.

* ``sparse-N``    N random aircraft spread over the demo annulus (10-200 km), demo clutter.
* ``clutter-N``   as ``sparse-1000`` with N false plots per scan (the radar's clutter_per_scan).
* ``crossing-N``  N random aircraft starting uniformly in a 25 km x 25 km rectangle centred
                  80 km from the radar (azimuth 45 deg), headings uniform, so that their
                  paths cross; demo clutter.
* ``small-N``     same as ``sparse-N`` (the name used for small, realistic scenes).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from skytrack.sim import Scenario, load_scenario, scale_traffic
from skytrack.sim.scenario import RegionSpec

BOX_SIDE_M = 25_000.0
BOX_CENTRE_RANGE_M = 80_000.0
BOX_CENTRE_AZIMUTH_DEG = 45.0


def scaled_demo(count: int, duration_s: float) -> Scenario:
    """The demo scenario with ``count`` random aircraft, all airborne from the start (no ADS-B:
    the tracker benchmarks time radar plots only)."""
    scenario = scale_traffic(load_scenario("demo"), count)
    traffic = dataclasses.replace(scenario.traffic, start_time_s=(0.0, 0.0))
    return dataclasses.replace(scenario, traffic=traffic, duration_s=duration_s, adsb=None)


def with_clutter(scenario: Scenario, clutter_per_scan: float) -> Scenario:
    """The same scenario with every radar producing ``clutter_per_scan`` false plots per scan (Poisson mean)."""
    sensors = [dataclasses.replace(s, clutter_per_scan=float(clutter_per_scan)) for s in scenario.sensors.sensors]
    return dataclasses.replace(scenario, sensors=dataclasses.replace(scenario.sensors, sensors=sensors))


def box_bounds() -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y intervals (common ENU frame = the demo radar's site) of the crossing box."""
    az = math.radians(BOX_CENTRE_AZIMUTH_DEG)
    cx, cy = BOX_CENTRE_RANGE_M * math.sin(az), BOX_CENTRE_RANGE_M * math.cos(az)
    half = BOX_SIDE_M / 2
    return (cx - half, cx + half), (cy - half, cy + half)


def crossing_box(count: int, duration_s: float) -> Scenario:
    """``count`` aircraft starting uniformly in the 25 km box with uniform headings."""
    scenario = scaled_demo(count, duration_s)
    x_m, y_m = box_bounds()
    traffic = dataclasses.replace(scenario.traffic, region=RegionSpec("rectangle", x_m=x_m, y_m=y_m),
                                  heading_deg=(0.0, 360.0))
    return dataclasses.replace(scenario, traffic=traffic)


def in_box_fraction(truth) -> float:
    """Mean over the truth samples of the share of aircraft (scripted ones included) inside the crossing box."""
    (x0, x1), (y0, y1) = box_bounds()
    x, y = truth["x"].to_numpy(), truth["y"].to_numpy()
    return float(np.mean((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)))


def build(name: str, duration_s: float) -> Scenario:
    """Scenario of a scene named ``kind-N`` (see the module docstring)."""
    kind, _, number = name.rpartition("-")
    n = int(number)
    if kind in ("sparse", "small"):
        return scaled_demo(n, duration_s)
    if kind == "clutter":
        return with_clutter(scaled_demo(1000, duration_s), n)
    if kind == "crossing":
        return crossing_box(n, duration_s)
    raise ValueError(f"unknown scene {name!r} (kinds: sparse-N, small-N, clutter-N, crossing-N)")

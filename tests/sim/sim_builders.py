"""Shared scenario builders for the simulator tests."""

from __future__ import annotations

import copy

import numpy as np

ORIGIN = {"lat": 48.86, "lon": 2.50, "alt_m": 0.0}


def radar(**overrides) -> dict:
    base = {
        "name": "radar1",
        "type": "radar-2d",
        "lat": ORIGIN["lat"],
        "lon": ORIGIN["lon"],
        "alt_m": 30.0,
        "scan_period_s": 4.0,
        "sigma_range_m": 40.0,
        "sigma_azimuth_deg": 0.07,
        "max_range_m": 250000.0,
        "min_elevation_deg": -0.5,
        "p_detection": 1.0,
        "clutter_per_scan": 0.0,
    }
    base.update(overrides)
    return base


def noise_free(**overrides) -> dict:
    return radar(sigma_range_m=0.0, sigma_azimuth_deg=0.0, **overrides)


def scenario(targets=(), sensors=None, duration_s=120.0, seed=1, **top) -> dict:
    data = {
        "origin": dict(ORIGIN),
        "duration_s": duration_s,
        "seed": seed,
        "sensors": copy.deepcopy(sensors) if sensors is not None else [radar()],
        "targets": copy.deepcopy(list(targets)),
    }
    data.update(top)
    return data


def target(id="t1", **overrides) -> dict:
    base = {"id": id, "x": 20000.0, "y": 40000.0, "alt_m": 9000.0, "speed_mps": 200.0, "heading_deg": 90.0}
    base.update(overrides)
    return base


def ring_of_targets(n: int, range_m: float = 60000.0, alt_m: float = 8000.0, speed_mps: float = 150.0, **extra) -> list[dict]:
    """n targets spread in azimuth around the radar, flying tangentially (stay in coverage)."""
    out = []
    for i, az in enumerate(np.linspace(0.0, 360.0, n, endpoint=False)):
        out.append(
            {
                "id": f"r{i:03d}",
                "range_m": range_m,
                "azimuth_deg": float(az),
                "sensor": "radar1",
                "alt_m": alt_m,
                "speed_mps": speed_mps,
                "heading_deg": float((az + 90.0) % 360.0),
                **extra,
            }
        )
    return out

"""Plot simulation for the tracker tests, written independently of ``skytrack.sim``.

Targets fly straight lines (constant velocity) in the common ENU frame.  A rotating
radar sees a target when its beam crosses the target's azimuth: the beam points north
at ``phase + k * period`` and turns clockwise, so the plot time of scan ``k`` solves
``t = phase + (k + az(t) / 2 pi) * period`` (fixed-point iteration; the target's
azimuth moves slowly during a scan).  The geometry uses pymap3d directly (common ENU ->
ECEF -> the radar's own ENU), not the code under test; the 2-D sphere model enters only
through the tracker.  Plots are returned as a FORMATS.md ``plots`` DataFrame.

The helpers are exposed to the tests through fixtures (``sim``), so that test modules
never import this conftest by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pymap3d
import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet

ORIGIN = Origin(48.86, 2.50, 0.0)
FT = 0.3048


@dataclass(frozen=True)
class Target:
    """Straight-line target: common-frame ENU position at t = 0 and constant velocity."""

    name: str
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]

    def at(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.asarray(self.position) + np.asarray(self.velocity) * t[..., None]


@dataclass(frozen=True)
class Radar:
    """What the simulator needs about a radar (geodetic position, scan, noise)."""

    name: str
    lat: float
    lon: float
    alt_m: float
    period: float
    phase: float
    sigma_range_m: float
    sigma_azimuth_deg: float
    sigma_elevation_deg: float | None = None
    sigma_range_rate_mps: float | None = None
    type: str = "radar-2d"
    max_range_m: float = 250_000.0

    def sensor(self, **overrides) -> Sensor:
        values = dict(
            name=self.name, type=self.type, lat=self.lat, lon=self.lon, alt_m=self.alt_m,
            scan_period_s=self.period, scan_phase_s=self.phase, sigma_range_m=self.sigma_range_m,
            sigma_azimuth_deg=self.sigma_azimuth_deg, sigma_elevation_deg=self.sigma_elevation_deg,
            sigma_range_rate_mps=self.sigma_range_rate_mps, max_range_m=self.max_range_m,
            p_detection=0.9, clutter_per_scan=0.0,
        )
        values.update(overrides)
        return Sensor(**values)


def sensor_set(radars: list[Radar], **overrides) -> SensorSet:
    return SensorSet(ORIGIN, [r.sensor(**overrides) for r in radars], epoch_utc="2021-10-07T12:00:00Z")


def common_to_radar(radar: Radar, points: np.ndarray) -> np.ndarray:
    """Common-frame ENU points [..., 3] to the radar's own ENU frame, through ECEF (pymap3d)."""
    x, y, z = pymap3d.enu2ecef(points[..., 0], points[..., 1], points[..., 2], ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    e, n, u = pymap3d.ecef2enu(x, y, z, radar.lat, radar.lon, radar.alt_m)
    return np.stack([e, n, u], axis=-1)


def common_vector_to_radar(radar: Radar, vectors: np.ndarray) -> np.ndarray:
    """Common-frame ENU vectors to the radar's ENU frame (rotation only)."""
    u, v, w = pymap3d.enu2ecefv(vectors[..., 0], vectors[..., 1], vectors[..., 2], ORIGIN.lat, ORIGIN.lon)
    e, n, up = pymap3d.ecef2enuv(u, v, w, radar.lat, radar.lon)
    return np.stack([e, n, up], axis=-1)


def height_above_ellipsoid(points: np.ndarray) -> np.ndarray:
    _, _, alt = pymap3d.enu2geodetic(points[..., 0], points[..., 1], points[..., 2], ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_m)
    return np.asarray(alt)


def crossing_times(radar: Radar, target: Target, t_start: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Beam-crossing times of the target in [t_start, t_end) and their scan indices."""
    k = np.arange(np.floor((t_start - radar.phase) / radar.period) - 1,
                  np.ceil((t_end - radar.phase) / radar.period) + 1)
    t = radar.phase + k * radar.period
    for _ in range(12):
        local = common_to_radar(radar, target.at(t))
        az = np.remainder(np.arctan2(local[:, 0], local[:, 1]), 2 * np.pi)
        t = radar.phase + (k + az / (2 * np.pi)) * radar.period
    keep = (t >= t_start) & (t < t_end)
    return t[keep], k[keep].astype(np.int64)


def radar_plots(
    radar: Radar,
    targets: list[Target],
    t_start: float,
    t_end: float,
    rng: np.random.Generator,
    *,
    p_detection: float = 1.0,
    missed: set[tuple[str, int]] | None = None,
    mode_c: bool = True,
    elevation: bool = False,
    range_rate: bool = False,
    noise: bool = True,
) -> pd.DataFrame:
    """Plots of the targets seen by one rotating radar, with Gaussian measurement noise."""
    frames = []
    for target in targets:
        t, scans = crossing_times(radar, target, t_start, t_end)
        detected = rng.random(len(t)) < p_detection
        if missed:
            detected &= np.array([(target.name, int(k)) not in missed for k in scans], dtype=bool)
        t, scans = t[detected], scans[detected]
        pos = target.at(t)
        local = common_to_radar(radar, pos)
        vel = common_vector_to_radar(radar, np.broadcast_to(np.asarray(target.velocity, float), pos.shape))
        rng_m = np.linalg.norm(local, axis=1)
        az = np.arctan2(local[:, 0], local[:, 1])
        el = np.arctan2(local[:, 2], np.hypot(local[:, 0], local[:, 1]))
        rdot = np.einsum("ki,ki->k", local, vel) / rng_m
        scale = 1.0 if noise else 0.0
        rng_m = rng_m + scale * radar.sigma_range_m * rng.standard_normal(len(t))
        az = az + scale * np.radians(radar.sigma_azimuth_deg) * rng.standard_normal(len(t))
        frame = {
            "time": t, "sensor": radar.name, "range_m": rng_m,
            "azimuth_deg": np.remainder(np.degrees(az), 360.0), "scan": scans,
        }
        if elevation:
            el = el + scale * np.radians(radar.sigma_elevation_deg) * rng.standard_normal(len(t))
            frame["elevation_deg"] = np.degrees(el)
        if range_rate:
            frame["range_rate_mps"] = rdot + scale * radar.sigma_range_rate_mps * rng.standard_normal(len(t))
        if mode_c:
            frame["mode_c_ft"] = height_above_ellipsoid(pos) / FT
        frame["truth_id"] = target.name
        frames.append(pd.DataFrame(frame))
    return merge_plots(frames)


def isolated_clutter(
    radar: Radar, t_start: float, t_end: float, per_scan: int, rng: np.random.Generator,
    min_range: float = 20_000.0, max_range: float = 150_000.0, separation: float = 15_000.0, memory: int = 6,
) -> pd.DataFrame:
    """False plots spread uniformly over the coverage, each at least ``separation`` from the
    clutter of the last ``memory`` scans (so that no two can belong to one track)."""
    rows = []
    recent: list[np.ndarray] = []
    k0 = int(np.ceil((t_start - radar.phase) / radar.period))
    k1 = int(np.floor((t_end - radar.phase) / radar.period))
    for k in range(k0, k1):
        pts = []
        while len(pts) < per_scan:
            ground = np.sqrt(rng.uniform(min_range**2, max_range**2))
            az = rng.uniform(0.0, 2 * np.pi)
            xy = ground * np.array([np.sin(az), np.cos(az)])
            others = [p for block in recent[-memory:] for p in block] + pts
            if all(np.hypot(*(xy - p)) > separation for p in others):
                pts.append(xy)
                rows.append({"time": radar.phase + (k + az / (2 * np.pi)) * radar.period, "sensor": radar.name,
                             "range_m": np.hypot(ground, 3000.0), "azimuth_deg": np.degrees(az), "scan": k,
                             "truth_id": ""})
        recent.append(np.array(pts))
    return merge_plots([pd.DataFrame(rows)])


def ring_targets(rng: np.random.Generator, count: int, r_min: float = 30e3, r_max: float = 120e3,
                 speed: tuple[float, float] = (150.0, 250.0), alt: tuple[float, float] = (3000.0, 11000.0),
                 prefix: str = "t") -> list[Target]:
    """``count`` level targets spread in azimuth slots around the origin, random heading and speed."""
    out = []
    for i in range(count):
        az = 2 * np.pi * (i + 0.5 * rng.random()) / count
        ground = rng.uniform(r_min, r_max)
        heading = rng.uniform(0, 2 * np.pi)
        v = rng.uniform(*speed)
        out.append(Target(f"{prefix}{i}", (ground * np.sin(az), ground * np.cos(az), rng.uniform(*alt)),
                          (v * np.sin(heading), v * np.cos(heading), 0.0)))
    return out


def merge_plots(frames: list[pd.DataFrame]) -> pd.DataFrame:
    frame = pd.concat([f for f in frames if len(f)], ignore_index=True)
    return frame.sort_values("time", kind="stable").reset_index(drop=True)


def assign_tracks_to_targets(tracks: pd.DataFrame, targets: list[Target]) -> dict[int, str]:
    """Each track id -> the target nearest to it on average (horizontal distance)."""
    p0 = np.array([tg.position for tg in targets])[:, :2]
    v = np.array([tg.velocity for tg in targets])[:, :2]
    out = {}
    for track_id, rows in tracks.groupby("track_id"):
        t = rows["time"].to_numpy()
        xy = rows[["x", "y"]].to_numpy()
        truth = p0[None, :, :] + v[None, :, :] * t[:, None, None]  # [rows, targets, 2]
        dist = np.linalg.norm(xy[:, None, :] - truth, axis=2).mean(axis=0)
        out[int(track_id)] = targets[int(np.argmin(dist))].name
    return out


@pytest.fixture
def sim():
    """The simulation helpers of this directory."""
    return SimpleNamespace(
        ORIGIN=ORIGIN, FT=FT, Target=Target, Radar=Radar, sensor_set=sensor_set, radar_plots=radar_plots,
        isolated_clutter=isolated_clutter, merge_plots=merge_plots, crossing_times=crossing_times,
        common_to_radar=common_to_radar, height_above_ellipsoid=height_above_ellipsoid,
        assign_tracks_to_targets=assign_tracks_to_targets, ring_targets=ring_targets,
    )


@pytest.fixture
def radar1():
    """A 2-D en-route radar at the origin: 4 s scans, sigma 40 m / 0.07 deg."""
    return Radar("radar1", ORIGIN.lat, ORIGIN.lon, 0.0, period=4.0, phase=0.0,
                 sigma_range_m=40.0, sigma_azimuth_deg=0.07)

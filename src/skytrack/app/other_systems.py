"""The second observation system of an identification run, as reports (issue 9; spec 001's ξ).

:class:`OtherSystem` holds the reports of the system that radar tracks are identified with:
ADS-B reports tracked per address (:func:`adsb_system`), or another radar's or an IFF
interrogator's track reports (:func:`track_system`: the plots each of its tracks took, each
carrying the identity its track showed at that time).  :func:`covered_area` is the area the
object density of the posterior P(same) spreads over (spec 001 R6, density form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

#: sigma (m, per axis) of ADS-B reports that give neither sigma_m nor a NACp
DEFAULT_ADSB_SIGMA_M = 40.0


@dataclass(frozen=True)
class OtherSystem:
    """The second observation system's reports (spec 001's ξ): one row per report."""

    source: str
    """``adsb``, ``radar`` or ``iff``: the ``identity_source`` of the labels it gives"""
    time: np.ndarray
    key: np.ndarray
    """track of the report: the ADS-B address, or the other radar's track id (as text)"""
    z: np.ndarray
    """horizontal positions ``[N, 2]`` in the common frame"""
    V: np.ndarray
    """their covariances ``[N, 2, 2]``"""
    icao24: np.ndarray
    """address the report names (null when unknown)"""
    callsign: np.ndarray
    mode3a: np.ndarray
    """Mode 3/A code its track carried (an interrogator's or another radar's; null for ADS-B)"""
    iff: np.ndarray
    """IFF status its track carried (null for ADS-B)"""

    @property
    def keys(self) -> int:
        return len(np.unique(self.key))


def _text(values) -> np.ndarray:
    series = pd.Series(values, dtype=object)
    return series.where(series.notna(), None).to_numpy(object)


def adsb_system(adsb: pd.DataFrame) -> OtherSystem:
    """ADS-B reports (:func:`skytrack.io.read_adsb`) as the other system, tracked per address."""
    adsb = adsb.sort_values("time", kind="stable")
    sigma = adsb["sigma_m"].to_numpy(float) if "sigma_m" in adsb else np.full(len(adsb), np.nan)
    sigma = np.where(np.isfinite(sigma), sigma, DEFAULT_ADSB_SIGMA_M)
    address = adsb["icao24"].astype(str).to_numpy(object)
    callsign = adsb["callsign"] if "callsign" in adsb else [None] * len(adsb)
    none = np.full(len(adsb), None, dtype=object)
    return OtherSystem("adsb", adsb["time"].to_numpy(float), address, adsb[["x", "y"]].to_numpy(float),
                       sigma[:, None, None] ** 2 * np.eye(2), address, _text(callsign), none, none)


def track_system(reports: pd.DataFrame, tracks: pd.DataFrame | None, source: str = "radar") -> OtherSystem:
    """Another radar's (or an interrogator's) track reports (:func:`skytrack.io.read_track_reports`)
    as the other system; each report names the identity its track carried at that time."""
    reports = reports.sort_values("time", kind="stable").reset_index(drop=True)
    V = np.empty((len(reports), 2, 2))
    V[:, 0, 0], V[:, 1, 1] = reports["var_x"], reports["var_y"]
    V[:, 0, 1] = V[:, 1, 0] = reports["cov_xy"]
    names = ("icao24", "callsign", "mode3a", "iff")
    identity = {name: np.full(len(reports), None, dtype=object) for name in names}
    if tracks is not None and len(tracks) and len(reports):
        present = [name for name in names if name in tracks.columns]
        labels = tracks[["time", "track_id", *present]].sort_values("time", kind="stable")
        joined = pd.merge_asof(reports[["time", "track_id"]].reset_index(), labels, on="time", by="track_id",
                               direction="backward").sort_values("index")
        identity.update({name: _text(joined[name]) for name in present})
    key = reports["track_id"].astype(np.int64).astype(str).to_numpy(object)
    return OtherSystem(source, reports["time"].to_numpy(float), key, reports[["x", "y"]].to_numpy(float), V,
                       *(identity[name] for name in names))


def covered_area(sensor_set, adsb: pd.DataFrame) -> float:
    """The area (m²) the object density of ``identity_p`` spreads over: the radars' coverage discs,
    or, without ranges, the ADS-B reports' bounding box."""
    radii = [] if sensor_set is None else [s.max_range_m for s in sensor_set.sensors if s.is_radar and s.max_range_m]
    if radii:
        return float(sum(math.pi * r ** 2 for r in radii))
    span = adsb[["x", "y"]].max() - adsb[["x", "y"]].min()
    return float(max(span["x"], 1e4) * max(span["y"], 1e4))

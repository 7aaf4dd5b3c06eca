"""ADS-B reports from the live feed (CAT021 over UDP) labelling the tracks of ``skytrack serve`` (issue 11 item 3).

The labeller (:class:`~skytrack.app.identification.TrackLabeler`, spec 001's sequential test) reads the
other system's reports in time order, up to each track row's time, from an
:class:`~skytrack.app.other_systems.OtherSystem` and remembers how far it read (``other_next``).
:class:`LiveAdsb` keeps that system bounded for a feed that never ends: each batch of CAT021 reports (I021/
080 address, 130/131 position, 073 time, 170 callsign, 090 NACp) is converted to the ADS-B layout
(positions in the common frame, ``sigma_m`` from NACp, :func:`skytrack.io.adsb.nacp_sigma_m`) and joined to
the reports the labeller has not read yet, in time order; the ones it has read are dropped.  A report older
than the last one the labeller read is late: counted, not used (the test cannot take time going backwards).

Without ``serve --adsb FILE`` the labeller is created at the first CAT021 report; the tracker records the
plots its confirmed tracks take from then on (the labeller's radar side).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.geo.wgs84 import geodetic_to_enu


def build_labeler(adsb, sensors, config=None):
    """A :class:`~skytrack.app.identification.TrackLabeler` from ADS-B reports (a path, or a table of
    :func:`skytrack.io.read_adsb`'s layout)."""
    from skytrack.app.identification import TrackLabeler
    from skytrack.app.other_systems import DEFAULT_ADSB_SIGMA_M, adsb_system, covered_area
    from skytrack.io import read_adsb

    if isinstance(adsb, (str, Path)):
        adsb = read_adsb(adsb, sensors=sensors, default_sigma_m=DEFAULT_ADSB_SIGMA_M)
    if len(adsb) == 0:
        raise ValueError("no ADS-B report to label tracks with")
    return TrackLabeler(adsb_system(adsb), covered_area(sensors, adsb), config)


def adsb_table(columns: dict[str, np.ndarray], tracker_time: np.ndarray, origin) -> pd.DataFrame:
    """Decoded CAT021 columns as ADS-B reports (docs/formats.md ``adsb``, with x/y in the common frame):
    rows without an address or a position are left out."""
    from skytrack.app.other_systems import DEFAULT_ADSB_SIGMA_M
    from skytrack.io.adsb import nacp_sigma_m

    icao24 = np.asarray(columns.get("icao24", np.zeros(0, object)), dtype=object)
    lat, lon = np.asarray(columns["lat"], float), np.asarray(columns["lon"], float)
    alt = np.nan_to_num(np.asarray(columns.get("alt_m", np.zeros(len(lat))), float))
    usable = np.isfinite(lat) & np.isfinite(lon) & np.array([a is not None for a in icao24], bool)
    x, y, _ = geodetic_to_enu(lat[usable], lon[usable], alt[usable], origin.lat, origin.lon, origin.alt_m)
    nacp = np.asarray(columns.get("nacp", np.full(len(lat), np.nan)), float)[usable]
    sigma = nacp_sigma_m(nacp) if nacp.size else np.zeros(0)
    sigma = np.where(np.isfinite(sigma) & (sigma > 0), sigma, DEFAULT_ADSB_SIGMA_M)
    callsign = np.asarray(columns.get("callsign", np.full(len(lat), None, object)), dtype=object)[usable]
    return pd.DataFrame({"time": np.asarray(tracker_time, float)[usable], "icao24": icao24[usable],
                         "x": np.asarray(x, float), "y": np.asarray(y, float), "alt_m": alt[usable],
                         "sigma_m": sigma, "callsign": callsign})


class LiveAdsb:
    """Feeds CAT021 reports to the pipeline's labeller as they arrive (see the module docstring)."""

    def __init__(self, pipeline) -> None:
        self.pipeline = pipeline

    def add(self, reports: pd.DataFrame) -> None:
        """Join a batch of ADS-B reports to the labeller's unread ones (creating the labeller if needed)."""
        from skytrack.app.other_systems import adsb_system

        pipeline = self.pipeline
        counters = pipeline.counters
        if len(reports) == 0:
            return
        labeler = pipeline.labeler
        if labeler is None:
            pipeline.labeler = labeler = build_labeler(reports, pipeline.sensors)
            pipeline.tracker.record_assignments()
            counters["adsb_reports_used"] += len(reports)
            return
        other, read = labeler.other, labeler.other_next
        read_until = float(other.time[read - 1]) if read > 0 else -np.inf
        late = reports["time"].to_numpy(float) < read_until
        if late.any():
            counters["adsb_reports_late"] += int(late.sum())
            reports = reports[~late]
        unread = {name: getattr(other, name)[read:] for name in ("time", "key", "z", "V", "icao24", "callsign",
                                                                 "mode3a", "iff")}
        new = adsb_system(reports)
        joined = {name: np.concatenate([unread[name], getattr(new, name)]) for name in unread}
        order = np.argsort(joined["time"], kind="stable")
        labeler.other = type(other)(other.source, *(joined[name][order] for name in unread))
        labeler.other_next = 0
        counters["adsb_reports_used"] += len(reports)

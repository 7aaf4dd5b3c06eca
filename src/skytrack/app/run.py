"""The tracking pipeline: read plots in chunks, track them, write tracks incrementally.

Beside the tracks, a run whose plots carried identity (Mode 3/A, Mode S, IFF) writes the
identity events (docs/formats.md: ``NAME.identity.parquet`` or ``.csv``; empty when no
confirmed track's identity changed).  A run without identity data writes none and removes an
events file a previous run left at that place, so the file beside the tracks is always theirs.

:func:`run_tracking` is what ``skytrack track`` runs; it prints nothing and reports its
progress through an optional callback, so a GUI, a service or a benchmark can call it too.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional

if TYPE_CHECKING:
    from skytrack.io import ReadReport
    from skytrack.tracker import TrackerConfig

#: ``progress(stage, completed, total)``: ``stage`` names the step ("simulate", "track"),
#: ``completed`` is how far it got (plots read, or a fraction), ``total`` the end value when
#: known (``None`` for a CSV input, whose row count is not known before it is read)
ProgressCallback = Callable[[str, float, Optional[float]], None]

#: plots per chunk by default (memory is bounded by one chunk plus the live tracks)
DEFAULT_CHUNK_ROWS = 200_000


@dataclass
class RunSummary:
    """What one tracking run did."""

    plots: int
    """plots read (after a lenient read dropped bad rows)"""
    track_rows: int
    """rows written to the tracks file"""
    elapsed_s: float
    """wall time of reading, tracking and writing (sensors.json excluded)"""
    stats: dict[str, int] = field(default_factory=dict)
    """the tracker's counters (``plots_assigned``, ``tracks_confirmed``, ...)"""
    warnings: list[str] = field(default_factory=list)
    """the tracker's warnings"""
    report: ReadReport | None = None
    """what a lenient read skipped (``None`` in strict mode)"""
    tracking_dim: int = 0
    """2 (horizontal) or 3"""
    tracks_file: str = ""
    """where the tracks were written"""
    no_tracks_reason: str | None = None
    """why no track row was written (``None`` when some were)"""
    identity_events_file: str | None = None
    """where the identity events were written (``None``: no plot carried identity, no file)"""
    identity_event_rows: int = 0
    """rows written to the identity-events file"""
    no_identity_events_reason: str | None = None
    """why no identity-events file was written (``None`` when one was)"""
    identification: dict | None = None
    """with ADS-B: what the labelling did (:class:`skytrack.app.identification.LabelStats`)"""
    reports_file: str | None = None
    """with ``write_reports``: the plots confirmed tracks took (``NAME.reports.parquet``)"""
    report_rows: int = 0

    @property
    def plots_per_s(self) -> float:
        return self.plots / self.elapsed_s if self.elapsed_s > 0 else float("nan")

    def to_dict(self) -> dict:
        """JSON-ready form (the read report as its text)."""
        return {
            "plots": self.plots, "tracks_file": self.tracks_file, "track_rows": self.track_rows,
            "elapsed_s": self.elapsed_s, "stats": dict(self.stats), "warnings": list(self.warnings),
            "report": None if self.report is None else str(self.report), "tracking_dim": self.tracking_dim,
            "no_tracks_reason": self.no_tracks_reason, "identity_events_file": self.identity_events_file,
            "identity_event_rows": self.identity_event_rows,
            "no_identity_events_reason": self.no_identity_events_reason,
            "identification": self.identification, "reports_file": self.reports_file, "report_rows": self.report_rows,
        }


def run_tracking(
    plots_path: str | Path,
    sensors_path: str | Path,
    out: str | Path,
    config: TrackerConfig | None = None,
    *,
    lenient: bool = False,
    chunk_rows: int = DEFAULT_CHUNK_ROWS,
    progress: ProgressCallback | None = None,
    units_confirmed: bool = False,
    range_rate_positive_closing: bool = False,
    adsb_path: str | Path | None = None,
    identification=None,
    write_reports: bool = False,
    only_sensors: list[str] | None = None,
) -> RunSummary:
    """Track a plots file (.parquet/.csv) and write the confirmed tracks to ``out``.

    Plots are read, validated and parsed once into plot batches ``chunk_rows`` at a time
    (Parquet and CSV are both streamed), fed to the tracker, and the tracks it emits are appended to ``out`` after
    every chunk, so memory is bounded by one chunk plus the live tracks.  With
    ``lenient=True`` malformed plot rows are skipped and counted in ``summary.report``.
    ``progress("track", plots_read, total_rows_or_None)`` is called after every chunk.  Values that
    look like kilometres or radians stop the run unless ``units_confirmed``.  With
    ``range_rate_positive_closing`` the file's range rates are positive for closing targets and are
    negated on reading (skytrack's convention is ``dD/dt``).  With ``adsb_path`` the tracks are
    labelled with the ADS-B identities the spec 001 test decides for them
    (:mod:`skytrack.app.identification`, settings ``identification``), and the label changes are
    identity events.  With ``write_reports`` the plots every confirmed track took are written
    beside the tracks (:func:`skytrack.io.track_reports.track_reports_path`), the input of
    ``skytrack identify tracks`` between two radars.  ``only_sensors`` tracks the plots of those
    sensors alone (the others' plots are read, checked and counted, not tracked).
    """
    from skytrack.io import ReadReport, identity_events_path, iter_plot_batches, read_sensors, refuse_overwriting
    from skytrack.io.identity_events import IdentityEventWriter
    from skytrack.io.tables import count_rows
    from skytrack.io.tracks import TrackWriter
    from skytrack.tracker import Tracker, TrackerConfig

    if chunk_rows < 1:
        raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
    plots_path, out = Path(plots_path), Path(out)
    refuse_overwriting(out, plots=plots_path, sensors=sensors_path)
    events_path = identity_events_path(out)
    refuse_overwriting(events_path, plots=plots_path, sensors=sensors_path)
    config = config if config is not None else TrackerConfig()
    report_progress = progress or (lambda stage, completed, total: None)
    sensor_set = read_sensors(sensors_path)
    read_set, keep_sensor = sensor_set, None
    if only_sensors:
        sensor_set, keep_sensor = _sensor_subset(sensor_set, only_sensors)
    report = ReadReport(file=str(plots_path)) if lenient else None
    total = count_rows(plots_path)
    tracker = Tracker(sensor_set, config)
    labeler = None
    if adsb_path is not None:
        labeler = _adsb_labeler(adsb_path, sensor_set, identification, config)
    reports = None
    if write_reports:
        from skytrack.io.track_reports import TrackReportWriter, track_reports_path

        refuse_overwriting(track_reports_path(out), plots=plots_path, sensors=sensors_path)
        reports = TrackReportWriter(track_reports_path(out), [sensor.name for sensor in sensor_set.sensors])
    if labeler is not None or reports is not None:
        tracker.record_assignments()
    started = time.perf_counter()
    plots_read = 0
    report_progress("track", 0, total)
    first_time, last_time = math.inf, -math.inf
    events = IdentityEventWriter(events_path)
    with TrackWriter(out, sensors=sensor_set) as writer:
        for chunk in iter_plot_batches(plots_path, read_set, lenient, chunk_rows=chunk_rows, report=report,
                                       units_confirmed=units_confirmed,
                                       range_rate_positive_closing=range_rate_positive_closing):
            if keep_sensor is not None:
                plots_read += len(chunk)
                chunk = chunk.take(keep_sensor[chunk.sensor] >= 0)
                chunk.sensor = keep_sensor[chunk.sensor]
                plots_read -= len(chunk)
                if len(chunk) == 0:
                    continue
            tracker.feed(chunk, source=str(plots_path))
            first_time, last_time = min(first_time, float(chunk.time.min())), max(last_time, float(chunk.time.max()))
            _write_chunk(tracker, labeler, writer, events, reports)
            plots_read += len(chunk)
            report_progress("track", plots_read, total)
        tracker.finish()
        _write_chunk(tracker, labeler, writer, events, reports)
        if reports is not None:
            reports.close()
        identity_seen = tracker.identity_seen or labeler is not None
        events.close(create=identity_seen)
        if not identity_seen:
            events_path.unlink(missing_ok=True)  # a previous run's events do not belong to these tracks
        # evaluate measures times (to the first track, ...) from the input's start, not the first track's
        writer.run_metadata = {
            "input_file": plots_path.name, "input_plots": plots_read, "epoch_utc": sensor_set.epoch_utc,
            "input_time_start_s": first_time if plots_read else None,
            "input_time_end_s": last_time if plots_read else None,
        }
    report_progress("track", plots_read, total if total is not None else plots_read)
    elapsed = time.perf_counter() - started
    summary = RunSummary(
        plots=plots_read, track_rows=writer.rows, elapsed_s=elapsed, stats=dict(tracker.stats),
        warnings=list(tracker.warnings), report=report, tracking_dim=tracker.dim, tracks_file=str(out),
    )
    if summary.track_rows == 0:
        summary.no_tracks_reason = no_tracks_reason(summary, config)
    if labeler is not None:
        summary.identification = labeler.stats.to_dict()
    if reports is not None:
        summary.reports_file, summary.report_rows = str(reports.path), reports.rows
    if identity_seen:
        summary.identity_events_file, summary.identity_event_rows = str(events_path), events.rows
    else:
        summary.no_identity_events_reason = "no plot carried a Mode 3/A code, a Mode S address or an IFF reply"
    return summary


def _sensor_subset(sensor_set, names: list[str]):
    """The sensor set of ``names`` alone, and the new index of every sensor of the file (-1: not kept)."""
    import numpy as np

    from skytrack.geo.sensors import SensorSet

    for name in names:
        sensor_set[name]  # an unknown name is a KeyError naming the known ones
    kept = [s for s in sensor_set.sensors if s.name in names]
    index = np.array([names.index(s.name) if s.name in names else -1 for s in sensor_set.sensors], dtype=np.int64)
    order = sorted(kept, key=lambda s: names.index(s.name))
    return SensorSet(sensor_set.origin, order, sensor_set.epoch_utc, sensor_set.format_version,
                     dict(sensor_set.extra)), index


def _adsb_labeler(adsb_path, sensor_set, identification, config):
    from skytrack.app.identification import TrackLabeler
    from skytrack.app.other_systems import DEFAULT_ADSB_SIGMA_M, adsb_system, covered_area
    from skytrack.io import read_adsb

    if config.output.full_covariance and identification is not None and identification.fuse:
        raise ValueError("--adsb-fuse writes the fused position and velocity variances; it cannot also write "
                         "the full covariance (--full-covariance)")
    adsb = read_adsb(adsb_path, sensors=sensor_set, default_sigma_m=DEFAULT_ADSB_SIGMA_M)
    if len(adsb) == 0:
        raise ValueError(f"{adsb_path}: no ADS-B report to identify tracks with")
    return TrackLabeler(adsb_system(adsb), covered_area(sensor_set, adsb), identification)


def _write_chunk(tracker, labeler, writer, events, reports=None) -> None:
    """The track rows and identity events produced so far, labelled with ADS-B when it is given
    (and the plots the tracks took, when they are written)."""
    table = tracker.drain_arrow()
    events.write(tracker.drain_identity_events())
    taken = tracker.drain_assignments()
    if reports is not None:
        reports.write(taken)
    if labeler is not None:
        table, adsb_events = labeler.label(table, taken)
        events.write(adsb_events)
    writer.write(table, checked=True)


def no_tracks_reason(summary: RunSummary, config: TrackerConfig) -> str:
    """One sentence on why a run wrote no track, from what the tracker counted."""
    stats = summary.stats
    lifecycle = config.lifecycle
    if summary.plots == 0:
        skipped = "" if summary.report is None or summary.report.ok else f" ({summary.report})"
        return f"no plot was read{skipped}"
    started, confirmed = stats.get("tracks_started", 0), stats.get("tracks_confirmed", 0)
    if started == 0:
        return f"none of the {summary.plots} plots started a track"
    if confirmed == 0 and config.score.track_logic == "score":
        return (f"{started} tentative tracks started but none reached the confirmation score: a track needs "
                "several plots that fit its motion, as many more as the false-track rate and the clutter density "
                "demand (check the radars' scan_period_s against the plots' times, and the plots' units)")
    if confirmed == 0:
        return (f"{started} tentative tracks started but none was confirmed by the {lifecycle.confirm_m}-of-"
                f"{lifecycle.confirm_n} rule: a track needs plots on {lifecycle.confirm_m} of {lifecycle.confirm_n} "
                "consecutive scans (check the radars' scan_period_s against the plots' times, and the plots' "
                "units)")
    return f"{confirmed} tracks were confirmed but no output instant fell within their lives"

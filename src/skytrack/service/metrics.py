"""``/metrics`` of ``skytrack serve`` in the Prometheus text exposition format (issue 11 item 3).

Counters (``_total``) count from the service's start; gauges are the value now.  Every metric is listed in
docs/service.md with its meaning; :data:`COUNTERS` and the gauges below are the whole set.
"""

from __future__ import annotations

import math
import time

#: counter name -> (pipeline counter, help text)
COUNTERS: dict[str, tuple[str, str]] = {
    "skytrack_datagrams_total": ("datagrams", "UDP datagrams decoded"),
    "skytrack_datagrams_dropped_overload_total": ("datagrams_dropped_overload",
                                                 "UDP datagrams dropped because the inbox was full (tracking behind)"),
    "skytrack_bytes_total": ("bytes", "bytes of UDP payload decoded"),
    "skytrack_plots_received_total": ("plots_received", "CAT048 plots decoded"),
    "skytrack_plots_tracked_total": ("plots_tracked", "plots fed to the tracker"),
    "skytrack_plots_late_total": ("plots_late", "plots older than the reorder buffer's release time (not tracked)"),
    "skytrack_plots_unknown_sensor_total": ("plots_unknown_sensor", "plots whose SAC/SIC is no sensor of sensors.json"),
    "skytrack_decode_problems_total": ("decode_problems", "ASTERIX decoding problems (damaged input, by kind below)"),
    "skytrack_service_messages_total": ("service_messages", "CAT034 service messages decoded"),
    "skytrack_adsb_reports_total": ("adsb_reports", "CAT021 ADS-B reports decoded"),
    "skytrack_adsb_reports_used_total": ("adsb_reports_used", "CAT021 reports given to the labeller (without --adsb)"),
    "skytrack_adsb_reports_late_total": ("adsb_reports_late",
                                         "CAT021 reports older than what the labeller had read (not used)"),
    "skytrack_frames_sent_total": ("frames_sent", "frames broadcast to the WebSocket clients"),
    "skytrack_frames_dropped_total": ("frames_dropped", "frames a slow WebSocket client did not get"),
    "skytrack_tracker_errors_total": ("tracker_errors", "plot batches the tracker refused (see /health)"),
    "skytrack_checkpoints_total": ("checkpoints", "checkpoints written"),
}


def _value(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "NaN"
    return repr(float(value)) if isinstance(value, float) else str(int(value))


def prometheus_text(service) -> str:
    """The metrics of a :class:`~skytrack.service.app.LiveService` as Prometheus text."""
    pipeline = service.pipeline
    counters = pipeline.counters
    lines: list[str] = []

    def metric(name: str, kind: str, help_text: str, samples: list[tuple[str, object]]) -> None:
        lines.append(f"# HELP {name} {help_text}")
        lines.append(f"# TYPE {name} {kind}")
        for labels, value in samples:
            lines.append(f"{name}{labels} {_value(value)}")

    for name, (key, help_text) in COUNTERS.items():
        metric(name, "counter", help_text, [("", counters[key])])
    metric("skytrack_decode_problems_by_kind_total", "counter", "ASTERIX decoding problems per kind",
           [(f'{{kind="{kind}"}}', count) for kind, count in sorted(pipeline.problems.items())])
    metric("skytrack_plots_late_by_sensor_total", "counter", "late plots per sensor",
           [(f'{{sensor="{name}"}}', int(n))
            for name, n in zip(pipeline.sensors.names, pipeline.reorder.late_per_sensor)])
    now = time.time()
    checkpoint_age = (now - service.last_checkpoint_wall
                      if service.last_checkpoint_wall == service.last_checkpoint_wall else float("nan"))
    last_age = now - service.last_datagram_wall if service.last_datagram_wall == service.last_datagram_wall \
        else float("nan")
    metric("skytrack_clients", "gauge", "WebSocket clients connected", [("", len(service.clients))])
    metric("skytrack_tracks_reported", "gauge", "tracks in the last frame", [("", pipeline.tracks_now)])
    metric("skytrack_tracks_confirmed", "gauge", "confirmed tracks in the tracker", [("", pipeline.confirmed_tracks)])
    metric("skytrack_tracks_confirmed_total", "counter", "tracks confirmed since the tracker started",
           [("", pipeline.tracker.stats.get("tracks_confirmed", 0))])
    metric("skytrack_plots_held", "gauge", "plots in the reorder buffer", [("", len(pipeline.reorder))])
    metric("skytrack_inbox_datagrams", "gauge", "datagrams waiting for the next tracking step",
           [("", len(service.inbox))])
    metric("skytrack_checkpoint_age_seconds", "gauge", "wall time since the last checkpoint", [("", checkpoint_age)])
    metric("skytrack_last_datagram_age_seconds", "gauge", "wall time since the last datagram", [("", last_age)])
    metric("skytrack_uptime_seconds", "gauge", "wall time since the service started",
           [("", now - service.started_wall)])
    metric("skytrack_plots_per_second", "gauge", "plots received per second (last second)",
           [("", service.plots_per_s)])
    quantiles = pipeline.latency_quantiles()
    lines.append("# HELP skytrack_processing_latency_seconds receipt of a frame's newest plot to the frame's broadcast "
                 f"(last {pipeline.latencies.maxlen} frames)")
    lines.append("# TYPE skytrack_processing_latency_seconds summary")
    for q, value in quantiles.items():
        lines.append(f'skytrack_processing_latency_seconds{{quantile="{q}"}} {_value(value)}')
    samples = list(pipeline.latencies)
    lines.append(f"skytrack_processing_latency_seconds_sum {_value(float(sum(samples)))}")
    lines.append(f"skytrack_processing_latency_seconds_count {len(samples)}")
    return "\n".join(lines) + "\n"

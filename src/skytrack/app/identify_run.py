"""``skytrack identify tracks``: identify one system's tracks with another's (spec 001 R13, R14; issue 9).

:func:`identify_tracks` takes

* system 1: a radar's plots (tracked first, with ``sensors.json``) or its tracks file with the
  track reports beside it (``skytrack track --reports``: the plots each track took);
* system 2: ADS-B reports (tracked per address), or another radar's or an IFF interrogator's
  tracks file with its track reports;

and runs :class:`~skytrack.app.identification.TrackLabeler` over system 1's output instants:
every pair the spec 001 test and the global assignment decide is logged (``NAME.pairs``
beside the output), the tracks of system 1 are written labelled with the identities system 2
names (``identity_source`` ``adsb``, ``radar`` or ``iff``) and, with ``fuse``, with the pair's
joint estimate (R14).  With truth, the outcome is scored: ADS-B labels by
:func:`skytrack.analysis.identification.identification_report`, track pairs by
:func:`skytrack.analysis.track_pairs.score_track_pairs`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd
import pyarrow as pa

from skytrack.app.identification import AdsbIdentificationConfig, TrackLabeler
from skytrack.app.other_systems import adsb_system, covered_area, track_system

SOURCES = ("radar", "iff")
#: spec 001 R1: what the radar reports are, said in every summary
APPROXIMATE_POLAR = ("radar reports are plots converted from range and azimuth by linearisation: their Gaussian "
                     "covariance, and so the test, is approximate (spec 001 R1)")


@dataclass
class IdentifySummary:
    """What :func:`identify_tracks` did."""

    tracks_file: str
    pairs_file: str
    events_file: str
    other_kind: str
    """``adsb``, ``radar`` or ``iff``"""
    track_rows: int = 0
    labelled_rows: int = 0
    tracks_identified: int = 0
    pair_rows: int = 0
    stats: dict = field(default_factory=dict)
    report: object = None
    """the report against truth (``None`` without truth)"""
    notes: list[str] = field(default_factory=lambda: [APPROXIMATE_POLAR])

    def to_dict(self) -> dict:
        report = self.report.to_dict() if hasattr(self.report, "to_dict") else self.report
        return {"tracks_file": self.tracks_file, "pairs_file": self.pairs_file, "events_file": self.events_file,
                "other_kind": self.other_kind, "track_rows": self.track_rows, "labelled_rows": self.labelled_rows,
                "tracks_identified": self.tracks_identified, "pair_rows": self.pair_rows, "stats": self.stats,
                "notes": list(self.notes), "report": report}


def _side_path(out: Path, kind: str) -> Path:
    from skytrack.io.identity_events import identity_events_path

    events = identity_events_path(out)
    return events.with_name(events.name.replace(".identity", f".{kind}"))


def is_plots_file(path: Path) -> bool:
    """A radar plots table (FORMATS.md plots: ``range_m`` and ``azimuth_deg``)."""
    from skytrack.io.tables import load_table

    columns = set(load_table(path)[0].columns) if path.suffix.lower() != ".json" else set()
    return {"range_m", "azimuth_deg"} <= columns


def is_adsb_file(path: Path) -> bool:
    """ADS-B reports (an ``icao24`` column and no ``track_id``), in any layout :func:`read_adsb` reads."""
    if path.name.lower().endswith((".json", ".jsonl", ".ndjson", ".json.gz", ".jsonl.gz")):
        return True
    from skytrack.io.tables import load_table

    columns = set(load_table(path)[0].columns)
    return "icao24" in columns and "track_id" not in columns


def _tracks_with_reports(path: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    from skytrack.io import read_tracks
    from skytrack.io.track_reports import read_track_reports, track_reports_path

    reports_path = track_reports_path(path)
    if not reports_path.is_file():
        raise ValueError(f"{path}: no track reports beside it ({reports_path.name}); track with "
                         "`skytrack track ... --reports`, or give the plots and --sensors")
    return read_tracks(path), read_track_reports(reports_path)


def identify_tracks(first: str | Path, second: str | Path, out: str | Path, *, sensors: str | Path | None = None,
                    truth: str | Path | None = None, config: AdsbIdentificationConfig | None = None,
                    source: str = "radar", tracker_config=None, progress=None) -> IdentifySummary:
    """Identify the tracks of ``first`` with ``second`` and write them to ``out`` (module docstring)."""
    from skytrack.io import read_adsb, read_sensors, read_truth, refuse_overwriting, write_tracks
    from skytrack.io.identity_events import identity_events_path
    from skytrack.io.tables import write_table

    if source not in SOURCES:
        raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
    first, second, out = Path(first), Path(second), Path(out)
    config = config if config is not None else AdsbIdentificationConfig()
    sensor_set = read_sensors(sensors) if sensors is not None else None
    adsb = None
    if is_adsb_file(second):
        adsb = read_adsb(second, sensors=sensor_set)
        other = adsb_system(adsb)
        if len(adsb) == 0:
            raise ValueError(f"{second}: no ADS-B report")
    else:
        tracks_b, reports_b = _tracks_with_reports(second)
        other = track_system(reports_b, tracks_b, source)
    refuse_overwriting(out, first=first, second=second, sensors=sensors, truth=truth)
    if is_plots_file(first):
        if sensor_set is None:
            raise ValueError(f"{first} holds plots: give --sensors to track them first")
        from skytrack.app.run import run_tracking

        tracked = out.with_name(out.stem + ".radar" + out.suffix)
        run_tracking(first, sensors, tracked, tracker_config, write_reports=True, progress=progress)
        first = tracked
    tracks_a, reports_a = _tracks_with_reports(first)
    area = covered_area(sensor_set, pd.DataFrame({"x": other.z[:, 0], "y": other.z[:, 1]}))
    labeler = TrackLabeler(other, area, config)
    labeler.add_radar({"track_id": reports_a["track_id"].to_numpy(), "time": reports_a["time"].to_numpy(float),
                       "position": reports_a[["x", "y", "z"]].to_numpy(float),
                       "covariance": _covariances(reports_a)})
    table, events = labeler.label(pa.Table.from_pandas(tracks_a, preserve_index=False), None)
    labelled = table.to_pandas()
    origin = sensor_set.origin if sensor_set is not None else None
    write_tracks(labelled, out, origin=origin)
    pairs = labeler.pairs_table()
    pairs_path = _side_path(out, "pairs")
    write_table(pairs.drop(columns="pair"), pairs_path)
    events_path = identity_events_path(out)
    write_table(events.to_pandas() if events is not None else pd.DataFrame(
        columns=["time", "track_id", "field", "old", "new", "source", "identity_p"]), events_path)
    summary = IdentifySummary(str(out), str(pairs_path), str(events_path), other.source, track_rows=len(labelled),
                              labelled_rows=labeler.stats.labelled_rows,
                              tracks_identified=len(labeler.stats.labelled_tracks), pair_rows=len(pairs),
                              stats={**labeler.stats.to_dict(), **labeler.identifier.stats})
    if truth is not None:
        truth_df = read_truth(truth, sensors=sensor_set) if sensor_set is not None else read_truth(truth)
        if adsb is not None:
            from skytrack.analysis.identification import identification_report

            summary.report = identification_report(labelled, truth_df, adsb)
        else:
            from skytrack.analysis.track_pairs import score_track_pairs

            summary.report = score_track_pairs(pairs, tracks_a, tracks_b, truth_df)
    return summary


def _covariances(reports: pd.DataFrame):
    import numpy as np

    cov = np.zeros((len(reports), 3, 3))
    for name, (i, j) in {"var_x": (0, 0), "var_y": (1, 1), "var_z": (2, 2), "cov_xy": (0, 1), "cov_xz": (0, 2),
                         "cov_yz": (1, 2)}.items():
        cov[:, i, j] = cov[:, j, i] = reports[name].to_numpy(float)
    return cov


def with_settings(config: AdsbIdentificationConfig, **settings) -> AdsbIdentificationConfig:
    """``config`` with the settings that are not None replaced."""
    return replace(config, **{k: v for k, v in settings.items() if v is not None})

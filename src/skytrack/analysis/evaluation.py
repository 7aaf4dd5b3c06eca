"""The result of an evaluation: :class:`Evaluation`, its JSON summary and its table rows."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

UNITS_NOTE = (
    "distances in m, velocities in m/s, times in s since the scenario epoch, durations in s; "
    "NEES dimensionless; continuity and fractions in [0, 1]; gospa_localisation is the sum of "
    "d^p over assigned pairs (m^p), gospa_missed / gospa_false are counts, and "
    "GOSPA^p = gospa_localisation + cutoff^p / 2 * (gospa_missed + gospa_false)"
)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(float(value)) else None
    if value is None or value is pd.NA or value is pd.NaT:
        return None
    return value if isinstance(value, str) else str(value)


def _records(frame: pd.DataFrame) -> list[dict[str, Any]]:
    return [_jsonable(r) for r in frame.to_dict(orient="records")]


@dataclass
class Evaluation:
    """Result of :func:`evaluate`.

    * ``series``: one row per output instant (``time, n_truth_visible, n_tracks, n_assigned,
      position_rmse_m, ospa_m, gospa_m, gospa_localisation, gospa_missed, gospa_false``);
    * ``per_target``: one row per truth object visible at some output instant;
    * ``per_track``: one row per confirmed track;
    * ``assignments``: one row per assigned (instant, truth, track) pair with its errors;
    * ``coverage``: the :func:`coverage_check` table for ``parameters['coverage_min_visible_s']``;
    * ``summary``: the scalar results (see :meth:`to_dict`).
    """

    parameters: dict[str, Any]
    dimension: str
    times: np.ndarray
    output_times_source: str
    series: pd.DataFrame
    per_target: pd.DataFrame
    per_track: pd.DataFrame
    assignments: pd.DataFrame
    coverage: pd.DataFrame
    summary: dict[str, Any]
    nees: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def false_track_ids(self) -> list[int]:
        return self.per_track.loc[self.per_track["is_false"], "track_id"].astype(int).tolist()

    def to_dict(self, per_target: bool = True) -> dict[str, Any]:
        """JSON-serialisable summary (NaN becomes null); ``per_target`` adds the per-object table."""
        cov = self.coverage
        untracked = cov.loc[~cov["tracked"], ["target_id", "segment", "start", "end", "duration_s"]]
        out: dict[str, Any] = {
            "units": UNITS_NOTE,
            "dimension": self.dimension,
            "notes": list(self.notes),
            "parameters": dict(self.parameters),
            "output_times_source": self.output_times_source,
            **self.summary,
            "nees": dict(self.nees),
            "false_tracks": {
                "count": self.summary["n_false_tracks"],
                "fraction_of_tracks": self.summary["false_track_fraction"],
                "fraction_of_track_time": self.summary["false_track_time_fraction"],
                "track_ids": self.false_track_ids,
            },
            "coverage": {
                "min_visible_s": self.parameters["coverage_min_visible_s"],
                "n_objects": int(len(cov)),
                "n_tracked": int(cov["tracked"].sum()),
                "all_tracked": bool(cov["tracked"].all()),
                "untracked": _records(untracked),
            },
        }
        if per_target:
            out["per_target"] = _records(self.per_target)
        return _jsonable(out)

    def _nees_split_rows(self, num) -> list[tuple[str, str, str]]:
        """NEES on straight flight and in or after manoeuvres, when the evaluation split it."""
        if self.nees.get("quiet_n") is None:
            return []
        return [("  straight flight / in or after manoeuvres",
                 f"{num(self.nees['quiet_mean'], '{:.2f}')} / {num(self.nees['manoeuvre_mean'], '{:.2f}')}", "")]

    def _manoeuvre_rows(self, num) -> list[tuple[str, str, str]]:
        """Position and velocity RMSE in the manoeuvre segments, when the evaluation was given them."""
        s = self.summary
        if "velocity_rmse_manoeuvre_mps" not in s:
            return []
        return [(f"  in manoeuvres ({s['n_manoeuvre_segments_visible']} segments, {s['n_manoeuvre_assigned']} samples): "
                 "position / velocity",
                 f"{num(s['position_rmse_manoeuvre_m'])} / {num(s['velocity_rmse_manoeuvre_mps'])}", "m, m/s")]

    def summary_rows(self) -> list[tuple[str, str, str]]:
        """(metric, value, unit) string rows for a table (e.g. ``rich.table.Table.add_row``)."""
        s = self.summary

        def num(value, fmt="{:.1f}"):
            return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else fmt.format(value)

        cov = self.coverage
        p = self.parameters
        rows = [
            ("evaluation", self.dimension, ""),
            ("output instants", f"{s['n_output_times']} ({num(s['time_start_s'])} .. {num(s['time_end_s'])})", "s"),
            ("truth objects (visible)", str(s["n_truth_objects"]), ""),
            ("confirmed tracks", str(s["n_tracks"]), ""),
            ("position RMSE", num(s["position_rmse_m"]), "m"),
        ]
        if s["position_rmse_vertical_m"] is not None and math.isfinite(s["position_rmse_vertical_m"]):
            rows.append(("  horizontal / vertical", f"{num(s['position_rmse_horizontal_m'])} / {num(s['position_rmse_vertical_m'])}", "m"))
        rows += [
            ("velocity RMSE", num(s["velocity_rmse_mps"]), "m/s"),
            *self._manoeuvre_rows(num),
            (
                f"NEES mean ({self.nees['state']}, {self.nees['covariance'].split(' ')[0]} covariance)",
                f"{num(self.nees['mean'], '{:.2f}')} (expected {self.nees['expected']}, 95% band "
                f"{num(self.nees['band_95'][0], '{:.2f}')}..{num(self.nees['band_95'][1], '{:.2f}')})",
                "",
            ),
            *self._nees_split_rows(num),
            ("continuity (mean over objects)", num(s["continuity_mean"], "{:.3f}"), ""),
            ("track breaks", str(s["track_breaks"]), ""),
            ("track swaps", f"{s['track_swaps']} ({s['n_swapped_tracks']} tracks)", ""),
            ("tracks per truth object", num(s["tracks_per_truth_mean"], "{:.2f}"), ""),
            ("time to first track (mean / max)", f"{num(s['time_to_first_track_mean_s'])} / {num(s['time_to_first_track_max_s'])}", "s"),
            ("objects never tracked", str(s["n_truth_never_tracked"]), ""),
            (
                "false tracks",
                f"{s['n_false_tracks']} ({num(100 * s['false_track_fraction'] if s['n_tracks'] else float('nan'))}% of tracks, "
                f"{num(100 * s['false_track_time_fraction'] if s['n_tracks'] else float('nan'))}% of track time)",
                "",
            ),
            (f"OSPA mean (c={p['cutoff_m']:g} m, p={p['order']:g})", num(s["ospa_mean_m"]), "m"),
            (f"GOSPA mean (c={p['cutoff_m']:g} m, p={p['order']:g})", num(s["gospa_mean_m"]), "m"),
            (
                f"coverage: objects visible >= {p['coverage_min_visible_s']:g} s tracked",
                f"{int(cov['tracked'].sum())} / {len(cov)}",
                "",
            ),
        ]
        return rows

"""Track reports beside a tracks file (docs/formats.md "track reports"): path, writer, reader.

One row per plot a confirmed track took: ``time``, ``track_id``, ``sensor``, the plot's
position ``x, y, z`` in the common ENU frame and its covariance ``var_x, var_y, var_z,
cov_xy, cov_xz, cov_yz`` (m²) — the conversion the tracker used (Mode C or assumed height
for 2-D radars).  ``skytrack track --reports`` writes it as ``NAME.reports.parquet`` (or
``.csv``); ``skytrack identify tracks`` reads it: these are the radar tracks' reports of
spec 001 R13 (independent measurements, unlike the track states, which are correlated in time).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.io.checks import RowChecks, as_float, as_int, flag_values, require_columns
from skytrack.io.tables import CSV_SUFFIXES, PARQUET_SUFFIXES, load_table, table_format, write_table

#: the columns of a track-reports file, in order
TRACK_REPORT_COLUMNS = ["time", "track_id", "sensor", "x", "y", "z", "var_x", "var_y", "var_z",
                        "cov_xy", "cov_xz", "cov_yz"]
_COVARIANCE_CELLS = {"var_x": (0, 0), "var_y": (1, 1), "var_z": (2, 2), "cov_xy": (0, 1), "cov_xz": (0, 2),
                     "cov_yz": (1, 2)}


def track_reports_path(tracks_path: str | Path) -> Path:
    """``NAME.reports`` + the tracks file's extension."""
    from skytrack.io.asterix.cat062 import beside_asterix, is_asterix_path  # the asterix package loads numba

    path = Path(tracks_path)
    if is_asterix_path(path):
        return beside_asterix(path, "reports")
    table_format(path)
    name = path.name
    suffix = next(s for s in sorted(CSV_SUFFIXES + PARQUET_SUFFIXES, key=len, reverse=True)
                  if name.lower().endswith(s))
    return path.with_name(name[: len(name) - len(suffix)] + ".reports" + name[len(name) - len(suffix):])


class TrackReportWriter:
    """Collects :meth:`skytrack.tracker.Tracker.drain_assignments` parts and writes them on close."""

    def __init__(self, path: str | Path, sensor_names: list[str] | None = None):
        self.path = Path(path)
        self.sensor_names = sensor_names
        self.parts: list[pd.DataFrame] = []
        self.rows = 0

    def write(self, taken: dict[str, np.ndarray] | None) -> None:
        if taken is None or len(taken["time"]) == 0:
            return
        cov = taken["covariance"]
        sensor = taken["sensor"]
        frame = {"time": taken["time"], "track_id": taken["track_id"],
                 "sensor": (np.asarray(self.sensor_names, dtype=object)[sensor] if self.sensor_names else sensor),
                 "x": taken["position"][:, 0], "y": taken["position"][:, 1], "z": taken["position"][:, 2]}
        for name, (i, j) in _COVARIANCE_CELLS.items():
            frame[name] = cov[:, i, j]
        self.parts.append(pd.DataFrame(frame))
        self.rows += len(taken["time"])

    def close(self) -> None:
        table = pd.concat(self.parts, ignore_index=True) if self.parts else pd.DataFrame(
            {name: pd.Series(dtype=float) for name in TRACK_REPORT_COLUMNS})
        write_table(table.sort_values("time", kind="stable"), self.path)


def read_track_reports(path: str | Path) -> pd.DataFrame:
    """Read and check a track-reports file; errors name the file, row and column."""
    df, source = load_table(path, text_columns=frozenset({"sensor"}))
    require_columns(df, source, ["time", "track_id", "x", "y", "var_x", "var_y"], "track reports")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    for name in ("time", "x", "y", "var_x", "var_y"):
        as_float(df, name, checks, required=True)
    as_int(df, "track_id", checks, nullable=False)
    for name in ("z", "var_z", "cov_xy", "cov_xz", "cov_yz"):
        if name in df.columns:
            as_float(df, name, checks, required=False)
        else:
            df[name] = 0.0
    det = df["var_x"] * df["var_y"] - df["cov_xy"] ** 2
    flag_values(checks, ~((df["var_x"] > 0) & (det > 0)), df["var_x"], "var_x",
                "with var_y and cov_xy is not a positive-definite covariance")
    return checks.finish(df, lenient=False, report=None)

"""Identification reports (FORMATS.md "identification reports"): the input of ``skytrack identify pair``.

Spec 001 R12 (and R1's clear errors): one row per report of either observation system, CSV or
Parquet.  Required: ``time`` (s, or ``timestamp`` converted as for plots), ``system`` (``1`` or
``eta``, ``2`` or ``xi``), ``x``, ``y`` (m, ENU) and a position covariance: ``sigma_m`` (per axis)
or ``var_x``, ``var_y`` [``cov_xy``] (m²; with ``z`` also ``var_z`` [``cov_xz``, ``cov_yz``]).
Optional: ``track_id``, ``z`` (then the test is 3-D and every row needs it), ``vx``, ``vy`` [``vz``]
(m/s; a row with a velocity measures it too and needs ``sigma_v_mps`` or ``var_vx``, ``var_vy``
[``cov_vx_vy``, ...]; velocity errors are independent of position errors).  Rows need not be in
time order.  Every problem names its row and CSV line: a missing or non-numeric value, an unknown
system, a covariance that is not positive definite, a velocity without its covariance.

:func:`read_ident_reports` returns the validated table; :func:`report_measurements` turns it into
per-report arrays (z, V padded to the largest measurement dimension m, and m per row).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.io.checks import RowChecks, as_float, emit_warnings, flag_values, require_columns, time_column
from skytrack.io.errors import ReadReport
from skytrack.io.schema import TEXT_COLUMNS
from skytrack.io.tables import TableSource, load_table

SYSTEM_NAMES = {"1": 1, "eta": 1, "2": 2, "xi": 2}
POSITION_AXES = ("x", "y", "z")
VELOCITY_AXES = ("vx", "vy", "vz")


@dataclass(frozen=True)
class ReportArrays:
    """Per-report arrays of an identification reports table (rows in file order)."""

    time: np.ndarray
    system: np.ndarray
    track_id: np.ndarray
    z: np.ndarray
    """``[R, m_max]``: positions, then velocities where given (zero padding after ``m``)"""
    V: np.ndarray
    """``[R, m_max, m_max]``"""
    m: np.ndarray
    ndim: int


def _covariance_blocks(df: pd.DataFrame, checks: RowChecks, names: tuple[str, ...], sigma_column: str,
                       rows_needing: np.ndarray, what: str) -> np.ndarray:
    """Covariances ``[R, d, d]`` from ``var_<a>`` and ``cov_<a><b>`` (or ``cov_<a>_<b>``; missing = 0), else
    from the per-axis ``sigma_column``; flags rows of ``rows_needing`` without one or not positive definite."""
    d = len(names)
    out = np.full((len(df), d, d), np.nan)
    variances = [f"var_{n}" for n in names]
    full = np.zeros(len(df), dtype=bool)
    if all(v in df.columns for v in variances):
        values = [as_float(df, v, checks, required=False) for v in variances]
        full = np.all([np.isfinite(v) for v in values], axis=0)
        for i, v in enumerate(values):
            out[:, i, i] = v
        for i in range(d):
            for j in range(i + 1, d):
                candidates = [f"cov_{names[i]}{names[j]}", f"cov_{names[i]}_{names[j]}"]
                column = next((c for c in candidates if c in df.columns), None)
                cov = as_float(df, column, checks, required=False) if column else np.zeros(len(df))
                out[:, i, j] = out[:, j, i] = np.where(np.isnan(cov), 0.0, cov)
    if sigma_column in df.columns:
        sigma = as_float(df, sigma_column, checks, required=False)
        flag_values(checks, sigma <= 0, sigma, sigma_column, "is not > 0")
        use = ~full & np.isfinite(sigma)
        out[use] = (sigma[use] ** 2)[:, None, None] * np.eye(d)
        full |= use
    missing = rows_needing & ~full
    alternatives = f"{sigma_column} or {', '.join(variances)}"
    checks.flag(missing, reason=f"{what} covariance missing", column=None,
                describe=lambda r: f"no {what} covariance: give {alternatives}")
    usable = rows_needing & full
    if usable.any():
        block = out[usable]
        eigen = np.linalg.eigvalsh(0.5 * (block + np.swapaxes(block, 1, 2)))[:, 0]
        bad = np.zeros(len(df), dtype=bool)
        bad[np.flatnonzero(usable)[~(eigen > 0)]] = True
        checks.flag(bad, reason=f"{what} covariance not positive definite", column=None,
                    describe=lambda r: f"the {what} covariance {np.round(out[r], 6).tolist()} is not positive definite")
    return out


def _validate(df: pd.DataFrame, source: TableSource, lenient: bool, report: ReadReport) -> pd.DataFrame:
    require_columns(df, source, [("time", "timestamp"), "system", "x", "y"], "identification reports")
    df = df.copy(deep=False)
    checks = RowChecks(source, len(df))
    time_column(df, checks, None, report)
    text = df["system"].astype("string").str.strip().str.lower()
    text = text.str.replace(r"\.0$", "", regex=True)  # 1.0 from a float column is system 1
    known = text.isin(list(SYSTEM_NAMES)).fillna(False).to_numpy(dtype=bool)
    raw = df["system"].to_numpy()
    checks.flag(~known, reason="unknown system", column="system",
                describe=lambda r: f"unknown system {raw[r]!r}: expected 1 (or eta) or 2 (or xi)")
    df["system"] = text.map(SYSTEM_NAMES).fillna(0).astype(np.int8).to_numpy()
    axes = POSITION_AXES if "z" in df.columns else POSITION_AXES[:2]
    for name in axes:
        as_float(df, name, checks, required=True)
    velocity_axes = tuple(v for v in VELOCITY_AXES[:len(axes)] if v in df.columns)
    has_velocity = np.zeros(len(df), dtype=bool)
    if velocity_axes:
        if len(velocity_axes) != len(axes):
            missing = [v for v in VELOCITY_AXES[:len(axes)] if v not in df.columns]
            raise source.error(f"velocity columns {', '.join(velocity_axes)} need {', '.join(missing)} as well")
        values = np.column_stack([as_float(df, v, checks, required=False) for v in velocity_axes])
        given = np.isfinite(values)
        has_velocity = given.all(axis=1)
        partial = given.any(axis=1) & ~has_velocity
        checks.flag(partial, reason="partial velocity", column=None,
                    describe=lambda r: f"velocity given on some axes only ({', '.join(velocity_axes)})")
    everyone = np.ones(len(df), dtype=bool)
    position_cov = _covariance_blocks(df, checks, axes, "sigma_m", everyone, "position")
    velocity_cov = (_covariance_blocks(df, checks, velocity_axes, "sigma_v_mps", has_velocity, "velocity")
                    if velocity_axes else None)
    if "track_id" in df.columns:
        df["track_id"] = df["track_id"].astype("string")
    df = df.assign(_row=np.arange(len(df)))
    df = checks.finish(df, lenient=lenient, report=report)
    kept = df["_row"].to_numpy()
    df.attrs["position_covariance"] = position_cov[kept]
    df.attrs["velocity_covariance"] = None if velocity_cov is None else velocity_cov[kept]
    df.attrs["has_velocity"] = has_velocity[kept]
    df.attrs["ndim"] = len(axes)
    return df.drop(columns="_row")


def read_ident_reports(path: str | Path, *, lenient: bool = False):
    """Read and validate identification reports; ``(table, read report)`` when ``lenient``.

    The covariances are in ``table.attrs`` (``position_covariance`` ``[R, d, d]``,
    ``velocity_covariance``, ``has_velocity``, ``ndim``); :func:`report_measurements` uses them.
    """
    report = ReadReport(file=str(path))
    df, source = load_table(path, text_columns=TEXT_COLUMNS | {"system", "track_id"}, lenient=lenient, report=report)
    table = _validate(df, source, lenient, report)
    emit_warnings(report, lenient)
    return (table, report) if lenient else table


def report_measurements(table: pd.DataFrame) -> ReportArrays:
    """z and V per report: positions, then velocities for the rows that have them."""
    d = int(table.attrs["ndim"])
    has_velocity = np.asarray(table.attrs["has_velocity"], dtype=bool)
    m_max = 2 * d if has_velocity.any() else d
    count = len(table)
    z = np.zeros((count, m_max))
    V = np.zeros((count, m_max, m_max))
    z[:, :d] = table[list(POSITION_AXES[:d])].to_numpy(float)
    V[:, :d, :d] = table.attrs["position_covariance"]
    if has_velocity.any():
        z[has_velocity, d:] = table.loc[has_velocity, list(VELOCITY_AXES[:d])].to_numpy(float)
        V[has_velocity, d:, d:] = table.attrs["velocity_covariance"][has_velocity]
    m = np.where(has_velocity, 2 * d, d)
    track = table["track_id"].to_numpy(dtype=object) if "track_id" in table.columns else np.full(count, None)
    return ReportArrays(table["time"].to_numpy(float), table["system"].to_numpy(np.int8), track, z, V, m, d)

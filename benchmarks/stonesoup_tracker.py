"""A standard Stone Soup GNN/EKF tracker on skytrack's plots: run by ``benchmarks/vs_stonesoup.py``.

This script runs in the benchmark's own Stone Soup virtual environment (stonesoup, numpy,
pandas, pyarrow; no skytrack import).  It reads a plots file and ``sensors.json`` in the
docs/formats.md layout (one ``radar-2d`` sensor: slant range, azimuth, time, optional
Mode C), tracks them with Stone Soup components and writes the confirmed tracks in
skytrack's tracks layout, so that ``skytrack evaluate`` (or ``skytrack.analysis.evaluate``)
scores them exactly as it scores ``skytrack track``'s output.

The tracker (all standard Stone Soup parts):

* state ``[x, vx, y, vy]`` in the common ENU frame; transition
  ``CombinedLinearGaussianTransitionModel`` of two ``ConstantVelocity(q)``;
* ``ExtendedKalmanPredictor`` / ``ExtendedKalmanUpdater`` (symmetric covariances);
* measurement model ``CartesianToBearingRange`` in the radar's frame (translation offset =
  the radar's position), one per plot: a 2-D radar measures *slant* range, which the
  Cartesian-to-bearing-range model does not know, so each plot's range is first turned
  into the horizontal range at the plot's Mode C height (else a default height) on the same
  sphere model skytrack uses (docs/formats.md), and the range variance is inflated by the
  height uncertainty (30 m with Mode C, 3000 m around the 6000 m default, skytrack's values).
  Without this, a 10 km high aircraft at 50 km would carry a 1 km range bias: a straw man;
* ``DistanceHypothesiser`` with the ``Mahalanobis`` measure and a gate (``missed_distance``),
  ``GNNWith2DAssignment``;
* a conservative pre-gate in front of the hypothesiser (:class:`PreGate`, on by default,
  ``--no-pregate`` turns it off): Stone Soup scores every track against every plot of a scan
  with a full EKF prediction (on the first 150 s of a cluttered window: 61.6 s CPU without the
  pre-gate, 2.9 s with it, identical tracks; 2026-11-24), and its own kd-tree pre-filter (``DetectionKDTreeGNN2D``) needs one
  measurement model for all plots, which the per-plot height conversion rules out.  The
  pre-gate drops a pair only when its Cartesian distance proves the Mahalanobis distance is
  beyond the gate (see :class:`PreGate`), so the hypotheses, and the tracks, are the same;
  it makes Stone Soup faster, never better or worse;
* ``MultiMeasurementInitiator``: a tentative track per unassociated plot (zero velocity
  with a ``v_sigma`` prior, ``SimpleMeasurementInitiator``), confirmed after ``min_points``
  plots, dropped after ``init_misses`` consecutive misses (``UpdateTimeStepsDeleter``): an
  M-of-N style confirmation;
* confirmed tracks deleted after ``delete_misses`` consecutive misses (``UpdateTimeStepsDeleter``).

What the tracker knows: the radar's position, scan period and phase, and range and azimuth
errors from sensors.json, as skytrack does.  P_D and the clutter rate are in the same file,
but none of these Stone Soup components takes them (a distance hypothesiser scores by
Mahalanobis distance alone); they enter through the tuning, which chose the gate, the
M-of-N confirmation and the deletion on windows of the same P_D and clutter
(``benchmarks/vs_stonesoup.py``).  Plots of other sensors are ignored; one radar-2d only.

Plots are fed scan by scan (the radar's antenna revolutions, from ``scan_period_s`` and
``scan_phase_s``), every plot with its own timestamp (the hypothesiser predicts each track
to each plot's time); the scan's time is its end (the next north crossing), which is also
where a missed track's prediction is stored.  After every scan, the confirmed tracks are
predicted to the scan end and written: the output instants of ``skytrack track``.

CPU time: ``time.process_time`` around the tracking loop only (tracker steps and the
prediction of the confirmed tracks to the output instants).  Reading the files, building
the Stone Soup detections and writing the tracks are excluded.  It is written to
``--cpu-json`` with the counts and the configuration.

Usage (in the Stone Soup venv):
    python stonesoup_tracker.py PLOTS SENSORS_JSON -o tracks.parquet --cpu-json cpu.json
        [--q 5] [--gate 4] [--min-points 3] [--init-misses 2] [--delete-misses 4] [--v-sigma 200]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import stonesoup
from stonesoup.base import Property
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.deleter.time import UpdateTimeStepsDeleter
from stonesoup.hypothesiser.base import Hypothesiser
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import Mahalanobis
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import ExtendedKalmanPredictor
from stonesoup.tracker.simple import MultiTargetTracker
from stonesoup.types.angle import Bearing
from stonesoup.types.array import CovarianceMatrix, StateVector
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.types.update import Update
from stonesoup.updater.kalman import ExtendedKalmanUpdater

#: mean Earth radius of skytrack's sphere model (docs/formats.md)
EARTH_RADIUS_M = 6_371_008.8
FT = 0.3048
#: skytrack's height assumptions for 2-D plots (docs/formats.md): Mode C +- 30 m, else 6000 +- 3000 m
MODE_C_SIGMA_M = 30.0
DEFAULT_ALT_M = 6000.0
DEFAULT_ALT_SIGMA_M = 3000.0

DEFAULTS = {"q": 5.0, "gate": 4.0, "min_points": 3, "init_misses": 2, "delete_misses": 4, "v_sigma": 200.0}

#: docs/formats.md "tracks": every column is written (nulls where Stone Soup has no value)
FLOAT_COLUMNS = ("x", "y", "z", "vx", "vy", "vz", "var_x", "var_y", "var_z", "var_vx", "var_vy", "var_vz",
                 "lat", "lon", "alt_m")
TEXT_COLUMNS = ("mode3a", "icao24", "callsign", "iff", "model_probs")
COLUMN_ORDER = ("time", "track_id", *FLOAT_COLUMNS, "status", "n_updates", "n_misses", *TEXT_COLUMNS)


def read_radar(path: Path) -> dict:
    """The one radar-2d of a sensors.json, with top-level defaults applied (docs/formats.md rules)."""
    doc = json.loads(path.read_text())
    sensors = doc["sensors"]
    defaults = {k: v for k, v in doc.items() if k not in ("format_version", "epoch_utc", "origin", "sensors")}
    radars = [{**defaults, **{k: v for k, v in s.items() if v is not None}} for s in sensors]
    if len(radars) != 1 or radars[0].get("type", "radar-2d") != "radar-2d":
        raise SystemExit(f"{path}: this script tracks exactly one radar-2d sensor, found "
                         f"{[r.get('type', 'radar-2d') for r in radars]}")
    radar = radars[0]
    if "x" not in radar or "y" not in radar:
        raise SystemExit(f"{path}: the radar needs its x, y in the common frame (skytrack writes them)")
    radar["epoch_utc"] = doc.get("epoch_utc")
    return radar


def read_plots(path: Path) -> pd.DataFrame:
    if path.suffix in (".parquet", ".pq"):
        return pd.read_parquet(path)
    return pd.read_csv(path, dtype={"sensor": str, "mode3a": str, "mode_s": str, "truth_id": str})


def horizontal_range(slant_m: np.ndarray, height_m: np.ndarray, radar_alt_m: float) -> np.ndarray:
    """Ground-plane range of a plot at ``height_m`` on skytrack's sphere model (NaN when impossible)."""
    a, b = EARTH_RADIUS_M + radar_alt_m, EARTH_RADIUS_M + height_m
    s = (slant_m**2 - (a - b) ** 2) / (4 * a * b)
    with np.errstate(invalid="ignore"):
        phi = 2 * np.arcsin(np.sqrt(np.where(s >= 0, s, np.nan)))
    return b * np.sin(phi)


def measurements(plots: pd.DataFrame, radar: dict) -> pd.DataFrame:
    """Bearing (rad, anticlockwise from the frame's +x) and horizontal range with their sigmas."""
    r = plots["range_m"].to_numpy(float)
    mode_c = plots["mode_c_ft"].to_numpy(float) * FT if "mode_c_ft" in plots else np.full(r.size, np.nan)
    known = np.isfinite(mode_c)
    h = np.where(known, mode_c, DEFAULT_ALT_M)
    sigma_h = np.where(known, MODE_C_SIGMA_M, DEFAULT_ALT_SIGMA_M)
    alt = float(radar.get("alt_m", 0.0))
    rho = horizontal_range(r, h, alt)
    # the range's sensitivity to slant range and height, by central differences (1 m steps)
    d_r = (horizontal_range(r + 1.0, h, alt) - horizontal_range(r - 1.0, h, alt)) / 2.0
    d_h = (horizontal_range(r, h + 1.0, alt) - horizontal_range(r, h - 1.0, alt)) / 2.0
    sigma_rho = np.sqrt((d_r * radar["sigma_range_m"]) ** 2 + (d_h * sigma_h) ** 2)
    # azimuth clockwise from the radar's north -> bearing anticlockwise from the common frame's east
    az = plots["azimuth_deg"].to_numpy(float) + float(radar.get("north_offset_deg", 0.0))
    bearing = np.radians(90.0 - az)
    frame = pd.DataFrame({"time": plots["time"].to_numpy(float), "bearing": bearing, "rho": rho,
                          "sigma_rho": sigma_rho})
    return frame[np.isfinite(rho) & np.isfinite(sigma_rho)]


class PreGate(Hypothesiser):
    """Hands the wrapped hypothesiser only the plots that can be inside its Mahalanobis gate.

    For a pair (track, plot) with innovation covariance S, the Mahalanobis distance d obeys
    d^2 >= |e|^2 / lambda_max(S) >= |e|^2 / trace(S), e the innovation.  In Cartesian terms
    (the EKF linearises the same way), sqrt(trace S) is at most the sum of the standard
    deviations of the track's position, of its velocity times dt, of the process noise
    (2 q dt^3 / 3 over two axes) and of the plot's position (range and cross-range sigmas);
    a plot farther from the track's straight-line prediction than ``margin`` x gate x that
    sum is outside the gate, and the hypothesiser would not have returned it.  ``margin``
    (1.5) covers the difference between the bearing-range innovation and its Cartesian
    linearisation (a few per cent over a gate at these ranges).
    """

    hypothesiser: Hypothesiser = Property(doc="the hypothesiser that scores the remaining pairs")
    gate: float = Property(doc="the wrapped hypothesiser's missed_distance (Mahalanobis)")
    q: float = Property(doc="the constant-velocity process noise per axis, m^2/s^3")
    plots: dict = Property(doc="Detection -> (time s, x, y, position sigma m)")
    epoch: dt.datetime = Property(doc="time zero of the detections' timestamps")
    margin: float = Property(default=1.5)

    def hypothesise(self, track, detections, timestamp, **kwargs):
        if detections:
            state = track.state
            sv, covar = state.state_vector, state.covar
            x, vx, y, vy = (float(sv[j, 0]) for j in range(4))
            sigma_p = math.sqrt(covar[0, 0] + covar[2, 2])
            sigma_v = math.sqrt(covar[1, 1] + covar[3, 3])
            t0 = (state.timestamp - self.epoch).total_seconds()
            listed = list(detections)
            t, px, py, sigma_z = np.array([self.plots[d] for d in listed]).T
            lag = np.abs(t - t0)
            radius = self.margin * self.gate * (sigma_p + lag * sigma_v + np.sqrt(2 * self.q * lag**3 / 3) + sigma_z)
            distance = np.hypot(px - (x + vx * (t - t0)), py - (y + vy * (t - t0)))
            detections = {d for d, near in zip(listed, distance <= radius) if near}
        return self.hypothesiser.hypothesise(track, detections, timestamp, **kwargs)


def build_scans(meas: pd.DataFrame, radar: dict, epoch: dt.datetime):
    """``[(scan end s, scan end datetime, set of Detection)]`` for every scan from the first to the last plot's."""
    period, phase = float(radar["scan_period_s"]), float(radar.get("scan_phase_s") or 0.0)
    sigma_b = math.radians(radar["sigma_azimuth_deg"])
    offset = StateVector([float(radar["x"]), float(radar["y"])])
    scan = np.floor((meas["time"].to_numpy() - phase) / period).astype(np.int64)
    groups: dict[int, set] = {}
    positions = {}
    for k, (t, b, rho, s_rho) in zip(scan, meas[["time", "bearing", "rho", "sigma_rho"]].itertuples(index=False)):
        model = CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([sigma_b**2, s_rho**2]),
                                        translation_offset=offset)
        detection = Detection(StateVector([Bearing(b), rho]), timestamp=epoch + dt.timedelta(seconds=float(t)),
                              measurement_model=model)
        groups.setdefault(int(k), set()).add(detection)
        positions[detection] = (float(t), offset[0, 0] + rho * math.cos(b), offset[1, 0] + rho * math.sin(b),
                                math.hypot(s_rho, rho * sigma_b))
    scans = []
    for k in range(int(scan.min()), int(scan.max()) + 1) if scan.size else ():
        end_s = phase + (k + 1) * period
        scans.append((end_s, epoch + dt.timedelta(seconds=end_s), groups.get(k, set())))
    return scans, offset, sigma_b, positions


def build_tracker(config: dict, offset, sigma_b, scans, positions=None, epoch=None):
    """The Stone Soup components of the module docstring, wired into a MultiTargetTracker."""
    q = float(config["q"])
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    # the updater's own model is only a fallback: every detection carries its own
    default_model = CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([sigma_b**2, 50.0**2]),
                                            translation_offset=offset)
    predictor = ExtendedKalmanPredictor(transition)
    updater = ExtendedKalmanUpdater(default_model, force_symmetric_covariance=True)
    hypothesiser = DistanceHypothesiser(predictor, updater, measure=Mahalanobis(), missed_distance=float(config["gate"]))
    if positions is not None:
        hypothesiser = PreGate(hypothesiser, gate=float(config["gate"]), q=q, plots=positions, epoch=epoch)
    associator = GNNWith2DAssignment(hypothesiser)
    v = float(config["v_sigma"])
    prior = GaussianState(StateVector([0.0, 0.0, 0.0, 0.0]), CovarianceMatrix(np.diag([0.0, v**2, 0.0, v**2])))
    initiator = MultiMeasurementInitiator(
        prior_state=prior, measurement_model=default_model,
        deleter=UpdateTimeStepsDeleter(int(config["init_misses"])),
        data_associator=associator, updater=updater, min_points=int(config["min_points"]))
    detector = [(when, detections) for _, when, detections in scans]
    tracker = MultiTargetTracker(initiator=initiator, deleter=UpdateTimeStepsDeleter(int(config["delete_misses"])),
                                 detector=detector, data_associator=associator, updater=updater)
    return tracker, predictor


def run(scans, tracker, predictor) -> list[tuple]:
    """The tracking loop: one tracker step per scan, then every confirmed track at the scan end."""
    rows = []
    n_updates: dict[str, int] = {}
    n_misses: dict[str, int] = {}
    for (end_s, when, _), (_, tracks) in zip(scans, tracker):
        for track in tracks:
            state = track.state
            updated = isinstance(state, Update) and bool(state.hypothesis)
            if track.id not in n_updates:  # just confirmed: its history comes from the initiator
                n_updates[track.id] = sum(1 for s in track.states if isinstance(s, Update) and s.hypothesis)
                n_misses[track.id] = 0 if updated else 1
            else:
                n_updates[track.id] += int(updated)
                n_misses[track.id] = 0 if updated else n_misses[track.id] + 1
            out = state if state.timestamp == when else predictor.predict(state, timestamp=when)
            rows.append((end_s, track.id, out.state_vector, out.covar, n_updates[track.id], n_misses[track.id]))
    return rows


def write_tracks(rows: list[tuple], path: Path, metadata: dict) -> int:
    """The rows in docs/formats.md's tracks layout (2-D tracking: z columns null)."""
    ids: dict[str, int] = {}
    # Stone Soup keeps its tracks in a set: order each instant's rows by position so that the
    # track numbers (first seen, first numbered) do not depend on the set's order
    rows = sorted(rows, key=lambda row: (row[0], float(row[2][0, 0]), float(row[2][2, 0])))
    n = len(rows)
    data = {c: np.full(n, np.nan) for c in FLOAT_COLUMNS}
    time_s, track_id = np.empty(n), np.empty(n, np.int64)
    n_upd, n_mis = np.empty(n, np.int64), np.empty(n, np.int64)
    for i, (t, key, sv, covar, updates, misses) in enumerate(rows):
        time_s[i] = t
        track_id[i] = ids.setdefault(key, len(ids) + 1)
        data["x"][i], data["vx"][i], data["y"][i], data["vy"][i] = (float(sv[j, 0]) for j in range(4))
        data["var_x"][i], data["var_vx"][i] = covar[0, 0], covar[1, 1]
        data["var_y"][i], data["var_vy"][i] = covar[2, 2], covar[3, 3]
        n_upd[i], n_mis[i] = updates, misses
    columns = {"time": pa.array(time_s), "track_id": pa.array(track_id)}
    columns.update({c: pa.array(data[c], mask=np.isnan(data[c])) for c in FLOAT_COLUMNS})
    columns["status"] = pa.array(np.where(n_mis == 0, "confirmed", "coasting").tolist(), pa.string())
    columns["n_updates"], columns["n_misses"] = pa.array(n_upd), pa.array(n_mis)
    columns.update({c: pa.nulls(n, pa.string()) for c in TEXT_COLUMNS})
    table = pa.table({c: columns[c] for c in COLUMN_ORDER})
    # evaluate starts the evaluated window at the input's first plot, as for skytrack's own files
    table = table.replace_schema_metadata({"skytrack.run": json.dumps(metadata)})
    pq.write_table(table, path)
    return len(ids)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("plots", type=Path)
    parser.add_argument("sensors", type=Path)
    parser.add_argument("-o", "--out", type=Path, required=True, help="tracks file (.parquet)")
    parser.add_argument("--cpu-json", type=Path, required=True, help="where to write the CPU time and counts")
    parser.add_argument("--no-pregate", action="store_true", help="score every track against every plot (slow)")
    for key, value in DEFAULTS.items():
        parser.add_argument("--" + key.replace("_", "-"), type=type(value), default=value)
    args = parser.parse_args()
    config = {key: getattr(args, key) for key in DEFAULTS}

    radar = read_radar(args.sensors)
    plots = read_plots(args.plots)
    plots = plots[plots["sensor"] == radar["name"]]
    epoch = dt.datetime(2000, 1, 1)  # any fixed instant: times are written back as seconds
    meas = measurements(plots, radar)
    scans, offset, sigma_b, positions = build_scans(meas, radar, epoch)
    tracker, predictor = build_tracker(config, offset, sigma_b, scans, None if args.no_pregate else positions, epoch)

    wall, cpu = time.perf_counter(), time.process_time()
    rows = run(scans, tracker, predictor)
    cpu_s, wall_s = time.process_time() - cpu, time.perf_counter() - wall

    metadata = {"input_file": args.plots.name, "input_plots": len(plots), "epoch_utc": radar.get("epoch_utc"),
                "input_time_start_s": float(plots["time"].min()) if len(plots) else None,
                "input_time_end_s": float(plots["time"].max()) if len(plots) else None,
                "tracker": f"stonesoup {stonesoup.__version__}"}
    n_tracks = write_tracks(rows, args.out, metadata)
    report = {"stonesoup_version": stonesoup.__version__, "config": config, "pregate": not args.no_pregate, "cpu_s": cpu_s, "wall_s": wall_s,
              "plots": len(plots), "plots_tracked": len(meas), "plots_unplaceable": int(len(plots) - len(meas)),
              "scans": len(scans), "track_rows": len(rows), "confirmed_tracks": n_tracks}
    args.cpu_json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()

"""skytrack side by side with a standard Stone Soup GNN/EKF tracker (a benchmark, not a test).

What it compares, on each window (``benchmarks/vs_stonesoup_windows.py``: one 2-D radar,
4.5 s scan, sigma_r 50 m, sigma_az 0.1 deg, P_D 0.9, 20 false plots per scan uniform in range
and azimuth, watching either 15 minutes of 40 simulated aircraft, 30 % manoeuvring, or
10-20 minutes of recorded aircraft over Switzerland; a new window is an entry of its table):

* skytrack: ``skytrack track PLOTS --sensors sensors.json -o tracks.parquet``, the default
  configuration (no option);
* Stone Soup: ``benchmarks/stonesoup_tracker.py`` (EKF, ``CartesianToBearingRange`` in the
  radar's frame, constant velocity, ``DistanceHypothesiser`` + Mahalanobis gate,
  ``GNNWith2DAssignment``, ``MultiMeasurementInitiator``, ``UpdateTimeStepsDeleter``; see
  its docstring), run in its own virtual environment, created once under
  ``~/.cache/skytrack-bench/stonesoup-<version>-venv`` with ``stonesoup==`` :data:`STONESOUP_VERSION`
  and numpy, pandas, pyarrow from PyPI.  It is given the same sensors.json as skytrack
  (P_D, clutter rate and the radar's errors) and the configuration :data:`STONESOUP_CONFIG`.

Both tracks files are scored by the same call, ``skytrack.analysis.evaluate`` (what
``skytrack evaluate`` runs), on the same output instants (the radar's scan ends from the
first plot's scan to the last plot's) and from the same start (the first plot): GOSPA
(c = 2 km, p = 2, mean over the instants) with its split (localisation as the root of its
mean sum of squared distances, and the mean numbers of missed aircraft and false tracks
per instant), false tracks (assigned less than half of their life), track breaks,
position and velocity RMSE.

CPU time, tracking only (reading, parsing and writing excluded for both):

* skytrack: in this process, ``Tracker(sensors, TrackerConfig())`` fed the plot batches of
  ``skytrack.io.iter_plot_batches`` (parsed once beforehand), then finished and drained:
  the loop of ``skytrack.app.run.run_tracking`` without its file I/O.  One untimed warm-up
  run first (numba compilation or cache loading is excluded), then ``--runs`` timed runs
  with ``time.process_time``; the median is reported.
* Stone Soup: ``time.process_time`` around its tracking loop, measured by the script
  itself (detections built beforehand), ``--stonesoup-runs`` runs (default 1: a run takes
  about half a minute; the output says how many).

All thread pools are pinned to one thread (both processes), so CPU time is one core's.
Plots per CPU-second = plots in the window / CPU time; the ratio is skytrack's over Stone
Soup's.  The acceptance lines compare, on every window: GOSPA (skytrack lower), false
tracks and track breaks (skytrack at most Stone Soup's), and the ratio (at least 1000).

Tuning (``--tune``): Stone Soup's parameters are chosen on the tuning windows only (other
seeds than the reported windows), by coordinate search: each parameter in turn takes the
value of :data:`TUNING_GRID` with the lowest mean GOSPA over the tuning windows, the
others held (``--tune-passes`` passes, from :data:`TUNING_START` or, with ``--tune-from
current``, from :data:`STONESOUP_CONFIG`).  Trials are cached in the workdir
(``tuning_trials.json``), so an extended grid costs only its new points.  The chosen values
are copied into :data:`STONESOUP_CONFIG` by hand.

Tuning record (stonesoup 1.9.1, windows tune-1 and tune-2, skytrack 3c0f3f3 for the
simulation and evaluation, 2026-11-24; 52 configurations, about 1.7 min each):

1. two passes from TUNING_START (q 10, gate 4, 3 plots, 2 misses, delete after 4, v_sigma
   200: GOSPA 1731 m, 8 false tracks, 20.5 breaks) over q 2-100, gate 3-6, min_points 2-4,
   init_misses 1-3, delete_misses 2-6, v_sigma 100-300 -> q 2, gate 4, 3, 2, 3, v_sigma 100
   (GOSPA 1517 m); q and v_sigma ended on the grid's lower edge;
2. the grid extended down (q 0.1-1, v_sigma 70), one pass from there (values that lost by
   far in every earlier sweep dropped: min_points 2, 75-109 false tracks; delete_misses 2
   and 6) -> the configuration below.  q and v_sigma are again on the lower edge: the search
   is not converged there (the time ran out); GOSPA fell by 1.5-3.5 % per step down in q.

Best trials (means over the two windows; skytrack's default on the same windows: GOSPA
1259 / 1242 m, 0 false tracks, 0 breaks, position RMSE 158 / 140 m)::

        q  gate  min_points  init_misses  delete_misses  v_sigma   GOSPA  false  breaks  pos. RMSE
      0.1     4           3            2              3       70    1380    0.0    34.0    156   <- chosen
      0.1     4           3            2              3      100    1394    1.5    34.5    155
      0.1     3           3            2              3      100    1406    0.5    40.0    158
      0.2     4           3            2              3      100    1415    1.5    34.5    158
      0.1     5           3            2              3      100    1417    2.5    31.0    159
      0.1     4           3            2              4      100    1423    1.5    29.0    159
      0.5     4           3            2              3      100    1463    1.5    31.5    170
        2     4           3            2              3      100    1517    1.5    30.5    177
       10     4           3            2              4      200    1731    8.0    20.5    198   (start)
      100     4           3            2              4      200    1874    9.0     7.5    235

What it shows: GOSPA rewards a nearly constant-velocity filter (most of the time the
aircraft fly straight) and breaking a track at a manoeuvre rather than following it with
more process noise; a high q (100) gives 7.5 breaks but 36 % more GOSPA.  No configuration
tried reached skytrack's 0 breaks.

Usage:
    python benchmarks/vs_stonesoup.py [--windows report-1,report-2,report-3 | --tune]
                                      [--runs 5] [--stonesoup-runs 1] [--json out.json] [--workdir DIR]
"""

from __future__ import annotations

import os

ONE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
os.environ.update(ONE_THREAD)  # before numpy is imported: CPU time is then one core's

import argparse
import datetime as dt
import hashlib
import json
import math
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import vs_stonesoup_windows as windows
from machine import cpu_model, usable_cores, versions

STONESOUP_VERSION = "1.9.1"
#: the Stone Soup venv's other packages (unpinned: whatever PyPI serves that fits stonesoup)
STONESOUP_DEPENDENCIES = ("numpy", "pandas", "pyarrow")
VENV = Path.home() / ".cache" / "skytrack-bench" / f"stonesoup-{STONESOUP_VERSION}-venv"
TRACKER_SCRIPT = Path(__file__).parent / "stonesoup_tracker.py"

#: Stone Soup's configuration (chosen by ``--tune``, see the docstring's tuning record)
STONESOUP_CONFIG = {"q": 0.1, "gate": 4.0, "min_points": 3, "init_misses": 2, "delete_misses": 3, "v_sigma": 70.0}
#: where ``--tune`` starts: textbook values for this radar (q for aircraft between straight
#: flight and turns, the 99.97 % gate of a 2-D innovation, 3 plots before 2 misses, 4 misses
#: to delete, a prior speed spread covering 110-250 m/s in any direction)
TUNING_START = {"q": 10.0, "gate": 4.0, "min_points": 3, "init_misses": 2, "delete_misses": 4, "v_sigma": 200.0}
#: values tried by ``--tune`` for each parameter, in this order: q (m^2/s^3, per axis), gate
#: (Mahalanobis distance), min_points (plots to confirm), init_misses (consecutive misses that
#: drop a tentative track), delete_misses (... a confirmed track), v_sigma (m/s, initial
#: velocity standard deviation)
TUNING_GRID = {
    "q": (0.1, 0.2, 0.5, 1.0, 2.0, 5.0),
    "gate": (3.0, 4.0, 5.0, 6.0),
    "min_points": (3, 4),
    "init_misses": (1, 2, 3),
    "delete_misses": (3, 4),
    "v_sigma": (70.0, 100.0, 200.0, 300.0),
}

GOSPA_CUTOFF_M = 2000.0
RATIO_TARGET = 1000.0


# ------------------------------------------------------------------------------ Stone Soup venv
def stonesoup_python(console) -> Path:
    """The Stone Soup venv's python, creating the venv the first time (about a minute)."""
    python = VENV / "bin" / "python"
    marker = VENV / "installed.json"
    if marker.exists() and python.exists():
        return python
    console.print(f"creating the Stone Soup venv {VENV} (stonesoup=={STONESOUP_VERSION}, once)")
    subprocess.run([sys.executable, "-m", "venv", "--clear", str(VENV)], check=True)
    install = [str(python), "-m", "pip", "install", "--quiet", f"stonesoup=={STONESOUP_VERSION}", *STONESOUP_DEPENDENCIES]
    done = subprocess.run(install, check=False, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(install)} failed:\n{done.stdout}\n{done.stderr}")
    listed = subprocess.run([str(python), "-m", "pip", "list", "--format", "json"], check=True, capture_output=True,
                            text=True).stdout
    marker.write_text(listed)
    return python


def stonesoup_versions(python: Path) -> dict[str, str]:
    wanted = {"stonesoup", "numpy", "scipy", "pandas", "pyarrow"}
    listed = json.loads((VENV / "installed.json").read_text()) if (VENV / "installed.json").exists() else []
    return {p["name"].lower(): p["version"] for p in listed if p["name"].lower() in wanted}


def run_stonesoup(python: Path, folder: Path, plots: Path, out: Path, config: dict, runs: int,
                  exhaustive: bool = False) -> dict:
    """Run the Stone Soup script ``runs`` times; its last tracks file stays in ``out``."""
    reports = []
    for k in range(runs):
        cpu_json = out.with_name(out.stem + f"_cpu{k}.json")
        options = [f"--{key.replace('_', '-')}={value}" for key, value in config.items()]
        options += ["--no-pregate"] if exhaustive else []
        command = [str(python), str(TRACKER_SCRIPT), str(plots), str(folder / "sensors.json"), "-o", str(out),
                   "--cpu-json", str(cpu_json), *options]
        done = subprocess.run(command, check=False, capture_output=True, text=True, env={**os.environ, **ONE_THREAD})
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(command)} failed:\n{done.stdout}\n{done.stderr}")
        reports.append(json.loads(cpu_json.read_text()))
    report = dict(reports[-1])
    report["cpu_runs_s"] = [r["cpu_s"] for r in reports]
    report["cpu_s"] = statistics.median(report["cpu_runs_s"])
    return report


# ----------------------------------------------------------------------------------- skytrack
def run_skytrack_command(folder: Path, plots: Path, out: Path, options: tuple[str, ...] = ()) -> None:
    """``skytrack track`` with no option (or ``options``): the tracks that are evaluated."""
    command = [sys.executable, "-m", "skytrack", "track", str(plots), "--sensors", str(folder / "sensors.json"),
               "-o", str(out), *options]
    done = subprocess.run(command, check=False, capture_output=True, text=True, env={**os.environ, **ONE_THREAD})
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stdout}\n{done.stderr}")


def time_skytrack(folder: Path, plots: Path, runs: int) -> dict:
    """CPU time of the default tracker on the window's plots, in this process (see the docstring)."""
    from skytrack.app.run import DEFAULT_CHUNK_ROWS
    from skytrack.io import iter_plot_batches, read_sensors
    from skytrack.tracker import Tracker, TrackerConfig

    sensors = read_sensors(folder / "sensors.json")
    batches = list(iter_plot_batches(plots, sensors, chunk_rows=DEFAULT_CHUNK_ROWS))

    def once() -> tuple[float, int]:
        tracker = Tracker(sensors, TrackerConfig())
        rows = 0
        started = time.process_time()
        for batch in batches:
            tracker.feed(batch)
            rows += tracker.drain_arrow().num_rows
        tracker.finish()
        rows += tracker.drain_arrow().num_rows
        return time.process_time() - started, rows

    warm_s, rows = once()  # untimed: numba compilation or cache loading
    cpu = [once()[0] for _ in range(runs)]
    return {"cpu_s": statistics.median(cpu), "cpu_runs_s": cpu, "warm_up_s": warm_s, "track_rows": rows,
            "plots": int(sum(len(b) for b in batches))}


def time_plain_stonesoup(python: Path, folder: Path, plots_frame, out_folder: Path, config: dict,
                         seconds: float) -> dict:
    """Standard Stone Soup (no pre-gate: every track scored against every plot) timed on the
    window's first ``seconds``, with the pre-gated one on the same plots for its speed-up.  Its
    cost per plot grows with the tracks it holds, so a window's start gives it its best rate
    (a ratio against it errs in Stone Soup's favour)."""
    from skytrack.io import read_sensors, write_plots

    first = plots_frame[plots_frame["time"] < plots_frame["time"].min() + seconds]
    part = out_folder / "plots_first.parquet"
    write_plots(first, part, sensors=read_sensors(folder / "sensors.json"))
    plain = run_stonesoup(python, folder, part, out_folder / "tracks_stonesoup_plain.parquet", config, 1, True)
    gated = run_stonesoup(python, folder, part, out_folder / "tracks_stonesoup_first.parquet", config, 1, False)
    return {"seconds": seconds, "plots": len(first), "cpu_s": plain["cpu_s"], "plots_per_cpu_s": len(first) / plain["cpu_s"],
            "pregate_cpu_s": gated["cpu_s"], "pregate_speedup": plain["cpu_s"] / gated["cpu_s"]}


# --------------------------------------------------------------------------------- evaluation
def output_instants(folder: Path, plots_frame) -> tuple:
    """The scan ends of the first radar from the first plot's scan to the last plot's, and the first plot time."""
    import numpy as np

    from skytrack.io import read_sensors

    radar = read_sensors(folder / "sensors.json").sensors[0]
    times = plots_frame["time"].to_numpy(float)
    period, phase = radar.scan_period_s, radar.scan_phase_s or 0.0
    first, last = math.floor((times.min() - phase) / period), math.floor((times.max() - phase) / period)
    return phase + period * (np.arange(first, last + 1) + 1.0), float(times.min())


def evaluate_tracks(tracks_path: Path, truth, instants, start_s: float, manoeuvre_segments=None) -> dict:
    """The summary of ``skytrack.analysis.evaluate`` with the figures this benchmark prints
    (and those of ``manoeuvre_segments``, passed on to ``evaluate``, when given)."""
    from skytrack.analysis import evaluate
    from skytrack.io import read_tracks

    evaluation = evaluate(read_tracks(tracks_path), truth, cutoff_m=GOSPA_CUTOFF_M, association_gate_m=GOSPA_CUTOFF_M,
                          output_times=instants, start_time_s=start_s, manoeuvre_segments=manoeuvre_segments)
    summary = evaluation.summary
    keys = ("gospa_mean_m", "gospa_missed_mean", "gospa_false_mean", "n_false_tracks", "track_breaks",
            "position_rmse_m", "velocity_rmse_mps", "n_tracks", "continuity_mean", "n_truth_objects",
            "time_to_first_track_mean_s", "ospa_mean_m")
    if manoeuvre_segments is not None:
        keys += tuple(key for key in summary if "manoeuvre" in key)
    figures = {key: summary[key] for key in keys}
    figures["gospa_localisation_rms_m"] = math.sqrt(summary["gospa_localisation_mean"])
    at_once = evaluation.series["n_truth_visible"]
    figures["aircraft_at_once"] = [int(at_once.min()), float(at_once.median()), int(at_once.max())]
    return figures


def run_window(window, workdir: Path, python: Path, config: dict, args, console, with_skytrack: bool = True) -> dict:
    """Prepare one window, run both trackers (or Stone Soup alone) and evaluate them."""
    from skytrack.io import read_plots, read_sensors, read_tracks, read_truth

    folder = window.source.prepare(workdir / window.name)
    plots = windows.table_file(folder, "plots")
    plots_frame = read_plots(plots)
    truth = read_truth(windows.table_file(folder, "truth"), sensors=read_sensors(folder / "sensors.json"))
    instants, start_s = output_instants(folder, plots_frame)
    result = {"window": window.name, "role": window.role, "source": window.source.describe(),
              "folder": str(folder), "plots": len(plots_frame),
              "false_plots": int((plots_frame["truth_id"] == "").sum()) if "truth_id" in plots_frame else None,
              "duration_min": float(instants[-1] - start_s) / 60.0, "output_instants": len(instants)}
    out_ss = workdir / window.name / "tracks_stonesoup.parquet"
    result["stonesoup"] = run_stonesoup(python, folder, plots, out_ss, config, args.stonesoup_runs,
                                        args.stonesoup_exhaustive)
    result["stonesoup"].update(evaluate_tracks(out_ss, truth, instants, start_s))
    if with_skytrack:
        out_sk = workdir / window.name / "tracks_skytrack.parquet"
        out_sk.unlink(missing_ok=True)
        run_skytrack_command(folder, plots, out_sk)
        result["skytrack"] = time_skytrack(folder, plots, args.runs)
        result["skytrack"].update(evaluate_tracks(out_sk, truth, instants, start_s))
        file_rows = len(read_tracks(out_sk))
        if file_rows != result["skytrack"]["track_rows"]:
            console.print(f"[yellow]{window.name}: the timed tracker wrote {result['skytrack']['track_rows']} rows, "
                          f"skytrack track {file_rows}: the timing is not of the evaluated run[/]")
    for name in ("skytrack", "stonesoup"):
        if name in result:
            result[name]["plots_per_cpu_s"] = result["plots"] / result[name]["cpu_s"]
    if with_skytrack and args.plain_seconds > 0 and not args.stonesoup_exhaustive:
        result["stonesoup_plain"] = time_plain_stonesoup(python, folder, plots_frame, workdir / window.name, config,
                                                         args.plain_seconds)
    result["truth_aircraft"] = result["stonesoup"]["n_truth_objects"]
    result["aircraft_at_once"] = result["stonesoup"]["aircraft_at_once"]
    return result


# ------------------------------------------------------------------------------------ printing
ROWS = (  # (label, key, format)
    ("GOSPA mean (c = 2 km, p = 2)", "gospa_mean_m", "{:,.1f} m"),
    ("  localisation (root mean sum of d²)", "gospa_localisation_rms_m", "{:,.1f} m"),
    ("  missed aircraft per instant", "gospa_missed_mean", "{:.3f}"),
    ("  false tracks per instant", "gospa_false_mean", "{:.3f}"),
    ("false tracks", "n_false_tracks", "{:d}"),
    ("track breaks", "track_breaks", "{:d}"),
    ("confirmed tracks", "n_tracks", "{:d}"),
    ("continuity (mean over aircraft)", "continuity_mean", "{:.3f}"),
    ("position RMSE", "position_rmse_m", "{:,.1f} m"),
    ("velocity RMSE", "velocity_rmse_mps", "{:,.1f} m/s"),
    ("time to first track (mean)", "time_to_first_track_mean_s", "{:.1f} s"),
    ("CPU time, tracking only (median)", "cpu_s", "{:.3f} s"),
    ("plots per CPU-second", "plots_per_cpu_s", "{:,.0f}"),
)


def window_table(result: dict, args):
    from rich.table import Table

    sk, ss = result["skytrack"], result["stonesoup"]
    low, _, high = result["aircraft_at_once"]
    title = (f"{result['window']} ({result['source']}): {result['duration_min']:.1f} min, "
             f"{result['truth_aircraft']} aircraft ({low} to {high} at once), {result['plots']:,} plots "
             f"({result['false_plots']:,} false)")
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("skytrack", justify="right")
    table.add_column("Stone Soup", justify="right")
    for label, key, fmt in ROWS:
        table.add_row(label, fmt.format(sk[key]), fmt.format(ss[key]))
    table.add_row("skytrack / Stone Soup plots per CPU-s", f"{sk['plots_per_cpu_s'] / ss['plots_per_cpu_s']:,.0f} x", "")
    plain = result.get("stonesoup_plain")
    if plain:
        table.add_row(f"standard Stone Soup (no pre-gate), first {plain['seconds']:g} s: plots per CPU-s", "",
                      f"{plain['plots_per_cpu_s']:,.0f} (pre-gate {plain['pregate_speedup']:.0f}x faster)")
        table.add_row("skytrack / standard Stone Soup plots per CPU-s",
                      f"{sk['plots_per_cpu_s'] / plain['plots_per_cpu_s']:,.0f} x", "")
    table.add_row("timed runs", f"{len(sk['cpu_runs_s'])} (+1 warm-up)", f"{len(ss['cpu_runs_s'])}")
    return table


def summary_table(results: list[dict]):
    from rich.table import Table

    table = Table(title="summary (skytrack / Stone Soup)")
    for column in ("window", "min", "aircraft (at once)", "GOSPA [m]", "false tracks", "track breaks", "pos. RMSE [m]",
                   "vel. RMSE [m/s]", "plots per CPU-s", "ratio", "standard SS plots/CPU-s", "ratio to standard"):
        table.add_column(column, justify="right")
    for r in results:
        sk, ss = r["skytrack"], r["stonesoup"]
        plain = r.get("stonesoup_plain")
        table.add_row(
            r["window"], f"{r['duration_min']:.0f}",
            f"{r['truth_aircraft']} ({r['aircraft_at_once'][0]}-{r['aircraft_at_once'][2]})",
            f"{sk['gospa_mean_m']:,.0f} / {ss['gospa_mean_m']:,.0f}",
            f"{sk['n_false_tracks']} / {ss['n_false_tracks']}", f"{sk['track_breaks']} / {ss['track_breaks']}",
            f"{sk['position_rmse_m']:,.0f} / {ss['position_rmse_m']:,.0f}",
            f"{sk['velocity_rmse_mps']:.1f} / {ss['velocity_rmse_mps']:.1f}",
            f"{sk['plots_per_cpu_s']:,.0f} / {ss['plots_per_cpu_s']:,.0f}",
            f"{sk['plots_per_cpu_s'] / ss['plots_per_cpu_s']:,.0f} x",
            f"{plain['plots_per_cpu_s']:,.0f}" if plain else "-",
            f"{sk['plots_per_cpu_s'] / plain['plots_per_cpu_s']:,.0f} x" if plain else "-",
        )
    return table


def acceptance(results: list[dict]) -> list[str]:
    """One line per acceptance criterion: met on every window, or where not."""
    checks = (
        ("lower GOSPA", lambda sk, ss: sk["gospa_mean_m"] < ss["gospa_mean_m"]),
        ("at most as many false tracks", lambda sk, ss: sk["n_false_tracks"] <= ss["n_false_tracks"]),
        ("no more track breaks", lambda sk, ss: sk["track_breaks"] <= ss["track_breaks"]),
        (f"at least {RATIO_TARGET:,.0f}x the plots per CPU-second of the pre-gated Stone Soup",
         lambda sk, ss: sk["plots_per_cpu_s"] >= RATIO_TARGET * ss["plots_per_cpu_s"]),
        (f"at least {RATIO_TARGET:,.0f}x the plots per CPU-second of the standard Stone Soup",
         lambda sk, ss: "plain" in ss and sk["plots_per_cpu_s"] >= RATIO_TARGET * ss["plain"]["plots_per_cpu_s"]),
    )
    lines = []
    for label, check in checks:
        failed = [r["window"] for r in results
                  if not check(r["skytrack"], {**r["stonesoup"], **({"plain": r["stonesoup_plain"]}
                                                                    if "stonesoup_plain" in r else {})})]
        lines.append(f"skytrack {label} on every window: " + ("met" if not failed else f"NOT met ({', '.join(failed)})"))
    return lines


def machine_lines(python: Path) -> list[str]:
    found = versions(("numpy", "numba", "pandas", "pyarrow", "skytrack"))
    listed = ", ".join(f"{name} {version}" for name, version in found.items())
    ss = ", ".join(f"{name} {version}" for name, version in stonesoup_versions(python).items())
    import skytrack

    # the skytrack that runs may be another checkout than this script's (PYTHONPATH)
    source = Path(skytrack.__file__).resolve().parent
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], check=False, capture_output=True, text=True,
                            cwd=source).stdout.strip() or "not a git checkout"
    return [
        (f"machine: {cpu_model()}, {os.cpu_count()} cores ({usable_cores()} usable; every run on one thread); "
         f"{platform.platform()}"),
        f"skytrack side: Python {platform.python_version()}, {listed}; skytrack from {source} ({commit})",
        f"Stone Soup side: {ss} (venv {VENV})",
        f"date: {dt.datetime.now().astimezone().isoformat(timespec='seconds')}",
    ]


# -------------------------------------------------------------------------------------- tuning
def tune(tuning_windows, workdir: Path, python: Path, args, console) -> dict:
    """Coordinate search of Stone Soup's parameters on the tuning windows (module docstring)."""
    from rich.table import Table

    # trials already scored in this workdir (same windows, same Stone Soup script) are reused,
    # so that a grid extended after a run costs only its new points
    cache = workdir / "tuning_trials.json"
    stamp = {"windows": [w.name for w in tuning_windows], "script": hashlib.sha256(TRACKER_SCRIPT.read_bytes()).hexdigest(),
             "stonesoup": STONESOUP_VERSION}
    stored = json.loads(cache.read_text()) if cache.exists() else {}
    tried: dict[tuple, dict] = {}
    if stored.get("stamp") == stamp:
        tried = {tuple(sorted(t["config"].items())): t for t in stored["trials"]}
        console.print(f"{len(tried)} trials reused from {cache}")

    def record(config: dict, rows: list[dict]) -> dict:
        key = tuple(sorted(config.items()))
        tried[key] = {"config": dict(config),
                      **{k: statistics.mean(r[k] for r in rows)
                         for k in ("gospa_mean_m", "n_false_tracks", "track_breaks", "position_rmse_m", "cpu_s")}}
        cache.write_text(json.dumps({"stamp": stamp, "trials": list(tried.values())}, indent=1))
        t = tried[key]
        console.print(f"  {config}: GOSPA {t['gospa_mean_m']:,.1f} m, false tracks {t['n_false_tracks']:.1f}, "
                      f"breaks {t['track_breaks']:.1f}, position RMSE {t['position_rmse_m']:,.1f} m, "
                      f"CPU {t['cpu_s']:.1f} s (means over {len(rows)} windows)")
        return t

    def score(config: dict) -> dict:
        key = tuple(sorted(config.items()))
        if key not in tried:
            record(config, [run_window(w, workdir, python, config, args, console, with_skytrack=False)["stonesoup"]
                            for w in tuning_windows])
        return tried[key]

    # the windows are simulated once; every trial tracks the same files
    tuning_windows = [windows.Window(w.name, w.role, windows.FolderSource(w.source.prepare(workdir / w.name)))
                      for w in tuning_windows]
    start = TUNING_START if args.tune_from == "start" else STONESOUP_CONFIG
    reference = [run_window(w, workdir, python, start, args, console) for w in tuning_windows]
    console.print("skytrack (default) on the tuning windows, for reference: "
                  + "; ".join(f"{r['window']} GOSPA {r['skytrack']['gospa_mean_m']:,.1f} m, false tracks "
                              f"{r['skytrack']['n_false_tracks']}, breaks {r['skytrack']['track_breaks']}"
                              for r in reference))
    console.print("pass 1")
    if tuple(sorted(start.items())) not in tried:
        record(start, [r["stonesoup"] for r in reference])
    best = dict(TUNING_START if args.tune_from == "start" else STONESOUP_CONFIG)
    for n_pass in range(args.tune_passes):
        if n_pass:
            console.print(f"pass {n_pass + 1}")
        for name, values in TUNING_GRID.items():
            trials = [score({**best, name: value}) for value in values]
            best = min(trials, key=lambda t: t["gospa_mean_m"])["config"]
    table = Table(title=f"Stone Soup tuning on {', '.join(w.name for w in tuning_windows)} (means over the windows)")
    for column in ("q", "gate", "min_points", "init_misses", "delete_misses", "v_sigma", "GOSPA [m]",
                   "false tracks", "breaks", "pos. RMSE [m]"):
        table.add_column(column, justify="right")
    for t in sorted(tried.values(), key=lambda t: t["gospa_mean_m"]):
        c = t["config"]
        table.add_row(*(f"{c[k]:g}" for k in TUNING_GRID), f"{t['gospa_mean_m']:,.1f}", f"{t['n_false_tracks']:.1f}",
                      f"{t['track_breaks']:.1f}", f"{t['position_rmse_m']:,.1f}")
    console.print(table)
    console.print(f"chosen: {best}")
    return {"chosen": best, "trials": list(tried.values()), "skytrack_reference": reference}


# ---------------------------------------------------------------------------------------- main
def main() -> None:
    from rich.console import Console

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", default=None,
                        help="comma-separated window names, folders or scenario YAMLs (default: the reported windows)")
    parser.add_argument("--tune", action="store_true", help="tune Stone Soup on the tuning windows instead")
    parser.add_argument("--tune-from", choices=("start", "current"), default="start",
                        help="--tune starts at TUNING_START (default) or at the current STONESOUP_CONFIG")
    parser.add_argument("--tune-passes", type=int, default=2, help="coordinate-search passes of --tune (default 2)")
    parser.add_argument("--runs", type=int, default=5, help="timed skytrack runs per window (median; default 5)")
    parser.add_argument("--stonesoup-runs", type=int, default=1, help="Stone Soup runs per window (median; default 1)")
    parser.add_argument("--stonesoup-exhaustive", action="store_true",
                        help="Stone Soup without its pre-gate: every track against every plot (same tracks, "
                             "much slower)")
    parser.add_argument("--plain-seconds", type=float, default=150.0,
                        help="also time the standard Stone Soup (no pre-gate) on each window's first N s (0: skip)")
    parser.add_argument("--json", type=Path, default=None, help="write every figure to this JSON file")
    parser.add_argument("--workdir", type=Path, default=None, help="where windows and tracks go (default: a temp dir)")
    args = parser.parse_args()
    if args.runs < 3:
        parser.error("--runs must be at least 3")
    if args.stonesoup_runs < 1:
        parser.error("--stonesoup-runs must be at least 1")
    console = Console(width=160)
    started = time.perf_counter()
    python = stonesoup_python(console)
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="vs-stonesoup-"))
    for line in machine_lines(python):
        console.print(line)
    console.print(f"windows and tracks in {workdir}")
    output = {"machine": machine_lines(python), "stonesoup_config": STONESOUP_CONFIG}
    if args.tune:
        chosen = windows.parse_windows(args.windows) if args.windows else windows.by_role("tune")
        output["tuning"] = tune(chosen, workdir, python, args, console)
    else:
        chosen = windows.parse_windows(args.windows) if args.windows else windows.by_role("report")
        console.print(f"Stone Soup configuration: {STONESOUP_CONFIG}")
        console.print(f"CPU time: skytrack median of {args.runs} runs after a warm-up run; Stone Soup "
                      + ("one run (slow)" if args.stonesoup_runs == 1 else f"median of {args.stonesoup_runs} runs")
                      + (", exhaustive (no pre-gate)" if args.stonesoup_exhaustive
                         else ", with its pre-gate (the same tracks as without it, faster; see stonesoup_tracker.py)"))
        results = []
        for window in chosen:
            result = run_window(window, workdir, python, STONESOUP_CONFIG, args, console)
            console.print(window_table(result, args))
            results.append(result)
        console.print(summary_table(results))
        for line in acceptance(results):
            console.print(line)
        output["windows"] = results
        output["acceptance"] = acceptance(results)
    elapsed = time.perf_counter() - started
    console.print(f"benchmark wall time {elapsed / 60:.1f} min")
    output["wall_time_s"] = elapsed
    if args.json:
        args.json.write_text(json.dumps(output, indent=2, default=str) + "\n")


if __name__ == "__main__":
    main()

"""skytrack's IMM against its default filter on the demo and the recorded-trajectory benchmark's windows.

What it compares: ``skytrack track PLOTS --sensors sensors.json -o tracks.parquet`` with no
option (the default filter: Kalman CV with the manoeuvre switch) and with ``--filter imm``
(the default model set; ``--imm-args`` adds options), on

* ``demo``: the bundled demo scenario (``skytrack simulate demo``: 78 aircraft over 10
  minutes, one 2-D radar, 4 s scan);
* the windows of role ``report`` of ``benchmarks/vs_stonesoup_windows.py``: ``report-1..3``
  (15 minutes of 40 simulated aircraft, 30 % manoeuvring) and ``swiss-0930``, ``swiss-1120``,
  ``swiss-1140``, ``swiss-1340`` (recorded aircraft over Switzerland as truth).

The IMM's settings were chosen on the ``tune-skytrack`` windows (``paris-1220``,
``paris-1330``) and the terminal scenario, never on these windows.

How it scores: both tracks files by ``vs_stonesoup.evaluate_tracks`` (that is
``skytrack.analysis.evaluate``, as in ``benchmarks/vs_stonesoup.py``: the radar's scan ends as
output instants, from the first plot; GOSPA c = 2 km, p = 2 with its split, false tracks,
track breaks, position and velocity RMSE), given the window's manoeuvre segments, so that
the same assignment of tracks to truth also gives the velocity RMSE in manoeuvres
(``velocity_rmse_manoeuvre_mps``: over the assigned pairs whose truth instant lies in a
segment of its own aircraft).

Manoeuvre segments (``skytrack.studies.maneuver.segments.maneuver_segments``): a segment is a
run of samples whose acceleration normal to the velocity exceeds ``accel_g`` or whose turn
rate exceeds ``turn_rate_deg_s``, lasting at least ``min_duration_s`` (``AIRLINER_RULE``:
0.2 g, 1 deg/s, 5 s, for every window; ``--rule`` changes it).  The acceleration is the
central difference of the sampled velocity (``numpy.gradient``), and a segment covers its
samples plus half a sample period on each side.  Sampled velocities:

* simulated windows: the truth (1 s samples);
* recorded windows (``--manoeuvres-from recorded``, the default): the aircraft's recorded
  velocities at the recording's samples (``adsb.parquet``, every 10 s; velocities that the
  cleaning found stale are null there and skipped).  Between those samples the truth is a
  Hermite curve through the recorded positions, and where a recorded position is off by a
  few hundred metres (not caught by the cleaning) the curve swerves: on the 1 s truth the
  rule then finds "turns" of 1-5 g that no airliner flies.  The segments of the truth curve
  are scored as well (``truth-curve`` figures) and ``--manoeuvres-from truth`` makes them the
  primary ones.

Printed: the machine and date, a table per window (default, IMM, IMM minus default), a
summary table and the acceptance lines (IMM GOSPA lower on every window; IMM velocity RMSE
in manoeuvres lower on every window; at least 5 manoeuvre segments with a visible instant
per window).  Every figure goes to ``imm_vs_default.json`` in the workdir.

Usage:
    python benchmarks/imm_vs_default.py [--windows demo,report-1,...,swiss-1340]
        [--rule turn_rate_deg_s=1,accel_g=0.2,min_duration_s=5] [--manoeuvres-from recorded|truth]
        [--imm-args "--model-set cv-ct"] [--workdir DIR] [--json FILE]
"""

from __future__ import annotations

import os

ONE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
os.environ.update(ONE_THREAD)  # the trackers run as on the other benchmarks: one thread

import argparse
import datetime as dt
import json
import math
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import vs_stonesoup as vs
import vs_stonesoup_windows as windows
from machine import cpu_model, usable_cores, versions

MIN_SEGMENTS = 5
WORKDIR_JSON = "imm_vs_default.json"
VELOCITY = ["vx", "vy", "vz"]


# ------------------------------------------------------------------------------------ windows
def demo_window() -> windows.Window:
    from skytrack.sim.scenario import bundled_scenario_path

    return windows.Window("demo", "report", windows.ScenarioSource(bundled_scenario_path("demo")))


def chosen_windows(text: str | None) -> list[windows.Window]:
    """``--windows``: ``demo`` and the names, folders or YAMLs of ``vs_stonesoup_windows``."""
    if text is None:
        return [demo_window(), *windows.by_role("report")]
    tokens = [t.strip() for t in text.split(",") if t.strip()]
    return [demo_window() if token == "demo" else windows.parse_windows(token)[0] for token in tokens]


# ------------------------------------------------------------------------ manoeuvre segments
def parse_rule(text: str | None):
    """``--rule key=value,...`` over AIRLINER_RULE's values (keys of ``ManeuverRule.from_dict``)."""
    from skytrack.studies.maneuver.segments import AIRLINER_RULE, ManeuverRule
    from skytrack.studies.maneuver.trajectory import G0

    values = {"accel_g": AIRLINER_RULE.accel_threshold_mps2 / G0, "min_duration_s": AIRLINER_RULE.min_duration_s,
              "turn_rate_deg_s": math.degrees(AIRLINER_RULE.turn_rate_threshold_rad_s)}
    for item in (text or "").split(","):
        if item.strip():
            key, _, value = item.partition("=")
            values[key.strip()] = float(value)
    return ManeuverRule.from_dict(values), values


def manoeuvre_segments_of(samples, id_column: str, rule):
    """The segments of ``rule`` on every object's sampled velocities (``time``, ``vx, vy, vz``).

    One row per segment: ``target_id`` (the object's ``id_column``), ``start`` and ``end``
    (its first and last sample, widened by half the sample period), and its peak normal
    acceleration (g) and turn rate (deg/s).
    """
    import numpy as np
    import pandas as pd

    from skytrack.studies.maneuver.segments import maneuver_segments, normal_acceleration
    from skytrack.studies.maneuver.trajectory import G0

    keys = [id_column, "segment"] if "segment" in samples.columns else [id_column]
    rows = []
    for key, rows_of_object in samples.groupby(keys, sort=True):
        object_id = key[0] if isinstance(key, tuple) else key
        rows_of_object = rows_of_object.dropna(subset=VELOCITY).sort_values("time")
        t = rows_of_object["time"].to_numpy(dtype=float)
        if t.size < 3:
            continue
        v = rows_of_object[VELOCITY].to_numpy(dtype=float)
        a = np.gradient(v, t, axis=0)
        a_perp, rate = normal_acceleration(v, a)
        half_period = 0.5 * float(np.median(np.diff(t)))
        for onset, end in maneuver_segments(t, v, a, rule):
            inside = (t >= onset) & (t <= end)
            rows.append((str(object_id), onset - half_period, end + half_period, float(a_perp[inside].max() / G0),
                         float(np.degrees(rate[inside].max()))))
    return pd.DataFrame(rows, columns=["target_id", "start", "end", "peak_accel_g", "peak_turn_rate_deg_s"])


def recorded_samples(folder: Path):
    """The window's recorded samples (``adsb.parquet``/``.csv``, segment id in ``truth_id``), or None."""
    from skytrack.io.tables import load_table

    found = [folder / f"adsb{suffix}" for suffix in (".parquet", ".pq", ".csv", ".csv.gz")]
    path = next((p for p in found if p.exists()), None)
    return None if path is None else load_table(path)[0]


def segment_sets(folder: Path, truth, rule, source: str) -> dict:
    """{"primary": (label, segments), "truth-curve": (...)} of a window (see the docstring)."""
    on_truth = ("truth", manoeuvre_segments_of(truth, "target_id", rule))
    recorded = recorded_samples(folder)
    if recorded is None:
        return {"primary": on_truth}
    on_recorded = ("recorded", manoeuvre_segments_of(recorded, "truth_id", rule))
    if source == "truth":
        return {"primary": on_truth, "other": on_recorded}
    return {"primary": on_recorded, "other": on_truth}


# ------------------------------------------------------------------------------------ running
CONFIGS = {"default": (), "imm": ("--filter", "imm")}


def run_window(window, workdir: Path, rule, args, console) -> dict:
    """Simulate one window, track it with both configurations and evaluate both."""
    from skytrack.io import read_plots, read_sensors, read_truth

    folder = window.source.prepare(workdir / window.name)
    plots = windows.table_file(folder, "plots")
    plots_frame = read_plots(plots)
    truth = read_truth(windows.table_file(folder, "truth"), sensors=read_sensors(folder / "sensors.json"))
    instants, start_s = vs.output_instants(folder, plots_frame)
    sets = segment_sets(folder, truth, rule, args.manoeuvres_from)
    result = {"window": window.name, "source": window.source.describe(), "folder": str(folder),
              "plots": len(plots_frame), "duration_min": float(instants[-1] - start_s) / 60.0,
              "output_instants": len(instants),
              "segments": {name: {"from": label, "segments": frame.to_dict(orient="list")}
                           for name, (label, frame) in sets.items()}}
    for name, options in CONFIGS.items():
        options = (*options, *shlex.split(args.imm_args)) if name == "imm" else options
        out = workdir / window.name / f"tracks_{name}.parquet"
        out.unlink(missing_ok=True)
        started = time.perf_counter()
        vs.run_skytrack_command(folder, plots, out, options)
        wall_s = time.perf_counter() - started
        figures = vs.evaluate_tracks(out, truth, instants, start_s, manoeuvre_segments=sets["primary"][1])
        if "other" in sets:
            other = vs.evaluate_tracks(out, truth, instants, start_s, manoeuvre_segments=sets["other"][1])
            figures.update({f"other_{key}": value for key, value in other.items() if "manoeuvre" in key})
        figures.update(options=list(options), command_wall_s=wall_s)
        result[name] = figures
    result["segments_from"] = sets["primary"][0]
    result["other_segments_from"] = sets["other"][0] if "other" in sets else None
    result["aircraft"] = result["default"]["n_truth_objects"]
    console.print(f"{window.name}: {result['plots']:,} plots, {result['aircraft']} aircraft, "
                  f"{result['default']['n_manoeuvre_segments_visible']} manoeuvre segments ({result['segments_from']})")
    return result


# ----------------------------------------------------------------------------------- printing
ROWS = (  # (label, key, format)
    *(row for row in vs.ROWS if row[1] not in ("cpu_s", "plots_per_cpu_s")),
    ("manoeuvre segments (with a visible instant)", "n_manoeuvre_segments_visible", "{:d}"),
    ("  assigned samples in them", "n_manoeuvre_assigned", "{:d}"),
    ("  position RMSE in manoeuvres", "position_rmse_manoeuvre_m", "{:,.1f} m"),
    ("  velocity RMSE in manoeuvres", "velocity_rmse_manoeuvre_mps", "{:,.1f} m/s"),
    ("truth-curve segments (recorded windows)", "other_n_manoeuvre_segments_visible", "{:d}"),
    ("  velocity RMSE in them", "other_velocity_rmse_manoeuvre_mps", "{:,.1f} m/s"),
)


def window_table(result: dict):
    from rich.table import Table

    title = (f"{result['window']} ({result['source']}): {result['duration_min']:.1f} min, {result['aircraft']} aircraft, "
             f"{result['plots']:,} plots; manoeuvres from the {result['segments_from']} velocities")
    table = Table(title=title)
    for column, justify in (("metric", "left"), ("default", "right"), ("IMM", "right"), ("IMM - default", "right")):
        table.add_column(column, justify=justify)
    default, imm = result["default"], result["imm"]
    for label, key, fmt in ROWS:
        if key not in default:
            continue
        table.add_row(label, fmt.format(default[key]), fmt.format(imm[key]), fmt.format(imm[key] - default[key]))
    return table


def summary_table(results: list[dict]):
    from rich.table import Table

    table = Table(title="summary (default / IMM)")
    for column in ("window", "GOSPA [m]", "localisation [m]", "missed / inst.", "false / inst.", "false tracks",
                   "breaks", "pos. RMSE [m]", "vel. RMSE [m/s]", "segments", "vel. RMSE in manoeuvres [m/s]",
                   "truth-curve segments: vel. RMSE [m/s]"):
        table.add_column(column, justify="right")
    for r in results:
        d, i = r["default"], r["imm"]
        other = (f"{d['other_n_manoeuvre_segments_visible']}: {d['other_velocity_rmse_manoeuvre_mps']:.1f} / "
                 f"{i['other_velocity_rmse_manoeuvre_mps']:.1f}") if r["other_segments_from"] == "truth" else "-"
        table.add_row(
            r["window"], f"{d['gospa_mean_m']:,.0f} / {i['gospa_mean_m']:,.0f}",
            f"{d['gospa_localisation_rms_m']:,.0f} / {i['gospa_localisation_rms_m']:,.0f}",
            f"{d['gospa_missed_mean']:.2f} / {i['gospa_missed_mean']:.2f}",
            f"{d['gospa_false_mean']:.2f} / {i['gospa_false_mean']:.2f}",
            f"{d['n_false_tracks']} / {i['n_false_tracks']}", f"{d['track_breaks']} / {i['track_breaks']}",
            f"{d['position_rmse_m']:,.0f} / {i['position_rmse_m']:,.0f}",
            f"{d['velocity_rmse_mps']:.1f} / {i['velocity_rmse_mps']:.1f}",
            f"{d['n_manoeuvre_segments_visible']} ({r['segments_from']})",
            f"{d['velocity_rmse_manoeuvre_mps']:.1f} / {i['velocity_rmse_manoeuvre_mps']:.1f}", other,
        )
    return table


def acceptance(results: list[dict]) -> list[str]:
    """One line per acceptance criterion: met on every window, or where not."""
    checks = (
        ("IMM lower GOSPA than the default filter", lambda r: r["imm"]["gospa_mean_m"] < r["default"]["gospa_mean_m"]),
        ("IMM lower velocity RMSE in manoeuvre segments",
         lambda r: r["imm"]["velocity_rmse_manoeuvre_mps"] < r["default"]["velocity_rmse_manoeuvre_mps"]),
        (f"at least {MIN_SEGMENTS} manoeuvre segments with a visible instant",
         lambda r: r["default"]["n_manoeuvre_segments_visible"] >= MIN_SEGMENTS),
    )
    lines = []
    for label, check in checks:
        failed = [r["window"] for r in results if not check(r)]
        lines.append(f"{label} on every window: " + ("met" if not failed else f"NOT met ({', '.join(failed)})"))
    return lines


def machine_lines(args, rule_values: dict) -> list[str]:
    import skytrack

    found = ", ".join(f"{name} {version}" for name, version in versions(("numpy", "numba", "pandas", "pyarrow")).items())
    source = Path(skytrack.__file__).resolve().parent
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], check=False, capture_output=True, text=True,
                            cwd=source).stdout.strip() or "not a git checkout"
    rule = ", ".join(f"{key} {value:g}" for key, value in rule_values.items())
    return [
        f"machine: {cpu_model()}, {os.cpu_count()} cores ({usable_cores()} usable; one thread); {platform.platform()}",
        f"Python {platform.python_version()}, {found}; skytrack {skytrack.__version__} from {source} ({commit})",
        f"date: {dt.datetime.now().astimezone().isoformat(timespec='seconds')}",
        f"IMM: skytrack track --filter imm {args.imm_args}".rstrip(),
        f"manoeuvre rule: {rule}; recorded windows' segments from the {args.manoeuvres_from} velocities",
    ]


# --------------------------------------------------------------------------------------- main
def main() -> None:
    from rich.console import Console

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", default=None,
                        help="comma-separated: demo, window names, folders or scenario YAMLs "
                             "(default: demo and the vs_stonesoup windows of role report)")
    parser.add_argument("--rule", default=None,
                        help="manoeuvre rule over AIRLINER_RULE, e.g. turn_rate_deg_s=1,accel_g=0.2,min_duration_s=5 "
                             "(also longitudinal_g, merge_gap_s)")
    parser.add_argument("--manoeuvres-from", choices=("recorded", "truth"), default="recorded",
                        help="recorded windows: detect manoeuvres on the recorded velocities (default) or the truth curve")
    parser.add_argument("--imm-args", default="", help="more options for the IMM run, e.g. \"--model-set cv-ct\"")
    parser.add_argument("--workdir", type=Path, default=None, help="where windows, tracks and the JSON go (default: a temp dir)")
    parser.add_argument("--json", type=Path, default=None, help=f"also write the JSON here (it always goes to WORKDIR/{WORKDIR_JSON})")
    args = parser.parse_args()
    try:
        rule, rule_values = parse_rule(args.rule)
    except ValueError as error:
        parser.error(f"--rule: {error}")
    console = Console(width=200)
    started = time.perf_counter()
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="imm-vs-default-"))
    workdir.mkdir(parents=True, exist_ok=True)
    machine = machine_lines(args, rule_values)
    for line in machine:
        console.print(line)
    console.print(f"windows and tracks in {workdir}")
    results = []
    for window in chosen_windows(args.windows):
        result = run_window(window, workdir, rule, args, console)
        console.print(window_table(result))
        results.append(result)
    console.print(summary_table(results))
    lines = acceptance(results)
    for line in lines:
        console.print(line)
    few = [r for r in results if r["default"]["n_manoeuvre_segments_visible"] < MIN_SEGMENTS]
    for r in few:
        d = r["default"]
        console.print(f"{r['window']}: {d['n_manoeuvre_segments_visible']} manoeuvre segments with a visible instant "
                      f"({d['n_manoeuvre_segments']} in the truth's aircraft, from the {r['segments_from']} velocities)")
    elapsed = time.perf_counter() - started
    console.print(f"benchmark wall time {elapsed / 60:.1f} min")
    output = {"machine": machine, "rule": rule_values, "manoeuvres_from": args.manoeuvres_from,
              "imm_args": args.imm_args, "windows": results, "acceptance": lines, "wall_time_s": elapsed}
    text = json.dumps(output, indent=1, default=str) + "\n"
    (workdir / WORKDIR_JSON).write_text(text)
    if args.json:
        args.json.write_text(text)
    console.print(f"figures written to {workdir / WORKDIR_JSON}")


if __name__ == "__main__":
    main()

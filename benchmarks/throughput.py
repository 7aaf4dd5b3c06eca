"""Tracker throughput on scaled versions of the demo scenario (a benchmark, not a test).

For each traffic size (default 100, 1 000 and 5 000 simultaneous aircraft, all airborne
from the start, with the demo radar's clutter) the scenario is simulated, then
``Tracker.run`` is timed on the in-memory plots table (no file I/O) and its peak memory is
measured with tracemalloc in a second, untimed run.  Everything runs on one core: the
BLAS thread pools are pinned to one thread before numpy is imported.

Usage:  python benchmarks/throughput.py [--sizes 100,1000,5000] [--duration 600] [--repeat 1]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from skytrack.sim import load_scenario, scale_traffic, simulate  # noqa: E402
from skytrack.tracker import Tracker, TrackerConfig  # noqa: E402


def scaled_demo(count: int, duration_s: float):
    scenario = scale_traffic(load_scenario("demo"), count)
    traffic = dataclasses.replace(scenario.traffic, start_time_s=(0.0, 0.0))
    return dataclasses.replace(scenario, traffic=traffic, duration_s=duration_s)


def measure(count: int, duration_s: float, repeat: int) -> dict:
    started = time.perf_counter()
    result = simulate(scaled_demo(count, duration_s))
    simulate_s = time.perf_counter() - started
    plots, sensors = result.plots, result.sensors
    best = float("inf")
    for _ in range(repeat):
        tracker = Tracker(sensors, TrackerConfig())
        started = time.perf_counter()
        tracks = tracker.run(plots)
        best = min(best, time.perf_counter() - started)
    tracemalloc.start()
    Tracker(sensors, TrackerConfig()).run(plots)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    n_false = int((plots["truth_id"] == "").sum())
    return {
        "aircraft": count + len(result.scenario.targets),
        "plots": len(plots),
        "false_plots": n_false,
        "scans": int(round(duration_s / sensors.sensors[0].scan_period_s)),
        "simulate_s": simulate_s,
        "track_s": best,
        "plots_per_s": len(plots) / best,
        "confirmed_tracks": int(tracks["track_id"].nunique()),
        "tracker_peak_mib": peak / 2**20,
        "process_peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="100,1000,5000", help="comma-separated numbers of random aircraft")
    parser.add_argument("--duration", type=float, default=600.0, help="scenario length (s)")
    parser.add_argument("--repeat", type=int, default=1, help="timed runs per size (best is kept)")
    args = parser.parse_args()
    console = Console(width=140)
    table = Table(title="skytrack tracker throughput (one core, scan-batched, no file I/O)")
    for column in ("aircraft", "plots (false)", "scans", "track time", "plots/s", "confirmed tracks",
                   "tracker peak", "process peak RSS"):
        table.add_column(column, justify="right")
    for size in (int(s) for s in args.sizes.split(",")):
        row = measure(size, args.duration, args.repeat)
        table.add_row(
            str(row["aircraft"]), f"{row['plots']:,} ({row['false_plots']:,})", str(row["scans"]),
            f"{row['track_s']:.2f} s", f"{row['plots_per_s']:,.0f}", str(row["confirmed_tracks"]),
            f"{row['tracker_peak_mib']:.0f} MiB", f"{row['process_peak_rss_mib']:.0f} MiB",
        )
        console.print(f"{size} aircraft: simulated in {row['simulate_s']:.1f} s, tracked at {row['plots_per_s']:,.0f} plots/s")
    console.print(table)


if __name__ == "__main__":
    main()

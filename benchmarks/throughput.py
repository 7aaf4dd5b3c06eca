"""Tracker-loop throughput on one core (a benchmark, not a test; issue 5, Acceptance).

What is measured: the tracker loop, the wall time of ``Tracker(sensors, TrackerConfig()).run(batch)``
on the plots of a simulated scene parsed once into a ``PlotBatch`` (as the io readers hand
them to the tracker; no file I/O: ``benchmarks/end_to_end.py`` measures the whole command).
Simulation and parsing are not timed.

How, per scene:
1. simulate the scene (``benchmarks/scenes.py``; default 300 s = 75 scans of the demo radar);
2. one untimed warm-up run of the same scene (start-up, numba compilation or cache loading);
3. ``--runs`` timed runs, each with a new Tracker: median, min and max of the wall time
   (the process CPU time is shown beside it: the machine may be shared);
4. one more untimed run under tracemalloc for the peak traced memory of the tracker.

Scenes (``--scenes``, comma list; see ``benchmarks/scenes.py``):
``sparse-1000`` demo scaled to 1 000 random aircraft, 20 false plots per scan;
``small-50`` the same with 50 aircraft; ``clutter-2000`` sparse-1000 with 2 000 false plots
per scan; ``crossing-1000`` 1 000 aircraft starting in a 25 km box 80 km from the radar with
uniform headings.  For the last two the cost per plot is compared with sparse-1000.

Filters (``--filters``, on the scenes of ``--filter-scenes``, default sparse-1000): ``default``
(the tracker's default Kalman filter with the psi switch), ``imm-cv-ct`` (``--filter imm
--model-set cv-ct``: CV and two coordinated turns, 3 models) and ``imm`` (``--filter imm``:
the tracker's default set, 4 models).  Spec 004's issue asks the 3-model IMM for at least a
third of the default filter's plots/s on the same scene; the ratio is printed.  Association rules
(issue 8) are variants too: ``nn`` (``--association-rule nn``, coordinates only), ``fuzzy``, ``crisp``,
``ml``; for them the scene's plots get IFF replies (70 % of an aircraft's plots, 5 % flipped) besides
their simulated Mode 3/A codes, and ``fuzzy`` / ``crisp`` are held to half of ``nn``'s plots/s.

One core: the OpenMP/BLAS/numba thread pools are pinned to one thread before numpy is
imported.  The script prints the machine, the date and the figures; it claims nothing.

Usage:  python benchmarks/throughput.py [--scenes sparse-1000,small-50,clutter-2000,crossing-1000]
                                        [--runs 3] [--duration 300]
                                        [--filters default,imm-cv-ct,imm] [--filter-scenes sparse-1000]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse  # noqa: E402
import datetime as dt  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

import scenes  # noqa: E402  (benchmarks/scenes.py, next to this file)
from machine import cpu_model, usable_cores, versions  # noqa: E402  (benchmarks/machine.py)
from skytrack.sim import simulate  # noqa: E402
from skytrack.core.plots import PlotBatch  # noqa: E402
from skytrack.tracker import Tracker, TrackerConfig  # noqa: E402
from skytrack.tracker.config import FilterConfig  # noqa: E402

DEFAULT_SCENES = "sparse-1000,small-50,clutter-2000,crossing-1000"
#: scene -> (kind of target, value): minimum plots/s, or maximum cost ratio to sparse-1000
TARGETS = {
    "sparse-1000": ("plots/s", 500_000.0),
    "small-50": ("plots/s", 150_000.0),
    "clutter-2000": ("ratio", 1.5),
    "crossing-1000": ("ratio", 1.5),
}
REFERENCE = "sparse-1000"
#: --filters: name -> the tracker's filter configuration (None: the default)
FILTERS = {
    "default": None,
    "imm-cv-ct": {"kind": "imm", "options": {"model_set": "cv-ct"}},
    "ct-omega-adaptive": {"kind": "ct-omega-adaptive", "options": {}},
    "imm": {"kind": "imm", "options": {}},
}
#: --filters also takes association rules (issue 8): the default filter with ``--association-rule``
RULES = ("nn", "fuzzy", "crisp", "ml")
DEFAULT_FILTERS = "default,imm-cv-ct,imm"
#: variants held to a fraction of another variant's plots/s on the same scene: name -> (baseline, fraction)
RELATIVE_TARGETS = {"imm-cv-ct": ("default", 1.0 / 3.0), "ct-omega-adaptive": ("default", 1.0 / 3.0), "fuzzy": ("nn", 0.5), "crisp": ("nn", 0.5)}
#: identity added to the plots for the rule variants: share of plots with an IFF reply, of flipped replies
IFF_REPLY_SHARE, IFF_FLIP_SHARE = 0.7, 0.05


def tracker_config(filter_name: str) -> TrackerConfig:
    if filter_name in RULES:
        return TrackerConfig(association_rule=filter_name)
    config = TrackerConfig()
    chosen = FILTERS[filter_name]
    if chosen is not None:
        config.filter = FilterConfig(kind=chosen["kind"], options=dict(chosen["options"]))
    return config


def with_iff(plots: pd.DataFrame, seed: int = 8) -> pd.DataFrame:
    """The plots with IFF replies: every aircraft friend or foe, IFF_REPLY_SHARE of its plots replying,
    IFF_FLIP_SHARE of the replies flipped; false plots do not reply (Mode 3/A as simulated)."""
    rng = np.random.default_rng(seed)
    truth = plots["truth_id"].to_numpy(dtype=object)
    ids, index = np.unique(truth.astype(str), return_inverse=True)
    status = rng.integers(0, 2, len(ids))[index]
    status = np.where(rng.random(len(plots)) < IFF_FLIP_SHARE, 1 - status, status)
    reply = (rng.random(len(plots)) < IFF_REPLY_SHARE) & (truth != "")
    out = plots.copy()
    out["iff"] = pd.array(np.where(reply, np.array(["friend", "foe"])[status], None), dtype="str")
    return out


def machine() -> str:
    found = versions(("numpy", "numba", "pandas"))
    listed = ", ".join(f"{name} {version}" for name, version in found.items())
    return (f"{cpu_model()}, {os.cpu_count()} cores ({usable_cores()} usable, the benchmark uses 1); "
            f"Python {platform.python_version()}, {listed}; {platform.platform()}")


def track_once(sensors, plots, filter_name: str = "default"):
    tracker = Tracker(sensors, tracker_config(filter_name))
    wall, cpu = time.perf_counter(), time.process_time()
    tracks = tracker.run(plots)
    return time.perf_counter() - wall, time.process_time() - cpu, tracks


def measure(name: str, duration_s: float, runs: int, console: Console, filters: list[str]) -> list[dict]:
    started = time.perf_counter()
    result = simulate(scenes.build(name, duration_s))
    simulate_s = time.perf_counter() - started
    plots, sensors = result.plots, result.sensors
    # the loop starts from plots parsed once, as the io readers hand them to the tracker
    batch = PlotBatch.from_frame(plots, sensors.names, [s.is_3d for s in sensors.sensors])
    identity = PlotBatch.from_frame(with_iff(plots), sensors.names, [s.is_3d for s in sensors.sensors])
    return [measure_filter(name, result, identity if filter_name in RULES else batch, filter_name, simulate_s, runs,
                           console) for filter_name in filters]


def measure_filter(name: str, result, batch, filter_name: str, simulate_s: float, runs: int, console: Console) -> dict:
    plots, sensors = result.plots, result.sensors
    warm_s, _, _ = track_once(sensors, batch, filter_name)  # untimed: start-up and JIT compilation / cache loading
    walls, cpus = [], []
    for _ in range(runs):
        wall, cpu, tracks = track_once(sensors, batch, filter_name)
        walls.append(wall)
        cpus.append(cpu)
    tracemalloc.start()
    Tracker(sensors, tracker_config(filter_name)).run(batch)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    n = len(plots)
    median = statistics.median(walls)
    row = {
        "scene": name,
        "filter": filter_name,
        "aircraft": int(result.truth["target_id"].nunique()),
        "plots": n,
        "false_plots": int((plots["truth_id"] == "").sum()),
        "scans": int(plots["scan"].nunique()),
        "confirmed_tracks": int(tracks["track_id"].nunique()),
        "median_s": median, "min_s": min(walls), "max_s": max(walls),
        "cpu_median_s": statistics.median(cpus),
        "plots_per_s": n / median,
        "us_per_plot": 1e6 * median / n,
        "peak_mib": peak / 2**20,
        "in_box": scenes.in_box_fraction(result.truth) if name.startswith("crossing") else None,
    }
    console.print(
        f"{name} / {filter_name}: simulated in {simulate_s:.1f} s, warm-up run {warm_s:.2f} s, timed runs "
        + ", ".join(f"{w:.3f}" for w in walls) + f" s -> {row['plots_per_s']:,.0f} plots/s"
        + ("" if row["in_box"] is None else f"; {100 * row['in_box']:.0f} % of truth samples inside the box")
    )
    return row


def verdicts(rows: list[dict], runs: int) -> list[str]:
    by_name = {r["scene"]: r for r in rows if r["filter"] == "default"}
    by_variant = {(r["scene"], r["filter"]): r for r in rows}
    reference = by_name.get(REFERENCE)
    lines = []
    for r in rows:
        head = (f"{r['scene']} / {r['filter']}: {r['plots_per_s']:,.0f} plots/s (median of {runs}), "
                f"{r['us_per_plot']:.3f} us/plot")
        if r["filter"] != "default":
            baseline_name, share = RELATIVE_TARGETS.get(r["filter"], ("default", None))
            baseline = by_variant.get((r["scene"], baseline_name))
            if share is None or baseline is None:
                lines.append(f"{head}" + ("" if baseline is None else
                                          f", {r['plots_per_s'] / baseline['plots_per_s']:.2f} of {baseline_name}'s"))
                continue
            fraction = r["plots_per_s"] / baseline["plots_per_s"]
            lines.append(f"{head}, {fraction:.2f} of {baseline_name}'s, target >= {share:.2f}: "
                         f"{'PASS' if fraction >= share else 'FAIL'}")
            continue
        kind, value = TARGETS.get(r["scene"], (None, None))
        if kind == "plots/s":
            lines.append(f"{head}, target {value:,.0f} plots/s: {'PASS' if r['plots_per_s'] >= value else 'FAIL'}")
        elif kind == "ratio" and reference is not None:
            ratio = r["us_per_plot"] / reference["us_per_plot"]
            lines.append(f"{head}, cost ratio to {REFERENCE} {ratio:.2f}, target <= {value:g}: "
                         f"{'PASS' if ratio <= value else 'FAIL'}")
        elif kind == "ratio":
            lines.append(f"{head}, target ratio <= {value:g} to {REFERENCE}: not run (add {REFERENCE} to --scenes)")
        else:
            lines.append(f"{head}, no target")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=DEFAULT_SCENES, help=f"comma-separated scenes (default {DEFAULT_SCENES})")
    parser.add_argument("--runs", type=int, default=3, help="timed runs per scene (the median is reported)")
    parser.add_argument("--duration", type=float, default=300.0, help="simulated time per scene in s (default 300 = 75 scans)")
    parser.add_argument("--filters", default=DEFAULT_FILTERS,
                        help=f"comma-separated filters of {', '.join(FILTERS)} (default {DEFAULT_FILTERS})")
    parser.add_argument("--filter-scenes", default=REFERENCE,
                        help=f"scenes on which filters other than the default run (default {REFERENCE})")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be >= 1")
    filters = [f.strip() for f in args.filters.split(",") if f.strip()]
    unknown = [f for f in filters if f not in FILTERS and f not in RULES]
    if unknown:
        parser.error(f"--filters: unknown {unknown}; known: {', '.join((*FILTERS, *RULES))}")
    filter_scenes = {s.strip() for s in args.filter_scenes.split(",")}
    console = Console(width=200)
    console.print(f"machine: {machine()}")
    console.print(f"date: {dt.datetime.now().astimezone().isoformat(timespec='seconds')}")
    console.print(f"scene length {args.duration:g} s, {args.runs} timed runs after one untimed warm-up run")
    rows = []
    for name in (n.strip() for n in args.scenes.split(",") if n.strip()):
        chosen = [f for f in filters if f == "default" or name in filter_scenes]
        rows += measure(name, args.duration, args.runs, console, chosen)
    reference = next((r for r in rows if r["scene"] == REFERENCE and r["filter"] == "default"), None)
    table = Table(title=f"skytrack tracker loop throughput (one core, in-memory plots, median of {args.runs} runs; cost ratio = us/plot / {REFERENCE})")
    for column in ("scene", "filter", "aircraft", "plots (false)", "scans", "confirmed tracks", "track time median [min-max]",
                   "CPU time", "plots/s", "us/plot", "cost ratio", "peak traced"):
        table.add_column(column, justify="right")
    for r in rows:
        ratio = "" if reference is None else f"{r['us_per_plot'] / reference['us_per_plot']:.2f}"
        table.add_row(
            r["scene"], r["filter"], f"{r['aircraft']:,}", f"{r['plots']:,} ({r['false_plots']:,})", str(r["scans"]),
            f"{r['confirmed_tracks']:,}", f"{r['median_s']:.3f} s [{r['min_s']:.3f}-{r['max_s']:.3f}]",
            f"{r['cpu_median_s']:.3f} s", f"{r['plots_per_s']:,.0f}", f"{r['us_per_plot']:.3f}", ratio,
            f"{r['peak_mib']:.0f} MiB",
        )
    console.print(table)
    for line in verdicts(rows, args.runs):
        print(line)


if __name__ == "__main__":
    main()

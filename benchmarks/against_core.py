"""The tracker loop of this checkout against the core restructuring's version (issue 5), measured back to back.

Why: the shared development machine's speed drifts by 10-20 % over a day, so a figure measured today
cannot be compared with one measured on another day.  The project's rule (no issue may leave the core's
benchmark figures more than 20 % worse) is checked here on ratios measured at the same time: the issue 5
version (``--core``, default the commit of its final figures) is checked out into a temporary git
worktree, and both versions time the scenes of ``benchmarks/throughput.py`` (``Tracker.run`` on plots
parsed once, one warm-up run, then timed runs) in alternating rounds, each round in a fresh process.
Printed: per scene and version the median over rounds of each round's median plots/s, and the ratio.

Usage:  python benchmarks/against_core.py [--rounds 3] [--runs 5] [--core d43754a]
"""

from __future__ import annotations

import argparse
import datetime as dt
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from machine import cpu_model, usable_cores  # noqa: E402  (benchmarks/machine.py)

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("sparse-1000", "small-50", "clutter-2000", "crossing-1000")
#: the commit of issue 5's final figures (README and CHANGELOG of the core restructuring)
CORE = "d43754a"
#: run in a child process with the version's src/ and benchmarks/ first on the path
CHILD = """
import os, statistics, sys, time
for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[name] = "1"
root, scenes_arg, runs = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path[:0] = [root + "/src", root + "/benchmarks"]
import scenes
from skytrack.core.plots import PlotBatch
from skytrack.sim import simulate
from skytrack.tracker import Tracker, TrackerConfig
for name in scenes_arg.split(","):
    result = simulate(scenes.build(name, 300.0))
    batch = PlotBatch.from_frame(result.plots, result.sensors.names, [s.is_3d for s in result.sensors.sensors])
    Tracker(result.sensors, TrackerConfig()).run(batch)
    walls = []
    for _ in range(runs):
        start = time.perf_counter()
        Tracker(result.sensors, TrackerConfig()).run(batch)
        walls.append(time.perf_counter() - start)
    print(name, len(batch) / statistics.median(walls))
"""


def measure(root: Path, scenes: str, runs: int) -> dict[str, float]:
    output = subprocess.run([sys.executable, "-c", CHILD, str(root), scenes, str(runs)], check=True,
                            capture_output=True, text=True).stdout
    return {line.split()[0]: float(line.split()[1]) for line in output.splitlines() if line.strip()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--core", default=CORE, help=f"the core version's commit (default {CORE})")
    parser.add_argument("--scenes", default=",".join(SCENES))
    args = parser.parse_args()
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    print(f"machine: {cpu_model()}, {usable_cores()} usable cores (1 used), Python {platform.python_version()}; "
          f"date: {dt.datetime.now().astimezone().isoformat(timespec='seconds')}")
    print(f"this checkout (HEAD {head}, working tree as it is) against {args.core}: {args.rounds} alternating "
          f"rounds of {args.runs} timed runs per scene")
    with tempfile.TemporaryDirectory(prefix="skytrack-core-") as tmp:
        core = Path(tmp) / "core"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(core), args.core], check=True,
                       capture_output=True)
        try:
            results: dict[str, list[dict[str, float]]] = {"core": [], "this": []}
            for _ in range(args.rounds):
                results["core"].append(measure(core, args.scenes, args.runs))
                results["this"].append(measure(ROOT, args.scenes, args.runs))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(core)], check=False,
                           capture_output=True)
    print("| scene | core (plots/s) | this checkout (plots/s) | change |")
    print("|---|---|---|---|")
    for name in args.scenes.split(","):
        core_rate = statistics.median(r[name] for r in results["core"])
        this_rate = statistics.median(r[name] for r in results["this"])
        print(f"| {name} | {core_rate:,.0f} | {this_rate:,.0f} | {100 * (this_rate / core_rate - 1):+.1f} % |")


if __name__ == "__main__":
    main()

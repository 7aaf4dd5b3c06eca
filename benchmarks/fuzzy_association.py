"""Spec 003 R21: plots/s of the studies' tracker with the fuzzy rule, greedy and global, at 200 tracks
and 200 plots per scan (a benchmark, not a test).

What is measured: the wall time of :meth:`skytrack.studies.fuzzy.paper_tracker.PaperTracker.run` on one
run of an airborne scenario with 200 targets (P_D = 1, so 200 plots per scan and, after the first
scan, 200 tracks): prediction, interrogation decision, scoring of every (plot, track) pair (stacked
Cholesky), the decision (greedy: one plot at a time, each scored against every live track; global: one
assignment per scan) and the EKF updates.  Simulation is not timed.  ``--runs`` timed repetitions after
one warm-up; the median, min and max are printed with the machine and the date.

Scene: the own-ship at (0, 0, 8000) m flying north at 250 m/s; 200 targets on a 20 x 10 grid 30-60 km
ahead, 1.5 km apart, at 4-8 km height, each flying at 200-300 m/s on a random heading (seeded); half
friend, half foe, each with its own Mode 3/A code; IFF policy ``always`` with p_reply = 0.9.

Usage:  python benchmarks/fuzzy_association.py [--runs 5] [--scans 20] [--targets 200]
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

import numpy as np  # noqa: E402

from machine import cpu_model, usable_cores  # noqa: E402  (benchmarks/machine.py)
from skytrack.association.identity_rules import RuleConfig  # noqa: E402
from skytrack.sim.airborne import AirborneScenario, AirborneTarget, ConstantVelocityLegs  # noqa: E402
from skytrack.studies.fuzzy.paper_tracker import PaperTracker, PaperTrackerConfig  # noqa: E402
from skytrack.studies.fuzzy.runs import IffSettings, simulate_runs  # noqa: E402


def scene(targets: int, scans: int, seed: int = 0) -> AirborneScenario:
    rng = np.random.default_rng(seed)
    columns = 20
    targets_list = []
    for i in range(targets):
        row, column = divmod(i, columns)
        position = (-14_250.0 + 1_500.0 * column, 30_000.0 + 1_500.0 * row * 2, float(rng.uniform(4000, 8000)))
        heading = rng.uniform(0, 2 * np.pi)
        speed = rng.uniform(200, 300)
        velocity = (speed * np.sin(heading), speed * np.cos(heading), 0.0)
        code = format(int(rng.integers(0, 4096)), "04o")
        targets_list.append(AirborneTarget(ConstantVelocityLegs.straight(position, velocity), 1.0,
                                           "friend" if i % 2 == 0 else "foe", code))
    own = ConstantVelocityLegs.straight((0.0, 0.0, 8000.0), (0.0, 250.0, 0.0))
    return AirborneScenario(own_ship=own, targets=tuple(targets_list), n_scans=scans)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--scans", type=int, default=20)
    parser.add_argument("--targets", type=int, default=200)
    args = parser.parse_args()
    simulated = simulate_runs(scene(args.targets, args.scans), 1, 1, IffSettings(0.9, 0.0, 0.0))
    plots = int(simulated.plots.valid.sum())
    print(f"machine: {cpu_model()}, {usable_cores()} usable cores, Python {platform.python_version()}; "
          f"date: {dt.date.today().isoformat()}")
    print(f"scene: {args.targets} targets, {args.scans} scans, {plots} plots ({plots // args.scans} per scan); "
          f"median of {args.runs} runs after one warm-up")
    for mode in ("greedy", "global"):
        tracker = PaperTracker(PaperTrackerConfig(rule=RuleConfig(rule="fuzzy", mode=mode), iff_policy="always"))
        decisions = tracker.run(simulated.plots)  # warm-up
        tracks = len(np.unique(decisions.track_id[simulated.plots.valid]))
        times = []
        for _ in range(args.runs):
            start = time.perf_counter()
            tracker.run(simulated.plots)
            times.append(time.perf_counter() - start)
        median = statistics.median(times)
        print(f"fuzzy {mode:6s}: {plots / median:9.0f} plots/s (median {median:.3f} s, min {min(times):.3f}, "
              f"max {max(times):.3f}); {tracks} tracks started")


if __name__ == "__main__":
    main()

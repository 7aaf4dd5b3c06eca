"""Cost of the per-step identifiability check and of one adaptive filter step (spec 002 §6 E8; a
benchmark, not a test).

The paper stresses the "computational simplicity" of its criterion (14).  What is measured, on one
core (the OpenMP/BLAS/numba pools are pinned to one thread before numpy is imported):

1. R5 on a stack of ``--matrices`` (default 10⁵) random 3 × 3 S matrices (entries N(0, 1), V_η = I):
   (a) :func:`skytrack.filters.identifiability_step.step_verdicts`, the filter's verdict, margin κ and
   zero-influence set (H = I, G = S); (b) :func:`skytrack.analysis.identifiability.check_identifiability`
   on the same stack, the full record with culprits, near-null space and precision (R5-R9);
2. R11: one :meth:`AdaptiveAugmentedFilter.step` (A1-A8 with R5 and the R12 estimator) on a bank of
   ``--tracks`` (default 10⁴) ``ct-omega`` tracks (R14 preset: q_a = 1 m²/s³, σ_min = 10⁻⁵ rad/s,
   σ_max = 2°/s, λ = 0.8), position + range-rate measurements (σ 20 m, 0.5 m/s), T = 1 s; random
   states 20-60 km from the sensor, 150-250 m/s, |ω| ≤ 3°/s.

Each figure is steps (matrices or track-steps) per second: the median of ``--runs`` timed runs after
one untimed warm-up, with the minimum and maximum beside it (the machine may be shared).  The script
prints the machine, the date and the figures; it claims nothing.

Usage:  python benchmarks/adaptive_identification.py [--matrices 100000] [--tracks 10000] [--runs 5]
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
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from machine import cpu_model, usable_cores, versions  # noqa: E402  (benchmarks/machine.py)
from skytrack.analysis.identifiability import check_identifiability  # noqa: E402
from skytrack.filters.adaptive_augmented import AdaptiveAugmentedFilter, AdaptiveSettings  # noqa: E402
from skytrack.filters.identifiability_step import step_verdicts  # noqa: E402
from skytrack.models.augmented import ct_omega  # noqa: E402
from skytrack.models.augmented_measurements import measurement_for  # noqa: E402

SIGMA_POS = 20.0
SIGMA_RDOT = 0.5


def machine() -> str:
    found = versions(("numpy", "scipy"))
    listed = ", ".join(f"{name} {version}" for name, version in found.items())
    return (f"{cpu_model()}, {os.cpu_count()} cores ({usable_cores()} usable, the benchmark uses 1); "
            f"Python {platform.python_version()}, {listed}; {platform.platform()}")


def timed_runs(prepare, work, runs: int) -> list[float]:
    """Wall seconds of ``work(prepare())`` for ``runs`` runs after one untimed warm-up (prepare untimed)."""
    work(prepare())
    seconds = []
    for _ in range(runs):
        argument = prepare()
        start = time.perf_counter()
        work(argument)
        seconds.append(time.perf_counter() - start)
    return seconds


def random_stack(count: int, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((count, 3, 3))


def filter_bank(tracks: int, seed: int = 2):
    """The R14 ``ct-omega-adaptive`` filter, a bank state of ``tracks`` random tracks, measurements, V_η."""
    rng = np.random.default_rng(seed)
    model = ct_omega(sigma_omega=1e-4, q_accel=1.0)
    measurement = measurement_for(model, ("pos", "rdot"))
    settings = AdaptiveSettings(sigma_min=[1e-5], sigma_max=[np.radians(2.0)], forgetting=0.8)
    filt = AdaptiveAugmentedFilter(model, measurement, settings)
    distance, bearing = rng.uniform(20e3, 60e3, tracks), rng.uniform(0, 2 * np.pi, tracks)
    speed, heading = rng.uniform(150, 250, tracks), rng.uniform(0, 2 * np.pi, tracks)
    x0 = np.c_[distance * np.cos(bearing), distance * np.sin(bearing), speed * np.cos(heading),
               speed * np.sin(heading), np.radians(rng.uniform(-3, 3, tracks))]
    P0 = np.diag([400.0, 400.0, 100.0, 100.0, np.radians(2.0) ** 2])
    truth = model.phi(x0, np.ones(tracks))
    h, _ = measurement.evaluate(truth)
    y = h + rng.standard_normal(h.shape) * [SIGMA_POS, SIGMA_POS, SIGMA_RDOT]
    noise_cov = np.diag([SIGMA_POS**2, SIGMA_POS**2, SIGMA_RDOT**2])
    return filt, x0, P0, y, noise_cov


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--matrices", type=int, default=100_000, help="random 3 × 3 S matrices for R5 (default 10⁵)")
    parser.add_argument("--tracks", type=int, default=10_000, help="ct-omega tracks in the R11 bank (default 10⁴)")
    parser.add_argument("--runs", type=int, default=5, help="timed runs per figure after one warm-up (default 5)")
    args = parser.parse_args()
    for option in ("matrices", "tracks", "runs"):
        if getattr(args, option) < 1:  # a rate over zero steps or zero runs has no meaning
            parser.error(f"--{option} must be >= 1, got {getattr(args, option)}")
    console = Console(width=150)  # the table stays readable in a pipe or a log
    console.print(f"date {dt.datetime.now(dt.timezone.utc):%Y-%m-%d %H:%M UTC}")
    console.print(f"machine: {machine()}")

    stack = random_stack(args.matrices)
    identity = np.broadcast_to(np.eye(3), stack.shape)
    results = []
    seconds = timed_runs(lambda: None, lambda _: step_verdicts(identity, stack, identity), args.runs)
    results.append(("R5 step_verdicts (filter's verdict, κ, Z)", f"{args.matrices:,} random 3 × 3 S", args.matrices,
                    seconds))
    seconds = timed_runs(lambda: None, lambda _: check_identifiability(stack, noise_cov=np.eye(3)), args.runs)
    results.append(("R5-R9 check_identifiability (full record)", f"{args.matrices:,} random 3 × 3 S", args.matrices,
                    seconds))
    filt, x0, P0, y, noise_cov = filter_bank(args.tracks)
    seconds = timed_runs(lambda: filt.initial_state(x0, P0), lambda state: filt.step(state, y, 1.0, noise_cov),
                         args.runs)
    results.append(("R11 AdaptiveAugmentedFilter.step (A1-A8)", f"{args.tracks:,} ct-omega tracks, pos + ṙ",
                    args.tracks, seconds))

    table = Table(title=f"spec 002 E8: steps per second on one core (median of {args.runs} runs, min … max)")
    for column in ("what", "batch", "median wall (ms)", "steps/s (median)", "steps/s (min … max)", "µs per step"):
        table.add_column(column, justify="right" if column != "what" else "left")
    for name, batch, count, runs in results:
        median = statistics.median(runs)
        table.add_row(name, batch, f"{1e3 * median:.1f}", f"{count / median:,.0f}",
                      f"{count / max(runs):,.0f} … {count / min(runs):,.0f}", f"{1e6 * median / count:.2f}")
    console.print(table)


if __name__ == "__main__":
    main()

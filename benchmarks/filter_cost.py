"""Cost per track update of the spec 004 filter families on one core (a benchmark, not a test; R22 b).

What is measured: one filter step of a track, ``predict`` + ``innovate`` + ``update`` (the step the
studies count), on a batch of ``--tracks`` (1000) tracks at once, as the Monte Carlo runner of
the studies calls it: ``us per update`` = wall time of the batch step / tracks.  Next to it the
multiply-adds per update of the R22 (a) model (``skytrack.core.linalg.counting``), the number
the studies assert on.

How, per filter (labels of the studies' catalogue, ``skytrack.studies.maneuver.filters``, plus the
E5 Berg variants and the E8 offline piecewise-gain filters):
1. measurements of the §6 default scenario (5 g turn, polar radar at 40 km, T = 1 s) for
   ``--tracks`` Monte Carlo runs, the runner's two-point start, then ``--warmup-scans`` (30)
   untimed scans (numba compilation / cache loading, input-estimation banks filled, offline
   gain schedules built);
2. ``--repeats`` (5) timed repeats, each from a copy of that warmed-up filter and state (filter-held
   caches included) over the next ``--scans`` (5) scans (straight flight before the turn): median,
   min and max of the wall time per track update; one more untimed pass counts the multiply-adds;
3. ``--measurements``: ``polar`` (converted plots, R changes with every plot, as in the studies)
   and/or ``cartesian`` (fixed R = (50 m)^2 I: the regime of the offline gain schedule, E8).

One core: the OpenMP/BLAS/numba thread pools are pinned to one thread before numpy is imported.
The script prints the machine, the date and the table; it claims nothing (the MAC asserts live in
the studies E4, E5, E8).

Usage:  python benchmarks/filter_cost.py [--filters LABELS] [--tracks 1000] [--repeats 5] [--scans 5]
                                         [--warmup-scans 30] [--measurements polar,cartesian] [--seed 1]
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import datetime as dt  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from machine import cpu_model, usable_cores, versions  # noqa: E402  (benchmarks/machine.py)
from skytrack.core import linalg  # noqa: E402
from skytrack.models.converted import ConvertedPositionModel  # noqa: E402
from skytrack.studies.maneuver.berg_frame import STUDY_FILTERS as BERG_FILTERS  # noqa: E402
from skytrack.studies.maneuver.filters import CATALOG, FilterSetting  # noqa: E402
from skytrack.studies.maneuver.measurements import simulate_measurements  # noqa: E402
from skytrack.studies.maneuver.reduced_cost import pcg_spec  # noqa: E402
from skytrack.studies.maneuver.runner import FIRST_SCAN, two_point_initiation  # noqa: E402
from skytrack.studies.maneuver.scenarios import named_cases  # noqa: E402

FILTERS = {**CATALOG, **BERG_FILTERS, **{f"pcg-offline-{n}": pcg_spec(n, "offline") for n in (1, 5, 20)}}
#: the families of studies E4, E5, E8 (``--filters all`` times every entry of FILTERS)
DEFAULT_FILTERS = ("kf-cv", "kf-singer", "per-axis", "transformed-gain", "pcg-1", "pcg-5", "pcg-20", "pcg-offline-1",
                   "pcg-offline-5", "pcg-offline-20", "alpha-beta-gamma", "ie", "berg-full", "berg-frame",
                   "berg-frame-no-rotation", "berg-frame-no-jerk", "berg-full-no-jerk")
#: (numerator, denominator) wall-time ratios printed under the table (E5: the paper's 1.5-2x)
RATIOS = (("berg-full", "berg-frame"), ("kf-singer", "per-axis"), ("kf-singer", "transformed-gain"),
          ("kf-singer", "pcg-offline-5"), ("kf-singer", "alpha-beta-gamma"), ("ie", "kf-cv"))
CARTESIAN_SIGMA_M = 50.0


def machine() -> str:
    found = versions(("numpy", "numba", "scipy"))
    listed = ", ".join(f"{name} {version}" for name, version in found.items())
    return (f"{cpu_model()}, {os.cpu_count()} cores ({usable_cores()} usable, the benchmark uses 1); "
            f"Python {platform.python_version()}, {listed}; {platform.platform()}")


def steps(filt, state, z, R, first: int, count: int, model):
    """``count`` scans of predict + innovate + update from scan ``first``; the final state."""
    rows = len(z[0])
    for k in range(first, first + count):
        predicted = filt.predict(state, np.ones(rows))
        innovation = filt.innovate(predicted, z[k], model, {"R": R[k]})
        state, _ = filt.update(predicted, z[k], innovation)
    return state


def measure(label: str, meas, case, args) -> dict:
    spec = FILTERS[label]
    filt, _ = spec.build(FilterSetting(case.dt, meas.R[0], case.sensor.position))
    order = filt.state_dim // 3
    model = ConvertedPositionModel(3, order)
    x0, P0 = two_point_initiation(meas.z[0], meas.z[1], meas.R[0], meas.R[1], case.dt, order)
    started = time.perf_counter()
    warm = steps(filt, filt.initiate(x0, P0), meas.z, meas.R, FIRST_SCAN, args.warmup_scans, model)
    warm_s = time.perf_counter() - started
    first = FIRST_SCAN + args.warmup_scans
    # every repeat starts from a copy of the warmed-up filter and state, so filter-held caches (the offline
    # gain schedules) are in the state they would have after the warm-up, not filled by an earlier repeat
    snapshot = copy.deepcopy((filt, warm))
    walls = []
    for _ in range(args.repeats):
        f, state = copy.deepcopy(snapshot)
        t0 = time.perf_counter()
        steps(f, state, meas.z, meas.R, first, args.scans, model)
        walls.append((time.perf_counter() - t0) / (args.scans * args.tracks) * 1e6)
    f, state = copy.deepcopy(snapshot)
    with linalg.counting() as ops:
        steps(f, state, meas.z, meas.R, first, args.scans, model)
    return {"filter": label, "kind": spec.kind, "madds": ops.madds / (args.scans * args.tracks),
            "median_us": statistics.median(walls), "min_us": min(walls), "max_us": max(walls), "warm_s": warm_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--filters", default=",".join(DEFAULT_FILTERS),
                        help="comma-separated labels of the studies' catalogue, or 'all' (default: the E4/E5/E8 families)")
    parser.add_argument("--tracks", type=int, default=1000, help="tracks per batch (default 1000)")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (the median is reported)")
    parser.add_argument("--scans", type=int, default=5, help="scans per timed repeat")
    parser.add_argument("--warmup-scans", type=int, default=30, help="untimed scans before the timed ones")
    parser.add_argument("--measurements", default="polar,cartesian", help="polar and/or cartesian (fixed R)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the simulated measurements")
    args = parser.parse_args()
    labels = list(FILTERS) if args.filters.strip() == "all" else [s.strip() for s in args.filters.split(",") if s.strip()]
    unknown = [label for label in labels if label not in FILTERS]
    if unknown:
        parser.error(f"--filters: unknown filter(s) {unknown}; known: {', '.join(FILTERS)}")
    modes = [m.strip() for m in args.measurements.split(",") if m.strip()]
    if not modes or any(m not in ("polar", "cartesian") for m in modes):
        parser.error(f"--measurements takes polar and/or cartesian, got {args.measurements!r}")
    if min(args.tracks, args.repeats, args.scans) < 1 or args.warmup_scans < 0:
        parser.error("--tracks, --repeats and --scans must be >= 1, --warmup-scans >= 0")
    case = named_cases("default", turn_g=(5.0,))[0]
    if FIRST_SCAN + args.warmup_scans + args.scans > case.scans:
        parser.error(f"--warmup-scans + --scans must stay within the scenario's {case.scans - FIRST_SCAN} filter scans")
    console = Console(width=200)
    console.print(f"machine: {machine()}")
    console.print(f"date: {dt.datetime.now().astimezone().isoformat(timespec='seconds')}")
    console.print(f"{args.tracks} tracks per batch ({case.label}), {args.warmup_scans} untimed warm-up scans, "
                  f"{args.repeats} timed repeats of {args.scans} scans; one update = predict + innovate + update")
    for mode in modes:
        meas = simulate_measurements(case, args.tracks, args.seed, mode, CARTESIAN_SIGMA_M if mode == "cartesian" else None)
        rows = []
        for label in labels:
            rows.append(measure(label, meas, case, args))
            r = rows[-1]
            console.print(f"  {mode} {label}: {r['median_us']:.2f} us/update, {r['madds']:.0f} MACs/update "
                          f"(warm-up {r['warm_s']:.1f} s)")
        title = (f"cost per track update, {mode} measurements"
                 + (f" (fixed R = ({CARTESIAN_SIGMA_M:g} m)^2 I)" if mode == "cartesian" else " (converted plots, R per plot)")
                 + f", batch of {args.tracks}, median of {args.repeats}")
        table = Table(title=title)
        for column in ("filter", "kind", "MACs / update", "us / update median [min-max]", "ns / MAC"):
            table.add_column(column, justify="right")
        for r in rows:
            table.add_row(r["filter"], r["kind"], f"{r['madds']:,.0f}",
                          f"{r['median_us']:.2f} [{r['min_us']:.2f}-{r['max_us']:.2f}]",
                          f"{1e3 * r['median_us'] / r['madds']:.2f}" if r["madds"] > 0 else "–")
        console.print(table)
        by_label = {r["filter"]: r for r in rows}
        for a, b in RATIOS:
            if a in by_label and b in by_label:
                print(f"{mode}: {a} / {b}: wall time ratio {by_label[a]['median_us'] / by_label[b]['median_us']:.2f}, "
                      f"MAC ratio {by_label[a]['madds'] / by_label[b]['madds']:.2f}")


if __name__ == "__main__":
    main()

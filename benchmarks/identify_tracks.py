"""Spec 001 R17: reports/s of the many-to-many identifier at 500 radar x 500 ADS-B tracks, 1 Hz, 300 s.

What is measured: the wall time of :meth:`skytrack.identify.identifier.TrackIdentifier.process` over
the whole report stream (fed in chunks of ``--chunk-s`` seconds, as a live feed would), plus one
global assignment (:meth:`~skytrack.identify.identifier.TrackIdentifier.assign`) at the end of every
chunk — 300 000 reports for the default scene.  The scene is built before the clock starts.
``--runs`` timed repetitions after one warm-up (numba compilation); the median, min and max are
printed with the mean number of pairs each report updates, the peak memory (tracemalloc) of one run,
the machine and the date.

Scene: 500 aircraft at uniform positions in a 400 km x 400 km square, speed 150-250 m/s on a
uniform heading, straight flight; each is seen by the radar (1 Hz, 100 m per axis) and by ADS-B
(1 Hz at a random phase, 20 m per axis): 500 tracks per system.  Identifier settings: those of
``skytrack track --adsb`` (:class:`skytrack.app.identification.AdsbIdentificationConfig`: CV with
q = 300 m^2/s^3, a 20 s pair horizon, the outlier gate, the default coarse gate of 10 km).

Usage:  python benchmarks/identify_tracks.py [--runs 5] [--tracks 500] [--duration 300]
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

from machine import cpu_model, usable_cores  # noqa: E402  (benchmarks/machine.py)
from skytrack.app.identification import AdsbIdentificationConfig  # noqa: E402
from skytrack.identify.identifier import TrackIdentifier  # noqa: E402


def scene(tracks: int, duration: float, seed: int = 0):
    """Reports of both systems, sorted by time: (side, track id, time, z, V)."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-200_000.0, 200_000.0, (tracks, 2))
    heading = rng.uniform(0, 2 * np.pi, tracks)
    speed = rng.uniform(150.0, 250.0, tracks)
    velocity = np.column_stack([speed * np.sin(heading), speed * np.cos(heading)])
    parts = []
    for side, sigma in ((1, 100.0), (2, 20.0)):
        phase = rng.uniform(0.0, 1.0, tracks)
        t = phase[:, None] + np.arange(int(duration))[None, :]
        position = start[:, None, :] + velocity[:, None, :] * t[..., None]
        position += rng.normal(0.0, sigma, position.shape)
        ids = np.repeat(np.arange(tracks) + side * 100_000, t.shape[1])
        parts.append((np.full(t.size, side, np.int8), ids, t.ravel(), position.reshape(-1, 2),
                      np.full(t.size, sigma ** 2)))
    side, ids, time_, z, variance = (np.concatenate(c) for c in zip(*parts))
    order = np.argsort(time_, kind="stable")
    V = variance[order, None, None] * np.eye(2)
    return side[order], ids[order], time_[order], z[order], V


def run(reports, chunk_s: float) -> TrackIdentifier:
    side, ids, time_, z, V = reports
    identifier = TrackIdentifier(AdsbIdentificationConfig().identifier_config())
    edges = np.searchsorted(time_, np.arange(0.0, time_[-1] + chunk_s, chunk_s), side="left")
    for start, stop in zip(edges[:-1], np.r_[edges[1:-1], len(time_)]):
        if stop > start:
            identifier.process(side[start:stop], ids[start:stop], time_[start:stop], z[start:stop], V[start:stop])
            identifier.assign()
    return identifier


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--tracks", type=int, default=500)
    parser.add_argument("--duration", type=float, default=300.0)
    parser.add_argument("--chunk-s", type=float, default=4.0, help="seconds of reports per process() call")
    args = parser.parse_args()
    reports = scene(args.tracks, args.duration)
    n_reports = len(reports[0])
    run(reports, args.chunk_s)  # warm-up: numba compilation and caches
    times = []
    for _ in range(args.runs):
        started = time.perf_counter()
        identifier = run(reports, args.chunk_s)
        times.append(time.perf_counter() - started)
    tracemalloc.start()
    run(reports, args.chunk_s)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    median = statistics.median(times)
    result = identifier.assign()
    print(f"spec 001 R17 identification benchmark, {dt.date.today().isoformat()}, {cpu_model()}, "
          f"{usable_cores()} usable cores (numba/BLAS threads: 1), Python {platform.python_version()}")
    print(f"scene: {args.tracks} radar x {args.tracks} ADS-B tracks, 1 Hz, {args.duration:g} s: {n_reports} reports; "
          f"chunks of {args.chunk_s:g} s, one global assignment per chunk")
    print(f"wall time over {args.runs} runs: median {median:.3f} s (min {min(times):.3f}, max {max(times):.3f})")
    print(f"reports/s (median run): {n_reports / median:,.0f}   ({n_reports / median / 2 / args.tracks:,.0f}x "
          f"real time per track set)")
    print(f"mean pairs updated per report: {identifier.mean_pairs_per_report:.2f}; pairs made "
          f"{identifier.stats['pairs_created']}, dropped {identifier.stats['pairs_dropped']}, refreshed "
          f"{identifier.stats['pairs_refreshed']}; reports left out as outliers {identifier.stats['reports_gated']}")
    print(f"identified at the end: {len(result.first_id)} of {args.tracks} (correct "
          f"{int(np.sum(result.first_id - 100_000 == result.second_id - 200_000))})")
    print(f"peak memory (tracemalloc, one run): {peak / 1e6:.1f} MB")


if __name__ == "__main__":
    main()

"""Benchmark (not a test): frame time of the browser air-situation display with 5 000 tracks (issue 11 item 4).

Usage: python benchmarks/display_frame_time.py [TRACKS] [RUNS]
Streams 90 frames of TRACKS (default 5 000) synthetic moving tracks (2 s of picture time per frame, so the
120 s trails are full from frame 64 on) through the test server of tests/service/display_harness.py to
Debian's headless Chromium (/usr/bin/chromium, 1280 x 800), and reads the page's own frame times
(``window.skytrackStats``: decoding, track update and drawing of a frame, rasterisation included) of the
frames drawn with full trails.  Prints p50/p95 of each run and the median over RUNS (default 5) runs, the
machine and the date.  The issue's target: p95 < 50 ms.
"""

from __future__ import annotations

import datetime
import platform
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests" / "service"))
from display_harness import (  # noqa: E402
    CHROMIUM,
    DisplayServer,
    SyntheticTraffic,
    chromium_page,
    hello_text,
    wait_for,
)
from machine import cpu_model, usable_cores  # noqa: E402

FRAMES = 90
FULL_TRAILS_FROM = 64


def one_run(traffic: SyntheticTraffic, frames: list[bytes]) -> list[float]:
    server = DisplayServer(hello_text(trail_s=120.0), frames, labels=traffic.labels, period_s=0.05)
    with server.running() as url, chromium_page(1280, 800) as page:
        page.goto(url)
        wait_for(page, f"window.skytrackStats && window.skytrackStats.lastSequence === {len(frames) - 1}",
                 timeout_s=60, what="the last frame")
        page.wait_for_timeout(200)
        stats = page.evaluate("window.skytrackStats")
    if stats["errors"]:
        raise RuntimeError(f"the display reported errors: {stats['errors']}")
    return [t for t, sequence in zip(stats["frameTimesMs"], stats["frameSequences"]) if sequence >= FULL_TRAILS_FROM]


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 5000
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    if not Path(CHROMIUM).exists():
        raise SystemExit(f"{CHROMIUM} is missing: apt-get install chromium")
    traffic = SyntheticTraffic(n, dt_s=2.0, seed=7)
    frames = [traffic.frame(k) for k in range(FRAMES)]
    version = subprocess.run([CHROMIUM, "--version"], capture_output=True, text=True).stdout.strip()
    print(f"display frame time, {n} tracks with 120 s trails, 1280 x 800, {version}")
    p50s, p95s = [], []
    for run in range(runs):
        times = one_run(traffic, frames)
        p50s.append(float(np.percentile(times, 50)))
        p95s.append(float(np.percentile(times, 95)))
        print(f"  run {run + 1}: {len(times)} frames, p50 {p50s[-1]:.1f} ms, p95 {p95s[-1]:.1f} ms, "
              f"max {max(times):.1f} ms")
    print(f"median of {runs} runs: p50 {statistics.median(p50s):.1f} ms, p95 {statistics.median(p95s):.1f} ms "
          "(target p95 < 50 ms)")
    print(f"machine: {cpu_model()}, {usable_cores()} usable cores, {platform.system()} {platform.release()}; "
          f"date {datetime.date.today().isoformat()}")


if __name__ == "__main__":
    main()

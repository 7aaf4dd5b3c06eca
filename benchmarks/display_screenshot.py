"""Screenshot of the browser air-situation display with the demo traffic (issue 11 item 4), for the README.

Usage: python benchmarks/display_screenshot.py [--until-s 300] [--select DEMO1] [--out docs/figures/display-demo.png]
Simulates the bundled demo scenario, tracks it (labelling the tracks with the demo's ADS-B, as `skytrack demo`
does), turns the tracks table into display frames (one per output instant up to ``--until-s`` seconds, encoded
with skytrack.service.frames) and streams them through the test server of tests/service/display_harness.py to
Debian's headless Chromium, clicks the track of ``--select`` (a callsign) to open its details panel, then saves
a screenshot of the last frame.  Needs /usr/bin/chromium.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "service"))
from display_harness import DisplayServer, chromium_page, wait_for  # noqa: E402

from skytrack.service.frames import (  # noqa: E402
    STATUS_COASTING,
    STATUS_CONFIRMED,
    STATUS_IDENTIFIED,
    encode_frame,
    hello_message,
    mode3a_codes,
)


def demo_tracks(workdir: Path):
    """The demo scenario simulated and tracked: (sensor set, tracks table)."""
    from skytrack.app.run import run_tracking
    from skytrack.app.simulate import run_simulation, write_simulation
    from skytrack.io import read_tracks
    from skytrack.tracker import TrackerConfig

    result = run_simulation("demo", None)
    paths = write_simulation(result, workdir, "parquet")
    run_tracking(paths["plots"], paths["sensors"], workdir / "tracks.parquet", TrackerConfig(),
                 adsb_path=paths.get("adsb"))
    return result.sensors, read_tracks(workdir / "tracks.parquet")


def track_frames(tracks: pd.DataFrame, until_s: float) -> tuple[list[bytes], dict[int, dict]]:
    """One frame per output instant of the tracks table up to ``until_s``, and the labels of the identified tracks."""
    tracks = tracks[tracks["time"] <= until_s]
    frames = []
    for sequence, (time_s, rows) in enumerate(tracks.groupby("time", sort=True)):
        callsign = rows["callsign"] if "callsign" in rows else pd.Series(None, index=rows.index)
        status = (STATUS_CONFIRMED
                  | np.where(rows["status"].to_numpy() == "coasting", STATUS_COASTING, 0)
                  | np.where(callsign.notna().to_numpy(), STATUS_IDENTIFIED, 0)).astype(np.uint8)
        frames.append(encode_frame(
            track_id=rows["track_id"].to_numpy(), lat_deg=rows["lat"].to_numpy(), lon_deg=rows["lon"].to_numpy(),
            alt_m=rows["alt_m"].to_numpy(), ve_mps=rows["vx"].to_numpy(), vn_mps=rows["vy"].to_numpy(),
            vu_mps=rows["vz"].fillna(0.0).to_numpy(), mode3a=mode3a_codes(rows["mode3a"].to_numpy()),
            status=status, t_s=float(time_s), last_plot_s=float(time_s), sequence=sequence))
    labelled = tracks[tracks["callsign"].notna()].drop_duplicates("track_id", keep="last")
    labels = {int(row.track_id): {"callsign": row.callsign, "icao24": row.icao24} for row in labelled.itertuples()}
    return frames, labels


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--until-s", type=float, default=300.0, help="picture time of the screenshot (s)")
    parser.add_argument("--select", default="DEMO1", help="callsign of the track whose details are shown ('' none)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "display-demo.png")
    args = parser.parse_args()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="skytrack-display-demo-") as workdir:
        sensors, tracks = demo_tracks(Path(workdir))
    frames, labels = track_frames(tracks, args.until_s)
    if not frames:
        raise SystemExit(f"the demo produced no track before t = {args.until_s} s: nothing to show")
    print(f"demo simulated and tracked in {time.perf_counter() - started:.1f} s: {len(frames)} frames up to "
          f"t = {args.until_s:.0f} s, {len(labels)} identified tracks")
    server = DisplayServer(hello_message(sensors), frames, labels=labels, period_s=0.03)
    with server.running() as url, chromium_page(1280, 800) as page:
        page.goto(url)
        wait_for(page, f"window.skytrackStats && window.skytrackStats.lastSequence === {len(frames) - 1} "
                       "&& window.skytrackStats.basemapLoaded", timeout_s=60, what="the last demo frame")
        selected = [track_id for track_id, label in labels.items() if label["callsign"] == args.select]
        position = page.evaluate(f"window.skytrackDisplay.screenPosition({selected[-1]})") if selected else None
        if position is not None:
            page.mouse.click(*position)
            page.wait_for_selector("#details:not([hidden])", timeout=5000)
        elif args.select:
            print(f"no track labelled {args.select!r} in the last frame: no details panel")
        page.wait_for_timeout(400)  # the status bar refreshes every 250 ms
        stats = page.evaluate("window.skytrackStats")
        args.out.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(args.out))
    print(f"{stats['tracks']} tracks, {stats['labelsDrawn']} labels drawn -> {args.out}")


if __name__ == "__main__":
    main()

"""The browser air-situation display (issue 11 item 4) in Debian's headless Chromium, driven by Playwright.

A small Starlette server (tests/service/display_harness.py) serves the built bundle
``skytrack/service/static`` and streams frames encoded with :func:`skytrack.service.frames.encode_frame`.
Checked: the page loads and decodes every column (the details panel shows the encoded values), tracks
appear and move by their speed, labels, a click opens the details panel, pan/zoom with the mouse, the UTC
clock, automatic reconnection, a screenshot holds the track colours at the tracks' projected positions and
the basemap's coastline colour; and with 5 000 tracks and full trails the 95th-percentile frame time
measured by the page stays under 50 ms.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from display_harness import (
    CHROMIUM,
    STATIC_DIR,
    DisplayServer,
    SyntheticTraffic,
    chromium_page,
    hello_text,
    wait_for,
)
from skytrack.service.frames import MODE3A_NONE, STATUS_COASTING, STATUS_CONFIRMED, STATUS_IDENTIFIED

needs_chromium = pytest.mark.skipif(not Path(CHROMIUM).exists(),
                                reason=f"{CHROMIUM} is missing: install Debian's chromium (the README's test "
                                       "command does)")

#: the display's colours (display/src/render.js TRACK_CLASSES, display/src/basemap.js BASEMAP_COLOURS)
COLOUR_CONFIRMED = (61, 220, 132)
COLOUR_IDENTIFIED = (76, 201, 240)
COLOUR_COASTING = (160, 168, 176)
COLOUR_COASTLINE = (79, 135, 168)
COLOUR_RADAR = (244, 211, 94)
N_TRACKS, N_FRAMES = 12, 30


def stats(page) -> dict:
    return page.evaluate("window.skytrackStats")


def screen_position(page, track_id: int) -> tuple[float, float]:
    position = page.evaluate(f"window.skytrackDisplay.screenPosition({track_id})")
    assert position is not None, f"track {track_id} not drawn"
    return position[0], position[1]


def colour_near(image, x: float, y: float, colour: tuple[int, int, int], radius: int = 5) -> int:
    """Pixels of exactly ``colour`` in the (2 radius + 1)^2 box around (x, y) of the screenshot."""
    row, column = int(y), int(x)
    pixels = np.asarray(image)[max(0, row - radius):row + radius + 1, max(0, column - radius):column + radius + 1, :3]
    return int(np.all(pixels == np.array(colour, np.uint8), axis=-1).sum())


@needs_chromium
def test_display_draws_moving_tracks_labels_details_and_basemap():
    from PIL import Image

    traffic = SyntheticTraffic(N_TRACKS, dt_s=2.0, radius_m=150_000.0, seed=3)
    frames = [traffic.frame(k) for k in range(N_FRAMES)]
    server = DisplayServer(hello_text(), frames, labels=traffic.labels, period_s=0.12)
    with server.running() as url, chromium_page() as page:
        page.goto(url)
        wait_for(page, f"window.skytrackStats && window.skytrackStats.tracks === {N_TRACKS} "
                       "&& window.skytrackStats.basemapLoaded", what=f"{N_TRACKS} tracks drawn")

        # tracks move between frames by their speed (pixels per metre of the view times metres flown)
        track = int(traffic.track_id[1])
        first = page.evaluate(f"[window.skytrackStats.lastSequence, window.skytrackDisplay.screenPosition({track})]")
        wait_for(page, f"window.skytrackStats.lastSequence >= {first[0] + 3}", what="three more frames")
        second = page.evaluate(f"[window.skytrackStats.lastSequence, window.skytrackDisplay.screenPosition({track})]")
        pixels_per_metre = page.evaluate("window.skytrackDisplay.view.pixelsPerMetre")
        moved_px = math.dist(first[1], second[1])
        flown_m = math.hypot(traffic.ve[1], traffic.vn[1]) * traffic.dt_s * (second[0] - first[0])
        expected_px = flown_m * pixels_per_metre
        assert moved_px > 1.0
        assert moved_px == pytest.approx(expected_px, rel=0.02)

        # the last frame: every column decoded, labels, clock
        wait_for(page, f"window.skytrackStats.lastSequence === {N_FRAMES - 1}", what="the last frame")
        page.wait_for_timeout(300)  # one status-bar refresh (every 250 ms)
        final = stats(page)
        assert final["framesReceived"] == N_FRAMES and final["errors"] == []
        assert final["tracks"] == N_TRACKS and final["labelsDrawn"] == N_TRACKS
        status_bar = page.inner_text("#status")
        assert f"2021-10-07 12:00:{2 * (N_FRAMES - 1):02d} UTC" in status_bar
        assert f"{N_TRACKS} tracks" in status_bar and "connected" in status_bar
        assert "Natural Earth" in page.inner_text("#attribution")
        licences = page.evaluate("fetch(document.querySelector('#attribution a').href).then(r => r.text())")
        assert "Natural Earth" in licences and "topojson-client" in licences

        # screenshot: each class's colour at its track's projected position, the coastline, the radar
        image = Image.open(io.BytesIO(page.screenshot())).convert("RGB")
        lat, lon, alt = traffic.positions(N_FRAMES - 1)
        checked = {"confirmed": 0, "identified": 0, "coasting": 0}
        for i, track_id in enumerate(traffic.track_id):
            x, y = screen_position(page, int(track_id))
            if not (40 < x < 1240 and 200 < y < 760):  # clear of the legend and the screen edges
                continue
            status = int(traffic.status[i])
            if status & STATUS_COASTING:
                kind, colour = "coasting", COLOUR_COASTING
            elif status & STATUS_IDENTIFIED and status & STATUS_CONFIRMED:
                kind, colour = "identified", COLOUR_IDENTIFIED
            elif status & STATUS_CONFIRMED:
                kind, colour = "confirmed", COLOUR_CONFIRMED
            else:
                continue
            assert colour_near(image, x, y, colour) >= 8, f"track {track_id} ({kind}) not drawn at ({x:.0f}, {y:.0f})"
            checked[kind] += 1
        assert all(checked.values()), checked
        screenshot = np.asarray(image)
        assert np.all(screenshot == np.array(COLOUR_COASTLINE, np.uint8), axis=-1).sum() > 200
        radar_x, radar_y = page.evaluate("[window.skytrackDisplay.view.toScreenX(0), "
                                         "window.skytrackDisplay.view.toScreenY(0)]")
        assert colour_near(image, radar_x, radar_y, COLOUR_RADAR, radius=4) >= 20

        # a click on a track opens its details with every field as encoded
        index = next(i for i in range(N_TRACKS)
                     if traffic.status[i] & STATUS_IDENTIFIED and traffic.mode3a[i] != MODE3A_NONE)
        track = int(traffic.track_id[index])
        x, y = screen_position(page, track)
        page.mouse.click(x, y)
        page.wait_for_selector("#details:not([hidden])", timeout=5000)
        assert page.get_attribute("#details", "data-track-id") == str(track)
        fields = dict(zip(page.locator("#details th").all_inner_texts(), page.locator("#details td").all_inner_texts()))
        label = traffic.labels[track]
        assert fields["track id"] == str(track)
        assert fields["callsign"] == label["callsign"] and fields["ICAO 24-bit"] == label["icao24"]
        assert fields["Mode 3/A"] == f"{int(traffic.mode3a[index]):04o}"
        assert fields["latitude"] == f"{np.float32(lat[index]):.5f}°"
        assert fields["longitude"] == f"{np.float32(lon[index]):.5f}°"
        assert fields["flight level"] == f"FL{round(float(np.float32(alt[index])) / 30.48):03d}"
        assert fields["v east / north"] == f"{traffic.ve[index]:.1f} / {traffic.vn[index]:.1f} m/s"
        assert fields["status"].startswith("confirmed") and "identified" in fields["status"]
        knots = math.hypot(traffic.ve[index], traffic.vn[index]) / (1852 / 3600)
        assert fields["ground speed"].startswith(f"{knots:.0f} kt")
        page.keyboard.press("Escape")
        page.wait_for_selector("#details", state="hidden", timeout=5000)

        # the wheel zooms about the cursor: the track under it stays, the others scale by the zoom factor
        before = page.evaluate("window.skytrackDisplay.view.pixelsPerMetre")
        other_track = int(traffic.track_id[(index + 1) % N_TRACKS])
        other = screen_position(page, other_track)
        page.mouse.move(x, y)
        page.mouse.wheel(0, -400)
        wait_for(page, f"window.skytrackDisplay.view.pixelsPerMetre > {before * 1.01}", what="zoom in")
        page.wait_for_timeout(100)
        factor = page.evaluate("window.skytrackDisplay.view.pixelsPerMetre") / before
        assert factor == pytest.approx(math.exp(400 * 0.0015), rel=1e-6)
        # (abs 1 px: the browser reports the cursor in whole pixels, and the zoom keeps that point in place)
        assert screen_position(page, track) == pytest.approx((x, y), abs=1.0)
        zoomed_other = screen_position(page, other_track)
        assert math.dist(zoomed_other, (x, y)) == pytest.approx(factor * math.dist(other, (x, y)), abs=1.0)
        # dragging pans by the mouse's displacement
        start = screen_position(page, track)
        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x - 60, y + 25, steps=5)
        page.mouse.up()
        page.wait_for_timeout(100)
        assert screen_position(page, track) == pytest.approx((start[0] - 60, start[1] + 25), abs=0.5)


@needs_chromium
def test_display_reconnects_after_the_server_closes():
    traffic = SyntheticTraffic(3, seed=5)
    server = DisplayServer(hello_text(), [traffic.frame(k) for k in range(3)], labels=traffic.labels,
                           period_s=0.05, close_after_last=True)
    with server.running() as url, chromium_page() as page:
        page.goto(url)
        wait_for(page, "window.skytrackStats && window.skytrackStats.connects >= 3", timeout_s=20,
                 what="two reconnections")
        assert server.connections >= 3
        assert stats(page)["framesReceived"] >= 6
        assert stats(page)["tracks"] == 3


@needs_chromium
def test_display_5000_tracks_with_full_trails_p95_frame_time_under_50ms():
    n, n_frames = 5000, 110
    traffic = SyntheticTraffic(n, dt_s=2.0, seed=7)
    frames = [traffic.frame(k) for k in range(n_frames)]
    server = DisplayServer(hello_text(trail_s=120.0), frames, labels=traffic.labels, period_s=0.05)
    with server.running() as url, chromium_page() as page:
        page.goto(url)
        wait_for(page, f"window.skytrackStats && window.skytrackStats.lastSequence === {n_frames - 1}",
                 timeout_s=40, what=f"the last of {n_frames} frames of {n} tracks")
        page.wait_for_timeout(200)
        final = stats(page)
        trail_points = page.evaluate("(() => { const s = window.skytrackDisplay.store; let total = 0;"
                                     " for (const slot of s.active) total += s.trailCount[slot]; return total; })()")
    assert final["tracks"] == n and final["errors"] == []
    # trails hold 64 points per track once 120 s of picture have passed: measure only those frames
    times = [t for t, sequence in zip(final["frameTimesMs"], final["frameSequences"]) if sequence >= 64]
    assert len(times) >= 25, final["frameSequences"]
    assert trail_points >= 60 * n
    p95 = float(np.percentile(times, 95))
    assert p95 < 50.0, f"p95 frame time {p95:.1f} ms over {len(times)} frames of {n} tracks"


def test_static_bundle_is_complete():
    index = (STATIC_DIR / "index.html").read_text()
    assets = sorted(p.name for p in (STATIC_DIR / "assets").iterdir())
    referenced = [name for name in assets if name in index]
    assert any(name.endswith(".js") for name in referenced) and any(name.endswith(".css") for name in referenced)
    assert any(name.startswith("countries-50m") and name.endswith(".json") for name in assets)
    licences = (STATIC_DIR / "assets" / "THIRD_PARTY_LICENSES.txt").read_text()
    for name in ("Natural Earth", "world-atlas", "topojson-client", "ISC"):
        assert name in licences
    # package-data covers static/* and static/assets/* only: nothing deeper
    assert all(p.parent in (STATIC_DIR, STATIC_DIR / "assets") for p in STATIC_DIR.rglob("*") if p.is_file())

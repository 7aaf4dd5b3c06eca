"""Test harness of the browser air-situation display (issue 11 item 4): a small Starlette server that serves the
built display (``skytrack/service/static``) and a ``/ws`` endpoint speaking the protocol of
:mod:`skytrack.service.frames` (hello, labels, then binary frames), run by uvicorn in a thread on a free
port; synthetic moving traffic; and Debian's Chromium driven by Playwright.

Used by ``tests/service/test_display_browser.py``, ``benchmarks/display_frame_time.py`` and
``benchmarks/display_screenshot.py``.  This is not ``skytrack serve`` (no tracker, no UDP): it replays
frames that the caller built.
"""

from __future__ import annotations

import asyncio
import json
import shutil
import socket
import tempfile
import threading
import time
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import skytrack
from skytrack.geo.wgs84 import enu_to_geodetic
from skytrack.service.frames import (
    MODE3A_NONE,
    STATUS_COASTING,
    STATUS_CONFIRMED,
    STATUS_IDENTIFIED,
    encode_frame,
    labels_message,
)

STATIC_DIR = Path(skytrack.__file__).parent / "service" / "static"
CHROMIUM = "/usr/bin/chromium"
#: the flags known to work on this machine's closed network (docs: machines/python.md)
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync")
#: the demo scenario's radar site
ORIGIN = {"lat": 48.86, "lon": 2.50, "alt_m": 0.0}
EPOCH_UTC = "2021-10-07T12:00:00Z"
RADAR = {"name": "radar1", "type": "radar-2d", "lat": 48.86, "lon": 2.50, "max_range_m": 250000.0}


def hello_text(*, origin=ORIGIN, sensors: Sequence[dict] = (RADAR,), epoch_utc: str = EPOCH_UTC,
               trail_s: float = 120.0) -> str:
    """The hello message for the given origin and sensors (the service builds it from a SensorSet)."""
    return json.dumps({"type": "hello", "epoch_utc": epoch_utc, "origin": dict(origin),
                       "sensors": [dict(s) for s in sensors], "trail_s": trail_s})


class SyntheticTraffic:
    """``n`` tracks flying straight at 120..250 m/s from random points within ``radius_m`` of the origin;
    every 10th is coasting, every 3rd identified (with a callsign label), every 17th tentative, the others
    confirmed; Mode 3/A codes for the even ones.  Frame ``k`` shows the picture at ``k * dt_s``."""

    def __init__(self, n: int, *, dt_s: float = 2.0, radius_m: float = 200_000.0, seed: int = 11):
        rng = np.random.default_rng(seed)
        self.n, self.dt_s = n, dt_s
        self.track_id = np.arange(1, n + 1, dtype=np.int64) * 7 + 1000
        radius = radius_m * np.sqrt(rng.uniform(0.0, 1.0, n))
        bearing = rng.uniform(0.0, 2 * np.pi, n)
        self.x0, self.y0 = radius * np.sin(bearing), radius * np.cos(bearing)
        speed, heading = rng.uniform(120.0, 250.0, n), rng.uniform(0.0, 2 * np.pi, n)
        self.ve, self.vn = speed * np.sin(heading), speed * np.cos(heading)
        self.vu = np.where(np.arange(n) % 5 == 0, rng.uniform(-10.0, 10.0, n), 0.0)
        self.alt0 = rng.uniform(3000.0, 12000.0, n)
        index = np.arange(n)
        self.status = np.full(n, STATUS_CONFIRMED, np.uint8)
        self.status[index % 3 == 0] |= STATUS_IDENTIFIED
        self.status[index % 10 == 0] |= STATUS_COASTING
        self.status[index % 17 == 1] = 0
        self.mode3a = np.where(index % 2 == 0, rng.integers(0, 0o7777 + 1, n), MODE3A_NONE).astype(np.uint16)
        self.labels = {int(self.track_id[i]): {"callsign": f"TST{i:04d}", "icao24": f"{0x3c0000 + i:06x}"}
                       for i in np.flatnonzero(self.status & STATUS_IDENTIFIED)}

    def positions(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """lat, lon, alt of every track in frame ``k``."""
        t = k * self.dt_s
        lat, lon, _ = enu_to_geodetic(self.x0 + self.ve * t, self.y0 + self.vn * t, np.zeros(self.n),
                                      ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt_m"])
        return lat, lon, self.alt0 + self.vu * t

    def frame(self, k: int) -> bytes:
        lat, lon, alt = self.positions(k)
        return encode_frame(track_id=self.track_id, lat_deg=lat, lon_deg=lon, alt_m=alt, ve_mps=self.ve,
                            vn_mps=self.vn, vu_mps=self.vu, mode3a=self.mode3a, status=self.status,
                            t_s=k * self.dt_s, last_plot_s=k * self.dt_s, sequence=k)


class DisplayServer:
    """Serves the display and streams ``frames`` (a list of encoded frames) to every WebSocket client: hello,
    labels, then one frame per ``period_s``; after the last frame the connection stays open, idle, or is
    closed by the server when ``close_after_last`` (the browser then reconnects and gets them again)."""

    def __init__(self, hello: str, frames: Sequence[bytes], *, labels: dict | None = None, period_s: float = 0.1,
                 close_after_last: bool = False, static_dir: Path = STATIC_DIR):
        from starlette.applications import Starlette
        from starlette.routing import Mount, WebSocketRoute
        from starlette.staticfiles import StaticFiles
        from starlette.websockets import WebSocketDisconnect

        if not (static_dir / "index.html").is_file():
            raise FileNotFoundError(f"{static_dir}/index.html missing: build the display (cd display && npm ci && "
                                    "npm run build)")
        self.hello, self.frames, self.period_s = hello, list(frames), period_s
        self.labels = labels or {}
        self.frames_sent = 0
        self.connections = 0

        async def stream(websocket):
            await websocket.accept()
            self.connections += 1
            try:
                await websocket.send_text(self.hello)
                await websocket.send_text(labels_message(self.labels))
                for frame in self.frames:
                    await websocket.send_bytes(frame)
                    self.frames_sent += 1
                    await asyncio.sleep(self.period_s)
                if close_after_last:
                    await websocket.close()
                    return
                while True:  # keep the connection open until the browser goes
                    await websocket.receive_text()
            except WebSocketDisconnect:
                pass

        self.app = Starlette(routes=[WebSocketRoute("/ws", stream),
                                     Mount("/", StaticFiles(directory=static_dir, html=True))])

    @contextmanager
    def running(self):
        """Yields the page URL while uvicorn serves on a free loopback port in a thread."""
        import uvicorn

        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", 0))
        port = listener.getsockname()[1]
        server = uvicorn.Server(uvicorn.Config(self.app, log_level="warning", ws="websockets-sansio", lifespan="off"))
        thread = threading.Thread(target=server.run, kwargs={"sockets": [listener]}, daemon=True)
        thread.start()
        deadline = time.monotonic() + 10
        while not server.started:
            if time.monotonic() > deadline or not thread.is_alive():
                raise RuntimeError(f"the display test server did not start on port {port}")
            time.sleep(0.02)
        try:
            yield f"http://127.0.0.1:{port}/"
        finally:
            server.should_exit = True
            thread.join(timeout=10)
            listener.close()


@contextmanager
def chromium_page(width: int = 1280, height: int = 800):
    """A Playwright page in Debian's Chromium (headless, fresh profile, the machine's flags)."""
    from playwright.sync_api import sync_playwright

    profile = tempfile.mkdtemp(prefix="skytrack-chromium-")
    try:
        with sync_playwright() as playwright:
            context = playwright.chromium.launch_persistent_context(
                profile, executable_path=CHROMIUM, headless=True, args=list(CHROMIUM_FLAGS),
                viewport={"width": width, "height": height})
            try:
                yield context.pages[0] if context.pages else context.new_page()
            finally:
                context.close()
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def wait_for(page, condition: str, timeout_s: float = 15.0, what: str = "") -> object:
    """Polls the JavaScript expression ``condition`` until it is truthy; its value (an error naming ``what``,
    the page's skytrackStats and console errors otherwise)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = page.evaluate(condition)
        if value:
            return value
        time.sleep(0.05)
    stats = page.evaluate("JSON.stringify(window.skytrackStats || null)")
    raise TimeoutError(f"{what or condition} not reached in {timeout_s} s; skytrackStats = {stats}")


def frame_times(page) -> list[float]:
    return list(page.evaluate("window.skytrackStats.frameTimesMs"))



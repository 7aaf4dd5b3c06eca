"""The network side of ``skytrack serve`` (issue 11 items 3 and 5): UDP in, HTTP and WebSocket out.

:class:`LiveService` owns a :class:`~skytrack.service.pipeline.LivePipeline` and three asyncio parts:

* an asyncio ``DatagramProtocol`` on the UDP port (unicast, or a multicast group it joins) that only
  appends each datagram and its receive time to a bounded inbox (``MAX_INBOX_DATAGRAMS``: beyond it the
  datagram is counted as dropped for overload, never silently lost);
* one tracking task: every ``tick_s`` it hands the inbox to its worker thread (one thread for the service's
  life: decode, reorder, track, encode), so the event loop stays free for the network, then broadcasts the frames; the
  checkpoint (``save_checkpoint``) is written in the same worker call, between two tracker steps;
* one bounded queue per WebSocket client: a client too slow to take a frame loses it (counted per client and
  in ``frames_dropped``), the tracker never waits for a client.

The Starlette app (:func:`build_app`) serves ``/`` (the display, ``static/index.html``, or a plain page saying
it is missing), ``/ws`` (:mod:`skytrack.service.frames`), ``/health`` (JSON) and ``/metrics`` (Prometheus
text, :mod:`skytrack.service.metrics`).
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from skytrack.service.frames import hello_message, labels_message, stamp_sent_time, status_message

#: datagrams held between two tracking steps at most (about 90 MB of 1 400-byte datagrams)
MAX_INBOX_DATAGRAMS = 65536
#: frames queued per WebSocket client before new ones are dropped for it
CLIENT_QUEUE_FRAMES = 8
#: kernel receive buffer asked for the UDP socket (bursts of a fast replay)
UDP_RECEIVE_BUFFER_BYTES = 8 * 1024 * 1024
#: seconds between two returns of freed heap memory to the system (glibc malloc_trim)
TRIM_EVERY_S = 5.0
STATIC_DIR = Path(__file__).resolve().parent / "static"
MISSING_DISPLAY_PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>skytrack serve</title></head>
<body><h1>skytrack serve</h1><p>The display (skytrack/service/static/index.html) is not installed in this copy of
skytrack. The service runs: <a href="/health">/health</a>, <a href="/metrics">/metrics</a>, WebSocket
<code>/ws</code> (protocol: docs/service.md).</p></body></html>"""


def _malloc_trim():
    """glibc's ``malloc_trim`` (None elsewhere)."""
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


_MALLOC_TRIM = _malloc_trim()


def parse_address(text: str, default_host: str) -> tuple[str, int]:
    """``HOST:PORT`` or ``PORT`` (on ``default_host``), with a clear error."""
    host, _, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"address {text!r}: expected HOST:PORT or PORT") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"address {text!r}: port {number} is not in 0..65535")
    return (host or default_host), number


def is_multicast(host: str) -> bool:
    try:
        first = int(host.split(".")[0])
    except ValueError:
        return False
    return 224 <= first <= 239


@dataclass(eq=False)
class Client:
    """One WebSocket client: its bounded frame queue and what it lost."""

    queue: asyncio.Queue = field(default_factory=lambda: asyncio.Queue(CLIENT_QUEUE_FRAMES))
    dropped: int = 0
    sent: int = 0


class _Receiver(asyncio.DatagramProtocol):
    def __init__(self, service: "LiveService") -> None:
        self.service = service

    def datagram_received(self, data: bytes, addr) -> None:
        self.service.receive(data)

    def error_received(self, exc: Exception) -> None:
        self.service.pipeline.counters["udp_errors"] += 1


class LiveService:
    """The live service's state and tasks (see the module docstring)."""

    def __init__(self, pipeline, udp: tuple[str, int], *, checkpoint_path: Path | None = None,
                 checkpoint_every_s: float = 10.0, tick_s: float = 0.05, resumed_from: str | None = None,
                 log=print) -> None:
        self.pipeline = pipeline
        self.udp = udp
        self.checkpoint_path = checkpoint_path
        self.checkpoint_every_s = checkpoint_every_s
        self.tick_s = tick_s
        self.log = log
        self.resumed_from = resumed_from
        self.inbox: list[bytes] = []
        self.inbox_times: list[float] = []
        self.clients: set[Client] = set()
        self.started_wall = time.time()
        self.last_datagram_wall = float("nan")
        self.last_checkpoint_wall = float("nan")
        self.checkpoint_errors = 0
        self.udp_bound: tuple[str, int] | None = None
        self._transport = None
        self._task: asyncio.Task | None = None
        # one worker thread for every tracking step: the tracker's memory stays in one allocator arena
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="skytrack-tracking")
        self._plots_rate = (time.time(), 0)
        self._last_trim = time.time()
        self.plots_per_s = 0.0

    # ------------------------------------------------------------------ UDP
    def receive(self, data: bytes) -> None:
        now = time.time()
        self.last_datagram_wall = now
        if len(self.inbox) >= MAX_INBOX_DATAGRAMS:
            self.pipeline.counters["datagrams_dropped_overload"] += 1
            return
        self.inbox.append(data)
        self.inbox_times.append(now)

    async def start(self) -> None:
        """Open the UDP socket and start the tracking task (a second call does nothing)."""
        if self._task is not None:
            return
        loop = asyncio.get_running_loop()
        host, port = self.udp
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        if is_multicast(host):  # several receivers of one group may share the port; a unicast port is ours alone
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_RECEIVE_BUFFER_BYTES)
        try:
            if is_multicast(host):
                sock.bind(("", port))
                membership = struct.pack("4s4s", socket.inet_aton(host), socket.inet_aton("0.0.0.0"))
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
            else:
                sock.bind((host, port))
        except OSError as error:
            sock.close()
            what = "join the multicast group" if is_multicast(host) else "listen on"
            raise OSError(error.errno, f"cannot {what} udp://{host}:{port}: {error.strerror}") from None
        self.udp_bound = sock.getsockname()
        self._transport, _ = await loop.create_datagram_endpoint(lambda: _Receiver(self), sock=sock)
        self._task = asyncio.create_task(self._track_forever())

    async def stop(self) -> None:
        """Stop receiving and tracking; with checkpoints, write a last one (a restart then resumes from here)."""
        if self._transport is not None:
            self._transport.close()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self.checkpoint_path is not None and self.pipeline.counters["plots_tracked"]:
            note = await asyncio.get_running_loop().run_in_executor(self._executor, self._save_checkpoint, time.time())
            self.log(note or f"checkpoint written to {self.checkpoint_path} at shutdown")
        self._executor.shutdown(wait=True)

    # ------------------------------------------------------------------ tracking
    def _work(self, datagrams: list[bytes], times: list[float]) -> tuple[list, str | None]:
        """The worker thread's part of one tick: ingest, track, maybe checkpoint."""
        pipeline = self.pipeline
        pipeline.ingest(datagrams, times)
        frames = pipeline.step()
        note = None
        now = time.time()
        if now - self._last_trim >= TRIM_EVERY_S:
            # the tracker's arrays grow and shrink with the tentative tracks: hand freed heap pages back, so
            # the RSS follows the live state rather than the allocator's high-water mark
            self._last_trim = now
            if _MALLOC_TRIM is not None:
                _MALLOC_TRIM(0)
        due = self.checkpoint_path is not None and not (now - self.last_checkpoint_wall < self.checkpoint_every_s)
        if due and pipeline.counters["plots_tracked"]:
            note = self._save_checkpoint(now)
        return frames, note

    def _save_checkpoint(self, now: float) -> str | None:
        from skytrack.app.checkpoint import save_checkpoint

        try:
            save_checkpoint(self.checkpoint_path, self.pipeline.tracker, self.pipeline.labeler)
        except OSError as error:
            self.checkpoint_errors += 1
            self.last_checkpoint_wall = now  # retried at the next period, not at every tick
            return f"checkpoint to {self.checkpoint_path} failed: {error}"
        self.last_checkpoint_wall = now
        self.pipeline.counters["checkpoints"] += 1
        return None

    async def _track_forever(self) -> None:
        next_status = time.time() + 1.0
        while True:
            await asyncio.sleep(self.tick_s)
            datagrams, times = self.inbox, self.inbox_times
            self.inbox, self.inbox_times = [], []
            try:
                frames, note = await asyncio.get_running_loop().run_in_executor(self._executor, self._work,
                                                                                 datagrams, times)
            except Exception as error:  # the service keeps running; the error is counted and shown
                self.pipeline.counters["step_errors"] += 1
                self.pipeline.tracker_errors.append(f"{type(error).__name__}: {error}")
                self.log(f"tracking step failed: {type(error).__name__}: {error}")
                continue
            if note:
                self.log(note)
            try:
                for out in frames:
                    self.broadcast(out)
                now = time.time()
                if now >= next_status:
                    self._update_rate(now)
                    self.send_text(status_message(self.status()))
                    next_status = now + 1.0
            except Exception as error:  # as above: a failed broadcast must not end the tracking task
                self.pipeline.counters["step_errors"] += 1
                self.log(f"broadcast failed: {type(error).__name__}: {error}")

    def _update_rate(self, now: float) -> None:
        then, plots_then = self._plots_rate
        plots = self.pipeline.counters["plots_received"]
        if now > then:
            self.plots_per_s = (plots - plots_then) / (now - then)
        self._plots_rate = (now, plots)

    def broadcast(self, out) -> None:
        """Queue a frame (and the labels that changed) for every client; a full queue drops the frame."""
        now = time.time()
        frame = stamp_sent_time(out.frame, now)
        self.pipeline.record_latency(now)
        self.pipeline.counters["frames_sent"] += 1
        if out.changed_labels:
            self.send_text(labels_message(out.changed_labels))
        for client in list(self.clients):
            try:
                client.queue.put_nowait(frame)
            except asyncio.QueueFull:
                client.dropped += 1
                self.pipeline.counters["frames_dropped"] += 1

    def send_text(self, text: str) -> None:
        for client in list(self.clients):
            try:
                client.queue.put_nowait(text)
            except asyncio.QueueFull:
                client.dropped += 1
                self.pipeline.counters["texts_dropped"] += 1

    # ------------------------------------------------------------------ reports
    def status(self) -> dict:
        pipeline = self.pipeline
        c = pipeline.counters
        return {"plots_per_s": round(float(self.plots_per_s), 1), "plots_received": int(c["plots_received"]),
                "plots_tracked": int(c["plots_tracked"]), "plots_late": int(c["plots_late"]),
                "clients": len(self.clients), "tracks": int(pipeline.tracks_now),
                "frames_dropped": int(c["frames_dropped"])}

    def health(self) -> dict:
        pipeline = self.pipeline
        now = time.time()
        age = now - self.last_datagram_wall if self.last_datagram_wall == self.last_datagram_wall else None
        checkpoint_age = (now - self.last_checkpoint_wall
                          if self.last_checkpoint_wall == self.last_checkpoint_wall else None)
        c = pipeline.counters
        return {
            "ok": self._task is not None and not self._task.done(),
            "uptime_s": now - self.started_wall,
            "udp": None if self.udp_bound is None else f"{self.udp_bound[0]}:{self.udp_bound[1]}",
            "last_datagram_age_s": age,
            "last_plot_age_s": (now - pipeline.newest_received_wall
                                if pipeline.newest_received_wall == pipeline.newest_received_wall else None),
            "last_plot_s": float(pipeline.last_plot_s) if pipeline.last_plot_s == pipeline.last_plot_s else None,
            "tracks": int(pipeline.tracks_now),
            "confirmed_tracks": pipeline.confirmed_tracks,
            "track_ids": sorted(int(i) for i in pipeline.confirmed_track_ids()),
            "plots_received": int(c["plots_received"]), "plots_tracked": int(c["plots_tracked"]),
            "plots_late": int(c["plots_late"]), "late_per_sensor": {
                name: int(n) for name, n in zip(pipeline.sensors.names, pipeline.reorder.late_per_sensor) if n},
            "plots_unknown_sensor": int(c["plots_unknown_sensor"]),
            "unknown_sac_sic": {key: int(n) for key, n in pipeline.unknown_sac_sic.items()},
            "held_plots": len(pipeline.reorder), "clients": len(self.clients),
            "checkpoint_age_s": checkpoint_age, "resumed_from": self.resumed_from,
            "recent_errors": list(pipeline.tracker_errors),
        }


def build_app(service: LiveService):
    """The Starlette app of a :class:`LiveService` (which it starts and stops with the app's lifespan)."""
    from starlette.applications import Starlette
    from starlette.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse
    from starlette.routing import Mount, Route, WebSocketRoute
    from starlette.staticfiles import StaticFiles
    from starlette.websockets import WebSocket, WebSocketDisconnect

    from skytrack.service.metrics import prometheus_text

    async def index(request):
        page = STATIC_DIR / "index.html"
        if page.exists():
            return FileResponse(page)
        return HTMLResponse(MISSING_DISPLAY_PAGE)

    async def health(request):
        return JSONResponse(service.health())

    async def metrics(request):
        return PlainTextResponse(prometheus_text(service), media_type="text/plain; version=0.0.4")

    async def websocket(ws: WebSocket):
        await ws.accept()
        client = Client()
        await ws.send_text(hello_message(service.pipeline.sensors))
        labels = {key: {"callsign": c, "icao24": i} for key, (c, i) in service.pipeline.labels.items()}
        await ws.send_text(labels_message(labels))
        service.clients.add(client)

        async def watch_close():
            with contextlib.suppress(WebSocketDisconnect, RuntimeError):
                while True:
                    message = await ws.receive()
                    if message["type"] == "websocket.disconnect":
                        return

        closed = asyncio.create_task(watch_close())
        try:
            while not closed.done():
                getter = asyncio.create_task(client.queue.get())
                done, _ = await asyncio.wait({getter, closed}, return_when=asyncio.FIRST_COMPLETED)
                if getter not in done:
                    getter.cancel()
                    break
                item = getter.result()
                if isinstance(item, bytes):
                    await ws.send_bytes(item)
                    client.sent += 1
                else:
                    await ws.send_text(item)
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            service.clients.discard(client)
            closed.cancel()

    @contextlib.asynccontextmanager
    async def lifespan(app):
        await service.start()
        try:
            yield
        finally:
            await service.stop()

    routes = [Route("/", index), Route("/health", health), Route("/metrics", metrics),
              WebSocketRoute("/ws", websocket)]
    if (STATIC_DIR / "assets").is_dir():
        routes.append(Mount("/assets", StaticFiles(directory=STATIC_DIR / "assets"), name="assets"))
    if STATIC_DIR.is_dir():
        routes.append(Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"))
    return Starlette(routes=routes, lifespan=lifespan)

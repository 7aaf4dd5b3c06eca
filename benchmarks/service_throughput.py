"""Throughput, latency and memory of ``skytrack serve`` fed by ``skytrack replay`` on loopback (issue 11 item 5).

    python benchmarks/service_throughput.py                  # 600 s, the acceptance run
    python benchmarks/service_throughput.py --duration 60    # a quick check

The scene: the demo radar (4 s scan, 250 km) with 1 500 aircraft and 6 000 false plots per scan (about
1 850 plots/s), 600 s simulated once and cached in ``--work`` (a folder in the temporary directory);
``skytrack replay --loop`` sends it at ``--speed`` x real time (28 by default: about 51 000 plots/s), each
pass later by the span rounded up to whole scans (the aircraft jump back to their start every pass, about 22 s
of wall time: their tracks end and new ones start, which the tracker pays for too).  Both commands run as
subprocesses; this script is the WebSocket client.

Measured:

* plots/s held: plots the service tracked per second of wall time over the measurement (after the warm-up),
  beside the plots/s replay sent, the late plots and the datagrams dropped for overload (all must stay 0 for
  "held");
* latency of a frame: its receive time here minus the wall time replay sent the newest plot in the frame
  (``last_plot_s`` in the frame header; replay's ``--send-log`` gives the send time of the first datagram whose
  newest record is at least that late, so the figure is an upper bound); p50, p99, max over the frames after
  the warm-up;
* memory: the service's RSS every second (psutil when installed, else /proc/PID/status VmRSS); growth = RSS at
  the end minus RSS after the warm-up (``--warmup``, 60 s; 10 s for a run under 2 minutes).

Writes ``--json`` (default ``service_throughput.json`` in ``--work``) and prints one summary line.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import machine  # noqa: E402
import scenes  # noqa: E402

AIRCRAFT = 1500
CLUTTER_PER_SCAN = 6000
SCENE_DURATION_S = 600.0


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def build_scene(work: Path) -> tuple[Path, Path]:
    plots_path, sensors_path = work / "plots.parquet", work / "sensors.json"
    if plots_path.exists() and sensors_path.exists():
        return plots_path, sensors_path
    from skytrack.io import write_sensors
    from skytrack.sim import simulate

    scenario = scenes.with_clutter(scenes.scaled_demo(AIRCRAFT, SCENE_DURATION_S), CLUTTER_PER_SCAN)
    result = simulate(scenario)
    columns = [c for c in ("time", "sensor", "range_m", "azimuth_deg", "mode3a", "mode_c_ft", "mode_s")
               if c in result.plots.columns]
    result.plots[columns].to_parquet(plots_path)
    write_sensors(result.sensors, sensors_path)
    return plots_path, sensors_path


def rss_bytes(pid: int) -> int | None:
    try:
        import psutil

        return psutil.Process(pid).memory_info().rss
    except ImportError:
        pass
    except Exception:
        return None
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def get_json(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=5) as response:
        return json.loads(response.read())


def metrics(url: str) -> dict[str, float]:
    with urllib.request.urlopen(url, timeout=5) as response:
        text = response.read().decode()
    return {name: float(value) for name, value in
            (line.rsplit(" ", 1) for line in text.splitlines() if line and not line.startswith("#"))}


class FrameClient(threading.Thread):
    """Receives frames from /ws; keeps (receive wall, t_s, last_plot_s, n) per frame."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.records: list[tuple[float, float, float, int]] = []
        self.stop = threading.Event()

    def run(self) -> None:
        from websockets.sync.client import connect

        with connect(self.url, max_size=None) as ws:
            while not self.stop.is_set():
                try:
                    message = ws.recv(timeout=0.5)
                except TimeoutError:
                    continue
                now = time.time()
                if isinstance(message, bytes):
                    n, t_s, last_plot_s = struct.unpack_from("<Idd", message, 4)
                    self.records.append((now, t_s, last_plot_s, n))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="seconds of replay (wall time)")
    parser.add_argument("--speed", type=float, default=28.0, help="replay speed (x real time)")
    parser.add_argument("--warmup", type=float, default=None, help="seconds before memory and latency count")
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "skytrack-service-throughput",
                        help="folder of the cached scene, the logs and the JSON")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--max-datagram", type=int, default=1400)
    args = parser.parse_args()
    warmup = args.warmup if args.warmup is not None else (60.0 if args.duration >= 120 else 10.0)
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    plots_path, sensors_path = build_scene(work)
    from skytrack.io import read_sensors
    from skytrack.service.pipeline import time_of_day_at_epoch

    sensors = read_sensors(sensors_path)
    tod_epoch = time_of_day_at_epoch(sensors.epoch_utc)
    udp_port, http_port = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    base = f"http://127.0.0.1:{http_port}"
    log_path = work / "send_log.bin"
    log_path.unlink(missing_ok=True)
    serve_out = open(work / "serve.log", "w")
    serve = subprocess.Popen([sys.executable, "-m", "skytrack", "serve", "--sensors", str(sensors_path),
                              "--udp", f"127.0.0.1:{udp_port}", "--http", f"127.0.0.1:{http_port}"],
                             stdout=serve_out, stderr=subprocess.STDOUT)
    replay = None
    try:
        deadline = time.time() + 60
        while True:
            try:
                get_json(base + "/health")
                break
            except OSError:
                if time.time() > deadline or serve.poll() is not None:
                    raise SystemExit(f"skytrack serve did not start: see {work / 'serve.log'}")
                time.sleep(0.2)
        client = FrameClient(f"ws://127.0.0.1:{http_port}/ws")
        client.start()
        rss: list[tuple[float, int]] = []
        started = time.time()
        replay = subprocess.Popen([sys.executable, "-m", "skytrack", "replay", str(plots_path), "--sensors",
                                   str(sensors_path), "--to", f"udp://127.0.0.1:{udp_port}", "--speed", str(args.speed),
                                   "--loop", "--duration-s", str(args.duration), "--send-log", str(log_path),
                                   "--max-datagram", str(args.max_datagram)],
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        at_warmup = None
        while replay.poll() is None:
            time.sleep(1.0)
            value = rss_bytes(serve.pid)
            if value is not None:
                rss.append((time.time() - started, value))
            if at_warmup is None and time.time() - started >= warmup:
                at_warmup = (time.time(), metrics(base + "/metrics"))
        replay_text = replay.stdout.read()
        ended = time.time()
        at_end = metrics(base + "/metrics")
        time.sleep(2.0)  # the last plots leave the reorder buffer
        final = metrics(base + "/metrics")
        health = get_json(base + "/health")
        client.stop.set()
        client.join(timeout=5)
    finally:
        if replay is not None and replay.poll() is None:
            replay.terminate()
        serve.send_signal(signal.SIGINT)
        try:
            serve.wait(timeout=15)
        except subprocess.TimeoutExpired:
            serve.kill()
        serve_out.close()

    from skytrack.service.replay import read_send_log

    log = read_send_log(log_path)
    frames = np.array(client.records, float).reshape(-1, 4)
    # frames after the replay ended carry the last plots, released when the feed went idle: not counted
    measured = frames[(frames[:, 0] >= started + warmup) & (frames[:, 0] <= ended)]
    carried = np.searchsorted(log[:, 0], measured[:, 2] + tod_epoch - 1e-6, side="left")
    known = carried < len(log)
    latency = measured[known, 0] - log[carried[known], 1]
    t_warm, m_warm = at_warmup if at_warmup is not None else (started, {})
    # rates over the warm-up's end .. the replay's end (plots still in the 2 s reorder window are not counted)
    tracked = at_end["skytrack_plots_tracked_total"] - m_warm.get("skytrack_plots_tracked_total", 0.0)
    received = at_end["skytrack_plots_received_total"] - m_warm.get("skytrack_plots_received_total", 0.0)
    span = ended - t_warm
    rss_after = [v for t, v in rss if t >= warmup]
    sent_line = [line for line in replay_text.splitlines() if line.startswith("sent ")]
    result = {
        "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpu": machine.cpu_model(), "cores": machine.usable_cores(), "python": platform.python_version()},
        "scene": {"aircraft": AIRCRAFT, "clutter_per_scan": CLUTTER_PER_SCAN, "scene_s": SCENE_DURATION_S,
                  "speed": args.speed, "max_datagram_bytes": args.max_datagram},
        "duration_s": args.duration, "warmup_s": warmup,
        "replay": sent_line[0] if sent_line else replay_text.strip()[-300:],
        "plots_received_per_s": received / span, "plots_tracked_per_s": tracked / span,
        "plots_late": int(final["skytrack_plots_late_total"]),
        "datagrams_dropped_overload": int(final["skytrack_datagrams_dropped_overload_total"]),
        "datagrams_received": int(final["skytrack_datagrams_total"]), "datagrams_sent": int(len(log)),
        "frames": int(len(frames)), "frames_measured": int(len(measured)),
        "latency_s": {"p50": float(np.percentile(latency, 50)) if len(latency) else None,
                      "p99": float(np.percentile(latency, 99)) if len(latency) else None,
                      "max": float(latency.max()) if len(latency) else None},
        "worst_latencies_s_at_s": [(round(float(measured[known][i, 0] - started), 1), round(float(latency[i]), 3))
                                   for i in np.argsort(latency)[-10:][::-1]],
        "service_latency_s_p99": final.get('skytrack_processing_latency_seconds{quantile="0.99"}'),
        "rss_mb": {"after_warmup": rss_after[0] / 2**20 if rss_after else None,
                   "end": rss_after[-1] / 2**20 if rss_after else None,
                   "growth": (rss_after[-1] - rss_after[0]) / 2**20 if rss_after else None,
                   "max": max(rss_after) / 2**20 if rss_after else None},
        "tracks_at_end": health.get("tracks"),
        "plots_tracked_total": int(final["skytrack_plots_tracked_total"]),
        "rss_mb_every_5s": [round(v / 2**20, 1) for t, v in rss[::5]],
    }
    out = args.json or work / "service_throughput.json"
    out.write_text(json.dumps(result, indent=2))
    lat = result["latency_s"]
    print(f"service_throughput: {result['plots_tracked_per_s']:,.0f} plots/s tracked over {span:.0f} s "
          f"(received {result['plots_received_per_s']:,.0f}/s, late {result['plots_late']}, overload drops "
          f"{result['datagrams_dropped_overload']}, "
          f"datagrams {result['datagrams_received']}/{result['datagrams_sent']}); "
          f"latency p50 {lat['p50']:.3f} s p99 {lat['p99']:.3f} s max {lat['max']:.3f} s over "
          f"{result['frames_measured']} frames; RSS growth {result['rss_mb']['growth']:+.1f} MB "
          f"(after warm-up {result['rss_mb']['after_warmup']:.0f} MB); {result['machine']['cpu']}, "
          f"{result['machine']['cores']} cores; {result['date_utc']} -> {out}")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()

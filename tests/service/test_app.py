"""skytrack serve's HTTP side (skytrack.service.app) with Starlette's TestClient and a real loopback UDP socket:
/health, /metrics, /ws hello + labels + frames, tracks appearing and moving, the display page, a slow client."""

from __future__ import annotations

import asyncio
import json
import socket
import time

import numpy as np
import pytest
from starlette.testclient import TestClient

from skytrack.service.app import LiveService, build_app, parse_address
from skytrack.service.frames import decode_frame
from skytrack.service.pipeline import sensor_sac_sic, time_of_day_at_epoch
from skytrack.service.replay import Replayer, scan_blocks
from skytrack.service.server import build_service


def _recording(sensors, plots):
    from skytrack.io.asterix.recording import encode_recording

    data = encode_recording(plots, sensor_sac_sic(sensors), max_records_per_block=60,
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc))
    return scan_blocks(np.frombuffer(data, np.uint8))


def _wait(predicate, timeout_s=20.0):
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def test_health_metrics_and_websocket_over_loopback_udp(small_scene, tmp_path):
    sensors, plots = small_scene
    service = build_service(None, ("127.0.0.1", 0), sensors=sensors, window_s=2.0, checkpoint_dir=tmp_path,
                            checkpoint_every_s=0.5, tick_s=0.02, log=lambda text: None)
    with TestClient(build_app(service)) as client:
        health = client.get("/health").json()
        assert health["ok"] is True and health["tracks"] == 0 and health["last_datagram_age_s"] is None
        assert health["last_plot_age_s"] is None
        port = service.udp_bound[1]
        with client.websocket_connect("/ws") as ws:
            hello = json.loads(ws.receive_text())
            assert hello["type"] == "hello" and hello["sensors"][0]["name"] == "radar1"
            assert hello["origin"] == {"lat": 48.86, "lon": 2.5, "alt_m": 0.0}
            assert json.loads(ws.receive_text()) == {"type": "labels", "labels": {}}
            # 120 s of plots at x40: about 3 s of wall time, through the real UDP socket
            report = Replayer(_recording(sensors, plots), ("127.0.0.1", port), speed=40.0).run()
            assert report.records == len(plots)
            frames, statuses = [], []
            deadline = time.time() + 20
            while time.time() < deadline and (not frames or decode_frame(frames[-1])["t_s"] < 100):
                message = ws.receive()
                if message.get("bytes") is not None:
                    frames.append(message["bytes"])
                elif message.get("text"):
                    statuses.append(json.loads(message["text"]))
        decoded = [decode_frame(f) for f in frames]
        assert [d["sequence"] for d in decoded] == sorted(d["sequence"] for d in decoded)
        assert decoded[-1]["n"] >= 10 and decoded[-1]["t_s"] >= 100
        # a track present early and late has moved kilometres
        first = next(d for d in decoded if d["n"] >= 5)
        common = np.intersect1d(first["track_id"], decoded[-1]["track_id"])
        assert len(common) >= 5
        k0, k1 = (np.flatnonzero(d["track_id"] == common[0])[0] for d in (first, decoded[-1]))
        moved_m = 111_200 * np.hypot(decoded[-1]["lat_deg"][k1] - first["lat_deg"][k0],
                                     (decoded[-1]["lon_deg"][k1] - first["lon_deg"][k0]) * np.cos(np.radians(48.86)))
        assert moved_m > 2_000
        assert {s["type"] for s in statuses} == {"status", "labels"}
        assert [s for s in statuses if s["type"] == "status"][-1]["clients"] == 1
        # Mode S tracks are labelled with their address (the scene has no ADS-B: no callsign)
        labels = {k: v for s in statuses if s["type"] == "labels" for k, v in s["labels"].items()}
        assert labels and all(len(v["icao24"]) == 6 and v["callsign"] is None for v in labels.values())
        assert _wait(lambda: service.pipeline.counters["plots_tracked"] == len(plots))
        health = client.get("/health").json()
        assert health["plots_received"] == len(plots) and health["plots_late"] == 0
        assert health["confirmed_tracks"] >= 10 and len(health["track_ids"]) == health["confirmed_tracks"]
        assert health["last_datagram_age_s"] < 30 and health["checkpoint_age_s"] is not None
        assert health["last_plot_age_s"] >= health["last_datagram_age_s"] - 0.1
        metrics = client.get("/metrics").text
        values = dict(line.rsplit(" ", 1) for line in metrics.splitlines() if line and not line.startswith("#"))
        assert int(values["skytrack_plots_received_total"]) == len(plots)
        assert int(values["skytrack_datagrams_total"]) == report.datagrams
        assert int(values["skytrack_frames_sent_total"]) >= len(frames)
        assert int(values["skytrack_checkpoints_total"]) >= 1 and (tmp_path / "skytrack.checkpoint.npz").exists()
        assert 0 <= float(values['skytrack_processing_latency_seconds{quantile="0.99"}']) < 10
        assert "# TYPE skytrack_plots_late_total counter" in metrics
        page = client.get("/")
        assert page.status_code == 200 and "<html" in page.text.lower()
        checkpoints = service.pipeline.counters["checkpoints"]
    # the app's shutdown writes one more checkpoint, with every plot tracked
    assert service.pipeline.counters["checkpoints"] == checkpoints + 1
    from skytrack.app.checkpoint import read_checkpoint

    header, _ = read_checkpoint(tmp_path / "skytrack.checkpoint.npz")
    assert header["last_plot_s"] == pytest.approx(float(plots["time"].max()), abs=1 / 128)


def test_a_slow_client_loses_frames_and_the_tracker_goes_on(small_scene):
    sensors, _ = small_scene
    service = build_service(None, ("127.0.0.1", 0), sensors=sensors, log=lambda text: None)

    class Out:
        frame = b"SKT1" + bytes(36)
        changed_labels = {}

    async def run():
        from skytrack.service.app import CLIENT_QUEUE_FRAMES, Client

        slow = Client()
        service.clients.add(slow)
        for _ in range(CLIENT_QUEUE_FRAMES + 5):
            service.broadcast(Out())
        return slow

    slow = asyncio.run(run())
    assert slow.dropped == 5 and service.pipeline.counters["frames_dropped"] == 5
    assert service.pipeline.counters["frames_sent"] == 13


def test_udp_datagrams_beyond_the_inbox_are_counted(small_scene, monkeypatch):
    import skytrack.service.app as app_module

    sensors, _ = small_scene
    service = build_service(None, ("127.0.0.1", 0), sensors=sensors, log=lambda text: None)
    monkeypatch.setattr(app_module, "MAX_INBOX_DATAGRAMS", 3)
    for _ in range(5):
        service.receive(b"\x30\x00\x03")
    assert len(service.inbox) == 3 and service.pipeline.counters["datagrams_dropped_overload"] == 2


def test_a_port_in_use_is_named(small_scene):
    sensors, _ = small_scene
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        service = build_service(None, ("127.0.0.1", port), sensors=sensors, log=lambda text: None)
        with pytest.raises(OSError, match=f"cannot listen on udp://127.0.0.1:{port}"):
            asyncio.run(service.start())


def test_addresses_are_checked():
    assert parse_address("239.1.2.3:5000", "0.0.0.0") == ("239.1.2.3", 5000)
    assert parse_address("8080", "127.0.0.1") == ("127.0.0.1", 8080)
    with pytest.raises(ValueError, match="expected HOST:PORT"):
        parse_address("localhost:http", "x")
    with pytest.raises(ValueError, match="not in 0..65535"):
        parse_address("1.2.3.4:70000", "x")


def test_multicast_group_is_joined(small_scene):
    sensors, plots = small_scene
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    service = LiveService(build_service(None, ("127.0.0.1", 0), sensors=sensors, log=lambda t: None).pipeline,
                          ("239.255.11.7", port), tick_s=0.02)

    async def run():
        try:
            await service.start()
        except OSError as error:  # no multicast-capable interface in this sandbox
            pytest.skip(str(error))
        try:
            sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sender.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
            sender.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            try:
                sender.sendto(b"\x30\x00\x03", ("239.255.11.7", port))
            except OSError as error:  # no multicast route in this sandbox
                pytest.skip(f"no multicast route: {error}")
            for _ in range(40):
                await asyncio.sleep(0.05)
                if service.pipeline.counters["datagrams"]:
                    break
        finally:
            await service.stop()

    asyncio.run(run())
    assert service.pipeline.counters["datagrams"] == 1
